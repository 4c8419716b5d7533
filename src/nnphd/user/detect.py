"""``nnphd detect FILE``: new-physics detection on the user's own trajectories.

Pipeline: :func:`nnphd.user.recording.load_trajectories` (validation, one-line errors) → :func:`nnphd.user.derivatives.to_dataset`
(q̇, q̈ per trajectory with a noise estimate) → :func:`nnphd.user.assess.assess` (standardised units, λ-sweep on held-out
trajectories, the checks that tell non-conservation from under-fitting, repeated seeds) → the blind explanation of
the learned non-conservative force in the file's own coordinate names → ``report.json``, ``report.html`` and the
figures in ``--out``. Every file is written atomically, and only after the whole analysis succeeded.
"""

from __future__ import annotations

import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from nnphd._config import release_compiled_if_crowded
from nnphd.explain.search import DECLARED_FIELDS, LawRun, decide_law, find_law
from nnphd.io.errors import DataError
from nnphd.io.limits import MIN_ROWS
from nnphd.io.progress import Progress
from nnphd.io.timing import StageTimer
from nnphd.user.assembly import declared_forces, field_entry, report_of, with_workers
from nnphd.user.derivatives import dense_thinned
from nnphd.user.report import write_report
from nnphd.user.result import DetectResult, FittedModel, Status
from nnphd.user.rules import (
    declared_field_decides,
    declared_field_effect,
    reconcile,
    unclaim_active,
    unclaim_against_evidence,
    unclaim_unidentifiable,
)
from nnphd.user.sampling import arc_noise
from nnphd.user.settings import DetectSettings, check_declared_field, check_field, check_law_fit, check_settings


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

    check_law_fit(settings.get("law_fit", "auto"))
    check_field(settings.get("field", "learned"), settings.get("law_fit", "auto"))
    if progress is not None:
        progress(0, 1, "reading the file")
    t0 = time.perf_counter()
    markers, fps = settings.pop("markers", None), settings.pop("fps", None)  # how the file is read
    ud = load_trajectories(path, angles, max_rows=max_rows, markers=markers, fps=fps)
    return detect_data(ud, out, progress=progress, read_s=time.perf_counter() - t0, **settings)[0].report


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


def _assessed(data, run: LawRun, s: DetectSettings, training):
    """:func:`nnphd.user.assess.assess` on the data set, with the file's angles and the position noise and q̈ errors
    of its derivative estimates; ``training``: the progress of the training rounds."""
    from nnphd.user.assess import AssessSettings, RecordFacts, assess

    pc = run.info["per_coordinate"]
    settings = AssessSettings(seed=s.seed, steps=s.steps, n_seeds=s.n_seeds, workers=s.workers, scheduler=s.scheduler,
                              **s.assess)  # fmt: skip
    record = RecordFacts(
        angles=list(run.is_angle),
        position_noise=[pc[c]["noise"] for c in run.coords],
        derivative_error=[pc[c]["qdd"]["relative_error"] for c in run.coords],
    )
    return assess(data, run.traj, settings, record, progress=training)


def detect_data(
    ud, out: str | Path | None = None, *, progress: Progress | None = None, read_s: float | None = None, **settings
) -> tuple[DetectResult, FittedModel]:
    """:func:`detect_file` on validated data (:class:`nnphd.user.recording.UserData`); returns (the result — its
    ``report`` is report.json —, the fitted pieces that :class:`nnphd.NNPhD` keeps). ``field``: the conservative
    force, a key of FIELDS ("uniform": the verdict and the law rest on a fit of the positions beside a uniform field,
    :func:`nnphd.user.rules.declared_field_verdict`; the record must not oscillate). ``read_s``: the seconds reading the file took
    (for the report's ``timings``: wall and JAX-compile seconds per stage, :class:`nnphd.io.timing.StageTimer`).
    ``settings``: the keywords of :class:`nnphd.user.settings.DetectSettings` (seed, steps, sr_time, n_seeds, trim,
    laws, law_fit, field, workers, scheduler, derivative_method, families, thin) and assess's own.
    ``derivative_method``: how q̇, q̈ are estimated (a name of :data:`nnphd.user.derivatives.METHODS`, a
    DerivativeEstimator, or a :class:`nnphd.user.derivatives.Derivatives` with its own trim); ``families``: the
    candidate law families ranked (keys and Family objects; None: all, :data:`nnphd.user.strategies.FAMILIES`) — the
    report's settings name them only when they are not the defaults; ``thin``: a dense record of more than THIN_ROWS
    rows is thinned after its derivatives are estimated (:func:`nnphd.user.derivatives.dense_thinned`; False: every
    row is used)."""
    from nnphd.user.strategies import family_filter

    s = DetectSettings.of(**settings)
    say = _Say(progress)
    check_settings(ud, s.laws, s.law_fit, s.field, s.families, s.derivative_method)
    families, field = family_filter(s.families), s.field
    release_compiled_if_crowded()  # a process fitting record after record must not run out of memory mappings
    timer = StageTimer()
    if read_s is not None:
        timer.add("reading the file", read_s)
    with timer:
        with timer.stage("derivatives"):
            data, info, trim, row_err, traj = prepared_data(ud, s.trim, s.derivative_method)
            check_declared_field(field, data, traj, ud, info)
            if s.thin:
                data, row_err, traj = dense_thinned(data, info, row_err, traj, ud)
        coords = list(ud.coords)
        run = LawRun(traj, tuple(coords), tuple(bool(a) for a in ud.is_angle), info, row_err, s.laws, s.law_fit, s.seed,
                     field, families, timer, lambda d, t, m: say(m))  # fmt: skip
        library = library_alongside(data, run)
        try:
            say("λ-sweep and trust checks")
            with timer.stage("training and trust checks"):
                assessed = _assessed(data, run, s, say.training)
            res, fn, fc = assessed.report, np.asarray(assessed.f_n), np.asarray(assessed.f_c)
            figures = _figures_alongside(out, res, data, run, (fc, fn))
            law, law_row, declared = _law_decision(assessed, data, run, library)
        finally:  # not needed (no law is fitted), or an error or an interrupt here: it stops at its next stage
            if library is not None:
                library[1].set()
        effect = declared_field_effect(law) if declared_field_decides(res, field) else None
        status, new_physics, confidence, reasons, law = reconcile(res, law, field)
        law = unclaim_against_evidence(res, law).law
        law = unclaim_active(res, law).law
        law = unclaim_unidentifiable(law).law
        fitted, fc, fn = declared_forces(law, declared, data, ud, fc, fn)
        blind = {}
        if status == Status.DETECTED and law.get("law") is None:  # fallback: no candidate family fits
            with timer.stage("blind formula"):
                blind = _blind(data, coords, fn, s.sr_time, s.seed, say, reasons)
        verdict = (status, new_physics, confidence, reasons, effect)
        entry = s.report_entry(trim, families)
        report = report_of(ud, res, info, law, verdict, field_entry(field, fitted, declared), blind, entry)

        def stamp() -> None:  # the times so far: every stage but the writing of report.json/html itself
            report["timings"] = with_workers(timer.to_dict(), list(assessed.timings_per_seed))
            report["wall_time_s"] = report["timings"]["total_s"]

        angles = tuple(bool(a) for a in ud.is_angle)
        law_row = law_row if law.get("law") else None
        model = FittedModel(assessed.conservative, law_row, data, traj, tuple(coords), angles, fc, fn, fitted)
        if out is not None:
            extra = {}
            if ud.markers is not None:
                from nnphd.user.report import plot_markers

                extra["markers.png"] = plot_markers(ud.markers)
            write_report(out, report, model, timer=timer, before_writing=stamp, made=figures, extra=extra)
        else:
            stamp()
    return DetectResult.from_dict(report), model


LIBRARY_ALONGSIDE = "law table: library base (alongside training)"


def library_alongside(data, run: LawRun):
    """The law table on the conservative library base (:func:`nnphd.explain.search.find_law`), started beside the training on a thread
    of its own — it needs no network — when it will be wanted: one coordinate, the learned field, a trajectory-level
    fit. (future, cancel) of :func:`nnphd.parallel.alongside`, or None: then it is fitted after the training, as
    before — also in a worker of a ``detect`` batch, which owns one core. The numbers are the same either way (the
    same programs on the same data); on 2 cores the cores the training leaves idle (tracing, Python) fit it."""
    import os

    from nnphd.parallel import alongside

    if run.field != "learned" or len(run.coords) != 1 or run.level == "pointwise" or os.environ.get("NNPHD_WORKER"):
        return None

    def library(cancel):
        with run.timer.alongside(LIBRARY_ALONGSIDE):
            return find_law(data, replace(run, timer=None, progress=None), cancel=cancel)

    return alongside(library)


FIGURES_ALONGSIDE = "figures (alongside the law table)"


def _figures_alongside(out, res, data, run: LawRun, forces):
    """The figures that need the training only (:func:`nnphd.user.report.training_figures`), made on a thread of
    their own while the law is fitted — the learned field, a report to write, not in a worker of a ``detect`` batch
    (which owns one core). A future of them, or None (then they are made with the others, as before)."""
    import os

    from nnphd.parallel import alongside
    from nnphd.user.report import training_figures

    if out is None or run.field != "learned" or os.environ.get("NNPHD_WORKER"):
        return None
    view = {k: res[k] for k in ("checks", "evidence", "table", "lambda_forces")} | {"field": {"kind": run.field}}
    fc, fn = forces

    def figures(cancel):  # noqa: ARG001 — nothing to stop early: a few seconds of drawing
        with run.timer.alongside(FIGURES_ALONGSIDE):
            return training_figures(view, data, run.traj, list(run.coords), fc, fn)

    return alongside(figures)[0]


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
    from nnphd.explain.symbolic import GeneticSearch, genetic_formula

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
            blind["genetic"] = genetic_formula(
                inputs, fn, comps, seed=seed, search=GeneticSearch(max_time=sr_time)
            ).to_hint_dict()
    except MissingExtra as e:  # the fallback is optional: say why it is missing
        reasons.append(f"no blind explanation: {e}")
    return blind


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
