"""The exact truth of a simulated session: HDF5 (:func:`save_truth`, :func:`load_truth`) and CSV.

Layout (``h5dump`` shows it; SI units and rad inside, joint angles in degrees)::

    /                       attrs: format = motionlab-truth, schema_version, config (JSON)
    /time                   (N,) true time (s) of the truth grid
    /segments/<seg>/        orientation (N,4) segment → ENU, position (N,3) segment origin (m)
    /sensors/<label>/       orientation (N,4) sensor → ENU and position (N,3) on the grid,
                            mounting (4,) sensor → segment, site (3,) m, sample_time (M,) true
                            time of each recorded sample, gyr_bias/acc_bias/mag_bias (M,3),
                            gyr_matrix/acc_matrix/mag_matrix (3,3), soft_iron (3,3),
                            hard_iron (3,); attrs: segment, clock_offset_s, clock_drift, jitter_s
                            With --mounting random|surface or soft tissue ``motion`` also:
                            wobble (N,4) the sensor's rotation on its segment in the sensor frame
                            (orientation = segment ⊗ mounting ⊗ wobble), displacement (N,3) m of
                            the site (position = segment origin + R_seg (site + displacement)),
                            normal (3,) skin normal at the site; attrs tissue_hz,
                            tissue_damping, slip_deg (see simulate/signals.py)
    /joint_angles/<column>  (N,) degrees, columns named by ``column_name`` (e.g. knee_r_flexion_deg)
    /steps/                 name, kind, phase, generator (str), start_s, end_s (true time)
    /gait/                  only with --gait: ic_r, fc_r, ic_l, fc_l (K,) event times (s, true
                            time) with *_steady (K,) bool; pelvis_tilt_deg, pelvis_obliquity_deg,
                            pelvis_rotation_deg (N,) and walking_heading (N,) rad on /time
    /markers/               labels, segments, kinds, local (M,3) m; lab_rotation (4,) lab → ENU,
                            lab_origin (3,); frame_time (F,) true time of each optical frame;
                            attrs: rate_hz, clock_offset_s, clock_drift
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import h5py
import numpy as np
import pandas as pd

from motionlab.atomic import atomic_path
from motionlab.errors import InputError
from motionlab.isolated import check_hdf5, open_hdf5

FORMAT = "motionlab-truth"
SCHEMA_VERSION = 1


@dataclass
class Truth:
    """Everything the simulator knows exactly (see the module docstring for the fields)."""

    time: np.ndarray
    segments: dict[str, dict[str, np.ndarray]] = field(default_factory=dict)
    sensors: dict[str, dict[str, Any]] = field(default_factory=dict)
    joint_angles: dict[str, np.ndarray] = field(default_factory=dict)
    steps: list[dict[str, Any]] = field(default_factory=list)
    markers: dict[str, Any] = field(default_factory=dict)
    config: dict[str, Any] = field(default_factory=dict)
    #: only with ``simulate(gait=...)``: events (s) per side and pelvis angles (deg), see
    #: :mod:`motionlab.simulate.gait_truth`
    gait: dict[str, Any] = field(default_factory=dict)

    def step(self, name: str) -> dict[str, Any]:
        """The step or task called ``name``."""
        for s in self.steps:
            if s["name"] == name:
                return s
        raise KeyError(name)

    def true_time(self, label: str, stamps: np.ndarray, t: np.ndarray) -> np.ndarray:
        """True time (s) of the instants ``t`` (s) read on sensor ``label``'s own clock.

        ``stamps``: the sensor's recorded stamps (s), the simulated session's
        ``sensors[label].time`` as written. An analysis's ``time_s`` is on its clock sync's
        reference sensor's clock, which is off the true time by that sensor's clock offset
        (tens of ms with the ``typical`` sensors): read the truth at
        ``true_time(reference, ...)``, not at ``time_s`` (23 ms out of step are 5° RMSE on
        a walk's knee flexion).
        """
        sample_time = np.asarray(self.sensors[label]["sample_time"], float)
        stamps = np.asarray(stamps, float)
        if stamps.shape != sample_time.shape:
            raise InputError(
                f"sensor {label!r} has {stamps.size} stamps, its truth {sample_time.size} samples",
                where="argument stamps",
                remedy="give the stamps of the simulated session this truth was written with",
            )
        return np.interp(np.asarray(t, float), stamps, sample_time)


def _write(group: h5py.Group, tree: dict[str, Any]) -> None:
    for key, value in tree.items():
        if isinstance(value, dict):
            _write(group.create_group(key, track_order=True), value)
        elif isinstance(value, np.ndarray) and value.dtype.kind not in "UO":
            group.create_dataset(key, data=value)
        elif isinstance(value, (list, np.ndarray)) and all(isinstance(v, str) for v in value):
            ds = group.create_dataset(key, data=list(value), dtype=h5py.string_dtype())
            ds.attrs["kind"] = "str"
        else:
            group.attrs[key] = json.dumps(value, default=_plain)


def _plain(value: Any) -> Any:
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    raise TypeError(f"cannot store {type(value).__name__}")


def _read(group: h5py.Group) -> dict[str, Any]:
    out: dict[str, Any] = {k: json.loads(v) for k, v in group.attrs.items()}
    for key, item in group.items():
        if isinstance(item, h5py.Group):
            out[key] = _read(item)
        elif item.attrs.get("kind") == "str":
            out[key] = list(item.asstr()[()])
        else:
            out[key] = item[()]
    return out


def save_truth(truth: Truth, path: str | Path, force: bool = False) -> None:
    """Write the truth file atomically (an existing file is replaced only with ``force``)."""
    steps = {col: [s[col] for s in truth.steps] for col in ("name", "kind", "phase", "generator")}
    steps.update({col: np.array([s[col] for s in truth.steps]) for col in ("start_s", "end_s")})
    with atomic_path(path, force=force) as tmp, h5py.File(tmp, "w", track_order=True) as f:
        f.attrs["format"] = FORMAT
        f.attrs["schema_version"] = SCHEMA_VERSION
        f.attrs["config"] = json.dumps(truth.config, default=_plain, sort_keys=True)
        f.create_dataset("time", data=truth.time).attrs["unit"] = "s"
        _write(f.create_group("segments", track_order=True), truth.segments)
        _write(f.create_group("sensors", track_order=True), truth.sensors)
        ja = f.create_group("joint_angles", track_order=True)
        for col, values in truth.joint_angles.items():
            ja.create_dataset(col, data=values).attrs["unit"] = "deg"
        _write(f.create_group("steps", track_order=True), steps)
        _write(f.create_group("markers", track_order=True), truth.markers)
        if truth.gait:  # only when asked for, so other truth files keep their bytes
            _write(f.create_group("gait", track_order=True), truth.gait)


def load_truth(path: str | Path) -> Truth:
    """Read a truth file written by :func:`save_truth`."""
    path = Path(path)
    if not path.is_file():
        raise InputError("no such truth file", path, remedy="check the path")
    check_hdf5(path)
    with open_hdf5(path, "not an HDF5 file", "give a truth file the simulator wrote") as f:
        if f.attrs.get("format") != FORMAT:
            raise InputError(
                "HDF5 file is not a motionlab truth file",
                path,
                remedy="give a truth file the simulator wrote (write_truth)",
            )
        steps = _read(f["steps"])
        n = len(steps.get("name", []))
        return Truth(
            time=f["time"][()],
            segments=_read(f["segments"]),
            sensors=_read(f["sensors"]),
            joint_angles={k: v[()] for k, v in f["joint_angles"].items()},
            steps=[
                {k: (v[i].item() if isinstance(v, np.ndarray) else v[i]) for k, v in steps.items()}
                for i in range(n)
            ],
            markers=_read(f["markers"]),
            config=json.loads(f.attrs["config"]),
            gait=_read(f["gait"]) if "gait" in f else {},
        )


def _quat_columns(prefix: str) -> list[str]:
    return [f"{prefix}_q{c}" for c in "wxyz"]


def _orientation_table(time: dict[str, np.ndarray], bodies: dict[str, dict]) -> pd.DataFrame:
    """``time_s`` and the four quaternion columns of each body's ``orientation``."""
    return pd.DataFrame(
        time
        | {
            col: body["orientation"][:, i]
            for name, body in bodies.items()
            for i, col in enumerate(_quat_columns(name))
        }
    )


def write_truth_csv(truth: Truth, folder: str | Path, force: bool = False) -> list[Path]:
    """Write the truth as CSV tables (degrees for angles, unit in every column name)."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    time = {"time_s": truth.time}
    tables: dict[str, pd.DataFrame] = {
        "joint_angles.csv": pd.DataFrame(time | truth.joint_angles),
        "segment_orientations.csv": _orientation_table(time, truth.segments),
        "sensor_orientations.csv": _orientation_table(time, truth.sensors),
        "steps.csv": pd.DataFrame(truth.steps),
    }
    rows = []
    for label, s in truth.sensors.items():
        row = {"sensor": label, "segment": s["segment"]}
        row |= dict(zip(_quat_columns("mounting"), s["mounting"], strict=True))
        row |= {f"site_{a}_m": v for a, v in zip("xyz", s["site"], strict=True)}
        row |= {"clock_offset_s": s["clock_offset_s"], "clock_drift_ppm": s["clock_drift"] * 1e6}
        row |= {
            f"gyr_bias0_{a}_deg_s": np.degrees(v)
            for a, v in zip("xyz", s["gyr_bias"][0], strict=True)
        }  # noqa: E501
        row |= {f"acc_bias0_{a}_m_s2": v for a, v in zip("xyz", s["acc_bias"][0], strict=True)}
        row |= {f"hard_iron_{a}_uT": v for a, v in zip("xyz", s["hard_iron"], strict=True)}
        rows.append(row)
    tables["sensors.csv"] = pd.DataFrame(rows)
    m = truth.markers
    if m:
        tables["markers.csv"] = pd.DataFrame(
            {"marker": m["labels"], "segment": m["segments"], "kind": m["kinds"]}
            | {f"{a}_m": m["local"][:, i] for i, a in enumerate("xyz")}
        )
        tables["lab_frame.csv"] = pd.DataFrame(
            [
                dict(zip(_quat_columns("lab_to_enu"), m["lab_rotation"], strict=True))
                | {f"origin_{a}_m": v for a, v in zip("xyz", m["lab_origin"], strict=True)}
                | {
                    "optical_clock_offset_s": m["clock_offset_s"],
                    "optical_clock_drift_ppm": m["clock_drift"] * 1e6,
                }  # fmt: skip
            ]
        )
    written = []
    for name, table in tables.items():
        with atomic_path(folder / name, force=force) as tmp:
            table.to_csv(tmp, index=False, float_format="%.9g")
        written.append(folder / name)
    return written
