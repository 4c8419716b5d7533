"""The report of ``nnphd detect``: the figures (data, L_e(λ), energy trend, forces) and report.json, report.html and
the PNGs in ``--out`` (:func:`write_report`), built with :mod:`nnphd.io.html`.  Column names and the file's path
are the user's text: escaped for matplotlib (:func:`nnphd.io.escape.mpl`) and HTML (:func:`nnphd.io.html.escape`)."""

from __future__ import annotations

import io
import json
from typing import TYPE_CHECKING

import numpy as np

from nnphd.engine.evidence import percent_per_period
from nnphd.io.escape import mpl as _m
from nnphd.io.html import bullets, details, figure, figures, page, section, table
from nnphd.io.html import escape as _e
from nnphd.io.results import atomic_write_bytes, ensure_writable_dir, subplots, write_json
from nnphd.user.checks import TIME_SCALES
from nnphd.user.result import Status

if TYPE_CHECKING:
    from nnphd.user.result import FittedModel

__all__ = [
    "fig_data",
    "fig_loss",
    "fig_energy",
    "fig_envelope",
    "fig_forces",
    "plot_data",
    "plot_loss",
    "plot_energy",
    "plot_forces",
    "write_report",
    "render_html",
    "declared_field",
]


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
        ax.set_ylabel(_m(c))  # a column name is the user's text: "$" escaped, never mathtext
    axes[-1, 0].set_xlabel("t")
    axes[0, 0].set_title("data (one colour per trajectory; first 20 shown)")
    return fig


def fig_markers(mm):
    """The tracked markers (a :class:`nnphd.user.markers.MarkerModel`) in the image plane (the first two axes): each
    marker's track, the fixed points and untracked pivots, the rods drawn at a few frames and the rails — the
    constraints the coordinates were chosen from."""
    fig, ax = subplots(figsize=(6, 6))
    P = mm.positions
    step = max(1, len(mm.t) // 4000)
    for m, p in P.items():
        ax.plot(p[::step, 0], p[::step, 1], lw=0.4, alpha=0.6, label=_m(m))
    for name, c in mm.anchors.items():
        ax.plot(c[0], c[1], "k^" if name not in P else "ko", ms=8)
        ax.annotate(_m(name), (c[0], c[1]), textcoords="offset points", xytext=(6, 6))
    frames = np.linspace(0, len(mm.t) - 1, 6).round().astype(int)
    for con in mm.constraints:
        if con.kind in ("rod", "pivot"):
            a, b = con.markers
            for k in frames:
                pa = P[a][k] if a in P else mm.anchors[a]
                ax.plot([pa[0], P[b][k, 0]], [pa[1], P[b][k, 1]], "k-", lw=1.2, alpha=0.5)
        elif con.kind == "rail":
            (m,) = con.markers
            c, u = P[m].mean(0), np.asarray(con.value)
            s = (P[m] - c) @ u
            ax.plot([c[0] + s.min() * u[0], c[0] + s.max() * u[0]], [c[1] + s.min() * u[1], c[1] + s.max() * u[1]],
                    "k--", lw=1.5)  # fmt: skip
    ax.set_aspect("equal", adjustable="datalim")
    ax.invert_yaxis()  # image rows grow downwards
    ax.set_xlabel("x")
    ax.set_ylabel("y")
    ax.legend(loc="best", fontsize=8)
    ax.set_title("markers: tracks, fixed points (▲ untracked), rods at 6 frames, rails (dashed)")
    return fig


def plot_markers(mm) -> bytes:
    return _png(fig_markers(mm))


def fig_loss(table, naive_ratio=None):
    fig, ax = subplots(figsize=(6, 4))
    lam = [r["lam"] for r in table]
    ax.loglog(lam, [r["L_e"] for r in table], "o-", label="$L_e$ (held out)")
    ax.loglog(
        lam, [max(r.get("L_e_train", float("nan")), 1e-16) for r in table], "^:", alpha=0.6, label="$L_e$ (training)"
    )
    if all("L_b" in r for r in table):
        ax.loglog(lam, [max(r["L_b"], 1e-16) for r in table], "s--", alpha=0.6, label="$L_b$")
    ax.axvline(1.0, color="k", lw=0.8, ls=":")
    ax.set_xlabel("λ")
    ax.set_ylabel("loss (file units)")
    ax.legend()
    ratio = "" if naive_ratio is None else f"; median above/below λ=1: ×{naive_ratio:.2g}"
    ax.set_title(f"pointwise test: $L_e(\\lambda)${ratio}", fontsize=10)
    return fig


def _unit(trend: dict) -> str:
    """What one block of the energy trend is: a period, or (motion that does not oscillate) a block of the record."""
    return "block" if trend.get("oscillating") is False else "period"


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
    ax.set_ylabel(f"learned energy above its minimum (per-{_unit(trend)} mean)")
    if trend.get("valid") and r is not None and np.isfinite(r):
        ax.set_title(
            f"energy {'decays' if r > 0 else 'grows'} {percent_per_period(trend['rate_per_period']):.2g}%/"
            f"{_unit(trend)}, "
            f"z = {trend['z']:.1f}",
            fontsize=10,
        )
    else:
        ax.set_title(
            "energy trend not used: "
            + (
                "contradicted by the kinetic energy"
                if not trend.get("consistent", True)
                else "not enough whole periods"
            ),
            fontsize=10,
        )
    if len(trend["block_t"]) > 1:
        ax.legend(fontsize=8)
    return fig


def fig_envelope(env: dict | None, coord: str = "q"):
    """The amplitude envelope (half swings between turning points) with each leading candidate law's prediction,
    log scale: viscous is a straight line, dry friction bends down, quadratic drag bends up."""
    if not env or not env.get("measured", {}).get("t"):
        return None
    fig, ax = subplots(figsize=(6, 4))
    m = env["measured"]
    t, A, k = np.asarray(m["t"]), np.asarray(m["A"]), np.asarray(m["traj"])
    ax.semilogy(t, A, "o", ms=3, color="0.35", label="measured (half swings)")
    styles = ["-", "--", "-.", ":"]
    for i, c in enumerate(env.get("candidates", [])):
        pred = np.asarray(c["A"], float)
        for j, kk in enumerate(np.unique(k)):
            sel = (k == kk) & (pred > 0)
            ax.semilogy(
                t[sel],
                pred[sel],
                styles[i % 4],
                lw=1.2,
                color=f"C{i}",
                label=f"{_m(c['law'])} (rms log error {c['rms_log_error']:.2g})" if j == 0 else None,
            )
    ax.set_xlabel("t")
    ax.set_ylabel(f"amplitude of {_m(coord)}")
    ax.set_title("amplitude envelope: straight = viscous, bends down = dry, bends up = quadratic", fontsize=9)
    ax.legend(fontsize=7)
    return fig


def fig_forces(data, traj, coords, fc, fn, lam=None, declared: bool = False):
    """Estimated q̈ with f_c beside it, and f_n — the network's at λ = ``lam``, or (``declared``: the conservative
    force a declared uniform field) the remainder q̈ − f_c."""
    n = len(coords)
    fig, axes = subplots(n, 2, figsize=(11, 2.4 * n), sharex=True, squeeze=False)
    for j, c in enumerate(coords):
        for k in np.unique(traj)[:5]:
            m = traj == k
            axes[j, 0].plot(data.t[m], data.qdd[m, j], color="0.7", lw=1.5)
            axes[j, 0].plot(data.t[m], fc[m, j], lw=0.8)
            axes[j, 1].plot(data.t[m], fn[m, j], lw=0.8)
        axes[j, 0].set_ylabel(_m(f"{c}_ddot"))
    lam = "" if lam is None else f" at λ = {lam:g}"
    if declared:
        axes[0, 0].set_title("declared uniform field f_c, fitted (grey: estimated q̈)", fontsize=10)
        axes[0, 1].set_title("non-conservative remainder q̈ − f_c (as noisy as q̈)", fontsize=10)
    else:
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


def plot_forces(data, traj, coords, fc, fn, lam=None, declared: bool = False) -> bytes:
    return _png(fig_forces(data, traj, coords, fc, fn, lam, declared))


# ---------------------------------------------------------------------------------------------------- output
def write_report(out, report: dict, model: FittedModel, timer=None, before_writing=None, made=None, extra=None) -> None:
    """report.json, the figures and a self-contained report.html (each atomic). The figures draw the ``model``'s data
    set, trajectories, coordinates and forces f_c, f_n (:class:`nnphd.user.result.FittedModel`). ``timer``: the figures are timed on
    it (:class:`nnphd.io.timing.StageTimer`); ``before_writing()`` is called after them, before any file is written
    (to put the timings into the report). ``made``: a future of :func:`training_figures` made already (on another
    thread, while the law was fitted); its wait counts in the figures stage. ``extra``: figures made already (PNG
    bytes by file name: the markers of a marker recording), first."""
    from contextlib import nullcontext

    outdir = ensure_writable_dir(out)
    with timer.stage("figures") if timer is not None else nullcontext():
        drawn = (model.data, model.traj, list(model.coords), model.fc, model.fn)
        figs = {**(extra or {}), **_figures(report, *drawn, None if made is None else made.result())}
    if before_writing is not None:
        before_writing()
    for name, png in figs.items():
        atomic_write_bytes(outdir / name, png)
    write_json(outdir / "report.json", report)
    atomic_write_bytes(outdir / "report.html", render_html(report, figs).encode())


def training_figures(report: dict, data, traj, coords, fc, fn) -> dict[str, bytes]:
    """The figures that need the training only: the data, the energy trend, L_e(λ) and the forces (of
    ``report`` they read checks, evidence, table, lambda_forces and field). PNG bytes by file name."""
    naive = [x for x in report["checks"]["naive"]["ratio"] if x is not None]
    figs = {"data.png": plot_data(data, traj, coords)}
    energy = plot_energy(report["evidence"]["energy_trend"])
    if energy is not None:
        figs["energy_trend.png"] = energy
    if report["table"]:  # no model is trained on data that cannot decide
        figs["loss_vs_lambda.png"] = plot_loss(report["table"], float(np.median(naive)) if naive else None)
        figs["forces.png"] = plot_forces(
            data, traj, coords, fc, fn, report.get("lambda_forces"), declared_field(report) is not None
        )
    return figs


def _figures(report: dict, data, traj, coords, fc, fn, made: dict | None = None) -> dict[str, bytes]:
    """Every figure of the report: :func:`training_figures` (``made``: made already) and the law's envelope."""
    figs = dict(made) if made is not None else training_figures(report, data, traj, coords, fc, fn)
    env = fig_envelope((report.get("law") or {}).get("envelope"), coords[0])
    if env is not None:
        figs["envelope.png"] = _png(env)
    return figs


def _evidence_rows(report: dict) -> list[list[str]]:
    """The rows (test, value, result, note) of the evidence table."""
    c = report["checks"]
    ev = report["evidence"]
    tr, sh = ev["energy_trend"], ev["shooting"]

    def row(name, value, verdict, note=""):
        return [_e(name), _e(value), _e(verdict), f"<small>{_e(note)}</small>"]

    rows = []
    if tr.get("valid"):
        rows.append(
            row(
                "energy trend of the learned Lagrangian (whole record)",
                f"{'decays' if tr['rate'] > 0 else 'grows'} {percent_per_period(tr['rate_per_period']):.3g}%/"
                f"{_unit(tr)}, rate {tr['rate']:.4g} ± {tr['se']:.2g} per time unit",
                f"z = {tr['z']:.1f}",
                f"{tr['n_blocks']} whole {_unit(tr)}s of {tr['period']:.3g}",
            )
        )
    else:
        rows.append(
            row(
                "energy trend of the learned Lagrangian",
                "not used",
                "—",
                tr.get("reason", f"{tr.get('n_blocks', 0)} whole periods (need ≥ 4)"),
            )
        )
    if sh.get("valid"):
        rows.append(
            row(
                "multiple shooting: positions integrated over windows, damping probe d",
                f"d = {sh['d_mean']:.4g} ± {sh['se_d_mean']:.2g} per time unit "
                f"(χ² {sh['chi2_conservative']:.4g} → {sh['chi2']:.4g})",
                f"z = {sh['z']:.1f}",
                f"{sh['n_windows']} windows of ~{sh['window_median_samples']} samples; se = max(jackknife over "
                f"{sh['jackknife_groups']} groups, model)",
            )
        )
    else:
        rows.append(row("multiple shooting", "not computed", "—", sh.get("reason", "")))
    ratio = [x for x in c["naive"]["ratio"] if x is not None]
    if not report["table"]:
        return rows
    rows.append(
        row(
            "λ-sweep (paper): L_e above / below λ = 1, held out",
            ", ".join(f"×{x:.3g}" for x in ratio) or "—",
            "pointwise",
            "blind to forces below the q̈ error",
        )
    )
    rows.append(
        row(
            "net power of the pointwise residual",
            ", ".join(f"{x:.2f}" for x in c["drift"]["rho_median"]),
            "significant" if any(c["drift"]["significant"]) else "not significant",
            "used as evidence only with ≥ 3 trajectories",
        )
    )
    rows.append(
        row(
            "explicit time dependence (leave one trajectory out)",
            ", ".join(f"×{x:.2f}" for x in c["time"]["gain"]),
            "testable" if report["clock"]["testable"] else "untestable",
            report["clock"]["why"],
        )
    )
    rows.append(
        row(
            "fit gap: conservative / free model, training data",
            ", ".join(f"×{x:.2f}" for x in c["gap"]["gap_train"]),
            "",
            "≥ 2 means the Lagrangian under-fits",
        )
    )
    opt = c["optimisation"]
    rows.append(
        row(
            "optimisation check: L_e(λ<1) ≤ L_e(λ>1) on training data",
            ", ".join(f"{a:.3g} vs {b:.3g}" for a, b in zip(opt["L_e_train_below"], opt["L_e_train_above"])),
            "ok" if all(opt["ok"]) else "violated",
            "retrained from the conservative solution" if any(opt["retrained"]) else "",
        )
    )
    if opt.get("L_e_heldout_below"):
        rows.append(
            row(
                "generalisation check: L_e(λ<1) ≤ 1.5 × L_e(λ>1) on held-out data",
                ", ".join(f"{a:.3g} vs {b:.3g}" for a, b in zip(opt["L_e_heldout_below"], opt["L_e_heldout_above"])),
                "ok" if all(opt["heldout_ok"]) else "violated: the free UAN generalises worse than none",
                "t enters the UAN only where the clock is testable",
            )
        )
    return rows


def declared_field(report: dict) -> dict | None:
    """The report's declared field as fitted ({"kind", "text", "law", "g", "stderr"}), or None when the
    conservative force was learned."""
    f = report.get("field") or {}
    return f if f.get("kind", "learned") != "learned" else None


def _field_html(report: dict) -> str:
    f = declared_field(report)
    if f is None:
        return "<p><b>Conservative force:</b> learned by the Lagrangian network</p>"
    g = "; ".join(f"{_e(c)}: {_e(_fmt(v))} ± {_e(_fmt(f['stderr'].get(c)))}" for c, v in (f.get("g") or {}).items())
    beside = f" (fitted beside {_e(f['law'])})" if f.get("law") not in (None, "none") else ""
    along = f.get("against_velocity")
    drag = (
        f"; share of the best law's force that opposes the velocity: {100 * along:.0f}% (a drag: 100%)"
        if isinstance(along, (int, float))
        else ""
    )
    return f"<p><b>Conservative force:</b> {_e(f['text'])}; g = {g or '—'}{beside}{drag}</p>"


def _markers_html(mk: dict | None) -> str:
    """The section of a marker recording: the constraints found, the coordinates chosen and why, what was assumed."""
    if not mk:
        return ""
    rows = [[_e(c["name"]), _e(c["kind"]), _e(c["why"])] for c in mk["coordinates"]]
    return section(
        "Markers → coordinates",
        f"<p>{_e(mk['summary'])}</p>"
        + (f"<p class='warn'>{_e(mk['note'])}</p>" if mk.get("note") else "")
        + bullets(_e(c["text"]) for c in mk["constraints"])
        + table(["coordinate", "kind", "why"], rows, left=3)
        + "".join(f"<p><small>{_e(a)}</small></p>" for a in mk["assumed"])
        + (f"<p>{mk['dropped_rows']} rows left out (a marker lost in that frame)</p>" if mk["dropped_rows"] else ""),
    )


def render_html(report: dict, figs: dict[str, bytes]) -> str:
    """The self-contained report.html: the verdict first, then the evidence, the data, the law, the figures (PNG bytes
    by file name: embedded and linked) and L_e(λ)."""
    status = report["status"]
    lam_rows = [
        [
            f"{r['lam']:g}",
            f"{r['L_e']:.4g}",
            f"{r.get('L_e_train', float('nan')):.4g}",
            f"{r.get('L_b', float('nan')):.4g}",
        ]
        for r in report["table"]
    ]
    noise = [
        [
            _e(c),
            f"{v['noise']:.3g}",
            f"{100 * v['noise_relative']:.3g}%",
            f"{_e(v['qd']['source'])}, rel. error {_e(_fmt(v['qd'].get('relative_error')))}",
            f"{_e(v['qdd']['source'])}, rel. error {_e(_fmt(v['qdd'].get('relative_error')))}",
        ]
        for c, v in report["noise"].items()
    ]
    f = report["formula"]
    formula = (
        (
            "<br>".join(f"<code>{_e(k)} = {_e(v)}</code>" for k, v in f["formula"].items())
            + f"<br><small>{_e(f['method'])}</small>"
        )
        if f
        else (
            "— (no law claimed; the blind formula found nothing readable)" if report["blind"] else "— (no law claimed)"
        )
    )
    h = report.get("hint")
    if h:
        formula += (
            "<p><b>Hint, not a law:</b> "
            + "; ".join(f"<code>{_e(k)} = {_e(v)}</code>" for k, v in h["formula"].items())
            + f"<br><small>{_e(h['method'])}</small></p>"
        )
    formula += _law_html(report.get("law") or {})
    q = report["quality"]
    angles = ", ".join(report.get("angles", [])) or "none"
    sugg = report.get("angle_suggestions") or []
    sugg_html = (
        (
            "<p><b>Possibly angles, not treated as such:</b> "
            + "; ".join(f"{_e(c)} ({_e(w)})" for c, w in sugg)
            + " — rerun with <code>--angles</code>.</p>"
        )
        if sugg
        else ""
    )
    n_traj = report["data"]["n_traj"]
    data = (
        f"<p>{n_traj} trajector{'y' if n_traj == 1 else 'ies'}, {report['data']['n_rows']} rows; angles (sin/cos "
        f"inside the networks): <b>{_e(angles)}</b>; {q['samples_per_period']:.1f} samples per "
        f"{_e(TIME_SCALES.get(q.get('time_scale', 'oscillation'), 'oscillation'))}; "
        f"data usable: {'yes' if q['usable'] else 'no'}, pointwise test possible: "
        f"{'yes' if q['pointwise_ok'] else 'no'}{(' — ' + _e(q['reason'])) if q['reason'] else ''}</p>"
        + (f"<p>{_e(report['data']['thinned']['text'])}</p>" if report["data"].get("thinned") else "")
        + table(["coordinate", "noise σ", "σ / std", "q̇", "q̈"], noise, left=1)
        + _field_html(report)
    )
    body = (
        f"<h1>nnphd detect: {_e(report['file'])}</h1>"
        f"<p class='status st-{_e(status)}'><b>{_e(status.upper())}</b>"
        f"{' — new physics' if status == Status.DETECTED else ''}</p>"
        f"<p><b>Effect:</b> {_e(report.get('effect') or '—')}</p>"
        f"<p><b>Confidence</b> {_e(_fmt(report['confidence']))} <small>({_e(report.get('confidence_basis', ''))})"
        "</small></p>"
        + bullets(_e(r) for r in report["reasons"])
        + "".join(f"<p class='warn'><b>Warning:</b> {_e(w)}</p>" for w in report.get("warnings", []))
        + sugg_html
        + section("Evidence", table(["test", "value", "result", "note"], _evidence_rows(report), left=4))
        + section("Data", data)
        + _markers_html(report.get("markers"))
        + section("Law of the non-conservative part", f"<p>{formula}</p>")
        + section("Figures", figures(figure(png, name) for name, png in figs.items()))
        + _timings_html(report.get("timings"))
        + section("L_e(λ)", table(["λ", "L_e held out", "L_e training", "L_b"], lam_rows, left=0))
        + details(
            "all checks and settings",
            f"{json.dumps(report['checks'], indent=1, default=str)}\n"
            f"{json.dumps(report['settings'], indent=1, default=str)}",
        )
    )
    return page(f"nnphd detect: {report['file']}", body)


def _timings_html(tm: dict | None) -> str:
    """Where the time went: wall and JAX-compile seconds per stage, and per seed."""
    if not tm:
        return ""
    rows = [[_e(s["stage"]), f"{s['s']:.1f}", f"{s['compile_s']:.1f}"] for s in tm["stages"]]
    rows.append(["(between stages)", f"{tm['other_s']:.1f}", ""])
    rows.append(["<b>total</b>", f"<b>{tm['total_s']:.1f}</b>", f"<b>{tm['compile_s']:.1f}</b>"])
    seeds = [
        f"seed {_e(p['seed'])}: {p.get('wall_s', 0.0):.1f} s ({p.get('compile_s', 0.0):.1f} s compiling, "
        f"{_e(p.get('where', ''))}); λ-sweep {p.get('lambda_sweep_s', 0.0):.1f} s ("
        + ", ".join(f"λ = {_e(k)}: {v:.1f}" for k, v in (p.get("per_lambda_s") or {}).items())
        + f"), conservative rounds {p.get('conservative_rounds_s', 0.0):.1f}, free model "
        f"{p.get('free_model_s', 0.0):.1f}, clock test {p.get('clock_test_s', 0.0):.1f}, energy trend "
        f"{p.get('energy_trend_s', 0.0):.1f}, shooting probe {p.get('shooting_probe_s', 0.0):.1f}, checks "
        f"{p.get('checks_s', 0.0):.1f}"
        for p in tm.get("per_seed") or []
    ]
    return section(
        "Where the time went",
        table(["stage", "seconds", "of which compiling"], rows, left=1)
        + bullets(seeds)
        + f"<p><small>{_e(tm.get('note', ''))}; the writing of this report is not included</small></p>",
    )


def _law_html(law: dict) -> str:
    """The ranked table of candidate laws (winner first)."""
    cands = law.get("candidates") or []
    if not cands:
        return f"<p><small>{_e(law.get('reason', ''))}</small></p>"
    rows = []
    for c in cands:
        params = "<br>".join(
            f"{_e(k)} = {v:.4g} ± {c['stderr'].get(k, float('nan')):.2g}" for k, v in c["params"].items()
        )
        formula = "<br>".join(f"<code>{_e(k)} = {_e(v)}</code>" for k, v in c["formula"].items())
        flag = (
            ""
            if c.get("significant", True)
            else " (a term within 2 se of zero or carrying < 5% of the force, or a parameter at the edge of its "
            "range: not eligible)"
        )
        shares = c.get("shares") or {}
        if len(shares) > 1:
            params += (
                "<br><small>share of the force: "
                + ", ".join(f"{_e(k)} {100 * v:.0f}%" for k, v in shares.items())
                + "</small>"
            )
        rows.append(
            [
                len(rows) + 1,
                f"{_e(c['title'])}{_e(flag)}",
                formula,
                params,
                f"{c['heldout_ratio']:.4f}",
                f"{c['delta_ic']:+.1f}",
                c["k"],
            ]
        )
    return (
        f"<p><b>{_e(law.get('reason', ''))}</b></p><p><small>Each candidate is fitted jointly with the "
        f"conservative model ({_e(law.get('settings', {}).get('method', ''))} fit); held-out error relative to no "
        f"law, on {_e(law.get('folds', ''))}; ΔIC = IC − IC(no law), IC = N_eff log(held-out MSE) + k log N_eff, "
        f"N_eff = {law.get('n_eff', float('nan')):.4g}; ± = bootstrap standard errors.</small></p>"
        + table(
            ["#", "law", "formula", "coefficients", "held-out error (rel.)", "ΔIC", "k"],
            rows,
            left=4,
            row_classes=["best"] * (1 + len(law.get("ties") or [])),
        )
    )


def _fmt(x) -> str:
    if isinstance(x, float):
        return f"{x:.3g}"
    return str(x)
