"""The one bit-law interface: forces and their slopes, compiled, dispatched by law id.

Every kernel (lumped chain, neutral, FEM/hybrid), the DP, the EID and the DHP design models call
the bit/rock law only through this module. A law is chosen by name in the parameters
(``BitParams.law``); :meth:`downhole.params.BitParams.kernel_params` builds its parameters and
its integer id once, by name, into one :class:`~downhole.params.bit.BitKernelParams` (a
``NamedTuple`` of floats, passed by value and read by attribute, ``p.epsilon``) that kernels
pass through unopened. The dispatch is an ``if`` on ``p.law`` inside compiled functions inlined
into the kernels; the branch is the same at every step, so it costs nothing measurable.

Interface (all compiled, no allocation):

- :func:`bit_forces` ``(d, v, omega, p) -> (wob, tob)``
- :func:`bit_forces_and_slopes` ``(d, v, omega, p) -> (wob, tob, dwob_dd, dwob_dv, dtob_dd,
  dtob_dv, dtob_domega)``: analytic partial slopes where the law is smooth
- :func:`bit_wob` ``(d, v, p) -> (wob, dwob_dd, dwob_dv)``: the axial part alone
- :func:`bit_contact_force` ``(d, v, p) -> (W_f, dW_f/dd, dW_f/dv)`` and
  :func:`bit_torque_at_contact` ``(d, W_f, omega, p) -> (tob, dtob_domega)``: the torque at a
  given contact force (the torsional implicit solve computes W_f once per step)
- :func:`approx_depth_of_cut`, :func:`approx_depth_rate`: the approximated depth of cut
  d = 2 pi v / max(omega, omega*) (Eqs. 2.11, 4.16)
- :func:`bit_force_slopes`: effective dampers -dWOB/dv, -dTOB/domega by central differences of
  the whole law (what the lumped and neutral kernels apply implicitly)
- :func:`solve_bit_node`: the exact implicit bit force on one node (safeguarded Newton on the
  analytic slopes), used by the FEM/hybrid kernel

d is the total depth of cut (all blades, m), v the bit axial velocity (m/s, positive into the
rock), omega the bit angular velocity (rad/s). The depth of cut itself comes from
:mod:`downhole.bit.rock_surface` (delayed) or :func:`approx_depth_of_cut`.

Adding a law (see docs/developing.md): write its compiled ``<law>_wob``,
``<law>_contact_force``, ``<law>_torque`` and ``<law>_forces_and_slopes`` in a new module of
this package, give it an id in :data:`downhole.params.bit.LAW_IDS` (and its parameters in
``BitParams``), add one branch to each of :func:`bit_wob`, :func:`bit_contact_force`,
:func:`bit_torque_at_contact` and :func:`bit_forces_and_slopes` below and one :class:`BitLaw`
entry to :data:`LAWS`.
"""

from __future__ import annotations

import importlib
import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from downhole.bit.aarsnes import aarsnes_contact_force, aarsnes_friction_factor
from downhole.bit.detournay import cutting, friction_factor, wear_flat_force
from downhole.params.bit import LAW_IDS, BitKernelParams, BitParams

__all__ = [
    "LAWS",
    "BitLaw",
    "approx_depth_of_cut",
    "approx_depth_rate",
    "bit_contact_force",
    "bit_force_slopes",
    "bit_forces",
    "bit_forces_and_slopes",
    "bit_forces_and_slopes_py",
    "bit_forces_py",
    "bit_forces_vec",
    "bit_torque_at_contact",
    "bit_wob",
    "law_id",
    "solve_bit_node",
]


@dataclass(frozen=True)
class BitLaw:
    """One registered bit law.

    Attributes
    ----------
    name : str
        Name used in ``BitParams.law`` and in a scenario's bit table (``law = "..."``).
    law_id : int
        Integer id the compiled dispatch branches on (:data:`downhole.params.bit.LAW_IDS`).
    module : str
        Module that holds the law's compiled functions.
    parameters : tuple of str
        ``BitParams`` fields the law reads.
    reference : str
        Where the law is published.
    """

    name: str
    law_id: int
    module: str
    parameters: tuple[str, ...]
    reference: str


_COMMON = ("epsilon", "zeta", "radius", "omega_reg", "a1", "b1", "a2", "b2", "friction_law",
           "mu_c", "mu_s", "gamma", "gamma_b", "v_f", "mu_gamma", "omega_floor")

#: The registered laws, by name.
LAWS = {
    "detournay": BitLaw("detournay", LAW_IDS["detournay"], "downhole.bit.detournay",
                        _COMMON + ("sigma", "wear_length", "d_star", "wear_flat_law",
                                   "contact_stiffness"),
                        "Detournay & Defourny (1992); Detournay et al. (2008); seed Eqs. 2.2-2.8"),
    "aarsnes": BitLaw("aarsnes", LAW_IDS["aarsnes"], "downhole.bit.aarsnes",
                      _COMMON + ("contact_force", "contact_depth", "sigma", "wear_length"),
                      "Aarsnes & van de Wouw, J. Sound Vib. 444 (2019) 127-151"),
}

_DETOURNAY = LAW_IDS["detournay"]
_AARSNES = LAW_IDS["aarsnes"]


def law_id(name: str) -> int:
    """Integer id of the bit law ``name``.

    Parameters
    ----------
    name : str
        Registered law name (a key of :data:`LAWS`, e.g. ``"detournay"``).

    Returns
    -------
    int
        The id the compiled dispatch branches on (:data:`downhole.params.bit.LAW_IDS`).

    Raises
    ------
    ValueError
        If ``name`` is not a registered law (the message names the known laws).
    """
    if name not in LAWS:
        raise ValueError(f"unknown bit law {name!r}: expected one of {sorted(LAWS)}")
    return LAWS[name].law_id


@njit(cache=True, inline="always")
def _law_contact_force(d, v, p, law):
    """The contact force ``(W_f, dW_f/dd, dW_f/dv)`` of law ``law`` for d > 0."""
    if law == _AARSNES:
        return aarsnes_contact_force(d, v, p)
    return wear_flat_force(d, v, p)


@njit(cache=True, inline="always")
def _law_friction_factor(omega, p, law):
    """``(k_f, dk_f/domega)`` of the friction torque T_f = k_f W_f of law ``law``."""
    if law == _AARSNES:
        return aarsnes_friction_factor(omega, p)
    return friction_factor(omega, p)


@njit(cache=True, inline="always")
def _law_wob(d, v, p, law):
    """:func:`bit_wob` of law ``law`` (cutting plus the law's contact force)."""
    if d <= 0.0:
        return 0.0, 0.0, 0.0
    wc, _, kw, _, _ = cutting(d, 0.0, p)
    wf, dwf_dd, dwf_dv = _law_contact_force(d, v, p, law)
    return wc + wf, kw + dwf_dd, dwf_dv


@njit(cache=True, inline="always")
def _law_torque(d, wf, omega, p, law):
    """:func:`bit_torque_at_contact` of law ``law`` (cutting plus the law's friction)."""
    if d <= 0.0:
        return 0.0, 0.0
    _, tc, _, _, dtc_dw = cutting(d, omega, p)
    kf, dkf = _law_friction_factor(omega, p, law)
    return tc + kf * wf, dtc_dw + dkf * wf


@njit(cache=True, inline="always")
def _law_forces_and_slopes(d, v, omega, p, law):
    """:func:`bit_forces_and_slopes` of law ``law``: TOB = T_c + k_f W_f, WOB = W_c + W_f."""
    if d <= 0.0:
        return 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    wc, tc, kw, dtc_dd, dtc_dw = cutting(d, omega, p)
    wf, dwf_dd, dwf_dv = _law_contact_force(d, v, p, law)
    kf, dkf = _law_friction_factor(omega, p, law)
    return (wc + wf, tc + kf * wf, kw + dwf_dd, dwf_dv, dtc_dd + kf * dwf_dd, kf * dwf_dv,
            dtc_dw + dkf * wf)


def _entry_points(lid):
    """The compiled ``(wob, torque, forces_and_slopes)`` of law id ``lid``, whatever ``p.law``."""

    @njit(inline="always")
    def wob(d, v, p):
        return _law_wob(d, v, p, lid)

    @njit(inline="always")
    def torque(d, wf, omega, p):
        return _law_torque(d, wf, omega, p, lid)

    @njit(inline="always")
    def forces_and_slopes(d, v, omega, p):
        return _law_forces_and_slopes(d, v, omega, p, lid)

    return {"wob": wob, "torque": torque, "forces_and_slopes": forces_and_slopes}


# Each law's module keeps its entry points importable under their names (``detournay_wob``,
# ``aarsnes_torque``, ...): one composition above serves them all.
for _law in LAWS.values():
    for _kind, _fn in _entry_points(_law.law_id).items():
        setattr(importlib.import_module(_law.module), f"{_law.name}_{_kind}", _fn)


@njit(cache=True, inline="always")
def bit_wob(d, v, p):
    """Weight on bit and its partial slopes ``(wob, dwob_dd, dwob_dv)`` of the selected law.

    Parameters
    ----------
    d, v : float
        Total depth of cut (all blades), m; bit axial velocity, m/s (positive into the rock).
    p : BitKernelParams
        Compiled bit parameters (law id ``p.law`` and the law's constants), from
        :meth:`downhole.params.BitParams.kernel_params`.

    Returns
    -------
    wob, dwob_dd, dwob_dv : float
        Weight on bit, N; dWOB/dd, N/m; dWOB/dv, N s/m. All zero for d <= 0.
    """
    return _law_wob(d, v, p, p.law)


@njit(cache=True, inline="always")
def bit_contact_force(d, v, p):
    """Contact (wear-flat) force of the selected law and its slopes; zero for d <= 0.

    Parameters
    ----------
    d, v, p
        As :func:`bit_wob`.

    Returns
    -------
    (W_f, dW_f/dd, dW_f/dv) : tuple of float
        Contact force (N) and its partial slopes (N/m, N s/m).
    """
    if d <= 0.0:
        return 0.0, 0.0, 0.0
    return _law_contact_force(d, v, p, p.law)


@njit(cache=True, inline="always")
def bit_torque_at_contact(d, wf, omega, p):
    """TOB and dTOB/domega of the selected law with the contact force held fixed.

    At depth of cut ``d`` with the contact force ``wf`` (from :func:`bit_contact_force`) held
    fixed: the torsional implicit solve iterates on omega only, so the contact force is computed
    once per step.

    Parameters
    ----------
    d : float
        Total depth of cut (all blades), m.
    wf : float
        Contact (wear-flat) force W_f, N.
    omega : float
        Bit angular velocity, rad/s.
    p : BitKernelParams
        As :func:`bit_wob`.

    Returns
    -------
    tob : float
        Torque on bit, N m.
    dtob_domega : float
        dTOB/domega, N m s/rad.
    """
    return _law_torque(d, wf, omega, p, p.law)


@njit(cache=True, inline="always")
def bit_forces_and_slopes(d, v, omega, p):
    """WOB (N), TOB (N m) and their partial slopes of the selected law.

    Parameters
    ----------
    d, v, p
        As :func:`bit_wob`.
    omega : float
        Bit angular velocity, rad/s.

    Returns
    -------
    tuple of 7 float
        ``(wob, tob, dwob_dd, dwob_dv, dtob_dd, dtob_dv, dtob_domega)``: N, N m, N/m, N s/m,
        N m/m, N m s/m, N m s/rad; all zero for d <= 0 (bit off bottom).
    """
    return _law_forces_and_slopes(d, v, omega, p, p.law)


@njit(cache=True, inline="always")
def bit_forces(d, v, omega, p):
    """Weight and torque on bit ``(wob, tob)`` of the selected law.

    Parameters
    ----------
    d, v, omega, p
        As :func:`bit_forces_and_slopes`.

    Returns
    -------
    (wob, tob) : tuple of float
        Weight on bit, N, and torque on bit, N m.
    """
    r = bit_forces_and_slopes(d, v, omega, p)
    return r[0], r[1]


@njit(cache=True, inline="always")
def approx_depth_of_cut(v, omega, p):
    """Approximated total depth of cut d = 2 pi v / max(omega, omega*) (Eqs. 2.11, 4.16), m.

    Parameters
    ----------
    v : float
        Bit axial velocity, m/s (positive into the rock).
    omega : float
        Bit angular velocity, rad/s.
    p : BitKernelParams
        Compiled bit parameters; ``p.omega_floor`` is omega*, rad/s.

    Returns
    -------
    float
        Depth of cut, m.
    """
    w = omega
    w = max(w, p.omega_floor)
    return 2.0 * math.pi * v / w


@njit(cache=True, inline="always")
def approx_depth_rate(omega, p):
    """dd/dv of the approximated depth of cut: 2 pi / max(omega, omega*), s.

    Parameters
    ----------
    omega, p
        As :func:`approx_depth_of_cut`.

    Returns
    -------
    float
        Slope of :func:`approx_depth_of_cut` with respect to v, s.
    """
    w = omega
    w = max(w, p.omega_floor)
    return 2.0 * math.pi / w


@njit(cache=True)
def bit_force_slopes(d, v, omega, p, approx):
    """Non-negative effective dampers -dWOB/dv and -dTOB/domega (central differences).

    Used by the lumped and neutral implicit integrators to apply the stiff regularised friction
    laws implicitly (frozen coefficients). With ``approx`` true the depth of cut follows v and
    omega. Differences of the whole law rather than its analytic slopes: they include the
    depth-of-cut coupling of the approximated depth and keep these kernels' results unchanged.

    Parameters
    ----------
    d : float
        Total depth of cut, m (ignored when ``approx`` is true).
    v : float
        Bit axial velocity, m/s (positive into the rock).
    omega : float
        Bit angular velocity, rad/s.
    p : BitKernelParams
        Compiled bit parameters (law id ``p.law`` and the law's constants), from
        :meth:`downhole.params.BitParams.kernel_params`.
    approx : bool
        If true, recompute d from v and omega with :func:`approx_depth_of_cut` at each
        perturbed point.

    Returns
    -------
    (c_axial, c_torsional) : tuple of float
        ``max(dWOB/dv, 0)`` in N s/m and ``max(dTOB/domega, 0)`` in N m s/rad (as computed;
        the kernels use them as implicit damper coefficients).
    """
    hv = 1e-7 + 1e-4 * abs(v)
    hw = 1e-6 + 1e-4 * abs(omega)
    if approx:
        w1, _ = bit_forces(approx_depth_of_cut(v + hv, omega, p), v + hv, omega, p)
        w0, _ = bit_forces(approx_depth_of_cut(v - hv, omega, p), v - hv, omega, p)
        _, t1 = bit_forces(approx_depth_of_cut(v, omega + hw, p), v, omega + hw, p)
        _, t0 = bit_forces(approx_depth_of_cut(v, omega - hw, p), v, omega - hw, p)
    else:
        w1, _ = bit_forces(d, v + hv, omega, p)
        w0, _ = bit_forces(d, v - hv, omega, p)
        _, t1 = bit_forces(d, v, omega + hw, p)
        _, t0 = bit_forces(d, v, omega - hw, p)
    ca = (w1 - w0) / (2.0 * hv)
    ct = (t1 - t0) / (2.0 * hw)
    return max(ca, 0.0), max(ct, 0.0)


@njit(cache=True)
def solve_bit_node(field, den, r, h, x, c0, c1, p, max_iter=60):
    """Solve ``den x + h F(x) = r`` for the bit node's new velocity (safeguarded Newton).

    ``field`` 0: x is the axial velocity and F = WOB(d = c0 + c1 x, v = x); 1: x is the angular
    velocity and F = TOB(d = c0, v = c1, omega = x). F is non-decreasing in x for the registered
    laws (Stribeck weakening is bracketed), so the root is bracketed as it goes and bisection
    takes over if Newton leaves the bracket.

    Parameters
    ----------
    field : int
        0 for the axial equation, 1 for the torsional one.
    den : float
        Coefficient of x in the equation (positive; same units as ``h dF/dx``, e.g. kg for
        the axial field and kg m^2 for the torsional one when the equation is a momentum balance).
    r : float
        Right-hand side, in the units of ``den x``.
    h : float
        Factor of the bit force in the equation (the step-size weight of the integrator), s.
    x : float
        Initial guess of the velocity, m/s (axial) or rad/s (torsional).
    c0 : float
        Axial: depth of cut at x = 0, m. Torsional: the depth of cut d, m.
    c1 : float
        Axial: dd/dx, s. Torsional: the axial velocity v, m/s (used for the contact force).
    p : BitKernelParams
        Compiled bit parameters (law id ``p.law`` and the law's constants), from
        :meth:`downhole.params.BitParams.kernel_params`.
    max_iter : int, optional
        Newton iterations at most (default 60: solved to round-off). 1 gives the linearly
        implicit step (the law linearized at the guess ``x``: one evaluation of the law).

    Returns
    -------
    float
        The velocity x solving the equation, m/s or rad/s (the last iterate after ``max_iter``
        iterations).
    """
    lo = -1e300
    hi = 1e300
    wf = bit_contact_force(c0, c1, p)[0] if field == 1 else 0.0
    for _ in range(max_iter):
        if field == 0:
            f, dwd, dwv = bit_wob(c0 + c1 * x, x, p)
            df = dwd * c1 + dwv
        else:
            f, df = bit_torque_at_contact(c0, wf, x, p)
        fx = den * x + h * f - r
        if fx == 0.0:
            return x
        if fx > 0.0:
            hi = x
        else:
            lo = x
        fp = den + h * df
        if not fp > 0.0:
            fp = den
        xn = x - fx / fp
        if abs(xn - x) < 1e-13 * (1.0 + abs(x)):
            return xn
        if not (lo < xn < hi):
            if lo > -1e299 and hi < 1e299:
                xn = 0.5 * (lo + hi)
            elif xn <= lo:
                xn = lo + 1.0 + abs(lo)
            else:
                xn = hi - 1.0 - abs(hi)
        x = xn
    return x


def _kernel_params(bit) -> BitKernelParams:
    """``bit`` (a :class:`BitParams` or already a :class:`BitKernelParams`) as the kernels take
    it; anything else is a ``TypeError`` naming both."""
    if isinstance(bit, BitParams):
        return bit.kernel_params()
    if isinstance(bit, BitKernelParams):
        return bit
    raise TypeError(f"expected BitParams or BitKernelParams, got {type(bit).__name__}")


def bit_forces_py(d, v, omega, bit: BitParams) -> tuple[float, float]:
    """Convenience wrapper of :func:`bit_forces` for a :class:`BitParams`.

    Parameters
    ----------
    d : float
        Total depth of cut (all blades), m.
    v : float
        Bit axial velocity, m/s (positive into the rock).
    omega : float
        Bit angular velocity, rad/s.
    bit : BitParams or BitKernelParams
        Bit parameters; a :class:`BitParams` is compiled with ``kernel_params()``.

    Returns
    -------
    (wob, tob) : tuple of float
        Weight on bit, N, and torque on bit, N m.

    Raises
    ------
    TypeError
        If ``bit`` is neither a :class:`BitParams` nor a :class:`BitKernelParams`.
    """
    return bit_forces(float(d), float(v), float(omega), _kernel_params(bit))


def bit_forces_and_slopes_py(d, v, omega, bit: BitParams) -> tuple[float, ...]:
    """Convenience wrapper of :func:`bit_forces_and_slopes` for a :class:`BitParams`.

    Parameters
    ----------
    d, v, omega, bit
        As :func:`bit_forces_py`.

    Returns
    -------
    tuple of 7 float
        ``(wob, tob, dwob_dd, dwob_dv, dtob_dd, dtob_dv, dtob_domega)`` as
        :func:`bit_forces_and_slopes` (N, N m and their slopes).

    Raises
    ------
    TypeError
        If ``bit`` is neither a :class:`BitParams` nor a :class:`BitKernelParams`.
    """
    return tuple(float(x) for x in
                 bit_forces_and_slopes(float(d), float(v), float(omega), _kernel_params(bit)))


def bit_forces_vec(d, v, omega, bit: BitParams):
    """Vectorised wrapper of :func:`bit_forces` over NumPy arrays (for plots and analysis).

    Parameters
    ----------
    d, v, omega : array_like
        Total depth of cut, m; bit axial velocity, m/s; bit angular velocity, rad/s.
    bit : BitParams or BitKernelParams
        As :func:`bit_forces_py`.

    Returns
    -------
    wob, tob : ndarray
        Weight on bit (N) and torque on bit (N m), with the broadcast shape of the inputs.

    Raises
    ------
    TypeError
        If ``bit`` is neither a :class:`BitParams` nor a :class:`BitKernelParams`.
    """
    p = _kernel_params(bit)
    d, v, omega = np.broadcast_arrays(np.asarray(d, float), np.asarray(v, float),
                                      np.asarray(omega, float))
    wob = np.empty(d.shape)
    tob = np.empty(d.shape)
    for i in np.ndindex(d.shape):
        wob[i], tob[i] = bit_forces(d[i], v[i], omega[i], p)
    return wob, tob
