"""Blind explanation by genetic symbolic regression (pyoperon) on synthetic residuals with known laws (1% noise)."""

import numpy as np
import pytest
import sympy as sp

from nnphd.explain.symbolic import GeneticSearch, genetic_formula

RNG = np.random.default_rng(0)
N = 300
X, Y, T = RNG.normal(size=N), RNG.normal(size=N), RNG.normal(size=N)
VX, VY = RNG.uniform(-1.3, 1.3, N), RNG.uniform(-1.3, 1.3, N)


def _noisy(f):
    return f * (1 + 0.01 * RNG.normal(size=f.shape))


def _on_data(expr: str, **cols) -> np.ndarray:
    e = sp.sympify(expr)
    syms = sorted(e.free_symbols, key=str)
    return np.broadcast_to(sp.lambdify(syms, e, "numpy")(*[cols[str(s)] for s in syms]), (N,))


# Budgets of generations on one thread, not of seconds: a time-bounded search runs fewer generations on a loaded
# machine and can then find another formula (it did in CI for the slow test below). 150 generations: 1–4 s each here.


@pytest.mark.slow  # a symbolic regression of 10-20 s: slow tier (`python3 dev.py test --slow`, and CI)
def test_friction_found_and_reproducible():
    fn = _noisy(np.stack([-0.02 * VX, -0.02 * VY], 1))
    inputs = {"theta1": X, "theta2": Y, "theta1_dot": VX, "theta2_dot": VY, "t": T}
    r = genetic_formula(inputs, fn, ["a1", "a2"], search=GeneticSearch(max_time=600, generations=150, n_threads=1))
    assert r.readable and r.rel_rms < 0.02
    e1, e2 = (sp.sympify(r.formula[c]) for c in ("a1", "a2"))
    assert e1.free_symbols == {sp.Symbol("theta1_dot")} and e2.free_symbols == {sp.Symbol("theta2_dot")}
    assert float(sp.diff(e1, "theta1_dot")) == pytest.approx(-0.02, rel=0.05)
    assert float(sp.diff(e2, "theta2_dot")) == pytest.approx(-0.02, rel=0.05)
    again = genetic_formula(inputs, fn, ["a1", "a2"], search=GeneticSearch(max_time=600, generations=150, n_threads=1))
    assert again.formula == r.formula


@pytest.mark.slow  # tens of seconds: run by `python3 dev.py test --slow` (and by CI)
def test_gravitational_radiation_law_found():
    v2 = VX**2 + VY**2
    fn = _noisy(np.stack([-0.00165 * v2**4 * VX, -0.00165 * v2**4 * VY], 1))
    # a budget of generations on one thread, not of seconds: a 10 s search found t in the formula when CI was loaded
    # (deterministic now; measured: 18 s, 2.8 % rms)
    inputs = {"x": X, "y": Y, "vx": VX, "vy": VY, "t": T}
    r = genetic_formula(inputs, fn, ["ax", "ay"], search=GeneticSearch(max_time=600, generations=1000, n_threads=1))
    assert r.readable and r.rel_rms < 0.03
    # the formula, not just a good fit: it matches the law off the data too
    for i, expr in enumerate(r.formula.values()):
        assert sp.sympify(expr).free_symbols <= {sp.Symbol("vx"), sp.Symbol("vy")}
        grid = dict(vx=np.linspace(-1.2, 1.2, N), vy=np.linspace(1.1, -0.9, N))
        law = -0.00165 * (grid["vx"] ** 2 + grid["vy"] ** 2) ** 4 * grid["vx" if i == 0 else "vy"]
        assert np.sqrt(np.mean((_on_data(expr, **grid) - law) ** 2)) < 0.05 * np.sqrt(np.mean(law**2))


def test_periodic_driving_found():
    r = genetic_formula(
        {"x": X, "t": T},
        _noisy((0.5 * np.sin(T))[:, None]),
        ["a"],
        search=GeneticSearch(max_time=600, generations=150, n_threads=1),
    )
    assert r.readable and sp.sympify(r.formula["a"]).free_symbols == {sp.Symbol("t")}
    tt = np.linspace(-2, 2, N)
    assert np.max(np.abs(_on_data(r.formula["a"], t=tt) - 0.5 * np.sin(tt))) < 0.02


def test_noise_is_nothing_readable():
    search = GeneticSearch(max_time=600, generations=150, n_threads=1)
    r = genetic_formula({"x": X, "t": T}, RNG.normal(size=(N, 1)), ["a"], search=search)
    assert not r.readable and "nothing readable" in r.note and r.rel_rms > 0.9


def test_bad_shape():
    with pytest.raises(ValueError, match="fn must have shape"):
        genetic_formula({"x": X}, np.zeros((N, 2)), ["a"])
