"""Blind explanation by sparse regression on synthetic residuals with known laws (1% noise)."""

import numpy as np
import pytest
import sympy as sp

from nnphd.explain.sparse import sparse_formula

RNG = np.random.default_rng(0)
N = 300
X, Y, T = RNG.normal(size=N), RNG.normal(size=N), RNG.normal(size=N)
VX, VY = RNG.uniform(-1.3, 1.3, N), RNG.uniform(-1.3, 1.3, N)


def _noisy(f):
    return f * (1 + 0.01 * RNG.normal(size=f.shape))


def _coef(expr: str, term: str) -> float:
    return float(sp.sympify(expr).as_coefficients_dict()[sp.sympify(term)])


def test_friction_found():
    fn = _noisy(np.stack([-0.02 * VX, -0.02 * VY], 1))
    r = sparse_formula(
        {"theta1": X, "theta2": Y, "theta1_dot": VX, "theta2_dot": VY, "t": T},
        fn,
        ["a1", "a2"],
        velocities=["theta1_dot", "theta2_dot"],
        time="t",
    )
    assert r.readable and r.n_terms == 2
    assert _coef(r.formula["a1"], "theta1_dot") == pytest.approx(-0.02, rel=0.05)
    assert _coef(r.formula["a2"], "theta2_dot") == pytest.approx(-0.02, rel=0.05)


def test_gravitational_radiation_law_found():
    v2 = VX**2 + VY**2
    fn = _noisy(np.stack([-0.00165 * v2**4 * VX, -0.00165 * v2**4 * VY], 1))
    r = sparse_formula(
        {"x": X, "y": Y, "vx": VX, "vy": VY, "t": T}, fn, ["ax", "ay"], velocities=["vx", "vy"], time="t"
    )
    assert r.readable and r.n_terms == 2
    assert _coef(r.formula["ax"], "vx*(vx**2 + vy**2)**4") == pytest.approx(-0.00165, rel=0.02)
    assert _coef(r.formula["ay"], "vy*(vx**2 + vy**2)**4") == pytest.approx(-0.00165, rel=0.02)


def test_periodic_driving_found():
    r = sparse_formula({"x": X, "t": T}, _noisy((0.5 * np.sin(T))[:, None]), ["a"], time="t")
    assert r.readable and r.n_terms == 1 and _coef(r.formula["a"], "sin(t)") == pytest.approx(0.5, rel=0.02)


def test_noise_is_nothing_readable():
    r = sparse_formula({"x": X, "t": T}, RNG.normal(size=(N, 1)), ["a"], time="t")
    assert not r.readable and "nothing readable" in r.note


def test_bad_shape():
    with pytest.raises(ValueError, match="fn must have shape"):
        sparse_formula({"x": X}, np.zeros((N, 2)), ["a"])
