"""`run_sweep`: the whole sweep pipeline of one system (data → λ-sweep → verdict → results.json + plot), resumable.

This is what ``nnphd sweep`` calls; a notebook can call it the same way.
"""

from __future__ import annotations

import copy
import math
import time
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from pathlib import Path

import jax

from nnphd.engine.adaptive import ALL_MODES, fast_sweep
from nnphd.engine.data import Dataset, train_test
from nnphd.engine.models import ModelConfig, init_nnphd
from nnphd.engine.systems import System, get_system
from nnphd.engine.train import (
    PAPER_LAMBDAS,
    SweepHooks,
    SweepPoint,
    SweepSchedule,
    TrainConfig,
    sweep,
    validate_lambdas,
)
from nnphd.engine.verdict import PhaseTransition, force_norm, verdict
from nnphd.io.cache import Cache
from nnphd.io.progress import Progress
from nnphd.io.results import ensure_writable_dir, plot_sweep, save_figure, write_json
from nnphd.paper.sweep_result import SweepResult, SweepRow

_POINT_NUMBERS = ("L_e", "L_b", "L_e_train", "L_b_train")  # a checkpointed λ's metadata: these, and m_c, m_n


def checkpointed_point(lam: float, m: dict, params) -> SweepPoint:
    """A checkpointed λ back as a SweepPoint; ValueError (the checkpoint is then ignored) if its metadata is not
    that of a sweep point: other keys, or losses that are not finite numbers."""
    if set(m) != {*_POINT_NUMBERS, "m_c", "m_n"}:
        raise ValueError(f"its steps hold {sorted(m)}, not the numbers of a λ-sweep point")
    for k, v in m.items():
        if k in _POINT_NUMBERS or v is not None:
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise ValueError(f"λ = {lam:g}: {k} is {v!r}, expected a finite number")
    return SweepPoint(lam, **m, params=params)


@dataclass
class SweepPlan:
    """A λ-sweep of a catalogue system, set up (data, model, settings, cache) but not yet run."""

    system: System
    lambdas: tuple[float, ...]
    mode: str
    seed: int
    train: Dataset
    test: Dataset | None  # None for trajectory systems (evaluated on the training trajectory, as the paper)
    cfg: ModelConfig
    tcfg: TrainConfig
    settings: dict
    cache: Cache  # keyed by ``settings``: the checkpoint of this sweep and any result saved under them

    def run(self, progress: Progress | None = None) -> SystemSweep:
        """Train (resuming from the checkpoint, saving one after every λ) and read the verdict."""
        done = self.cache.restore(init_nnphd(jax.random.PRNGKey(0), self.cfg), build=checkpointed_point)
        resumed = sorted(done)

        def on_point(pt: SweepPoint):
            done[pt.lam] = pt
            _save_checkpoint(self.cache, done)

        t0 = time.perf_counter()
        common = dict(
            seed=self.seed, test_data=self.test, hooks=SweepHooks(resume=done, on_point=on_point, progress=progress)
        )
        protocol = None
        if self.mode == "fast":
            points, info = fast_sweep(self.train, self.cfg, self.tcfg, self.lambdas, **common)
            protocol = info.to_dict()
        else:
            points = sweep(self.train, self.cfg, self.tcfg, SweepSchedule(self.lambdas, self.mode), **common)
        wall = time.perf_counter() - t0
        ev = self.test if self.test is not None else self.train
        return SystemSweep(self, points, verdict(points, force_norm(ev.qdd, self.tcfg.p)), wall, resumed, protocol)


@dataclass
class SystemSweep:
    """A finished λ-sweep of a catalogue system."""

    plan: SweepPlan
    points: list[SweepPoint]
    verdict: PhaseTransition
    wall_time_s: float
    resumed: list[float]
    protocol: dict | None = None  # mode "fast": what it trained (FastInfo.to_dict)


@dataclass(frozen=True)
class SweepSettings:
    """How a λ-sweep of a catalogue system is run (:func:`plan_sweep`, :func:`run_sweep`): the loss ``p``, training
    ``steps`` per λ, the ``seed`` (data and initialisation), the λ grid ``lambdas``, the sweep ``mode`` (one of
    :data:`nnphd.engine.adaptive.ALL_MODES`), the networks' ``model_cfg`` (None: ``ModelConfig(n=system.n)``), the
    Gaussian sample sizes ``n_train``, ``n_test`` (ignored for trajectory systems) and whether the networks see
    ``standardize``-d inputs. Checked when the sweep is planned."""

    p: float | str = 1.0
    steps: int = 2000
    seed: int = 0
    lambdas: Sequence[float] = PAPER_LAMBDAS
    mode: str = "warm"
    model_cfg: ModelConfig | None = None
    n_train: int = 1000
    n_test: int = 1000
    standardize: bool = True


def plan_sweep(
    system: System | str,
    settings: SweepSettings = SweepSettings(),
    out: Path | None = None,
    extra_settings: dict | None = None,
) -> SweepPlan:
    """Data of a catalogue system, the model and the settings of its λ-sweep (plus ``extra_settings``, for callers
    that store more under the same key); the checkpoint lives in ``out``."""
    s = settings
    sysm = get_system(system) if isinstance(system, str) else system
    if s.mode not in ALL_MODES:
        raise ValueError(f"mode must be one of {', '.join(ALL_MODES)}, got {s.mode!r}")
    tcfg = TrainConfig(steps=s.steps, p=s.p)
    lams = validate_lambdas(s.lambdas)
    train, test = train_test(sysm, seed=s.seed, n_train=s.n_train, n_test=s.n_test)
    cfg = s.model_cfg or ModelConfig(n=sysm.n)
    if s.standardize:  # the networks see order-one inputs whatever the units (t runs to 100 on the Neptune orbit)
        cfg = cfg.standardized(train.q, train.qd, train.t)
    recorded = {
        "system": sysm.name,
        "system_params": dict(sysm.params),
        "p": tcfg.p,
        "steps_per_lambda": tcfg.steps,
        "learning_rates": list(tcfg.lrs),
        "batch_size": tcfg.batch_size,
        "seed": s.seed,
        "lambdas": sorted(lams),
        "mode": s.mode,
        "data": sysm.data,
        "n_train": s.n_train if sysm.data == "gaussian" else None,
        "n_test": s.n_test if sysm.data == "gaussian" else None,
        "model": asdict(cfg),
        **(extra_settings or {}),
    }
    return SweepPlan(sysm, lams, s.mode, s.seed, train, test, cfg, tcfg, recorded, Cache(out, recorded))


def _save_checkpoint(cache: Cache, done: dict[float, SweepPoint]) -> None:
    cache.checkpoint({lam: ({k: v for k, v in pt.row().items() if k != "lam"}, pt.params) for lam, pt in done.items()})


def run_sweep(
    system: System | str,
    settings: SweepSettings | None = None,
    *,
    out: str | Path | None = None,
    progress: Progress | None = None,
    resume: bool = True,
    plan: SweepPlan | None = None,
) -> SweepResult:
    """Run a λ-sweep on a catalogue system and return its :class:`SweepResult` (``.to_dict()``, results.json's
    content, is also written to ``out`` if given, with the L_e(λ) plot).

    ``settings`` (:class:`SweepSettings`; None: the defaults) as :func:`plan_sweep`, or ``plan``: one made already (a
    caller that also needs its data and model settings makes them once). With ``out``, every finished λ is
    checkpointed there (``resume=False`` starts afresh)."""
    outdir = ensure_writable_dir(out) if out is not None else None
    if outdir is not None and not resume:
        Cache(outdir, {}).clear_checkpoint()
    if plan is None:
        plan = plan_sweep(system, settings or SweepSettings(), out=outdir)
    elif settings is not None or outdir is not None:
        raise ValueError("run_sweep: give either plan or the plan's settings (and out), not both")
    r = plan.run(progress)
    res = SweepResult(
        system=plan.system.name,
        description=plan.system.description,
        truth_conservative=plan.system.conservative,
        verdict=r.verdict,
        table=tuple(SweepRow(**pt.row()) for pt in r.points),
        settings=copy.deepcopy(plan.settings),
        evaluated_on="test set" if plan.test is not None else "training trajectory (as the paper)",
        wall_time_s=r.wall_time_s,
        resumed_lambdas=tuple(r.resumed),
        protocol=r.protocol,
        jax_version=jax.__version__,
    )
    if outdir is not None:
        results = res.to_dict()
        write_json(outdir / "results.json", results)
        title = f"{res.system}, p={plan.tcfg.p}: new physics = {res.new_physics}"
        save_figure(plot_sweep({res.system: results["table"]}, title), outdir / "loss_vs_lambda.png")
        plan.cache.clear_checkpoint()
    return res
