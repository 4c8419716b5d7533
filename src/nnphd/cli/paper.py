"""The paper's commands: ``nnphd systems``, ``sweep``, ``discover``, ``predict``, ``study lambda-p``,
``study data-quality``, ``reproduce`` and ``demo neptune`` — thin shells over :mod:`nnphd.paper` and
:mod:`nnphd.astro`."""

from __future__ import annotations

import math
import sys
from dataclasses import dataclass

import typer
from rich.table import Table

from nnphd.cli.common import (
    DTYPE_HELP,
    MAX_SEED,
    MAX_STEPS,
    P_HELP,
    DiscoverySystem,
    InputError,
    Precision,
    SweepMode,
    app,
    claim_out,
    console,
    demo_app,
    fraction_option,
    options_command,
    parse_csv,
    parse_lambdas,
    parse_loss_p,
    progress_bar,
    scheduler_option,
    study_app,
    workers_option,
)
from nnphd.io.escape import one_line
from nnphd.io.escape import rich as _r  # --out, a --scheduler address: the user's text (markup, control chars escaped)


@app.command()
def systems():
    """List the built-in systems with their ground truth and default settings."""
    from nnphd.engine.systems import SYSTEMS

    for s in SYSTEMS.values():
        params = ", ".join(f"{k}={v:.6g}" for k, v in s.params.items())
        kind = "conservative" if s.conservative else "non-conservative"
        console.print(
            f"[bold]{s.name}[/]  n={s.n}, {kind}, data: {s.data} (dt={s.dt:g}, {s.n_steps} steps from "
            f"{tuple(round(x, 6) for x in s.x0)})"
        )
        console.print(f"    {params}")
        console.print(f"    {s.description}", highlight=False)


@dataclass(frozen=True)
class SweepOptions:
    """``nnphd sweep``'s options as given on the command line (typer fills them:
    :func:`nnphd.cli.common.options_command`)."""

    system: str = typer.Option(..., "--system", "-s", help="system name (see `nnphd systems`)")
    p: str = typer.Option("1", "--p", "--loss-p", help=P_HELP)
    steps: int = typer.Option(
        2000, "--steps", min=4, max=MAX_STEPS, help="training steps per λ (split over the 4 learning rates)"
    )
    seed: int = typer.Option(0, "--seed", min=0, max=MAX_SEED, help="random seed (data and initialisation)")
    lambdas: str | None = typer.Option(None, "--lambdas", help="comma-separated λ values (default: the paper's 13)")
    mode: SweepMode = typer.Option(
        SweepMode.warm,
        "--mode",
        help="warm (paper: warm start, increasing λ), vmap (every λ from the same start, one vmapped run), scratch (the same, one λ after the other) or fast (4 λ, warm, each until converged; the paper protocol when that verdict is close)",
    )
    param: list[str] = typer.Option(
        [], "--param", help="override a system parameter, e.g. --param gamma=0.2 (repeatable)"
    )
    out: str = typer.Option("out/sweep", "--out", help="output directory for results.json and loss_vs_lambda.png")
    resume: bool = typer.Option(True, "--resume/--no-resume", help="continue an interrupted sweep in --out")
    standardize: bool = typer.Option(
        True,
        "--standardize/--no-standardize",
        help="networks see (q, q̇, t) standardised by the training data's mean and std",
    )
    dtype: Precision = typer.Option(Precision.float64, "--dtype", help=DTYPE_HELP)


@app.command()
@options_command(SweepOptions)
def sweep(o: SweepOptions):
    """λ-sweep on one system: prints L_e(λ) and the verdict; writes results.json and an L_e(λ) plot."""
    from nnphd.engine.systems import get_system

    # --- validate everything before any work
    try:
        overrides = {}
        for item in o.param:
            if "=" not in item:
                raise InputError(f"--param must look like name=value, got {item!r}")
            k, v = item.split("=", 1)
            try:
                overrides[k.strip()] = float(v)
            except ValueError:
                raise InputError(f"--param {k.strip()} must be a number, got {v!r}") from None
            if not math.isfinite(overrides[k.strip()]):
                raise InputError(f"--param {k.strip()} must be a finite number, got {v!r}")
        sysm = get_system(o.system, **overrides)
        pp = parse_loss_p(o.p)
        lams = parse_lambdas(o.lambdas)
        claim_out(o.out)
    except ValueError as e:
        raise InputError(str(e)) from None

    from nnphd.engine.models import ModelConfig
    from nnphd.paper.sweep import SweepSettings, run_sweep

    console.print(f"[bold]{sysm.name}[/]: {sysm.description}")
    settings = SweepSettings(
        p=pp,
        steps=o.steps,
        seed=o.seed,
        lambdas=lams,
        mode=o.mode.value,
        model_cfg=ModelConfig(n=sysm.n, dtype=o.dtype.value),
        standardize=o.standardize,
    )
    with progress_bar("λ-sweep (first λ includes compilation)") as bar:
        res = run_sweep(sysm, settings, out=o.out, resume=o.resume, progress=bar)
    t = Table(title=f"L_e(λ) — {sysm.name}, p={pp}")
    has_m = res.table[0].m_c is not None
    for col in ("λ", "L_e", "L_b") + (("m_c", "m_n") if has_m else ()):
        t.add_column(col, justify="right")
    for r in res.table:
        row = [f"{r.lam:g}", f"{r.L_e:.4g}", f"{r.L_b:.4g}"]
        if has_m:
            row += [f"{r.m_c:.4f}", f"{r.m_n:.4f}"]
        t.add_row(*row)
    console.print(t)
    v = res.verdict
    tag = "[bold red]NEW PHYSICS[/]" if v.new_physics else "[bold green]no new physics[/]"
    console.print(f"verdict: {tag} — {v.reason}")
    console.print(
        f"statistic: L_e ratio across λ=1 = {res.le_ratio:.3g} (threshold {v.min_ratio:g}); "
        f"|f_n| ≈ {v.fn_size_from_jump:.3g} (jump) / {v.fn_size_from_uan:.3g} (UAN)"
    )
    pr = res.protocol
    if pr is not None:
        paper_steps = o.steps * len(res.settings["lambdas"])
        if pr["ran_paper_protocol"]:
            console.print(f"fast mode: the first verdict was close ({'; '.join(pr['doubts'])}): ran the paper protocol")
        else:
            console.print(
                f"fast mode: {len(pr['first_lambdas'])} λ, {pr['steps_total']} training steps "
                f"(the paper protocol: {paper_steps})"
            )
    if res.resumed_lambdas:
        console.print(f"resumed {len(res.resumed_lambdas)} finished λ from a checkpoint")
    console.print(_r(f"wrote {o.out}/results.json and {o.out}/loss_vs_lambda.png ({res.wall_time_s:.1f} s)"))


@dataclass(frozen=True)
class DiscoverOptions:
    """``nnphd discover``'s options as given on the command line (typer fills them:
    :func:`nnphd.cli.common.options_command`)."""

    system: DiscoverySystem | None = typer.Option(None, "--system", "-s", help="one Table I system")
    all_: bool = typer.Option(False, "--all", help="all three systems, our Table II beside the paper's, and Fig. 3")
    steps: int = typer.Option(
        2000, "--steps", min=4, max=MAX_STEPS, help="training steps of the constrained Lagrangian + UAN"
    )
    sweep_steps: int = typer.Option(
        2000, "--sweep-steps", min=4, max=MAX_STEPS, help="training steps per λ of the detection sweep"
    )
    lam: float = typer.Option(0.2, "--lam", help="λ of the constrained training, in (0, 1) (paper: 0.2)")
    seed: int = typer.Option(0, "--seed", min=0, max=MAX_SEED, help="random seed")
    standardize: bool = typer.Option(True, "--standardize/--no-standardize", help="standardise the networks' inputs")
    n_steps: int = typer.Option(
        0, "--n-steps", min=0, help="RK4 steps of the trajectory (0: 600/1000/1000; the paper's: 300/1000/300)"
    )
    sr_time: int = typer.Option(
        20, "--sr-time", min=0, help="seconds of genetic symbolic regression per force component (0: skip)"
    )
    out: str = typer.Option("out/discover", "--out", help="output directory (one subdirectory per system)")
    dtype: Precision = typer.Option(Precision.float64, "--dtype", help=DTYPE_HELP)


@app.command()
@options_command(DiscoverOptions)
def discover(o: DiscoverOptions):
    """Rediscover friction, Neptune or gravitational waves: verdict, Table II row, blind formula (paper Fig. 3, Table II)."""
    from nnphd.paper.discover import DISCOVERY_SYSTEMS

    try:
        if o.all_ == (o.system is not None):
            raise InputError("give either --system (double-pendulum, neptune, gw) or --all")
        if 0 < o.n_steps < 20:
            raise InputError(f"--n-steps must be 0 (default) or ≥ 20, got {o.n_steps!r}")
        lam_v = o.lam
        if not (0 < lam_v < 1):
            raise InputError(f"--lam must be a number in (0, 1) (below the phase transition), got {o.lam!r}")
        claim_out(o.out)
    except ValueError as e:
        raise InputError(str(e)) from None

    from pathlib import Path

    from nnphd.paper.discover import DiscoverSettings, write_discovery, write_table2
    from nnphd.paper.discover import discover as run_discover

    settings = DiscoverSettings(
        steps=o.steps,
        sweep_steps=o.sweep_steps,
        lam=lam_v,
        seed=o.seed,
        standardize=o.standardize,
        n_steps=o.n_steps or None,
        sr_time=o.sr_time,
        dtype=o.dtype.value,
    )
    systems_ = DISCOVERY_SYSTEMS if o.all_ else (o.system.value,)
    results = []
    for name in systems_:
        with progress_bar(f"{name}: starting") as bar:
            res = run_discover(name, settings, progress=bar)
        write_discovery(res, Path(o.out) / name)
        results.append(res)
        v = res["verdict"]
        tag = "[bold red]NEW PHYSICS[/]" if res["new_physics"] else "[bold green]no new physics[/]"
        console.print(f"[bold]{name}[/]: {tag} (L_e ratio across λ=1: {v['ratio']:.3g}) — {res['wall_time_s']:.0f} s")
        console.print(f"  constrained Lagrangian: {res['constrained_lagrangian']['formula']}", highlight=False)
        lw = res["law"]["law"]
        console.print(
            f"  law (joint fit, winner of {len(res['law']['candidates'])} candidates): "
            + ("; ".join(f"{k} = {e}" for k, e in lw["formula"].items()) if lw else "none"),
            highlight=False,
        )
        console.print(f"  post-hoc parametric fit of the UAN's f_n: {res['parametric']['formula']}", highlight=False)
        for method, b in res["blind"].items():
            console.print(
                f"  blind ({method}): "
                f"{'; '.join(f'{k} = {e}' for k, e in b['formula'].items()) if b['readable'] else '—'}"
                f"  ({b['note']})",
                highlight=False,
            )
    t = Table(title="Table II — ground truth, paper, ours")
    for col in ("system", "quantity", "truth", "paper", "ours (joint)", "± stderr", "goal", "met", "post hoc"):
        t.add_column(col, justify="right")
    for res in results:
        for r in res["table2"]:
            t.add_row(
                res["system"].replace("double-pendulum", "pendulum"),
                r["quantity"],
                f"{r['truth']:.4g}",
                f"{r['paper']:.4g}",
                f"{r['ours']:.6g}",
                f"{r['stderr']:.2g}",
                r["goal"],
                "yes" if r["goal_met"] else "[red]no[/]",
                f"{r['posthoc']:.4g}",
            )
    console.print(t)
    if o.all_:
        write_table2(results, o.out)
        console.print(_r(f"wrote {o.out}/<system>/results.json, {o.out}/fig3_loss_vs_lambda.png, {o.out}/table2.json"))
    else:
        console.print(_r(f"wrote {o.out}/{o.system}/results.json and loss_vs_lambda.png"))


def _print_claims(claims) -> None:
    """A study's judged claims (:class:`nnphd.paper.study_results.Claim`), one line each."""
    for c in claims:
        tag = "[bold green]met[/]" if c.met else "[bold red]not met[/]"
        console.print(f"{tag}: {c.claim} — {c.ours}", highlight=False)


@app.command()
def predict(
    steps: int = typer.Option(
        2000, "--steps", min=4, max=MAX_STEPS, help="training steps of each model (split over the 4 learning rates)"
    ),
    seed: int = typer.Option(0, "--seed", min=0, max=MAX_SEED, help="random seed (initialisation and minibatches)"),
    uan_time: bool = typer.Option(
        False,
        "--uan-time/--no-uan-time",
        help="UAN sees (q, q̇, t) as in the paper (default: (q, q̇), see nnphd.paper.predict)",
    ),
    out: str = typer.Option("out/predict", "--out", help="output directory for results.json and the figures"),
):
    """Extrapolate the damped double pendulum with NNPhD, an LNN and a black box (paper Fig. 4)."""
    try:
        claim_out(out)
    except ValueError as e:
        raise InputError(str(e)) from None

    from nnphd.paper.predict import LABELS, MODELS, THETA_TOL, PredictionSettings, run_prediction

    with progress_bar("starting") as bar:
        res = run_prediction(PredictionSettings(seed=seed, steps=steps, uan_time=uan_time), out=out, progress=bar)
    t = Table(title=f"prediction from t = 30 (train t ≤ 30), {steps} training steps, seed {seed}")
    for col in (
        "model",
        "θ1 RMSE [30,40]",
        "θ1 RMSE [30,200]",
        "E RMSE [30,200]",
        f"|Δθ1| > {THETA_TOL:g} at t",
        "train |Δq̈|",
    ):
        t.add_column(col, justify="right")
    for kind in MODELS:
        m = res.metrics[kind]
        t.add_row(
            LABELS[kind],
            f"{m.theta1_rmse_30_40:.4g}",
            f"{m.theta1_rmse_30_200:.4g}",
            f"{m.energy_rmse_30_200:.4g}",
            "never" if m.t_error_exceeds is None else f"{m.t_error_exceeds:.1f}",
            f"{m.train_force_error:.3g}",
        )
    console.print(t)
    b = res.energy_balance
    console.print(
        f"energy balance (NNPhD rollout): dH/dt vs q̇ᵀ(∂²L/∂q̇²)f_n: rel. rms difference "
        f"{b.dHdt_vs_power_rel_rms:.3g}, correlation {b.dHdt_vs_power_corr:.4f}; learned vs true "
        f"dissipation: correlation {b.learned_vs_true_power_corr:.3f}",
        highlight=False,
    )
    _print_claims(res.claims)
    console.print(_r(f"wrote {out}/results.json, prediction.png, energy_balance.png ({res.wall_time_s:.1f} s)"))


@study_app.command("lambda-p")
def study_lambda_p(
    steps: int = typer.Option(
        2000, "--steps", min=4, max=MAX_STEPS, help="training steps per λ (split over the 4 learning rates)"
    ),
    seed: int = typer.Option(0, "--seed", min=0, max=MAX_SEED, help="random seed (data and initialisation)"),
    systems_: str | None = typer.Option(None, "--systems", help="comma-separated toy systems (default: all five)"),
    ps: str | None = typer.Option(
        None, "--ps", help="comma-separated losses: p in [1, 10] (see sweep --p) or mse (default: 1,2,3,mse)"
    ),
    lambdas: str | None = typer.Option(None, "--lambdas", help="comma-separated λ values (default: the paper's 13)"),
    out: str = typer.Option(
        "out/study-lambda-p", "--out", help="output directory (results.json, fig5*.png, runs/ cache)"
    ),
    workers: int | None = workers_option(),
    scheduler: str | None = scheduler_option(),
):
    """L_e(λ) of the five toy systems for p = 1, 2, 3 and MSE, verdicts, HO+LD alignment; claims vs the paper (Fig. 5)."""
    from nnphd.paper.lambda_p import LOSSES, TOY_SYSTEMS, p_label

    try:

        def sys_conv(tok):
            if tok not in TOY_SYSTEMS:
                raise InputError(f"--systems must be among {', '.join(TOY_SYSTEMS)}; got {tok!r}")
            return tok

        syss = parse_csv("--systems", systems_, sys_conv, TOY_SYSTEMS)
        pvals = parse_csv("--ps", ps, parse_loss_p, LOSSES)
        if len(set(syss)) != len(syss) or len({p_label(p) for p in pvals}) != len(pvals):
            raise InputError("--systems and --ps must not repeat an entry")
        lams = parse_lambdas(lambdas)
        claim_out(out)
    except ValueError as e:
        raise InputError(str(e)) from None

    from nnphd.paper.lambda_p import LambdaPSettings, lambda_p_study

    settings = LambdaPSettings(steps=steps, seed=seed, lambdas=lams, ps=pvals, systems=syss)
    with progress_bar("λ/p study (each sweep compiles first)") as bar:
        res = lambda_p_study(settings, out=out, progress=bar, workers=workers, scheduler=scheduler)
    t = Table(title=f"verdicts — {steps} steps per λ, seed {seed}, L_e on the test set")
    for col in ("system", "loss", "L_e λ<1", "L_e λ>1", "stat.", "verdict", "sharpness", "rise"):
        t.add_column(col, justify="right")
    for v in res.verdicts:
        verd = "new" if v.new_physics else "none"
        t.add_row(
            v.system,
            "MSE" if v.p == "mse" else f"p={v.p}",
            f"{v.L_below:.3g}",
            f"{v.L_above:.3g}",
            f"{v.ratio:.3g}",
            verd if v.correct else f"[red]{verd} ✗[/]",
            ("—" if v.sharpness is None else f"{v.sharpness:.2f}") + f" {v.transition}",
            "—" if v.rise_fraction is None else f"{v.rise_fraction:.2f}",
        )
    console.print(t)
    al = res.alignment
    if al is not None:
        t = Table(title="HO+LD misalignment m_c / m_n (test set)")
        t.add_column("λ", justify="right")
        for l in al.by_p:
            t.add_column("MSE" if l == "mse" else f"p={l}", justify="right")
        for rows in zip(*al.by_p.values()):  # one row per λ, a column per loss
            t.add_row(f"{rows[0].lam:g}", *[f"{r.m_c:.3f} / {r.m_n:.3f}" for r in rows])
        console.print(t)
    _print_claims(res.claims)
    if res.cached:
        console.print(_r(f"loaded {len(res.cached)} of {len(res.verdicts)} sweeps from the cache in {out}/runs"))
    figs = "fig5.png" + (", fig5_forces.png" if al is not None else "")
    console.print(_r(f"wrote {out}/results.json, {figs} ({res.wall_time_s:.1f} s)"))


@study_app.command("data-quality")
def study_data_quality(
    steps: int = typer.Option(
        2000, "--steps", min=4, max=MAX_STEPS, help="training steps per data set (split over the 4 learning rates)"
    ),
    seed: int = typer.Option(0, "--seed", min=0, max=MAX_SEED, help="random seed (data and initialisation)"),
    alphas: str | None = typer.Option(
        None, "--alphas", help="comma-separated pie coverages α in [0,1] (default 0, 0.125, …, 1)"
    ),
    betas: str | None = typer.Option(
        None, "--betas", help="comma-separated imbalances β in [0,1] (default 0, 0.125, …, 1)"
    ),
    out: str = typer.Option("out/study-data-quality", "--out", help="output directory (results.json, fig6.png, cache)"),
    workers: int | None = workers_option(),
    scheduler: str | None = scheduler_option(),
):
    """HO+CD L_e vs pie coverage α (λ=10) and HO+LD misalignment vs imbalance β (λ=0.5); claims vs the paper (Fig. 6)."""
    from nnphd.paper.data_quality import DQ_GRID

    try:
        al = parse_csv("--alphas", alphas, fraction_option("--alphas"), DQ_GRID)
        be = parse_csv("--betas", betas, fraction_option("--betas"), DQ_GRID)
        claim_out(out)
    except ValueError as e:
        raise InputError(str(e)) from None

    from nnphd.paper.data_quality import DataQualitySettings, data_quality_study

    settings = DataQualitySettings(steps=steps, seed=seed, alphas=al, betas=be)
    with progress_bar("data-quality study: starting") as bar:
        res = data_quality_study(settings, out=out, progress=bar, workers=workers, scheduler=scheduler)
    s = res.settings
    t = Table(title=f"HO+CD, λ={s['lam_alpha']:g}: L_e vs pie coverage α (p=1, {steps} steps)")
    for col in ("α", "L_e (test, same α)", "L_e (train)", "L_e (full Gaussian)", "L_b"):
        t.add_column(col, justify="right")
    for r in res.alpha.table:
        t.add_row(f"{r.alpha:g}", f"{r.L_e:.4g}", f"{r.L_e_train:.4g}", f"{r.L_e_full:.4g}", f"{r.L_b:.3g}")
    console.print(t)
    t = Table(title=f"HO+LD, λ={s['lam_beta']:g}: misalignment vs imbalance β")
    for col in ("β", "m_c (test, same β)", "m_n (test, same β)", "m_c (balanced)", "m_n (balanced)", "L_e"):
        t.add_column(col, justify="right")
    for r in res.beta.table:
        t.add_row(
            f"{r.beta:g}", f"{r.m_c:.4f}", f"{r.m_n:.4f}", f"{r.m_c_full:.4f}", f"{r.m_n_full:.4f}", f"{r.L_e:.3g}"
        )
    console.print(t)
    _print_claims(res.claims)
    if res.cached:
        console.print(_r(f"loaded {' and '.join(res.cached)} from the cache in {out}"))
    console.print(_r(f"wrote {out}/results.json and fig6.png ({res.wall_time_s:.1f} s)"))


@app.command()
def reproduce(
    quick: bool = typer.Option(
        False, "--quick", help="fewer training steps, same code (a smoke-scale run, ≤ 10 min on 2 cores)"
    ),
    seed: int = typer.Option(0, "--seed", min=0, max=MAX_SEED, help="random seed of every experiment"),
    out: str | None = typer.Option(
        None, "--out", help="output directory (default out/reproduce or out/reproduce-quick)"
    ),
    workers: int | None = workers_option(),
    scheduler: str | None = scheduler_option(),
):
    """Every experiment of the paper (Figs. 3–6, Table II) and one self-contained HTML report; resumes from its cache."""

    out = out or ("out/reproduce-quick" if quick else "out/reproduce")
    try:
        claim_out(out)
    except ValueError as e:
        raise InputError(str(e)) from None

    from nnphd.paper.reproduce import reproduce as run_reproduce

    with progress_bar("reproduce: starting") as bar:
        s = run_reproduce(out=out, quick=quick, seed=seed, progress=bar, workers=workers, scheduler=scheduler)
    from nnphd.paper.reproduce import EXPERIMENTS, TITLES

    t = Table(title=f"nnphd reproduce ({s['mode']}, seed {seed}): the paper's claims (details in the report)")
    for col in ("experiment", "claims met", "not met"):
        t.add_column(col, justify="left")
    for exp in EXPERIMENTS:
        cs = [c for c in s["claims"] if c["experiment"] == exp]
        t.add_row(
            TITLES[exp],
            f"{sum(c['met'] for c in cs)} of {len(cs)}",
            "\n".join(f"{c['claim']} — ours: {c['ours']}" for c in cs if not c["met"]) or "—",
        )
    console.print(t)
    cached = [k for k, r in s["runs"].items() if r["cached"]]
    if cached:
        console.print(f"loaded from the cache: {', '.join(cached)}")
    console.print(
        f"claims met: {s['claims_met']} of {s['claims_total']}; wall time {s['wall_time_s']:.0f} s "
        f"(compute time of all units as measured when they ran: {s['compute_time_s']:.0f} s; JAX compilation in "
        f"this run: {s['compile_time_s']:.0f} s; workers: {_r(s['workers'])})"
    )
    console.print(_r(f"wrote {out}/report.html and {out}/summary.json"))
    if s["failed"]:
        k, e = next(iter(s["failed"].items()))
        msg = f"{len(s['failed'])} units failed ({k}: {e}); the others are cached in {out}: rerun to resume"
        print(one_line(f"error: {msg}"), file=sys.stderr)  # quotes --out and errors: control characters escaped
        raise typer.Exit(1)


@demo_app.command("neptune")
def demo_neptune(
    out: str = typer.Option("out/demo-neptune", "--out", help="output directory (results.json, figures)"),
    seed: int = typer.Option(0, "--seed", min=0, max=MAX_SEED, help="random seed"),
):
    """Le Verrier again: Neptune located from Uranus' real JPL DE405 orbit by NNPhD."""
    from nnphd.astro.ephemeris import EphemerisUnavailable, available

    try:
        if not available():
            raise InputError(
                "the Neptune demo needs the JPL ephemeris packages: pip install 'nnphd[astro]' "
                "(python3 dev.py setup installs them)"
            )
        claim_out(out)
    except ValueError as e:
        raise InputError(str(e)) from None
    from nnphd.astro.neptune import NeptuneSettings, print_summary, run_neptune_demo

    try:
        with progress_bar("neptune: starting") as bar:
            res = run_neptune_demo(NeptuneSettings(seed=seed), out=out, progress=bar)
    except EphemerisUnavailable as e:
        raise InputError(str(e)) from None
    print_summary(res, console)
    console.print(_r(f"wrote {out}/results.json ({res['wall_time_s']:.0f} s)"))
