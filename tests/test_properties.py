"""Property tests (hypothesis) of what a careless or hostile user can hand nnphd: random CSV and NPZ tables go either
into validated data or into one :class:`DataError` line; random ``nnphd detect`` argument lists give either a run or
exit code 2 with one ``error:`` line — never a traceback.  The number of examples is fixed (``EXAMPLES``)."""

from __future__ import annotations

import csv
import io
import math
import types

import numpy as np
import pytest
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from nnphd.cli import main
from nnphd.user.recording import DataError, UserData, load_trajectories

EXAMPLES = {"csv": 300, "npz": 150, "cli": 200}
_SETTINGS = dict(deadline=None, derandomize=True, suppress_health_check=[HealthCheck.function_scoped_fixture])

NAMES = ["t", "x", "y", "traj", "x_dot", "x_ddot", "y_dot", "theta", "q_ddot", "", " t ", "T", "1", "a;b", "é"]
EXTREMES = [0.0, -0.0, 1.0, -1.0, 1e-320, 2.2e-308, 1e-300, 1e30, 1e31, 1e300, 1.7976931348623157e308]
NUMBERS = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from(EXTREMES),
    st.integers(min_value=-(2**70), max_value=2**70),
    st.floats(min_value=-10, max_value=10),
)
FLOATS = st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.sampled_from(EXTREMES), st.floats(-10, 10))
CELLS = st.one_of(
    NUMBERS.map(repr),
    NUMBERS.map(str),
    st.sampled_from(["", " ", "nan", "inf", "-inf", "1,5", "1;5", "abc", "0x10", "1e", "+", "١٢", "1_000", "9" * 400]),
    st.text(max_size=6),
)


@st.composite
def tables(draw):
    header = draw(st.lists(st.sampled_from(NAMES), min_size=0, max_size=5))
    n_rows = draw(st.integers(0, 20))
    width = len(header)
    rows = []
    for _ in range(n_rows):
        w = width if draw(st.integers(0, 9)) else draw(st.integers(0, width + 2))  # sometimes ragged
        rows.append([draw(CELLS) for _ in range(w)])
    if width and draw(st.booleans()):  # often a plausible table: increasing t, moving x, small integer traj
        header = ["t", "x"] + [h for h in header if h not in ("t", "x")][: draw(st.integers(0, 2))]
        n_rows = draw(st.integers(6, 20))
        x = st.floats(-10, 10).map(repr) if draw(st.integers(0, 3)) else NUMBERS.map(repr)
        extra = st.integers(0, 2).map(str) if draw(st.booleans()) else CELLS
        rows = [[repr(0.1 * i), draw(x), *[draw(extra) for _ in header[2:]]] for i in range(n_rows)]
    return header, rows


def _check_one_line(e: DataError, path) -> None:
    msg = str(e)
    assert "\n" not in msg and msg.startswith(str(path)) and len(msg) < 2000, msg


@settings(max_examples=EXAMPLES["csv"], **_SETTINGS)
@given(table=tables(), angles=st.lists(st.sampled_from(NAMES), max_size=2))
def test_any_csv_is_data_or_one_line_error(table, angles, tmp_path_factory):
    header, rows = table
    path = tmp_path_factory.mktemp("csv") / "f.csv"
    buf = io.StringIO()
    w = csv.writer(buf)
    if header:
        w.writerow(header)
    w.writerows(rows)
    path.write_text(buf.getvalue(), encoding="utf-8")
    try:
        ud = load_trajectories(path, angles)
    except DataError as e:
        _check_one_line(e, path)
        event("refused")
        return
    event("read")
    assert isinstance(ud, UserData)
    for tr in ud.trajectories:  # what passes is finite, in range, increasing in t, long enough
        assert np.all(np.isfinite(tr.q)) and np.all(np.diff(tr.t) > 0) and len(tr) >= 8
        assert np.all(np.abs(tr.q) <= 1e30) and np.all(np.abs(tr.t) <= 1e30)


ARRAYS = st.one_of(
    st.lists(FLOATS, min_size=0, max_size=20).map(lambda v: np.array(v, dtype=float)),
    st.lists(st.integers(-(2**63), 2**63 - 1), max_size=20).map(lambda v: np.array(v, dtype=np.int64)),
    st.lists(st.integers(0, 2**64 - 1), max_size=20).map(lambda v: np.array(v, dtype=np.uint64)),
    st.just(np.array(["a", "b"])),
    st.just(np.zeros((3, 2))),
    st.just(np.array([True, False])),
    st.just(np.zeros(0)),
)


@st.composite
def npz_tables(draw):
    arrays = draw(st.dictionaries(st.sampled_from([n for n in NAMES if n.strip()]), ARRAYS, max_size=4))
    if draw(st.booleans()):  # a plausible file: t, x of one length, maybe with a random extra array
        n = draw(st.integers(6, 20))
        extra = {k: v for k, v in arrays.items() if k not in ("t", "x")}
        arrays = {"t": np.arange(n) * 0.1, "x": np.array(draw(st.lists(st.floats(-10, 10), min_size=n, max_size=n)))}
        if extra and draw(st.booleans()):
            k = next(iter(extra))
            arrays[k] = extra[k]
        elif draw(st.booleans()):
            arrays["traj"] = np.array(draw(st.lists(st.integers(0, 1), min_size=n, max_size=n)))
    return arrays


@settings(max_examples=EXAMPLES["npz"], **_SETTINGS)
@given(arrays=npz_tables())
def test_any_npz_is_data_or_one_line_error(arrays, tmp_path_factory):
    path = tmp_path_factory.mktemp("npz") / "f.npz"
    np.savez(path, **{k.strip() or "blank": v for k, v in arrays.items()})
    try:
        ud = load_trajectories(path)
    except DataError as e:
        _check_one_line(e, path)
        event("refused")
        return
    event("read")
    assert all(len(tr) >= 8 and np.all(np.isfinite(tr.q)) for tr in ud.trajectories)


# ---- the command line -----------------------------------------------------------------------------------------
VALUES = st.one_of(
    st.integers(-5, 2**70).map(str),
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.sampled_from(["", " ", "0", "1", "8", "1e12", "-1", "nan", "abc", "0.5,2", "0.1,0.1,2", "x", "x,", "yes"]),
    st.sampled_from(["0.05,0.1,2", "2,5", "0.5", "1", "x: -g*x_dot", "c*x_dot*abs(x_dot)", "import os", "x_dot**"]),
    st.text(max_size=8),
)
OPTIONS = [
    "--seed",
    "--steps",
    "--repeats",
    "--sr-time",
    "--lambdas",
    "--angles",
    "--width",
    "--trim",
    "--law",
    "--law-fit",
]


@settings(max_examples=EXAMPLES["cli"], **_SETTINGS)
@given(
    opts=st.lists(st.tuples(st.sampled_from(OPTIONS + ["--bogus", "-x"]), VALUES), max_size=4),
    out=st.sampled_from(["out", "", "nested/out", "data.csv", "/proc/nnphd-out"]),
)
def test_any_detect_arguments_run_or_give_exit_2(opts, out, tmp_path_factory, capsys, monkeypatch):
    """The training is replaced by a stub (the arguments are what is tested): a valid argument list runs the stub and
    prints the verdict; an invalid one gives exit 2, one line; nothing else."""
    import nnphd.user.detect as detect_mod

    calls = []

    def stub(path, **kw):
        calls.append(kw)
        return {"status": "none", "new_physics": False, "confidence": 1.0, "reasons": ["stub"], "formula": None}

    stub_rep = {"blind": {}, "law": {}, "wall_time_s": 0.0}
    result = lambda ud, **kw: types.SimpleNamespace(report={**stub(ud, **kw), **stub_rep})  # noqa: E731 — the CLI prints its report
    monkeypatch.setattr(detect_mod, "detect_data", lambda ud, **kw: (result(ud, **kw), None))
    d = tmp_path_factory.mktemp("cli")
    t = np.linspace(0, 10, 50)
    (d / "data.csv").write_text("t,x\n" + "\n".join(f"{a!r},{math.cos(a)!r}" for a in t) + "\n")
    argv = ["detect", str(d / "data.csv"), "--out", str(d / out) if out.strip() and not out.startswith("/") else out]
    for name, value in opts:
        argv += [name, value]
    capsys.readouterr()
    rc = main(argv)
    cap = capsys.readouterr()
    event(f"exit {rc}")
    assert "Traceback" not in cap.err + cap.out
    if rc == 0:
        assert len(calls) == 1 and "NONE" in cap.out
    else:
        lines = [ln for ln in cap.err.splitlines() if ln.strip()]
        assert rc == 2 and len(lines) == 1 and lines[0].startswith("error: "), (rc, cap.err)
        assert not calls


@pytest.mark.parametrize("argv", [["detect"], ["nope"], ["sweep", "--system"], ["study", "lambda-p", "--p", "x"]])
def test_fixed_bad_argument_lists(argv, capsys):
    assert main(argv) == 2
    cap = capsys.readouterr()
    assert "Traceback" not in cap.err + cap.out
