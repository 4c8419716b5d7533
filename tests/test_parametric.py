"""Parametric explanation fits (paper §III.A.3, Table II): recover known parameters from synthetic f_n."""

import numpy as np
import pytest

from nnphd.explain.law import Law
from nnphd.explain.parametric import fit_drag_power, fit_linear_friction, fit_perturber


def _noisy(fn, rng, level):
    return fn + level * np.sqrt(np.mean(fn**2)) * rng.standard_normal(fn.shape)


def _assert_errs(fit: Law):
    errs = np.array(list(fit.stderr.values()))
    assert set(fit.stderr) == set(fit.params)
    assert np.all(np.isfinite(errs)) and np.all(errs > 0)


@pytest.mark.parametrize("noise", [0.0, 0.01])
def test_linear_friction(noise):
    rng = np.random.default_rng(0)
    gamma = np.array([[0.02, 0.0], [0.0, 0.02]])
    qd = rng.normal(size=(500, 2))
    fn = _noisy(-qd @ gamma.T, rng, noise)
    fit = fit_linear_friction(qd, fn)
    assert fit.key == "linear_friction" and fit.status == "candidate"
    assert set(fit.params) == {"Gamma_11", "Gamma_12", "Gamma_21", "Gamma_22"}
    tol = 1e-12 if noise == 0 else 5e-4
    assert abs(fit.params["Gamma_11"] - 0.02) <= tol
    assert abs(fit.params["Gamma_22"] - 0.02) <= tol
    assert abs(fit.params["Gamma_12"]) <= tol and abs(fit.params["Gamma_21"]) <= tol
    assert fit.rel_rms == pytest.approx(noise, abs=0.003)
    if noise:
        _assert_errs(fit)
    assert "Gamma" in fit.text()


def _orbit_speeds(rng, n=1000):
    speed = rng.uniform(0.7, 1.3, n)
    ang = rng.uniform(0, 2 * np.pi, n)
    return speed[:, None] * np.column_stack([np.cos(ang), np.sin(ang)])


@pytest.mark.parametrize("noise", [0.0, 0.01])
def test_drag_power(noise):
    rng = np.random.default_rng(1)
    k, m = 0.00165, 4.0
    qd = _orbit_speeds(rng)
    fn = -k * (np.sum(qd**2, axis=1) ** m)[:, None] * qd
    fn = _noisy(fn, rng, noise)
    fit = fit_drag_power(qd, fn)
    if noise == 0:
        assert fit.params["k"] == pytest.approx(k, rel=1e-8)
        assert fit.params["m"] == pytest.approx(m, abs=1e-8)
        assert fit.rel_rms < 1e-8
    else:
        assert fit.params["k"] == pytest.approx(k, rel=0.02)
        assert fit.params["m"] == pytest.approx(m, abs=0.03)
        assert fit.rel_rms == pytest.approx(noise, abs=0.003)
        _assert_errs(fit)
    assert fit.text().startswith("f_n = -")


def test_drag_power_respects_m_bounds():
    rng = np.random.default_rng(2)
    qd = _orbit_speeds(rng, 300)
    fn = -0.00165 * (np.sum(qd**2, axis=1) ** 4.0)[:, None] * qd
    fit = fit_drag_power(qd, fn, m_bounds=(0.0, 2.0))
    assert 0.0 <= fit.params["m"] <= 2.0 + 1e-12


def _perturber_data(noise, seed=3):
    gm, R, w, phi = 0.005, 3.0, 3.0**-1.5, 0.0
    t = np.linspace(0.0, 100.0, 1000)
    q = 2.0 * np.column_stack([np.cos(t / 2**1.5), np.sin(t / 2**1.5)])
    rp = R * np.column_stack([np.cos(w * t + phi), np.sin(w * t + phi)])
    d = rp - q
    fn = gm * d / np.linalg.norm(d, axis=1)[:, None] ** 3
    return q, t, _noisy(fn, np.random.default_rng(seed), noise), (gm, R, w, phi)


@pytest.mark.parametrize("noise", [0.0, 0.01])
def test_perturber(noise):
    q, t, fn, (gm, R, w, phi) = _perturber_data(noise)
    fit = fit_perturber(q, t, fn)
    p = fit.params
    assert p["GM"] == pytest.approx(gm, rel=0.02 if noise else 1e-6)
    assert p["R"] == pytest.approx(R, rel=0.003 if noise else 1e-6)
    assert p["omega"] == pytest.approx(w, rel=0.005 if noise else 1e-6)
    assert abs(p["phi"] - phi) < (0.05 if noise else 1e-5)
    assert -np.pi < p["phi"] <= np.pi
    assert fit.rel_rms == pytest.approx(noise, abs=0.003)
    if noise:
        _assert_errs(fit)
    assert "r_p" in fit.text()


def test_perturber_retrograde():
    gm, R, w, phi = 0.005, 3.0, -(3.0**-1.5), 2.0
    t = np.linspace(0.0, 100.0, 600)
    q = 2.0 * np.column_stack([np.cos(t / 2**1.5), np.sin(t / 2**1.5)])
    d = R * np.column_stack([np.cos(w * t + phi), np.sin(w * t + phi)]) - q
    fn = gm * d / np.linalg.norm(d, axis=1)[:, None] ** 3
    fit = fit_perturber(q, t, fn)
    assert fit.params["omega"] == pytest.approx(w, rel=1e-6)
    assert fit.params["phi"] == pytest.approx(phi, abs=1e-5)


def test_fit_is_frozen():
    rng = np.random.default_rng(4)
    qd = rng.normal(size=(50, 2))
    fit = fit_linear_friction(qd, -0.1 * qd)
    with pytest.raises(AttributeError):
        fit.rms = 1.0


def test_bad_inputs_raise():
    rng = np.random.default_rng(5)
    qd = rng.normal(size=(20, 2))
    with pytest.raises(ValueError, match="fn"):
        fit_linear_friction(qd, qd[:, :1])
    with pytest.raises(ValueError, match="qd"):
        fit_drag_power(qd[:, 0], qd)
    bad = qd.copy()
    bad[0, 0] = np.nan
    with pytest.raises(ValueError, match="fn"):
        fit_drag_power(qd, bad)
    q3 = rng.normal(size=(20, 3))
    with pytest.raises(ValueError, match="q"):
        fit_perturber(q3, np.arange(20.0), q3)
    with pytest.raises(ValueError, match="t"):
        fit_perturber(qd, np.arange(19.0), qd)
