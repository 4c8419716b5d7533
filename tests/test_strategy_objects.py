"""The strategy objects hold objects, as pysindy's do: a derivative estimator of your own
(``nnphd.Derivatives(MyEstimator())``) and a law family of your own (``nnphd.LawLibrary(families=(..., my_family))``)
are what ``NNPhD.fit`` uses; the built-in estimators are classes that the method names stand for (the same numbers);
the fitted model's law is a :class:`nnphd.Law` that predicts, and a loaded model's law predicts the same."""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp

import nnphd
from nnphd.engine.data import Dataset
from nnphd.explain.laws import CandidateSet, rank_laws
from nnphd.user.derivatives import estimate_derivatives
from nnphd.user.recording import from_arrays
from nnphd.user.strategies import FAMILIES

C = 0.2  # the friction c|ẋ|^1.5 sign(ẋ) of the constructed records
GAMMA = 0.1  # the viscous friction γẋ of the others


def _rk4(accel, x0: float, dt: float = 0.1, T: float = 30.0, sub: int = 20):
    """t, x, ẋ of ẍ = accel(x, ẋ) from (x0, 0), RK4 with ``sub`` steps per sample."""
    n, h = int(round(T / dt)) + 1, dt / sub
    xs, vs = np.empty(n), np.empty(n)
    x, v = x0, 0.0
    for i in range(n):
        xs[i], vs[i] = x, v
        for _ in range(sub):
            k1x, k1v = v, accel(x, v)
            k2x, k2v = v + h / 2 * k1v, accel(x + h / 2 * k1x, v + h / 2 * k1v)
            k3x, k3v = v + h / 2 * k2v, accel(x + h / 2 * k2x, v + h / 2 * k2v)
            k4x, k4v = v + h * k3v, accel(x + h * k3x, v + h * k3v)
            x, v = x + h / 6 * (k1x + 2 * k2x + 2 * k3x + k4x), v + h / 6 * (k1v + 2 * k2v + 2 * k3v + k4v)
    return np.arange(n) * dt, xs, vs


def power15(x, v):
    return -x - C * np.abs(v) ** 1.5 * np.sign(v)


def viscous(x, v):
    return -x - GAMMA * v


class Oracle(nnphd.DerivativeEstimator):
    """An estimator that knows the truth: the recorded q̇ of each trajectory (found by its first position) and q̈ of
    ``accel`` there, with row errors of 1e-3 — and notes the q̈ it returned."""

    name = "oracle"

    def __init__(self, records, accel):
        self.qd = {float(x[0]): v for _, x, v in records}
        self.accel = accel
        self.returned: list[np.ndarray] = []

    def estimate(self, t, q, trim=False):
        x = np.ravel(q)
        qd = self.qd[float(x[0])]
        est = nnphd.DerivativeEstimate.from_values(
            t, q, qd, self.accel(x, qd), method=self.name, errors=np.full((2, len(t)), 1e-3)
        )
        self.returned.append(est.qdd[:, 0])
        return est


class Gradient(nnphd.DerivativeEstimator):
    """The docstring's example: numpy's central differences."""

    name = "gradient"

    def estimate(self, t, q, trim=False):
        qd = np.gradient(q, t, axis=0)
        return nnphd.DerivativeEstimate.from_values(t, q, qd, np.gradient(qd, t, axis=0), method=self.name)


def power15_family() -> nnphd.Family:
    """A family of your own: −c |ẋ|^1.5 sign(ẋ) (its spec, a formula, lets a model that claims it be saved)."""
    return nnphd.Family(
        "power1.5",
        "c |q̇|^1.5 sign(q̇)",
        ("c",),
        lambda xp, th, q, v, t: (-(xp.abs(v) ** 1.5) * xp.sign(v))[:, :, None],
        lambda th, Q, V, T: [[-(sp.Abs(V[0]) ** sp.Rational(3, 2)) * sp.sign(V[0])]],
        terms=("|q̇|^1.5",),
        spec={"kind": "user", "text": "-c*abs(x_dot)**1.5*sign(x_dot)"},
    )


def _records(accel, x0s=(1.0, -0.8)):
    return [_rk4(accel, x0) for x0 in x0s]


def _data(records) -> nnphd.Trajectories:
    return nnphd.Trajectories([r[0] for r in records], [r[1] for r in records], names=["x"])


def _candidate(model, key) -> dict:
    return next(r for r in model.report_["law"]["candidates"] if r["law"] == key)


STATES = (np.linspace(-1, 1, 7)[:, None], np.linspace(-0.9, 0.8, 7)[:, None], np.linspace(0, 5, 7))


# ---- the estimators -------------------------------------------------------------------------------------------------
def test_the_method_names_are_the_estimator_classes_bit_for_bit():
    t = np.arange(401) * 0.05
    q = np.c_[np.sin(t) + 0.3 * np.cos(2.1 * t), np.full(t.size, 2.0)]
    jitter = np.cumsum(np.full(300, 0.1) * (1 + 0.02 * np.random.default_rng(0).standard_normal(300)))
    cases = [(t, q, c) for c in (nnphd.SavitzkyGolay, nnphd.LocalPolynomial, nnphd.SmoothingSpline)]
    cases.append((jitter, np.sin(jitter), nnphd.AutoDerivatives))
    for tt, qq, cls in cases:
        for trim in (False, True):
            a, b = estimate_derivatives(tt, qq, cls.name, trim=trim), cls().estimate(tt, qq, trim=trim)
            for name in a.__dataclass_fields__:
                x, y = getattr(a, name), getattr(b, name)
                assert np.array_equal(x, y) if isinstance(x, np.ndarray) else x == y, (cls.name, name)
    assert estimate_derivatives(jitter, np.sin(jitter)).method == "local"  # auto chose local polynomials
    assert nnphd.Derivatives("spline").estimator == nnphd.SmoothingSpline()
    assert nnphd.Derivatives(nnphd.SmoothingSpline()).name == "spline"


def test_an_estimator_of_your_own_makes_the_data_set():
    t = np.arange(200) * 0.05
    ud = from_arrays([t, t[:150]], [np.sin(t), np.cos(t[:150])], names=["x"])
    d = nnphd.Derivatives(Gradient(), trim=False).dataset(ud)
    want = np.concatenate([np.gradient(np.gradient(x, t[: len(x)]), t[: len(x)]) for x in (np.sin(t), np.cos(t[:150]))])
    np.testing.assert_array_equal(d.data.qdd[:, 0], want)
    assert d.info["method"] == "gradient" and d.info["per_coordinate"]["x"]["qdd"]["error"] == 0.0
    assert nnphd.Derivatives(Gradient()).name == "gradient"

    class Wrong(nnphd.DerivativeEstimator):
        def estimate(self, t, q, trim=False):
            return np.gradient(q, t, axis=0)

    with pytest.raises(TypeError, match="'custom' returned a ndarray, not a DerivativeEstimate"):
        nnphd.Derivatives(Wrong()).dataset(ud)
    with pytest.raises(ValueError, match="or a DerivativeEstimator, got <object"):
        nnphd.Derivatives(object())


@pytest.mark.slow  # a whole fit compiled in its worker (~30 s): the slow tier (CI runs it)
def test_fit_uses_your_estimator(tmp_path):
    """The pipeline ranks the laws on the oracle's q̈: it says the friction is γ = 0.3 where the positions have
    0.1 — no estimator of the positions could make that number — and the report names the estimator."""
    recs = _records(viscous)
    oracle = Oracle(recs, lambda x, v: viscous(x, v) - 0.2 * v)
    lib = nnphd.LawLibrary(families=("linear", "quadratic"), fit="pointwise")
    m = nnphd.NNPhD(steps=20, n_seeds=1, derivatives=nnphd.Derivatives(oracle), library=lib).fit(_data(recs))
    assert m.report_["settings"]["derivative_method"] == "oracle"
    assert [tr["method"] for tr in m.report_["data"]["trajectories"]] == ["oracle", "oracle"]
    assert len(oracle.returned) == 2 and all(len(q) == 301 for q in oracle.returned)
    assert _candidate(m, "linear")["params"]["gamma"] == pytest.approx(0.3, rel=1e-4)


# ---- the law families -----------------------------------------------------------------------------------------------
def test_the_library_takes_family_objects():
    fam = power15_family()
    lib = nnphd.LawLibrary(families=(*FAMILIES, fam))
    assert lib.families[-1] is fam and nnphd.LawLibrary(families=fam).families == (fam,)
    for bad, words in (
        ((fam, power15_family()), "'power1.5' is a built-in one's or given twice"),
        ((nnphd.Family("linear", "mine", ("g",), None, None),), "'linear' is a built-in one's"),
        (("linear", "viscous"), "unknown law family 'viscous'"),
    ):
        with pytest.raises(ValueError, match=words) as e:
            nnphd.LawLibrary(families=bad)
        assert "\n" not in str(e.value)


def test_rank_laws_ranks_a_family_object():
    t, x, v = _rk4(power15, 1.0)
    data = Dataset(q=np.c_[x], qd=np.c_[v], t=t, qdd=np.c_[power15(x, v)])
    table = rank_laws(data, names=["x"], candidates=CandidateSet(include=("linear", power15_family())))
    assert {r.key for r in table.rows} == {"linear", "power1.5", "none"}
    assert table.law.key == "power1.5" and table.law.params["c"] == pytest.approx(C, rel=1e-4)


def test_fit_ranks_your_family_and_the_loaded_law_predicts_the_same(tmp_path):
    recs = _records(power15)
    lib = nnphd.LawLibrary(families=(*FAMILIES, power15_family()), fit="pointwise")
    oracle = Oracle(recs, power15)  # exact derivatives
    m = nnphd.NNPhD(steps=20, n_seeds=1, derivatives=nnphd.Derivatives(oracle), library=lib).fit(_data(recs))
    row = _candidate(m, "power1.5")
    assert row["params"]["c"] == pytest.approx(C, rel=1e-4)
    assert m.report_["settings"]["families"][-1] == "power1.5"
    # the model holds one Law, which predicts: the law's force at any states
    assert m.law_ is m.result_.law and m.law_.key in ("power1.5", "power")
    q, qd, t = STATES
    fn = m.law_.predict(q, qd, t)
    np.testing.assert_allclose(fn, -C * np.abs(qd) ** 1.5 * np.sign(qd), rtol=1e-3)
    np.testing.assert_array_equal(m.forces(q, qd, t)[1], fn)
    loaded = nnphd.load(m.save(tmp_path / "m.npz"))
    assert loaded.law_ == m.law_
    np.testing.assert_allclose(loaded.law_.predict(q, qd, t), fn, rtol=0, atol=1e-12)
    np.testing.assert_allclose(loaded.forces(q, qd, t)[1], fn, rtol=0, atol=1e-12)


def test_a_law_read_from_a_report_does_not_predict():
    law = nnphd.Law("linear", "t", {"x_ddot": "-0.1*x_dot"}, {}, {"gamma": 0.1}, {}, "pointwise")
    with pytest.raises(ValueError, match="holds no fitted family"):
        law.predict(*STATES)
