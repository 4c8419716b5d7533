"""nnphd detect on positions only: HO+LD (friction) and HO+MF (magnetic, conservative), several trajectories with
0.1% noise — the verdicts must be right, the report complete, the formula in the file's own names."""

import json

import numpy as np
import pytest
import sympy

from nnphd.cli import main
from nnphd.engine.data import rk4_trajectory
from nnphd.engine.systems import get_system


def _write_positions(path, system, n_traj=6, dt=0.05, n_steps=600, noise=1e-3, seed=0):
    sysm = get_system(system)
    rng = np.random.default_rng(seed)
    coords = [f"q{i + 1}" for i in range(sysm.n)]
    lines = ["traj,t," + ",".join(coords)]
    for k in range(n_traj):
        x0 = rng.uniform(-1.5, 1.5, 2 * sysm.n)
        t, q, _ = rk4_trajectory(sysm.f, x0, dt, n_steps)
        q = np.asarray(q)
        q = q + noise * q.std(axis=0) * rng.standard_normal(q.shape)
        lines += [f"{k},{ti:.6f}," + ",".join(f"{v:.10g}" for v in row) for ti, row in zip(np.asarray(t), q)]
    path.write_text("\n".join(lines) + "\n")
    return path


@pytest.mark.slow  # tens of seconds: run by `python3 dev.py test --slow` (and by CI)
@pytest.mark.parametrize("system,expected", [("ho+ld", "detected"), ("ho+mf", "none")])
def test_positions_only_verdicts(system, expected, tmp_path, capsys):
    path = _write_positions(tmp_path / f"{system}.csv", system)
    out = tmp_path / "out"
    rc = main(
        [
            "detect",
            str(path),
            "--out",
            str(out),
            "--steps",
            "300",
            "--repeats",
            "1",
            "--sr-time",
            "0",
            "--law-fit",
            "pointwise",
        ]
    )
    assert rc == 0
    rep = json.loads((out / "report.json").read_text())
    assert rep["status"] == expected
    assert rep["new_physics"] is (expected == "detected")
    assert 0.0 <= rep["confidence"] <= 1.0 and rep["confidence"] >= 0.5
    # noise estimate: 0.1% of each coordinate's std, within a factor 2
    for c, v in rep["noise"].items():
        assert 5e-4 <= v["noise_relative"] <= 2e-3, (c, v["noise_relative"])
    assert rep["data"]["n_traj"] == 6
    assert [r["lam"] for r in rep["table"]] == sorted(r["lam"] for r in rep["table"])
    for name in ("report.html", "data.png", "loss_vs_lambda.png", "forces.png"):
        assert (out / name).stat().st_size > 1000
    html = (out / "report.html").read_text()
    # data, energy trend, L_e(λ), forces; the report leads with the verdict
    # (and the amplitude envelope where the law table measured one: one oscillating coordinate)
    env = (rep["law"].get("envelope") or {}).get("measured", {}).get("A")
    assert bool(env) == (out / "envelope.png").exists()
    assert expected.upper() in html and html.count("data:image/png;base64,") == 4 + bool(env)
    assert html.index(expected.upper()) < html.index("Evidence") < html.index("Figures")
    if expected == "detected":
        # the blind formula speaks the file's names; HO+LD's f_n = −½ q̇ → a q1_dot term near −0.5
        f = rep["formula"]
        assert f is not None and set(f["formula"]) == {"q1_ddot"}
        assert "q1_dot" in f["formula"]["q1_ddot"]
        coef = float(sympy.sympify(f["formula"]["q1_ddot"]).coeff(sympy.Symbol("q1_dot")))
        assert -0.6 < coef < -0.4, f["formula"]
    else:
        assert rep["formula"] is None and rep["blind"] == {}
    assert expected.upper() in capsys.readouterr().out
