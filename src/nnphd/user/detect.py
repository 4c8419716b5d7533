"""``nnphd detect FILE``: new-physics detection on the user's own trajectories.

Pipeline: :func:`nnphd.user.recording.load_trajectories` (validation, one-line errors) → :func:`nnphd.user.derivatives.to_dataset`
(q̇, q̈ per trajectory with a noise estimate) → :func:`nnphd.user.assess.assess` (standardised units, λ-sweep on held-out
trajectories, the checks that tell non-conservation from under-fitting, repeated seeds) → the blind explanation of
the learned non-conservative force in the file's own coordinate names → ``report.json``, ``report.html`` and the
figures in ``--out``. Every file is written atomically, and only after the whole analysis succeeded.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from contextlib import nullcontext
from dataclasses import replace
from pathlib import Path

import numpy as np

from nnphd._config import release_compiled_if_crowded
from nnphd.io.errors import DataError
from nnphd.io.progress import Progress, Stages
from nnphd.io.timing import StageTimer
from nnphd.parallel import runs_in_this_process
from nnphd.user.limits import MIN_ROWS
from nnphd.user.report import write_report
from nnphd.user.rules import (
    LIBRARY_BASE,
    RECONCILED_BASIS,
    against_velocity,
    position_explained,
    reconcile,
    unclaim_active,
    unclaim_against_evidence,
    unclaim_unidentifiable,
    work_per_trajectory,
)


def detect_file(
    path: str | Path,
    out: str | Path | None = None,
    angles=(),
    progress: Progress | None = None,
    max_rows: int | None = None,
    **settings,
) -> dict:
    """Load ``path``, assess it, find the law of f_n; write report.json / report.html / PNGs to ``out`` if given.

    ``settings`` as :func:`detect_data` (seed, steps, sr_time, n_seeds, trim, laws, law_fit and the keywords of
    :func:`nnphd.user.assess.assess`); the law level is checked before the file is read.  ``max_rows``: the row
    limit of :func:`nnphd.user.recording.load_trajectories`.
    """
    from nnphd.user.recording import load_trajectories

    _check_law_fit(settings.get("law_fit", "auto"))
    check_field(settings.get("field", "learned"), settings.get("law_fit", "auto"))
    if progress is not None:
        progress(0, 1, "reading the file")
    t0 = time.perf_counter()
    ud = load_trajectories(path, angles, max_rows=max_rows)
    return detect_data(ud, out, progress=progress, read_s=time.perf_counter() - t0, **settings)[0]


def _check_law_fit(law_fit: str) -> None:
    if law_fit not in ("auto", "pointwise", "trajectory"):
        raise ValueError(f"law_fit must be 'auto', 'pointwise' or 'trajectory', got {law_fit!r}")


# the conservative force the user declares: learned by the LNN (any conservative force, the default), or a uniform
# field — gravity near the ground, or none — for motion that does not oscillate (a throw, a fall, a coast-down).
# Along one arc every force of the state is a force of position, so a learned potential absorbs a drag and such a
# record cannot tell a drag from a field that varies over it (measured on the 2-D throw look-alike, 3 mm noise: a
# uniform field leaves χ²/N = 3.1, the uniform field + drag 0.94, a field varying linearly over the record 1.01 —
# benchmarks/results/friction_laws.json); a physicist filming a throw knows the field is uniform, and says so.
FIELDS = {
    "learned": "learned by the Lagrangian network (any conservative force)",
    "uniform": "declared uniform (gravity near the ground, or none): a constant acceleration, fitted",
    "vertical": "declared uniform and along the last coordinate (gravity, with that coordinate pointing up, e.g. a "
    "level camera's y): its size fitted, no field along the others",
}
# the declared fields: no force of position beyond a constant one. Knowing gravity's direction is one parameter fewer,
# and along a 1.2-s arc that parameter matters: a sideways constant force lets linear drag stand in for quadratic
# (on the 2-D throw look-alike, seed 0, a whole-trajectory fit of linear drag is Δχ² 1.9 *better* than quadratic
# with the field's direction free and 8.6 worse with it vertical; seeds 1, 2: −5.2 / 6.5, −10.3 / 23.0)
DECLARED_FIELDS = ("uniform", "vertical")


def check_field(field: str, law_fit: str = "auto") -> None:
    if field not in FIELDS:
        raise ValueError(f"field must be one of {', '.join(map(repr, FIELDS))}, got {field!r}")
    if field in DECLARED_FIELDS and law_fit == "pointwise":
        raise ValueError(
            "a declared uniform field is judged by a fit of the positions: law_fit must be 'auto' or 'trajectory', "
            "got 'pointwise'"
        )


def check_declared_field(field: str, data, traj, ud, info) -> None:
    """A declared uniform field cannot make motion oscillate (no force of position): refuse an oscillating record
    before any training, with the period found as :func:`nnphd.user.assess.assess` finds it."""
    if field not in DECLARED_FIELDS:
        return
    from nnphd.user.assess import motion_period

    arc = arc_noise(data, traj, list(ud.coords), info)  # a tracker's correlated noise must not read as swings
    noise = [max(arc["difference"][c], arc["smooth_curve"][c]) if np.isfinite(arc["smooth_curve"][c])
             else arc["difference"][c] for c in ud.coords]  # fmt: skip
    period = motion_period(data, traj, [bool(a) for a in ud.is_angle], noise)
    path = ud.path
    if np.isfinite(period):
        raise DataError(
            f"{path}: the field was declared uniform, under which nothing oscillates, but this record swings back and "
            f"forth (period {period:.4g} in its time unit): it oscillates, or its positions are mostly noise; leave the "
            "field to be learned (field 'learned', the default)"
        )


def _check_settings(ud, laws: Sequence[str], law_fit: str, field: str, families=None, method: str = "auto") -> None:
    """Refuse bad settings before any work: the law level, the field, the law families and the derivative method,
    and every ``laws`` entry (a --law) parsed on the file's coordinates."""
    from nnphd.explain.families import parse_law
    from nnphd.user.derivatives import Derivatives
    from nnphd.user.strategies import check_families

    _check_law_fit(law_fit)
    check_field(field, law_fit)
    check_families(families or ())
    Derivatives(method)
    for x in laws:  # fail on a bad --law before any work
        parse_law(x, ud.coords)


class _Say:
    """The progress of :func:`detect_data`: the training rounds of the checks fill the bar (:meth:`training`); the
    other stages are messages beside it (a call)."""

    def __init__(self, progress: Progress | None) -> None:
        self.progress = progress
        self.done = [0, 1]  # the training rounds of the checks: the bar shows them; the other stages are messages

    def __call__(self, message: str) -> None:
        """Say ``message`` beside the bar as it stands."""
        if self.progress is not None:
            self.progress(self.done[0], self.done[1], message)

    def training(self, d: int, total: int, message: str) -> None:
        """A training round done: ``d`` of ``total``."""
        self.done[:] = [d, total]
        self(f"training: {message}")


def _assessed(data, traj, ud, info, training, seed, steps, n_seeds, workers, scheduler, assess_kw: dict) -> dict:
    """:func:`nnphd.user.assess.assess` on the data set, with the file's angles and the position noise and q̈ errors
    of its derivative estimates; ``training``: the progress of the training rounds."""
    from nnphd.user.assess import assess

    pc = info["per_coordinate"]
    return assess(
        data,
        traj,
        seed=seed,
        steps=steps,
        n_seeds=n_seeds,
        progress=training,
        angles=[bool(a) for a in ud.is_angle],
        position_noise=[pc[c]["noise"] for c in ud.coords],
        derivative_error=[pc[c]["qdd"]["relative_error"] for c in ud.coords],
        workers=workers,
        scheduler=scheduler,
        **assess_kw,
    )


def _declared_forces(law: dict, data, ud, fc, fn):
    """The declared uniform field as the law table fitted it, popped from ``law``: (its entry, the field fitted —
    with the law when there is one, else alone — or None, f_c, f_n); f_c and f_n as given without a declared field."""
    declared = law.pop("_field", None) or {}
    fitted = declared.get("with_law" if law.get("law") else "alone")
    if fitted is not None:  # the declared field is the conservative force; f_n the remainder of q̈ beside it
        fc = field_force(fitted, data.q, ud.is_angle)
        fn = np.asarray(data.qdd, float) - fc
    return declared, fitted, fc, fn


def _field_entry(field: str, fitted: dict | None, declared: dict) -> dict:
    """The report's ``field``: the conservative force declared, and a uniform field as fitted (its law, g and
    standard error per coordinate; whether the law's force opposes the velocity)."""
    return (
        {"kind": field, "text": FIELDS[field]}
        | ({k: fitted[k] for k in ("law", "g", "stderr")} if fitted else {})
        | ({"against_velocity": declared["against_velocity"]} if "against_velocity" in declared else {})
    )


def _report(
    ud, res: dict, info: dict, coords: list, law: dict, verdict, field: dict, blind: dict, settings: dict
) -> dict:
    """The report of :func:`detect_data` (without its timings): ``verdict`` = (status, new_physics, confidence,
    reasons) of :func:`nnphd.user.rules.reconcile`; ``field``: :func:`_field_entry`'s; ``settings``: the run's own,
    to which assess's are added."""
    from nnphd.user.recording import suggest_angles

    status, new_physics, confidence, reasons = verdict
    return {
        "file": str(ud.path),
        "new_physics": new_physics,
        "status": status,
        "statistic": res["statistic"],
        "effect": law.pop("_effect", None) or res["effect"],
        "evidence": res["evidence"],
        "confidence": confidence,
        "confidence_basis": res["confidence_basis"] if status == res["status"] else RECONCILED_BASIS,
        "reasons": reasons,
        "quality": res["quality"],
        "angles": [c for c, a in zip(coords, res["angles"]) if a],
        "angle_suggestions": [list(x) for x in suggest_angles(ud)],
        "warnings": derivative_warnings(info, coords),
        "clock": res["clock"],
        "checks": res["checks"],
        "table": res["table"],
        "lambda_forces": res["lambda_forces"],
        "noise": {c: info["per_coordinate"][c] for c in coords},
        "data": {k: v for k, v in info.items() if k != "per_coordinate"},
        "formula": law_formula(law),
        "law": law,
        "field": field,
        "blind": blind,
        "hint": best_formula(blind),
        "settings": {**settings, **res.get("settings", {})},
        "units": "forces in the file's units (coordinate units / time unit²)",
    }


def detect_data(
    ud,
    out: str | Path | None = None,
    *,
    seed: int = 0,
    steps: int = 1000,
    sr_time: float = 10.0,
    n_seeds: int = 2,
    progress: Progress | None = None,
    trim: bool | str = "auto",
    laws: Sequence[str] = (),
    law_fit: str = "auto",
    field: str = "learned",
    workers: int | None = 1,
    scheduler: str | None = None,
    read_s: float | None = None,
    derivative_method: str = "auto",
    families: Sequence[str] | None = None,
    thin: bool = True,
    **assess_kw,
) -> tuple[dict, dict]:
    """:func:`detect_file` on validated data (:class:`nnphd.user.recording.UserData`); returns (report, model) with
    model = the fitted pieces (``conservative``: the LNN and its scaling, ``law``: the claimed Candidate or None, the
    data set, trajectory ids, f_c and f_n on the rows) — what :class:`nnphd.NNPhD` keeps. ``field``: the conservative
    force, a key of FIELDS ("uniform": the verdict and the law rest on a fit of the positions beside a uniform field,
    :func:`declared_field_verdict`; the record must not oscillate). ``read_s``: the seconds reading the file took
    (for the report's ``timings``: wall and JAX-compile seconds per stage, :class:`nnphd.io.timing.StageTimer`).
    ``derivative_method``: how q̇, q̈ are estimated (:data:`nnphd.user.derivatives.METHODS`); ``families``: the
    candidate law families ranked (None: all, :data:`nnphd.user.strategies.FAMILIES`) — the report's settings name
    them only when they are not the defaults; ``thin``: a dense record of more than THIN_ROWS rows is thinned after
    its derivatives are estimated (:func:`dense_thinned`; False: every row is used)."""
    from nnphd.user.strategies import family_filter

    say = _Say(progress)
    _check_settings(ud, laws, law_fit, field, families, derivative_method)
    families = family_filter(families)
    release_compiled_if_crowded()  # a process fitting record after record must not run out of memory mappings
    timer = StageTimer()
    if read_s is not None:
        timer.add("reading the file", read_s)
    with timer:
        with timer.stage("derivatives"):
            data, info, trim, row_err, traj = prepared_data(ud, trim, derivative_method)
            check_declared_field(field, data, traj, ud, info)
            if thin:
                data, row_err, traj = dense_thinned(data, info, row_err, traj, ud)
        coords = list(ud.coords)
        library = library_alongside(data, traj, ud, info, row_err, laws, law_fit, seed, field, families, timer)
        try:
            say("λ-sweep and trust checks")
            with timer.stage("training and trust checks"):
                res = _assessed(data, traj, ud, info, say.training, seed, steps, n_seeds, workers, scheduler,
                                assess_kw)  # fmt: skip
            fn, fc = np.asarray(res["f_n"]), np.asarray(res["f_c"])
            figures = _figures_alongside(out, res, data, traj, coords, fc, fn, field, timer)
            law, law_row = _law_table(res, data, traj, coords, ud, info, row_err, laws, law_fit, seed,
                                      lambda d, t, m: say(m), field, timer, families, library)  # fmt: skip
        finally:  # not needed (no law is fitted), or an error or an interrupt here: it stops at its next stage
            if library is not None:
                library[1].set()
        status, new_physics, confidence, reasons = reconcile(res, law, field)
        unclaim_against_evidence(res, law)
        unclaim_active(res, law)
        unclaim_unidentifiable(law)
        declared, fitted, fc, fn = _declared_forces(law, data, ud, fc, fn)
        blind = {}
        if status == "detected" and law.get("law") is None:  # fallback: no candidate family fits
            with timer.stage("blind formula"):
                blind = _blind(data, coords, fn, sr_time, seed, say, reasons)
        settings = {
            "seed": seed,
            "steps": steps,
            "n_seeds": n_seeds,
            "law_fit": law_fit,
            "sr_time_per_component_s": sr_time,
            "trim": trim,
            "field": field,
            **({"derivative_method": derivative_method} if derivative_method != "auto" else {}),
            **({"families": list(families)} if families is not None else {}),
            **({"thin": False} if not thin else {}),
            **assess_kw,
        }
        verdict = (status, new_physics, confidence, reasons)
        report = _report(ud, res, info, coords, law, verdict, _field_entry(field, fitted, declared), blind, settings)

        def stamp() -> None:  # the times so far: every stage but the writing of report.json/html itself
            report["timings"] = with_workers(timer.to_dict(), res.get("timings_per_seed", []))
            report["wall_time_s"] = report["timings"]["total_s"]

        if out is not None:
            write_report(out, report, data, traj, coords, fc, fn, timer=timer, before_writing=stamp, made=figures)
        else:
            stamp()
    model = {
        "conservative": res.get("_conservative"),
        "law": law_row if law.get("law") else None,
        "data": data,
        "traj": traj,
        "coords": coords,
        "angles": [bool(a) for a in ud.is_angle],
        "fc": fc,
        "fn": fn,
        "field": fitted,
    }
    return report, model


LIBRARY_ALONGSIDE = "law table: library base (alongside training)"
LIBRARY_WAIT = "law table: library base, waited for"


def library_alongside(data, traj, ud, info, row_err, laws, law_fit, seed, field, families, timer):
    """The law table on the conservative library base (:func:`_law_table`), started beside the training on a thread
    of its own — it needs no network — when it will be wanted: one coordinate, the learned field, a trajectory-level
    fit. (future, cancel) of :func:`nnphd.parallel.alongside`, or None: then it is fitted after the training, as
    before — also in a worker of a ``detect`` batch, which owns one core. The numbers are the same either way (the
    same programs on the same data); on 2 cores the cores the training leaves idle (tracing, Python) fit it."""
    import os

    from nnphd.parallel import alongside

    if field != "learned" or len(ud.coords) != 1 or law_fit == "pointwise" or os.environ.get("NNPHD_WORKER"):
        return None
    angles = [bool(a) for a in ud.is_angle]

    def library(cancel):
        with timer.alongside(LIBRARY_ALONGSIDE):
            return find_law(data, traj, list(ud.coords), angles, info, row_err, laws=laws, level=law_fit, seed=seed,
                            families=families, cancel=cancel)  # fmt: skip

    return alongside(library)


FIGURES_ALONGSIDE = "figures (alongside the law table)"


def _figures_alongside(out, res, data, traj, coords, fc, fn, field, timer):
    """The figures that need the training only (:func:`nnphd.user.report.training_figures`), made on a thread of
    their own while the law is fitted — the learned field, a report to write, not in a worker of a ``detect`` batch
    (which owns one core). A future of them, or None (then they are made with the others, as before)."""
    import os

    from nnphd.parallel import alongside
    from nnphd.user.report import training_figures

    if out is None or field != "learned" or os.environ.get("NNPHD_WORKER"):
        return None
    view = {k: res[k] for k in ("checks", "evidence", "table", "lambda_forces")} | {"field": {"kind": field}}

    def figures(cancel):  # noqa: ARG001 — nothing to stop early: a few seconds of drawing
        with timer.alongside(FIGURES_ALONGSIDE):
            return training_figures(view, data, traj, coords, fc, fn)

    return alongside(figures)[0]


def with_workers(tm: dict, per_seed: list[dict]) -> dict:
    """The run's timings with each seed's (``per_seed``); compilation on worker processes, which this process's
    listener does not see, is added to the training stage (compile seconds are then summed over processes, and
    workers run side by side: they can exceed the stage's wall time; so can the seeds on threads of this process,
    whose compilation it saw already)."""
    elsewhere = sum(p.get("compile_s", 0.0) for p in per_seed if not runs_in_this_process(p.get("where", "in-process")))
    stages = [
        st | {"compile_s": st["compile_s"] + elsewhere} if st["stage"] == "training and trust checks" else dict(st)
        for st in tm["stages"]
    ]
    note = tm["note"] + "; the seeds' compilation on worker processes is added to the training stage, summed over them"
    return tm | {"stages": stages, "compile_s": tm["compile_s"] + elsewhere, "note": note, "per_seed": per_seed}


def prepared_data(ud, trim, method: str = "auto"):
    """(data set, info, trim used, per-row errors, trajectory id per row) of validated data, the derivatives by
    ``method``; a trim that leaves too few rows of a trajectory is refused."""
    d = _dataset(ud, trim, method)
    data, info, trim, row_err = d.data, d.info, d.trim, d.row_errors
    traj = np.concatenate([np.full(b - a, i) for i, tr in enumerate(info["trajectories"]) for a, b in [tr["kept"]]])
    for tr in info["trajectories"]:
        kept = tr["kept"][1] - tr["kept"][0]
        if kept < MIN_ROWS:  # only an explicit trim=True gets here: "auto" does not trim so far
            raise DataError(
                f"{ud.path}: trimming the ends of trajectory {tr['id']} leaves {kept} of its "
                f"{tr['n_samples']} rows; at least {MIN_ROWS} are needed: do not trim (--trim no)"
            )
    return data, info, trim, row_err, traj


def _blind(data, coords, fn, sr_time, seed, say, reasons) -> dict:
    """The blind explanation of f_n when no candidate family fits: a sparse regression, then (``sr_time`` > 0)
    genetic symbolic regression — hints, never the law; a missing optional extra is said in ``reasons``."""
    from nnphd._extras import MissingExtra
    from nnphd.explain.sparse import sparse_formula
    from nnphd.explain.symbolic import genetic_formula

    blind = {}
    names = coords + [f"{c}_dot" for c in coords]
    inputs = {n: col for n, col in zip(names, np.concatenate([data.q, data.qd], axis=1).T)}
    inputs["t"] = data.t
    comps = [f"{c}_ddot" for c in coords]
    try:
        say("blind explanation (sparse regression)")
        blind["sparse"] = sparse_formula(
            inputs, fn, comps, velocities=[f"{c}_dot" for c in coords], time="t"
        ).to_hint_dict()
        if sr_time > 0:
            say("blind explanation (genetic symbolic regression)")
            blind["genetic"] = genetic_formula(inputs, fn, comps, seed=seed, max_time=sr_time).to_hint_dict()
    except MissingExtra as e:  # the fallback is optional: say why it is missing
        reasons.append(f"no blind explanation: {e}")
    return blind


WARN_QDD_ERR = 0.2  # a coordinate whose estimated relative q̈ error exceeds this gets a warning


def derivative_warnings(info: dict, coords) -> list[str]:
    """Plain-language warnings about the derivatives (the verdict itself accounts for them)."""
    out = []
    for c in coords:
        e = info["per_coordinate"][c]["qdd"].get("relative_error")
        if e is not None and e > WARN_QDD_ERR:
            out.append(
                f"q̈ of {c!r} has an estimated relative error of {100 * e:.0f}%: pointwise tests (the λ-sweep, "
                "the fit gap) are weak for it; the verdict leans on the trajectory-level evidence"
            )
    if not info.get("trim") and info.get("n_samples", 0) > 0:
        out.append(
            "the ends of the trajectories were not trimmed (too short): their derivatives are the least accurate rows"
        )
    return out


# A dense record is thinned once its derivatives are estimated at the full rate: a record of more than THIN_ROWS rows
# (after trimming) keeps every k-th row of each trajectory, k the smallest that brings it to ≤ THIN_ROWS rows, but
# never fewer than THIN_MIN_PER_PERIOD rows per period and never more than half the shortest derivative window (so
# every dropped row's q̇ and q̈ come from a smoothing window that a kept row's window mostly shares: neighbouring
# estimates are strongly correlated, and the dropped rows add little). The real double pendulum at its full 400 Hz
# (18 038 rows, Savitzky–Golay windows of 21–31 rows, 333 rows per period) took 221 s, 133 of them in the
# trajectory-level fits; thinned to every 4th row it takes about what its 100-Hz record takes, with better
# derivatives. Records with given q̇ or q̈ (no window) and records that do not oscillate are not thinned.
THIN_ROWS = 5000
THIN_MIN_PER_PERIOD = 80


def dense_thinned(data, info: dict, row_err, traj, ud):
    """(data, row errors, trajectory ids) of a dense record thinned as the comment above says, or as given; the
    thinning, when there is one, is recorded in ``info["thinned"]`` (every, rows_before, rows, period_rows,
    text)."""
    from nnphd.explain.jointfit import trajectory_segments
    from nnphd.user.assess import motion_period

    n = len(data)
    if n <= THIN_ROWS:
        return data, row_err, traj
    pc = info["per_coordinate"]
    wins = [pc[c][k].get("windows") for c in ud.coords for k in ("qd", "qdd")]
    if not all(wins):
        return data, row_err, traj
    period = motion_period(data, traj, [bool(a) for a in ud.is_angle], [pc[c]["noise"] for c in ud.coords])
    segs = trajectory_segments(traj)
    dts = np.concatenate([np.diff(data.t[s]) for s in segs if len(s) > 1] or [np.ones(1)])
    dt = float(np.median(dts))
    if not (np.isfinite(period) and dt > 0):
        return data, row_err, traj
    per_period = period / dt
    k = min(-(-n // THIN_ROWS), int(per_period // THIN_MIN_PER_PERIOD), min(min(w) for w in wins) // 2)
    if k <= 1:
        return data, row_err, traj
    keep = np.concatenate([s[::k] for s in segs])
    info["thinned"] = {
        "every": k,
        "rows_before": n,
        "rows": len(keep),
        "period_rows": per_period,
        "text": (
            f"a dense record: one row in {k} of its {n} is used ({len(keep)} rows, {per_period / k:.0f} per "
            f"period), its derivatives estimated at the full rate first (windows of {min(min(w) for w in wins)} "
            f"rows or more)"
        ),
    }
    errs = None if row_err is None else {name: np.asarray(v)[keep] for name, v in row_err.items()}
    return data.subset(keep), errs, np.asarray(traj)[keep]


def _dataset(ud, trim, method: str = "auto"):
    """to_dataset with the ends trimmed (``trim="auto"``: drop the half-window at each end of every trajectory,
    where the one-sided derivative estimates are ~20x worse, unless that would leave a trajectory with less than
    TRIM_KEEP_MIN of its rows: :meth:`nnphd.user.derivatives.Derivatives.dataset`), the derivatives by ``method``
    (:data:`nnphd.user.derivatives.METHODS`). Returns :class:`nnphd.user.derivatives.DerivedData`."""
    from nnphd.user.derivatives import Derivatives

    return Derivatives(method, trim if isinstance(trim, str) and trim == "auto" else bool(trim)).dataset(ud)


def best_formula(blind: dict) -> dict | None:
    """The readable blind formula with the smaller residual (sparse wins ties: fewer, library terms) — a *hint* when
    no candidate law fits, never reported as the law (a blind fit of the learned f_n is a curve: on a noisy record it
    was a 13th-degree polynomial in q̇); marked as such."""
    ok = [(b["rel_rms"], i, name, b) for i, (name, b) in enumerate(blind.items()) if b.get("readable")]
    if not ok:
        return None
    _, _, name, b = min(ok)
    return {
        "method": f"hint only — {name} (blind regression of the UAN output; not a law, no family is claimed)",
        "formula": b["formula"],
        "rel_rms": b["rel_rms"],
    }


def law_formula(law: dict) -> dict | None:
    w = law.get("law")
    if not w:
        return None
    if law.get("status") == "tie":
        titles = " or ".join([w["title"], *(r["title"] for r in law.get("ties", []))])
        method = f"tie ({w['method']} fit): {titles} — the record cannot tell them apart; the first is shown"
    else:
        method = f"candidate law: {w['title']} ({w['method']} fit)"
    return {
        "method": method,
        "formula": w["formula"],
        "heldout_ratio": w["heldout_ratio"],
        "params": w["params"],
        "stderr": w["stderr"],
    }


def _law_table(
    res,
    data,
    traj,
    coords,
    ud,
    info,
    row_err,
    laws,
    level,
    seed,
    progress,
    field="learned",
    timer=None,
    families=None,
    library=None,
) -> tuple[dict, object]:
    """The ranked candidate laws with the LNN's f_c as the conservative base — and, for one coordinate, with the
    conservative library alone (no network, so no seed), the two combined by
    :func:`nnphd.explain.table.combine_bases`: a family is claimed only when both bases point to it. The law of a
    real record rested on each seed's LNN before: a seismometer's viscous damping (7 % from the reference) became a
    van der Pol law 63 % off with seed 2. For one coordinate the library is a flexible conservative model (potential
    gradients to degree 4 — in sin θ, cos θ for an angle — and a q̇² term); with more coordinates its degree-3
    potential and constant mass matrix miss what a double pendulum needs, and the LNN alone is the base — except for
    motion that does not oscillate (a throw, a fall), where the library is the uniform field alone, seed-free in any
    dimension (the LNN absorbs a throw's drag: along one arc any force of the state is a force of position). A law is
    claimed only when the verdict is "detected" (:func:`reconcile`). A declared uniform field is the only base.
    ``families``: the candidate families ranked (:func:`find_law`). Returns (the table as a dict, the winning Candidate
    or None)."""
    from nnphd.user.assess import conservative_fn

    cons = res.get("_conservative")
    if cons is None:
        return {
            "law": None,
            "reason": "no law fitted: " + (res["quality"].get("reason") or "the data cannot decide"),
            "candidates": [],
        }, None
    fc = np.asarray(cons["fc"])
    ok = bool(np.all(np.isfinite(fc))) and field == "learned"
    table = find_law(
        data,
        traj,
        coords,
        [bool(a) for a in ud.is_angle],
        info,
        row_err,
        fc=fc if ok else None,
        fc_fn=conservative_fn(cons) if ok else None,
        laws=laws,
        level=level,
        seed=seed,
        progress=progress,
        field=field,
        timer=timer,
        families=families,
    )
    arcs = not res["quality"].get("oscillating", True)  # a throw, a fall: the library is the uniform field alone
    if ok and (len(coords) == 1 or arcs) and level != "pointwise":
        from nnphd.explain.table import combine_bases

        if library is not None:  # started beside the training (:func:`library_alongside`)
            with timer.stage(LIBRARY_WAIT) if timer is not None else nullcontext():
                lib = library[0].result()
        else:
            lib = find_law(data, traj, coords, [bool(a) for a in ud.is_angle], info, row_err, laws=laws, level=level,
                           seed=seed, progress=progress, timer=timer, families=families)  # fmt: skip
        if len(coords) == 1 or lib.settings.get("library") == "minimal":  # (the law stage's own period decides)
            table = combine_bases([(LIBRARY_BASE, lib), (f"seed {seed}'s LNN", table)])
    else:
        lib = table  # the library itself is the base (a declared field, no finite f_c) — or there is none
    if table.status == "tie" and level != "pointwise":  # can the whole record tell them apart?
        from nnphd.explain.wholerecord import break_tie

        with timer.stage(WHOLE_RECORD) if timer is not None else nullcontext():
            table = break_tie(table, lib)
    out = table.to_dict()
    with timer.stage(ENVELOPE_PICTURE) if timer is not None else nullcontext():
        out["envelope"] = _envelope(table, data, traj, coords, info, bool(ud.is_angle[0]))
    if field in DECLARED_FIELDS:
        out["noise"] = arc_noise(data, traj, coords, info)
        zero = next((r for r in table.rows if r.key == "none"), None)
        out["_field"] = {k: fitted_field(table, r, coords, ud.is_angle, data.q) for k, r in
                         (("alone", zero), ("with_law", table.law))}  # fmt: skip
    if table.law is not None:  # the law's share against the velocity: a drag's is 1, a thrust's −1
        f_law = table.law.predict(data.q, data.qd, data.t)
        out["_against_velocity"] = against_velocity(f_law, data.qd)
        out["work_per_trajectory"] = work_per_trajectory(f_law, data.qd, traj)
        period = table.settings.get("period", np.nan)
        out["by_position"] = position_explained(f_law, data.q, data.t, traj, period)
        out["by_state"] = position_explained(f_law, np.hstack([data.q, data.qd]), data.t, traj, period)
        from nnphd.explain.wholerecord import passivity

        with timer.stage(PASSIVITY) if timer is not None else nullcontext():
            out["_passivity"] = passivity(table, lib, data.q, data.qd, data.t)
        if field in DECLARED_FIELDS:  # a drag opposes the velocity (:data:`DRAG_ALONG_MIN`)
            out["_field"]["against_velocity"] = out["_against_velocity"]
    return out, table.law


def arc_noise(data, traj, coords, info) -> dict:
    """The position noise that the χ²/N of a declared field's fits is judged against (:func:`nnphd.user.rules.
    declared_field_verdict`): the difference estimate of the derivative stage (:func:`nnphd.user.sampling.
    noise_level`), unless a low-degree curve through each arc (:func:`nnphd.user.sampling.smooth_curve_noise`,
    pooled over the trajectories) leaves more for every coordinate — noise correlated from frame to frame, which
    differences cancel (a tracker's): then the curve's, the smallest ratio over the coordinates. ``chi2_scale``
    divides a χ²/N computed with the difference estimate."""
    from nnphd.explain.jointfit import trajectory_segments
    from nnphd.user.sampling import smooth_curve_noise

    segs = trajectory_segments(np.zeros(len(data.t), int) if traj is None else traj)
    diff = [float(info["per_coordinate"][c]["noise"]) for c in coords]
    curve = []
    for j in range(len(coords)):
        v = [(smooth_curve_noise(data.t[s], data.q[s, j]), len(s)) for s in segs]
        v = [(x, n) for x, n in v if np.isfinite(x)]
        curve.append(float(np.sqrt(sum(x * x * n for x, n in v) / sum(n for _, n in v))) if v else float("nan"))
    ratio = [c / d if d > 0 and np.isfinite(c) else float("nan") for c, d in zip(curve, diff)]
    use = bool(ratio and np.all(np.isfinite(ratio)) and min(ratio) > 1.0)
    return {
        "difference": dict(zip(coords, diff)),
        "smooth_curve": dict(zip(coords, curve)),
        "used": "smooth curve" if use else "differences",
        "chi2_scale": float(min(ratio) ** 2) if use else 1.0,
    }


def field_force(fitted: dict, q, is_angle, xp=np):
    """The fitted declared field's acceleration at positions ``q`` (N, n) (:func:`fitted_field`)."""
    from nnphd.explain.conservative import conservative_basis

    center = fitted["center"]
    center = None if center is None else tuple(xp.asarray(x) for x in center)
    lib = fitted.get("library", "minimal")
    B = conservative_basis(xp, q, xp.zeros_like(q), [bool(a) for a in is_angle], None, center, lib)
    return xp.einsum("nik,k->ni", B, xp.asarray(fitted["coefficients"]))


def fitted_field(table, row, coords, is_angle, q) -> dict | None:
    """The declared uniform field as the joint trajectory-level fit of ``row`` (a Candidate: the zero law or the law)
    found it: its conservative coefficients over the library's columns (:func:`nnphd.explain.conservative.
    conservative_basis`, library "minimal"), their centring, and the field g with its standard error per coordinate
    at the record's mean position (constant for coordinates that are not angles). None without a fit."""
    from nnphd.explain.conservative import conservative_basis

    if row is None or row.conservative is None:
        return None
    center = table.base.center if table.base is not None else None
    alpha = np.asarray(row.conservative, float)
    qm = np.asarray(q, float).mean(axis=0, keepdims=True)
    lib = "vertical" if table.settings.get("library") == "vertical" else "minimal"
    B = conservative_basis(np, qm, np.zeros_like(qm), [bool(a) for a in is_angle], None, center, lib)[0]
    if B.shape[1] != len(alpha):
        return None
    cov = np.asarray(row.conservative_cov, float) if row.conservative_cov is not None else np.zeros((len(alpha),) * 2)
    g, se = B @ alpha, np.sqrt(np.maximum(np.einsum("nk,kl,nl->n", B, cov, B), 0.0))
    return {
        "law": row.key,
        "g": {c: float(x) for c, x in zip(coords, g)},
        "stderr": {c: float(x) for c, x in zip(coords, se)},
        "coefficients": alpha.tolist(),
        "library": lib,
        "center": [np.asarray(x, float).tolist() for x in center] if center is not None else None,
    }


ENVELOPE_PICTURE = "law table: the envelope picture"
WHOLE_RECORD = "law table: a tie fitted over the whole record"
PASSIVITY = "law table: is the law passive"


def _envelope(table, data, traj, coords, info, angle: bool = False) -> dict | None:
    """One coordinate: the measured amplitude envelope and those of the law, its ties and the next best eligible
    candidates (:mod:`nnphd.explain.envelope`); None otherwise."""
    from nnphd.explain.envelope import envelope_report

    if len(coords) != 1:
        return None
    lead = [r for r in table.rows if r.family is not None and r.significant]
    return envelope_report(
        lead,
        data.q[:, 0],
        data.qd[:, 0],
        data.t,
        traj,
        info["per_coordinate"][coords[0]]["noise"],
        table.settings.get("period", float("nan")),
        angle=angle,
    )


def find_law(
    data,
    traj,
    coords,
    is_angle,
    info,
    row_err=None,
    *,
    fc=None,
    fc_fn=None,
    laws=(),
    level="auto",
    seed=0,
    progress: Progress | None = None,
    field: str = "learned",
    timer: StageTimer | None = None,
    families: Sequence[str] | None = None,
    cancel=None,
):
    """Rank the candidate laws (:mod:`nnphd.explain.laws`) on a data set from :func:`nnphd.user.derivatives.to_dataset`
    (``info`` its info, ``row_err`` its per-row errors, :class:`nnphd.user.derivatives.DerivedData`): pointwise joint fits to the estimated q̈ (weighted by
    the per-row q̈ errors), then — unless ``level`` is "pointwise" — re-ranked at trajectory level by multiple
    shooting on the positions when the data oscillate. ``fc``/``fc_fn``: a conservative force to use as the base
    (on the rows / as a JAX function); without it the conservative library alone — the uniform field alone when
    ``field`` is "uniform" (declared: nothing oscillates). ``timer``: the stages are timed on it (law table:
    pointwise fits, trajectory-level fits, rests, stops and envelope). ``families``: the keys of the candidate
    families to rank (:func:`nnphd.explain.laws.rank_laws`' ``include``; None: all); your ``laws`` are always ranked.
    ``cancel`` (a threading.Event): once set, the next stage is not begun (CancelledError). Returns a LawTable."""
    from concurrent.futures import CancelledError

    timed = timer.stage if timer is not None else (lambda _name: nullcontext())
    say = Stages(progress, 2)

    def go_on() -> None:
        if cancel is not None and cancel.is_set():
            raise CancelledError("the law table was no longer wanted")

    say("candidate laws (pointwise joint fits)")
    given = (data, traj)
    with timed("law table: pointwise fits"):
        table, data, traj, rest, whole, period = _pointwise_table(
            data, traj, coords, is_angle, info, row_err, fc, laws, level, seed, field, families
        )
    pointwise = table
    if level != "pointwise":
        go_on()
        say("candidate laws (trajectory level: multiple shooting on the positions)")
        with timed("law table: trajectory-level fits"):
            table = _trajectory_table(table, data, traj, coords, is_angle, info, period, fc, fc_fn, seed)
    go_on()
    with timed("law table: rests, stops and envelope"):
        table = _evidence_of_rests(table, data, traj, coords, is_angle, info, period, rest, whole, fc, fc_fn, level,
                                   seed)  # fmt: skip
    if fc is None and level != "pointwise" and len(coords) == 1 and np.isfinite(period):
        from nnphd.explain.wholerecord import context

        sigma = [info["per_coordinate"][c]["noise"] for c in coords]
        rows = _thinned(data.t, traj, period)  # what a tie's whole-record fits need (nnphd.explain.wholerecord)

        def refit(library):  # the pointwise table beside another conservative library
            return _pointwise_table(*given, coords, is_angle, info, row_err, None, laws, level, seed, field, families,
                                    library=library)[0]  # fmt: skip

        table = replace(table, whole_record=context(pointwise, data, traj, rows, sigma, period, is_angle, seed, refit))
    return table


def _pointwise_table(
    data, traj, coords, is_angle, info, row_err, fc, laws, level, seed, field, families=None, library=None
):
    """find_law's pointwise stage: (the table, the moving rows' data and trajectory ids, the rest found, the whole
    data and ids, the period). ``library``: the conservative library (None: :func:`_library`'s choice)."""
    from nnphd.engine.evidence import dominant_period
    from nnphd.explain.jointfit import trajectory_segments
    from nnphd.explain.laws import rank_laws

    err = None if row_err is None else row_err["qdd_err"]
    period = dominant_period(
        np.concatenate([data.q, data.qd], axis=1),
        data.t,
        trajectory_segments(traj),
        position_noise=[info["per_coordinate"][c]["noise"] for c in coords],
    )
    if field in DECLARED_FIELDS:  # no force of position: nothing oscillates, the library is the declared field
        period = float("inf")
        library = "vertical" if field == "vertical" and library is None else library
    # the positions are fitted up to the moment the body sticks; the pointwise rows also lose the q̈ estimator's
    # half window before it (their q̈ is smeared across the jump of the force)
    moving, traj_m, _, _, rest = moving_rows(data, traj, coords, info, None, None, period, margin=False)
    data_p, traj_p, err, fc, _ = moving_rows(data, traj, coords, info, err, fc, period)
    whole = (data, traj)  # rests included: a final rest is evidence (nnphd.explain.stuck)
    data, traj = moving, traj_m
    table = rank_laws(
        data_p.q,
        data_p.qd,
        data_p.qdd,
        data_p.t,
        traj_p,
        names=coords,
        angles=is_angle,
        qdd_err=err,
        fc=fc,
        user_laws=laws,
        include=families,
        seed=seed,
        library=_library(data.t, traj, period, level) if library is None else library,
    )
    return table, data, traj, rest, whole, period


def _trajectory_table(table, data, traj, coords, is_angle, info, period, fc, fc_fn, seed):
    """find_law's trajectory-level stage: the table re-ranked by multiple shooting on the positions."""
    from nnphd.explain.jointfit import trajectory_segments
    from nnphd.explain.trajectory import rank_trajectory

    sigma = [info["per_coordinate"][c]["noise"] for c in coords]
    rows = _thinned(data.t, traj, period)
    return rank_trajectory(
        table,
        data.q[rows],
        data.qd[rows],
        data.t[rows],
        traj[rows],
        sigma=sigma,
        # no oscillation (a throw, a fall): each trajectory one window, ranked in-sample
        period=period if np.isfinite(period) else float(max(np.ptp(data.t[s]) for s in trajectory_segments(traj))),
        angles=is_angle,
        fc_fn=fc_fn if fc is not None else None,
        seed=seed,
        **(SHORT_RECORDS if len(coords) == 1 or not np.isfinite(period) else {}),
    )


def _evidence_of_rests(table, data, traj, coords, is_angle, info, period, rest, whole, fc, fc_fn, level, seed):
    """find_law's last stage: what a rest, a stop and the amplitude envelope say about the candidates (one
    coordinate), and the rest left out said in the table's reason."""
    fc_fn = fc_fn if fc is not None else None
    stuck = {}
    if level != "pointwise" and rest is not None and len(coords) == 1 and np.isfinite(period):
        from nnphd.explain.stuck import stop_contradictions, stuck_contradictions
        from nnphd.user.rest import REST_WINDOW_PERIODS

        stuck = stuck_contradictions(table, rest["final"], angles=is_angle, fc_fn=fc_fn)
        stop = stop_contradictions(
            table,
            rest["final"],
            whole[0].q,
            whole[0].qd,
            whole[0].t,
            whole[1],
            period,
            angles=is_angle,
            fc_fn=fc_fn,
            seed=seed,
            window_periods=REST_WINDOW_PERIODS,
        )
        stuck = {**stop, **stuck}
    if level != "pointwise" and len(coords) == 1:
        from nnphd.explain.envelope import envelope_evidence

        table = envelope_evidence(
            table,
            data.q[:, 0],
            data.qd[:, 0],
            data.t,
            traj,
            info["per_coordinate"][coords[0]]["noise"],
            angle=bool(is_angle[0]),
        )
    if stuck:
        from nnphd.explain.stuck import bar_stuck

        table = bar_stuck(table, stuck)
    table.settings["period"] = float(period)
    if rest is not None:
        table.settings["at_rest"] = rest
        table.reason += (
            f"; {rest['rows']} row(s) at rest ({rest['text']}) were left out of the law fits: a stuck phase "
            "(q̇ = q̈ = 0 off the equilibrium, as dry friction holds a body) would bias them"
        )
    return table


# one coordinate, or no oscillation: windows of ¾ period while there are MIN_WINDOWS of them, else each trajectory
# whole, ranked by its in-sample fit (a servo drop of two periods, a throw). Windows of 1.5–3 periods were tried:
# on the look-alikes with the conservative library as base they told the laws apart far better (string pendulum
# ΔIC −419 → −2563, a jittered clock's viscous law right), but with the LNN's f_c as base on the law table's noisy
# pendulum a dry + quadratic law beat the true viscous one by ΔIC 66 (1.5 periods: a tie) — a conservative misfit
# accumulates over long windows and friction terms soak it up — so the windows stay at ¾ period.
SHORT_RECORDS = {"window_periods": (0.75,), "allow_in_sample": True}


def _library(t, traj, period: float, level: str):
    """The conservative library of the law fits: "minimal" (the uniform field) when nothing oscillates, "short"
    (a pendulum about any rest angle, springs to degree 3) when the record is too short for held-out shooting
    windows and is ranked in-sample, else the full one (:func:`nnphd.explain.conservative.conservative_basis`)."""
    from nnphd.engine.shooting import shooting_windows
    from nnphd.explain.jointfit import trajectory_segments
    from nnphd.explain.trajectory import MIN_WINDOWS

    if not np.isfinite(period):
        return "minimal"
    if level == "pointwise":
        return True
    wins = shooting_windows(trajectory_segments(traj), t, period, periods=min(SHORT_RECORDS["window_periods"]))
    return "short" if len(wins) < MIN_WINDOWS else True


SHOOT_SAMPLES_PER_PERIOD = 200  # the trajectory-level fits keep every k-th row: 200–400 rows per period remain


def _thinned(t, traj, period: float) -> np.ndarray:
    """The rows the trajectory-level fits use: every k-th row of each trajectory, k such that ≥ SHOOT_SAMPLES_PER_PERIOD
    rows per period remain — a 1 kHz encoder (1260 rows per period) took 15 minutes to rank at full rate, and the
    positions between the kept rows add little that the noise does not hide."""
    from nnphd.explain.jointfit import trajectory_segments

    segs = trajectory_segments(traj)
    dts = np.concatenate([np.diff(t[s]) for s in segs if len(s) > 1] or [np.ones(1)])
    dt = float(np.median(dts)) if dts.size else 1.0
    k = int(period / (SHOOT_SAMPLES_PER_PERIOD * dt)) if np.isfinite(period) and dt > 0 else 1
    if k <= 1:
        return np.arange(len(t))
    return np.concatenate([s[::k] for s in segs])


def moving_rows(data, traj, coords, info, err, fc, period, margin: bool = True):
    """The data set without its stretches at rest (:mod:`nnphd.user.rest`) for the law fits: (data, traj, err, fc,
    rest) with rest = {"rows", "stretches" [[t0, t1], …], "text"}, or the inputs and None when nothing rests (or
    too little would be left to fit)."""
    from nnphd.user.rest import REST_TOL_SIGMA, rest_mask, without_rest

    pc = info["per_coordinate"]
    margin = max((max(pc[c]["qdd"].get("windows") or [0]) for c in coords), default=0) // 2 if margin else 0
    every = info.get("thinned", {}).get("every", 1)  # the q̈ windows count the rows before a dense record's thinning
    margin = -(-margin // every)
    rest = rest_mask(
        data.q,
        data.t,
        traj,
        [pc[c]["noise"] for c in coords],
        [pc[c].get("quantization_step", 0.0) for c in coords],
        period,
        margin,
    )
    if not rest.any():
        return data, traj, err, fc, None
    d, tr, keep, extra = without_rest(data, traj, rest, {"err": err, "fc": fc})
    if keep.sum() < max(MIN_ROWS, 0.2 * len(keep)):
        return data, traj, err, fc, None
    idx = np.flatnonzero(rest)
    traj = np.asarray(traj)
    runs = np.split(idx, np.flatnonzero((np.diff(idx) != 1) | (np.diff(traj[idx]) != 0)) + 1)
    stretches = [[float(data.t[r[0]]), float(data.t[r[-1]])] for r in runs]
    text = ", ".join(f"t = {a:.4g}–{b:.4g}" for a, b in stretches[:4]) + (" …" if len(stretches) > 4 else "")
    spread = np.ptp(data.q, axis=0)
    tol = [max(REST_TOL_SIGMA * pc[c]["noise"] + 0.5 * pc[c].get("quantization_step", 0.0), 1e-12 * spread[j])
           for j, c in enumerate(coords)]  # fmt: skip
    last = {int(k): int(np.flatnonzero(traj == k)[-1]) for k in np.unique(traj)}
    # the rests that end their trajectory: where the body came to rest by itself (a rest before the release, or
    # one the body leaves again, was held or pushed from outside)
    where = [
        {
            "q": np.mean(data.q[r], axis=0).tolist(),
            "seconds": float(data.t[r[-1]] - data.t[r[0]]),
            "tolerance": tol,
            "t0": float(data.t[r[0]]),
            "traj": int(traj[r[0]]),
        }
        for r in runs
        if r[-1] == last[int(traj[r[-1]])]
    ]
    info = {"rows": int((~keep).sum()), "stretches": stretches, "text": text, "final": where}
    return d, tr, extra["err"], extra["fc"], info
