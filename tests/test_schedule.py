"""The cluster simulation's list schedule (:func:`nnphd.parallel.list_schedule`) against schedules worked by hand
and the bounds every list schedule obeys."""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from nnphd.parallel import list_schedule


def test_schedules_worked_by_hand():
    # 8 equal units on 4 workers: two rounds, every worker busy all the time
    s = list_schedule([3.0] * 8, 4)
    assert s["makespan_s"] == 6.0 and s["efficiency"] == 1.0 and s["loads_s"] == [6.0] * 4
    # one long unit dominates: 10 | 4 + 3 + 2 (largest first: 10→w0, 4→w1, 3→w1 (frees at 4), 2→w1 (7))
    s = list_schedule([2.0, 10.0, 3.0, 4.0], 2)
    assert s["loads_s"] == [10.0, 9.0] and s["makespan_s"] == 10.0 and s["efficiency"] == pytest.approx(19 / 20)
    # more workers than units: idle workers cost efficiency; the overhead is paid once per unit
    s = list_schedule([5.0, 5.0], 4, overhead_s=0.5)
    assert s["makespan_s"] == 5.5 and s["total_s"] == 11.0 and s["efficiency"] == pytest.approx(11 / 22)
    assert list_schedule([], 3)["makespan_s"] == 0.0


def test_bad_schedules_are_refused():
    with pytest.raises(ValueError, match="workers must be an integer ≥ 1"):
        list_schedule([1.0], 0)
    with pytest.raises(ValueError, match="non-negative"):
        list_schedule([1.0, float("nan")], 2)
    with pytest.raises(ValueError, match="non-negative"):
        list_schedule([1.0], 2, overhead_s=-1.0)


@settings(max_examples=200, deadline=None)
@given(
    st.lists(st.floats(0.0, 1e3, allow_nan=False), min_size=1, max_size=60),
    st.integers(1, 70),
    st.floats(0.0, 5.0, allow_nan=False),
)
def test_every_list_schedule_is_within_grahams_bounds(durations, workers, overhead):
    s = list_schedule(durations, workers, overhead)
    units = [d + overhead for d in durations]
    total = sum(units)
    assert s["total_s"] == pytest.approx(total)
    lower = max(max(units), total / workers)  # no schedule beats this
    # Graham (1966): a list schedule ends by total/W + (1 − 1/W) × the longest unit
    upper = total / workers + (1 - 1 / workers) * max(units)
    assert lower * (1 - 1e-12) <= s["makespan_s"] <= upper * (1 + 1e-12) + 1e-9
    assert 0 < s["efficiency"] <= 1 + 1e-12 or total == 0
    assert list_schedule(durations, 1, overhead)["makespan_s"] == pytest.approx(total)  # one worker does it all


def test_one_unit_more_than_workers_leaves_workers_idle():
    # 4 equal units on 3 workers: one worker runs two (2.0) where the lower bound is 4/3 — the schedule is optimal
    s = list_schedule([1.0] * 4, 3)
    assert s["makespan_s"] == 2.0 and s["efficiency"] == pytest.approx(4 / 6)
