"""Wellbore contact: soft-string (Johancsik) normal force and regularized Coulomb friction.

Per unit length the wall reaction of a string under effective tension T (positive in tension)
along a path with curvature vector dt/ds is N = |T dt/ds + w g_perp|, with w the buoyed weight per
length and g_perp the part of the downward unit vector normal to the tangent. In inclination /
azimuth terms this is Johancsik's N = sqrt((T theta' - w sin theta)^2 + (T sin theta phi')^2).
Friction mu N acts against the sliding velocity (axial v, circumferential r omega) with the
regularized direction v / sqrt(|v|^2 + v_eps^2). Kernels apply it as a frozen-coefficient damper
c = mu N / sqrt(v^2 + (r omega)^2 + v_eps^2) on the new velocities, which is dissipative and
therefore stable for any v_eps. The torque arm r is the pipe's outer radius (not the wellbore
radius of seed Eq. 4.7).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

__all__ = ["normal_force_per_length", "friction_damper", "friction_forces",
           "soft_string_normal_force"]


@njit(cache=True)
def normal_force_per_length(tension, kx, ky, kz, gx, gy, gz):
    """|T dt/ds + w g_perp| for one element, N/m (``k*`` = dt/ds, ``g*`` = w g_perp)."""
    x = tension * kx + gx
    y = tension * ky + gy
    z = tension * kz + gz
    return math.sqrt(x * x + y * y + z * z)


@njit(cache=True)
def friction_damper(normal_force, mu, v, r_omega, v_eps):
    """Frozen friction coefficient c = mu N / sqrt(v^2 + (r omega)^2 + v_eps^2), N s/m."""
    return mu * normal_force / math.sqrt(v * v + r_omega * r_omega + v_eps * v_eps)


@njit(cache=True)
def friction_forces(normal_force, mu, v, omega, radius, v_eps):
    """Axial friction force (N) and torque (N m) opposing (v, r omega), regularized."""
    c = friction_damper(normal_force, mu, v, radius * omega, v_eps)
    return -c * v, -c * radius * radius * omega


def soft_string_normal_force(tension, curvature_vector, weight_per_length, tangent):
    """Soft-string normal force per unit length (N/m), vectorised over elements.

    Parameters
    ----------
    tension : array_like, shape (m,)
        Effective tension, N (positive in tension).
    curvature_vector : array_like, shape (m, 3)
        dt/ds (north, east, down), 1/m, e.g. :meth:`WellPath.curvature_vector`.
    weight_per_length : array_like, shape (m,)
        Buoyed weight per length, N/m.
    tangent : array_like, shape (m, 3)
        Unit tangent (north, east, down).

    Returns
    -------
    ndarray, shape (m,)

    Examples
    --------
    >>> import numpy as np
    >>> t = np.array([[1.0, 0.0, 0.0]])          # horizontal, no curvature: N = w
    >>> float(soft_string_normal_force([1e5], np.zeros((1, 3)), [300.0], t)[0])
    300.0
    """
    T = np.asarray(tension, float)[:, None]
    k = np.asarray(curvature_vector, float)
    t = np.asarray(tangent, float)
    w = np.asarray(weight_per_length, float)[:, None]
    down = np.array([0.0, 0.0, 1.0])
    gperp = down - (t @ down)[:, None] * t
    return np.linalg.norm(T * k + w * gperp, axis=1)
