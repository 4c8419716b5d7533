"""NNPhD's strategy objects (as pysindy's ``SINDy(differentiation_method=…, feature_library=…)``):
nnphd.Derivatives (how q̇ and q̈ are estimated) and nnphd.LawLibrary (which candidate laws are ranked, and how), their
checks, their defaults = what ran before, the older keywords mapped onto them, and the law families threaded from
``NNPhD(...)`` to the ranking. No training: the fit's later stages are stood in for."""

from __future__ import annotations

import numpy as np
import pytest

import nnphd
from nnphd.user.derivatives import Derivatives, estimate_derivatives, to_dataset
from nnphd.user.recording import from_arrays
from nnphd.user.result import ConservativeModel
from nnphd.user.strategies import FAMILIES, LawLibrary, family_filter

T = np.arange(401) * 0.05  # 0…20 s
Q = np.sin(T) + 0.3 * np.cos(2.1 * T)
QD = np.cos(T) - 0.63 * np.sin(2.1 * T)
QDD = -np.sin(T) - 1.323 * np.cos(2.1 * T)


def _rel(est, truth, keep) -> float:
    return float(np.sqrt(np.mean((est[keep, 0] - truth[keep]) ** 2)) / np.sqrt(np.mean(truth[keep] ** 2)))


def _same(a, b) -> None:
    """Two DerivativeEstimates, field for field, bit for bit."""
    for name in a.__dataclass_fields__:
        x, y = getattr(a, name), getattr(b, name)
        if isinstance(x, np.ndarray):
            np.testing.assert_array_equal(x, y, err_msg=name)
        else:
            assert x == y, name


# ---- the checks -----------------------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    "kw, words",
    [
        ({"method": "bogus"}, ["method", "'bogus'", "'auto', 'savgol', 'local', 'spline'"]),
        ({"method": None}, ["method", "None"]),
        ({"trim": "yes"}, ["trim", "'yes'", "'auto', True or False"]),
        ({"trim": 1}, ["trim", "got 1"]),
        ({"thin": "no"}, ["thin", "'no'", "True or False"]),
    ],
)
def test_derivatives_refuses_bad_fields(kw, words):
    with pytest.raises(ValueError) as e:
        nnphd.Derivatives(**kw)
    assert all(w in str(e.value) for w in words), str(e.value)
    assert str(e.value).startswith("Derivatives: ") and "\n" not in str(e.value)


@pytest.mark.parametrize(
    "kw, words",
    [
        ({"families": ("viscous",)}, ["unknown law family 'viscous'", *FAMILIES]),
        ({"families": ("linear", "dry", "wet")}, ["unknown law families 'dry', 'wet'", "coulomb"]),
        ({"fit": "shooting"}, ["fit", "'shooting'", "'auto', 'pointwise', 'trajectory'"]),
        ({"laws": ("c*x_dot.real",)}, ["law 'c*x_dot.real'", "attribute access"]),
        ({"laws": ("c*__import__('os')",)}, ["not a function that may be called"]),
        ({"families": (), "laws": ()}, ["nothing to rank"]),
    ],
)
def test_law_library_refuses_bad_fields(kw, words):
    with pytest.raises(ValueError) as e:
        nnphd.LawLibrary(**kw)
    assert all(w in str(e.value) for w in words), str(e.value)
    assert "\n" not in str(e.value)


def test_the_defaults_are_what_ran_before():
    d, lib = nnphd.Derivatives(), nnphd.LawLibrary()
    assert (d.method, d.trim) == ("auto", "auto")
    assert lib.laws == () and lib.fit == "auto" and lib.families == FAMILIES
    assert FAMILIES[:3] == ("linear", "linear-diag", "linear-full") and FAMILIES[-2:] == ("drive", "sparse")
    assert len(FAMILIES) == 17 and "perturber" not in FAMILIES  # the orbits' perturber stays opt-in
    assert family_filter(None) is None and family_filter(FAMILIES) is None  # every family: the unfiltered list
    assert family_filter(("quadratic", "linear")) == ("quadratic", "linear")
    one = nnphd.LawLibrary(families="linear", laws="c*x_dot")  # one str is one key / one law, not its characters
    assert one.families == ("linear",) and one.laws == ("c*x_dot",)
    with pytest.raises(TypeError, match="families must be strings"):
        nnphd.LawLibrary(families=("linear", 3))


# ---- Derivatives.estimate ---------------------------------------------------------------------------------------------
def test_estimate_is_estimate_derivatives_bit_for_bit():
    """Derivatives(…).estimate is estimate_derivatives with the same method and trim; "auto" trims the ends of a long
    record (as trim=True) and leaves a short one whole (trimming would keep fewer than 12 of its 16 rows)."""
    _same(nnphd.Derivatives().estimate(T, Q), estimate_derivatives(T, Q, trim=True))
    _same(nnphd.Derivatives(trim=False).estimate(T, Q), estimate_derivatives(T, Q))
    _same(nnphd.Derivatives("local", trim=True).estimate(T, Q), estimate_derivatives(T, Q, "local", trim=True))
    short = nnphd.Derivatives().estimate(T[:16], Q[:16])
    _same(short, estimate_derivatives(T[:16], Q[:16]))
    assert short.trimmed == 0
    assert nnphd.Derivatives().estimate(T[:18], Q[:18]).trimmed == 6  # 12 of 18 rows kept: enough


def test_estimate_is_accurate_and_the_method_matters():
    est = nnphd.Derivatives().estimate(T, Q)
    assert est.method == "savgol" and est.trimmed == 6
    assert _rel(est.qd, QD, est.keep) < 1e-7 and _rel(est.qdd, QDD, est.keep) < 1e-7  # measured 5.3e-9, 2.0e-9
    spl = nnphd.Derivatives("spline").estimate(T, Q)
    assert spl.method == "spline" and spl.window_qd == (None,)
    assert _rel(spl.qdd, QDD, spl.keep) < 1e-5  # measured 1.4e-7
    inner = est.keep & spl.keep
    assert not np.array_equal(spl.qdd[inner], est.qdd[inner])  # another estimator, other numbers
    with pytest.raises(ValueError, match="Savitzky–Golay needs uniform sampling"):
        nnphd.Derivatives("savgol").estimate(T + 0.01 * np.sin(7 * T), Q)


def test_dataset_auto_trim_is_the_old_rule():
    """Derivatives.dataset: what detect's data set was — trimmed when every trajectory keeps enough rows, else not."""
    data = from_arrays([T, T[:16]], [Q, Q[:16]], names=["x"])  # what nnphd.Trajectories holds
    d = nnphd.Derivatives().dataset(data)
    ds, info, trim = d.data, d.info, d.trim
    ref, ref_info = to_dataset(data, trim=False)  # the 16-row trajectory cannot be trimmed: neither is
    assert trim is False and info["trim"] is False
    np.testing.assert_array_equal(ds.qdd, ref.qdd)
    long = from_arrays([T, T[:200]], [Q, Q[:200]], names=["x"])
    d = nnphd.Derivatives().dataset(long)
    ds, info, trim = d.data, d.info, d.trim
    ref, _ = to_dataset(long, trim=True)
    assert trim is True and len(ds) == len(ref) == 401 + 200 - 2 * 6  # 3 rows off each end
    np.testing.assert_array_equal(ds.qdd, ref.qdd)
    d = nnphd.Derivatives("spline", trim=False).dataset(long)
    ds, info = d.data, d.info
    assert info["method"] == "spline" and len(ds) == 601


# ---- NNPhD(...) --------------------------------------------------------------------------------------------------------
def test_old_keywords_and_objects_give_the_same_settings():
    old = nnphd.NNPhD(trim=False, laws="c*x_dot*abs(x_dot)", law_fit="pointwise")
    new = nnphd.NNPhD(
        derivatives=nnphd.Derivatives(trim=False),
        library=nnphd.LawLibrary(laws=("c*x_dot*abs(x_dot)",), fit="pointwise"),
    )
    for m in (old, new):
        assert m.derivatives == nnphd.Derivatives("auto", False)
        assert m.library == nnphd.LawLibrary(FAMILIES, ("c*x_dot*abs(x_dot)",), "pointwise")
        assert (m.trim, m.laws, m.law_fit) == (False, ("c*x_dot*abs(x_dot)",), "pointwise")  # the older names
    plain = nnphd.NNPhD()
    assert plain.derivatives == nnphd.Derivatives() and plain.library == nnphd.LawLibrary()
    assert (plain.trim, plain.laws, plain.law_fit) == ("auto", (), "auto")
    # an old keyword that agrees with the object is fine
    both = nnphd.NNPhD(
        trim=True, derivatives=nnphd.Derivatives("spline", True), law_fit="auto", library=nnphd.LawLibrary()
    )
    assert both.derivatives == nnphd.Derivatives("spline", True) and both.library == nnphd.LawLibrary()


@pytest.mark.parametrize(
    "kw, words",
    [
        ({"trim": False, "derivatives": Derivatives()}, ["trim=False disagrees with derivatives=", "trim='auto'"]),
        ({"laws": ["c*x_dot"], "library": LawLibrary()}, ["laws=['c*x_dot'] disagrees with library.laws=()"]),
        ({"law_fit": "pointwise", "library": LawLibrary(fit="trajectory")}, ["law_fit='pointwise' disagrees"]),
        ({"trim": "sometimes"}, ["Derivatives: trim must be 'auto', True or False"]),
        ({"law_fit": "shooting"}, ["LawLibrary: fit must be"]),
    ],
)
def test_conflicting_or_bad_settings_are_refused(kw, words):
    with pytest.raises(ValueError) as e:
        nnphd.NNPhD(**kw)
    assert all(w in str(e.value) for w in words), str(e.value)
    assert "give one of them" in str(e.value) or "must be" in str(e.value)


def test_objects_of_the_wrong_type_are_refused():
    with pytest.raises(TypeError, match="derivatives must be an nnphd.Derivatives, got str"):
        nnphd.NNPhD(derivatives="spline")
    with pytest.raises(TypeError, match="library must be an nnphd.LawLibrary, got tuple"):
        nnphd.NNPhD(library=("linear",))


class _Stop(Exception):
    pass


def _stand_ins(monkeypatch, seen: dict) -> None:
    """detect_data's training and law table stood in for: what reaches them is noted in ``seen``."""
    import nnphd.explain.search as search
    import nnphd.user.assess as assess_mod
    import nnphd.user.derivatives as derivatives

    derive = derivatives.derive

    def derived(*a, **k):  # the derivatives as estimated (the last data set made is the one used)
        d = derive(*a, **k)
        seen.update(method=d.info["method"], trim=d.info["trim"])
        return d

    def assess(data, traj, *a, **k):
        seen.update(rows=len(data))
        n = (len(data), 1)
        nan = np.full(n, np.nan)  # a conservative force that is not finite: only the library base is ranked
        cons = ConservativeModel(None, None, nan, None)
        return assess_mod.Assessment({"quality": {"oscillating": True}}, nan, nan, cons)

    def find_law(data, run, *a, **k):
        seen.update(families=run.families, laws=run.laws, level=run.level)
        raise _Stop

    monkeypatch.setattr(derivatives, "derive", derived)
    monkeypatch.setattr(assess_mod, "assess", assess)
    monkeypatch.setattr(search, "find_law", find_law)


def test_fit_threads_the_objects_to_the_derivatives_and_the_law_table(monkeypatch):
    data = nnphd.Trajectories([T, T[:300]], [Q, Q[:300]], names=["x"])
    seen: dict = {}
    _stand_ins(monkeypatch, seen)
    with pytest.raises(_Stop):
        nnphd.NNPhD().fit(data)
    assert seen == {"method": "savgol", "trim": True, "rows": 689, "families": None, "laws": (), "level": "auto"}
    seen.clear()
    lib = nnphd.LawLibrary(families=("quadratic", "linear"), laws=("c*x_dot**3",), fit="pointwise")
    with pytest.raises(_Stop):
        nnphd.NNPhD(derivatives=nnphd.Derivatives("spline", trim=False), library=lib).fit(data)
    assert seen == {
        "method": "spline",
        "trim": False,
        "rows": 701,
        "families": ("quadratic", "linear"),
        "laws": ("c*x_dot**3",),
        "level": "pointwise",
    }


def test_restricted_families_are_the_only_candidates_ranked():
    """find_law (what the fit's law table calls) ranks only the families asked for, beside the zero law and your own
    laws; without a restriction every family that fits is a row."""
    from nnphd.explain.search import LawRun, find_law

    rng = np.random.default_rng(0)
    ts = [np.arange(0.0, T_, 0.1) for T_ in (30.0, 25.0)]
    w = np.sqrt(1 - 0.05**2)
    xs = [x0 * np.exp(-0.05 * t) * np.cos(w * t) + 1e-4 * rng.standard_normal(t.size) for x0, t in zip((1.0, -0.7), ts)]
    ud = from_arrays(ts, xs, names=["x"])
    d = nnphd.Derivatives().dataset(ud)
    ds, info, rows = d.data, d.info, d.row_errors
    traj = np.concatenate([np.full(b - a, i) for i, tr in enumerate(info["trajectories"]) for a, b in [tr["kept"]]])

    def ranked(**kw):
        table = find_law(ds, LawRun(traj, ("x",), (False,), info, rows, level="pointwise", **kw))
        return {r.key for r in table.rows}, table

    keys, table = ranked(families=("linear",))
    assert keys == {"linear", "none"}
    assert table.law is not None and table.law.key == "linear"
    assert next(iter(table.law.params.values())) == pytest.approx(0.1, rel=0.05)  # truth −0.1 ẋ (γ = 0.0998)
    keys, _ = ranked(families=("quadratic",), laws=("c*x_dot**3",))
    assert keys == {"quadratic", "user", "none"}  # your own laws are ranked whatever the families
    keys, _ = ranked()
    assert {"linear", "quadratic", "coulomb", "power", "none"} <= keys and len(keys) > 8


def test_cli_families_option(tmp_path, capsys):
    from nnphd.cli import main

    path = tmp_path / "d.csv"
    path.write_text("t,x\n" + "".join(f"{float(a)!r},{float(b)!r}\n" for a, b in zip(T, Q)))
    out = tmp_path / "out"
    for arg, msg in (
        ("linear,viscous", "error: --families: unknown law family 'viscous'; expected some of linear,"),
        (",", "error: --families names no family and no --law is given"),
    ):
        rc = main(["detect", str(path), "--families", arg, "--out", str(out)])
        err = capsys.readouterr().err
        assert rc == 2 and err.startswith(msg) and len(err.strip().splitlines()) == 1, err
        assert not out.exists()


def test_cli_families_reach_the_detection(tmp_path, capsys, monkeypatch):
    """--families is LawLibrary.families: the same setting reaches detect_data (stood in for here)."""
    import nnphd.user.detect as detect
    from nnphd.cli import main

    seen: dict = {}

    def detect_data(ud, **kw):
        seen.update(kw)
        raise _Stop

    monkeypatch.setattr(detect, "detect_data", detect_data)
    path = tmp_path / "d.csv"
    path.write_text("t,x\n" + "".join(f"{float(a)!r},{float(b)!r}\n" for a, b in zip(T, Q)))
    for args, families in ((["--families", " linear, quadratic"], ("linear", "quadratic")), ([], None)):
        seen.clear()
        rc = main(["detect", str(path), "--out", str(tmp_path / "out"), "--law-fit", "pointwise", *args])
        assert rc != 0 and "_Stop" in capsys.readouterr().err  # the stand-in ended it
        assert seen.get("families") == families and seen["law_fit"] == "pointwise" and seen["trim"] == "auto"
