"""Joint angles, repetitions and cycles, and the metrics computed from them."""
