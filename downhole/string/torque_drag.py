"""Torque and drag: soft-string tension, torque and side force along the string; hook loads.

The classic soft-string model (Johancsik et al. 1984, SPE 11380): the string is a cable that
follows the well path's centre line and lies on the wall; its bending stiffness is neglected.
For each element from the bit up to the surface:

* buoyed weight per length ``w = g A (rho_steel - rho_mud)`` (open-ended pipe, mud inside and
  out; the tension is the *effective* tension, which at surface is the hook load);
* wall reaction per length ``N = |T dt/ds + w g_perp|`` from the well path's curvature vector
  and the part of the weight normal to the string -- the package's one soft-string formula,
  :func:`downhole.contact.softstring.normal_force_per_length`, i.e. Johancsik's
  ``sqrt((T theta' - w sin theta)^2 + (T sin theta phi')^2)``;
* ``dT = w dTVD + s mu N dL`` with ``s = +1`` tripping out (pick-up: friction opposes the upward
  motion), ``s = -1`` tripping in (slack-off) and ``s = 0`` rotating (the axial velocity is
  negligible against the surface speed of the rotating pipe, so the friction is all
  circumferential);
* ``dM = mu N r dL`` while rotating, with the torque arm ``r`` the pipe's outer radius (tool
  joints and stabilizers are not modelled).

Boundary conditions at the bit: no load off bottom (tripping, rotating off bottom); drilling
(rotating on bottom) has ``T = -WOB`` and ``M = TOB``. Each element is integrated with the
explicit midpoint rule (normal force at the element's mid tension), the geometry of the
minimum-curvature arc at the element's midpoint and the exact change of true vertical depth,
so the results converge at second order in the element length.

:func:`torque_drag` gives the profiles along measured depth with the bit at total depth and the
hook load and surface torque against bit depth (the broomstick plot's curves) for several
friction factors. See ``docs/torque-drag.md``.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from downhole.contact.softstring import normal_force_per_length, normal_weight
from downhole.errors import DownholeInputError
from downhole.errors import positive_number as _finite_positive
from downhole.string.drillstring import DrillString
from downhole.units import si_or_number
from downhole.well.path import WellPath

__all__ = ["CASES", "CASE_LABELS", "TorqueDrag", "md_nodes", "torque_drag"]

#: Load cases: pick-up (trip out), slack-off (trip in), rotating off bottom, drilling (rotating
#: on bottom with WOB and TOB).
CASES = ("trip_out", "trip_in", "rotating", "drilling")

#: Readable names of :data:`CASES`.
CASE_LABELS = {"trip_out": "pick-up (trip out)", "trip_in": "slack-off (trip in)",
               "rotating": "rotating off bottom", "drilling": "drilling (on bottom)"}

_AXIAL = {"trip_out": 1.0, "trip_in": -1.0, "rotating": 0.0, "drilling": 0.0}
_ROTATING = {"trip_out": 0.0, "trip_in": 0.0, "rotating": 1.0, "drilling": 1.0}

#: Most nodes a computation may use (total depth / step).
MAX_NODES = 200_000
#: Most bit depths of the hook-load curves (each needs one integration over the string above):
#: with more nodes, evenly spread nodes including the total depth.
MAX_BIT_DEPTHS = 1000


@njit(cache=True)
def _march(elem, dzw, radius, mu, axial, rotating, t_bit, m_bit, tension, torque, side):
    """Integrate tension and torque from the bit (last node) to the top node.

    ``elem``: element rows in :data:`~downhole.contact.softstring.ELEM_LAYOUT` (top first,
    one more row than elements); ``dzw``: buoyed weight times the change of TVD per element (N);
    ``radius``: torque arm per element (m). Fills ``tension``/``torque`` (per node) and ``side``
    (normal force per length per element, N/m)."""
    m = elem.shape[0] - 1
    t = t_bit
    q = m_bit
    tension[m] = t
    torque[m] = q
    for e in range(m - 1, -1, -1):
        length = elem[e, 0]
        f = mu * elem[e, 7]
        n1 = normal_force_per_length(t, elem[e, 1], elem[e, 2], elem[e, 3], elem[e, 4],
                                     elem[e, 5], elem[e, 6])
        t_mid = t + 0.5 * (dzw[e] + axial * f * n1 * length)
        n = normal_force_per_length(t_mid, elem[e, 1], elem[e, 2], elem[e, 3], elem[e, 4],
                                    elem[e, 5], elem[e, 6])
        side[e] = n
        t = t + dzw[e] + axial * f * n * length
        q = q + rotating * f * n * length * radius[e]
        tension[e] = t
        torque[e] = q


def md_nodes(well: WellPath, step: float, extra=()) -> np.ndarray:
    """Nodes from the top of the well to its total depth, at most ``step`` m apart, including
    every survey station and the measured depths in ``extra`` (clipped to the well)."""
    step = _finite_positive("step", step)
    top, td = well.top_depth, well.total_depth
    if (td - top) / step > MAX_NODES:
        raise DownholeInputError(f"step = {step:g} m gives more than {MAX_NODES} nodes over "
                                 f"{td - top:g} m; use a larger step")
    fixed = np.concatenate([well.stations["md"], np.asarray(list(extra), float)])
    fixed = np.unique(np.clip(fixed, top, td))
    nodes = [fixed[:1]]
    for a, b in itertools.pairwise(fixed):
        n = max(1, int(math.ceil((b - a) / step - 1e-9)))
        nodes.append(np.linspace(a, b, n + 1)[1:])
    md = np.concatenate(nodes)
    keep = np.concatenate([[True], np.diff(md) > 1e-9 * max(1.0, td)])
    return md[keep]


def _frictions(friction) -> tuple:
    vals = [friction] if np.ndim(friction) == 0 else list(friction)
    if not vals:
        raise DownholeInputError("friction: give at least one friction factor")
    if len(vals) > 20:
        raise DownholeInputError(f"friction: at most 20 friction factors, got {len(vals)}")
    out = []
    for v in vals:
        x = _finite_positive("friction factor", v, allow_zero=True)
        if x > 10:
            raise DownholeInputError(f"friction factor must be at most 10, got {v!r}")
        out.append(x)
    return tuple(out)


def _cumulative(string: DrillString, per_segment):
    """Breakpoints (distance from the bit, m) and the running integral of a per-segment value
    from the bit up (piecewise linear in the distance)."""
    lengths = np.array([s.length for s in string.segments])[::-1]
    vals = np.asarray(per_segment, float)[::-1]
    x = np.concatenate([[0.0], np.cumsum(lengths)])
    y = np.concatenate([[0.0], np.cumsum(lengths * vals)])
    return x, y


@dataclass(frozen=True)
class TorqueDrag:
    """Torque-and-drag results for one well and string at several friction factors.

    Attributes
    ----------
    md : ndarray, shape (n,)
        Nodes along the string, top (surface) to bit, measured depth m.
    friction : tuple of float
        Friction factors (k of them).
    tension, torque, side_force : dict of str to ndarray, shape (k, n)
        Per case (:data:`CASES`), with the bit at total depth: effective tension (N, positive
        in tension), torque (N m) and wall reaction per length (N/m, nodal average of the
        adjacent elements).
    bit_depth : ndarray, shape (d,)
        Bit depths of the hook-load curves, m: every node below the top (at most
        :data:`MAX_BIT_DEPTHS`, evenly spread, with the total depth).
    hook_load, surface_torque : dict of str to ndarray, shape (k, d)
        Per case, the tension (N) and torque (N m) at surface with the bit at ``bit_depth``
        (the broomstick plot; the drilling case applies WOB and TOB at every depth).
    wob, tob : float
        Bit load (N) and bit torque (N m) of the drilling case.
    """

    md: np.ndarray
    friction: tuple
    tension: dict
    torque: dict
    side_force: dict
    bit_depth: np.ndarray
    hook_load: dict
    surface_torque: dict
    wob: float
    tob: float

    def at(self, case: str, friction: float) -> dict:
        """The profiles of one case at one of the friction factors:
        ``{"md", "tension", "torque", "side_force"}``."""
        if case not in CASES:
            raise DownholeInputError(f"case must be one of {CASES}, got {case!r}")
        k = self._index(friction)
        return {"md": self.md, "tension": self.tension[case][k], "torque": self.torque[case][k],
                "side_force": self.side_force[case][k]}

    def _index(self, friction: float) -> int:
        for k, f in enumerate(self.friction):
            if abs(f - float(friction)) <= 1e-12:
                return k
        raise DownholeInputError(f"friction {friction!r} was not computed; computed "
                                 f"{list(self.friction)}")


def torque_drag(well: WellPath, string: DrillString, *, friction=(0.1, 0.2, 0.3),
                wob: float = 0.0, tob: float = 0.0, step: float = 10.0,
                hook_load: bool = True) -> TorqueDrag:
    """Soft-string torque and drag of ``string`` in ``well`` (module docstring).

    Parameters
    ----------
    well : WellPath
        The trajectory; the bit is at its total depth for the profiles.
    string : DrillString
        Segments from surface to bit and the mud density; it must reach from the top of the well
        to the bit (its length is the well's).
    friction : float or sequence of float
        Friction factor(s) mu (0..10).
    wob, tob : float, str or pint Quantity
        Weight on bit (N, >= 0) and torque on bit (N m) of the drilling case (``"20 klbf"``,
        ``"10 kft*lbf"``: unit strings and quantities are accepted). This function knows no bit:
        :meth:`downhole.system.DrillingSystem.torque_drag` and ``downhole torque-drag`` take
        the TOB from the bit law at the WOB by default.
    step : float, str or pint Quantity
        Largest element length, m (``"30 ft"``); every survey station and segment joint is a
        node.
    hook_load : bool
        Also compute hook load and surface torque against bit depth (one integration per node).

    Returns
    -------
    TorqueDrag

    Raises
    ------
    DownholeInputError
        A string that does not fill the well, a bad friction factor, WOB, TOB or step.

    Examples
    --------
    >>> from downhole.string.drillstring import DrillString, pipe_section
    >>> from downhole.well import Vertical, WellPath
    >>> well = WellPath.from_sections([Vertical(1000.0)])
    >>> string = DrillString.uniform(1000.0, pipe_section(0.12, 0.06))
    >>> td = torque_drag(well, string, friction=0.3)
    >>> round(float(td.tension["trip_out"][0, 0]))   # vertical: hook load = weight, no drag
    653209
    """
    if not isinstance(well, WellPath):
        raise DownholeInputError(f"well must be a WellPath, got {type(well).__name__}")
    if not isinstance(string, DrillString):
        raise DownholeInputError(f"string must be a DrillString, got {type(string).__name__}")
    mus = _frictions(friction)
    wob = _finite_positive("wob", si_or_number(wob, "force", "wob"), allow_zero=True)
    tob = si_or_number(tob, "torque", "tob")
    step = si_or_number(step, "length", "step")
    try:
        tob = float(tob)
    except (TypeError, ValueError):
        raise DownholeInputError(f"tob must be a number, got {tob!r}") from None
    if not math.isfinite(tob):
        raise DownholeInputError(f"tob must be finite, got {tob!r}")
    span = well.total_depth - well.top_depth
    if abs(string.length - span) > 1e-6 * max(1.0, span):
        raise DownholeInputError(
            f"torque and drag needs a string from surface to the bit: the string is "
            f"{string.length:g} m long, the well {span:g} m")

    td = well.total_depth
    joints = td - string.boundaries[::-1]            # segment joints (bit at total depth)
    md = md_nodes(well, step, extra=joints)
    mid = 0.5 * (md[:-1] + md[1:])
    length = np.diff(md)
    t_mid = np.atleast_2d(well.tangent(mid))
    dtds = np.atleast_2d(well.curvature_vector(mid))
    gperp = normal_weight(t_mid, np.ones(mid.size))
    dtvd = np.diff(np.asarray(well.tvd(md), float))
    g, rho_mud = string.g, string.mud_density
    w_seg = [g * s.section.weight_factor * s.section.area * (s.section.density - rho_mud)
             for s in string.segments]
    r_seg = [0.5 * s.section.outer_diameter for s in string.segments]
    xw, yw = _cumulative(string, w_seg)
    xr, yr = _cumulative(string, r_seg)

    def loads(bit_md, k_bit):
        """Mean buoyed weight and torque arm of elements 0..k_bit-1 with the bit at bit_md."""
        a, b = bit_md - md[1:k_bit + 1], bit_md - md[:k_bit]     # distance from the bit
        lw = np.interp(b, xw, yw) - np.interp(a, xw, yw)
        lr = np.interp(b, xr, yr) - np.interp(a, xr, yr)
        return lw / length[:k_bit], lr / length[:k_bit]

    def elements(w, k_bit):
        elem = np.zeros((k_bit + 1, 8))
        elem[:k_bit, 0] = length[:k_bit]
        elem[:k_bit, 1:4] = dtds[:k_bit]
        elem[:k_bit, 4:7] = gperp[:k_bit] * w[:, None]
        elem[:k_bit, 7] = 1.0
        return elem

    def run(k_bit, case, mu, elem, dzw, radius):
        tension = np.empty(k_bit + 1)
        torque = np.empty(k_bit + 1)
        side = np.empty(k_bit)
        on_bottom = case == "drilling"
        _march(elem, dzw, radius, mu, _AXIAL[case], _ROTATING[case],
               -wob if on_bottom else 0.0, tob if on_bottom else 0.0, tension, torque, side)
        return tension, torque, side

    n = md.size
    kb = n - 1
    w, r = loads(td, kb)
    elem, dzw = elements(w, kb), w * dtvd
    prof = {key: {c: np.empty((len(mus), n)) for c in CASES}
            for key in ("tension", "torque", "side_force")}
    for c in CASES:
        for k, mu in enumerate(mus):
            tension, torque, side = run(kb, c, mu, elem, dzw, r)
            prof["tension"][c][k] = tension
            prof["torque"][c][k] = torque
            nodal = np.empty(n)
            nodal[0], nodal[-1] = side[0], side[-1]
            nodal[1:-1] = (side[:-1] * length[:-1] + side[1:] * length[1:]) / (
                length[:-1] + length[1:])
            prof["side_force"][c][k] = nodal

    if hook_load:
        depth_idx = np.arange(1, n)
        if depth_idx.size > MAX_BIT_DEPTHS:
            depth_idx = np.unique(np.round(np.linspace(1, n - 1, MAX_BIT_DEPTHS)).astype(int))
        hook = {c: np.empty((len(mus), depth_idx.size)) for c in CASES}
        storque = {c: np.empty((len(mus), depth_idx.size)) for c in CASES}
        for j, k_bit in enumerate(depth_idx):
            w, r = loads(md[k_bit], k_bit)
            elem, dzw = elements(w, k_bit), w * dtvd[:k_bit]
            for c in CASES:
                for k, mu in enumerate(mus):
                    tension, torque, _ = run(k_bit, c, mu, elem, dzw, r)
                    hook[c][k, j] = tension[0]
                    storque[c][k, j] = torque[0]
        bit_depth = md[depth_idx]
    else:
        bit_depth = np.empty(0)
        hook = {c: np.empty((len(mus), 0)) for c in CASES}
        storque = {c: np.empty((len(mus), 0)) for c in CASES}
    return TorqueDrag(md=md, friction=mus, tension=prof["tension"], torque=prof["torque"],
                      side_force=prof["side_force"], bit_depth=bit_depth, hook_load=hook,
                      surface_torque=storque, wob=wob, tob=tob)
