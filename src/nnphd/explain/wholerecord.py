r"""Can the whole record tell the tied laws apart? A tie of the law table (:mod:`nnphd.explain.table`) re-judged by
fitting each tied family to the *whole* record at once (one coordinate, the conservative library as base).

The shooting windows of the trajectory-level ranking (:mod:`nnphd.explain.trajectory`) start from free states
every ¾ period: they see how a force acts within a window, not how the energy it removes adds up over the record.
The amplitude envelope (:mod:`nnphd.explain.envelope`) sees that, but only through the turning points. A fit of
the positions over whole trajectories, each integrated from its own initial state to its end, uses every sample's
phase and amplitude: a loss that is a little wrong at some amplitude moves every later sample. On a two-minute
string pendulum in air (linear + quadratic drag, 60 periods, video noise 0.003 rad) the windows and the envelope
left viscous + quadratic, dry + quadratic and a power law within ΔIC 6; fitted over the whole record, the other two
are ≥ 37 behind on seeds 0–2 (the independent whole-trajectory fit of benchmarks/friction_reference.py puts dry +
quadratic ΔIC 38 behind on seed 0).

Such a fit is only as good as its conservative part: over sixty periods a small error of the restoring force
accumulates, and friction terms can soak it up — which is why the law table's windows stay short, and why this
stage (a) uses the conservative libraries alone (the full one — potential gradients in sin θ, cos θ for an angle, to
degree 4 — and the short one, a pendulum or a spring; fitted jointly, no network, no seed — never the LNN's f_c,
which over long windows let a dry + quadratic law beat the true viscous one by ΔIC 66 on a noisy pendulum), (b) judges only when the best whole-record fit follows the
record to its noise (χ²/N ≤ :data:`MAX_CHI2_PER_ROW` in the position noise's units; else the library does not hold
the record's conservative force well enough to judge, and the tie stands), (c) counts the residuals' correlation
(the IC's n_eff = N/τ of :mod:`nnphd.explain.trajectory`), and (d) only removes families from a tie — it never
makes a law the table did not offer, nor claims a family whose whole-record fit is not eligible (a term within 2 se
of zero, a power law at a simpler family's exponent).

API: :func:`break_tie` (the combined table, the library base's table) → the table, with ``settings["whole_record"]``
saying what the whole record said (or why it was not asked).
"""

from __future__ import annotations

from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from nnphd.explain.trajectory import Motion

__all__ = ["MAX_CHI2_PER_ROW", "active_share", "break_tie", "context", "passivity"]

MAX_CHI2_PER_ROW = 2.0  # the best whole-record fit's χ²/N (position noise units) above which it does not judge
ALL_WINDOWS = 10**9  # min_windows for rank_trajectory: never enough windows, so whole trajectories in-sample


def context(pointwise, motion: Motion, sigma, period: float, angles, seed: int, refit=None) -> dict:
    """What :func:`break_tie` needs of a library-base law table, kept as its ``whole_record``: the
    pointwise table (its rows carry the conservative starts of the fits), the moving rows the trajectory-level fits
    use (``motion``: thinned, its trajectory ids given), the position noise, the period, the angles, the seed, and
    ``refit(library)`` → the pointwise table with another conservative library ("short": a pendulum about any rest
    angle, springs to degree 3), or None."""
    return {
        "pointwise": pointwise,
        "refit": refit,
        "q": np.asarray(motion.q, float),
        "qd": np.asarray(motion.qd, float),
        "t": np.asarray(motion.t, float),
        "traj": np.asarray(motion.traj),
        "sigma": list(sigma),
        "period": float(period),
        "angles": [bool(a) for a in angles],
        "seed": int(seed),
    }


def whole_record_fits(ctx: dict, keys: list[str]):
    """The families ``keys`` and the zero law, each fitted to the whole trajectories of ``ctx`` (in-sample) beside
    each conservative library: the full one of the law table and, where ``ctx`` can refit it, the short one (a
    pendulum about any rest angle, springs to degree 3, no velocity terms — the model of an independent reference).
    Returns ([(library name, ranked LawTable), …], None) or (None, why not)."""
    from nnphd.explain.trajectory import Motion, TrajectorySettings, WindowPlan, rank_trajectory

    short = "the short library (a pendulum or a spring)"
    is_short = ctx["pointwise"].settings.get("library") == "short"  # a record too short for held-out windows
    tables = [(short if is_short else "the conservative library", ctx["pointwise"])]
    if ctx.get("refit") is not None and not is_short:
        tables.append((short, ctx["refit"]("short")))
    out, why = [], "the record is too long to fit whole (or no whole-trajectory fit was finite)"
    for name, pw in tables:
        by_key = {r.key: r for r in pw.rows}
        missing = [k for k in ["none", *keys] if k not in by_key]
        if missing:
            why = f"no pointwise fit of {', '.join(missing)} beside {name}"
            continue
        sub = replace(pw, rows=[by_key["none"], *(by_key[k] for k in keys)], law=None, ties=[])
        ranked = rank_trajectory(
            sub,
            Motion(ctx["q"], ctx["qd"], ctx["t"], ctx["traj"]),
            sigma=ctx["sigma"],
            period=ctx["period"],
            angles=ctx["angles"],
            fc_fn=None,
            windows=WindowPlan(window_periods=(0.75,), min_windows=ALL_WINDOWS, allow_in_sample=True),
            settings=TrajectorySettings(seed=ctx["seed"]),  # in-sample: every tied family is fitted (no funnel)
            library_of=pw,  # the program of every tie set: the table's whole library, not the tied families alone
        )
        if ranked is not sub and ranked.settings.get("in_sample"):
            out.append((name, ranked))
    return (out, None) if out else (None, why)


def _family_ics(fits, keys: list[str], n_res: int):
    """Each family's whole-record IC, n_eff·log(χ²/n) + (k + K_c)·log(n_eff) — its law's k parameters and the K_c
    conservative coefficients of the library it is fitted beside — at its better library among those whose fit
    follows the record (χ²/N ≤ :data:`MAX_CHI2_PER_ROW`); n_eff = n/τ with the largest τ of the fits (the most
    cautious). Returns ({family: (IC, its row, library name, χ²/N)}, n_eff, τ)."""
    tau = max(float(r.tau) for _, r in fits)
    n_eff = n_res / max(tau, 1.0)
    best: dict = {}
    for name, ranked in fits:
        kc = int(ranked.settings.get("conservative_columns", 0))
        for r in ranked.rows:
            if r.key not in keys:
                continue
            chi2n = float(r.heldout_mse)
            if not np.isfinite(chi2n) or chi2n <= 0 or chi2n > MAX_CHI2_PER_ROW:
                continue
            ic = n_eff * np.log(chi2n) + (r.k + kc) * np.log(max(n_eff, 2.0))
            if r.key not in best or ic < best[r.key][0]:
                best[r.key] = (float(ic), r, name, chi2n)
    return best, n_eff, tau


def break_tie(table, lib):
    """``table`` (a LawTable whose status is "tie"; any other is returned as it is) re-judged by the whole record,
    fitted beside the conservative libraries (``lib``: the library base's table, with its ``whole_record``
    from :func:`context`; without it the tie stands; :func:`_family_ics`). Families ≥ IC_TIE behind the best
    whole-record fit leave the tie; one left is claimed (the table's own row of it: its coefficients from the windows
    and the envelope). The tie stands where a member has no whole-record fit at an optimum that follows the record
    (χ²/N ≤ :data:`MAX_CHI2_PER_ROW`), the best whole-record fit is not eligible, or all stay within IC_TIE.
    ``settings["whole_record"]``: what was found, or why not."""
    from nnphd.explain.law import TableStatus
    from nnphd.explain.table import IC_TIE

    if table.status != TableStatus.TIE:
        return table
    ctx = lib.whole_record if lib is not None else None
    members = [table.law, *table.ties]
    keys = [m.key for m in members]

    def stands(why: str, extra: dict | None = None):
        info = {"status": "tie stands", "families": keys, "why": why, **(extra or {})}
        return replace(table, settings={**table.settings, "whole_record": info})

    if ctx is None:
        return stands("no whole-record fit for this record (one coordinate that oscillates, the library base)")
    fits, why = whole_record_fits(ctx, keys)
    if fits is None:
        return stands(why)
    fam, n_eff, tau = _family_ics(fits, keys, len(ctx["t"]))
    chi2s = {name: min((float(r.heldout_mse) for r in ranked.rows if r.key in keys), default=np.inf)
             for name, ranked in fits}  # fmt: skip
    if len(fam) < len(keys):
        left = ", ".join(k for k in keys if k not in fam)
        return stands(
            f"no whole-record fit of {left} at an optimum that follows the record to its noise (χ²/N ≤ "
            f"{MAX_CHI2_PER_ROW:g}; the best χ²/N of the tied families: "
            + ", ".join(f"{c:.3g} beside {n}" for n, c in chi2s.items())
            + ")",
            {"chi2_per_row_by_library": chi2s},
        )
    ic_best = min(v[0] for v in fam.values())
    best_key = min(fam, key=lambda k: fam[k][0])
    best, chi2n = fam[best_key][1], fam[best_key][3]
    delta = {k: float(v[0] - ic_best) for k, v in fam.items()}
    found = {
        "families": keys,
        "delta_ic": delta,
        "best": best.key,
        "library": {k: v[2] for k, v in fam.items()},
        "chi2_per_row": chi2n,
        "chi2_per_row_by_library": chi2s,
        "n_eff": float(n_eff),
        "tau": float(tau),
        "rows": int(len(ctx["t"])),
        "trajectories": int(fits[0][1].settings.get("windows", 0)),
        "params": {k: dict(v[1].params) for k, v in fam.items()},
        "stderr": {k: dict(v[1].stderr) for k, v in fam.items()},
    }
    text = ", ".join(f"{k} {delta[k]:+.1f}" for k in sorted(keys, key=delta.get))
    if not best.significant:
        return stands(f"the best whole-record fit ({best.key}) is not eligible there (ΔIC {text})", found)
    keep = [m for m in members if delta[m.key] < IC_TIE]
    if len(keep) == len(members):
        return stands(f"the whole record cannot tell them apart either (ΔIC {text} < {IC_TIE:g})", found)
    law = next(m for m in keep if m.key == best.key)
    ties = [m for m in keep if m is not law]
    out_keys = [m.key for m in members if m not in keep]
    words = (
        f"fitted over whole trajectories at once ({found['trajectories']} trajectory(ies), {found['rows']} rows, "
        f"beside {fam[best_key][2]}, χ²/N = {chi2n:.2f}, n_eff = {n_eff:.0f}): ΔIC {text}"
    )
    found["status"] = "claimed" if not ties else "tie narrowed"
    found["dropped"] = out_keys
    settings = {**table.settings, "whole_record": found}
    rows = [law, *ties, *(r for r in table.rows if r is not law and r not in ties)]
    if not ties:
        reason = (
            f"{law.title}: the windows and the envelope left {' or '.join(m.title for m in members)} within ΔIC "
            f"{IC_TIE:g}, but the whole record tells them apart — {words}; {', '.join(out_keys)} "
            f"{'is' if len(out_keys) == 1 else 'are'} ≥ {IC_TIE:g} behind — {law.key}: "
            + ", ".join(f"{p} = {v:.4g} ± {law.stderr.get(p, float('nan')):.2g}" for p, v in law.params.items())
        )
        return replace(table, rows=rows, law=law, ties=[], settings=settings, reason=reason)
    reason = (
        f"{' or '.join(m.title for m in keep)}: this record cannot tell them apart, though the whole record rules "
        f"out {', '.join(out_keys)} — {words}; no family is claimed, all are shown (the first, {law.key}, is used "
        "for predictions) — " + table.reason
    )
    return replace(table, rows=rows, law=law, ties=ties, settings=settings, reason=reason)


# ------------------------------------------------------------------------------------------------------------------
# passivity: a law that adds energy where the record loses it

ACTIVE_SHARE_MAX = 0.10  # a law adding energy (f·q̇ > 0) on at least this share of the moving rows is "active"
PASSIVE_MARGIN_IC = 10.0  # ... and is claimed on a record that loses energy only this far ahead of every passive family
ACTIVE_TOL = 0.01  # f·q̇ counts as adding energy above this share of |f||q̇| (a drag is exactly 0 across the motion)


def active_share(f, qd) -> float | None:
    """The share of the moving rows on which the force ``f`` (N, n) adds energy, f·q̇ > ACTIVE_TOL·|f||q̇| (in the
    record's coordinates; for Cartesian coordinates and one coordinate the power itself). None when nothing moves
    or the force is zero everywhere."""
    f, qd = np.asarray(f, float), np.asarray(qd, float)
    f, qd = f.reshape(len(f), -1), qd.reshape(len(qd), -1)
    size = np.linalg.norm(f, axis=1) * np.linalg.norm(qd, axis=1)
    ok = np.isfinite(size) & (size > 0)
    if not np.any(ok):
        return None
    power = np.einsum("ni,ni->n", f[ok], qd[ok])
    return float(np.mean(power > ACTIVE_TOL * size[ok]))


def passivity(table, lib, q, qd, t) -> dict | None:
    """Is the claimed law of ``table`` passive on this record, and if not, does the whole record prefer it to every
    passive candidate? None when no law is claimed.

    ``active_share`` (:func:`active_share`) of the law and of each eligible candidate on the rows (q, q̇, t). Where
    the law's is ≥ ACTIVE_SHARE_MAX, the law and the eligible passive candidates (share below it) are fitted over the
    whole record beside the conservative libraries (:func:`whole_record_fits`, the library base ``lib``'s context;
    one coordinate that oscillates) and ``margin`` = the best passive family's IC − the law's (> 0: the law is
    better). The decision — the record loses energy, and the margin is below PASSIVE_MARGIN_IC — is the verdict's
    (:func:`nnphd.user.rules.unclaim_active`)."""
    law = table.law
    if law is None:
        return None
    share = active_share(law.predict(q, qd, t), qd)
    info = {"law": law.key, "active_share": share, "active": share is not None and share >= ACTIVE_SHARE_MAX,
            "threshold": ACTIVE_SHARE_MAX}  # fmt: skip
    if not info["active"]:
        return info
    passive = []
    for r in table.rows:
        if r.family is None or r is law or not r.significant:
            continue
        s = active_share(r.predict(q, qd, t), qd)
        if s is not None and s < ACTIVE_SHARE_MAX:
            passive.append(r.key)
    info["passive_candidates"] = passive
    ctx = lib.whole_record if lib is not None else None
    if not passive:
        info["why"] = "no eligible passive candidate to compare with"
        return info
    if ctx is None:
        info["why"] = "no whole-record fit for this record (one coordinate that oscillates, the library base)"
        return info
    fits, why = whole_record_fits(ctx, [law.key, *passive])
    if fits is None:
        info["why"] = why
        return info
    fam, n_eff, _ = _family_ics(fits, [law.key, *passive], len(ctx["t"]))
    if law.key not in fam:
        info["why"] = (
            f"the law's whole-record fit does not follow the record to its noise (χ²/N > {MAX_CHI2_PER_ROW:g})"
        )
        return info
    rivals = {k: v[0] for k, v in fam.items() if k != law.key}
    if not rivals:
        info["margin"] = float("inf")
        info["why"] = "no passive family's whole-record fit follows the record to its noise"
        return info
    best = min(rivals, key=rivals.get)
    info.update(margin=float(rivals[best] - fam[law.key][0]), best_passive=best, n_eff=float(n_eff),
                chi2_per_row=float(fam[law.key][3]))  # fmt: skip
    return info
