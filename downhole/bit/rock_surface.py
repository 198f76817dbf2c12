"""Depth of cut from the bit's own history: the state-dependent delay of seed Eqs. 2.9-2.10.

The rock surface is stored on a uniform grid of *unwrapped bit angle* (``nb`` points per blade
pitch 2 pi/n). A blade at angle theta cuts against the surface left at theta - 2 pi/n, which is
exactly x_bit(t - t_n) with theta(t) - theta(t - t_n) = 2 pi/n (Eq. 2.10), solved by
interpolation instead of a root search. With ``memory`` on (default, SPEC correction) the surface
is the hole bottom: the maximum of the cut depths (x positive downward), so after a bounce the
blade measures against rock, not against its own airborne path. If the bit turns backward and then
forward again over angles it has already cut, the blade meets its own surface.

State lives in two arrays so that compiled kernels can own it: ``surf`` (ring buffer, m) and
``istate = [j_next]`` (index of the next grid angle not yet reached).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

__all__ = ["RockSurfaceSpec", "rock_init", "rock_init_helix", "rock_depth", "rock_advance"]


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

    def params(self, theta_ref: float) -> np.ndarray:
        """Packed float array ``[theta_ref, h, nb, cap, n_blades, memory]`` for the kernels."""
        return np.array([theta_ref, self.h, self.nb, self.cap, self.n_blades,
                         1.0 if self.memory else 0.0])


def rock_init(spec: RockSurfaceSpec, x0: float, theta0: float):
    """Fresh state: the bit rests on a flat bottom at ``x0`` (m) with angle ``theta0`` (rad).

    Returns ``(surf, istate, rp)``."""
    surf = np.full(spec.cap, float(x0))
    istate = np.zeros(1, dtype=np.int64)  # j_next = 0: grid point 0 sits at theta0
    return surf, istate, spec.params(theta0)


@njit(cache=True)
def _surf_at(surf, rp, jf):
    """Surface interpolated at fractional grid index jf (must be recorded)."""
    mask = int(rp[3]) - 1
    j0 = int(math.floor(jf))
    f = jf - j0
    s0 = surf[j0 & mask]
    s1 = surf[(j0 + 1) & mask]
    return s0 + f * (s1 - s0)


@njit(cache=True)
def rock_depth(surf, istate, rp, x, theta):
    """Total depth of cut d = n (x - surface) for the bit at axial position x, angle theta."""
    theta_ref, h, nb, cap, nbl = rp[0], rp[1], rp[2], rp[3], rp[4]
    j_next = istate[0]
    jf = (theta - theta_ref) / h
    if jf >= j_next - 1:
        # at the cutting front: previous blade's surface one pitch back (Eq. 2.10)
        q = jf - nb
        if q > j_next - 1.0:
            q = j_next - 1.0
        if q < j_next - cap + 1.0:
            q = j_next - cap + 1.0
        s = _surf_at(surf, rp, q - 1e-12 if q == j_next - 1.0 else q)
    else:
        # re-traversing angles this blade already cut (after backward rotation)
        q = jf
        if q < j_next - cap + 1.0:
            q = j_next - cap + 1.0
        s = _surf_at(surf, rp, q)
    return nbl * (x - s)


@njit(cache=True)
def rock_advance(surf, istate, rp, theta_prev, x_prev, theta_new, x_new):
    """Record the blade's path from (theta_prev, x_prev) to (theta_new, x_new)."""
    if not (theta_new > theta_prev) or not math.isfinite(theta_new + x_new):
        return  # backward, stuck (or a diverging run): nothing is cut
    theta_ref, h, nb, cap, memory = rp[0], rp[1], int(rp[2]), int(rp[3]), rp[5]
    mask = cap - 1
    j_next = istate[0]
    if abs(theta_new - theta_ref) / h > 1e15 or abs(theta_prev - theta_ref) / h > 1e15:
        return  # runaway angle (diverging run): grid indices would overflow
    j_lo = int(math.floor((theta_prev - theta_ref) / h)) + 1
    j_hi = int(math.floor((theta_new - theta_ref) / h))
    if j_lo < j_next - cap + nb + 1:
        j_lo = j_next - cap + nb + 1
    if j_hi - j_lo >= cap - nb:
        # more than the ring in one step (a runaway): only the last points can be kept
        j_lo = j_hi - cap + nb + 1
    dth = theta_new - theta_prev
    for j in range(j_lo, j_hi + 1):
        th = theta_ref + j * h
        xj = x_prev + (x_new - x_prev) * (th - theta_prev) / dth
        if j >= j_next:
            if memory > 0.5:
                below = surf[(j - nb) & mask]
                surf[j & mask] = xj if xj > below else below
            else:
                surf[j & mask] = xj
        elif memory > 0.5:
            if xj > surf[j & mask]:
                surf[j & mask] = xj
    if j_hi + 1 > j_next:
        istate[0] = j_hi + 1


def rock_init_helix(spec: RockSurfaceSpec, x0: float, theta0: float, depth_of_cut: float):
    """State of a bit cutting steadily: a helical hole bottom with total depth of cut
    ``depth_of_cut`` (m per revolution, all blades) under the bit at ``x0`` (m), ``theta0`` (rad).

    The surface recorded one pitch back lies ``depth_of_cut / n`` above the bit, so
    :func:`rock_depth` returns ``depth_of_cut`` at (x0, theta0). Returns ``(surf, istate, rp)``.
    """
    surf, istate, rp = rock_init(spec, x0, theta0)
    rise = depth_of_cut / (2.0 * math.pi) * spec.h  # axial advance per grid point
    j = np.arange(spec.cap)
    past = j - spec.cap  # grid indices -cap .. -1 map onto the whole ring
    surf[past & (spec.cap - 1)] = x0 + past * rise
    surf[0] = x0
    return surf, istate, rp
