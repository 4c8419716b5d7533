"""The tables of docs/RESULTS.md, docs/paper.md and docs/scaling.md generated from benchmarks/results/*.json match
the JSON (they cannot drift)."""

from __future__ import annotations

import importlib.util
import os
import re

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def _script():
    spec = importlib.util.spec_from_file_location(
        "results_tables", os.path.join(ROOT, "benchmarks", "results_tables.py")
    )
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_every_generated_table_matches_its_json():
    rt = _script()
    names = []
    for doc in rt.DOCS:
        text = open(doc, encoding="utf-8").read()
        names += re.findall(r"<!-- generated: ([a-z_]+) -->", text)
        new, changed = rt.render(text)
        assert changed == [] and new == text, f"regenerate with: python benchmarks/results_tables.py ({doc}: {changed})"
    assert set(names) == set(rt.TABLES) and len(names) == len(set(names))  # each table once in the pages, none left out


def test_a_table_edited_by_hand_is_found():
    rt = _script()
    text = open(rt.DOC, encoding="utf-8").read()
    edited = text.replace("15 of 15 right", "14 of 15 right", 1)
    assert edited != text
    assert rt.render(edited)[1] == ["declared_field_guard"]
