r"""The λ/p study (paper section III.C, Fig. 5 a–h).

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

The sweeps are cached in ``out`` (one JSON per (system, p) under ``out/runs/``, :mod:`nnphd.io.cache`): a repeated
call with the same settings loads them (flag ``cached``) instead of training, and an interrupted λ-sweep resumes
from its per-λ checkpoint. A cache file is only used when its fingerprint (every training setting) matches.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import jax
import numpy as np

from nnphd.engine.systems import SYSTEMS
from nnphd.engine.train import (
    PAPER_LAMBDAS,
    TrainConfig,
    evaluate,
    parse_p,
    validate_lambdas,
)
from nnphd.engine.verdict import MIN_RATIO
from nnphd.io.progress import Progress, nested
from nnphd.io.results import ensure_writable_dir, write_results
from nnphd.paper.figures import plot_fig5, plot_fig5_forces
from nnphd.paper.study_results import (
    Alignment,
    AlignmentRow,
    Claim,
    CurveRow,
    LambdaPResult,
    LambdaPVerdict,
    LearnedForces,
)
from nnphd.paper.sweep import SweepSettings, plan_sweep
from nnphd.parallel import Unit, UnitsFailed, run_units, runs_here

__all__ = [
    "TOY_SYSTEMS",
    "LOSSES",
    "FORCE_SYSTEM",
    "FORCE_LAMBDAS",
    "JUMP_SHARPNESS",
    "SMOOTH_SHARPNESS",
    "ALIGN_TOL",
    "p_label",
    "transition_sharpness",
    "LambdaPSettings",
    "lambda_p_study",
]

TOY_SYSTEMS: tuple[str, ...] = ("ho+mf", "ho+cg", "ho+ld", "ho+cd", "ho+pf")
NONCONSERVATIVE: tuple[str, ...] = ("ho+ld", "ho+cd", "ho+pf")
LOSSES: tuple = (1, 2, 3, "mse")
FORCE_SYSTEM = "ho+ld"  # Fig. 5 e–h: q̈ = −q − ½q̇
FORCE_LAMBDAS: tuple[float, ...] = (0.01, 0.1, 0.5, 2.0, 10.0)  # λ at which f_c^NN, f_n^NN are recorded and plotted
N_FORCE_POINTS = 400  # test points whose learned forces are stored for the plots
JUMP_SHARPNESS = 2.0  # sharpness ≥ this: the step across λ = 1 is a jump (first-order transition)
SMOOTH_SHARPNESS = 1.0  # sharpness < this: smooth (the curve is as steep elsewhere)
ALIGN_TOL = 0.05  # "aligned": m_c, m_n ≤ 0.05 = 10% of the rms of the true f_n = −½q̇ (rms 0.5 on N(0,1) data)
NEAR_ZERO_FRACTION = 0.1  # "nearly zero" L_e: ≤ 10% of the rms/L1 size of the non-conservative force on the data

RESULT_FORMAT = 1  # version of the cached sub-run files (bump when their content changes)


@dataclass(frozen=True)
class LambdaPSettings:
    """What a λ/p study (:func:`lambda_p_study`) runs: training ``steps`` per λ, the ``seed``, the λ grid
    ``lambdas`` (values below and above 1), the losses ``ps`` (p-norms and "mse"), the toy ``systems``, the Gaussian
    sample sizes ``n_train``, ``n_test``, and the ``force_lambdas`` at which HO+LD's learned forces are kept. Checked
    (and normalised: sorted distinct λ, parsed losses) when the study starts."""

    steps: int = 2000
    seed: int = 0
    lambdas: Sequence[float] = PAPER_LAMBDAS
    ps: Sequence = LOSSES
    systems: Sequence[str] = TOY_SYSTEMS
    n_train: int = 1000
    n_test: int = 1000
    force_lambdas: Sequence[float] = FORCE_LAMBDAS


def p_label(p) -> str:
    """'1', '2', '3', '1.5' or 'mse' — the key of a loss in results and file names."""
    p = parse_p(p)
    return "mse" if p == "mse" else f"{p:g}"


# ----------------------------------------------------------------------------------------------------------------
# jump vs smooth


def transition_sharpness(
    lams: Sequence[float], L_e: Sequence[float], jump: float = JUMP_SHARPNESS, smooth: float = SMOOTH_SHARPNESS
) -> dict:
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
    return {
        "sharpness": sharp,
        "slope_across": across,
        "slope_max_other": max_other,
        "lam_below": lo[0],
        "lam_above": hi[0],
        "kind": kind,
        "jump_threshold": jump,
        "smooth_threshold": smooth,
        "rise_fraction": rise_fraction,
    }


# ----------------------------------------------------------------------------------------------------------------
# λ/p study: one cached sub-run per (system, p)


def _rms(a) -> float:
    a = np.asarray(a, float)
    return float(np.sqrt(np.mean(a * a)))


def lambda_p_subrun(
    system: str, sweep: SweepSettings, subdir: Path | None, force_lams, progress: Progress | None
) -> dict:
    """One λ-sweep of :func:`nnphd.paper.sweep.plan_sweep` (``sweep``: warm mode, standardised inputs), cached in
    ``subdir`` with the learned forces of the test set at ``force_lams``."""
    lambdas = sweep.lambdas
    force_lams = sorted(x for x in force_lams if x in lambdas) if system == FORCE_SYSTEM else []
    extra = {
        "n_train": sweep.n_train,
        "n_test": sweep.n_test,
        "force_lambdas": force_lams,
        "n_force_points": N_FORCE_POINTS if force_lams else 0,
        "format": RESULT_FORMAT,
    }
    plan = plan_sweep(system, sweep, subdir, extra)
    cached = plan.cache.load()
    if cached is not None:
        cached["cached"] = True
        if progress:
            progress(len(lambdas), len(lambdas), "cached")
        return cached
    if subdir is not None:
        ensure_writable_dir(subdir)
    r = plan.run(progress)
    sysm, test, cfg, tcfg = plan.system, plan.test, plan.cfg, plan.tcfg
    table = []
    forces = None
    if force_lams:
        k = min(N_FORCE_POINTS, len(test))
        forces = {
            "evaluated_on": f"first {k} test points",
            "q": test.q[:k, 0],
            "qd": test.qd[:k, 0],
            "fc_true": test.fc[:k, 0],
            "fn_true": test.fn[:k, 0],
            "by_lambda": {},
        }
    for pt in r.points:
        ev = evaluate(pt.params, test, cfg, tcfg.p)
        table.append(
            {
                **pt.row(),
                "fn_rms": _rms(ev.fn),
                # robust companions of m_c, m_n: the median |f^NN − f^PHY| over the test samples
                "m_c_median": float(np.median(np.abs(ev.fc - test.fc))),
                "m_n_median": float(np.median(np.abs(ev.fn - test.fn))),
            }
        )
        if forces is not None and pt.lam in force_lams:
            forces["by_lambda"][f"{pt.lam:g}"] = {"lam": pt.lam, "fc": ev.fc[:k, 0], "fn": ev.fn[:k, 0]}
    res = plan.cache.save(
        {
            "system": sysm.name,
            "p": p_label(tcfg.p),
            "truth_conservative": sysm.conservative,
            "table": table,
            "verdict": r.verdict.to_dict(),
            "fn_true_rms": _rms(test.fn),
            "forces": forces,
            "evaluated_on": "test set (10³ Gaussian samples independent of the training set)",
            "settings": plan.settings,
            "train_wall_time_s": r.wall_time_s,
            "resumed_lambdas": r.resumed,
        }
    )
    plan.cache.clear_checkpoint()
    res["cached"] = False
    return res


def _validated(settings: LambdaPSettings) -> LambdaPSettings:
    """The settings of a λ/p study, checked and normalised (sorted distinct λ, parsed losses, integer steps and
    seed, systems as a tuple)."""
    systems, ps, steps, seed, lambdas = settings.systems, settings.ps, settings.steps, settings.seed, settings.lambdas
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

    return replace(settings, systems=systems, ps=tuple(pvals), steps=steps, seed=seed, lambdas=lams)


def study_units(settings: LambdaPSettings, out: str | Path) -> list[Unit]:
    """The sweeps of ``lambda_p_study(settings, out=out)`` as units (``nnphd reproduce`` runs them beside its other
    units; the study then loads them from ``out``'s cache)."""
    return lambda_p_units(_validated(settings), Path(out))


def lambda_p_units(settings: LambdaPSettings, outdir: Path | None, progress: Progress | None = None) -> list[Unit]:
    """One :class:`nnphd.parallel.Unit` per (system, p) sweep of the checked ``settings``, keyed
    ``"<system>/p=<p>"``; ``progress`` (for in-process runs) follows every λ of every sweep."""
    st = settings
    total = len(st.systems) * len(st.ps) * len(st.lambdas)
    units = []
    for s in st.systems:
        for p in st.ps:
            l = p_label(p)
            base = len(units) * len(st.lambdas)
            sub = outdir / "runs" / f"{s}_p{l}" if outdir is not None else None
            sweep = SweepSettings(
                p=p,
                steps=st.steps,
                seed=st.seed,
                lambdas=st.lambdas,
                mode="warm",
                n_train=st.n_train,
                n_test=st.n_test,
                standardize=True,
            )
            kw = dict(
                system=s, sweep=sweep, subdir=sub, force_lams=st.force_lambdas,
                progress=nested(progress, f"{s} p={l}: done ", base, total),
            )  # fmt: skip
            units.append(Unit(f"{s}/p={l}", lambda_p_subrun, kw))
    return units


def run_lambda_p_sweeps(
    settings: LambdaPSettings,
    outdir: Path | None,
    progress: Progress | None,
    workers: int | None,
    scheduler: str | None,
) -> dict[str, dict[str, dict]]:
    """Every (system, p) sweep of the checked ``settings`` (trained, or loaded from ``outdir``'s cache):
    {system: {p label: sub-run}}."""
    systems = settings.systems
    here = runs_here(workers, scheduler, len(systems) * len(settings.ps))
    units = lambda_p_units(settings, outdir, progress if here else None)
    outs = run_units(units, workers, scheduler, progress=None if here else progress)
    failed = [o for o in outs.values() if not o.ok]
    if failed:
        where = (
            f"; the {len(units) - len(failed)} finished ones are cached in {outdir}: rerun to resume" if outdir else ""
        )
        raise UnitsFailed(f"{len(failed)} of {len(units)} sweeps failed ({failed[0].key}: {failed[0].error}){where}")
    runs: dict[str, dict[str, dict]] = {s: {} for s in systems}
    for u in units:
        s, l = u.key.split("/p=")
        runs[s][l] = {**outs[u.key].value, "compile_time_s": outs[u.key].compile_time_s}
    return runs


def _fmt(x, nd=3) -> str:
    return "—" if x is None else f"{x:.{nd}g}"


def _nonconservative_pnorm_claims(runs: dict, nc: list, pnorm_labels: list) -> list[dict]:
    """The non-conservative systems under the p-norm losses: the verdict finds new physics, and the transition at
    λ = 1 is a sharp step."""
    claims = []
    ok, parts = True, []
    for l in pnorm_labels:
        for s in nc:
            v = runs[s][l]["verdict"]
            ok &= v["new_physics"]
            parts.append(f"{s} p={l}: ×{v['ratio']:.3g} ({'new physics' if v['new_physics'] else 'none'})")
    claims.append(
        {
            "claim": f"L_e jumps at λ=1 (verdict: new physics) for {', '.join(nc)} with p={', '.join(pnorm_labels)}",
            "ours": "; ".join(parts),
            "met": bool(ok),
        }
    )
    ok, parts = True, []
    for l in pnorm_labels:
        for s in nc:
            t = runs[s][l]["transition"]
            ok &= t["kind"] == "jump"
            parts.append(f"{s} p={l}: {_fmt(t['sharpness'])} ({t['kind']})")
    claims.append(
        {
            "claim": f"those transitions are sharp steps: sharpness ≥ {JUMP_SHARPNESS:g} "
            f"(slope across λ=1 vs steepest slope elsewhere)",
            "ours": "; ".join(parts),
            "met": bool(ok),
        }
    )
    return claims


def _conservative_pnorm_claims(runs: dict, cons: list, pnorm_labels: list) -> list[dict]:
    """The conservative systems under the p-norm losses: the verdict finds no new physics."""
    claims = []
    ok, parts = True, []
    for l in pnorm_labels:
        for s in cons:
            v = runs[s][l]["verdict"]
            ok &= not v["new_physics"]
            parts.append(f"{s} p={l}: ×{v['ratio']:.3g} ({'new physics' if v['new_physics'] else 'none'})")
    claims.append(
        {
            "claim": f"no jump at λ=1 (verdict: no new physics) for {', '.join(cons)} with p={', '.join(pnorm_labels)}",
            "ours": "; ".join(parts),
            "met": bool(ok),
        }
    )
    return claims


def _mse_claims(runs: dict, nc: list) -> list[dict]:
    """The non-conservative systems under the MSE loss: a smooth (second-order) transition."""
    claims = []
    ok, parts = True, []
    for s in nc:
        t = runs[s]["mse"]["transition"]
        v = runs[s]["mse"]["verdict"]
        ok &= t["kind"] == "smooth"
        parts.append(
            f"{s}: sharpness {_fmt(t['sharpness'])} ({t['kind']}; L_e ×{v['ratio']:.3g} across λ=1, "
            f"verdict {'new physics' if v['new_physics'] else 'none'})"
        )
    claims.append(
        {
            "claim": f"MSE loss gives a smooth (second-order) transition for {', '.join(nc)}: "
            f"sharpness < {SMOOTH_SHARPNESS:g}",
            "ours": "; ".join(parts),
            "met": bool(ok),
        }
    )
    return claims


def _force_claims(runs: dict, labels, lambdas) -> list[dict]:
    """The learned forces of HO+LD (FORCE_SYSTEM): f_c^NN and f_n^NN against the truth below λ = 1, f_n^NN ≈ 0 and
    f_c^NN ≈ −q above it (p = 1), and the UAN absorbing part of the conservative force at the smallest λ."""
    claims = []
    by_p = runs[FORCE_SYSTEM]
    rng = [x for x in lambdas if 0.05 <= x < 1]
    for l in labels:
        rows = [r for r in by_p[l]["table"] if r["lam"] in rng]
        if not rows:
            continue
        worst = max(max(r["m_c"], r["m_n"]) for r in rows)
        claims.append(
            {
                "claim": f"HO+LD, p={l}, 0.05 ≲ λ < 1: f_c^NN ≈ −q and f_n^NN ≈ −½q̇ (m_c, m_n ≤ {ALIGN_TOL:g} "
                f"at λ = {', '.join(f'{x:g}' for x in rng)})",
                "ours": "; ".join(f"λ={r['lam']:g}: {r['m_c']:.3f}/{r['m_n']:.3f}" for r in rows),
                "met": bool(worst <= ALIGN_TOL),
            }
        )
    if "1" in labels:
        t1 = by_p["1"]["table"]
        fnr = by_p["1"]["fn_true_rms"]
        hi = [r for r in t1 if r["lam"] > 1]
        if hi:
            claims.append(
                {
                    "claim": f"HO+LD, p=1, λ > 1: f_n^NN ≈ 0 (rms ≤ {NEAR_ZERO_FRACTION:g}× rms f_n^PHY = "
                    f"{NEAR_ZERO_FRACTION * fnr:.3f})",
                    "ours": "; ".join(f"λ={r['lam']:g}: {r['fn_rms']:.2g}" for r in hi),
                    "met": bool(all(r["fn_rms"] <= NEAR_ZERO_FRACTION * fnr for r in hi)),
                }
            )
            claims.append(
                {
                    "claim": f"HO+LD, p=1, λ > 1: f_c^NN ≈ f_c^PHY = −q (m_c ≤ {ALIGN_TOL:g})",
                    "ours": "; ".join(f"λ={r['lam']:g}: m_c {r['m_c']:.3f}" for r in hi),
                    "met": bool(all(r["m_c"] <= ALIGN_TOL for r in hi)),
                }
            )
        lo = min(t1, key=lambda r: r["lam"])
        mid = [r for r in t1 if 0.1 <= r["lam"] <= 0.5]
        if lo["lam"] <= 0.05 and mid:
            ref = max(r["m_c"] for r in mid)
            claims.append(
                {
                    "claim": "HO+LD, p=1, λ ≲ 0.05: the weakly penalised UAN absorbs part of the conservative force "
                    "(m_c at the smallest λ above every m_c on 0.1 ≤ λ ≤ 0.5)",
                    "ours": f"m_c(λ={lo['lam']:g}) = {lo['m_c']:.3f} vs max m_c on [0.1, 0.5] = {ref:.3f}",
                    "met": bool(lo["m_c"] > ref),
                }
            )
    return claims


def _lambda_p_claims(runs: dict, systems, labels, lambdas) -> list[dict]:
    claims = []
    nc = [s for s in systems if s in NONCONSERVATIVE]
    cons = [s for s in systems if s not in NONCONSERVATIVE]
    pnorm_labels = [l for l in labels if l in ("1", "2", "3")]
    if nc and pnorm_labels:
        claims += _nonconservative_pnorm_claims(runs, nc, pnorm_labels)
    if cons and pnorm_labels:
        claims += _conservative_pnorm_claims(runs, cons, pnorm_labels)
    if "ho+mf" in systems and "1" in labels:
        v = runs["ho+mf"]["1"]["verdict"]
        claims.append(
            {
                "claim": "HO+MF has lower L_e above λ=1 than below (p=1; the LNN beats the black box)",
                "ours": f"median L_e above / below = {v['ratio']:.3g} ({v['L_above']:.3g} / {v['L_below']:.3g})",
                "met": bool(v["ratio"] < 1),
            }
        )
    if nc and "mse" in labels:
        claims += _mse_claims(runs, nc)
    if FORCE_SYSTEM in systems:
        claims += _force_claims(runs, labels, lambdas)
    return claims


def lambda_p_study(
    settings: LambdaPSettings = LambdaPSettings(),
    out: str | Path | None = None,
    progress: Progress | None = None,
    workers: int | None = 1,
    scheduler: str | None = None,
) -> LambdaPResult:
    """Fig. 5: λ-sweeps of the toy systems for every loss, verdicts, HO+LD alignment and forces, claims.

    Returns a :class:`nnphd.paper.study_results.LambdaPResult`: ``curves`` (system → p → one row per λ: lam, L_e,
    L_b, m_c, m_n, ...), ``verdicts`` (one per (system, p) with the verdict statistic and the jump/smooth
    sharpness), ``alignment`` (HO+LD: m_c, m_n per loss and the learned forces at ``force_lambdas``), ``claims``
    (claim, ours, met), ``cached`` (the sub-runs loaded from ``out`` instead of trained), ``settings`` and
    ``wall_time_s``; ``to_dict()`` is results.json's content. With ``out``: writes results.json, fig5.png (a–d
    L_e(λ) per loss; e, f learned vs true forces of HO+LD, p=1; g, h m_c, m_n vs λ) and fig5_forces.png (learned
    forces for every loss), and caches each sweep in out/runs/<system>_p<p>/. ``settings``: :class:`LambdaPSettings`.

    The (system, p) sweeps are independent units of :func:`nnphd.parallel.run_units`: ``workers`` local worker
    processes (1: here, in this process; None: one per core) or an existing Dask ``scheduler``. The numbers do not
    depend on the number of workers. A sweep that fails is reported after the others have finished (and been cached).
    """
    t0 = time.perf_counter()
    st = _validated(settings)
    systems, lams = st.systems, st.lambdas
    labels = [p_label(p) for p in st.ps]
    outdir = ensure_writable_dir(out) if out is not None else None

    runs = run_lambda_p_sweeps(st, outdir, progress, workers, scheduler)
    _add_transitions(runs, systems, labels)
    result = LambdaPResult(
        settings=_study_settings(st, labels),
        evaluated_on="test set (L_e, L_b, m_c, m_n, forces)",
        curves={s: {l: _curve(runs[s][l]["table"], s, l) for l in labels} for s in systems},
        verdicts=_verdict_rows(runs, systems, labels),
        alignment=_alignment(runs, labels) if FORCE_SYSTEM in systems else None,
        claims=tuple(Claim(**c) for c in _lambda_p_claims(runs, systems, labels, lams)),
        compile_time_s=sum(runs[s][l]["compile_time_s"] for s in systems for l in labels),  # in this call
        wall_time_s=0.0,  # of this call (small when the sweeps come from the cache): set by write_results
        jax_version=jax.__version__,
    )
    figs = {"fig5.png": plot_fig5, **({"fig5_forces.png": plot_fig5_forces} if result.alignment is not None else {})}
    return write_results(outdir, result, figs, t0)


def _curve(table: list[dict], system: str, label: str) -> tuple[CurveRow, ...]:
    """A sub-run's table (as cached: JSON) as typed rows, checked."""
    return tuple(CurveRow.from_dict(r, f"curves.{system}.{label}[{i}]", "λ/p study") for i, r in enumerate(table))


def _add_transitions(runs: dict, systems, labels) -> None:
    """Add to every sub-run in ``runs`` its jump/smooth measure across λ = 1 (key "transition"), in place."""
    for s in systems:
        for l in labels:
            r = runs[s][l]
            r["transition"] = transition_sharpness([x["lam"] for x in r["table"]], [x["L_e"] for x in r["table"]])


def _verdict_rows(runs: dict, systems, labels) -> tuple[LambdaPVerdict, ...]:
    """One row per (system, p): the verdict, whether it is correct, and the sharpness of the transition."""
    verdicts = []
    for s in systems:
        for l in labels:
            r = runs[s][l]
            v = r["verdict"]
            verdicts.append(
                LambdaPVerdict(
                    system=s,
                    p=l,
                    truth_conservative=r["truth_conservative"],
                    new_physics=v["new_physics"],
                    correct=v["new_physics"] != r["truth_conservative"],
                    ratio=v["ratio"],
                    L_below=v["L_below"],
                    L_above=v["L_above"],
                    relative_size=v["relative_size"],
                    reason=v["reason"],
                    sharpness=r["transition"]["sharpness"],
                    transition=r["transition"]["kind"],
                    rise_fraction=r["transition"]["rise_fraction"],
                    train_wall_time_s=r["train_wall_time_s"],
                    cached=r["cached"],
                )
            )
    return tuple(verdicts)


def _alignment(runs: dict, labels) -> Alignment:
    """HO+LD (Fig. 5 e–h): m_c, m_n and the rms of f_n per loss and λ, and the learned forces."""
    by_p = runs[FORCE_SYSTEM]
    return Alignment(
        system=FORCE_SYSTEM,
        truth="f_c = −q, f_n = −½q̇",
        fn_true_rms=by_p[labels[0]]["fn_true_rms"],
        by_p={
            l: tuple(
                AlignmentRow(lam=r["lam"], m_c=r["m_c"], m_n=r["m_n"], fn_rms=r["fn_rms"]) for r in by_p[l]["table"]
            )
            for l in labels
        },
        forces={
            l: None
            if by_p[l]["forces"] is None
            else LearnedForces.from_dict(by_p[l]["forces"], f"alignment.forces.{l}", "λ/p study")
            for l in labels
        },
    )


def _study_settings(settings: LambdaPSettings, labels) -> dict:
    """The "settings" entry of the study's result: everything the sweeps depended on (``settings``: checked)."""
    return {
        "systems": list(settings.systems),
        "ps": labels,
        "lambdas": list(settings.lambdas),
        "steps_per_lambda": settings.steps,
        "seed": settings.seed,
        "mode": "warm (paper appendix B: increasing λ, each from the previous λ's parameters)",
        "n_train": settings.n_train,
        "n_test": settings.n_test,
        "data": "iid N(0,1) q, q̇, t (paper III.C)",
        "standardize": True,
        "learning_rates": list(TrainConfig().lrs),
        "batch_size": TrainConfig().batch_size,
        "force_system": FORCE_SYSTEM,
        "force_lambdas": [x for x in settings.force_lambdas if x in settings.lambdas],
        "jump_sharpness": JUMP_SHARPNESS,
        "smooth_sharpness": SMOOTH_SHARPNESS,
        "align_tol": ALIGN_TOL,
        "verdict_min_ratio": MIN_RATIO,
    }


# ----------------------------------------------------------------------------------------------------------------
# figures of the λ/p study
