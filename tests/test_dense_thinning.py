"""A dense record is thinned after its derivatives are estimated at the full rate (nnphd.user.derivatives.dense_thinned):
which records, by how much, that the derivatives kept are the full-rate ones, and what is left alone."""

from __future__ import annotations

import numpy as np
import pytest

from nnphd.user.derivatives import THIN_MIN_PER_PERIOD, THIN_ROWS, dense_thinned
from nnphd.user.detect import prepared_data
from nnphd.user.recording import from_arrays


def _damped(rate: float, seconds: float, n_traj: int = 1, period: float = 1.0, seed: int = 0, **kw):
    """A damped oscillator x(t) = e^(−0.1 t) cos(2π t / period) sampled at ``rate`` (1e-4 noise), ``n_traj`` runs."""
    rng = np.random.default_rng(seed)
    t = np.arange(int(rate * seconds)) / rate
    w = 2 * np.pi / period
    ts, qs = [], []
    for i in range(n_traj):
        ts.append(t)
        qs.append(np.exp(-0.1 * t) * np.cos(w * t + 0.3 * i) + 1e-4 * rng.standard_normal(t.size))
    return from_arrays(ts, qs, names=["x"], **kw)


def _thin(ud):
    data, info, _, row_err, traj = prepared_data(ud, "auto")
    full = (data, {k: v.copy() for k, v in row_err.items()}, traj.copy())
    return full, dense_thinned(data, info, row_err, traj, ud), info


def test_a_dense_record_keeps_every_kth_row_of_each_trajectory_with_its_full_rate_derivatives():
    ud = _damped(1000.0, 4.0, n_traj=3)  # 12 000 rows, 1000 rows per period
    (d0, e0, tr0), (d1, e1, tr1), info = _thin(ud)
    th = info["thinned"]
    n = len(d0)
    wmin = min(min(info["per_coordinate"]["x"][k]["windows"]) for k in ("qd", "qdd"))
    k = min(-(-n // THIN_ROWS), int(th["period_rows"] // THIN_MIN_PER_PERIOD), wmin // 2)
    assert th["every"] == k == 3  # the row budget decides here: ⌈~11 900 / 5000⌉
    assert abs(th["period_rows"] - 1000.0) < 20.0  # the motion's period, in rows
    assert th["rows_before"] == n and th["rows"] == len(d1) <= THIN_ROWS
    # every k-th row of each trajectory, starting at its first: no row crosses into another trajectory
    for i in np.unique(tr0):
        rows0 = np.flatnonzero(tr0 == i)
        np.testing.assert_array_equal(d1.t[tr1 == i], d0.t[rows0[::k]])
        np.testing.assert_array_equal(d1.qdd[tr1 == i], d0.qdd[rows0[::k]])  # estimated before the thinning
        np.testing.assert_array_equal(e1["qdd_err"][tr1 == i], e0["qdd_err"][rows0[::k]])
    assert th["text"].startswith(f"a dense record: one row in 3 of its {n} is used ({len(d1)} rows, ")


def test_the_thinning_keeps_enough_rows_per_period_and_stays_inside_the_derivative_windows():
    # 400 rows per period: ⌈12 000 / 5000⌉ = 3 would do for the budget, 400 / 80 = 5 allows it
    ud = _damped(400.0, 30.0, period=1.0)
    (_, _, _), (d1, _, _), info = _thin(ud)
    th = info["thinned"]
    assert th["every"] >= 2 and th["period_rows"] / th["every"] >= THIN_MIN_PER_PERIOD
    wmin = min(min(info["per_coordinate"]["x"][k]["windows"]) for k in ("qd", "qdd"))
    assert th["every"] <= wmin // 2
    # 100 rows per period and 6000 rows: 100 // 80 = 1 — not thinned
    ud = _damped(100.0, 60.0, period=1.0)
    (d0, _, tr0), (d1, _, tr1), info = _thin(ud)
    assert "thinned" not in info and d1 is d0 and len(tr1) == len(tr0)


@pytest.mark.parametrize("case", ["short", "given", "no oscillation"])
def test_what_is_not_thinned(case):
    if case == "short":  # at most THIN_ROWS rows
        ud = _damped(1000.0, 4.0)
    elif case == "given":  # given velocities and accelerations: no smoothing windows shared by neighbours
        t = np.arange(12000) / 1000.0
        w = 2 * np.pi
        ud = from_arrays(t, np.cos(w * t), names=["x"], qd=-w * np.sin(w * t), qdd=-(w**2) * np.cos(w * t))
    else:  # a fall: no period
        t = np.arange(12000) / 1000.0
        ud = from_arrays(t, 5.0 - 4.9 * t**2 + 1e-4 * np.random.default_rng(0).standard_normal(t.size), names=["y"])
    (d0, _, _), (d1, _, _), info = _thin(ud)
    assert "thinned" not in info and len(d1) == len(d0)


def test_the_rest_margin_counts_the_rows_that_remain():
    """The rows next to a stuck stretch that go with it: half the q̈ window, counted in the rows before the thinning
    — so in rows after it, divided by k (rounded up)."""
    from types import SimpleNamespace
    from unittest import mock

    from nnphd.explain import search

    q = np.concatenate([np.cos(np.linspace(0, 20 * np.pi, 800)), np.zeros(200)])[:, None]
    data = SimpleNamespace(q=q, qd=np.zeros_like(q), qdd=np.zeros_like(q), t=np.arange(1000) * 0.01)
    seen = []

    def rest_mask(*a):
        seen.append(a[-1])
        return np.zeros(len(q), bool)

    for thinned, margin in (({}, 15), ({"thinned": {"every": 4}}, 4)):
        info = {"per_coordinate": {"x": {"noise": 1e-4, "quantization_step": 0.0, "qdd": {"windows": [31]}}}}
        info |= thinned
        with mock.patch("nnphd.explain.rest.rest_mask", rest_mask):
            search.moving_rows(data, np.zeros(1000, int), ["x"], info, None, None, 0.4)
        assert seen[-1] == margin


@pytest.mark.parametrize(("flag", "thin"), [([], None), (["--no-thin"], False)])
def test_detect_no_thin_reaches_detect_data(tmp_path, monkeypatch, flag, thin):
    """``nnphd detect --no-thin`` passes thin=False (the default passes nothing: detect_data's default, thinning)."""
    import math

    import nnphd.user.detect as ud
    from nnphd.cli import main

    monkeypatch.chdir(tmp_path)
    (tmp_path / "d.csv").write_text("t,x\n" + "".join(f"{0.1 * i:.3f},{math.cos(0.1 * i):.9f}\n" for i in range(40)))
    seen = {}

    def stop(*a, **k):
        seen.update(k)
        raise KeyboardInterrupt

    monkeypatch.setattr(ud, "detect_data", stop)
    assert main(["detect", "d.csv", *flag]) == 130
    assert seen.get("thin") is thin


@pytest.mark.parametrize("thin", [True, False])
def test_the_notebook_api_passes_its_thinning(monkeypatch, thin):
    """``NNPhD(derivatives=nnphd.Derivatives(thin=…)).fit`` runs detect_data with that thinning."""
    import nnphd
    import nnphd.user.detect as ud

    seen = {}

    def stop(*a, **k):
        seen.update(k)
        raise KeyboardInterrupt

    monkeypatch.setattr(ud, "detect_data", stop)
    t = np.arange(40) * 0.1
    with pytest.raises(KeyboardInterrupt):
        nnphd.NNPhD(derivatives=nnphd.Derivatives(thin=thin)).fit(nnphd.Trajectories(t, np.cos(t)))
    assert seen["thin"] is thin
