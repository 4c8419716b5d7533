"""One result type for a law (nnphd.explain.law.Law) — the ranked table's law, a parametric fit and a blind
formula are all a frozen Law; dicts only at the JSON boundary (to_dict / from_dict, checked as untrusted input)."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from nnphd.explain.law import STATUSES, Law
from nnphd.explain.parametric import fit_drag_power, fit_linear_friction
from nnphd.explain.table import Candidate, select_law

FULL = Law(
    key="quadratic",
    title="quadratic drag",
    formula={"x_ddot": "-0.021*x_dot*Abs(x_dot)"},
    latex={"x_ddot": r"- 0.021 x_{dot} \left|{x_{dot}}\right|"},
    params={"c": 0.021},
    stderr={"c": 0.0004},
    method="trajectory",
    table=({"law": "quadratic", "ic": -12.5}, {"law": "none", "ic": 0.0}),
    status="tie",
    ties=({"law": "linear", "ic": -11.0},),
    rms=1.5e-4,
    rel_rms=0.031,
    n_terms=2,
    readable=True,
    note="a note",
)


def test_round_trip_through_json_is_equal():
    d = FULL.to_dict()
    assert set(d) == {f.name for f in dataclasses.fields(Law)} - {"fitted"}  # the fitted family is not JSON
    assert Law.from_dict(d) == FULL
    assert Law.from_dict(json.loads(json.dumps(d))) == FULL  # lists for tuples: the same Law
    bare = Law("none", "t", {}, {}, {}, {}, "pointwise")  # the defaulted fields may be left out
    assert Law.from_dict({k: v for k, v in bare.to_dict().items() if k in ("key", "title", "formula", "latex",
                                                                           "params", "stderr", "method")}) == bare  # fmt: skip
    assert FULL.text() == "x_ddot = -0.021*x_dot*Abs(x_dot)"


def test_a_law_is_frozen_and_one_type_everywhere():
    import nnphd
    from nnphd import api

    assert nnphd.Law is api.Law is Law
    with pytest.raises(dataclasses.FrozenInstanceError):
        FULL.status = "claimed"


@pytest.mark.parametrize(
    "field, value, message",
    [
        ("params", {"c": "0.02"}, "law: params['c'] must be a number"),
        ("params", {"c": True}, "law: params['c'] must be a number"),
        ("stderr", [0.1], "law: stderr must be an object"),
        ("formula", {"x_ddot": 3}, "law: formula['x_ddot'] must be a string"),
        ("latex", "x", "law: latex must be an object"),
        ("key", 7, "law: key must be a string"),
        ("status", "won", "law: status must be one of 'claimed', 'tie', 'candidate', 'hint'"),
        ("table", [1, 2], "law: table must be a list of objects"),
        ("ties", {"law": "x"}, "law: ties must be a list of objects"),
        ("rel_rms", "0.1", "law: rel_rms must be a number or null"),
        ("rms", [1.0], "law: rms must be a number or null"),
        ("n_terms", -1, "law: n_terms must be a count"),
        ("n_terms", 2.0, "law: n_terms must be a count"),
        ("readable", "yes", "law: readable must be true, false or null"),
        ("note", None, "law: note must be a string"),
    ],
)
def test_from_dict_names_the_bad_field(field, value, message):
    d = FULL.to_dict()
    d[field] = value
    with pytest.raises(ValueError) as e:
        Law.from_dict(d)
    assert str(e.value).startswith(message), str(e.value)


def test_from_dict_rejects_missing_and_unknown_fields_and_non_objects():
    d = FULL.to_dict()
    del d["method"]
    with pytest.raises(ValueError, match="^law: method is missing$"):
        Law.from_dict(d)
    with pytest.raises(ValueError, match="^law: unknown field 'code'$"):
        Law.from_dict({**FULL.to_dict(), "code": "import os"})
    with pytest.raises(ValueError, match="^m.json: expected an object, got list$"):
        Law.from_dict([], where="m.json")


def test_from_report_checks_as_before():
    with pytest.raises(ValueError, match="^r: law.law.params must be a dict$"):
        Law.from_report({"law": {"law": {**_row("quadratic", 1, -5.0).to_dict(), "params": [1]}}}, "r")
    with pytest.raises(ValueError, match="^r: law must be an object$"):
        Law.from_report({"law": [1]}, "r")
    assert Law.from_report({"law": {"law": None}}) is None and Law.from_report({}) is None


def test_from_report_checks_the_values_too():
    """An untrusted report.json's law is checked value by value, as Law.from_dict checks a law file."""
    good = _row("quadratic", 1, -5.0).to_dict()
    with pytest.raises(ValueError, match=r"^r: law.law.params\['c'\] must be a number, got 'x'$"):
        Law.from_report({"law": {"law": {**good, "params": {"c": "x"}}}}, "r")
    with pytest.raises(ValueError, match=r"^r: law.law.formula\['x_ddot'\] must be a string, got 3$"):
        Law.from_report({"law": {"law": {**good, "formula": {"x_ddot": 3}}}}, "r")
    with pytest.raises(ValueError, match="^r: law.status must be one of"):
        Law.from_report({"law": {"law": good, "status": "[red]won[/red]"}}, "r")
    with pytest.raises(ValueError, match="^r: law.candidates must be a list of objects$"):
        Law.from_report({"law": {"law": good, "candidates": [1]}}, "r")
    law = Law.from_report({"law": {"law": {**good, "stderr": {"c": float("nan")}}, "status": "tie"}}, "r")
    assert law.status == "tie" and law.params == {k: float(v) for k, v in good["params"].items()}


def test_linear_friction_exact_case_is_a_candidate_law():
    qd = np.random.default_rng(0).normal(size=(200, 1))
    law = fit_linear_friction(qd, -0.3 * qd)  # f_n = −0.3 q̇ exactly
    assert isinstance(law, Law) and law.key == "linear_friction" and law.status == "candidate"
    assert abs(law.params["Gamma_11"] - 0.3) < 1e-9 and law.rel_rms < 1e-9 and law.rms < 1e-9
    assert law.text() == "f_n = -Gamma q_dot, Gamma = [+0.3]"
    d = law.to_fit_dict()  # results.json's "parametric", as it always was
    assert list(d) == ["form", "formula", "params", "stderr", "rel_rms"]
    assert d["form"] == "linear_friction" and d["formula"] == law.text() and d["rel_rms"] == law.rel_rms
    assert Law.from_dict(json.loads(json.dumps(law.to_dict()))) == law


def test_drag_power_exact_case():
    rng = np.random.default_rng(1)
    qd = rng.uniform(0.5, 1.5, (300, 1)) * np.sign(rng.normal(size=(300, 1)))
    law = fit_drag_power(qd, -0.3 * np.sum(qd**2, axis=1, keepdims=True) * qd)  # k = 0.3, m = 1
    assert law.params["k"] == pytest.approx(0.3, abs=1e-9) and law.params["m"] == pytest.approx(1.0, abs=1e-9)
    assert law.rel_rms < 1e-9 and law.text().startswith("f_n = -0.3 (|q_dot|^2)^1 q_dot")


def test_a_blind_formula_is_a_hint_never_the_law():
    pytest.importorskip("pysindy")
    from nnphd.explain.sparse import sparse_formula

    rng = np.random.default_rng(2)
    v, x = rng.uniform(-1.3, 1.3, 300), rng.normal(size=300)
    law = sparse_formula({"x": x, "x_dot": v}, (-0.02 * v)[:, None], ["x_ddot"], velocities=["x_dot"])
    assert law.status == "hint" and law.key == "sparse" and law.params == {} and law.readable and law.n_terms == 1
    assert float(law.formula["x_ddot"].split("*")[0]) == pytest.approx(-0.02, rel=1e-6) and law.rel_rms < 1e-6
    d = law.to_hint_dict()  # the "blind" entries of results.json / report.json, as they always were
    assert list(d) == ["method", "formula", "rel_rms", "n_terms", "readable", "note"]
    assert d["formula"] == law.formula and d["n_terms"] == 1 and d["readable"] is True


def _row(key, k, ic, params=None):
    terms = {"none": (), "linear": ("q̇",), "quadratic": ("|q̇|q̇",)}[key]
    p = params if params is not None else ({"c": 0.5} if k else {})
    r = Candidate(key, key + " title", k, p, {n: 0.01 for n in p}, {"x_ddot": key}, {"x_ddot": key}, 1.0, 1.0, ic,
                  ic, 0.1, terms, method="trajectory")  # fmt: skip
    r.family = object() if key != "none" else None
    return r


@pytest.mark.parametrize("second_ic, status", [(-20.0, "claimed"), (-49.0, "tie")])
def test_a_table_law_is_the_law_report_json_gives_back(second_ic, status):
    rows = [_row("none", 0, 0.0), _row("linear", 1, -50.0, {"gamma": 0.1}), _row("quadratic", 1, second_ic)]
    tab = select_law(rows, 100.0, 1.0, "folds", {}, judge=False)
    law = tab.to_law()
    assert law.status == status == tab.status and law.key == "linear" and law.params == {"gamma": 0.1}
    assert [r["law"] for r in law.ties] == (["quadratic"] if status == "tie" else [])
    assert [r["law"] for r in law.table] == [r.key for r in tab.rows]
    report = json.loads(json.dumps({"law": tab.to_dict()}))  # what report.json holds, read back
    assert Law.from_report(report) == law
    cand = tab.rows[-1].to_law()
    assert cand.status == "candidate" and cand.key == tab.rows[-1].key and cand.table == ()
    assert set(STATUSES) == {"claimed", "tie", "candidate", "hint"}


def test_no_law_without_a_winner():
    tab = select_law([_row("none", 0, 0.0), _row("linear", 1, 5.0)], 100.0, 1.0, "folds", {}, judge=False)
    assert tab.to_law() is None and Law.from_report({"law": tab.to_dict()}) is None
