"""The one signal registry: units agree with pint and the dimension names, every channel a
kernel records is declared, commands are range-checked."""

import math

import pint
import pytest

from downhole.signals import (
    METRICS,
    SIGNALS,
    STANDARD_CHANNELS,
    check_command_value,
    register_signal,
    signal,
    unit_of,
)
from downhole.units import SI_UNITS

UREG = pint.UnitRegistry()


def _dim(unit: str):
    return UREG.Quantity(1.0, unit or "dimensionless").dimensionality


@pytest.mark.parametrize("name", sorted(SIGNALS))
def test_every_signal_unit_matches_its_dimension_in_pint(name):
    sig = SIGNALS[name]
    assert sig.dimension in SI_UNITS, sig
    assert _dim(sig.unit) == _dim(SI_UNITS[sig.dimension]), sig
    assert sig.description


def test_metric_units_parse():
    for m in METRICS.values():
        assert m.unit == "-" or _dim(m.unit) is not None
    assert METRICS["mse"].unit == "Pa" and _dim("Pa") == _dim("N/m**2")


def test_every_kernel_channel_is_declared():
    from downhole.control.eid.neutral_runner import EID_CHANNELS
    from downhole.sim.kernel import CHANNELS as kernel
    from downhole.sim.lumped_model import CHAIN_CHANNELS as chain

    for name in set(chain) | set(kernel) | set(EID_CHANNELS) | set(STANDARD_CHANNELS):
        assert name in SIGNALS, name


def test_result_takes_units_from_the_registry():
    import numpy as np

    from downhole.sim import Result

    r = Result(np.arange(3.0), {"surface_torque": np.ones(3), "x_custom": np.ones(3)},
               units={"x_custom": "m"})
    assert r.dataset["surface_torque"].attrs["units"] == "N*m"
    assert r.dataset["x_custom"].attrs["units"] == "m"


def test_command_values_are_checked():
    assert check_command_value("top_drive_angular_velocity", 12.0) is None
    assert "finite" in check_command_value("top_drive_angular_velocity", math.nan)
    assert "finite" in check_command_value("hook_load", math.inf)
    msg = check_command_value("top_drive_angular_velocity", 1e300)
    assert "admissible range" in msg and "rad/s" in msg
    assert "admissible range" in check_command_value("hook_load", -1.0)
    assert "expected a number" in check_command_value("hook_load", "abc")


def test_registration_is_idempotent_and_conflicts_raise():
    sig = signal("wob")
    assert register_signal(sig.name, sig.unit, sig.dimension, sig.description) == sig
    with pytest.raises(ValueError, match="already declared"):
        register_signal("wob", "kN", "force", "weight on bit")
    with pytest.raises(KeyError, match="unknown signal"):
        signal("no_such_signal")
    assert unit_of("no_such_signal", default="?") == "?"
    with pytest.raises(ValueError, match="range"):
        register_signal("x_bad_range", "m", "length", "bad", low=1.0, high=0.0)
