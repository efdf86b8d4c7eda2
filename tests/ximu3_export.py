"""A small synthetic x-IMU3 export (the x-IMU3 GUI's folder per device, one CSV per channel),
made here because the real recordings we have carry no licence. Used by
``tests/test_io_ximu3.py`` and the fault campaign (``tests/faults.py``).

The device turns at ``RATE_DEG_S`` about its z axis with gravity along +z (1 g), so its
quaternion (NWU) is a known turn about the vertical and every value can be checked.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

T0_US = 3_682_016_768  # a device clock that does not start at 0, as in the real exports
INERTIAL_HZ, MAG_HZ, QUAT_HZ = 50.0, 20.0, 100.0
RATE_DEG_S = 30.0


def _csv(header: str, rows: np.ndarray, stamps: np.ndarray) -> bytes:
    lines = [header] + [
        f"{int(t)}," + ",".join(f"{v:.6f}" for v in row)
        for t, row in zip(stamps, rows, strict=True)
    ]
    return ("\n".join(lines) + "\n").encode()


def device_files(name: str, serial: str, seconds: float = 3.0) -> dict[str, bytes]:
    """``{file name: bytes}`` of one device folder."""
    n = int(seconds * INERTIAL_HZ)
    t_in = T0_US + np.round(np.arange(n) * 1e6 / INERTIAL_HZ)
    gyr = np.tile([0.0, 0.0, RATE_DEG_S], (n, 1))
    acc = np.tile([0.0, 0.0, 1.0], (n, 1))
    nm = int(seconds * MAG_HZ)
    t_mag = T0_US + 3000 + np.round(np.arange(nm) * 1e6 / MAG_HZ)
    yaw_m = np.radians(RATE_DEG_S) * (t_mag - T0_US) * 1e-6
    mag = np.column_stack([np.cos(-yaw_m) * 0.4, np.sin(-yaw_m) * 0.4, -0.9 + 0 * yaw_m])
    nq = int(seconds * QUAT_HZ)
    t_q = T0_US + np.round(np.arange(nq) * 1e6 / QUAT_HZ)
    half = 0.5 * np.radians(RATE_DEG_S) * (t_q - T0_US) * 1e-6
    quat = np.column_stack([np.cos(half), 0 * half, 0 * half, np.sin(half)])
    return {
        "Inertial.csv": _csv(
            "Timestamp (us),Gyroscope X (deg/s),Gyroscope Y (deg/s),Gyroscope Z (deg/s),"
            "Accelerometer X (g),Accelerometer Y (g),Accelerometer Z (g)",
            np.hstack([gyr, acc]),
            t_in,
        ),
        "Magnetometer.csv": _csv("Timestamp (us),X (a.u.),Y (a.u.),Z (a.u.)", mag, t_mag),
        "Quaternion.csv": _csv("Timestamp (us),W,X,Y,Z", quat, t_q),
        "HighGAccelerometer.csv": _csv("Timestamp (us),X (g),Y (g),Z (g)", acc, t_in),
        "Battery.csv": b"Timestamp (us),Percentage (%),Voltage (V),Charging Status\n"
        + f"{T0_US},87.4,3.87,0.0\n".encode(),
        "Command.json": json.dumps(
            [
                {"ping": {"deviceName": name, "interface": "UDP", "serialNumber": serial}},
                {"time": "2025-02-13 11:28:59"},
            ],
            indent=4,
        ).encode(),
    }


DEVICES = (("Back", "B4A2-5410-EC7B-D68C"), ("Chest", "37CE-5410-EC7B-D8A2"))


def export_files(devices=DEVICES, seconds: float = 3.0) -> dict[str, bytes]:
    """``{relative path: bytes}`` of a trial folder ``imu/`` holding one folder per device."""
    out = {}
    for name, serial in devices:
        for f, data in device_files(name, serial, seconds).items():
            out[f"imu/{name} {serial} (UDP)/{f}"] = data
    return out


def write(root: Path, files: dict[str, bytes]) -> Path:
    """Write ``files`` under ``root``; returns ``root / "imu"``."""
    for rel, data in files.items():
        p = root / rel
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_bytes(data)
    return root / "imu"
