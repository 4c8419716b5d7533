"""Shape classes: rows, windows and steps padded so that one compiled program serves records of many lengths, with
the padding inert — the same numbers as unpadded (to 1e-10), against references that pad nothing."""

import jax
import jax.numpy as jnp
import numpy as np
import optax
import pytest
from test_alongside import _rk4_written_out

from nnphd.engine.batching import bucket, by_rows, pad_rows, train_bucket
from nnphd.engine.shooting import (
    Integrator,
    ShootingWindows,
    model_jac,
    model_residuals,
    model_residuals_and_jac,
    pad_windows,
    shooting_windows,
    window_shape_class,
)
from nnphd.engine.train import TrainConfig, make_trainer, pnorm


def test_the_classes_of_rows_windows_and_steps():
    assert [bucket(n) for n in (1, 44, 1024, 1025, 4565, 16384)] == [1024, 1024, 1024, 2048, 8192, 16384]
    assert bucket(5, minimum=1) == 8 and bucket(1, minimum=1) == 1
    # training pads to one class up to 16384 rows, then 65536 (its padding is never drawn: memory only), then powers of 2
    assert [train_bucket(n) for n in (44, 1025, 5000, 16384, 16385, 40000, 70000)] == [16384] * 4 + [65536] * 2 + [
        131072
    ]
    assert window_shape_class(7, 10) == ((16,), 80)  # grid windows: compiled for MAX_WINDOW steps, run for their own
    assert window_shape_class(1, 58) == ((1,), 8192)  # a whole record: one window, up to 8192 steps one class
    assert window_shape_class(33, 80) == ((16, 16, 16), 80) and window_shape_class(64, 80) == ((16,) * 4, 80)
    assert window_shape_class(300, 80) == ((16,) * 19, 80)  # 16 at a time, the last call padded
    assert window_shape_class(1, 9000) == ((1,), 32768) and window_shape_class(2, 600) == (
        (1, 1),
        8192,
    )  # whole records
    assert (
        window_shape_class(9, 400) == ((1,) * 9, 8192)
        and window_shape_class(16, 400) == ((16,), 512)
        and window_shape_class(1, 1858)[1] == window_shape_class(1, 2322)[1]
    )
    # every record of two windows or more runs the same program
    assert {c for w in range(2, 1000) for c in window_shape_class(w, 30)[0]} == {16}
    # files of one kind and other lengths share a class: a few windows fewer, another period (steps per window)
    assert window_shape_class(40, 21) == window_shape_class(34, 21) == window_shape_class(36, 31)


def test_rows_padded_by_repeating_the_last_one():
    a = np.arange(6.0).reshape(3, 2)
    (p,) = pad_rows((a,), 5)
    assert p.shape == (5, 2) and np.array_equal(p[:3], a) and np.array_equal(p[3:], [[4.0, 5.0], [4.0, 5.0]])
    with pytest.raises(ValueError, match="cannot pad 3 rows to 2"):
        pad_rows((a,), 2)


def test_a_row_function_on_padded_rows_gives_the_unpadded_numbers():
    @jax.jit
    def f(w, a):
        return jnp.tanh(a @ w) ** 3

    rng = np.random.default_rng(4)
    w = rng.normal(size=(3, 4))
    calls = []

    def g(w_, a_):
        calls.append(a_.shape)
        return f(w_, a_)

    for n in (1, 37, 1100, 3000):  # 1024 rows a call: one shape for every record
        a = rng.normal(size=(n, 3))
        np.testing.assert_allclose(by_rows(g, w, a), np.tanh(a @ w) ** 3, rtol=1e-12, atol=1e-14)
    assert set(calls) == {(1024, 3)} and len(calls) == 1 + 1 + 2 + 3


def _reference_train(params, arrays, lam, key, tcfg, loss):
    """The trainer written plainly, on the unpadded rows (the row count a Python int)."""
    opt = optax.adam(tcfg.schedule())
    n = arrays[0].shape[0]

    def obj(p, batch):
        le, lb = loss(p, *batch)
        return le + lam * lb

    state = opt.init(params)
    for k in jax.random.split(key, tcfg.steps):
        idx = jax.random.randint(k, (tcfg.batch_size,), 0, n)
        g = jax.grad(obj)(params, tuple(a[idx] for a in arrays))
        up, state = opt.update(g, state, params)
        params = optax.apply_updates(params, up)
    return params


def test_training_on_rows_padded_to_their_class_is_training_on_the_rows():
    tcfg = TrainConfig(steps=40, batch_size=8)

    def loss(p, q, qd, t, qdd):  # a small nonlinear model: q̈ = a·tanh(b q) + c q̇
        r = p["a"] * jnp.tanh(p["b"] * q) + p["c"] * qd - qdd
        return pnorm(r, 1.0), pnorm(p["c"] * qd, 1.0)

    rng = np.random.default_rng(5)
    n = 44  # padded to 1024 by the trainer
    q, qd, t = rng.normal(size=(n, 1)), rng.normal(size=(n, 1)), rng.normal(size=(n, 1))
    qdd = -2.0 * np.tanh(0.7 * q) - 0.1 * qd
    arrays = tuple(jnp.asarray(a) for a in (q, qd, t, qdd))
    p0 = {"a": jnp.asarray(-1.0), "b": jnp.asarray(1.0), "c": jnp.asarray(0.0)}
    key, lam = jax.random.PRNGKey(7), jnp.asarray(0.5)
    got, _ = make_trainer(None, tcfg, loss)(p0, arrays, lam, key)
    want = _reference_train(p0, arrays, lam, key, tcfg, loss)
    for k in p0:
        np.testing.assert_allclose(float(got[k]), float(want[k]), rtol=1e-10, atol=1e-12)
    assert abs(float(got["a"]) - float(p0["a"])) > 1e-3  # it trained: a comparison that can fail


def _pendulum_windows(n_rows, periods=0.75):
    rng = np.random.default_rng(3)
    t = np.cumsum(rng.uniform(0.05, 0.12, n_rows))  # an uneven clock
    q = (0.6 * np.exp(-0.05 * t) * np.cos(2.0 * t))[:, None]
    qd = np.gradient(q[:, 0], t)[:, None]
    if periods == "halves":  # two whole records
        wins = [np.arange(t.size // 2), np.arange(t.size // 2, t.size)]
    elif periods is None:
        wins = [np.arange(t.size)]
    else:
        wins = shooting_windows([np.arange(t.size)], t, np.pi, periods=periods)
    tw, qw, mask, s0 = pad_windows(wins, t, q, (q, qd))
    t0w, tw = tw[:, 0].copy(), tw - tw[:, :1]
    windows = ShootingWindows(jnp.asarray(tw), jnp.asarray(t0w), jnp.asarray(qw), jnp.asarray(mask), jnp.asarray([1.0]))
    return windows, tw, qw, mask, s0


def _rhs(theta, q_, v_, tt, aux):
    return -aux * jnp.sin(q_) - theta[0] * v_


@pytest.mark.parametrize("n_rows, periods", [(120, 0.75), (5000, 0.75), (120, None), (300, "halves")])
def test_shooting_residuals_on_padded_windows_are_those_written_out(n_rows, periods):
    """7 windows (padded to 16); 130+ (16 at a time, the last call padded); one whole record of 120 steps
    (to 8192); two whole records of 150 steps (one a call, to 8192)."""
    windows, tw, qw, mask, s0 = _pendulum_windows(n_rows, periods)
    W, L = tw.shape
    assert window_shape_class(W, L) != ((W,), L) and (n_rows < 1000 or W > 128)
    if periods == "halves":
        assert window_shape_class(W, L) == ((1, 1), 8192)
    r = model_residuals(s0, jnp.asarray([0.07]), jnp.asarray(4.0), windows, Integrator(_rhs, 2))
    assert np.shape(r) == (W, L, 1)
    want = _rk4_written_out(s0, tw, qw, 0.07, 4.0, 2) * mask[..., None]
    np.testing.assert_allclose(np.asarray(r), want, rtol=0, atol=1e-12)
    assert np.max(np.abs(want)) > 1e-3


def test_shooting_derivatives_do_not_depend_on_the_padding_or_the_chunks():
    """The derivatives of 130+ windows (16 at a time, the last call padded) are, window for window, those of
    the same windows fitted in other classes (the first 8 alone; windows 3–5: padded windows),
    and match finite differences."""
    windows, tw, qw, mask, s0 = _pendulum_windows(5000)
    model, th, aux = Integrator(_rhs, 2), jnp.asarray([0.07]), jnp.asarray(4.0)
    r, jac = model_residuals_and_jac(s0, th, aux, windows, model)
    assert np.array_equal(np.asarray(model_jac(s0, th, aux, windows, model)), np.asarray(jac))
    assert np.array_equal(np.asarray(model_residuals(s0, th, aux, windows, model)), np.asarray(r))
    for sl in (slice(0, 8), slice(3, 6), slice(126, 131)):
        sub = ShootingWindows(*(a[sl] for a in windows[:4]), windows.inv_sigma)
        r_s, j_s = model_residuals_and_jac(s0[sl], th, aux, sub, model)
        np.testing.assert_allclose(np.asarray(r_s), np.asarray(r)[sl], rtol=0, atol=1e-10)
        np.testing.assert_allclose(np.asarray(j_s), np.asarray(jac)[:, sl], rtol=0, atol=1e-10)
    h = 1e-6
    fd = (np.asarray(model_residuals(s0, th.at[0].add(h), aux, windows, model)) - np.asarray(r)) / h
    np.testing.assert_allclose(np.asarray(jac)[-1], fd, rtol=0, atol=1e-4 * np.max(np.abs(fd)))
    assert np.max(np.abs(fd)) > 1e-3


def test_time_features_padded_to_one_width_train_as_the_record_s_own():
    # the UAN sees the time features at one width (zero columns appended, their first-layer weights zero): the same
    # training as on the record's own 1 + 2J columns, and the padded weights stay exactly zero
    from nnphd.engine.models import ModelConfig, free_force, init_free, widen_inputs
    from nnphd.user.scaling import TIME_FEATURE_WIDTH, padded_time_features, time_features

    cfg = ModelConfig(n=1, lnn_widths=(8,), uan_widths=(8, 8))
    tcfg = TrainConfig(steps=60, batch_size=16)

    def loss(p, q, qd, t, qdd):
        return pnorm(free_force(p, q, qd, t, cfg) - qdd, 1.0), jnp.zeros(())

    rng = np.random.default_rng(2)
    tp = np.sort(rng.uniform(0, 5.0, 90))
    feats = time_features(tp, 5.0)
    assert 3 <= feats.shape[1] < TIME_FEATURE_WIDTH  # 1 + 2J columns of the record's own
    wide = padded_time_features(feats)
    assert wide.shape == (90, TIME_FEATURE_WIDTH) and np.array_equal(wide[:, : feats.shape[1]], feats)
    assert not wide[:, feats.shape[1] :].any() and padded_time_features(np.zeros((4, 0))).shape == (4, 0)
    q, qd = rng.normal(size=(90, 1)), rng.normal(size=(90, 1))
    qdd = np.sin(1.3 * tp)[:, None] * q - 0.2 * qd  # a force that depends on time
    p0 = init_free(jax.random.PRNGKey(3), cfg, n_time=feats.shape[1])
    pw = widen_inputs(p0, TIME_FEATURE_WIDTH - feats.shape[1])
    assert pw[0]["w"].shape == (2 + TIME_FEATURE_WIDTH, 8)
    key, lam = jax.random.PRNGKey(4), jnp.asarray(0.0)
    train = make_trainer(cfg, tcfg, loss)
    own, _ = train(p0, tuple(jnp.asarray(a) for a in (q, qd, feats, qdd)), lam, key)
    padded, _ = train(pw, tuple(jnp.asarray(a) for a in (q, qd, wide, qdd)), lam, key)
    k = 2 + feats.shape[1]
    assert not np.asarray(padded[0]["w"][k:]).any()  # nothing learned on the zero columns
    np.testing.assert_allclose(np.asarray(padded[0]["w"][:k]), np.asarray(own[0]["w"]), rtol=1e-10, atol=1e-12)
    for a, b in zip(jax.tree_util.tree_leaves(padded[1:]), jax.tree_util.tree_leaves(own[1:])):
        np.testing.assert_allclose(np.asarray(a), np.asarray(b), rtol=1e-10, atol=1e-12)
    assert np.max(np.abs(np.asarray(own[0]["w"]) - np.asarray(p0[0]["w"]))) > 1e-3  # it trained


@pytest.mark.slow
def test_a_sparse_law_s_slots_and_the_fitted_directions_padded_change_no_number(tmp_path, monkeypatch):
    # the universal θ of the trajectory-level law fits pads a sparse law's coefficients to a multiple of SPARSE_SLOTS,
    # the fitted directions to a multiple of DIRECTION_STEP and θ to a multiple of THETA_STEP (one compiled program
    # for records whose sparse law keeps another number of terms): the same law table as with no padding
    from nnphd.explain import trajectory as T
    from nnphd.explain.search import LawRun, find_law
    from nnphd.user.derivatives import Derivatives
    from nnphd.user.recording import load_trajectories
    from tests.fixtures import laws as LF

    rec = LF.make("quadratic-drag-2d", seed=0)
    ud = load_trajectories(rec.write_csv(tmp_path / "d.csv"), [])
    d = Derivatives().dataset(ud)
    traj = np.concatenate([np.full(b - a, i) for i, tr in enumerate(d.info["trajectories"]) for a, b in [tr["kept"]]])
    run = LawRun(traj, tuple(ud.coords), tuple(bool(a) for a in ud.is_angle), d.info, d.row_errors, seed=0)
    for name in ("SPARSE_SLOTS", "DIRECTION_STEP", "THETA_STEP"):
        monkeypatch.setattr(T, name, 1)
    plain = find_law(d.data, run).to_dict()
    monkeypatch.setattr(T, "SPARSE_SLOTS", 5)  # the sparse law's 8 coefficients in 10 slots
    monkeypatch.setattr(T, "DIRECTION_STEP", 16)
    monkeypatch.setattr(T, "THETA_STEP", 64)  # θ with an unused tail
    padded = find_law(d.data, run).to_dict()
    assert padded["settings"]["method"] == plain["settings"]["method"] == "trajectory"
    assert len({c["law"]: c for c in padded["candidates"]}["sparse"]["params"]) == 8  # padding to do
    assert [c["law"] for c in padded["candidates"]] == [c["law"] for c in plain["candidates"]]
    for a, b in zip(padded["candidates"], plain["candidates"]):
        np.testing.assert_allclose(a["ic"], b["ic"], rtol=1e-8)
        for k in a["params"]:
            np.testing.assert_allclose(a["params"][k], b["params"][k], rtol=1e-6, atol=1e-9)
    assert padded["law"] == plain["law"]


@pytest.mark.slow
def test_a_conservative_base_with_its_numbers_apart_gives_the_table_of_the_closure(tmp_path):
    # the trained model's numbers enter the trajectory-level law fits as data of the program (ConservativeFn), not
    # as constants of it: the same law table as the same force written as a plain function
    import math

    from nnphd.explain.search import LawRun, find_law
    from nnphd.explain.trajectory import fc_parts
    from nnphd.user.assess import ConservativeFn
    from nnphd.user.derivatives import Derivatives
    from nnphd.user.recording import load_trajectories
    from tests.fixtures import friction as F

    rec = F.make("heavy-damping", seed=0)
    ud = load_trajectories(rec.write_csv(tmp_path / "hd.csv"), rec.angles)
    d = Derivatives().dataset(ud)
    traj = np.concatenate([np.full(b - a, i) for i, tr in enumerate(d.info["trajectories"]) for a, b in [tr["kept"]]])
    run = LawRun(traj, tuple(ud.coords), (True,), d.info, d.row_errors, seed=0)

    def apply(params, q, v):
        (w2,) = params
        return -w2 * jnp.sin(q)

    fn = ConservativeFn(apply, (jnp.asarray((2 * math.pi / 0.8) ** 2),))
    assert fc_parts(fn)[0] is apply and fc_parts(lambda q, v: q) == (None, ())
    fc = np.asarray(fn(jnp.asarray(d.data.q), jnp.asarray(d.data.qd)))
    apart = find_law(d.data, run, fc, fn).to_dict()
    closure = find_law(d.data, run, fc, lambda q, v: fn(q, v)).to_dict()
    assert apart["settings"]["method"] == "trajectory" and apart["settings"]["conservative_base"]
    assert apart["law"] == closure["law"] and apart["law"]["law"] == "linear"  # the look-alike's friction
    assert abs(apart["law"]["params"]["gamma"] - 2 * 0.13 * 2 * math.pi / 0.8) < 0.05
    for a, b in zip(apart["candidates"], closure["candidates"]):
        assert a["law"] == b["law"]
        np.testing.assert_allclose(a["ic"], b["ic"], rtol=1e-10)
        for k in a["params"]:
            np.testing.assert_allclose(a["params"][k], b["params"][k], rtol=1e-8, atol=1e-12)
