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

from downhole.bit.detournay import contact_speed_factor, friction_torque_factor

__all__ = [
    "aarsnes_contact_force",
    "aarsnes_friction_factor",
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
def aarsnes_friction_factor(omega, p):
    """k_f = gamma mu a g(omega) of T_f = k_f W_f and dk_f/domega (no factor 1/2).

    Parameters
    ----------
    omega, p
        As :func:`downhole.bit.detournay.friction_torque_factor`.
    """
    return friction_torque_factor(omega, p, 1.0)
