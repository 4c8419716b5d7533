"""The verdict's rules (:mod:`nnphd.user.rules`) return a new law table and leave the one handed to them as it was;
the statuses they write are the enums: :class:`nnphd.user.result.Status` for the verdict,
:class:`nnphd.explain.law.TableStatus` for how the law table ended."""

from __future__ import annotations

import copy

import pytest

from nnphd.explain.law import LawStatus, TableStatus
from nnphd.user.checks import seed_status
from nnphd.user.result import DetectResult, Status
from nnphd.user.rules import (
    Reconciled,
    combine_seeds,
    reconcile,
    unclaim_active,
    unclaim_against_evidence,
    unclaim_unidentifiable,
    withhold,
)

WINNER = {"law": "vanderpol", "title": "van der Pol", "delta_ic": -3.0, "heldout_ratio": 0.9}
KEYS = ["law", "status", "ties", "reason", "against_velocity", "by_position", "candidates", "passivity", "settings"]


def _table(**changes) -> dict:
    law = {
        "law": WINNER,
        "status": "claimed",
        "ties": [{"law": "rayleigh"}],
        "reason": "r",
        "against_velocity": -0.9,
        "by_position": 0.8,
        "candidates": [],
        "passivity": {"active": True, "active_share": 0.6, "margin": 1.0, "best_passive": "linear"},
        "settings": {},
    }
    return law | changes


def _res(status: str = "inconclusive") -> dict:
    return {
        "status": status,
        "new_physics": True,
        "confidence": 0.6,
        "reasons": ["seed 0: x"],
        "evidence": {"combined": {"direction": "loses energy", "significant": True}},
    }


def _withdrawn(new: dict, keys: list[str], why: str) -> None:
    assert list(new) == keys
    assert new["law"] is None and new["candidate_law"] is WINNER and new["ties"] == [] and new["reason"] == why
    assert new["status"] is TableStatus.NONE and new["status"] == "none"


def test_withhold_returns_a_new_table_and_leaves_its_input_as_it_was():
    law = _table()
    before = copy.deepcopy(law)
    new = withhold(law, Status.INCONCLUSIVE)
    why = "the verdict is 'inconclusive', so no law is claimed (the best candidate, van der Pol, would beat zero: r)"
    _withdrawn(new, [*KEYS, "candidate_law"], why)
    assert law == before and list(law) == KEYS
    kept = withhold(law, Status.DETECTED)  # a detection keeps the law: an equal table, not the same dict
    assert kept == law and kept is not law
    none = {"law": None, "status": "none", "reason": "no candidate"}
    assert withhold(none, Status.NONE, "why") == {"law": None, "status": "none", "reason": "why"}
    assert none["reason"] == "no candidate"


def test_the_unclaim_rules_return_a_new_table_with_the_keys_where_they_were_and_leave_their_input_as_it_was():
    law = _table()
    before = copy.deepcopy(law)
    # a pump (−90 % of its force against the velocity) on a record that loses energy: withdrawn, the share moved last
    new, why = unclaim_against_evidence(_res(), law)
    assert why.startswith("no law is claimed: the best candidate, van der Pol, adds energy (-90% of its force")
    moved = [k for k in KEYS if k != "against_velocity"] + ["against_velocity", "candidate_law"]
    _withdrawn(new, moved, why)
    assert new["against_velocity"] == -0.9 and new["by_position"] == 0.8
    # active on 60 % of the states, only +1.0 in IC ahead of the passive families: withdrawn, passivity moved last
    new, why = unclaim_active(_res(), law)
    assert "adds energy on 60% of the visited states" in why and "only +1.0 in IC" in why
    _withdrawn(new, [k for k in KEYS if k != "passivity"] + ["passivity", "candidate_law"], why)
    # no net work (10 % against the velocity) and 80 % a function of position: withdrawn in place of the keys
    quiet = _table(against_velocity=0.1)
    new, why = unclaim_unidentifiable(quiet)
    assert "(10% of its force against the velocity) and 80% of its force is a function of position" in why
    _withdrawn(new, [*KEYS, "candidate_law"], why)
    assert quiet["law"] is WINNER and quiet["status"] == "claimed" and "candidate_law" not in quiet
    assert law == before and list(law) == KEYS
    # a law that stands: an equal table with the same keys (the share still moved after the table's own entries)
    new, why = unclaim_against_evidence(_res(), _table(against_velocity=0.9))
    assert why is None and new["law"] is WINNER and new["status"] == "claimed" and list(new)[-1] == "against_velocity"
    new, why = unclaim_active(_res(), _table(passivity=None))
    assert why is None and "passivity" not in new and list(new) == [k for k in KEYS if k != "passivity"]


def test_reconcile_returns_the_verdict_as_enums_and_a_new_table():
    law = _table()
    before = copy.deepcopy(law)
    out = reconcile(_res(), law)
    assert isinstance(out, Reconciled) and out.status is Status.INCONCLUSIVE
    assert (out.new_physics, out.confidence, out.reasons) == (True, 0.6, ["seed 0: x"])
    assert out.law["law"] is None and out.law["candidate_law"] is WINNER and out.law["status"] is TableStatus.NONE
    assert law == before and list(law) == KEYS
    out = reconcile(_res("detected"), law)  # a detection claims the law: a new table equal to the one handed in
    assert out.status is Status.DETECTED and out.law == law and out.law is not law


def test_statuses_are_enums_and_the_tables_none_is_not_the_verdicts():
    assert [s.value for s in Status] == ["detected", "none", "inconclusive"]
    assert [s.value for s in TableStatus] == ["claimed", "tie", "none"]
    assert [s.value for s in LawStatus] == ["claimed", "tie", "candidate", "hint"]
    assert TableStatus.NONE is not Status.NONE and type(TableStatus.NONE) is not type(Status.NONE)
    drift = {"significant": False, "valid": True, "bootstrap_fraction": 1.0, "rho_median": 0.0,
             "magnitude_median": 0.0, "slow_ratio_median": 0.0}  # fmt: skip
    tchk = {"significant": False, "valid": True, "gain": 1.0, "testable": "yes"}
    gap = {"large": False, "gap_train": 1.0}
    traj = {"significant": False, "valid": True, "bootstrap_fraction": 0.1, "rate_bound": None, "effect": "flat"}
    status, reason, agree = seed_status(drift, tchk, gap, {}, traj, None, 3)
    assert status is Status.NONE and agree == 0.9 and reason.startswith("a Lagrangian fits the data")
    seeds = [{"seed": k, "status": "none", "reason": "r", "agreement": 1.0} for k in range(2)]
    assert combine_seeds(seeds)[:3] == (Status.NONE, False, 1.0) and combine_seeds(seeds)[0] is Status.NONE


def test_a_report_read_back_gives_the_tables_status_as_its_enum():
    report = {"status": "none", "new_physics": False, "confidence": 0.9, "reasons": [], "law": {"law": None}}
    res = DetectResult.from_dict(report)
    assert res.status is Status.NONE and res.law_status is TableStatus.NONE  # no status written: no law claimed
    res = DetectResult.from_dict(report | {"law": {"law": None, "status": "tie"}})
    assert res.law_status is TableStatus.TIE
    with pytest.raises(ValueError, match="report: law.status must be one of 'claimed', 'tie', 'none', got 'maybe'"):
        DetectResult.from_dict(report | {"law": {"law": None, "status": "maybe"}})
