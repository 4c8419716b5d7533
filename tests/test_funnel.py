"""The law search's funnel (issue 57): the shortlist is fitted by shooting in rounds, in the pointwise order, while a
round still lands within reach of the best eligible IC; then the special cases of the rows within reach (the
parsimony rule may prefer one); the whole shortlist when the reach is infinite."""

from __future__ import annotations

import math
from types import SimpleNamespace

import pytest


def _row(key, ic, terms=(), significant=True):
    return SimpleNamespace(key=key, ic=ic, terms=list(terms), significant=significant)


def _run(cands, reach, threads=1):
    """fit_rows with the funnel over fake rows whose fitted IC is fixed: (the keys fitted in order, the funnel)."""
    from nnphd.explain.trajectory import Funnel, fit_rows

    def fit(ci, row, warm=None):
        return (None if row.ic is None else row), None

    funnel = Funnel(lambda entries: list(entries), reach)
    out = fit_rows(fit, _row("none", 0.0), cands, threads, funnel)
    return [r.key for r in out], funnel


@pytest.mark.parametrize("threads", [1, 2])
def test_a_round_out_of_reach_ends_the_funnel(threads):
    from nnphd.explain.trajectory import FUNNEL_BATCH

    assert FUNNEL_BATCH == 4
    ics = [-100.0, -97.0, -40.0, -30.0, -95.5, -20.0, -10.0, -5.0, -93.0, -92.0, -1.0]
    cands = [_row(f"f{i}", ic, [f"t{i}"]) for i, ic in enumerate(ics)]
    keys, funnel = _run(cands, 6.0, threads)
    # round 1 (f0–f3): f0 is the best, f1 within 6; round 2 (f4–f7): f4 at 4.5; round 3 (f8–f10): f8 at 7,
    # f9 at 8, f10 at 99 — all out of reach, but it was fitted: the funnel stops after it, past the shortlist's end
    assert keys == ["none"] + [f"f{i}" for i in range(11)]
    assert not funnel.cut
    ics[4] = -80.0  # now round 2 lands out of reach: round 3 is not fitted
    cands = [_row(f"f{i}", ic, [f"t{i}"]) for i, ic in enumerate(ics)]
    keys, funnel = _run(cands, 6.0, threads)
    assert keys == ["none"] + [f"f{i}" for i in range(8)]
    assert funnel.cut


def test_the_special_cases_of_a_row_within_reach_are_fitted_after_the_cut():
    """A sum of terms within reach: its terms alone (later in the pointwise order) are fitted all the same, since
    parsimony may choose one of them; a family that is no special case of a near row is not."""
    cands = [
        _row("a+b", -100.0, ["a", "b"]),
        _row("c", -50.0, ["c"]),
        _row("d", -50.0, ["d"]),
        _row("e", -50.0, ["e"]),
        _row("f", -60.0, ["f"]),
        _row("g", -60.0, ["g"]),
        _row("h", -60.0, ["h"]),
        _row("i", -60.0, ["i"]),
        _row("j", -99.0, ["j"]),  # would be near, but is no special case of a near row: not fitted
        _row("b", -98.0, ["b"]),  # a special case of a+b: fitted
    ]
    keys, funnel = _run(cands, 6.0)
    assert keys == ["none", "a+b", "c", "d", "e", "f", "g", "h", "i", "b"]
    assert funnel.cut


def test_ineligible_rows_do_not_set_the_best_but_count_as_within_reach():
    cands = [_row(f"f{i}", ic, [f"t{i}"]) for i, ic in enumerate([-10.0, -9.0, -8.0, -7.0])]
    cands += [_row("x", -200.0, ["x"], significant=False), *(_row(f"y{i}", -1.0, [f"y{i}"]) for i in range(3))]
    cands += [_row("z", -9.5, ["z"])]
    keys, _ = _run(cands, 6.0)
    # round 2 holds x, far below the best eligible (f0): a row the reason names — the funnel goes on to z
    assert keys[-1] == "z"


def test_an_infinite_reach_or_no_funnel_fits_the_whole_shortlist_in_order():
    from nnphd.explain.trajectory import fit_rows

    cands = [_row(f"f{i}", float(-i % 5) * 40, [f"t{i}"]) for i in range(13)]
    cands[5].ic = None  # a fit that fails is left out
    keys, funnel = _run(cands, math.inf)
    want = ["none"] + [f"f{i}" for i in range(13) if i != 5]
    assert keys == want and not funnel.cut
    out = fit_rows(lambda ci, row, warm=None: ((None if row.ic is None else row), None), _row("none", 0.0), cands, 2)
    assert [r.key for r in out] == want


def test_a_round_without_any_fit_does_not_end_the_funnel():
    cands = [_row(f"f{i}", ic, [f"t{i}"]) for i, ic in enumerate([-10.0, -9.0, -8.0, -7.0])]
    cands += [_row(f"bad{i}", None) for i in range(4)] + [_row("late", -9.0, ["late"])]
    keys, funnel = _run(cands, 6.0)
    assert keys[-1] == "late" and not funnel.cut


@pytest.mark.slow  # ~10 s: the law table of a pendulum look-alike at trajectory level
def test_one_coordinate_fits_every_family_and_keeps_a_tie_the_pointwise_order_hides(tmp_path):
    """A damped pendulum look-alike (one coordinate, held-out windows, the library base): every family is fitted.
    The windows and the amplitude envelope tie linear and Coulomb friction, where the pointwise fits put dry friction
    far down (a Coulomb force's smoothed q̈): a funnel in the pointwise order dropped it and claimed linear friction
    (benchmarks/funnel_audit.py, docs/scaling.md)."""
    import numpy as np

    from nnphd.explain.search import LawRun, find_law
    from nnphd.user.derivatives import Derivatives
    from nnphd.user.recording import load_trajectories
    from tests.fixtures import recordings

    rec = recordings.make("pendulum-damped", 0)
    ud = load_trajectories(rec.write_csv(tmp_path / "p.csv"), list(rec.angles))
    d = Derivatives().dataset(ud)
    traj = np.concatenate([np.full(b - a, i) for i, tr in enumerate(d.info["trajectories"]) for a, b in [tr["kept"]]])
    run = LawRun(traj, tuple(ud.coords), tuple(bool(a) for a in ud.is_angle), d.info, d.row_errors, seed=0)
    table = find_law(d.data, run)
    f = table.settings["funnel"]
    assert not table.settings["in_sample"] and f["reach"] is None and not f["cut"], f
    assert f["trajectory"] == f["shortlist"] == f["pointwise"], f
    pointwise = [r["law"] for r in table.settings["pointwise_candidates"]]
    assert pointwise.index("coulomb") >= 8, pointwise  # far down the pointwise order
    assert table.law.key == "linear" and [r.key for r in table.ties] == ["coulomb"], table.reason
