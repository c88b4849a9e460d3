r"""Sparse symmetric eigenproblems of a Laplacian: :math:`L\phi = \lambda M\phi`.

One solver for every place that needs the low end of a mesh's Laplace-Beltrami spectrum (the
heat diffusion metric, the dense maps' bases, the spectral signatures): shift-invert Lanczos
(ARPACK: Lehoucq, Sorensen & Yang, *ARPACK Users' Guide*, SIAM 1998) about a shift just below
the spectrum, the operator :math:`(L - \sigma M)^{-1}` applied with a sparse Cholesky factor
(CHOLMOD's supernodal factorisation: Chen, Davis, Hager & Rajamanickam, ACM TOMS 35(3), 2008;
through ``cholespy``) where that package is installed, else with SuperLU.
"""

from __future__ import annotations

import numpy as np

from ._arrays import one_blas_thread


def spd_solver(a, method: str = "auto"):
    """``(solve, name)``: ``solve(b)`` = :math:`a^{-1} b` for a sparse symmetric positive
    definite ``a``, by CHOLMOD (``cholespy``; ``method`` "auto" where installed and ``a``
    factors, or "cholmod") or by SuperLU ("superlu", and "auto" otherwise)."""
    import scipy.sparse as sp

    if method not in ("auto", "cholmod", "superlu"):
        raise ValueError(f"method must be 'auto', 'cholmod' or 'superlu', got {method!r}")
    a = sp.csr_matrix(a, dtype=np.float64)
    cholespy = None
    if method != "superlu":
        try:
            import cholespy
        except ImportError:
            if method == "cholmod":
                raise ImportError("the CHOLMOD factorisation needs cholespy: pip install cholespy") from None
    if cholespy is not None:
        a.sort_indices()
        try:
            chol = cholespy.CholeskySolverD(a.shape[0], a.indptr.astype(np.int32), a.indices.astype(np.int32),
                                            np.ascontiguousarray(a.data), cholespy.MatrixType.CSR)
        except ValueError:   # not positive definite (a degenerate mesh): the LU below
            if method == "cholmod":
                raise
            chol = None
        if chol is not None:
            def solve(b):
                b = np.ascontiguousarray(b, dtype=np.float64)
                x = np.empty_like(b)
                chol.solve(b, x)
                return x
            return solve, "cholmod"
    from scipy.sparse.linalg import splu

    return splu(a.tocsc()).solve, "superlu"


def shift_invert_eigsh(L, M, k: int, *, sigma: float, method: str = "auto"):
    r"""``(eigenvalues (k,), eigenvectors (n, k))``: ARPACK's ``k`` eigenpairs of
    :math:`L\phi = \lambda M\phi` nearest ``sigma`` (< 0, below the spectrum of the positive
    semi-definite ``L``), as ``scipy.sparse.linalg.eigsh(L, k, M, sigma)`` computes them, with
    :func:`spd_solver` (``method``) for the shift-invert operator, a Krylov space of
    :math:`\lfloor 3k/2 \rfloor + 1` vectors (at least 20) and a fixed start vector: the same
    eigenpairs on every run. BLAS runs on one thread."""
    from scipy.sparse.linalg import LinearOperator, eigsh

    n = L.shape[0]
    solve, _ = spd_solver(L - sigma * M, method)
    op = LinearOperator((n, n), matvec=lambda x: solve(np.ravel(x)), dtype=np.float64)
    v0 = np.full(n, 1.0 / np.sqrt(n))
    # Lanczos makes many small, memory-bound BLAS calls: threads only add overhead there, and
    # next to another busy process they slow it several times
    with one_blas_thread():
        return eigsh(L, k=k, M=M, sigma=sigma, which="LM", v0=v0, OPinv=op,
                     ncv=min(n, max(k + k // 2 + 1, 20)))
