"""Normative reference data for the report: cycle bands and expected accuracy (data files).

The files live in ``motionlab/report_data/`` (``reports/`` at the top of the repository):

- ``normative_curves.csv`` + ``normative.yaml``: mean ± 1 SD curves over the cycle (0-100 %) at
  key instants, interpolated with a shape-preserving cubic (PCHIP, scipy); the YAML names each
  band's source. Angles are named ``<joint type>_<angle>`` (``knee_flexion``) and apply to
  both sides.
- ``accuracy.yaml``: motionlab's own accuracy per protocol and angle (RMSE against a known
  truth: simulated recordings), with the date, version and command that produced it; a
  protocol's ``real`` entry holds the figures of real recordings against an optical reference
  (offset-free RMSE, median and worst over the recordings, with their conditions).

Normal *ranges* (min-max per task) belong to each protocol's ``normative`` key, not here.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import yaml
from scipy.interpolate import PchipInterpolator

from motionlab.errors import InputError

DATA = Path(__file__).resolve().parent.parent / "report_data"
CURVES = DATA / "normative_curves.csv"
SOURCES = DATA / "normative.yaml"
ACCURACY = DATA / "accuracy.yaml"
GAIT_SOURCES = DATA / "gait_normative.yaml"
CURVE_COLUMNS = ("task", "angle", "percent_pct", "mean_deg", "sd_deg")


@dataclass
class Band:
    """A normative cycle band: ``mean`` and ``sd`` (deg) at ``percent`` (0-100)."""

    task: str
    angle: str
    percent: np.ndarray
    mean: np.ndarray
    sd: np.ndarray
    source: str
    note: str = ""


def _yaml(path: Path) -> dict[str, Any]:
    try:
        doc = yaml.safe_load(path.read_text(encoding="utf-8")) or {}
    except (OSError, yaml.YAMLError) as exc:
        raise InputError(f"cannot read ({exc})", path, remedy="reinstall motionlab") from None
    if not isinstance(doc, dict):
        raise InputError("is not a mapping", path, remedy="reinstall motionlab")
    return doc


@lru_cache(maxsize=4)
def load_bands(curves: Path = CURVES, sources: Path = SOURCES) -> dict[tuple[str, str], Band]:
    """All bands ``{(task, angle): Band}`` on a 0, 1, …, 100 % grid."""
    table = pd.read_csv(curves, comment="#")
    missing = [c for c in CURVE_COLUMNS if c not in table.columns]
    if missing:
        raise InputError(f"missing columns {', '.join(missing)}", curves, "header")
    info = _yaml(sources).get("curves", {})
    grid = np.arange(101.0)
    out = {}
    for (task, angle), rows in table.groupby(["task", "angle"], sort=False):
        rows = rows.sort_values("percent_pct")
        pct = rows["percent_pct"].to_numpy(float)
        if len(pct) < 2 or pct[0] > 0 or pct[-1] < 100 or np.any(np.diff(pct) <= 0):
            raise InputError(
                "key instants must rise from 0 to 100 %",
                curves,
                f"task {task}, angle {angle}",
            )
        src = (info.get(task) or {}).get(angle) or {}
        if not src.get("source"):
            raise InputError(f"no source for the band {task}/{angle}", sources, f"curves.{task}")
        out[(str(task), str(angle))] = Band(
            task=str(task),
            angle=str(angle),
            percent=grid,
            mean=PchipInterpolator(pct, rows["mean_deg"].to_numpy(float))(grid),
            sd=PchipInterpolator(pct, rows["sd_deg"].to_numpy(float))(grid),
            source=" ".join(str(src["source"]).split()),
            note=str(src.get("note", "")),
        )
    return out


@lru_cache(maxsize=1)
def gait_bands() -> dict[str, Any]:
    """``report_data/gait_normative.yaml``: the spatio-temporal bands of healthy adults at a
    self-selected speed (``spatiotemporal``: ``{column: [low, high]}``) and their sources."""
    return _yaml(GAIT_SOURCES)


def band_for(task: str, joint_type: str, angle: str) -> Band | None:
    """The band of ``<joint_type>_<angle>`` in ``task``, if there is one."""
    return load_bands().get((task, f"{joint_type}_{angle}"))


def load_accuracy(path: Path = ACCURACY) -> dict[str, Any]:
    """The expected-accuracy table (see ``accuracy.yaml``); empty if the file is absent."""
    if not path.is_file():
        return {}
    return _yaml(path)
