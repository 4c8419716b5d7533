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
  NOISE_REL_MAX for every coordinate) or motion sampled below MIN_SAMPLES_PER_PERIOD samples per time scale (its
  period; for motion that does not oscillate — a throw, a fall — 2π × the time in which the velocity changes by its own
  size, :func:`nnphd.user.checks.motion_time_scale`) →
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
standardised units, time features and hold-out: :mod:`nnphd.user.scaling`. Over seeds
(:func:`nnphd.user.rules.combine_seeds`): the common status; where they differ, a seed whose "inconclusive" is an
optimisation failure (its LNN under-fits where another seed's fits as well as a free model) is discounted and the
others decide if they agree; else ``inconclusive`` ("seeds disagree"). ``confidence`` = mean over seeds of [seed
status = final status] × the share of window/block bootstrap replicas of that seed's trajectory-level evidence
(trajectories, for the net-power check) that reproduce its call — how often a similar record would give the same call, not a probability that the call is right.
``new_physics`` (best call): the status, or when inconclusive, the majority of seeds.
"""

from __future__ import annotations

import functools
import os
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import jax.numpy as jnp
import numpy as np

from nnphd.engine.data import Dataset
from nnphd.engine.evidence import dominant_period
from nnphd.engine.models import (
    ModelConfig,
)
from nnphd.io.limits import MIN_ROWS
from nnphd.io.progress import Progress
from nnphd.parallel import Unit, UnitsFailed, run_units, runs_here
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
    clock_testable,
    data_quality,
    motion_time_scale,
)
from nnphd.user.result import ConservativeModel, Status
from nnphd.user.rounds import (
    lnn_accel_fn,
    one_seed,
)
from nnphd.user.rules import combine_seeds
from nnphd.user.scaling import (
    Scaling,
    fit_scaling,
    segments,
    time_features,
)

__all__ = ["AssessSettings", "Assessment", "ConservativeFn", "RecordFacts", "assess", "conservative_fn"]


@dataclass(frozen=True, eq=False)
class Assessment:
    """What :func:`assess` found: ``report``, the JSON-ready verdict with its evidence (the keys of :func:`assess`'s
    docstring, which report.json carries), the learned forces ``f_c`` and ``f_n`` on every row (file units), the
    first seed's ``conservative`` model (None when no model was trained: the data cannot decide) and each seed's
    wall and compile seconds ``timings_per_seed``."""

    report: dict
    f_c: np.ndarray
    f_n: np.ndarray
    conservative: ConservativeModel | None
    timings_per_seed: tuple = ()

    @property
    def status(self) -> str:
        return self.report["status"]

    @property
    def new_physics(self) -> bool:
        return self.report["new_physics"]

    @property
    def confidence(self) -> float:
        return self.report["confidence"]

    @property
    def reasons(self) -> list[str]:
        return self.report["reasons"]


DEFAULT_LAMBDAS = (0.05, 0.1, 0.2, 0.5, 2.0, 5.0, 10.0)


# ------------------------------------------------------------------------------------------------------------------
# the entry point


def _motion(data: Dataset, traj, is_angle: np.ndarray, position_noise=None):
    """The scaled data and the period of the motion: (scaling, (q, q̇, t, q̈) scaled, segments, positions with angles
    unwrapped per trajectory, position noise per coordinate (estimated when None), period in scaled time (inf: the
    motion does not oscillate — a throw, a fall; swings within the noise do not count))."""
    sc = fit_scaling(data, is_angle)
    q, qd, tp, qdd = sc.apply(data)
    segs = segments(traj, data.t)
    q_pos = q.copy()  # positions for integration: angles unwrapped per trajectory
    for s in segs:
        q_pos[np.ix_(s, np.flatnonzero(is_angle))] = np.unwrap(q[np.ix_(s, np.flatnonzero(is_angle))], axis=0)
    if position_noise is None:
        from nnphd.user.sampling import noise_level

        position_noise = [
            float(np.sqrt(np.mean([noise_level(data.t[s], data.q[s, j]) ** 2 for s in segs]))) for j in range(data.n)
        ]
    period = dominant_period(np.concatenate([q_pos, qd], axis=1), tp, segs, np.asarray(position_noise) / sc.s_q)
    return sc, (q, qd, tp, qdd), segs, q_pos, position_noise, period


def motion_period(data: Dataset, traj=None, angles: Sequence[bool] | None = None, position_noise=None) -> float:
    """The dominant period of the motion in the data's time unit, as :func:`assess` finds it (inf: the motion
    does not oscillate — a throw, a fall, a coast-down)."""
    is_angle = np.zeros(data.n, bool) if angles is None else np.asarray(angles, bool)
    sc, _, _, _, _, period = _motion(data, traj, is_angle, position_noise)
    return float(period * sc.s_t)


@dataclass(frozen=True)
class AssessSettings:
    """How :func:`assess` trains and checks: ``seed`` (the seeds are seed, seed+1, …, each with its own held-out
    trajectories), training ``steps`` per λ and per extra round of the conservative and free models, the λ grid
    ``lambdas``, ``n_seeds``, the hidden units ``width`` of every network (two layers), the held-out share
    ``holdout_frac``, ``long_factor`` extra rounds for the conservative model, and where the seeds train:
    ``workers`` / ``scheduler`` (:func:`nnphd.parallel.run_units`: 1, one after another here; None, side by side on
    one thread per core of this process, sharing their compiled programs; N, N local Dask worker processes; or an
    existing Dask scheduler — the same numbers either way)."""

    seed: int = 0
    steps: int = 1000
    lambdas: Sequence[float] = DEFAULT_LAMBDAS
    n_seeds: int = 2
    width: int = 64
    holdout_frac: float = 0.25
    long_factor: int = 3
    workers: int | None = 1
    scheduler: str | None = None


@dataclass(frozen=True)
class RecordFacts:
    """What the record's reading and derivative stage know, per coordinate: which are ``angles`` (they enter every
    network as sin, cos; whole turns are fine), the ``position_noise`` σ (None: estimated), and the
    ``derivative_error``, the relative RMS error of the estimated q̈ (from :func:`nnphd.user.derivatives.to_dataset`;
    None: q̈ assumed exact)."""

    angles: Sequence[bool] | None = None
    position_noise: Sequence[float] | None = None
    derivative_error: Sequence[float] | None = None


def assess(
    data: Dataset,
    traj: np.ndarray | None = None,
    settings: AssessSettings = AssessSettings(),
    record: RecordFacts = RecordFacts(),
    progress: Progress | None = None,
) -> Assessment:
    """Is there new physics in trajectory data (q, q̇, t, q̈), with checks against under-fitting?

    ``data``: a :class:`~nnphd.engine.data.Dataset` (its fc/fn, if any, are ignored); ``traj``: a trajectory id per row
    (None: a single trajectory); ``settings``: :class:`AssessSettings` (seed, steps, λ grid, seeds, widths, where the
    seeds train); ``record``: :class:`RecordFacts` (angles, position noise, q̈ error per coordinate);
    ``progress(done, total, message)``: called after every training round. The method: module docstring.

    Returns an :class:`Assessment`, whose ``report`` holds:

    * ``status``: "detected" | "none" | "inconclusive"; ``new_physics``: the best call (bool);
    * ``statistic``: {"name", "value"}: the z of the energy trend along the record (median over seeds);
    * ``effect``: the effect size and significance in words; ``evidence``: energy trend and shooting numbers of
      the first seed (file units);
    * ``confidence``: in [0, 1]: mean over seeds of [seed agrees with the status] × the share of window/block
      bootstrap replicas of that seed's evidence that reproduce its call;
    * ``reasons``: human-readable, one per seed (first: "seeds disagree" if they do, or which seed was discounted
      and why);
    * ``quality``: whether the data can decide (noise, sampling, derivative error);
    * ``checks``: every check's numbers per seed, ``per_seed`` with everything, the scaling and the thresholds;
    * ``table``: per λ, L_e and L_b on held-out data (original units; ``_rel``: over ‖f‖) and on the training data,
      median over seeds;
    * ``lambda_forces``: the λ of the forces ``f_c``, ``f_n`` on every row of ``data`` (original units; the
      Assessment's) — the grid value below 1 nearest 0.2, first seed.
    """
    seed, steps, lambdas, n_seeds = settings.seed, settings.steps, settings.lambdas, settings.n_seeds
    width, long_factor, workers = settings.width, settings.long_factor, settings.workers
    angles, position_noise, derivative_error = record.angles, record.position_noise, record.derivative_error
    _validate(data, traj, steps, lambdas, n_seeds)
    t_start = time.perf_counter()
    n = data.n
    is_angle = np.zeros(n, bool) if angles is None else np.asarray(angles, bool)
    if is_angle.shape != (n,):
        raise ValueError(f"angles must have one flag per coordinate ({n}), got shape {is_angle.shape}")
    sc, (q, qd, tp, qdd), segs, q_pos, position_noise, period = _motion(data, traj, is_angle, position_noise)
    dts = np.concatenate([np.diff(tp[s]) for s in segs])
    scale, scale_kind = motion_time_scale(period, tp, qd, qdd, segs, derivative_error)
    period_samples = scale / float(np.median(dts))
    sd = np.std(q_pos * sc.s_q, axis=0)
    noise_rel = [p / s if s > 0 else 0.0 for p, s in zip(position_noise, sd)]
    quality = data_quality(period_samples, noise_rel, derivative_error, time_scale=scale_kind)
    clock = clock_testable(tp, segs)
    if not quality["usable"]:  # nothing to learn from: say so at once instead of training on noise
        zeros = np.zeros_like(data.q)
        return Assessment(_unusable(quality, sc, is_angle, clock, time.perf_counter() - t_start), zeros, zeros, None)
    cfg_kw = {"periodic": tuple(int(i) for i in np.flatnonzero(is_angle))} if is_angle.any() else {}
    ctx = {
        "q": q,
        "qd": qd,
        "tp": tp,
        "qdd": qdd,
        "segs": segs,
        "q_pos": q_pos,
        "sc": sc,
        "steps": steps,
        "lambdas": tuple(lambdas),
        "width": width,
        "long_factor": long_factor,
        "holdout_frac": settings.holdout_frac,
        # t enters the UAN only where a clock can be told from a trajectory label; along one trajectory (or at
        # disjoint times) it only lets the UAN fit the training times and extrapolate wildly to held-out ones
        "feats": time_features(tp, float(tp.max() - tp.min())) if clock[0] else np.zeros((len(tp), 0)),
        "period": period,
        "sigma": np.asarray(position_noise, float) / sc.s_q,
        "quality": quality,
        "clock": clock,
        "cfg": ModelConfig(n=n, lnn_widths=(width, width), uan_widths=(width, width), **cfg_kw),
    }
    total = n_seeds * (len(lambdas) + 2 * long_factor + 1)
    done = [0]
    lock, stop = threading.Lock(), threading.Event()

    def tick():
        if stop.is_set():  # interrupted while the seeds train on threads: each stops after its round
            raise KeyboardInterrupt
        with lock:
            done[0] += 1
            if progress:
                progress(done[0], total, "training")

    # default: the seeds on threads of this process, which trace and compile their programs once for all seeds
    scheduler = settings.scheduler
    threads = workers is None and scheduler is None
    if threads and os.environ.get("NNPHD_WORKER"):  # a Dask worker of nnphd owns one core: one seed after another
        workers = 1
    here = threads or runs_here(workers, scheduler, n_seeds)
    units = [Unit(f"seed {seed + i}", one_seed, dict(ctx=ctx, seed=seed + i, tick=tick if here else None)) for i in range(n_seeds)]  # fmt: skip
    if not here and progress:
        progress(0, n_seeds, f"training {n_seeds} seeds on Dask workers")
    outs = run_units(units, workers, scheduler, progress=None if here else progress, threads=threads, cancel=stop)
    bad = [o for o in outs.values() if not o.ok]
    if bad:
        raise UnitsFailed(f"the training of {bad[0].key} failed: {bad[0].error}")
    seeds = [outs[u.key].value for u in units]
    for u, s in zip(units, seeds):  # measured where the seed ran (a worker process too): wall and JAX compilation
        s["timings"] = {"wall_s": outs[u.key].wall_time_s, "compile_s": outs[u.key].compile_time_s,
                        "where": outs[u.key].where, **s.get("timings", {})}  # fmt: skip
    res, (fc, fn) = _combine(seeds, sc, data, time.perf_counter() - t_start)
    res["quality"] = quality
    res["angles"] = [bool(a) for a in is_angle]
    res["clock"] = {"testable": ctx["clock"][0], "why": ctx["clock"][1]}
    timings = tuple({"seed": s["seed"], **s["timings"]} for s in seeds)
    return Assessment(res, fc, fn, seeds[0]["conservative"], timings)


def _unusable(quality: dict, sc: Scaling, is_angle, clock, wall: float) -> dict:
    """The result for data that cannot decide (no training is done): inconclusive, with the reason."""
    empty = {"valid": False, "reason": "not computed: " + quality["reason"]}
    keys = {
        "energy_trend": ("rate", "se", "z", "rate_per_period", "n_blocks", "valid"),
        "shooting": ("d_mean", "se_d_mean", "z", "c", "n_windows", "valid"),
        "drift": ("rho_median", "magnitude_median", "slow_ratio_median", "bootstrap_fraction", "significant", "valid"),
        "uan_power": ("rho_median", "magnitude_median", "significant"),
        "time": ("gain", "abs_gain", "improved_fraction", "significant", "valid"),
        "gap": ("gap_train", "gap_test", "conservative_train", "conservative_test", "free_train", "free_test", "large"),
        "capacity": ("relative_drop", "still_falling"),
        "optimisation": ("L_e_train_below", "L_e_train_above", "retrained", "ok"),
    }
    checks = {name: {k: [] for k in ks} for name, ks in keys.items()}
    checks.update(naive={"new_physics": [], "ratio": []}, per_seed=[], scaling=sc.to_dict(), wall_time_s=wall)
    return {
        "status": Status.INCONCLUSIVE,
        "new_physics": False,
        "statistic": {"name": "z of the energy trend (not computed: the data cannot decide)", "value": None},
        "effect": None,
        "evidence": {
            "energy_trend": empty,
            "shooting": empty,
            "combined": {"significant": False, "valid": False, "bootstrap_fraction": None},
        },
        "confidence": 1.0,
        "confidence_basis": "the data-quality gate alone (no model was trained): the reason is a property of the data",
        "reasons": [f"the data cannot decide: {quality['reason']}"],
        "checks": checks,
        "table": [],
        "lambda_forces": None,
        "quality": quality,
        "angles": [bool(a) for a in is_angle],
        "clock": {"testable": clock[0], "why": clock[1]},
    }


def _combine(seeds: list[dict], sc: Scaling, data: Dataset, wall: float) -> tuple[dict, tuple]:
    """The seeds' verdicts and checks combined: (the report part of the :class:`Assessment`, (f_c, f_n) of the first
    seed)."""
    status, new, conf, reasons = combine_seeds(seeds)
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
        "energy_trend": _agg(
            [{"e": public(s["energy_trend"])} for s in seeds],
            "e",
            ("rate", "se", "z", "rate_per_period", "n_blocks", "valid"),
        ),
        "shooting": _agg(
            [{"e": public(s["shooting"])} for s in seeds], "e", ("d_mean", "se_d_mean", "z", "c", "n_windows", "valid")
        ),
        "drift": _agg(
            seeds,
            "drift",
            ("rho_median", "magnitude_median", "slow_ratio_median", "bootstrap_fraction", "significant", "valid"),
        ),
        "uan_power": _agg(seeds, "uan_power", ("rho_median", "magnitude_median", "significant")),
        "time": _agg(seeds, "time", ("gain", "abs_gain", "improved_fraction", "significant", "valid")),
        "gap": _agg(
            seeds,
            "gap",
            ("gap_train", "gap_test", "conservative_train", "conservative_test", "free_train", "free_test", "large"),
        ),
        "capacity": _agg(seeds, "capacity", ("relative_drop", "still_falling")),
        "optimisation": _agg(
            seeds,
            "optimisation",
            (
                "L_e_train_below",
                "L_e_train_above",
                "retrained",
                "ok",
                "L_e_heldout_below",
                "L_e_heldout_above",
                "heldout_ok",
            ),
        ),
        "naive": {
            "new_physics": [s["naive"]["new_physics"] for s in seeds],
            "ratio": [s["naive"]["ratio"] for s in seeds],
        },
        "per_seed": [
            {
                k: (public(v) if isinstance(v, dict) else v)
                for k, v in s.items()
                if k not in ("forces", "table", "conservative", "timings")  # (timings: not numbers of the data)
            }
            for s in seeds
        ],
        "scaling": sc.to_dict(),
        "thresholds": {
            "rho_min": RHO_MIN,
            "rho_low": RHO_LOW,
            "z_min": Z_MIN,
            "drift_min": DRIFT_MIN,
            "min_oscillations": MIN_OSCILLATIONS,
            "z_both": Z_BOTH,
            "z_one": Z_ONE,
            "z_contradict": Z_CONTRA,
            "time_gain_min": TIME_GAIN_MIN,
            "time_abs_min": TIME_ABS_MIN,
            "gap_min": GAP_MIN,
            "still_falling": STILL_FALLING,
        },
        "wall_time_s": wall,
    }
    zs = [s["energy_trend"]["z"] if s["energy_trend"].get("valid") else float("nan") for s in seeds]
    first = seeds[0]
    return {
        "status": status,
        "new_physics": new,
        "statistic": {
            "name": "z of the energy trend of the learned Lagrangian along the record (decay > 0; median over seeds)",
            "value": float(np.nanmedian(zs)) if np.any(np.isfinite(zs)) else None,
        },
        "effect": first["trajectory_evidence"].get("effect"),
        "evidence": {
            "energy_trend": public(first["energy_trend"]),
            "shooting": public(first["shooting"]),
            "combined": first["trajectory_evidence"],
        },
        "confidence": conf,
        "confidence_basis": "mean over seeds of [seed agrees] × the share of window/block bootstrap replicas of its "
        "trajectory-level evidence (or of trajectories, for the net-power check) that give "
        "the same call",
        "reasons": reasons,
        "checks": checks,
        "table": table,
        "lambda_forces": lam_rep,
    }, (fc, fn)


@dataclass(frozen=True, eq=False)
class ConservativeFn:
    """A conservative force f_c(q, q̇) = ``apply(params, q, q̇)`` (JAX, batched) whose numbers ``params`` (a pytree
    of arrays) are given apart from the function: programs that integrate it take them as data, so one compiled
    program serves every record of a shape (:func:`nnphd.explain.trajectory.fc_parts`). Called as ``fn(q, q̇)``."""

    apply: Callable
    params: tuple

    def __call__(self, q, qd):
        return self.apply(self.params, q, qd)


@functools.lru_cache(maxsize=64)
def _scaled_lnn_accel(cfg):
    """f_c in the file's units from the LNN's in standardised ones: one function object per LNN config."""
    accel = lnn_accel_fn(cfg)

    def apply(params, q, qd):
        lnn, mu, s_q, s_t = params
        return accel(lnn, (q - mu) / s_q, qd * s_t / s_q) * s_q / s_t**2

    apply.export_key = f"scaled_lnn_accel|{accel.export_key}"  # what it computes, for stored programs
    return apply


def conservative_fn(cons: ConservativeModel) -> ConservativeFn:
    """The LNN's conservative acceleration f_c(q, q̇) in the file's units as a JAX function (batched), from
    :attr:`Assessment.conservative` — for fits that integrate the model (the laws' trajectory-level ranking)."""
    sc = cons.scaling
    params = (cons.lnn, jnp.asarray(sc.mu_q), jnp.asarray(sc.s_q), jnp.asarray(float(sc.s_t)))
    return ConservativeFn(_scaled_lnn_accel(cons.cfg), params)


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
        if len(s) < MIN_ROWS:
            raise ValueError(f"every trajectory needs at least {MIN_ROWS} samples, one has {len(s)}")
    if int(steps) != steps or steps < 4:
        raise ValueError(f"steps must be an integer ≥ 4, got {steps}")
    lams = [float(x) for x in lambdas]
    if not any(x < 1 for x in lams) or any(x <= 0 for x in lams):
        raise ValueError(f"lambdas must be > 0 and include a value below 1, got {lams}")
    if n_seeds < 1:
        raise ValueError(f"n_seeds must be ≥ 1, got {n_seeds}")
