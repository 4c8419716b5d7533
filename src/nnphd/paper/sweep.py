"""`run_sweep`: the whole sweep pipeline of one system (data → λ-sweep → verdict → results.json + plot), resumable.

This is what ``nnphd sweep`` calls; a notebook can call it the same way.
"""
from __future__ import annotations

import hashlib
import json
import pickle
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict
from pathlib import Path

import jax
import numpy as np

from nnphd.engine.data import train_test
from nnphd.engine.models import ModelConfig
from nnphd.engine.systems import System, get_system
from nnphd.engine.train import PAPER_LAMBDAS, SweepPoint, TrainConfig, sweep, validate_lambdas
from nnphd.engine.verdict import force_norm, verdict
from nnphd.io.results import atomic_write_bytes, ensure_writable_dir, plot_sweep, save_figure, write_json

CHECKPOINT = ".sweep-checkpoint.pkl"


def _fingerprint(settings: dict) -> str:
    return hashlib.sha256(json.dumps(settings, sort_keys=True, default=str).encode()).hexdigest()[:16]


def _load_checkpoint(path: Path, fp: str) -> dict[float, SweepPoint]:
    if not path.exists():
        return {}
    try:
        with open(path, "rb") as fh:
            ck = pickle.load(fh)
    except Exception:  # a corrupt or foreign checkpoint is ignored, never trusted
        return {}
    if ck.get("fingerprint") != fp:
        return {}
    return {pt.lam: pt for pt in ck["points"]}


def _save_checkpoint(path: Path, fp: str, done: dict[float, SweepPoint]) -> None:
    pts = []
    for pt in done.values():
        d = SweepPoint(**{**asdict(pt), "params": None})
        d.params = jax.tree_util.tree_map(np.asarray, pt.params)
        pts.append(d)
    atomic_write_bytes(path, pickle.dumps({"fingerprint": fp, "points": pts}))


def run_sweep(
    system: System | str,
    p: float | str = 1.0,
    steps: int = 2000,
    seed: int = 0,
    lambdas: Sequence[float] = PAPER_LAMBDAS,
    mode: str = "warm",
    out: str | Path | None = None,
    model_cfg: ModelConfig | None = None,
    n_train: int = 1000,
    n_test: int = 1000,
    progress: Callable[[int, float], None] | None = None,
    resume: bool = True,
    standardize: bool = True,
) -> dict:
    """Run a λ-sweep on a catalogue system and return the results dict (also written to ``out`` if given)."""
    sysm = get_system(system) if isinstance(system, str) else system
    tcfg = TrainConfig(steps=steps, p=p)
    lams = validate_lambdas(lambdas)
    train, test = train_test(sysm, seed=seed, n_train=n_train, n_test=n_test)
    cfg = model_cfg or ModelConfig(n=sysm.n)
    if standardize:  # the networks see order-one inputs whatever the units (t runs to 100 on the Neptune orbit)
        cfg = cfg.standardized(train.q, train.qd, train.t)
    outdir = ensure_writable_dir(out) if out is not None else None
    settings = {
        "system": sysm.name,
        "system_params": dict(sysm.params),
        "p": tcfg.p,
        "steps_per_lambda": tcfg.steps,
        "learning_rates": list(tcfg.lrs),
        "batch_size": tcfg.batch_size,
        "seed": seed,
        "lambdas": sorted(lams),
        "mode": mode,
        "data": sysm.data,
        "n_train": n_train if sysm.data == "gaussian" else None,
        "n_test": n_test if sysm.data == "gaussian" else None,
        "model": asdict(cfg),
    }
    fp = _fingerprint(settings)
    ckpath = outdir / CHECKPOINT if outdir is not None else None
    done = _load_checkpoint(ckpath, fp) if (ckpath is not None and resume) else {}
    resumed = sorted(done)

    def on_point(pt: SweepPoint):
        done[pt.lam] = pt
        if ckpath is not None:
            _save_checkpoint(ckpath, fp, done)

    t0 = time.perf_counter()
    points = sweep(train, cfg, tcfg, lams, seed=seed, test_data=test, mode=mode, progress=progress, resume=done, on_point=on_point)
    wall = time.perf_counter() - t0
    evald = test if test is not None else train
    v = verdict(points, force_norm(evald.qdd, tcfg.p))
    table = [
        {"lam": pt.lam, "L_e": pt.L_e, "L_b": pt.L_b, "L_e_train": pt.L_e_train, "L_b_train": pt.L_b_train, "m_c": pt.m_c, "m_n": pt.m_n}
        for pt in points
    ]
    aligned = [r for r in table if 0.1 <= r["lam"] <= 0.5 and r["m_c"] is not None]
    results = {
        "system": sysm.name,
        "description": sysm.description,
        "new_physics": v.new_physics,
        "truth_conservative": sysm.conservative,
        "statistic": {"name": "ratio of median L_e above λ=1 to median L_e below λ=1", "value": v.ratio},
        "verdict": v.to_dict(),
        "table": table,
        "alignment_lambda_0.1_to_0.5": {
            "max_m_c": max(r["m_c"] for r in aligned) if aligned else None,
            "max_m_n": max(r["m_n"] for r in aligned) if aligned else None,
        },
        "settings": settings,
        "evaluated_on": "test set" if test is not None else "training trajectory (as the paper)",
        "wall_time_s": wall,
        "resumed_lambdas": resumed,
        "jax_version": jax.__version__,
    }
    if outdir is not None:
        write_json(outdir / "results.json", results)
        save_figure(plot_sweep({sysm.name: table}, f"{sysm.name}, p={tcfg.p}: new physics = {v.new_physics}"), outdir / "loss_vs_lambda.png")
        if ckpath is not None and ckpath.exists():
            ckpath.unlink()
    return results
