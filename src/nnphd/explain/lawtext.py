"""Formulas from untrusted text, without executing it: a whitelist walk over Python's syntax tree.

A law's text reaches nnphd from ``nnphd detect --law``, from ``nnphd.NNPhD(laws=[...])`` and from a model file
someone shared (:func:`nnphd.load`). ``sympy.sympify`` / ``parse_expr`` evaluate their input with Python's ``eval``
(an empty ``global_dict`` does not help: ``__import__`` and every builtin stay reachable), so they must never see
such text. :func:`parse_formula` instead reads the text with ``ast.parse(mode="eval")`` — which only parses — and
builds the SymPy expression itself from a short list of allowed nodes:

- numbers: int and float literals (no strings, bytes, booleans, complex numbers or None);
- names: the given symbols, ``pi``, and any other identifier as a new real symbol (a parameter); names that start with
  ``_`` (other than a given symbol) and the allowed function names used bare are refused;
- unary ``+``/``-``, binary ``+ - * / **`` and ``^`` as power (as ``sympify`` reads it);
- calls of the allowed functions by name, with the right number of positional arguments: see :data:`FUNCTIONS`.

Everything else (attribute access, indexing, lambdas, comprehensions, comparisons, ``and``/``or``, conditional
expressions, strings, f-strings, ``:=``, starred arguments, keywords, ...) is refused. Bounds keep hostile text cheap:
at most :data:`MAX_CHARS` characters (checked before parsing), :data:`MAX_NODES` syntax nodes, nesting depth
:data:`MAX_DEPTH`, numeric exponents of at most :data:`MAX_EXPONENT` in size and exact constants of at most
:data:`MAX_BITS` bits (``9**9**9**9`` is refused, not computed). Every refusal is a ValueError with one line that
names the problem and what is expected.
"""

from __future__ import annotations

import ast
import math
import warnings
from collections.abc import Callable, Mapping

import sympy as sp

__all__ = [
    "FUNCTIONS",
    "MAX_CHARS",
    "MAX_DEPTH",
    "MAX_NODES",
    "compile_formulas",
    "float_value",
    "parse_formula",
    "short",
    "substitute",
]

MAX_CHARS = 2000  # the longest text read at all
MAX_NODES = 400  # syntax-tree nodes
MAX_DEPTH = 100  # nesting of operations and calls (a sum of k terms nests k deep)
MAX_EXPONENT = 100  # |e| of a numeric exponent
MAX_BITS = 1024  # an exact constant (numerator, denominator) stays below 2**MAX_BITS (~308 digits)
MAX_FLOAT_DIGITS = 50  # the precision of a float literal (digits)

# name -> (SymPy constructor, number of arguments)
FUNCTIONS: dict[str, tuple[Callable, int]] = {
    "abs": (sp.Abs, 1),
    "Abs": (sp.Abs, 1),
    "sign": (sp.sign, 1),
    "exp": (sp.exp, 1),
    "log": (sp.log, 1),
    "sqrt": (sp.sqrt, 1),
    "sin": (sp.sin, 1),
    "cos": (sp.cos, 1),
    "tan": (sp.tan, 1),
    "sinh": (sp.sinh, 1),
    "cosh": (sp.cosh, 1),
    "tanh": (sp.tanh, 1),
    "asin": (sp.asin, 1),
    "acos": (sp.acos, 1),
    "atan": (sp.atan, 1),
}
CONSTANTS = {"pi": sp.pi}

_FUNC_LIST = ", ".join(dict.fromkeys(FUNCTIONS))
EXPECTED = f"a formula of numbers, names, + - * / ** (or ^), parentheses and {_FUNC_LIST}"

_BINOPS = {
    ast.Add: lambda a, b: a + b,
    ast.Sub: lambda a, b: a - b,
    ast.Mult: lambda a, b: a * b,
    ast.Div: lambda a, b: a / b,
}
_OP_TEXT = {
    ast.FloorDiv: "//",
    ast.Mod: "%",
    ast.MatMult: "@",
    ast.LShift: "<<",
    ast.RShift: ">>",
    ast.BitOr: "|",
    ast.BitAnd: "&",
    ast.BitXor: "^",
    ast.Invert: "~",
    ast.Not: "not",
}
# what a refused node is, in words
_NODE_TEXT = {
    "Attribute": "attribute access ('.') is not allowed",
    "Subscript": "indexing ('[...]') is not allowed",
    "Slice": "slices are not allowed",
    "Lambda": "lambda is not allowed",
    "ListComp": "comprehensions are not allowed",
    "SetComp": "comprehensions are not allowed",
    "DictComp": "comprehensions are not allowed",
    "GeneratorExp": "comprehensions are not allowed",
    "Compare": "comparisons are not allowed",
    "BoolOp": "'and'/'or' are not allowed",
    "IfExp": "conditional expressions ('if ... else') are not allowed",
    "JoinedStr": "f-strings are not allowed",
    "FormattedValue": "f-strings are not allowed",
    "NamedExpr": "assignment (':=') is not allowed",
    "Starred": "starred arguments ('*') are not allowed",
    "List": "lists are not allowed",
    "Tuple": "tuples (',') are not allowed",
    "Set": "sets are not allowed",
    "Dict": "dicts are not allowed",
    "Await": "'await' is not allowed",
    "Yield": "'yield' is not allowed",
    "YieldFrom": "'yield' is not allowed",
}


def short(text: object, limit: int = 60) -> str:
    """``repr`` of untrusted text, cut to about ``limit`` characters (one line, quotes and escapes included)."""
    s = str(text)
    return repr(s if len(s) <= limit else s[: limit - 1] + "…")


class _Refused(Exception):
    """A refusal inside the walk (turned into one ValueError line by :func:`parse_formula`)."""


def parse_formula(
    text: str,
    symbols: Mapping[str, sp.Symbol],
    *,
    label: str | None = None,
    expected: str = EXPECTED,
    new_symbols: bool = True,
) -> sp.Expr:
    """The SymPy expression ``text`` writes, built without evaluating the text (see the module docstring).

    ``symbols``: names → the symbols they stand for (e.g. the coordinates). Another name becomes a new
    ``Symbol`` (a parameter) when ``new_symbols``, else it is refused. ``label`` starts every error message
    (default: ``formula '<text>'``), ``expected`` ends it. Raises ValueError with a one-line message.
    """
    label = label if label is not None else f"formula {short(text)}"

    def fail(problem: str) -> ValueError:
        return ValueError(" ".join(f"{label}: {problem}; expected {expected}".split()))

    if not isinstance(text, str):
        raise fail(f"a {type(text).__name__} is not text")
    if len(text) > MAX_CHARS:
        raise fail(f"{len(text)} characters is too long (at most {MAX_CHARS})")
    if not text.strip():
        raise fail("it is empty")
    src = text.replace("^", "**")  # as sympify's convert_xor: x^2 is x**2 (strings are refused anyway)
    try:
        with warnings.catch_warnings():  # a SyntaxWarning ("invalid decimal literal") must not reach stderr
            warnings.simplefilter("ignore")
            tree = ast.parse(src.strip(), mode="eval")
    except SyntaxError as e:
        where = f" at column {e.offset}" if e.offset else ""
        raise fail(f"cannot read {short(text)} as a formula (invalid syntax{where})") from None
    except (ValueError, RecursionError, MemoryError, OverflowError) as e:
        raise fail(f"cannot read {short(text)} as a formula ({type(e).__name__})") from None
    _check_size(tree, fail)
    try:
        expr = _Builder(src.strip(), symbols, new_symbols).build(tree.body, 0)
    except _Refused as e:
        raise fail(str(e)) from None
    except (RecursionError, MemoryError, OverflowError, ZeroDivisionError) as e:  # not expected within the bounds
        raise fail(f"cannot build it ({type(e).__name__})") from None
    if not isinstance(expr, sp.Expr):
        raise fail("it is not a formula")
    if expr.has(sp.zoo, sp.oo, -sp.oo, sp.nan):
        raise fail("it divides by zero or holds an infinite value")
    if expr.has(sp.I):
        raise fail("it holds a complex number")
    return expr


def _check_size(tree: ast.AST, fail) -> None:
    """Refuse more than MAX_NODES nodes or nesting deeper than MAX_DEPTH (without recursion)."""
    n, stack = 0, [(tree, 0)]
    while stack:
        node, d = stack.pop()
        n += 1
        if n > MAX_NODES:
            raise fail(f"it is too large (more than {MAX_NODES} syntax nodes)")
        if d > MAX_DEPTH:
            raise fail(f"it is nested too deeply (more than {MAX_DEPTH} levels)")
        stack.extend((c, d + 1) for c in ast.iter_child_nodes(node))


def _bits(x: sp.Rational) -> int:
    return max(abs(int(x.p)).bit_length(), abs(int(x.q)).bit_length())


def _check_number(x):
    """Refuse exact constants beyond MAX_BITS and floats beyond float64's range: ``x`` itself or the numeric
    coefficient / term a product or sum collects (2*c*10**300*10**300 folds into one number)."""
    for n in x.args if isinstance(x, (sp.Mul, sp.Add)) else (x,):
        if isinstance(n, sp.Rational) and _bits(n) > MAX_BITS:
            raise _Refused(f"a constant in it is too large (more than {MAX_BITS} bits)")
        if isinstance(n, sp.Float) and not math.isfinite(float(n)):
            raise _Refused("a constant in it is too large (beyond the range of a float)")
    return x


class _Builder:
    def __init__(self, src: str, symbols: Mapping[str, sp.Symbol], new_symbols: bool):
        self.src, self.symbols, self.new_symbols = src, dict(symbols), new_symbols

    def build(self, node: ast.AST, depth: int) -> sp.Expr:
        if depth > MAX_DEPTH:
            raise _Refused(f"it is nested too deeply (more than {MAX_DEPTH} levels)")
        name = type(node).__name__
        if isinstance(node, ast.Constant):
            return self._constant(node)
        if isinstance(node, ast.Name):
            return self._name(node.id)
        if isinstance(node, ast.UnaryOp):
            if isinstance(node.op, ast.USub):
                return _check_number(-self.build(node.operand, depth + 1))
            if isinstance(node.op, ast.UAdd):
                return self.build(node.operand, depth + 1)
            raise _Refused(f"the operator {_OP_TEXT.get(type(node.op), '?')!r} is not allowed")
        if isinstance(node, ast.BinOp):
            a, b = self.build(node.left, depth + 1), self.build(node.right, depth + 1)
            if isinstance(node.op, ast.Pow):
                return self._pow(a, b)
            op = _BINOPS.get(type(node.op))
            if op is None:
                raise _Refused(f"the operator {_OP_TEXT.get(type(node.op), '?')!r} is not allowed")
            if isinstance(node.op, ast.Div) and b == 0:
                raise _Refused("it divides by zero")
            return _check_number(op(a, b))
        if isinstance(node, ast.Call):
            return self._call(node, depth)
        raise _Refused(_NODE_TEXT.get(name, f"{name} syntax is not allowed"))

    def _constant(self, node: ast.Constant) -> sp.Expr:
        v = node.value
        if isinstance(v, bool) or v is None or v is Ellipsis:
            raise _Refused(f"the constant {v!r} is not allowed")
        if isinstance(v, (str, bytes)):
            raise _Refused("strings are not allowed")
        if isinstance(v, int):
            if v.bit_length() > MAX_BITS:
                raise _Refused(f"a constant in it is too large (more than {MAX_BITS} bits)")
            return sp.Integer(v)
        if isinstance(v, float):
            if not math.isfinite(v):
                raise _Refused("a constant in it is too large (beyond the range of a float)")
            seg = (ast.get_source_segment(self.src, node) or repr(v)).replace("_", "")
            # the precision of the literal's digits, as sympify: '0.1' is Float('0.1') (15 digits), a long literal
            # keeps its digits (up to MAX_FLOAT_DIGITS); but '1e308' gets 15 digits, not sympify's exact 310
            mantissa = seg.lower().split("e")[0].replace(".", "").lstrip("0")
            try:
                return sp.Float(seg, min(max(15, len(mantissa)), MAX_FLOAT_DIGITS))
            except (ValueError, TypeError):
                return sp.Float(v)
        raise _Refused(f"a {type(v).__name__} constant is not allowed")

    def _name(self, name: str) -> sp.Expr:
        if name in self.symbols:
            return self.symbols[name]
        if name.startswith("_"):
            raise _Refused(f"the name {short(name, 30)} is not allowed (names may not start with '_')")
        if name in CONSTANTS:
            return CONSTANTS[name]
        if name in FUNCTIONS:
            raise _Refused(f"the function {name!r} is used without arguments")
        if not self.new_symbols:
            raise _Refused(f"unknown name {short(name, 30)}")
        return sp.Symbol(name, real=True)  # real: SymPy's assumption queries on complex symbols can take minutes

    def _call(self, node: ast.Call, depth: int) -> sp.Expr:
        f = node.func
        if not isinstance(f, ast.Name):
            if isinstance(f, ast.Attribute):
                raise _Refused(_NODE_TEXT["Attribute"])
            raise _Refused(f"only the functions {_FUNC_LIST} may be called")
        if f.id not in FUNCTIONS or f.id in self.symbols:
            raise _Refused(f"{short(f.id, 30)} is not a function that may be called (only {_FUNC_LIST})")
        if node.keywords:
            raise _Refused(f"keyword arguments are not allowed in {f.id}(...)")
        if any(isinstance(a, ast.Starred) for a in node.args):
            raise _Refused(_NODE_TEXT["Starred"])
        fn, arity = FUNCTIONS[f.id]
        if len(node.args) != arity:
            raise _Refused(f"{f.id}() takes {arity} argument{'s' if arity != 1 else ''}, got {len(node.args)}")
        args = [self.build(a, depth + 1) for a in node.args]
        if all(not a.free_symbols for a in args):  # a function of numbers: its value in float64, never SymPy's
            v = float_value(fn(*args, evaluate=False))  # (cos(sinh(1e30)) asked SymPy for π to 10³⁰ bits)
            if not math.isfinite(v):
                raise _Refused(f"{f.id}(...) of its numbers is not a real, finite float64 number")
            return sp.Float(v)
        return fn(*args)

    def _pow(self, a: sp.Expr, b: sp.Expr) -> sp.Expr:
        if b.is_Number:
            if isinstance(b, sp.Float) or not isinstance(b, sp.Rational):
                big = abs(float(b)) > MAX_EXPONENT
            else:
                big = abs(b) > MAX_EXPONENT or _bits(b) > 64
            if big:
                raise _Refused(f"the exponent {short(b, 30)} is too large (|exponent| ≤ {MAX_EXPONENT})")
            if a.is_Number:
                if a == 0 and b.is_negative:
                    raise _Refused("it divides by zero")
                if isinstance(a, sp.Rational) and _bits(a) * abs(float(b)) > MAX_BITS:
                    raise _Refused(f"a constant in it is too large (more than {MAX_BITS} bits)")
        return _check_number(a**b)


# ---------------------------------------------------------------------------------------- numbers in float64 only
# SymPy evaluates a function of numbers in arbitrary precision, which a hostile formula turns into unbounded work:
# cos(sinh(1e30)) reduces its argument modulo 2π with π to 10³⁰ bits. Where a formula meets numbers (a function of
# numbers while parsing, fitted parameters put in for display), they are computed here instead, in float64.
_FLOAT_FUNCS: dict[type, Callable[[float], float]] = {
    sp.Abs: abs,
    sp.sign: lambda x: float(math.copysign(1.0, x)) if x else 0.0,
    sp.exp: math.exp,
    sp.log: math.log,
    sp.sin: math.sin,
    sp.cos: math.cos,
    sp.tan: math.tan,
    sp.sinh: math.sinh,
    sp.cosh: math.cosh,
    sp.tanh: math.tanh,
    sp.asin: math.asin,
    sp.acos: math.acos,
    sp.atan: math.atan,
}


def float_value(e: sp.Expr) -> float:
    """The value of an expression without symbols in float64 (NaN where it is not a real float64 number: a
    function SymPy added that is not listed here, log of a negative number, an overflow). One pass over the tree,
    whatever the numbers: never SymPy's arbitrary-precision evaluation."""
    try:
        if e.is_Number:
            return float(e)
        if e is sp.pi:
            return math.pi
        if e is sp.E:
            return math.e
        vals = [float_value(a) for a in e.args]
        if isinstance(e, sp.Add):
            return math.fsum(vals)
        if isinstance(e, sp.Mul):
            return math.prod(vals)
        if isinstance(e, sp.Pow):
            r = vals[0] ** vals[1]
            return r if isinstance(r, float) else math.nan  # a negative number to a fractional power: complex
        fn = _FLOAT_FUNCS.get(type(e)) or _FLOAT_FUNCS.get(getattr(e, "func", None))
        return float(fn(*vals)) if fn is not None and len(vals) == 1 else math.nan
    except (ValueError, OverflowError, ZeroDivisionError, TypeError):
        return math.nan


def substitute(e: sp.Expr, sub: Mapping[sp.Symbol, sp.Expr]) -> sp.Expr:
    """``e.xreplace(sub)`` where every part that becomes a number is computed in float64 (:func:`float_value`;
    NaN where it has no float64 value), so putting numbers into a hostile formula costs one pass over it."""
    if e in sub:
        return sub[e]
    if not e.args:
        return e
    args = [substitute(a, sub) for a in e.args]
    if all(not a.free_symbols for a in args):
        with sp.evaluate(False):
            v = float_value(e.func(*args))
        return sp.Float(v) if math.isfinite(v) else sp.nan
    return e.func(*args)


def compile_formulas(args, exprs, module: str = "numpy"):
    """``sp.lambdify(args, exprs, module)`` with every symbol of ``args`` (nested lists allowed) renamed to a
    positional identifier ``_0``, ``_1``, … first, so no name from the user (a parameter called ``numpy``, a column
    called ``x pos``) reaches the generated code. Not lambdify's own ``dummify``: its Dummies drop the symbols'
    ``real`` assumption, and SymPy's re-evaluation over complex symbols took 30 s on a hostile formula."""
    flat: list = []

    def walk(a):
        if isinstance(a, (list, tuple)):
            return [walk(x) for x in a]
        flat.append(a)
        return sp.Symbol(f"_{len(flat) - 1}", real=True)

    new_args = walk(args)
    ren = dict(zip(flat, (sp.Symbol(f"_{i}", real=True) for i in range(len(flat)))))
    new_exprs = [e.xreplace(ren) for e in exprs]
    return sp.lambdify(new_args, new_exprs, modules=module, dummify=False)
