"""Hardening of the command line and the execution layer: nothing a run opens listens beyond loopback, a
bad or unreachable --scheduler and a --p out of range are one-line input errors (exit 2), and a failed or interrupted
run leaves no result file and no folder it created behind."""

from __future__ import annotations

import os
import socket
from pathlib import Path

import pytest

from nnphd.cli import main
from nnphd.parallel import SchedulerError, Unit, check_scheduler_address, run_units

LOOPBACK = {"127.0.0.1", "::1"}


def _listening() -> list[tuple[int, str, int]]:
    """(pid, ip, port) of every listening TCP socket of this process and all its descendants."""
    import psutil

    me = psutil.Process()
    found = []
    for proc in [me, *me.children(recursive=True)]:
        try:
            conns = proc.net_connections(kind="inet")
        except psutil.Error:  # a process that ended meanwhile
            continue
        found += [(proc.pid, c.laddr.ip, c.laddr.port) for c in conns if c.status == psutil.CONN_LISTEN]
    return found


def test_local_cluster_listens_on_loopback_only():
    """During a 2-worker run (scheduler here, nannies and workers in child processes) every listening socket of the
    process tree — the scheduler's and workers' comms and their HTTP servers (/health, /metrics …) — is bound to
    127.0.0.1 or ::1; with Dask's default dashboard_address (":8787" or ":0": every interface) this fails."""
    seen: list[list[tuple[int, str, int]]] = []
    outs = run_units(
        [Unit("a", dict, {"x": 1}), Unit("b", dict, {"x": 2})],  # dict: picklable by name, and cheap
        workers=2,
        on_outcome=lambda _oc: seen.append(_listening()),  # called here while the cluster is up
    )
    assert all(o.ok for o in outs.values()) and outs["b"].value == {"x": 2}
    socks = {s for snap in seen for s in snap}
    assert len({pid for pid, _, _ in socks}) >= 2 and len(socks) >= 4, socks  # scheduler here + the workers
    assert all(ip in LOOPBACK for _, ip, _ in socks), sorted(socks)


@pytest.mark.parametrize("address", ["not-an-address", "tcp://host", "tcp://host:abc", "tcp://host:0", " "])
def test_scheduler_address_form(address, tmp_path, capsys):
    """A malformed --scheduler: one line, exit 2, checked when the command line is read (nothing is created)."""
    out = tmp_path / "a" / "b"
    rc = main(["study", "lambda-p", "--steps", "4", "--scheduler", address, "--out", str(out)])
    err = [ln for ln in capsys.readouterr().err.splitlines() if ln.strip()]
    assert rc == 2 and len(err) == 1, err
    assert err[0] == f"error: --scheduler {address!r} is not a Dask scheduler address (expected tcp://host:port)"
    assert list(tmp_path.iterdir()) == []
    with pytest.raises(SchedulerError):
        run_units([Unit("a", dict)], scheduler=address)


def test_scheduler_address_good_forms():
    for a in ("tcp://127.0.0.1:8786", "host:8786", "tcp://[::1]:8786"):
        assert check_scheduler_address(a) == a
    for a in ("tls://h.example:1", "ucx://h:1", "inproc://x", "ws://h:80"):  # tls:// crashed in Dask (no context)
        with pytest.raises(SchedulerError, match=r"transport is not supported \(expected tcp://host:port\)"):
            check_scheduler_address(a)


@pytest.mark.parametrize("reply", [b"", b"HTTP/1.0 400 Bad Request\r\n\r\n"])
def test_a_server_that_is_not_dask_is_one_line(reply, monkeypatch):
    """--scheduler at something that accepts but is no Dask scheduler: silent (Dask's timeout does not cover it:
    an HTTP server hung the run for minutes) or answering HTTP (read as a frame length of exabytes: MemoryError,
    reported as 'out of memory'). Either way SchedulerError (exit 2) within the connect timeout's bound."""
    import threading

    srv = socket.socket()
    srv.bind(("127.0.0.1", 0))
    srv.listen(4)
    srv.settimeout(10)
    conns = []

    def serve():
        try:
            while True:
                c, _ = srv.accept()
                conns.append(c)
                if reply:
                    c.recv(65536)
                    c.sendall(reply * 4)
        except OSError:
            pass

    threading.Thread(target=serve, daemon=True).start()
    monkeypatch.setenv("NNPHD_SCHEDULER_TIMEOUT", "0.5")
    try:
        with pytest.raises(SchedulerError) as e:
            run_units([Unit("a", dict), Unit("b", dict)], scheduler=f"tcp://127.0.0.1:{srv.getsockname()[1]}")
        assert "\n" not in str(e.value) and "Dask scheduler" in str(e.value)
    finally:
        srv.close()
        for c in conns:
            c.close()


def test_unreachable_scheduler_one_line_exit_2(tmp_path, capsys, monkeypatch):
    """A scheduler address where nothing listens (a closed port here): one line within the connect timeout
    (NNPHD_SCHEDULER_TIMEOUT), exit 2, and the folders the run created are gone."""
    with socket.socket() as s:  # a port that was free a moment ago: nothing listens there
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    monkeypatch.setenv("NNPHD_SCHEDULER_TIMEOUT", "0.5")
    address = f"tcp://127.0.0.1:{port}"
    out = tmp_path / "a" / "b"
    argv = ["study", "lambda-p", "--systems", "ho+ld", "--ps", "1", "--lambdas", "0.5,2", "--steps", "4"]
    rc = main([*argv, "--scheduler", address, "--out", str(out)])
    err = [ln for ln in capsys.readouterr().err.splitlines() if ln.strip()]
    assert rc == 2 and len(err) == 1, err
    assert err[0].startswith(f"error: --scheduler {address!r} cannot be reached within 0.5 s"), err
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(
    "argv",
    [
        ["sweep", "--system", "ho+ld", "--p", "1000"],
        ["sweep", "--system", "ho+ld", "--loss-p", "10.5"],
        ["study", "lambda-p", "--ps", "1,1000"],
    ],
)
def test_p_out_of_range_exit_2_nothing_written(argv, tmp_path, capsys):
    out = tmp_path / "a" / "b"
    assert main([*argv, "--out", str(out)]) == 2
    err = [ln for ln in capsys.readouterr().err.splitlines() if ln.strip()]
    assert len(err) == 1 and err[0].startswith("error: p must be at most 10 (or 'mse'), got "), err
    assert list(tmp_path.iterdir()) == []


def test_p_at_the_limit_is_accepted():
    from nnphd.cli.common import MAX_P, parse_loss_p

    assert parse_loss_p(str(MAX_P)) == MAX_P and parse_loss_p("MSE") == "mse" and parse_loss_p("1") == 1


def test_p_limit_holds_for_the_api_too():
    """The command line's help quotes the engine's limit; the Python API (run_sweep, lambda_p_study) refuses the
    same p."""
    from nnphd.cli.common import MAX_P
    from nnphd.engine import train

    assert train.MAX_P == MAX_P
    with pytest.raises(ValueError, match="at most 10"):
        train.parse_p(1000)
    assert train.parse_p(10.0) == 10.0


def _sweep_raises(monkeypatch, exc, write=()):
    """nnphd sweep's run_sweep replaced by one that writes ``write`` (names in --out) as nnphd writes its files
    (:func:`nnphd.io.results.atomic_write_bytes`, which keeps the list of what this run wrote) and raises ``exc``."""
    import nnphd.paper.sweep as sweep_mod
    from nnphd.io.results import atomic_write_bytes

    def run(*a, out=None, **k):
        for name in write:
            atomic_write_bytes(Path(out) / name, b"{}")
        raise exc

    monkeypatch.setattr(sweep_mod, "run_sweep", run)


@pytest.mark.parametrize("exc,code", [(KeyboardInterrupt(), 130), (RuntimeError("boom"), 1), (MemoryError(), 1)])
def test_failed_run_removes_the_folders_it_created(exc, code, tmp_path, capsys, monkeypatch):
    """--out a/b/c where only tmp_path existed: an interrupt or a failure removes c, b and a (innermost first),
    and leaves tmp_path; the results.json the failed run wrote is removed too."""
    _sweep_raises(monkeypatch, exc, write=["results.json"])
    (tmp_path / "keep").mkdir()  # a folder that existed before stays, empty or not
    out = tmp_path / "a" / "b" / "c"
    assert main(["sweep", "--system", "ho+ld", "--out", str(out)]) == code
    err = [ln for ln in capsys.readouterr().err.splitlines() if ln.strip()]
    assert len(err) == 1 and err[0].startswith("error: "), err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["keep"]


def test_existing_parents_and_other_files_stay(tmp_path, capsys, monkeypatch):
    """Only folders the run created are removed, and only if empty: a/ existed (kept), a/b/ was created but holds
    a checkpoint at the end (kept, and named as the place to resume from)."""
    (tmp_path / "a").mkdir()
    out = tmp_path / "a" / "b"
    _sweep_raises(monkeypatch, KeyboardInterrupt(), write=[".checkpoint.npz", "results.json"])
    assert main(["sweep", "--system", "ho+ld", "--out", str(out)]) == 130
    err = capsys.readouterr().err.strip()
    assert "run the same command again to resume" in err and "\n" not in err
    assert sorted(p.name for p in out.iterdir()) == [".checkpoint.npz"]  # results.json of the failed run is gone


def test_an_older_result_file_is_kept(tmp_path, capsys, monkeypatch):
    """A results.json the failed run did not write (a finished earlier run's) stays."""
    out = tmp_path / "o"
    out.mkdir()
    (out / "results.json").write_text('{"old": 1}')
    os.utime(out / "results.json", (1_000_000_000, 1_000_000_000))
    _sweep_raises(monkeypatch, RuntimeError("boom"))
    assert main(["sweep", "--system", "ho+ld", "--out", str(out)]) == 1
    assert "internal error" in capsys.readouterr().err
    assert (out / "results.json").read_text() == '{"old": 1}'


@pytest.mark.parametrize("existed", [False, True])
def test_default_out_folder_is_removed_on_interrupt(existed, tmp_path, capsys, monkeypatch):
    """No --out: the default out/sweep (and out/, if the run created it) go on an interrupt; an out/ that existed
    stays."""
    monkeypatch.chdir(tmp_path)
    if existed:
        (tmp_path / "out").mkdir()
    _sweep_raises(monkeypatch, KeyboardInterrupt())
    assert main(["sweep", "--system", "ho+ld"]) == 130
    assert capsys.readouterr().err.strip() == "error: interrupted"
    assert [p.name for p in tmp_path.iterdir()] == (["out"] if existed else [])
    if existed:
        assert list((tmp_path / "out").iterdir()) == []


def test_default_out_of_reproduce_is_removed_on_failure(tmp_path, capsys, monkeypatch):
    """reproduce chooses its default --out in the command (out/reproduce-quick with --quick): removed too."""
    import nnphd.paper.reproduce as rep

    monkeypatch.chdir(tmp_path)

    def broken(**kw):
        raise KeyboardInterrupt

    monkeypatch.setattr(rep, "reproduce", broken)
    assert main(["reproduce", "--quick", "--workers", "1"]) == 130
    assert capsys.readouterr().err.strip() == "error: interrupted"
    assert list(tmp_path.iterdir()) == []


def test_default_out_of_detect_is_removed_on_interrupt(tmp_path, capsys, monkeypatch):
    """nnphd detect FILE without --out: its default out/detect (and out/) go again on an interrupt; the file stays."""
    import math

    import nnphd.user.detect as ud

    monkeypatch.chdir(tmp_path)
    rows = "".join(f"{0.1 * i:.3f},{math.cos(0.1 * i):.9f}\n" for i in range(40))
    (tmp_path / "d.csv").write_text("t,x\n" + rows)

    def interrupted(*a, **k):
        raise KeyboardInterrupt

    monkeypatch.setattr(ud, "detect_data", interrupted)
    assert main(["detect", "d.csv"]) == 130
    assert capsys.readouterr().err.strip() == "error: interrupted"
    assert [p.name for p in tmp_path.iterdir()] == ["d.csv"]
