"""The Python API (nnphd.Trajectories, nnphd.NNPhD, nnphd.load): the README's quickstart as is, save/load exact,
no side effects of `import nnphd`, clear errors."""
from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import nnphd

ROOT = Path(__file__).resolve().parents[1]


def _quickstart() -> str:
    """The README's first python code block that calls .fit(."""
    blocks = re.findall(r"```python\n(.*?)```", (ROOT / "README.md").read_text(), flags=re.DOTALL)
    return next(b for b in blocks if ".fit(" in b)


def _fresh(code: str, cwd, env=None):
    return subprocess.run([sys.executable, "-c", code], cwd=cwd, capture_output=True, text=True, timeout=600, check=False,
                          env={**os.environ, **(env or {})})


def test_import_changes_nothing_in_the_session(tmp_path):
    """`import nnphd` (and touching its API) leaves JAX's float64 switch, XLA_FLAGS and the matplotlib backend as
    they were; computing with it in float64 does not turn float64 on for the caller either."""
    code = """
import json, os, matplotlib, jax
def state():
    return [bool(jax.config.jax_enable_x64), os.environ.get("XLA_FLAGS"), dict.__getitem__(matplotlib.rcParams, "backend")]
before = state()
import nnphd
nnphd.NNPhD, nnphd.Trajectories, nnphd.load
import nnphd.api, nnphd.userdetect, nnphd.trust, nnphd.explain.laws, nnphd.report
after = state()
fig, ax = nnphd.report.subplots()
print(json.dumps([before, after, state(), jax.numpy.ones(1).dtype.name]))
"""
    r = _fresh(code, tmp_path, env={"XLA_FLAGS": "--xla_dump_to=/nonexistent", "MPLBACKEND": "svg"})
    assert r.returncode == 0, r.stderr
    before, after, later, dtype = json.loads(r.stdout.strip().splitlines()[-1])
    assert before == after == later
    assert before[0] is False and before[1] == "--xla_dump_to=/nonexistent" and before[2] == "svg"
    assert dtype == "float32"


def test_configure_sets_float64_and_the_flag(tmp_path):
    r = _fresh("import os, jax, nnphd; nnphd.configure(); print(jax.config.jax_enable_x64, os.environ['XLA_FLAGS'])",
               tmp_path, env={"XLA_FLAGS": ""})
    assert r.returncode == 0, r.stderr
    assert r.stdout.split() == ["True", nnphd.XLA_FLAG]


def test_readme_quickstart_runs_as_is_in_an_empty_folder(tmp_path):
    """The very block from the README, in a fresh interpreter in an empty folder: it makes its own data (several
    trajectories of different lengths), finds the damping and writes no file."""
    code = _quickstart() + "\nimport json\nprint('RESULT', json.dumps({'status': model.status_, " \
                           "'law': model.law_.params if model.law_ else None, 'fn': fn.tolist()}))\n"
    r = _fresh(code, tmp_path)
    assert r.returncode == 0, r.stderr[-3000:]
    res = json.loads(r.stdout.split("RESULT", 1)[1])
    assert res["status"] == "detected"
    assert res["law"] is not None and len(res["law"]) == 1
    assert next(iter(res["law"].values())) == pytest.approx(0.1, rel=0.1)  # truth: x'' = -x - 0.1 x'
    assert list(tmp_path.iterdir()) == []  # nothing written


@pytest.fixture(scope="module")
def fitted():
    rng = np.random.default_rng(1)
    ts, qs = [], []
    for x0, T in [(1.0, 30.0), (-0.7, 25.0), (0.6, 35.0)]:
        t = np.arange(0.0, T, 0.1)
        w = np.sqrt(1 - 0.05**2)
        x = x0 * np.exp(-0.05 * t) * (np.cos(w * t) + 0.05 / w * np.sin(w * t))
        qs.append(x + 1e-3 * rng.standard_normal(t.size))
        ts.append(t)
    data = nnphd.Trajectories(ts, qs, names=["x"])
    return data, nnphd.NNPhD(seed=0, steps=200, n_seeds=1, law_fit="pointwise").fit(data)


def test_fit_forces_simulate_save_load(fitted, tmp_path):
    data, model = fitted
    assert repr(data) == "Trajectories(3 trajectories, 900 samples, coordinates x)"
    assert model.status_ == "detected" and model.verdict_.to_dict()["status"] == "detected"
    assert model.law_ is not None and model.law_.to_dict()["key"] == model.law_.key
    rng = np.random.default_rng(2)
    q, qd, t = rng.uniform(-0.7, 0.7, (50, 1)), rng.uniform(-0.7, 0.7, (50, 1)), rng.uniform(0, 30, 50)  # in range
    fc, fn = model.forces(q, qd, t)
    # the law is linear friction: f_n = −γ q̇ with γ the reported one
    gamma = next(iter(model.law_.params.values()))
    np.testing.assert_allclose(fn, -gamma * qd, rtol=1e-12)
    # f_c is the learned spring −x within the data's range (the LNN alone, after 200 steps)
    assert np.sqrt(np.mean((fc + q) ** 2)) < 0.15 * np.sqrt(np.mean(q**2))
    p = model.save(tmp_path / "m.npz")
    mask = os.umask(0)
    os.umask(mask)
    assert p.stat().st_mode & 0o777 == 0o666 & ~mask  # as a plain open() would make it (mkstemp's are 0600)
    loaded = nnphd.load(p)
    fc2, fn2 = loaded.forces(q, qd, t)
    np.testing.assert_allclose(fc2, fc, rtol=0, atol=1e-12)
    np.testing.assert_allclose(fn2, fn, rtol=0, atol=1e-12)
    assert loaded.status_ == model.status_ and loaded.law_ == model.law_
    # simulate: the rolled-out model decays like the data (energy falls by ~e^{-0.1 t})
    tt = np.arange(0.0, 20.0, 0.1)
    qs, qds = loaded.simulate([1.0], [0.0], tt)
    E = 0.5 * qds[:, 0] ** 2 + 0.5 * qs[:, 0] ** 2
    assert qs.shape == (200, 1) and np.exp(-2.0 * 1.5) < E[-1] / E[0] < np.exp(-2.0 * 0.5)
    figs = model.figures()
    assert {"data", "loss_vs_lambda", "forces"} <= set(figs) and all(hasattr(f, "savefig") for f in figs.values())


@pytest.mark.parametrize("args, kw, msg", [
    ((np.arange(10.0), np.zeros((9, 1))), {}, "q must be (N,) or (N, n) with N = 10"),
    ((np.arange(10.0), np.zeros((10, 2))), {"names": ["x"]}, "names must be 2 distinct names"),
    ((np.arange(10.0), np.zeros(10)), {"angles": ["y"]}, "angle 'y' is not a coordinate"),
    ((np.r_[0.0, 2.0, 1.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0], np.arange(10.0)), {}, "t is not strictly increasing"),
    (([np.arange(10.0)], [np.zeros(10), np.zeros(10)]), {}, "q must be a list of 1 arrays"),
])
def test_bad_arrays_give_one_line_errors(args, kw, msg):
    with pytest.raises(ValueError) as e:
        nnphd.Trajectories(*args, **kw)
    assert msg in str(e.value) and "\n" not in str(e.value)


def test_unfitted_and_bad_files(tmp_path):
    with pytest.raises(RuntimeError, match="not fitted"):
        nnphd.NNPhD().forces([0.0], [0.0])
    bad = tmp_path / "x.npz"
    np.savez(bad, a=np.zeros(3))
    with pytest.raises(ValueError, match="not an nnphd model file"):
        nnphd.load(bad)
