"""Estimator parameters: documented, valid defaults, unknown names refused, and packed for the
numba kernels from the dataclass fields (every slot filled, each with its own field)."""

from __future__ import annotations

import dataclasses
from types import ModuleType

import numpy as np
import pytest

from motionlab.errors import InputError
from motionlab.fusion import _kalman_common as kc
from motionlab.fusion import _mekf_kernels as mekf_k
from motionlab.fusion import _particle_kernels as particle_k
from motionlab.fusion import mekf, particle
from motionlab.fusion.registry import KernelParams, available, describe, get, make_params

ESTIMATORS = list(available())  # VQF's two only when the package is installed


def test_the_registry_holds_every_estimator():
    assert {"adaptive_cf", "ekf", "kf", "liu_gn", "madgwick", "mahony"} <= set(ESTIMATORS)
    assert {"mekf", "particle", "smoother", "ukf"} <= set(ESTIMATORS)


def test_the_default_estimator_loads_no_other_filter_nor_the_optional_peers():
    """``get("default")`` imports the estimator modules in order until the smoother is there
    (a fresh interpreter, through ``sys.modules``); asking for another name loads the rest."""
    import subprocess
    import sys

    from conftest import ROOT

    probe = (
        "import sys\n"
        "from motionlab.fusion import registry\n"
        "registry.get('default')\n"
        "print(' '.join(m for m in ('motionlab.fusion.ukf', 'motionlab.fusion.particle', "
        "'motionlab.fusion.complementary', 'vqf') if m in sys.modules))\n"
        "registry.get('madgwick')\n"
        "print('madgwick' in registry.available())\n"
    )
    out = subprocess.run([sys.executable, "-c", probe], cwd=ROOT, capture_output=True, text=True)
    assert out.stdout.splitlines() == ["", "True"], out.stderr


@pytest.mark.parametrize("name", ESTIMATORS)
def test_parameters_have_help_and_units(name):
    for f in dataclasses.fields(get(name).params_cls):
        assert f.metadata.get("help"), f"{name}.{f.name} has no help"
        assert "unit" in f.metadata, f"{name}.{f.name} has no unit"
        if isinstance(f.default, float):
            assert f.metadata["unit"], f"{name}.{f.name} is a number without a unit"
        assert "deg" not in f.metadata["unit"], f"{name}.{f.name}: angles are in rad"
        assert not isinstance(f.default, np.generic), f"{name}.{f.name}: default not a plain type"


@pytest.mark.parametrize("name", ESTIMATORS)
def test_defaults_are_valid_and_survive_the_command_line(name):
    est = get(name)
    defaults = make_params(est, {})
    assert defaults == est.params_cls()
    # every default given back as the text of --param key=value gives the same parameters
    as_text = {f.name: str(getattr(defaults, f.name)) for f in dataclasses.fields(defaults)}
    assert make_params(est, as_text) == defaults


@pytest.mark.parametrize("name", ESTIMATORS)
def test_unknown_parameter_is_refused_in_one_line(name):
    with pytest.raises(InputError) as err:
        make_params(get(name), {"no_such_parameter": "1"})
    message = str(err.value)
    assert "no_such_parameter" in message and name in message and "\n" not in message


@pytest.mark.parametrize("value", ["-5", "nan", "inf"])
def test_a_negative_or_non_finite_parameter_is_refused(value):
    """The hostile-input audit: ``--param beta=-5`` ran, ``beta=nan`` was blamed on the data."""
    with pytest.raises(InputError, match=rf"beta='{value}' of estimator 'madgwick' is not a "
                       r"finite number ≥ 0"):  # fmt: skip
        make_params(get("madgwick"), {"beta": value})


def test_listing_shows_every_parameter_with_its_unit():
    text = describe()
    for name in ESTIMATORS:
        for f in dataclasses.fields(get(name).params_cls):
            assert f"    {f.name} = " in text
    assert "np.float64" not in text
    assert "mag_dip_tol = 0.10471975511965978 rad (6°)" in text


# ---------------------------------------------------------------- packing for the kernels

LAYOUTS = [(mekf_k, mekf_k.PRM), (particle_k, particle_k.PRM), (kc, kc.PRM)]


@pytest.mark.parametrize(("module", "layout"), LAYOUTS)
def test_kernel_indices_are_named_after_their_slots(module: ModuleType, layout: KernelParams):
    for i, name in enumerate(layout.names):
        assert getattr(module, name.upper()) == i, name


def _distinct(cls: type) -> object:
    """Parameters whose float fields all differ from each other and from the defaults."""
    values = {
        f.name: 1000.0 + i
        for i, f in enumerate(dataclasses.fields(cls))
        if isinstance(f.default, float)
    }
    return cls(**values)


def _prepared() -> kc.Prepared:
    return kc.Prepared(np.array([1.0, 0, 0, 0]), np.zeros(3, bool), np.zeros((1, 3)),
                       np.ones(3, bool), False, 48.0, 1.1)  # fmt: skip


PACKERS = {
    "mekf": (mekf_k.PRM, mekf.MekfParams, mekf._pack),
    "smoother": (mekf_k.PRM, mekf.SmootherParams, mekf._pack),
    "particle": (particle_k.PRM, particle.ParticleParams, lambda p: particle._pack(p, 9.8, 48, 1)),
    "kalman": (kc.PRM, kc.KalmanCommon, lambda p: kc.pack(p, _prepared())),
}


@pytest.mark.parametrize("which", PACKERS)
@pytest.mark.parametrize("make", [lambda cls: cls(), _distinct], ids=["defaults", "distinct"])
def test_every_slot_is_packed_from_its_field(which, make):
    layout, cls, pack = PACKERS[which]
    params = make(cls)
    prm = pack(params)
    assert prm.shape == (len(layout),)
    assert not np.isnan(prm).any(), "a slot was left unfilled"
    back = layout.unpack(prm)
    fields = {f.name for f in dataclasses.fields(cls)}
    for name in set(layout.names) & fields:
        assert back[name] == getattr(params, name), name


def test_a_slot_without_a_value_is_an_error_not_uninitialised_memory():
    layout = KernelParams("gyr_noise", "gravity")
    params = mekf.MekfParams()
    with pytest.raises(ValueError, match="no value for .'gravity'"):
        layout.pack(params)
    with pytest.raises(ValueError, match="no such slot .'nope'"):
        layout.pack(params, gravity=9.81, nope=1.0)
    with pytest.raises(ValueError, match="given as field and derived .'gyr_noise'"):
        layout.pack(params, gravity=9.81, gyr_noise=1.0)
    with pytest.raises(ValueError, match="repeated"):
        KernelParams("a", "a")
    assert layout.unpack(layout.pack(params, gravity=9.81)) == {"gyr_noise": 0.01, "gravity": 9.81}
