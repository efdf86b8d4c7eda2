"""motionlab: clinical motion analysis with wearable inertial sensors.

Conventions (fixed, see docs/architecture.md): SI units inside the code, Hamilton quaternions
scalar first ``[w, x, y, z]`` mapping sensor-frame vectors into the ENU earth frame, ISB segment
frames, first array dimension is time.
"""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("motionlab")
except PackageNotFoundError:  # running from a source tree that was not installed
    __version__ = "0.0.0+unknown"
