"""`Law`: the one result type for a law of the non-conservative force f_n.

Whatever found it — the ranked candidate table (:mod:`nnphd.explain.table`: the claimed law, a tie, any candidate
via :meth:`~nnphd.explain.table.Candidate.to_law`), a post-hoc parametric fit of a learned f_n
(:mod:`nnphd.explain.parametric`: the paper's Table II hypotheses) or a blind formula
(:mod:`nnphd.explain.sparse`, :mod:`nnphd.explain.symbolic`) — its result is a frozen :class:`Law`. ``status`` says
what it is worth (:class:`LawStatus`): "claimed" (the law), "tie" (the record cannot tell it from other families),
"candidate" (fitted, not claimed) or "hint" (a blind formula: a suggestion, never the law). How a ranked law table
ended — report.json's ``law.status`` — is a :class:`TableStatus`: "claimed", "tie" or "none" (no law claimed).

Dicts only at the JSON boundary: :meth:`Law.to_dict` / :meth:`Law.from_dict` (checked as untrusted input, one
ValueError naming the field); :meth:`Law.from_report` reads the claimed law of a report.json; the shapes older files
always had are written by :meth:`Law.to_fit_dict` (results.json's ``parametric``) and :meth:`Law.to_hint_dict`
(the ``blind`` formulas).
"""

from __future__ import annotations

import copy
from dataclasses import dataclass, field, fields
from enum import StrEnum
from typing import Any

import numpy as np

__all__ = ["STATUSES", "FittedFamily", "Law", "LawStatus", "TableStatus"]


class LawStatus(StrEnum):
    """What a :class:`Law` is worth, from the law itself to a blind hint. A str: ``LawStatus.CLAIMED == "claimed"``,
    written to JSON as the plain word.

    - ``CLAIMED``: the law — one family of the ranked table, the others clearly worse;
    - ``TIE``: the first of families the record cannot tell apart (no family is claimed; predictions use it);
    - ``CANDIDATE``: fitted, not claimed (a row of the table, a post-hoc parametric fit);
    - ``HINT``: a blind formula — a suggestion, never the law."""

    CLAIMED = "claimed"
    TIE = "tie"
    CANDIDATE = "candidate"
    HINT = "hint"


class TableStatus(StrEnum):
    """How a ranked law table ended: :attr:`nnphd.explain.table.LawTable.status`, report.json's ``law.status``. A
    str, written to JSON as the plain word.

    - ``CLAIMED``: one family is claimed, the others clearly worse;
    - ``TIE``: the record cannot tell the best family from others: no family is claimed;
    - ``NONE``: no law is claimed — no candidate beats zero, or the verdict's rules withdrew the table's law
      (:mod:`nnphd.user.rules`). Not the verdict's "none" (the motion is conservative): a verdict of "detected"
      can stand without a law."""

    CLAIMED = "claimed"
    TIE = "tie"
    NONE = "none"


STATUSES = tuple(s.value for s in LawStatus)  # what a Law is worth, as plain words

# a report's law.law (a candidate row of the table): its keys and their types, checked by Law.from_report
_REPORT_KEYS = {"law": str, "title": str, "formula": dict, "latex": dict, "params": dict, "stderr": dict, "method": str}


def _error(where: str, what: str) -> ValueError:
    return ValueError(f"{where}: {what}")


def _is_number(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


@dataclass(frozen=True, eq=False)
class FittedFamily:
    """A :class:`~nnphd.explain.families.Family` with its fitted coefficients β (its ``coef_names``) and nonlinear
    parameters θ (its ``nl_names``): the force g(q, q̇, t) it predicts (:meth:`predict`). What a :class:`Law`
    predicts with, and what a model file keeps of a law (the family's ``spec``, β and θ)."""

    family: Any  # a Family (nnphd.explain.families imports what imports this module: not imported here)
    beta: np.ndarray
    theta: np.ndarray

    def predict(self, q, qd, t, xp=np):
        """g at states q, qd (N, n) and times t (N,): (N, n); ``xp`` numpy, or jax.numpy to trace it (e.g. inside an
        integrator)."""
        q, qd, t = (xp.asarray(a, dtype=float) for a in (q, qd, t))
        theta = xp.asarray(self.theta)
        g = xp.einsum("snk,k->sn", self.family.basis(xp, theta, q, qd, t), xp.asarray(self.beta))
        if self.family.fixed is not None:
            g = g + self.family.fixed(xp, theta, q, qd, t)
        return g


@dataclass(frozen=True)
class Law:
    """A law of f_n and how well it holds.

    ``key``: the family or fit (e.g. "quadratic", "linear_friction", "sparse"); ``title``: its name in words;
    ``formula``: component name → SymPy string (a parametric fit of the whole vector: one entry "f_n"); ``latex``:
    the same in LaTeX (empty where none is made); ``params`` ± ``stderr``: the fitted parameters (empty for a blind
    formula, whose numbers are in the formula); ``method``: how it was fitted. A law of the ranked table also carries
    the ``table`` (every candidate, best first, as report.json writes them) and the families it ``ties`` with
    (``status`` "tie": then no family is claimed and this one, the first, is only what predictions use).
    ``rms`` / ``rel_rms``: the residual rms of a pointwise fit and that over the rms of the learned f_n (None where
    not measured); ``n_terms``: a blind formula's size (nonzero library terms, or expression-tree nodes);
    ``readable``: whether a blind formula is short and close enough to read; ``note``: a line about it."""

    key: str
    title: str
    formula: dict[str, str]
    latex: dict[str, str]
    params: dict[str, float]
    stderr: dict[str, float]
    method: str
    table: tuple[dict, ...] = field(default=(), repr=False)
    status: LawStatus = LawStatus.CLAIMED
    ties: tuple[dict, ...] = field(default=(), repr=False)
    rms: float | None = None
    rel_rms: float | None = None
    n_terms: int | None = None
    readable: bool | None = None
    note: str = ""
    fitted: FittedFamily | None = field(default=None, repr=False, compare=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "status", LawStatus(self.status))  # a plain word is taken as its LawStatus

    def predict(self, q, qd, t=None, xp=np):
        """The law's force at states q, qd (N, n) and times t (N,; None: zeros): (N, n); ``xp`` numpy, or jax.numpy
        to trace it. A law of the ranked table (a fit, or a model loaded by :func:`nnphd.load`) holds its family with
        the fitted coefficients (``fitted``); one read back from a report.json, a parametric fit or a blind formula
        does not: ValueError."""
        if self.fitted is None:
            raise ValueError(f"the law {self.key!r:.60} holds no fitted family to predict with (read from a report?)")
        t = xp.zeros(xp.shape(q)[0]) if t is None else t
        return self.fitted.predict(q, qd, t, xp)

    def text(self) -> str:
        """The law in one line: ``"<component> = <expression>"``, joined by "; "."""
        return "; ".join(f"{c} = {e}" for c, e in self.formula.items())

    # ------------------------------------------------------------------------------------------ JSON boundary
    def to_dict(self) -> dict:
        """Every field under its name (a deep copy) but ``fitted`` (the family's code and arrays: a model file keeps
        them, :meth:`nnphd.NNPhD.save`); :meth:`from_dict` reads it back."""
        return {name: copy.deepcopy(getattr(self, name)) for name in _JSON_FIELDS}

    @classmethod
    def from_dict(cls, d: Any, where: str = "law") -> Law:
        """From :meth:`to_dict`'s dict (e.g. parsed JSON), checked: the fields without a default present, no unknown
        key, each value of its field's type, ``status`` one of :data:`STATUSES`. ValueError ``"<where>: <field> …"``
        otherwise."""
        if not isinstance(d, dict):
            raise _error(where, f"expected an object, got {type(d).__name__}")
        extra = [k for k in d if k not in _JSON_FIELDS]
        if extra:
            raise _error(where, f"unknown field {str(extra[0])!r:.60}")
        vals = {}
        for name in _JSON_FIELDS:
            if name not in d:
                if name in _REQUIRED:
                    raise _error(where, f"{name} is missing")
                continue
            vals[name] = _READ[name](d[name], name, where)
        return cls(**vals)

    @classmethod
    def from_report(cls, report: dict, where: str = "report") -> Law | None:
        """The law of a report.json dict (its ``law`` object, :meth:`nnphd.explain.table.LawTable.to_dict`): None
        without one; with one, of status "claimed" or "tie", carrying the candidates and ties. Checked as untrusted
        input, value by value as :meth:`from_dict` (formulas strings, parameters numbers, the status one of
        :data:`STATUSES`, the candidates and ties objects): ValueError ``"<where>: law.…"`` naming what is wrong."""
        table = report.get("law") or {}
        if not isinstance(table, dict):
            raise _error(where, "law must be an object")
        w = table.get("law")
        if not w:
            return None
        if not isinstance(w, dict):
            raise _error(where, "law.law must be an object")
        for k, typ in _REPORT_KEYS.items():
            if not isinstance(w.get(k), typ):
                raise _error(where, f"law.law.{k} must be a {typ.__name__}")
        cands = _rows(table.get("candidates", []), "law.candidates", where)
        ties = _rows(table.get("ties", []), "law.ties", where)
        status = _status(table.get("status", LawStatus.CLAIMED), "law.status", where)
        return cls(
            w["law"],
            w["title"],
            *(_READ[k](w[k], f"law.law.{k}", where) for k in ("formula", "latex", "params", "stderr")),
            w["method"],
            cands,
            status=status,
            ties=ties,
        )

    def to_fit_dict(self) -> dict:
        """A parametric fit as results.json's ``parametric`` has always held it: form, one-line formula, parameters,
        standard errors, relative residual rms."""
        return {
            "form": self.key,
            "formula": self.text(),
            "params": dict(self.params),
            "stderr": dict(self.stderr),
            "rel_rms": self.rel_rms,
        }

    def to_hint_dict(self) -> dict:
        """A blind formula as the ``blind`` entries of results.json and report.json have always held it."""
        return {
            "method": self.method,
            "formula": dict(self.formula),
            "rel_rms": self.rel_rms,
            "n_terms": self.n_terms,
            "readable": self.readable,
            "note": self.note,
        }


_REQUIRED = ("key", "title", "formula", "latex", "params", "stderr", "method")
_JSON_FIELDS = tuple(f.name for f in fields(Law) if f.name != "fitted")  # what to_dict writes and from_dict reads


def _text(v: Any, name: str, where: str) -> str:
    if not isinstance(v, str):
        raise _error(where, f"{name} must be a string, got {v!r:.60}")
    return v


def _texts(v: Any, name: str, where: str) -> dict[str, str]:
    """An object of strings (a formula by component)."""
    if not isinstance(v, dict):
        raise _error(where, f"{name} must be an object, got {v!r:.60}")
    for k, x in v.items():
        if not isinstance(x, str):
            raise _error(where, f"{name}[{str(k)!r:.40}] must be a string, got {x!r:.60}")
    return dict(v)


def _numbers(v: Any, name: str, where: str) -> dict[str, float]:
    """An object of numbers (parameters, standard errors)."""
    if not isinstance(v, dict):
        raise _error(where, f"{name} must be an object, got {v!r:.60}")
    for k, x in v.items():
        if not _is_number(x):
            raise _error(where, f"{name}[{str(k)!r:.40}] must be a number, got {x!r:.60}")
    return {k: float(x) for k, x in v.items()}


def _rows(v: Any, name: str, where: str) -> tuple[dict, ...]:
    """A list of objects (table rows)."""
    if not isinstance(v, (list, tuple)) or not all(isinstance(r, dict) for r in v):
        raise _error(where, f"{name} must be a list of objects")
    return tuple(v)


def _status(v: Any, name: str, where: str) -> LawStatus:
    if v not in STATUSES:
        raise _error(where, f"{name} must be one of {', '.join(map(repr, STATUSES))}, got {v!r:.60}")
    return LawStatus(v)


def _optional_number(v: Any, name: str, where: str) -> float | None:
    if v is None:
        return None
    if not _is_number(v):
        raise _error(where, f"{name} must be a number or null, got {v!r:.60}")
    return float(v)


def _optional_count(v: Any, name: str, where: str) -> int | None:
    if v is None:
        return None
    if not isinstance(v, int) or isinstance(v, bool) or v < 0:
        raise _error(where, f"{name} must be a count (an integer ≥ 0) or null, got {v!r:.60}")
    return v


def _optional_flag(v: Any, name: str, where: str) -> bool | None:
    if v is not None and not isinstance(v, bool):
        raise _error(where, f"{name} must be true, false or null, got {v!r:.60}")
    return v


_READ = {
    "key": _text,
    "title": _text,
    "formula": _texts,
    "latex": _texts,
    "params": _numbers,
    "stderr": _numbers,
    "method": _text,
    "table": _rows,
    "status": _status,
    "ties": _rows,
    "rms": _optional_number,
    "rel_rms": _optional_number,
    "n_terms": _optional_count,
    "readable": _optional_flag,
    "note": _text,
}
