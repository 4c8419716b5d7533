"""nnphd detect: every bad input is a one-line error naming the problem, exit code 2, and nothing written."""

import errno
import os

import numpy as np
import pytest

from nnphd.cli import main


def _csv(path, header, rows):
    path.write_text(header + "\n" + "".join(",".join(str(v) for v in r) + "\n" for r in rows))
    return path


def _write(path, data):
    (path.write_bytes if isinstance(data, bytes) else path.write_text)(data)
    return path


def _good_rows(n=40):
    t = np.arange(n) * 0.1
    return [(ti, np.cos(ti), -np.sin(ti)) for ti in t]


BAD = {
    "empty": (lambda p: _write(p, ""), "the file is empty"),
    "header_only": (lambda p: _csv(p, "t,x", []), "no data rows"),
    "missing_t": (lambda p: _csv(p, "time,x", [(i, i * i) for i in range(20)]), "no 't' column"),
    "non_numeric": (
        lambda p: _csv(p, "t,x", [(i, "abc" if i == 3 else i * i) for i in range(20)]),
        "column 'x' row 4 (line 5): 'abc' is not a number",
    ),
    "unknown_column": (
        lambda p: _csv(p, "t,x,y_ddot", [(i, i * i, 0) for i in range(20)]),
        "column 'y_ddot' has no coordinate column 'y'",
    ),
    "nan": (lambda p: _csv(p, "t,x", [(i, "nan" if i == 5 else i * i) for i in range(20)]), "is not finite"),
    "inf": (lambda p: _csv(p, "t,x", [(i, "inf" if i == 5 else i * i) for i in range(20)]), "is not finite"),
    "non_monotonic": (
        lambda p: _csv(p, "t,x", [(5 - i if i == 6 else i, i * i) for i in range(20)]),
        "t is not strictly increasing",
    ),
    "duplicate_t": (lambda p: _csv(p, "t,x", [(i - 1 if i == 6 else i, i * i) for i in range(20)]), "duplicate time"),
    "too_few": (lambda p: _csv(p, "t,x", [(i, i * i) for i in range(4)]), "has 4 samples; at least 8"),
    "single": (lambda p: _csv(p, "t,x", [(0, 1)]), "single sample"),
    "constant": (lambda p: _csv(p, "t,x,y", [(i, 1, 2) for i in range(20)]), "all coordinates are constant"),
    "unreadable": (lambda p: _write(p.with_suffix(".npz"), b"not a zip file"), "cannot read as .npz"),
    "missing_file": (lambda p: p.with_name("nope.csv"), "file not found"),
    "wrong_type": (lambda p: _write(p.with_suffix(".dat"), "t,x\n0,1\n"), "unsupported file type"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_file_one_line_exit_2(case, tmp_path, capsys):
    make, msg = BAD[case]
    path = make(tmp_path / "data.csv")
    out = tmp_path / "out"
    rc = main(["detect", str(path), "--out", str(out)])
    err = capsys.readouterr().err
    assert rc == 2
    assert len(err.strip().splitlines()) == 1 and err.startswith("error: ")
    assert msg in err, err
    assert not out.exists()


def test_bad_angle_and_options(tmp_path, capsys):
    path = _csv(tmp_path / "d.csv", "t,x,v", _good_rows())
    for argv, msg in (
        (["--angles", "theta"], "angle 'theta' is not a coordinate"),
        (["--steps", "x"], "Invalid value for '--steps'"),
        (["--repeats", "0"], "--repeats"),
        (["--n-seeds", "0"], "Invalid value for '--n-seeds' / '--repeats'"),  # one setting, NNPhD(n_seeds=…)
        (["--angles", "x,"], "--angles must be comma-separated"),
        (["--width", "1"], "Invalid value for '--width': Input should be greater than or equal to 2"),
        (["--lambdas", "0.1,0.5"], "values both below and above 1"),
        (["--trim", "maybe"], "'maybe' is not one of 'auto', 'yes', 'no'"),
    ):
        rc = main(["detect", str(path), "--out", str(tmp_path / "o"), *argv])
        err = capsys.readouterr().err
        assert rc == 2 and msg in err and len(err.strip().splitlines()) == 1, err
        assert not (tmp_path / "o").exists()


def _deny_under(monkeypatch, folder, name):
    """``os.<name>`` of any path under ``folder`` fails as the kernel fails it for a user without write permission
    there (root is never refused, so the refusal is simulated rather than set up with chmod)."""
    real = getattr(os, name)

    def denied(path, *args, **kw):
        if os.path.abspath(os.fspath(path)).startswith(str(folder) + os.sep):
            raise PermissionError(errno.EACCES, os.strerror(errno.EACCES), os.fspath(path))
        return real(path, *args, **kw)

    monkeypatch.setattr(os, name, denied)


@pytest.mark.parametrize(
    "call,out",
    [("mkdir", "sub"), ("open", "")],  # a folder that cannot be made; an existing one where no file can be written
)
def test_unwritable_out(call, out, tmp_path, capsys, monkeypatch):
    path = _csv(tmp_path / "d.csv", "t,x", [(r[0], r[1]) for r in _good_rows()])
    ro = tmp_path / "ro"
    ro.mkdir()
    _deny_under(monkeypatch, ro, call)
    rc = main(["detect", str(path), "--out", str(ro / out)])
    err = capsys.readouterr().err
    assert rc == 2 and len(err.strip().splitlines()) == 1, err
    assert f"--out {str(ro / out)!r} is not a writable directory (Permission denied)" in err, err
    assert list(ro.iterdir()) == []  # nothing written: no folder, no probe file left behind


def test_out_is_a_file(tmp_path, capsys):
    path = _csv(tmp_path / "d.csv", "t,x", [(r[0], r[1]) for r in _good_rows()])
    f = tmp_path / "file"
    f.write_text("x")
    rc = main(["detect", str(path), "--out", str(f)])
    err = capsys.readouterr().err
    assert rc == 2 and "not a writable directory" in err and len(err.strip().splitlines()) == 1
