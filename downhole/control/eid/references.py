"""Closed-loop references for the EID controller. The plant-side signals are defined in the
mechanics core (:mod:`downhole.sim.references`, which the neutral-model runner samples) and
re-exported here; this module adds the start-ups that keep the loop out of the regenerative
region of the delayed depth of cut ("rotate first, then drill").

Why a start-up matters: with the delayed depth of cut the bit/rock interaction is regenerative,
and at low rotary speed (long delay 2 pi/(n omega) between blades) the linearized bit/rock mode is
unstable even in open loop (about +2 1/s at 5-12 rad/s with Table 3.1,
:func:`downhole.control.eid.stability.bit_rock_open_loop_roots`); the EID cannot stabilize it
there (see docs/neutral-eid.md, "Envelope"). A reference that asks for a rate of penetration while
the rotation is still slow parks the loop in that region, and the bit bounces. The start-ups below
hold the axial reference at zero (the bit rests on the bottom, not cutting) until the rotary-speed
reference has passed ``omega_on``, then ramp the rate of penetration in."""

from __future__ import annotations

import math

import numpy as np

from downhole.errors import DownholeInputError
from downhole.sim.inputs import sample_signal
from downhole.sim.references import (
    Reference,
    as_reference,
    constant_reference,
    eq_3_34,
    eq_3_35,
    seed_tracking_reference,
    user_reference,
)

__all__ = [
    "Reference",
    "as_reference",
    "constant_reference",
    "envelope_tracking_reference",
    "eq_3_34",
    "eq_3_35",
    "rotate_then_drill",
    "seed_tracking_reference",
    "startup_reference",
    "startup_time",
    "user_reference",
]


def _positive(name, value, allow_zero=False):
    v = float(value)
    if not math.isfinite(v) or v < 0 or (v == 0 and not allow_zero):
        raise DownholeInputError(f"{name} must be {'>= 0' if allow_zero else 'positive'} and "
                                 f"finite, got {value!r}")
    return v


def rotate_then_drill(reference, omega_on: float, ramp_time: float = 2.0,
                      horizon: float = 1.0e4, resolution: float = 1e-3) -> Reference:
    """Start-up of ``reference``: the axial reference is 0 until the angular reference first
    reaches ``omega_on`` (time ``t_on``), then it is multiplied by a linear ramp from 0 to 1 over
    ``ramp_time`` seconds; afterwards both signals are those of ``reference``.

    Parameters
    ----------
    reference : Reference or pair of signals
    omega_on : float
        Rotary speed (rad/s) from which the rate of penetration is ramped in; choose it inside
        the region where the linearized closed loop with the delayed depth of cut is stable
        (:func:`downhole.control.eid.stability.regenerative_closed_loop`).
    ramp_time : float
        Duration of the rate-of-penetration ramp, s (> 0).
    horizon, resolution : float
        ``t_on`` is searched on a grid of ``resolution`` s up to ``horizon`` s.

    Returns
    -------
    Reference
        Named ``"<name>-rotate-then-drill"``; :func:`startup_time` gives ``t_on``.

    Raises
    ------
    DownholeInputError
        Bad numbers, or the angular reference never reaches ``omega_on`` within ``horizon``.
    """
    ref = as_reference(reference)
    omega_on = _positive("omega_on", omega_on)
    ramp = _positive("ramp_time", ramp_time)
    horizon = _positive("horizon", horizon)
    resolution = _positive("resolution", resolution)
    t_on = startup_time(ref, omega_on, horizon, resolution)
    axial, angular = ref.axial, ref.angular

    def a(t):
        t = np.asarray(t, float)
        return sample_signal(axial, t, "reference axial") * np.clip((t - t_on) / ramp, 0.0, 1.0)

    return Reference(a, angular, f"{ref.name}-rotate-then-drill")


def startup_time(reference, omega_on: float, horizon: float = 1.0e4,
                 resolution: float = 1e-3) -> float:
    """First time (s, on a grid of ``resolution``) at which the angular reference of
    ``reference`` reaches ``omega_on``; :class:`DownholeInputError` if it never does before
    ``horizon``."""
    ref = as_reference(reference)
    n = int(math.ceil(horizon / resolution))
    chunk = 200000
    for k0 in range(0, n + 1, chunk):
        t = np.arange(k0, min(k0 + chunk, n + 1)) * resolution
        w = sample_signal(ref.angular, t, "reference angular")
        hit = np.nonzero(w >= omega_on)[0]
        if hit.size:
            return float(t[hit[0]])
    raise DownholeInputError(f"the angular reference never reaches omega_on = {omega_on} rad/s "
                             f"within {horizon} s; nothing to start the rate of penetration on")


def startup_reference(rop: float, omega: float, spin_up: float = 5.0,
                      ramp_time: float = 2.0, approach_omega: float | None = None,
                      descent_rate: float = 1.0, hold: float = 1.0) -> Reference:
    """Set point (``rop`` m/s, ``omega`` rad/s) reached from rest by rotating first: the angular
    reference ramps linearly from 0 to ``omega`` over ``spin_up`` s with the axial reference at 0,
    then the axial reference ramps from 0 to ``rop`` over ``ramp_time`` s.

    With ``approach_omega`` above ``omega`` the set point is approached *from above* (drill
    fast, then slow down): the rotation ramps to ``approach_omega`` over ``spin_up`` s, the rate
    of penetration is ramped in there (depth of cut 2 pi rop/approach_omega, smaller than at the
    set point), held ``hold`` s, then the rotary-speed reference is lowered to ``omega`` in
    (approach_omega - omega)/descent_rate s with the rate of penetration held, linearly in
    1/omega, so that the depth of cut grows linearly. The torque on bit then grows
    slowly to its (large) low-speed value instead of arriving as a step that the torsional loop
    cannot hold (see docs/neutral-eid.md, "Envelope")."""
    rop = _positive("rop", rop, allow_zero=True)
    omega = _positive("omega", omega)
    spin = _positive("spin_up", spin_up)
    ramp = _positive("ramp_time", ramp_time)
    top = omega
    if approach_omega is not None:
        top = max(omega, _positive("approach_omega", approach_omega))
    rate = _positive("descent_rate", descent_rate)
    t_down = spin + ramp + _positive("hold", hold, allow_zero=True)
    t_end = t_down + (top - omega) / rate

    def w(t):
        t = np.asarray(t, float)
        if top == omega:
            return omega * np.clip(t / spin, 0.0, 1.0)
        f = np.clip((t - t_down) / (t_end - t_down), 0.0, 1.0)
        # linear in 1/omega: the depth of cut 2 pi rop/omega (and the bit forces) grow linearly
        down = 1.0 / (1.0 / top + (1.0 / omega - 1.0 / top) * f)
        return np.where(t < t_down, top * np.clip(t / spin, 0.0, 1.0), down)

    def a(t):
        return rop * np.clip((np.asarray(t, float) - spin) / ramp, 0.0, 1.0)

    return Reference(a, w, "startup" if top == omega else "startup-from-above")


def envelope_tracking_reference(omega_on: float = 18.0, ramp_time: float = 2.0,
                                v: float = 0.005, omega: float = 20.0) -> Reference:
    """Eqs. 3.34/3.35 (seed Fig. 3.6) with the rotate-then-drill start-up: the rate of
    penetration is ramped in from the time the multi-ramp reaches ``omega_on`` (27 s for the
    default 18 rad/s, reached at 20 rad/s per 30 s) over ``ramp_time`` s, so that the loop never
    cuts at the low rotary speeds where the delayed depth of cut is regenerative."""
    return rotate_then_drill(seed_tracking_reference(v, omega, max_depth_of_cut=None),
                             omega_on, ramp_time, horizon=1.0e3)
