"""Every experiment of the paper in one call, and one self-contained HTML report (``nnphd reproduce``).

Experiments (each is exactly the code behind its own command):

* ``discover``     — Fig. 3 and Table II: friction, Neptune, gravitational waves (``nnphd discover --all``);
* ``predict``      — Fig. 4: extrapolating the damped double pendulum (``nnphd predict``);
* ``lambda-p``     — Fig. 5: L_e(λ) for the five toy systems and p = 1, 2, 3, MSE (``nnphd study lambda-p``);
* ``data-quality`` — Fig. 6: pie coverage α and imbalance β (``nnphd study data-quality``).

``quick=True`` runs the same code with fewer training steps (:data:`QUICK`) — a smoke-scale reproduction whose
numbers are *not* the paper-scale ones (the report says so at the top); the full settings (:data:`FULL`) are the
paper's (2000 Adam steps per λ / per model).

Caching and resume: every unit of work (each discovery system, and each other experiment) writes its results under
``out/<experiment>/`` and then a marker ``reproduce.json`` holding the settings it was run with. A later call with
the same settings loads the results instead of recomputing (an interrupted run therefore resumes at the first unit
without a marker; the two studies additionally resume inside a run from their own per-sweep caches). Different
settings recompute and replace.

The report (``out/report.html``) embeds every figure as a PNG data URI (it opens anywhere, alone) and links the PNG
file beside it; each figure sits beside the paper's claim, each number beside the paper's number, with every claim
judged met / not met and the settings used. ``out/summary.json`` holds the same verdicts as data.
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable
from datetime import UTC, datetime
from pathlib import Path

from nnphd.io.cache import Cache
from nnphd.io.html import bullets, details, figure_file, figures, page, section, table
from nnphd.io.html import escape as _e
from nnphd.io.progress import Progress
from nnphd.io.results import atomic_write_bytes, ensure_writable_dir, write_json
from nnphd.parallel import Outcome, Unit, n_workers, run_units, runs_here

EXPERIMENTS = ("discover", "predict", "lambda-p", "data-quality")
MARKER = "reproduce.json"

# keyword arguments of each experiment's function; discover's "systems" is the list of Table I systems to run
FULL: dict[str, dict] = {
    "discover": {"systems": ["double-pendulum", "neptune", "gw"], "steps": 2000, "sweep_steps": 2000, "sr_time": 20.0},
    "predict": {"steps": 2000},
    "lambda-p": {"steps": 2000},
    "data-quality": {"steps": 2000},
}
QUICK: dict[str, dict] = {
    "discover": {"systems": ["double-pendulum", "neptune", "gw"], "steps": 1000, "sweep_steps": 400, "sr_time": 5.0},
    "predict": {"steps": 1000},
    "lambda-p": {"steps": 300},
    "data-quality": {"steps": 1000},
}

# the paper's words for each figure (captions and text of sections III.A–III.D)
PAPER_CLAIMS = {
    "discover": "“In all our three examples, clear phase transitions at λ=1 indicate the existence of new physics.” "
    "(Fig. 3) — and NNPhD + symbolic regression recovers the friction matrix, Neptune's GM, orbit radius "
    "and frequency, and the radiation-reaction law (Table II).",
    "predict": "“Both NNPhD and the black-box can accurately fit the angle θ1 of training samples, and can successfully "
    "extrapolate for a brief period, while LNN fails to model the non-conservative dynamics; NNPhD "
    "correctly predicts the exponential energy decay on testing samples, while the black-box generalizes "
    "worse, and LNN incorrectly conserves energy.” (Fig. 4)",
    "lambda-p": "“For ‖·‖_p (p=1,2,3), non-conservative dynamics has an error jump at λ=1, while conservative dynamics "
    "does not. Mean squared loss leads to a smooth phase transition for non-conservative dynamics.” "
    "(Fig. 5 a–d); f_c and f_n of q̈ = −q − ½q̇ align with the physical split for 0.05 ≲ λ < 1 (Fig. 5 e–h).",
    "data-quality": "“Low quality data might prevent new physics discovery via (a) incomplete data coverage and (b) "
    "biased data distribution.” L_e is nearly zero for α ≤ 0.5 and jumps past it; the misalignment "
    "is smallest for balanced data, β = 0.5 (Fig. 6).",
}
TITLES = {
    "discover": "Fig. 3 and Table II — friction, Neptune, gravitational waves",
    "predict": "Fig. 4 — prediction of the damped double pendulum",
    "lambda-p": "Fig. 5 — dependence on λ and on the loss",
    "data-quality": "Fig. 6 — data quality",
}
FIGURES = {  # files (relative to out/) shown in each section, in order
    "discover": ["discover/fig3_loss_vs_lambda.png"],
    "predict": ["predict/prediction.png", "predict/energy_balance.png"],
    "lambda-p": ["lambda-p/fig5.png", "lambda-p/fig5_forces.png"],
    "data-quality": ["data-quality/fig6.png"],
}


# ---------------------------------------------------------------------------------------------------- running
def plan(quick: bool = False, overrides: dict[str, dict] | None = None) -> dict[str, dict]:
    """The keyword arguments of every experiment: :data:`QUICK` or :data:`FULL`, updated by ``overrides``."""
    base = QUICK if quick else FULL
    out = {k: dict(v) for k, v in base.items()}
    for exp, kw in (overrides or {}).items():
        if exp not in out:
            raise ValueError(f"unknown experiment {exp!r}; expected one of {', '.join(EXPERIMENTS)}")
        out[exp].update(kw)
    return out


def run_unit(d: Path, settings: dict, fn: Callable[[], dict], log: dict) -> dict:
    """Load the unit's results from ``d`` when its marker (:class:`nnphd.io.cache.Cache`) records exactly
    ``settings``, else run ``fn`` (which writes ``d/results.json``) and mark ``d``."""
    cache = Cache(d, settings)
    sealed = cache.load_sealed(MARKER, "results.json")
    if sealed is not None and isinstance(sealed[1], dict):
        marker, res = sealed
        log["cached"] = True
        log["compute_time_s"] = float(marker.get("wall_time_s", 0.0))
        return res
    t0 = time.perf_counter()
    res = fn()
    wall = time.perf_counter() - t0
    cache.seal(
        {"settings": settings, "wall_time_s": wall, "finished": datetime.now(UTC).isoformat(timespec="seconds")},
        MARKER,
        ("results.json",),
    )
    log["cached"] = False
    log["compute_time_s"] = wall
    return res


def _run_experiment(exp: str, name: str | None, d: Path, seed: int, kw: dict, progress: Progress | None) -> dict:
    """Run one experiment (``name``: the discovery system) into ``d``; returns its results as a dict (results.json's
    content, as a cached unit reads it back)."""
    if exp == "discover":
        from nnphd.paper.discover import DiscoverSettings, discover, write_discovery

        r = discover(name, DiscoverSettings(seed=seed, **kw), progress=progress)
        write_discovery(r, d)
        return r
    if exp == "predict":
        from nnphd.paper.predict import PredictionSettings, run_prediction

        return run_prediction(PredictionSettings(seed=seed, **kw), out=d, progress=progress).to_dict()
    if exp == "lambda-p":
        from nnphd.paper.lambda_p import LambdaPSettings, lambda_p_study

        return lambda_p_study(LambdaPSettings(seed=seed, **kw), out=d, progress=progress).to_dict()
    from nnphd.paper.data_quality import DataQualitySettings, data_quality_study

    return data_quality_study(DataQualitySettings(seed=seed, **kw), out=d, progress=progress).to_dict()


def experiment_unit(
    exp: str, name: str | None, d: str, settings: dict, seed: int, kw: dict, progress: Progress | None = None
) -> dict:
    """One unit of ``reproduce`` (a module-level function, so a Dask worker can run it): the experiment's results
    from ``d``'s cache when its marker records ``settings``, else computed, written and marked.
    Returns {"result", "log"}."""
    log: dict = {}
    path = ensure_writable_dir(d)
    res = run_unit(path, settings, lambda: _run_experiment(exp, name, path, seed, kw, progress), log)
    return {"result": res, "log": log}


def _part(progress: Progress | None, i: int, n: int, label: str) -> Progress | None:
    """The progress of unit ``i`` of ``n``, counted in units of the whole run."""
    if progress is None:
        return None
    return lambda done, tot, msg: progress(i, n, f"{label} ({done}/{tot}): {msg}")


def _spread(units: list[Unit], outdir: Path, seed: int, lp_kw: dict) -> list[Unit]:
    """For workers: the λ/p study (most of the time) as its 20 sweeps, unless its results are cached already; the
    longest units first (the discovery systems, then the sweeps, then predict and data quality)."""
    from nnphd.paper.lambda_p import LambdaPSettings, study_units

    lp = next(u for u in units if u.key == "lambda-p")
    if Cache(outdir / "lambda-p", lp.kwargs["settings"]).load(MARKER) is not None:
        return units
    sweeps = [
        Unit(f"lambda-p/{u.key}", u.fn, u.kwargs)
        for u in study_units(LambdaPSettings(seed=seed, **lp_kw), outdir / "lambda-p")
    ]
    disc = [u for u in units if u.key.startswith("discover/")]
    return disc + sweeps + [u for u in units if u.key != "lambda-p" and not u.key.startswith("discover/")]


def reproduce(
    out: str | Path = "out/reproduce",
    quick: bool = False,
    seed: int = 0,
    overrides: dict[str, dict] | None = None,
    progress: Progress | None = None,
    workers: int | None = 1,
    scheduler: str | None = None,
) -> dict:
    """Run (or load from the cache) every experiment, write ``report.html`` and ``summary.json``; return the summary.

    The experiments' units — each discovery system, predict, data quality and each (system, p) sweep of the λ/p
    study — run through :func:`nnphd.parallel.run_units`: ``workers`` local processes (1: here; None: one per core)
    or an existing Dask ``scheduler``. A unit that fails is reported in the summary (``failed``) and the report,
    the others finish and are cached, and a rerun resumes.
    """
    outdir = ensure_writable_dir(out)
    kw = plan(quick, overrides)
    t_start = time.perf_counter()
    runs: dict[str, dict] = {}
    results: dict[str, object] = {}

    dk = dict(kw["discover"])
    systems = list(dk.pop("systems"))
    specs = [  # (key, experiment, discovery system, folder, settings, keyword arguments)
        # "table2": how Table II is read (results cached by an older way are recomputed)
        (f"discover/{n}", "discover", n, outdir / "discover" / n, {"system": n, "seed": seed, "table2": "joint law fit", **dk}, dk)
        for n in systems
    ] + [(e, e, None, outdir / e, {"seed": seed, **kw[e]}, kw[e]) for e in EXPERIMENTS[1:]]  # fmt: skip
    labels = {"predict": "predict", "lambda-p": "λ/p study", "data-quality": "data-quality study"}
    here = runs_here(workers, scheduler, len(specs))
    units = []
    for i, (key, exp, name, d, settings, k) in enumerate(specs):
        part = _part(progress, i, len(specs), labels.get(exp, key.replace("/", " "))) if here else None
        units.append(Unit(key, experiment_unit, dict(exp=exp, name=name, d=str(d), settings=settings, seed=seed, kw=k, progress=part)))  # fmt: skip
    if not here:
        units = _spread(units, outdir, seed, kw["lambda-p"])
    outs = run_units(units, workers, scheduler, progress=None if here else progress)
    if not here:  # the λ/p study itself, from its sweeps (cached by the units above): figures and claims, here
        spec = next(sp for sp in specs if sp[0] == "lambda-p")
        failed_sweeps = [o for key, o in outs.items() if key.startswith("lambda-p/") and not o.ok]
        if "lambda-p" in outs:  # its results were cached: loaded by a unit
            pass
        elif not failed_sweeps:
            t0 = time.perf_counter()
            try:
                value = experiment_unit("lambda-p", None, str(spec[3]), spec[4], seed, spec[5])
                value["log"]["cached"] = False
                wall = sum(o.wall_time_s for key, o in outs.items() if key.startswith("lambda-p/"))
                value["log"]["compute_time_s"] = wall + time.perf_counter() - t0
                outs["lambda-p"] = Outcome("lambda-p", True, value, wall_time_s=time.perf_counter() - t0)
            except Exception as e:  # contained like a unit's failure
                outs["lambda-p"] = Outcome("lambda-p", False, error=f"{type(e).__name__}: {e}")
        else:
            o = failed_sweeps[0]
            outs["lambda-p"] = Outcome(
                "lambda-p", False, error=f"{len(failed_sweeps)} sweeps failed ({o.key}: {o.error})"
            )
    failed = {}
    disc = []
    for key, exp, *_ in specs:
        o = outs[key]
        if not o.ok:
            failed[key] = o.error
            runs[key] = {"cached": False, "compute_time_s": o.wall_time_s, "error": o.error}
            continue
        runs[key] = {**o.value["log"], "where": o.where, "compile_time_s": o.compile_time_s}
        if exp == "discover":
            disc.append(o.value["result"])
        else:
            results[exp] = o.value["result"]
    from nnphd.paper.discover import write_table2

    if disc:
        write_table2(disc, outdir / "discover")
    results["discover"] = disc

    wall = time.perf_counter() - t_start
    claims = collect_claims(results)
    summary = {
        "mode": "quick" if quick else "full",
        "seed": seed,
        "settings": kw,
        "runs": runs,
        "wall_time_s": wall,
        "compute_time_s": sum(r["compute_time_s"] for r in runs.values()),
        "compile_time_s": sum(r.get("compile_time_s", 0.0) for r in runs.values())
        + sum(o.compile_time_s for k, o in outs.items() if k.startswith("lambda-p/")),  # of this run's units
        "claims": claims,
        "claims_met": sum(c["met"] for c in claims),
        "claims_total": len(claims),
        "failed": failed,  # unit → its error (the unit's experiment is missing from the claims and the report)
        "workers": "in-process" if here else (scheduler or n_workers(workers, None, len(units))),
        "report": "report.html",
    }
    write_json(outdir / "summary.json", summary)
    atomic_write_bytes(outdir / "report.html", render_html(outdir, summary, results).encode())
    return summary


# ---------------------------------------------------------------------------------------------------- claims
def _discover_claims(disc: list[dict]) -> list[dict]:
    claims = []
    for r in disc:
        v = r["verdict"]
        claims.append(
            {
                "experiment": "discover",
                "claim": f"{r['system']}: a jump of L_e at λ = 1, verdict new physics",
                "paper": "new physics",
                "ours": f"{'new physics' if r['new_physics'] else 'no new physics'} "
                f"(L_e ratio across λ=1: {v['ratio']:.3g})",
                "met": bool(r["new_physics"]),
            }
        )
        for row in r["table2"]:
            claims.append(
                {
                    "experiment": "discover",
                    "claim": f"{r['system']}: {row['quantity']} = {row['truth']:.4g} (goal {row['goal']})",
                    "paper": f"{row['paper']:.4g}",
                    "ours": f"{row['ours']:.4g} ± {row['stderr']:.2g}",
                    "met": bool(row["goal_met"]),
                }
            )
    return claims


def collect_claims(results: dict) -> list[dict]:
    """Every judged claim of every experiment as {experiment, claim, paper, ours, met}."""
    claims = _discover_claims(results.get("discover", []))
    for exp in EXPERIMENTS[1:]:
        for c in results[exp]["claims"] if exp in results else []:
            claims.append(
                {
                    "experiment": exp,
                    "claim": c["claim"],
                    "paper": c.get("paper", ""),
                    "ours": c["ours"],
                    "met": bool(c["met"]),
                }
            )
    return claims


# ---------------------------------------------------------------------------------------------------- HTML
def _met(m: bool) -> str:
    return '<span class="met">met</span>' if m else '<span class="miss">not met</span>'


def _claims_table(claims: list[dict]) -> str:
    return table(
        ["claim", "paper", "ours", ""],
        [[_e(c["claim"]), _e(c["paper"]), _e(c["ours"]), _met(c["met"])] for c in claims],
        left=3,
    )


def _fmt(x, nd=4) -> str:
    return "—" if x is None else (f"{x:.{nd}g}" if isinstance(x, (int, float)) else _e(x))


def _discover_body(disc: list[dict]) -> str:
    rows = [
        [
            _e(r["system"]),
            "new physics" if r["new_physics"] else "no new physics",
            _fmt(r["verdict"]["ratio"], 3),
            _fmt(r["settings"]["trajectory"]["n_steps"]),
            _fmt(r["settings"]["trajectory"]["paper_n_steps"]),
            _fmt(r["wall_time_s"], 3),
        ]
        for r in disc
    ]
    s = "<h3>Verdicts</h3>" + table(
        ["system", "verdict", "L_e ratio across λ=1", "trajectory steps", "paper's steps", "time (s)"], rows
    )
    t2 = []
    for r in disc:
        for row in r["table2"]:
            t2.append(
                [
                    _e(r["system"]),
                    _e(row["quantity"]),
                    _fmt(row["truth"]),
                    _fmt(row["paper"]),
                    f"{_fmt(row['ours'])} ± {_fmt(row['stderr'], 2)}",
                    _e(row["goal"]),
                    _met(row["goal_met"]),
                    f"{_fmt(row['posthoc'])} ± {_fmt(row['posthoc_stderr'], 2)}",
                ]
            )
    s += "<h3>Table II: ground truth, paper, ours</h3>" + table(
        [
            "system",
            "quantity",
            "truth",
            "paper",
            "ours (joint law fit) ± stderr",
            "goal",
            "",
            "post hoc (the paper's way) ± stderr",
        ],
        t2,
        left=2,
    )
    s += "<h3>Explanations of the learned non-conservative force</h3>"
    ex = []
    for r in disc:
        ex.append(
            [
                _e(r["system"]),
                "parametric",
                f"<code>{_e(r['parametric']['formula'])}</code>",
                _fmt(r["parametric"]["rel_rms"], 3),
            ]
        )
        for method, b in r["blind"].items():
            f = (
                "<br>".join(f"<code>{_e(k)} = {_e(v)}</code>" for k, v in b["formula"].items())
                if b["readable"]
                else "nothing readable"
            )
            ex.append(
                [
                    _e(r["system"]),
                    f"blind ({_e(method)})",
                    f + f"<br><small>{_e(b['note'])}</small>",
                    _fmt(b["rel_rms"], 3),
                ]
            )
    s += table(["system", "method", "formula", "rel. rms"], ex, left=3)
    return s


def _predict_body(res: dict) -> str:
    from nnphd.paper.predict import LABELS, MODELS, THETA_TOL

    tkey = f"t_error_exceeds_{THETA_TOL:g}"
    rows = [
        [
            _e(LABELS[k]),
            _fmt(res["metrics"][k]["theta1_rmse_30_40"]),
            _fmt(res["metrics"][k]["theta1_rmse_30_200"]),
            _fmt(res["metrics"][k]["energy_rmse_30_200"]),
            "never" if res["metrics"][k][tkey] is None else _fmt(res["metrics"][k][tkey], 3),
        ]
        for k in MODELS
    ]
    b = res["energy_balance"]
    return (
        "<h3>Metrics (rollout from t = 30)</h3>"
        + table(
            ["model", "θ1 RMSE [30,40]", "θ1 RMSE [30,200]", "E RMSE [30,200]", f"|Δθ1| > {THETA_TOL:g} at t"], rows
        )
        + f"<p>Energy balance of the NNPhD rollout: dH/dt against the power of the learned f_n — rel. rms "
        f"difference {_fmt(b['dHdt_vs_power_rel_rms'], 3)}, correlation {_fmt(b['dHdt_vs_power_corr'], 4)}; "
        f"learned vs true dissipated power: correlation {_fmt(b['learned_vs_true_power_corr'], 3)}.</p>"
    )


def _lambda_p_body(res: dict) -> str:
    rows = [
        [
            _e(v["system"]),
            "MSE" if v["p"] == "mse" else f"p={_e(v['p'])}",
            _fmt(v["L_below"], 3),
            _fmt(v["L_above"], 3),
            _fmt(v["ratio"], 3),
            "new physics" if v["new_physics"] else "none",
            "" if v["correct"] else '<span class="miss">wrong</span>',
            f"{_fmt(v['sharpness'], 3)} ({_e(v['transition'])})",
        ]
        for v in res["verdicts"]
    ]
    return "<h3>Verdict per system and loss</h3>" + table(
        ["system", "loss", "L_e λ<1", "L_e λ>1", "ratio", "verdict", "", "sharpness"], rows, left=2
    )


def _data_quality_body(res: dict) -> str:
    a = [[_fmt(r["alpha"], 3), _fmt(r["L_e"]), _fmt(r["L_e_full"])] for r in res["alpha"]["table"]]
    b = [[_fmt(r["beta"], 3), _fmt(r["m_c"]), _fmt(r["m_n"])] for r in res["beta"]["table"]]
    return figures(
        [
            "<div><h3>HO+CD, λ = 10: L_e(α)</h3>"
            + table(["α", "L_e (same-α test)", "L_e (full Gaussian)"], a)
            + "</div>",
            "<div><h3>HO+LD, λ = 0.5: misalignment(β)</h3>" + table(["β", "m_c", "m_n"], b) + "</div>",
        ]
    )


def render_html(outdir: Path, summary: dict, results: dict) -> str:
    """The self-contained report: one section per experiment, figures embedded as data URIs and linked."""
    render = {
        "discover": _discover_body,
        "predict": _predict_body,
        "lambda-p": _lambda_p_body,
        "data-quality": _data_quality_body,
    }
    bodies = {e: render[e](results[e]) for e in EXPERIMENTS if results.get(e)}
    failed = summary.get("failed") or {}
    parts = ["<h1>nnphd — reproduction of the paper's experiments</h1>"]
    if summary["mode"] == "quick":
        parts.append(
            '<p class="quick"><b>Quick mode:</b> the same code with fewer training steps (see the settings). '
            "Its numbers are a smoke test, not the paper-scale results; run <code>nnphd reproduce</code> "
            "without <code>--quick</code> for those.</p>"
        )
    n_cached = sum(r["cached"] for r in summary["runs"].values())
    parts.append(
        f"<p>Mode <b>{_e(summary['mode'])}</b>, seed {summary['seed']}, written "
        f"{datetime.now(UTC).isoformat(timespec='seconds')}. This run: {summary['wall_time_s']:.0f} s "
        f"({n_cached} of {len(summary['runs'])} units loaded from the cache); compute time of all units as "
        f"measured when they ran: {summary['compute_time_s']:.0f} s; of this run's time, "
        f"{summary.get('compile_time_s', 0.0):.0f} s went to JAX compilation (workers: "
        f"{_e(summary.get('workers', 'in-process'))}). Claims met: "
        f"<b>{summary['claims_met']} of {summary['claims_total']}</b>.</p>"
    )
    parts.append(bullets(f'<a href="#{e}">{_e(TITLES[e])}</a>' for e in EXPERIMENTS))
    if failed:
        parts.append(
            '<p class="quick"><b>Failed units</b> (the others finished and are cached; run the same command again '
            "to resume): " + "; ".join(f"<code>{_e(k)}</code>: {_e(v)}" for k, v in failed.items()) + "</p>"
        )
    for exp in EXPERIMENTS:
        if exp not in bodies:
            errs = "; ".join(f"{k}: {v}" for k, v in failed.items() if k.split("/")[0] == exp)
            parts.append(section(TITLES[exp], f'<p class="miss">Not run to the end: {_e(errs)}</p>', exp))
            continue
        claims = [c for c in summary["claims"] if c["experiment"] == exp]
        settings = json.dumps(summary["settings"][exp], indent=1)
        units = {k: v for k, v in summary["runs"].items() if k.split("/")[0] == exp}
        parts.append(
            section(
                TITLES[exp],
                f'<div class="claim"><b>Paper:</b> {_e(PAPER_CLAIMS[exp])}</div>'
                + figures(figure_file(outdir, rel) for rel in FIGURES[exp])
                + bodies[exp]
                + f"<h3>Claims</h3>{_claims_table(claims)}"
                + details("settings and run log", f"{settings}\n{json.dumps(units, indent=1)}"),
                exp,
            )
        )
    return page("nnphd reproduce", "".join(parts))
