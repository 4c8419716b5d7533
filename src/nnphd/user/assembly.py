"""The report of a detection, assembled from the stages' results (:func:`nnphd.user.detect.detect_data`): the
verdict with its evidence, the law entry and its formula, the conservative field as declared and fitted, the data's
warnings, the blind formula as a hint, and the run's timings with its seeds' — what report.json writes.
"""

from __future__ import annotations

import numpy as np

from nnphd.explain.law import TableStatus
from nnphd.explain.search import field_force
from nnphd.parallel import runs_in_this_process
from nnphd.user.rules import RECONCILED_BASIS
from nnphd.user.settings import FIELDS

__all__ = [
    "best_formula",
    "declared_forces",
    "derivative_warnings",
    "field_entry",
    "law_formula",
    "report_of",
    "with_workers",
]


def declared_forces(law: dict, declared: dict, data, ud, fc, fn):
    """The declared uniform field as the law table fitted it (``declared``: {"alone", "with_law"[,
    "against_velocity"]}, empty without a declared field): (the field fitted — with the law when one is claimed,
    else alone — or None, f_c, f_n); f_c and f_n as given without a declared field."""
    fitted = declared.get("with_law" if law.get("law") else "alone")
    if fitted is not None:  # the declared field is the conservative force; f_n the remainder of q̈ beside it
        fc = field_force(fitted, data.q, ud.is_angle)
        fn = np.asarray(data.qdd, float) - fc
    return fitted, fc, fn


def field_entry(field: str, fitted: dict | None, declared: dict) -> dict:
    """The report's ``field``: the conservative force declared, and a uniform field as fitted (its law, g and
    standard error per coordinate; whether the law's force opposes the velocity)."""
    return (
        {"kind": field, "text": FIELDS[field]}
        | ({k: fitted[k] for k in ("law", "g", "stderr")} if fitted else {})
        | ({"against_velocity": declared["against_velocity"]} if "against_velocity" in declared else {})
    )


def report_of(ud, res: dict, info: dict, law: dict, verdict, field: dict, blind: dict, settings: dict) -> dict:
    """The report of :func:`detect_data` (without its timings): ``res``: the assessment's report; ``verdict`` =
    (status, new_physics, confidence, reasons, effect) of :func:`nnphd.user.rules.reconcile` and the effect beside a
    declared field (None: the assessment's); ``field``: :func:`field_entry`'s; ``settings``: the run's own, to
    which assess's are added."""
    from nnphd.user.recording import suggest_angles

    status, new_physics, confidence, reasons, effect = verdict
    coords = list(ud.coords)
    return {
        "file": str(ud.path),
        **({"markers": ud.markers.to_dict()} if getattr(ud, "markers", None) is not None else {}),
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
    if law.get("status") == TableStatus.TIE:
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
