"""The law search: which candidate law of the non-conservative force the record supports, ranked beside a
conservative base — the learned Lagrangian's f_c, the seed-free conservative library, or a declared uniform field.

:func:`decide_law` is the entry (``nnphd detect`` calls it once, with the trained model's f_c): :func:`find_law`
ranks the candidates on one base (pointwise joint fits to the estimated q̈, then multiple shooting on the positions,
then what rests, stops and the amplitude envelope say), the bases are combined
(:func:`nnphd.explain.table.combine_bases`), a tie is re-judged over the whole record
(:func:`nnphd.explain.wholerecord.break_tie`), and the winner's force is described (its share against the velocity,
per trajectory, as a function of position and of the state, whether it is passive). The result is a
:class:`LawDecision`; the verdict's rules (:mod:`nnphd.user.rules`) decide whether its law is claimed.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from contextlib import nullcontext
from dataclasses import dataclass, replace

import numpy as np

from nnphd.explain.law import TableStatus
from nnphd.io.limits import MIN_ROWS
from nnphd.io.progress import Progress, Stages
from nnphd.io.timing import StageTimer

__all__ = ["DECLARED_FIELDS", "LIBRARY_BASE", "LawDecision", "LawRun", "decide_law", "find_law", "moving_rows"]

# the declared fields: no force of position beyond a constant one. Knowing gravity's direction is one parameter fewer,
# and along a 1.2-s arc that parameter matters: a sideways constant force lets linear drag stand in for quadratic
# (on the 2-D throw look-alike, seed 0, a whole-trajectory fit of linear drag is Δχ² 1.9 *better* than quadratic
# with the field's direction free and 8.6 worse with it vertical; seeds 1, 2: −5.2 / 6.5, −10.3 / 23.0)
DECLARED_FIELDS = ("uniform", "vertical")
LIBRARY_BASE = "the conservative library"  # the law table's seed-free conservative base
LIBRARY_WAIT = "law table: library base, waited for"


@dataclass(frozen=True)
class LawRun:
    """What the law search needs beside the data set: the trajectory id per row, the coordinates and which are
    angles, the derivative stage's info and per-row errors (:class:`nnphd.user.derivatives.DerivedData`), your own
    ``laws``, the ranking ``level`` ("auto", "pointwise", "trajectory"), the ``seed``, the conservative ``field``
    ("learned" or one of :data:`DECLARED_FIELDS`), the ``families`` to rank (None: all), and the run's ``timer`` and
    ``progress``."""

    traj: np.ndarray
    coords: tuple
    is_angle: tuple
    info: dict
    row_err: dict | None = None
    laws: Sequence[str] = ()
    level: str = "auto"
    seed: int = 0
    field: str = "learned"
    families: Sequence[str] | None = None
    timer: StageTimer | None = None
    progress: Progress | None = None


@dataclass(frozen=True, eq=False)
class LawDecision:
    """What the law search found: ``entry``, the law table as report.json writes it (its law, status, candidates,
    reason, settings, the envelope, the winner's share against the velocity, per trajectory, as a function of
    position and of the state, its passivity), ``law``, the winning Candidate (None when no candidate beats zero),
    and ``declared``: a declared uniform field as fitted alone and with the law ({"alone", "with_law",
    "against_velocity"}; empty without a declared field)."""

    entry: dict
    law: object | None
    declared: dict


def decide_law(data, run: LawRun, base: tuple | None, arcs: bool, library=None, noise: dict | None = None):
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
    ``base``: (f_c on the rows, f_c as a JAX function) of the trained model, None when there is none to use (no
    finite f_c, or a declared field); ``arcs``: the record does not oscillate; ``library``: the library base's table
    started alongside the training ((future, cancel) of :func:`nnphd.parallel.alongside`), None: fitted here;
    ``noise``: the position noise of a declared field's fits (the report's ``noise``). Returns a
    :class:`LawDecision`."""
    from nnphd.explain.table import combine_bases
    from nnphd.explain.wholerecord import break_tie, passivity
    from nnphd.explain.work import against_velocity, position_explained, work_per_trajectory

    coords, level, timer = list(run.coords), run.level, run.timer
    timed = timer.stage if timer is not None else (lambda _name: nullcontext())
    fc, fc_fn = base if base is not None else (None, None)
    table = find_law(data, run, fc, fc_fn)
    if base is not None and (len(coords) == 1 or arcs) and level != "pointwise":
        if library is not None:  # started beside the training
            with timed(LIBRARY_WAIT):
                lib = library[0].result()
        else:
            lib = find_law(data, replace(run, field="learned"))
        if len(coords) == 1 or lib.settings.get("library") == "minimal":  # (the law stage's own period decides)
            table = combine_bases([(LIBRARY_BASE, lib), (f"seed {run.seed}'s LNN", table)])
    else:
        lib = table  # the library itself is the base (a declared field, no finite f_c) — or there is none
    if table.status == TableStatus.TIE and level != "pointwise":  # can the whole record tell them apart?
        with timed(WHOLE_RECORD):
            table = break_tie(table, lib)
    out = table.to_dict()
    with timed(ENVELOPE_PICTURE):
        out["envelope"] = _envelope(table, data, run.traj, coords, run.info, bool(run.is_angle[0]))
    declared = {}
    if run.field in DECLARED_FIELDS:
        out["noise"] = noise
        zero = next((r for r in table.rows if r.key == "none"), None)
        declared = {k: fitted_field(table, r, coords, run.is_angle, data.q) for k, r in
                    (("alone", zero), ("with_law", table.law))}  # fmt: skip
    if table.law is not None:  # the law's share against the velocity: a drag's is 1, a thrust's −1
        f_law = table.law.predict(data.q, data.qd, data.t)
        out["against_velocity"] = against_velocity(f_law, data.qd)
        out["work_per_trajectory"] = work_per_trajectory(f_law, data.qd, run.traj)
        period = table.settings.get("period", np.nan)
        out["by_position"] = position_explained(f_law, data.q, data.t, run.traj, period)
        out["by_state"] = position_explained(f_law, np.hstack([data.q, data.qd]), data.t, run.traj, period)
        with timed(PASSIVITY):
            out["passivity"] = passivity(table, lib, data.q, data.qd, data.t)
        if run.field in DECLARED_FIELDS:  # a drag opposes the velocity (:data:`nnphd.user.rules.DRAG_ALONG_MIN`)
            declared["against_velocity"] = out["against_velocity"]
    return LawDecision(out, table.law, declared)


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
    from nnphd.explain.trajectory import Motion

    if len(coords) != 1:
        return None
    lead = [r for r in table.rows if r.family is not None and r.significant]
    return envelope_report(
        lead,
        Motion(data.q, data.qd, data.t, traj),
        info["per_coordinate"][coords[0]]["noise"],
        table.settings.get("period", float("nan")),
        angle=angle,
    )


def find_law(data, run: LawRun, fc=None, fc_fn=None, cancel=None):
    """Rank the candidate laws (:mod:`nnphd.explain.laws`) on a data set from :func:`nnphd.user.derivatives.derive`
    (``run``: its trajectory ids, coordinates, info and per-row errors, the laws, level, seed, field, families, timer
    and progress): pointwise joint fits to the estimated q̈ (weighted by the per-row q̈ errors), then — unless
    ``run.level`` is "pointwise" — re-ranked at trajectory level by multiple shooting on the positions when the data
    oscillate. ``fc``/``fc_fn``: a conservative force to use as the base (on the rows / as a JAX function); without
    it the conservative library alone — the uniform field alone when ``run.field`` is declared (nothing
    oscillates). ``run.timer``: the stages are timed on it (law table: pointwise fits, trajectory-level fits, rests,
    stops and envelope). ``run.families``: the candidate families to rank (:func:`nnphd.explain.laws.rank_laws`'
    ``include``; None: all); your ``run.laws`` are always ranked. ``cancel`` (a threading.Event): once set, the next
    stage is not begun (CancelledError). Returns a LawTable."""
    from concurrent.futures import CancelledError

    timed = run.timer.stage if run.timer is not None else (lambda _name: nullcontext())
    say = Stages(run.progress, 2)
    coords, level = list(run.coords), run.level

    def go_on() -> None:
        if cancel is not None and cancel.is_set():
            raise CancelledError("the law table was no longer wanted")

    say("candidate laws (pointwise joint fits)")
    given = data
    with timed("law table: pointwise fits"):
        table, moving, rests, period = _pointwise_table(data, run, fc)
    pointwise = table
    if level != "pointwise":
        go_on()
        say("candidate laws (trajectory level: multiple shooting on the positions)")
        with timed("law table: trajectory-level fits"):
            table = _trajectory_table(table, moving, run, period, (fc, fc_fn))
    go_on()
    with timed("law table: rests, stops and envelope"):
        table = _evidence_of_rests(table, moving, run, period, rests, (fc, fc_fn))
    if fc is None and level != "pointwise" and len(coords) == 1 and np.isfinite(period):
        from nnphd.explain.trajectory import Motion
        from nnphd.explain.wholerecord import context

        sigma = [run.info["per_coordinate"][c]["noise"] for c in coords]
        data, traj = moving
        rows = _thinned(data.t, traj, period)  # what a tie's whole-record fits need (nnphd.explain.wholerecord)

        def refit(library):  # the pointwise table beside another conservative library
            return _pointwise_table(given, run, None, library=library)[0]

        thinned = Motion(data.q, data.qd, data.t, traj).take(rows)
        table = replace(table, whole_record=context(pointwise, thinned, sigma, period, list(run.is_angle), run.seed,
                                                    refit))  # fmt: skip
    return table


def _pointwise_table(data, run: LawRun, fc, library=None):
    """find_law's pointwise stage on the data set as given (trajectory ids ``run.traj``): (the table, (the moving
    rows' data, their trajectory ids), (the rest found, the whole data and ids), the period). ``library``: the
    conservative library (None: :func:`_library`'s choice)."""
    from nnphd.engine.evidence import dominant_period
    from nnphd.explain.jointfit import trajectory_segments
    from nnphd.explain.laws import CandidateSet, ConservativeBase, PointwiseSettings, rank_laws

    traj, coords, info, field = run.traj, list(run.coords), run.info, run.field
    err = None if run.row_err is None else run.row_err["qdd_err"]
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
    table = rank_laws(
        data_p,
        traj_p,
        names=coords,
        angles=list(run.is_angle),
        qdd_err=err,
        base=ConservativeBase(fc, _library(moving.t, traj_m, period, run.level) if library is None else library),
        candidates=CandidateSet(include=run.families, user_laws=run.laws),
        settings=PointwiseSettings(seed=run.seed),
    )
    return table, (moving, traj_m), (rest, whole), period


def _trajectory_table(table, moving, run: LawRun, period, base):
    """find_law's trajectory-level stage: the table re-ranked by multiple shooting on the positions of the moving
    rows (``moving`` = (data, trajectory ids)) beside ``base`` = (f_c, f_c as a JAX function) or (None, None)."""
    data, traj = moving
    coords, (fc, fc_fn) = list(run.coords), base
    from nnphd.explain.jointfit import trajectory_segments
    from nnphd.explain.trajectory import Motion, TrajectorySettings, WindowPlan, rank_trajectory

    sigma = [run.info["per_coordinate"][c]["noise"] for c in coords]
    rows = _thinned(data.t, traj, period)
    return rank_trajectory(
        table,
        Motion(data.q, data.qd, data.t, traj).take(rows),
        sigma=sigma,
        # no oscillation (a throw, a fall): each trajectory one window, ranked in-sample
        period=period if np.isfinite(period) else float(max(np.ptp(data.t[s]) for s in trajectory_segments(traj))),
        angles=list(run.is_angle),
        fc_fn=fc_fn if fc is not None else None,
        windows=(
            WindowPlan(window_periods=SHORT_RECORDS, allow_in_sample=True)
            if len(coords) == 1 or not np.isfinite(period)
            else WindowPlan()
        ),
        # the funnel where the windows alone rank; on one coordinate the amplitude envelope adds its evidence after
        # (nnphd.explain.envelope) and can reorder families far apart in the windows' IC: every one is fitted
        settings=TrajectorySettings(seed=run.seed, reach=None if len(coords) > 1 else math.inf),
    )


def _evidence_of_rests(table, moving, run: LawRun, period, rests, base):
    """find_law's last stage: what a rest, a stop and the amplitude envelope say about the candidates (one
    coordinate), and the rest left out said in the table's reason. ``moving``: (data, trajectory ids) of the moving
    rows; ``rests``: (the rest found, (the whole data, its ids)); ``base``: (f_c, its JAX function) or (None, None)."""
    (data, traj), (rest, whole), (fc, fc_fn) = moving, rests, base
    coords, is_angle, info, level, seed = list(run.coords), list(run.is_angle), run.info, run.level, run.seed
    fc_fn = fc_fn if fc is not None else None
    stuck = {}
    if level != "pointwise" and rest is not None and len(coords) == 1 and np.isfinite(period):
        from nnphd.explain.rest import REST_WINDOW_PERIODS
        from nnphd.explain.stuck import StopSettings, stop_contradictions, stuck_contradictions
        from nnphd.explain.trajectory import Motion

        stuck = stuck_contradictions(table, rest["final"], angles=is_angle, fc_fn=fc_fn)
        stop = stop_contradictions(
            table,
            rest["final"],
            Motion(whole[0].q, whole[0].qd, whole[0].t, whole[1]),
            period,
            angles=is_angle,
            fc_fn=fc_fn,
            stop=StopSettings(seed=seed, window_periods=REST_WINDOW_PERIODS),
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
SHORT_RECORDS = (0.75,)  # the window lengths (periods) of such records, ranked in-sample where too few


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
    wins = shooting_windows(trajectory_segments(traj), t, period, periods=min(SHORT_RECORDS))
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
    """The data set without its stretches at rest (:mod:`nnphd.explain.rest`) for the law fits: (data, traj, err, fc,
    rest) with rest = {"rows", "stretches" [[t0, t1], …], "text"}, or the inputs and None when nothing rests (or
    too little would be left to fit)."""
    from nnphd.explain.rest import REST_TOL_SIGMA, rest_mask, without_rest

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
