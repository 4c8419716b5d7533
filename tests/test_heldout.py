"""The held-out χ² of the trajectory-level law fits (:func:`nnphd.explain.trajectory.heldout_chi2`): the linearised
leave-one-group-out prediction, and the check that the fit it is linearised at is an optimum."""

from __future__ import annotations

import numpy as np
import pytest

from nnphd.explain.trajectory import heldout_chi2


def _windows(seed=0, W=12, P=2, m=6):
    """Linear least squares split into W windows: y_w = X_w θ + noise; per window c (χ² at θ̂), S = XᵀX, g = Xᵀr."""
    rng = np.random.default_rng(seed)
    X = rng.standard_normal((W, m, P))
    y = X @ np.array([1.0, -0.5]) + 0.1 * rng.standard_normal((W, m))
    theta = np.linalg.lstsq(X.reshape(-1, P), y.reshape(-1), rcond=None)[0]
    return X, y, theta


def normal_blocks(X, y, theta):
    r = X @ theta - y
    return np.sum(r * r, axis=1), np.einsum("wmp,wmq->wpq", X, X), np.einsum("wmp,wm->wp", X, r)


def test_at_the_optimum_it_is_the_exact_leave_one_group_out_error_of_a_linear_fit():
    X, y, theta = _windows()
    groups = np.array_split(np.arange(len(X)), 4)
    c, S, g = normal_blocks(X, y, theta)
    exact = 0.0
    for grp in groups:
        keep = np.setdiff1d(np.arange(len(X)), grp)
        th = np.linalg.lstsq(X[keep].reshape(-1, 2), y[keep].reshape(-1), rcond=None)[0]
        exact += float(np.sum((X[grp] @ th - y[grp]) ** 2))
    cv = heldout_chi2(c, S, g, groups)
    assert cv == pytest.approx(exact, rel=1e-6)
    assert cv > c.sum()  # held out is worse than in sample


def test_away_from_the_optimum_it_refuses_to_rank():
    # linearised at a point that is no optimum, the "held-out" χ² of some group falls below its in-sample χ² (here
    # below zero: a drive with free ω on a 2-D drag record had held-out χ² < 0 and was claimed with ΔIC −39418)
    X, y, theta = _windows()
    groups = np.array_split(np.arange(len(X)), 4)
    c, S, g = normal_blocks(X, y, theta + np.array([0.8, -0.6]))
    assert heldout_chi2(c, S, g, groups) is None
    # a fit a little short of the optimum (a few LM iterations): its groups' held-out χ² stays near their in-sample
    # χ² (here 1.02–1.08 of it) — still ranked
    c, S, g = normal_blocks(X, y, theta + np.array([1e-3, 0.0]))
    assert heldout_chi2(c, S, g, groups) is not None


def test_the_ic_correlation_time_is_the_noise_of_the_fits_that_explain_the_record():
    """ρ of the IC's correlation time: the median lag-one correlation of the fits within ADEQUATE_CHI2 of the lowest
    held-out χ² — the smooth residuals of the fits that miss the record (ρ near 1) are misfit, counted by their χ²,
    and must not shrink every candidate's n_eff (an offset-rest look-alike: ρ 0.93 over all 13 fits, n_eff 6)."""
    from nnphd.explain.trajectory import ADEQUATE_CHI2, noise_correlation

    def fits(pairs):  # (held-out χ², ρ) → the ranking entries' layout: χ² at [2], ρ at [4]
        return [(None, None, c, None, r, None, None, None) for c, r in pairs]

    edge = ADEQUATE_CHI2 * 100.0  # the largest held-out χ² still adequate beside a best of 100
    good = [(100.0, 0.10), (0.5 * (100.0 + edge), 0.30), (edge, 0.20)]  # median ρ 0.20
    misfits = [(50 * edge, 0.95), (90 * edge, 0.97), (2e2 * edge, 0.98), (8e2 * edge, 0.99), (3e3 * edge, 0.99)]
    assert noise_correlation(fits(good + misfits)) == pytest.approx(0.20)  # over all eight: 0.96
    assert noise_correlation(fits(misfits[:1] + good)) == pytest.approx(0.20)  # the order does not matter
    assert noise_correlation(fits([(100.0, 0.1), (1.005 * edge, 0.9)])) == pytest.approx(0.1)  # just past the factor
    assert noise_correlation(fits([(100.0, 0.99)])) == 0.95  # clipped at 0.95
    assert noise_correlation(fits([(100.0, -0.4), (120.0, -0.2)])) == 0.0
