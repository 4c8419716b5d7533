r"""A verdict users can trust: is a jump of L_e at λ = 1 new physics, or a Lagrangian network that has not fit yet?

The naive verdict (:func:`nnphd.engine.verdict.verdict`) reads "new physics" off a jump of the error L_e across λ = 1. A jump
has two causes: (1) a force no Lagrangian explains, or (2) a conservative LNN that has not fit an unusual potential
while, below λ = 1, the free UAN soaked up its error. :func:`assess` takes trajectory data (q, q̇, t, q̈; several
trajectories told apart by ``traj``; no ground truth) and separates the two with checks whose answer does not depend
on how well the LNN fits.

Method (per seed; ``n_seeds`` repeats with other initialisations, minibatches and held-out trajectories)
---------------------------------------------------------------------------------------------------------

* **Units.** q' = (q − μ_q)/s_q per coordinate and t' = (t − t₀)/s_t, so q̇' = q̇ s_t/s_q and q̈' = q̈ s_t²/s_q. A point
  transformation plus a time rescaling maps conservative systems to conservative ones, so nothing is lost. s_t is the
  geometric mean of the per-coordinate time scales s_q/rms(q̇) and √(s_q/rms(q̈)). Forces and L_e, L_b are reported in
  the original units (f = f' s_q/s_t²). Time enters the free networks as τ = t'/std(t') plus Fourier features
  sin/cos(ω_j t'), ω_j = 2πj/span(t') ≤ 3 (at most 24 pairs): a plain MLP of a raw t spanning tens of periods could
  not represent a periodic drive (measured: with the package's UAN of (q, q̇, t), a 2.5 % drive cos(1.3 t) gave no
  jump at all, L_e below λ = 1 ≈ L_e above). Angles (``angles``) keep their radians (no shift or scale) and enter
  every network as (sin θ, cos θ) (:attr:`nnphd.engine.models.ModelConfig.periodic`), so whole turns and unwrapped values
  of ±100 rad are the same states as their remainders; they are unwrapped per trajectory for integration.
* **Data quality** (:func:`nnphd.user.checks.data_quality`, before any training): positions that are mostly noise (σ/std ≥
  NOISE_REL_MAX for every coordinate) or motion sampled below MIN_SAMPLES_PER_PERIOD samples per oscillation →
  "inconclusive" at once, with the reason and no training; an estimated relative q̈ error ≥ QDD_ERR_MAX for every
  coordinate marks the pointwise tests as blind (only trajectory-level evidence can then decide).
* **Hold-out.** Whole trajectories (a quarter, at least one); with a single trajectory, its last quarter.
* **Models.** (a) NNPhD (LNN + UAN of (q, q̇, τ, features)) through the λ grid with warm starts, as the paper's sweep:
  the L_e(λ), L_b(λ) table on held-out data, the naive ratio, and f_c, f_n at λ = 0.2. *Optimisation check*: the
  training L_e below λ = 1 (free UAN) must not exceed the one above it by more than 10 %; where it does, the λ < 1
  points are retrained downwards from the largest-λ solution and the better objective is kept (``optimisation``).
  (b) The conservative model: the
  LNN alone, continued from the largest-λ point for ``long_factor`` more rounds of ``steps``; the round with the lowest
  *training* error is used (held-out data play no part in choosing it). (c) A free MLP of (q, q̇), ``1 + long_factor``
  rounds. (d) Ridge regressions of the conservative residual q̈ − f_c on state monomials (degree ≤ 3) with and without
  time features × (1, q, q̇) (the frequency grid twice as fine as above), leave-one-trajectory-out.

The checks on the fitted models, the status per seed and how the thresholds were set: :mod:`nnphd.user.checks`;
standardised units, time features and hold-out: :mod:`nnphd.user.scaling`. Over seeds: the common status, or
``inconclusive`` ("seeds disagree"). ``confidence`` = mean over seeds of [seed status = final status] × the share of
window/block bootstrap replicas of that seed's trajectory-level evidence (trajectories, for the net-power check) that
reproduce its call — how often a similar record would give the same call, not a probability that the call is right.
``new_physics`` (best call): the status, or when inconclusive, the majority of seeds.
"""
from __future__ import annotations

import functools
import time
from collections.abc import Callable, Sequence

import jax
import jax.numpy as jnp
import numpy as np

from nnphd.engine.data import Dataset
from nnphd.engine.evidence import dominant_period, energy_trend, shooting_fit
from nnphd.engine.models import (
    ModelConfig,
    embed_periodic,
    free_force,
    init_free,
    init_lnn,
    lnn_accel,
    lnn_derivatives,
    lnn_energy,
)
from nnphd.engine.train import SweepPoint, TrainConfig, lambda_sweep, make_trainer, pnorm
from nnphd.engine.verdict import verdict as naive_verdict
from nnphd.user.checks import (
    DRIFT_MIN,
    GAP_MIN,
    MIN_OSCILLATIONS,
    RHO_LOW,
    RHO_MIN,
    STILL_FALLING,
    TIME_ABS_MIN,
    TIME_GAIN_MIN,
    Z_BOTH,
    Z_CONTRA,
    Z_MIN,
    Z_ONE,
    _effect,
    _seed_status,
    capacity_check,
    clock_testable,
    data_quality,
    drift_check,
    energy_net_fraction,
    gap_check,
    ridge_fit_predict,
    time_check,
    time_design,
    trajectory_evidence,
)
from nnphd.user.scaling import (
    Scaling,
    _shoot_units,
    _trend_units,
    fit_scaling,
    holdout,
    oscillations,
    segments,
    time_features,
)

__all__ = ["assess", "conservative_fn"]

DEFAULT_LAMBDAS = (0.05, 0.1, 0.2, 0.5, 2.0, 5.0, 10.0)
REPRESENTATIVE_LAMBDA = 0.2


# ------------------------------------------------------------------------------------------------------------------
# models


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
    return make_trainer(cfg, tcfg, loss)


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
def _accel_fn(cfg: ModelConfig):
    """f_c(params, q, q̇) of an LNN config: one function object per config, so the shooting fit compiles once."""
    def accel(lnn, q, qd):
        return lnn_accel(lnn, q, qd, cfg)
    return accel


def _l1(r) -> float:
    return float(np.mean(np.abs(r))) if np.size(r) else float("nan")


def _seg_mean(x, segs):
    return np.asarray([float(np.mean(x[s])) for s in segs])


# ------------------------------------------------------------------------------------------------------------------
# one seed


def _sweep(params, train, arrays, A_tr, lambdas, k_sweep, cfg, back, qdd, tr, te, fnorm_te, tick):
    """The warm-started λ-sweep; then the optimisation check: the training error below λ = 1 (where the UAN is free)
    must not exceed the one above it. Where it does (beyond 10 %), the λ < 1 points are retrained in decreasing
    order, warm-started from the largest-λ solution (the UAN then only has to add to a fitted LNN), and the better
    objective is kept."""
    lams = sorted(lambdas)
    pts = lambda_sweep(train, params, A_tr, lams, k_sweep, "warm", progress=lambda *_: tick())

    def evaluate(p):
        fc, fn, power, kin = (np.asarray(x) for x in _nnphd_eval(p, *arrays[:3], cfg))
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

        lambda_sweep(train, pts[lams[-1]], A_tr, below, jax.random.fold_in(k_sweep, 1), "warm", descending=True,
                     accept=keep_better)
        check["L_e_train_below_after"] = med_train(below)
    table = []
    for lam in lams:
        _, _, _, _, r, fnb = evals[lam]
        table.append({"lam": lam, "L_e": _l1(r[te]), "L_b": _l1(fnb[te]), "L_e_train": _l1(r[tr]),
                      "L_b_train": _l1(fnb[tr]), "L_e_rel": _l1(r[te]) / fnorm_te, "L_b_rel": _l1(fnb[te]) / fnorm_te})
    check["ok"] = not below or not above or med_train(below) <= 1.1 * med_train(above)
    if below and above:  # the same comparison on held-out data: a free UAN that generalises worse than none
        held = [float(np.median([r["L_e"] for r in table if (r["lam"] < 1) == side])) for side in (True, False)]
        check.update(L_e_heldout_below=held[0], L_e_heldout_above=held[1], heldout_ok=held[0] <= 1.5 * held[1])
    return pts, evals, table, check


def _one_seed(ctx: dict, seed: int, tick) -> dict:
    q, qd, tp, qdd, segs = ctx["q"], ctx["qd"], ctx["tp"], ctx["qdd"], ctx["segs"]
    steps, lambdas, width, long_factor, sc = ctx["steps"], ctx["lambdas"], ctx["width"], ctx["long_factor"], ctx["sc"]
    feats = ctx["feats"]
    rng = np.random.default_rng(seed)
    tr_segs, te_segs = holdout(segs, ctx["holdout_frac"], rng)
    tr, te = np.concatenate(tr_segs), np.concatenate(te_segs)
    cfg = ctx["cfg"]
    tcfg = TrainConfig(steps=steps)
    arrays = tuple(jnp.asarray(a) for a in (q, qd, feats, qdd))
    A_tr = tuple(a[tr] for a in arrays)
    back = lambda r: sc.force_back(r)  # noqa: E731
    fnorm = _l1(back(qdd))  # ‖f‖ over all data, original units
    fnorm_te = _l1(back(qdd[te]))
    fnorm_tr = _l1(back(qdd[tr]))
    key = jax.random.PRNGKey(seed)
    k_lnn, k_uan, k_sweep, k_long, k_free = jax.random.split(key, 5)

    # (a) NNPhD λ-sweep with warm starts (and the optimisation check)
    params = {"lnn": init_lnn(k_lnn, cfg), "uan": init_free(k_uan, cfg, n_time=feats.shape[1], widths=(width, width))}
    train = _trainer("nnphd", cfg, tcfg)
    pts, evals, table, opt_check = _sweep(params, train, arrays, A_tr, lambdas, k_sweep, cfg, back, qdd, tr, te,
                                          fnorm_te, tick)
    lams = sorted(lambdas)
    lam_rep = min((x for x in lams if x < 1), key=lambda x: abs(x - REPRESENTATIVE_LAMBDA))
    fc_rep, _, power_rep, kin_rep, _, fn_rep = evals[lam_rep]
    rep = (lam_rep, back(fc_rep), fn_rep, power_rep, kin_rep)
    params = pts[lams[-1]]
    points = [SweepPoint(r["lam"], r["L_e"], r["L_b"], r["L_e_train"], r["L_b_train"]) for r in table]
    try:
        nv = naive_verdict(points, fnorm_te)
        naive = {"new_physics": nv.new_physics, "ratio": nv.ratio, "reason": nv.reason}
    except ValueError as e:  # no λ on one side of 1
        naive = {"new_physics": None, "ratio": None, "reason": str(e)}

    # (b) the LNN alone, continued from the largest λ; the conservative model is the round with the lowest
    # *training* error (a round that diverges is not used; the held-out data play no part in the choice)
    lnn_train = _trainer("lnn", cfg, tcfg)
    lp = {"lnn": params["lnn"]}
    hist, hist_tr, best = [], [], None
    for i, k in enumerate([None, *jax.random.split(k_long, long_factor)]):
        if k is not None:
            lp, _ = lnn_train(lp, A_tr, jnp.asarray(0.0, jnp.float64), k)
            tick()
        ev = tuple(np.asarray(x) for x in _lnn_eval(lp["lnn"], *arrays[:2], arrays[3], cfg))
        r = back(ev[0] - qdd)
        hist.append(_l1(r[te]))
        hist_tr.append(_l1(r[tr]) if np.all(np.isfinite(r[tr])) else np.inf)
        if best is None or hist_tr[-1] < hist_tr[best[0]]:
            best = (i, ev, lp["lnn"])
    fc_l, power_l, kin_l, E_l, E_rest, kin_signed = best[1]
    # L and −L give the same motion: orient the learned Lagrangian so that its kinetic term is positive (else its
    # "energy" is −E and a decay reads as growth)
    orient = -1.0 if np.median(kin_signed) < 0 else 1.0
    lnn_best = best[2]
    cons_tr, cons_te = hist_tr[best[0]], hist[best[0]]

    # (c) the free model of (q, q̇)
    fp = {"mlp": init_free(k_free, cfg, n_time=0, widths=(width, width))}
    ft = _trainer("free", cfg, tcfg)
    for k in jax.random.split(k_free, 1 + long_factor):
        fp, _ = ft(fp, A_tr, jnp.asarray(0.0, jnp.float64), k)
        tick()
    r_free = back(np.asarray(_free_eval(fp, *arrays[:2], cfg)) - qdd)
    free_tr, free_te = _l1(r_free[tr]), _l1(r_free[te])

    # (d) time dependence of the conservative residual: ridge regressions on state monomials, without and with time
    # features, each trajectory predicted by a fit to the others (leave-one-trajectory-out; linear, so cheap)
    resid = qdd - fc_l
    X_s, X_t = time_design(np.concatenate([np.asarray(embed_periodic(jnp.asarray(q), cfg.periodic)), qd], axis=1),
                           time_features(tp, float(tp.max() - tp.min()), oversample=2))
    errs = {"state": [], "timed": []}
    if len(segs) > 1:
        for k, seg in enumerate(segs):
            rest = np.concatenate([x for j, x in enumerate(segs) if j != k])
            for name, X in (("state", X_s), ("timed", X_t)):
                errs[name].append(_l1(back(resid[seg] - ridge_fit_predict(X[rest], resid[rest], X[seg]))))
    else:
        for name, X in (("state", X_s), ("timed", X_t)):
            errs[name].append(_l1(back(resid[te] - ridge_fit_predict(X[tr], resid[tr], X[te]))))
    w = np.asarray([len(x) for x in (segs if len(segs) > 1 else [te])], float)
    e_state, e_timed = (float(np.average(errs[k], weights=w)) for k in ("state", "timed"))
    improved = float(np.mean(np.asarray(errs["timed"]) < np.asarray(errs["state"])))

    # (e) evidence over whole trajectories from the conservative model: the trend of its energy over the record and
    # the multiple-shooting fit of the positions with a damping probe (nnphd.engine.evidence)
    period = ctx["period"]
    trend = energy_trend(orient * E_l, float(np.min(orient * E_rest)), tp, segs, period, seed=seed, kinetic=kin_l)
    trend["orientation"] = orient
    if np.all(np.isfinite(power_l)):
        shoot = shooting_fit(_accel_fn(cfg), lnn_best, ctx["q_pos"], qd, tp, segs, ctx["sigma"], period, seed=seed)
    else:
        shoot = {"valid": False, "reason": "the conservative model diverged"}
    trend = _trend_units(trend, sc)
    shoot = _shoot_units(shoot, sc)

    # checks
    osc = oscillations(np.concatenate([ctx["q_pos"], qd], axis=1), segs)
    drift = drift_check(power_l, tp, segs, _seg_mean(kin_l, segs), osc, seed=seed)
    drift["rho_from_energy"] = energy_net_fraction(E_l, segs).tolist()
    uan_drift = drift_check(rep[3], tp, segs, _seg_mean(rep[4], segs), osc, seed=seed)
    tchk = time_check(e_state, e_timed, fnorm, improved if len(segs) > 2 else None)
    tchk.update(residual_state=e_state / fnorm, residual_timed=e_timed / fnorm, improved_fraction=improved,
                valid=ctx["clock"][0], testable=ctx["clock"][1], n_trajectories=len(segs))
    gap = gap_check(cons_tr, free_tr, cons_te, free_te)
    gap.update(conservative_train=cons_tr / fnorm_tr, conservative_test=cons_te / fnorm_te,
               free_train=free_tr / fnorm_tr, free_test=free_te / fnorm_te)
    cap = capacity_check(hist)
    cap.update(errors_rel=(np.asarray(hist) / fnorm_te).tolist(),
               train_errors_rel=(np.asarray(hist_tr) / fnorm_tr).tolist(), chosen_round=best[0])
    traj = trajectory_evidence(trend, shoot)
    traj["effect"] = _effect(traj, trend, shoot)

    if np.all(np.isfinite(power_l)) and np.isfinite(cons_tr):
        status, reason, boot_agree = _seed_status(drift, tchk, gap, cap, traj, ctx["quality"], len(segs))
    else:
        status, reason, boot_agree = ("inconclusive", "the conservative model diverged (non-finite forces): "
                                      "lower the learning rates or standardise the data differently", 1.0)
    return {
        "seed": seed,
        "status": status,
        "reason": reason,
        "agreement": boot_agree,
        "drift": drift,
        "uan_power": {k: uan_drift[k] for k in ("rho_median", "magnitude_median", "significant", "bootstrap_fraction")}
        | {"lam": rep[0]},
        "time": tchk,
        "gap": gap,
        "capacity": cap,
        "optimisation": opt_check,
        "energy_trend": trend,
        "shooting": shoot,
        "trajectory_evidence": traj,
        "naive": naive,
        "table": table,
        "forces": (rep[0], rep[1], rep[2]),
        "holdout": [int(len(s)) for s in te_segs],
        "force_norm": fnorm,
        "_conservative": {"lnn": lnn_best, "cfg": cfg, "fc": back(fc_l)},
    }


# ------------------------------------------------------------------------------------------------------------------
# the entry point


def assess(
    data: Dataset,
    traj: np.ndarray | None = None,
    seed: int = 0,
    steps: int = 1000,
    lambdas: Sequence[float] = DEFAULT_LAMBDAS,
    n_seeds: int = 2,
    progress: Callable[[int, int, str], None] | None = None,
    width: int = 64,
    holdout_frac: float = 0.25,
    long_factor: int = 3,
    angles: Sequence[bool] | None = None,
    position_noise: Sequence[float] | None = None,
    derivative_error: Sequence[float] | None = None,
) -> dict:
    """Is there new physics in trajectory data (q, q̇, t, q̈), with checks against under-fitting?

    ``data``: a :class:`~nnphd.engine.data.Dataset` (its fc/fn, if any, are ignored); ``traj``: a trajectory id per row
    (None: a single trajectory); ``steps``: training steps per λ and per extra round of the conservative and free
    models; ``n_seeds``: seeds seed, seed+1, … (each with its own held-out trajectories); ``width``: hidden units of
    every network (two layers); ``long_factor``: extra rounds for the conservative model;
    ``angles``: (n,) bools, coordinates that are angles (enter every network as sin, cos; whole turns are fine);
    ``position_noise``: (n,) σ of the positions (default: estimated); ``derivative_error``: (n,) relative RMS
    error of the estimated q̈ (from :func:`nnphd.user.derivatives.to_dataset`; None: q̈ assumed exact);
    ``progress(done, total, message)``: called after every training round. The method: module docstring.

    Returns a dict:

    * ``status``: "detected" | "none" | "inconclusive"; ``new_physics``: the best call (bool);
    * ``statistic``: {"name", "value"}: the z of the energy trend along the record (median over seeds);
    * ``effect``: the effect size and significance in words; ``evidence``: energy trend and shooting numbers of
      the first seed (file units);
    * ``confidence``: in [0, 1]: mean over seeds of [seed agrees with the status] × the share of window/block
      bootstrap replicas of that seed's evidence that reproduce its call;
    * ``reasons``: human-readable, one per seed (first: "seeds disagree" if they do);
    * ``quality``: whether the data can decide (noise, sampling, derivative error);
    * ``checks``: every check's numbers per seed, ``per_seed`` with everything, the scaling and the thresholds;
    * ``table``: per λ, L_e and L_b on held-out data (original units; ``_rel``: over ‖f‖) and on the training data,
      median over seeds;
    * ``f_c``, ``f_n``: the learned forces on every row of ``data`` (original units) at λ = ``lambda_forces``
      (the grid value below 1 nearest 0.2), first seed.
    """
    _validate(data, traj, steps, lambdas, n_seeds)
    t_start = time.perf_counter()
    n = data.n
    is_angle = np.zeros(n, bool) if angles is None else np.asarray(angles, bool)
    if is_angle.shape != (n,):
        raise ValueError(f"angles must have one flag per coordinate ({n}), got shape {is_angle.shape}")
    sc = fit_scaling(data, is_angle)
    q, qd, tp, qdd = sc.apply(data)
    segs = segments(traj, data.t)
    q_pos = q.copy()  # positions for integration: angles unwrapped per trajectory
    for s in segs:
        q_pos[np.ix_(s, np.flatnonzero(is_angle))] = np.unwrap(q[np.ix_(s, np.flatnonzero(is_angle))], axis=0)
    period = dominant_period(np.concatenate([q_pos, qd], axis=1), tp, segs)
    dts = np.concatenate([np.diff(tp[s]) for s in segs])
    period_samples = period / float(np.median(dts)) if np.isfinite(period) else 0.0
    if position_noise is None:
        from nnphd.user.sampling import noise_level

        position_noise = [float(np.sqrt(np.mean([noise_level(data.t[s], data.q[s, j]) ** 2 for s in segs])))
                          for j in range(n)]
    sd = np.std(q_pos * sc.s_q, axis=0)
    noise_rel = [p / s if s > 0 else 0.0 for p, s in zip(position_noise, sd)]
    quality = data_quality(period_samples, noise_rel, derivative_error)
    clock = clock_testable(tp, segs)
    if not quality["usable"]:  # nothing to learn from: say so at once instead of training on noise
        return _unusable(quality, sc, data, is_angle, clock, time.perf_counter() - t_start)
    cfg_kw = {"periodic": tuple(int(i) for i in np.flatnonzero(is_angle))} if is_angle.any() else {}
    ctx = {
        "q": q, "qd": qd, "tp": tp, "qdd": qdd, "segs": segs, "q_pos": q_pos, "sc": sc, "steps": steps,
        "lambdas": tuple(lambdas), "width": width, "long_factor": long_factor, "holdout_frac": holdout_frac,
        # t enters the UAN only where a clock can be told from a trajectory label; along one trajectory (or at
        # disjoint times) it only lets the UAN fit the training times and extrapolate wildly to held-out ones
        "feats": time_features(tp, float(tp.max() - tp.min())) if clock[0] else np.zeros((len(tp), 0)),
        "period": period, "sigma": np.asarray(position_noise, float) / sc.s_q, "quality": quality, "clock": clock,
        "cfg": ModelConfig(n=n, lnn_widths=(width, width), uan_widths=(width, width), **cfg_kw),
    }
    total = n_seeds * (len(lambdas) + 2 * long_factor + 1)
    done = [0]

    def tick():
        done[0] += 1
        if progress:
            progress(done[0], total, "training")

    seeds = [_one_seed(ctx, seed + i, tick) for i in range(n_seeds)]
    res = _combine(seeds, sc, data, time.perf_counter() - t_start)
    res["quality"] = quality
    res["angles"] = [bool(a) for a in is_angle]
    res["clock"] = {"testable": ctx["clock"][0], "why": ctx["clock"][1]}
    return res


def _unusable(quality: dict, sc: Scaling, data: Dataset, is_angle, clock, wall: float) -> dict:
    """The result for data that cannot decide (no training is done): inconclusive, with the reason."""
    empty = {"valid": False, "reason": "not computed: " + quality["reason"]}
    keys = {"energy_trend": ("rate", "se", "z", "rate_per_period", "n_blocks", "valid"),
            "shooting": ("d_mean", "se_d_mean", "z", "c", "n_windows", "valid"),
            "drift": ("rho_median", "magnitude_median", "slow_ratio_median", "bootstrap_fraction", "significant",
                      "valid"),
            "uan_power": ("rho_median", "magnitude_median", "significant"),
            "time": ("gain", "abs_gain", "improved_fraction", "significant", "valid"),
            "gap": ("gap_train", "gap_test", "conservative_train", "conservative_test", "free_train", "free_test",
                    "large"),
            "capacity": ("relative_drop", "still_falling"),
            "optimisation": ("L_e_train_below", "L_e_train_above", "retrained", "ok")}
    checks = {name: {k: [] for k in ks} for name, ks in keys.items()}
    checks.update(naive={"new_physics": [], "ratio": []}, per_seed=[], scaling=sc.to_dict(), wall_time_s=wall)
    zeros = np.zeros_like(data.q)
    return {
        "status": "inconclusive", "new_physics": False,
        "statistic": {"name": "z of the energy trend (not computed: the data cannot decide)", "value": None},
        "effect": None,
        "evidence": {"energy_trend": empty, "shooting": empty,
                     "combined": {"significant": False, "valid": False, "bootstrap_fraction": None}},
        "confidence": 1.0,
        "confidence_basis": "the data-quality gate alone (no model was trained): the reason is a property of the data",
        "reasons": [f"the data cannot decide: {quality['reason']}"],
        "checks": checks, "table": [], "lambda_forces": None, "f_c": zeros, "f_n": zeros,
        "quality": quality, "angles": [bool(a) for a in is_angle], "clock": {"testable": clock[0], "why": clock[1]},
    }


def _combine(seeds: list[dict], sc: Scaling, data: Dataset, wall: float) -> dict:
    statuses = [s["status"] for s in seeds]
    if len(set(statuses)) == 1:
        status = statuses[0]
        reasons = [f"seed {s['seed']}: {s['reason']}" for s in seeds]
    else:
        status = "inconclusive"
        reasons = [f"seeds disagree ({', '.join(statuses)})"] + [f"seed {s['seed']}: {s['reason']}" for s in seeds]
    conf = float(np.mean([(s["status"] == status) * s["agreement"] for s in seeds]))
    if status == "inconclusive" and len(set(statuses)) > 1:
        conf = float(np.mean([s["status"] == "detected" for s in seeds]))
        conf = max(conf, 1 - conf)
    det = float(np.mean([s["status"] == "detected" for s in seeds]))
    if status == "detected":
        new = True
    elif status == "none":
        new = False
    else:  # best call when inconclusive
        new = bool(det > 0.5)
    lams = [r["lam"] for r in seeds[0]["table"]]
    table = []
    for j, lam in enumerate(lams):
        row = {"lam": lam}
        for key in ("L_e", "L_b", "L_e_train", "L_b_train", "L_e_rel", "L_b_rel"):
            row[key] = float(np.median([s["table"][j][key] for s in seeds]))
        table.append(row)
    lam_rep, fc, fn = seeds[0]["forces"]

    def public(d):
        return {k: v for k, v in d.items() if not k.startswith("_")}

    checks = {
        "energy_trend": _agg([{"e": public(s["energy_trend"])} for s in seeds], "e",
                             ("rate", "se", "z", "rate_per_period", "n_blocks", "valid")),
        "shooting": _agg([{"e": public(s["shooting"])} for s in seeds], "e",
                         ("d_mean", "se_d_mean", "z", "c", "n_windows", "valid")),
        "drift": _agg(seeds, "drift", ("rho_median", "magnitude_median", "slow_ratio_median", "bootstrap_fraction",
                                       "significant", "valid")),
        "uan_power": _agg(seeds, "uan_power", ("rho_median", "magnitude_median", "significant")),
        "time": _agg(seeds, "time", ("gain", "abs_gain", "improved_fraction", "significant", "valid")),
        "gap": _agg(seeds, "gap", ("gap_train", "gap_test", "conservative_train", "conservative_test", "free_train",
                                   "free_test", "large")),
        "capacity": _agg(seeds, "capacity", ("relative_drop", "still_falling")),
        "optimisation": _agg(seeds, "optimisation", ("L_e_train_below", "L_e_train_above", "retrained", "ok",
                                                     "L_e_heldout_below", "L_e_heldout_above", "heldout_ok")),
        "naive": {"new_physics": [s["naive"]["new_physics"] for s in seeds],
                  "ratio": [s["naive"]["ratio"] for s in seeds]},
        "per_seed": [{k: (public(v) if isinstance(v, dict) else v) for k, v in s.items()
                      if k not in ("forces", "table", "_conservative")} for s in seeds],
        "scaling": sc.to_dict(),
        "thresholds": {"rho_min": RHO_MIN, "rho_low": RHO_LOW, "z_min": Z_MIN, "drift_min": DRIFT_MIN,
                       "min_oscillations": MIN_OSCILLATIONS, "z_both": Z_BOTH, "z_one": Z_ONE,
                       "z_contradict": Z_CONTRA, "time_gain_min": TIME_GAIN_MIN, "time_abs_min": TIME_ABS_MIN,
                       "gap_min": GAP_MIN, "still_falling": STILL_FALLING},
        "wall_time_s": wall,
    }
    zs = [s["energy_trend"]["z"] if s["energy_trend"].get("valid") else float("nan") for s in seeds]
    first = seeds[0]
    return {
        "status": status,
        "new_physics": new,
        "statistic": {"name": "z of the energy trend of the learned Lagrangian along the record (decay > 0; median "
                              "over seeds)",
                      "value": float(np.nanmedian(zs)) if np.any(np.isfinite(zs)) else None},
        "effect": first["trajectory_evidence"].get("effect"),
        "evidence": {"energy_trend": public(first["energy_trend"]), "shooting": public(first["shooting"]),
                     "combined": first["trajectory_evidence"]},
        "confidence": conf,
        "confidence_basis": "mean over seeds of [seed agrees] × the share of window/block bootstrap replicas of its "
                            "trajectory-level evidence (or of trajectories, for the net-power check) that give "
                            "the same call",
        "reasons": reasons,
        "checks": checks,
        "table": table,
        "lambda_forces": lam_rep,
        "f_c": fc,
        "f_n": fn,
        "_conservative": {**first["_conservative"], "scaling": sc},
    }


def conservative_fn(cons: dict):
    """The LNN's conservative acceleration f_c(q, q̇) in the file's units as a JAX function (batched), from
    ``assess(...)["_conservative"]`` — for fits that integrate the model (the laws' trajectory-level ranking)."""
    accel = _accel_fn(cons["cfg"])
    lnn, sc = cons["lnn"], cons["scaling"]
    mu, s_q, s_t = jnp.asarray(sc.mu_q), jnp.asarray(sc.s_q), float(sc.s_t)

    def fc(q, qd):
        return accel(lnn, (q - mu) / s_q, qd * s_t / s_q) * s_q / s_t**2
    return fc


def _agg(seeds, name, keys):
    return {k: [s[name].get(k) for s in seeds] for k in keys}


def _validate(data, traj, steps, lambdas, n_seeds):
    if not isinstance(data, Dataset):
        raise ValueError(f"data must be a nnphd.engine.data.Dataset, got {type(data).__name__}")
    for name in ("q", "qd", "t", "qdd"):
        a = getattr(data, name)
        if not np.all(np.isfinite(a)):
            bad = np.argwhere(~np.isfinite(a))[0]
            raise ValueError(f"data.{name} has a non-finite value at row {int(bad[0])}")
    if traj is not None and np.shape(traj) != data.t.shape:
        raise ValueError(f"traj must have one id per row ({len(data)}), got shape {np.shape(traj)}")
    for s in segments(traj, data.t):
        if len(s) < 8:
            raise ValueError(f"every trajectory needs at least 8 samples, one has {len(s)}")
    if int(steps) != steps or steps < 4:
        raise ValueError(f"steps must be an integer ≥ 4, got {steps}")
    lams = [float(x) for x in lambdas]
    if not any(x < 1 for x in lams) or any(x <= 0 for x in lams):
        raise ValueError(f"lambdas must be > 0 and include a value below 1, got {lams}")
    if n_seeds < 1:
        raise ValueError(f"n_seeds must be ≥ 1, got {n_seeds}")
