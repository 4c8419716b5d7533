"""The amplitude envelope as evidence for the law (:mod:`nnphd.explain.envelope`): the pendulum's exact orbit, the
envelope of an autonomous amplitude equation, each family fitted to a measured envelope, and the pooling of the
windows' and the envelope's coefficients — each against an analytic truth."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.integrate import solve_ivp

from nnphd.explain.envelope import (
    Orbit,
    envelope_curve,
    fit_envelope,
    measured_envelope,
    pooled_row,
    swing_centre,
    swing_orbit,
)
from nnphd.explain.families import families
from nnphd.explain.table import dissipative_ok, law_row, zero_row


def _fam(key: str):
    return next(f for f in families(1, ["th"], np.ones(1)) if f.key == key)


def _row(key: str, beta, se, theta=()):
    fam = _fam(key)
    r = law_row(
        fam, np.asarray(beta, float), np.asarray(theta, float), np.asarray(se, float), ["th"], 1.0, "trajectory"
    )
    r.fn_rel = 0.1  # the law's size on the data, relative to q̈ (set by the table)
    return r


@pytest.mark.parametrize("A", [0.3, 1.5, 2.7])
def test_the_pendulum_orbit_conserves_its_energy_and_has_the_elliptic_period(A):
    w, q0 = 3.0, 0.05
    orb = Orbit(w, q0, pendulum=True)
    q, v = orb.states([A])
    E = 0.5 * v[0] ** 2 + w**2 * (1 - np.cos(q[0] - q0))
    assert np.allclose(E, w**2 * (1 - np.cos(A)), rtol=1e-9)
    assert np.max(q[0]) == pytest.approx(q0 + A, abs=0.02 * A)
    # half period against a direct integration of θ̈ = −w² sin θ from the turning point to the other one
    sol = solve_ivp(
        lambda t, y: [y[1], -(w**2) * np.sin(y[0])],
        (0, 10),
        [A, 0.0],
        events=lambda t, y: y[1] if t > 1e-6 else -1.0,
        rtol=1e-11,
        atol=1e-12,
    )
    assert float(orb.half_period(A)) == pytest.approx(sol.t_events[0][0], rel=1e-6)
    # the harmonic orbit is its small-amplitude limit
    assert float(Orbit(w).half_period(A)) == pytest.approx(np.pi / w)
    assert float(orb.energy_slope(A)) == pytest.approx(w**2 * np.sin(A))


def test_the_envelope_of_an_amplitude_equation_is_its_closed_form():
    grid = np.geomspace(0.01, 2.0, 400)
    t = np.linspace(0, 10, 50)
    # dry friction: a linear fall that stops at the grid's floor
    A = envelope_curve(np.full(len(grid), -0.1), grid, 1.0, t)
    live = 1.0 - 0.1 * t > 0.02
    assert np.allclose(A[live], 1.0 - 0.1 * t[live], atol=1e-3)
    # viscous: exponential
    A = envelope_curve(-0.15 * grid, grid, 1.0, t)
    assert np.allclose(A, np.exp(-0.15 * t), rtol=5e-3)
    # self-excitation a·A − b·A³ grows to its limit cycle √(a/b) and stalls there
    A = envelope_curve(0.5 * grid - 2.0 * grid**3, grid, 0.1, np.array([0.0, 2.0, 40.0]))
    exact = 0.1 * np.exp(0.5 * 2.0) / np.sqrt(1 + 4 * 0.01 * (np.exp(2 * 0.5 * 2.0) - 1))  # Bernoulli's solution
    assert A[1] == pytest.approx(exact, rel=0.01)
    assert A[2] == pytest.approx(0.5, rel=0.01)


def test_a_rate_too_small_to_invert_stalls_the_envelope_without_a_warning():
    """A decay rate of ~1e-310 (a hypothesis example of the test below): the time to cross a grid interval
    overflows to infinity — the envelope stays where it is, and numpy's overflow warning is not let out."""
    import warnings

    grid = np.geomspace(0.01, 2.0, 300)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        A = envelope_curve(np.full(len(grid), -1e-310), grid, 0.7, np.linspace(0, 20, 9))
    assert np.all(A == 0.7)


def _decay(gamma, mu, c, A0=2.5, w2=9.0, T=40.0, fs=200.0):
    """A pendulum θ̈ = −w² sin θ − γθ̇ − μ sign(θ̇) − c|θ̇|θ̇ released from A0 (large: the orbit is no sine)."""

    def f(t, y):
        return [y[1], -w2 * np.sin(y[0]) - gamma * y[1] - mu * np.tanh(y[1] / 1e-3) - c * abs(y[1]) * y[1]]

    t = np.arange(0, T, 1 / fs)
    s = solve_ivp(f, (0, T), [A0, 0.0], t_eval=t, rtol=1e-10, atol=1e-12, method="DOP853")
    return s.y[0], s.y[1], t


@pytest.mark.parametrize("pendulum", [True, False])
def test_a_coarse_record_times_its_half_swings_to_a_fraction_of_a_sample(pendulum):
    """66 Hz, ω 7.5, swings 0.5 → 0.1 rad (the servo-like look-alike): the half swings' midpoint times are the exact
    ones to well within a sample — a row-after-the-sign-change timing was off by up to half a sample, 3.6 % of a half
    period, hiding the pendulum's 1.4 % lengthening: its orbit came out harmonic, its dry friction 5 % low."""
    w2, gamma = 7.5**2, 0.8

    def f(_, y):
        return [y[1], -w2 * (np.sin(y[0]) if pendulum else y[0]) - gamma * y[1]]

    fs, T = 66.0, 4.0
    fine = solve_ivp(f, (0, T), [0.55, 0.0], dense_output=True, rtol=1e-11, atol=1e-12, method="DOP853")
    t = np.arange(0, T, 1 / fs)
    q, qd = fine.sol(t)
    tm, A, k = measured_envelope(q, qd, t, np.zeros(len(t), int), sigma=1e-4)
    # the exact turning times: the velocity's zero crossings of the dense solution
    tt = np.linspace(0, T, 400_001)
    v = fine.sol(tt)[1]
    i = np.flatnonzero(np.sign(v[1:]) * np.sign(v[:-1]) < 0)
    turns = tt[i] - v[i] * (tt[i + 1] - tt[i]) / (v[i + 1] - v[i])
    exact = 0.5 * (turns[:-1] + turns[1:])
    err = np.array([np.min(np.abs(exact - x)) for x in tm])
    assert len(tm) >= 8 and err.max() < 0.05 / fs  # a twentieth of a sample (the old timing: up to a half)
    orbit = swing_orbit(tm, A, k, swing_centre(q, qd, np.zeros(len(t), int)), angle=True)
    assert orbit.pendulum == pendulum
    assert orbit.omega == pytest.approx(np.sqrt(w2 - gamma**2 / 4), rel=0.01)


@pytest.mark.parametrize(
    "key, truth",
    [("linear+coulomb", {"gamma": 0.08, "mu": 0.15}), ("linear+quadratic", {"gamma": 0.05, "c": 0.03})],
)
def test_a_mixed_law_is_fitted_to_a_large_amplitude_pendulum_envelope(key, truth):
    q, qd, t = _decay(truth.get("gamma", 0.0), truth.get("mu", 0.0), truth.get("c", 0.0))
    traj = np.zeros(len(t), int)
    tm, A, k = measured_envelope(q, qd, t, traj, sigma=1e-4)
    orbit = swing_orbit(tm, A, k, swing_centre(q, qd, traj), angle=True)
    assert orbit.pendulum and orbit.omega == pytest.approx(3.0, rel=0.02)
    start = _row(key, [0.5 * v for v in truth.values()], [1.0, 1.0])  # a poor start: the fit must move
    fits = {f["key"]: f for f in fit_envelope([zero_row(["th"], 1.0, 10, "x"), start], tm, A, k, 1e-4, orbit)}
    for p, b in zip(_fam(key).coef_names, fits[key]["beta"]):
        assert b == pytest.approx(truth[{"gamma": "gamma", "mu": "mu", "c": "c"}[p]], rel=0.05), (p, b)
    assert fits[key]["chi2"] < 1e-3 * fits["none"]["chi2"]
    # the harmonic orbit misreads a swing from 2.5 rad: its coefficients are worse
    harm = Orbit(orbit.omega, orbit.q0)
    worse = {f["key"]: f for f in fit_envelope([start], tm, A, k, 1e-4, harm)}[key]
    assert worse["chi2"] > 3 * fits[key]["chi2"]


def test_the_windows_and_the_envelope_are_pooled_and_two_laws_are_not_one():
    q = np.sin(np.linspace(0, 20, 400))
    qd = np.cos(np.linspace(0, 20, 400))
    t = np.linspace(0, 20, 400)
    win = _row("linear+coulomb", [0.2, 0.1], [0.02, 0.05])
    env = {"beta": np.array([0.24, 0.12]), "cov": np.diag([0.01**2, 0.01**2]), "chi2": 10.0, "k": 3}
    new = pooled_row(win, env, n=13, n_eff=13, q=q, qd=qd, t=t, names=["th"])
    # inverse-variance weights: γ (0.2 ± 0.02, 0.24 ± 0.01) → 0.232; μ (0.1 ± 0.05, 0.12 ± 0.01) → 0.1192
    assert new.params["gamma"] == pytest.approx((0.2 / 0.02**2 + 0.24 / 0.01**2) / (1 / 0.02**2 + 1 / 0.01**2))
    assert new.params["mu"] == pytest.approx((0.1 / 0.05**2 + 0.12 / 0.01**2) / (1 / 0.05**2 + 1 / 0.01**2))
    assert new.envelope["agree"] and new.significant
    # the same family with an envelope that needs a damping twice as strong: two laws, not eligible
    far = dict(env, beta=np.array([0.4, 0.12]))
    bad = pooled_row(win, far, n=13, n_eff=13, q=q, qd=qd, t=t, names=["th"])
    assert not bad.envelope["agree"] and not bad.significant


def test_a_sum_of_friction_terms_with_a_negative_term_is_not_a_friction_law():
    fam = _fam("linear+coulomb")
    assert dissipative_ok(fam, [0.1, 0.2]) and not dissipative_ok(fam, [0.1, -0.01])
    assert dissipative_ok(_fam("rayleigh"), [0.1, -0.01])  # self-excitation has its own families


@settings(max_examples=60, deadline=None)
@given(
    gamma=st.floats(0.0, 2.0),
    mu=st.floats(0.0, 2.0),
    c=st.floats(0.0, 2.0),
    A0=st.floats(0.05, 1.5),
)
def test_a_dissipative_envelope_never_rises_and_never_jumps_below_its_floor(gamma, mu, c, A0):
    """Any friction law that takes energy out (viscous + dry + quadratic rates, all ≤ 0) gives a non-increasing
    envelope that stays within the tabulated amplitudes, and no law at all keeps the amplitude."""
    grid = np.geomspace(0.01, 2.0, 300)
    rate = -(0.5 * gamma * grid + mu + c * grid**2)
    t = np.linspace(0, 20, 60)
    A = envelope_curve(rate, grid, A0, t)
    assert A[0] == pytest.approx(A0)
    assert np.all(np.diff(A) <= 1e-12) and np.all(A >= grid[0] - 1e-12)
    assert np.allclose(envelope_curve(np.zeros(len(grid)), grid, A0, t), A0)
