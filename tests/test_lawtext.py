"""Law text is read, never executed (nnphd.explain.lawtext): code in a --law, an API law or a shared model file's
law is refused with one line, size bombs are refused quickly, and valid laws read as SymPy read them before."""

from __future__ import annotations

import contextlib
import signal

import numpy as np
import pytest
import sympy as sp
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from nnphd.explain.families import family_from_spec, parse_law
from nnphd.explain.lawtext import FUNCTIONS, MAX_CHARS, parse_formula

X, XD, T = sp.symbols("x x_dot t")


def _payloads(marker) -> list[str]:
    m = repr(str(marker))
    return [
        f"__import__('pathlib').Path({m}).touch()",
        f"c*x_dot + __import__('pathlib').Path({m}).touch()",
        f"(lambda: 0).__builtins__['__import__']('pathlib').Path({m}).touch()",
        "__import__('os').system('touch MARKER')",
        "().__class__.__base__.__subclasses__()",
        "c*x_dot + (lambda: 1)()",
        "c*x_dot + (lambda m: m)(1)",
        "x.__class__",
        "c*x_dot.real",
        "open('/etc/passwd')",
        "exec('import os')",
        "eval('1')",
        "getattr(x, 'y')",
        "[c for c in ()]",
        "c*x_dot*sum(c for c in (1,))",
        "x_dot if c else 1",
        "'a'",
        "b'a'",
        "f'{c}'",
        "c*x_dot; import os",
        "c*x_dot[0]",
        "(c := 1)*x_dot",
        "c*x_dot == 1",
        "c*x_dot and 1",
        "c*sin(*x_dot)",
        "c*sin(x=x_dot)",
        "c*Symbol('x')",
        "c*x_dot*__builtins__",
        "_c*x_dot",
        "c*x_dot*True",
        "c*x_dot*None",
        "c*x_dot*1j",
        "c*x_dot % 2",
        "c*sin",
        "c*x(1)",
    ]


def test_payloads_are_refused_and_never_run(tmp_path):
    marker = tmp_path / "MARKER"
    for p in _payloads(marker):
        with pytest.raises(ValueError) as e:
            parse_law(p, ["x"])
        msg = str(e.value)
        assert "\n" not in msg and msg.startswith("law ") and len(msg) < 400, msg
        assert not marker.exists()
    # the same through a shared model file's law (nnphd.load rebuilds it with family_from_spec)
    with pytest.raises(ValueError, match="is not allowed"):
        family_from_spec({"kind": "user", "text": _payloads(marker)[1]}, ["x"])
    assert not marker.exists()


def test_refusals_name_the_problem():
    for text, msg in (
        ("x.__class__", r"attribute access \('\.'\) is not allowed"),
        ("c*x_dot[0]", "indexing"),
        ("c*x_dot + (lambda: 1)()", "not a coordinate"),  # the ':' reads as a component name
        ("c*x_dot + (lambda m: m)(1)", "not a coordinate"),
        ("__import__('os')", "'__import__' is not a function that may be called"),
        ("c*x_dot*__builtins__", "may not start with '_'"),
        ("'a'", "strings are not allowed"),
        ("x_dot if c else 1", "conditional expressions"),
        ("[c for c in ()]", "comprehensions"),
        ("c*x_dot; import os", "second formula"),
        ("c*sin", "'sin' is used without arguments"),
        ("c*abs(x_dot, x)", r"abs\(\) takes 1 argument, got 2"),
        ("c/0*x_dot", "divides by zero"),
        ("c*sqrt(-1)*x_dot", r"sqrt\(...\) of its numbers is not a real, finite"),
        ("c*x_dot + cos(sinh(1e30))", r"sinh\(...\) of its numbers is not a real, finite"),
    ):
        with pytest.raises(ValueError, match=msg) as e:
            parse_law(text, ["x"])
        assert "expected" in str(e.value) or "coordinate" in str(e.value), str(e.value)


def test_empty_globals_parse_expr_is_not_enough(tmp_path):
    """Why lawtext exists: sympy's parse_expr (and so sympify) runs the text, even with an empty global_dict (eval
    adds the builtins; a lambda's ``__builtins__`` reaches ``__import__`` without naming anything)."""
    from sympy.parsing.sympy_parser import parse_expr

    marker = tmp_path / "MARKER"
    m = repr(str(marker))
    for run, payload in (
        (
            lambda s: parse_expr(s, global_dict={}),
            f"(lambda: 0).__builtins__['__import__']('pathlib').Path({m}).touch()",
        ),
        (sp.sympify, f"__import__('pathlib').Path({m}).touch()"),
    ):
        run(payload)
        assert marker.exists()  # the payload ran
        marker.unlink()
        with pytest.raises(ValueError, match="is not allowed|not a function that may be called"):
            parse_formula(payload, {})
        assert not marker.exists()


@pytest.mark.parametrize(
    "text, coords, expected",
    [
        ("-c*x_dot*abs(x_dot)", ["x"], "-c*x_dot*Abs(x_dot)"),
        ("c*x_dot**m", ["x"], "c*x_dot**m"),
        ("a*sign(x_dot) + b*x_dot", ["x"], "a*sign(x_dot) + b*x_dot"),
        ("A*cos(w*t+p)", ["x"], "A*cos(w*t + p)"),
        ("c*x_dot^2", ["x"], "c*x_dot**2"),
        ("c*x**(1/2)*x_dot", ["x"], "c*sqrt(x)*x_dot"),
        ("0.5*c*x_dot + 2*d*x_dot**3", ["x"], "0.5*c*x_dot + 2*d*x_dot**3"),
        ("c*exp(-x_dot**2/2)*x_dot", ["x"], "c*exp(-x_dot**2/2)*x_dot"),
    ],
)
def test_valid_laws_read_as_sympy_read_them(text, coords, expected):
    known = {s.name: s for s in (X, XD, T)}
    want = sp.sympify(expected, locals=known)  # (trusted text: the test's own)
    # new names are real parameters (SymPy's evaluation on complex symbols can take seconds: see lawtext)
    want = want.xreplace({s: sp.Symbol(s.name, real=True) for s in want.free_symbols if s.name not in known})
    assert parse_formula(text, known) == want
    fam = parse_law(text, coords)
    assert fam.terms == (text,) and fam.spec == {"kind": "user", "text": text}


def test_two_coordinates_and_repeated_component():
    fam = parse_law("x: -c*x_dot; y: -c*y_dot", ["x", "y"])
    q, v, t = np.ones((3, 2)), np.array([[1.0, 2.0]] * 3), np.zeros(3)
    np.testing.assert_array_equal(fam.basis(np, [], q, v, t)[:, :, 0], -v)
    with pytest.raises(ValueError, match="component 'x' is given twice"):
        parse_law("x: a*x_dot; x: b*x_dot", ["x", "y"])


def test_lambdify_does_not_see_user_names():
    """A parameter named like a module lambdify uses (numpy, jax) does not shadow it in the generated code."""
    fam = parse_law("numpy*sign(x_dot) + jax*x_dot", ["x"])
    v = np.array([[-2.0], [3.0]])
    b = fam.basis(np, [], np.zeros((2, 1)), v, np.zeros(2))
    np.testing.assert_array_equal(b[:, 0, :], [[-2.0, -1.0], [3.0, 1.0]])


@pytest.mark.parametrize(
    "text, msg",
    [
        ("c*x_dot*9**9**9**9", "exponent"),
        ("c*x_dot*(10**100)**100**100", "exponent"),
        ("c*x_dot**1000", "exponent"),
        ("c*x_dot*(10**90)**50", "too large"),
        ("c*x_dot*1e300*1e300", "too large"),
        ("(" * 10_000 + "c*x_dot" + ")" * 10_000, "too long"),
        ("(" * 500 + "c*x_dot" + ")" * 500, "cannot read"),
        ("-" * 1500 + "c*x_dot", "nested too deeply"),
        ("c*x_dot" + "+c" * 600, "nested too deeply"),
        ("+".join(["(" + "+".join(["c"] * 40) + ")"] * 10), "too large"),
        ("c*x_dot+" + "1" * 400, "too large"),
        ("c*x_dot" * 150_000, "too long"),  # ~1 MB
    ],
)
def test_size_bombs_are_refused(text, msg):
    with _ends_within(30), pytest.raises(ValueError, match=msg) as e:
        parse_law(text, ["x"])
    assert "\n" not in str(e.value) and len(str(e.value)) < 500


@contextlib.contextmanager
def _ends_within(seconds: int):
    """A hang guard (not a timing): the block must end within ``seconds``, else the test fails instead of hanging."""

    def stop(*_):
        raise AssertionError(f"still running after {seconds} s: unbounded work on hostile text")

    old = signal.signal(signal.SIGALRM, stop)
    signal.alarm(seconds)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)


@pytest.mark.parametrize(
    "text, coords",
    [  # found by fuzzing: the first hung nnphd.load for minutes in SymPy's arbitrary-precision evalf/simplify
        ("x: (((((m-1e308)^(b**2))^0.5)*c)**(-1+exp(((c*m)**(x_dot*1e308))))); y: (-b+(-1**c))", ["x", "y"]),
        ("c*x_dot + sqrt(abs((cosh((2-3))+((t^100)*(1e30^c)))))", ["x"]),
        ("c*x_dot + exp(exp(22*m))*x", ["x"]),
        ("c*x_dot + exp(exp(30))*x*m", ["x"]),
        ("c*x_dot + exp(-1000*m)*x", ["x"]),
        ("c*x_dot + abs(cosh(((x^100)/0.5)))", ["x"]),  # 5 s of SymPy assumptions on complex symbols
        ("c*x_dot + (((x*t)-b)/((m+-1)/(c+0.5)))", ["x"]),  # 1/(m - 1) at the start m = 1: inf, not an exception
        # 37 s in lambdify (its Dummies drop the real assumption) and in SymPy's assumptions on complex symbols
        (
            "c*x_dot + (cosh(tanh(((abs(cos(t))^100)*(b**(-1/(x**m))))))**cosh((tanh(t)/(((atan(b)^(-2.5**-1))*b)**100))))",
            ["x"],
        ),
        ("c*x_dot + abs(sqrt(tanh(((((x**x)-tan(c))**(b^m))-((sqrt(x_dot)^c)+((2-t)**acos(m)))))))", ["x"]),
    ],
)
def test_hostile_formulas_end_with_a_law_or_one_line(text, coords):
    with _ends_within(30):
        try:
            fam = parse_law(text, coords)
        except ValueError as e:
            assert "\n" not in str(e)
            return
        q = np.full((4, len(coords)), 0.7)
        with np.errstate(all="ignore"):
            assert fam.basis(np, [1.0] * len(fam.nl_names), q, q, np.ones(4)).shape[:2] == (4, len(coords))


def test_the_remainder_is_the_law_without_its_linear_parameters():
    """c*x_dot + (c - 2): SymPy keeps c*x_dot + c - 2 - c*(x_dot + 1) unexpanded; the fixed part is the law at c = 0
    (-2), so evaluating it never meets the linear parameter (a NameError before)."""
    fam = parse_law("c*x_dot + (c - 2)", ["x"])
    q, v, t = np.array([[0.3], [1.1]]), np.array([[0.5], [-2.0]]), np.zeros(2)
    np.testing.assert_allclose(fam.basis(np, [], q, v, t)[:, 0, 0], [1.5, -1.0])
    np.testing.assert_allclose(fam.fixed(np, [], q, v, t)[:, 0], [-2.0, -2.0])
    assert parse_law("c*x_dot*abs(x_dot)", ["x"]).fixed is None


_ATOMS = ["x", "x_dot", "t", "c", "m", "b", "1e308", "1e-308", "-1", "0", "0.5", "2", "100", "1e30"]
_FORMULAS = st.recursive(
    st.sampled_from(_ATOMS),
    lambda inner: st.one_of(
        st.tuples(st.sampled_from(sorted(FUNCTIONS)), inner).map(lambda a: f"{a[0]}({a[1]})"),
        st.tuples(inner, st.sampled_from(["+", "-", "*", "/", "**", "^"]), inner).map(lambda a: f"({''.join(a)})"),
    ),
    max_leaves=24,
)


@settings(max_examples=60, deadline=None)
@given(body=_FORMULAS)
def test_random_formulas_give_a_usable_law_or_one_line(body):
    """Well-formed formulas over every allowed function and extreme numbers: a family whose basis and fixed part
    evaluate (NaN/inf allowed: it is the user's law), or one ValueError line; never another exception, never a hang."""
    with _ends_within(60):
        try:
            fam = parse_law(f"c*x_dot + {body}", ["x"])
        except ValueError as e:
            assert "\n" not in str(e)
            return
        q, v, t = np.array([[0.7], [1.3]]), np.array([[0.4], [-0.9]]), np.array([0.1, 2.0])
        th = [1.0] * len(fam.nl_names)
        with np.errstate(all="ignore"):
            assert fam.basis(np, th, q, v, t).shape == (2, 1, len(fam.coef_names))
            if fam.fixed is not None:
                assert fam.fixed(np, th, q, v, t).shape == (2, 1)


def test_text_limit_is_checked_before_parsing():
    ok = "c*x_dot" + "+0" * ((MAX_CHARS - 7) // 2)
    assert len(ok) <= MAX_CHARS
    with pytest.raises(ValueError, match="too long"):
        parse_formula(ok + "+0" * 10, {})


_FRAGMENTS = [
    "c", "m", "x", "x_dot", "t", "a1", "sin", "abs", "sign", "exp", "pi", "os", "Path", "touch", "system",
    "__import__", "__class__", "__builtins__", "_x", "lambda", "if", "else", "for", "in", "import",
    "0", "2", "0.5", "1e308", "9", "10**100",
    "+", "-", "*", "/", "**", "^", "%", "//", "@", "~", "==", "<", "and", "not",
    "(", ")", "[", "]", "{", "}", ".", ",", ":", ";", "'", '"', " ", "=", ":=", "\\", "\n", "#",
    "__import__('pathlib').Path(M).touch()", "().__class__", "getattr(x, 'y')", "(lambda: 1)()",
]  # fmt: skip


@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(
    parts=st.lists(st.sampled_from(_FRAGMENTS), max_size=12),
    noise=st.text(max_size=6),
    two=st.booleans(),
)
def test_random_text_is_a_law_or_one_line_value_error(parts, noise, two, tmp_path):
    marker = tmp_path / "MARKER"
    text = "".join(parts).replace("M", repr(str(marker))) + noise
    coords = ["x", "y"] if two else ["x"]
    try:
        fam = parse_law(text, coords)
    except ValueError as e:
        assert "\n" not in str(e) and len(str(e)) < 600, str(e)
    else:
        assert fam.key == "user" and fam.coef_names
    assert not marker.exists()


def _csv(path, header, rows):
    path.write_text(header + "\n" + "".join(",".join(str(v) for v in r) + "\n" for r in rows))
    return path


def _no_training(monkeypatch):
    """Any work on the data (its derivatives, which come before any training) fails the test: a bad law is refused
    before it."""
    import nnphd.user.derivatives as derivatives

    def processed(*a, **k):
        raise AssertionError("the data were processed before the law was refused")

    monkeypatch.setattr(derivatives, "to_dataset", processed)
    monkeypatch.setattr(derivatives.Derivatives, "dataset", processed)


def test_cli_refuses_code_in_law_before_anything(tmp_path, capsys, monkeypatch):
    from nnphd.cli import main

    _no_training(monkeypatch)
    t = np.arange(40) * 0.1
    path = _csv(tmp_path / "d.csv", "t,x", [(ti, np.cos(ti)) for ti in t])
    marker, out = tmp_path / "MARKER", tmp_path / "out"
    path2 = _csv(tmp_path / "e.csv", "t,y", [(ti, np.sin(ti)) for ti in t])
    for payload in _payloads(marker)[:3] + ["x: a*x_dot; x: b*x_dot", "c*x_dot*9**9**9**9"]:
        for files in ([path], [path, path2]):  # one file, and a batch (its files may have other coordinates)
            rc = main(["detect", *map(str, files), "--law", payload, "--out", str(out)])
            err = capsys.readouterr().err
            assert rc == 2, err
            assert len(err.strip().splitlines()) == 1 and err.startswith("error: law "), err
            assert not marker.exists() and not out.exists()


def test_law_text_checks_without_coordinates():
    """A batch's pre-check: the formula and its component names, whatever the files' coordinates."""
    from nnphd.explain.families import check_law_text

    check_law_text("x: -c*x_dot; y: -c*y_dot")
    check_law_text("-c*_th_dot")  # a coordinate may start with _ (parse_law decides with the file's names)
    for text, msg in (
        ("x: a*x_dot; x: b*x_dot", "given twice"),
        ("c*__import__('os')", "not a function that may be called"),
        ("c*x_dot.real", "attribute access"),
        ("", "empty"),
    ):
        with pytest.raises(ValueError, match=msg):
            check_law_text(text)


def test_api_refuses_code_in_law_before_training(tmp_path, monkeypatch):
    from nnphd import NNPhD, Trajectories

    _no_training(monkeypatch)
    marker = tmp_path / "MARKER"
    t = np.arange(40) * 0.1
    data = Trajectories(t, np.cos(t), names=["x"])
    with pytest.raises(ValueError, match="attribute access"):
        NNPhD(laws=[_payloads(marker)[0]], steps=10).fit(data)
    assert not marker.exists()


def test_numbers_put_into_a_formula_are_computed_in_float64():
    """Fitted parameters put into a user law (its formula in the report, nnphd.load's check) go through float64:
    cos(sinh(1e30*m)) at m = 1 asked SymPy for π to 10³⁰ bits; now its part without symbols is NaN at once."""
    from nnphd.explain.lawtext import float_value, substitute

    m, x = sp.Symbol("m", real=True), sp.Symbol("x", real=True)
    assert float_value(sp.cos(sp.Integer(2), evaluate=False)) == pytest.approx(np.cos(2.0), rel=1e-15)
    assert np.isnan(float_value(sp.Pow(sp.Integer(-2), sp.Rational(1, 2), evaluate=False)))  # complex: no float
    assert substitute(sp.sin(m * x) + m**2, {m: sp.Float(2.0)}) == sp.sin(2.0 * x) + 4.0
    with _ends_within(30):
        fam = parse_law("c*x_dot + cos(sinh(1e30*m))*x", ["x"])
        row = fam.symbols([1.0], [X], [XD], T)
        assert fam.fixed is not None and str(row[0][0]) == "x_dot"
        assert np.isnan(float_value(substitute(sp.cos(sp.sinh(sp.Float(1e30) * m)), {m: sp.Float(1.0)})))


@pytest.mark.parametrize(
    "text, linear, nonlinear",
    [
        ("c*x_dot*abs(x_dot)", ("c",), ()),
        ("c*x_dot**m", ("c",), ("m",)),
        ("(a + b*x**2)*x_dot", ("a", "b"), ()),
        ("A*cos(w*t + p)", ("A",), ("p", "w")),
        ("abs(c)*x_dot + d*x", ("d",), ("c",)),  # |c| is affine only for c > 0: tested on both sides of 0
        ("c*d*x_dot + c*x", ("c",), ("d",)),  # jointly: c*d is not linear in both
        ("c*x_dot + cos(sinh(1e30*m))*x", ("c",), ("m",)),  # a term that overflows does not hide the others
    ],
)
def test_linear_parameters_are_found_numerically(text, linear, nonlinear):
    """Which parameters are solved exactly (linear) and which by least squares, found from float64 differences of
    the law's terms, not from symbolic derivatives (exponential in a hostile formula's nesting)."""
    fam = parse_law(text, ["x"])
    assert fam.coef_names == linear and fam.nl_names == nonlinear
