"""Hostile or careless input to the trajectory reader (``nnphd detect FILE``) and to ``nnphd.Trajectories``: devices,
FIFOs, endless lines, thousands of columns, NPZ headers that promise gigabytes, complex or textual arrays, unusable
names.  Each gives one :class:`DataError` line naming the problem, within bounded time and memory; an error message
never carries more than a short, quoted piece of the file."""

from __future__ import annotations

import csv
import io
import os
import threading
import tracemalloc
import zipfile

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import nnphd
import nnphd.user.recording as rec
from nnphd.cli import main
from nnphd.io.limits import MAX_COLUMNS, MAX_COORDS, MAX_LINE, MAX_NAME
from nnphd.user.recording import DataError, UserData, load_trajectories

_SETTINGS = dict(deadline=None, derandomize=True, suppress_health_check=[HealthCheck.function_scoped_fixture])


def _refused(path, *parts, angles=(), **kw) -> str:
    """load_trajectories(path) raises one DataError line holding every part; the message."""
    with pytest.raises(DataError) as err:
        load_trajectories(path, angles=angles, **kw)
    return _one_line(err.value, *parts)


def _one_line(e: BaseException, *parts) -> str:
    msg = str(e)
    assert isinstance(e, DataError) and isinstance(e, ValueError)
    assert "\n" not in msg and "\r" not in msg and len(msg) < 600, msg
    for p in parts:
        assert p in msg, (p, msg)
    return msg


def _good(n=20):
    t = np.arange(n) * 0.1
    return t, np.cos(t)


def _csv_text(n=20):
    t, x = _good(n)
    return "t,x\n" + "".join(f"{float(a)!r},{float(b)!r}\n" for a, b in zip(t, x))


# ---- not a regular file -------------------------------------------------------------------------------------------
@pytest.mark.skipif(not os.path.exists("/dev/zero"), reason="needs /dev/zero")
@pytest.mark.parametrize("ext", [".csv", ".npz"])
def test_link_to_dev_zero_is_refused_at_once(tmp_path, ext, monkeypatch):
    """Refused from ``os.stat``, before the device is opened: not one byte of it is read."""
    link = tmp_path / f"zero{ext}"
    link.symlink_to("/dev/zero")
    opened = _spy_on_open(monkeypatch)
    _refused(link, "not a regular file (a character device)", "expected a .csv or .npz file")
    assert opened == []


def _spy_on_open(monkeypatch) -> list:
    """The paths that ``os.open`` (the reader's only way into a file) is asked to open from now on; opening a
    device or a FIFO fails the test at once instead of reading or blocking."""
    opened: list = []
    real_open = os.open

    def spy(path, flags, *args, **kw):
        opened.append(os.fspath(path))
        if not os.path.isfile(path):
            raise AssertionError(f"os.open of {path!r}, not a regular file")
        return real_open(path, flags, *args, **kw)

    monkeypatch.setattr(os, "open", spy)
    return opened


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="needs FIFOs")
@pytest.mark.parametrize("ext", [".csv", ".npz"])
def test_fifo_is_refused_without_blocking(tmp_path, ext, monkeypatch):
    """Refused from ``os.stat`` before it is opened (the join's timeout only keeps a blocked reader from hanging the
    run)."""
    fifo = tmp_path / f"pipe{ext}"
    os.mkfifo(fifo)
    link = tmp_path / f"link{ext}"
    link.symlink_to(fifo)
    real_open = os.open
    opened = _spy_on_open(monkeypatch)
    for path in (fifo, link):
        box: dict = {}

        def run(path=path, box=box):
            try:
                load_trajectories(path)
            except BaseException as e:  # noqa: BLE001 - reported below
                box["e"] = e

        th = threading.Thread(target=run, daemon=True)
        th.start()
        th.join(2.0)
        if th.is_alive():  # unblock the reader before failing
            os.close(real_open(fifo, os.O_WRONLY | os.O_NONBLOCK))
            pytest.fail(f"{path}: the reader blocked on a FIFO")
        _one_line(box["e"], "not a regular file (a FIFO (named pipe))")
    assert opened == []


def test_missing_dangling_and_unreadable(tmp_path):
    _refused(tmp_path / "none.csv", "file not found")
    (tmp_path / "dangling.csv").symlink_to(tmp_path / "gone.csv")
    _refused(tmp_path / "dangling.csv", "file not found")
    (tmp_path / "dir.npz").mkdir()
    _refused(tmp_path / "dir.npz", "is a directory")
    name = tmp_path / "bad\nname.csv"  # a file name with a line break still gives one line
    name.write_text("t,x\n")
    _refused(name, "no data rows", repr(str(name)))


# ---- CSV: bounded lines and records ------------------------------------------------------------------------------
def _peak(fn) -> int:
    tracemalloc.start()
    try:
        fn()
    finally:
        peak = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
    return peak


def _refused_peak(path) -> tuple[DataError, int]:
    """The DataError that reading ``path`` raises, and the peak of Python memory allocated until then."""
    box = {}

    def read():
        with pytest.raises(DataError) as err:
            load_trajectories(path)
        box["e"] = err.value

    peak = _peak(read)
    return box["e"], peak


def test_a_20_mb_line_without_newline_is_refused_in_bounded_memory(tmp_path):
    path = tmp_path / "one_line.csv"
    size = 20 * 2**20
    with open(path, "w") as fh:
        fh.write("t,x\n0,1\n")
        chunk = "1" * 2**20
        for _ in range(size // len(chunk)):
            fh.write(chunk)
    e, peak = _refused_peak(path)
    _one_line(e, "line 3 is longer than 1,048,576 characters", "line breaks")
    assert peak < 4 * MAX_LINE < size / 4, peak  # a couple of copies of one bounded line (measured 2.1 MB)


def test_a_record_spanning_lines_is_bounded_too(tmp_path):
    """Quoted fields may hold line breaks: csv.reader would join them into one record without end."""
    path = tmp_path / "quotes.csv"
    field = '"' + "a" * 1000 + '\n",'  # one line each, within the csv module's field limit
    path.write_text("t,x\n" + "0," + field * 3000 + "\n")
    e, peak = _refused_peak(path)
    _one_line(e, "the record from line 2 to", "unclosed quote")
    assert peak < 4 * MAX_LINE, peak
    path.write_text("t,x\n" + '0,"' + "1\n" * 100_000 + '"\n')  # one field beyond the csv module's limit
    _refused(path, "line", "field larger than field limit", "expected a CSV file")


def test_long_cells_are_cut_in_messages(tmp_path):
    path = tmp_path / "cells.csv"
    secret = "x" * 5000
    path.write_text(_csv_text().replace("0.1,", f"{secret},", 1))
    msg = _refused(path, "column 't' row 2 (line 3)", "is not a number")
    assert "x" * 21 not in msg
    path.write_text("traj,t,x\n" + "".join(f"{'9' * 5000},{i},{i * i}\n" for i in range(10)))
    msg = _refused(path, "column 'traj' row 1 (line 2)", "trajectory id", "beyond ±2**53")
    assert "9" * 21 not in msg


def test_a_link_to_a_private_key_puts_no_key_line_in_the_message(tmp_path):
    lines = [
        "b3BlbnNzaC1rZXktdjEAAAAABG5vbmUAAAAEbm9uZQAAAAAAAAABAAAAMwAAAAtzc2gtZW",
        "QyNTUxOQAAACDx3Zq0yN2Hc9d8QsI4Z0aUjtmKQ6pG8yNn7zKJ+u5tAAAAJjQxZ1E0MWd",
        "RAAAAAtzc2gtZWQyNTUxOQAAACDx3Zq0yN2Hc9d8QsI4Z0aUjtmKQ6pG8yNn7zKJ+u5tAA",
    ]
    key = tmp_path / "id_ed25519"
    key.write_text("-----BEGIN OPENSSH PRIVATE KEY-----\n" + "\n".join(lines) + "\n-----END OPENSSH PRIVATE KEY-----\n")
    link = tmp_path / "data.csv"
    link.symlink_to(key)
    msg = _refused(link, "row 1 (line 2)", "is not a number")
    assert not any(line[:21] in msg for line in lines), msg


# ---- CSV: columns, coordinates, cells, names ---------------------------------------------------------------------
def test_thousand_coordinate_columns_are_refused_from_the_header(tmp_path):
    path = tmp_path / "wide.csv"
    names = [f"c{j}" for j in range(1000)]
    row = ",".join("1.5" for _ in names)
    path.write_text("t," + ",".join(names) + "\n" + "".join(f"{i},{row}\n" for i in range(120)))
    e, peak = _refused_peak(path)
    _one_line(e, "1,001 columns", f"expected at most {MAX_COLUMNS}", "keep the columns of one system")
    assert peak < 2 * 2**20, peak
    names = [f"c{j}" for j in range(MAX_COORDS + 1)]
    path.write_text("t," + ",".join(names) + "\n" + "".join(f"{i},{','.join('1' for _ in names)}\n" for i in range(9)))
    _refused(path, f"{MAX_COORDS + 1} coordinate columns", f"expected at most {MAX_COORDS} coordinates")
    # the full width is accepted: MAX_COORDS coordinates with their derivatives
    names = [f"c{j}" for j in range(MAX_COORDS)]
    header = ["t", "traj", *names, *(c + "_dot" for c in names), *(c + "_ddot" for c in names)]
    assert len(header) == MAX_COLUMNS
    rows = "".join(f"{i},0," + ",".join(str(np.sin(i + j)) for j in range(len(header) - 2)) + "\n" for i in range(9))
    path.write_text(",".join(header) + "\n" + rows)
    assert load_trajectories(path).n == MAX_COORDS


def test_cells_are_capped_while_streaming(tmp_path, monkeypatch):
    monkeypatch.setattr(rec, "MAX_CELLS", 1000)
    path = tmp_path / "tall.csv"
    path.write_text("t,x,y,z\n" + "".join(f"{i},{i},{-i},{i * i}\n" for i in range(400)))
    _refused(path, "more than 1,000 values (4 columns × 250 rows)", "thin the file")
    path.write_text("t,x,y,z\n" + "".join(f"{i},{i},{-i},{i * i}\n" for i in range(250)))
    assert load_trajectories(path).n_samples == 250
    # --max-rows raises the cap in proportion
    path.write_text("t,x,y,z\n" + "".join(f"{i},{i},{-i},{i * i}\n" for i in range(400)))
    assert load_trajectories(path, max_rows=2 * rec.MAX_ROWS).n_samples == 400


@pytest.mark.parametrize(
    "name,expected",
    [
        ("x\x07", "control character '\\x07'"),
        ("x\u202ey", "control character '\\u202e'"),  # a right-to-left override
        ("x\u2028y", "control character '\\u2028'"),  # a line separator
        ("n" * (MAX_NAME + 1), f"has {MAX_NAME + 1} characters; expected at most {MAX_NAME}"),
        ("", "column 2 of the header has no name"),
    ],
)
def test_unusable_header_names(tmp_path, name, expected):
    path = tmp_path / "names.csv"
    path.write_text(f"t,{name}\n" + "".join(f"{i},{i * i}\n" for i in range(10)), encoding="utf-8")
    msg = _refused(path, expected)
    assert "n" * 41 not in msg


# ---- NPZ: checked from the headers before anything is read -------------------------------------------------------
def _npy_header(shape, dtype="<f8", fortran=False, version=(1, 0)) -> bytes:
    buf = io.BytesIO()
    d = {"descr": dtype, "fortran_order": fortran, "shape": shape}
    if version == (1, 0):
        np.lib.format.write_array_header_1_0(buf, d)
    else:
        np.lib.format.write_array_header_2_0(buf, d)
    return buf.getvalue()


def _zip(path, members: dict, compress=zipfile.ZIP_DEFLATED):
    with zipfile.ZipFile(path, "w", compress) as zf:
        for name, data in members.items():
            zf.writestr(name, data)
    return path


def test_npz_shapes_dtypes_and_sizes_come_from_the_headers(tmp_path):
    good_t = _npy_header((10,)) + np.arange(10.0).tobytes()
    cases = {  # headers only: an array that were read would fail with "EOF", not with these messages
        "2d": ({"t.npy": good_t, "x.npy": _npy_header((1, 400_000_000))}, "has shape (1, 400000000)", "1-D"),
        "rows": ({"t.npy": _npy_header((400_000_000,))}, "more than 10,000,000 data rows", "thin the file"),
        "object": ({"t.npy": good_t, "x.npy": _npy_header((10,), "|O")}, "has dtype object", "not complex, text"),
        "complex": ({"t.npy": good_t, "x.npy": _npy_header((10,), "<c16")}, "has dtype complex128", "expected num"),
        "text": ({"t.npy": good_t, "x.npy": _npy_header((10,), "<U3")}, "has dtype <U3", "expected numbers"),
        "lengths": ({"t.npy": good_t, "x.npy": _npy_header((11,))}, "'x' has 11 values but 't' has 10", "equal"),
        "cells": (
            {f"c{j}.npy": _npy_header((5_000_000,)) for j in range(25)},
            "more than 100,000,000 values",
            "drop columns",
        ),
        "members": ({f"c{j}.npy": b"" for j in range(MAX_COLUMNS + 1)}, f"{MAX_COLUMNS + 1} members", "at most"),
        "not_npy": ({"t.npy": good_t, "notes.txt": b"0" * 10**6}, "member 'notes.txt' is not a .npy array", "savez"),
        "bad_name": ({"t.npy": good_t, "x\x07y.npy": good_t}, "control character '\\x07'", "array 2"),
        "version": ({"t.npy": b"\x93NUMPY\x09\x00" + good_t[8:]}, "format version (9, 0)", "expected 1.0 to 3.0"),
    }
    for key, (members, *parts) in cases.items():
        path = _zip(tmp_path / f"{key}.npz", members)
        e, peak = _refused_peak(path)
        _one_line(e, *parts)
        assert peak < 4 * 2**20, (key, peak)


def test_npz_formats_that_are_fine(tmp_path):
    t, x = _good()
    for version in ((1, 0), (2, 0), (3, 0)):
        members = {}
        for name, a in (("t", t), ("x", x), ("traj", np.zeros(len(t), dtype=np.int32))):
            buf = io.BytesIO()
            np.lib.format.write_array(buf, np.asfortranarray(a), version=version)
            members[f"{name}.npy"] = buf.getvalue()
        ud = load_trajectories(_zip(tmp_path / f"v{version[0]}.npz", members, zipfile.ZIP_STORED))
        np.testing.assert_array_equal(ud.trajectories[0].q[:, 0], x)
    np.savez_compressed(tmp_path / "c.npz", t=t, x=x.astype(np.float32), traj=np.zeros(len(t), np.uint8))
    assert load_trajectories(tmp_path / "c.npz").n_samples == len(t)


def test_broken_npz_files(tmp_path):
    t, x = _good()
    (tmp_path / "empty.npz").write_bytes(b"")
    _refused(tmp_path / "empty.npz", "the file is empty", "numpy.savez")
    np.savez(tmp_path / "whole.npz", t=t, x=x)
    data = (tmp_path / "whole.npz").read_bytes()
    (tmp_path / "cut.npz").write_bytes(data[: len(data) // 2])
    _refused(tmp_path / "cut.npz", "cannot read as .npz", "numpy.savez")
    np.savez_compressed(tmp_path / "z.npz", t=np.arange(5000.0), x=np.cos(np.arange(5000.0)))
    data = bytearray((tmp_path / "z.npz").read_bytes())
    data[len(data) // 2 : len(data) // 2 + 64] = bytes(64)  # corrupt the deflate stream of 'x'
    (tmp_path / "corrupt.npz").write_bytes(bytes(data))
    _refused(tmp_path / "corrupt.npz", "cannot read as .npz")
    np.save(tmp_path / "single.npy", t)
    os.rename(tmp_path / "single.npy", tmp_path / "single.npz")
    _refused(tmp_path / "single.npz", "a single .npy array, not an .npz archive")
    with zipfile.ZipFile(tmp_path / "dup.npz", "w") as zf:
        zf.writestr("t.npy", _npy_header((20,)) + t.tobytes())
        with pytest.warns(UserWarning):
            zf.writestr("t.npy", _npy_header((20,)) + t.tobytes())
    _refused(tmp_path / "dup.npz", "duplicate column name 't'")


# ---- random bytes and random names -------------------------------------------------------------------------------
@settings(max_examples=60, **_SETTINGS)
@given(data=st.binary(max_size=300), ext=st.sampled_from([".csv", ".npz"]), prefix=st.sampled_from([b"", b"t,x\n"]))
def test_random_bytes_give_data_or_one_line(data, ext, prefix, tmp_path_factory):
    path = tmp_path_factory.mktemp("bytes") / f"f{ext}"
    path.write_bytes(prefix + data)
    try:
        assert isinstance(load_trajectories(path), UserData)
    except DataError as e:
        _one_line(e)


@settings(max_examples=80, **_SETTINGS)
@given(names=st.lists(st.text(max_size=70), min_size=1, max_size=4))
def test_random_header_names_give_data_or_one_line(names, tmp_path_factory):
    path = tmp_path_factory.mktemp("names") / "f.csv"
    t, x = _good(10)
    buf = io.StringIO()
    w = csv.writer(buf)
    w.writerow(["t", *names])
    for i in range(10):
        w.writerow([t[i], *(x[i] * (j + 1) for j in range(len(names)))])
    path.write_text(buf.getvalue(), encoding="utf-8")
    try:
        ud = load_trajectories(path)
    except DataError as e:
        _one_line(e)
        return
    for c in ud.coords:  # every name that passes is usable
        assert c and c == c.strip() and len(c) <= MAX_NAME and not any(ch in c for ch in "\n\r\x00\x85\u2028")


# ---- nnphd.Trajectories ------------------------------------------------------------------------------------------
def _api_refused(fn, *parts) -> str:
    with pytest.raises(DataError) as err:
        fn()
    return _one_line(err.value, *parts)


def test_api_refuses_complex_text_objects_and_empty_arrays():
    t, x = _good()
    T = nnphd.Trajectories
    _api_refused(lambda: T(t, x + 1e-3j), "q is complex", "expected real numbers")
    _api_refused(lambda: T(t.astype(complex), x), "t is complex")
    _api_refused(lambda: T(t, x, qd=x * 1j), "q_dot is complex")
    _api_refused(lambda: T(t, x.astype(str)), "q has dtype <U", "expected real numbers")
    _api_refused(lambda: T(t, np.array([*x[:-1], "1.5"], dtype=object)), "q holds '1.5' (a str)")
    _api_refused(lambda: T(t, [*x[:-1], None]), "q holds None")
    _api_refused(lambda: T(t, x > 0), "q has dtype bool")
    _api_refused(lambda: T([], []), "t must be a non-empty 1-D array")
    _api_refused(lambda: T(np.zeros(0), np.zeros((0, 2))), "non-empty")
    _api_refused(lambda: T([t, []], [x, []]), "t[1] must be a non-empty 1-D array")
    _api_refused(lambda: T(t, [[1.0, 2.0], [3.0]] * 10), "q is not an array of numbers", "rectangular")
    _api_refused(lambda: T([t, t[:12]], [x, x[:10]]), "q[1] must have shape (12, 1) like t[1], got (10, 1)")
    _api_refused(lambda: T(t, x, qd=x[:7]), "q_dot must have the shape of q (20, 1), got (7, 1)")
    _api_refused(
        lambda: T(t, np.ones((len(t), 40)) * x[:, None]), f"40 coordinate columns; expected at most {MAX_COORDS}"
    )


def test_api_trajectory_ids_stay_exact():
    t, x = _good(16)
    T = nnphd.Trajectories
    ids = np.array([2**53] * 8 + [2**53 - 1] * 8, dtype=np.int64)  # as float64 these merge
    d = T(t, np.sin(3 * t) + x, traj=ids)
    assert d.n_trajectories == 2  # not merged into one
    ud = rec.from_arrays(t, np.sin(3 * t) + x, traj=ids)  # what the constructor holds: the ids as given
    assert [tr.id for tr in ud.trajectories] == [2**53, 2**53 - 1]
    _api_refused(lambda: T(t, x, traj=[2**53 + 1] * 16), "traj index 0", "2**53")
    _api_refused(lambda: T(t, x, traj=np.array([0.2] * 8 + [0.7] * 8)), "traj index 0: 0.2 is not an integer id")
    _api_refused(lambda: T(t, x, traj=np.full(16, np.nan)), "traj index 0")
    _api_refused(lambda: T(t, x, traj=["a"] * 16), "traj has dtype <U1", "integer trajectory ids")
    _api_refused(lambda: T(t, x, traj=np.zeros(15)), "traj must have one id per sample (16)")
    assert T(t, x, traj=[1.0] * 8 + [2] * 8).n_trajectories == 2  # whole floats and mixed lists are fine
    assert T(t, x, traj=np.array([10**3] * 8 + [5] * 8, dtype=object)).n_trajectories == 2


def test_api_names_and_angles():
    t = np.arange(20) * 0.1
    q = np.column_stack([np.cos(t), np.sin(t)])
    T = nnphd.Trajectories
    assert T(t, q[:, 0], names="theta", angles="theta").angles == ("theta",)  # one name, not its letters
    assert T(t, q, names=["x", "theta"], angles="theta").angles == ("theta",)
    _api_refused(lambda: T(t, q, names="xy"), "names must be 2 distinct names (one per column of q), got 1")
    _api_refused(lambda: T(t, q[:, 0], names=[""]), "names[0] has no name")
    _api_refused(lambda: T(t, q[:, 0], names=[" x"]), "leading or trailing whitespace")
    _api_refused(lambda: T(t, q[:, 0], names=["x\ny"]), "control character '\\n'")
    _api_refused(lambda: T(t, q[:, 0], names=["a" * 200]), f"expected at most {MAX_NAME}")
    _api_refused(lambda: T(t, q[:, 0], names=[3]), "names[0]: the name 3 is a int; expected a str")
    _api_refused(lambda: T(t, q, names=["x", "x"]), "duplicate column name 'x'")
    _api_refused(lambda: T(t, q, names=["x", "t"]), "must not be 't'")
    _api_refused(lambda: T(t, q, names=["x", "y"], angles="theta"), "angle 'theta' is not a coordinate")
    _api_refused(lambda: T(t, q, names=["x", "y"], angles=[1]), "angle 1 is a int")


def test_api_from_dataframe_and_files():
    t = np.arange(20) * 0.1
    T = nnphd.Trajectories
    _api_refused(lambda: T.from_dataframe({"t": t, "x": np.cos(t)[:15]}), "column 'x' has shape (15,)", "equal")
    _api_refused(lambda: T.from_dataframe({"t": t, "x": [[1, 2], [3]]}), "column 'x' is not an array of numbers")
    _api_refused(lambda: T.from_dataframe({"t": t, "x": np.cos(t) * 1j}), "column 'x' is complex")
    _api_refused(lambda: T.from_dataframe({"t": [], "x": []}), "no samples")
    _api_refused(lambda: T.from_dataframe({"t": t, "x": np.cos(t), "traj": [0.5] * 20}), "not an integer id")
    _api_refused(lambda: T.from_dataframe(42), "expected a DataFrame or a mapping")
    cols = {"t": t, **{f"c{j}": np.cos(t + j) for j in range(1000)}}
    _api_refused(lambda: T.from_dataframe(cols), "1,001 columns", f"at most {MAX_COLUMNS}")
    d = T.from_dataframe({"t": t, "theta": np.cos(t), "traj": [2**53] * 10 + [2**53 - 1] * 10}, angles="theta")
    assert d.angles == ("theta",) and d.n_trajectories == 2
    _api_refused(lambda: T.from_csv("x.npz"), "expected a .csv file")


# ---- the command line --------------------------------------------------------------------------------------------
@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="needs FIFOs")
def test_cli_refuses_a_device_link_and_a_fifo_and_writes_nothing(tmp_path, capsys, monkeypatch):
    fifo = tmp_path / "pipe.csv"
    os.mkfifo(fifo)
    link = tmp_path / "zero.csv"
    link.symlink_to("/dev/zero")
    opened = _spy_on_open(monkeypatch)
    for path, kind in ((link, "a character device"), (fifo, "a FIFO (named pipe)")):
        out = tmp_path / f"out_{path.stem}"
        rc = main(["detect", str(path), "--out", str(out)])
        err = capsys.readouterr().err
        # refused before it was opened: nothing read from the device, nothing to block on
        assert rc == 2 and all(os.path.isfile(p) for p in opened), opened
        assert len(err.strip().splitlines()) == 1 and err.startswith("error: "), err
        assert f"not a regular file ({kind})" in err
        assert not out.exists()
