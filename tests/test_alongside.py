"""Work beside the run's own: the thread pools of nnphd carry the caller's JAX float64 setting and its
stage, a stage run on another thread is timed as one of its own, the law table on the conservative library fitted
beside the training is the one fitted after it, and RK4's stages written as a loop integrate as the four written
out."""

from __future__ import annotations

import json
import threading
import time

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import nnphd  # noqa: F401  (float64)
from nnphd.io.timing import StageTimer
from nnphd.parallel import Unit, alongside, as_here, run_units


def _dtype(_x=None):
    return str(jnp.zeros(1).dtype)


def _fit_dtype(ci, row, warm=None):
    return (ci, _dtype()), "warm"


@pytest.mark.parametrize("x64", [False, True])
def test_every_thread_pool_computes_in_the_callers_precision(x64):
    """``jax.enable_x64`` is thread-local: ``NNPhD.fit`` runs inside ``with jax.enable_x64(True)``, and its pool
    threads computed in float32 (its trajectory-level law fits failed). The test process has float64 on globally,
    so the pools are checked with the caller's setting off as well as on."""
    from nnphd.explain.trajectory import fit_rows, map_in_threads

    want = "float64" if x64 else "float32"
    with jax.enable_x64(x64):
        assert _dtype() == want
        assert map_in_threads(_dtype, [0, 1, 2], 2) == [want] * 3
        assert [d for _, d in fit_rows(_fit_dtype, "zero", ["a", "b"], 2)] == [want] * 3
        outs = run_units([Unit(f"u{i}", _dtype, {}) for i in range(2)], workers=2, threads=True)
        assert [o.value for o in outs.values()] == [want] * 2
        future, _cancel = alongside(lambda cancel: _dtype())
        assert future.result(timeout=60) == want


def test_as_here_carries_a_copy_of_the_context_per_call():
    import contextvars
    from concurrent.futures import ThreadPoolExecutor

    var = contextvars.ContextVar("v", default="unset")

    def seen_then_changed():
        before = var.get()
        var.set("changed")
        return before, var.get()

    token = var.set("caller")
    try:
        fn = as_here(seen_then_changed)
    finally:
        var.reset(token)
    assert var.get() == "unset"
    with ThreadPoolExecutor(2) as ex:  # the same wrapped function on two threads at once, each with its own copy
        assert list(ex.map(lambda _: fn(), range(4))) == [("caller", "changed")] * 4
    assert fn() == ("caller", "changed") and var.get() == "unset"  # here too, and the caller's context is untouched


def test_an_alongside_stage_is_timed_on_its_own_and_keeps_its_compilations():
    """A stage entered on another thread (``timer.alongside``): its wall seconds are its own and overlap the
    others' (not in their sum, so not in ``other_s``), and the compilations of its thread — and of the pools it
    starts — count in it, not in the stage the run is in meanwhile."""
    from nnphd.explain.trajectory import map_in_threads

    def beside(cancel):
        with timer.alongside("beside"):
            jax.jit(lambda x: jnp.tanh(x) * 7.0 - x)(jnp.arange(4.0)).block_until_ready()
            map_in_threads(lambda k: float(jax.jit(lambda x: jnp.cosh(x) + k)(jnp.ones(3))[0]), [1.0, 2.0], 2)
            time.sleep(0.2)
            return "done"

    with StageTimer() as timer:
        with timer.stage("main"):
            future, _ = alongside(beside)
            assert future.result(timeout=60) == "done"
            time.sleep(0.05)
    d = timer.to_dict()
    by = {s["stage"]: s for s in d["stages"]}
    assert by["beside"]["alongside"] is True and "alongside" not in by["main"]
    assert by["beside"]["s"] >= 0.2 and by["main"]["s"] >= by["beside"]["s"] + 0.05
    assert by["beside"]["compile_s"] > 0 and by["main"]["compile_s"] == 0.0
    assert d["other_s"] == pytest.approx(max(d["total_s"] - by["main"]["s"], 0.0), abs=1e-9)
    assert "alongside" in d["note"]


def _rk4_written_out(s0, tw, qw, gamma, w2, nsub):
    """The residual positions of a damped pendulum's windows by RK4 with its four stages written out (numpy)."""
    n = 1
    out = np.zeros_like(qw)

    def f(q_, v_):
        return v_, -w2 * np.sin(q_) - gamma * v_

    for w in range(len(s0)):
        q, v = s0[w, :n].copy(), s0[w, n:].copy()
        out[w, 0] = q
        for j in range(1, tw.shape[1]):
            h = (tw[w, j] - tw[w, j - 1]) / nsub
            for _ in range(nsub):
                k1q, k1v = f(q, v)
                k2q, k2v = f(q + 0.5 * h * k1q, v + 0.5 * h * k1v)
                k3q, k3v = f(q + 0.5 * h * k2q, v + 0.5 * h * k2v)
                k4q, k4v = f(q + h * k3q, v + h * k3v)
                q = q + h / 6.0 * (k1q + 2 * k2q + 2 * k3q + k4q)
                v = v + h / 6.0 * (k1v + 2 * k2v + 2 * k3v + k4v)
            out[w, j] = q
    return out - qw


@pytest.mark.parametrize("nsub", [1, 3])
def test_rk4_stages_in_a_loop_integrate_as_the_four_written_out(nsub):
    from nnphd.engine.shooting import Integrator, ShootingWindows, model_residuals, pad_windows, shooting_windows

    rng = np.random.default_rng(3)
    t = np.cumsum(rng.uniform(0.05, 0.12, 120))  # an uneven clock
    q = (0.6 * np.exp(-0.05 * t) * np.cos(2.0 * t))[:, None]
    qd = np.gradient(q[:, 0], t)[:, None]
    tw, qw, mask, s0 = pad_windows(shooting_windows([np.arange(t.size)], t, np.pi), t, q, (q, qd))
    t0w, tw = tw[:, 0].copy(), tw - tw[:, :1]

    def rhs(theta, q_, v_, tt, aux):
        return -aux * jnp.sin(q_) - theta[0] * v_

    windows = ShootingWindows(jnp.asarray(tw), jnp.asarray(t0w), jnp.asarray(qw), jnp.asarray(mask), jnp.asarray([1.0]))
    r = model_residuals(s0, jnp.asarray([0.07]), jnp.asarray(4.0), windows, Integrator(rhs, nsub))
    want = _rk4_written_out(s0, tw, qw, 0.07, 4.0, nsub) * mask[..., None]
    np.testing.assert_allclose(np.asarray(r), want, rtol=0, atol=1e-13)
    assert np.max(np.abs(want)) > 1e-3  # the positions moved away from the data: a comparison that can fail


def test_the_library_base_fitted_beside_the_training_is_the_one_fitted_after_it(tmp_path, monkeypatch):
    """detect_data starts the law table on the conservative library on a thread of its own before the training
    (:func:`nnphd.user.detect.library_alongside`): the same table as :func:`find_law` one after another."""
    from dataclasses import replace

    from nnphd.explain.search import LawRun, find_law
    from nnphd.user.derivatives import Derivatives
    from nnphd.user.detect import LIBRARY_ALONGSIDE, library_alongside
    from nnphd.user.recording import load_trajectories
    from tests.fixtures import friction as F

    monkeypatch.delenv("NNPHD_WORKER", raising=False)
    rec = F.make("heavy-damping", seed=0)
    ud = load_trajectories(rec.write_csv(tmp_path / "hd.csv"), rec.angles)
    d = Derivatives().dataset(ud)
    data, info, rows = d.data, d.info, d.row_errors
    traj = np.concatenate([np.full(b - a, i) for i, tr in enumerate(info["trajectories"]) for a, b in [tr["kept"]]])
    angles = [bool(a) for a in ud.is_angle]
    with StageTimer() as timer:
        run = LawRun(traj, tuple(ud.coords), tuple(angles), info, rows, timer=timer)
        job = library_alongside(data, run)
        assert job is not None
        beside = job[0].result(timeout=600)
    plain = find_law(data, LawRun(traj, tuple(ud.coords), tuple(angles), info, rows, level="auto", seed=0))
    assert plain.settings["method"] == "trajectory"  # the trajectory-level fits ran, both times
    # one coordinate: no funnel (the amplitude envelope ranks after the windows) — the whole shortlist was fitted
    assert plain.settings["funnel"]["reach"] is None and not plain.settings["funnel"]["cut"]
    assert plain.settings["funnel"]["shortlist"] == min(16, plain.settings["funnel"]["pointwise"])
    assert json.dumps(beside.to_dict(), sort_keys=True, default=str) == json.dumps(
        plain.to_dict(), sort_keys=True, default=str
    )
    assert {s["stage"]: s.get("alongside") for s in timer.to_dict()["stages"]} == {LIBRARY_ALONGSIDE: True}
    # not wanted beside: another field, a pointwise law, several coordinates, a worker of a batch (one core)
    assert library_alongside(data, replace(run, level="pointwise")) is None
    assert library_alongside(data, replace(run, field="uniform")) is None
    assert library_alongside(data, replace(run, coords=("x", "y"), is_angle=(False, False))) is None
    monkeypatch.setenv("NNPHD_WORKER", "1")
    assert library_alongside(data, run) is None


def test_a_cancelled_law_table_stops_before_its_next_stage(tmp_path):
    from concurrent.futures import CancelledError

    from nnphd.explain.search import LawRun, find_law
    from nnphd.user.derivatives import Derivatives
    from nnphd.user.recording import load_trajectories
    from tests.fixtures import friction as F

    rec = F.make("heavy-damping", seed=0)
    ud = load_trajectories(rec.write_csv(tmp_path / "hd.csv"), rec.angles)
    d = Derivatives().dataset(ud)
    data, info, rows = d.data, d.info, d.row_errors
    traj = np.zeros(len(data.t), int)
    stop = threading.Event()
    stop.set()
    with pytest.raises(CancelledError):
        find_law(data, LawRun(traj, tuple(ud.coords), tuple(bool(a) for a in ud.is_angle), info, rows), cancel=stop)


# two coordinates, an angle and a length, in the fast tier; one angle alone in the slow tier (a compilation each)
@pytest.mark.parametrize("n, angles", [pytest.param(1, (True,), marks=pytest.mark.slow), (2, (True, False))])
def test_the_conservative_columns_differentiated_per_row_are_jaxs_own(n, angles):
    """The trajectory-level law fits differentiate the conservative columns — (W, n, Kc), the LNN's f_c among them
    — once per row (rowwise_jvp over 2n directions) instead of once per direction of the shooting Jacobian (53 on a
    double pendulum: its Jacobians 3.5× faster): the same values, and JAX's own derivatives to rounding, for many
    directions at once as the Jacobian pushes them."""
    from nnphd.engine.shooting import rowwise_jvp
    from nnphd.explain.conservative import conservative_basis

    rng = np.random.default_rng(n)
    W = 6
    q, v = jnp.asarray(rng.normal(0, 0.7, (W, n))), jnp.asarray(rng.normal(0, 1.2, (W, n)))
    center = (jnp.full(n, 0.1), jnp.full(n, 0.8))  # (mean, std) of the non-angle coordinates

    def fc(q_, v_):  # a force of position and velocity, as an LNN's
        return -jnp.sin(q_) * (1 + 0.3 * v_**2) + 0.1 * jnp.roll(q_, 1, axis=1) * v_

    def cols(_, q_, v_):
        return conservative_basis(jnp, q_, v_, angles, fc(q_, v_), center, True)

    rows = rowwise_jvp(cols)
    dq, dv = jnp.asarray(rng.normal(size=(9, W, n))), jnp.asarray(rng.normal(size=(9, W, n)))
    # compiled, as the shooting Jacobian runs them (op by op the two took 15–50 s of the fast tier)
    own = jax.jit(jax.vmap(lambda a, b: jax.jvp(lambda x, y: cols(None, x, y), (q, v), (a, b))))(dq, dv)
    per_row = jax.jit(jax.vmap(lambda a, b: jax.jvp(lambda x, y: rows(None, x, y), (q, v), (a, b))))(dq, dv)
    assert own[0].shape == (9, W, n, cols(None, q, v).shape[-1]) and own[0].shape[-1] > 10
    assert np.array_equal(np.asarray(own[0]), np.asarray(per_row[0]))
    scale = float(jnp.max(jnp.abs(own[1])))
    assert scale > 1e-3 and float(jnp.max(jnp.abs(per_row[1] - own[1]))) <= 1e-12 * scale


# two coordinates, an angle and a length, in the fast tier; one angle alone in the slow tier (a compilation each)
@pytest.mark.parametrize("n, angles", [pytest.param(1, (True,), marks=pytest.mark.slow), (2, (True, False))])
def test_the_conservative_combination_differentiated_per_row_is_jaxs_own(n, angles):
    """The trajectory-level law fits' conservative part Σ α_k column_k (rowwise_combination): its state Jacobian
    per row contracted with α once, each direction of the shooting Jacobian then a (W, n) tangent (the double
    pendulum's trajectory-level fits 84 → 64 s) — the same values as the plain combination, and JAX's own
    derivatives to rounding, along state and coefficient directions at once."""
    from nnphd.engine.shooting import rowwise_combination
    from nnphd.explain.conservative import conservative_basis

    rng = np.random.default_rng(10 + n)
    W = 6
    q, v = jnp.asarray(rng.normal(0, 0.7, (W, n))), jnp.asarray(rng.normal(0, 1.2, (W, n)))
    center = (jnp.full(n, 0.1), jnp.full(n, 0.8))

    def fc(q_, v_):
        return -jnp.sin(q_) * (1 + 0.3 * v_**2) + 0.1 * jnp.roll(q_, 1, axis=1) * v_

    def cols(_, q_, v_):
        return conservative_basis(jnp, q_, v_, angles, fc(q_, v_), center, True)

    K = jax.eval_shape(lambda x, y: cols(None, x, y), q, v).shape[-1]
    c = jnp.asarray(rng.normal(size=K))

    def plain(c_, x, y):
        return jnp.einsum("wnk,k->wn", cols(None, x, y), c_)

    rows = rowwise_combination(cols)
    dc = jnp.asarray(rng.normal(size=(9, K)))
    dq, dv = jnp.asarray(rng.normal(size=(9, W, n))), jnp.asarray(rng.normal(size=(9, W, n)))
    # compiled, as the shooting Jacobian runs them (op by op: 20 s of the fast tier each)
    own = jax.jit(jax.vmap(lambda a, b, d: jax.jvp(plain, (c, q, v), (d, a, b))))(dq, dv, dc)
    per_row = jax.jit(jax.vmap(lambda a, b, d: jax.jvp(lambda c_, x, y: rows(None, c_, x, y), (c, q, v), (d, a, b))))(
        dq, dv, dc
    )
    assert own[1].shape == (9, W, n) and K > 10
    np.testing.assert_allclose(np.asarray(own[0]), np.asarray(per_row[0]), rtol=1e-14, atol=1e-15)
    scale = float(jnp.max(jnp.abs(own[1])))
    assert scale > 1e-3 and float(jnp.max(jnp.abs(per_row[1] - own[1]))) <= 1e-12 * scale
    # a coefficient direction alone moves the output by the columns times it
    only_c, by_c = jax.jit(lambda d: (jax.jvp(lambda c_: rows(None, c_, q, v), (c,), (d,))[1], plain(d, q, v)))(dc[0])
    np.testing.assert_allclose(np.asarray(only_c), np.asarray(by_c), rtol=1e-12, atol=1e-14)
