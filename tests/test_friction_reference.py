"""benchmarks/friction_reference.py — the independent whole-trajectory reference of the friction laws — on a
two-coordinate flight (its projectile model): a throw with known drag is fitted back to its coefficients,
and the family is told apart where the record can tell it. The truth is integrated here with scipy's DOP853 at a
tight tolerance, not by the script's own integrator."""

from __future__ import annotations

import importlib.util
import os

import numpy as np
import pytest
from scipy.integrate import solve_ivp

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def _script():
    spec = importlib.util.spec_from_file_location(
        "friction_reference", os.path.join(ROOT, "benchmarks", "friction_reference.py")
    )
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def _throw_csv(path, *, c=0.0, e=0.0, g=9.81, duration=2.0, fs=60.0, noise=1e-3, seed=0):
    """A throw (x, y in metres) under q̈ = (0, −g) − c q̇ − e |q̇| q̇ with white position noise, written as t,x,y."""

    def rhs(_, s):
        v = s[2:]
        return [*v, *((0.0, -g) - c * v - e * np.linalg.norm(v) * v)]

    t = np.arange(0.0, duration + 1e-9, 1.0 / fs)
    s0 = [0.0, 2.0, 12 * np.cos(1.0), 12 * np.sin(1.0)]
    sol = solve_ivp(rhs, (0.0, t[-1]), s0, t_eval=t, method="DOP853", rtol=1e-12, atol=1e-12)
    xy = sol.y[:2].T + noise * np.random.default_rng(seed).standard_normal((len(t), 2))
    np.savetxt(path, np.column_stack([t, xy]), delimiter=",", header="t,x,y", comments="")
    return path


@pytest.mark.parametrize(("truth", "best"), [({"e": 0.03}, ("e",)), ({"c": 0.4}, ("c",))])
def test_a_throw_gives_back_its_drag_law(tmp_path, truth, best):
    fr = _script()
    rec = fr.load_record(_throw_csv(tmp_path / "throw.csv", **truth))
    assert rec.model == "projectile"
    fits = fr.fit_record(rec)
    _, chosen = fr.decide(fits)
    assert chosen == best
    p = fits[best]["params"]
    for k, v in truth.items():
        assert p[k] == pytest.approx(v, rel=0.02)
    assert p["gravity"] == pytest.approx(9.81, rel=2e-3)
    assert fits[best]["rms"] == pytest.approx(1e-3, rel=0.2)  # metres: the truth's own family leaves the noise
    # the wrong family leaves a visible residual on a 2-s throw at 12 m/s (drag a sizeable share of g)
    other = ("c",) if best == ("e",) else ("e",)
    assert fits[other]["rms"] > 3 * fits[best]["rms"]
