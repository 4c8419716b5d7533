"""``nnphd detect FILE``: is there new physics in your trajectories? A thin shell over :mod:`nnphd.user.detect`."""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

import typer

from nnphd.cli.common import (
    MAX_N_SEEDS,
    MAX_SEED,
    MAX_SR_TIME,
    MAX_STEPS,
    Field,
    InputError,
    LawLevel,
    Trim,
    app,
    console,
    options_command,
    parse_lambdas,
    progress_bar,
    scheduler_option,
    workers_option,
)
from nnphd.explain.law import TableStatus
from nnphd.io.escape import one_line
from nnphd.io.escape import rich as _r
from nnphd.io.limits import MAX_ROWS, MIN_ROWS
from nnphd.user.result import Status


@dataclass(frozen=True)
class DetectOptions:
    """``nnphd detect``'s arguments and options as given on the command line (typer fills them:
    :func:`nnphd.cli.common.options_command`)."""

    files: list[str] = typer.Argument(
        ...,
        help="CSV (header: t, coordinates, optional traj, <coord>_dot, <coord>_ddot), NPZ, or camera markers (see "
        "--markers; also Tracker's .txt data table); several files or a "
        "folder: a batch (one report per file in OUT/<name>/, summary.csv/html)",
        show_default=False,
    )
    out: str = typer.Option("out/detect", "--out", help="output directory (report.json, report.html, figures)")
    angles: str | None = typer.Option(None, "--angles", help="comma-separated angular coordinates (unwrapped)")
    markers: str | None = typer.Option(
        None,
        "--markers",
        help="a camera's marker positions (<marker>_x, <marker>_y[, _z] columns): nnphd finds the constraints (fixed "
        "points, rods, rails) and chooses the coordinates — 'auto' (the default when every column is a marker's), "
        "'none' (read the columns as coordinates) or the markers' names, comma-separated",
        show_default=False,
    )
    fps: float | None = typer.Option(
        None, "--fps", min=1e-9, max=1e9, help="frames per second of a marker recording with a frame column, no t"
    )
    seed: int = typer.Option(0, "--seed", min=0, max=MAX_SEED, help="random seed")
    steps: int = typer.Option(
        1000, "--steps", min=4, max=MAX_STEPS, help="training steps per λ (and per extra round of the checks)"
    )
    n_seeds: int = typer.Option(
        2,
        "--n-seeds",
        "--repeats",
        min=1,
        max=MAX_N_SEEDS,
        help="how many seeds (other initialisation and held-out trajectories; NNPhD(n_seeds=…); --repeats is "
        "its old name)",
    )
    sr_time: int = typer.Option(
        10, "--sr-time", min=0, max=MAX_SR_TIME, help="seconds of genetic symbolic regression per component (0: skip)"
    )
    law: list[str] | None = typer.Option(
        None,
        "--law",
        help="a candidate law of your own, as a formula in the "
        "coordinates, <name>_dot and t; other symbols are fitted, e.g. "
        "'c*x_dot*abs(x_dot)' or 'x: -g*x_dot; y: -g*y_dot' (repeatable)",
    )
    law_fit: LawLevel = typer.Option(
        LawLevel.auto,
        "--law-fit",
        help="how the candidate laws are ranked (trajectory: multiple shooting on the positions)",
    )
    families: str | None = typer.Option(
        None,
        "--families",
        help="comma-separated candidate law families to rank (default: all — linear, quadratic, coulomb, their sums "
        "such as linear+coulomb, power, rayleigh, vanderpol, rayleigh-vdp, drive, sparse; -diag/-full variants for "
        "two or more coordinates); your --law laws are ranked too (NNPhD(library=LawLibrary(families=…)))",
    )
    field: Field = typer.Option(
        Field.learned,
        "--field",
        help="the conservative force: learned (by the Lagrangian network, any force) or uniform (declared: gravity "
        "near the ground, or none — for a throw, a fall, a coast-down, which a learned potential can follow whatever "
        "force acts), or vertical (declared uniform and along the last coordinate, which points up: gravity filmed "
        "with a level camera — one parameter fewer than uniform); the verdict then rests on a fit of the positions "
        "beside the fitted field",
    )
    lambdas: str | None = typer.Option(
        None,
        "--lambdas",
        help="comma-separated λ of the sweep (default 0.05,0.1,0.2,0.5,2,5,10; values below and above 1)",
    )
    width: int = typer.Option(64, "--width", min=2, help="hidden width of the LNN and the UAN (two layers each)")
    max_rows: int = typer.Option(
        MAX_ROWS,
        "--max-rows",
        min=MIN_ROWS,
        help="refuse files with more data rows than this (memory: see docs/promises.md)",
    )
    trim: Trim = typer.Option(
        Trim.auto,
        "--trim",
        help="drop the ends of each trajectory, where the one-sided derivative estimates are ~20x worse",
    )
    thin: bool = typer.Option(
        True,
        "--thin/--no-thin",
        help="use every k-th row of a dense record (over 5000 rows, over 80 per period), its derivatives estimated "
        "at the full rate first",
    )
    workers: int | None = workers_option()
    scheduler: str | None = scheduler_option()


@app.command()
@options_command(DetectOptions)
def detect(o: DetectOptions):
    """Is there new physics in YOUR trajectories? Verdict (detected / none / inconclusive), forces, the law."""
    fams = _families_setting(o.families, o.law)  # checked before anything is read or created
    ang, extra, trim_v, paths = _checked_options(o)
    extra |= fams
    settings = _run_settings(o, trim_v, extra)
    if not o.thin:
        settings["thin"] = False
    if paths is not None:
        settings |= {k: v for k, v in (("markers", o.markers), ("fps", o.fps)) if v is not None}
        return _batch(o.files, len(paths), o.out, ang, o.max_rows, o.workers, o.scheduler, settings)
    ud, t_read = _read_file(o.files[0], ang, o.max_rows, o.law, o.out, (o.markers, o.fps))
    rep = _detect_one(ud, o.out, o.workers, o.scheduler, t_read, settings)
    _print_report(rep)
    console.print(_r(f"wrote {o.out}/report.json and {o.out}/report.html ({rep['wall_time_s']:.0f} s)"))


def _checked_options(o: DetectOptions):
    """The options checked before any file is read: (angle names, extra settings (width, λ), the trim setting, the
    batch's paths or None for one file). A batch's --law texts are checked and its output folder claimed here. A bad
    value is an :class:`InputError`."""
    from nnphd.cli.common import claim_out as claim_out_dir  # notes the folders it creates (removed on a failure)
    from nnphd.user.recording import DataError

    try:
        files, out, angles, law = o.files, o.out, o.angles, o.law
        extra = {"width": o.width}
        if o.lambdas is not None:
            extra["lambdas"] = parse_lambdas(o.lambdas)
        trim_v = {"auto": "auto", "yes": True, "no": False}[o.trim.value]
        from nnphd.user.settings import check_field

        check_field(o.field.value, o.law_fit.value)
        ang = tuple(a.strip() for a in angles.split(",")) if angles else ()
        if any(not a for a in ang):
            raise InputError(f"--angles must be comma-separated coordinate names, got {angles!r}")
        if len(files) > 1 or Path(files[0]).is_dir():
            from nnphd.explain.families import check_law_text
            from nnphd.user.batch import expand_paths

            for x in law or []:  # a bad --law is refused before any file is read (each file parses it again)
                check_law_text(x)

            paths = expand_paths(files, out)  # validated here, before anything is written
            claim_out_dir(out)
        else:
            paths = None
    except (ValueError, DataError) as e:
        raise InputError(str(e)) from None
    return ang, extra, trim_v, paths


def _families_setting(families: str | None, law) -> dict:
    """``--families`` as the setting of :func:`nnphd.user.detect.detect_data` (none when not given), checked: a
    family that does not exist, or nothing to rank at all, is an :class:`InputError`."""
    if families is None:
        return {}
    from nnphd.user.strategies import check_families

    keys = tuple(k.strip() for k in families.split(",") if k.strip())
    try:
        check_families(keys)
    except ValueError as e:
        raise InputError(f"--families: {e}") from None
    if not keys and not law:
        raise InputError("--families names no family and no --law is given: there is nothing to rank")
    return {"families": keys}


def _run_settings(o: DetectOptions, trim_v, extra: dict) -> dict:
    """The settings of :func:`nnphd.user.detect.detect_data` (and of each file of a batch): the options ``o``, the
    ``trim`` setting they give (``trim_v``) and the ``extra`` ones (width, λ, families)."""
    return dict(
        seed=o.seed,
        steps=o.steps,
        n_seeds=o.n_seeds,
        sr_time=o.sr_time,
        laws=tuple(o.law or ()),
        law_fit=o.law_fit.value,
        field=o.field.value,
        trim=trim_v,
        **extra,
    )


def _read_file(file, ang, max_rows, law, out, camera=(None, None)):
    """One file read and checked (its --law texts parsed on its coordinates) before anything is created, then its
    output folder claimed: (the trajectories, the seconds the read took). ``camera``: (--markers, --fps). A bad file
    is an :class:`InputError`."""
    from nnphd.cli.common import claim_out as claim_out_dir
    from nnphd.user.recording import DataError, load_trajectories

    try:
        t_read = time.perf_counter()
        markers, fps = camera  # validate the file before anything is created
        ud = load_trajectories(file, ang, max_rows=max_rows, markers=markers, fps=fps)
        t_read = time.perf_counter() - t_read
        from nnphd.explain.families import parse_law

        for x in law or []:
            parse_law(x, ud.coords)
        claim_out_dir(out)
    except (ValueError, DataError) as e:
        raise InputError(str(e)) from None
    return ud, t_read


def _detect_one(ud, out, workers, scheduler, t_read, settings) -> dict:
    """The detection on one file's trajectories, under a progress bar: its report."""
    from nnphd.user.detect import detect_data

    with progress_bar("detect: starting") as status:
        result, _ = detect_data(
            ud, out=out, progress=status, workers=workers, scheduler=scheduler, read_s=t_read, **settings
        )
    return result.report


def _print_report(rep: dict) -> None:
    """The verdict of one file's report on the console: status, effect, warnings, angle notes, reasons, the law
    and the hint or blind formula."""
    # every text from the report may quote the file's column names or path: markup and control characters escaped (_r)
    colour = {Status.DETECTED: "bold red", Status.NONE: "bold green"}.get(rep["status"], "bold yellow")
    console.print(
        f"[{colour}]{_r(rep['status'].upper())}[/] — new physics: {'yes' if rep['new_physics'] else 'no'} "
        f"(confidence {rep['confidence']:.2g})",
        highlight=False,
    )
    if rep.get("effect"):
        console.print(f"  effect: {_r(rep['effect'])}", highlight=False)
    for w in rep.get("warnings") or []:
        console.print(f"  [yellow]warning:[/] {_r(w)}", highlight=False)
    if (rep.get("data") or {}).get("thinned"):
        console.print(f"  data: {_r(rep['data']['thinned']['text'])}", highlight=False)
    for c, why in rep.get("angle_suggestions") or []:
        console.print(
            f"  note: {_r(repr(c))} looks like an angle ({_r(why)}); rerun with --angles to treat it as one",
            highlight=False,
        )
    mk = rep.get("markers")
    if mk:
        console.print(f"  markers: {_r(mk['summary'])}", highlight=False)
        if mk.get("note"):
            console.print(f"  [yellow]markers:[/] {_r(mk['note'])}", highlight=False)
        for c in mk["constraints"]:
            console.print(f"    {_r(c['text'])}", highlight=False)
    for r in rep["reasons"]:
        console.print(f"  • {_r(r)}", highlight=False)
    f = rep["formula"]
    _print_law(rep.get("law") or {})
    h = rep.get("hint")
    if h is not None:
        console.print(
            _r(
                "  hint (not a law): " + "; ".join(f"{k} = {v}" for k, v in h["formula"].items()) + f"  [{h['method']}]"
            ),
            highlight=False,
        )
    elif rep["blind"] and f is None:
        console.print("  blind formula: nothing readable", highlight=False)


def _print_law(lw: dict) -> None:
    """The law of a report (``rep["law"]``) on the console: the winner and any ties with their parameters, or why
    there is none."""
    if lw.get("law"):
        tie = lw.get("status") == TableStatus.TIE
        if tie:
            console.print(f"  law: [bold]tie[/] — {_r(lw['reason'])}", highlight=False)
        for w in [lw["law"], *(lw.get("ties") or [])]:
            console.print(
                _r(
                    f"  {'   or' if tie else 'law'}: {w['title']}: "
                    + "; ".join(f"{k} = {v}" for k, v in w["formula"].items())
                ),
                highlight=False,
            )
            console.print(
                _r("       " + ", ".join(f"{k} = {v:.4g} ± {w['stderr'][k]:.2g}" for k, v in w["params"].items())),
                highlight=False,
            )
    if lw.get("reason") and not lw.get("law"):
        console.print(f"  law: none — {_r(lw['reason'])}", highlight=False)


def _batch(paths, n_files, out, angles, max_rows, workers, scheduler, settings) -> None:
    """Several files (``paths`` as given: :func:`nnphd.user.batch.scan_paths` lists what it skips, ``n_files`` to
    read): one report each, a summary table; exit 1 when a file failed (its error is in the summary)."""
    import sys

    from rich.table import Table

    from nnphd.user.batch import FileStatus, detect_batch

    with progress_bar(f"detect: {n_files} files") as status:
        s = detect_batch(
            paths, out, angles, max_rows=max_rows, workers=workers, scheduler=scheduler, progress=status, **settings
        )
    t = Table(title=_r(f"nnphd detect — {s['n_files']} files (workers: {s['workers']})"))
    for col in ("file", "verdict", "confidence", "law", "time (s)", "error"):
        t.add_column(col, justify="left")
    for r in s["rows"]:
        t.add_row(  # file names, laws and errors quote the data: markup and control characters escaped (_r)
            _r(r["file"]),
            _r(r["status"]),
            "" if r["confidence"] is None else f"{r['confidence']:.2g}",
            _r(r["law"] or ""),
            "" if r["wall_time_s"] is None else f"{r['wall_time_s']:.0f}" + (" (cached)" if r["cached"] else ""),
            _r(r["error"] or ""),
        )
    for k in s.get("skipped", []):
        t.add_row(_r(k["file"]), FileStatus.SKIPPED.value, "", "", "", _r(k["reason"]))
    console.print(t)
    console.print(
        _r(
            f"wrote {out}/summary.csv, summary.html, summary.json and one folder per file ({s['wall_time_s']:.0f} s; "
            f"JAX compilation {s['compile_time_s']:.0f} s of {s['compute_time_s']:.0f} s of compute)"
        )
    )
    if s["failed"]:
        first = next(r for r in s["rows"] if r["status"] == FileStatus.ERROR)
        print(  # the error and --out quote names: one line, control and bidi characters shown as escapes
            one_line(f"error: {s['failed']} of {s['n_files']} files failed ({first['error']}); see {out}/summary.csv"),
            file=sys.stderr,
        )
        raise typer.Exit(1)
