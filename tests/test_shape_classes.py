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
    import math

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
    monkeypatch.setattr(T, "FUNNEL_REACH", math.inf)  # every shortlisted family fitted: the sparse law among them
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


def test_the_fitted_directions_are_two_classes_whatever_the_data_keep():
    # a candidate's directions (α and its law's parameters, each a tangent simulation) are padded to one number for
    # every family but the sparse law and one for the sparse law: whether a record's sparse law is fitted, and how
    # many terms it keeps, no longer changes the other candidates' programs (a 2-D drag record: 48 directions each
    # with its 25-term sparse law among the fitted, 32 on its 80 % copy without it — two programs compiled again)
    from nnphd.explain.families import families, odd_monomials, sparse_family
    from nnphd.explain.trajectory import DIRECTION_STEP, SPARSE_SLOTS, Directions, parameter_layout, with_sparse_slots

    def up(p):
        return -(-p // DIRECTION_STEP) * DIRECTION_STEP

    def directions(n, Kc, support=None):
        names = [f"q{i}" for i in range(n)]
        fams = families(n, names, np.ones(n)) + ([] if support is None else [sparse_family(n, names, support)])
        return parameter_layout(with_sparse_slots(sorted(fams, key=lambda f: f.key), n), Kc)[1]

    for n, Kc in ((1, 5), (2, 23)):
        M = len(odd_monomials(n))
        few, many = np.zeros((n, M), bool), np.ones((n, M), bool)
        few[0, :3] = True
        many[0, 0] = False
        dirs = {directions(n, Kc), directions(n, Kc, few), directions(n, Kc, many)}
        largest = max(len(f.coef_names) + len(f.nl_names) for f in families(n, ["q"] * n, np.ones(n)))
        # the sparse class: its largest possible support (n × the odd monomials; 4 and 32 here)
        assert dirs == {Directions(up(Kc + largest), up(Kc + n * M))}, (n, dirs)
    assert directions(2, 23) == (32, 56)  # 23 + the largest built-in family's 6 → 32; 23 + 2 × 16 → 56
    # three coordinates (120 possible terms): a sparse law's class follows its slots (multiples of SPARSE_SLOTS)
    M3 = len(odd_monomials(3))
    few, many = np.zeros((3, M3), bool), np.ones((3, M3), bool)
    many[0, :20] = False
    few[0, :3] = True
    assert directions(3, 40).sparse == directions(3, 40, few).sparse == up(40 + SPARSE_SLOTS)
    assert directions(3, 40, many).sparse == up(40 + 3 * M3)  # 100 terms: 128 slots, at most the 120 possible
    d = directions(2, 23)
    sparse = sparse_family(2, ["x", "y"], np.ones((2, 16), bool))
    assert d.of(None) == d.of(families(2, ["x", "y"], np.ones(2))[0]) == 32 and d.of(sparse) == 56


def test_one_right_hand_side_per_structure_not_per_record():
    # the shooting programs take the universal right-hand side as a static argument hashed by identity: records of
    # other lengths (other speeds, other sparse supports, other trained numbers) with the same structure get the
    # same function object, so this process traces their programs once; another structure gets another
    from nnphd.explain.conservative import conservative_basis
    from nnphd.explain.families import families, odd_monomials, sparse_family
    from nnphd.explain.trajectory import universal_rhs, with_sparse_slots
    from nnphd.user.assess import ConservativeFn

    def fams(v_rms, support, sign="tanh"):
        return with_sparse_slots(
            [*families(2, ("x", "y"), np.asarray(v_rms), sign), sparse_family(2, ("x", "y"), support)], 2
        )

    M = len(odd_monomials(2))
    s1, s2 = np.zeros((2, M), bool), np.zeros((2, M), bool)
    s1[0, 0] = s2[1, :3] = True

    def apply(params, q, v):
        return -params[0] * q

    fc1, fc2 = ConservativeFn(apply, (jnp.asarray(1.0),)), ConservativeFn(apply, (jnp.asarray(3.0),))
    q, v, t = jnp.asarray([[0.3, -0.2], [0.1, 0.4]]), jnp.asarray([[0.5, 0.7], [-0.02, 0.01]]), jnp.zeros(2)
    Kc = conservative_basis(jnp, q, v, (False, False), fc2(q, v)).shape[-1]
    a = universal_rhs(fams([1.0, 2.0], s1), Kc, (False, False), fc1)
    b = universal_rhs(fams([0.3, 5.0], s2), Kc, (False, False), fc2)
    assert a is b  # speeds, supports and the force's numbers are data of the program
    others = [
        universal_rhs(fams([1.0, 2.0], s1, "sqrt"), Kc, (False, False), fc1),  # another smoothed sign
        universal_rhs(fams([1.0, 2.0], s1), Kc + 1, (False, False), fc1),  # another conservative library
        universal_rhs(fams([1.0, 2.0], s1), Kc, (True, False), fc1),  # an angle
        universal_rhs(fams([1.0, 2.0], s1), Kc, (False, False), None),  # no trained force
        universal_rhs(fams([1.0, 2.0], s1), Kc, (False, False), lambda q, v: -q),  # a force without its numbers
        universal_rhs(fams([1.0, 2.0], s1)[:-1], Kc, (False, False), fc1),  # a family fewer
        universal_rhs(fams([1.0, 2.0], s1), Kc, (False, False), fc1, "short"),  # another library
    ]
    assert len({id(r) for r in [a, *others]}) == 1 + len(others)
    # and the shared function computes each record's own law: its speeds and its sparse support from aux
    from nnphd.explain.trajectory import builtin_speeds, coef_slots, sparse_supports

    # (two of the families: the program of them all compiles for ~10 s; the switch over families is the same code)
    F2 = with_sparse_slots(
        [next(f for f in families(2, ("x", "y"), np.asarray([0.3, 5.0]), "tanh") if f.key == "coulomb"),
         sparse_family(2, ("x", "y"), s2)], 2)  # fmt: skip
    b = universal_rhs(F2, Kc, (False, False), fc2)
    aux_data = (None, jnp.asarray(builtin_speeds(F2)[0]),
                tuple((jnp.asarray(i), jnp.asarray(m)) for i, m in sparse_supports(F2)), fc2.params)  # fmt: skip
    sizes = [coef_slots(f) + len(f.nl_names) + 1 for f in F2]
    for key in ("coulomb", "sparse"):
        k = next(i for i, f in enumerate(F2) if f.key == key)
        f, off = F2[k], Kc + sum(sizes[:k])
        K = len(f.coef_names)
        theta = np.zeros(Kc + sum(sizes))  # α = 0: the law's term alone
        theta[off : off + K] = np.linspace(0.5, 1.5, K)
        theta[off + coef_slots(f) + len(f.nl_names)] = 1.0  # its gate
        aux = (jnp.asarray(theta), jnp.zeros((0, theta.size)), jnp.asarray(k + 1, jnp.int32), *aux_data)
        got = np.asarray(jax.jit(b)(jnp.zeros(0), q, v, t, aux))
        want = np.einsum("wnk,k->wn", np.asarray(f.basis(jnp, jnp.zeros(0), q, v, t)), theta[off : off + K])
        assert np.abs(want).max() > 0.1
        np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-15)


@pytest.mark.slow
def test_every_tie_set_s_whole_record_fit_runs_the_table_s_one_program(tmp_path, monkeypatch):
    # a tie's whole-record fits hold the pointwise table's whole library in the right-hand side (library_of), so
    # another tie set runs the same program; the fitted numbers are the tie's own (the other families' slots unused)
    from dataclasses import replace

    from nnphd.explain import trajectory as T
    from nnphd.explain import wholerecord as W
    from nnphd.explain.search import LawRun, find_law
    from nnphd.user.derivatives import Derivatives
    from nnphd.user.recording import load_trajectories
    from tests.fixtures import friction as F

    rec = F.make("heavy-damping", seed=0)
    ud = load_trajectories(rec.write_csv(tmp_path / "hd.csv"), rec.angles)
    d = Derivatives().dataset(ud)
    traj = np.concatenate([np.full(b - a, i) for i, tr in enumerate(d.info["trajectories"]) for a, b in [tr["kept"]]])
    ctx = find_law(d.data, LawRun(traj, tuple(ud.coords), (True,), d.info, d.row_errors, seed=0)).whole_record
    pw = ctx["pointwise"]
    keys = [r.key for r in pw.rows if r.key != "none"]
    made = []
    shared = T.universal_rhs
    monkeypatch.setattr(T, "universal_rhs", lambda *a, **k: made.append(shared(*a, **k)) or made[-1])
    fits = [W.whole_record_fits(ctx, ks)[0] for ks in (keys[:2], keys[2:4])]
    assert all(f is not None and len(f) == 1 for f in fits)
    assert len(made) == 2 and made[0] is made[1]
    for ks, ((_, wide),) in zip((keys[:2], keys[2:4]), fits):
        by_key = {r.key: r for r in pw.rows}
        sub = replace(pw, rows=[by_key["none"], *(by_key[k] for k in ks)], law=None, ties=[])
        own = T.rank_trajectory(
            sub, T.Motion(ctx["q"], ctx["qd"], ctx["t"], ctx["traj"]), sigma=ctx["sigma"], period=ctx["period"],
            angles=ctx["angles"], windows=T.WindowPlan(window_periods=(0.75,), min_windows=W.ALL_WINDOWS,
                                                       allow_in_sample=True), settings=T.TrajectorySettings(seed=0),
        )  # fmt: skip
        assert made[-1] is not made[0]  # its own program: the tied families alone
        assert [r.key for r in wide.rows] == [r.key for r in own.rows] and set(ks) <= {r.key for r in own.rows}
        for a, b in zip(wide.rows, own.rows):
            np.testing.assert_allclose(a.heldout_mse, b.heldout_mse, rtol=1e-10)
            assert a.params.keys() == b.params.keys()
            for k in a.params:
                np.testing.assert_allclose(a.params[k], b.params[k], rtol=1e-9, atol=1e-12)
