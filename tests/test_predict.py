"""Prediction experiment (paper Fig. 4): rollout alignment, physics of the baselines, determinism, CLI."""

import json
import re

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from nnphd.cli import main
from nnphd.engine.data import trajectory_dataset
from nnphd.engine.models import ModelConfig, lnn_accel
from nnphd.engine.systems import get_system
from nnphd.paper.predict import (
    MODELS,
    PredictionSettings,
    init_model,
    learned_power,
    model_forces,
    prediction_claims,
    rollout,
    run_prediction,
)
from nnphd.paper.study_results import PredictionResult

SMALL = dict(steps=200, widths=(32, 32), n_traj=600)  # train t ≤ 30, extrapolate to t = 60


@pytest.fixture(scope="module")
def small():
    return run_prediction(PredictionSettings(seed=1, **SMALL))


def _true_accel(params, q, qd, t):
    return get_system("double-pendulum").f(q, qd, t)


def test_rollout_of_the_true_force_reproduces_the_data():
    """Start at the data's state at t = 30 and integrate the true force: the data trajectory from t = 30 on, to 1e-8."""
    sysm = get_system("double-pendulum")
    d = trajectory_dataset(sysm, n_steps=2000)
    i0 = 300
    assert d.t[i0] == pytest.approx(30.0)
    t, q, qd = rollout(_true_accel, {}, d.q[i0], d.qd[i0], d.t[i0], 0.1, 2000 - i0)
    np.testing.assert_allclose(t, d.t[i0:], atol=1e-9)
    np.testing.assert_allclose(q, d.q[i0:], atol=1e-8)
    np.testing.assert_allclose(qd, d.qd[i0:], atol=1e-8)


def test_rollout_time_is_passed_to_the_force():
    """A force that depends on t only: q̈ = cos t from (0, 0) at t0 gives q = cos t0 − cos t − sin t0 (t − t0)."""
    accel = lambda params, q, qd, t: jnp.cos(t) * jnp.ones_like(q)  # noqa: E731
    t, q, _ = rollout(accel, {}, np.zeros(1), np.zeros(1), 2.0, 0.01, 300)
    exact = np.cos(2.0) - np.cos(t) - np.sin(2.0) * (t - 2.0)
    np.testing.assert_allclose(q[:, 0], exact, atol=1e-9)


@pytest.mark.slow  # training of three models: slow tier (`python3 dev.py test --slow`, and CI)
def test_models_forces_and_learned_power():
    cfg = ModelConfig(n=2, lnn_widths=(8, 8), uan_widths=(8, 8))
    key = jax.random.PRNGKey(0)
    rng = np.random.default_rng(0)
    q, qd, t = rng.normal(size=(5, 2)), rng.normal(size=(5, 2)), rng.normal(size=5)
    p = {k: init_model(k, key, cfg, uan_time=False) for k in MODELS}
    # the LNN alone is NNPhD's LNN (same initialisation) with no non-conservative part
    fc, fn = model_forces("lnn", p["lnn"], q, qd, t, cfg, False)
    np.testing.assert_array_equal(np.asarray(fn), 0.0)
    np.testing.assert_allclose(fc, model_forces("nnphd", p["nnphd"], q, qd, t, cfg, False)[0], rtol=1e-12)
    np.testing.assert_allclose(fc, lnn_accel(p["lnn"]["lnn"], q, qd, cfg), rtol=1e-12)
    # without t, the UAN ignores t
    a = model_forces("nnphd", p["nnphd"], q, qd, t, cfg, False)[1]
    b = model_forces("nnphd", p["nnphd"], q, qd, t + 100.0, cfg, False)[1]
    np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
    # the black box has no split
    np.testing.assert_array_equal(np.asarray(model_forces("blackbox", p["blackbox"], q, qd, t, cfg, False)[0]), 0.0)
    # with split_mass only (L_NN = 0 is not exactly true at init, but H_vv ≈ I + small): power ≈ q̇·f_n
    fn = rng.normal(size=(5, 2))
    pw = learned_power(p["lnn"]["lnn"], q, qd, fn, cfg)
    assert pw.shape == (5,) and np.all(np.isfinite(pw))
    zero = jax.tree_util.tree_map(jnp.zeros_like, p["lnn"]["lnn"])  # L = ½ q̇·q̇ exactly: H_vv = I
    np.testing.assert_allclose(learned_power(zero, q, qd, fn, cfg), np.sum(qd * fn, axis=1), rtol=1e-12)


@pytest.mark.slow  # tens of seconds: run by `python3 dev.py test --slow` (and by CI)
def test_small_run_numbers(small):
    res = small
    assert isinstance(res, PredictionResult)
    assert res.settings["seed"] == 1 and res.settings["steps"] == 200 and res.settings["lambda"] == 0.2
    assert res.settings["widths"] == [32, 32] and res.settings["t_split"] == 30.0
    assert list(res.metrics) == list(MODELS) == list(res.train_time_s)
    for kind in MODELS:
        m = res.metrics[kind]
        for key in ("theta1_rmse_30_40", "theta1_rmse_30_200", "energy_rmse_30_200", "train_force_error"):
            assert np.isfinite(getattr(m, key)) and getattr(m, key) > 0, (kind, key, m)
        assert m.diverged_at is None
        tx = m.t_error_exceeds
        assert tx == m.to_dict()["t_error_exceeds_0.1"] and (tx is None or 30.0 < tx <= 60.0 + 1e-9)
        assert m.theta1_rmse_30_40 <= m.theta1_rmse_30_200 * np.sqrt(301 / 101) + 1e-12  # subset of the window
    # the truth loses energy over [30, 60]
    assert res.truth.energy_loss > 0.1
    # an LNN cannot dissipate: its own learned energy is conserved along its rollout (up to RK4 error: far less than
    # it varies along the true, damped trajectory), and the true energy of its rollout drifts much less than the truth's
    assert res.lnn_energy_constancy.lnn_learned_energy_range_ratio < 0.05
    assert res.lnn_energy_constancy.lnn_true_energy_drift_over_truth_drift < 0.5
    # energy balance of the learned energy along the NNPhD rollout: dH/dt = q̇ᵀ H_vv f_n (an identity for the
    # model's own motion; the difference is the finite-difference and RK4 error)
    b = res.energy_balance
    assert b.rollout_finite and b.dHdt_vs_power_corr > 0.99 and b.dHdt_vs_power_rel_rms < 0.1
    # each claim's verdict is its threshold applied to the numbers reported above: NNPhD's energy RMSE against ½ × the
    # black box's and against the LNN's, the LNN's true-energy drift against 0.1 × the truth's, the training errors
    d = res.to_dict()
    m, c = d["metrics"], d["lnn_energy_constancy"]
    e = {k: m[k]["energy_rmse_30_200"] for k in MODELS}
    expected = [
        e["nnphd"] <= 0.5 * e["blackbox"],
        e["nnphd"] < e["lnn"],
        c["lnn_true_energy_drift_over_truth_drift"] < 0.1,
        m["lnn"]["train_force_error"] > m["nnphd"]["train_force_error"],
    ]
    assert [cl.met for cl in res.claims] == expected, res.claims
    # and each one turns with its numbers: an NNPhD with no energy or training error, beside an LNN whose energy does
    # not drift, meets all four; one with a huge error meets none that compare it (the drift claim is the LNN's)
    perfect = {**m, "nnphd": {**m["nnphd"], "energy_rmse_30_200": 0.0, "train_force_error": 0.0}}
    still = {**c, "lnn_true_energy_drift_over_truth_drift": 0.0}
    assert [cl["met"] for cl in prediction_claims(perfect, still, None)] == [True, True, True, True]
    awful = {**m, "nnphd": {**m["nnphd"], "energy_rmse_30_200": 1e300, "train_force_error": 1e300}}
    assert [cl["met"] for cl in prediction_claims(awful, still, None)] == [False, False, True, False]
    assert PredictionResult.from_dict(json.loads(json.dumps(d))).to_dict() == d  # JSON-able, and reads back


@pytest.mark.slow  # tens of seconds: run by `python3 dev.py test --slow` (and by CI)
def test_same_seed_same_numbers(small):
    again = run_prediction(PredictionSettings(seed=1, **SMALL))
    assert again.metrics == small.metrics
    assert again.energy_balance == small.energy_balance and again.claims == small.claims


def test_bad_settings_raise():
    with pytest.raises(ValueError, match="steps must be an integer"):
        run_prediction(PredictionSettings(steps=2))
    with pytest.raises(ValueError, match="t_split"):
        run_prediction(PredictionSettings(steps=8, n_traj=200, t_split=30.05))
    with pytest.raises(ValueError, match="λ must be > 0"):
        run_prediction(PredictionSettings(steps=8, lam=0))


@pytest.mark.slow  # tens of seconds: run by `python3 dev.py test --slow` (and by CI)
def test_cli_writes_results_and_figure(tmp_path, capsys):
    out = tmp_path / "p"
    rc = main(["predict", "--steps", "8", "--seed", "2", "--out", str(out)])
    assert rc == 0
    res = json.loads((out / "results.json").read_text())
    assert res["settings"]["steps"] == 8 and res["settings"]["seed"] == 2
    assert set(res["metrics"]) == set(MODELS) and res["wall_time_s"] > 0
    assert (out / "prediction.png").stat().st_size > 1000
    assert (out / "energy_balance.png").stat().st_size > 1000
    text = capsys.readouterr().out
    assert "NNPhD" in text and "black box" in text
    # each claim of results.json printed once, as "met: …" or "not met: …" with our numbers, as judged there
    flat = " ".join(text.split())  # the console wraps long lines
    assert len(re.findall(r"\b(?:not )?met: ", flat)) == len(res["claims"]) > 0, text
    for c in res["claims"]:
        line = f"met: {c['claim']} — {c['ours']}"
        assert (f"not {line}" in flat) is not c["met"] and line in flat, (c, text)


@pytest.mark.parametrize(
    "argv,msg",
    [
        (["predict", "--steps", "x"], "Invalid value for '--steps': Input should be a valid integer"),
        (["predict", "--steps", "2"], "Invalid value for '--steps': Input should be greater than or equal to 4"),
        (["predict", "--steps", "1.5"], "Invalid value for '--steps': Input should be a valid integer"),
        (["predict", "--seed", "-1"], "Invalid value for '--seed': Input should be greater than or equal to 0"),
    ],
)
def test_cli_bad_input(argv, msg, tmp_path, capsys):
    out = tmp_path / "never"
    assert main(argv + ["--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("error: ") and msg in err and "\n" not in err
    assert not out.exists()
