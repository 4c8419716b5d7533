"""Loss, trainer, λ-sweep and verdict: numbers, reproducibility, resume, and the phase transition (reduced steps)."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import nnphd  # noqa: F401
from nnphd.engine.data import gaussian_dataset
from nnphd.engine.models import ModelConfig, init_nnphd, nnphd_forces
from nnphd.engine.systems import get_system
from nnphd.engine.train import (
    SweepHooks,
    SweepPoint,
    SweepSchedule,
    TrainConfig,
    loss_terms,
    make_trainer,
    parse_p,
    pnorm,
    sweep,
)
from nnphd.engine.verdict import verdict
from nnphd.paper.sweep import SweepSettings, run_sweep

SMALL = ModelConfig(n=1, lnn_widths=(32, 32), uan_widths=(32, 32))


@pytest.mark.parametrize("p", [1, 2, 3, 1.5])
def test_pnorm_is_the_papers_average(p):
    r = np.random.default_rng(0).normal(size=(50, 3))
    expected = (np.sum(np.abs(r) ** p) / r.size) ** (1 / p)
    assert abs(float(pnorm(jnp.asarray(r), p)) - expected) < 1e-12


def test_mse_is_squared_l2():
    r = np.random.default_rng(1).normal(size=(40, 2))
    assert abs(float(pnorm(jnp.asarray(r), "mse")) - np.mean(r**2)) < 1e-12


def test_pnorm_gradient_finite_at_zero():
    for p in (1, 2, 3, "mse"):
        g = jax.grad(lambda x, p=p: pnorm(x, p))(jnp.zeros((4, 2)))
        assert bool(jnp.all(jnp.isfinite(g)))


@pytest.mark.parametrize("bad", [0.5, 0, -1, "abc", float("nan")])
def test_parse_p_rejects(bad):
    with pytest.raises(ValueError, match="p must be"):
        parse_p(bad)


def test_parse_p_accepts():
    assert parse_p("mse") == "mse" and parse_p("2") == 2.0 and parse_p(1) == 1.0


@pytest.mark.slow  # a training run: slow tier (`python3 dev.py test --slow`, and CI)
def test_loss_terms_match_forces():
    d = gaussian_dataset("ho+ld", 64, seed=0)
    params = init_nnphd(jax.random.PRNGKey(0), SMALL)
    q, qd, t, qdd = (jnp.asarray(a) for a in (d.q, d.qd, d.t, d.qdd))
    le, lb = loss_terms(params, q, qd, t, qdd, SMALL, 2.0)
    fc, fn = nnphd_forces(params, q, qd, t, SMALL)
    assert abs(float(le) - np.sqrt(np.mean((np.asarray(fc + fn) - d.qdd) ** 2))) < 1e-12
    assert abs(float(lb) - np.sqrt(np.mean(np.asarray(fn) ** 2))) < 1e-12


def test_training_reduces_loss_and_is_reproducible():
    d = gaussian_dataset("ho+ld", 256, seed=0)
    arrays = tuple(jnp.asarray(a) for a in (d.q, d.qd, d.t, d.qdd))
    train = make_trainer(SMALL, TrainConfig(steps=200))
    p0 = init_nnphd(jax.random.PRNGKey(0), SMALL)
    p1, (le1, _) = train(p0, arrays, 0.2, jax.random.PRNGKey(1))
    p2, (le2, _) = train(p0, arrays, 0.2, jax.random.PRNGKey(1))
    _, (le3, _) = train(p0, arrays, 0.2, jax.random.PRNGKey(2))
    from nnphd.engine.train import evaluate

    before, after = evaluate(p0, d, SMALL, 1.0).L_e, evaluate(p1, d, SMALL, 1.0).L_e
    assert after < 0.25 * before, (before, after)
    np.testing.assert_array_equal(np.asarray(le1), np.asarray(le2))
    assert not np.array_equal(np.asarray(le1), np.asarray(le3))


def test_learning_rate_schedule_is_the_papers():
    sched = TrainConfig(steps=2000).schedule()
    assert [float(sched(s)) for s in (0, 499, 500, 999, 1000, 1500, 1999)] == pytest.approx(
        [1e-2, 1e-2, 1e-3, 1e-3, 1e-4, 1e-5, 1e-5]
    )


@pytest.mark.slow  # a vmapped sweep and its independent runs: slow tier (`python3 dev.py test --slow`, and CI)
def test_vmapped_sweep_equals_independent_runs():
    tr = gaussian_dataset("ho+ld", 200, seed=0)
    tcfg = TrainConfig(steps=40)
    pts = sweep(tr, SMALL, tcfg, SweepSchedule((0.2, 5.0), "vmap"), seed=3)
    # train λ=5 alone from the same init and key
    k_init, k_train = jax.random.split(jax.random.PRNGKey(3))
    train = make_trainer(SMALL, tcfg)
    arrays = tuple(jnp.asarray(a) for a in (tr.q, tr.qd, tr.t, tr.qdd))
    p, _ = train(init_nnphd(k_init, SMALL), arrays, 5.0, k_train)
    from nnphd.engine.train import evaluate

    assert abs(evaluate(p, tr, SMALL, 1.0).L_e - pts[1].L_e) < 1e-8


@pytest.mark.slow  # an interrupted and resumed sweep: slow tier (`python3 dev.py test --slow`, and CI)
def test_sweep_resumes_after_interruption(tmp_path, monkeypatch):
    settings = SweepSettings(
        p=1.0, steps=40, seed=1, lambdas=(0.1, 0.5, 2.0, 10.0), model_cfg=SMALL, n_train=100, n_test=100
    )
    full = run_sweep("ho+ld", settings)

    calls = {"n": 0}
    from nnphd.io.cache import Cache

    orig = Cache.checkpoint

    def save_then_die(self, *a, **k):  # the sweep checkpoints after every λ: interrupted after the second
        orig(self, *a, **k)
        calls["n"] += 1
        if calls["n"] == 2:
            raise KeyboardInterrupt

    monkeypatch.setattr(Cache, "checkpoint", save_then_die)
    with pytest.raises(KeyboardInterrupt):
        run_sweep("ho+ld", settings, out=tmp_path)
    monkeypatch.undo()
    assert calls["n"] == 2
    assert not (tmp_path / "results.json").exists()  # nothing half-written
    resumed = run_sweep("ho+ld", settings, out=tmp_path)
    assert resumed.resumed_lambdas == (0.1, 0.5)
    np.testing.assert_allclose([r.L_e for r in resumed.table], [r.L_e for r in full.table], rtol=1e-9)
    assert (tmp_path / "results.json").exists() and (tmp_path / "loss_vs_lambda.png").exists()
    assert not (tmp_path / ".checkpoint.npz").exists()


# ---- verdict on hand-made curves ----------------------------------------------------------------------------------


def _pts(values):
    lams = (0.05, 0.1, 0.2, 0.5, 2, 5, 10)
    return [SweepPoint(l, v, 0.3 if l < 1 else 0.0, v, 0.0) for l, v in zip(lams, values)]


def test_verdict_jump():
    v = verdict(_pts([0.002, 0.002, 0.003, 0.002, 0.35, 0.34, 0.33]), force_norm=1.0)
    assert v.new_physics and v.ratio == pytest.approx(0.34 / 0.002) and v.fn_size_from_jump == pytest.approx(0.34)


def test_verdict_no_jump():
    v = verdict(_pts([0.002, 0.002, 0.0015, 0.001, 0.0008, 0.0005, 0.0004]), force_norm=1.0)
    assert not v.new_physics and "no jump" in v.reason


def test_verdict_tiny_remainder_is_not_new_physics():
    v = verdict(_pts([1e-7, 1e-7, 1e-7, 1e-7, 1e-5, 1e-5, 1e-5]), force_norm=1.0)
    assert v.ratio == pytest.approx(100) and not v.new_physics


def test_verdict_needs_both_sides():
    with pytest.raises(ValueError, match="below and above"):
        verdict([SweepPoint(0.1, 0.1, 0.1, 0.1, 0.1)], 1.0)


# ---- the phase transition on the paper's toy systems (reduced steps: 300 per λ, paper widths) ---------------------

REDUCED_LAMBDAS = (0.05, 0.1, 0.2, 0.5, 2.0, 5.0, 10.0)


# ho+ld and ho+mf (a jump and none) in the fast tier; the other three in the slow tier
@pytest.mark.parametrize(
    "name",
    ["ho+ld", "ho+mf", *(pytest.param(n, marks=pytest.mark.slow) for n in ("ho+cd", "ho+pf", "ho+cg"))],
)
def test_phase_transition_reduced(name):
    s = get_system(name)
    res = run_sweep(s, SweepSettings(p=1.0, steps=300, seed=0, lambdas=REDUCED_LAMBDAS, n_train=1000, n_test=1000))
    v = res.verdict
    assert v.new_physics == (not s.conservative), v
    if not s.conservative:
        assert res.le_ratio > 3
        assert v.L_above > 0.1  # the non-conservative forces are ~0.3–0.5 in L1
    else:
        assert res.le_ratio < 2


@pytest.mark.slow  # tens of seconds: run by `python3 dev.py test --slow` (and by CI)
@pytest.mark.parametrize("name", ["ho+ld", "ho+mf"])
def test_phase_transition_reduced_float32(name):
    """float32 training (what a GPU user may choose): the same verdicts, within the same bands, as float64."""
    s = get_system(name)
    cfg = ModelConfig(n=s.n, dtype="float32")
    settings = SweepSettings(
        p=1.0, steps=300, seed=0, lambdas=REDUCED_LAMBDAS, model_cfg=cfg, n_train=1000, n_test=1000
    )
    res = run_sweep(s, settings)
    assert res.settings["model"]["dtype"] == "float32"
    v = res.verdict
    assert v.new_physics == (not s.conservative), v
    if not s.conservative:
        assert res.le_ratio > 3 and v.L_above > 0.1
    else:
        assert res.le_ratio < 2


def test_verdict_exact_fit_below_one():
    v = verdict(_pts([0.0, 0.0, 0.0, 0.0, 0.3, 0.3, 0.3]), force_norm=1.0)
    assert v.L_below == 0.0 and v.new_physics and v.ratio > 1e9


@pytest.mark.slow  # three λ-sweeps: slow tier (`python3 dev.py test --slow`, and CI)
def test_lambda_sweep_modes():
    """The one λ-sweep: "scratch" equals "vmap" (every λ from the same start and key), "warm" chains, ``accept``
    chooses what the chain keeps, ``resume`` skips finished λ."""
    from nnphd.engine.train import as_arrays, lambda_sweep

    sysm = get_system("ho+ld")
    tr = gaussian_dataset(sysm, 64, 0)
    tcfg = TrainConfig(steps=40)
    train = make_trainer(SMALL, tcfg)
    p0 = init_nnphd(jax.random.PRNGKey(0), SMALL)
    arrays, key, lams = as_arrays(tr, jnp.float64), jax.random.PRNGKey(1), (0.1, 2.0, 0.5)
    scratch = lambda_sweep(train, p0, arrays, SweepSchedule(lams, "scratch"), key)
    vm = lambda_sweep(train, p0, arrays, SweepSchedule(lams, "vmap"), key)
    assert list(scratch) == [0.1, 0.5, 2.0]
    for lam in lams:
        direct, _ = train(p0, arrays, jnp.asarray(lam), key)
        for a, b, c in zip(
            jax.tree_util.tree_leaves(scratch[lam]),
            jax.tree_util.tree_leaves(vm[lam]),
            jax.tree_util.tree_leaves(direct),
        ):
            np.testing.assert_allclose(a, b, atol=1e-10)
            np.testing.assert_array_equal(a, c)
    seen = []
    warm = lambda_sweep(
        train, p0, arrays, SweepSchedule(lams), key, SweepHooks(on_point=lambda lam, p: seen.append(lam))
    )
    k = jax.random.split(key, 3)
    p1, _ = train(p0, arrays, jnp.asarray(0.1), k[0])
    p2, _ = train(p1, arrays, jnp.asarray(0.5), k[1])
    np.testing.assert_array_equal(jax.tree_util.tree_leaves(warm[0.5])[0], jax.tree_util.tree_leaves(p2)[0])
    assert seen == [0.1, 0.5, 2.0]
    # accept keeps the old params: the chain continues from them; resume skips a λ and continues from its params
    kept = lambda_sweep(train, p0, arrays, SweepSchedule(lams), key, accept=lambda lam, p: p0)
    np.testing.assert_array_equal(jax.tree_util.tree_leaves(kept[2.0])[0], jax.tree_util.tree_leaves(p0)[0])
    seen.clear()
    hooks = SweepHooks(resume={0.1: p1}, on_point=lambda lam, p: seen.append(lam))
    res = lambda_sweep(train, p0, arrays, SweepSchedule(lams), key, hooks)
    assert seen == [0.5, 2.0]
    np.testing.assert_array_equal(jax.tree_util.tree_leaves(res[0.5])[0], jax.tree_util.tree_leaves(p2)[0])
    with pytest.raises(ValueError, match="mode must be one of"):
        lambda_sweep(train, p0, arrays, SweepSchedule(lams, "cold"), key)
