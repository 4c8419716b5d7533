"""`SweepResult`: a λ-sweep's result, typed — what :func:`nnphd.paper.sweep.run_sweep` returns.

Dicts only at the JSON boundary: :meth:`SweepResult.to_dict` is results.json's content (the keys and order it always
had), :meth:`SweepResult.from_dict` reads such a dict back, checked as untrusted input (every field's type, no missing
or unknown keys, and the copies the dict keeps — ``new_physics``, ``statistic``, the alignment maxima — agreeing with
the verdict and the table they repeat). A field that is wrong gives one ValueError naming it.
"""

from __future__ import annotations

import copy
import math
from dataclasses import asdict, dataclass, fields
from typing import Any

from nnphd.engine.verdict import PhaseTransition

STATISTIC_NAME = "ratio of median L_e above λ=1 to median L_e below λ=1"  # results.json's "statistic" → "name"
ALIGNMENT_KEY = "alignment_lambda_0.1_to_0.5"
ALIGNMENT_RANGE = (0.1, 0.5)  # the λ over which the alignments' maxima are taken
RESULT_KEYS = (
    "system",
    "description",
    "new_physics",
    "truth_conservative",
    "statistic",
    "verdict",
    "table",
    ALIGNMENT_KEY,
    "settings",
    "evaluated_on",
    "wall_time_s",
    "resumed_lambdas",
    "protocol",
    "jax_version",
)


def _error(where: str, what: str) -> ValueError:
    return ValueError(f"{where}: {what}")


def _keys(d: Any, keys: tuple[str, ...], name: str, where: str) -> dict:
    """``d`` as an object with exactly ``keys``."""
    if not isinstance(d, dict):
        raise _error(where, f"{name} must be an object, got {type(d).__name__}")
    missing = [k for k in keys if k not in d]
    extra = [k for k in d if k not in keys]
    if missing:
        raise _error(where, f"{name} has no {missing[0]!r}")
    if extra:
        raise _error(where, f"{name} has an unknown key {str(extra[0])!r:.60}")
    return d


def _number(v: Any, name: str, where: str, optional: bool = False) -> float | None:
    if v is None and optional:
        return None
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise _error(where, f"{name} must be a number{' or null' if optional else ''}, got {v!r:.60}")
    return float(v)


def _typed(v: Any, typ: type, name: str, where: str):
    if not isinstance(v, typ):
        raise _error(where, f"{name} must be a {'string' if typ is str else typ.__name__}, got {v!r:.60}")
    return v


def _same(a: float | None, b: float | None) -> bool:
    return a == b or (a is not None and b is not None and math.isnan(a) and math.isnan(b))


@dataclass(frozen=True)
class SweepRow:
    """One λ of a sweep: the losses on the evaluation set (``L_e``, ``L_b``) and on the training set, and the
    alignments ``m_c``, ``m_n`` of the learned forces with the true ones (None where the truth is not known). Its
    dict is a row of results.json's ``table``."""

    lam: float
    L_e: float
    L_b: float
    L_e_train: float
    L_b_train: float
    m_c: float | None = None
    m_n: float | None = None

    def to_dict(self) -> dict:
        return asdict(self)

    @classmethod
    def from_dict(cls, d: Any, name: str = "row", where: str = "sweep result") -> SweepRow:
        keys = tuple(f.name for f in fields(cls))
        _keys(d, keys, name, where)
        row = {k: _number(d[k], f"{name}.{k}", where, optional=k in ("m_c", "m_n")) for k in keys}
        if (row["m_c"] is None) != (row["m_n"] is None):
            raise _error(where, f"{name}: m_c and m_n must both be numbers or both null")
        return cls(**row)


def _phase_transition(d: Any, where: str) -> PhaseTransition:
    """results.json's "verdict", checked."""
    keys = tuple(f.name for f in fields(PhaseTransition))
    _keys(d, keys, "verdict", where)
    vals = {}
    for k in keys:
        if k == "new_physics":
            vals[k] = _typed(d[k], bool, "verdict.new_physics", where)
        elif k == "reason":
            vals[k] = _typed(d[k], str, "verdict.reason", where)
        else:
            vals[k] = _number(d[k], f"verdict.{k}", where)
    return PhaseTransition(**vals)


@dataclass(frozen=True)
class SweepResult:
    """A finished λ-sweep of a catalogue system (:func:`nnphd.paper.sweep.run_sweep`), typed.

    ``verdict``: the phase transition read off L_e(λ) (:class:`nnphd.engine.verdict.PhaseTransition`); ``le_ratio``
    its statistic, how many times the held-out error L_e grows across λ = 1 (results.json's ``statistic.value``);
    ``table``: one :class:`SweepRow` per λ, in the order trained; ``max_m_c`` / ``max_m_n``: the largest alignments
    over 0.1 ≤ λ ≤ 0.5; ``settings``: everything the run depended on; ``evaluated_on``: the test set, or the training
    trajectory for trajectory systems (as the paper); ``resumed_lambdas``: the λ loaded from a checkpoint;
    ``protocol``: what mode "fast" trained (None in the other modes). :meth:`to_dict` is results.json's content."""

    system: str
    description: str
    truth_conservative: bool
    verdict: PhaseTransition
    table: tuple[SweepRow, ...]
    settings: dict
    evaluated_on: str
    wall_time_s: float
    resumed_lambdas: tuple[float, ...]
    protocol: dict | None
    jax_version: str

    @property
    def new_physics(self) -> bool:
        """The verdict: a non-conservative force is there (``verdict.new_physics``)."""
        return self.verdict.new_physics

    @property
    def le_ratio(self) -> float:
        """The phase-transition statistic: the median L_e above λ = 1 over the median below (``verdict.ratio``;
        results.json's ``statistic.value``)."""
        return self.verdict.ratio

    def _aligned(self) -> list[SweepRow]:
        lo, hi = ALIGNMENT_RANGE
        return [r for r in self.table if lo <= r.lam <= hi and r.m_c is not None]

    @property
    def max_m_c(self) -> float | None:
        """The largest m_c over 0.1 ≤ λ ≤ 0.5 (None without alignments there)."""
        aligned = self._aligned()
        return max(r.m_c for r in aligned) if aligned else None

    @property
    def max_m_n(self) -> float | None:
        """The largest m_n over 0.1 ≤ λ ≤ 0.5 (None without alignments there)."""
        aligned = self._aligned()
        return max(r.m_n for r in aligned) if aligned else None

    def to_dict(self) -> dict:
        """results.json's content (a copy: changing it changes nothing here)."""
        return {
            "system": self.system,
            "description": self.description,
            "new_physics": self.new_physics,
            "truth_conservative": self.truth_conservative,
            "statistic": {"name": STATISTIC_NAME, "value": self.le_ratio},
            "verdict": self.verdict.to_dict(),
            "table": [r.to_dict() for r in self.table],
            ALIGNMENT_KEY: {"max_m_c": self.max_m_c, "max_m_n": self.max_m_n},
            "settings": copy.deepcopy(self.settings),
            "evaluated_on": self.evaluated_on,
            "wall_time_s": self.wall_time_s,
            "resumed_lambdas": list(self.resumed_lambdas),
            "protocol": copy.deepcopy(self.protocol),
            "jax_version": self.jax_version,
        }

    @classmethod
    def from_dict(cls, d: Any, where: str = "sweep result") -> SweepResult:
        """From a results dict (results.json's content), checked as untrusted input; ValueError with one line naming
        the field when it is not one."""
        _keys(d, RESULT_KEYS, "the result", where)
        table = _typed(d["table"], list, "table", where)
        resumed = _typed(d["resumed_lambdas"], list, "resumed_lambdas", where)
        protocol = d["protocol"]
        if protocol is not None and not isinstance(protocol, dict):
            raise _error(where, f"protocol must be an object or null, got {protocol!r:.60}")
        res = cls(
            system=_typed(d["system"], str, "system", where),
            description=_typed(d["description"], str, "description", where),
            truth_conservative=_typed(d["truth_conservative"], bool, "truth_conservative", where),
            verdict=_phase_transition(d["verdict"], where),
            table=tuple(SweepRow.from_dict(r, f"table[{i}]", where) for i, r in enumerate(table)),
            settings=copy.deepcopy(_typed(d["settings"], dict, "settings", where)),
            evaluated_on=_typed(d["evaluated_on"], str, "evaluated_on", where),
            wall_time_s=_number(d["wall_time_s"], "wall_time_s", where),
            resumed_lambdas=tuple(_number(x, f"resumed_lambdas[{i}]", where) for i, x in enumerate(resumed)),
            protocol=copy.deepcopy(protocol),
            jax_version=_typed(d["jax_version"], str, "jax_version", where),
        )
        res._check_copies(d, where)
        return res

    def _check_copies(self, d: dict, where: str) -> None:
        """The dict repeats the verdict's call and ratio, and the table's alignment maxima: they must agree."""
        if _typed(d["new_physics"], bool, "new_physics", where) != self.new_physics:
            raise _error(where, f"new_physics is {d['new_physics']}, the verdict's is {self.new_physics}")
        stat = _keys(d["statistic"], ("name", "value"), "statistic", where)
        if stat["name"] != STATISTIC_NAME:
            raise _error(where, f"statistic.name must be {STATISTIC_NAME!r}, got {stat['name']!r:.60}")
        if not _same(_number(stat["value"], "statistic.value", where), self.le_ratio):
            raise _error(where, f"statistic.value is {stat['value']!r}, the verdict's ratio is {self.le_ratio!r}")
        al = _keys(d[ALIGNMENT_KEY], ("max_m_c", "max_m_n"), ALIGNMENT_KEY, where)
        for k, derived in (("max_m_c", self.max_m_c), ("max_m_n", self.max_m_n)):
            if not _same(_number(al[k], f"{ALIGNMENT_KEY}.{k}", where, optional=True), derived):
                raise _error(where, f"{ALIGNMENT_KEY}.{k} is {al[k]!r}, the table's is {derived!r}")
