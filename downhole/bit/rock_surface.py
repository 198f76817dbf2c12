"""Depth of cut from the bit's own history: the state-dependent delay of seed Eqs. 2.9-2.10.

The rock surface is stored on a uniform grid of *unwrapped bit angle* (``nb`` points per blade
pitch 2 pi/n). A blade at angle theta cuts against the surface left at theta - 2 pi/n, which is
exactly x_bit(t - t_n) with theta(t) - theta(t - t_n) = 2 pi/n (Eq. 2.10), solved by
interpolation instead of a root search. With ``memory`` on (default, correction,
docs/seed-errata.md) the surface is the hole bottom: the maximum of the cut depths (x positive
downward), so after a bounce the blade measures against rock, not against its own airborne path. If
the bit turns backward and then forward again over angles it has already cut, the blade meets its
own surface.

State lives in two arrays so that compiled kernels can own it: ``surf`` (ring buffer, m) and
``istate = [j_next]`` (index of the next grid angle not yet reached). This is the one depth-of-cut
memory of the package: :func:`rock_depth_at` and :func:`rock_advance_to` take the grid layout
unpacked (kernels unpack ``rp``, a :class:`RockSurfaceParams`, once before their time loop and
keep ``j_next`` in a local); :func:`rock_depth` and :func:`rock_advance` are the same functions
on ``(surf, istate, rp)``.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

__all__ = [
    "RockSurfaceParams",
    "RockSurfaceSpec",
    "rock_advance",
    "rock_advance_to",
    "rock_depth",
    "rock_depth_at",
    "rock_init",
    "rock_init_helix",
]


class RockSurfaceParams(NamedTuple):
    """The constant grid layout of one rock-surface memory as the kernels take it (``rp``).

    Attributes
    ----------
    theta_ref : float
        Bit angle of grid index 0, rad.
    h : float
        Grid step in angle, rad.
    nb : int
        Grid points per blade pitch.
    cap : int
        Ring capacity (a power of two).
    n_blades : float
        Number of blades (multiplies the per-blade depth of cut).
    memory : bool
        Hole-bottom memory (True) or the printed Eq. 2.9.
    """

    theta_ref: float
    h: float
    nb: int
    cap: int
    n_blades: float
    memory: bool


class RockSurfaceSpec:
    """Grid layout of the rock-surface memory.

    Parameters
    ----------
    n_blades : int
        Number of blades n (pitch 2 pi/n).
    points_per_pitch : int
        Grid points per blade pitch (default 512).
    memory : bool
        True: hole-bottom memory (max of history). False: the printed Eq. 2.9 (x at t - t_n).

    Raises
    ------
    ValueError
        If ``n_blades`` < 1 or ``points_per_pitch`` < 4.
    """

    def __init__(self, n_blades: int, points_per_pitch: int = 512, memory: bool = True):
        if n_blades < 1:
            raise ValueError(f"n_blades must be >= 1, got {n_blades}")
        if points_per_pitch < 4:
            raise ValueError(f"points_per_pitch must be >= 4, got {points_per_pitch}")
        self.n_blades = int(n_blades)
        self.nb = int(points_per_pitch)
        # ring capacity: a power of two >= 4 pitches, so indices wrap with a bit mask
        self.cap = 1 << int(math.ceil(math.log2(4 * self.nb)))
        self.h = 2.0 * math.pi / n_blades / self.nb
        self.memory = bool(memory)

    def params(self, theta_ref: float) -> RockSurfaceParams:
        """The grid layout for the kernels (:class:`RockSurfaceParams`).

        Parameters
        ----------
        theta_ref : float
            Bit angle of grid index 0, rad.

        Returns
        -------
        RockSurfaceParams
        """
        return RockSurfaceParams(theta_ref=float(theta_ref), h=float(self.h), nb=int(self.nb),
                                 cap=int(self.cap), n_blades=float(self.n_blades),
                                 memory=bool(self.memory))


def rock_init(spec: RockSurfaceSpec, x0: float, theta0: float):
    """Fresh state: the bit rests on a flat bottom at ``x0`` with angle ``theta0``.

    Parameters
    ----------
    spec : RockSurfaceSpec
        Grid layout.
    x0 : float
        Bit axial position (and hole bottom), m.
    theta0 : float
        Bit angle, rad (grid index 0 sits there).

    Returns
    -------
    surf : ndarray, shape (cap,)
        Flat surface at ``x0``, m.
    istate : ndarray, shape (1,), int64
        ``[0]``.
    rp : RockSurfaceParams
    """
    surf = np.full(spec.cap, float(x0))
    istate = np.zeros(1, dtype=np.int64)  # j_next = 0: grid point 0 sits at theta0
    return surf, istate, spec.params(theta0)


@njit(cache=True, inline="always")
def rock_depth_at(surf, j_next, theta_ref, h, nb, cap, nbl, x, theta):
    """Total depth of cut d = n (x - surface) for the bit at axial position x, angle theta.

    At the cutting front the blade meets the previous blade's surface one pitch back
    (Eq. 2.10); over angles it already cut (after backward rotation) it meets its own surface.

    Parameters
    ----------
    surf : ndarray, shape (cap,), float64
        Ring buffer of the rock surface, m.
    j_next : int
        Index of the next grid angle not yet reached.
    theta_ref : float
        Bit angle of grid index 0, rad.
    h : float
        Grid step in angle, rad.
    nb : int
        Grid points per blade pitch.
    cap : int
        Ring capacity (a power of two).
    nbl : float
        Number of blades n.
    x : float
        Bit axial position, m (positive downward).
    theta : float
        Bit angle, rad.

    Returns
    -------
    float
        Total depth of cut (all blades), m; negative when the bit is off bottom.
    """
    mask = cap - 1
    jf = (theta - theta_ref) / h
    if jf >= j_next - 1:
        q = jf - nb
        q = min(q, j_next - 1.0)
        q = max(q, j_next - cap + 1.0)
        if q == j_next - 1.0:
            q = q - 1e-12
    else:
        q = jf
        q = max(q, j_next - cap + 1.0)
    j0 = int(math.floor(q))
    f = q - j0
    s0 = surf[j0 & mask]
    s = s0 + f * (surf[(j0 + 1) & mask] - s0)
    return nbl * (x - s)


@njit(cache=True)
def rock_advance_to(surf, j_next, theta_ref, h, nb, cap, memory, theta_prev, x_prev, theta_new,
                    x_new):
    """Record the blade's path from (theta_prev, x_prev) to (theta_new, x_new).

    Nothing is cut while the bit turns backward or stands still, or when the state is
    not finite (a diverging run). With ``memory`` the surface keeps the maximum (hole bottom).

    Parameters
    ----------
    surf : ndarray, shape (cap,), float64
        Ring buffer of the rock surface, m; updated in place.
    j_next, theta_ref, h, nb, cap
        As :func:`rock_depth_at`.
    memory : bool
        Hole-bottom memory (True) or the printed Eq. 2.9.
    theta_prev : float
        Bit angle at the start of the step, rad.
    x_prev : float
        Bit axial position at the start of the step, m (positive downward).
    theta_new : float
        Bit angle at the end of the step, rad.
    x_new : float
        Bit axial position at the end of the step, m.

    Returns
    -------
    int
        The new ``j_next``.
    """
    if not (theta_new > theta_prev) or not math.isfinite(theta_new + x_new):
        return j_next
    a0 = (theta_prev - theta_ref) / h
    a1 = (theta_new - theta_ref) / h
    if abs(a1) > 1e15 or abs(a0) > 1e15:
        return j_next  # runaway angle (diverging run): grid indices would overflow
    mask = cap - 1
    j_lo = int(math.floor(a0)) + 1
    j_hi = int(math.floor(a1))
    j_lo = max(j_lo, j_next - cap + nb + 1)
    if j_hi - j_lo >= cap - nb:
        # more than the ring in one step (a runaway): only the last points can be kept
        j_lo = j_hi - cap + nb + 1
    slope = (x_new - x_prev) / (theta_new - theta_prev)
    for j in range(j_lo, j_hi + 1):
        xj = x_prev + slope * (theta_ref + j * h - theta_prev)
        if j >= j_next:
            if memory:
                below = surf[(j - nb) & mask]
                surf[j & mask] = max(below, xj)
            else:
                surf[j & mask] = xj
        elif memory:
            surf[j & mask] = max(surf[j & mask], xj)
    if j_hi + 1 > j_next:
        return j_hi + 1
    return j_next


@njit(cache=True, inline="always")
def rock_depth(surf, istate, rp, x, theta):
    """:func:`rock_depth_at` on the packed layout ``rp`` and state ``istate = [j_next]``.

    Parameters
    ----------
    surf : ndarray, shape (cap,), float64
        Ring buffer of the rock surface (axial position of the hole bottom per grid angle),
        m, x positive downward; updated in place by the advance functions.
    istate : ndarray, shape (1,), int64
        ``[j_next]``, the index of the next grid angle not yet reached.
    rp : RockSurfaceParams
        Grid layout (:meth:`RockSurfaceSpec.params`).
    x : float
        Bit axial position, m (positive downward).
    theta : float
        Bit angle, rad.

    Returns
    -------
    float
        Total depth of cut (all blades), m.
    """
    return rock_depth_at(surf, istate[0], rp.theta_ref, rp.h, rp.nb, rp.cap, rp.n_blades, x,
                         theta)


@njit(cache=True)
def rock_advance(surf, istate, rp, theta_prev, x_prev, theta_new, x_new):
    """:func:`rock_advance_to` on the packed layout ``rp`` and state ``istate = [j_next]``.

    Updates ``surf`` and ``istate`` in place.

    Parameters
    ----------
    surf, istate, rp
        As :func:`rock_depth`.
    theta_prev : float
        Bit angle at the start of the step, rad.
    x_prev : float
        Bit axial position at the start of the step, m (positive downward).
    theta_new : float
        Bit angle at the end of the step, rad.
    x_new : float
        Bit axial position at the end of the step, m.
    """
    istate[0] = rock_advance_to(surf, istate[0], rp.theta_ref, rp.h, rp.nb, rp.cap, rp.memory,
                                theta_prev, x_prev, theta_new, x_new)


def rock_init_helix(spec: RockSurfaceSpec, x0: float, theta0: float, depth_of_cut: float):
    """State of a bit cutting steadily: a helical hole bottom under the bit.

    The surface recorded one pitch back lies ``depth_of_cut / n`` above the bit, so
    :func:`rock_depth` returns ``depth_of_cut`` at (x0, theta0).

    Parameters
    ----------
    spec : RockSurfaceSpec
        Grid layout.
    x0 : float
        Bit axial position, m.
    theta0 : float
        Bit angle, rad.
    depth_of_cut : float
        Total depth of cut, m per revolution (all blades).

    Returns
    -------
    surf : ndarray, shape (cap,)
        Helical surface, m.
    istate : ndarray, shape (1,), int64
        ``[0]``.
    rp : RockSurfaceParams
    """
    surf, istate, rp = rock_init(spec, x0, theta0)
    rise = depth_of_cut / (2.0 * math.pi) * spec.h  # axial advance per grid point
    j = np.arange(spec.cap)
    past = j - spec.cap  # grid indices -cap .. -1 map onto the whole ring
    surf[past & (spec.cap - 1)] = x0 + past * rise
    surf[0] = x0
    return surf, istate, rp
