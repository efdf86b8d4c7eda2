"""Sensor error model and its presets (``clean``, ``typical``, ``harsh``, ``loose``, ``skin``).

Per triaxial channel (units of the channel: gyr rad/s, acc m/s², mag µT)::

    y_k = Q( sat( (I + S + M) x_k + b_0 + w_k + n_k ) )

``S`` diagonal scale-factor errors, ``M`` off-diagonal axis misalignment (rad), ``b_0`` a
constant bias, ``w_k`` a bias random walk (rate random walk coefficient ``K``: increments
N(0, K²Δt), Allan deviation ``K √(τ/3)``), ``n_k`` white noise of density ``N`` (per-sample
σ = N √f_s, Allan deviation ``N / √τ``; IEEE Std 952-1997, Annex C), ``sat`` clipping at the
full-scale range and ``Q`` rounding to the least significant bit. The magnetometer first sees
soft iron (a symmetric matrix near I) and hard iron (an offset).

Timing: each sensor clock reads ``offset + (1 + drift) t`` at true time ``t``; a sample is taken
when the clock reads ``k / f_s + jitter`` and stamped ``k / f_s``; dropped packets (runs of
geometrically distributed length, mean ``drop_burst`` samples) are removed, leaving gaps.

``typical`` figures are those of consumer MEMS IMUs: Bosch BMI160 datasheet (BST-BMI160-DS000,
2020): gyro noise 0.007 °/s/√Hz, 16.4 LSB/(°/s) at ±2000 °/s, accelerometer noise 180 µg/√Hz,
2048 LSB/g at ±16 g, sensitivity tolerance ±1 %; TDK ICM-20948 / AK09916 magnetometer:
0.15 µT/LSB, ±4900 µT; Xsens MTw Awinda user manual: magnetometer noise 0.2 mG/√Hz
(0.02 µT/√Hz). The gyro bias (0.5 °/s) is a residual after factory trim, the clocks are ±20 ppm
crystals. ``harsh`` multiplies noise and biases, narrows the gyro range so fast movements
saturate, and adds packet loss, magnetic disturbances and soft-tissue wobble. ``loose`` is
``typical`` with a loosely strapped sensor: larger soft-tissue motion driven by the segment's
acceleration, and a slow slip of the mounting (:mod:`.signals`). ``skin`` is ``typical`` on skin
as it moves over the bone in real movement: tissue motion scaled per segment, the skin's shift
after heel strikes and with the joint angles (docs/simulator.md).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field, replace

import numpy as np

from motionlab.errors import InputError
from motionlab.units import STANDARD_GRAVITY

_DEG = math.pi / 180.0
_G = STANDARD_GRAVITY


@dataclass(frozen=True)
class ChannelModel:
    """Error parameters of one triaxial channel, in the channel's SI unit."""

    noise_density: float = 0.0  # unit/√Hz
    bias_sigma: float = 0.0  # unit, per axis
    bias_walk: float = 0.0  # unit/√s (rate random walk coefficient K)
    scale_sigma: float = 0.0  # fraction
    misalignment_sigma: float = 0.0  # rad
    full_scale: float = math.inf  # unit, saturation at ±full_scale
    lsb: float = 0.0  # unit, 0 = no quantisation


@dataclass(frozen=True)
class TimingModel:
    """Sampling errors of one sensor's clock and radio link."""

    jitter_s: float = 0.0
    drop_fraction: float = 0.0
    drop_burst: float = 1.0  # mean dropped samples per gap
    clock_offset_sigma_s: float = 0.0
    clock_drift_sigma: float = 0.0  # fraction (20e-6 = 20 ppm)


@dataclass(frozen=True)
class Preset:
    """Everything that makes a simulated recording imperfect."""

    name: str
    gyr: ChannelModel = field(default_factory=ChannelModel)
    acc: ChannelModel = field(default_factory=ChannelModel)
    mag: ChannelModel = field(default_factory=ChannelModel)
    timing: TimingModel = field(default_factory=TimingModel)
    hard_iron_sigma: float = 0.0  # µT
    soft_iron_sigma: float = 0.0  # fraction
    wobble_deg: float = 0.0  # soft-tissue wobble amplitude of the mounting
    soft_tissue: str = "impacts"  # impacts: ringing after heel strikes; motion: + acceleration
    tissue_gain: float = 1.0  # strength of the acceleration-driven motion (soft_tissue=motion)
    slip_deg: float = 0.0  # slow slip of the mounting over the recording (deg)
    sta_deg: float = 0.0  # skin artefact driven by the joint angles (soft_tissue=skin), thigh, deg
    sta_impact_deg: float = 0.0  # skin artefact after heel strikes (soft_tissue=skin), thigh, deg
    sta_shock_mm: float = 0.0  # the tissue ringing after its leg's heel strike (skin), thigh, mm
    dipole_moment: float = 0.0  # A·m², a ferromagnetic object in the room (0 = none)
    carried_field_ut: float = 0.0  # a field that moves with one sensor for a while (0 = none)
    marker_noise_m: float = 0.0
    occlusions_per_min: float = 0.0  # per marker
    occlusion_mean_s: float = 0.2


PRESETS = {
    "clean": Preset("clean"),
    "typical": Preset(
        "typical",
        gyr=ChannelModel(0.007 * _DEG, 0.5 * _DEG, 0.002 * _DEG, 0.005, 0.3 * _DEG,
                         2000 * _DEG, 2000 * _DEG / 32768),
        acc=ChannelModel(180e-6 * _G, 0.10, 2e-4, 0.005, 0.3 * _DEG, 16 * _G, 16 * _G / 32768),
        mag=ChannelModel(0.02, 0.0, 0.0, 0.01, 0.5 * _DEG, 4900.0, 0.15),
        timing=TimingModel(1e-4, 0.005, 3.0, 0.010, 20e-6),
        hard_iron_sigma=5.0,
        soft_iron_sigma=0.02,
        wobble_deg=0.5,
        marker_noise_m=0.001,
        occlusions_per_min=2.0,
    ),
    "harsh": Preset(
        "harsh",
        gyr=ChannelModel(0.03 * _DEG, 2.0 * _DEG, 0.01 * _DEG, 0.02, 1.0 * _DEG,
                         500 * _DEG, 500 * _DEG / 32768),
        acc=ChannelModel(500e-6 * _G, 0.3, 1e-3, 0.02, 1.0 * _DEG, 4 * _G, 4 * _G / 32768),
        mag=ChannelModel(0.1, 0.0, 0.0, 0.03, 1.5 * _DEG, 4900.0, 0.15),
        timing=TimingModel(1e-3, 0.03, 10.0, 0.050, 100e-6),
        hard_iron_sigma=20.0,
        soft_iron_sigma=0.08,
        wobble_deg=2.0,
        dipole_moment=15.0,
        carried_field_ut=15.0,
        marker_noise_m=0.002,
        occlusions_per_min=6.0,
        occlusion_mean_s=0.5,
    ),
}  # fmt: skip
# A strap that sits loosely: the sensors of ``typical``, three times the wobble after heel strikes,
# soft tissue that follows the segment's acceleration three times as strongly (≈3-8° in gait) and
# a mounting that slips by a few degrees over the recording.
PRESETS["loose"] = replace(
    PRESETS["typical"],
    name="loose",
    wobble_deg=1.5,
    soft_tissue="motion",
    tissue_gain=3.0,
    slip_deg=5.0,
)
# Sensors strapped on skin as people strap them: the sensors of ``typical``, the tissue ringing
# after heel strikes as a real walk's leg sensors ring (a 5° wobble and a 6-mm shock on the thigh
# and shank, little on the pelvis: ``STA_RING_SCALE``, docs/simulator.md), the
# acceleration-driven tissue motion of ``typical`` (scaled per
# segment, largest on the thigh), the skin's shift after heel strikes, and the
# soft-tissue artefact that follows the joint angles (``sta_deg`` on the thigh, less on the other
# segments; :func:`~motionlab.simulate.signals.skin_artefact`), largest on the thigh and of a few
# degrees as in the bone-pin studies (Leardini et al. 2005, Gait Posture 21:212; Cappozzo et al.
# 1996, Clin Biomech 11:90; Benoit et al. 2006), its level set so that Seel's hinge fit on a
# simulated walk with the anatomical knee leaves the residual real walks leave
# (bench/sim_realism.py, docs/simulator.md).
PRESETS["skin"] = replace(
    PRESETS["typical"],
    name="skin",
    wobble_deg=5.0,
    soft_tissue="skin",
    sta_deg=8.0,
    sta_impact_deg=3.0,
    sta_shock_mm=6.0,
)
SOFT_TISSUE = ("impacts", "motion", "skin")
# Preset fields added after the first release: left out of the stored error model at their
# defaults, so that the files of the older presets keep their bytes.
NEW_FIELDS = {
    "soft_tissue": "impacts",
    "tissue_gain": 1.0,
    "slip_deg": 0.0,
    "sta_deg": 0.0,
    "sta_impact_deg": 0.0,
    "sta_shock_mm": 0.0,
}


def error_model(preset: Preset) -> dict:
    """The preset as a plain dict for the truth's config (new fields only when not default)."""
    return {k: v for k, v in asdict(preset).items() if NEW_FIELDS.get(k, ...) != v}


def get_preset(preset: str | Preset) -> Preset:
    """A preset by name (``clean``, ``typical``, ``harsh``, ``loose``, ``skin``) or a
    :class:`Preset`."""
    if isinstance(preset, Preset):
        return preset
    if preset not in PRESETS:
        raise InputError(
            f"unknown preset {preset!r}",
            where="argument preset",
            argument="preset",
            remedy=f"use one of {', '.join(PRESETS)}",
        )
    return PRESETS[preset]


@dataclass
class ChannelDraw:
    """The constant errors drawn for one sensor channel."""

    bias0: np.ndarray  # (3,)
    matrix: np.ndarray  # (3, 3) = I + scale + misalignment


def draw_channel(model: ChannelModel, rng: np.random.Generator) -> ChannelDraw:
    """Draw the constant bias, scale factors and misalignment of one channel."""
    bias0 = rng.normal(0.0, 1.0, 3) * model.bias_sigma
    scale = rng.normal(0.0, 1.0, 3) * model.scale_sigma
    mis = rng.normal(0.0, 1.0, (3, 3)) * model.misalignment_sigma
    np.fill_diagonal(mis, 0.0)
    return ChannelDraw(bias0, np.eye(3) + np.diag(scale) + mis)


def apply_channel(
    ideal: np.ndarray,
    model: ChannelModel,
    draw: ChannelDraw,
    rate_hz: float,
    rng: np.random.Generator,
) -> tuple[np.ndarray, np.ndarray]:
    """Measured samples (N, 3) and the bias (N, 3) for ideal samples at ``rate_hz``."""
    n = len(ideal)
    dt = 1.0 / rate_hz
    walk = np.cumsum(rng.normal(0.0, 1.0, (n, 3)), axis=0) * (model.bias_walk * math.sqrt(dt))
    bias = draw.bias0 + walk
    noise = rng.normal(0.0, 1.0, (n, 3)) * (model.noise_density * math.sqrt(rate_hz))
    y = ideal @ draw.matrix.T + bias + noise
    y = np.clip(y, -model.full_scale, model.full_scale)
    if model.lsb > 0:
        y = np.round(y / model.lsb) * model.lsb
    return y, bias


def soft_hard_iron(preset: Preset, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Soft-iron matrix (symmetric, near I) and hard-iron offset (µT) of one magnetometer."""
    a = rng.normal(0.0, 1.0, (3, 3)) * preset.soft_iron_sigma
    return np.eye(3) + (a + a.T) / 2, rng.normal(0.0, 1.0, 3) * preset.hard_iron_sigma


@dataclass
class Clock:
    """A sensor clock: reads ``offset + (1 + drift) t`` at true time ``t`` (s)."""

    offset: float = 0.0
    drift: float = 0.0
    jitter_s: float = 0.0

    def true_time(self, clock_time: np.ndarray) -> np.ndarray:
        return (np.asarray(clock_time) - self.offset) / (1.0 + self.drift)


def draw_clock(timing: TimingModel, rng: np.random.Generator) -> Clock:
    return Clock(
        float(rng.normal() * timing.clock_offset_sigma_s),
        float(rng.normal() * timing.clock_drift_sigma),
        timing.jitter_s,
    )


def sample_times(
    clock: Clock, rate_hz: float, duration: float, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray]:
    """Stamps (sensor clock, s) and true sampling instants (s) of the samples in [0, duration]."""
    k0 = math.ceil(clock.offset * rate_hz - 1e-9)
    k1 = math.floor((clock.offset + (1.0 + clock.drift) * duration) * rate_hz + 1e-9)
    stamps = np.arange(k0, k1 + 1) / rate_hz
    jitter = rng.normal(0.0, 1.0, len(stamps)) * clock.jitter_s
    return stamps, clock.true_time(stamps + jitter)


def dropped(n: int, timing: TimingModel, rng: np.random.Generator) -> np.ndarray:
    """Boolean mask (n,) of dropped packets: alternating kept and lost runs, geometric lengths.

    The lost runs have mean ``drop_burst`` samples and the kept runs
    ``drop_burst (1 - f) / f``, so the long-run lost fraction is ``f = drop_fraction``.
    """
    f = timing.drop_fraction
    if f <= 0 or n == 0:
        return np.zeros(n, dtype=bool)
    bad_mean = max(timing.drop_burst, 1.0)
    good_mean = bad_mean * (1 - f) / f
    n_runs = int(2 * n / (good_mean + bad_mean)) + 20
    while True:
        good = rng.geometric(1.0 / max(good_mean, 1.0), n_runs)
        bad = rng.geometric(1.0 / bad_mean, n_runs)
        if good.sum() + bad.sum() >= n:
            break
        n_runs *= 2
    lengths = np.column_stack([good, bad]).ravel()
    flags = np.tile([False, True], n_runs)
    mask = np.repeat(flags, lengths)[:n]
    mask[0] = False  # a recording starts with its first packet
    return mask
