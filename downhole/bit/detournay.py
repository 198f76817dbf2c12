"""The corrected Detournay PDC bit/rock law (cutting + wear-flat friction), seed Eqs. 2.2-2.8.

The first implementation of the bit-law interface of :mod:`downhole.bit.law`: forces and their
analytic partial slopes with respect to the depth of cut d, the bit axial velocity v and the bit
angular velocity omega. Kernels do not call this module directly; they call the dispatch in
:mod:`downhole.bit.law`, which selects the law named in ``BitParams.law``.

Corrections applied here (see docs/seed-errata.md): cutting torque vanishes for
omega <= 0 (smooth ramp of width ``omega_reg``); wear-flat force saturates continuously at d*
(default); the Stribeck law acts on |omega|.

The pieces (:func:`cutting`, :func:`contact_speed_factor`, :func:`friction_coefficient`,
:func:`friction_sign`) are shared with the other laws, which differ in the contact force and in
the friction torque's factor.
"""

from __future__ import annotations

import math

from numba import njit

__all__ = [
    "contact_speed_factor",
    "cutting",
    "friction_coefficient",
    "friction_factor",
    "friction_sign",
    "friction_torque_factor",
    "wear_flat_force",
]


@njit(cache=True, inline="always")
def cutting(d, omega, p):
    """Cutting forces of Eqs. 2.3-2.4 with the backward-rotation correction.

    The cutting torque is switched off for omega <= 0 by a linear ramp over [0, omega_reg].

    Parameters
    ----------
    d : float
        Total depth of cut (all blades), m. Meant for d > 0 (no check here).
    omega : float
        Bit angular velocity, rad/s.
    p : BitKernelParams
        Compiled bit parameters: ``epsilon`` (intrinsic specific energy, Pa), ``zeta`` (-),
        ``radius`` a (m), ``omega_reg`` (ramp width, rad/s).

    Returns
    -------
    tuple of 5 float
        ``(wob_c, tob_c, dwob_c/dd, dtob_c/dd, dtob_c/domega)``: N, N m, N/m, N m/m, N m s/rad,
        with ``wob_c = zeta eps a d`` and ``tob_c = 1/2 eps a^2 d s(omega)``.
    """
    eps = p.epsilon
    a = p.radius
    kw = p.zeta * eps * a
    s = omega / p.omega_reg
    ds = 1.0 / p.omega_reg
    if s < 0.0:
        s = 0.0
        ds = 0.0
    elif s > 1.0:
        s = 1.0
        ds = 0.0
    kt = 0.5 * eps * a * a
    return kw * d, kt * d * s, kw, kt * s, kt * d * ds


@njit(cache=True, inline="always")
def contact_speed_factor(v, p):
    """f(v) = 1 / (1 + exp(a1 v + b1)) of Eq. 2.5 and df/dv (contact lost while the bit lifts).

    Parameters
    ----------
    v : float
        Bit axial velocity, m/s (positive into the rock).
    p : BitKernelParams
        Compiled bit parameters: ``a1`` (s/m), ``b1`` (-).

    Returns
    -------
    (f, df_dv) : tuple of float
        The factor in [0, 1] (dimensionless) and its slope, s/m.
    """
    arg = p.a1 * v + p.b1
    if arg > 50.0:
        return 0.0, 0.0
    if arg < -40.0:
        return 1.0, 0.0  # 1 / (1 + e^arg) rounds to 1 exactly: skip the exp
    fv = 1.0 / (1.0 + math.exp(arg))
    return fv, -p.a1 * fv * (1.0 - fv)


@njit(cache=True, inline="always")
def friction_coefficient(omega, p):
    """mu * gamma of the wear-flat friction and its omega-slope.

    Stribeck in |omega| (Eq. 2.8, correction, docs/seed-errata.md) when
    ``p.friction_stribeck`` is set, otherwise the constant ``mu_gamma``.

    Parameters
    ----------
    omega : float
        Bit angular velocity, rad/s.
    p : BitKernelParams
        Compiled bit parameters: ``friction_stribeck``, ``mu_c``, ``mu_s``, ``gamma`` (-),
        ``gamma_b`` (-), ``v_f`` (rad/s), ``mu_gamma`` (-).

    Returns
    -------
    (mu_gamma, dmu_gamma_domega) : tuple of float
        The product mu gamma (dimensionless) and its slope, s/rad.
    """
    if p.friction_stribeck > 0.5:
        e = math.exp(-p.gamma_b / p.v_f * abs(omega))
        mu = p.mu_c + (p.mu_s - p.mu_c) * e
        sgn = 1.0 if omega > 0.0 else -1.0
        return mu * p.gamma, -(p.mu_s - p.mu_c) * p.gamma * p.gamma_b / p.v_f * e * sgn
    return p.mu_gamma, 0.0


@njit(cache=True, inline="always")
def friction_sign(omega, p):
    """g(omega) = tanh(a2 omega + b2) of Eq. 2.6 and dg/domega.

    Parameters
    ----------
    omega : float
        Bit angular velocity, rad/s.
    p : BitKernelParams
        Compiled bit parameters: ``a2`` (s/rad), ``b2`` (-).

    Returns
    -------
    (g, dg_domega) : tuple of float
        The smoothed sign in [-1, 1] and its slope, s/rad.
    """
    z = p.a2 * omega + p.b2
    if z > 20.0:
        return 1.0, 0.0  # tanh rounds to +-1 exactly beyond |z| = 19.1: skip it
    if z < -20.0:
        return -1.0, 0.0
    g = math.tanh(z)
    return g, p.a2 * (1.0 - g * g)


@njit(cache=True, inline="always")
def wear_flat_force(d, v, p):
    """Wear-flat contact force W_f of Eq. 2.5 and its slopes, for d > 0.

    Continuous saturation at d* by default (``p.wear_flat_continuous``), or the printed
    piecewise form (linear spring ``contact_stiffness`` below d*).

    Parameters
    ----------
    d : float
        Total depth of cut (all blades), m.
    v : float
        Bit axial velocity, m/s (positive into the rock).
    p : BitKernelParams
        Compiled bit parameters: ``sigma`` (contact stress, Pa), ``wear_length`` (m),
        ``radius`` (m), ``d_star`` (m), ``contact_stiffness`` (N/m), ``a1``, ``b1``.

    Returns
    -------
    (W_f, dW_f/dd, dW_f/dv) : tuple of float
        Contact force (N) and its slopes (N/m, N s/m).
    """
    fv, dfv = contact_speed_factor(v, p)
    full = p.sigma * p.wear_length * p.radius
    if p.wear_flat_continuous > 0.5:
        r = d / p.d_star
        if r > 1.0:
            return full * fv, 0.0, full * dfv
        return full * r * fv, full / p.d_star * fv, full * r * dfv
    if d > p.d_star:
        return full * fv, 0.0, full * dfv
    return p.contact_stiffness * d, p.contact_stiffness, 0.0


@njit(cache=True, inline="always")
def friction_torque_factor(omega, p, scale):
    """k_f = scale mu gamma a g(omega) of TOB_f = k_f W_f and dk_f/domega.

    Parameters
    ----------
    omega : float
        Bit angular velocity, rad/s.
    p : BitKernelParams
        Compiled bit parameters (:meth:`downhole.params.BitParams.kernel_params`).
    scale : float
        The law's factor: 1/2 for Detournay (Eq. 2.6), 1 for Aarsnes & van de Wouw.

    Returns
    -------
    (k_f, dk_f_domega) : tuple of float
        The factor, m (N m of torque per N of contact force), and its slope, m s/rad.
    """
    mugam, dmugam = friction_coefficient(omega, p)
    g, dg = friction_sign(omega, p)
    a = p.radius
    return scale * mugam * a * g, scale * a * (dmugam * g + mugam * dg)


@njit(cache=True, inline="always")
def friction_factor(omega, p):
    """k_f = 1/2 mu gamma a g(omega) of TOB_f = k_f W_f (Eq. 2.6) and dk_f/domega.

    Parameters
    ----------
    omega, p
        As :func:`friction_torque_factor`.

    Returns
    -------
    (k_f, dk_f_domega) : tuple of float
        :func:`friction_torque_factor` at scale 1/2.
    """
    return friction_torque_factor(omega, p, 0.5)
