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

This module is the package's only soft-string contact code. Element data use the layout of
``DirectionalModel.elem`` (:data:`ELEM_LAYOUT`): per element its length, dt/ds (3), w g_perp (3)
and a contact flag; each element gives half its normal force ``L N`` to each end node.

* compiled (numba, called from the FEM/hybrid kernel and the DHP directional exporter):
  :func:`normal_force_per_length`, :func:`element_normal_half`, :func:`friction_damper`,
  :func:`friction_forces`, :func:`contact_elements`;
* NumPy (model assembly, design exporters, reference ODEs): :func:`normal_weight`,
  :func:`soft_string_normal_force`, :func:`nodal_friction_forces`.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from downhole.errors import DownholeInputError

__all__ = [
    "ELEM_LAYOUT",
    "contact_elements",
    "contact_elements_into",
    "element_normal_half",
    "friction_damper",
    "friction_forces",
    "nodal_friction_forces",
    "normal_force_per_length",
    "normal_weight",
    "soft_string_normal_force",
]

#: Columns of the per-element contact array (``DirectionalModel.elem``).
ELEM_LAYOUT = ("length", "dtds_north", "dtds_east", "dtds_down", "wg_north", "wg_east", "wg_down",
               "contact")

_DOWN = np.array([0.0, 0.0, 1.0])


@njit(cache=True)
def normal_force_per_length(tension, kx, ky, kz, gx, gy, gz):
    """|T dt/ds + w g_perp| for one element, N/m.

    Parameters
    ----------
    tension : float
        Effective tension T, N (positive in tension).
    kx, ky, kz : float
        Curvature vector dt/ds (north, east, down), 1/m.
    gx, gy, gz : float
        Normal weight w g_perp (north, east, down), N/m.

    Returns
    -------
    float
        Soft-string normal force per unit length, N/m.
    """
    x = tension * kx + gx
    y = tension * ky + gy
    z = tension * kz + gz
    return math.sqrt(x * x + y * y + z * z)


@njit(cache=True)
def element_normal_half(elem, e, tension):
    """Half the soft-string normal force of element ``e``, ``0.5 L |T dt/ds + w g_perp|`` (N).

    The share of each of its two end nodes (the contact flag of the element is not applied
    here).

    Parameters
    ----------
    elem : ndarray, shape (n, 8)
        Element data, columns :data:`ELEM_LAYOUT` (length m, dt/ds 1/m, w g_perp N/m, contact
        flag).
    e : int
        Element index.
    tension : float
        Effective tension of the element, N (positive in tension).

    Returns
    -------
    float
        Half the element's normal force, N.
    """
    return 0.5 * elem[e, 0] * normal_force_per_length(tension, elem[e, 1], elem[e, 2],
                                                      elem[e, 3], elem[e, 4], elem[e, 5],
                                                      elem[e, 6])


@njit(cache=True)
def contact_elements_into(elem, out):
    """Write the indices of the elements whose normal force can be non-zero into ``out``.

    An element takes part when its contact flag is set and it is curved or not vertical; a
    straight vertical element has zero curvature and zero normal weight, so its soft-string
    normal force is exactly 0 whatever the tension, and the kernels skip it. The last row of
    ``elem`` (one per node) is never an element.

    Parameters
    ----------
    elem : ndarray, shape (n, 8)
        Element data, columns :data:`ELEM_LAYOUT`.
    out : ndarray of int64, shape (>= n - 1,)
        Receives the element indices, ascending.

    Returns
    -------
    int
        Number of indices written.
    """
    k = 0
    for e in range(elem.shape[0] - 1):
        if elem[e, 7] > 0.5 and (elem[e, 1] != 0.0 or elem[e, 2] != 0.0 or elem[e, 3] != 0.0
                                 or elem[e, 4] != 0.0 or elem[e, 5] != 0.0
                                 or elem[e, 6] != 0.0):
            out[k] = e
            k += 1
    return k


@njit(cache=True)
def contact_elements(elem):
    """Indices (int64) of the elements whose normal force can be non-zero (see
    :func:`contact_elements_into`).

    Parameters
    ----------
    elem : ndarray, shape (n, 8)
        Element data, columns :data:`ELEM_LAYOUT`.

    Returns
    -------
    ndarray of int64
        Element indices, ascending.
    """
    out = np.empty(max(elem.shape[0] - 1, 0), np.int64)
    return out[:contact_elements_into(elem, out)]


@njit(cache=True)
def friction_damper(normal_force, mu, v, r_omega, v_eps):
    """Frozen friction coefficient c = mu N / sqrt(v^2 + (r omega)^2 + v_eps^2), N s/m.

    Parameters
    ----------
    normal_force : float
        Normal force N, N.
    mu : float
        Friction coefficient (dimensionless).
    v : float
        Axial velocity, m/s.
    r_omega : float
        Circumferential velocity r omega, m/s.
    v_eps : float
        Regularization velocity, m/s (> 0).

    Returns
    -------
    float
        The damper coefficient c, N s/m.
    """
    return mu * normal_force / math.sqrt(v * v + r_omega * r_omega + v_eps * v_eps)


@njit(cache=True)
def friction_forces(normal_force, mu, v, omega, radius, v_eps):
    """Axial friction force (N) and torque (N m) opposing (v, r omega), regularized.

    Parameters
    ----------
    normal_force, mu, v
        As :func:`friction_damper`.
    omega : float
        Angular velocity, rad/s.
    radius : float
        Torque arm r, m.
    v_eps : float
        Regularization velocity, m/s (> 0).

    Returns
    -------
    (force, torque) : tuple of float
        ``(-c v, -c r^2 omega)``: N and N m, with c from :func:`friction_damper`.
    """
    c = friction_damper(normal_force, mu, v, radius * omega, v_eps)
    return -c * v, -c * radius * radius * omega


def normal_weight(tangent, weight_per_length):
    """Part of the buoyed weight normal to the string, ``w g_perp`` (N/m), per element.

    Parameters
    ----------
    tangent : array_like, shape (m, 3)
        Unit tangent (north, east, down).
    weight_per_length : array_like, shape (m,)
        Buoyed weight per length, N/m.

    Returns
    -------
    ndarray, shape (m, 3)
        ``w (e_down - (t . e_down) t)``.
    """
    t = np.asarray(tangent, float)
    w = np.asarray(weight_per_length, float)
    gperp = _DOWN[None, :] - (t @ _DOWN)[:, None] * t
    return w[:, None] * gperp


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
    return np.linalg.norm(T * k + normal_weight(tangent, weight_per_length), axis=1)


def nodal_friction_forces(tension, elem, radius, mu, v_axial, v_angular, v_eps):
    """Wellbore friction on every node (NumPy, vectorised over a leading batch of states).

    Each element's normal force ``L |T dt/ds + w g_perp|`` is shared equally by its end nodes;
    at node i the regularized Coulomb friction is ``-c (v_i, r_i^2 omega_i)`` with
    ``c = mu N_i / sqrt(v_i^2 + (r_i omega_i)^2 + v_eps^2)`` (the same law as the compiled
    :func:`friction_damper`, evaluated explicitly).

    Parameters
    ----------
    tension : array_like, shape (..., n - 1)
        Effective tension per element, N (positive in tension).
    elem : ndarray, shape (n, 8)
        Element data, :data:`ELEM_LAYOUT` (rows beyond ``n - 1`` are ignored).
    radius : array_like, shape (n,)
        Torque arm per node, m.
    mu : float
        Friction coefficient.
    v_axial, v_angular : array_like, shape (..., n)
        Nodal axial (m/s) and angular (rad/s) velocities.
    v_eps : float
        Regularization velocity, m/s (> 0).

    Returns
    -------
    force : ndarray, shape (..., n)
        Axial friction force, N.
    torque : ndarray, shape (..., n)
        Friction torque, N m.

    Raises
    ------
    DownholeInputError
        If the shapes do not fit together or ``v_eps`` is not positive.
    """
    T = np.asarray(tension, float)
    elem = np.asarray(elem, float)
    vax = np.asarray(v_axial, float)
    vtr = np.asarray(v_angular, float)
    r = np.asarray(radius, float)
    m = T.shape[-1] if T.ndim else 0
    if T.ndim == 0 or elem.ndim != 2 or elem.shape[1] != 8 or elem.shape[0] < m + 1:
        raise DownholeInputError(
            f"nodal_friction_forces: tension (..., n - 1) and elem (n, 8) expected, got tension "
            f"{T.shape} and elem {elem.shape}")
    if vax.shape[-1:] != (m + 1,) or vtr.shape[-1:] != (m + 1,) or r.shape != (m + 1,):
        raise DownholeInputError(
            f"nodal_friction_forces: velocities (..., {m + 1}) and radius ({m + 1},) expected "
            f"for {m} elements, got {vax.shape}, {vtr.shape} and {r.shape}")
    if not (float(v_eps) > 0.0 and math.isfinite(float(v_eps))):
        raise DownholeInputError(f"nodal_friction_forces: v_eps must be > 0 m/s, got {v_eps!r}")
    Nl = np.linalg.norm(T[..., None] * elem[:m, 1:4] + elem[:m, 4:7], axis=-1)
    Nl *= elem[:m, 7] * elem[:m, 0] * 0.5
    Nn = np.zeros(T.shape[:-1] + (m + 1,))
    Nn[..., :-1] += Nl
    Nn[..., 1:] += Nl
    c = mu * Nn / np.sqrt(vax**2 + (r * vtr) ** 2 + v_eps**2)
    return -(c * vax), -(c * r**2 * vtr)
