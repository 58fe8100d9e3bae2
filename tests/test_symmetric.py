"""Symmetric helpers: mirrored upper triangles and the 3x3 smallest eigenvalue."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.linalg import blas, lapack

from snake_pin._symmetric import smallest_eigenvalue_3x3, symmetric_from_upper


def _upper_gram(rng: np.random.Generator, kind: str) -> np.ndarray:
    """An upper triangle of a 3x3 Gram matrix H12 H12^T (dsyrk, as PFL makes it), or of a
    matrix with chosen eigenvalues, of the given kind."""
    if kind in ("double_bottom", "double_top", "exact_double", "two_small"):
        q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
        lams = np.sort(rng.uniform(0.1, 10.0, 3))
        if kind == "double_top":
            lams[2] = lams[1] * (1 + 1e-9 * rng.uniform())
        elif kind == "two_small":  # near a singular posture: two small, one large
            lams[:2] = np.sort(10.0 ** rng.uniform(-9, -2, 2))
        else:
            lams[1] = lams[0] * (1 + (0.0 if kind == "exact_double" else 1e-9 * rng.uniform()))
        return np.triu(q @ np.diag(lams) @ q.T)
    h12 = rng.normal(size=(3, 9))
    if kind == "near_singular":
        h12[2] = h12[1] * (1 + 1e-7 * rng.normal()) + 1e-9 * rng.normal(size=9)
    elif kind == "scaled":
        h12 *= 10.0 ** rng.uniform(-5, 5)
    return blas.dsyrk(1.0, np.asfortranarray(h12))


@pytest.mark.parametrize("kind", ["random", "near_singular", "scaled", "double_bottom",
                                  "double_top", "exact_double", "two_small"])
def test_smallest_eigenvalue_3x3_against_lapack(kind: str, rng: np.random.Generator) -> None:
    """The closed form (or LAPACK where it would lose digits) is numpy's eigvalsh to 1e-13
    of the largest eigenvalue (without the fallback near-double bottoms were 7e-9 off), and
    LAPACK's own dsyev below 1e-6 of it (near-singular postures: R's check as before),
    whatever the strict lower triangle holds (PFL's buffer keeps a Cholesky factor there)."""
    lower = np.tril_indices(3, -1)
    for _ in range(500):
        upper = _upper_gram(rng, kind)
        expected = np.linalg.eigvalsh(symmetric_from_upper(upper))
        smallest = smallest_eigenvalue_3x3(upper)
        stale = upper.copy(order="F")
        stale[lower] = 1e3 * rng.normal(size=3)
        assert smallest_eigenvalue_3x3(stale) == smallest
        assert abs(smallest - expected[0]) <= 1e-13 * expected[-1]
        if expected[0] < 0.5e-6 * expected[-1]:
            assert smallest == lapack.dsyev(upper, compute_v=0)[0][0]


def test_smallest_eigenvalue_3x3_special_matrices() -> None:
    """Multiples of I, exact double roots at either end, and NaN entries."""
    assert smallest_eigenvalue_3x3(2.0 * np.eye(3)) == 2.0
    assert smallest_eigenvalue_3x3(np.diag([1.0, 1.0, 3.0])) == pytest.approx(1.0, abs=1e-15)
    assert smallest_eigenvalue_3x3(np.diag([1.0, 3.0, 3.0])) == pytest.approx(1.0, abs=1e-15)
    assert smallest_eigenvalue_3x3(np.zeros((3, 3))) == 0.0
    assert np.isnan(smallest_eigenvalue_3x3(np.full((3, 3), np.nan)))
    # spreads too small for p^3: LAPACK
    assert smallest_eigenvalue_3x3(np.diag([3.0, 2.0, 1.0]) * 1e-200) == 1e-200
    nearly_isotropic = np.eye(3)
    nearly_isotropic[0, 1] = 1e-110
    assert smallest_eigenvalue_3x3(nearly_isotropic) == pytest.approx(1.0, abs=1e-15)


def test_symmetric_from_upper_mirrors_and_keeps_the_input(rng: np.random.Generator) -> None:
    """The strict lower triangle comes from the upper one; the argument is not modified."""
    upper = np.triu(rng.normal(size=(5, 5)))
    before = upper.copy()
    full = symmetric_from_upper(upper)
    assert np.array_equal(full, full.T) and np.array_equal(np.triu(full), upper)
    assert np.array_equal(upper, before)
