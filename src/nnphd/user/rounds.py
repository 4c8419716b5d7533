"""The training rounds of one seed of :func:`nnphd.user.assess.assess`: the λ-sweep of NNPhD with its optimisation
check, the LNN alone continued to its floor, a free model of (q, q̇), the time regressions and the whole-record
evidence, then the checks of :mod:`nnphd.user.checks` on them."""

from __future__ import annotations

import functools
import time
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from nnphd._config import release_compiled_if_crowded
from nnphd.engine.batching import by_rows
from nnphd.engine.evidence import energy_trend, evidence_block, fit_error_bound
from nnphd.engine.models import (
    ModelConfig,
    embed_periodic,
    free_force,
    init_free,
    init_lnn,
    lnn_accel,
    lnn_derivatives,
    lnn_energy,
    widen_inputs,
)
from nnphd.engine.shooting import ShootingData, ShootingOptions, shooting_fit
from nnphd.engine.train import (
    SweepHooks,
    SweepPoint,
    SweepSchedule,
    TrainConfig,
    lambda_sweep,
    make_trainer,
    pnorm,
)
from nnphd.engine.verdict import verdict as naive_verdict
from nnphd.user.checks import (
    by_learned_power,
    capacity_check,
    drift_check,
    effect_text,
    energy_net_fraction,
    gap_check,
    ridge_fit_predict,
    seed_status,
    time_check,
    time_design,
    trajectory_evidence,
)
from nnphd.user.result import ConservativeModel, Status
from nnphd.user.scaling import (
    holdout,
    oscillations,
    padded_time_features,
    shoot_units,
    time_features,
    trend_units,
)

REPRESENTATIVE_LAMBDA = 0.2


@functools.lru_cache(maxsize=64)
def _trainer(kind: str, cfg: ModelConfig, tcfg: TrainConfig):
    """Jitted trainers, cached so repeated calls (seeds, tests) compile once. ``t`` carries the time features."""
    p = tcfg.p

    if kind == "nnphd":

        def loss(params, q, qd, t, qdd):
            fn = free_force(params["uan"], q, qd, t, cfg)
            return pnorm(lnn_accel(params["lnn"], q, qd, cfg) + fn - qdd, p), pnorm(fn, p)
    elif kind == "lnn":

        def loss(params, q, qd, t, qdd):
            return pnorm(lnn_accel(params["lnn"], q, qd, cfg) - qdd, p), jnp.zeros((), q.dtype)
    elif kind == "free":

        def loss(params, q, qd, t, qdd):
            return pnorm(free_force(params["mlp"], q, qd, None, cfg) - qdd, p), jnp.zeros((), q.dtype)
    else:  # pragma: no cover
        raise ValueError(kind)
    return make_trainer(cfg, tcfg, loss, export_key=f"rounds._trainer|{kind}")


@functools.partial(jax.jit, static_argnames=("cfg",))
def _nnphd_eval(params, q, qd, t, cfg):
    fc = lnn_accel(params["lnn"], q, qd, cfg)
    fn = free_force(params["uan"], q, qd, t, cfg)
    _, hvv, _ = lnn_derivatives(params["lnn"], q, qd, cfg)
    return fc, fn, jnp.einsum("bi,bij,bj->b", qd, hvv, fn), jnp.abs(jnp.einsum("bi,bij,bj->b", qd, hvv, qd))


@functools.partial(jax.jit, static_argnames=("cfg",))
def _lnn_eval(lnn, q, qd, qdd, cfg):
    fc = lnn_accel(lnn, q, qd, cfg)
    _, hvv, _ = lnn_derivatives(lnn, q, qd, cfg)
    power = jnp.einsum("bi,bij,bj->b", qd, hvv, qdd - fc)
    kin = jnp.einsum("bi,bij,bj->b", qd, hvv, qd)
    return fc, power, jnp.abs(kin), lnn_energy(lnn, q, qd, cfg), lnn_energy(lnn, q, jnp.zeros_like(qd), cfg), kin


@functools.partial(jax.jit, static_argnames=("cfg",))
def _free_eval(params, q, qd, cfg):
    return free_force(params["mlp"], q, qd, None, cfg)


@functools.lru_cache(maxsize=64)
def lnn_accel_fn(cfg: ModelConfig):
    """f_c(params, q, q̇) of an LNN config: one function object per config, so the shooting fit compiles once."""

    def accel(lnn, q, qd):
        return lnn_accel(lnn, q, qd, cfg)

    accel.export_key = f"lnn_accel|{cfg!r}"  # what it computes, for stored programs (nnphd.engine.stored)
    return accel


RIDGE_ROWS = 20000  # rows of the time-dependence regressions (check d); more are thinned evenly


def _thin(n: int, cap: int):
    """(selected rows, map of row indices → positions among them): all rows up to ``cap``, else ``cap`` evenly
    spaced ones (a trajectory keeps its evenly spaced rows)."""
    if n <= cap:
        return slice(None), lambda idx: idx
    sel = np.unique(np.linspace(0, n - 1, cap).round().astype(int))
    keep = np.zeros(n, bool)
    keep[sel] = True
    pos = np.cumsum(keep) - 1
    return sel, lambda idx: pos[np.asarray(idx)[keep[np.asarray(idx)]]]


def _l1(r) -> float:
    return float(np.mean(np.abs(r))) if np.size(r) else float("nan")


def _seg_mean(x, segs):
    return np.asarray([float(np.mean(x[s])) for s in segs])


def _sweep(ctx: dict, d: _Split, train, params, k_sweep, back, tick, per_lambda=None):
    """The warm-started λ-sweep of ``train`` from ``params`` over ``ctx["lambdas"]`` on the training rows of ``d``;
    then the optimisation check: the training error below λ = 1 (where the UAN is free) must not exceed the one above
    it. Where it does (beyond 10 %), the λ < 1 points are retrained in decreasing order, warm-started from the
    largest-λ solution (the UAN then only has to add to a fitted LNN), and the better objective is kept.
    ``per_lambda``: a dict given the wall seconds of each λ's training (compilation included)."""
    cfg, qdd = ctx["cfg"], ctx["qdd"]
    arrays, A_tr, tr, te, fnorm_te = d.arrays, d.A_tr, d.tr, d.te, d.fnorm_te
    lams = sorted(ctx["lambdas"])
    last = [time.perf_counter()]

    def point(lam, p):  # each λ's training, finished (JAX dispatches asynchronously) and timed
        if per_lambda is not None:
            jax.block_until_ready(p)
            now = time.perf_counter()
            per_lambda[float(lam)] = per_lambda.get(float(lam), 0.0) + now - last[0]
            last[0] = now

    pts = lambda_sweep(
        train,
        params,
        A_tr,
        SweepSchedule(lams, "warm"),
        k_sweep,
        SweepHooks(on_point=point, progress=lambda *_: tick()),
    )

    def evaluate(p):
        fc, fn, power, kin = by_rows(_nnphd_eval, p, *arrays[:3], cfg=cfg)
        return fc, fn, power, kin, back(fc + fn - qdd), back(fn)

    evals = {lam: evaluate(pts[lam]) for lam in lams}
    below = [lam for lam in lams if lam < 1]
    above = [lam for lam in lams if lam > 1]

    def med_train(ls):
        return float(np.median([_l1(evals[lam][4][tr]) for lam in ls])) if ls else float("nan")

    check = {"L_e_train_below": med_train(below), "L_e_train_above": med_train(above), "retrained": False}
    if below and above and check["L_e_train_below"] > 1.1 * check["L_e_train_above"]:
        check["retrained"] = True

        def keep_better(lam, p):  # the chain continues from whichever of the two has the lower objective
            ev = evaluate(p)
            obj_new = _l1(ev[4][tr]) + lam * _l1(ev[5][tr])
            obj_old = _l1(evals[lam][4][tr]) + lam * _l1(evals[lam][5][tr])
            if obj_new < obj_old:
                pts[lam], evals[lam] = p, ev
            return pts[lam]

        last[0] = time.perf_counter()
        lambda_sweep(
            train,
            pts[lams[-1]],
            A_tr,
            SweepSchedule(below, "warm", descending=True),
            jax.random.fold_in(k_sweep, 1),
            SweepHooks(on_point=point),
            accept=keep_better,
        )
        check["L_e_train_below_after"] = med_train(below)
    table = []
    for lam in lams:
        _, _, _, _, r, fnb = evals[lam]
        table.append(
            {
                "lam": lam,
                "L_e": _l1(r[te]),
                "L_b": _l1(fnb[te]),
                "L_e_train": _l1(r[tr]),
                "L_b_train": _l1(fnb[tr]),
                "L_e_rel": _l1(r[te]) / fnorm_te,
                "L_b_rel": _l1(fnb[te]) / fnorm_te,
            }
        )
    check["ok"] = not below or not above or med_train(below) <= 1.1 * med_train(above)
    if below and above:  # the same comparison on held-out data: a free UAN that generalises worse than none
        held = [float(np.median([r["L_e"] for r in table if (r["lam"] < 1) == side])) for side in (True, False)]
        check.update(L_e_heldout_below=held[0], L_e_heldout_above=held[1], heldout_ok=held[0] <= 1.5 * held[1])
    return pts, evals, table, check


class _Split(NamedTuple):
    """One seed's held-out split of the rows, the data as JAX arrays and the force scales (original units)."""

    tr_segs: list  # the training trajectories (row indices of each)
    te_segs: list  # the held-out trajectories
    tr: np.ndarray  # the training rows
    te: np.ndarray  # the held-out rows
    arrays: tuple  # (q, q̇, time features, q̈) on all rows, as JAX arrays
    A_tr: tuple  # the same on the training rows
    fnorm: float  # ‖f‖ over all data
    fnorm_te: float  # ‖f‖ over the held-out rows (the whole record's where these are at rest)
    fnorm_tr: float  # ‖f‖ over the training rows


def _holdout_split(ctx: dict, seed: int, back) -> _Split:
    """The held-out trajectories of seed ``seed`` (:func:`nnphd.user.scaling.holdout`), the arrays the networks
    train on and the force scales the errors are divided by."""
    q, qd, qdd, segs, feats = ctx["q"], ctx["qd"], ctx["qdd"], ctx["segs"], ctx["feats"]
    rng = np.random.default_rng(seed)
    tr_segs, te_segs = holdout(segs, ctx["holdout_frac"], rng)
    tr, te = np.concatenate(tr_segs), np.concatenate(te_segs)
    # copied and indexed on the host: jnp.asarray and a JAX array indexed by rows compile small programs for each
    # number of rows (0.6 s of XLA on a second file of another length); device_put and numpy's indexing compile none
    host = tuple(np.asarray(a) for a in (q, qd, padded_time_features(feats), qdd))
    arrays = tuple(jax.device_put(a) for a in host)
    A_tr = tuple(jax.device_put(a[tr]) for a in host)
    fnorm = _l1(back(qdd))  # ‖f‖ over all data, original units
    fnorm_te = _l1(back(qdd[te]))
    if not fnorm_te > 0:  # a held-out stretch at rest (a recording that ends stuck): scale by the whole record's
        fnorm_te = fnorm  # force instead of dividing by zero (the relative held-out errors are then of that scale)
    fnorm_tr = _l1(back(qdd[tr]))
    return _Split(tr_segs, te_segs, tr, te, arrays, A_tr, fnorm, fnorm_te, fnorm_tr)


class _Stopwatch:
    """The wall seconds of each stage of one seed, by stage name in the order the stages end."""

    def __init__(self) -> None:
        self.times: dict[str, float] = {}
        self._last = time.perf_counter()

    def done(self, stage: str) -> None:
        """The wall seconds since the last stage ended (its results are numbers by now)."""
        now = time.perf_counter()
        self.times[stage] = now - self._last
        self._last = now


def _naive(table: list[dict], fnorm_te: float) -> dict:
    """The naive verdict of :func:`nnphd.engine.verdict.verdict` on the λ-sweep's table."""
    points = [SweepPoint(r["lam"], r["L_e"], r["L_b"], r["L_e_train"], r["L_b_train"]) for r in table]
    try:
        nv = naive_verdict(points, fnorm_te)
        naive = {"new_physics": nv.new_physics, "ratio": nv.ratio, "reason": nv.reason}
    except ValueError as e:  # no λ on one side of 1
        naive = {"new_physics": None, "ratio": None, "reason": str(e)}
    return naive


class _SeedKeys(NamedTuple):
    """The PRNG keys of one seed's stages, split from the seed's key in this order."""

    lnn: jax.Array  # the LNN's initialisation
    uan: jax.Array  # the UAN's initialisation
    sweep: jax.Array  # the λ-sweep's minibatches
    long: jax.Array  # the conservative rounds
    free: jax.Array  # the free model


def _lambda_stage(ctx: dict, tcfg: TrainConfig, d: _Split, keys: _SeedKeys, back, tick, per_lambda):
    """(a) NNPhD's λ-sweep with warm starts and the optimisation check (:func:`_sweep`). Returns (the largest λ's
    parameters, the representative λ's (λ, f_c in original units, f_n, power, kinetic term), the sweep's table,
    the optimisation check, the naive verdict)."""
    cfg, width, lambdas = ctx["cfg"], ctx["width"], ctx["lambdas"]
    k = ctx["feats"].shape[1]  # the record's time features; the networks see them padded (_holdout_split)
    uan = init_free(keys.uan, cfg, n_time=k, widths=(width, width))
    params = {
        "lnn": init_lnn(keys.lnn, cfg),
        "uan": widen_inputs(uan, padded_time_features(ctx["feats"][:1]).shape[1] - k),
    }
    train = _trainer("nnphd", cfg, tcfg)
    pts, evals, table, opt_check = _sweep(ctx, d, train, params, keys.sweep, back, tick, per_lambda)
    lams = sorted(lambdas)
    lam_rep = min((x for x in lams if x < 1), key=lambda x: abs(x - REPRESENTATIVE_LAMBDA))
    fc_rep, _, power_rep, kin_rep, _, fn_rep = evals[lam_rep]
    rep = (lam_rep, back(fc_rep), fn_rep, power_rep, kin_rep)
    params = pts[lams[-1]]
    return params, rep, table, opt_check, _naive(table, d.fnorm_te)


class _Rounds(NamedTuple):
    """The conservative model: the LNN's round with the lowest training error (b), and what it gives on the rows."""

    chosen: int  # the chosen round (0: the largest λ's LNN as it was)
    hist: list  # each round's held-out error (original units)
    hist_tr: list  # each round's training error (inf where it diverged)
    lnn: dict  # the chosen round's parameters
    fc: object  # f_c on every row (standardised units)
    power: object  # the power of the residual q̈ − f_c
    kin: object  # |the kinetic term|
    E: object  # the learned energy
    E_rest: object  # the learned energy at q̇ = 0
    orient: float  # ±1: the sign that makes the kinetic term positive
    train_err: float  # the chosen round's training error
    test_err: float  # the chosen round's held-out error


def _conservative_rounds(ctx: dict, tcfg: TrainConfig, d: _Split, lnn, k_long, back, tick) -> _Rounds:
    """(b) The LNN alone, continued from the largest λ's ``lnn`` for ``long_factor`` rounds: the round chosen."""
    # the conservative model is the round with the lowest *training* error (a round that diverges is not used; the
    # held-out data play no part in the choice)
    cfg, long_factor, qdd = ctx["cfg"], ctx["long_factor"], ctx["qdd"]
    arrays, tr, te = d.arrays, d.tr, d.te
    lnn_train = _trainer("lnn", cfg, tcfg)
    lp = {"lnn": lnn}
    hist, hist_tr, best = [], [], None
    for i, k in enumerate([None, *jax.random.split(k_long, long_factor)]):
        if k is not None:
            lp, _ = lnn_train(lp, d.A_tr, jnp.asarray(0.0, jnp.float64), k)
            tick()
        ev = by_rows(_lnn_eval, lp["lnn"], *arrays[:2], arrays[3], cfg=cfg)
        r = back(ev[0] - qdd)
        hist.append(_l1(r[te]))
        hist_tr.append(_l1(r[tr]) if np.all(np.isfinite(r[tr])) else np.inf)
        if best is None or hist_tr[-1] < hist_tr[best[0]]:
            best = (i, ev, lp["lnn"])
    fc_l, power_l, kin_l, E_l, E_rest, kin_signed = best[1]
    # L and −L give the same motion: orient the learned Lagrangian so that its kinetic term is positive (else its
    # "energy" is −E and a decay reads as growth)
    orient = -1.0 if np.median(kin_signed) < 0 else 1.0
    return _Rounds(
        best[0], hist, hist_tr, best[2], fc_l, power_l, kin_l, E_l, E_rest, orient, hist_tr[best[0]], hist[best[0]]
    )


def _free_model(ctx: dict, tcfg: TrainConfig, d: _Split, k_free, back, tick) -> tuple[float, float]:
    """(c) The free model of (q, q̇): its (training, held-out) errors, original units."""
    cfg, width, long_factor, qdd = ctx["cfg"], ctx["width"], ctx["long_factor"], ctx["qdd"]
    fp = {"mlp": init_free(k_free, cfg, n_time=0, widths=(width, width))}
    ft = _trainer("free", cfg, tcfg)
    for k in jax.random.split(k_free, 1 + long_factor):
        fp, _ = ft(fp, d.A_tr, jnp.asarray(0.0, jnp.float64), k)
        tick()
    r_free = back(by_rows(_free_eval, fp, *d.arrays[:2], cfg=cfg) - qdd)
    return _l1(r_free[d.tr]), _l1(r_free[d.te])


def _clock_test(ctx: dict, d: _Split, fc_l, back) -> tuple[float, float, float]:
    """(d) The time dependence of the conservative residual q̈ − f_c: (the weighted held-out error of the state
    regression, that of the regression with time features, the fraction of trajectories the time features
    improve)."""
    q, qd, tp, qdd, segs, cfg = ctx["q"], ctx["qd"], ctx["tp"], ctx["qdd"], ctx["segs"], ctx["cfg"]
    tr, te = d.tr, d.te
    # ridge regressions on state monomials, without and with time features, each trajectory predicted by a fit to
    # the others (leave-one-trajectory-out; linear, so cheap)
    # the design has hundreds of columns: beyond RIDGE_ROWS rows it is built on rows thinned evenly (memory bounded)
    sel, sub = _thin(len(q), RIDGE_ROWS)
    resid = (qdd - fc_l)[sel]
    X_s, X_t = time_design(
        np.concatenate([np.asarray(embed_periodic(jnp.asarray(q[sel]), cfg.periodic)), qd[sel]], axis=1),
        time_features(tp[sel], float(tp.max() - tp.min()), oversample=2),
    )
    errs = {"state": [], "timed": []}
    segs_s, tr_s, te_s = [sub(x) for x in segs], sub(tr), sub(te)
    if len(segs) > 1:
        for k, seg in enumerate(segs_s):
            rest = np.concatenate([x for j, x in enumerate(segs_s) if j != k])
            for name, X in (("state", X_s), ("timed", X_t)):
                errs[name].append(_l1(back(resid[seg] - ridge_fit_predict(X[rest], resid[rest], X[seg]))))
    else:
        for name, X in (("state", X_s), ("timed", X_t)):
            errs[name].append(_l1(back(resid[te_s] - ridge_fit_predict(X[tr_s], resid[tr_s], X[te_s]))))
    w = np.asarray([len(x) for x in (segs_s if len(segs) > 1 else [te_s])], float)
    e_state, e_timed = (float(np.average(errs[k], weights=w)) for k in ("state", "timed"))
    improved = float(np.mean(np.asarray(errs["timed"]) < np.asarray(errs["state"])))
    return e_state, e_timed, improved


def _energy_trend(ctx: dict, seed: int, cons: _Rounds, block) -> dict:
    """(e) The trend of the conservative model's energy over the record (:func:`nnphd.engine.evidence.energy_trend`),
    in standardised units."""
    trend = energy_trend(
        cons.orient * cons.E,
        float(np.min(cons.orient * cons.E_rest)),
        ctx["tp"],
        ctx["segs"],
        block,
        seed=seed,
        kinetic=cons.kin,
    )
    trend["orientation"] = cons.orient
    trend.update(fit_error_bound(cons.orient * cons.E, cons.power, ctx["tp"], ctx["segs"], block,
                                 float(np.min(cons.orient * cons.E_rest))))  # fmt: skip
    return trend


def _shooting_probe(ctx: dict, seed: int, cons: _Rounds, block) -> dict:
    """(e) The multiple-shooting fit of the positions with the conservative model and a damping probe
    (:func:`nnphd.engine.shooting.shooting_fit`), in standardised units; invalid where the model diverged."""
    if np.all(np.isfinite(cons.power)):
        return shooting_fit(
            lnn_accel_fn(ctx["cfg"]),
            cons.lnn,
            ShootingData(ctx["q_pos"], ctx["qd"], ctx["tp"], ctx["segs"], ctx["sigma"], block),
            ShootingOptions(seed=seed),
        )
    return {"valid": False, "reason": "the conservative model diverged"}


def _checks(ctx: dict, seed: int, d: _Split, cons: _Rounds, rep, free_err, clock_errs, evidence) -> dict:
    """The checks of :mod:`nnphd.user.checks` on the seed's stages: the seed's report entries drift, uan_power, time,
    gap, capacity and trajectory_evidence. ``free_err``: (training, held-out) errors of the free model;
    ``clock_errs``: :func:`_clock_test`'s; ``evidence``: (energy trend, shooting probe, their bootstrap replicas'
    z) in the file's units."""
    trend, shoot, replicas = evidence
    tp, segs = ctx["tp"], ctx["segs"]
    fnorm, fnorm_tr, fnorm_te = d.fnorm, d.fnorm_tr, d.fnorm_te
    e_state, e_timed, improved = clock_errs
    free_tr, free_te = free_err
    osc = oscillations(np.concatenate([ctx["q_pos"], ctx["qd"]], axis=1), segs)
    drift = drift_check(cons.power, tp, segs, _seg_mean(cons.kin, segs), osc, seed=seed)
    drift["rho_from_energy"] = energy_net_fraction(cons.E, segs).tolist()
    uan_drift = drift_check(rep[3], tp, segs, _seg_mean(rep[4], segs), osc, seed=seed)
    tchk = time_check(e_state, e_timed, fnorm, improved if len(segs) > 2 else None)
    tchk.update(
        residual_state=e_state / fnorm,
        residual_timed=e_timed / fnorm,
        improved_fraction=improved,
        valid=ctx["clock"][0],
        testable=ctx["clock"][1],
        n_trajectories=len(segs),
    )
    gap = gap_check(cons.train_err, free_tr, cons.test_err, free_te)
    gap.update(
        conservative_train=cons.train_err / fnorm_tr,
        conservative_test=cons.test_err / fnorm_te,
        free_train=free_tr / fnorm_tr,
        free_test=free_te / fnorm_te,
    )
    cap = capacity_check(cons.hist)
    cap.update(
        errors_rel=(np.asarray(cons.hist) / fnorm_te).tolist(),
        train_errors_rel=(np.asarray(cons.hist_tr) / fnorm_tr).tolist(),
        chosen_round=cons.chosen,
    )
    traj = trajectory_evidence(trend, shoot, replicas)
    traj["effect"] = effect_text(traj, trend, shoot)
    uan_power = {k: uan_drift[k] for k in ("rho_median", "magnitude_median", "significant", "bootstrap_fraction")}
    return {
        "drift": drift,
        "uan_power": uan_power | {"lam": rep[0]},
        "time": tchk,
        "gap": gap,
        "capacity": cap,
        "trajectory_evidence": traj,
    }


def _seed_status(ctx: dict, cons: _Rounds, chk: dict) -> tuple[str, str, float, bool]:
    """The seed's (status, reason, bootstrap agreement, ``by_learned_power``) from its checks
    (:func:`nnphd.user.checks.seed_status`); inconclusive where the conservative model diverged.
    ``by_learned_power``: the status is "inconclusive" only because of the pointwise net power of the learned
    Lagrangian's residual (:func:`nnphd.user.checks.by_learned_power`)."""
    if np.all(np.isfinite(cons.power)) and np.isfinite(cons.train_err):
        args = (chk["time"], chk["gap"], chk["capacity"], chk["trajectory_evidence"], ctx["quality"], len(ctx["segs"]))
        status, reason, agree = seed_status(chk["drift"], *args)
        return status, reason, agree, by_learned_power(status, chk["drift"], *args)
    return (
        Status.INCONCLUSIVE,
        "the conservative model diverged (non-finite forces): "
        "lower the learning rates or standardise the data differently",
        1.0,
        False,
    )


def one_seed(ctx: dict, seed: int, tick=None) -> dict:
    """One seed of :func:`nnphd.user.assess.assess` on its context ``ctx``: the held-out split, (a) the λ-sweep,
    (b) the conservative rounds, (c) the free model, (d) the clock test, (e) the whole-record evidence, then the
    checks. ``tick`` is called after each training round. Module-level (and so are its stages): it runs on worker
    processes too."""
    release_compiled_if_crowded()  # a worker process training seed after seed (nnphd._config.MAP_SHARE_MAX)
    tick = tick or (lambda: None)
    cfg, sc = ctx["cfg"], ctx["sc"]
    tcfg = TrainConfig(steps=ctx["steps"])
    back = lambda r: sc.force_back(r)  # noqa: E731
    d = _holdout_split(ctx, seed, back)
    key = jax.random.PRNGKey(seed)
    keys = _SeedKeys(*jax.random.split(key, 5))
    per_lambda: dict[float, float] = {}
    watch = _Stopwatch()

    # (a) NNPhD λ-sweep with warm starts (and the optimisation check)
    params, rep, table, opt_check, naive = _lambda_stage(ctx, tcfg, d, keys, back, tick, per_lambda)
    watch.done("lambda_sweep_s")

    # (b) the LNN alone, continued from the largest λ: the conservative model
    cons = _conservative_rounds(ctx, tcfg, d, params["lnn"], keys.long, back, tick)
    watch.done("conservative_rounds_s")

    # (c) the free model of (q, q̇)
    free_err = _free_model(ctx, tcfg, d, keys.free, back, tick)
    watch.done("free_model_s")

    # (d) time dependence of the conservative residual
    clock_errs = _clock_test(ctx, d, cons.fc, back)
    watch.done("clock_test_s")

    # (e) evidence over whole trajectories from the conservative model: the trend of its energy over the record and
    # the multiple-shooting fit of the positions with a damping probe (nnphd.engine.evidence)
    # blocks of one period; motion that does not oscillate (a throw, a fall) has no period: blocks of a fraction of
    # the record (nnphd.engine.evidence.evidence_block), and the trend then reads "per block", not "per period"
    oscillating = bool(np.isfinite(ctx["period"]))
    block = evidence_block(ctx["period"], ctx["tp"], ctx["segs"])
    trend = _energy_trend(ctx, seed, cons, block)
    watch.done("energy_trend_s")
    shoot = _shooting_probe(ctx, seed, cons, block)
    watch.done("shooting_probe_s")
    replicas = (trend.pop("bootstrap_z", []), shoot.pop("bootstrap_z", []))  # for the call, not for the report
    trend = trend_units(trend, sc)
    shoot = shoot_units(shoot, sc)
    trend["oscillating"] = shoot["oscillating"] = oscillating

    # checks
    chk = _checks(ctx, seed, d, cons, rep, free_err, clock_errs, (trend, shoot, replicas))
    status, reason, boot_agree, learned_only = _seed_status(ctx, cons, chk)
    watch.done("checks_s")
    times = watch.times
    times["per_lambda_s"] = {f"{lam:g}": sec for lam, sec in sorted(per_lambda.items())}
    return {
        "seed": seed,
        "timings": times,
        "status": status,
        "reason": reason,
        "agreement": boot_agree,
        "by_learned_power": learned_only,
        "drift": chk["drift"],
        "uan_power": chk["uan_power"],
        "time": chk["time"],
        "gap": chk["gap"],
        "capacity": chk["capacity"],
        "optimisation": opt_check,
        "energy_trend": trend,
        "shooting": shoot,
        "trajectory_evidence": chk["trajectory_evidence"],
        "naive": naive,
        "table": table,
        "forces": (rep[0], rep[1], rep[2]),
        "holdout": [int(len(s)) for s in d.te_segs],
        "force_norm": d.fnorm,
        "conservative": ConservativeModel(cons.lnn, cfg, back(cons.fc), sc),
    }
