"""nnphd detect on many files: one report per file, a summary table (CSV, HTML, JSON), a bad file reported without
stopping the others, a rerun that loads what is finished; detect's seeds on 2 workers give the same report."""

import csv
import json

import pytest
from test_detect_file import _write_positions

from nnphd.cli import main
from nnphd.user.batch import expand_paths, unique_names

QUICK = [
    "--steps", "100", "--repeats", "1", "--sr-time", "0", "--law-fit", "pointwise", "--width", "16",
    "--lambdas", "0.2,0.5,2,5",
]  # fmt: skip


@pytest.mark.slow  # an end-to-end run of tens of seconds: slow tier (`python3 dev.py test --slow`, and CI)
def test_batch_summary_failures_workers_and_resume(tmp_path, capsys):
    d = tmp_path / "recordings"
    d.mkdir()
    _write_positions(d / "friction.csv", "ho+ld", n_traj=3, n_steps=300)
    _write_positions(d / "magnetic.csv", "ho+mf", n_traj=3, n_steps=300, seed=1)
    (d / "broken.csv").write_text("t,x\n0,1\n")
    (d / "notes.txt").write_text("not data")  # not a .csv/.npz: not part of the batch
    out = tmp_path / "out"

    rc = main(["detect", str(d), "--out", str(out), "--workers", "2", *QUICK])
    err = capsys.readouterr().err.strip()
    assert rc == 1
    assert len(err.splitlines()) == 1 and err.startswith("error: 1 of 3 files failed") and "broken.csv" in err
    with open(out / "summary.csv") as f:
        rows = list(csv.DictReader(f))
    assert [r["name"] for r in rows] == ["broken", "friction", "magnetic"]  # the folder's sorted files
    assert [r["status"] for r in rows] == ["error", "detected", "none"]
    assert "DataError" in rows[0]["error"] and rows[1]["error"] == rows[2]["error"] == ""
    assert "x_dot" not in rows[1]["law"] and "q1_dot" in rows[1]["law"]  # the law in the file's own names
    summary = json.loads((out / "summary.json").read_text())
    assert summary["counts"] == {"detected": 1, "none": 1, "inconclusive": 0, "error": 1}
    assert summary["workers"] == 2 and {r["where"] for r in summary["rows"][1:]} != {"in-process"}
    html = (out / "summary.html").read_text()
    assert 'href="friction/report.html"' in html and "broken" in html
    for n in ("friction", "magnetic"):
        assert (out / n / "report.html").stat().st_size > 1000
        # where the time went: every stage of the run, each seed's and each λ's
        tm = json.loads((out / n / "report.json").read_text())["timings"]
        names = [s["stage"] for s in tm["stages"]]
        assert names[:3] == ["reading the file", "derivatives", "training and trust checks"]
        assert "law table: pointwise fits" in names and names[-1] == "figures"
        assert sum(s["s"] for s in tm["stages"]) <= tm["total_s"] + 1e-6
        (seed,) = tm["per_seed"]
        assert 0 < seed["compile_s"] < seed["wall_s"]  # (the file ran on a worker, its seed in that process)
        assert list(seed["per_lambda_s"]) == ["0.2", "0.5", "2", "5"]
        assert seed["lambda_sweep_s"] >= sum(seed["per_lambda_s"].values()) - 1e-6
        assert "Where the time went" in (out / n / "report.html").read_text()
    assert all(float(r["training_s"]) > 0 and float(r["compile_s"]) >= 0 for r in rows[1:])
    assert not (out / "broken").exists() or not any((out / "broken").iterdir())

    # a rerun with the same settings loads the finished files and retries the broken one
    capsys.readouterr()
    rc = main(["detect", str(d), "--out", str(out), "--workers", "1", *QUICK])
    assert rc == 1
    rows = json.loads((out / "summary.json").read_text())["rows"]
    assert [r["cached"] for r in rows] == [False, True, True]
    assert [r["status"] for r in rows] == ["error", "detected", "none"]


def test_batch_bad_paths_one_line_nothing_written(tmp_path, capsys):
    empty = tmp_path / "empty"
    empty.mkdir()
    good = tmp_path / "a.csv"
    good.write_text("t,x\n" + "".join(f"{i / 10},{i}\n" for i in range(20)))
    cases = [
        ([str(good), str(tmp_path / "missing.csv")], "missing.csv: no such file or folder"),
        ([str(empty)], "the folder holds no .csv or .npz file"),
        ([str(good), str(good)], "a.csv: the file is given twice"),
    ]
    for args, msg in cases:
        out = tmp_path / "out"
        rc = main(["detect", *args, "--out", str(out)])
        err = capsys.readouterr().err.strip()
        assert rc == 2 and len(err.splitlines()) == 1 and msg in err, err
        assert not out.exists()


def test_expand_and_names(tmp_path):
    (tmp_path / "b.CSV").write_text("t\n")
    (tmp_path / "a.npz").write_bytes(b"")
    (tmp_path / "sub").mkdir()
    assert [p.name for p in expand_paths([tmp_path])] == ["a.npz", "b.CSV"]
    assert unique_names(
        [tmp_path / "x/run.csv", tmp_path / "y/run.csv", tmp_path / "RUN.npz", tmp_path / "summary.csv"]
    ) == [
        "run",
        "run-2",
        "RUN-3",
        "summary-2",
    ]
    with pytest.raises(ValueError, match="no such file"):
        expand_paths([tmp_path / "nope"])


@pytest.mark.slow  # tens of seconds: run by `python3 dev.py test --slow` (and by CI)
def test_detect_seeds_on_two_workers_same_report(tmp_path):
    """nnphd detect trains its repeated seeds as units: on 2 worker processes the report's numbers are those of
    the run in this process."""
    path = _write_positions(tmp_path / "friction.csv", "ho+ld", n_traj=3, n_steps=300)
    args = list(QUICK)
    args[args.index("--repeats") + 1] = "2"
    reps = {}
    for w in ("1", "2"):
        assert main(["detect", str(path), "--out", str(tmp_path / w), "--workers", w, *args]) == 0
        reps[w] = json.loads((tmp_path / w / "report.json").read_text())
    assert reps["1"]["settings"]["n_seeds"] == 2 and reps["1"]["settings"]["law_fit"] == "pointwise"  # as set
    for k in ("status", "confidence", "statistic", "effect", "table"):
        assert reps["1"][k] == reps["2"][k], k
    timeless = [{k: v for k, v in r["checks"].items() if k != "wall_time_s"} for r in reps.values()]
    assert timeless[0] == timeless[1]


def test_batch_hands_the_biggest_files_to_the_workers_first(tmp_path, monkeypatch):
    """A long file started last keeps one worker busy while the others idle: units carry their file's size as cost
    and Dask gets them largest first (ties in the given order); the summary keeps the files' order."""
    import nnphd.user.batch as batch
    from nnphd.parallel import Outcome, largest_first

    sizes = {"a.csv": 10, "b.csv": 300, "c.csv": 20, "d.csv": 300}
    for name, size in sizes.items():
        (tmp_path / name).write_text("t\n" + "0\n" * ((size - 2) // 2))
    seen = {}

    def fake_run_units(units, workers, scheduler, progress=None):
        seen["order"] = [u.key for u in largest_first(units)]
        return {u.key: Outcome(u.key, False, error="not run") for u in units}

    monkeypatch.setattr(batch, "run_units", fake_run_units)
    summary = batch.detect_batch([tmp_path], tmp_path / "out", workers=2)
    assert seen["order"] == ["b", "d", "c", "a"]
    assert [r["name"] for r in summary["rows"]] == ["a", "b", "c", "d"]
