"""Blind explanation by genetic symbolic regression (pyoperon) of a learned non-conservative acceleration f_n.

For each component of f_n, pyoperon evolves expression trees over the named inputs (q, q̇, t) with the operators
+ − × ÷, square, sin, cos and fitted constants, optimising accuracy and size together (NSGA-II); from the resulting
Pareto front (the best fit at each size) the model minimising the BIC-type score log(rms) + NODE_COST·nodes is kept
and printed as SymPy. pyoperon's own in-sample BIC (N log MSE + k log N) keeps growing trees that fit the learned
f_n's own small errors (on a friction or radiation law it picks 30-node trees over the 5- and 13-node truth), so each
node must instead cut the residual by ≈5.7% — the sparse step's rule of 25% per term, at ~4 nodes a term. Like the sparse regression it says when the result is not readable (too long or leaving a large residual).
Complements :mod:`nnphd.explain.sparse`: no fixed library, so it can find forms that are not in one, at the price of
being stochastic (the seed fixes it) and slower.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import sympy as sp

from nnphd.explain.law import Law
from nnphd.explain.lawtext import parse_formula
from nnphd.explain.sparse import READABLE_MAX_REL_RMS, BlindMethod, blind_law, regression_data

READABLE_MAX_LENGTH = 30  # expression-tree nodes per component
NODE_COST = float(np.log(1.25)) / 4
OPERATORS = "add,sub,mul,div,square,sin,cos,constant,variable"
GENETIC = BlindMethod(
    "genetic",
    "blind formula (genetic symbolic regression)",
    "genetic symbolic regression (pyoperon; Pareto front of accuracy vs size; each node must cut the residual by 5.7%)",
)


@dataclass(frozen=True)
class GeneticSearch:
    """pyoperon's search per component of f_n: at most ``max_time`` seconds and ``generations`` generations
    (whichever comes first) of a population of ``population_size`` trees of at most ``max_length`` nodes, evaluated
    on ``n_threads`` threads (single-threaded search is deterministic; with more, pyoperon's evaluation order may
    differ run to run)."""

    max_time: float = 20.0
    generations: int = 1000
    population_size: int = 1000
    max_length: int = 30
    n_threads: int = 2


def _round_floats(expr: sp.Expr, digits: int = 4) -> sp.Expr:
    return expr.xreplace({f: sp.Float(f, digits) for f in expr.atoms(sp.Float)})


def _tidy(expr: sp.Expr, y_rms: float) -> sp.Expr:
    """Readable form: powers of sums get their leading coefficient pulled out ((a x² + b y²)⁴ → a⁴ (x² + (b/a) y²)⁴),
    an additive constant below 1% of f_n's rms (pyoperon always fits an intercept) is dropped, floats get 4 digits."""

    def pull(e):
        terms = sp.Add.make_args(sp.expand(e.base))
        lead = max((t.as_coeff_Mul()[0] for t in terms), key=lambda c: abs(float(c)))
        return lead**e.exp * sp.Add(*[t / lead for t in terms]) ** e.exp

    expr = expr.replace(lambda e: e.is_Pow and e.base.is_Add and e.exp.is_Integer and e.exp > 1, pull)
    c, rest = expr.as_coeff_Add()
    if c != 0 and abs(float(c)) < 0.01 * y_rms:
        expr = rest
    return _round_floats(expr)


def genetic_formula(
    inputs: dict[str, np.ndarray],
    fn: np.ndarray,
    component_names: Sequence[str],
    seed: int = 0,
    search: GeneticSearch = GeneticSearch(),
) -> Law:
    """Genetic symbolic-regression formula for f_n (N, n) in terms of the named input columns (each (N,)): a
    :class:`~nnphd.explain.law.Law` of status "hint" (``n_terms``: expression-tree nodes over all components).

    ``search`` bounds the search per component (:class:`GeneticSearch`: pyoperon stops at whichever of time and
    generations comes first). Same seed and inputs → the same formula (single-threaded search is deterministic; with
    more threads pyoperon's evaluation order may differ run to run).
    """
    from nnphd._extras import require

    SymbolicRegressor = require("pyoperon.sklearn", "the genetic (blind) explanation").SymbolicRegressor

    names, x, y = regression_data(inputs, fn, component_names)
    # pyoperon names variables X1..Xk; SymPy needs names it can parse
    safe = [f"v{i}" for i in range(len(names))]
    back = {sp.Symbol(s): sp.Symbol(n) for s, n in zip(safe, names)}
    scale = float(np.sqrt(np.mean(y**2))) or 1.0
    exprs, lengths, sq_err = [], [], 0.0
    for i in range(y.shape[1]):
        yi = y[:, i] / scale
        reg = SymbolicRegressor(  # pyoperon always adds a linear scale and an intercept for the r2 objective
            allowed_symbols=OPERATORS,
            objectives=["r2", "length"],
            max_length=search.max_length,
            generations=search.generations,
            population_size=search.population_size,
            max_evaluations=10**8,
            max_time=max(1, int(round(search.max_time))),
            n_threads=search.n_threads,
            random_state=seed + i,
        )
        reg.fit(x, yi)
        front = [m for m in reg.pareto_front_ if np.isfinite(m["mean_squared_error"])]

        def score(m):
            return float(np.log(max(np.sqrt(m["mean_squared_error"]), 1e-12)) + NODE_COST * m["length"])

        best = min(front, key=lambda m: (score(m), m["length"])) if front else None
        if best is None:
            exprs.append(sp.Integer(0))
            lengths.append(0)
            sq_err += float(np.sum(yi**2))
            continue
        pred = np.asarray(reg.evaluate_model(best["tree"], x), float)
        sq_err += float(np.sum((pred - yi) ** 2))
        model = reg.get_model_string(best["tree"], 8, safe)
        # read without eval (nnphd.explain.lawtext); pyoperon writes e.g. ((-0.5) + (1.2 * (sin(v0) ^ 2)))
        expr = parse_formula(model, {s: sp.Symbol(s) for s in safe}, label="pyoperon model", new_symbols=False)
        expr = _tidy(expr * scale, scale).xreplace(back)
        exprs.append(expr)
        lengths.append(int(best["length"]))
    rel = float(np.sqrt(sq_err / y.size))
    readable = bool(rel <= READABLE_MAX_REL_RMS and max(lengths) <= READABLE_MAX_LENGTH and any(lengths))
    if readable:
        note = f"expression trees of {max(lengths)} nodes at most explain f_n to {100 * rel:.1f}% rms"
    else:
        note = (
            f"nothing readable: the selected models leave {100 * rel:.0f}% rms with up to {max(lengths)} nodes "
            f"(readable means ≤ {READABLE_MAX_LENGTH} nodes and ≤ {100 * READABLE_MAX_REL_RMS:.0f}%)"
        )
    return blind_law(GENETIC, exprs, component_names, rel, int(sum(lengths)), readable, note)
