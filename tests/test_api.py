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
    return subprocess.run(
        [sys.executable, "-c", code],
        cwd=cwd,
        capture_output=True,
        text=True,
        timeout=600,
        check=False,
        env={**os.environ, **(env or {})},
    )


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
import nnphd.api, nnphd.user.detect, nnphd.user.assess, nnphd.explain.laws, nnphd.io.results
after = state()
fig, ax = nnphd.io.results.subplots()
print(json.dumps([before, after, state(), jax.numpy.ones(1).dtype.name]))
"""
    r = _fresh(code, tmp_path, env={"XLA_FLAGS": "--xla_dump_to=/nonexistent", "MPLBACKEND": "svg"})
    assert r.returncode == 0, r.stderr
    before, after, later, dtype = json.loads(r.stdout.strip().splitlines()[-1])
    assert before == after == later
    assert before[0] is False and before[1] == "--xla_dump_to=/nonexistent" and before[2] == "svg"
    assert dtype == "float32"


def test_configure_sets_float64_and_the_flag(tmp_path):
    r = _fresh(
        "import os, jax, nnphd; nnphd.configure(); print(jax.config.jax_enable_x64, os.environ['XLA_FLAGS'])",
        tmp_path,
        env={"XLA_FLAGS": ""},
    )
    assert r.returncode == 0, r.stderr
    assert r.stdout.split() == ["True", *nnphd.ONE_THREAD_FLAGS.split(), nnphd.XLA_FLAG]


def test_compile_cache_folder_choice(monkeypatch, tmp_path):
    monkeypatch.delenv(nnphd.COMPILE_CACHE_ENV, raising=False)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert nnphd.compile_cache_dir() is None and nnphd.compile_cache_dir(False) is None
    assert nnphd.compile_cache_dir(True) == tmp_path / "xdg" / "nnphd" / "jax"
    assert nnphd.compile_cache_dir(tmp_path / "c") == tmp_path / "c"
    monkeypatch.setenv(nnphd.COMPILE_CACHE_ENV, str(tmp_path / "env"))
    assert nnphd.compile_cache_dir() == nnphd.compile_cache_dir(True) == tmp_path / "env"
    assert nnphd.compile_cache_dir(tmp_path / "c") == tmp_path / "c" and nnphd.compile_cache_dir(False) is None
    for off in ("0", "off", ""):
        monkeypatch.setenv(nnphd.COMPILE_CACHE_ENV, off)
        assert nnphd.compile_cache_dir(True) is None


def test_compile_cache_is_loaded_by_the_next_process_same_numbers(tmp_path):
    """A program compiled in one process is written to the cache folder and loaded (not compiled) by the next; the
    numbers are bit for bit the same, and a cache that cannot be created leaves nnphd compiling as before."""
    code = """
import json, jax, jax.numpy as jnp, jax.monitoring, nnphd
nnphd.configure()
hits = []
jax.monitoring.register_event_listener(lambda e, **kw: hits.append(e) if e.endswith("cache_hits") else None)
x = jnp.linspace(0.1, 1.0, 600).reshape(20, 30)
n = len(hits)
y = jax.jit(lambda x: jnp.tanh(jnp.sin(x) @ x.T).sum(axis=0).cumsum() ** 1.5)(x)
print(json.dumps([y.tolist(), jax.config.jax_compilation_cache_dir, len(hits) - n]))
"""
    cache = tmp_path / "cache"
    runs = [_fresh(code, tmp_path, env={nnphd.COMPILE_CACHE_ENV: str(cache)}) for _ in range(2)]
    assert all(r.returncode == 0 for r in runs), runs[0].stderr
    (y1, d1, h1), (y2, d2, h2) = (json.loads(r.stdout.strip().splitlines()[-1]) for r in runs)
    assert d1 == d2 == str(cache) and y1 == y2
    assert (h1, h2) == (0, 1)  # compiled by the first process, loaded from the cache by the second
    entries = [p for p in cache.iterdir() if not p.name.startswith(".")]
    assert len(entries) >= 1  # the program (and JAX's own small ones) were written
    blocked = tmp_path / "file"
    blocked.write_text("x")  # a folder cannot be made under a file: no cache, same result
    r = _fresh(code, tmp_path, env={nnphd.COMPILE_CACHE_ENV: str(blocked / "sub")})
    assert r.returncode == 0, r.stderr
    y3, d3, h3 = json.loads(r.stdout.strip().splitlines()[-1])
    assert y3 == y1 and d3 is None and h3 == 0


CHECKS = """
# --- appended by the test (not in the README): the fitted model, in this same session (float64 off) ---
import json, os, tempfile
rng = np.random.default_rng(2)
qs_, qds_, ts_ = rng.uniform(-0.7, 0.7, (50, 1)), rng.uniform(-0.7, 0.7, (50, 1)), rng.uniform(0, 30, 50)
fc1, fn1 = model.forces(qs_, qds_, ts_)
d = tempfile.mkdtemp()  # not the working folder
p = model.save(os.path.join(d, "m.npz"))
loaded = nnphd.load(p)
fc2, fn2 = loaded.forces(qs_, qds_, ts_)
qq, vv = loaded.simulate([1.0], [0.0], np.arange(0.0, 20.0, 0.1))
figs = model.figures()
mask = os.umask(0)
os.umask(mask)
import jax
print("RESULT", json.dumps({
    "status": model.status_, "verdict": model.verdict_.to_dict()["status"], "law": model.law_.params,
    "law_dict_key": model.law_.to_dict()["key"] == model.law_.key, "repr": repr(data), "fn": fn.tolist(),
    "q": qs_.tolist(), "qd": qds_.tolist(), "fc1": fc1.tolist(), "fn1": fn1.tolist(),
    "d_fc": float(np.max(np.abs(fc2 - fc1))), "d_fn": float(np.max(np.abs(fn2 - fn1))),
    "same": loaded.status_ == model.status_ and loaded.law_ == model.law_,
    "mode_ok": (os.stat(p).st_mode & 0o777) == (0o666 & ~mask), "E": (0.5 * vv[:, 0]**2 + 0.5 * qq[:, 0]**2).tolist(),
    "figs": sorted(figs), "figs_ok": all(hasattr(f, "savefig") for f in figs.values()),
    "x64_after": bool(jax.config.jax_enable_x64)}))
"""


@pytest.mark.slow  # an end-to-end run of tens of seconds: slow tier (`python3 dev.py test --slow`, and CI)
def test_readme_quickstart_runs_as_is_in_an_empty_folder(tmp_path):
    """The very block from the README, in a fresh interpreter in an empty folder: it makes its own data (several
    trajectories of different lengths), finds the damping and writes no file there. Then, in the same session: the
    fitted model's forces, save/load (equal to 1e-12), a roll-out, the figures — all with the caller's float64
    switch left off."""
    r = _fresh(_quickstart() + CHECKS, tmp_path)
    assert r.returncode == 0, r.stderr[-3000:]
    assert list(tmp_path.iterdir()) == []  # nothing written in the working folder
    res = json.loads(r.stdout.split("RESULT", 1)[1])
    assert res["status"] == res["verdict"] == "detected"
    assert res["repr"] == "Trajectories(3 trajectories, 1050 samples, coordinates x)"
    assert len(res["law"]) == 1 and res["law_dict_key"]
    gamma = next(iter(res["law"].values()))
    assert gamma == pytest.approx(0.1, rel=0.1)  # truth: x'' = -x - 0.1 x'
    q, qd = np.asarray(res["q"]), np.asarray(res["qd"])
    np.testing.assert_allclose(res["fn1"], -gamma * qd, rtol=1e-12)  # f_n is the law, −γ q̇
    # f_c is the learned spring −x within the data's range
    assert np.sqrt(np.mean((np.asarray(res["fc1"]) + q) ** 2)) < 0.15 * np.sqrt(np.mean(q**2))
    assert res["d_fc"] <= 1e-12 and res["d_fn"] <= 1e-12 and res["same"]
    assert res["mode_ok"]  # as a plain open() would make it (mkstemp's are 0600)
    E = np.asarray(res["E"])  # the rolled-out model loses energy like the data, ~e^{-0.1 t}
    assert len(E) == 200 and np.exp(-2.0 * 1.5) < E[-1] / E[0] < np.exp(-2.0 * 0.5)
    assert {"data", "loss_vs_lambda", "forces"} <= set(res["figs"]) and res["figs_ok"]
    assert res["x64_after"] is False


@pytest.mark.parametrize(
    "args, kw, msg",
    [
        ((np.arange(10.0), np.zeros((9, 1))), {}, "q must be (N,) or (N, n) with N = 10"),
        ((np.arange(10.0), np.zeros((10, 2))), {"names": ["x"]}, "names must be 2 distinct names"),
        ((np.arange(10.0), np.zeros(10)), {"angles": ["y"]}, "angle 'y' is not a coordinate"),
        (
            (np.r_[0.0, 2.0, 1.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0], np.arange(10.0)),
            {},
            "t is not strictly increasing",
        ),
        (([np.arange(10.0)], [np.zeros(10), np.zeros(10)]), {}, "q must be a list of 1 arrays"),
    ],
)
def test_bad_arrays_give_one_line_errors(args, kw, msg):
    with pytest.raises(ValueError) as e:
        nnphd.Trajectories(*args, **kw)
    assert msg in str(e.value) and "\n" not in str(e.value)


def test_unfitted_and_bad_files(tmp_path):
    with pytest.raises(RuntimeError, match="not fitted"):
        nnphd.NNPhD().forces([0.0], [0.0])
    bad = tmp_path / "x.npz"
    np.savez(bad, a=np.zeros(3))
    with pytest.raises(ValueError, match="not a valid nnphd model file"):
        nnphd.load(bad)


def test_the_four_ways_in_give_the_same_data(tmp_path):
    """Arrays with ids, per-trajectory lists, a CSV file and a table of columns: the same trajectories."""
    t1, t2 = np.arange(0.0, 5.0, 0.1), np.arange(0.0, 3.0, 0.1)
    q1, q2 = np.column_stack([np.cos(t1), np.sin(t1)]), np.column_stack([np.cos(t2), 2 * np.sin(t2)])
    lists = nnphd.Trajectories([t1, t2], [q1, q2], names=["x", "th"], angles=["th"])
    ids = nnphd.Trajectories(
        np.r_[t1, t2], np.r_[q1, q2], traj=np.r_[np.zeros(50), np.ones(30)], names=["x", "th"], angles=["th"]
    )
    cols = {
        "t": np.r_[t1, t2],
        "traj": np.r_[np.zeros(50), np.ones(30)],
        "x": np.r_[q1[:, 0], q2[:, 0]],
        "th": np.r_[q1[:, 1], q2[:, 1]],
    }
    table = nnphd.Trajectories.from_dataframe(cols, angles=["th"])
    path = tmp_path / "d.csv"
    path.write_text(
        "t,traj,x,th\n"
        + "".join(f"{float(a)!r},{int(b)},{float(c)!r},{float(d)!r}\n" for a, b, c, d in zip(*cols.values()))
    )
    csv = nnphd.Trajectories.from_csv(path, angles=["th"])
    for d in (lists, ids, table, csv):
        assert d.names == ("x", "th") and d.angles == ("th",) and d.n_trajectories == 2 and d.n_samples == 80
        assert len(d.arrays()) == 2
        for (ta, qa), (tb, qb) in zip(d.arrays(), lists.arrays()):
            np.testing.assert_array_equal(ta, tb)
            np.testing.assert_array_equal(qa, qb)
    with pytest.raises(ValueError, match="expected a .csv file"):
        nnphd.Trajectories.from_csv(tmp_path / "d.npz")


def test_every_public_name_resolves_and_the_errors_are_exported(tmp_path):
    """Each name of nnphd.__all__ is there; a file nnphd cannot use raises nnphd.DataError (a ValueError), which a
    notebook can catch without importing a private module; nnphd.MissingExtra is an ImportError."""
    for name in nnphd.__all__:
        assert getattr(nnphd, name) is not None, name
    assert issubclass(nnphd.DataError, ValueError) and issubclass(nnphd.MissingExtra, ImportError)
    bad = tmp_path / "bad.csv"
    bad.write_text("t,x\n0,1\n")
    with pytest.raises(nnphd.DataError, match="bad.csv"):
        nnphd.Trajectories.from_csv(bad)
