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
from dataclasses import dataclass, field

import numpy as np

from downhole.errors import DownholeInputError

__all__ = ["StateSpace", "zoh"]


@dataclass(frozen=True, eq=False)
class StateSpace:
    """A discrete-time linear model ``x[k+1] = A x[k] + B u[k]``, ``y[k] = C x[k] + D u[k]``
    with named states, inputs and outputs, and its step ``dt`` (s).

    It unpacks like the ``(A, B)`` pair that ``linear_model`` used to return
    (``A_d, B_d = model.linear_model(dt)`` keeps working; ``ss[0]``, ``ss[1]``, ``len(ss) == 2``
    as well). :meth:`to_control` gives a python-control ``StateSpace`` when the optional
    ``control`` package is installed.
    """

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    dt: float
    state_names: tuple[str, ...] = field(default=())
    input_names: tuple[str, ...] = field(default=())
    output_names: tuple[str, ...] = field(default=())

    def __post_init__(self):
        n, m = self.A.shape[0], self.B.shape[1]
        p = self.C.shape[0]
        if self.A.shape != (n, n) or self.B.shape[0] != n or self.C.shape != (p, n) \
                or self.D.shape != (p, m):
            raise DownholeInputError(
                f"StateSpace: inconsistent shapes A {self.A.shape}, B {self.B.shape}, "
                f"C {self.C.shape}, D {self.D.shape}")
        for attr, size in (("state_names", n), ("input_names", m), ("output_names", p)):
            names = tuple(getattr(self, attr))
            if names and len(names) != size:
                raise DownholeInputError(f"StateSpace: {attr} has {len(names)} names, "
                                         f"expected {size}")
            object.__setattr__(self, attr, names)

    @classmethod
    def full_state(cls, A, B, dt: float, state_names=(), input_names=()) -> StateSpace:
        """The model whose output is the whole state: ``C = I``, ``D = 0``, outputs named as
        the states."""
        A = np.asarray(A, float)
        B = np.asarray(B, float)
        n, m = A.shape[0], B.shape[1]
        return cls(A, B, np.eye(n), np.zeros((n, m)), float(dt), tuple(state_names),
                   tuple(input_names), tuple(state_names))

    @property
    def n_states(self) -> int:
        return self.A.shape[0]

    @property
    def n_inputs(self) -> int:
        return self.B.shape[1]

    @property
    def n_outputs(self) -> int:
        return self.C.shape[0]

    # --- the old (A, B) tuple ------------------------------------------------------------------
    def __iter__(self):
        return iter((self.A, self.B))

    def __len__(self) -> int:
        return 2

    def __getitem__(self, i):
        return (self.A, self.B)[i]

    def to_control(self):
        """This model as :func:`control.ss` (python-control, optional: ``pip install control``)
        with the step ``dt`` and the state, input and output names."""
        try:
            import control
        except ImportError:
            raise ImportError("StateSpace.to_control needs python-control: "
                              "pip install control") from None
        kw = {}
        if self.state_names:
            kw["states"] = list(self.state_names)
        if self.input_names:
            kw["inputs"] = list(self.input_names)
        if self.output_names:
            kw["outputs"] = list(self.output_names)
        return control.ss(self.A, self.B, self.C, self.D, self.dt, **kw)

    def __repr__(self) -> str:
        return (f"StateSpace({self.n_states} states, {self.n_inputs} inputs "
                f"{list(self.input_names)}, {self.n_outputs} outputs, dt={self.dt:g} s)")


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
