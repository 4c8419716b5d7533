"""``nnphd detect FILE``: new-physics detection on the user's own trajectories.

Pipeline: :func:`nnphd.user.recording.load_trajectories` (validation, one-line errors) → :func:`nnphd.user.derivatives.to_dataset`
(q̇, q̈ per trajectory with a noise estimate) → :func:`nnphd.user.assess.assess` (standardised units, λ-sweep on held-out
trajectories, the checks that tell non-conservation from under-fitting, repeated seeds) → the blind explanation of
the learned non-conservative force in the file's own coordinate names → ``report.json``, ``report.html`` and the
figures in ``--out``. Every file is written atomically, and only after the whole analysis succeeded.
"""
from __future__ import annotations

import base64
import html
import io
import json
import time
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from nnphd.io.results import atomic_write_bytes, ensure_writable_dir, subplots, write_json

Progress = Callable[[str], None]


def detect_file(path: str | Path, out: str | Path | None = None, angles=(), seed: int = 0, steps: int = 1000,
                sr_time: float = 10.0, n_seeds: int = 2, progress: Progress | None = None, trim: bool | str = "auto",
                laws: Sequence[str] = (), law_level: str = "auto", **assess_kw) -> dict:
    """Load ``path``, assess it, find the law of f_n; write report.json / report.html / PNGs to ``out`` if given.

    ``laws``: user candidate laws (SymPy strings, :func:`nnphd.explain.laws.parse_law`), ranked with the built-in
    ones; ``law_level``: "pointwise" (fits to the estimated q̈ only), "trajectory" (re-ranked by multiple shooting
    on the positions) or "auto" (trajectory whenever the data oscillate enough for shooting windows).
    """
    from nnphd.user.recording import load_trajectories

    if law_level not in ("auto", "pointwise", "trajectory"):
        raise ValueError(f"law_level must be 'auto', 'pointwise' or 'trajectory', got {law_level!r}")
    (progress or (lambda msg: None))("reading the file")
    ud = load_trajectories(path, angles)
    return detect_data(ud, out, seed=seed, steps=steps, sr_time=sr_time, n_seeds=n_seeds, progress=progress,
                       trim=trim, laws=laws, law_level=law_level, **assess_kw)[0]


def detect_data(ud, out: str | Path | None = None, *, seed: int = 0, steps: int = 1000, sr_time: float = 10.0,
                n_seeds: int = 2, progress: Progress | None = None, trim: bool | str = "auto",
                laws: Sequence[str] = (), law_level: str = "auto", **assess_kw) -> tuple[dict, dict]:
    """:func:`detect_file` on validated data (:class:`nnphd.user.recording.UserData`); returns (report, model) with
    model = the fitted pieces (``conservative``: the LNN and its scaling, ``law``: the claimed LawFit or None, the
    data set, trajectory ids, f_c and f_n on the rows) — what :class:`nnphd.NNPhD` keeps."""
    from nnphd._extras import MissingExtra
    from nnphd.explain.laws import parse_law
    from nnphd.explain.sparse import sparse_formula
    from nnphd.explain.symbolic import genetic_formula
    from nnphd.user.assess import assess
    from nnphd.user.recording import suggest_angles

    say = progress or (lambda msg: None)
    if law_level not in ("auto", "pointwise", "trajectory"):
        raise ValueError(f"law_level must be 'auto', 'pointwise' or 'trajectory', got {law_level!r}")
    t0 = time.perf_counter()
    path = ud.path
    for x in laws:  # fail on a bad --law before any work
        parse_law(x, ud.coords)
    data, info, trim = _dataset(ud, trim)
    row_err = info.pop("_rows", None)
    traj = np.concatenate([np.full(b - a, i) for i, tr in enumerate(info["trajectories"]) for a, b in [tr["kept"]]])
    say("λ-sweep and trust checks")
    pc = info["per_coordinate"]
    res = assess(data, traj, seed=seed, steps=steps, n_seeds=n_seeds,
                 progress=lambda done, total, msg: say(f"training ({done}/{total}): {msg}"),
                 angles=[bool(a) for a in ud.is_angle], position_noise=[pc[c]["noise"] for c in ud.coords],
                 derivative_error=[pc[c]["qdd"]["relative_error"] for c in ud.coords], **assess_kw)
    coords = list(ud.coords)
    fn = np.asarray(res["f_n"])
    fc = np.asarray(res["f_c"])
    law, law_fit = _law_table(res, data, traj, coords, ud, info, row_err, laws, law_level, seed, say)
    status, new_physics, confidence, reasons = _reconcile(res, law)
    blind = {}
    if res["status"] == "detected" and law.get("law") is None:  # fallback: no candidate family fits
        names = coords + [f"{c}_dot" for c in coords]
        inputs = {n: col for n, col in zip(names, np.concatenate([data.q, data.qd], axis=1).T)}
        inputs["t"] = data.t
        comps = [f"{c}_ddot" for c in coords]
        try:
            say("blind explanation (sparse regression)")
            blind["sparse"] = sparse_formula(inputs, fn, comps, velocities=[f"{c}_dot" for c in coords],
                                             time="t").to_dict()
            if sr_time > 0:
                say("blind explanation (genetic symbolic regression)")
                blind["genetic"] = genetic_formula(inputs, fn, comps, seed=seed, max_time=sr_time).to_dict()
        except MissingExtra as e:  # the fallback is optional: say why it is missing
            reasons.append(f"no blind explanation: {e}")
    best = _law_formula(law) or _best_formula(blind)
    report = {
        "file": str(path),
        "new_physics": new_physics,
        "status": status,
        "statistic": res["statistic"],
        "effect": res["effect"],
        "evidence": res["evidence"],
        "confidence": confidence,
        "confidence_basis": res["confidence_basis"],
        "reasons": reasons,
        "quality": res["quality"],
        "angles": [c for c, a in zip(coords, res["angles"]) if a],
        "angle_suggestions": [list(x) for x in suggest_angles(ud)],
        "warnings": _warnings(info, coords),
        "clock": res["clock"],
        "checks": res["checks"],
        "table": res["table"],
        "lambda_forces": res["lambda_forces"],
        "noise": {c: info["per_coordinate"][c] for c in coords},
        "data": {k: v for k, v in info.items() if k != "per_coordinate"},
        "formula": best,
        "law": law,
        "blind": blind,
        "settings": {"seed": seed, "steps": steps, "n_seeds": n_seeds, "sr_time_per_component_s": sr_time,
                     "trim": trim, **assess_kw, **res.get("settings", {})},
        "units": "forces in the file's units (coordinate units / time unit²)",
        "wall_time_s": time.perf_counter() - t0,
    }
    if out is not None:
        write_report(out, report, data, traj, coords, fc, fn)
    model = {"conservative": res.get("_conservative"), "law": law_fit if law.get("law") else None, "data": data,
             "traj": traj, "coords": coords, "angles": [bool(a) for a in ud.is_angle], "fc": fc, "fn": fn}
    return report, model


WARN_QDD_ERR = 0.2  # a coordinate whose estimated relative q̈ error exceeds this gets a warning


def _warnings(info: dict, coords) -> list[str]:
    """Plain-language warnings about the derivatives (the verdict itself accounts for them)."""
    out = []
    for c in coords:
        e = info["per_coordinate"][c]["qdd"].get("relative_error")
        if e is not None and e > WARN_QDD_ERR:
            out.append(f"q̈ of {c!r} has an estimated relative error of {100 * e:.0f}%: pointwise tests (the λ-sweep, "
                       "the fit gap) are weak for it; the verdict leans on the trajectory-level evidence")
    if not info.get("trim") and info.get("n_samples", 0) > 0:
        out.append("the ends of the trajectories were not trimmed (too short): their derivatives are the least "
                   "accurate rows")
    return out


def _dataset(ud, trim):
    """to_dataset with the ends trimmed (``trim="auto"``: drop the half-window at each end of every trajectory,
    where the one-sided derivative estimates are ~20x worse, unless that would leave a trajectory with less than
    TRIM_KEEP_MIN of its rows). Returns (dataset, info, the trim actually used)."""
    from nnphd.user.derivatives import to_dataset
    from nnphd.user.recording import DataError

    if trim != "auto":
        return (*to_dataset(ud, trim=bool(trim)), bool(trim))
    try:
        data, info = to_dataset(ud, trim=True)
    except DataError:
        return (*to_dataset(ud, trim=False), False)
    kept = [(b - a) / tr["n_samples"] for tr in info["trajectories"] for a, b in [tr["kept"]]]
    if min(kept) < TRIM_KEEP_MIN or min(b - a for tr in info["trajectories"] for a, b in [tr["kept"]]) < 12:
        return (*to_dataset(ud, trim=False), False)
    return data, info, True


TRIM_KEEP_MIN = 0.6


def _best_formula(blind: dict) -> dict | None:
    """The readable blind formula with the smaller residual (sparse wins ties: fewer, library terms) — the fallback
    when no candidate law fits; marked as such."""
    ok = [(b["rel_rms"], i, name, b) for i, (name, b) in enumerate(blind.items()) if b.get("readable")]
    if not ok:
        return None
    _, _, name, b = min(ok)
    return {"method": f"{name} (fallback: blind regression of the UAN output, not a candidate law)",
            "formula": b["formula"], "rel_rms": b["rel_rms"]}


def _law_formula(law: dict) -> dict | None:
    w = law.get("law")
    if not w:
        return None
    return {"method": f"candidate law: {w['title']} ({w['method']} fit)", "formula": w["formula"],
            "heldout_ratio": w["heldout_ratio"], "params": w["params"], "stderr": w["stderr"]}


LAW_CONFLICT_DIC = -10.0  # a candidate law this much better than none (held out) contradicts a verdict of "none"


def _reconcile(res: dict, law: dict) -> tuple[str, bool, float, list[str]]:
    """The verdict after the law table: "none" while a candidate law beats no law on held-out data by ΔIC ≤
    LAW_CONFLICT_DIC is conflicting evidence — "inconclusive" (best call: new physics), confidence 0.5 (the
    evidence is split), never a confident "none". A drive of a few periods can cancel in the energy trend and go
    unseen by the verdict's checks, while the joint fit of A cos(ωt + φ) finds it."""
    status, new, conf, reasons = res["status"], bool(res["new_physics"]), float(res["confidence"]), list(res["reasons"])
    cand = law.get("candidate_law")
    if status == "none" and cand and cand["delta_ic"] <= LAW_CONFLICT_DIC:
        why = (f"conflicting evidence: the checks find no non-conservation, but a candidate law, {cand['title']}, "
               f"lowers the held-out error by {100 * (1 - cand['heldout_ratio']):.1f}% (ΔIC = {cand['delta_ic']:.1f} "
               f"against no law)")
        law["reason"] = why + " — no law is claimed"
        return "inconclusive", True, 0.5, [why, *reasons]
    return status, new, conf, reasons


def _law_table(res, data, traj, coords, ud, info, row_err, laws, level, seed, say) -> tuple[dict, object]:
    """The ranked candidate laws with the LNN's f_c as the conservative base; a law is claimed only when the verdict
    is "detected". Returns (the table as a dict, the winning LawFit or None)."""
    from nnphd.user.assess import conservative_fn

    cons = res.get("_conservative")
    if cons is None:
        return {"law": None, "reason": "no law fitted: " + (res["quality"].get("reason") or "the data cannot decide"),
                "candidates": []}, None
    fc = np.asarray(cons["fc"])
    ok = bool(np.all(np.isfinite(fc)))
    table = find_law(data, traj, coords, [bool(a) for a in ud.is_angle], info, row_err, fc=fc if ok else None,
                     fc_fn=conservative_fn(cons) if ok else None, laws=laws, level=level, seed=seed, progress=say)
    out = table.to_dict()
    if res["status"] != "detected" and out["law"] is not None:
        out["candidate_law"] = out["law"]
        out["law"] = None
        out["reason"] = (f"the verdict is {res['status']!r}, so no law is claimed (the best candidate, "
                         f"{out['candidate_law']['title']}, would beat zero: {table.reason})")
    return out, table.law


def find_law(data, traj, coords, is_angle, info, row_err=None, *, fc=None, fc_fn=None, laws=(), level="auto",
             seed=0, progress: Progress | None = None):
    """Rank the candidate laws (:mod:`nnphd.explain.laws`) on a data set from :func:`nnphd.user.derivatives.to_dataset`
    (``info`` its info, ``row_err`` its ``info["_rows"]``): pointwise joint fits to the estimated q̈ (weighted by
    the per-row q̈ errors), then — unless ``level`` is "pointwise" — re-ranked at trajectory level by multiple
    shooting on the positions when the data oscillate. ``fc``/``fc_fn``: a conservative force to use as the base
    (on the rows / as a JAX function); without it the conservative library alone. Returns a LawTable."""
    from nnphd.engine.evidence import dominant_period
    from nnphd.explain.laws import _segments, rank_laws, rank_trajectory

    say = progress or (lambda msg: None)
    say("candidate laws (pointwise joint fits)")
    err = None if row_err is None else row_err["qdd_err"]
    table = rank_laws(data.q, data.qd, data.qdd, data.t, traj, names=coords, angles=is_angle, qdd_err=err, fc=fc,
                      user_laws=laws, seed=seed)
    period = dominant_period(np.concatenate([data.q, data.qd], axis=1), data.t, _segments(traj))
    if level != "pointwise" and np.isfinite(period):
        say("candidate laws (trajectory level: multiple shooting on the positions)")
        sigma = [info["per_coordinate"][c]["noise"] for c in coords]
        table = rank_trajectory(table, data.q, data.qd, data.t, traj, sigma=sigma, period=period, angles=is_angle,
                                fc_fn=fc_fn if fc is not None else None, seed=seed)
    return table


# ---------------------------------------------------------------------------------------------------- figures
def _png(fig) -> bytes:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110, bbox_inches="tight")
    return buf.getvalue()


def fig_data(data, traj, coords):
    n = len(coords)
    fig, axes = subplots(n, 1, figsize=(8, 2.2 * n), sharex=True, squeeze=False)
    for j, c in enumerate(coords):
        ax = axes[j, 0]
        for k in np.unique(traj)[:20]:
            m = traj == k
            ax.plot(data.t[m], data.q[m, j], lw=0.8)
        ax.set_ylabel(c)
    axes[-1, 0].set_xlabel("t")
    axes[0, 0].set_title("data (one colour per trajectory; first 20 shown)")
    return fig


def fig_loss(table, naive_ratio=None):
    fig, ax = subplots(figsize=(6, 4))
    lam = [r["lam"] for r in table]
    ax.loglog(lam, [r["L_e"] for r in table], "o-", label="$L_e$ (held out)")
    ax.loglog(lam, [max(r.get("L_e_train", float("nan")), 1e-16) for r in table], "^:", alpha=0.6,
              label="$L_e$ (training)")
    if all("L_b" in r for r in table):
        ax.loglog(lam, [max(r["L_b"], 1e-16) for r in table], "s--", alpha=0.6, label="$L_b$")
    ax.axvline(1.0, color="k", lw=0.8, ls=":")
    ax.set_xlabel("λ")
    ax.set_ylabel("loss (file units)")
    ax.legend()
    ratio = "" if naive_ratio is None else f"; median above/below λ=1: ×{naive_ratio:.2g}"
    ax.set_title(f"pointwise test: $L_e(\\lambda)${ratio}", fontsize=10)
    return fig


def fig_energy(trend: dict):
    """Per-period mean of the learned energy above its minimum, with the fitted decay (log scale)."""
    if not trend.get("block_t"):
        return None
    fig, ax = subplots(figsize=(6, 4))
    r = trend.get("rate")
    for i, (tt, ee) in enumerate(zip(trend["block_t"], trend["block_dE"])):
        tt, ee = np.asarray(tt), np.asarray(ee)
        line = ax.semilogy(tt, ee, "o", ms=4, label=f"trajectory {i + 1}" if i < 5 else None)[0]
        if r is not None and np.isfinite(r) and len(tt) > 1:
            a = np.mean(np.log(ee) + r * tt)
            ax.semilogy(tt, np.exp(a - r * tt), "-", color=line.get_color(), lw=1)
    ax.set_xlabel("t")
    ax.set_ylabel("learned energy above its minimum (per-period mean)")
    if trend.get("valid") and r is not None and np.isfinite(r):
        ax.set_title(f"energy {'decays' if r > 0 else 'grows'} {100 * abs(trend['rate_per_period']):.2g}%/period, "
                     f"z = {trend['z']:.1f}", fontsize=10)
    else:
        ax.set_title("energy trend not used: " + ("contradicted by the kinetic energy" if not trend.get(
            "consistent", True) else "not enough whole periods"), fontsize=10)
    if len(trend["block_t"]) > 1:
        ax.legend(fontsize=8)
    return fig


def fig_forces(data, traj, coords, fc, fn, lam=None):
    n = len(coords)
    fig, axes = subplots(n, 2, figsize=(11, 2.4 * n), sharex=True, squeeze=False)
    for j, c in enumerate(coords):
        for k in np.unique(traj)[:5]:
            m = traj == k
            axes[j, 0].plot(data.t[m], data.qdd[m, j], color="0.7", lw=1.5)
            axes[j, 0].plot(data.t[m], fc[m, j], lw=0.8)
            axes[j, 1].plot(data.t[m], fn[m, j], lw=0.8)
        axes[j, 0].set_ylabel(f"{c}_ddot")
    lam = "" if lam is None else f" at λ = {lam:g}"
    axes[0, 0].set_title("conservative part f_c (grey: estimated q̈)", fontsize=10)
    axes[0, 1].set_title(f"non-conservative part f_n{lam} (pointwise fit: as noisy as q̈)", fontsize=10)
    axes[-1, 0].set_xlabel("t")
    axes[-1, 1].set_xlabel("t")
    return fig


def plot_data(data, traj, coords) -> bytes:
    return _png(fig_data(data, traj, coords))


def plot_loss(table, naive_ratio=None) -> bytes:
    return _png(fig_loss(table, naive_ratio))


def plot_energy(trend: dict) -> bytes | None:
    fig = fig_energy(trend)
    return None if fig is None else _png(fig)


def plot_forces(data, traj, coords, fc, fn, lam=None) -> bytes:
    return _png(fig_forces(data, traj, coords, fc, fn, lam))


# ---------------------------------------------------------------------------------------------------- output
def write_report(out, report: dict, data, traj, coords, fc, fn) -> None:
    """report.json, the figures and a self-contained report.html (each atomic)."""
    outdir = ensure_writable_dir(out)
    naive = [x for x in report["checks"]["naive"]["ratio"] if x is not None]
    figs = {"data.png": plot_data(data, traj, coords)}
    energy = plot_energy(report["evidence"]["energy_trend"])
    if energy is not None:
        figs["energy_trend.png"] = energy
    if report["table"]:  # no model is trained on data that cannot decide
        figs["loss_vs_lambda.png"] = plot_loss(report["table"], float(np.median(naive)) if naive else None)
        figs["forces.png"] = plot_forces(data, traj, coords, fc, fn, report.get("lambda_forces"))
    for name, png in figs.items():
        atomic_write_bytes(outdir / name, png)
    write_json(outdir / "report.json", report)
    atomic_write_bytes(outdir / "report.html", render_html(report, figs).encode())


def _e(x) -> str:
    return html.escape(str(x))


def _evidence_rows(report: dict) -> str:
    c = report["checks"]
    ev = report["evidence"]
    tr, sh = ev["energy_trend"], ev["shooting"]

    def row(name, value, verdict, note=""):
        return (f"<tr><td>{_e(name)}</td><td>{_e(value)}</td><td>{_e(verdict)}</td>"
                f"<td><small>{_e(note)}</small></td></tr>")

    rows = []
    if tr.get("valid"):
        rows.append(row("energy trend of the learned Lagrangian (whole record)",
                        f"{'decays' if tr['rate'] > 0 else 'grows'} {100 * abs(tr['rate_per_period']):.3g}%/period, "
                        f"rate {tr['rate']:.4g} ± {tr['se']:.2g} per time unit",
                        f"z = {tr['z']:.1f}", f"{tr['n_blocks']} whole periods of {tr['period']:.3g}"))
    else:
        rows.append(row("energy trend of the learned Lagrangian", "not used", "—",
                        tr.get("reason", f"{tr.get('n_blocks', 0)} whole periods (need ≥ 4)")))
    if sh.get("valid"):
        rows.append(row("multiple shooting: positions integrated over windows, damping probe d",
                        f"d = {sh['d_mean']:.4g} ± {sh['se_d_mean']:.2g} per time unit "
                        f"(χ² {sh['chi2_conservative']:.4g} → {sh['chi2']:.4g})", f"z = {sh['z']:.1f}",
                        f"{sh['n_windows']} windows of ~{sh['window_median_samples']} samples; se = max(jackknife over "
                        f"{sh['jackknife_groups']} groups, model)"))
    else:
        rows.append(row("multiple shooting", "not computed", "—", sh.get("reason", "")))
    ratio = [x for x in c["naive"]["ratio"] if x is not None]
    if not report["table"]:
        return "".join(rows)
    rows.append(row("λ-sweep (paper): L_e above / below λ = 1, held out",
                    ", ".join(f"×{x:.3g}" for x in ratio) or "—", "pointwise",
                    "blind to forces below the q̈ error"))
    rows.append(row("net power of the pointwise residual", ", ".join(f"{x:.2f}" for x in c["drift"]["rho_median"]),
                    "significant" if any(c["drift"]["significant"]) else "not significant",
                    "used as evidence only with ≥ 3 trajectories"))
    rows.append(row("explicit time dependence (leave one trajectory out)",
                    ", ".join(f"×{x:.2f}" for x in c["time"]["gain"]),
                    "testable" if report["clock"]["testable"] else "untestable", report["clock"]["why"]))
    rows.append(row("fit gap: conservative / free model, training data",
                    ", ".join(f"×{x:.2f}" for x in c["gap"]["gap_train"]), "", "≥ 2 means the Lagrangian under-fits"))
    opt = c["optimisation"]
    rows.append(row("optimisation check: L_e(λ<1) ≤ L_e(λ>1) on training data",
                    ", ".join(f"{a:.3g} vs {b:.3g}" for a, b in zip(opt["L_e_train_below"], opt["L_e_train_above"])),
                    "ok" if all(opt["ok"]) else "violated",
                    "retrained from the conservative solution" if any(opt["retrained"]) else ""))
    if opt.get("L_e_heldout_below"):
        rows.append(row("generalisation check: L_e(λ<1) ≤ 1.5 × L_e(λ>1) on held-out data",
                        ", ".join(f"{a:.3g} vs {b:.3g}" for a, b in zip(opt["L_e_heldout_below"],
                                                                         opt["L_e_heldout_above"])),
                        "ok" if all(opt["heldout_ok"]) else "violated: the free UAN generalises worse than none",
                        "t enters the UAN only where the clock is testable"))
    return "".join(rows)


def render_html(report: dict, figs: dict[str, bytes]) -> str:
    status = report["status"]
    colour = {"detected": "#c00", "none": "#070", "inconclusive": "#a60"}.get(status, "#333")
    rows = "".join(f"<tr><td>{r['lam']:g}</td><td>{r['L_e']:.4g}</td><td>{r.get('L_e_train', float('nan')):.4g}</td>"
                   f"<td>{r.get('L_b', float('nan')):.4g}</td></tr>" for r in report["table"])
    noise = "".join(
        f"<tr><td>{_e(c)}</td><td>{v['noise']:.3g}</td><td>{100 * v['noise_relative']:.3g}%</td>"
        f"<td>{_e(v['qd']['source'])}, rel. error {_e(_fmt(v['qd'].get('relative_error')))}</td>"
        f"<td>{_e(v['qdd']['source'])}, rel. error {_e(_fmt(v['qdd'].get('relative_error')))}</td></tr>"
        for c, v in report["noise"].items())
    f = report["formula"]
    formula = ("<br>".join(f"<code>{_e(k)} = {_e(v)}</code>" for k, v in f["formula"].items())
               + f"<br><small>{_e(f['method'])}</small>") if f else \
        ("nothing readable" if report["blind"] else "— (no law claimed)")
    formula += _law_html(report.get("law") or {})
    img = "".join(f'<figure><img style="max-width:100%" src="data:image/png;base64,{base64.b64encode(b).decode()}">'
                  f'<figcaption><a href="{_e(n)}">{_e(n)}</a></figcaption></figure>' for n, b in figs.items())
    q = report["quality"]
    angles = ", ".join(report.get("angles", [])) or "none"
    sugg = report.get("angle_suggestions") or []
    sugg_html = ("<p><b>Possibly angles, not treated as such:</b> " + "; ".join(
        f"{_e(c)} ({_e(w)})" for c, w in sugg) + " — rerun with <code>--angles</code>.</p>") if sugg else ""
    return (f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>nnphd detect: {_e(report['file'])}</title>"
            "<style>body{font-family:system-ui,sans-serif;max-width:1100px;margin:2em auto;padding:0 1em}"
            "td,th{border:1px solid #ccc;padding:2px 8px}table{border-collapse:collapse}</style></head><body>"
            f"<h1>nnphd detect: {_e(report['file'])}</h1>"
            f"<p style='font-size:1.4em;color:{colour}'><b>{_e(status.upper())}</b>"
            f"{' — new physics' if status == 'detected' else ''}</p>"
            f"<p><b>Effect:</b> {_e(report.get('effect') or '—')}</p>"
            f"<p><b>Confidence</b> {_e(_fmt(report['confidence']))} <small>({_e(report.get('confidence_basis', ''))})"
            "</small></p><ul>" + "".join(f"<li>{_e(r)}</li>" for r in report["reasons"]) + "</ul>"
            + "".join(f"<p style='color:#a60'><b>Warning:</b> {_e(w)}</p>" for w in report.get("warnings", [])) +
            f"{sugg_html}<h2>Evidence</h2><table><tr><th>test</th><th>value</th><th>result</th><th>note</th></tr>"
            f"{_evidence_rows(report)}</table>"
            f"<h2>Data</h2><p>{report['data']['n_traj']} trajector{'y' if report['data']['n_traj'] == 1 else 'ies'}, "
            f"{report['data']['n_rows']} rows; angles (sin/cos inside the networks): <b>{_e(angles)}</b>; "
            f"{q['samples_per_period']:.1f} samples per oscillation; "
            f"data usable: {'yes' if q['usable'] else 'no'}, pointwise test possible: "
            f"{'yes' if q['pointwise_ok'] else 'no'}{(' — ' + _e(q['reason'])) if q['reason'] else ''}</p>"
            f"<table><tr><th>coordinate</th><th>noise σ</th><th>σ / std</th>"
            f"<th>q̇</th><th>q̈</th></tr>{noise}</table>"
            f"<h2>Law of the non-conservative part</h2><p>{formula}</p><h2>Figures</h2>{img}"
            f"<h2>L_e(λ)</h2><table><tr><th>λ</th><th>L_e held out</th><th>L_e training</th><th>L_b</th></tr>"
            f"{rows}</table>"
            f"<details><summary>all checks and settings</summary><pre>"
            f"{_e(json.dumps(report['checks'], indent=1, default=str))}"
            f"\n{_e(json.dumps(report['settings'], indent=1, default=str))}</pre></details></body></html>")


def _law_html(law: dict) -> str:
    """The ranked table of candidate laws (winner first)."""
    cands = law.get("candidates") or []
    if not cands:
        return f"<p><small>{_e(law.get('reason', ''))}</small></p>"
    rows = []
    for i, c in enumerate(cands):
        params = "<br>".join(f"{_e(k)} = {v:.4g} ± {c['stderr'].get(k, float('nan')):.2g}"
                             for k, v in c["params"].items())
        formula = "<br>".join(f"<code>{_e(k)} = {_e(v)}</code>" for k, v in c["formula"].items())
        style = " style='font-weight:bold'" if i == 0 else ""
        flag = "" if c.get("significant", True) else " (a term within 2 se of zero, or a parameter at the edge of its range: not eligible)"
        rows.append(f"<tr{style}><td>{i + 1}</td><td>{_e(c['title'])}{_e(flag)}</td><td>{formula}</td>"
                    f"<td>{params}</td><td>{c['heldout_ratio']:.4f}</td><td>{c['delta_ic']:+.1f}</td>"
                    f"<td>{c['k']}</td></tr>")
    return (f"<p><b>{_e(law.get('reason', ''))}</b></p><p><small>Each candidate is fitted jointly with the "
            f"conservative model ({_e(law.get('settings', {}).get('method', ''))} fit); held-out error relative to no "
            f"law, on {_e(law.get('folds', ''))}; ΔIC = IC − IC(no law), IC = N_eff log(held-out MSE) + k log N_eff, "
            f"N_eff = {law.get('n_eff', float('nan')):.4g}; ± = bootstrap standard errors.</small></p>"
            "<table><tr><th>#</th><th>law</th><th>formula</th><th>coefficients</th><th>held-out error (rel.)"
            "</th><th>ΔIC</th><th>k</th></tr>" + "".join(rows) + "</table>")


def _fmt(x) -> str:
    if isinstance(x, float):
        return f"{x:.3g}"
    return str(x)
