"""CLI: listing, a small sweep end to end, and every bad input → one line on stderr, exit 2, nothing written."""

import json
import os
import subprocess
import sys

import numpy as np
import pytest

from nnphd.cli import main
from nnphd.engine.data import train_test
from nnphd.engine.systems import SYSTEMS
from nnphd.engine.verdict import MIN_RATIO, MIN_RELATIVE_SIZE


def test_systems_lists_every_system(capsys):
    assert main(["systems"]) == 0
    out = capsys.readouterr().out
    for name in SYSTEMS:
        assert name in out
    assert "gamma=0.02" in out and "GMn=0.005" in out


@pytest.mark.slow  # a training run of 10-20 s: slow tier (`python3 dev.py test --slow`, and CI)
def test_small_sweep_writes_results(tmp_path, capsys):
    out = tmp_path / "o"
    rc = main(["sweep", "--system", "ho+ld", "--steps", "40", "--lambdas", "0.2,5", "--seed", "3", "--out", str(out)])
    assert rc == 0
    res = json.loads((out / "results.json").read_text())
    # the statistic and the verdict, recomputed from the table: one λ on each side of 1, so the ratio is L_e(5) over
    # L_e(0.2); ‖f‖₁ is the mean |q̈| of the test set (seed 3, 1000 samples) the table's L_e is measured on
    le = {r["lam"]: r["L_e"] for r in res["table"]}
    assert res["statistic"]["value"] == pytest.approx(le[5.0] / le[0.2], rel=1e-12)
    fnorm = float(np.mean(np.abs(train_test("ho+ld", seed=3, n_train=1000, n_test=1000)[1].qdd)))
    assert res["verdict"]["force_norm"] == pytest.approx(fnorm, rel=1e-12)
    assert res["new_physics"] is (le[5.0] >= MIN_RATIO * le[0.2] and le[5.0] >= MIN_RELATIVE_SIZE * fnorm)
    assert [r["lam"] for r in res["table"]] == [0.2, 5.0]
    for r in res["table"]:
        assert r["L_e"] >= 0 and r["L_b"] >= 0 and r["m_c"] is not None
    assert res["settings"]["seed"] == 3 and res["settings"]["steps_per_lambda"] == 40
    assert (out / "loss_vs_lambda.png").stat().st_size > 1000
    assert "verdict" in capsys.readouterr().out
    # same seed → same numbers
    out2 = tmp_path / "o2"
    main(["sweep", "--system", "ho+ld", "--steps", "40", "--lambdas", "0.2,5", "--seed", "3", "--out", str(out2)])
    res2 = json.loads((out2 / "results.json").read_text())
    assert [r["L_e"] for r in res2["table"]] == [r["L_e"] for r in res["table"]]
    # --dtype float32 (a GPU user's choice) is carried to the model, and trains other numbers
    out3 = tmp_path / "o3"
    argv = ["sweep", "--system", "ho+ld", "--steps", "40", "--lambdas", "0.2,5", "--seed", "3", "--dtype", "float32"]
    assert main([*argv, "--out", str(out3)]) == 0
    res3 = json.loads((out3 / "results.json").read_text())
    assert res["settings"]["model"]["dtype"] == "float64" and res3["settings"]["model"]["dtype"] == "float32"
    assert [r["L_e"] for r in res3["table"]] != [r["L_e"] for r in res["table"]]


@pytest.mark.slow  # a fast-mode sweep end to end: slow tier (`python3 dev.py test --slow`, and CI)
def test_fast_sweep_reports_its_protocol(tmp_path, capsys):
    out = tmp_path / "f"
    lams = "0.05,0.1,0.5,2,10,20"
    assert (
        main(["sweep", "--system", "ho+ld", "--steps", "40", "--lambdas", lams, "--mode", "fast", "--out", str(out)])
        == 0
    )
    res = json.loads((out / "results.json").read_text())
    pr = res["protocol"]
    assert pr["first_lambdas"] == [0.1, 0.5, 2.0, 10.0] and res["settings"]["mode"] == "fast"
    # 40 steps per λ leave the 4-λ chain far from converged (measured: L_e 0.13-0.18 below λ = 1, a ratio ×1.9 inside
    # the close band [×1, ×6)), so the paper protocol runs on the whole grid and the table is its six λ
    assert pr["ran_paper_protocol"] and any("ratio" in w for w in pr["doubts"]), pr
    assert [r["lam"] for r in res["table"]] == [0.05, 0.1, 0.5, 2.0, 10.0, 20.0]
    # 40 steps over 4 learning rates is 10 per rate, less than one 100-step chunk, so no stopping rule shortens it:
    # 40 steps at each chain λ, and the paper protocol's 40 at every λ of the grid
    assert pr["steps_by_lambda"] == {"0.05": 40, "0.1": 80, "0.5": 80, "2": 80, "10": 80, "20": 40}
    assert pr["steps_total"] == 4 * 40 + 6 * 40
    # the verdict is the paper protocol's: median L_e over λ = 2, 10, 20 over the median over λ = 0.05, 0.1, 0.5
    le = [r["L_e"] for r in res["table"]]
    assert res["verdict"]["ratio"] == pytest.approx(np.median(le[3:]) / np.median(le[:3]), rel=1e-12)
    assert "fast mode:" in capsys.readouterr().out


BAD = [
    (["sweep", "--system", "nope"], "unknown system 'nope'"),
    (["sweep", "--system", "ho+ld", "--lambdas", "0,1,2"], "λ must be > 0"),
    (["sweep", "--system", "ho+ld", "--lambdas", "-1,2"], "λ must be > 0"),
    (["sweep", "--system", "ho+ld", "--lambdas", "0.5,x"], "--lambdas must be comma-separated numbers"),
    (["sweep", "--system", "ho+ld", "--p", "0.5"], "p must be a number ≥ 1 or 'mse'"),
    (["sweep", "--system", "ho+ld", "--p", "two"], "p must be a number ≥ 1 or 'mse'"),
    (["sweep", "--system", "ho+ld", "--steps", "1.5"], "Invalid value for '--steps': Input should be a valid integer"),
    (["sweep", "--system", "ho+ld", "--steps", "abc"], "Invalid value for '--steps': Input should be a valid integer"),
    (
        ["sweep", "--system", "ho+ld", "--steps", "0"],
        "Invalid value for '--steps': Input should be greater than or equal to 4",
    ),
    (
        ["sweep", "--system", "ho+ld", "--seed", "-1"],
        "Invalid value for '--seed': Input should be greater than or equal to 0",
    ),
    (["sweep", "--system", "ho+ld", "--mode", "quick"], "'quick' is not one of 'warm', 'vmap', 'scratch', 'fast'"),
    (["sweep", "--system", "ho+ld", "--param", "zeta=1"], "unknown parameter(s) 'zeta'"),
    (["sweep", "--system", "ho+ld", "--param", "gamma"], "--param must look like name=value"),
    (["sweep", "--system", "ho+ld", "--param", "gamma=nan"], "--param gamma must be a finite number"),
    (["sweep", "--system", "ho+ld", "--param", "gamma=inf"], "--param gamma must be a finite number"),
    (["sweep", "--system", "ho+ld", "--lambdas", "0.5,0.5,2"], "λ values must be distinct"),
    (["sweep", "--system", "ho+ld", "--seed", str(2**64)], "Invalid value for '--seed'"),
    (["sweep", "--system", "ho+ld", "--steps", str(10**12)], "Invalid value for '--steps'"),
    (["sweep", "--system", "ho+ld", "--wat"], "No such option"),
    (["sweep"], "Missing option"),
]


@pytest.mark.parametrize("argv,msg", BAD)
def test_bad_input_one_line_exit_2(argv, msg, tmp_path, capsys):
    out = tmp_path / "never"
    rc = main(argv + ["--out", str(out)] if "--wat" not in argv else argv)
    err = capsys.readouterr().err
    assert rc == 2
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: ") and msg in lines[0], err
    assert not out.exists() or not any(out.iterdir())


def test_unwritable_out(tmp_path, capsys):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    rc = main(["sweep", "--system", "ho+ld", "--out", str(blocker / "sub")])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and err.startswith("error: --out") and "not a writable directory" in err and "\n" not in err


def test_console_script_no_traceback(tmp_path):
    exe = os.path.join(os.path.dirname(sys.executable), "nnphd")
    r = subprocess.run(
        [exe, "sweep", "--system", "ho+xx", "--out", str(tmp_path / "o")], capture_output=True, text=True
    )
    assert r.returncode == 2
    assert "Traceback" not in r.stderr and r.stderr.strip().startswith("error: unknown system")


@pytest.mark.slow  # tens of seconds: run by `python3 dev.py test --slow` (and by CI)
def test_discover_small_run_writes_table2_row(tmp_path, capsys):
    out = tmp_path / "d"
    rc = main(
        [
            "discover",
            "--system",
            "double-pendulum",
            "--steps",
            "100",
            "--sweep-steps",
            "20",
            "--sr-time",
            "1",
            "--n-steps",
            "300",
            "--out",
            str(out),
        ]
    )
    assert rc == 0
    res = json.loads((out / "double-pendulum" / "results.json").read_text())
    assert [r["quantity"] for r in res["table2"]] == ["Gamma_11", "Gamma_12", "Gamma_21", "Gamma_22"]
    assert res["law_hypothesis"] == "linear-full"
    for r in res["table2"]:
        assert np.isfinite(r["ours"]) and r["stderr"] > 0 and isinstance(r["goal_met"], bool)
        # 100 training steps leave the Lagrangian's coefficients far off (the post-hoc fit of the UAN is then
        # meaningless); the joint re-fit still covers the truth within 3 standard errors
        assert abs(r["ours"] - r["truth"]) <= 3 * r["stderr"], r
    assert set(res["blind"]) == {"sparse", "genetic"}
    for b in res["blind"].values():
        assert set(b["formula"]) == {"theta1_ddot", "theta2_ddot"} and isinstance(b["readable"], bool)
    assert res["settings"]["trajectory"]["n_steps"] == 300 and res["settings"]["trajectory"]["paper_n_steps"] == 300
    assert (out / "double-pendulum" / "loss_vs_lambda.png").exists()
    assert "Table II" in capsys.readouterr().out


@pytest.mark.parametrize(
    "argv,msg",
    [
        (["discover"], "give either --system"),
        (["discover", "--system", "ho+ld"], "'ho+ld' is not one of 'double-pendulum', 'neptune', 'gw'"),
        (["discover", "--all", "--system", "gw"], "give either --system"),
        (["discover", "--system", "gw", "--lam", "1.5"], "--lam must be a number in (0, 1)"),
        (["discover", "--system", "gw", "--steps", "x"], "Invalid value for '--steps'"),
        (["discover", "--system", "gw", "--n-steps", "5"], "--n-steps must be 0 (default) or ≥ 20"),
        (["discover", "--system", "gw", "--sr-time", "-1"], "Invalid value for '--sr-time'"),
        (["discover", "--system", "gw", "--dtype", "float16"], "Invalid value for '--dtype'"),
    ],
)
def test_discover_bad_input(argv, msg, tmp_path, capsys):
    out = tmp_path / "never"
    assert main(argv + ["--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("error: ") and msg in err and "\n" not in err
    assert not out.exists()


def test_version_and_short_help(capsys):
    from nnphd import __version__

    assert main(["--version"]) == 0
    assert capsys.readouterr().out.strip() == f"nnphd {__version__}"
    assert main(["detect", "-h"]) == 0
    out = capsys.readouterr().out
    assert "--law-fit" in out and "--angles" in out
    assert main(["sweep", "-h"]) == 0
    assert "--loss-p" in capsys.readouterr().out


def test_options_are_typed(capsys):
    """Ints are ints and choices are enums in --help; the discover choices are the discovery systems."""
    from nnphd.cli.common import DiscoverySystem
    from nnphd.paper.discover import DISCOVERY_SYSTEMS

    assert tuple(s.value for s in DiscoverySystem) == tuple(DISCOVERY_SYSTEMS)
    assert main(["sweep", "-h"]) == 0
    out = capsys.readouterr().out
    assert "<int range>" in out and "warm|vmap" in out
    assert main(["detect", "-h"]) == 0
    out = capsys.readouterr().out
    assert "auto|point" in out and "auto|yes|no" in out


def test_empty_out_is_refused(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(["sweep", "--system", "ho+ld", "--out", ""]) == 2
    err = capsys.readouterr().err.strip()
    assert err == "error: --out must name a directory, got an empty string"
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("checkpoint", [False, True])
def test_interrupt_exits_130_and_says_how_to_resume(checkpoint, tmp_path, capsys, monkeypatch):
    """Ctrl-C (KeyboardInterrupt in the run): exit 130, one line; a folder the run created and left empty is
    removed; a kept checkpoint is named."""
    import nnphd.paper.sweep as sweep_mod

    out = tmp_path / "o"

    def interrupted(*a, **k):
        if checkpoint:
            (out / ".checkpoint.npz").write_bytes(b"")
        raise KeyboardInterrupt

    monkeypatch.setattr(sweep_mod, "run_sweep", interrupted)
    assert main(["sweep", "--system", "ho+ld", "--out", str(out)]) == 130
    lines = [ln for ln in capsys.readouterr().err.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: interrupted")
    if checkpoint:
        assert "run the same command again to resume" in lines[0] and out.is_dir()
    else:
        assert not out.exists()
