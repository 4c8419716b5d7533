"""Hostile files: no raw terminal control reaches the console, and the smaller holes — an
infinite NNPHD_SCHEDULER_TIMEOUT, Dask's shared scratch folder, an unchecked compile cache folder, thousands of
--lambdas — are closed. The hostile names and folders are built here at run time; nothing trains."""

from __future__ import annotations

import ast
import os
import stat
import subprocess
import sys
import tempfile
import textwrap
import unicodedata
import warnings
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from nnphd.cli import main
from nnphd.io.escape import TERMINAL_ESCAPED, one_line, rich, terminal

# ESC ] 0 ; … BEL (sets the window title), ESC [ 2 J (clears the screen), a right-to-left override, a C1 CSI, DEL
TITLE, CLEAR, RLO, CSI, DEL = "\x1b]0;pwned\x07", "\x1b[2J", "\u202e", "\x9b", "\x7f"
RAW = ("\x1b", "\x07", "\x9b", "\x7f", "\u202e", "\u2066", "\u200f", "\x00")  # none of these may reach the console
SHOWN_TITLE, SHOWN_CLEAR, SHOWN_RLO = r"\x1b]0;pwned\x07", r"\x1b[2J", r"\u202e"


def _no_raw(text: str) -> None:
    """No raw control, format or bidi character in console text (newlines of the output itself aside)."""
    bad = sorted({c for c in text if c not in "\n" and unicodedata.category(c) in TERMINAL_ESCAPED})
    assert not bad, (bad, text)
    assert not any(c in text for c in RAW)


def _csv(path: Path, header: str = "t,x", n: int = 40) -> Path:
    t = np.arange(n) * 0.1
    path.write_text(header + "\n" + "".join(f"{ti},{np.cos(ti)}\n" for ti in t))
    return path


# ---- terminal(): the one function every console text goes through ------------------------------------------------


def test_terminal_shows_controls_and_bidi_as_escapes():
    name = f"a{TITLE}b{CLEAR}c{RLO}d{CSI}e{DEL}\n\t\u2028\u2069\u061c\ufeff\U000e0001\udc9b"
    shown = terminal(name)
    assert shown == (r"a\x1b]0;pwned\x07b\x1b[2Jc\u202ed\x9be\x7f\n\t\u2028\u2069\u061c\ufeff\U000e0001\udc9b")
    assert terminal("data/λ-sweep [1] ünïcode ✓.csv") == "data/λ-sweep [1] ünïcode ✓.csv"  # printable: unchanged
    assert terminal(3.5) == "3.5"
    # one-line messages: their own line breaks become spaces, every other control an escape, cut before escaping
    assert one_line(f"x:\n  y{CLEAR}\tz\x1c") == r"x: y\x1b[2J z\x1c"
    assert one_line("ab\x1bcd", 3) == r"ab\x1b…"


hostile_text = st.text(
    alphabet=st.characters(exclude_categories=())  # every code point, surrogates included
    | st.sampled_from([*RAW, "\n", "\t", "\r", "\\", "[", "]", "\u2028", "\U000e0041", "\u0378"]),
    max_size=40,
)


@settings(max_examples=400, deadline=None)
@given(text=hostile_text)
def test_terminal_property(text):
    """terminal(): no character of a control, format or separator category survives (so no Cc/Cf reaches a
    terminal); everything else is kept as it is, character by character; each escape reads back (as a Python
    string literal) to the one character it shows; applying it twice changes nothing."""
    out = terminal(text)
    assert not any(unicodedata.category(c) in TERMINAL_ESCAPED for c in out)
    assert not any(unicodedata.category(c) in ("Cc", "Cf") for c in out)
    assert out == "".join(terminal(c) for c in text)
    for c in text:
        if unicodedata.category(c) in TERMINAL_ESCAPED:
            assert terminal(c) != c and ast.literal_eval(f'"{terminal(c)}"') == c
        else:
            assert terminal(c) == c
    assert terminal(out) == out
    line = one_line(text)
    assert "\n" not in line and not any(unicodedata.category(c) in TERMINAL_ESCAPED for c in line)


@settings(max_examples=200, deadline=None)
@given(text=st.text(alphabet=st.characters(exclude_categories=tuple(TERMINAL_ESCAPED)), max_size=40))
def test_terminal_keeps_printable_text(text):
    assert terminal(text) == text


def test_rich_applies_terminal():
    import io

    from rich.console import Console

    con = Console(file=io.StringIO(), width=10_000, emoji=False)
    con.print(f"[bold]v[/] {rich(f'{TITLE}[/x]{CLEAR}{RLO}')}", highlight=False)
    out = con.file.getvalue()
    _no_raw(out)
    assert out == f"v {SHOWN_TITLE}[/x]{SHOWN_CLEAR}{SHOWN_RLO}\n"


# ---- through the command line --------------------------------------------------------------------------------------


def test_batch_table_and_error_show_hostile_file_names_escaped(tmp_path, capsys, monkeypatch):
    """`nnphd detect a.csv b.csv --out o` on two bad CSVs whose names hold ESC]0;…BEL, ESC[2J, U+202E and a C1
    CSI: the batch table, the progress bar and the closing error line show the names escaped, never raw (the
    file column printed them raw: Rich escapes markup, not control codes)."""
    import nnphd.cli.common as common

    monkeypatch.setattr(common.console, "width", 10_000)  # no wrapping inside an escape
    a = tmp_path / f"a{TITLE}.csv"
    b = tmp_path / f"b{CLEAR}{RLO}{CSI}.csv"
    a.write_text("not a csv\n")
    b.write_text("t,x\n1,2\n")  # a single row: refused
    rc = main(["detect", str(a), str(b), "--out", str(tmp_path / "o"), "--workers", "1"])
    cap = capsys.readouterr()
    assert rc == 1
    _no_raw(cap.out + cap.err)
    assert terminal(a) in cap.out and terminal(b) in cap.out  # the table's file column
    assert f"a{SHOWN_TITLE}.csv" in cap.out and rf"b{SHOWN_CLEAR}{SHOWN_RLO}\x9b.csv" in cap.out
    err = [ln for ln in cap.err.splitlines() if ln.strip()]
    assert len(err) == 1 and err[0].startswith("error: 2 of 2 files failed") and SHOWN_TITLE in err[0]


@pytest.mark.parametrize("n_files", [1, 2])
def test_missing_file_error_is_escaped(n_files, tmp_path, capsys, monkeypatch):
    """`nnphd detect 'missing<ESC>[2J<RLO>.csv'` (one file, or in a batch beside a real one): one error line, exit 2,
    the name escaped."""
    monkeypatch.chdir(tmp_path)
    other = [str(_csv(tmp_path / "ok.csv"))] if n_files == 2 else []
    rc = main(["detect", f"missing{CLEAR}{RLO}{TITLE}.csv", *other, "--out", "o"])
    cap = capsys.readouterr()
    assert rc == 2
    _no_raw(cap.out + cap.err)
    err = [ln for ln in cap.err.splitlines() if ln.strip()]
    assert len(err) == 1 and f"missing{SHOWN_CLEAR}{SHOWN_RLO}{SHOWN_TITLE}.csv" in err[0], err
    assert not (tmp_path / "o").exists()


def test_click_errors_quoting_arguments_are_escaped(capsys):
    """An unknown option is quoted by click in its message, as typed: escaped in the one error line too."""
    rc = main(["detect", "x.csv", f"--bogus{CLEAR}{RLO}"])
    cap = capsys.readouterr()
    assert rc == 2
    _no_raw(cap.out + cap.err)
    assert SHOWN_CLEAR + SHOWN_RLO in cap.err


_SCRIPT = """
import sys, types, warnings
import nnphd.user.detect as ud
from nnphd.io.cache import warn_ignored
from nnphd.cli import main

TITLE, CLEAR, RLO, CSI = "\\x1b]0;pwned\\x07", "\\x1b[2J", "\\u202e", "\\x9b"

def fake_detect_data(data, out=None, progress=None, **kw):
    c = data.coords[0]
    progress(0, 1, f"training on {c} {TITLE}")
    warn_ignored(f"{out}/cache{CLEAR}.json", f"planted {RLO}")
    warnings.warn(f"column {c}: odd {CLEAR}{RLO}", UserWarning)
    formula = {f"{c}_ddot": f"-k*{c}_dot"}
    rep = {
        "status": "detected", "new_physics": True, "confidence": 0.9, "effect": f"friction {TITLE} on {c}",
        "warnings": [f"{c}: noisy {CLEAR}"], "angle_suggestions": [[c, f"wraps {RLO}"]], "reasons": [f"f_n of {c}"],
        "formula": None, "blind": False, "wall_time_s": 1.0,
        "law": {"law": {"title": f"linear {CSI}", "formula": formula, "params": {"k": 0.5}, "stderr": {"k": 0.1}}},
    }
    return types.SimpleNamespace(report=rep), None  # the CLI prints the result's report

ud.detect_data = fake_detect_data
sys.exit(main(sys.argv[1:]))
"""


def test_report_progress_and_warnings_are_escaped_on_a_real_terminal_stream(tmp_path):
    """A whole `nnphd detect` in a fresh process (its detection faked: no training) on a file and an --out whose
    names hold ESC]0;…BEL and U+202E, and whose report, progress message and warnings (an IgnoredFileWarning from
    :func:`nnphd.io.cache.warn_ignored` and a plain UserWarning) quote control characters: the real stdout and stderr
    hold none of them raw."""
    data = _csv(tmp_path / f"d{TITLE}{RLO}.csv")
    out = tmp_path / f"o{CLEAR}"
    env = {**os.environ, "COLUMNS": "10000", "NNPHD_COMPILE_CACHE": "0"}
    res = subprocess.run(
        [sys.executable, "-c", textwrap.dedent(_SCRIPT), "detect", str(data), "--out", str(out)],
        capture_output=True,
        env=env,
        timeout=120,
    )
    text = (res.stdout + res.stderr).decode("utf-8", "surrogateescape")
    assert res.returncode == 0, text
    _no_raw(text)
    for shown in (
        rf"training on x {SHOWN_TITLE}",  # the progress bar's last message
        rf"friction {SHOWN_TITLE} on x",  # the report
        rf"x: noisy {SHOWN_CLEAR}",
        rf"wraps {SHOWN_RLO}",
        r"linear \x9b",
        rf"o{SHOWN_CLEAR}/report.json",  # --out
        rf"cache{SHOWN_CLEAR}.json: ignored (planted {SHOWN_RLO}); starting from scratch",  # IgnoredFileWarning
        rf"column x: odd {SHOWN_CLEAR}{SHOWN_RLO}",  # any other warning
    ):
        assert shown in text, (shown, text)


def test_warn_ignored_message_is_escaped(tmp_path):
    from nnphd.io.cache import IgnoredFileWarning, warn_ignored

    with pytest.warns(IgnoredFileWarning) as rec:
        warn_ignored(tmp_path / f"r{TITLE}.json", f"bad\n{RLO}")
    msg = str(rec[0].message)
    _no_raw(msg)
    assert "\n" not in msg and f"r{SHOWN_TITLE}.json: ignored (bad {SHOWN_RLO})" in msg


# ---- NNPHD_SCHEDULER_TIMEOUT: a finite number of seconds --------------------------------------------------------


@pytest.mark.parametrize("value", ["inf", "1e300", "nan", "-1", "0", "86401", "abc", "-inf"])
def test_bad_scheduler_timeout_is_one_line_exit_2(value, tmp_path, capsys, monkeypatch):
    """NNPHD_SCHEDULER_TIMEOUT=inf (or 1e300, nan, -1 …) gave `internal error (OverflowError …)`: now one line naming
    the variable and what it takes, exit 2, before anything is created or contacted — and a SchedulerError from
    the API before any unit is submitted."""
    from nnphd.parallel import SchedulerError, Unit, connect_timeout, run_units

    monkeypatch.setenv("NNPHD_SCHEDULER_TIMEOUT", value)
    out = tmp_path / "a" / "b"
    argv = ["study", "lambda-p", "--systems", "ho+ld", "--ps", "1", "--lambdas", "0.5,2", "--steps", "4"]
    rc = main([*argv, "--scheduler", "tcp://127.0.0.1:9", "--out", str(out)])
    err = [ln for ln in capsys.readouterr().err.splitlines() if ln.strip()]
    assert rc == 2 and len(err) == 1, err
    assert err[0].startswith(f"error: NNPHD_SCHEDULER_TIMEOUT={value!r} is not a number of seconds"), err
    assert "at most 86400" in err[0] and "internal error" not in err[0]
    assert list(tmp_path.iterdir()) == []
    with pytest.raises(SchedulerError, match="NNPHD_SCHEDULER_TIMEOUT"):
        connect_timeout()
    with pytest.raises(SchedulerError, match="NNPHD_SCHEDULER_TIMEOUT"):
        run_units([Unit("a", dict)], scheduler="tcp://127.0.0.1:9")


def test_good_scheduler_timeouts(monkeypatch):
    from nnphd.parallel import CONNECT_TIMEOUT_S, connect_timeout

    for value, expected in (("0.5", 0.5), (" 86400 ", 86400.0), ("", CONNECT_TIMEOUT_S)):
        monkeypatch.setenv("NNPHD_SCHEDULER_TIMEOUT", value)
        assert connect_timeout() == expected
    monkeypatch.delenv("NNPHD_SCHEDULER_TIMEOUT")
    assert connect_timeout() == CONNECT_TIMEOUT_S


# ---- --workers: Dask's scratch space in a private folder ----------------------------------------------------------


def test_local_cluster_scratch_is_private_and_removed():
    """The scheduler's, the nanny's and the worker's scratch folders lie in one folder of this user, mode 0700 (not
    Dask's shared, predictable <tmp>/dask-scratch-space); afterwards it is gone, and so are the sys.path entries
    Dask had put into it."""
    from distributed import Client

    from nnphd.parallel import local_cluster

    shared = os.path.join(tempfile.gettempdir(), "dask-scratch-space")
    with local_cluster(1) as cluster:
        with Client(cluster) as client:
            worker_dirs = list(client.run(lambda dask_worker: dask_worker.local_directory).values())
        dirs = [*worker_dirs, cluster.scheduler.local_directory, *(n.local_directory for n in cluster.workers.values())]
        top = {Path(d).parent.parent if Path(d).name != "dask-scratch-space" else Path(d).parent for d in dirs}
        assert len(worker_dirs) == 1 and len(top) == 1, dirs
        (private,) = top
        st_ = os.stat(private)
        assert stat.S_IMODE(st_.st_mode) == 0o700 and st_.st_uid == os.getuid(), oct(st_.st_mode)
        assert not any(d.startswith(shared) for d in dirs), dirs
        assert os.path.isdir(worker_dirs[0])
    assert not private.exists()
    assert not any(str(p).startswith(str(private)) for p in sys.path)


# ---- the compile cache folder must be the user's own ------------------------------------------------------------


def test_compile_cache_folder_created_private(tmp_path):
    from nnphd import compile_cache_problem

    cache = tmp_path / "xdg" / "nnphd" / "jax"
    assert compile_cache_problem(cache) is None
    assert cache.is_dir() and stat.S_IMODE(cache.stat().st_mode) == 0o700
    ok = tmp_path / "mine"
    ok.mkdir(mode=0o755)
    os.chmod(ok, 0o755)
    assert compile_cache_problem(ok) is None  # readable by others is fine: only writing is not


def _refused(cache: Path, monkeypatch) -> str:
    """configure() with ``cache``: the warning's text; JAX's cache folder is left as it was."""
    import jax

    import nnphd

    monkeypatch.setenv(nnphd.COMPILE_CACHE_ENV, str(cache))
    before = jax.config.jax_compilation_cache_dir
    with warnings.catch_warnings(record=True) as rec:
        warnings.simplefilter("always")
        nnphd.configure(compile_cache=cache)
    assert jax.config.jax_compilation_cache_dir == before
    assert os.environ[nnphd.COMPILE_CACHE_ENV] == "0"  # the workers started from here skip it too
    msgs = [str(w.message) for w in rec if issubclass(w.category, nnphd.CompileCacheWarning)]
    assert len(msgs) == 1 and "\n" not in msgs[0], [str(w.message) for w in rec]
    return msgs[0]


def test_compile_cache_writable_by_others_is_refused(tmp_path, monkeypatch):
    cache = tmp_path / f"shared{CLEAR}"
    cache.mkdir()
    os.chmod(cache, 0o777)
    msg = _refused(cache, monkeypatch)
    _no_raw(msg)
    assert msg.startswith(str(tmp_path) + f"/shared{SHOWN_CLEAR}: not used as the compile cache (writable by group")
    assert "mode 777" in msg and "compiling without it" in msg
    os.chmod(cache, 0o720)
    assert "writable by group (mode 720" in _refused(cache, monkeypatch)


def test_compile_cache_of_another_owner_is_refused(tmp_path, monkeypatch):
    cache = tmp_path / "theirs"
    cache.mkdir(mode=0o700)
    real = os.getuid()
    monkeypatch.setattr(os, "getuid", lambda: real + 4242)  # as if the folder were someone else's
    msg = _refused(cache, monkeypatch)
    assert f"owned by another user (uid {real})" in msg


# ---- --lambdas is bounded ---------------------------------------------------------------------------------------


def test_lambdas_count_is_bounded(tmp_path, capsys):
    from nnphd.cli.common import MAX_LAMBDAS, InputError, parse_lambdas

    grid = [str(0.01 * 1.1**k) for k in range(MAX_LAMBDAS)]  # below and above 1, distinct
    assert len(parse_lambdas(",".join(grid))) == MAX_LAMBDAS >= 4 * 13  # the paper's 13 with a wide margin
    with pytest.raises(InputError, match=f"at most {MAX_LAMBDAS} values"):
        parse_lambdas(",".join([*grid, "3.3"]))
    many = ",".join(str(0.001 * (k + 1)) for k in range(5000))
    out = tmp_path / "a" / "b"
    for argv in (["sweep", "--system", "ho+ld"], ["study", "lambda-p"]):
        rc = main([*argv, "--lambdas", many, "--out", str(out)])
        err = [ln for ln in capsys.readouterr().err.splitlines() if ln.strip()]
        assert rc == 2 and err == [f"error: --lambdas takes at most {MAX_LAMBDAS} values (the paper's grid has 13), got 5000"]  # fmt: skip
    assert list(tmp_path.iterdir()) == []
