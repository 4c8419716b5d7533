"""The verdict's rules after the seeds have spoken: how the law table, the declared field and the seed-free fits
of the positions change the status the seeds' checks gave (:func:`reconcile`), each rule with its threshold and the
record on which that threshold was measured.

The order in which :func:`reconcile` applies them:

1. **A declared uniform field** (``field="uniform"``) decides alone, from the fit of the positions beside it
   (:func:`declared_field_verdict`): "detected" when a law beats the field alone by ΔIC ≤ LAW_DETECT_DIC, lowers the
   error by ≥ LAW_EFFECT_MIN, fits to the noise (χ²/N ≤ FIELD_FIT_MSE) and opposes the velocity
   (≥ DRAG_ALONG_MIN of its force: a drag); "none" when the field alone fits and nothing beats it; else
   "inconclusive" with the reason.
2. **A detection that rests on the learned Lagrangian alone** — its energy trend, with the shooting probe pointing
   the other way and no strong candidate law — is "inconclusive" (:func:`trend_unsupported`).
3. **A drive** the law table claims, on trajectories whose clock can be told, is "detected" with the drive as the
   law (:func:`drive_evidence`: ΔIC ≤ LAW_CONFLICT_DIC, error −DRIVE_EFFECT_MIN or more).
4. **"none" against a strong law**: a candidate with ΔIC ≤ LAW_CONFLICT_DIC that lowers the held-out error by
   ≥ LAW_EFFECT_MIN makes a "none" "inconclusive" (confidence 0.5: the evidence is split) — when the record shows
   the law to be non-conservative (:func:`does_work`) and it is ≥ MIN_RELATIVE_SIZE of the force; "detected" where
   that law does no net work, is no function of position and every conservative base finds it
   (:func:`balanced_force_evidence`: a limit cycle).
5. **"inconclusive" from the learned energy alone**: seeds that are "inconclusive" only because their learned
   Lagrangian's energy swings slowly (one or two trajectories), on a record whose law table — a drive included —
   has no candidate that would contradict "none", give "none" (:func:`learned_power_unconfirmed`).
6. **"inconclusive" with every conservative base agreeing** (one coordinate: the seed-free library and the seed's
   LNN each find a law with ΔIC ≤ LAW_DETECT_DIC and error −LAW_DETECT_EFFECT or more) is "detected"
   (:func:`seed_free_evidence`).
7. Otherwise the seeds' status stands; a record that does not oscillate gets a hint of what would decide
   (:func:`uniform_field_hint`).

No law is claimed unless the final status is "detected" (:func:`withhold`), nor one that pumps energy into a record
that loses it unless a whole-record fit puts it ≥ PASSIVE_MARGIN_IC ahead of every passive family
(:func:`unclaim_active`), nor a law of the state that does no net work and is a function of position along the record
(:func:`unclaim_unidentifiable`), nor a law whose force works against the record-level evidence: one that adds energy (≤ −LAW_AGAINST_EVIDENCE of its force against the velocity) where
the record loses it, or takes it where the record gains it, is only a candidate
(:func:`unclaim_against_evidence`; measured on the camera look-alike of a damped chaotic double pendulum, seed 1: a
power law with k = −3.1e-15, m = 6.35, a thrust at the fastest rows, on a record losing energy at z = 7.4).
Before them, the seeds' own statuses (:func:`nnphd.user.checks.seed_status`) are combined by :func:`combine_seeds`: their common status; where they
differ, a seed whose conservative model failed to fit (an optimisation failure another seed shows the data do not
cause) is discounted, and the others decide if they agree; else "inconclusive" — and "inconclusive" too where seeds
detect with opposite signs of the energy change (:func:`opposite_signs`). The paper's phase-transition rule
is :mod:`nnphd.engine.verdict`.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from nnphd.engine.verdict import MIN_RELATIVE_SIZE
from nnphd.explain.law import TableStatus
from nnphd.explain.search import LIBRARY_BASE
from nnphd.user.checks import Z_BOTH, Z_CONTRA
from nnphd.user.result import Status

LAW_CONFLICT_DIC = -10.0  # a candidate law this much better than none (held out) contradicts a verdict of "none"
# ... and only when it lowers the held-out error by at least this much: a sparse polynomial that lowered a gyroscopic
# record's error by 0.4 % (ΔIC −19: significant on 10⁴ rows, immaterial) made both seeds' "none" "inconclusive"
LAW_EFFECT_MIN = 0.01


# a seed's "inconclusive" is discounted as an optimisation failure when its conservative model's training error is
# at least this multiple of another seed's, whose model fits as well as a free one (gap < GAP_MIN): a Lagrangian of
# the same data does fit, so the under-fit says nothing about the data. Measured (benchmarks/seed_robustness.py,
# the conservative eccentric Kepler case of 8 noisy trajectories): internal seed 2's LNN reached a training error
# of 0.295 (×2.4 the free model's 0.122) where seed 1's reached 0.070 (×0.58 the free model's), and seed 3's fit
# like seed 1's — runs with seeds 1 and 2 said "inconclusive (seeds disagree)" on a conservative record.
UNDERFIT_RATIO = 2.0


def underfit_against(seed: dict, seeds: list[dict]) -> str | None:
    """Why ``seed``'s "inconclusive" is an optimisation failure (see UNDERFIT_RATIO), or None: its status is
    "inconclusive", its conservative model under-fits (training error ≥ GAP_MIN × the free model's), its own
    record-level evidence is below Z_BOTH (it holds no evidence of its own), and another seed's conservative model
    reaches ≤ 1/UNDERFIT_RATIO of its training error while fitting as well as a free model."""
    gap = seed.get("gap") or {}
    traj = seed.get("trajectory_evidence") or {}
    if seed["status"] != Status.INCONCLUSIVE or not gap.get("large"):
        return None
    if any(z is not None and abs(z) >= Z_BOTH for z in (traj.get("z_energy"), traj.get("z_shooting"))):
        return None
    mine = gap.get("conservative_train")
    fits = [
        s for s in seeds
        if s is not seed and not (s.get("gap") or {}).get("large", True)
        and mine is not None and (s["gap"].get("conservative_train") or math.inf) * UNDERFIT_RATIO <= mine
    ]  # fmt: skip
    if not fits:
        return None
    best = min(fits, key=lambda s: s["gap"]["conservative_train"])
    return (
        f"seed {seed['seed']} is discounted: its conservative model's training error ({mine:.3g}, x"
        f"{gap['gap_train']:.1f} the free model's) is x{mine / best['gap']['conservative_train']:.1f} seed "
        f"{best['seed']}'s ({best['gap']['conservative_train']:.3g}, x{best['gap']['gap_train']:.2f} the free "
        f"model's): a Lagrangian of these data does fit, so its under-fit is an optimisation failure, not evidence"
    )


def corroborates(seed: dict, detecting: dict) -> str | None:
    """Why ``seed``'s "inconclusive" backs ``detecting``'s record-level detection rather than contradicting it, or
    None: the detection rests on the record-level evidence (energy trend, shooting probe), and ``seed``'s own
    statistics point the same way — one at |z| ≥ Z_BOTH of the detection's sign, none at |z| ≥ Z_CONTRA of the other
    sign (weaker evidence of the same loss, "too strong for a none"). Measured: a camera look-alike of a damped chaotic
    double pendulum (two 10-s takes): seed 0's learned energy decayed at z = 4.6 (probe z = −1.2), "inconclusive";
    seed 1's at z = 7.4 (probe 0.7), "detected" — the same loss seen more or less sharply, not two verdicts."""
    det = detecting.get("trajectory_evidence") or {}
    mine = seed.get("trajectory_evidence") or {}
    if seed["status"] != Status.INCONCLUSIVE or detecting["status"] != Status.DETECTED or not det.get("significant"):
        return None
    sign = {"loses energy": 1.0, "gains energy": -1.0}.get(det.get("direction"))
    zs = [z for z in (mine.get("z_energy"), mine.get("z_shooting")) if z is not None]
    if sign is None or not any(sign * z >= Z_BOTH for z in zs) or any(sign * z <= -Z_CONTRA for z in zs):
        return None
    shown = ", ".join(f"{k} z = {mine[k2]:.1f}" for k, k2 in (("energy trend", "z_energy"), ("shooting probe",
                      "z_shooting")) if mine.get(k2) is not None)  # fmt: skip
    return (
        f'seed {seed["seed"]}\'s "inconclusive" is weaker evidence of the same {"loss" if sign > 0 else "gain"} '
        f"of energy ({shown}), not a contradiction: seed {detecting['seed']}'s detection stands"
    )


def combine_seeds(seeds: list[dict]) -> tuple[Status, bool, float, list[str]]:
    """(status, new_physics, confidence, reasons) from the seeds' own statuses.

    - All seeds agree: their status. ``confidence`` = mean over seeds of the share of bootstrap replicas of the
      seed's evidence that give its call.
    - They differ: seeds whose "inconclusive" is an optimisation failure (:func:`underfit_against`) are set aside,
      and "inconclusive" seeds whose own evidence backs another seed's record-level detection
      (:func:`corroborates`) count with it; if what is left agrees, it decides, and the reasons say which seed was
      set aside or counted and why.
      ``confidence`` = mean over *all* seeds of [agrees] × bootstrap share (a discounted seed counts against it).
    - Otherwise "inconclusive" ("seeds disagree": well-fitted models disagree), confidence the larger share of
      seeds on one side of detected / not detected; ``new_physics`` (best call) the majority.
    """
    statuses = [s["status"] for s in seeds]
    per_seed = [f"seed {s['seed']}: {s['reason']}" for s in seeds]
    status, notes = (statuses[0], []) if len(set(statuses)) == 1 else _settle(seeds)
    det = float(np.mean([s["status"] == Status.DETECTED for s in seeds]))
    opposite = opposite_signs(seeds) if status == Status.DETECTED else None
    if opposite is not None:
        return Status.INCONCLUSIVE, False, 1.0 - det if det < 1 else 0.5, [opposite, *per_seed]
    if status is None:
        disagree = f"seeds disagree ({', '.join(statuses)})"
        return Status.INCONCLUSIVE, det > 0.5, max(det, 1 - det), [disagree, *per_seed]
    conf = float(np.mean([(s["status"] == status) * s["agreement"] for s in seeds]))
    new = {Status.DETECTED: True, Status.NONE: False}.get(status, det > 0.5)
    return Status(status), new, conf, notes + per_seed


def opposite_signs(seeds: list[dict]) -> str | None:
    """Why the seeds' record-level detections contradict each other, or None: one seed's record loses energy and
    another's gains it (the direction of :func:`nnphd.user.checks.trajectory_evidence`). Two learned Lagrangians whose
    energies trend in opposite directions measure their own approximation errors, not the record: measured on a day
    of a laser-ranging satellite's orbit (J2 only, conservative), seed 0's learned energy decayed 0.023 %/period at
    z = 428 and seed 1's grew 0.0064 %/period at z = −68 — counted as two seeds agreeing on "detected" before."""
    dirs = {}
    for s in seeds:
        te = s.get("trajectory_evidence") or {}
        if (
            s["status"] == Status.DETECTED
            and te.get("significant")
            and te.get("direction") in ("loses energy", "gains energy")
        ):
            dirs.setdefault(te["direction"], []).append(s["seed"])
    if len(dirs) < 2:
        return None
    said = "; ".join(
        f"seed{'s' if len(v) > 1 else ''} {', '.join(map(str, v))}: the record {k}" for k, v in dirs.items()
    )
    return (
        f"seeds disagree on the sign of the energy change ({said}): the learned Lagrangians' trends measure their own "
        "approximation errors, not the record"
    )


def _settle(seeds: list[dict]) -> tuple[Status | None, list[str]]:
    """(the status, why) when the seeds' differing statuses settle — under-fitted seeds set aside
    (:func:`underfit_against`), "inconclusive" seeds that back a detection (:func:`corroborates`) — else (None, [])."""
    notes = [(s, why) for s in seeds if (why := underfit_against(s, seeds))]
    kept = [s for s in seeds if all(s is not d for d, _ in notes)]
    left = {s["status"] for s in kept}
    if left == {Status.DETECTED, Status.INCONCLUSIVE} and (backing := _corroborated(kept)):
        notes, left = notes + backing, {Status.DETECTED}
    if notes and len(left) == 1:
        return left.pop(), [why for _, why in notes]
    return None, []


def _corroborated(kept: list[dict]) -> list[tuple[dict, str]] | None:
    """[(seed, why)] when every "inconclusive" seed of ``kept`` backs a detecting seed (:func:`corroborates`), else
    None."""
    detecting = [s for s in kept if s["status"] == Status.DETECTED]
    out = []
    for s in (s for s in kept if s["status"] == Status.INCONCLUSIVE):
        why = next((w for d in detecting if (w := corroborates(s, d))), None)
        if why is None:
            return None
        out.append((s, why))
    return out


# a candidate law that depends on the state alone contradicts "none" only when it does net work along the record:
# |share of its force against the velocity| (:func:`nnphd.explain.work.against_velocity`) at least this (a drag: 1, a pump: −1, a force
# across the motion: 0). On one orbit the states lie on a closed curve, where a force odd in q̇ can stand in for a
# correction of the learned potential: measured on DE405 orbits (Mercury, Venus, Jupiter, one trajectory each),
# a sparse polynomial odd in q̇ lowered the LNN's held-out error by 76–95 % (ΔIC −68 … −3246) on records the
# checks called "none" — the LNN's approximation error, not a force the record shows (the energy does not change)
LAW_WORK_MIN = 0.5
TIME_KEYS = ("drive", "perturber")  # families of explicit time: they need no net work (a drive's power averages out)


POSITION_MAX = 0.5  # ... or when less than this share of its force is a function of position along the record
STATE_MIN = 0.5  # ... and a law of the state only when at least this share of its force recurs at the same states


def does_work(
    cand: dict,
    share: float | None,
    by_position: float | None = None,
    by_state: float | None = None,
    per_trajectory: float | None = None,
) -> bool:
    """Is this candidate law's force shown to be non-conservative by the record? A law of explicit time (a drive, a
    perturber) always; a law of the state when its force is a reproducible function of the state over the record's
    passes (:func:`nnphd.explain.work.position_explained` of the states ≥ STATE_MIN, or unknown) and does net work on the record
    (|share against the velocity| ≥ LAW_WORK_MIN) or is not a function of position along it
    (:func:`nnphd.explain.work.position_explained` < POSITION_MAX: a Rayleigh pump on its limit cycle does no net work, yet no
    potential can stand in for it) — in balance along each trajectory as on a limit cycle, not only over the pool
    (``per_trajectory``, :func:`nnphd.explain.work.work_per_trajectory` < LAW_WORK_MIN, or unknown): a law that pumps some trajectories
    and brakes others as much, on a record whose trajectories keep their energy, is contradicted by each of them
    (the case behind it: a van der Pol law, 0.06 % of the force, fitted to 8 trajectories of a conservative Morse
    oscillator, −10 % of its force against the velocity over the pool and no function of position, made a "none"
    "inconclusive" — benchmarks/seed_robustness.py, seed 1; its per-trajectory share was not stored, and the same
    file and seed re-run later found no candidate at all); unknown numbers: yes."""
    key = str(cand.get("law", ""))
    if share is None or any(k in key for k in TIME_KEYS) or "drive" in str(cand.get("title", "")):
        return True
    if by_state is not None and by_state < STATE_MIN:
        return False
    if abs(share) >= LAW_WORK_MIN:
        return True
    balanced = per_trajectory is None or per_trajectory < LAW_WORK_MIN
    return by_position is None or (by_position < POSITION_MAX and balanced)


class Reconciled(NamedTuple):
    """The verdict after the law table (:func:`reconcile`): ``status``, ``new_physics`` (the best call),
    ``confidence``, ``reasons`` (a new list), and ``law`` — the law table as a new dict, made to agree with the
    status (no law is claimed unless it is "detected"); the table handed to :func:`reconcile` is left as it was."""

    status: Status
    new_physics: bool
    confidence: float
    reasons: list[str]
    law: dict


class LawRuling(NamedTuple):
    """The law table after one of the rules that withdraw a claimed law (:func:`unclaim_against_evidence`,
    :func:`unclaim_active`, :func:`unclaim_unidentifiable`): ``law``, a new dict (the table handed to the rule is
    left as it was), and ``why`` the rule withdrew the law (None: the law stands)."""

    law: dict
    why: str | None


def reconcile(res: dict, law: dict, field: str = "learned") -> Reconciled:
    """The verdict after the law table (``law``, the table as a dict; the returned :class:`Reconciled` holds a new
    table made to agree with the verdict: no law is claimed unless the final status is "detected").

    - "detected" by the learned-energy trend alone — the shooting probe pointing the other way, no strong candidate
      law — is "inconclusive", confidence 0.5 (:func:`trend_unsupported`).
    - "none" while a candidate law beats no law on held-out data by ΔIC ≤ LAW_CONFLICT_DIC, and by at least
      LAW_EFFECT_MIN of the held-out error (an effect below it does not contradict "none", however significant),
      whose force the record shows to be non-conservative (:func:`does_work`) and is at least the paper's floor
      MIN_RELATIVE_SIZE of the whole force (below it, within the conservative model's accuracy: a 108-term sparse
      polynomial at 10⁻⁵ of the force lowered the LNN's held-out error on a satellite's precise orbit by 99 %), is
      conflicting evidence — "inconclusive" (best call: new physics), confidence 0.5 (the evidence is split), never a
      confident "none". A drive of a few periods can cancel in the energy trend and go unseen by the verdict's
      checks, while the joint fit of A cos(ωt + φ) finds it.
    - "inconclusive" only because of the net power of the learned Lagrangian's residual (a slow swing of its
      energy on one or two trajectories), where the law table, a drive included, has no candidate that would
      contradict "none": "none", confidence LEARNED_SWING_CONFIDENCE (:func:`learned_power_unconfirmed`).
    - "inconclusive" with no seed saying "none", on an oscillating record of one coordinate, where *every*
      conservative base of the law table (the seed-free library and the seed's LNN) finds a law that beats no law by
      ΔIC ≤ LAW_DETECT_DIC and lowers its error by ≥ LAW_DETECT_EFFECT, is "detected" (:func:`seed_free_evidence`).
    - any verdict but "detected" where the table claims a drive on trajectories whose clock can be told is "detected",
      the drive the law (:func:`drive_evidence`; checked first).
    - a declared uniform field: the fit of the positions beside it decides (:func:`declared_field_verdict`).
    """
    status, new, conf = Status(res["status"]), bool(res["new_physics"]), float(res["confidence"])
    reasons = list(res["reasons"])
    if declared_field_decides(res, field):
        status, conf, why = declared_field_verdict(law)
        kept = withhold(law, status, None if status == Status.DETECTED else why)
        return Reconciled(status, status != Status.NONE, conf, [why, *reasons], kept)
    cand = law.get("law") or law.get("candidate_law")
    if status == Status.DETECTED and (alone := trend_unsupported(res, law)):
        kept = withhold(law, Status.INCONCLUSIVE, alone + " — no law is claimed")
        return Reconciled(Status.INCONCLUSIVE, True, 0.5, [alone, *reasons], kept)
    drive = drive_evidence(res, law) if status != Status.DETECTED else None
    if drive is not None:
        return Reconciled(Status.DETECTED, True, DRIVE_CONFIDENCE, [drive, *reasons], dict(law))
    if (
        status == Status.INCONCLUSIVE
        and not contradicts_none(cand, law)
        and (quiet := learned_power_unconfirmed(res, law))
    ):
        return Reconciled(Status.NONE, False, LEARNED_SWING_CONFIDENCE, [quiet, *reasons], withhold(law, Status.NONE))
    if status == Status.NONE and contradicts_none(cand, law):
        balanced = balanced_force_evidence(res, law)
        if balanced is not None:
            return Reconciled(Status.DETECTED, True, LAW_DETECT_CONFIDENCE, [balanced, *reasons], dict(law))
        why = (
            f"conflicting evidence: the checks find no non-conservation, but a candidate law, {cand['title']}, "
            f"lowers the held-out error by {100 * (1 - cand['heldout_ratio']):.1f}% (ΔIC = {cand['delta_ic']:.1f} "
            f"against no law)"
        )
        kept = withhold(law, Status.INCONCLUSIVE, why + " — no law is claimed")
        return Reconciled(Status.INCONCLUSIVE, True, 0.5, [why, *reasons], kept)
    free = seed_free_evidence(res, law) if status == Status.INCONCLUSIVE else None
    if free is not None:
        return Reconciled(Status.DETECTED, True, LAW_DETECT_CONFIDENCE, [free, *reasons], dict(law))
    kept = withhold(law, status)
    hint = uniform_field_hint(res, kept) if status == Status.INCONCLUSIVE else None
    return Reconciled(status, new, conf, reasons + ([hint] if hint else []), kept)


def contradicts_none(cand: dict | None, law: dict) -> bool:
    """Does this candidate law contradict a verdict of "none" (see :func:`reconcile`): ΔIC ≤ LAW_CONFLICT_DIC against
    no law, the held-out error lowered by ≥ LAW_EFFECT_MIN, a force the record shows to be non-conservative
    (:func:`does_work`) and ≥ MIN_RELATIVE_SIZE of the whole force."""
    return bool(
        cand
        and cand["delta_ic"] <= LAW_CONFLICT_DIC
        and 1 - cand["heldout_ratio"] >= LAW_EFFECT_MIN
        and does_work(
            cand,
            law.get("against_velocity"),
            law.get("by_position"),
            law.get("by_state"),
            law.get("work_per_trajectory"),
        )
        and cand.get("fn_rel", 1.0) >= MIN_RELATIVE_SIZE
    )


def _strong(cand: dict) -> bool:
    """A candidate of the law table as strong as :func:`contradicts_none` asks, whatever its force does (the table's
    numbers on work and position are for its winner only; a candidate the table set aside — a drive on one
    trajectory, whose clock is confounded with the state — still counts)."""
    return (
        cand.get("delta_ic", math.inf) <= LAW_CONFLICT_DIC
        and 1 - cand.get("heldout_ratio", 1.0) >= LAW_EFFECT_MIN
        and cand.get("fn_rel", 1.0) >= MIN_RELATIVE_SIZE
    )


def _any_strong(law: dict) -> bool:
    """Is any candidate of the law table (not the zero law) :func:`_strong`?"""
    return any(_strong(c) for c in law.get("candidates") or [] if c.get("law") != "none")


def trend_unsupported(res: dict, law: dict) -> str | None:
    """Why a detection rests on the learned Lagrangian alone, or None: every detecting seed was detected by its
    record-level evidence (not by a clock), through its learned-energy trend while its shooting probe — the fit of
    the positions — points the other way (the energy falls, the probe finds anti-damping, or the reverse), and no
    candidate of the law table beats no law as strongly as :func:`contradicts_none` asks (:func:`_strong`). Then
    nothing outside the learned Lagrangian shows the change, and on an orbit that moves through its states that
    Lagrangian's own error makes trends (:data:`nnphd.user.checks.FIT_ERROR_RATIO`). Measured: a J2 satellite in the
    Earth-fixed frame (constructed, conservative; benchmarks/conservative_controls.py, seed 1): internal seed 2's
    learned energy decayed 0.099 %/period at z = 6.2, 3.9× its fit error, while the probe found d = −4.3·10⁻⁴ ±
    4.1·10⁻⁴ and every candidate law cost more than it gained (ΔIC ≥ +2.1) — "detected" (confidence 0.29) before."""
    seeds = (res.get("checks") or {}).get("per_seed") or []
    detecting = [s for s in seeds if s.get("status") == Status.DETECTED]
    if not detecting:
        return None
    for s in detecting:
        te, clock = s.get("trajectory_evidence") or {}, s.get("time") or {}
        ze, zs = te.get("z_energy"), te.get("z_shooting")
        if not te.get("significant") or (clock.get("significant") and clock.get("valid")):
            return None
        if ze is None or zs is None or not ze or not zs or np.sign(ze) == np.sign(zs):
            return None
    if _any_strong(law):
        return None
    said = "; ".join(
        f"seed {s['seed']}: energy trend z = {s['trajectory_evidence']['z_energy']:.1f}, shooting probe z = "
        f"{s['trajectory_evidence']['z_shooting']:.1f}"
        for s in detecting
    )
    return (
        f"the learned energy changes along the record, but nothing outside the learned Lagrangian shows it ({said}): "
        "the fit of the positions by integration points the other way and no candidate law beats no law by the "
        "margin that would count — on an orbit that moves through its states the learned Lagrangian's own error "
        "makes such trends; a record with more trajectories or more periods would decide"
    )


# the confidence of a "none" that the fit of the positions decided against a swing of the learned energy: one line of
# evidence (the seeds' own checks were not decisive), as LAW_DETECT_CONFIDENCE
LEARNED_SWING_CONFIDENCE = 0.75


def learned_power_unconfirmed(res: dict, law: dict) -> str | None:
    """The reason for "none" on an oscillating record whose seeds say "none" or are "inconclusive" only because of the
    net power of their learned Lagrangian's residual (``by_learned_power`` of
    :func:`nnphd.user.checks.by_learned_power`: a slow swing of the learned energy on one or two trajectories), when the
    law table — which fitted a drive A cos(ωt + φ), the force without net power such a swing could mean, beside the
    autonomous families — has no candidate that contradicts "none" (:func:`contradicts_none`, checked by the
    caller, and no candidate as strong, :func:`_strong`, even one the table set aside); else None. That evidence is
    the learned Lagrangian's alone, and a fit of the positions that needs no force wins over it. Measured: the
    Earth–Moon barycentre in a frame turning with Jupiter (DE405, one orbit of 8 years) swung at Z = 2.2–3.4 while
    every candidate, the drive included, cost more than it gained (ΔIC ≥ +0.9); one trajectory of a Duffing
    oscillator under 0.1 cos(1.3 t) swings at Z = 5.3–5.4 and its drive, which the table does not claim on one
    trajectory, beats no law by ΔIC −2343 (error −96 %): it stays "inconclusive" (benchmarks/conservative_controls.py;
    tests/test_law_verdict.py)."""
    quality = res.get("quality") or {}
    if not quality.get("usable", True) or not quality.get("oscillating", True):
        return None
    seeds = (res.get("checks") or {}).get("per_seed") or []
    swinging = [s for s in seeds if s.get("by_learned_power")]
    if not swinging or any(s["status"] != Status.NONE and not s.get("by_learned_power") for s in seeds):
        return None
    cands = {c.get("law"): c for c in law.get("candidates") or []}
    if "drive" not in cands or _any_strong(law):
        return None
    said = "; ".join(
        f"seed {s['seed']}: slow ratio Z = {s['drift']['slow_ratio_median']:.1f}, net power "
        f"{s['drift']['rho_median']:.2f} of the power moved"
        for s in swinging
    )
    best = min((c for k, c in cands.items() if k not in ("none", "drive")), key=lambda c: c["delta_ic"], default=None)
    shown = [("the drive", cands["drive"])] + ([("the best other", best)] if best else [])
    beaten = "; ".join(
        f"{name}{'' if name == 'the drive' else ', ' + c.get('title', c['law'])}: ΔIC = {c['delta_ic']:+.1f}, error "
        f"{100 * (c['heldout_ratio'] - 1):+.0f}%"
        for name, c in shown
    )
    return (
        f"no non-conservation: the learned energy swings from one oscillation to the next ({said}), but that is "
        "evidence from the learned Lagrangian alone — its own fit error swings it as much on an orbit that moves "
        "through its states — and the fit of the positions finds no force it would need: no candidate law, a drive "
        f'A cos(ω t + φ) included, beats no law by the margin that would contradict "none" ({beaten})'
    )


def uniform_field_hint(res: dict, law: dict) -> str | None:
    """What would decide a record that does not oscillate: the fit of its positions beside a uniform field (the
    law table's seed-free base), if it finds a law that beats the field alone by ΔIC ≤ LAW_DETECT_DIC — said, not
    used: the field must be declared (``--field uniform``), since along one arc a field that varies could explain
    the same motion."""
    if (res.get("quality") or {}).get("oscillating", True):
        return None
    lib = next((b for b in (law.get("settings") or {}).get("bases") or [] if b["base"] == LIBRARY_BASE), None)
    w = (lib or {}).get("law")
    if not w or w["delta_ic"] > LAW_DETECT_DIC:
        return None
    return (
        f"what would decide: if the conservative force is a uniform field (gravity near the ground, or none), "
        f"declare it (--field uniform; NNPhD(field='uniform')): beside a uniform field {w['title']} lowers the error "
        f"of the fit of the positions by {100 * (1 - w['heldout_ratio']):.0f}% (ΔIC = {w['delta_ic']:.1f} against "
        "no law)"
    )


RECONCILED_BASIS = (
    "set by the law table, which changed the seeds' verdict (the first reason says how): 0.5 where it contradicts "
    "their 'none' (the evidence is split), 0.75 where it alone decides 'detected' (one line of evidence)"
)

# "inconclusive" becomes "detected" when every conservative base of a one-coordinate law table finds a law at least
# this much better than none (the strong end of the IC scale, as LAW_CONFLICT_DIC) ...
LAW_DETECT_DIC = -10.0
# ... that lowers the error of the trajectory-level fit by at least this share: a servo drop whose 3 periods are too
# few for the energy trend and whose LNN (one trajectory) absorbed most of the damping — shooting probe z = 0.7 —
# while the seed-free fit of its positions needs viscous friction (error −93 %, ΔIC −17; LNN base −97 %, ΔIC −36)
LAW_DETECT_EFFECT = 0.25
# the confidence of such a verdict: one line of evidence, the seeds' own checks not decisive
LAW_DETECT_CONFIDENCE = 0.75


# a drive claimed by the law table (no tie with an autonomous family) on trajectories whose clock can be told from
# their state — at least CLOCK_MIN_TRAJ overlapping in time — is "detected" with the drive as the law when it beats
# no law by ΔIC ≤ LAW_CONFLICT_DIC and lowers the held-out error by at least this share. A drive is explicit time
# dependence, the paper's third kind of new physics; the seeds' clock tests (a regression of the residual on
# features of t) can miss it where the joint fit of A cos(ωt + φ) finds it: a Duffing oscillator under
# 0.2 cos(0.7 t), 3 trajectories, both seeds "none" while the drive lowered the held-out error by 97 % (ΔIC −480).
DRIVE_EFFECT_MIN = 0.05
DRIVE_CONFIDENCE = 0.75


def drive_evidence(res: dict, law: dict) -> str | None:
    """The reason for "detected" from a drive the law table claims, or None (see DRIVE_EFFECT_MIN)."""
    w = law.get("law")
    clock = res.get("clock") or {}
    if not w or w["law"] != "drive" or law.get("status") != TableStatus.CLAIMED or not clock.get("testable"):
        return None
    cut = 1 - w["heldout_ratio"]
    if w["delta_ic"] > LAW_CONFLICT_DIC or cut < DRIVE_EFFECT_MIN:
        return None
    p = w["params"]
    amp = ", ".join(f"{math.hypot(v, p.get('A_sin' + k[5:], 0.0)):.3g}" for k, v in p.items() if k.startswith("A_cos"))
    return (
        f"the force depends on t explicitly: a drive of amplitude {amp} and angular frequency "
        f"{abs(p.get('omega', float('nan'))):.4g} lowers the held-out error of the fit of the positions by "
        f"{100 * cut:.1f}% (ΔIC = {w['delta_ic']:.1f} against no law; every autonomous candidate is worse), on "
        f"{clock.get('why', 'trajectories overlapping in time')}"
    )


def seed_free_evidence(res: dict, law: dict, allow_none: bool = False) -> str | None:
    """The reason for "detected" from the law table when the seeds' checks were not decisive, or None. Needs an
    oscillating record of usable quality, no seed saying "none", and a table ranked with more than one conservative
    base (one coordinate: the seed-free library and the LNN) in which every base finds a law (claimed or a tie; not
    a drive — on one trajectory time and state are confounded) with ΔIC ≤ LAW_DETECT_DIC against no law and an
    error lowered by ≥ LAW_DETECT_EFFECT. The law and the verdict then rest on evidence of the same strength."""
    quality = res.get("quality") or {}
    if not quality.get("usable", True) or not quality.get("oscillating", True):
        return None
    if not allow_none and any(s.get("status") == Status.NONE for s in (res.get("checks") or {}).get("per_seed", [])):
        return None
    bases = (law.get("settings") or {}).get("bases") or []
    if len(bases) < 2:
        return None
    views = []
    for b in bases:
        w = b.get("law")
        ruled = b.get("status") not in (TableStatus.CLAIMED, TableStatus.TIE)
        if ruled or not w or "drive" in [w["law"], *b.get("families", [])]:
            return None
        cut = 1 - w["heldout_ratio"]
        if w["delta_ic"] > LAW_DETECT_DIC or cut < LAW_DETECT_EFFECT:
            return None
        views.append(f"with {b['base']}: {w['title']}, error −{100 * cut:.0f}%, ΔIC = {w['delta_ic']:.1f}")
    return (
        "a fit of the positions with a non-conservative law beats the conservative model alone beside every "
        f"conservative base ({'; '.join(views)} against no law), while the seeds' own checks were not decisive"
    )


def balanced_force_evidence(res: dict, law: dict) -> str | None:
    """The reason for "detected" on a record the checks call "none" (no net change of the energy) where the law table
    claims a force of the state that does no net work yet is no function of position (a pump and a loss in balance:
    a limit cycle), found by every conservative base as strongly as :func:`seed_free_evidence` asks; else None.
    Measured: a Rayleigh oscillator on its limit cycle — no energy trend (z = −0.7), its law lowering
    the held-out error by 85 % (ΔIC −2013) — was "inconclusive" (conflicting evidence)."""
    w = law.get("law")
    share, pos = law.get("against_velocity"), law.get("by_position")
    if not w or law.get("status") != TableStatus.CLAIMED or share is None or pos is None:
        return None
    if abs(share) >= LAW_WORK_MIN or pos >= POSITION_MAX:
        return None
    if (law.get("work_per_trajectory") or 0.0) >= LAW_WORK_MIN:  # balanced over the pool only (:func:`does_work`)
        return None
    free = seed_free_evidence(res, law, allow_none=True)
    if free is None:
        return None
    return (
        f"the energy does not change along the record, but {w['title']} acts on it: it does no net work "
        f"({100 * share:.0f}% of its force against the velocity) and only {100 * max(pos, 0.0):.0f}% of its force "
        "is a function of position, so no potential can stand in for it (a pump and a loss in balance, as on a limit "
        f"cycle); {free}"
    )


# a declared uniform field: the fit of the positions beside it explains the record when its mean squared residual per
# coordinate and row, in units of the estimated position noise, is at most this (≈ 1 when it fits to the noise; the
# noise estimate of a short record can be ~40 % off in χ²). On the 2-D throw look-alike the uniform field alone leaves
# ~3, with a drag ~0.9 (benchmarks/results/friction_laws.json).
FIELD_FIT_MSE = 2.0

# beside a declared uniform field, a drag opposes the velocity: the share of the law's force along −v̂
# (:func:`nnphd.explain.work.against_velocity`) is 1 for any drag of the speed. A field that varies over the record, fitted as uniform,
# leaves a remainder that is no drag: on arcs of a 1/r² field (R = 5, 20, 100 m, g = 9.81 at the release, the throw's
# 1.2 s at 60 fps, 2 mm noise, seeds 0–2) the winning law's share is −0.85 … 0.39, and 1.000 on every throw with
# quadratic drag (results/declared_field_guard.json).
DRAG_ALONG_MIN = 0.8


def declared_field_decides(res: dict, field: str) -> bool:
    """Whether the fit of the positions beside a declared uniform field decides the verdict (:func:`reconcile`): a
    field declared and data that can decide."""
    return field in ("uniform", "vertical") and bool((res.get("quality") or {}).get("usable", True))


def declared_field_effect(law: dict) -> str | None:
    """The effect size beside a declared uniform field: how much the best law lowers the error of the fit of the
    positions, from what to what (the network's record-level evidence says nothing here: it can absorb a drag)."""
    rows = law.get("candidates") or []
    zero = next((r for r in rows if r["law"] == "none"), None)
    best = law.get("law") or next((r for r in rows if r["law"] != "none" and r.get("significant", True)), None)
    if zero is None or best is None:
        return None
    scale = float((law.get("noise") or {}).get("chi2_scale", 1.0))
    return (
        f"beside the declared uniform field, {best['title']} lowers the error of the fit of the positions by "
        f"{100 * (1 - best['heldout_ratio']):.0f}% (χ²/N {zero['heldout_mse'] / scale:.2f} → "
        f"{best['heldout_mse'] / scale:.2f}, "
        f"ΔIC = {best['delta_ic']:.1f})"
    )


def declared_field_verdict(law: dict) -> tuple[Status, float, str]:
    """(status, confidence, reason) when the conservative force is declared uniform: the law table (the uniform
    field as its only base, each trajectory one window, in-sample IC) decides, as a single line of evidence
    (confidence LAW_DETECT_CONFIDENCE).

    - "detected": the best law (claimed or leading a tie) beats the field alone by ΔIC ≤ LAW_DETECT_DIC, lowers the
      error by ≥ LAW_EFFECT_MIN and fits to the noise (χ²/N ≤ FIELD_FIT_MSE);
    - "none": the field alone fits to the noise and no law beats it by ΔIC ≤ LAW_DETECT_DIC;
    - "inconclusive" otherwise: the field does not explain the record even with the best law (so the declaration
      or the candidate laws are wrong), or a law helps but not decisively."""
    rows = law.get("candidates") or []
    zero = next((r for r in rows if r["law"] == "none"), None)
    if zero is None or not rows or rows[0].get("method") != "trajectory":
        return (
            Status.INCONCLUSIVE,
            1.0,
            (
                "the field was declared uniform, but no fit of the positions beside it could be made "
                f"({law.get('reason') or 'no law table'}); the verdict rests on that fit"
            ),
        )
    w = law.get("law")
    noise = law.get("noise") or {}
    scale = float(noise.get("chi2_scale", 1.0))
    if w is not None:
        w = {**w, "heldout_mse": w["heldout_mse"] / scale}
    z_mse = zero["heldout_mse"] / scale
    against = (
        "; χ²/N against the noise a low-degree curve through each arc leaves (the difference estimate was "
        f"x{scale**0.5:.2f} lower: noise correlated from frame to frame)"
        if noise.get("used") == "smooth curve"
        else ""
    )
    base = f"the uniform field alone leaves χ²/N = {z_mse:.2f} (1: it fits to the noise{against})"
    along = law.get("against_velocity")
    caveat = (
        "; this rests on the declared uniform field: along an arc that does not return a field that varies over it "
        "could also explain the record"
    )
    if w is not None:
        cut = 1 - w["heldout_ratio"]
        say = (
            f"{w['title']} lowers the error of the fit of the positions by {100 * cut:.0f}% (ΔIC = "
            f"{w['delta_ic']:.1f} against no law) to χ²/N = {w['heldout_mse']:.2f}"
        )
        decisive = w["delta_ic"] <= LAW_DETECT_DIC and cut >= LAW_EFFECT_MIN and w["heldout_mse"] <= FIELD_FIT_MSE
        if decisive and along is not None and along < DRAG_ALONG_MIN:
            return (
                Status.INCONCLUSIVE,
                1.0,
                (
                    f"beside the declared uniform field {say}, but that force is no drag: only {100 * along:.0f}% of it "
                    f"opposes the velocity (a drag: 100%, decisive at ≥ {100 * DRAG_ALONG_MIN:.0f}%). A field that "
                    "varies over the record leaves such a remainder beside a uniform one, and so would a lift or a "
                    "thrust; one arc cannot tell them apart — check that the field is uniform over the record"
                ),
            )
        if decisive:
            return (
                Status.DETECTED,
                LAW_DETECT_CONFIDENCE,
                (
                    f"beside the declared uniform field the motion needs a non-conservative force: {say}, where {base}"
                    + caveat
                ),
            )
        if w["heldout_mse"] > FIELD_FIT_MSE:
            return (
                Status.INCONCLUSIVE,
                1.0,
                (
                    f"the declared uniform field does not explain the record even with the best law ({say}, above "
                    f"{FIELD_FIT_MSE:g}): the field is not uniform, or a force acts that no candidate law has"
                ),
            )
        if w["delta_ic"] <= LAW_DETECT_DIC / 2 or z_mse > FIELD_FIT_MSE:
            return (
                Status.INCONCLUSIVE,
                1.0,
                f"beside the declared uniform field a law helps, but not decisively: {say}, where {base}",
            )
    best = min((r["delta_ic"] for r in rows if r["law"] != "none"), default=float("nan"))
    if w is None and best <= LAW_DETECT_DIC:
        return (
            Status.INCONCLUSIVE,
            1.0,
            (
                f"beside the declared uniform field a candidate law beats the field alone (ΔIC = {best:.1f}) but none has "
                f"every term significant, where {base}"
            ),
        )
    if z_mse <= FIELD_FIT_MSE:
        return (
            Status.NONE,
            LAW_DETECT_CONFIDENCE,
            (
                f"the declared uniform field alone explains the motion: {base}, and no candidate law beats it "
                f"(best ΔIC = {best:.1f}, decisive at ≤ {LAW_DETECT_DIC:g}); this rests on the declared uniform field: "
                "along an arc that does not return a field that varies over it could hide a drag"
            ),
        )
    return (
        Status.INCONCLUSIVE,
        1.0,
        (
            f"the declared uniform field does not explain the record ({base}, above {FIELD_FIT_MSE:g}) and no candidate "
            "law does: the field is not uniform, or a force acts that no candidate law has"
        ),
    )


# a claimed law whose force pumps energy in on net where the record-level evidence says the record loses it (or takes
# it out where the record gains it) explains the opposite of what was measured: measured on the camera look-alike of a
# damped chaotic double pendulum (--seed 1), where a power law −k(|q̇|²)^m q̇ with k = −3.1e-15, m = 6.35 (a thrust
# acting only at the fastest rows) won the law table while the learned energy decayed at z = 7.4
LAW_AGAINST_EVIDENCE = 0.5


def _withdrawn(law: dict, why: str) -> dict:
    """A new law table whose law is withdrawn: it becomes ``candidate_law``, no family is claimed (status "none", no
    ties), ``why`` the reason. The keys keep their places; those the table lacked follow in that order."""
    return {**law, "candidate_law": law["law"], "law": None, "status": TableStatus.NONE, "ties": [], "reason": why}


def unclaim_against_evidence(res: dict, law: dict) -> LawRuling:
    """Withdraw the claimed law when its force works against the verdict's record-level evidence: the share of its
    force against the velocity (:func:`nnphd.explain.work.against_velocity`) ≤ −LAW_AGAINST_EVIDENCE while the record loses energy
    (≥ LAW_AGAINST_EVIDENCE while it gains it). The law becomes ``candidate_law`` with the reason (``why``; None
    when the law stands). In the new table ``against_velocity`` follows the table's own entries (None when absent);
    ``law`` is left as it was."""
    share = law.get("against_velocity")
    moved = {k: v for k, v in law.items() if k != "against_velocity"} | {"against_velocity": share}
    comb = (res.get("evidence") or {}).get("combined") or {}
    sign = {"loses energy": 1.0, "gains energy": -1.0}.get(comb.get("direction"))
    if not moved.get("law") or share is None or sign is None or not comb.get("significant"):
        return LawRuling(moved, None)
    if sign * share > -LAW_AGAINST_EVIDENCE:
        return LawRuling(moved, None)
    why = (
        f"no law is claimed: the best candidate, {moved['law']['title']}, {'adds' if share < 0 else 'takes'} energy "
        f"({100 * share:.0f}% of its force against the velocity) where the record {comb['direction']} along its whole "
        "length — it fits the record's positions, not its physics"
    )
    return LawRuling(_withdrawn(moved, why), why)


def unclaim_active(res: dict, law: dict) -> LawRuling:
    """Withdraw a claimed law that adds energy on a sizeable part of the visited states (f·q̇ > 0 on ≥
    ACTIVE_SHARE_MAX of the rows, :func:`nnphd.explain.wholerecord.passivity`) on a record that loses energy (the
    verdict's record-level evidence), unless a fit over the whole record puts it ≥ PASSIVE_MARGIN_IC ahead of every
    eligible passive candidate. A pump (van der Pol, a drive) stays claimable where the record supports it: on a
    limit cycle or a driven record the energy is not lost. Measured: an encoder pendulum released from 157°
    with viscous-like damping was claimed 0.53 θ²θ̇ − 0.70 θ̇, anti-damping wherever |θ| > 1.15 rad. The law
    becomes ``candidate_law`` with the reason (``why``; None when the law stands); ``passivity`` keeps the numbers,
    after the table's own entries in the new table (dropped when it holds None); ``law`` is left as it was."""
    from nnphd.explain.wholerecord import PASSIVE_MARGIN_IC

    info = law.get("passivity")
    moved = {k: v for k, v in law.items() if k != "passivity"}
    if info is not None:  # after the share against the velocity in the report, as the two checks run
        moved["passivity"] = info
    comb = (res.get("evidence") or {}).get("combined") or {}
    if not moved.get("law") or not info or not info.get("active") or comb.get("direction") != "loses energy":
        return LawRuling(moved, None)
    margin = info.get("margin")
    if margin is not None and margin >= PASSIVE_MARGIN_IC:
        return LawRuling(moved, None)
    share = 100 * info["active_share"]
    if margin is not None:
        against = (
            f"fitted over the whole record it is only {margin:+.1f} in IC against the best passive family, "
            f"{info['best_passive']} (it must be ≥ {PASSIVE_MARGIN_IC:g} ahead)"
        )
    else:
        against = f"no fit over the whole record could prefer it ({info.get('why', 'not computed')})"
    why = (
        f"no law is claimed: the best candidate, {moved['law']['title']}, adds energy on {share:.0f}% of the visited "
        f"states while the record loses energy, and {against}"
    )
    return LawRuling(_withdrawn(moved, why), why)


def unclaim_unidentifiable(law: dict) -> LawRuling:
    """Withdraw a claimed law of the state that does no net work on the record and whose force is a function of
    position along it (:func:`does_work` false): a learned potential can stand in for it, so the record does not
    show it is non-conservative (measured: a LAGEOS-like satellite under J2, one day, was claimed a sparse polynomial
    of 108 terms at 10⁻⁵ of the force, 0.8 of it a function of position). Call after :func:`unclaim_against_evidence`
    (the share against the velocity is ``law["against_velocity"]``). A new table (``why``: None when the law
    stands); ``law`` is left as it was."""
    w = law.get("law")
    if not w or does_work(w, law.get("against_velocity"), law.get("by_position")):
        return LawRuling(dict(law), None)
    why = (
        f"no law is claimed: the best candidate, {w['title']}, does no net work on the record "
        f"({100 * law['against_velocity']:.0f}% of its force against the velocity) and "
        f"{100 * law['by_position']:.0f}% of its force is a function of position along it — a learned potential "
        "can stand in for it, so the record does not show that it is non-conservative"
    )
    return LawRuling(_withdrawn(law, why), why)


def withhold(law: dict, status: Status, why: str | None = None) -> dict:
    """No law is claimed unless the verdict is "detected": a new law table whose law (if any) becomes
    ``candidate_law``, with ``why`` (or a reason naming the verdict) as its reason; ``law`` is left as it was."""
    if status == Status.DETECTED:
        return dict(law)
    if law.get("law") is None:
        return {**law, "reason": why} if why else dict(law)
    return _withdrawn(
        law,
        why
        or (
            f"the verdict is {str(status)!r}, so no law is claimed (the best candidate, {law['law']['title']}, "
            f"would beat zero: {law.get('reason', '')})"
        ),
    )
