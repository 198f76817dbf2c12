"""The wave segment: a lossless d'Alembert/Bergeron delay line between an upper node B and a lower
node C. It is the one implementation shared by the neutral-type model (Ch. 3) and the hybrid
FEM + transfer-matrix model (Ch. 5, straight section BC).

Contract (sign convention of docs/seed-errata.md)
----------------------------------
One field (axial *or* torsional) per segment. Velocity ``v`` is positive downward / forward
(axial m/s, or angular rad/s); the internal force ``N`` (axial force N, or torque N m) is positive
in tension / twisting the lower end forward. Along the line the state splits into a forward
(downward) wave ``a`` and a backward (upward) wave ``b``, both in velocity units::

    v = a + b,        N = Z (b - a),        Z = impedance

so a pure downward wave carries ``N = -Z v``. At the ends, with ``b_in`` the upward wave arriving
at B and ``a_in`` the downward wave arriving at C:

* force of the segment on B (downward positive): ``F_B = Z (2 b_in - v_B)``
* force of the segment on C (downward positive): ``F_C = Z (2 a_in - v_C)``
* wave leaving B: ``a_out = v_B - b_in``; wave leaving C: ``b_out = v_C - a_in``
* each outgoing wave arrives at the other end after ``delay = length / wave_speed``.

An implicit integrator therefore treats ``-Z v_end`` as a damper on the end node (coefficient
``Z``) and ``2 Z w_in`` as a known force, because ``w_in`` depends only on the past (the delay is
at least one step). Equivalently, for the force ``P = -F_B`` that node B applies to the line,
``P(t) = P(t - 2 tau) + Z v_B(t) + Z v_B(t - 2 tau) - 2 Z v_C(t - tau)`` (docs/seed-errata.md,
correction of seed Eq. 5.15, checked in ``tests/test_wave.py``).

The waves carry deviations from a static tension profile. A segment without distributed weight
has a uniform static tension; a hanging segment with weight ``w`` per unit length has
``N_s(z) = N_C + w (L - z)``: add :func:`static_end_forces` to the dynamic end forces ("gravity
preload").

Compiled state
--------------
:func:`wave_state` returns plain arrays ``(hist, pos, wp)``:

* ``hist`` (2, cap) float64: ring buffers of past outgoing waves sampled at the simulation step
  ``dt`` -- row 0 the downward waves leaving B (``a_out``), row 1 the upward waves leaving C
  (``b_out``); sample ``k`` is at time ``t0 + k dt``;
* ``pos`` (1,) int64: the number ``n`` of samples pushed; the *current* time is ``t_n``;
* ``wp`` a :class:`WaveParams` (``impedance`` Z, ``delay_steps`` delay/dt, ``cap``, ``a_init``,
  ``b_init``; a ``NamedTuple`` the kernels take by value); before ``t0`` the outgoing waves
  equal their initial values (a line in a steady state).

Per step: ``a_in, b_in = wave_incoming(hist, pos, wp)`` gives the incoming waves at ``t_n``
(linear interpolation for a non-integer ``delay/dt``, which must be >= 1), the integrator solves
the end nodes (with :func:`wave_source_forces` as known forces and ``Z`` as end dampers), then
``F_B, F_C = wave_step(hist, pos, wp, v_B, v_C, a_in, b_in)`` stores the outgoing waves of
``t_n`` (``v_B - b_in``, ``v_C - a_in``), advances to ``t_{n+1}`` and returns the end forces of
``t_n``. These compiled functions are the package's one wave-segment stepping: the neutral kernel
(:mod:`downhole.string.neutral`) and the FEM/hybrid kernel (:mod:`downhole.sim.kernel`)
both call them.

The read position ``t_n - delay`` is split once into an integer offset ``floor(-delay/dt)`` and
an interpolation weight, both exact, so the weight does not pick up round-off as ``n`` grows.
Kernels with a small cost per step keep that split, the clock ``n`` and ``cap`` in locals:
``off, frac = wave_read_plan(delay/dt)`` once, then per step ``wave_read_at(hist, n, off, frac,
cap, a_init, b_init)`` and ``wave_step_at(hist, n, cap, Z, v_B, v_C, a_in, b_in)`` (the caller
advances ``n`` and writes it back to ``pos``); :func:`wave_incoming` and :func:`wave_step` are
these with the state arrays, and give the same numbers.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from numba import njit

from downhole.errors import DownholeInputError

__all__ = [
    "WaveParams",
    "WaveSegment",
    "initial_waves",
    "line_preload",
    "segments_from_pipe",
    "static_end_forces",
    "wave_end_forces",
    "wave_incoming",
    "wave_outgoing",
    "wave_push",
    "wave_read",
    "wave_read_at",
    "wave_read_plan",
    "wave_source_forces",
    "wave_state",
    "wave_step",
    "wave_step_at",
]


class WaveParams(NamedTuple):
    """The constant part of a wave segment's compiled state (built by :func:`wave_state`).

    Attributes
    ----------
    impedance : float
        Characteristic impedance Z (N s/m, or N m s/rad).
    delay_steps : float
        One-way delay in simulation steps, delay / dt (>= 1).
    cap : int
        Length of the ring buffers.
    a_init, b_init : float
        Outgoing waves before the first sample (the line's initial steady state).
    """

    impedance: float
    delay_steps: float
    cap: int
    a_init: float
    b_init: float


def _positive(name: str, value) -> float:
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise DownholeInputError(f"{name} must be a number, got {value!r}") from None
    if not math.isfinite(x) or x <= 0.0:
        raise DownholeInputError(f"{name} must be a positive finite number, got {value!r}")
    return x


@dataclass(frozen=True)
class WaveSegment:
    """Immutable description of one lossless wave segment (one field: axial or torsional).

    Parameters
    ----------
    length : float
        Segment length L, m.
    wave_speed : float
        Wave speed c, m/s (sqrt(E/rho) axial, sqrt(G/rho) torsional).
    impedance : float
        Characteristic impedance Z: N s/m (axial, A sqrt(rho E)) or N m s/rad (torsional,
        J sqrt(rho G)).

    Raises
    ------
    DownholeInputError
        If any argument is not a positive finite number.

    Examples
    --------
    >>> seg = WaveSegment(1000.0, 5184.5, 3.45e5)
    >>> round(seg.delay, 5)
    0.19288
    """

    length: float
    wave_speed: float
    impedance: float

    def __post_init__(self):
        for name in ("length", "wave_speed", "impedance"):
            object.__setattr__(self, name, _positive(f"WaveSegment.{name}", getattr(self, name)))

    @property
    def delay(self) -> float:
        """One-way travel time tau = L / c, s."""
        return self.length / self.wave_speed

    def delay_steps(self, dt: float) -> float:
        """One-way delay in simulation steps, tau / dt.

        Parameters
        ----------
        dt : float
            Simulation step, s.

        Returns
        -------
        float
            ``delay / dt`` (dimensionless, >= 1).

        Raises
        ------
        DownholeInputError
            If ``dt`` is not a positive finite number, or if the delay is shorter than one step
            (the line must not be shorter than one step).
        """
        dt = _positive("dt", dt)
        d = self.delay / dt
        if d < 1.0:
            raise DownholeInputError(
                f"wave segment delay {self.delay:.6g} s is shorter than the step dt = {dt:.6g} s; "
                "use dt <= delay (or model this piece with lumped/FEM elements)")
        return d


def segments_from_pipe(pipe, length: float) -> tuple[WaveSegment, WaveSegment]:
    """Axial and torsional wave segments of a uniform pipe.

    Parameters
    ----------
    pipe : downhole.params.PipeSection
        Geometry and material.
    length : float
        Segment length, m.

    Returns
    -------
    (axial, torsional) : tuple of WaveSegment
        Axial: Z = A sqrt(rho E) (N s/m), c = sqrt(E/rho). Torsional: Z = J sqrt(rho G)
        (N m s/rad), c = sqrt(G/rho).
    """
    length = _positive("length", length)
    axial = WaveSegment(length, pipe.axial_wave_speed, pipe.axial_impedance)
    torsional = WaveSegment(length, pipe.torsional_wave_speed, pipe.torsional_impedance)
    return axial, torsional


def initial_waves(impedance: float, velocity: float = 0.0, tension: float = 0.0):
    """Waves ``(a, b)`` of a line in a uniform state: v = a + b, N = Z (b - a).

    Parameters
    ----------
    impedance : float
        Characteristic impedance Z, N s/m (axial) or N m s/rad (torsional).
    velocity : float, optional
        Uniform velocity v of the line, m/s or rad/s (default 0).
    tension : float, optional
        Uniform dynamic force N carried by the waves, N or N m, tension positive (default 0).

    Returns
    -------
    (a, b) : tuple of float
        Downward and upward waves, in velocity units (m/s or rad/s):
        ``((v - N/Z) / 2, (v + N/Z) / 2)``.

    Raises
    ------
    DownholeInputError
        If ``impedance`` is not a positive finite number.
    """
    z = _positive("impedance", impedance)
    return 0.5 * (velocity - tension / z), 0.5 * (velocity + tension / z)


def wave_state(segment: WaveSegment, dt: float, velocity: float = 0.0, tension: float = 0.0):
    """Fresh compiled state of ``segment`` at step ``dt``, the line in a uniform steady state.

    Parameters
    ----------
    segment : WaveSegment
        The segment.
    dt : float
        Simulation step, s (at most ``segment.delay``).
    velocity : float
        Initial uniform velocity of the line (m/s or rad/s).
    tension : float
        Initial uniform dynamic force N carried by the waves (N or N m), tension positive.

    Returns
    -------
    hist : ndarray (2, cap)
    pos : ndarray (1,) int64
    wp : WaveParams
        See the module docstring.

    Raises
    ------
    DownholeInputError
        If ``dt`` is not positive or exceeds the segment's delay.
    """
    d = segment.delay_steps(dt)
    cap = int(math.ceil(d)) + 3
    a0, b0 = initial_waves(segment.impedance, velocity, tension)
    hist = np.empty((2, cap))
    hist[0, :] = a0
    hist[1, :] = b0
    pos = np.zeros(1, dtype=np.int64)
    wp = WaveParams(impedance=float(segment.impedance), delay_steps=float(d), cap=cap,
                    a_init=float(a0), b_init=float(b0))
    return hist, pos, wp


@njit(cache=True)
def _sample(hist, row, k, cap, init):
    if k < 0:
        return init
    return hist[row, k % cap]


@njit(cache=True)
def wave_read_plan(lag_steps):
    """Loop-invariant part of a read ``lag_steps`` steps behind the current time.

    The integer offset ``floor(-lag_steps)`` and the interpolation weight
    ``-lag_steps - floor(-lag_steps)`` (both exact). A kernel computes them once per call and
    reads with :func:`wave_read_at`.

    Parameters
    ----------
    lag_steps : float
        Lag behind the current time, in simulation steps (delay / dt).

    Returns
    -------
    off : int
        Integer sample offset, ``floor(-lag_steps)`` (<= -1 for ``lag_steps`` >= 1).
    frac : float
        Interpolation weight in [0, 1) of sample ``n + off + 1``.
    """
    off = int(math.floor(-lag_steps))
    return off, -lag_steps - off


@njit(cache=True, inline="always")
def wave_read_at(hist, n, off, frac, cap, a_init, b_init):
    """Outgoing waves ``(a_out_B, b_out_C)`` at time ``t_{n + off + frac}``.

    ``off``, ``frac`` come from :func:`wave_read_plan`; linear interpolation between samples
    ``n + off`` and ``n + off + 1``; before the first sample the initial waves.

    Inlined into the calling kernel at Numba IR level: LLVM leaves this call in place, which
    costs ~5 % of a small hybrid step (24 states).

    Parameters
    ----------
    hist : ndarray, shape (2, cap), float64
        Ring buffers of past outgoing waves (row 0 ``a_out`` at B, row 1 ``b_out`` at C), m/s or
        rad/s.
    n : int
        Current sample index (number of samples pushed).
    off : int
        Integer offset from :func:`wave_read_plan`.
    frac : float
        Interpolation weight from :func:`wave_read_plan`.
    cap : int
        Length of the ring buffers.
    a_init, b_init : float
        Outgoing waves before the first sample, m/s or rad/s.

    Returns
    -------
    (a, b) : tuple of float
        Interpolated ``a_out`` leaving B and ``b_out`` leaving C, m/s or rad/s.
    """
    k0 = n + off
    a = (1.0 - frac) * _sample(hist, 0, k0, cap, a_init) + frac * _sample(hist, 0, k0 + 1, cap,
                                                                          a_init)
    b = (1.0 - frac) * _sample(hist, 1, k0, cap, b_init) + frac * _sample(hist, 1, k0 + 1, cap,
                                                                          b_init)
    return a, b


@njit(cache=True)
def wave_read(hist, pos, wp, lag_steps):
    """Outgoing waves ``(a_out_B, b_out_C)`` at time ``t_n - lag_steps * dt``.

    Linear interpolation; ``lag_steps`` >= 1 and <= cap - 2.

    Parameters
    ----------
    hist : ndarray, shape (2, cap), float64
        Ring buffers of past outgoing waves (see :func:`wave_state`).
    pos : ndarray, shape (1,), int64
        Number ``n`` of samples pushed (the current time is ``t_n``).
    wp : WaveParams
        Constant part of the state.
    lag_steps : float
        Lag behind the current time, in simulation steps.

    Returns
    -------
    (a, b) : tuple of float
        ``a_out`` leaving B and ``b_out`` leaving C at that time, m/s or rad/s.
    """
    off, frac = wave_read_plan(lag_steps)
    return wave_read_at(hist, pos[0], off, frac, wp.cap, wp.a_init, wp.b_init)


@njit(cache=True)
def wave_incoming(hist, pos, wp):
    """Incoming waves at the current time ``t_n``: ``(a_in at C, b_in at B)``.

    Parameters
    ----------
    hist : ndarray, shape (2, cap), float64
        Ring buffers of past outgoing waves (see :func:`wave_state`).
    pos : ndarray, shape (1,), int64
        Number ``n`` of samples pushed.
    wp : WaveParams
        Constant part of the state; the read lags ``wp.delay_steps`` steps.

    Returns
    -------
    (a_in, b_in) : tuple of float
        Downward wave arriving at C and upward wave arriving at B, m/s or rad/s.
    """
    return wave_read(hist, pos, wp, wp.delay_steps)


@njit(cache=True)
def wave_push(hist, pos, wp, a_out_b, b_out_c):
    """Store the outgoing waves of the current time ``t_n`` and advance to ``t_{n+1}``.

    Parameters
    ----------
    hist : ndarray, shape (2, cap), float64
        Ring buffers, written in place at slot ``n % cap``.
    pos : ndarray, shape (1,), int64
        Sample counter ``n``, incremented in place.
    wp : WaveParams
        Constant part of the state (``cap``).
    a_out_b : float
        Downward wave leaving B, m/s or rad/s.
    b_out_c : float
        Upward wave leaving C, m/s or rad/s.
    """
    cap = wp.cap
    k = pos[0] % cap
    hist[0, k] = a_out_b
    hist[1, k] = b_out_c
    pos[0] += 1


@njit(cache=True)
def wave_step_at(hist, n, cap, z, v_b, v_c, a_in, b_in):
    """:func:`wave_step` with the clock ``n``, ``cap`` and ``Z`` in the caller's locals.

    Store the outgoing waves of ``t_n`` in slot ``n % cap`` and return the end forces of ``t_n``
    (the caller advances ``n``).

    Parameters
    ----------
    hist : ndarray, shape (2, cap), float64
        Ring buffers, written in place.
    n : int
        Current sample index.
    cap : int
        Length of the ring buffers.
    z : float
        Characteristic impedance Z, N s/m or N m s/rad.
    v_b, v_c : float
        Velocities of the end nodes B and C at ``t_n``, m/s or rad/s (downward / forward positive).
    a_in, b_in : float
        Incoming waves at C and at B (from :func:`wave_read_at`), m/s or rad/s.

    Returns
    -------
    (F_B, F_C) : tuple of float
        Forces of the line on B and C, downward positive, N (or N m), as :func:`wave_end_forces`.
    """
    k = n % cap
    hist[0, k] = v_b - b_in
    hist[1, k] = v_c - a_in
    return wave_end_forces(z, v_b, v_c, a_in, b_in)


@njit(cache=True)
def wave_step(hist, pos, wp, v_b, v_c, a_in, b_in):
    """End of one step at ``t_n``: store the outgoing waves and advance to ``t_{n+1}``.

    Pushes the outgoing waves ``(v_B - b_in, v_C - a_in)``, advances to ``t_{n+1}`` and returns
    the forces of the line on its ends at ``t_n``, ``(F_B, F_C)`` as :func:`wave_end_forces`
    (``a_in, b_in`` from :func:`wave_incoming`).

    Parameters
    ----------
    hist : ndarray, shape (2, cap), float64
        Ring buffers, written in place.
    pos : ndarray, shape (1,), int64
        Sample counter ``n``, incremented in place.
    wp : WaveParams
        Constant part of the state (``impedance``, ``cap``).
    v_b, v_c : float
        Velocities of the end nodes B and C at ``t_n``, m/s or rad/s.
    a_in, b_in : float
        Incoming waves at C and at B, m/s or rad/s.

    Returns
    -------
    (F_B, F_C) : tuple of float
        Forces of the line on B and C, downward positive, N (or N m).
    """
    f = wave_step_at(hist, pos[0], wp.cap, wp.impedance, v_b, v_c, a_in, b_in)
    pos[0] += 1
    return f


@njit(cache=True)
def wave_source_forces(z, a_in, b_in):
    """The part of the end forces known before the step, ``(2 Z b_in, 2 Z a_in)``.

    An implicit integrator applies these as forces and ``Z`` as a damper on each end node, since
    ``F_B = 2 Z b_in - Z v_B`` and ``F_C = 2 Z a_in - Z v_C``.

    Parameters
    ----------
    z : float
        Characteristic impedance Z, N s/m or N m s/rad.
    a_in, b_in : float
        Incoming waves at C and at B, m/s or rad/s.

    Returns
    -------
    (S_B, S_C) : tuple of float
        Known forces on B and C, downward positive, N (or N m).
    """
    return 2.0 * z * b_in, 2.0 * z * a_in


@njit(cache=True)
def wave_outgoing(v_b, v_c, a_in, b_in):
    """Outgoing waves ``(a_out = v_B - b_in, b_out = v_C - a_in)``.

    Parameters
    ----------
    v_b, v_c : float
        Velocities of the end nodes B and C, m/s or rad/s.
    a_in, b_in : float
        Incoming waves at C and at B, m/s or rad/s.

    Returns
    -------
    (a_out, b_out) : tuple of float
        Downward wave leaving B and upward wave leaving C, m/s or rad/s.
    """
    return v_b - b_in, v_c - a_in


@njit(cache=True)
def wave_end_forces(z, v_b, v_c, a_in, b_in):
    """Forces of the line on its ends, downward positive.

    Parameters
    ----------
    z : float
        Characteristic impedance Z, N s/m or N m s/rad.
    v_b, v_c, a_in, b_in
        As :func:`wave_outgoing`.

    Returns
    -------
    (F_B, F_C) : tuple of float
        ``(Z (2 b_in - v_B), Z (2 a_in - v_C))``, N (or N m).
    """
    return z * (2.0 * b_in - v_b), z * (2.0 * a_in - v_c)


def static_end_forces(segment: WaveSegment, bottom_tension: float,
                      weight_per_length: float = 0.0) -> tuple[float, float]:
    """Static (preload) forces of a hanging segment on its end nodes, downward positive.

    With static tension ``N_s(z) = N_C + w (L - z)`` (``w`` = weight per unit length along the
    axis, e.g. rho A g cos(inclination)), the line pulls B down with ``N_s(0)`` and C up with
    ``N_C``. Add these to :func:`wave_end_forces`, whose waves carry the deviations.

    Parameters
    ----------
    segment : WaveSegment
        The segment (its ``length`` L, m, is used).
    bottom_tension : float
        Static tension N_C at the lower end C, N (tension positive).
    weight_per_length : float, optional
        Axial weight per unit length w, N/m (default 0: uniform tension).

    Returns
    -------
    (F_B, F_C) : tuple of float
        ``(N_C + w L, -N_C)``, N.
    """
    return line_preload(bottom_tension, float(weight_per_length) * segment.length)


def line_preload(bottom_tension: float, line_weight: float) -> tuple[float, float]:
    """Static forces ``(N_C + W, -N_C)`` of a hanging line on B and C, downward positive.

    :func:`static_end_forces` with ``W = w L``.

    Parameters
    ----------
    bottom_tension : float
        Static tension N_C at the lower end C, N (tension positive).
    line_weight : float
        Total axial weight W of the line, N.

    Returns
    -------
    (F_B, F_C) : tuple of float
        ``(N_C + W, -N_C)``, N.
    """
    n_c = float(bottom_tension)
    return n_c + float(line_weight), -n_c
