r"""The candidate laws g(q, q̇, t; β, θ) of the non-conservative force, each a :class:`Family`: linear in its
coefficients β given a few nonlinear parameters θ (an exponent m, a drive frequency ω).

Every candidate is odd under time reversal (it does work) or explicitly time-dependent. Built-in families
(:func:`families`): linear friction (isotropic, diagonal, full Γ), quadratic drag −c|q̇|q̇, Coulomb −μ sign(q̇)
(smoothed: tanh(q̇/ε), ε = 2 % of the rms speed), the power law −k(|q̇|²)^m q̇ with m free, Rayleigh (a + c q̇²)q̇,
van der Pol (a + b q²)q̇ and both together, a drive A cos(ωt + φ) with ω started from the peaks of the conservative
residual's Lomb–Scargle spectrum. Besides them: the perturber on a circular orbit (:func:`perturber_family`, opt-in),
a sparse polynomial (odd in q̇, degree ≤ 3, :func:`sparse_family` on a support thresholded jointly with f_c by
:func:`nnphd.explain.laws.rank_laws`), and user laws written as formulas (:func:`parse_law`; the text is read
by :mod:`nnphd.explain.lawtext`, never evaluated).
:func:`family_from_spec` rebuilds any of them from its JSON-ready :attr:`Family.spec`.
"""

from __future__ import annotations

import functools
import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

import numpy as np
import sympy as sp

from nnphd.explain.lawtext import FUNCTIONS, MAX_CHARS, compile_formulas, parse_formula, short, substitute

__all__ = [
    "Family",
    "check_law_text",
    "families",
    "family_from_spec",
    "family_keys",
    "parse_law",
    "perturber_family",
    "sparse_family",
]

COULOMB_EPS = 0.02  # smoothing of sign(q̇), as a fraction of the rms speed
SPARSE_DEGREE = 3
DIGITS = 4
MAX_PARAMS = 20  # of a user law
FUNC_LIST = ", ".join(FUNCTIONS)
TERM_TITLES = {"linear": "viscous −γ q̇", "coulomb": "dry (Coulomb) −μ sign(q̇)", "quadratic": "quadratic drag −c |q̇| q̇"}


@dataclass(frozen=True, eq=False)
class Family:
    """A candidate law g = Σ_k β_k b_k(q, q̇, t; θ): ``basis(xp, θ, q, v, t)`` → (N, n, K) with xp numpy or jax.numpy;
    ``symbols(θ, Q, V, T)`` → n×K SymPy basis (Q, V lists of coordinate / velocity symbols, T time)."""

    key: str
    title: str
    coef_names: tuple[str, ...]
    basis: Callable
    symbols: Callable
    nl_names: tuple[str, ...] = ()
    nl_starts: Callable | None = None  # (ctx) -> list of start vectors θ0
    nl_bounds: tuple = ((), ())
    terms: tuple[str, ...] = ()  # structural labels, e.g. ("q̇",) — what "the form" of the law is
    fixed: Callable | None = None  # (xp, θ, q, v, t) -> (N, n): a parameter-free part of a user law
    per_term: bool = True  # each coefficient multiplies its own term (so each must be significant)
    spec: dict | None = None  # how to build it again (:func:`family_from_spec`): JSON-ready
    dissipative: bool = False  # a sum of friction terms: each coefficient must be ≥ 0 (a negative one pumps energy in)

    @property
    def k(self) -> int:
        return len(self.coef_names) + len(self.nl_names)


def eye_columns(xp, cols):
    """(N, n) columns → (N, n, n) with column j in component j only."""
    n = cols.shape[1]
    return cols[:, :, None] * xp.eye(n, dtype=cols.dtype)[None]


def _sym_diag(n, per):
    """n×n SymPy matrix with per[i] on the diagonal."""
    return [[per[i] if i == j else sp.Integer(0) for j in range(n)] for i in range(n)]


def _traced(x) -> bool:
    import sys

    jax = sys.modules.get("jax")  # a tracer exists only where jax is already in use
    return jax is not None and isinstance(x, jax.core.Tracer)


def families(n: int, names: Sequence[str], v_rms: np.ndarray, sign: str = "tanh") -> list[Family]:
    """The built-in candidate families for n coordinates (names for the parameters; v_rms (n,) the rms speeds;
    ``sign`` the form of the smoothed sign(q̇), :func:`smooth_sign`). ``v_rms`` may be traced (inside a compiled
    program, so that the speeds are its data and not its constants): the same bases then, without ``spec``."""
    if sign not in SIGN_FORMS:
        raise ValueError(f"unknown smoothed sign {sign!r}; expected one of {', '.join(SIGN_FORMS)}")
    nm = list(names)
    traced = _traced(v_rms)  # speeds that are data of a compiled program (the trajectory-level fits' right-hand side)
    if traced:
        import jax.numpy as xp
    else:
        xp, v_rms = np, np.asarray(v_rms, float)
    eps = xp.where(v_rms > 0, COULOMB_EPS * v_rms, 1.0)  # relative to the speeds: units must not matter
    v_all = xp.sqrt(xp.sum(xp.square(v_rms)))
    eps_all = xp.where(v_all > 0, COULOMB_EPS * v_all, 1.0)
    if not traced:
        eps_all = float(eps_all)
    out: list[Family] = [
        *_linear_families(n, nm),
        *_quadratic_families(n, nm),
        *_coulomb_families(n, nm, eps, eps_all, sign),
        *_mixed_families(n, nm, eps, sign),
        _power_family(n),
        *_rayleigh_vdp_families(n, nm),
        _drive_family(n, nm),
    ]
    if traced:  # the same bases, without ``spec`` (its speeds would be tracers)
        return out
    spec = {"kind": "builtin", "v_rms": [float(x) for x in np.asarray(v_rms, float)], "sign": sign}
    return [replace(f, spec={**spec, "key": f.key}) for f in out]


def family_keys() -> tuple[str, ...]:
    """The keys of the candidate families, in ranking order: every built-in one (:func:`families`; the "-diag" and
    "-full" variants exist for two or more coordinates only) and "sparse" (the sparse polynomial law, odd in q̇) —
    what ``include`` of :func:`nnphd.explain.laws.rank_laws` selects from; the opt-in "perturber" is not one."""
    return (*(f.key for f in families(3, ("q1", "q2", "q3"), np.ones(3))), "sparse")


def _linear_families(n: int, nm: list[str]) -> list[Family]:
    """Linear friction: −γ q̇ (isotropic, n > 1), −γ_i q̇_i (per coordinate), −Γ q̇ (full Γ, n > 1)."""
    one = n == 1
    out: list[Family] = []
    if not one:
        out.append(
            Family(
                "linear",
                "linear friction −γ q̇ (isotropic)",
                ("gamma",),
                lambda xp, th, q, v, t: -v[:, :, None],
                lambda th, Q, V, T: [[-V[i]] for i in range(n)],
                terms=("q̇",),
            )
        )
    out.append(
        Family(
            "linear-diag" if not one else "linear",
            "linear friction −γ_i q̇_i" if not one else "linear friction −γ q̇",
            tuple(f"gamma_{c}" for c in nm) if not one else ("gamma",),
            lambda xp, th, q, v, t: eye_columns(xp, -v),
            lambda th, Q, V, T: _sym_diag(n, [-x for x in V]),
            terms=("q̇_i",) if not one else ("q̇",),
        )
    )
    if not one:
        out.append(
            Family(
                "linear-full",
                "linear friction −Γ q̇ (full Γ)",
                tuple(f"Gamma_{a}{b}" for a in nm for b in nm),
                lambda xp, th, q, v, t: (
                    -(v[:, None, None, :] * xp.eye(n, dtype=v.dtype)[None, :, :, None]).reshape(v.shape[0], n, n * n)
                ),
                lambda th, Q, V, T: [
                    [(-V[j] if a == i else sp.Integer(0)) for a in range(n) for j in range(n)] for i in range(n)
                ],
                terms=("Γq̇",),
            )
        )
    return out


def _quadratic_families(n: int, nm: list[str]) -> list[Family]:
    """Quadratic drag: −c |q̇| q̇ (on the speed, n > 1) and −c_i |q̇_i| q̇_i (per coordinate)."""
    one = n == 1
    out: list[Family] = []
    if not one:
        out.append(
            Family(
                "quadratic",
                "quadratic drag −c |q̇| q̇",
                ("c",),
                lambda xp, th, q, v, t: -(xp.sqrt(xp.sum(v * v, axis=1))[:, None] * v)[:, :, None],
                lambda th, Q, V, T: [[-sp.sqrt(sum(x**2 for x in V)) * V[i]] for i in range(n)],
                terms=("|q̇|q̇",),
            )
        )
    out.append(
        Family(
            "quadratic-diag" if not one else "quadratic",
            "quadratic drag −c_i |q̇_i| q̇_i" if not one else "quadratic drag −c |q̇| q̇",
            tuple(f"c_{c}" for c in nm) if not one else ("c",),
            lambda xp, th, q, v, t: eye_columns(xp, -xp.abs(v) * v),
            lambda th, Q, V, T: _sym_diag(n, [-sp.Abs(x) * x for x in V]),
            terms=("|q̇_i|q̇_i",) if not one else ("|q̇|q̇",),
        )
    )
    return out


SIGN_FORMS = ("tanh", "sqrt")  # tanh(v/ε) (since 2026-11-27); v/√(v² + ε²) (model files saved before: no "sign")


def smooth_sign(xp, v, eps, form: str = "tanh"):
    """sign(v) smoothed over ε: tanh(v/ε) — within 1e-4 of ±1 beyond 5ε. The older algebraic form v/√(v² + ε²)
    (``form="sqrt"``, kept for the model files fitted with it) has the same slope 1/ε at zero but falls short of ±1
    by ε²/2v² far out (0.5 % at 10ε): on a dry-friction record a dry term with it acts as viscous friction at a few
    ε, and dry + quadratic drag stood in for viscous + dry (an offset-rest look-alike: a tie, ΔIC 1)."""
    e = xp.asarray(eps, v.dtype)
    return xp.tanh(v / e) if form == "tanh" else v / xp.sqrt(v * v + e * e)


def _sign_scale(xp, s, eps, form: str = "tanh"):
    """smooth_sign(s)/s for speeds s ≥ 0 (1/ε at s = 0): v times it is the smoothed unit vector of v."""
    tiny = s <= 1e-3 * eps
    safe = xp.where(tiny, 1.0, s)
    return xp.where(tiny, 1.0 / eps, smooth_sign(xp, safe, eps, form) / safe)


def _coulomb_families(n: int, nm: list[str], eps: np.ndarray, eps_all: float, sign: str) -> list[Family]:
    """Coulomb (dry) friction with a smoothed sign: −μ q̇/|q̇| (on the velocity, n > 1; smoothing eps_all) and
    −μ_i sign(q̇_i) (per coordinate; smoothing eps (n,))."""
    one = n == 1
    out: list[Family] = []
    if not one:
        out.append(
            Family(
                "coulomb",
                "Coulomb friction −μ q̇/|q̇|",
                ("mu",),
                lambda xp, th, q, v, t: (
                    -(v * _sign_scale(xp, xp.sqrt(xp.sum(v * v, axis=1)), eps_all, sign)[:, None])[:, :, None]
                ),
                lambda th, Q, V, T: [[-V[i] / sp.sqrt(sum(x**2 for x in V))] for i in range(n)],
                terms=("q̇/|q̇|",),
            )
        )
    out.append(
        Family(
            "coulomb-diag" if not one else "coulomb",
            "Coulomb friction −μ_i sign(q̇_i)" if not one else "Coulomb friction −μ sign(q̇)",
            tuple(f"mu_{c}" for c in nm) if not one else ("mu",),
            lambda xp, th, q, v, t: eye_columns(xp, -smooth_sign(xp, v, eps, sign)),
            lambda th, Q, V, T: _sym_diag(n, [-sp.sign(x) for x in V]),
            terms=("sign(q̇_i)",) if not one else ("sign(q̇)",),
        )
    )
    return out


def _mixed_families(n: int, nm: list[str], eps: np.ndarray, sign: str) -> list[Family]:
    """Mixed friction: sums of the textbook terms per coordinate (real friction is rarely one family: gearboxes and
    bearings are viscous + dry, air is linear + quadratic drag); each term must be significant on its own."""
    one = n == 1
    out: list[Family] = []
    term = {
        "linear": ("gamma", lambda xp, v: -v, lambda x: -x, "q̇"),
        "coulomb": ("mu", lambda xp, v: -smooth_sign(xp, v, eps, sign), lambda x: -sp.sign(x),
                    "sign(q̇)"),
        "quadratic": ("c", lambda xp, v: -xp.abs(v) * v, lambda x: -sp.Abs(x) * x, "|q̇|q̇"),
    }  # fmt: skip
    for combo in (("linear", "coulomb"), ("linear", "quadratic"), ("coulomb", "quadratic"),
                  ("linear", "coulomb", "quadratic")):  # fmt: skip
        parts = [term[c] for c in combo]

        def _mixed_basis(xp, th, q, v, t, parts=parts):
            return xp.concatenate([eye_columns(xp, f(xp, v)) for _, f, _, _ in parts], axis=2)

        def _mixed_sym(th, Q, V, T, parts=parts):
            rows = [_sym_diag(n, [s(x) for x in V]) for _, _, s, _ in parts]
            return [sum((r[i] for r in rows), []) for i in range(n)]

        out.append(
            Family(
                "+".join(combo),
                " + ".join(TERM_TITLES[c] for c in combo) + ("" if one else " (per coordinate)"),
                tuple(f"{p}{'' if one else '_' + c}" for p, _, _, _ in parts for c in nm),
                _mixed_basis,
                _mixed_sym,
                terms=tuple(lbl for _, _, _, lbl in parts),
                dissipative=True,
            )
        )
    return out


def _power_family(n: int) -> Family:
    """The power law −k (|q̇|²)^m q̇ with the exponent m free."""

    def _pow_basis(xp, th, q, v, t):
        s = xp.sum(v * v, axis=1)
        sm = xp.where(s > 0, xp.where(s > 0, s, 1.0) ** th[0], 0.0)
        return -(sm[:, None] * v)[:, :, None]

    return Family(
        "power",
        "power-law drag −k (|q̇|²)^m q̇",
        ("k",),
        _pow_basis,
        lambda th, Q, V, T: [[-((sum(x**2 for x in V)) ** sp.Float(th[0], DIGITS)) * V[i]] for i in range(n)],
        nl_names=("m",),
        nl_starts=lambda ctx: [[0.25], [1.0], [2.0], [4.0]],
        nl_bounds=([0.0], [8.0]),
        terms=("(|q̇|²)^m q̇",),
        per_term=False,
    )


def _suffix(n: int) -> Callable[[str], str]:
    """A coefficient's suffix for coordinate c: "_c", or nothing for one coordinate."""
    return (lambda c: f"_{c}") if n != 1 else (lambda c: "")


def _rayleigh_vdp_families(n: int, nm: list[str]) -> list[Family]:
    """Rayleigh (a + c q̇²) q̇, van der Pol (a + b q²) q̇ and both together, per coordinate."""
    sfx = _suffix(n)
    return [
        Family(
            "rayleigh",
            "Rayleigh (a + c q̇²) q̇",
            tuple(f"{p}{sfx(c)}" for p in ("a", "c") for c in nm),
            lambda xp, th, q, v, t: xp.concatenate([eye_columns(xp, v), eye_columns(xp, v**3)], axis=2),
            lambda th, Q, V, T: [r1 + r2 for r1, r2 in zip(_sym_diag(n, V), _sym_diag(n, [x**3 for x in V]))],
            terms=("q̇", "q̇³"),
        ),
        Family(
            "vanderpol",
            "van der Pol (a + b q²) q̇",
            tuple(f"{p}{sfx(c)}" for p in ("a", "b") for c in nm),
            lambda xp, th, q, v, t: xp.concatenate([eye_columns(xp, v), eye_columns(xp, q * q * v)], axis=2),
            lambda th, Q, V, T: [
                r1 + r2 for r1, r2 in zip(_sym_diag(n, V), _sym_diag(n, [x**2 * y for x, y in zip(Q, V)]))
            ],
            terms=("q̇", "q²q̇"),
        ),
        Family(
            "rayleigh-vdp",
            "Rayleigh–van der Pol (a + b q² + c q̇²) q̇",
            tuple(f"{p}{sfx(c)}" for p in ("a", "b", "c") for c in nm),
            lambda xp, th, q, v, t: xp.concatenate(
                [eye_columns(xp, v), eye_columns(xp, q * q * v), eye_columns(xp, v**3)], axis=2
            ),
            lambda th, Q, V, T: [
                r1 + r2 + r3
                for r1, r2, r3 in zip(
                    _sym_diag(n, V), _sym_diag(n, [x**2 * y for x, y in zip(Q, V)]), _sym_diag(n, [x**3 for x in V])
                )
            ],
            terms=("q̇", "q²q̇", "q̇³"),
        ),
    ]


def _drive_family(n: int, nm: list[str]) -> Family:
    """A drive A cos(ω t + φ) of unknown frequency ω, started from the residual's spectral peaks
    (``ctx["drive_omegas"]``)."""
    sfx = _suffix(n)

    def _drive_basis(xp, th, q, v, t):
        c, s = xp.cos(th[0] * t), xp.sin(th[0] * t)
        ones = xp.ones_like(q)
        return xp.concatenate([eye_columns(xp, c[:, None] * ones), eye_columns(xp, s[:, None] * ones)], axis=2)

    return Family(
        "drive",
        "drive A cos(ω t + φ)",
        tuple(f"{p}{sfx(c)}" for p in ("A_cos", "A_sin") for c in nm),
        _drive_basis,
        lambda th, Q, V, T: [
            r1 + r2
            for r1, r2 in zip(
                _sym_diag(n, [sp.cos(sp.Float(th[0], 6) * T)] * n), _sym_diag(n, [sp.sin(sp.Float(th[0], 6) * T)] * n)
            )
        ],
        nl_names=("omega",),
        nl_starts=lambda ctx: [[w] for w in ctx["drive_omegas"]],
        nl_bounds=([1e-9], [np.inf]),
        terms=("cos(ωt)",),
        per_term=False,
    )


def family_from_spec(spec: dict, names: Sequence[str]) -> Family:
    """The family a :attr:`Family.spec` describes, for the coordinates ``names`` (to load a saved law)."""
    names = list(names)
    kind = spec.get("kind")
    if kind == "builtin":
        # a file saved before the tanh form names no "sign": it was fitted with the algebraic one
        for f in families(len(names), names, np.asarray(spec["v_rms"], float), spec.get("sign", "sqrt")):
            if f.key == spec["key"]:
                return f
        raise ValueError(f"no built-in law family {spec['key']!r} for {len(names)} coordinate(s)")
    if kind == "sparse":
        return sparse_family(len(names), names, np.asarray(spec["support"], bool))
    if kind == "user":
        return parse_law(spec["text"], names)
    if kind == "perturber":
        return perturber_family(names)
    raise ValueError(f"unknown law family spec {spec!r}; expected kind builtin, sparse, user or perturber")


def perturber_family(names: Sequence[str]) -> Family:
    """A point mass on a circular orbit, g = GM (r_p(t) − q)/|r_p(t) − q|³, r_p = R (cos(ωt + φ), sin(ωt + φ)) (n = 2;
    the paper's Neptune). GM is linear; R, ω, φ are started from :func:`nnphd.explain.parametric.fit_perturber`'s grid
    on the conservative residual (ctx["residual"]). Opt-in (``rank_laws(candidates=CandidateSet(perturber=True))``): it only makes sense
    for orbits."""

    def _rp(xp, th, t):
        ang = th[1] * t + th[2]
        return th[0] * xp.stack([xp.cos(ang), xp.sin(ang)], axis=1)

    def basis(xp, th, q, v, t):
        d = _rp(xp, th, t) - q
        return (d / xp.sum(d * d, axis=1, keepdims=True) ** 1.5)[:, :, None]

    def symbols(th, Q, V, T):
        R, w, ph = (sp.Float(x, 6) for x in th)
        d = [R * sp.cos(w * T + ph) - Q[0], R * sp.sin(w * T + ph) - Q[1]]
        r3 = (d[0] ** 2 + d[1] ** 2) ** sp.Rational(3, 2)
        return [[d[0] / r3], [d[1] / r3]]

    def starts(ctx):
        from nnphd.explain.parametric import fit_perturber

        try:
            f = fit_perturber(ctx["q"], ctx["t"], ctx["residual"])
        except ValueError:
            return []
        return [[f.params["R"], f.params["omega"], f.params["phi"]]]

    return Family(
        "perturber",
        "perturber GM (r_p(t) − q)/|r_p(t) − q|³ on a circular orbit",
        ("GM",),
        basis,
        symbols,
        nl_names=("R", "omega", "phi"),
        nl_starts=starts,
        nl_bounds=([1e-9, -np.inf, -np.inf], [np.inf, np.inf, np.inf]),
        terms=("(r_p(t) − q)/|r_p − q|³",),
        per_term=False,
        spec={"kind": "perturber"},
    )


@functools.cache
def odd_monomials(n: int, degree: int = SPARSE_DEGREE) -> tuple[tuple[tuple[int, ...], tuple[int, ...]], ...]:
    """Exponent pairs (of q, of q̇) of the monomials of total degree ≤ degree that are odd in q̇ (computed once per
    (n, degree): the sparse laws' basis asks for them at every evaluation)."""
    import itertools

    out = []
    for e in itertools.product(range(degree + 1), repeat=2 * n):
        if 0 < sum(e) <= degree and sum(e[n:]) % 2 == 1:
            out.append((tuple(e[:n]), tuple(e[n:])))
    out.sort(key=lambda m: (sum(m[0]) + sum(m[1]), m[1][::-1], m[0][::-1]))
    return tuple(out)


def _monomial_cols(xp, mons, q, v):
    cols = []
    for eq, ev in mons:
        c = xp.ones_like(q[:, 0])
        for j, e in enumerate(eq):
            if e:
                c = c * q[:, j] ** e
        for j, e in enumerate(ev):
            if e:
                c = c * v[:, j] ** e
        cols.append(c)
    return xp.stack(cols, axis=1)


def _monomial_sym(mons, Q, V):
    return [sp.Mul(*[x**e for x, e in zip(Q, eq)], *[x**e for x, e in zip(V, ev)]) for eq, ev in mons]


def sparse_index(support) -> tuple[np.ndarray, np.ndarray]:
    """(component, monomial) of each coefficient of the sparse law on ``support`` (n × M boolean over
    :func:`odd_monomials`), in the order of its coefficients."""
    support = np.asarray(support, bool)
    i, m = np.nonzero(support)  # row-major: component by component, monomials in order
    return i.astype(np.int32), m.astype(np.int32)


def sparse_basis(xp, q, v, comp, mono):
    """(N, n, K) basis of the sparse law whose coefficient k is monomial ``mono[k]`` of :func:`odd_monomials` in
    component ``comp[k]`` (:func:`sparse_index`); the indices may be data of a compiled program."""
    n = q.shape[1]
    cols = _monomial_cols(xp, odd_monomials(n), q, v)  # (N, M)
    onehot = xp.asarray(xp.arange(n)[:, None] == xp.asarray(comp)[None, :], dtype=q.dtype)  # (n, K)
    return cols[:, xp.asarray(mono)][:, None, :] * onehot[None]


def sparse_family(n: int, names: Sequence[str], support: np.ndarray) -> Family:
    """The sparse polynomial law restricted to ``support`` (n × M boolean over :func:`odd_monomials`)."""
    mons = odd_monomials(n)
    comp, mono = sparse_index(support)
    idx = list(zip(comp.tolist(), mono.tolist()))

    def basis(xp, th, q, v, t):
        return sparse_basis(xp, q, v, comp, mono)

    def symbols(th, Q, V, T):
        ms = _monomial_sym(mons, Q, V)
        return [[ms[m] if i == c else sp.Integer(0) for c, m in idx] for i in range(n)]

    Qs = [sp.Symbol(c) for c in names]
    Vs = [sp.Symbol(f"{c}_dot") for c in names]
    msym = _monomial_sym(mons, Qs, Vs)
    coef = tuple(f"{names[i]}_ddot:{msym[m]}" for i, m in idx)
    return Family(
        "sparse",
        "sparse polynomial (odd in q̇, degree ≤ 3)",
        coef,
        basis,
        symbols,
        terms=tuple(sorted({str(msym[m]) for _, m in idx})),
        spec={"kind": "sparse", "support": np.asarray(support, bool).tolist()},
    )


# ---------------------------------------------------------------------------------------------------------- user laws
_USER_SPLIT = re.compile(r"\s*;\s*")


# A user law's linear parameters are found numerically, never by symbolic differentiation or simplification: on a
# hostile law (a --law, a shared model file's law) sp.diff of nested powers grows exponentially and sp.simplify /
# arbitrary-precision evalf ran for minutes (nnphd.load hung). Float64 evaluation costs one pass over the formula.
_AFFINE_STARTS = (-2.5, 0.5, 1.0)  # a parameter's test values: a, a + h, a + 2h for each (a, h) pair below
_AFFINE_STEPS = (3.0, 0.5, 0.25)
_ZERO_TOL = 1e-9  # relative to the size of the values compared


def _float_fn(exprs: list, syms: list):
    """``exprs`` as one NumPy function of ``syms`` (None when SymPy cannot print one: the safe side)."""
    try:
        return compile_formulas(syms, exprs)
    except Exception:  # noqa: BLE001 — anything SymPy cannot turn into NumPy code
        return None


def _values(f, points: np.ndarray) -> np.ndarray | None:
    """f at each row of ``points`` as an (n_points, n_exprs) complex array (NaN where it fails)."""
    out = []
    with np.errstate(all="ignore"):
        for row in points:
            try:
                out.append([complex(v) for v in f(*row)])
            except Exception:  # noqa: BLE001 — a value that is not a number
                return None
    return np.asarray(out)


def _close_to_zero(d: np.ndarray, scale: np.ndarray) -> bool | None:
    """Whether every finite, nonzero-scale entry of ``d`` is zero relative to ``scale``; None if none counts."""
    ok = np.isfinite(d) & np.isfinite(scale) & (scale > 0)
    if not ok.any():
        return None
    return bool(np.all(np.abs(d[ok]) <= _ZERO_TOL * scale[ok]))


def _linear_params(exprs: list, params: list) -> list:
    """The parameters ``exprs`` are jointly affine in, in order: every term (of the sums) that holds a parameter
    has a vanishing second difference in it, and every term that holds two of them a vanishing mixed difference,
    at random values of every symbol over several offsets and step sizes (terms evaluated one by one, so a term that
    overflows does not hide the others)."""
    terms = [t for e in exprs for t in sp.Add.make_args(e) if t.free_symbols & set(params)]
    syms = sorted({s for t in terms for s in t.free_symbols}, key=lambda s: s.name)
    f = _float_fn(terms, syms) if terms else None
    if f is None:
        return []
    base = np.random.default_rng(0).uniform(0.5, 1.5, size=(4, len(syms)))
    col = {s: i for i, s in enumerate(syms)}

    def at(shifts: dict) -> np.ndarray | None:
        pts = base.copy()
        for s, v in shifts.items():
            pts[:, col[s]] = v
        return _values(f, pts)

    def affine(tests, cols) -> bool:
        seen = False
        for vals in tests:
            if any(v is None for v in vals):
                return False
            vals = [v[:, cols] for v in vals]
            with np.errstate(all="ignore"):  # inf - inf where a value overflows: NaN, not counted
                d = vals[0] - vals[1] - vals[2] + vals[3]
                scale = sum(np.abs(v) for v in vals)
                if not np.all((np.isfinite(d) & np.isfinite(scale) & (scale > 0)).any(axis=0)):
                    return False  # a term with no finite value at any point: not known to be affine
                zero = _close_to_zero(d, scale)
            if zero is False:
                return False
            seen = seen or bool(zero)
        return seen

    lin: list = []
    for p in params:
        ok = True
        for a, h in zip(_AFFINE_STARTS, _AFFINE_STEPS):
            f0, f1, f2 = at({p: a}), at({p: a + h}), at({p: a + 2 * h})
            # the second difference f2 - 2 f1 + f0, over the terms that hold p
            ok = ok and affine([(f2, f1, f1, f0)], [k for k, t in enumerate(terms) if p in t.free_symbols])
            for p2 in lin:
                both = [k for k, t in enumerate(terms) if p in t.free_symbols and p2 in t.free_symbols]
                if ok and both:
                    b2 = 0.7 * h
                    ok = affine([(at({p: a + h, p2: b2 + h}), at({p: a + h, p2: b2}), at({p: a, p2: b2 + h}),
                                  at({p: a, p2: b2}))], both)  # fmt: skip
        if ok:
            lin.append(p)
    return lin


def _is_zero(e: sp.Expr) -> bool:
    """Whether ``e`` is zero: structurally, or its float64 value is zero (relative to its terms' sizes) at random
    positive values of its symbols. Where it cannot be evaluated it is not zero (the safe side)."""
    if e == 0:
        return True
    syms = sorted(e.free_symbols, key=lambda s: s.name)
    f = _float_fn([e, *sp.Add.make_args(e)], syms)
    vals = None if f is None else _values(f, np.random.default_rng(1).uniform(0.5, 1.5, size=(5, len(syms))))
    if vals is None:
        return False
    return bool(_close_to_zero(vals[:, 0], np.sum(np.abs(vals[:, 1:]), axis=1)))


def check_law_text(text: str) -> None:
    """The checks of :func:`parse_law` that need no coordinate names, for a batch of files whose coordinates may
    differ: the text's size, each component's formula (read by :func:`nnphd.explain.lawtext.parse_formula`, any
    name allowed) and no component named twice. ValueError with one line, as parse_law."""
    text = str(text).strip()
    if not text:
        raise ValueError("--law is empty: expected a formula such as 'c*x_dot*abs(x_dot)'")
    if len(text) > MAX_CHARS:
        raise ValueError(f"law {short(text)}: {len(text)} characters is too long (at most {MAX_CHARS})")
    label, heads = f"law {short(text)}", []
    for p in (p for p in _USER_SPLIT.split(text) if p):
        head, sep, body = p.partition(":")
        if sep:
            name = head.strip().removesuffix("_ddot")
            if name in heads:
                raise ValueError(f"{label}: the component {short(name, 30)} is given twice (write each component once)")
            heads.append(name)
        # a coordinate may be named _x; dunder names stay refused
        own = {n: sp.Symbol(n) for n in re.findall(r"(?<![\w.])_(?!_)\w*", body if sep else p)}
        parse_formula(body if sep else p, own, label=label)


def _law_components(text: str, coords: list[str], label: str) -> dict[int, str]:
    """The formula text of each component of a law, by coordinate index: ``"x: ...; y: ..."`` names them, a single
    coordinate may take one unnamed formula. ValueError (one line) on an unknown, repeated or unnamed component."""
    comps: dict[int, str] = {}
    for p in (p for p in _USER_SPLIT.split(text) if p):
        head, sep, body = p.partition(":")
        if sep:
            name = head.strip().removesuffix("_ddot")
            if name not in coords:
                raise ValueError(
                    f"{label}: {short(head.strip())} is not a coordinate (expected one of {', '.join(coords)})"
                )
            i = coords.index(name)
            if i in comps:
                raise ValueError(f"{label}: the component {name!r} is given twice (write each component once)")
            comps[i] = body
        elif len(coords) == 1 and not comps:
            comps[0] = p
        elif len(coords) == 1:
            raise ValueError(
                f"{label}: {short(p)} is a second formula for the one coordinate {coords[0]!r} "
                "(separate components with ';' only with several coordinates)"
            )
        else:
            raise ValueError(
                f"{label}: with {len(coords)} coordinates name the component of each term, "
                f"e.g. '{coords[0]}: -c*{coords[0]}_dot; {coords[1]}: -c*{coords[1]}_dot'"
            )
    return comps


def _law_params(exprs: list, known: dict, coords: list[str], label: str) -> list:
    """The parameters of a law (its symbols other than ``known``), sorted by name. ValueError (one line) when there
    is none, more than MAX_PARAMS, or one that looks like the velocity of an unknown coordinate."""
    params = sorted({s for e in exprs for s in e.free_symbols} - set(known.values()), key=lambda s: s.name)
    if not params:
        raise ValueError(
            f"{label} has no free parameter to fit (symbols other than the coordinates, "
            f"their _dot velocities and t are parameters)"
        )
    if len(params) > MAX_PARAMS:
        raise ValueError(f"{label} has {len(params)} parameters; at most {MAX_PARAMS} can be fitted")
    bad = [p.name for p in params if p.name.endswith("_dot")]
    if bad:
        raise ValueError(
            f"{label}: {short(bad[0])} is not the velocity of a coordinate (coordinates: {', '.join(coords)})"
        )
    return params


def _separate_linear(exprs: list, lin: list, label: str) -> tuple[list, list]:
    """The law split over its linear parameters ``lin``: (rest, base), rest[i] the component i without them (0
    where it is numerically zero), base[i][k] the term of component i that lin[k] multiplies. ValueError (one line)
    when the split produces an infinity or NaN."""
    # affine in the linear parameters: the law at lin = 0 is what is left without them, and a parameter's term
    # is the law at that parameter = 1 (the others 0) less it (substitution; no symbolic derivative)
    # (parts that become numbers are computed in float64: exact evaluation of exp(1e30 + 0**x_dot) overflows)
    zero = {p: sp.Integer(0) for p in lin}
    rest = [substitute(e, zero) for e in exprs]
    base = [[substitute(e, {**zero, p: sp.Integer(1)}) - r for p in lin] for e, r in zip(exprs, rest)]
    if any(x.has(sp.zoo, sp.nan, sp.oo, -sp.oo) for x in (*rest, *(b for row in base for b in row))):
        raise ValueError(f"{label}: its linear parameters cannot be separated; expected terms linear in a coefficient")
    rest = [sp.Integer(0) if _is_zero(r) else r for r in rest]
    return rest, base


def parse_law(text: str, coords: Sequence[str]) -> Family:
    """A user law from a formula: ``"-c*x_dot*abs(x_dot)"`` (one coordinate) or ``"x: -c*x_dot; y: -c*y_dot"``.

    The text is untrusted (a --law, a shared model file): :func:`nnphd.explain.lawtext.parse_formula` reads it
    without evaluating it — numbers, names, + - * / ** (^), parentheses and the functions of
    :data:`nnphd.explain.lawtext.FUNCTIONS` only.

    Symbols: the coordinate names, ``<name>_dot``, ``t``; every other symbol is a parameter (shared between
    components). Parameters the law is linear in are solved exactly, the rest (e.g. an exponent) by least squares
    from 1. Raises ValueError with a one-line message on a law that cannot be used.
    """
    coords = list(coords)
    text = str(text).strip()
    if not text:
        raise ValueError("--law is empty: expected a formula such as 'c*x_dot*abs(x_dot)'")
    if len(text) > MAX_CHARS:
        raise ValueError(f"law {short(text)}: {len(text)} characters is too long (at most {MAX_CHARS})")
    label = f"law {short(text)}"
    comps = _law_components(text, coords, label)
    # real symbols: on complex ones SymPy's automatic evaluation asks for real and imaginary parts, which took 5 s
    # for abs(cosh(2*x**100)) (and the formula is real: the force of real states)
    Q = [sp.Symbol(c, real=True) for c in coords]
    V = [sp.Symbol(f"{c}_dot", real=True) for c in coords]
    T = sp.Symbol("t", real=True)
    known = {s.name: s for s in (*Q, *V, T)}
    exprs = [sp.Integer(0)] * len(coords)
    expected = (
        f"a formula of the coordinates, their _dot velocities, t, parameters, numbers, + - * / ** and {FUNC_LIST}"
    )
    for i, body in comps.items():  # never sympify: it evaluates the text with Python's eval (see lawtext)
        exprs[i] = parse_formula(body, known, label=label, expected=expected)
    params = _law_params(exprs, known, coords, label)
    # the parameters the law is jointly linear in (their coefficients may hold the others)
    lin = _linear_params(exprs, params)
    if not lin:  # before any more SymPy work
        raise ValueError(
            f"{label}: it must be linear in at least one parameter (a coefficient in front of a "
            "term), e.g. 'c*x_dot**m'"
        )
    nl = [p for p in params if p not in lin]
    rest, base = _separate_linear(exprs, lin, label)
    args = (nl, Q, V, T)
    n = len(coords)

    def _fn(xp, exprs_):
        mod = "jax" if xp.__name__.startswith("jax") else "numpy"
        f = compile_formulas(args, exprs_, mod)  # user names never reach the generated code

        def ev(th, q, v, t):
            th = [xp.asarray(x, dtype=q.dtype) for x in th]  # array arithmetic: 1/0 is inf, not ZeroDivisionError
            vals = f(th, [q[:, j] for j in range(n)], [v[:, j] for j in range(n)], t)
            return [xp.broadcast_to(xp.asarray(x, dtype=q.dtype), t.shape) for x in vals]

        return ev

    flat = [b for row in base for b in row]
    cache: dict = {}

    def basis(xp, th, q, v, t):
        key = (xp.__name__, "b")
        if key not in cache:
            cache[key] = _fn(xp, flat)
        vals = cache[key](th, q, v, t)
        K = len(lin)
        cols = [xp.stack([vals[i * K + k] for i in range(n)], axis=1) for k in range(K)]
        return xp.stack(cols, axis=2) if cols else xp.zeros((q.shape[0], n, 0), q.dtype)

    fixed = None
    if any(r != 0 for r in rest):

        def fixed(xp, th, q, v, t):
            key = (xp.__name__, "f")
            if key not in cache:
                cache[key] = _fn(xp, rest)
            return xp.stack(cache[key](th, q, v, t), axis=1)

    def symbols(th, Qs, Vs, Ts):
        # the caller's symbols as real ones of the same names (printed alike): over complex symbols SymPy's
        # re-evaluation of a hostile formula took seconds
        real = lambda b: sp.Symbol(b.name, real=True) if isinstance(b, sp.Symbol) else b  # noqa: E731
        sub = {
            **{a: real(b) for a, b in zip(Q, Qs)},
            **{a: real(b) for a, b in zip(V, Vs)},
            T: real(Ts),
            **{p: sp.Float(x, DIGITS) for p, x in zip(nl, th)},
        }
        # numbers in float64: SymPy would evaluate the formula with numbers in place of its parameters in arbitrary
        # precision, and cos(sinh(1e30*m)) at m = 1 asks for π to 10³⁰ bits (a hostile model file's law hung load)
        return [[substitute(b, sub) for b in row] for row in base]

    fam = Family(
        "user",
        f"user law {text}",
        tuple(p.name for p in lin),
        basis,
        symbols,
        nl_names=tuple(p.name for p in nl),
        nl_starts=(lambda ctx: [[1.0] * len(nl)]) if nl else None,
        nl_bounds=([-np.inf] * len(nl), [np.inf] * len(nl)),
        terms=(text,),
        fixed=fixed,
        per_term=False,
        spec={"kind": "user", "text": text},
    )
    _ = fam.symbols([1.0] * len(nl), Q, V, T)  # fail early on a formula SymPy cannot rebuild
    return fam
