"""The estimator registry, the common result type and input validation.

An estimator module defines a parameter dataclass (every tunable with a default; units and a
one-line help in ``field(metadata={"unit": ..., "help": ...})``, written ``param(default, unit,
help)``) and a function ``run(gyr, acc, mag, rate, params) -> FusionResult``, and registers it::

    @register("madgwick", MadgwickParams, "Madgwick gradient-descent filter (IMU and MARG)")
    def run(gyr, acc, mag, rate, params): ...

Inputs reaching ``run`` are validated: float64, C-contiguous, N×3, finite (NaN samples are
replaced by the previous valid sample and reported in ``FusionResult.extra['nan_filled']``),
``mag`` may be None.
"""

from __future__ import annotations

import dataclasses
import importlib
import inspect
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from motionlab.errors import InputError
from motionlab.fusion.timegrid import (
    CUBIC_MAX_S,
    checked_time,
    gap_grid,
    gap_noise,
    with_patterns,
)

DEFAULT_ESTIMATOR = "smoother"

#: modules that register estimators when imported; the default's first (:func:`get` imports
#: them in this order until the estimator asked for is registered)
ESTIMATOR_MODULES = (
    "mekf",
    "complementary",
    "kalman",
    "ekf",
    "ukf",
    "particle",
    "vqf_backend",
)


def param(default: Any, unit: str, help: str) -> Any:
    """A parameter dataclass field: its default, unit and one-line help (see :func:`describe`).

    Units are SI (angles in rad); a numpy scalar default (``np.deg2rad(6.0)``) is stored as the
    Python float of the same value.
    """
    if isinstance(default, np.floating):
        default = float(default)
    return field(default=default, metadata={"unit": unit, "help": help})


class KernelParams:
    """The float parameter vector of a numba kernel: named slots in a fixed order.

    A slot named after a field of the estimator's parameter dataclass takes that field; the
    others are values the caller derives (``pack(params, gravity=g)``). Every slot must get a
    value, so nothing reaches a kernel uninitialised. The kernel module names the indices after
    the slots, upper case (``GYR_NOISE = 0`` for ``"gyr_noise"``; checked by the tests).
    """

    def __init__(self, *names: str) -> None:
        if len(set(names)) != len(names):
            raise ValueError(f"repeated kernel parameter in {names}")
        self.names = names
        self.index = {name: i for i, name in enumerate(names)}

    def __len__(self) -> int:
        return len(self.names)

    def pack(self, params: Any, **derived: float) -> np.ndarray:
        """The vector of ``params``' fields and the ``derived`` values, by slot name."""
        fields = {f.name for f in dataclasses.fields(params)} & set(self.names)
        both = sorted(fields & set(derived))
        unknown = sorted(set(derived) - set(self.names))
        missing = [n for n in self.names if n not in fields and n not in derived]
        if both or unknown or missing:
            raise ValueError(
                f"kernel parameters: given as field and derived {both}, no such slot {unknown}, "
                f"no value for {missing}"
            )
        values = {name: getattr(params, name) for name in fields} | derived
        prm = np.full(len(self.names), np.nan)
        for name, value in values.items():
            prm[self.index[name]] = value
        return prm

    def unpack(self, prm: np.ndarray) -> dict[str, float]:
        """Slot name → value of a packed vector (the inverse of :meth:`pack`)."""
        return {name: float(prm[i]) for i, name in enumerate(self.names)}


@dataclass
class FusionResult:
    """Output of every estimator.

    Attributes
    ----------
    quat
        (N, 4) orientation, scalar first, sensor → ENU earth, unit norm, sign-continuous.
    name
        Registered estimator name.
    params
        The parameters used (dataclass as dict).
    gyro_bias
        (N, 3) estimated gyroscope bias in rad/s, where the estimator estimates it.
    rest
        (N,) bool, samples detected as rest.
    mag_disturbed
        (N,) bool, samples where the magnetometer was judged disturbed and gated/down-weighted.
    extra
        Anything else worth keeping (covariances, effective sample size, ...).
    """

    quat: np.ndarray
    name: str
    params: dict[str, Any]
    gyro_bias: np.ndarray | None = None
    rest: np.ndarray | None = None
    mag_disturbed: np.ndarray | None = None
    extra: dict[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class Estimator:
    name: str
    params_cls: type
    description: str
    run: Callable[..., FusionResult]
    needs_mag: bool = False


_REGISTRY: dict[str, Estimator] = {}
_loaded = False


def register(name: str, params_cls: type, description: str, needs_mag: bool = False):
    """Decorator registering ``run(gyr, acc, mag, rate, params)`` under ``name``."""

    def wrap(fn: Callable[..., FusionResult]) -> Callable[..., FusionResult]:
        _REGISTRY[name] = Estimator(name, params_cls, description, fn, needs_mag)
        return fn

    return wrap


def _load(until: str | None = None) -> None:
    """Import the estimator modules: all of them, or in order until ``until`` is registered (a
    run of the default smoother then loads neither the other filters nor the optional peers)."""
    global _loaded
    if _loaded or until in _REGISTRY:
        return
    for mod in ESTIMATOR_MODULES:
        try:
            importlib.import_module(f"motionlab.fusion.{mod}")
        except ModuleNotFoundError as exc:
            # a module not written yet, or an optional backend whose package is absent
            if exc.name not in (f"motionlab.fusion.{mod}", "vqf"):
                raise
        if until in _REGISTRY:
            return
    _loaded = True


def available() -> dict[str, Estimator]:
    """All registered estimators by name (importing the estimator modules on first call)."""
    _load()
    return dict(sorted(_REGISTRY.items()))


def get(name: str) -> Estimator:
    """The estimator registered as ``name`` (``"default"`` is the offline smoother)."""
    key = DEFAULT_ESTIMATOR if name == "default" else name
    _load(until=key)
    if key not in _REGISTRY:
        names = ", ".join(available())
        raise InputError(f"unknown estimator '{name}'", remedy=f"choose one of {names}")
    return _REGISTRY[key]


def make_params(est: Estimator, overrides: dict[str, Any]) -> Any:
    """The estimator's parameter dataclass with ``overrides`` applied and type-converted."""
    fields = {f.name: f for f in dataclasses.fields(est.params_cls)}
    unknown = sorted(set(overrides) - set(fields))
    if unknown:
        raise InputError(
            f"estimator '{est.name}' has no parameter {', '.join(unknown)}",
            remedy=f"its parameters are {', '.join(fields) or 'none'}",
        )
    converted = {}
    defaults = est.params_cls()
    for key, value in overrides.items():
        current = getattr(defaults, key)
        try:
            converted[key] = type(current)(value) if not isinstance(current, bool) else _bool(value)
        except (TypeError, ValueError):
            raise InputError(
                f"parameter {key}={value!r} is not a {type(current).__name__}",
                remedy=f"the default is {current!r}",
            ) from None
        number = converted[key]
        if isinstance(number, int | float) and not isinstance(number, bool):
            # every parameter is a noise, gain, time, threshold or count: none is negative;
            # infinite only where the default is (a time constant that never decays)
            finite = np.isfinite(number) or (np.isinf(current) and number > 0)
            if not (finite and number >= 0):
                raise InputError(
                    f"parameter {key}={value!r} of estimator '{est.name}' is not a finite "
                    "number ≥ 0",
                    remedy=f"the default is {current!r}",
                )
    return dataclasses.replace(defaults, **converted)


def _bool(value: Any) -> bool:
    if isinstance(value, str):
        if value.lower() in ("1", "true", "yes", "on"):
            return True
        if value.lower() in ("0", "false", "no", "off"):
            return False
        raise ValueError(value)
    return bool(value)


def _vectors(name: str, arr: np.ndarray | None, n: int | None) -> np.ndarray | None:
    if arr is None:
        return None
    arr = np.ascontiguousarray(arr, dtype=float)
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise InputError(f"{name} has shape {arr.shape}, expected (N, 3)")
    if n is not None and len(arr) != n:
        raise InputError(f"{name} has {len(arr)} samples, gyr has {n}", remedy="resample first")
    return arr


def _fill_nan(arr: np.ndarray, name: str) -> tuple[np.ndarray, int]:
    finite = np.isfinite(arr)
    if finite.all():  # the common case, 30 × faster than the row-wise test below
        return arr, 0
    bad = ~finite.all(axis=1)
    if bad.all():
        raise InputError(f"{name} has no finite sample", remedy="check the recording")
    return hold_last_finite(arr), int(bad.sum())


def hold_last_finite(arr: np.ndarray) -> np.ndarray:
    """(N, k) rows with a non-finite value replaced by the last finite row before them (the
    first finite row for those at the start); unchanged when every row is finite or none is."""
    bad = ~np.isfinite(arr).all(axis=1)
    if not bad.any() or bad.all():
        return arr
    idx = np.where(~bad, np.arange(len(arr)), 0)
    np.maximum.accumulate(idx, out=idx)
    idx[: np.argmax(~bad)] = np.argmax(~bad)
    return np.ascontiguousarray(arr[idx])


def takes_references(name: str) -> bool:
    """Whether estimator ``name`` can fuse marker reference vectors (``references=``)."""
    return "references" in inspect.signature(get(name).run).parameters


def takes_gaps(name: str) -> bool:
    """Whether estimator ``name`` widens its attitude where packet-loss gaps were bridged
    (``gaps=``, :func:`motionlab.fusion.timegrid.gap_noise`)."""
    return "gaps" in inspect.signature(get(name).run).parameters


def _bridged(t: np.ndarray, spans: Any, grid: Any) -> tuple[np.ndarray, np.ndarray]:
    """``(recorded, linear)`` (M,) bool on the estimator's samples: the samples recorded, and
    the filled ones bridged linearly (ingest's filled ``spans``, ``[start_s, end_s]`` each, and
    the grid's gaps over ``CUBIC_MAX_S``); see :func:`.timegrid.gap_noise`."""
    recorded = np.ones(len(t), bool)
    ends = np.asarray(spans if spans is not None else [], float).reshape(-1, 2)
    # t strictly increasing (checked_time): the samples inside each span by bisection, so the
    # cost grows with the samples plus the spans, not their product
    first = np.searchsorted(t, ends[:, 0], side="right")  # t > start
    stop = np.where(np.isnan(ends[:, 1]), 0, np.searchsorted(t, ends[:, 1], side="left"))  # t < end
    for a, b in zip(first, stop, strict=True):
        recorded[a:b] = False
    if grid is None:
        return recorded, ~recorded
    on_grid = np.zeros(len(grid.time), bool)
    on_grid[grid.index] = recorded
    linear = np.zeros(len(grid.time), bool)
    linear[grid.index] = ~recorded
    spans = grid.stamps[grid.before + 1] - grid.stamps[grid.before]
    filled = np.ones(len(grid.time), bool)  # the filled instants, in grid order
    filled[grid.index] = False
    linear[filled] = spans > CUBIC_MAX_S
    return on_grid, linear


def estimate(
    name: str,
    gyr: np.ndarray,
    acc: np.ndarray,
    mag: np.ndarray | None = None,
    rate: float = 100.0,
    references: Any = None,
    time: np.ndarray | None = None,
    filled_spans: Any = None,
    **params: Any,
) -> FusionResult:
    """Run estimator ``name`` on gyroscope (rad/s), accelerometer (m/s²), magnetometer (µT).

    Parameters
    ----------
    name
        A registered estimator (see :func:`available`), or ``"default"``.
    gyr, acc, mag
        (N, 3) arrays in the sensor frame; ``mag=None`` gives a 6-D estimate.
    rate
        Sampling rate in Hz.
    references
        Optional :class:`~motionlab.fusion.markers.MarkerReferences` on the same samples (IMU +
        marker fusion); only for estimators whose ``run`` takes ``references``.
    time
        Optional (N,) sample times (s). Where packets were lost (intervals over 1.5/``rate``)
        the estimator runs on a grid with the gaps filled and the result is taken back to these
        times, with the filled spans in ``extra["resampled"]`` (:mod:`motionlab.fusion.timegrid`).
        Without ``time`` every interval is taken as ``1/rate``. An estimator that takes
        ``gaps`` (the default smoother; ``liu_gn``, whose marker steps use it) also gets how
        uncertain each gap's bridge is (:func:`~motionlab.fusion.timegrid.gap_noise`).
    filled_spans
        Optional ``[start_s, end_s]`` pairs of gaps already filled (linearly) in ``time``, as
        ingest lists them in ``SensorStream.qc["filled_spans_s"]``: treated as gaps too.
    **params
        Overrides of the estimator's parameter dataclass.
    """
    est = get(name)
    if not np.isfinite(rate) or rate <= 0:
        raise InputError(f"sampling rate {rate} Hz is not positive")
    gyr = _vectors("gyr", gyr, None)
    n = len(gyr)
    if n < 2:
        raise InputError(f"{n} samples are too few to estimate an orientation")
    acc = _vectors("acc", acc, n)
    mag = _vectors("mag", mag, n)
    if est.needs_mag and mag is None:
        raise InputError(f"estimator '{est.name}' needs a magnetometer")
    filled = {}
    gyr, filled["gyr"] = _fill_nan(gyr, "gyr")
    acc, filled["acc"] = _fill_nan(acc, "acc")
    if mag is not None:
        mag, filled["mag"] = _fill_nan(mag, "mag")
    p = make_params(est, params)
    t = None if time is None else checked_time(time, n)
    grid = None if t is None else gap_grid(t, rate)
    kwargs = {}
    noise = None
    if t is not None:  # each gap bridged as its neighbourhood says is better, and its noise
        recorded, linear = _bridged(t, filled_spans, grid)
        grid_time = t if grid is None else grid.time
        on_grid = gyr if grid is None else grid.vectors(gyr)
        noise = gap_noise(grid_time, on_grid, recorded, float(rate), linear, choose=True)
        if takes_gaps(est.name):
            kwargs["gaps"] = noise
    if grid is not None:
        gyr, acc, mag = (grid.vectors(x, noise.linear) for x in (gyr, acc, mag))
    gyr, acc, mag = (with_patterns(x, noise) for x in (gyr, acc, mag))
    if references is not None:
        takes = [k for k in available() if takes_references(k)]
        if est.name not in takes:
            raise InputError(
                f"estimator '{est.name}' cannot fuse marker references",
                remedy=f"use one of {', '.join(takes)}",
            )
        references = references.validated(n)
        kwargs["references"] = references if grid is None else grid.references(references)
    result = est.run(gyr, acc, mag, float(rate), p, **kwargs)
    if grid is not None:
        result = grid.back(result)
    if noise is not None:  # the turn each bridge may have missed, after its gap (s, deg)
        total = np.degrees(noise.sigma) * np.sqrt(3.0)
        after = grid_time[noise.after]
        result.extra["gaps_missed_deg"] = np.column_stack([after, total]).tolist()  # not per sample
    result.name = est.name
    result.params = dataclasses.asdict(p)
    if any(filled.values()):
        result.extra["nan_filled"] = filled
    return result


def _shown(value: Any, unit: str) -> str:
    """A default with its unit; an angle (rad, rad/s) also in degrees for people."""
    text = f"{value!r} {unit}".rstrip()
    angle = unit in ("rad", "rad/s") and isinstance(value, float) and np.isfinite(value)
    if angle and value != 0.0:
        text += f" ({np.degrees(value):.4g}°{unit[3:]})"
    return text


def describe() -> str:
    """Text listing of every estimator with its parameters, defaults and units."""
    lines = []
    for name, est in available().items():
        tag = " (default)" if name == DEFAULT_ESTIMATOR else ""
        lines.append(f"{name}{tag}: {est.description}")
        for f in dataclasses.fields(est.params_cls):
            unit = f.metadata.get("unit", "")
            help_ = f.metadata.get("help", "")
            default = f.default if f.default is not dataclasses.MISSING else f.default_factory()
            lines.append(f"    {f.name} = {_shown(default, unit)}  {help_}".rstrip())
    return "\n".join(lines)
