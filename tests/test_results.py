"""Typed results: ``NNPhD.result_`` and :func:`nnphd.read_report` give a :class:`nnphd.DetectResult` (a
:class:`nnphd.Verdict` with a :class:`nnphd.Status`, the claimed :class:`nnphd.Law`, timings, warnings …); a dict
only at the JSON boundary. A report.json read back is untrusted input: checked, one-line ValueError naming the
path."""

from __future__ import annotations

import json
import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from nnphd.api import DetectResult, Law, Status, Verdict, read_report
from tests.fixtures.modelfiles import tiny_model

LAW = {
    "law": "quadratic",
    "title": "quadratic drag −c |q̇| q̇",
    "formula": {"x": "-0.021*x_dot*Abs(x_dot)"},
    "latex": {"x": r"- 0.021 \dot{x} \left|\dot{x}\right|"},
    "params": {"c": 0.021},
    "stderr": {"c": 0.001},
    "method": "trajectory",
    "delta_ic": -190.0,
}
REPORT = {
    "file": "throw.csv",
    "status": "detected",
    "new_physics": True,
    "confidence": 0.75,
    "reasons": ["beside the declared uniform field the motion needs a non-conservative force"],
    "statistic": {"name": "z", "value": None},
    "effect": "lowers the error of the fit of the positions by 48%",
    "evidence": {"energy_trend": {"z": 4.0}},
    "law": {"law": LAW, "status": "tie", "ties": [dict(LAW, law="linear")], "candidates": [LAW], "reason": "tie"},
    "timings": {"total_s": 12.5, "stages": {"training": {"wall_s": 9.0}}},
    "warnings": ["x: quantized"],
    "field": {"kind": "uniform", "g": {"x": -9.81}},
    "settings": {"seed": 0, "n_seeds": 2, "law_fit": "auto"},
}


def test_a_status_is_a_word_and_written_as_one():
    assert Status.DETECTED == "detected" and Status("none") is Status.NONE
    assert json.dumps({"s": Status.INCONCLUSIVE}) == '{"s": "inconclusive"}'
    assert [s.value for s in Status] == ["detected", "none", "inconclusive"]


def test_a_report_dict_becomes_typed_and_back():
    r = DetectResult.from_dict(REPORT)
    assert r.verdict == Verdict(Status.DETECTED, True, 0.75, tuple(REPORT["reasons"]), None)
    assert r.status is Status.DETECTED
    assert isinstance(r.law, Law) and r.law.key == "quadratic" and r.law.params == {"c": 0.021}
    assert r.law.status == "tie" and r.law.ties[0]["law"] == "linear" and r.law_status == "tie"
    assert r.timings["total_s"] == 12.5 and r.warnings == ("x: quantized",) and r.field["kind"] == "uniform"
    assert r.settings["law_fit"] == "auto" and r.effect.startswith("lowers")
    d = r.to_dict()
    assert d == REPORT and d is not r.report  # a copy: changing it changes nothing here
    d["status"] = "none"
    assert r.to_dict()["status"] == "detected"
    # no law claimed: law None, the table's status and reason kept
    assert math.isnan(DetectResult.from_dict(dict(REPORT, confidence=float("nan"))).verdict.confidence)  # not known
    none = dict(REPORT, status="none", new_physics=False, law={"law": None, "status": "none", "reason": "no law"})
    r = DetectResult.from_dict(none)
    assert r.law is None and r.law_status == "none" and r.law_reason == "no law" and r.status is Status.NONE


def test_the_estimator_holds_the_typed_result(tmp_path):
    m = tiny_model(REPORT, tmp_path / "m.npz")  # a model file with REPORT as its report, read by nnphd.load
    assert m.result_ == DetectResult.from_dict(REPORT)
    assert m.status_ is Status.DETECTED and m.verdict_ is m.result_.verdict and m.law_ is m.result_.law


def test_a_report_file_is_read_back_and_checked(tmp_path):
    path = tmp_path / "report.json"
    path.write_text(json.dumps(REPORT))
    assert read_report(path).to_dict() == REPORT
    bad = {
        "not json {": "not a readable report.json (JSONDecodeError",
        json.dumps([1, 2]): "expected a JSON object, got list",
        json.dumps(
            dict(REPORT, status="maybe")
        ): "status must be one of 'detected', 'none', 'inconclusive', got 'maybe'",
        json.dumps(dict(REPORT, confidence=2)): "confidence must be a number in [0, 1], got 2",
        json.dumps(dict(REPORT, confidence=True)): "confidence must be a number in [0, 1], got True",
        json.dumps(dict(REPORT, reasons="one")): "reasons must be a list of strings",
        json.dumps(dict(REPORT, law={"law": dict(LAW, title=7)})): "law.law.title must be a str",
        json.dumps(dict(REPORT, law={"law": LAW, "ties": {}})): "law.ties must be a list of objects",
        json.dumps(dict(REPORT, warnings=[1])): "warnings must be a list of strings",
        json.dumps(dict(REPORT, timings=[])): "timings must be an object",
        b"\xff\xfe": "not a readable report.json (UnicodeDecodeError",
    }
    for text, msg in bad.items():
        (path.write_bytes if isinstance(text, bytes) else path.write_text)(text)
        with pytest.raises(ValueError) as e:
            read_report(path)
        assert str(e.value).startswith(f"{path}: ") and msg in str(e.value) and "\n" not in str(e.value), e.value
    with pytest.raises(ValueError, match="not a readable report.json"):
        read_report(tmp_path / "missing.json")


def test_a_report_larger_than_a_report_is_refused_unread(tmp_path, monkeypatch):
    path = tmp_path / "report.json"
    path.write_text(json.dumps(REPORT))
    import nnphd.user.result as result

    monkeypatch.setattr(result, "MAX_REPORT_BYTES", 100)
    with pytest.raises(ValueError, match=r"bytes, more than a report holds \(100 at most\)"):
        read_report(path)


JSON = st.recursive(
    st.none() | st.booleans() | st.floats(allow_nan=False) | st.integers() | st.text(max_size=8),
    lambda c: st.lists(c, max_size=4) | st.dictionaries(st.text(max_size=8), c, max_size=4),
    max_leaves=20,
)


@settings(max_examples=150, deadline=None)
@given(key=st.sampled_from(sorted(REPORT)), value=JSON)
def test_any_json_in_any_field_is_typed_or_refused_in_one_line(key, value):
    try:
        r = DetectResult.from_dict(dict(REPORT, **{key: value}))
    except ValueError as e:
        assert str(e).startswith("report: ") and "\n" not in str(e)
    else:
        assert isinstance(r.status, Status) and 0 <= r.verdict.confidence <= 1
