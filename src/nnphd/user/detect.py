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
from pathlib import Path

import numpy as np

from nnphd._config import release_compiled_if_crowded
from nnphd.explain.search import DECLARED_FIELDS, LawRun, decide_law, field_force, find_law
from nnphd.io.errors import DataError
from nnphd.io.limits import MIN_ROWS
from nnphd.io.progress import Progress
from nnphd.io.timing import StageTimer
from nnphd.parallel import runs_in_this_process
from nnphd.user.report import write_report
from nnphd.user.result import DetectResult, FittedModel
from nnphd.user.rules import (
    RECONCILED_BASIS,
    declared_field_decides,
    declared_field_effect,
    reconcile,
    unclaim_active,
    unclaim_against_evidence,
    unclaim_unidentifiable,
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
    return detect_data(ud, out, progress=progress, read_s=time.perf_counter() - t0, **settings)[0].report


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


def _check_settings(ud, laws: Sequence[str], law_fit: str, field: str, families=None, method="auto") -> None:
    """Refuse bad settings before any work: the law level, the field, the law families (keys and Family objects)
    and the derivative method (a name, a DerivativeEstimator or a Derivatives), and every ``laws`` entry (a --law)
    parsed on the file's coordinates."""
    from nnphd.explain.families import parse_law
    from nnphd.user.derivatives import Derivatives
    from nnphd.user.strategies import check_families

    _check_law_fit(law_fit)
    check_field(field, law_fit)
    check_families(families or ())
    if not isinstance(method, Derivatives):
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


def _assessed(data, traj, ud, info, training, seed, steps, n_seeds, workers, scheduler, assess_kw: dict):
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


def _declared_forces(law: dict, declared: dict, data, ud, fc, fn):
    """The declared uniform field as the law table fitted it (``declared``: {"alone", "with_law"[,
    "against_velocity"]}, empty without a declared field): (the field fitted — with the law when one is claimed,
    else alone — or None, f_c, f_n); f_c and f_n as given without a declared field."""
    fitted = declared.get("with_law" if law.get("law") else "alone")
    if fitted is not None:  # the declared field is the conservative force; f_n the remainder of q̈ beside it
        fc = field_force(fitted, data.q, ud.is_angle)
        fn = np.asarray(data.qdd, float) - fc
    return fitted, fc, fn


def _field_entry(field: str, fitted: dict | None, declared: dict) -> dict:
    """The report's ``field``: the conservative force declared, and a uniform field as fitted (its law, g and
    standard error per coordinate; whether the law's force opposes the velocity)."""
    return (
        {"kind": field, "text": FIELDS[field]}
        | ({k: fitted[k] for k in ("law", "g", "stderr")} if fitted else {})
        | ({"against_velocity": declared["against_velocity"]} if "against_velocity" in declared else {})
    )


def _report(ud, res: dict, info: dict, law: dict, verdict, field: dict, blind: dict, settings: dict) -> dict:
    """The report of :func:`detect_data` (without its timings): ``res``: the assessment's report; ``verdict`` =
    (status, new_physics, confidence, reasons, effect) of :func:`nnphd.user.rules.reconcile` and the effect beside a
    declared field (None: the assessment's); ``field``: :func:`_field_entry`'s; ``settings``: the run's own, to
    which assess's are added."""
    from nnphd.user.recording import suggest_angles

    status, new_physics, confidence, reasons, effect = verdict
    coords = list(ud.coords)
    return {
        "file": str(ud.path),
        "new_physics": new_physics,
        "status": status,
        "statistic": res["statistic"],
        "effect": effect or res["effect"],
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
    derivative_method="auto",
    families: Sequence[str] | None = None,
    thin: bool = True,
    **assess_kw,
) -> tuple[DetectResult, FittedModel]:
    """:func:`detect_file` on validated data (:class:`nnphd.user.recording.UserData`); returns (the result — its
    ``report`` is report.json —, the fitted pieces that :class:`nnphd.NNPhD` keeps). ``field``: the conservative
    force, a key of FIELDS ("uniform": the verdict and the law rest on a fit of the positions beside a uniform field,
    :func:`declared_field_verdict`; the record must not oscillate). ``read_s``: the seconds reading the file took
    (for the report's ``timings``: wall and JAX-compile seconds per stage, :class:`nnphd.io.timing.StageTimer`).
    ``derivative_method``: how q̇, q̈ are estimated (a name of :data:`nnphd.user.derivatives.METHODS`, a
    DerivativeEstimator, or a :class:`nnphd.user.derivatives.Derivatives` with its own trim); ``families``: the
    candidate law families ranked (keys and Family objects; None: all, :data:`nnphd.user.strategies.FAMILIES`) — the
    report's settings name them only when they are not the defaults; ``thin``: a dense record of more than THIN_ROWS rows is thinned after
    its derivatives are estimated (:func:`dense_thinned`; False: every row is used)."""
    from nnphd.user.derivatives import derivative_name
    from nnphd.user.strategies import family_filter, family_names

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
                assessed = _assessed(data, traj, ud, info, say.training, seed, steps, n_seeds, workers, scheduler,
                                     assess_kw)  # fmt: skip
            res, fn, fc = assessed.report, np.asarray(assessed.f_n), np.asarray(assessed.f_c)
            figures = _figures_alongside(out, res, data, traj, coords, fc, fn, field, timer)
            run = LawRun(traj, tuple(coords), tuple(bool(a) for a in ud.is_angle), info, row_err, laws, law_fit, seed,
                         field, families, timer, lambda d, t, m: say(m))  # fmt: skip
            law, law_row, declared = _law_decision(assessed, data, run, library)
        finally:  # not needed (no law is fitted), or an error or an interrupt here: it stops at its next stage
            if library is not None:
                library[1].set()
        effect = declared_field_effect(law) if declared_field_decides(res, field) else None
        status, new_physics, confidence, reasons = reconcile(res, law, field)
        unclaim_against_evidence(res, law)
        unclaim_active(res, law)
        unclaim_unidentifiable(law)
        fitted, fc, fn = _declared_forces(law, declared, data, ud, fc, fn)
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
            **({"derivative_method": name} if (name := derivative_name(derivative_method)) != "auto" else {}),
            **({"families": family_names(families)} if families is not None else {}),
            **({"thin": False} if not thin else {}),
            **assess_kw,
        }
        verdict = (status, new_physics, confidence, reasons, effect)
        report = _report(ud, res, info, law, verdict, _field_entry(field, fitted, declared), blind, settings)

        def stamp() -> None:  # the times so far: every stage but the writing of report.json/html itself
            report["timings"] = with_workers(timer.to_dict(), list(assessed.timings_per_seed))
            report["wall_time_s"] = report["timings"]["total_s"]

        if out is not None:
            write_report(out, report, data, traj, coords, fc, fn, timer=timer, before_writing=stamp, made=figures)
        else:
            stamp()
    angles = tuple(bool(a) for a in ud.is_angle)
    law_row = law_row if law.get("law") else None
    model = FittedModel(assessed.conservative, law_row, data, traj, tuple(coords), angles, fc, fn, fitted)
    return DetectResult.from_dict(report), model


LIBRARY_ALONGSIDE = "law table: library base (alongside training)"


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


def prepared_data(ud, trim, method="auto"):
    """(data set, info, trim used, per-row errors, trajectory id per row) of validated data, the derivatives by
    ``method`` (a Derivatives, a name or a DerivativeEstimator: :func:`_dataset`); a trim that leaves too few rows
    of a trajectory is refused."""
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


def _dataset(ud, trim, method="auto"):
    """to_dataset with the ends trimmed (``trim="auto"``: drop the half-window at each end of every trajectory,
    where the one-sided derivative estimates are ~20x worse, unless that would leave a trajectory with less than
    TRIM_KEEP_MIN of its rows: :meth:`nnphd.user.derivatives.Derivatives.dataset`), the derivatives by ``method``:
    a :class:`nnphd.user.derivatives.Derivatives` (its own ``dataset``, trim and estimator: ``trim`` is not used), or
    a name of :data:`nnphd.user.derivatives.METHODS` or a DerivativeEstimator (with ``trim``). Returns
    :class:`nnphd.user.derivatives.DerivedData`."""
    from nnphd.user.derivatives import Derivatives

    if isinstance(method, Derivatives):
        return method.dataset(ud)
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


def _law_decision(assessed, data, run: LawRun, library):
    """The law search (:func:`nnphd.explain.search.decide_law`) beside the trained model's f_c — unless no model was
    trained (the data cannot decide: no law is fitted) or its f_c is not finite: (the law table as a dict, the
    winning Candidate or None, the declared field as fitted)."""
    from nnphd.user.assess import conservative_fn

    cons, quality = assessed.conservative, assessed.report["quality"]
    if cons is None:
        why = "no law fitted: " + (quality.get("reason") or "the data cannot decide")
        return {"law": None, "reason": why, "candidates": []}, None, {}
    fc = np.asarray(cons.fc)
    base = (fc, conservative_fn(cons)) if bool(np.all(np.isfinite(fc))) and run.field == "learned" else None
    noise = arc_noise(data, run.traj, list(run.coords), run.info) if run.field in DECLARED_FIELDS else None
    arcs = not quality.get("oscillating", True)  # a throw, a fall: the library is the uniform field alone
    found = decide_law(data, run, base, arcs, library, noise)
    return found.entry, found.law, found.declared


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
