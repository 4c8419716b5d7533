"""Caches, checkpoints and batch inputs that nnphd did not write: a planted or edited cache in a shared or
pre-created ``--out`` is recomputed, never trusted (it carries no valid HMAC of this user's key); a cached file that
is a FIFO, a device or a link is refused without blocking; names on a batch's command line are taken like a
folder's entries (no links, no devices); a failed run removes only the files it wrote itself.  The hostile files are
built here, at run time."""

from __future__ import annotations

import json
import os
import threading
import time
import warnings

import numpy as np
import pytest

import nnphd.user.batch as batch
from nnphd.cli import main
from nnphd.cli.common import begin_run, claim_out, undo_run
from nnphd.io.cache import (
    Cache,
    IgnoredFileWarning,
    fingerprint,
    key_path,
    load_npz,
    normalise,
    save_npz,
    sign,
    signed_by_us,
)
from nnphd.io.outdir import release_out_dirs
from nnphd.io.results import write_json
from nnphd.paper import reproduce

SETTINGS = {"system": "ho+ld", "steps": 100, "seed": 0}


def _ignored(fn, *words):
    """fn() under recorded warnings: its value and the one IgnoredFileWarning line, which holds every word."""
    with warnings.catch_warnings(record=True) as w:
        warnings.simplefilter("always")
        value = fn()
    msgs = [str(x.message) for x in w if issubclass(x.category, IgnoredFileWarning)]
    assert len(msgs) == 1 and "\n" not in msgs[0], msgs
    for word in words:
        assert word in msgs[0], (word, msgs[0])
    return value


def _quiet(fn):
    with warnings.catch_warnings():
        warnings.simplefilter("error", IgnoredFileWarning)
        return fn()


# ---- the signature ------------------------------------------------------------------------------------------------
def test_the_key_is_private_and_a_signature_covers_every_value():
    _quiet(lambda: sign({}))  # creates the key where there is none
    st = os.lstat(key_path())
    assert st.st_mode & 0o777 == 0o600 and st.st_size == 32 and st.st_uid == os.getuid()
    obj = {"status": "none", "confidence": 1.0, "nested": {"L_e": [0.1, 2.5e-9]}}
    signed = {**obj, "signature": sign(obj)}
    assert signed_by_us(signed)
    for forged in (
        {**signed, "status": "detected"},
        {**signed, "nested": {"L_e": [0.1, 2.5e-8]}},
        {**obj, "signature": "0" * 64},
        dict(obj),
        {**obj, "signature": None},
    ):
        assert not signed_by_us(forged)
    assert sign(obj, b"a") != sign(obj, b"b") != sign(obj)


def test_a_planted_result_with_the_public_fingerprint_is_recomputed(tmp_path):
    cache = Cache(tmp_path, SETTINGS)
    planted = {"status": "pwned", "fingerprint": fingerprint(SETTINGS)}  # the fingerprint is a public hash
    write_json(tmp_path / "results.json", planted)
    assert _ignored(cache.load, "results.json", "not signed") is None
    saved = cache.save({"status": "none", "L_e": [1e-3, 2.0]})
    assert _quiet(cache.load) == saved  # what this user's nnphd wrote is used
    edited = json.loads((tmp_path / "results.json").read_text())
    edited["status"] = "detected"
    write_json(tmp_path / "results.json", edited)
    assert _ignored(cache.load, "not signed") is None


def test_a_forged_checkpoint_never_changes_a_resumed_sweep(tmp_path):
    """A sweep resumes from ``Cache.restore`` (nnphd.paper.sweep.SweepPlan.run): the steps of a checkpoint whose
    metadata or weights were edited, or that was written without this user's key, are not restored."""
    like = {"w": np.zeros((2, 3)), "b": np.zeros(3)}
    cache = Cache(tmp_path, SETTINGS)
    tree = {"w": np.arange(6.0).reshape(2, 3), "b": np.ones(3)}
    cache.checkpoint({0.5: ({"L_e": 0.25}, tree), 2.0: ({"L_e": 0.5}, tree)})
    assert sorted(_quiet(lambda: cache.restore(like))) == [0.5, 2.0]
    path = tmp_path / Cache.CHECKPOINT
    meta, arrays = load_npz(path)

    def forged(m, a):
        save_npz(path, m, a)
        return _ignored(lambda: cache.restore(like), str(path), "not signed")

    steps = [[k, {**md, "L_e": 1e-9}] for k, md in meta["steps"]]  # "no new physics": a tiny recovery error
    assert forged({**meta, "steps": steps}, arrays) == {}
    assert forged(meta, {**arrays, "s0_0": np.zeros_like(arrays["s0_0"])}) == {}
    unsigned = {k: v for k, v in meta.items() if k != "signature"}
    assert forged(unsigned, arrays) == {}


# ---- a batch's cached reports ------------------------------------------------------------------------------------
def _stub_detect(calls):
    def detect_file(path, out, angles=(), max_rows=None, **settings):
        calls.append(path)
        rep = {"status": "none", "confidence": 1.0, "effect": None, "reasons": ["stub"], "law": None}
        os.makedirs(out, exist_ok=True)
        write_json(os.path.join(out, "report.json"), rep)
        return rep

    return detect_file


def _plant(out, data, report_text):
    """A batch cache as an attacker makes it: batch.json with the (public) fingerprint of the file and settings."""
    key = {"file_sha256": batch.file_sha256(data), "angles": [], "max_rows": None}
    out.mkdir(parents=True, exist_ok=True)
    write_json(out / "batch.json", {"settings": key, "finished": 0, "fingerprint": fingerprint(normalise(key))})
    if report_text is not None:
        (out / "report.json").write_text(report_text)


@pytest.mark.parametrize(
    "report",
    [
        json.dumps({"status": "pwned", "confidence": 1.0}),
        json.dumps({"status": "detected", "confidence": "1.0", "law": {"status": "claimed"}}),
        json.dumps({"status": "detected", "confidence": 0.99, "law": {"status": "claimed", "law": {"law": "x"}}}),
    ],
)
def test_a_planted_batch_cache_is_not_reported(tmp_path, monkeypatch, report):
    import nnphd.user.detect as detect

    calls = []
    monkeypatch.setattr(detect, "detect_file", _stub_detect(calls))
    data = tmp_path / "a.csv"
    data.write_text("t,x\n0,1\n")
    out = tmp_path / "out" / "a"
    _plant(out, data, report)
    row = _ignored(lambda: batch.detect_one(str(data), str(out), "a"), "not signed")
    assert calls == [str(data)] and row["status"] == "none" and row["cached"] is False
    row = _quiet(lambda: batch.detect_one(str(data), str(out), "a"))  # its own cache is used on the rerun
    assert len(calls) == 1 and row["cached"] is True and row["status"] == "none"


def test_a_sealed_report_that_changed_or_is_not_a_file_is_recomputed_without_blocking(tmp_path, monkeypatch):
    import nnphd.user.detect as detect

    calls = []
    monkeypatch.setattr(detect, "detect_file", _stub_detect(calls))
    data = tmp_path / "a.csv"
    data.write_text("t,x\n0,1\n")
    out = tmp_path / "a"
    _quiet(lambda: batch.detect_one(str(data), str(out), "a"))
    rep = out / "report.json"
    text = rep.read_text()
    rep.write_text(text.replace('"none"', '"detected"'))  # edited after nnphd wrote it
    _ignored(lambda: batch.detect_one(str(data), str(out), "a"), "changed since nnphd wrote it")
    assert len(calls) == 2
    for make in (lambda: os.symlink("/dev/zero", rep), lambda: os.mkfifo(rep)):
        rep.unlink()
        make()
        row = _ignored(lambda: batch.detect_one(str(data), str(out), "a"), "report.json")  # nothing read or waited on
        assert row["status"] == "none" and not row["cached"]
        assert rep.is_file() and not rep.is_symlink()  # written anew by the stub (atomic rename over the link/FIFO)
    assert len(calls) == 4


def test_reproduce_does_not_wait_on_a_fifo_results_json(tmp_path):
    d = tmp_path / "unit"
    d.mkdir()
    runs = []

    def fn():
        runs.append(1)
        write_json(d / "results.json", {"value": len(runs)})
        return {"value": len(runs)}

    assert reproduce.run_unit(d, SETTINGS, fn, {}) == {"value": 1}
    assert _quiet(lambda: reproduce.run_unit(d, SETTINGS, fn, {})) == {"value": 1}  # sealed: loaded
    (d / "results.json").unlink()
    os.mkfifo(d / "results.json")
    done = {}
    worker = threading.Thread(target=lambda: done.update(v=_ignored(lambda: reproduce.run_unit(d, SETTINGS, fn, {}))))
    worker.start()
    worker.join(timeout=20)
    if worker.is_alive():  # unblock the reader so that the test run does not hang
        with open(d / "results.json", "w"):
            pass
        pytest.fail("reproduce blocked on a FIFO results.json")
    assert done["v"] == {"value": 2}


# ---- a batch's command line --------------------------------------------------------------------------------------
def test_links_fifos_and_devices_named_on_the_command_line_are_skipped(tmp_path):
    good = tmp_path / "a.csv"
    good.write_text("t,x\n0,1\n")
    secret = tmp_path / ".env"
    secret.write_text("API_KEY=sk-live-0123456789abcdef\n")
    os.symlink(secret, tmp_path / "env.csv")
    os.mkfifo(tmp_path / "fifo.csv")
    names = [good, tmp_path / "env.csv", tmp_path / "fifo.csv"] + ([] if not os.path.exists("/dev/zero") else ["/dev/zero"])  # fmt: skip
    files, skipped = batch.scan_paths(names)
    assert files == [good]
    reasons = {os.path.basename(s["file"]): s["reason"] for s in skipped}
    assert reasons["env.csv"] == "symbolic link, not followed" and reasons["fifo.csv"] == "not a regular file"
    assert reasons.get("zero", "not a regular file") == "not a regular file"
    with pytest.raises(ValueError, match="no .csv or .npz file to read: .*fifo.csv is not a regular file"):
        batch.scan_paths([tmp_path / "fifo.csv"])


def test_a_batch_copies_nothing_behind_a_link_into_its_summary(tmp_path, capsys):
    (tmp_path / "a.csv").write_text("t,x\n0,1\n")  # too short: an error row at once, no training
    secret = tmp_path / ".env"
    secret.write_text("API_KEY=sk-live-0123456789abcdef\n")
    os.symlink(secret, tmp_path / "b.csv")
    os.mkfifo(tmp_path / "c.csv")
    out = tmp_path / "out"
    args = [str(tmp_path / n) for n in ("a.csv", "b.csv", "c.csv")]
    rc = main(["detect", *args, "--out", str(out), "--workers", "1"])
    captured = capsys.readouterr()
    assert rc == 1  # one file gave an error; the link and the FIFO were skipped, not opened
    for name in ("summary.csv", "summary.json", "summary.html"):
        text = (out / name).read_text()
        assert "sk-live" not in text and "API_KEY" not in text
    assert "sk-live" not in captured.out + captured.err
    skipped = json.loads((out / "summary.json").read_text())["skipped"]
    assert [os.path.basename(s["file"]) for s in skipped] == ["b.csv", "c.csv"]


def test_a_file_swapped_for_a_fifo_after_the_scan_is_not_waited_on(tmp_path):
    fifo = tmp_path / "x.csv"
    os.mkfifo(fifo)
    with pytest.raises(ValueError, match="x.csv: not a regular file"):
        batch.file_sha256(fifo)


# ---- a failed run removes only what it wrote ---------------------------------------------------------------------
def test_a_failed_run_keeps_the_files_it_did_not_write(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    later = time.time() + 3600
    for name in ("report.json", "results.json", "summary.json", "table2.json"):
        (out / name).write_text("{}")
        os.utime(out / name, (later, later))  # modified "after the run started"
    begin_run()
    try:
        claim_out(out)
        undo_run()
        assert sorted(p.name for p in out.iterdir()) == ["report.json", "results.json", "summary.json", "table2.json"]
        write_json(out / "report.json", {"status": "none"})  # written by this run: removed
        write_json(out / "summary.json", {"rows": []})
        (out / "summary.json").unlink()
        (out / "summary.json").write_text("{}")  # put there by someone else since: kept
        undo_run()
        assert sorted(p.name for p in out.iterdir()) == ["results.json", "summary.json", "table2.json"]
    finally:
        release_out_dirs()


def test_the_batch_knows_every_verdict():
    from nnphd.api import Status

    assert set(batch.VERDICTS) == {s.value for s in Status}
