"""Bit/rock law of Aarsnes & van de Wouw (2019): a contact force independent of the depth of cut.

U. J. F. Aarsnes and N. van de Wouw, "Axial and torsional self-excited vibrations of a
distributed drill-string", Journal of Sound and Vibration 444 (2019) 127-151. The cutting
process is Detournay's (W_c = zeta eps a d, T_c = 1/2 eps a^2 d, with the same backward-rotation
ramp); the wear flats press on the rock with a force W_f that does not grow with the depth of
cut once the bit is in contact, and rub with the friction torque T_f = gamma mu a W_f g(omega)::

    W_f = F_c min(d / d_c, 1) f(v),      F_c = ``contact_force`` (default sigma l a)

d_c = ``contact_depth`` (default 10 um) only regularises the step at first contact so that the
implicit integrators see a finite slope; f(v) and g(omega) are the regularisations of the
Detournay law (contact lost while the bit lifts off, friction sign). Note the factor: this law's
T_f carries no 1/2, so for the same bit its gamma is half of the Detournay law's.

Added through the extension point of :mod:`downhole.bit.law` (see docs/developing.md).
"""

from __future__ import annotations

from numba import njit

from downhole.bit.detournay import (
    contact_speed_factor,
    cutting,
    friction_coefficient,
    friction_sign,
)

__all__ = [
    "aarsnes_contact_force",
    "aarsnes_forces_and_slopes",
    "aarsnes_friction_factor",
    "aarsnes_torque",
    "aarsnes_wob",
]


@njit(cache=True, inline="always")
def aarsnes_contact_force(d, v, p):
    """Contact force W_f and its slopes ``(W_f, dW_f/dd, dW_f/dv)`` for d > 0.

    W_f = F_c min(d / d_c, 1) f(v): the contact force rises linearly over the depth of cut
    ``contact_depth`` d_c and is then independent of d.

    Parameters
    ----------
    d : float
        Total depth of cut (all blades), m. Meant for d > 0.
    v : float
        Bit axial velocity, m/s (positive into the rock).
    p : BitKernelParams
        Compiled bit parameters: ``contact_force`` F_c (N), ``contact_depth`` d_c (m), ``a1``,
        ``b1``.

    Returns
    -------
    (W_f, dW_f/dd, dW_f/dv) : tuple of float
        N, N/m, N s/m.
    """
    fv, dfv = contact_speed_factor(v, p)
    r = d / p.contact_depth
    dr = 1.0 / p.contact_depth
    if r > 1.0:
        r = 1.0
        dr = 0.0
    fc = p.contact_force
    return fc * r * fv, fc * dr * fv, fc * r * dfv


@njit(cache=True, inline="always")
def aarsnes_wob(d, v, p):
    """Weight on bit and its slopes ``(WOB, dWOB/dd, dWOB/dv)``; zero for d <= 0.

    Parameters
    ----------
    d : float
        Total depth of cut (all blades), m.
    v : float
        Bit axial velocity, m/s (positive into the rock).
    p : BitKernelParams
        Compiled bit parameters (:meth:`downhole.params.BitParams.kernel_params`).

    Returns
    -------
    (wob, dwob_dd, dwob_dv) : tuple of float
        N, N/m, N s/m.
    """
    if d <= 0.0:
        return 0.0, 0.0, 0.0
    wc, _, kw, _, _ = cutting(d, 0.0, p)
    wf, dwf_dd, dwf_dv = aarsnes_contact_force(d, v, p)
    return wc + wf, kw + dwf_dd, dwf_dv


@njit(cache=True, inline="always")
def aarsnes_friction_factor(omega, p):
    """k_f = gamma mu a g(omega) of T_f = k_f W_f and dk_f/domega (no factor 1/2).

    Parameters
    ----------
    omega : float
        Bit angular velocity, rad/s.
    p : BitKernelParams
        Compiled bit parameters (:meth:`downhole.params.BitParams.kernel_params`).

    Returns
    -------
    (k_f, dk_f_domega) : tuple of float
        The factor, m (N m of torque per N of contact force), and its slope, m s/rad.
    """
    mugam, dmugam = friction_coefficient(omega, p)
    g, dg = friction_sign(omega, p)
    a = p.radius
    return mugam * a * g, a * (dmugam * g + mugam * dg)


@njit(cache=True, inline="always")
def aarsnes_torque(d, wf, omega, p):
    """TOB and dTOB/domega at depth of cut ``d`` with the contact force ``wf`` held fixed.

    Zero for d <= 0.

    Parameters
    ----------
    d : float
        Total depth of cut (all blades), m.
    wf : float
        Contact force W_f, N.
    omega : float
        Bit angular velocity, rad/s.
    p : BitKernelParams
        Compiled bit parameters (:meth:`downhole.params.BitParams.kernel_params`).

    Returns
    -------
    (tob, dtob_domega) : tuple of float
        Torque on bit, N m, and its slope, N m s/rad.
    """
    if d <= 0.0:
        return 0.0, 0.0
    _, tc, _, _, dtc_dw = cutting(d, omega, p)
    kf, dkf = aarsnes_friction_factor(omega, p)
    return tc + kf * wf, dtc_dw + dkf * wf


@njit(cache=True, inline="always")
def aarsnes_forces_and_slopes(d, v, omega, p):
    """WOB, TOB and their partial slopes of the Aarsnes law; zero for d <= 0.

    Parameters
    ----------
    d : float
        Total depth of cut (all blades), m.
    v : float
        Bit axial velocity, m/s (positive into the rock).
    omega : float
        Bit angular velocity, rad/s.
    p : BitKernelParams
        Compiled bit parameters (:meth:`downhole.params.BitParams.kernel_params`).

    Returns
    -------
    tuple of 7 float
        ``(wob, tob, dwob_dd, dwob_dv, dtob_dd, dtob_dv, dtob_domega)``: N, N m, N/m, N s/m,
        N m/m, N m s/m, N m s/rad.
    """
    if d <= 0.0:
        return 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    wc, tc, kw, dtc_dd, dtc_dw = cutting(d, omega, p)
    wf, dwf_dd, dwf_dv = aarsnes_contact_force(d, v, p)
    kf, dkf = aarsnes_friction_factor(omega, p)
    return (wc + wf, tc + kf * wf, kw + dwf_dd, dwf_dv, dtc_dd + kf * dwf_dd, kf * dwf_dv,
            dtc_dw + dkf * wf)
