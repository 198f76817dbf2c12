"""BLAS/LAPACK routines called directly from compiled (numba) kernels.

Numba's ``np.dot`` reaches BLAS gemm, and ``np.linalg.cholesky`` reaches LAPACK potrf through
a copy and a transpose; neither gives the symmetric rank-k update or the triangular solves the
DHP trainer's per-step least-squares fit is made of. This module links SciPy's own
``cython_blas`` / ``cython_lapack`` entry points (the same OpenBLAS that NumPy and numba use, so
``threadpoolctl`` limits apply to them too) under ``downhole_*`` symbol names and declares them
as external functions of the compiled code. The symbols are resolved when a kernel is loaded,
not baked into it, so kernels that call them stay cacheable (``@njit(cache=True)``); importing
this module (which every user does through its import chain) registers the symbols before any
cached kernel is loaded.

Conventions: arrays are C-ordered, so a C array (r, c) is a Fortran array (c, r). A symmetric
matrix is held in the *upper* triangle of a C array (Fortran's lower), and its Cholesky factor
as the upper C factor U with G = U^T U (:func:`chol_solve_right`). The lower C triangle is left as scratch.
"""

from __future__ import annotations

import llvmlite.binding as llvm
import numpy as np
from numba import njit, types
from numba.extending import get_cython_function_address

__all__ = ["chol_solve_right", "potrf_upper", "syrk_gram"]


def _register(module: str, name: str) -> str:
    symbol = "downhole_" + name
    llvm.add_symbol(symbol, get_cython_function_address(module, name))
    return symbol


_vp = types.voidptr
_dsyrk = types.ExternalFunction(_register("scipy.linalg.cython_blas", "dsyrk"),
                                types.void(*([_vp] * 10)))
_dtrsm = types.ExternalFunction(_register("scipy.linalg.cython_blas", "dtrsm"),
                                types.void(*([_vp] * 11)))
_dpotrf = types.ExternalFunction(_register("scipy.linalg.cython_lapack", "dpotrf"),
                                 types.void(*([_vp] * 5)))

_L, _R, _T, _N = ord("L"), ord("R"), ord("T"), ord("N")


@njit(cache=True, nogil=True)
def syrk_gram(At, G):
    """Upper C triangle of G = At At^T by BLAS dsyrk; half the multiply-adds of the full product.

    Parameters
    ----------
    At : ndarray, shape (p, k), float64, C-contiguous
        The factor.
    G : ndarray, shape (p, p), float64, C-contiguous
        Output; its upper triangle (row <= column) is overwritten with At At^T, the strict lower
        triangle is left as it was.
    """
    p, k = At.shape
    ch = np.empty(2, dtype=np.uint8)
    ch[0] = _L
    ch[1] = _T
    iv = np.empty(4, dtype=np.int32)
    iv[0] = p
    iv[1] = k
    iv[2] = k
    iv[3] = p
    dv = np.empty(2)
    dv[0] = 1.0
    dv[1] = 0.0
    # Fortran view: A = At^T (k x p, lda = k), C = A^T A, lower = the C upper triangle
    _dsyrk(ch[0:].ctypes, ch[1:].ctypes, iv[0:].ctypes, iv[1:].ctypes, dv[0:].ctypes,
           At.ctypes, iv[2:].ctypes, dv[1:].ctypes, G.ctypes, iv[3:].ctypes)


@njit(cache=True, nogil=True)
def potrf_upper(G):
    """In place: the upper C triangle of G -> its upper Cholesky factor U, G = U^T U (dpotrf).

    Parameters
    ----------
    G : ndarray, shape (p, p), float64, C-contiguous
        Symmetric positive definite matrix given by its upper triangle; overwritten with U
        (the strict lower triangle is not referenced).

    Returns
    -------
    int
        LAPACK's info: 0 ok, > 0 not positive definite; -1 for a non-positive or non-finite
        diagonal (checked first, ``G`` untouched).
    """
    p = G.shape[0]
    for j in range(p):
        if not (G[j, j] > 0.0 and G[j, j] < np.inf):
            return -1
    ch = np.empty(1, dtype=np.uint8)
    ch[0] = _L
    iv = np.empty(3, dtype=np.int32)
    iv[0] = p
    iv[1] = p
    iv[2] = 0
    _dpotrf(ch.ctypes, iv[0:].ctypes, G.ctypes, iv[1:].ctypes, iv[2:].ctypes)
    return iv[2]


@njit(cache=True, nogil=True)
def chol_solve_right(U, B):
    """In place: B (p, q) <- (U^T U)^-1 B for the upper C factor U of :func:`potrf_upper`.

    Two BLAS dtrsm; in Fortran terms B^T <- B^T L^-T L^-1 with L = U^T.

    Parameters
    ----------
    U : ndarray, shape (p, p), float64, C-contiguous
        Upper Cholesky factor from :func:`potrf_upper`.
    B : ndarray, shape (p, q), float64, C-contiguous
        Right-hand sides, overwritten with the solution.
    """
    p = U.shape[0]
    q = B.shape[1]
    ch = np.empty(4, dtype=np.uint8)
    ch[0] = _R
    ch[1] = _L
    ch[2] = _T
    ch[3] = _N
    iv = np.empty(4, dtype=np.int32)
    iv[0] = q
    iv[1] = p
    iv[2] = p
    iv[3] = q
    dv = np.ones(1)
    _dtrsm(ch[0:].ctypes, ch[1:].ctypes, ch[2:].ctypes, ch[3:].ctypes, iv[0:].ctypes,
           iv[1:].ctypes, dv.ctypes, U.ctypes, iv[2:].ctypes, B.ctypes, iv[3:].ctypes)
    ch[2] = _N
    _dtrsm(ch[0:].ctypes, ch[1:].ctypes, ch[2:].ctypes, ch[3:].ctypes, iv[0:].ctypes,
           iv[1:].ctypes, dv.ctypes, U.ctypes, iv[2:].ctypes, B.ctypes, iv[3:].ctypes)
