"""The law table's faster paths give the numbers of the plain ones, bit for bit: the shooting's residuals
and derivatives from their own compiled functions, the Levenberg–Marquardt search that keeps a trial's residuals,
the candidates' fits and the stops' integrations side by side on threads."""

from __future__ import annotations

import threading

import jax.numpy as jnp
import numpy as np
import pytest

import nnphd  # noqa: F401  (float64)
from nnphd.engine.shooting import (
    Integrator,
    LMSettings,
    ShootingWindows,
    damping_rhs,
    lm_windows,
    model_jac,
    model_residuals,
    model_residuals_and_jac,
    pad_windows,
    shooting_windows,
)

W0 = 1.1


def _accel(p, q, v):
    return -p * jnp.sin(q)


def _windows(gamma=0.02, noise=0.0025, seed=0):
    """A damped pendulum's noisy positions, cut into shooting windows: (args of the model functions, start states)."""
    rng = np.random.default_rng(seed)
    t = np.arange(0, 8 * 2 * np.pi / W0, 1 / 6)
    q = 0.5 * np.exp(-gamma * t / 2) * np.cos(W0 * t)
    qd = np.gradient(q, t)
    q, qd = (q + rng.normal(0, noise, t.size))[:, None], (qd + rng.normal(0, 2 * noise, t.size))[:, None]
    wins = shooting_windows([np.arange(t.size)], t, 2 * np.pi / W0)
    tw, qw, mask, s0 = pad_windows(wins, t, q, (q, qd))
    tw = tw - tw[:, :1]
    tw, qw, mask = jnp.asarray(tw), jnp.asarray(qw), jnp.asarray(mask)
    windows = ShootingWindows(tw, jnp.zeros(len(wins)), qw, mask, jnp.asarray([1 / noise]))
    return (jnp.asarray(W0**2), windows), s0


def test_residuals_and_derivatives_alone_are_those_of_the_joint_function():
    args, s0 = _windows()
    model = Integrator(damping_rhs(_accel), 2)
    for th in (np.zeros(2), np.array([0.03, 0.05])):
        r, jac = model_residuals_and_jac(s0, th, *args, model)
        assert np.array_equal(np.asarray(model_residuals(s0, th, *args, model)), np.asarray(r))
        assert np.array_equal(np.asarray(model_jac(s0, th, *args, model)), np.asarray(jac))


def test_the_search_that_keeps_its_trials_residuals_takes_the_same_steps():
    """lm_windows with the residuals and the derivatives from their own functions (a trial's residuals kept at an
    accepted point) ends where it ends with the joint function, bit for bit, with fewer simulations."""
    args, s0 = _windows()
    model = Integrator(damping_rhs(_accel), 2)
    calls = {"resjac": 0, "res": 0, "jac": 0}

    def counted(name, f):
        def g(s, th):
            calls[name] += 1
            return f(s, th, *args, model)

        return g

    resjac, res, jac = (counted(k, f) for k, f in (("resjac", model_residuals_and_jac), ("res", model_residuals),
                                                   ("jac", model_jac)))  # fmt: skip
    free = np.ones(2, bool)
    start = np.array([-0.5, 1.0])  # far: trial steps get rejected on the way
    a = lm_windows(resjac, s0, start, free, res=res)
    n_resjac, n_res = calls["resjac"], calls["res"]
    calls.update(resjac=0, res=0, jac=0)
    b = lm_windows(None, s0, start, free, res=res, jac_fn=jac)
    for x, y in zip(a, b):
        assert np.array_equal(np.asarray(x), np.asarray(y))
    assert calls["resjac"] == 0 and calls["jac"] == n_resjac and calls["res"] == n_res + 1
    assert n_res > n_resjac - 1  # some trials were rejected: the path is not trivial


@pytest.mark.parametrize("threads", [1, 2, 3])
def test_the_candidates_fits_come_back_in_order_whatever_the_threads(threads):
    """fit_rows: the zero law's entry first, then the candidates' in their order (those without one left out); the
    candidates start only once the zero law's fit is done, from it (its ``warm`` value)."""
    from nnphd.explain.trajectory import fit_rows

    done = threading.Event()
    started = []

    def fit(ci, row, warm=None):
        if ci == 0:
            assert warm is None and not started
            done.set()
            return (0, row), "zero's fit"
        started.append(ci)
        assert done.is_set() and warm == "zero's fit"
        return (None if row == "bad" else (ci, row)), ("unused", ci)

    cands = ["a", "bad", "c", "d", "bad", "f"]
    out = fit_rows(fit, "zero", cands, threads)
    assert out == [(0, "zero"), (1, "a"), (3, "c"), (4, "d"), (6, "f")]
    assert sorted(started) == [1, 2, 3, 4, 5, 6]


@pytest.mark.parametrize("threads", [1, 2])
def test_without_the_zero_laws_fit_nothing_is_ranked(threads):
    from nnphd.explain.trajectory import fit_rows

    seen = []

    def fit(ci, row, warm=None):
        seen.append(ci)
        return None, None

    assert fit_rows(fit, "zero", ["a", "b"], threads) is None
    assert seen == [0]  # the candidates are not fitted at all


def test_map_in_threads_does_not_start_the_rest_after_an_error():
    from nnphd.explain.trajectory import map_in_threads

    ran = []

    def fn(x):
        ran.append(x)
        if x == 0:
            raise ValueError("bad piece")
        threading.Event().wait(0.05)
        return x

    with pytest.raises(ValueError, match="bad piece"):
        map_in_threads(fn, list(range(40)), 2)
    assert len(ran) < 40


def test_map_in_threads_keeps_the_order():
    from nnphd.explain.trajectory import map_in_threads

    items = list(range(9))
    for threads in (1, 2, 4):
        assert map_in_threads(lambda x: x * x, items, threads) == [x * x for x in items]
    assert map_in_threads(lambda x: x, [], 2) == []


def _swing(q0, gam=0.3, mu=0.8, w2=50.0, dt=0.01, seconds=9.0):
    """The stick-slip pendulum of tests/test_stuck.py from rest at q0: (q, t)."""
    from tests.fixtures.friction import stick_slip_euler

    return stick_slip_euler(q0, gam, mu, w2, dt, seconds)


@pytest.mark.parametrize("with_fc", [False, True])
def test_the_stops_integrated_side_by_side_give_the_same_contradictions(with_fc):
    """Two swings that stop for good: their integrations on one thread and on two give the same contradictions,
    with a conservative force given as a JAX function (compiled once for the integration) or none."""
    from types import SimpleNamespace

    from nnphd.explain.families import families
    from nnphd.explain.search import moving_rows
    from nnphd.explain.stuck import StopSettings, stop_contradictions
    from nnphd.explain.table import LawTable, law_row, zero_row
    from nnphd.explain.trajectory import Motion

    (q1, t1), (q2, t2) = _swing(0.3), _swing(0.25)
    q, t = np.concatenate([q1, q2]), np.concatenate([t1, t2])
    traj = np.r_[np.zeros(len(t1), int), np.ones(len(t2), int)]
    qd = np.concatenate([np.gradient(q1, t1, axis=0), np.gradient(q2, t2, axis=0)])
    data = SimpleNamespace(q=q, qd=qd, qdd=np.zeros_like(q), t=t)
    info = {"per_coordinate": {"th": {"noise": 1e-4, "quantization_step": 0.0, "qdd": {"windows": [4]}}}}
    period = 2 * np.pi / np.sqrt(50.0)
    *_, rest = moving_rows(data, traj, ["th"], info, None, None, period, margin=False)
    assert len(rest["final"]) == 2

    def row(key, beta):
        fam = next(f for f in families(1, ["th"], np.ones(1)) if f.key == key)
        r = law_row(fam, np.asarray(beta, float), np.zeros(len(fam.nl_names)), 0.01 * np.ones(len(beta)), ["th"],
                    1.0, "trajectory")  # fmt: skip
        r.ic = r.delta_ic = -20.0
        r.conservative = np.array([1.0]) if with_fc else np.array([0.0, 50.0])
        r.conservative_cov = 1e-4 * np.eye(len(r.conservative))
        return r

    rows = [row("linear", [2.0]), row("quadratic", [3.0])]
    zero = zero_row(["th"], 1.0, 10, "trajectory")
    zero.ic = zero.delta_ic = 0.0
    settings = {"method": "trajectory", "names": ["th"], "library": False if with_fc else "short"}
    table = LawTable([rows[0], zero, rows[1]], rows[0], "r", 10.0, 1.0, "f", settings)
    fc_fn = (lambda q_, v_: -50.0 * jnp.sin(q_)) if with_fc else None
    outs = [stop_contradictions(table, rest["final"], Motion(q, qd, t, traj), period, angles=(True,), fc_fn=fc_fn,
                                stop=StopSettings(threads=k)) for k in (1, 2)]  # fmt: skip
    assert "linear" in outs[0] and outs[0] == outs[1]


def test_lowest_first_orders_the_starts_by_their_chi2():
    """The candidates' starts (the zero law's fit with the law at zero, at its pointwise values, the pointwise fit):
    the lowest χ² first, a start that blows up last, ties in their order."""
    from nnphd.explain.trajectory import lowest_first

    def res(s, u):
        return np.array([s, u]) if u != "inf" else np.array([np.inf])

    starts = [(1.0, 3.0, "a"), (0.0, 1.0, "b"), (1.0, "inf", "c"), (1.0, 0.0, "d"), (0.0, 1.0, "e")]
    assert [x[2] for x in lowest_first(res, starts)] == ["b", "d", "e", "a", "c"]


def test_lm_says_whether_it_converged():
    """lm_windows's ``info``: converged once χ² stops falling by more than ``tol``; not when the iterations run out
    first — the trajectory-level law fits start the candidates from the zero law's fit only where it converged."""
    args, s0 = _windows()
    model = Integrator(damping_rhs(_accel), 2)

    def res(s, th):
        return model_residuals(s, th, *args, model)

    def jac(s, th):
        return model_jac(s, th, *args, model)

    start, free = np.array([-0.5, 1.0]), np.ones(2, bool)
    done, capped = {}, {}
    full = lm_windows(None, s0, start, free, LMSettings(iters=40), res=res, jac_fn=jac, info=done)
    short = lm_windows(None, s0, start, free, LMSettings(iters=2), res=res, jac_fn=jac, info=capped)
    assert done == {"converged": True} and capped == {"converged": False}
    assert short[4] > full[4] * (1 + 1e-6)  # two iterations were not enough: χ² was still falling


def test_lm_statistical_stop_ends_within_a_share_of_a_standard_error():
    """With ``dof`` (LMSettings), LM stops once what χ² has still to fall (a geometric series from its last two
    falls) is below eps of the reduced χ²: fewer derivative evaluations from a far start, and every parameter within
    √(2·eps) of its standard error of the optimum that the relative tolerance alone reaches, χ² within eps·s²."""
    from nnphd.engine.shooting import normal_blocks, schur_complement, settled

    # the rule itself, on numbers: falls 4 then 2 (ρ = ½) leave 2 to fall, not below eps·χ²/dof = 0.01·1000/5 = 2
    lm = LMSettings(dof=5)
    assert not settled(2.0, 4.0, 1000.0, lm) and settled(1.9, 3.8, 1000.0, lm)
    assert not settled(1.0, None, 1000.0, lm) and not settled(1.0, 2.0, 1000.0, LMSettings())  # off without dof
    assert not settled(1.0, 0.5, 1000.0, LMSettings(dof=100))  # a growing fall: ρ capped at 0.95, 19 to go
    args, s0 = _windows()
    model = Integrator(damping_rhs(_accel), 2)
    calls = {"jac": 0}

    def res(s, th):
        return model_residuals(s, th, *args, model)

    def jac(s, th):
        calls["jac"] += 1
        return model_jac(s, th, *args, model)

    start, free = np.array([-0.5, 1.0]), np.ones(2, bool)
    s_t, th_t, r_t, j_t, c_t = lm_windows(None, s0, start, free, LMSettings(iters=60, tol=1e-14), res=res, jac_fn=jac)
    n_tight = calls["jac"]
    n_res, W = int(np.asarray(args[1].mask).sum()), s0.shape[0]
    dof = n_res - 2 * W - 2
    calls["jac"] = 0
    s_f, th_f, r_f, j_f, c_f = lm_windows(None, s0, start, free, LMSettings(iters=60, tol=1e-14, dof=dof), res=res,
                                          jac_fn=jac)  # fmt: skip
    assert calls["jac"] < n_tight
    s2 = c_t / dof
    assert c_t <= c_f <= c_t + 0.01 * s2
    AtA, AtB, BtB, Atr, Btr, _ = normal_blocks(r_t, j_t, 2)
    S, *_ = schur_complement(AtA, AtB, BtB, Atr, Btr, 0.0, free)
    se = np.sqrt(np.diag(s2 * np.linalg.inv(S.sum(0))))
    assert np.all(np.abs(th_f - th_t) <= np.sqrt(2 * 0.01) * se)
    assert np.max(np.abs(th_f - th_t) / se) > 1e-6  # it did stop short of the tight optimum
