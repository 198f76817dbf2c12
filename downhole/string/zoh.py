"""Exact zero-order-hold (ZOH) discretization of a linear time-invariant model.

For ``x' = A x + B u`` with ``u`` held constant over a step ``dt``::

    x_{k+1} = A_d x_k + B_d u_k,    A_d = e^{A dt},    B_d = int_0^dt e^{A s} ds B,

both read off the matrix exponential of the augmented matrix (Van Loan 1978)::

    expm([[A, B], [0, 0]] dt) = [[A_d, B_d], [0, I]].

This is the one place in the package that discretizes a linear model: the directional FEM's
linear and control-affine design models (:mod:`downhole.string.fem`), the lumped DHP design
model, the DHP directional exporter and the hardware-in-the-loop string plant all call
:func:`zoh`. With ``gamma=True`` it also returns the input integral
``Gamma = int_0^dt e^{A s} ds`` (n, n), the ZOH map of an arbitrary held term added to ``x'``.
"""

from __future__ import annotations

import math

import numpy as np

from downhole.errors import DownholeInputError

__all__ = ["zoh"]


def zoh(A, B, dt: float, *, gamma: bool = False):
    """Exact zero-order-hold discretization ``(A_d, B_d)`` of ``x' = A x + B u``.

    Parameters
    ----------
    A : array_like, shape (n, n)
        Continuous-time state matrix.
    B : array_like, shape (n, m)
        Continuous-time input matrix (``m`` may be 0).
    dt : float
        Step, s (> 0, finite).
    gamma : bool
        Also return ``Gamma = int_0^dt e^{A s} ds`` (n, n), so that ``B_d = Gamma @ B``.

    Returns
    -------
    A_d : ndarray, shape (n, n)
        ``e^{A dt}``.
    B_d : ndarray, shape (n, m)
        ``int_0^dt e^{A s} ds B``.
    Gamma : ndarray, shape (n, n)
        Only with ``gamma=True``.

    Raises
    ------
    DownholeInputError
        If the shapes do not match, an entry is not finite or ``dt`` is not a positive finite
        number.

    Examples
    --------
    >>> import numpy as np
    >>> A_d, B_d = zoh([[0.0]], [[1.0]], 0.5)      # an integrator: x += dt u
    >>> float(A_d[0, 0]), float(B_d[0, 0])
    (1.0, 0.5)
    """
    from scipy.linalg import expm

    try:
        step = float(dt)
    except (TypeError, ValueError):
        raise DownholeInputError(f"zoh: dt must be a number of seconds, got {dt!r}") from None
    if not (math.isfinite(step) and step > 0.0):
        raise DownholeInputError(f"zoh: dt must be > 0 s and finite, got {dt!r}")
    A = np.asarray(A, dtype=float)
    B = np.asarray(B, dtype=float)
    if A.ndim != 2 or A.shape[0] != A.shape[1] or A.shape[0] == 0:
        raise DownholeInputError(f"zoh: A must be a non-empty square matrix, got shape {A.shape}")
    n = A.shape[0]
    if B.ndim == 1 and B.size == n:
        B = B[:, None]
    if B.ndim != 2 or B.shape[0] != n:
        raise DownholeInputError(f"zoh: B must have shape ({n}, m) to match A, got {B.shape}")
    if not (np.all(np.isfinite(A)) and np.all(np.isfinite(B))):
        raise DownholeInputError("zoh: A and B must be finite")
    m = B.shape[1]
    if gamma:
        # one exponential gives both: [[A, B, I], 0] -> the B_d block and the Gamma block
        aug = np.zeros((n + m + n, n + m + n))
        aug[:n, :n] = A
        aug[:n, n:n + m] = B
        aug[:n, n + m:] = np.eye(n)
        E = expm(aug * step)
        return E[:n, :n], E[:n, n:n + m], E[:n, n + m:]
    aug = np.zeros((n + m, n + m))
    aug[:n, :n] = A
    aug[:n, n:] = B
    E = expm(aug * step)
    return E[:n, :n], E[:n, n:]
