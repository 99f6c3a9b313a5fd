"""The Hodrick-Prescott filter, solved for many series at once.

The HP trend tau of a series y minimises ||y - tau||^2 + lambda ||D tau||^2 with D the
second-difference operator, i.e. (I + lambda D'D) tau = y. The matrix is symmetric,
positive definite and pentadiagonal, so one banded Cholesky solve (scipy
``solveh_banded``) handles every joint coordinate of a clip together, instead of one
sparse solve per series (``statsmodels.tsa.filters.hp_filter.hpfilter``, the reference).
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import solveh_banded


def hp_banded(n: int, lamb: float) -> np.ndarray:
    """Upper banded form (3 x n) of I + lambda D'D for ``solveh_banded``."""
    main = np.full(n, 1.0 + 6.0 * lamb)
    main[[0, -1]] = 1.0 + lamb
    main[[1, -2]] = 1.0 + 5.0 * lamb
    first = np.full(n - 1, -4.0 * lamb)
    first[[0, -1]] = -2.0 * lamb
    second = np.full(n - 2, lamb)
    ab = np.zeros((3, n))
    ab[0, 2:] = second
    ab[1, 1:] = first
    ab[2, :] = main
    return ab


def hp_trend(series: np.ndarray, lamb: float = 1.0) -> np.ndarray:
    """HP trend along axis 0 of ``series`` (T x ...), every other axis a separate series."""
    y = np.asarray(series, dtype=np.float64)
    n = y.shape[0]
    if n < 3 or lamb == 0:
        return y.copy()
    if n == 3:  # the band formulas above assume n >= 4
        d = np.array([[1.0, -2.0, 1.0]])
        return np.linalg.solve(np.eye(3) + lamb * d.T @ d, y.reshape(3, -1)).reshape(y.shape)
    flat = y.reshape(n, -1)
    return solveh_banded(hp_banded(n, lamb), flat, check_finite=False).reshape(y.shape)
