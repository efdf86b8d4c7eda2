"""The benches' ``--seeds`` syntax: a range ``0-9`` (both ends included) or a list ``1,4,7``."""

from __future__ import annotations

import argparse


def seeds_arg(text: str) -> list[int]:
    """``--seeds`` for argparse's ``type=``: ``"0-9"`` → 0, 1, …, 9; ``"1,4,7"`` → [1, 4, 7].
    Anything else is argparse's one-line usage error, not a traceback."""
    try:
        if "-" in text:
            first, last = text.split("-")
            seeds = list(range(int(first), int(last) + 1))
        else:
            seeds = [int(s) for s in text.split(",") if s.strip()]
    except ValueError:
        seeds = []
    if not seeds:
        raise argparse.ArgumentTypeError(
            f"{text!r}: give a range such as 0-9 or a list such as 1,4,7"
        )
    return seeds
