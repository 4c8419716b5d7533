"""SweepResult, the typed λ-sweep result: to_dict is results.json's content (keys, order, values), from_dict rebuilds
it and refuses a wrong field by name. Built from a hand-made dict: no training."""

from __future__ import annotations

import copy
import json
import math
import sys
from dataclasses import FrozenInstanceError, fields
from pathlib import Path

import pytest

import nnphd
from nnphd.engine.train import SweepPoint
from nnphd.engine.verdict import PhaseTransition
from nnphd.io.results import json_default
from nnphd.paper.sweep_result import RESULT_KEYS, STATISTIC_NAME, SweepResult, SweepRow

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from tests.fixtures.edit import set_item  # noqa: E402


def _results() -> dict:
    """A results dict as run_sweep writes it (the numbers of a 40-step HO+LD sweep, rounded)."""
    table = [
        {"lam": 0.1, "L_e": 0.1613, "L_b": 1.0672, "L_e_train": 0.1946, "L_b_train": 1.0292, "m_c": 1.193, "m_n": 1.2356},
        {"lam": 0.5, "L_e": 0.3433, "L_b": 0.3995, "L_e_train": 0.3146, "L_b_train": 0.4044, "m_c": 0.8075, "m_n": 0.5164},
        {"lam": 2.0, "L_e": 0.4524, "L_b": 0.0012, "L_e_train": 0.4411, "L_b_train": 0.0013, "m_c": 0.4321, "m_n": 0.9876},
        {"lam": 5.0, "L_e": 0.5031, "L_b": 0.0004, "L_e_train": 0.4987, "L_b_train": 0.0005, "m_c": 0.4102, "m_n": 0.9931},
    ]  # fmt: skip
    verdict = {
        "new_physics": False,
        "ratio": 1.8937294122945576,
        "jump": 0.22546641294568864,
        "L_below": 0.25227592361185364,
        "L_above": 0.4777423365575423,
        "relative_size": 0.5313857902730021,
        "force_norm": 0.8990498904987649,
        "fn_size_from_jump": 0.4777423365575423,
        "fn_size_from_uan": 0.7333670830765696,
        "min_ratio": 3.0,
        "min_relative_size": 0.0001,
        "reason": "no jump of L_e across λ=1 (x1.89 < x3): a Lagrangian explains the force",
    }
    return {
        "system": "ho+ld",
        "description": "harmonic oscillator + linear damping: q̈ = -k q - γ q̇",
        "new_physics": False,
        "truth_conservative": False,
        "statistic": {"name": STATISTIC_NAME, "value": 1.8937294122945576},
        "verdict": verdict,
        "table": table,
        "alignment_lambda_0.1_to_0.5": {"max_m_c": 1.193, "max_m_n": 1.2356},
        "settings": {"system": "ho+ld", "p": 1.0, "steps_per_lambda": 40, "seed": 0, "lambdas": [0.1, 0.5, 2.0, 5.0]},
        "evaluated_on": "test set",
        "wall_time_s": 1.25,
        "resumed_lambdas": [0.1],
        "protocol": None,
        "jax_version": "0.10.2",
    }


def test_round_trip_gives_the_same_dict_and_bytes():
    d = _results()
    res = SweepResult.from_dict(copy.deepcopy(d))
    out = res.to_dict()
    assert out == d and list(out) == list(RESULT_KEYS) == list(d)
    dump = lambda x: json.dumps(x, indent=2, default=json_default, allow_nan=True)  # noqa: E731  (as write_json)
    assert dump(out) == dump(d)
    again = SweepResult.from_dict(json.loads(dump(out)))
    assert again == res and again.to_dict() == d


def test_typed_fields_hold_the_numbers():
    d = _results()
    res = SweepResult.from_dict(d)
    assert res.le_ratio == d["statistic"]["value"] == 1.8937294122945576
    assert isinstance(res.verdict, PhaseTransition) and res.verdict.L_above == 0.4777423365575423
    assert res.new_physics is False and res.truth_conservative is False
    assert [r.lam for r in res.table] == [0.1, 0.5, 2.0, 5.0]
    assert [r.L_e for r in res.table] == [0.1613, 0.3433, 0.4524, 0.5031]
    assert res.table[1] == SweepRow(0.5, 0.3433, 0.3995, 0.3146, 0.4044, 0.8075, 0.5164)
    # the alignment maxima are over 0.1 ≤ λ ≤ 0.5 only (λ = 2 and 5 are outside)
    assert (res.max_m_c, res.max_m_n) == (1.193, 1.2356)
    assert res.resumed_lambdas == (0.1,) and res.wall_time_s == 1.25 and res.protocol is None
    assert nnphd.SweepResult is SweepResult and "SweepResult" in nnphd.__all__


def test_result_is_frozen_and_to_dict_is_a_copy():
    res = SweepResult.from_dict(_results())
    with pytest.raises(FrozenInstanceError):
        res.system = "ho+mf"
    with pytest.raises(FrozenInstanceError):
        res.verdict.ratio = 10.0
    out = res.to_dict()
    out["settings"]["seed"] = 99
    out["verdict"]["ratio"] = 10.0
    assert res.settings["seed"] == 0 and res.le_ratio == 1.8937294122945576


def test_row_keys_are_those_of_a_sweep_point():
    pt = SweepPoint(0.5, 0.1, 0.2, 0.3, 0.4, None, None)
    assert [f.name for f in fields(SweepRow)] == list(pt.row())
    assert SweepRow(**pt.row()).to_dict() == pt.row()


def test_no_alignment_gives_null_maxima():
    d = _results()
    for r in d["table"]:
        r["m_c"] = r["m_n"] = None
    d["alignment_lambda_0.1_to_0.5"] = {"max_m_c": None, "max_m_n": None}
    res = SweepResult.from_dict(d)
    assert res.max_m_c is None and res.max_m_n is None and res.to_dict() == d


def test_nan_ratio_survives_the_round_trip():
    d = _results()
    d["verdict"]["ratio"] = d["statistic"]["value"] = math.nan
    res = SweepResult.from_dict(json.loads(json.dumps(d)))
    assert math.isnan(res.le_ratio) and math.isnan(res.to_dict()["statistic"]["value"])


def _set(path: str, value):
    """The hand-made dict with the item at ``path`` ("a/b/0/c") replaced (or removed, for value ...)."""
    return set_item(_results(), path, value)


@pytest.mark.parametrize(
    "path,value,message",
    [
        ("system", 3, "system must be a string, got 3"),
        ("truth_conservative", "no", "truth_conservative must be a bool"),
        ("new_physics", 0, "new_physics must be a bool"),
        ("wall_time_s", "1.2", "wall_time_s must be a number, got '1.2'"),
        ("wall_time_s", True, "wall_time_s must be a number, got True"),
        ("verdict/ratio", "big", "verdict.ratio must be a number"),
        ("verdict/new_physics", 1, "verdict.new_physics must be a bool"),
        ("verdict/reason", None, "verdict.reason must be a string"),
        ("verdict/jump", ..., "verdict has no 'jump'"),
        ("table", {}, "table must be a list"),
        ("table/2/L_e", None, r"table\[2\].L_e must be a number, got None"),
        ("table/0/m_n", None, r"table\[0\]: m_c and m_n must both be numbers or both null"),
        ("table/1", [0.5], r"table\[1\] must be an object, got list"),
        ("resumed_lambdas/0", "0.1", r"resumed_lambdas\[0\] must be a number"),
        ("settings", [], "settings must be a dict"),
        ("protocol", "fast", "protocol must be an object or null"),
        ("jax_version", 10, "jax_version must be a string"),
        ("new_physics", True, "new_physics is True, the verdict's is False"),
        ("statistic/value", 2.5, "statistic.value is 2.5, the verdict's ratio is 1.89"),
        ("statistic/name", "ratio", "statistic.name must be"),
        ("alignment_lambda_0.1_to_0.5/max_m_c", 0.5, r"alignment_\S+.max_m_c is 0.5, the table's is 1.193"),
        ("evaluated_on", ..., "the result has no 'evaluated_on'"),
        ("extra", 1, "the result has an unknown key 'extra'"),
    ],
)
def test_from_dict_names_the_wrong_field(path, value, message):
    with pytest.raises(ValueError, match=f"^sweep result: {message}"):
        SweepResult.from_dict(_set(path, value))


def test_from_dict_refuses_a_non_object_and_names_where():
    with pytest.raises(ValueError, match="^out/results.json: the result must be an object, got list"):
        SweepResult.from_dict([], where="out/results.json")
