r"""The λ/p study (paper section III.C, Fig. 5 a–h) and the data-quality study (section III.D, Fig. 6).

**λ/p study** (:func:`lambda_p_study`). For each toy system (HO+MF, HO+CG, HO+LD, HO+CD, HO+PF) and each loss
(p = 1, 2, 3 and MSE) one λ-sweep at the paper's settings — 10³ Gaussian training and 10³ test samples, 13 λ,
2000 Adam steps per λ, warm start with increasing λ (appendix B), inputs standardised as ``nnphd sweep`` does. Each
sub-run is exactly ``nnphd sweep --system S --p P`` (same data, initialisation and numbers). Recorded: L_e(λ) on the
test set (Fig. 5 a–d), the verdict of :func:`nnphd.engine.verdict.verdict` per (system, p), m_c(λ) and m_n(λ) for HO+LD
(Fig. 5 g–h here) and the learned f_c, f_n of HO+LD at a few λ on the test points against the truth f_c = −q,
f_n = −½q̇ (Fig. 5 e–f here: f_c^NN against q, f_n^NN against q̇, since the true parts depend on q and q̇ only).

*Jump or smooth.* Theorem 1 predicts, for a p-norm loss, a first-order transition: L_e ≈ 0 for λ < 1 and
L_e ≈ ‖f_n‖ for λ > 1, a step at λ = 1. With the MSE loss (squared norms) the minimiser is instead
f_n^NN = (f − f_c)/(1+λ), so L_e = (λ/(1+λ))²‖f_n‖² rises smoothly, with log-log slope 2/(1+λ): steepest at small λ
(slope → 2) and only slope 1 at λ = 1. The measurable criterion (:func:`transition_sharpness`) compares the log-log
slope of L_e(λ) across λ = 1 — between the largest grid λ below 1 and the smallest above 1 (λ = 1 itself, where the
split is degenerate, is skipped) — with the steepest |slope| between any other neighbouring grid λ (pairs on the
same side of 1)::

    sharpness = [ln L_e(λ₊) − ln L_e(λ₋)] / ln(λ₊/λ₋)  ÷  max_other |Δ ln L_e / Δ ln λ|

A jump makes the step across λ = 1 the steepest part of the curve by far: **jump** when sharpness ≥ 2. The ideal
MSE curve gives 0.5 on the paper's grid (≤ 0.7 even when the small-λ end sits on a fitting floor): **smooth** when
sharpness < 1, i.e. the curve is at least as steep somewhere away from λ = 1; "ambiguous" in between; "none" when
L_e does not rise across λ = 1. The criterion is only meaningful where there is something to jump (the
non-conservative systems); for the conservative ones it reads noise and is reported but not judged.

The sharpness (fixed before the first full run, and the one the claims use) is sensitive to noise of L_e on its
low plateau: a factor 2–5 between neighbouring λ on a 10⁻³ floor is a steep log-log slope. A second, less
noise-sensitive measure, added *after* the first full run and reported for information only (no claim uses it), is
the ``rise_fraction``: the log-rise across λ = 1 as a fraction of the rise between the plateaus, with the
verdict's medians,

    rise_fraction = ln[L_e(λ₊)/L_e(λ₋)] / ln[median L_e(λ > 1) / median L_e(0.05 ≤ λ < 1)]

≈ 1 for a step (all of the rise happens across λ = 1), ≈ 0.36 for the ideal MSE curve on the paper's grid.

**Data-quality study** (:func:`data_quality_study`). HO+CD (q̈ = −q − ½ sgn q̇) with 10³ samples in a phase-plane pie
of angular fraction α, trained at λ = 10 → L_e(α); HO+LD (q̈ = −q − ½q̇) with a fraction β of the samples at q̇ > 0,
trained at λ = 0.5 → m_c(β), m_n(β). p = 1. Each grid point is one training run of 2000 steps from the same
initialisation (no λ-sweep: the paper trains "with λ = 10" / "λ = 0.5" directly); all grid points are trained in one
``jax.vmap`` over the data sets. The model is the same for every grid point: the inputs are *not* standardised per
data set (the toy data are order one already, and a per-α standardisation would give each α a differently scaled
network, and break the vmap).

*Which data L_e and m are measured on.* The paper's reading of Fig. 6a — "when α ≤ 0.5 … L_e is nearly zero,
revealing no sign of non-conservation", because on q̇ > 0 alone the damping looks like a constant conservative
force — only holds on the data's own distribution (on the full plane the conservative model of a half-plane is
wrong by the full damping on the other half). So the primary numbers are on a held-out test set drawn from the same
distribution as the training set (same α or β, another seed); L_e on the training set itself and, for contrast,
L_e and m on a full (balanced) Gaussian test set are reported beside them. m_c, m_n follow the paper's formula
(rms over samples and components, :func:`nnphd.engine.train.alignment`).

Both studies cache their sub-runs in ``out`` (one JSON per (system, p) sweep under ``out/runs/``, one per data-quality
grid): a repeated call with the same settings loads them (flag ``cached``) instead of training, and an interrupted
λ-sweep resumes from its per-λ checkpoint. A cache file is only used when its fingerprint (every training setting)
matches; a call with other settings retrains and replaces it.
"""
from __future__ import annotations

import json
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from nnphd.engine.data import Dataset, gaussian_dataset, imbalanced_dataset, pie_dataset, train_test
from nnphd.engine.models import ModelConfig, init_nnphd
from nnphd.engine.systems import SYSTEMS, get_system
from nnphd.engine.train import (
    PAPER_LAMBDAS,
    TrainConfig,
    _as_arrays,
    alignment,
    evaluate,
    make_trainer,
    parse_p,
    sweep,
    validate_lambdas,
)
from nnphd.engine.verdict import MIN_RATIO, force_norm, verdict
from nnphd.io.results import ensure_writable_dir, save_figure, subplots, write_json
from nnphd.paper.sweep import CHECKPOINT, _fingerprint, _load_checkpoint, _save_checkpoint

__all__ = [
    "TOY_SYSTEMS",
    "LOSSES",
    "FORCE_SYSTEM",
    "FORCE_LAMBDAS",
    "DQ_GRID",
    "JUMP_SHARPNESS",
    "SMOOTH_SHARPNESS",
    "ALIGN_TOL",
    "p_label",
    "transition_sharpness",
    "lambda_p_study",
    "data_quality_study",
]

TOY_SYSTEMS: tuple[str, ...] = ("ho+mf", "ho+cg", "ho+ld", "ho+cd", "ho+pf")
NONCONSERVATIVE: tuple[str, ...] = ("ho+ld", "ho+cd", "ho+pf")
LOSSES: tuple = (1, 2, 3, "mse")
FORCE_SYSTEM = "ho+ld"  # Fig. 5 e–h: q̈ = −q − ½q̇
FORCE_LAMBDAS: tuple[float, ...] = (0.01, 0.1, 0.5, 2.0, 10.0)  # λ at which f_c^NN, f_n^NN are recorded and plotted
N_FORCE_POINTS = 400  # test points whose learned forces are stored for the plots
DQ_GRID: tuple[float, ...] = tuple(i / 8 for i in range(9))  # α and β grid: 0, 0.125, …, 1
DQ_LAM_ALPHA = 10.0
DQ_LAM_BETA = 0.5
DQ_P = 1.0
JUMP_SHARPNESS = 2.0  # sharpness ≥ this: the step across λ = 1 is a jump (first-order transition)
SMOOTH_SHARPNESS = 1.0  # sharpness < this: smooth (the curve is as steep elsewhere)
ALIGN_TOL = 0.05  # "aligned": m_c, m_n ≤ 0.05 = 10% of the rms of the true f_n = −½q̇ (rms 0.5 on N(0,1) data)
NEAR_ZERO_FRACTION = 0.1  # "nearly zero" L_e: ≤ 10% of the rms/L1 size of the non-conservative force on the data

_FORMAT = 1  # version of the cached sub-run files (bump when their content changes)

Progress = Callable[[int, int, str], None]  # progress(done, total, description)


def p_label(p) -> str:
    """'1', '2', '3', '1.5' or 'mse' — the key of a loss in results and file names."""
    p = parse_p(p)
    return "mse" if p == "mse" else f"{p:g}"


# ----------------------------------------------------------------------------------------------------------------
# jump vs smooth


def transition_sharpness(lams: Sequence[float], L_e: Sequence[float],
                         jump: float = JUMP_SHARPNESS, smooth: float = SMOOTH_SHARPNESS) -> dict:
    """How step-like L_e(λ) is at λ = 1 (see the module docstring): the log-log slope across λ = 1 divided by the
    steepest |slope| between other neighbouring grid points. Returns a dict with ``sharpness``, ``slope_across``,
    ``slope_max_other``, ``lam_below``, ``lam_above`` and ``kind`` ∈ {"jump", "smooth", "ambiguous", "none"}."""
    pts = sorted((float(l), max(float(e), 1e-300)) for l, e in zip(lams, L_e) if float(l) != 1.0)
    below = [pt for pt in pts if pt[0] < 1.0]
    above = [pt for pt in pts if pt[0] > 1.0]
    if not below or not above:
        raise ValueError("the λ grid must contain values below and above 1")

    def slope(a, b):
        return (math.log(b[1]) - math.log(a[1])) / (math.log(b[0]) - math.log(a[0]))

    lo, hi = below[-1], above[0]
    across = slope(lo, hi)
    others = [abs(slope(a, b)) for side in (below, above) for a, b in zip(side, side[1:])]
    max_other = max(others) if others else None
    if max_other is None:
        sharp = None
    elif max_other > 0:
        sharp = across / max_other
    else:
        sharp = math.inf if across > 0 else 0.0
    if across <= 0:
        kind = "none"
    elif sharp is None:
        kind = "ambiguous"
    elif sharp >= jump:
        kind = "jump"
    elif sharp < smooth:
        kind = "smooth"
    else:
        kind = "ambiguous"
    lo_plateau = [e for l, e in below if l >= 0.05] or [e for _, e in below]
    rise = math.log(float(np.median([e for _, e in above]))) - math.log(float(np.median(lo_plateau)))
    rise_fraction = (math.log(hi[1]) - math.log(lo[1])) / rise if rise != 0 else None
    return {"sharpness": sharp, "slope_across": across, "slope_max_other": max_other, "lam_below": lo[0],
            "lam_above": hi[0], "kind": kind, "jump_threshold": jump, "smooth_threshold": smooth,
            "rise_fraction": rise_fraction}


# ----------------------------------------------------------------------------------------------------------------
# λ/p study: one cached sub-run per (system, p)


def _rms(a) -> float:
    a = np.asarray(a, float)
    return float(np.sqrt(np.mean(a * a)))


def _load_cached(path: Path, fp: str) -> dict | None:
    if not path.exists():
        return None
    try:
        res = json.loads(path.read_text())
    except Exception:  # unreadable or foreign: ignored, never trusted
        return None
    return res if res.get("fingerprint") == fp else None


def _lambda_p_subrun(system: str, p, steps: int, seed: int, lambdas, subdir: Path | None, force_lams,
                     n_train: int, n_test: int, progress: Callable[[int, float], None] | None) -> dict:
    """One λ-sweep, set up exactly as :func:`nnphd.paper.sweep.run_sweep` (warm mode, standardised inputs)."""
    sysm = get_system(system)
    tcfg = TrainConfig(steps=steps, p=p)
    train, test = train_test(sysm, seed=seed, n_train=n_train, n_test=n_test)
    cfg = ModelConfig(n=sysm.n).standardized(train.q, train.qd, train.t)
    force_lams = sorted(x for x in force_lams if x in lambdas) if system == FORCE_SYSTEM else []
    settings = {
        "system": sysm.name, "system_params": dict(sysm.params), "p": tcfg.p, "steps_per_lambda": tcfg.steps,
        "learning_rates": list(tcfg.lrs), "batch_size": tcfg.batch_size, "seed": seed, "lambdas": sorted(lambdas),
        "mode": "warm", "data": sysm.data, "n_train": n_train, "n_test": n_test, "model": asdict(cfg),
        "force_lambdas": force_lams, "n_force_points": N_FORCE_POINTS if force_lams else 0,
        "format": _FORMAT,
    }
    fp = _fingerprint(settings)
    if subdir is not None:
        cached = _load_cached(subdir / "results.json", fp)
        if cached is not None:
            cached["cached"] = True
            if progress:
                for j, lam in enumerate(sorted(lambdas)):
                    progress(j + 1, lam)
            return cached
        ensure_writable_dir(subdir)
    ckpath = subdir / CHECKPOINT if subdir is not None else None
    done = _load_checkpoint(ckpath, fp) if ckpath is not None else {}
    resumed = sorted(done)

    def on_point(pt):
        done[pt.lam] = pt
        if ckpath is not None:
            _save_checkpoint(ckpath, fp, done)

    t0 = time.perf_counter()
    points = sweep(train, cfg, tcfg, lambdas, seed=seed, test_data=test, mode="warm", progress=progress,
                   resume=done, on_point=on_point)
    wall = time.perf_counter() - t0
    v = verdict(points, force_norm(test.qdd, tcfg.p))
    table = []
    forces = None
    if force_lams:
        k = min(N_FORCE_POINTS, len(test))
        forces = {"evaluated_on": f"first {k} test points", "q": test.q[:k, 0], "qd": test.qd[:k, 0],
                  "fc_true": test.fc[:k, 0], "fn_true": test.fn[:k, 0], "by_lambda": {}}
    for pt in points:
        ev = evaluate(pt.params, test, cfg, tcfg.p)
        table.append({"lam": pt.lam, "L_e": pt.L_e, "L_b": pt.L_b, "L_e_train": pt.L_e_train, "L_b_train": pt.L_b_train,
                      "m_c": pt.m_c, "m_n": pt.m_n, "fn_rms": _rms(ev.fn),
                      # robust companions of m_c, m_n: the median |f^NN − f^PHY| over the test samples
                      "m_c_median": float(np.median(np.abs(ev.fc - test.fc))),
                      "m_n_median": float(np.median(np.abs(ev.fn - test.fn)))})
        if forces is not None and pt.lam in force_lams:
            forces["by_lambda"][f"{pt.lam:g}"] = {"lam": pt.lam, "fc": ev.fc[:k, 0], "fn": ev.fn[:k, 0]}
    res = {
        "system": sysm.name,
        "p": p_label(tcfg.p),
        "truth_conservative": sysm.conservative,
        "table": table,
        "verdict": v.to_dict(),
        "fn_true_rms": _rms(test.fn),
        "forces": forces,
        "evaluated_on": "test set (10³ Gaussian samples independent of the training set)",
        "settings": settings,
        "fingerprint": fp,
        "train_wall_time_s": wall,
        "resumed_lambdas": resumed,
    }
    if subdir is not None:
        write_json(subdir / "results.json", res)
        if ckpath.exists():
            ckpath.unlink()
        res = json.loads((subdir / "results.json").read_text())  # the same (JSON-normalised) object a rerun loads
    else:
        res = json.loads(json.dumps(res, default=_jsonable))
    res["cached"] = False
    return res


def _jsonable(o):
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, (np.floating, np.integer)):
        return o.item()
    if isinstance(o, np.bool_):
        return bool(o)
    raise TypeError(type(o))


def _fmt(x, nd=3) -> str:
    return "—" if x is None else f"{x:.{nd}g}"


def _lambda_p_claims(runs: dict, systems, labels, lambdas) -> list[dict]:
    claims = []
    nc = [s for s in systems if s in NONCONSERVATIVE]
    cons = [s for s in systems if s not in NONCONSERVATIVE]
    pnorm_labels = [l for l in labels if l in ("1", "2", "3")]
    if nc and pnorm_labels:
        ok, parts = True, []
        for l in pnorm_labels:
            for s in nc:
                v = runs[s][l]["verdict"]
                ok &= v["new_physics"]
                parts.append(f"{s} p={l}: ×{v['ratio']:.3g} ({'new physics' if v['new_physics'] else 'none'})")
        claims.append({"claim": f"L_e jumps at λ=1 (verdict: new physics) for {', '.join(nc)} with p={', '.join(pnorm_labels)}",
                       "ours": "; ".join(parts), "met": bool(ok)})
        ok, parts = True, []
        for l in pnorm_labels:
            for s in nc:
                t = runs[s][l]["transition"]
                ok &= t["kind"] == "jump"
                parts.append(f"{s} p={l}: {_fmt(t['sharpness'])} ({t['kind']})")
        claims.append({"claim": f"those transitions are sharp steps: sharpness ≥ {JUMP_SHARPNESS:g} "
                                f"(slope across λ=1 vs steepest slope elsewhere)",
                       "ours": "; ".join(parts), "met": bool(ok)})
    if cons and pnorm_labels:
        ok, parts = True, []
        for l in pnorm_labels:
            for s in cons:
                v = runs[s][l]["verdict"]
                ok &= not v["new_physics"]
                parts.append(f"{s} p={l}: ×{v['ratio']:.3g} ({'new physics' if v['new_physics'] else 'none'})")
        claims.append({"claim": f"no jump at λ=1 (verdict: no new physics) for {', '.join(cons)} with p={', '.join(pnorm_labels)}",
                       "ours": "; ".join(parts), "met": bool(ok)})
    if "ho+mf" in systems and "1" in labels:
        v = runs["ho+mf"]["1"]["verdict"]
        claims.append({"claim": "HO+MF has lower L_e above λ=1 than below (p=1; the LNN beats the black box)",
                       "ours": f"median L_e above / below = {v['ratio']:.3g} ({v['L_above']:.3g} / {v['L_below']:.3g})",
                       "met": bool(v["ratio"] < 1)})
    if nc and "mse" in labels:
        ok, parts = True, []
        for s in nc:
            t = runs[s]["mse"]["transition"]
            v = runs[s]["mse"]["verdict"]
            ok &= t["kind"] == "smooth"
            parts.append(f"{s}: sharpness {_fmt(t['sharpness'])} ({t['kind']}; L_e ×{v['ratio']:.3g} across λ=1, "
                         f"verdict {'new physics' if v['new_physics'] else 'none'})")
        claims.append({"claim": f"MSE loss gives a smooth (second-order) transition for {', '.join(nc)}: "
                                f"sharpness < {SMOOTH_SHARPNESS:g}",
                       "ours": "; ".join(parts), "met": bool(ok)})
    if FORCE_SYSTEM in systems:
        by_p = runs[FORCE_SYSTEM]
        rng = [x for x in lambdas if 0.05 <= x < 1]
        for l in labels:
            rows = [r for r in by_p[l]["table"] if r["lam"] in rng]
            if not rows:
                continue
            worst = max(max(r["m_c"], r["m_n"]) for r in rows)
            claims.append({
                "claim": f"HO+LD, p={l}, 0.05 ≲ λ < 1: f_c^NN ≈ −q and f_n^NN ≈ −½q̇ (m_c, m_n ≤ {ALIGN_TOL:g} "
                         f"at λ = {', '.join(f'{x:g}' for x in rng)})",
                "ours": "; ".join(f"λ={r['lam']:g}: {r['m_c']:.3f}/{r['m_n']:.3f}" for r in rows),
                "met": bool(worst <= ALIGN_TOL),
            })
        if "1" in labels:
            t1 = by_p["1"]["table"]
            fnr = by_p["1"]["fn_true_rms"]
            hi = [r for r in t1 if r["lam"] > 1]
            if hi:
                claims.append({
                    "claim": f"HO+LD, p=1, λ > 1: f_n^NN ≈ 0 (rms ≤ {NEAR_ZERO_FRACTION:g}× rms f_n^PHY = "
                             f"{NEAR_ZERO_FRACTION * fnr:.3f})",
                    "ours": "; ".join(f"λ={r['lam']:g}: {r['fn_rms']:.2g}" for r in hi),
                    "met": bool(all(r["fn_rms"] <= NEAR_ZERO_FRACTION * fnr for r in hi)),
                })
                claims.append({
                    "claim": f"HO+LD, p=1, λ > 1: f_c^NN ≈ f_c^PHY = −q (m_c ≤ {ALIGN_TOL:g})",
                    "ours": "; ".join(f"λ={r['lam']:g}: m_c {r['m_c']:.3f}" for r in hi),
                    "met": bool(all(r["m_c"] <= ALIGN_TOL for r in hi)),
                })
            lo = min(t1, key=lambda r: r["lam"])
            mid = [r for r in t1 if 0.1 <= r["lam"] <= 0.5]
            if lo["lam"] <= 0.05 and mid:
                ref = max(r["m_c"] for r in mid)
                claims.append({
                    "claim": "HO+LD, p=1, λ ≲ 0.05: the weakly penalised UAN absorbs part of the conservative force "
                             "(m_c at the smallest λ above every m_c on 0.1 ≤ λ ≤ 0.5)",
                    "ours": f"m_c(λ={lo['lam']:g}) = {lo['m_c']:.3f} vs max m_c on [0.1, 0.5] = {ref:.3f}",
                    "met": bool(lo["m_c"] > ref),
                })
    return claims


def lambda_p_study(
    steps: int = 2000,
    seed: int = 0,
    lambdas: Sequence[float] = PAPER_LAMBDAS,
    ps: Sequence = LOSSES,
    systems: Sequence[str] = TOY_SYSTEMS,
    out: str | Path | None = None,
    progress: Progress | None = None,
    n_train: int = 1000,
    n_test: int = 1000,
    force_lambdas: Sequence[float] = FORCE_LAMBDAS,
) -> dict:
    """Fig. 5: λ-sweeps of the toy systems for every loss, verdicts, HO+LD alignment and forces, claims.

    Returns a JSON-able dict with "settings", "curves" (system → p → rows lam, L_e, L_b, m_c, m_n, ...),
    "verdicts" (one per (system, p) with the verdict statistic and the jump/smooth sharpness), "alignment" (HO+LD:
    m_c, m_n per loss and the learned forces at ``force_lambdas``), "claims" ({claim, ours, met}), "cached"
    (the sub-runs loaded from ``out`` instead of trained) and "wall_time_s". With ``out``: writes results.json,
    fig5.png (a–d L_e(λ) per loss; e, f learned vs true forces of HO+LD, p=1; g, h m_c, m_n vs λ) and
    fig5_forces.png (learned forces for every loss), and caches each sweep in out/runs/<system>_p<p>/.
    """
    t0 = time.perf_counter()
    lams = tuple(sorted(set(validate_lambdas(lambdas))))
    if not any(x < 1 for x in lams) or not any(x > 1 for x in lams):
        raise ValueError("lambdas must contain values both below and above 1 (the transition is read across λ=1)")
    if isinstance(steps, bool) or int(steps) != steps or steps < 4:
        raise ValueError(f"steps must be an integer ≥ 4, got {steps!r}")
    if isinstance(seed, bool) or int(seed) != seed or seed < 0:
        raise ValueError(f"seed must be an integer ≥ 0, got {seed!r}")
    steps, seed = int(steps), int(seed)
    pvals = [parse_p(p) for p in ps]
    labels = [p_label(p) for p in pvals]
    if not pvals or len(set(labels)) != len(labels):
        raise ValueError(f"ps must be distinct losses, got {list(ps)!r}")
    systems = tuple(systems)
    for s in systems:
        if s not in SYSTEMS or SYSTEMS[s].data != "gaussian":
            raise ValueError(f"systems must be toy systems ({', '.join(TOY_SYSTEMS)}), got {s!r}")
    if not systems or len(set(systems)) != len(systems):
        raise ValueError(f"systems must be distinct, got {list(systems)!r}")
    outdir = ensure_writable_dir(out) if out is not None else None

    total = len(systems) * len(pvals) * len(lams)
    runs: dict[str, dict[str, dict]] = {}
    k = 0
    for s in systems:
        runs[s] = {}
        for p, l in zip(pvals, labels):
            base = k

            def prog(j, lam, base=base, s=s, l=l):
                if progress:
                    progress(base + j, total, f"{s} p={l}: done λ={lam:g}")

            if progress:
                progress(base, total, f"{s} p={l}: training")
            sub = outdir / "runs" / f"{s}_p{l}" if outdir is not None else None
            r = _lambda_p_subrun(s, p, steps, seed, lams, sub, force_lambdas, n_train, n_test, prog)
            r["transition"] = transition_sharpness([x["lam"] for x in r["table"]], [x["L_e"] for x in r["table"]])
            runs[s][l] = r
            k += len(lams)

    curves = {s: {l: runs[s][l]["table"] for l in labels} for s in systems}
    verdicts = []
    for s in systems:
        for l in labels:
            r = runs[s][l]
            v = r["verdict"]
            verdicts.append({
                "system": s, "p": l, "truth_conservative": r["truth_conservative"], "new_physics": v["new_physics"],
                "correct": v["new_physics"] != r["truth_conservative"], "ratio": v["ratio"], "L_below": v["L_below"],
                "L_above": v["L_above"], "relative_size": v["relative_size"], "reason": v["reason"],
                "sharpness": r["transition"]["sharpness"], "transition": r["transition"]["kind"],
                "rise_fraction": r["transition"]["rise_fraction"],
                "train_wall_time_s": r["train_wall_time_s"], "cached": r["cached"],
            })
    alignment_ = None
    if FORCE_SYSTEM in systems:
        alignment_ = {
            "system": FORCE_SYSTEM,
            "truth": "f_c = −q, f_n = −½q̇",
            "fn_true_rms": runs[FORCE_SYSTEM][labels[0]]["fn_true_rms"],
            "by_p": {l: [{"lam": r["lam"], "m_c": r["m_c"], "m_n": r["m_n"], "fn_rms": r["fn_rms"]}
                         for r in runs[FORCE_SYSTEM][l]["table"]] for l in labels},
            "forces": {l: runs[FORCE_SYSTEM][l]["forces"] for l in labels},
        }
    result = {
        "settings": {
            "systems": list(systems), "ps": labels, "lambdas": list(lams), "steps_per_lambda": steps, "seed": seed,
            "mode": "warm (paper appendix B: increasing λ, each from the previous λ's parameters)",
            "n_train": n_train, "n_test": n_test, "data": "iid N(0,1) q, q̇, t (paper III.C)",
            "standardize": True, "learning_rates": list(TrainConfig().lrs), "batch_size": TrainConfig().batch_size,
            "force_system": FORCE_SYSTEM, "force_lambdas": [x for x in force_lambdas if x in lams],
            "jump_sharpness": JUMP_SHARPNESS, "smooth_sharpness": SMOOTH_SHARPNESS, "align_tol": ALIGN_TOL,
            "verdict_min_ratio": MIN_RATIO,
        },
        "evaluated_on": "test set (L_e, L_b, m_c, m_n, forces)",
        "curves": curves,
        "verdicts": verdicts,
        "alignment": alignment_,
        "claims": _lambda_p_claims(runs, systems, labels, lams),
        "cached": [f"{v['system']}/p={v['p']}" for v in verdicts if v["cached"]],
        "train_wall_time_s": sum(v["train_wall_time_s"] for v in verdicts),  # of the sweeps, when they were trained
        "wall_time_s": None,  # of this call (small when the sweeps come from the cache)
        "jax_version": jax.__version__,
    }
    if outdir is not None:
        save_figure(plot_fig5(result), outdir / "fig5.png")
        if alignment_ is not None:
            save_figure(plot_fig5_forces(result), outdir / "fig5_forces.png")
    result["wall_time_s"] = time.perf_counter() - t0
    if outdir is not None:
        write_json(outdir / "results.json", result)
    return result


# ----------------------------------------------------------------------------------------------------------------
# figures of the λ/p study

_SYS_LABEL = {"ho+mf": "HO+MF", "ho+cg": "HO+CG", "ho+ld": "HO+LD", "ho+cd": "HO+CD", "ho+pf": "HO+PF"}


def _loss_title(l: str) -> str:
    return "MSE" if l == "mse" else f"p = {l}"


def _force_panels(ax_c, ax_n, forces: dict, title: str, letters=("", "")):
    q, qd = np.asarray(forces["q"]), np.asarray(forces["qd"])
    order = sorted(forces["by_lambda"].values(), key=lambda d: d["lam"])
    import matplotlib

    cmap = matplotlib.colormaps["viridis"]
    for i, d in enumerate(order):
        c = cmap(i / max(1, len(order) - 1))
        ax_c.scatter(q, d["fc"], s=3, color=c, alpha=0.6, label=f"λ={d['lam']:g}")
        ax_n.scatter(qd, d["fn"], s=3, color=c, alpha=0.6, label=f"λ={d['lam']:g}")
    xs = np.linspace(min(q.min(), qd.min()), max(q.max(), qd.max()), 50)
    ax_c.plot(xs, -xs, "r--", lw=1.2, label="truth −q")
    ax_n.plot(xs, -0.5 * xs, "r--", lw=1.2, label="truth −q̇/2")
    ax_c.set_xlabel("q")
    ax_c.set_ylabel(r"$f_c^{NN}$")
    ax_n.set_xlabel(r"$\dot q$")
    ax_n.set_ylabel(r"$f_n^{NN}$")
    # a few points where the learned Lagrangian's mass is nearly singular can be far off: keep the axes on the truth's
    # scale and count what falls outside
    for ax, _x, truth, preds in ((ax_c, q, -q, [d["fc"] for d in order]), (ax_n, qd, -0.5 * qd, [d["fn"] for d in order])):
        lim = 2.0 * float(np.max(np.abs(truth))) + 0.5
        n_out = sum(int(np.sum(np.abs(np.asarray(p)) > lim)) for p in preds)
        ax.set_ylim(-lim, lim)
        if n_out:
            ax.text(0.02, 0.02, f"{n_out} points off scale", transform=ax.transAxes, fontsize=7)
    pre = [f"({x}) " if x else "" for x in letters]
    ax_c.set_title(f"{pre[0]}{title}: $f_c^{{NN}}$ vs $q$", fontsize=9)
    ax_n.set_title(f"{pre[1]}{title}: $f_n^{{NN}}$ vs $\\dot q$", fontsize=9)


def plot_fig5(result: dict):
    """Fig. 5 analogue: (a–d) L_e(λ) per loss, five systems each; (e, f) HO+LD learned f_c vs q and f_n vs q̇ for
    p = 1 (first loss) at several λ; (g, h) HO+LD m_c(λ) and m_n(λ) for every loss."""
    labels = result["settings"]["ps"]
    ncol = max(4, len(labels))
    fig, axes = subplots(2, ncol, figsize=(4.0 * ncol, 7.6))
    letters = "abcdefghijklmnop"
    for j in range(ncol):
        ax = axes[0, j]
        if j >= len(labels):
            ax.axis("off")
            continue
        l = labels[j]
        for i, (s, by_p) in enumerate(result["curves"].items()):
            rows = by_p[l]
            ax.plot([r["lam"] for r in rows], [max(r["L_e"], 1e-9) for r in rows], "o-", ms=3, color=f"C{i}",
                    label=_SYS_LABEL.get(s, s))
        ax.axvline(1.0, color="k", lw=0.8, ls=":")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel(r"$\lambda$")
        ax.set_ylabel(r"$L_e$ (test)" + (" (mean square)" if l == "mse" else ""))
        ax.set_title(f"({letters[j]}) {_loss_title(l)}", fontsize=10)
        if j == 0:
            ax.legend(fontsize=7)
    al = result.get("alignment")
    row2 = axes[1]
    if al is None:
        for ax in row2:
            ax.axis("off")
    else:
        l0 = labels[0]
        _force_panels(row2[0], row2[1], al["forces"][l0], f"HO+LD {_loss_title(l0)}", (letters[ncol], letters[ncol + 1]))
        row2[0].legend(fontsize=6, markerscale=3)
        for j, key in ((2, "m_c"), (3, "m_n")):
            ax = row2[j]
            for i, l in enumerate(labels):
                rows = al["by_p"][l]
                ax.plot([r["lam"] for r in rows], [max(r[key], 1e-9) for r in rows], "o-", ms=3, color=f"C{i}",
                        label=_loss_title(l))
            ax.axvline(1.0, color="k", lw=0.8, ls=":")
            ax.axhline(ALIGN_TOL, color="gray", lw=0.8, ls="--")
            ax.set_xscale("log")
            ax.set_yscale("log")
            ax.set_xlabel(r"$\lambda$")
            ax.set_ylabel(f"${key[0]}_{key[2]}$")
            ax.set_title(f"({letters[ncol + j]}) HO+LD misalignment ${key[0]}_{key[2]}$", fontsize=10)
            ax.legend(fontsize=7)
        for ax in row2[4:]:
            ax.axis("off")
    fig.tight_layout()
    return fig


def plot_fig5_forces(result: dict):
    """HO+LD learned f_c (vs q) and f_n (vs q̇) on test points at several λ, one row per loss, truth dashed."""
    al = result["alignment"]
    labels = result["settings"]["ps"]
    fig, axes = subplots(len(labels), 2, figsize=(8.5, 3.2 * len(labels)), squeeze=False)
    for i, l in enumerate(labels):
        _force_panels(axes[i, 0], axes[i, 1], al["forces"][l], f"HO+LD {_loss_title(l)}")
    axes[0, 0].legend(fontsize=6, markerscale=3)
    fig.tight_layout()
    return fig


# ----------------------------------------------------------------------------------------------------------------
# data-quality study


def _stack(datasets: Sequence[Dataset]):
    arrs = [_as_arrays(d, jnp.float64) for d in datasets]
    return tuple(jnp.stack([a[i] for a in arrs]) for i in range(4))


def _train_grid(train_sets: Sequence[Dataset], lam: float, cfg: ModelConfig, tcfg: TrainConfig, seed: int):
    """Train one NNPhD per data set at the same λ, from the same initialisation and minibatch keys, in one vmap."""
    k_init, k_train = jax.random.split(jax.random.PRNGKey(seed))
    params0 = init_nnphd(k_init, cfg)
    train = make_trainer(cfg, tcfg)
    vtrain = jax.jit(jax.vmap(train, in_axes=(None, 0, None, None)))
    pstack, _ = vtrain(params0, _stack(train_sets), jnp.asarray(lam, jnp.float64), k_train)
    return [jax.tree_util.tree_map(lambda a, i=i: a[i], pstack) for i in range(len(train_sets))]


def _dq_grid_run(kind: str, grid, steps: int, seed: int, n_train: int, n_test: int, path: Path | None) -> dict:
    if kind == "alpha":
        system, lam, make = "ho+cd", DQ_LAM_ALPHA, pie_dataset
    else:
        system, lam, make = "ho+ld", DQ_LAM_BETA, imbalanced_dataset
    sysm = get_system(system)
    cfg = ModelConfig(n=1)
    tcfg = TrainConfig(steps=steps, p=DQ_P)
    settings = {"kind": kind, "system": system, "system_params": dict(sysm.params), "lam": lam, "p": DQ_P,
                "grid": list(grid), "steps": steps, "seed": seed, "n_train": n_train, "n_test": n_test,
                "learning_rates": list(tcfg.lrs), "batch_size": tcfg.batch_size, "model": asdict(cfg),
                "standardize": False, "training": "from scratch at fixed λ, all grid points in one vmap",
                "format": _FORMAT}
    fp = _fingerprint(settings)
    if path is not None:
        cached = _load_cached(path, fp)
        if cached is not None:
            cached["cached"] = True
            return cached
    s_train, s_test, s_full = np.random.SeedSequence(seed).spawn(3)
    # the same seeds for every grid point (common random numbers: only α or β changes between data sets)
    trains = [make(sysm, n_train, g, s_train) for g in grid]
    tests = [make(sysm, n_test, g, s_test) for g in grid]
    full = gaussian_dataset(sysm, n_test, s_full)
    t0 = time.perf_counter()
    params = _train_grid(trains, lam, cfg, tcfg, seed)
    wall = time.perf_counter() - t0
    rows = []
    for g, prm, tr, te in zip(grid, params, trains, tests):
        e_te, e_tr, e_full = (evaluate(prm, d, cfg, DQ_P) for d in (te, tr, full))
        row = {
            "alpha" if kind == "alpha" else "beta": g,
            "L_e": e_te.L_e, "L_b": e_te.L_b, "L_e_train": e_tr.L_e, "L_e_full": e_full.L_e,
            "fn_size": float(np.mean(np.abs(te.fn))),  # ‖f_n‖₁ on the evaluation data (the L_e a Lagrangian-only model would leave if it fits f_c exactly)
            "m_c": alignment(e_te.fc, te.fc), "m_n": alignment(e_te.fn, te.fn),
            "m_c_train": alignment(e_tr.fc, tr.fc), "m_n_train": alignment(e_tr.fn, tr.fn),
            "m_c_full": alignment(e_full.fc, full.fc), "m_n_full": alignment(e_full.fn, full.fn),
            # robust companions of m_c, m_n (rms): the median |f^NN − f^PHY| over the test samples
            "m_c_median": float(np.median(np.abs(e_te.fc - te.fc))), "m_n_median": float(np.median(np.abs(e_te.fn - te.fn))),
            "frac_qd_pos": float(np.mean(tr.qd[:, 0] > 0)),
        }
        rows.append(row)
    res = {"settings": settings, "fingerprint": fp, "table": rows, "train_wall_time_s": wall,
           "evaluated_on": ("L_e, L_b, m_c, m_n: held-out test set from the same distribution as the training set "
                            "(same α/β, other seed); *_train: the training set; *_full: a full N(0,1) Gaussian test set")}
    res = json.loads(json.dumps(res, default=_jsonable))
    if path is not None:
        write_json(path, res)
    res["cached"] = False
    return res


def _dq_claims(alpha_rows: list[dict], beta_rows: list[dict]) -> list[dict]:
    claims = []
    lo = [r for r in alpha_rows if r["alpha"] <= 0.5]
    hi = [r for r in alpha_rows if r["alpha"] > 0.5]
    if lo:
        worst = max(lo, key=lambda r: r["L_e"])
        tol = NEAR_ZERO_FRACTION * max(r["fn_size"] for r in lo) if any(r["fn_size"] > 0 for r in lo) else None
        tol = NEAR_ZERO_FRACTION * 0.5 if tol is None else tol
        claims.append({
            "claim": f"HO+CD, λ=10: L_e nearly zero for α ≤ 0.5 (≤ {NEAR_ZERO_FRACTION:g}× ‖f_n‖₁ = {tol:.3g}): "
                     "on q̇ ≥ 0 the damping looks like a constant conservative force",
            "ours": f"max L_e = {worst['L_e']:.3g} at α={worst['alpha']:g}; "
                    + ", ".join(f"α={r['alpha']:g}: {r['L_e']:.3g}" for r in lo),
            "met": bool(worst["L_e"] <= tol),
        })
    if lo and hi:
        med_lo = float(np.median([r["L_e"] for r in lo]))
        med_hi = float(np.median([r["L_e"] for r in hi]))
        claims.append({
            "claim": f"HO+CD, λ=10: L_e jumps past α = 0.5 (median L_e over α > 0.5 ≥ {MIN_RATIO:g}× median over "
                     "α ≤ 0.5, the verdict's statistic)",
            "ours": f"median {med_hi:.3g} vs {med_lo:.3g}: ×{med_hi / max(med_lo, 1e-300):.3g}",
            "met": bool(med_hi >= MIN_RATIO * med_lo),
        })
        mn_hi = min(r["L_e"] for r in hi)
        mx_lo = max(r["L_e"] for r in lo)
        claims.append({
            "claim": f"HO+CD, λ=10: every α > 0.5 has L_e ≥ {MIN_RATIO:g}× every α ≤ 0.5 (strict reading)",
            "ours": f"min over α > 0.5 = {mn_hi:.3g}, max over α ≤ 0.5 = {mx_lo:.3g}: ×{mn_hi / max(mx_lo, 1e-300):.3g}",
            "met": bool(mn_hi >= MIN_RATIO * mx_lo),
        })
    if beta_rows:
        half = [r for r in beta_rows if r["beta"] == 0.5]
        if half and len(beta_rows) > 1:
            bc = min(beta_rows, key=lambda r: r["m_c"])
            bn = min(beta_rows, key=lambda r: r["m_n"])
            claims.append({
                "claim": "HO+LD, λ=0.5: misalignment m_c, m_n is smallest at β = 0.5 (balanced data)",
                "ours": f"argmin m_c: β={bc['beta']:g} ({bc['m_c']:.3g}); argmin m_n: β={bn['beta']:g} ({bn['m_n']:.3g})",
                "met": bool(bc["beta"] == 0.5 and bn["beta"] == 0.5),
            })
        if half:
            h = half[0]
            claims.append({
                "claim": f"HO+LD, λ=0.5: nearly zero misalignment at β = 0.5 (m_c, m_n ≤ {ALIGN_TOL:g})",
                "ours": f"m_c = {h['m_c']:.3g}, m_n = {h['m_n']:.3g}",
                "met": bool(max(h["m_c"], h["m_n"]) <= ALIGN_TOL),
            })
    return claims


def _check_grid(values, name: str) -> tuple[float, ...]:
    try:
        vals = tuple(float(v) for v in values)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be numbers in [0, 1], got {values!r}") from None
    if not vals:
        raise ValueError(f"{name} must not be empty")
    for v in vals:
        if not (0.0 <= v <= 1.0):
            raise ValueError(f"{name} must be numbers in [0, 1], got {v:g}")
    return tuple(sorted(set(vals)))


def data_quality_study(
    steps: int = 2000,
    seed: int = 0,
    alphas: Sequence[float] = DQ_GRID,
    betas: Sequence[float] = DQ_GRID,
    out: str | Path | None = None,
    progress: Progress | None = None,
    n_train: int = 1000,
    n_test: int = 1000,
) -> dict:
    """Fig. 6: L_e(α) of HO+CD at λ=10 on pie-shaped data, m_c(β), m_n(β) of HO+LD at λ=0.5 on imbalanced data.

    Returns a JSON-able dict with "settings", "alpha" and "beta" (the two tables and their settings), "claims"
    ({claim, ours, met}), "cached" and "wall_time_s". With ``out``: writes results.json and fig6.png, and caches the
    two grids in out/alpha.json, out/beta.json (a repeated call with the same settings loads them).
    """
    t0 = time.perf_counter()
    if isinstance(steps, bool) or int(steps) != steps or steps < 4:
        raise ValueError(f"steps must be an integer ≥ 4, got {steps!r}")
    if isinstance(seed, bool) or int(seed) != seed or seed < 0:
        raise ValueError(f"seed must be an integer ≥ 0, got {seed!r}")
    steps, seed = int(steps), int(seed)
    al = _check_grid(alphas, "alphas")
    be = _check_grid(betas, "betas")
    outdir = ensure_writable_dir(out) if out is not None else None
    if progress:
        progress(0, 2, f"HO+CD pie coverage: {len(al)} α at λ={DQ_LAM_ALPHA:g}")
    ares = _dq_grid_run("alpha", al, steps, seed, n_train, n_test, outdir / "alpha.json" if outdir else None)
    if progress:
        progress(1, 2, f"HO+LD imbalance: {len(be)} β at λ={DQ_LAM_BETA:g}")
    bres = _dq_grid_run("beta", be, steps, seed, n_train, n_test, outdir / "beta.json" if outdir else None)
    if progress:
        progress(2, 2, "done")
    result = {
        "settings": {"steps": steps, "seed": seed, "alphas": list(al), "betas": list(be), "p": DQ_P,
                     "lam_alpha": DQ_LAM_ALPHA, "lam_beta": DQ_LAM_BETA, "n_train": n_train, "n_test": n_test,
                     "alpha_system": "ho+cd", "beta_system": "ho+ld", "standardize": False,
                     "training": "from scratch at fixed λ (no sweep), one vmap over the grid, same init",
                     "align_tol": ALIGN_TOL},
        "evaluated_on": ares["evaluated_on"],
        "alpha": ares,
        "beta": bres,
        "claims": _dq_claims(ares["table"], bres["table"]),
        "cached": [k for k, r in (("alpha", ares), ("beta", bres)) if r["cached"]],
        "train_wall_time_s": ares["train_wall_time_s"] + bres["train_wall_time_s"],  # when they were trained
        "wall_time_s": None,  # of this call (small when both grids come from the cache)
        "jax_version": jax.__version__,
    }
    if outdir is not None:
        save_figure(plot_fig6(result), outdir / "fig6.png")
    result["wall_time_s"] = time.perf_counter() - t0
    if outdir is not None:
        write_json(outdir / "results.json", result)
    return result


def plot_fig6(result: dict):
    """Fig. 6 analogue: (a) L_e(α) of HO+CD at λ=10; (b) m_c(β), m_n(β) of HO+LD at λ=0.5."""
    fig, (a, b) = subplots(1, 2, figsize=(10, 4))
    rows = result["alpha"]["table"]
    x = [r["alpha"] for r in rows]
    a.plot(x, [max(r["L_e"], 1e-9) for r in rows], "o-", label="test, same α")
    a.plot(x, [max(r["L_e_train"], 1e-9) for r in rows], "s--", ms=3, alpha=0.7, label="training set")
    a.plot(x, [max(r["L_e_full"], 1e-9) for r in rows], "^:", ms=3, alpha=0.6, color="gray", label="full Gaussian")
    a.axvline(0.5, color="k", lw=0.8, ls=":")
    a.set_yscale("log")
    a.set_xlabel(r"pie coverage $\alpha$")
    a.set_ylabel(r"$L_e$ (p=1)")
    a.set_title(rf"(a) HO+CD, $\lambda$={result['settings']['lam_alpha']:g}: incomplete coverage", fontsize=10)
    a.legend(fontsize=7)
    rows = result["beta"]["table"]
    x = [r["beta"] for r in rows]
    b.plot(x, [r["m_c"] for r in rows], "o-", label=r"$m_c$")
    b.plot(x, [r["m_n"] for r in rows], "s-", label=r"$m_n$")
    b.plot(x, [r["m_c_full"] for r in rows], "o:", ms=3, alpha=0.6, color="C0", label=r"$m_c$ on balanced data")
    b.plot(x, [r["m_n_full"] for r in rows], "s:", ms=3, alpha=0.6, color="C1", label=r"$m_n$ on balanced data")
    b.axvline(0.5, color="k", lw=0.8, ls=":")
    b.set_xlabel(r"fraction $\beta$ of samples with $\dot q > 0$")
    b.set_ylabel("misalignment")
    b.set_title(rf"(b) HO+LD, $\lambda$={result['settings']['lam_beta']:g}: imbalanced data", fontsize=10)
    b.legend(fontsize=7)
    fig.tight_layout()
    return fig
