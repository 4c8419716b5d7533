"""`SweepResult`: a λ-sweep's result, typed — what :func:`nnphd.paper.sweep.run_sweep` returns.

Dicts only at the JSON boundary: :meth:`SweepResult.to_dict` is results.json's content (the keys and order it always
had), :meth:`SweepResult.from_dict` reads such a dict back, checked as untrusted input (every field's type, no missing
or unknown keys, and the copies the dict keeps — ``new_physics``, ``statistic``, the alignment maxima — agreeing with
the verdict and the table they repeat). A field that is wrong gives one ValueError naming it.
"""

from __future__ import annotations

import copy
from dataclasses import asdict, dataclass, fields
from typing import Any

from nnphd.engine.verdict import PhaseTransition
from nnphd.paper.result_checks import exact_keys, field_error, number, of_type, same_number

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
        exact_keys(d, keys, name, where)
        row = {k: number(d[k], f"{name}.{k}", where, optional=k in ("m_c", "m_n")) for k in keys}
        if (row["m_c"] is None) != (row["m_n"] is None):
            raise field_error(where, f"{name}: m_c and m_n must both be numbers or both null")
        return cls(**row)


def _phase_transition(d: Any, where: str) -> PhaseTransition:
    """results.json's "verdict", checked."""
    keys = tuple(f.name for f in fields(PhaseTransition))
    exact_keys(d, keys, "verdict", where)
    vals = {}
    for k in keys:
        if k == "new_physics":
            vals[k] = of_type(d[k], bool, "verdict.new_physics", where)
        elif k == "reason":
            vals[k] = of_type(d[k], str, "verdict.reason", where)
        else:
            vals[k] = number(d[k], f"verdict.{k}", where)
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
        exact_keys(d, RESULT_KEYS, "the result", where)
        table = of_type(d["table"], list, "table", where)
        resumed = of_type(d["resumed_lambdas"], list, "resumed_lambdas", where)
        protocol = d["protocol"]
        if protocol is not None and not isinstance(protocol, dict):
            raise field_error(where, f"protocol must be an object or null, got {protocol!r:.60}")
        res = cls(
            system=of_type(d["system"], str, "system", where),
            description=of_type(d["description"], str, "description", where),
            truth_conservative=of_type(d["truth_conservative"], bool, "truth_conservative", where),
            verdict=_phase_transition(d["verdict"], where),
            table=tuple(SweepRow.from_dict(r, f"table[{i}]", where) for i, r in enumerate(table)),
            settings=copy.deepcopy(of_type(d["settings"], dict, "settings", where)),
            evaluated_on=of_type(d["evaluated_on"], str, "evaluated_on", where),
            wall_time_s=number(d["wall_time_s"], "wall_time_s", where),
            resumed_lambdas=tuple(number(x, f"resumed_lambdas[{i}]", where) for i, x in enumerate(resumed)),
            protocol=copy.deepcopy(protocol),
            jax_version=of_type(d["jax_version"], str, "jax_version", where),
        )
        res._check_copies(d, where)
        return res

    def _check_copies(self, d: dict, where: str) -> None:
        """The dict repeats the verdict's call and ratio, and the table's alignment maxima: they must agree."""
        if of_type(d["new_physics"], bool, "new_physics", where) != self.new_physics:
            raise field_error(where, f"new_physics is {d['new_physics']}, the verdict's is {self.new_physics}")
        stat = exact_keys(d["statistic"], ("name", "value"), "statistic", where)
        if stat["name"] != STATISTIC_NAME:
            raise field_error(where, f"statistic.name must be {STATISTIC_NAME!r}, got {stat['name']!r:.60}")
        if not same_number(number(stat["value"], "statistic.value", where), self.le_ratio):
            raise field_error(where, f"statistic.value is {stat['value']!r}, the verdict's ratio is {self.le_ratio!r}")
        al = exact_keys(d[ALIGNMENT_KEY], ("max_m_c", "max_m_n"), ALIGNMENT_KEY, where)
        for k, derived in (("max_m_c", self.max_m_c), ("max_m_n", self.max_m_n)):
            if not same_number(number(al[k], f"{ALIGNMENT_KEY}.{k}", where, optional=True), derived):
                raise field_error(where, f"{ALIGNMENT_KEY}.{k} is {al[k]!r}, the table's is {derived!r}")
