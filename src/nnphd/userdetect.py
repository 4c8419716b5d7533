"""``nnphd detect FILE``: new-physics detection on the user's own trajectories.

Pipeline: :func:`nnphd.userdata.load_trajectories` (validation, one-line errors) → :func:`nnphd.userdata.to_dataset`
(q̇, q̈ per trajectory with a noise estimate) → :func:`nnphd.trust.assess` (standardised units, λ-sweep on held-out
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
from pathlib import Path
from typing import Callable

import numpy as np

from .report import atomic_write_bytes, ensure_writable_dir, write_json

Progress = Callable[[str], None]


def detect_file(path: str | Path, out: str | Path | None = None, angles=(), seed: int = 0, steps: int = 1000,
                sr_time: float = 10.0, n_seeds: int = 2, progress: Progress | None = None, trim: bool = False,
                **assess_kw) -> dict:
    """Load ``path``, assess it, explain f_n; write report.json / report.html / PNGs to ``out`` if given."""
    from .explain.sparse import sparse_formula
    from .explain.symbolic import genetic_formula
    from .trust import assess
    from .userdata import load_trajectories, to_dataset

    say = progress or (lambda msg: None)
    t0 = time.perf_counter()
    say("reading the file")
    ud = load_trajectories(path, angles)
    data, info = to_dataset(ud, trim=trim)
    traj = np.concatenate([np.full(b - a, i) for i, tr in enumerate(info["trajectories"]) for a, b in [tr["kept"]]])
    say("λ-sweep and trust checks")
    res = assess(data, traj, seed=seed, steps=steps, n_seeds=n_seeds,
                 progress=lambda done, total, msg: say(f"training ({done}/{total}): {msg}"), **assess_kw)
    coords = list(ud.coords)
    fn = np.asarray(res["f_n"])
    fc = np.asarray(res["f_c"])
    blind = {}
    if res["status"] == "detected":
        names = coords + [f"{c}_dot" for c in coords]
        inputs = {n: col for n, col in zip(names, np.concatenate([data.q, data.qd], axis=1).T)}
        inputs["t"] = data.t
        comps = [f"{c}_ddot" for c in coords]
        say("blind explanation (sparse regression)")
        blind["sparse"] = sparse_formula(inputs, fn, comps, velocities=[f"{c}_dot" for c in coords], time="t").to_dict()
        if sr_time > 0:
            say("blind explanation (genetic symbolic regression)")
            blind["genetic"] = genetic_formula(inputs, fn, comps, seed=seed, max_time=sr_time).to_dict()
    best = _best_formula(blind)
    report = {
        "file": str(path),
        "new_physics": bool(res["new_physics"]),
        "status": res["status"],
        "statistic": res["statistic"],
        "confidence": res["confidence"],
        "reasons": res["reasons"],
        "checks": res["checks"],
        "table": res["table"],
        "noise": {c: info["per_coordinate"][c] for c in coords},
        "data": {k: v for k, v in info.items() if k != "per_coordinate"},
        "formula": best,
        "blind": blind,
        "settings": {"seed": seed, "steps": steps, "n_seeds": n_seeds, "sr_time_per_component_s": sr_time,
                     "trim": trim, **assess_kw, **res.get("settings", {})},
        "units": "forces in the file's units (coordinate units / time unit²)",
        "wall_time_s": time.perf_counter() - t0,
    }
    if out is not None:
        write_report(out, report, data, traj, coords, fc, fn)
    return report


def _best_formula(blind: dict) -> dict | None:
    """The readable blind formula with the smaller residual (sparse wins ties: fewer, library terms)."""
    ok = [(b["rel_rms"], i, name, b) for i, (name, b) in enumerate(blind.items()) if b.get("readable")]
    if not ok:
        return None
    _, _, name, b = min(ok)
    return {"method": name, "formula": b["formula"], "rel_rms": b["rel_rms"]}


# ---------------------------------------------------------------------------------------------------- figures
def _png(fig) -> bytes:
    import matplotlib.pyplot as plt

    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110, bbox_inches="tight")
    plt.close(fig)
    return buf.getvalue()


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def plot_data(data, traj, coords) -> bytes:
    plt = _plt()
    n = len(coords)
    fig, axes = plt.subplots(n, 1, figsize=(8, 2.2 * n), sharex=True, squeeze=False)
    for j, c in enumerate(coords):
        ax = axes[j, 0]
        for k in np.unique(traj)[:20]:
            m = traj == k
            ax.plot(data.t[m], data.q[m, j], lw=0.8)
        ax.set_ylabel(c)
    axes[-1, 0].set_xlabel("t")
    axes[0, 0].set_title("data (one colour per trajectory; first 20 shown)")
    return _png(fig)


def plot_loss(table) -> bytes:
    plt = _plt()
    fig, ax = plt.subplots(figsize=(6, 4))
    lam = [r["lam"] for r in table]
    ax.loglog(lam, [r["L_e"] for r in table], "o-", label="$L_e$ (held out)")
    if all("L_b" in r for r in table):
        ax.loglog(lam, [max(r["L_b"], 1e-16) for r in table], "s--", alpha=0.6, label="$L_b$")
    ax.axvline(1.0, color="k", lw=0.8, ls=":")
    ax.set_xlabel("λ")
    ax.set_ylabel("loss (model units)")
    ax.legend()
    ax.set_title("$L_e(\\lambda)$: a jump at λ = 1 means non-conservative")
    return _png(fig)


def plot_forces(data, traj, coords, fc, fn) -> bytes:
    plt = _plt()
    n = len(coords)
    fig, axes = plt.subplots(n, 2, figsize=(11, 2.4 * n), sharex=True, squeeze=False)
    for j, c in enumerate(coords):
        for k in np.unique(traj)[:5]:
            m = traj == k
            axes[j, 0].plot(data.t[m], data.qdd[m, j], color="0.7", lw=1.5)
            axes[j, 0].plot(data.t[m], fc[m, j], lw=0.8)
            axes[j, 1].plot(data.t[m], fn[m, j], lw=0.8)
        axes[j, 0].set_ylabel(f"{c}_ddot")
    axes[0, 0].set_title("conservative part f_c (grey: q̈ of the data)")
    axes[0, 1].set_title("non-conservative part f_n")
    axes[-1, 0].set_xlabel("t")
    axes[-1, 1].set_xlabel("t")
    return _png(fig)


# ---------------------------------------------------------------------------------------------------- output
def write_report(out, report: dict, data, traj, coords, fc, fn) -> None:
    """report.json, data.png, loss_vs_lambda.png, forces.png and a self-contained report.html (each atomic)."""
    outdir = ensure_writable_dir(out)
    figs = {"data.png": plot_data(data, traj, coords), "loss_vs_lambda.png": plot_loss(report["table"]),
            "forces.png": plot_forces(data, traj, coords, fc, fn)}
    for name, png in figs.items():
        atomic_write_bytes(outdir / name, png)
    write_json(outdir / "report.json", report)
    atomic_write_bytes(outdir / "report.html", render_html(report, figs).encode())


def _e(x) -> str:
    return html.escape(str(x))


def render_html(report: dict, figs: dict[str, bytes]) -> str:
    status = report["status"]
    colour = {"detected": "#c00", "none": "#070", "inconclusive": "#a60"}.get(status, "#333")
    rows = "".join(f"<tr><td>{r['lam']:g}</td><td>{r['L_e']:.4g}</td><td>{r.get('L_b', float('nan')):.4g}</td></tr>"
                   for r in report["table"])
    noise = "".join(
        f"<tr><td>{_e(c)}</td><td>{v['noise']:.3g}</td><td>{100 * v['noise_relative']:.3g}%</td>"
        f"<td>{_e(v['qd']['source'])}, rel. error {_e(_fmt(v['qd'].get('relative_error')))}</td>"
        f"<td>{_e(v['qdd']['source'])}, rel. error {_e(_fmt(v['qdd'].get('relative_error')))}</td></tr>"
        for c, v in report["noise"].items())
    f = report["formula"]
    formula = ("<br>".join(f"<code>{_e(k)} = {_e(v)}</code>" for k, v in f["formula"].items())
               + f"<br><small>{_e(f['method'])}, {100 * f['rel_rms']:.3g}% rms of f_n left</small>") if f else \
        ("nothing readable" if report["blind"] else "— (no non-conservative force detected)")
    img = "".join(f'<figure><img style="max-width:100%" src="data:image/png;base64,{base64.b64encode(b).decode()}">'
                  f'<figcaption><a href="{_e(n)}">{_e(n)}</a></figcaption></figure>' for n, b in figs.items())
    return (f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>nnphd detect: {_e(report['file'])}</title>"
            "<style>body{font-family:system-ui,sans-serif;max-width:1100px;margin:2em auto;padding:0 1em}"
            "td,th{border:1px solid #ccc;padding:2px 8px}table{border-collapse:collapse}</style></head><body>"
            f"<h1>nnphd detect: {_e(report['file'])}</h1>"
            f"<p style='font-size:1.3em;color:{colour}'><b>{_e(status.upper())}</b> — new physics: "
            f"{'yes' if report['new_physics'] else 'no'}; statistic {report['statistic']['value']:.3g} "
            f"({_e(report['statistic']['name'])}); confidence "
            f"{_e(_fmt(report['confidence']))}</p><ul>" + "".join(f"<li>{_e(r)}</li>" for r in report["reasons"]) +
            f"</ul><h2>Formula of the non-conservative part</h2><p>{formula}</p><h2>Figures</h2>{img}"
            f"<h2>L_e(λ)</h2><table><tr><th>λ</th><th>L_e</th><th>L_b</th></tr>{rows}</table>"
            f"<h2>Data and derivatives</h2><table><tr><th>coordinate</th><th>noise σ</th><th>σ / std</th>"
            f"<th>q̇</th><th>q̈</th></tr>{noise}</table>"
            f"<details><summary>checks and settings</summary><pre>{_e(json.dumps(report['checks'], indent=1, default=str))}"
            f"\n{_e(json.dumps(report['settings'], indent=1, default=str))}</pre></details></body></html>")


def _fmt(x) -> str:
    if isinstance(x, float):
        return f"{x:.3g}"
    return str(x)
