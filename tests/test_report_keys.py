"""The detect pipeline carries its data in typed values, not in hidden dict keys: every dict that a stage hands to the
next — the derivatives' info, the assessment's report, the law table's settings and entry, the verdict's inputs —
and the report itself hold no key that starts with "_" (a side channel that the JSON boundary has to strip)."""

from __future__ import annotations

import numpy as np
import pytest

import nnphd.explain.search as search
import nnphd.user.assess as assess_mod
import nnphd.user.derivatives as derivatives
import nnphd.user.detect as detect
from nnphd.user.recording import from_arrays

pytestmark = pytest.mark.slow  # a whole detect_data (about 30 s): `python3 dev.py test --slow` and CI


def _hidden(obj, path: str = "") -> list[str]:
    """The paths of the keys starting with "_" anywhere in nested dicts and lists."""
    out = []
    if isinstance(obj, dict):
        for k, v in obj.items():
            if isinstance(k, str) and k.startswith("_"):
                out.append(f"{path}/{k}")
            out += _hidden(v, f"{path}/{k}")
    elif isinstance(obj, (list, tuple)):
        for i, v in enumerate(obj):
            out += _hidden(v, f"{path}[{i}]")
    return out


def test_no_dict_of_the_pipeline_carries_an_underscore_key(monkeypatch):
    handed: dict[str, object] = {}
    derive, assess, find_law, reconcile = derivatives.derive, assess_mod.assess, search.find_law, detect.reconcile

    def derived(*a, **k):
        d = derive(*a, **k)
        handed["derivatives info"] = d.info
        return d

    def assessed(*a, **k):
        r = assess(*a, **k)
        handed["assessment"] = r.report
        return r

    def law_table(*a, **k):
        t = find_law(*a, **k)
        handed[f"law table settings {len(handed)}"] = t.settings
        handed[f"law table {len(handed)}"] = t.to_dict()
        return t

    def reconciled(res, law, field="learned"):
        handed["verdict's evidence"], handed["law entry"] = res, law
        return reconcile(res, law, field)

    monkeypatch.setattr(derivatives, "derive", derived)
    monkeypatch.setattr(assess_mod, "assess", assessed)
    monkeypatch.setattr(search, "find_law", law_table)
    monkeypatch.setattr(detect, "reconcile", reconciled)
    t = np.arange(0.0, 30.0, 0.05)
    x = [np.exp(-0.05 * t) * np.cos(t + p) for p in (0.0, 1.0, 2.0)]
    ud = from_arrays([t] * 3, x, names=["x"])
    result, model = detect.detect_data(ud, None, seed=0, steps=4, n_seeds=1, sr_time=0, law_fit="pointwise")
    handed["report"] = result.report
    assert {"derivatives info", "assessment", "verdict's evidence", "law entry", "report"} <= set(handed)
    assert any(k.startswith("law table ") for k in handed)  # the law table was ranked (pointwise)
    assert {name: _hidden(d) for name, d in handed.items() if _hidden(d)} == {}
    # the rules return a new table: the report's holds every key of the one handed to them (and no hidden one)
    assert set(handed["law entry"]) <= set(result.report["law"]) and model.coords == ("x",)
