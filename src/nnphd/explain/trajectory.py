r"""Trajectory-level ranking of the law: the pointwise table's best candidates (and the zero law) re-fitted to the
*positions* by multiple shooting and ranked again (:func:`rank_trajectory`) — for records whose pointwise q̈ is too
noisy or biased for the law (a Coulomb force's jumps are smeared, cubic terms biased).
"""

from __future__ import annotations

import json
import math
import threading
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from typing import NamedTuple

import numpy as np

from nnphd.explain.conservative import conservative_basis
from nnphd.explain.families import Family, families, odd_monomials, sparse_basis, sparse_family, sparse_index
from nnphd.explain.jointfit import N_BOOT, ridge_regularised, solve_or_lstsq, trajectory_segments
from nnphd.explain.table import (
    IC_TIE,
    LawTable,
    law_row,
    nested,
    overdispersion_c_hat,
    overdispersion_ratio,
    relative_to_zero,
    select_law,
    zero_row,
)

__all__ = ["Motion", "TrajectorySettings", "WindowPlan", "rank_trajectory"]

MIN_WINDOWS = 6  # fewer shooting windows: the pointwise table stands (or, allowed, whole trajectories in-sample)
IN_SAMPLE_MAX_ROWS = 4000  # whole-trajectory fits only for short records (one window per trajectory)
# the funnel (:class:`Funnel`): the shortlist is fitted by shooting in rounds of FUNNEL_BATCH candidates, in the
# pointwise table's order; a round none of whose fits lands within FUNNEL_REACH of the best eligible IC (IC_TIE: a
# tie or better) ends it — the rest of the shortlist is out of reach. benchmarks/funnel_audit.py compares the
# verdicts, laws and ties with those of the whole shortlist (FUNNEL_REACH = inf) on records of every kind
FUNNEL_BATCH = 4
FUNNEL_REACH = IC_TIE


@dataclass(frozen=True, eq=False)
class Motion:
    """The recorded motion a fit follows: positions ``q`` and velocities ``qd`` (N, n), times ``t`` (N,) and each
    row's trajectory id ``traj`` (N,; rows of a trajectory contiguous; None: one trajectory)."""

    q: np.ndarray
    qd: np.ndarray
    t: np.ndarray
    traj: np.ndarray | None = None

    def take(self, rows) -> Motion:
        """The motion on the rows ``rows`` (an index array)."""
        traj = None if self.traj is None else np.asarray(self.traj)[rows]
        return Motion(self.q[rows], self.qd[rows], self.t[rows], traj)


@dataclass(frozen=True)
class WindowPlan:
    """How the record is cut into shooting windows: the first length in ``window_periods`` (periods; None: ¾, ⅜,
    3/16) that gives ``min_windows`` windows of at most ``max_window_rows`` rows each (None: the shooting module's
    cap), thinned evenly to ``max_windows``. With fewer and ``allow_in_sample``, each trajectory is one window and the
    IC uses the in-sample χ² (BIC; no held-out groups, no bootstrap)."""

    window_periods: tuple[float, ...] | None = None
    max_window_rows: int | None = None
    max_windows: int = 200
    min_windows: int = MIN_WINDOWS
    allow_in_sample: bool = False


@dataclass(frozen=True)
class TrajectorySettings:
    """How the trajectory-level ranking measures: the first ``shortlist`` candidates of the pointwise table are
    re-fitted — on held-out windows in rounds while a round still lands within ``reach`` of the best IC (None:
    :data:`FUNNEL_REACH`; inf: the whole shortlist; :class:`Funnel`), on whole trajectories in-sample all of them —,
    with ``n_boot`` window-bootstrap replicates drawn with ``seed``, side by side on ``threads`` threads (None:
    :func:`default_threads`; the same numbers whatever the number)."""

    shortlist: int = 16
    n_boot: int = N_BOOT
    seed: int = 0
    threads: int | None = None
    reach: float | None = None


class Directions(NamedTuple):
    """The parameters one candidate of the trajectory-level law fits fits — its directions of the shooting Jacobian,
    each a tangent simulation: α and its law's, padded with zero directions (never free) to one number for every
    family but the sparse law (``small``: the table's largest other family, whether fitted or not) and one for the
    sparse law (``sparse``: its largest possible support, n × the odd monomials, or its slots where fewer), each a
    multiple of :data:`DIRECTION_STEP`. Two classes, not one: a sparse law among the fitted candidates (a 2-D drag
    record's, 25 coefficients) gave every candidate its directions (48 where 32 would do), and a copy of the record
    whose sparse law was not fitted, or had fewer terms, compiled the candidates' programs again (4 s of XLA of a
    2-D drag record's 80 % copy). Now every record with the same families and conservative columns runs the same
    two (the sparse law, where it is fitted, with more zero directions than before: 56 against 48 there)."""

    small: int
    sparse: int

    def of(self, fam: Family | None) -> int:
        return self.sparse if fam is not None and is_sparse(fam) else self.small


class _Layout(NamedTuple):
    """The universal θ of one ranking (:func:`parameter_layout`): each family's ``slots`` (offset, K, m), the
    parameters one candidate fits ``P_dir`` (:class:`Directions`), the default θ ``nl_defaults``, the pointwise α of
    every row ``alpha0`` (by ``id(row)``) and the conservative columns ``Kc``."""

    slots: list
    P_dir: Directions
    nl_defaults: np.ndarray
    alpha0: dict
    Kc: int


class _Shot(NamedTuple):
    """One candidate's multiple-shooting fit (:func:`_shoot_candidate`): the window states ``s``, the parameters
    ``th``, the residuals ``r`` and their Jacobian ``jac``, ``chi2`` and whether LM ``converged``."""

    s: np.ndarray
    th: np.ndarray
    r: np.ndarray
    jac: np.ndarray
    chi2: float
    converged: bool


@dataclass(frozen=True, eq=False)
class _Windows:
    """The shooting windows of one ranking: ``args`` the windows as the model residuals take them
    (:class:`nnphd.engine.shooting.ShootingWindows`, :func:`_window_arrays`), ``s0`` their start states from the data, ``nsub`` the RK4 substeps per step, ``n`` the
    coordinates, ``W`` the windows, ``groups`` their held-out groups, ``n_res`` the residuals and ``in_sample``
    (whole trajectories, ranked by their in-sample fit)."""

    args: tuple
    s0: np.ndarray
    nsub: int
    n: int
    W: int
    groups: list
    n_res: int
    in_sample: bool


@dataclass(frozen=True, eq=False)
class _Ranking:
    """What every candidate's fit of one trajectory-level ranking shares (:func:`_fit_row`): the shortlisted
    candidates ``cands``, the universal θ's ``layout``, the right-hand side ``rhs`` (:func:`_universal_rhs`), the
    ``windows`` and the ranking's ``settings``."""

    cands: list
    layout: _Layout
    rhs: Callable
    windows: _Windows
    settings: TrajectorySettings
    centre: np.ndarray | None = None  # the centre of the potential's library (:func:`_universal_rhs`'s aux)
    speeds: list | None = None  # the built-in families' rms speeds (:func:`builtin_speeds`, the same aux)
    supports: tuple = ()  # the sparse laws' indices (:func:`sparse_supports`, the same aux)
    fc_params: object = ()  # the conservative force's parameters (:func:`fc_parts`, the same aux)


def _universal_rhs(fams: Sequence[Family], Kc: int, angles: tuple, fc_fn, library: bool = True):
    """q̈ = f_c + gate_f · g_f as one function of θ = (α, [β_f, θ_f, gate_f]…) and the candidate's number f (0: no
    law, i: the i-th of ``fams``): one compiled shooting function for all of them, which evaluates only the chosen
    family (``lax.switch`` on a number that is data, not a traced derivative). The parameters actually fitted are u,
    with θ = base + u·D (``aux`` = (base, D, f, the centre of the potential's library, the built-in families'
    speeds, the sparse laws' supports))."""
    import jax
    import jax.numpy as jnp

    from nnphd.engine.shooting import rowwise_combination

    sizes = [(coef_slots(f), len(f.nl_names)) for f in fams]

    # the conservative part Σ α_k column_k — the LNN's f_c among the columns — is differentiated once per row (2n
    # directions), not once per fitted parameter: a shooting Jacobian pushes 2n + P directions through it (53 on a
    # double pendulum), each a (W, n) tangent
    # the centre of the potential's library is data (in aux), not a constant of the program: one compiled program
    # serves every record with the same families; so are the trained model's parameters where ``fc_fn`` gives them
    # (:func:`fc_parts`) — as constants they made every record's program another (11 s of XLA on a 2-D drag record)
    fc_apply = fc_parts(fc_fn)[0]

    def columns(data, q, v):
        centre, fc_params = data
        fc = None if fc_fn is None else fc_apply(fc_params, q, v) if fc_apply is not None else fc_fn(q, v)
        return conservative_basis(jnp, q, v, angles, fc, centre, library)

    conservative = rowwise_combination(columns)

    def family_term(f, off, K, m):
        def term(theta, q, v, t):
            b, th, gate = theta[off : off + K], theta[off + K : off + K + m], theta[off + K + m]
            g = jnp.einsum("wnk,k->wn", f.basis(jnp, th, q, v, t), b)
            if f.fixed is not None:
                g = g + f.fixed(jnp, th, q, v, t)
            return gate * g

        return term

    def rhs(u, q, v, t, aux):
        base, D, which, centre, speeds, supports, fc_params = aux
        theta = base + u @ D
        branches, off = [lambda theta, q, v, t: jnp.zeros_like(v)], Kc
        for f, (K, m) in zip(families_of_data(fams, q.shape[-1], speeds, supports), sizes):
            branches.append(family_term(f, off, K, m))
            off += K + m + 1
        return conservative((centre, fc_params), theta[:Kc], q, v) + jax.lax.switch(which, branches, theta, q, v, t)

    return rhs


def families_of_data(fams: Sequence[Family], n: int, speeds, supports) -> list[Family]:
    """``fams`` with their record's numbers as data of a compiled program, not constants of it: the built-in families
    (:func:`builtin_of` the speeds of :func:`builtin_speeds`) built again from ``speeds`` (their smoothed signs' ε;
    traced), each sparse law's basis from its entry of ``supports`` (the (component, monomial) indices of
    :func:`nnphd.explain.families.sparse_index`, in the order of the sparse laws among ``fams``), the others as they
    are. For programs traced inside (the law fits' right-hand side, the stop check's integration)."""
    v_rms, sign = builtin_speeds(fams)
    own = {} if v_rms is None else {f.key: f for f in families(n, [f"q{i}" for i in range(n)], speeds, sign)}
    supports, out = list(supports), []
    for f in fams:
        if v_rms is not None and builtin_of(f, v_rms, sign):
            f = own[f.key]
        elif is_sparse(f):
            index = supports.pop(0)
            f = replace(f, basis=lambda xp, th, q, v, t, index=index: sparse_basis(xp, q, v, *index))
        out.append(f)
    return out


# One right-hand side per structure, in this process: the compiled shooting programs take it as a static argument
# hashed by identity (:class:`nnphd.engine.shooting.Integrator`), so a record of another length, another seed or
# another call with the same families, libraries and conservative force runs the programs already traced and
# lowered (~10 s of a video pendulum's 80 % copy run after the full record in one process, every tracing of the
# shooting programs). The key holds everything :func:`_universal_rhs` builds into the program: each family's
# place and slots (built-in families by key and smoothed sign — their speeds are data; sparse laws by their slots —
# their supports are data; any other family, a law of the user's or the perturber, by the object itself, kept
# alive with its entry), the conservative columns, the angles, the conservative library and the conservative
# force (its ``apply`` where its numbers are data, else the function itself).
_RHS_CACHE: dict = {}
_RHS_CACHE_SIZE = 16
_RHS_LOCK = threading.Lock()


def _rhs_key(fams: Sequence[Family], Kc: int, angles: tuple, fc_fn, library) -> tuple:
    v_rms, sign = builtin_speeds(fams)

    def shape(f):
        if v_rms is not None and builtin_of(f, v_rms, sign):
            return ("builtin", f.key, coef_slots(f), len(f.nl_names))
        if is_sparse(f):
            return ("sparse", coef_slots(f), len(f.nl_names))
        return ("own", id(f))

    apply = fc_parts(fc_fn)[0]
    force = None if fc_fn is None else ("apply", id(apply)) if apply is not None else ("own", id(fc_fn))
    return tuple(shape(f) for f in fams), int(Kc), tuple(bool(a) for a in angles), force, library, sign


def _export_key(key: tuple, fc_fn) -> str | None:
    """:func:`_rhs_key` as a text another process computes alike (:mod:`nnphd.engine.stored`), or None where it
    names an object by identity (a law of the user's, a force without a described ``apply``)."""
    fams, Kc, angles, force, library, sign = key
    if any(f[0] == "own" for f in fams):
        return None
    if force is not None:
        force = getattr(fc_parts(fc_fn)[0], "export_key", None)
        if force is None:
            return None
    return json.dumps(["universal", fams, Kc, angles, force, library, sign])


def universal_rhs(fams: Sequence[Family], Kc: int, angles: tuple, fc_fn, library=True):
    """:func:`_universal_rhs`, the same function object for the same structure (see the comment above)."""
    key = _rhs_key(fams, Kc, angles, fc_fn, library)
    with _RHS_LOCK:
        hit = _RHS_CACHE.pop(key, None)
        if hit is None:  # the objects named by identity in the key stay alive with the entry (no id is reused)
            rhs = _universal_rhs(fams, Kc, angles, fc_fn, library)
            rhs.export_key = _export_key(key, fc_fn)  # the programs stored for the next process (engine.stored)
            hit = (rhs, tuple(fams), fc_fn, fc_parts(fc_fn)[0])
        _RHS_CACHE[key] = hit  # the most recent last; the oldest dropped
        while len(_RHS_CACHE) > _RHS_CACHE_SIZE:
            _RHS_CACHE.pop(next(iter(_RHS_CACHE)))
    return hit[0]


def fc_parts(fc_fn) -> tuple:
    """(apply, params) of a conservative force ``fc_fn`` that carries them — ``fc_fn(q, v) = apply(params, q, v)``
    with ``params`` a pytree of arrays (:class:`nnphd.user.assess.ConservativeFn`) — else (None, ()): a plain
    function, whose numbers are constants of the programs that call it."""
    apply, params = getattr(fc_fn, "apply", None), getattr(fc_fn, "params", None)
    return (apply, params) if callable(apply) and params is not None else (None, ())


def builtin_of(f: Family, v_rms, sign) -> bool:
    """Whether ``f`` is a built-in family (:func:`nnphd.explain.families.families`) of these speeds and smoothed
    sign: a program may then build it again from the speeds given as data."""
    spec = f.spec or {}
    return spec.get("kind") == "builtin" and spec.get("v_rms") == v_rms and spec.get("sign") == sign


def is_sparse(f: Family) -> bool:
    """Whether ``f`` is a fitted sparse polynomial law (:func:`nnphd.explain.families.sparse_family`)."""
    return (f.spec or {}).get("kind") == "sparse" and f.fixed is None


# Shape classes of the universal θ (as :mod:`nnphd.engine.shooting`'s of the windows): a sparse law's coefficients
# — how many the data keep (6 on a 2-D drag record, 8 on its first 80 %) — take a multiple of SPARSE_SLOTS slots of
# θ, the rest at zero on a zero column (component −1 in :func:`sparse_supports`); the directions one candidate fits
# (α and its law: P_dir, each a tangent simulation) are one of two numbers (:class:`Directions`), each a multiple of
# DIRECTION_STEP, the rest zero rows of D, never free; the whole θ is a multiple of THETA_STEP, its tail unused by
# the right-hand side (zero columns of D). None changes a number; a record of another length with the same families
# then runs the programs of the first (it compiled them again: 11 s of XLA). Slots of 32 hold every sparse law of
# two coordinates (at most 2 × 16 terms) in one class; θ in multiples of 16 gave the whole-record tie fits of a video
# pendulum and of its 80 % copy one size (θ of 21 and 27 before). A table that kept no sparse law keeps an empty
# one's slots (:func:`with_sparse_slots`).
SPARSE_SLOTS = 32
DIRECTION_STEP = 4
THETA_STEP = 16


def coef_slots(f: Family) -> int:
    """The slots of θ the coefficients of family ``f`` take in the universal right-hand side: its coefficients,
    a sparse law's padded to a multiple of :data:`SPARSE_SLOTS`."""
    K = len(f.coef_names)
    return max(1, -(-K // SPARSE_SLOTS)) * SPARSE_SLOTS if is_sparse(f) else K


def with_sparse_slots(fams: Sequence[Family], n: int) -> list[Family]:
    """``fams`` (sorted by key), with an empty sparse law in its sorted place where none of them is one: its slots
    in θ, never a branch that is fitted. Whether the pointwise search keeps a sparse law depends on the data (a video
    pendulum's did, its 80 % copy's did not: θ of 96 against 64, 17 s of XLA of its own); with the slots kept, both
    run one compiled program (the supports are data, :func:`sparse_supports`)."""
    fams = list(fams)
    if not any(is_sparse(f) for f in fams):
        empty = sparse_family(n, [f"q{i}" for i in range(n)], np.zeros((n, len(odd_monomials(n))), bool))
        fams.insert(sum(1 for f in fams if f.key < empty.key), empty)
    return fams


def sparse_supports(fams: Sequence[Family]) -> tuple:
    """The (component, monomial) indices (:func:`nnphd.explain.families.sparse_index`) of the sparse laws among
    ``fams``, in their order, each padded to :func:`coef_slots` with component −1 (a zero column of
    :func:`nnphd.explain.families.sparse_basis`): data of the universal right-hand side."""
    out = []
    for f in fams:
        if is_sparse(f):
            comp, mono = sparse_index(f.spec["support"])
            pad = coef_slots(f) - len(comp)
            out.append(
                (np.concatenate([comp, np.full(pad, -1, np.int32)]), np.concatenate([mono, np.zeros(pad, np.int32)]))
            )
    return tuple(out)


def builtin_speeds(fams: Sequence[Family]):
    """(v_rms, sign) of the built-in families among ``fams`` (:func:`nnphd.explain.families.families`; those of the
    first where several differ), or (None, None) where there is none."""
    for f in fams:
        spec = f.spec or {}
        if spec.get("kind") == "builtin":
            return spec["v_rms"], spec["sign"]
    return None, None


MU_WARM = 1e-5  # LM's first damping from a start at (or next to) the zero law's optimum: its quadratic model holds
# there (1e-3, LM's default, took 10 Jacobians per candidate on a double pendulum, 1e-5 took 7–8 to the same χ²)
HELDOUT_FLOOR = 0.5  # a group's held-out χ² below this share of its in-sample χ²: the fit is no optimum


def heldout_chi2(c_loc, S, g, groups) -> float | None:
    """The held-out χ² of a multiple-shooting fit: each group of windows predicted by the fit to the others,
    linearised at the fit (c_loc (W,) the windows' χ², S (W, P, P) and g (W, P) their Schur-reduced normal matrices
    and gradients). At an optimum (Σ g = 0) a group's held-out χ² is at least its in-sample χ²
    (2 g·d + d·S_g·d ≥ 0 for d = S₋g⁻¹ g_g); a fit a little short of it (a few LM iterations) gives a little less,
    one far from it much less — below HELDOUT_FLOOR of its in-sample χ² (or not finite) the linearised held-out error
    means nothing: None then. (Not checked before: a drive with free ω on a 2-D drag record had held-out χ² < 0,
    clipped to 1e-300, ΔIC −39418, and was claimed as the law.)"""
    Stot, gtot = S.sum(0), g.sum(0)
    cv = 0.0
    for grp in groups:
        Sg, gg = S[grp].sum(0), g[grp].sum(0)
        d = -solve_or_lstsq(ridge_regularised(Stot - Sg), gtot - gg)
        c_g = float(c_loc[grp].sum())
        cv_g = float(c_g + 2 * gg @ d + d @ Sg @ d)
        if not np.isfinite(cv_g) or cv_g < HELDOUT_FLOOR * c_g:
            return None
        cv += cv_g
    return cv


def _choose_windows(segs, t, period: float, plan: WindowPlan):
    """The shooting windows of ``plan``: the first length in ``window_periods`` (periods; default ¾, ⅜, 3/16) that
    gives ``min_windows`` windows of at most ``max_window_rows`` rows, thinned evenly to ``max_windows``. Returns
    (windows, in_sample); with fewer windows the whole trajectories (in_sample True) where allowed and short enough,
    else None: the record is not ranked by trajectory."""
    from nnphd.engine.shooting import MAX_WINDOW, MIN_WINDOW, WINDOW_PERIODS, shooting_windows

    window_periods, max_window_rows, max_windows = plan.window_periods, plan.max_window_rows, plan.max_windows
    min_windows, allow_in_sample = plan.min_windows, plan.allow_in_sample

    # the first of the window lengths that leaves min_windows of them (else, allowed, whole trajectories in-sample)
    cap = MAX_WINDOW if max_window_rows is None else max(MAX_WINDOW, int(max_window_rows))
    for periods in window_periods or (WINDOW_PERIODS, WINDOW_PERIODS / 2, WINDOW_PERIODS / 4):
        wins = shooting_windows(segs, t, period, periods=periods, max_window=cap)
        if len(wins) >= min_windows:
            break
    if len(wins) > max_windows:
        keep = np.unique(np.linspace(0, len(wins) - 1, max_windows).round().astype(int))
        wins = [wins[i] for i in keep]
    in_sample = len(wins) < min_windows
    if in_sample:  # too short for held-out windows: whole trajectories, ranked by their in-sample fit (BIC)
        wins = [sg for sg in segs if len(sg) >= 2 * MIN_WINDOW] if allow_in_sample else []
        if not wins or sum(len(w) for w in wins) > IN_SAMPLE_MAX_ROWS:
            return None
    return wins, in_sample


def _window_arrays(wins, t, q_pos, qd, sigma, period: float):
    """The windows padded for the shooting fit. Returns (args, s0, mask, nsub): the JAX arguments of the model
    residuals (times from each window's start, start times, positions, mask, 1/σ with σ at least 1e-3 of each
    coordinate's spread), the windows' start states, the mask of recorded rows, and the RK4 substeps per step (enough
    for 0.3 rad of the fastest motion, at most 8)."""
    import jax.numpy as jnp

    from nnphd.engine.shooting import ShootingWindows, pad_windows

    n = q_pos.shape[1]
    spread = np.array([np.ptp(q_pos[:, j]) for j in range(n)])
    sig = np.maximum(np.asarray(sigma, float), 1e-3 * np.maximum(spread, 1e-12))
    tw, qw, mask, s0 = pad_windows(wins, t, q_pos, (q_pos, qd))
    t0w = tw[:, 0].copy()
    tw = tw - tw[:, :1]
    dtmax = float(np.max(np.diff(tw, axis=1)))
    vmax = float(np.max(np.abs(qd)) / max(np.min(spread), 1e-12))
    nsub = int(min(8, max(1, math.ceil(dtmax * max(vmax, 2 * math.pi / period if np.isfinite(period) else 0) / 0.3))))
    args = ShootingWindows(
        jnp.asarray(tw), jnp.asarray(t0w), jnp.asarray(qw), jnp.asarray(mask), jnp.asarray(1.0 / sig)
    )
    return args, s0, mask, nsub


def parameter_layout(fams: Sequence[Family], Kc: int):
    """The universal θ = (α, [β_f, θ_f, gate_f]…) of :func:`_universal_rhs`. Returns (slots, P_dir, nl_defaults):
    each family's (offset, K, m) in θ, the numbers of parameters one candidate fits (:class:`Directions`: every one
    of them is a direction of the shooting Jacobian), and the default θ — each family's nonlinear parameters at 1
    (within their bounds), all else 0."""
    slots, off = [], Kc  # where each family's (β, θ, gate) sit in the universal θ
    for f in fams:
        K, m = coef_slots(f), len(f.nl_names)
        slots.append((off, K, m))
        off += K + m + 1
    P_glob = -(-off // THETA_STEP) * THETA_STEP  # the tail: no family's (see THETA_STEP)
    step = lambda p: -(-p // DIRECTION_STEP) * DIRECTION_STEP  # noqa: E731
    small = [len(f.coef_names) + m for f, (_, _, m) in zip(fams, slots) if not is_sparse(f)]
    sparse = [min(K, np.size(f.spec["support"])) + m for f, (_, K, m) in zip(fams, slots) if is_sparse(f)]
    P_dir = Directions(step(Kc + max(small, default=0)), step(Kc + max(sparse, default=0)))
    nl_defaults = np.zeros(P_glob)
    for f, (o, K, m) in zip(fams, slots):
        if m:
            lo, hi = (np.asarray(x, float) for x in f.nl_bounds)
            nl_defaults[o + K : o + K + m] = np.clip(1.0, lo, np.where(np.isfinite(hi), hi, 1.0))
    return slots, P_dir, nl_defaults


def _candidate_start(row, ci: int, slots, nl_defaults, alpha0, Kc: int, P_dir: Directions):
    """One row's parametrisation θ = base + u·D of the universal θ: u = its α, then (a family) its β and θ — that
    family's gate at 1, the others' at 0. Returns (base, D, u0, n_fit): u0 the row's pointwise fit (padded with zeros
    to P_dir), n_fit the number of its parameters."""
    fam = row.family
    base = nl_defaults.copy()
    idx = list(range(Kc))
    u0 = list(alpha0[id(row)])
    if fam is not None:
        o, K, m = slots[ci - 1]  # K: the family's slots; its own coefficients the first of them
        base[o + K + m] = 1.0
        idx += list(range(o, o + len(fam.coef_names))) + list(range(o + K, o + K + m))
        u0 += list(row.beta) + list(row.theta)
        base[o : o + K + m] = 0.0
    P = P_dir.of(fam)
    D = np.zeros((P, len(nl_defaults)))
    D[np.arange(len(idx)), idx] = 1.0
    u0 = np.concatenate([u0, np.zeros(P - len(idx))])
    return base, D, u0, len(idx)


def _shoot_candidate(model, starts, free, fam: Family | None, Kc: int, n_fit: int, dof: int = 0):
    """Levenberg–Marquardt of the windows from each of ``starts`` ((window states, u, LM's first damping)) until one
    gives a finite χ²; a family's nonlinear parameters out of their bounds are clipped, fixed (in ``free``, in place)
    and the fit repeated. ``model``: the residuals and the derivatives (res, jac_fn) of
    :func:`nnphd.engine.shooting.lm_windows`; ``dof`` the residuals less the fitted parameters (LM's statistical
    stop, :class:`nnphd.engine.shooting.LMSettings`; 0: none). Returns the fit (:class:`_Shot`: s, θ, r, jac, χ²,
    converged: whether LM stopped with χ² no longer falling), or None when no fit is finite."""
    from nnphd.engine.shooting import LMSettings, lm_windows

    res, jac_fn = model
    chi2 = np.nan
    info = {}
    for s_start, u_start, mu0 in starts:
        try:
            s, th, r, jac, chi2 = lm_windows(
                None, s_start, u_start, free, LMSettings(iters=15, mu0=mu0, dof=dof), res=res, jac_fn=jac_fn, info=info
            )
        except (np.linalg.LinAlgError, FloatingPointError, ValueError):
            continue
        if np.isfinite(chi2):
            break
    if not np.isfinite(chi2):
        return None
    if fam is not None and fam.nl_names:  # LM knows no bounds: out of them, fit again with θ clipped and fixed
        lo, hi = (np.asarray(x, float) for x in fam.nl_bounds)
        K = len(fam.coef_names)
        nl = th[Kc + K : n_fit]
        if np.any(nl < lo) or np.any(nl > hi):
            th1 = th.copy()
            th1[Kc + K : n_fit] = np.clip(nl, lo, hi)
            free[Kc + K : n_fit] = False
            s, th, r, jac, chi2 = lm_windows(
                None, s, th1, free, LMSettings(iters=15, dof=dof), res=res, jac_fn=jac_fn, info=info
            )
            if not np.isfinite(chi2):
                return None
    return _Shot(s, th, r, jac, chi2, bool(info.get("converged")))


def lowest_first(res, starts: list) -> list:
    """``starts`` ((window states, u, …)) by their χ² (``res(s, u)``), the lowest first (a start whose χ² is not
    finite last; ties in their order)."""

    def chi2(st):
        with np.errstate(over="ignore", invalid="ignore"):
            c = float(np.sum(np.asarray(res(*st[:2])) ** 2))
        return c if np.isfinite(c) else np.inf

    costs = [chi2(st) for st in starts]
    return [starts[i] for i in sorted(range(len(starts)), key=costs.__getitem__)]


def _window_bootstrap(th, fi, S, g, W: int, n_boot: int, seed: int) -> list:
    """``n_boot`` window-bootstrap replicates of θ: the fit moved by one linearised step to the windows drawn with
    replacement (S, g the windows' Schur-reduced normal matrices and gradients over the free parameters ``fi``)."""
    rng = np.random.default_rng(seed)
    reps = []
    for _ in range(n_boot):
        idx = rng.integers(0, W, W)
        rep = th.copy()
        rep[fi] -= solve_or_lstsq(ridge_regularised(S[idx].sum(0)), g[idx].sum(0))
        reps.append(rep)
    return reps


def _candidate_statistics(row, shot: _Shot, free, n_fit: int, ranking: _Ranking):
    """A fitted row's ranking entry (row, θ, held-out χ², se, ρ, overdispersion ratio, law covariance, conservative
    covariance) from its fit ``shot``: the held-out χ² of the groups of windows (in-sample: the fit's χ²), se the
    larger of the window bootstrap's and the model's, ρ the residuals' lag-one correlation. None when the fit is not
    at an optimum."""
    from nnphd.engine.shooting import normal_blocks, schur_complement

    th, r, jac, chi2 = shot.th, shot.r, shot.jac, shot.chi2
    wins, Kc = ranking.windows, ranking.layout.Kc
    n, W, groups, in_sample, n_res = wins.n, wins.W, wins.groups, wins.in_sample, wins.n_res
    n_boot, seed = ranking.settings.n_boot, ranking.settings.seed
    th = th[:n_fit]
    free = free[:n_fit]
    jac = jac[: 2 * n + n_fit]
    AtA, AtB, BtB, Atr, Btr, rr = normal_blocks(r, jac, 2 * n)
    S, g, _XB, Xr = schur_complement(AtA, AtB, BtB, Atr, Btr, 0.0, free)
    c_loc = rr - np.einsum("wi,wi->w", Atr, Xr)  # χ² per window with its states re-optimised
    Stot = S.sum(0)
    cv = chi2 if in_sample else heldout_chi2(c_loc, S, g, groups)
    if cv is None:  # not at an optimum: its held-out error means nothing — the candidate is not ranked
        return None
    fi = np.flatnonzero(free)  # S, g are over the free parameters
    reps = _window_bootstrap(th, fi, S, g, W, n_boot if row.family is not None else 0, seed)
    law_idx = np.arange(Kc, len(th))
    se_b = np.asarray(reps)[:, law_idx].std(axis=0) if reps else np.zeros(len(law_idx))
    s2 = chi2 / max(n_res - W * 2 * n - len(fi), 1)
    var = np.zeros(len(th))
    cov_full = s2 * np.linalg.pinv(ridge_regularised(Stot))  # over the free parameters; the Kc conservative ones first
    var[fi] = np.diag(cov_full)
    se_m = np.sqrt(np.maximum(var[law_idx], 0.0))
    R = r.reshape(W, -1)
    rho = float(np.sum(R[:, n:] * R[:, :-n]) / max(np.sum(R * R), 1e-300))
    se = np.maximum(se_b, se_m)
    corr = np.eye(len(law_idx))
    if len(reps) > len(law_idx) + 1:  # the terms' trade-off from the bootstrap, the sizes from se
        with np.errstate(all="ignore"):
            c = np.corrcoef(np.asarray(reps)[:, law_idx].T)
        corr = np.where(np.isfinite(c), c, corr) if c.ndim == 2 else corr
    return (row, th, max(cv, 1e-300), se, rho, overdispersion_ratio(se_b, se_m, th[Kc:]), corr * np.outer(se, se),
            cov_full[:Kc, :Kc])  # fmt: skip


ADEQUATE_CHI2 = 2.0  # fits within this factor of the lowest held-out χ²: their residuals are the noise's


def noise_correlation(results) -> float:
    """The residuals' lag-one correlation ρ that sets the IC's correlation time: the median over the fits whose
    held-out χ² is within :data:`ADEQUATE_CHI2` of the lowest — a fit that misses the record leaves a smooth residual,
    and its correlation is misfit (which its χ² counts already), not the noise's."""
    best = min(x[2] for x in results)
    ok = [x[4] for x in results if x[2] <= ADEQUATE_CHI2 * best]
    return float(np.clip(np.median(ok), 0.0, 0.95))


def _trajectory_rows(results, settings: dict, y_rms: float, q_pos, qd, t, n_res: int):
    """The table's rows from the ranking entries: IC with n_eff = n_res/τ residuals, τ = (1 + ρ)/(1 − ρ)·ĉ from the
    lag-one correlation ρ of the adequate fits (:func:`noise_correlation`) and the overdispersion ĉ; each row with
    its joint fit's conservative part. Returns (rows, n_eff, τ)."""
    Kc = settings["conservative_columns"]
    N = q_pos.shape[0]
    rho = noise_correlation(results)
    c_hat = overdispersion_c_hat([x[5] for x in results], [x[2] for x in results])
    tau = (1 + rho) / (1 - rho) * c_hat
    n_eff = n_res / tau
    rows = []
    for row, th, cv, se, _, _, cov, cov_c in results:
        fam = row.family
        if fam is None:
            new = zero_row(settings["names"], cv / n_res, N, "trajectory")
        else:
            K = len(fam.coef_names)
            new = law_row(fam, th[Kc : Kc + K], th[Kc + K :], se, settings["names"], cv / n_res, "trajectory")
            new.on_rows(q_pos, qd, t)
            new.cov = cov[:K, :K]
        new.ic = n_eff * math.log(cv / n_res) + row.k * math.log(max(n_eff, 2.0))
        # the conservative part of the joint fit; its covariance widened by the residuals' correlation (τ)
        new.conservative, new.conservative_cov = np.asarray(th[:Kc], float), cov_c * tau
        rows.append(new)
    relative_to_zero(rows, y_rms)
    return rows, n_eff, tau


def _fit_row(ci: int, row, *, ranking: _Ranking, warm=None):
    """The ranking entry of ``row`` (branch ``ci`` of the universal right-hand side, 0 the zero law;
    :func:`_candidate_statistics`): its joint fit by multiple shooting, or None when no fit is finite or it is not at
    an optimum; and the fit's window states and conservative α (the candidates' ``warm`` start), or None (no fit, or
    LM did not converge). ``ranking``: the universal θ's layout, the right-hand side, the windows and the settings.

    Starts: the row's pointwise fit (window states ``s0`` from the data) and, given ``warm`` (the zero law's
    trajectory-level fit, where LM converged), the zero law's window states and α with this row's law at zero and at its pointwise values
    — the lowest χ² first (:func:`lowest_first`). The pointwise α is far from the trajectory-level optimum (χ² 100×
    the optimum's on a double pendulum's 43 conservative columns): LM spent a third of its Jacobians getting from
    there to where the zero law's fit already is."""
    import jax.numpy as jnp

    from nnphd.engine.shooting import Integrator, model_jac, model_residuals

    cands, (slots, P_dir, nl_defaults, alpha0, Kc) = ranking.cands, ranking.layout
    args, rhs, nsub = ranking.windows.args, ranking.rhs, ranking.windows.nsub
    s0, in_sample = ranking.windows.s0, ranking.windows.in_sample
    fam = row.family
    base, D, u0, n_fit = _candidate_start(row, ci, slots, nl_defaults, alpha0, Kc, P_dir)
    centre = None if ranking.centre is None else jnp.asarray(ranking.centre)
    speeds = None if ranking.speeds is None else jnp.asarray(np.asarray(ranking.speeds, float))
    supports = tuple((jnp.asarray(i), jnp.asarray(m)) for i, m in ranking.supports)
    aux = (jnp.asarray(base), jnp.asarray(D), jnp.asarray(ci, jnp.int32), centre, speeds, supports, ranking.fc_params)

    def res(s_, u_):
        return model_residuals(s_, u_, aux, args, Integrator(rhs, nsub))

    def jac(s_, u_):
        return model_jac(s_, u_, aux, args, Integrator(rhs, nsub))

    free = np.zeros(P_dir.of(fam), bool)
    free[:n_fit] = True
    # the conservative starts: this row's own, then (the zero law, whole trajectories) the other rows' — the
    # zero law's pointwise f_c soaks up what it can of the friction and can run away over a long window
    starts = [(s0, u0, 1e-3)] + [
        (s0, np.concatenate([alpha0[id(c)], u0[Kc:]]), 1e-3) for c in (cands[:2] if fam is None and in_sample else [])
    ]
    if warm is not None:  # the zero law's fit, with this row's law at zero (the zero law's χ²) and pointwise
        s_w, a_w = warm
        u_w = np.concatenate([a_w, u0[Kc:]])
        u_z = u_w.copy()
        if fam is not None:
            u_z[Kc : Kc + len(fam.coef_names)] = 0.0
        starts = lowest_first(res, [(s_w, u_z, MU_WARM), (s_w, u_w, MU_WARM), *starts])
    wins = ranking.windows
    dof = max(wins.n_res - wins.W * 2 * wins.n - n_fit, 1)
    fit = _shoot_candidate((res, jac), starts, free, fam, Kc, n_fit, dof)
    if fit is None:
        return None, None
    entry = _candidate_statistics(row, fit, free, n_fit, ranking)
    s, th, converged = fit.s, fit.th, fit.converged
    # a start for the others only where LM converged: a fit stopped by the iteration cap is no optimum to start from
    # (a seismometer's LNN base: its zero law's χ² still falling after 15 iterations; candidates started from it
    # ended, at their own cap, where the pointwise starts ended lower)
    return entry, ((np.asarray(s), np.asarray(th[:Kc])) if converged else None)


def default_threads() -> int:
    """Threads for the candidates' fits: one per core this process may use — but one in a worker of
    :mod:`nnphd.parallel`, which owns a single core (a ``detect`` batch fills the cores with files)."""
    import os

    from nnphd.parallel import default_workers

    return 1 if os.environ.get("NNPHD_WORKER") else default_workers()


def map_in_threads(fn, items: list, threads: int | None = None) -> list:
    """``[fn(x) for x in items]`` on ``threads`` threads (None: :func:`default_threads`): for independent pieces of
    work whose time is spent in compiled XLA programs (or numpy), which run outside Python's global lock. Each piece
    runs the same programs on the same data as one after another: the numbers do not depend on the threads. On an
    error or an interrupt the pieces not started are not started."""
    from concurrent.futures import ThreadPoolExecutor

    from nnphd.parallel import as_here

    threads = min(default_threads() if threads is None else int(threads), len(items))
    if threads <= 1:
        return [fn(x) for x in items]
    with ThreadPoolExecutor(max_workers=threads, thread_name_prefix="nnphd") as ex:
        futures = [ex.submit(as_here(fn), x) for x in items]
        try:
            return [f.result() for f in futures]
        except BaseException:
            ex.shutdown(cancel_futures=True)
            raise


def fit_rows(fit, zero, cands, threads: int | None, choose=None) -> list | None:
    """The ranking entries of the zero law and ``cands`` (``fit(ci, row, warm=…)`` → (entry, warm):
    :func:`_fit_row`; a candidate without an entry left out), or None when the zero law has none — nothing is
    ranked against it then, and the candidates are not fitted. The zero law is fitted first; the candidates start
    from its fit (``warm``; None where it did not converge), side by side on ``threads`` threads (None:
    :func:`default_threads`) — their time is spent in compiled XLA programs, which run outside Python's global lock.
    Each fit runs the same programs on the same data as one after another: the numbers do not depend on the
    threads.

    The candidates are fitted in rounds, the first :data:`FUNNEL_BATCH` of them first; after each round
    ``choose(entries, new, rest)`` (the entries so far, this round's, the candidates not fitted yet as (branch, row)
    in their order) gives the next round, [] to stop (None: the next :data:`FUNNEL_BATCH` until all are fitted).
    The entries are in the order the candidates were fitted."""
    first, warm = fit(0, zero)
    if first is None:
        return None
    out = [first]
    rest = list(enumerate(cands, 1))
    batch = rest[:FUNNEL_BATCH]
    while batch:
        new = map_in_threads(lambda item: fit(*item, warm=warm)[0], batch, threads)
        new = [x for x in new if x is not None]
        out += new
        done = {i for i, _ in batch}
        rest = [x for x in rest if x[0] not in done]
        batch = rest[:FUNNEL_BATCH] if choose is None else list(choose(out, new, rest))
    return out


class Funnel:
    """``choose`` of :func:`fit_rows` for the funnel: ``rank(entries)`` → the table's rows, one per entry in their
    order, judged (:func:`nnphd.explain.table.select_law`). The next :data:`FUNNEL_BATCH` candidates are fitted
    while one of the last round's rows lands within ``reach`` of the lowest IC of an eligible row — eligible or not
    (a row below the winner is named in the verdict's reason); then one last round: the candidates not fitted that
    are special cases of a row within reach (the parsimony rule of :func:`nnphd.explain.table.select_law` may
    prefer one). ``cut``: whether it ended the fits before the shortlist's end."""

    def __init__(self, rank, reach: float) -> None:
        self.rank, self.reach, self.cut = rank, reach, False

    def __call__(self, entries, new, rest) -> list:
        if self.cut or not rest:
            return []
        if not new:
            return rest[:FUNNEL_BATCH]  # nothing in this round could be fitted: it says nothing about the next
        rows = self.rank(entries)
        edge = min((r.ic for r in rows if r.significant), default=-math.inf) + self.reach
        if any(r.ic <= edge for r in rows[len(entries) - len(new) :]):
            return rest[:FUNNEL_BATCH]
        self.cut = True
        near = [r for r in rows if r.ic <= edge]
        return [(i, c) for i, c in rest if any(nested(c, r) for r in near)]


def rank_trajectory(
    table: LawTable,
    motion: Motion,
    *,
    sigma,
    period: float,
    angles=None,
    fc_fn=None,
    windows: WindowPlan = WindowPlan(),
    settings: TrajectorySettings = TrajectorySettings(),
    library_of: LawTable | None = None,
) -> LawTable:
    """Re-fit the pointwise table's best candidates (and the zero law) to the *positions* of ``motion`` by multiple
    shooting and rank them again — for records whose pointwise q̈ is too noisy or biased for the law (see
    :mod:`nnphd.engine.evidence`: windows of ¾ period with free initial states, RK4 at the recorded times).

    The model is the same joint one, q̈ = f_c(q, q̇; α) + g(q, q̇, t; β, θ), with (α, β, θ) started from the
    pointwise fit; held-out error = χ² of contiguous groups of windows predicted by the fit to the others (window
    states re-fitted, linearised at the optimum); uncertainties = window bootstrap (or the model-based error, if
    larger); IC as in :func:`nnphd.explain.laws.rank_laws` with the position residuals. ``fc_fn(q, v)`` (JAX) must reproduce the ``fc``
    given to :func:`nnphd.explain.laws.rank_laws`; ``sigma`` (n,) the position noise.

    ``windows``: how the record is cut (:class:`WindowPlan`); with too few windows and ``allow_in_sample``, a zero
    law that runs away over a whole trajectory is started again from the candidates' conservative fits.
    ``settings``: the shortlist, the funnel's reach, the bootstrap and the threads (:class:`TrajectorySettings`;
    :func:`fit_rows`, :class:`Funnel`); the table's note and ``settings["funnel"]`` say how many families were fitted.
    ``library_of``: a larger table whose rows hold ``table``'s (a sub-table of it): the compiled programs are built
    for all its families, so every sub-table of it runs the same ones (only ``table``'s candidates are fitted).
    """
    if table.settings.get("conservative_extra", 0):
        raise ValueError("a law table fitted with conservative_cols can only be ranked pointwise")
    q_pos, qd, t = (np.asarray(a, float) for a in (motion.q, motion.qd, motion.t))
    N, n = q_pos.shape
    traj = np.zeros(N, int) if motion.traj is None else np.asarray(motion.traj)
    angles = tuple(bool(a) for a in (np.zeros(n, bool) if angles is None else angles))
    segs = trajectory_segments(traj)
    chosen = _choose_windows(segs, t, period, windows)
    if chosen is None:
        return table
    wins, in_sample = chosen
    args, s0, mask, nsub = _window_arrays(wins, t, q_pos, qd, sigma, period)
    W = len(wins)
    G = min(W, 10)
    groups = np.array_split(np.arange(W), G)
    n_res = int(mask.sum()) * n
    Kc = table.settings["conservative_columns"]
    zero = next(r for r in table.rows if r.key == "none")
    cands = [r for r in table.rows if r.key != "none"][: settings.shortlist]  # the table holds one row per family
    alpha0 = table.base.alphas
    # the universal right-hand side holds every family of the table in one fixed order (by key), not the shortlist in
    # the order of this record's pointwise ranking: one compiled program for every record with the same families
    # (``library_of``'s, where a sub-table of it is ranked: the whole-record fits of every tie set share one program)
    held = [r for r in (table if library_of is None else library_of).rows if r.key != "none"]
    held += [r for r in cands if all(r is not h for h in held)]
    library = sorted(held, key=lambda r: (r.key, r.family.k))
    fams = with_sparse_slots([r.family for r in library], n)
    branch = {id(r): next(i for i, f in enumerate(fams, 1) if f is r.family) for r in library}
    slots, P_dir, nl_defaults = parameter_layout(fams, Kc)
    rhs = universal_rhs(fams, Kc, angles, fc_fn, table.settings.get("library", True))
    ranking = _Ranking(
        cands,
        _Layout(slots, P_dir, nl_defaults, alpha0, Kc),
        rhs,
        _Windows(args, s0, nsub, n, W, groups, n_res, in_sample),
        settings,
        table.base.center,
        builtin_speeds(fams)[0],
        sparse_supports(fams),
        fc_parts(fc_fn)[1],
    )

    def fit(ci, row, warm=None):  # the row's branch of the universal right-hand side (0: the zero law)
        return _fit_row(branch[id(row)] if ci else 0, row, ranking=ranking, warm=warm)

    def judged(results):  # the table's rows of these entries, judged (select_law marks the eligible ones)
        rows = _trajectory_rows(results, table.settings, table.base.y_rms, q_pos, qd, t, n_res)[0]
        select_law(rows, 1.0, 1.0, "", {}, base=table.base)
        return rows

    reach = FUNNEL_REACH if settings.reach is None else float(settings.reach)
    # whole trajectories in-sample (a throw, a short drop): the pointwise order of such a record says little about
    # the trajectory-level one (on a 2-D throw the funnel claimed linear drag where the whole shortlist ties it
    # with the true quadratic drag: benchmarks/funnel_audit.py) — every family is fitted
    funnel = None if math.isinf(reach) or in_sample else Funnel(judged, reach)
    results = fit_rows(fit, zero, cands, settings.threads, funnel)
    if results is None or len(results) < 2:  # no zero law, or nothing beside it: the table stands
        return table
    rows, n_eff, tau = _trajectory_rows(results, table.settings, table.base.y_rms, q_pos, qd, t, n_res)
    n_pw, n_fit = sum(r.key != "none" for r in table.rows), len(results) - 1
    kept = f"{n_fit} of the {n_pw} families fitted by shooting" + (
        f" (in the pointwise ranking's order, rounds of {FUNNEL_BATCH} while a round came within ΔIC {reach:g} of"
        " the best eligible, then the special cases of the rows within it; the others out of reach)"
        if funnel is not None and funnel.cut
        else f" (the pointwise ranking's first {len(cands)})"
        if len(cands) < n_pw
        else ""
    )
    return select_law(
        rows,
        n_eff,
        tau,
        (
            f"in-sample fits of {W} whole trajectories (too short for held-out windows; IC with the fit's own error)"
            if in_sample
            else f"{G} held-out groups of shooting windows ({W} windows)"
        )
        + f"; {kept}",
        {
            **table.settings,
            "method": "trajectory",
            "windows": W,
            "in_sample": in_sample,
            "substeps": nsub,
            "pointwise_candidates": [r.to_dict() for r in table.rows],
            "funnel": {
                "pointwise": n_pw,
                "shortlist": len(cands),
                "trajectory": n_fit,
                "reach": None if funnel is None else reach,  # None: every shortlisted family
                "cut": bool(funnel is not None and funnel.cut),
            },
        },
        base=table.base,
    )
