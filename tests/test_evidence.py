"""nnphd.engine.evidence on analytic truths: the per-period energy trend and the multiple-shooting damping probe, with an
exact conservative model (no networks), plus the verdict rules built on them (nnphd.user.checks)."""

import jax.numpy as jnp
import numpy as np
import pytest
from scipy.integrate import solve_ivp

import nnphd  # noqa: F401  (float64)
from nnphd.engine.evidence import dominant_period, energy_trend, period_blocks
from nnphd.engine.shooting import ShootingData, shooting_fit, shooting_windows
from nnphd.user.checks import (
    EFFECT_MIN,
    Z_BOTH,
    Z_ONE,
    by_learned_power,
    clock_testable,
    effect_text,
    seed_status,
    trajectory_evidence,
)

W0 = 1.1


def test_dominant_period_and_blocks():
    t = np.linspace(0, 100, 2001)
    x = np.cos(W0 * t)[:, None]
    P = dominant_period(np.c_[x, -W0 * np.sin(W0 * t)], t, [np.arange(len(t))])
    assert abs(P / (2 * np.pi / W0) - 1) < 0.005
    blocks = period_blocks(t, [np.arange(len(t))], P)[0]
    assert len(blocks) == int(100 // P)
    assert all(abs((t[b][-1] - t[b][0]) - P) < 2 * (t[1] - t[0]) for b in blocks)


def test_energy_trend_recovers_an_exponential_decay_and_sees_none_in_a_constant():
    rng = np.random.default_rng(0)
    t = np.linspace(0, 90, 3000)
    P = 2 * np.pi / W0
    wobble = 1 + 0.3 * np.cos(2 * W0 * t)  # a state function oscillates within each period
    E_dec = 2.0 + np.exp(-0.011 * t) * wobble + 1e-3 * rng.standard_normal(t.size)
    r = energy_trend(E_dec, 2.0, t, [np.arange(t.size)], P)
    assert r["valid"] and abs(r["rate"] / 0.011 - 1) < 0.02 and r["z"] > 20
    assert abs(r["rate_per_period"] - 0.011 * P) < 0.002
    E_con = 2.0 + wobble + 1e-3 * rng.standard_normal(t.size)
    r0 = energy_trend(E_con, 2.0, t, [np.arange(t.size)], P)
    assert r0["valid"] and abs(r0["z"]) < 3
    # a learned energy that falls while the kinetic energy grows is not used (a poor energy, or a 1/r potential)
    K = np.exp(+0.011 * t) * wobble
    rk = energy_trend(E_dec, 2.0, t, [np.arange(t.size)], P, kinetic=K)
    assert not rk["valid"] and not rk["consistent"] and "other way" in rk["reason"] and rk["kinetic_z"] < -20
    ok = energy_trend(E_dec, 2.0, t, [np.arange(t.size)], P, kinetic=np.exp(-0.011 * t) * wobble)
    assert ok["valid"] and ok["consistent"] and abs(ok["kinetic_rate"] / 0.011 - 1) < 0.02


def _pendulum(gamma, seed=0, noise=0.0025):
    rng = np.random.default_rng(seed)
    T = 15 * 2 * np.pi / W0
    t = np.sort(np.arange(0, T, 1 / 6) + rng.normal(0, 0.02 / 6, len(np.arange(0, T, 1 / 6))))
    t = t - t[0]
    sol = solve_ivp(
        lambda _, y: [y[1], -(W0**2) * np.sin(y[0]) - gamma * y[1]],
        (t[0], t[-1]),
        [0.5, 0.0],
        t_eval=t,
        rtol=1e-10,
        atol=1e-12,
    )
    q = sol.y[0][:, None] + rng.normal(0, noise, (t.size, 1))
    qd = sol.y[1][:, None] + rng.normal(0, 2 * noise, (t.size, 1))
    return t, q, qd


def _accel(p, q, v):
    return -p * jnp.sin(q)


@pytest.mark.parametrize("gamma", [0.011, 0.0])
def test_shooting_fit_measures_the_damping_of_a_noisy_pendulum(gamma):
    t, q, qd = _pendulum(gamma)
    segs = [np.arange(t.size)]
    P = 2 * np.pi / W0
    # the conservative model is 1 % too stiff: the nuisance c takes it up, d stays the damping
    r = shooting_fit(_accel, jnp.asarray(1.01 * W0**2), ShootingData(q, qd, t, segs, [0.0025], P))
    assert r["valid"] and r["n_windows"] >= 15
    assert abs(r["c"] + 0.01) < 0.003
    assert abs(r["d_mean"] - gamma) < 3 * r["se_d_mean"] + 1e-4
    if gamma:
        assert r["z"] > 10 and r["chi2"] < 0.7 * r["chi2_conservative"]
    else:
        assert abs(r["z"]) < 3
    assert 0.5 < r["reduced_chi2"] < 2  # residuals at the noise level
    assert r["window_periods"] == 0.75 and r["fallbacks"] == []  # no fallback on a fit that works


def test_a_collapsed_shooting_fit_is_no_measurement():
    from nnphd.engine.shooting import collapsed

    # a real double pendulum's probe: d = 2e-21 ± 1.3e-12 — it never moved from its start
    assert "no progress" in collapsed([2e-21, 0.0], 1.3e-12, [0.0, 0.0], 1.0)
    # it moved, but a standard error of 1e-14 per time unit is no record's: a Jacobian blown up by chaos
    assert "collapsed" in collapsed([0.05, 0.02], 1e-14, [0.0, 0.0], 1.0)
    assert "collapsed" in collapsed([0.05], 5e-9, [0.0], 0.1)  # the bound is 1e-9 per period: 1e-8 for P = 0.1
    # an honest fit: the pendulum's damping, and a conservative record's d ≈ 0 with a real error
    assert collapsed([0.011], 0.001, [0.0], 5.7) is None
    assert collapsed([3e-5], 2e-4, [0.0], 5.7) is None


def test_a_fit_that_fails_on_long_windows_is_tried_on_shorter_ones(monkeypatch):
    import nnphd.engine.shooting as sh

    calls = []

    def fake(*args):
        periods = args[-1]
        calls.append(periods)
        if periods == sh.WINDOW_PERIODS:
            return {"valid": False, "n_windows": 30, "reason": "the shooting fit collapsed (…)"}
        return {"valid": True, "n_windows": 60, "d_mean": 0.1}

    monkeypatch.setattr(sh, "shooting_fit_on_windows", fake)
    data = sh.ShootingData(np.zeros((5, 1)), np.zeros((5, 1)), np.arange(5.0), [np.arange(5)], [0.1], 1.0)
    r = sh.shooting_fit(None, None, data)
    assert r["valid"] and r["window_periods"] == sh.WINDOW_PERIODS / 2 and calls == [0.75, 0.375]
    assert r["fallbacks"] == ["windows of 0.75 period: the shooting fit collapsed (…)"]
    # too few windows is no failure of the fit: not retried
    calls.clear()
    monkeypatch.setattr(
        sh, "shooting_fit_on_windows", lambda *a: calls.append(a[-1]) or {"valid": False, "n_windows": 2}
    )
    r = sh.shooting_fit(None, None, data)
    assert not r["valid"] and calls == [0.75]
    # every length fails: the last reason, and why the longer ones failed
    monkeypatch.setattr(
        sh, "shooting_fit_on_windows", lambda *a: {"valid": False, "n_windows": 9, "reason": f"bad {a[-1]}"}
    )
    r = sh.shooting_fit(None, None, data)
    assert not r["valid"] and r["reason"] == "bad 0.1875" and len(r["fallbacks"]) == 2


def test_shooting_windows_are_three_quarters_of_a_period():
    t = np.arange(0, 60, 0.1)
    wins = shooting_windows([np.arange(t.size)], t, period=4.0)
    assert all(len(w) == 30 for w in wins[:-1]) and sum(len(w) for w in wins) == t.size


def test_clock_is_testable_only_with_overlapping_or_many_trajectories():
    t = np.r_[np.arange(0, 30, 0.1), np.arange(100, 130, 0.1)]
    segs = [np.arange(300), np.arange(300, 600)]
    ok, why = clock_testable(t, segs)
    assert not ok and "tell the trajectories apart" in why
    assert not clock_testable(np.arange(0, 30, 0.1), [np.arange(300)])[0]
    t3 = np.tile(np.arange(0, 30, 0.1), 3)
    assert clock_testable(t3, [np.arange(300) + 300 * k for k in range(3)])[0]
    assert not clock_testable(np.tile(np.arange(0, 30, 0.1), 2), [np.arange(300), np.arange(300, 600)])[0]


def test_trajectory_evidence_rules():
    tr = {"valid": True, "z": 0.0, "rate": 0.0, "se": 0.001}
    sh = {"valid": True, "z": 0.0}
    assert trajectory_evidence(tr | {"z": Z_BOTH}, sh | {"z": Z_BOTH})["significant"]
    assert not trajectory_evidence(tr | {"z": Z_BOTH}, sh | {"z": -Z_BOTH})["significant"]  # disagree
    assert trajectory_evidence(tr | {"z": Z_ONE}, sh | {"z": 1.0})["significant"]
    assert not trajectory_evidence(tr | {"z": Z_ONE}, sh | {"z": -2.5})["significant"]  # contradicted
    assert trajectory_evidence(tr | {"z": -Z_ONE}, {"valid": False})["direction"] == "gains energy"
    assert not trajectory_evidence({"valid": False}, {"valid": False})["valid"]
    none = trajectory_evidence(tr | {"z": 0.5, "rate": 0.0005}, sh)
    assert not none["significant"] and abs(none["rate_bound"] - 0.0025) < 1e-12


def test_a_significant_but_negligible_energy_change_counts_as_none():
    """One trajectory of the conservative Morse oscillator (trust table, 2026-11-27): the learned energy trended
    1.2e-7 per period at z = 16.9 and the seeds' "detected" came from it. Below EFFECT_MIN per period a statistic
    counts as z = 0, however significant; just above it, the same z detects."""
    good = {"usable": True, "pointwise_ok": True, "reason": ""}
    period = 6.3
    trend = {"valid": True, "z": 16.9, "rate": 1.2e-7 / period, "se": 1e-9, "rate_per_period": 1.2e-7,
             "period": period, "n_blocks": 15}  # fmt: skip
    shoot = {"valid": True, "z": 0.1, "d_mean": 4e-7, "se_d_mean": 3e-6, "n_windows": 21}
    replicas = ([16.0] * 50, [0.1] * 50)
    tiny = trajectory_evidence(trend, shoot, replicas)
    assert not tiny["significant"] and tiny["negligible"] == ["energy", "shooting"] and tiny["z_energy"] == 0.0
    assert tiny["bootstrap_fraction"] is None  # no replica to judge: both statistics count as zero
    tiny["effect"] = effect_text(tiny, trend, shoot)
    assert "too small to count" in tiny["effect"] and "0.001%/period" in tiny["effect"]
    assert seed_status(*_checks(), tiny, good, 1)[0] == "none"
    # the same z at 2× the floor (energy) is a detection; so is a damping whose 2·d·period is above it
    above = trajectory_evidence(trend | {"rate_per_period": 2 * EFFECT_MIN}, shoot, replicas)
    assert above["bootstrap_fraction"] == 1.0  # every replica of the trend (z = 16) stays significant
    assert above["significant"] and above["negligible"] == ["shooting"]
    damp = trajectory_evidence(trend, shoot | {"z": 16.9, "d_mean": EFFECT_MIN / period})
    assert damp["significant"] and damp["negligible"] == ["energy"] and damp["z_shooting"] == 16.9
    # a throw has no period: no floor
    throw = trajectory_evidence(trend | {"period": float("inf"), "oscillating": False}, shoot)
    assert throw["negligible"] == [] and throw["z_energy"] == 16.9


def _checks(rho=0.0, sig=False):
    drift = {
        "bootstrap_fraction": 0.0,
        "rho_median": rho,
        "magnitude_median": 0.0,
        "significant": sig,
        "valid": True,
        "slow_ratio_median": 0.0,
    }
    tchk = {"significant": False, "valid": False, "testable": "one trajectory", "gain": 1.0}
    gap = {"large": False, "gap_train": 1.0}
    cap = {"still_falling": False, "relative_drop": 0.0}
    return drift, tchk, gap, cap


def test_verdict_refuses_when_derivatives_are_too_noisy_and_the_record_is_silent():
    weak = {"significant": False, "valid": True, "bootstrap_fraction": 0.0, "rate_bound": 0.01, "effect": "energy flat"}
    bad_qdd = {"usable": True, "pointwise_ok": False, "reason": "q̈ error 80%"}
    status, reason, _ = seed_status(*_checks(rho=0.9, sig=True), weak, bad_qdd, 1)
    assert status == "inconclusive" and "derivatives too noisy for a pointwise test" in reason
    good = {"usable": True, "pointwise_ok": True, "reason": ""}
    status, reason, _ = seed_status(*_checks(), weak, good, 1)
    assert status == "none" and "95% bound" in reason
    # one trajectory: a pointwise net-power signal alone, unconfirmed by the record, is not a detection
    status, _, _ = seed_status(*_checks(rho=0.9, sig=True), weak, good, 1)
    assert status == "inconclusive"
    strong = weak | {"significant": True, "bootstrap_fraction": 0.97, "effect": "energy decays 6%/period, z = 40"}
    status, reason, agree = seed_status(*_checks(), strong, bad_qdd, 1)
    assert status == "detected" and "z = 40" in reason and agree == 0.97
    # one trajectory whose energy swings without a trend (a drive off resonance): not "none"
    swing = _checks()
    swing[0]["slow_ratio_median"] = 5.0
    status, reason, _ = seed_status(*swing, weak, good, 1)
    assert status == "inconclusive" and "swings slowly" in reason
    # ... owed to the learned Lagrangian's power alone (a fit of the positions decides: nnphd.user.rules), unless
    # there are ≥ 3 trajectories or the record-level evidence itself is too strong for a "none"
    assert by_learned_power(status, *swing, weak, good, 1)
    assert not by_learned_power(status, *swing, weak, good, 3)
    three_sigma = weak | {"z_energy": 3.4, "z_shooting": 0.2}
    status3, reason3, _ = seed_status(*swing, three_sigma, good, 1)
    assert status3 == "inconclusive" and not by_learned_power(status3, *swing, three_sigma, good, 1)
    assert not by_learned_power("none", *_checks(), weak, good, 1)
    unusable = {"usable": False, "pointwise_ok": False, "reason": "the positions are mostly noise"}
    assert seed_status(*_checks(), strong, unusable, 1)[0] == "inconclusive"


def test_a_none_that_one_statistic_contradicts_at_three_sigma_is_inconclusive():
    """A real double pendulum's 12-s piece: energy trend z = 4.5, probe z = 0.8 — no detection (both ≥ 3 or one ≥ 6),
    but no "none" either."""
    good = {"usable": True, "pointwise_ok": True, "reason": ""}
    base = {"significant": False, "valid": True, "bootstrap_fraction": 0.2, "rate_bound": 0.05, "effect": "decays"}
    status, reason, _ = seed_status(*_checks(), base | {"z_energy": 4.5, "z_shooting": 0.8}, good, 1)
    assert status == "inconclusive" and "energy trend is at z = 4.5" in reason and "shooting" not in reason
    status, reason, _ = seed_status(*_checks(), base | {"z_energy": 0.5, "z_shooting": -3.2}, good, 1)
    assert status == "inconclusive" and "shooting probe is at z = -3.2" in reason
    # below Z_BOTH on both (or a statistic missing): "none" with its bound, as before
    assert seed_status(*_checks(), base | {"z_energy": 0.99 * Z_BOTH, "z_shooting": None}, good, 1)[0] == "none"
    assert seed_status(*_checks(), base | {"z_energy": None, "z_shooting": -2.9}, good, 1)[0] == "none"


@pytest.mark.slow  # compiles JAX's full Jacobian (~20 s): slow tier (`python3 dev.py test --slow`, and CI)
def test_rowwise_jvp_gives_jaxs_own_jacobian_of_a_shooting_fit():
    """The shooting Jacobian with f_c differentiated once per row (rowwise_jvp) equals JAX's own forward derivatives
    through a small LNN's Euler–Lagrange solve, for window states and parameters alike; the values are identical."""
    import jax

    from nnphd.engine.models import ModelConfig, init_nnphd, lnn_accel
    from nnphd.engine.shooting import Integrator, ShootingWindows, model_residuals_and_jac, rowwise_jvp

    cfg = ModelConfig(n=2, lnn_widths=(16, 16), uan_widths=(8,))
    lnn = init_nnphd(jax.random.PRNGKey(0), cfg)["lnn"]

    def accel(p, q, v):
        return lnn_accel(p, q, v, cfg)

    fc = rowwise_jvp(accel)
    rng = np.random.default_rng(0)
    W, L = 5, 7
    tw = jnp.asarray(np.tile(np.linspace(0.0, 0.6, L), (W, 1)))
    qw = jnp.asarray(0.1 * rng.standard_normal((W, L, 2)))
    s = jnp.asarray(0.3 * rng.standard_normal((W, 4)))
    theta = jnp.asarray([0.1, -0.2, 0.05])
    args = (lnn, ShootingWindows(tw, jnp.zeros(W), qw, jnp.ones((W, L)), jnp.ones(2)))

    def plain(th, q, v, t, p):
        return (1 + th[0]) * accel(p, q, v) - th[1:] * v * q

    def rowwise(th, q, v, t, p):
        return (1 + th[0]) * fc(p, q, v) - th[1:] * v * q

    r0, j0 = model_residuals_and_jac(s, theta, *args, Integrator(plain, 2))
    r1, j1 = model_residuals_and_jac(s, theta, *args, Integrator(rowwise, 2))
    assert j0.shape == (7, W, L, 2) and float(jnp.max(jnp.abs(j0))) > 1e-3
    assert np.array_equal(np.asarray(r0), np.asarray(r1))
    assert float(jnp.max(jnp.abs(j1 - j0))) <= 1e-12 * float(jnp.max(jnp.abs(j0)))
    # and by finite differences: a local direction moves the same state component of every window; a parameter
    h = 1e-6
    e = jnp.zeros_like(s).at[:, 1].set(h)
    fd = (model_residuals_and_jac(s + e, theta, *args, Integrator(rowwise, 2))[0] - r1) / h
    assert float(jnp.max(jnp.abs(fd - j1[1]))) < 1e-4 * float(jnp.max(jnp.abs(j1[1])))
    fd = (model_residuals_and_jac(s, theta.at[0].add(h), *args, Integrator(rowwise, 2))[0] - r1) / h
    assert float(jnp.max(jnp.abs(fd - j1[4]))) < 1e-4 * float(jnp.max(jnp.abs(j1[4])))


def test_lm_judges_trial_steps_on_the_residuals_alone():
    """Levenberg–Marquardt with ``res`` (residuals only for a trial step, derivatives only where a step is accepted)
    reaches the same fit as with the derivatives at every trial, with fewer derivative evaluations."""
    from nnphd.engine.shooting import (
        Integrator,
        ShootingWindows,
        damping_rhs,
        lm_windows,
        model_residuals,
        model_residuals_and_jac,
        pad_windows,
    )

    t, q, qd = _pendulum(0.011)
    wins = shooting_windows([np.arange(t.size)], t, 2 * np.pi / W0)
    tw, qw, mask, s0 = pad_windows(wins, t, q, (q, qd))
    tw = tw - tw[:, :1]
    p, t0w, inv_sigma = jnp.asarray(1.01 * W0**2), jnp.zeros(len(wins)), jnp.asarray([1 / 0.0025])
    args = (p, ShootingWindows(jnp.asarray(tw), t0w, jnp.asarray(qw), jnp.asarray(mask), inv_sigma))
    model = Integrator(damping_rhs(_accel), 2)
    calls = {"jac": 0, "res": 0}

    def resjac(s, th):
        calls["jac"] += 1
        return model_residuals_and_jac(s, th, *args, model)

    def res(s, th):
        calls["res"] += 1
        return model_residuals(s, th, *args, model)

    free = np.ones(2, bool)
    # from the noisy data's own states and a far start (c = −0.5, d = 1): trial steps get rejected on the way
    s_a, th_a, r_a, j_a, c_a = lm_windows(resjac, s0, np.array([-0.5, 1.0]), free)
    n_plain = calls["jac"]
    calls.update(jac=0, res=0)
    s_b, th_b, r_b, j_b, c_b = lm_windows(resjac, s0, np.array([-0.5, 1.0]), free, res=res)
    assert calls["res"] == n_plain - 1  # every trial judged on its residuals (the first point needs the derivatives)
    assert calls["jac"] < n_plain  # and derivatives only at the accepted points
    assert c_b == pytest.approx(c_a, rel=1e-12) and np.allclose(th_b, th_a, rtol=0, atol=1e-10)
    assert np.allclose(s_b, s_a, rtol=0, atol=1e-10) and np.allclose(j_b, j_a, rtol=1e-9, atol=1e-12)
    assert abs(th_b[1] - 0.011) < 0.003  # and it is the damping


def test_percent_per_period_is_a_share_of_the_energy():
    """E ∝ exp(−r t): a decay of r·period = 2 loses 86.5 % of the energy per period (it was printed as
    "2e+02 %/period"); a growth of 2 gains 639 %; small rates ≈ 100·|r·period|."""
    from nnphd.engine.evidence import percent_per_period

    assert percent_per_period(2.0) == pytest.approx(100 * (1 - np.exp(-2.0)))  # 86.47 %
    assert percent_per_period(-2.0) == pytest.approx(100 * (np.exp(2.0) - 1))
    assert percent_per_period(1e-3) == pytest.approx(0.1, rel=1e-3) and percent_per_period(0.0) == 0.0
    assert all(0 < percent_per_period(x) <= 100 for x in (0.5, 5.0, 50.0, 1e3))  # never more than all of it


@pytest.mark.parametrize("stop", [8.4, 4.0])  # the last 30 % at rest (a dry-friction record), the last two thirds
def test_dominant_period_is_not_fooled_by_a_body_at_rest(monkeypatch, stop):
    """A swing that ends stuck: the velocity flickers about zero at rest and crosses its mean again and again;
    counted with hysteresis the period is the swing's (counted blindly it was half of it and less)."""
    from scipy.signal import savgol_filter

    import nnphd.engine.evidence as ev

    rng = np.random.default_rng(0)
    t = np.arange(0, 12, 1 / 30)
    w = 2 * np.pi / 1.5
    q = np.where(t < stop, 0.4 * (1 - t / (stop + 0.5)) * np.cos(w * t), 0.0) + 0.002 * rng.normal(size=len(t))
    qd = savgol_filter(q, 15, 3, deriv=1, delta=t[1] - t[0])  # smoothed, as nnphd's derivative estimators
    segs = [np.arange(len(t))]
    P = dominant_period(np.c_[q, qd], t, segs, position_noise=[0.002])
    assert abs(P / 1.5 - 1) < 0.03
    monkeypatch.setattr(ev, "CROSSING_HYSTERESIS", 0.0)
    assert dominant_period(np.c_[q, qd], t, segs, position_noise=[0.002]) < 0.8 * 1.5


def test_a_learned_energy_trend_within_the_fit_errors_reach_does_not_count():
    """The Moon over a year (DE405; its Kepler energy has no trend) — the learned energy decayed 0.25 %/period
    at z = 8 while the residual's power moved 2.9 % in and out per period: 3.2 % over 13 periods < 3 × 2.9 %. A
    string pendulum in air: 4 %/period over 58 periods against 5.6 % per period counts."""
    from nnphd.user.checks import FIT_ERROR_RATIO, trajectory_evidence, within_fit_error

    moon = {"valid": True, "z": 8.0, "rate": 9.05e-05, "se": 1.1e-5, "rate_per_period": 0.00248, "period": 27.4,
            "n_blocks": 13, "fit_error": {"gross_smooth": 0.0291, "periods": 13.0}}  # fmt: skip
    assert within_fit_error(moon)
    shoot = {"valid": True, "z": -0.4, "d_mean": -1.9e-4}
    ev = trajectory_evidence(moon, shoot)
    assert not ev["significant"] and ev["z_energy"] == 0.0 and ev["within_fit_error"]
    assert ev["rate_bound"] == pytest.approx(FIT_ERROR_RATIO * 0.0291 / (13 * 27.4))  # what the fit error can hide
    string = {**moon, "z": 16.9, "rate_per_period": 0.0404, "fit_error": {"gross_smooth": 0.0559, "periods": 58.0}}
    assert not within_fit_error(string)
    assert trajectory_evidence(string, {**shoot, "z": 14.4, "d_mean": 0.026})["significant"]
    # motion that does not oscillate has its own rule
    assert not within_fit_error({**moon, "oscillating": False})
    # between one period's fit error and FIT_ERROR_RATIO× it (a camera look-alike of a damped double pendulum: 2.1,
    # z = 4.7): no detection, but its z stays for the reasons, so the seed is "inconclusive", never "none"
    from nnphd.user.checks import FIT_ERROR_NONE, seed_status

    dp = {**moon, "z": 4.7, "rate_per_period": 0.0418, "fit_error": {"gross_smooth": 0.1405, "periods": 7.0}}
    assert FIT_ERROR_NONE <= 0.0418 * 7 / 0.1405 < FIT_ERROR_RATIO and within_fit_error(dp)
    ev = trajectory_evidence(dp, {**shoot, "z": -1.2, "d_mean": -0.12})
    assert not ev["significant"] and ev["z_energy"] == 4.7
    ev["effect"] = "e"
    drift = {"significant": False, "bootstrap_fraction": 0.0, "rho_median": 0.1, "magnitude_median": 0.01,
             "slow_ratio_median": 0.5, "valid": True}  # fmt: skip
    tchk = {"significant": False, "valid": False, "testable": "one trajectory", "gain": 1.0}
    gap = {"large": False, "gap_train": 0.9}
    assert seed_status(drift, tchk, gap, {"still_falling": False, "relative_drop": 0.0}, ev)[0] == "inconclusive"
    # the Moon, within one period's fit error: "none" is possible
    ev_moon = trajectory_evidence(moon, shoot)
    ev_moon["effect"] = "e"
    assert seed_status(drift, tchk, gap, {"still_falling": False, "relative_drop": 0.0}, ev_moon)[0] == "none"
