"""Closed-loop references of bit velocity (axial m/s, angular rad/s): constant, the seed's sinusoid
and multi-ramp (Eqs. 3.34-3.35) and user-defined signals.

They live in the mechanics core because the plant runners sample them (e.g.
:func:`downhole.sim.simulate` hands the sampled reference to any controller);
:mod:`downhole.control.eid.references` re-exports them for the EID controller."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from downhole.errors import DownholeInputError

__all__ = [
    "Reference",
    "as_reference",
    "constant_reference",
    "eq_3_34",
    "eq_3_35",
    "seed_tracking_reference",
    "user_reference",
]


@dataclass(frozen=True)
class Reference:
    """A pair of signals (axial m/s, angular rad/s): numbers, ``(t, values)`` or ``f(t)``.

    Parameters
    ----------
    axial : float, tuple or callable
        Reference bit axial velocity, m/s: a number, ``(times, values)`` samples (times in s,
        interpolated linearly) or a callable ``f(t)``.
    angular : float, tuple or callable
        Reference bit angular velocity, rad/s, of the same forms.
    name : str, optional
        Label (default ``"user"``).
    """

    axial: object
    angular: object
    name: str = "user"

    def sample(self, t) -> np.ndarray:
        """Array (2, len(t)) of the reference at times ``t``.

        Parameters
        ----------
        t : array_like, shape (n,)
            Sample times, s.

        Returns
        -------
        ndarray, shape (2, n)
            Row 0 the axial reference, m/s; row 1 the angular reference, rad/s.

        Raises
        ------
        DownholeInputError
            If a signal cannot be evaluated, has the wrong shape or non-finite values.
        """
        from downhole.sim.inputs import sample_signal

        t = np.asarray(t, float)
        return np.vstack([sample_signal(self.axial, t, "reference axial"),
                          sample_signal(self.angular, t, "reference angular")])


def constant_reference(rop: float = 0.01, omega: float = 20.0) -> Reference:
    """Constant reference; default the seed's r' = [10 mm/s, 20 rad/s] (Sec. 3.5).

    Parameters
    ----------
    rop : float, optional
        Bit axial velocity (rate of penetration), m/s (default 0.01).
    omega : float, optional
        Bit angular velocity, rad/s (default 20).

    Returns
    -------
    Reference
    """
    return Reference(float(rop), float(omega), "constant")


def eq_3_34(t, v: float = 0.005):
    """Axial reference of Eq. 3.34: 3 v + 0.5 v sin(pi t / 20), m/s.

    Parameters
    ----------
    t : array_like
        Times, s.
    v : float, optional
        Velocity scale v, m/s (default 0.005).

    Returns
    -------
    ndarray
        Reference bit axial velocity, m/s, shaped like ``t``.
    """
    t = np.asarray(t, float)
    return 3 * v + 0.5 * v * np.sin(np.pi * t / 20.0)


def eq_3_35(t, omega: float = 20.0):
    """Torsional multi-ramp of Eq. 3.35, rad/s.

    0 -> w over 30 s, w, ramp to 2 w, 2 w, ramp back to w, w (breakpoints every 30 s up to
    150 s).

    Parameters
    ----------
    t : array_like
        Times, s.
    omega : float, optional
        Base angular velocity w, rad/s (default 20).

    Returns
    -------
    ndarray
        Reference bit angular velocity, rad/s, shaped like ``t``.
    """
    t = np.asarray(t, float)
    w = omega
    return np.piecewise(
        t, [t < 30, (t >= 30) & (t < 60), (t >= 60) & (t < 90), (t >= 90) & (t < 120),
            (t >= 120) & (t < 150), t >= 150],
        [lambda s: w * s / 30, w, lambda s: w * s / 30 - w, 2 * w, lambda s: -w * s / 30 + 6 * w,
         w])


def seed_tracking_reference(v: float = 0.005, omega: float = 20.0,
                            max_depth_of_cut: float | None = 6e-3) -> Reference:
    """Eqs. 3.34 (sinusoid, axial) and 3.35 (multi-ramp, torsional), v = 5 mm/s, w = 20 rad/s.

    Eq. 3.35 starts the rotation at 0 rad/s while Eq. 3.34 asks for 15 mm/s from t = 0: drilling
    without rotation is impossible (the bit stalls and the integrators wind up). With
    ``max_depth_of_cut`` the axial reference is limited to
    ``max_depth_of_cut * omega_ref / (2 pi)``; it is inactive once omega_ref >= 20 rad/s.

    Parameters
    ----------
    v : float, optional
        Velocity scale of Eq. 3.34, m/s (default 0.005).
    omega : float, optional
        Base angular velocity of Eq. 3.35, rad/s (default 20).
    max_depth_of_cut : float or None, optional
        Largest depth of cut the axial reference may ask for, m per revolution (default 6e-3);
        ``None`` gives the printed pair.

    Returns
    -------
    Reference
    """
    if max_depth_of_cut is None:
        return Reference(lambda t: eq_3_34(t, v), lambda t: eq_3_35(t, omega), "eq3.34-3.35")
    dmax = float(max_depth_of_cut)
    return Reference(
        lambda t: np.minimum(eq_3_34(t, v), dmax * eq_3_35(t, omega) / (2 * np.pi)),
        lambda t: eq_3_35(t, omega), "eq3.34-3.35-limited")


def user_reference(axial, angular) -> Reference:
    """User-defined reference from numbers, ``(t, values)`` samples or callables.

    Parameters
    ----------
    axial : float, tuple or callable
        Axial reference, m/s: a number, a ``(times, values)`` pair of 1-D arrays (times in s,
        non-decreasing; linear interpolation) or a callable ``f(t)``.
    angular : float, tuple or callable
        Angular reference, rad/s, of the same forms.

    Returns
    -------
    Reference
        Named ``"user"`` (signals are checked when sampled).
    """
    return Reference(axial, angular, "user")


def as_reference(ref) -> Reference:
    """Coerce ``ref`` (Reference, pair of signals, or None) to a :class:`Reference`.

    Parameters
    ----------
    ref : Reference, tuple or None
        A Reference; a pair ``(axial, angular)`` of signals (m/s, rad/s) as
        :func:`user_reference`; or None for :func:`constant_reference` with its defaults.

    Returns
    -------
    Reference

    Raises
    ------
    DownholeInputError
        If ``ref`` is neither a Reference nor a pair.
    """
    if ref is None:
        return constant_reference()
    if isinstance(ref, Reference):
        return ref
    try:
        a, w = ref
    except (TypeError, ValueError):
        raise DownholeInputError(f"reference must be a Reference or a pair (axial, angular), "
                                 f"got {ref!r}") from None
    return Reference(a, w, "user")
