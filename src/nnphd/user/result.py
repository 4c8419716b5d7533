"""What ``nnphd detect`` and :meth:`nnphd.NNPhD.fit` return, typed: the :class:`Verdict` (its :class:`Status`), the
:class:`DetectResult` (written as report.json at the boundary — :meth:`DetectResult.to_dict` — and read back with
:meth:`DetectResult.from_dict` / :func:`read_report`), and the :class:`FittedModel` (the fitted pieces that
:class:`nnphd.NNPhD` keeps: the conservative model, the claimed law, the data and forces on its rows).
"""

from __future__ import annotations

import json
import os
import sys
from dataclasses import asdict, dataclass, field
from enum import StrEnum
from pathlib import Path

import numpy as np

from nnphd.explain.law import Law, TableStatus

__all__ = ["MAX_REPORT_BYTES", "ConservativeModel", "DetectResult", "FittedModel", "Status", "Verdict", "read_report"]


class Status(StrEnum):
    """The verdict's status. A str: ``Status.DETECTED == "detected"``, and it is written to JSON as the plain word."""

    DETECTED = "detected"  # a non-conservative force (or an explicit time dependence) is there
    NONE = "none"  # the motion is conservative within what the record can tell
    INCONCLUSIVE = "inconclusive"  # the record cannot decide; the reasons say why


@dataclass(frozen=True)
class Verdict:
    """Is there new physics? ``status`` (:class:`Status`); ``new_physics`` the best call (True with
    "inconclusive" when the evidence leans that way); ``confidence`` the repeatability of the call (docs/RESULTS.md,
    "Can you trust the verdict?"); ``reasons`` why; ``statistic`` the energy-trend z."""

    status: Status
    new_physics: bool
    confidence: float
    reasons: tuple[str, ...]
    statistic: float | None

    def to_dict(self) -> dict:
        return asdict(self)


MAX_REPORT_BYTES = 256 * 2**20  # a report.json larger than this is refused unread


def _report_error(where: str, what: str) -> ValueError:
    return ValueError(f"{where}: {what}")


def _verdict_of(report: dict, where: str = "report") -> Verdict:
    """The report's verdict, checked: a report read from a file is untrusted."""
    try:
        status = Status(report.get("status"))
    except ValueError:
        raise _report_error(
            where, f"status must be one of {', '.join(repr(s.value) for s in Status)}, got {report.get('status')!r:.60}"
        ) from None
    conf = report.get("confidence")
    if isinstance(conf, bool) or not isinstance(conf, (int, float)) or not (0.0 <= conf <= 1.0 or conf != conf):
        raise _report_error(where, f"confidence must be a number in [0, 1], got {conf!r:.60}")  # (NaN: not known)
    reasons = report.get("reasons", [])
    if not isinstance(reasons, list) or not all(isinstance(r, str) for r in reasons):
        raise _report_error(where, "reasons must be a list of strings")
    stat = (report.get("statistic") or {}).get("value") if isinstance(report.get("statistic"), dict) else None
    if stat is not None and (isinstance(stat, bool) or not isinstance(stat, (int, float))):
        raise _report_error(where, f"statistic.value must be a number or null, got {stat!r:.60}")
    return Verdict(status, bool(report.get("new_physics")), float(conf), tuple(reasons), stat)


def _table_status_of(table: dict, where: str) -> TableStatus:
    """How the report's law table ended (its ``status``; "none" when absent), checked."""
    try:
        return TableStatus(table.get("status", TableStatus.NONE))
    except ValueError:
        allowed = ", ".join(repr(s.value) for s in TableStatus)
        raise _report_error(where, f"law.status must be one of {allowed}, got {table.get('status')!r:.60}") from None


@dataclass(frozen=True)
class DetectResult:
    """What ``nnphd detect`` / :meth:`NNPhD.fit` found, typed: the :class:`Verdict`, the effect size in words, the
    evidence, the claimed :class:`Law` (None unless "detected" with a law), how the law table ended (``law_status``,
    a :class:`~nnphd.explain.law.TableStatus`: "claimed" / "tie" / "none", ``law_reason``), the per-stage
    ``timings``, data ``warnings``, the conservative ``field`` and the ``settings``. ``report`` is the JSON as
    written (report.json); :meth:`to_dict` returns it and :meth:`from_dict` / :func:`read_report` check it back."""

    verdict: Verdict
    effect: str | None
    evidence: dict
    law: Law | None
    law_status: TableStatus
    law_reason: str
    timings: dict
    warnings: tuple[str, ...]
    field: dict
    settings: dict
    report: dict = field(repr=False, compare=False)

    @property
    def status(self) -> Status:
        return self.verdict.status

    @classmethod
    def from_dict(cls, report: dict, where: str = "report") -> DetectResult:
        """From a report dict (report.json's content); ValueError with one line when it is not one."""
        if not isinstance(report, dict):
            raise _report_error(where, f"expected a JSON object, got {type(report).__name__}")
        verdict, law = _verdict_of(report, where), Law.from_report(report, where)
        effect = report.get("effect")
        warnings = report.get("warnings", [])
        if effect is not None and not isinstance(effect, str):
            raise _report_error(where, "effect must be a string or null")
        if not isinstance(warnings, list) or not all(isinstance(w, str) for w in warnings):
            raise _report_error(where, "warnings must be a list of strings")
        parts = {k: {} if report.get(k) is None else report[k] for k in ("evidence", "timings", "field", "settings")}
        for k, v in parts.items():
            if not isinstance(v, dict):
                raise _report_error(where, f"{k} must be an object")
        table = report.get("law") or {}
        return cls(
            verdict,
            effect,
            parts["evidence"],
            law,
            _table_status_of(table, where),
            str(table.get("reason", "")),
            parts["timings"],
            tuple(warnings),
            parts["field"],
            parts["settings"],
            report,
        )

    def to_dict(self) -> dict:
        """The report as written (a deep copy: changing it changes nothing here)."""
        return json.loads(json.dumps(self.report))


def read_report(path) -> DetectResult:
    """A report.json written by ``nnphd detect`` (or :meth:`NNPhD.report`), read and checked: bounded in size, parsed
    as JSON only (never executed), its verdict and law checked for type. ValueError with one line naming the path
    and what is wrong. Only a regular file is read, checked on a non-blocking descriptor before any read
    (:func:`nnphd.io.cache.open_regular`): a FIFO, a device or a link to one is refused at once, not waited on."""
    from nnphd.io.cache import open_regular

    path = Path(path)
    try:
        f = open_regular(path, sys.maxsize)  # (the size is checked below, to say it as a report's limit)
    except ValueError as e:  # no such file, not a regular file, not readable
        raise _report_error(str(path), f"not a readable report.json ({e})") from None
    with f:
        size = os.fstat(f.fileno()).st_size
        if size > MAX_REPORT_BYTES:
            raise _report_error(str(path), f"{size} bytes, more than a report holds ({MAX_REPORT_BYTES} at most)")
        try:
            data = f.read(MAX_REPORT_BYTES + 1)
            if len(data) > MAX_REPORT_BYTES:  # it grew while read
                raise _report_error(str(path), f"more than a report holds ({MAX_REPORT_BYTES} bytes at most)")
            report = json.loads(data.decode("utf-8"))
        except (OSError, UnicodeDecodeError, json.JSONDecodeError, RecursionError) as e:
            why = f"{type(e).__name__}: {str(e)[:120]}"
            raise _report_error(str(path), f"not a readable report.json ({why})") from None
    return DetectResult.from_dict(report, str(path))


@dataclass(frozen=True, eq=False)
class ConservativeModel:
    """The learned conservative model of one seed: the LNN's parameters ``lnn`` and ``cfg``
    (:class:`nnphd.engine.models.ModelConfig`), its acceleration ``fc`` on the data set's rows (file units; None for
    a model read from a file) and the ``scaling`` between the file's units and the model's
    (:class:`nnphd.user.scaling.Scaling`)."""

    lnn: object
    cfg: object
    fc: np.ndarray | None
    scaling: object


@dataclass(frozen=True, eq=False)
class FittedModel:
    """The fitted pieces of one run, what :class:`nnphd.NNPhD` keeps: ``conservative`` (the LNN with its config and
    scaling, :class:`ConservativeModel`; None when no model was trained), ``law`` (the claimed
    law's Candidate, None unless a law is claimed), the data set and trajectory ids it was fitted on, the coordinate
    names and which are angles, f_c and f_n on the rows, and the declared field as fitted (None unless declared)."""

    conservative: ConservativeModel | None
    law: object | None
    data: object
    traj: np.ndarray
    coords: tuple[str, ...]
    angles: tuple[bool, ...]
    fc: np.ndarray
    fn: np.ndarray
    field: dict | None = None
