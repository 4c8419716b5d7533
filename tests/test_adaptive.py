"""The fast protocol (``--mode fast``): chunked training with convergence stopping, the adaptive λ grid, its verdicts."""

import itertools

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import nnphd  # noqa: F401
from nnphd.engine import adaptive
from nnphd.engine.adaptive import (
    ChunkTrainer,
    StopRule,
    fast_sweep,
    first_lambdas,
    make_chunk_trainer,
    train_converged,
    undecided,
)
from nnphd.engine.data import gaussian_dataset
from nnphd.engine.models import ModelConfig, init_nnphd
from nnphd.engine.train import (
    PAPER_LAMBDAS,
    SweepHooks,
    SweepPoint,
    SweepSchedule,
    TrainConfig,
    as_arrays,
    loss_terms,
    sweep,
)
from nnphd.engine.verdict import verdict
from nnphd.paper.sweep import SweepSettings, run_sweep

SMALL = ModelConfig(n=1, lnn_widths=(32, 32), uan_widths=(32, 32))


def _pts(lams, les):
    return [SweepPoint(lam, le, 0.0, le, 0.0) for lam, le in zip(lams, les)]


def test_first_lambdas_nearest_on_each_side():
    assert first_lambdas(PAPER_LAMBDAS) == (0.1, 0.5, 2.0, 10.0)
    assert first_lambdas((0.3, 0.7, 3.0, 30.0, 300.0)) == (0.3, 0.7, 3.0, 30.0)
    # 1 itself is never chosen; the same λ nearest two targets is trained once
    assert first_lambdas((0.01, 0.02, 1.0, 100.0, 200.0)) == (0.02, 100.0)
    assert first_lambdas((0.5, 5.0)) == (0.5, 5.0)


def test_undecided_reasons():
    lams = (0.1, 0.5, 2.0, 10.0)
    clear = _pts(lams, [1e-3, 1.2e-3, 0.30, 0.31])
    assert undecided(verdict(clear, 1.0), clear) == []
    flat = _pts(lams, [0.010, 0.011, 0.010, 0.012])
    none = _pts(lams, [0.020, 0.022, 0.012, 0.014])  # L_e lower above λ = 1: ×0.6
    assert undecided(verdict(none, 1.0), none) == []
    assert undecided(verdict(flat, 1.0), flat) != []  # ×1.05 is not clearly below ×1
    near = _pts(lams, [0.10, 0.10, 0.40, 0.40])  # ×4: in [×1, ×6)
    assert any("ratio" in w for w in undecided(verdict(near, 1.0), near))
    weak = _pts(lams, [0.10, 0.10, 0.12, 0.12])  # ×1.2: "no jump", but not clearly
    assert any("ratio" in w for w in undecided(verdict(weak, 1.0), weak))
    split = _pts(lams, [1e-3, 1e-2, 0.30, 0.31])  # the two below λ = 1 disagree ×10
    assert any("below" in w for w in undecided(verdict(split, 1.0), split))
    small = _pts(lams, [1e-6, 1e-6, 2e-4, 2e-4])  # remainder 2e-4 of the force: within ×3 of 1e-4
    assert any("remainder" in w for w in undecided(verdict(small, 1.0), small))


def test_undecided_when_the_uan_below_one_has_not_settled():
    """A jump whose UAN output differs ×1.5 between the λ below 1 is not reported (the HO+MF false jump at 800 steps:
    L_b 1.15 at λ = 0.1, 0.51 at λ = 0.5, L_e 0.078, 0.038 | 0.51, 0.51); a settled UAN (HO+LD: 0.41, 0.36) is."""

    def pts(le, lb):
        return [SweepPoint(lam, e, b, e, b) for lam, e, b in zip((0.1, 0.5, 2.0, 10.0), le, lb)]

    false_jump = pts([0.078, 0.038, 0.507, 0.506], [1.15, 0.512, 9e-5, 4e-5])
    v = verdict(false_jump, 1.11)
    assert v.new_physics and v.ratio > 6  # the verdict alone is a confident "detected"
    assert [w for w in undecided(v, false_jump) if "UAN" in w] and len(undecided(v, false_jump)) == 1
    settled = pts([0.0068, 0.0135, 0.335, 0.339], [0.408, 0.36, 6e-5, 3e-5])  # ×1.13
    assert undecided(verdict(settled, 0.88), settled) == []
    at_limit = pts([0.0068, 0.0135, 0.335, 0.339], [0.54, 0.36, 6e-5, 3e-5])  # ×1.5 exactly
    assert [w for w in undecided(verdict(at_limit, 0.88), at_limit) if "×1.5 " in w]
    # no jump claimed: an unsettled UAN does not matter (its output is noise next to L_e)
    none = pts([0.0036, 0.0031, 0.0028, 0.0028], [8e-4, 1.7e-4, 3e-5, 2e-5])
    assert undecided(verdict(none, 1.18), none) == []


def test_stop_rule_rejects():
    with pytest.raises(ValueError, match="chunk"):
        StopRule(chunk=0)
    with pytest.raises(ValueError, match="rel_tol"):
        StopRule(rel_tol=1.0)


@pytest.mark.slow  # a training run of 10-20 s: slow tier (`python3 dev.py test --slow`, and CI)
def test_chunk_trainer_objective_and_learning_rate():
    """``run`` returns L_e + λ L_b on all the data at its returned parameters; lr = 0 leaves them unchanged."""
    d = gaussian_dataset("ho+ld", 128, seed=0)
    tcfg = TrainConfig(steps=40)
    arrays = as_arrays(d, jnp.float64)
    run, init, _, _ = make_chunk_trainer(SMALL, tcfg, 10)
    p0 = init_nnphd(jax.random.PRNGKey(0), SMALL)
    lam = jnp.asarray(0.5)
    p1, _, obj = run(p0, init(p0), arrays, lam, jnp.asarray(1e-3), jax.random.PRNGKey(1))
    le, lb = loss_terms(p1, *arrays, SMALL, 1.0)
    assert abs(float(obj) - float(le + 0.5 * lb)) < 1e-12
    le0, lb0 = loss_terms(p0, *arrays, SMALL, 1.0)
    assert float(obj) < float(le0 + 0.5 * lb0)  # ten steps at lr 1e-3 lower it
    p10, _, _ = run(p0, init(p0), arrays, lam, jnp.asarray(1e-3), jax.random.PRNGKey(1), n_steps=10)
    p5, _, _ = run(p0, init(p0), arrays, lam, jnp.asarray(1e-3), jax.random.PRNGKey(1), n_steps=5)
    leaves = [jax.tree_util.tree_leaves(x) for x in (p1, p10, p5)]
    assert all(np.array_equal(a, b) for a, b in zip(leaves[0], leaves[1]))  # n_steps = chunk is the default
    assert not all(np.array_equal(a, b) for a, b in zip(leaves[0], leaves[2]))  # a shorter chunk is another run
    same, _, _ = run(p0, init(p0), arrays, lam, jnp.asarray(0.0), jax.random.PRNGKey(1))
    assert all(np.array_equal(a, b) for a, b in zip(jax.tree_util.tree_leaves(same), jax.tree_util.tree_leaves(p0)))


@pytest.mark.slow  # training runs: slow tier (`python3 dev.py test --slow`, and CI)
def test_train_converged_counts_its_steps():
    d = gaussian_dataset("ho+ld", 128, seed=0)
    tcfg = TrainConfig(steps=400)  # ≤ 100 steps per learning rate
    arrays = as_arrays(d, jnp.float64)
    p0 = init_nnphd(jax.random.PRNGKey(0), SMALL)
    tr = make_chunk_trainer(SMALL, tcfg, 20)
    # every chunk must improve the objective by 99%: each learning rate stops after its first chunk
    _, used = train_converged(tr, p0, arrays, 0.5, jax.random.PRNGKey(2), tcfg, StopRule(20, 0.99))
    assert used == 4 * 20
    # rel_tol 0: a learning rate stops at its first chunk that does not lower the objective. Record every chunk the
    # trainer runs (learning rate, length, objective) and check the count and the stops against that record
    calls = []

    def recording_run(params, opt_state, arrays, lam, lr, key, n_steps=tr.chunk):
        out = tr.run(params, opt_state, arrays, lam, lr, key, n_steps=n_steps)
        calls.append((float(lr), n_steps, float(out[2])))
        return out

    _, used = train_converged(
        ChunkTrainer(recording_run, tr.init, tr.objective, tr.chunk),
        p0,
        arrays,
        0.5,
        jax.random.PRNGKey(2),
        tcfg,
        StopRule(20, 0.0),
    )
    assert used == sum(n for _, n, _ in calls)  # the steps it reports are the steps it ran
    groups = [[(n, obj) for _, n, obj in g] for _, g in itertools.groupby(calls, key=lambda c: c[0])]
    assert [lr for lr, _ in itertools.groupby(c[0] for c in calls)] == list(tcfg.lrs)  # each learning rate, in order
    prev = float(tr.objective(p0, arrays, jnp.asarray(0.5, jnp.float64)))  # the objective before the first chunk
    for g in groups:
        assert all(n == 20 for n, _ in g) and sum(n for n, _ in g) <= 100  # 20-step chunks, ≤ 400 / 4 steps
        for k, (_, obj) in enumerate(g):
            last = k == len(g) - 1
            # every chunk but the last lowered the objective; the last did not, or it used up the 100 steps
            assert obj < prev or last, (g, prev)
            assert not last or obj >= prev or sum(n for n, _ in g) == 100, (g, prev)
            prev = obj
    # never stopping, it takes exactly the budget, also when a learning rate's share (30, 10) is not a multiple of
    # the chunk: its last chunk is shortened (it used to run 2 × 20 = 40 and 20 steps per learning rate)
    for steps in (120, 40):
        _, used = train_converged(tr, p0, arrays, 0.5, jax.random.PRNGKey(2), TrainConfig(steps=steps), None)
        assert used == steps


@pytest.mark.slow  # a sweep end to end: slow tier (`python3 dev.py test --slow`, and CI)
def test_fast_sweep_runs_the_paper_protocol_when_undecided(monkeypatch):
    tr = gaussian_dataset("ho+ld", 128, seed=0)
    tcfg = TrainConfig(steps=40)
    lams = (0.05, 0.1, 0.5, 2.0, 10.0, 20.0)
    real_undecided, chains = adaptive.undecided, []

    def spy(v, points):  # the real rule, remembering the 4-λ chain it judged
        chains.append(list(points))
        return real_undecided(v, points)

    monkeypatch.setattr(adaptive, "undecided", spy)
    pts, info = fast_sweep(tr, SMALL, tcfg, lams, rule=StopRule(10, 0.5))
    paper = sweep(tr, SMALL, tcfg, SweepSchedule(lams, "warm"), seed=0)
    # 40 steps per λ leave the chain far from converged: L_e below λ = 1 is 0.10-0.15 against 0.37-0.40 above it
    # (measured), a ratio ×3.1 inside the close band [×1, ×6) -> the paper protocol runs and its points are returned
    assert [p.lam for p in chains[0]] == [0.1, 0.5, 2.0, 10.0]
    assert info.paper_protocol and any("ratio" in w for w in info.doubts), info.doubts
    assert [(p.lam, p.L_e, p.L_b) for p in pts] == [(p.lam, p.L_e, p.L_b) for p in paper]
    # 40 steps over 4 learning rates is 10 per rate = one chunk of 10, which no stopping rule can shorten: each chain
    # λ trains 40 steps, and the paper protocol adds its 40 at every λ of the grid
    assert info.steps == {0.05: 40, 0.1: 80, 0.5: 80, 2.0: 80, 10.0: 80, 20.0: 40}
    # a decided verdict returns the 4-λ chain itself, and the same seed trains the same chain again
    monkeypatch.setattr(adaptive, "undecided", lambda v, p: [])
    again, info_d = fast_sweep(tr, SMALL, tcfg, lams, rule=StopRule(10, 0.5))
    assert [p.lam for p in again] == [0.1, 0.5, 2.0, 10.0] and info_d.doubts == [] and not info_d.paper_protocol
    assert info_d.steps == {0.1: 40, 0.5: 40, 2.0: 40, 10.0: 40}
    assert [(p.L_e, p.L_b) for p in again] == [(p.L_e, p.L_b) for p in chains[0]]  # same seed, same numbers
    monkeypatch.setattr(adaptive, "undecided", lambda v, p: ["forced"])
    saved = {}
    pts2, info2 = fast_sweep(
        tr, SMALL, tcfg, lams, rule=StopRule(10, 0.5), hooks=SweepHooks(on_point=lambda pt: saved.update({pt.lam: pt}))
    )
    assert info2.paper_protocol and info2.doubts == ["forced"]
    assert [(p.lam, p.L_e, p.L_b) for p in pts2] == [(p.lam, p.L_e, p.L_b) for p in paper]  # exactly the paper's
    assert sorted(saved) == list(lams)  # only the paper protocol's points are checkpointed
    # a resume continues the paper protocol: nothing is trained again
    pts3, info3 = fast_sweep(tr, SMALL, tcfg, lams, hooks=SweepHooks(resume=saved))
    assert info3.paper_protocol and [p.L_e for p in pts3] == [p.L_e for p in paper]


@pytest.mark.slow  # tens of seconds: run by `python3 dev.py test --slow` (and by CI)
def test_fast_mode_does_not_report_an_unlearned_lagrangian_as_a_jump():
    """HO+MF (conservative) at 800 steps per λ, 300 samples, seed 0: the 4-λ chain alone says "detected" (×8.7; the
    LNN had not learned the magnetic term when the UAN was switched off); the unsettled UAN (×2.25) sends it to the
    paper's protocol, which says no jump (×0.65). (This chain was first found at ``steps=600``, when a learning
    rate's share of 150 steps still ran as two chunks of 100; at 600 now the chain's L_e above λ = 1 disagrees ×166
    and sends it to the paper protocol for that reason.) Which doubt sends it there depends on the processor's
    rounding, which the undertrained chain amplifies: on another machine (2026-11-28, an AVX-512 Xeon) it was "L_e
    below λ = 1 varies ×5.03", and the paper protocol's verdict the same (×0.40)."""
    res = run_sweep("ho+mf", SweepSettings(seed=0, mode="fast", n_train=300, n_test=300, steps=800))
    pr = res.protocol
    assert pr["ran_paper_protocol"] and pr["doubts"], pr
    assert not res.new_physics and res.le_ratio < 2, res.verdict


@pytest.mark.slow  # tens of seconds: run by `python3 dev.py test --slow` (and by CI)
@pytest.mark.parametrize("name", ["ho+ld", "ho+mf"])
def test_fast_mode_verdicts(name):
    """--mode fast gives the right verdict on a damped and a conservative toy, in < 1/3 of the paper protocol's steps
    (HO+MF: or, where its chain is close on this processor's rounding, by the paper protocol with its doubts said)."""
    # 60 % of the paper's budget per λ (1200 of 2000 steps) and 300 samples; the paper-size runs are
    # benchmarks/time_to_verdict.py. With less HO+MF's 4-λ chain is undertrained: at 800 steps it claims a jump (the
    # test above), at 1000 too (its UAN below λ = 1 unsettled, so the paper protocol runs and says none) — this test
    # ran at 1000 before the chunk fix, when 1000 meant 1200 steps at the first λ and up to 300 per learning rate
    res = run_sweep(name, SweepSettings(seed=0, mode="fast", n_train=300, n_test=300, steps=1200))
    v = res.verdict
    conservative = name == "ho+mf"
    assert v.new_physics == (not conservative), v
    assert (res.le_ratio < 2) if conservative else (res.le_ratio > 6 and v.L_above > 0.1), v
    pr = res.protocol
    assert pr["first_lambdas"] == [0.1, 0.5, 2.0, 10.0]
    if conservative and pr["ran_paper_protocol"]:
        # HO+MF's chain at 1200 steps is close on some processors' rounding (2026-11-28, an AVX-512 Xeon: ×5.94 in
        # the close band [×1, ×6), L_e above λ = 1 ×123 apart; at 1600 steps still close): the fast mode then says
        # why and runs the paper protocol, whose verdict is checked above. On the machine before it decided alone.
        assert pr["doubts"], pr
    else:
        assert not pr["ran_paper_protocol"] and pr["steps_total"] < 1200 * len(PAPER_LAMBDAS) / 3, pr
    assert [r.lam for r in res.table] == [float(k) for k in pr["steps_by_lambda"]]
