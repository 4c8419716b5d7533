"""The pointwise law table's statistics (:func:`nnphd.explain.jointfit.linear_stats`): the vectorised sums (batched
products, block sums by reduceat, every bootstrap replicate in one product) against the plain loops they replace,
and the model-based standard error against ordinary least squares' textbook formula."""

import math

import numpy as np
import pytest

from nnphd.explain.jointfit import linear_stats, ridge_regularised, solve_or_lstsq


def _plain(J, R, folds, segs, tau, n_boot, seed, law_idx):
    """The statistics written out row by row, block by block and replicate by replicate."""
    N, rows2, P = J.shape
    n = rows2 // 2
    Gs = np.array([J[s].T @ J[s] for s in range(N)])
    hs = np.array([J[s].T @ R[s] for s in range(N)])
    G, h = Gs.sum(0), hs.sum(0)
    sse, m = 0.0, 0
    for f in folds:
        d = solve_or_lstsq(ridge_regularised(G - Gs[f].sum(0)), h - hs[f].sum(0))
        pred = np.array([R[s, :n] - J[s, :n] @ d for s in f])
        sse += float(np.sum(pred**2))
        m += pred.size
    L = max(1, math.ceil(2 * tau))
    blocks = [s[i : i + L] for s in segs for i in range(0, len(s), L)]
    rng = np.random.default_rng(seed)
    reps = []
    for _ in range(n_boot):
        idx = rng.integers(0, len(blocks), len(blocks))
        Gr = sum(Gs[blocks[i]].sum(0) for i in idx)
        hr = sum(hs[blocks[i]].sum(0) for i in idx)
        reps.append(solve_or_lstsq(ridge_regularised(Gr), hr)[law_idx])
    return sse / m, np.asarray(reps).std(axis=0)


@pytest.mark.parametrize(("N", "n", "P", "tau"), [(240, 1, 5, 1.0), (180, 2, 7, 2.6), (90, 3, 4, 4.2)])
def test_linear_stats_equals_the_plain_loops(N, n, P, tau):
    rng = np.random.default_rng(N)
    J, R = rng.normal(size=(N, 2 * n, P)), rng.normal(size=(N, 2 * n))
    segs = [np.arange(0, N // 3), np.arange(N // 3, N)]
    folds = np.array_split(np.arange(N), 5)
    law_idx = np.arange(P - 2, P)
    mse, se_b, _ = linear_stats(J, R, folds, segs, tau, 60, 7, law_idx)
    mse_ref, se_ref = _plain(J, R, folds, segs, tau, 60, 7, law_idx)
    assert mse == pytest.approx(mse_ref, rel=1e-12)
    np.testing.assert_allclose(se_b, se_ref, rtol=1e-10)


def test_linear_stats_model_error_is_least_squares_textbook():
    """One coordinate, no penalty rows, τ = 1: se_model = sqrt(s² (XᵀX)⁻¹) with s² = RSS/(N − P), the residual R
    taken at the least-squares optimum; the bootstrap's spread (blocks of 2 rows) agrees with it within 20 %."""
    rng = np.random.default_rng(3)
    N, P = 4000, 3
    X = rng.normal(size=(N, P))
    y = X @ np.array([1.0, -2.0, 0.5]) + 0.3 * rng.normal(size=N)
    beta = np.linalg.lstsq(X, y, rcond=None)[0]
    r = y - X @ beta
    J = np.zeros((N, 2, P))
    J[:, 0] = X
    R = np.zeros((N, 2))
    R[:, 0] = r
    idx = np.arange(P)
    _, se_b, se_m = linear_stats(J, R, np.array_split(np.arange(N), 5), [np.arange(N)], 1.0, 400, 0, idx)
    se_ols = np.sqrt(np.sum(r**2) / (N - P) * np.diag(np.linalg.inv(X.T @ X)))
    np.testing.assert_allclose(se_m, se_ols, rtol=1e-6)
    np.testing.assert_allclose(se_b, se_ols, rtol=0.2)
