"""A tie of the law table re-judged over the whole record (:mod:`nnphd.explain.wholerecord`): the decision rules on
constructed tables (fast), and the string pendulum in air (linear + quadratic drag, two minutes at 20 Hz), whose tie
of three families the whole record breaks (slow: the law stage, tens of seconds)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pytest

from nnphd.explain import wholerecord as W
from nnphd.explain.table import IC_TIE, LawTable


@dataclass
class _Row:  # what break_tie reads of a Candidate
    key: str
    ic: float = 0.0
    k: int = 2
    heldout_mse: float = 1.0
    significant: bool = True
    params: dict = field(default_factory=lambda: {"a": 1.0})
    stderr: dict = field(default_factory=lambda: {"a": 0.1})

    @property
    def title(self) -> str:
        return self.key


def _tie(keys=("power", "linear+quadratic", "coulomb+quadratic")) -> LawTable:
    rows = [_Row(k) for k in keys]
    return LawTable(rows, rows[0], "a tie", 100.0, 1.0, "windows", {}, ties=rows[1:])


@dataclass
class _Ranked:
    rows: list
    n_eff: float = 2365.0
    tau: float = 1.0
    settings: dict = field(default_factory=lambda: {"windows": 1, "in_sample": True, "conservative_columns": 3})


def _lib():
    ctx = {"t": np.zeros(2365)}
    return LawTable([], None, "", 1.0, 1.0, "", {}, whole_record=ctx)


N_RES = 2365  # the residuals of _lib()'s record: its n_eff with τ = 1


def _with_fits(monkeypatch, ics: dict, chi2n: float = 1.0, significant=True, short: dict | None = None):
    """Whole-record fits whose n_eff·log(χ²/N) differ by ``ics`` (the χ²/N of each family set so; their IC adds
    (k + K_c)·log n_eff, K_c = 3); ``short``: a second library's fits, K_c = 1, its χ² terms by the same rule."""

    def ranked(d: dict, kc: int) -> _Ranked:
        rows = [_Row("none", ic=1e4, heldout_mse=50.0)] + [
            _Row(k, heldout_mse=chi2n * np.exp(v / N_RES), significant=significant) for k, v in d.items()
        ]
        return _Ranked(rows, settings={"windows": 1, "in_sample": True, "conservative_columns": kc})

    fits = [("the conservative library", ranked(ics, 3))]
    if short is not None:
        fits.append(("the short library", ranked(short, 1)))
    monkeypatch.setattr(W, "whole_record_fits", lambda ctx, keys: (fits, None))


def test_the_whole_record_claims_the_family_the_others_trail_by_ic_tie(monkeypatch):
    _with_fits(monkeypatch, {"power": 28.1, "linear+quadratic": 0.0, "coulomb+quadratic": 49.9})
    table = _tie()
    out = W.break_tie(table, _lib())
    assert out.status == "claimed" and out.law.key == "linear+quadratic"
    assert out.law is table.ties[0]  # the table's own row (windows + envelope), not a new fit
    wr = out.settings["whole_record"]
    assert wr["status"] == "claimed" and sorted(wr["dropped"]) == ["coulomb+quadratic", "power"]
    assert wr["delta_ic"]["power"] == pytest.approx(28.1)
    assert "whole record tells them apart" in out.reason


def test_a_family_within_ic_tie_stays_in_a_narrowed_tie(monkeypatch):
    _with_fits(monkeypatch, {"power": IC_TIE - 0.5, "linear+quadratic": 0.0, "coulomb+quadratic": IC_TIE + 0.5})
    out = W.break_tie(_tie(), _lib())
    assert out.status == "tie"
    assert [out.law.key, *(r.key for r in out.ties)] == ["linear+quadratic", "power"]
    assert out.settings["whole_record"]["dropped"] == ["coulomb+quadratic"]


@pytest.mark.parametrize(
    ("ics", "chi2n", "significant", "why"),
    [
        ({"power": 3.0, "linear+quadratic": 0.0, "coulomb+quadratic": 5.9}, 1.0, True, "cannot tell them apart"),
        ({"power": 30.0, "linear+quadratic": 0.0, "coulomb+quadratic": 50.0}, 2.5, True, "to its noise (χ²/N ≤ 2"),
        ({"power": 30.0, "linear+quadratic": 0.0, "coulomb+quadratic": 50.0}, 1.0, False, "not eligible"),
    ],
)
def test_the_tie_stands_where_the_whole_record_cannot_judge(monkeypatch, ics, chi2n, significant, why):
    _with_fits(monkeypatch, ics, chi2n, significant)
    table = _tie()
    out = W.break_tie(table, _lib())
    assert out.status == "tie" and out.law is table.law and out.ties == table.ties
    assert out.settings["whole_record"]["status"] == "tie stands"
    assert why in out.settings["whole_record"]["why"]


def test_each_family_is_judged_at_its_better_library(monkeypatch):
    """Beside the full library dry + quadratic is 2.7 ahead in χ² (its conservative columns trade with the friction);
    beside the short one, two columns fewer (2·log 2365 ≈ 15.6 less IC), viscous + quadratic fits as well as there and
    dry + quadratic 40 worse — each family at its lower IC: viscous + quadratic (short) 15.6 − 2.7 ahead of dry +
    quadratic (full), and the whole record decides."""
    _with_fits(monkeypatch, {"linear+quadratic": 2.7, "coulomb+quadratic": 0.0},
               short={"linear+quadratic": 2.7, "coulomb+quadratic": 40.0})  # fmt: skip
    out = W.break_tie(_tie(("coulomb+quadratic", "linear+quadratic")), _lib())
    wr = out.settings["whole_record"]
    assert out.status == "claimed" and out.law.key == "linear+quadratic", wr
    assert wr["library"] == {"linear+quadratic": "the short library", "coulomb+quadratic": "the conservative library"}
    assert wr["delta_ic"]["coulomb+quadratic"] == pytest.approx(2 * np.log(N_RES) - 2.7, abs=1e-6)


def test_no_context_or_a_missing_fit_leaves_the_tie(monkeypatch):
    table = _tie()
    out = W.break_tie(table, LawTable([], None, "", 1.0, 1.0, "", {}))
    assert out.status == "tie" and "no whole-record fit" in out.settings["whole_record"]["why"]
    _with_fits(monkeypatch, {"power": 30.0, "linear+quadratic": 0.0})  # coulomb+quadratic not at an optimum
    out = W.break_tie(table, _lib())
    assert out.status == "tie" and "coulomb+quadratic" in out.settings["whole_record"]["why"]


def test_a_claimed_table_is_not_touched(monkeypatch):
    rows = [_Row("linear")]
    table = LawTable(rows, rows[0], "claimed", 1.0, 1.0, "", {})
    monkeypatch.setattr(W, "whole_record_fits", lambda ctx, keys: pytest.fail("fitted a claimed table"))
    assert W.break_tie(table, _lib()) is table


@pytest.mark.slow  # tens of seconds: run by `python3 dev.py test --slow` (and by CI)
def test_the_string_pendulum_in_air_is_told_apart_by_its_whole_record(tmp_path):
    """Linear + quadratic drag over 60 periods (video noise 0.003 rad): the windows and the envelope leave a power law
    and dry + quadratic within ΔIC 6; the whole record puts both ≥ 6 behind (an independent whole-trajectory fit of
    the positions, benchmarks/friction_reference.py: dry + quadratic Δχ² 38 behind on seed 0) and the true family
    is claimed with its coefficients."""
    from tests.test_friction_lookalikes import _force_error, _law_table

    rec, tab = _law_table("linear-quadratic", tmp_path)
    out = W.break_tie(tab, tab)  # the law stage alone: the library is the base
    wr = out.settings.get("whole_record", {})
    assert out.status == "claimed" and out.law.key == "linear+quadratic", (out.reason, wr)
    assert wr["chi2_per_row"] < W.MAX_CHI2_PER_ROW
    assert all(d >= IC_TIE for k, d in wr["delta_ic"].items() if k != "linear+quadratic"), wr["delta_ic"]
    for p, v in rec.truth["coefficients"].items():
        assert out.law.params[p] == pytest.approx(v, rel=0.1), (p, out.law.params)
    assert _force_error(rec, out.law) < 0.1
