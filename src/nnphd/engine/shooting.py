"""Multiple shooting: the positions fitted window by window by RK4 of q̈ = (1 + c)·f_c − D q̇ with free initial
states; point 2 of :mod:`nnphd.engine.evidence`, which explains the method."""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from nnphd.engine import stored

MIN_WINDOW = 8


MAX_WINDOW = 80


WINDOW_PERIODS = 0.75


class ShootingWindows(NamedTuple):
    """The windows to fit, as JAX arrays (a pytree: traced under jax.jit): ``tw`` (W, L) the times from each window's
    start (a padded row repeats the last time: dt = 0), ``t0w`` (W,) the windows' start times (the model's time is
    t0w + tw), ``qw`` (W, L, n) the positions, ``mask`` (W, L) 1 on a recorded row and 0 on padding, ``inv_sigma``
    (n,) the residuals' weights 1/σ; ``steps`` (optional, an int32 scalar) the steps actually integrated — L − 1 when
    None; with a number the steps beyond it are padding that costs nothing (:func:`_padded_calls`)."""

    tw: jax.Array
    t0w: jax.Array
    qw: jax.Array
    mask: jax.Array
    inv_sigma: jax.Array
    steps: jax.Array | None = None


@dataclass(frozen=True)
class Integrator:
    """The model integrated across every window: q̈ = ``rhs``(theta, q, v, t, aux), by RK4 with ``nsub`` sub-steps
    per sample step. A static argument of the compiled shooting functions (hashable: ``rhs`` by identity), so one
    compiled function serves every call with the same right-hand side and sub-steps."""

    rhs: Callable
    nsub: int


STAT_EPS = 0.01  # LM's statistical stop: what χ² has still to fall, against the reduced χ² (one unit of Δχ²/s²)


@dataclass(frozen=True)
class LMSettings:
    """Levenberg–Marquardt's settings (:func:`lm_windows`): at most ``iters`` iterations, stopping once χ² falls by
    less than ``tol`` of itself; ``mu0`` the first damping (relative to the normal matrix's diagonal), smaller where
    the start is known to be near an optimum.

    ``dof`` > 0 (the residuals less the fitted parameters) adds the statistical stop: once what χ² has still to
    fall — estimated from its last two falls as a geometric series, f·ρ/(1 − ρ), ρ = f/f_prev ≤ 0.95 — is below
    ``eps`` of the reduced χ² (χ²/dof), the fit is where more iterations cannot move anything that is reported:
    every parameter within √(2·eps) ≈ 0.14 of its standard error of the optimum, an information criterion within
    eps. (With tol alone, a double pendulum's candidates spent 3–5 of their 9–12 Jacobians moving χ² by 1e-4 of
    itself — 1e-3 of a standard error.)"""

    iters: int = 20
    tol: float = 1e-8
    mu0: float = 1e-3
    dof: int = 0
    eps: float = STAT_EPS


@dataclass(frozen=True, eq=False)
class ShootingData:
    """What a shooting fit fits: ``q``, ``qd`` (N, n) the positions and the estimated velocities (these only start
    the windows), ``t`` (N,) the times, ``segs`` the rows of each trajectory, ``sigma`` (n,) the position noise and
    ``period`` the oscillation period (it sets the window length)."""

    q: np.ndarray
    qd: np.ndarray
    t: np.ndarray
    segs: Sequence[np.ndarray]
    sigma: Sequence[float]
    period: float


@dataclass(frozen=True)
class ShootingOptions:
    """How a shooting fit measures: ``kinetic_weights`` (n,) the weights of d in d̄ (None: mean q̇_j²),
    ``n_boot`` window-bootstrap replicas drawn from ``seed``, at most ``max_windows`` windows (an evenly spaced
    subset beyond)."""

    kinetic_weights: Sequence[float] | None = None
    n_boot: int = 200
    seed: int = 0
    max_windows: int = 400


def shooting_windows(
    segs,
    t,
    period: float,
    dt_median: float | None = None,
    periods: float = WINDOW_PERIODS,
    max_window: int = MAX_WINDOW,
) -> list[np.ndarray]:
    """Row indices of consecutive windows of ≈ ``periods``·period within each segment (MIN_WINDOW…``max_window``
    samples; a short remainder is merged into the previous window when that stays ≤ max_window, else dropped)."""
    t = np.asarray(t, float)
    if dt_median is None:
        dts = np.concatenate([np.diff(t[s]) for s in segs if len(s) > 1])
        dt_median = float(np.median(dts)) if dts.size else 1.0
    L = periods * period / dt_median if np.isfinite(period) else max_window
    L = int(min(max_window, max(MIN_WINDOW, round(L))))
    wins = []
    for s in segs:
        k = len(s) // L
        if k == 0:
            if len(s) >= MIN_WINDOW:
                wins.append(s)
            continue
        parts = [s[i * L : (i + 1) * L] for i in range(k)]
        rest = s[k * L :]
        if len(rest) >= MIN_WINDOW:
            parts.append(rest)
        elif len(rest) and len(parts[-1]) + len(rest) <= max_window:
            parts[-1] = np.concatenate([parts[-1], rest])
        wins.extend(parts)
    return wins


def rowwise_jvp(f):
    """``f(aux, q, v)`` → (W, …), each row a function of its own row of (q, v) only, with forward derivatives taken
    through the per-row Jacobian ∂f/∂(q, v): computed once per call from 2n directions and applied to every tangent.
    A shooting Jacobian pushes P_loc + P_glob tangent directions through the conservative force (35 for a law ranked
    at trajectory level), all at the same point: JAX's own jvp would differentiate the LNN's Euler–Lagrange solve
    once per direction. Same values, same derivatives (to rounding). ``aux`` is data: its tangent is ignored, so do
    not differentiate with respect to it."""

    @jax.custom_jvp
    def g(aux, q, v):
        return f(aux, q, v)

    @g.defjvp
    def g_jvp(primals, tangents):
        aux, q, v = primals
        _, dq, dv = tangents
        n = q.shape[-1]
        y, lin = jax.linearize(lambda q_, v_: f(aux, q_, v_), q, v)

        def column(e):  # ∂f/∂(q, v)_j of every row: the same unit direction j in every row
            return lin(jnp.broadcast_to(e[:n], q.shape), jnp.broadcast_to(e[n:], v.shape))

        J = jax.vmap(column)(jnp.eye(2 * n, dtype=q.dtype))  # (2n, W, …)
        return y, jnp.einsum("jw...,wj->w...", J, jnp.concatenate([dq, dv], axis=-1))

    return g


def rowwise_combination(f):
    """``g(aux, c, q, v) = Σ_k f(aux, q, v)[..., k] c_k`` — a linear combination of columns ``f`` (W, …, K), each row
    a function of its own row of (q, v) only — with forward derivatives taken through the per-row Jacobian of the
    *combination*: ∂f/∂(q, v) from 2n directions, contracted with c once, applied to every tangent; plus f · dc. A
    shooting Jacobian pushes every direction through it (53 on a double pendulum's 43 conservative columns):
    :func:`rowwise_jvp` of f and then the combination carried each direction's (W, n, K) tangent of the columns,
    this carries its (W, n). The same values; the derivatives to rounding (the sums in another order). ``aux`` is
    data, not differentiated."""

    def combine(cols, c):
        return jnp.einsum("w...k,k->w...", cols, c)

    @jax.custom_jvp
    def g(aux, c, q, v):
        return combine(f(aux, q, v), c)

    @g.defjvp
    def g_jvp(primals, tangents):
        aux, c, q, v = primals
        _, dc, dq, dv = tangents
        n = q.shape[-1]
        cols, lin = jax.linearize(lambda q_, v_: f(aux, q_, v_), q, v)

        def column(e):  # ∂(f·c)/∂(q, v)_j of every row: the same unit direction j in every row
            return combine(lin(jnp.broadcast_to(e[:n], q.shape), jnp.broadcast_to(e[n:], v.shape)), c)

        J = jax.vmap(column)(jnp.eye(2 * n, dtype=q.dtype))  # (2n, W, …)
        dy = jnp.einsum("jw...,wj->w...", J, jnp.concatenate([dq, dv], axis=-1)) + combine(cols, dc)
        return combine(cols, c), dy

    return g


@functools.lru_cache(maxsize=64)
def damping_rhs(accel):
    """q̈ = (1 + θ₀)·f_c(q, q̇) − diag(θ₁…θₙ) q̇ with the conservative model's parameters as ``aux`` (one function
    object per ``accel``, so the shooting fit compiles once per model: every seed of a record, every record of a
    shape in this process; stored for the next process where ``accel`` says what it computes, ``export_key``)."""

    fc = rowwise_jvp(accel)

    def rhs(theta, q, v, t, params):
        return (1.0 + theta[0]) * fc(params, q, v) - theta[1:] * v

    inner = getattr(accel, "export_key", None)
    rhs.export_key = None if inner is None else f"damping|{inner}"
    return rhs


def _residuals_and_jac(params, s, theta, windows: ShootingWindows, model: Integrator):
    """Residuals (W, L, n) of the windows under the damping probe and their forward derivatives along every local
    direction (one direction perturbs the same component of every window's initial state; windows are independent)
    and every global one (see :func:`model_residuals_and_jac`) — by the two programs :func:`_lm` runs (the numbers
    of :func:`model_residuals_and_jac`, bit for bit), so that no third is compiled."""
    return model_residuals(s, theta, params, windows, model), model_jac(s, theta, params, windows, model)


def _solve(A, b):
    """A⁻¹b for one matrix or a stack; least squares where a matrix is singular (a window or parameter the data
    do not constrain)."""
    try:
        return np.linalg.solve(A, b)
    except np.linalg.LinAlgError:
        if A.ndim == 2:
            return np.linalg.lstsq(A, b, rcond=None)[0]
        return np.stack([np.linalg.lstsq(a, bb, rcond=None)[0] for a, bb in zip(A, b)])


def normal_blocks(r, jac, P_loc):
    """Per-window normal-equation blocks from residuals (W, L, n) and forward derivatives (P, W, L, n)."""
    W = r.shape[0]
    R = r.reshape(W, -1)
    J = jac.reshape(jac.shape[0], W, -1)
    Jl, Jg = J[:P_loc], J[P_loc:]
    AtA = np.einsum("iwx,jwx->wij", Jl, Jl)
    AtB = np.einsum("iwx,kwx->wik", Jl, Jg)
    BtB = np.einsum("kwx,lwx->wkl", Jg, Jg)
    Atr = np.einsum("iwx,wx->wi", Jl, R)
    Btr = np.einsum("kwx,wx->wk", Jg, R)
    return AtA, AtB, BtB, Atr, Btr, np.sum(R * R, axis=1)


def schur_complement(AtA, AtB, BtB, Atr, Btr, mu, free):
    """Per-window Schur complements (W, G, G), (W, G) over the free global parameters, and the local solves."""
    _W, P, _ = AtA.shape
    diag = np.einsum("wii->wi", AtA)
    scale = np.maximum(diag.mean(axis=1), 1e-300)[:, None, None]
    damp = AtA + mu * diag[:, :, None] * np.eye(P)[None] + 1e-10 * scale * np.eye(P)[None]
    rhs = np.concatenate([AtB[:, :, free], Atr[:, :, None]], axis=2)
    X = _solve(damp, rhs)
    XB, Xr = X[:, :, :-1], X[:, :, -1]
    S = BtB[:, free][:, :, free] - np.einsum("wik,wil->wkl", AtB[:, :, free], XB)
    g = Btr[:, free] - np.einsum("wik,wi->wk", AtB[:, :, free], Xr)
    return S, g, XB, Xr


def _lm(params, model: Integrator, s, theta, windows: ShootingWindows, free, settings: LMSettings = LMSettings()):
    """Levenberg–Marquardt over window initial states and the free global parameters."""

    def jac(s_, th_):  # at an accepted point: its trial's residuals are kept, the simulation not run again
        return model_jac(s_, th_, params, windows, model)

    def res(s_, th_):
        return model_residuals(s_, th_, params, windows, model)

    return lm_windows(None, s, theta, free, settings, res=res, jac_fn=jac)


def lm_windows(resjac, s, theta, free, settings: LMSettings = LMSettings(), res=None, jac_fn=None, info=None):
    """Levenberg–Marquardt over per-window states ``s`` (W, P_loc) and global parameters ``theta`` (only the ``free``
    ones move); ``resjac(s, theta)`` → residuals (W, L, n) and forward derivatives (P_loc + P_glob, W, L, n). The
    window states are eliminated per step (Schur complement). Returns (s, theta, r, jac, χ²).

    ``res(s, theta)`` → the residuals alone: then a trial step is judged on them and the derivatives are computed
    only where a step is accepted (a third of the trials of the trajectory-level law ranking were rejected, and the
    derivatives cost one simulation per direction). The accepted points, and so the result, are those of the search without it.
    ``jac_fn(s, theta)`` → the derivatives alone (with ``res``; ``resjac`` may then be None): at an accepted point
    the residuals of its trial are kept, and the simulation is not run a second time (a seventh of the time of
    ``resjac``). The numbers are those of ``resjac`` (:func:`model_residuals` and :func:`model_jac` give
    :func:`model_residuals_and_jac`'s, bit for bit: tests/test_speed_equivalence.py). ``settings``: the iterations,
    the tolerance and the first damping (:class:`LMSettings`). ``info``: a dict, given, gets ``converged`` — False
    when the iterations ran out with χ² still falling by more than ``settings.tol``."""
    iters, tol = settings.iters, settings.tol
    P_loc = s.shape[1]
    mu = settings.mu0
    if jac_fn is not None:
        r, jac = np.asarray(res(s, theta)), np.asarray(jac_fn(s, theta))
    else:
        r, jac = (np.asarray(a) for a in resjac(s, theta))
    with np.errstate(over="ignore", invalid="ignore"):  # a start that blows up gives NaN, below
        cost = float(np.sum(r * r))
    if not (np.isfinite(cost) and np.all(np.isfinite(jac))):
        return s, theta, r, jac, float("nan")
    converged = False
    fall = fall_prev = None  # χ²'s last two falls (the statistical stop, :func:`settled`)
    for _ in range(iters):
        AtA, AtB, BtB, Atr, Btr, _ = normal_blocks(r, jac, P_loc)
        improved = False
        for _try in range(8):
            S, g, XB, Xr = schur_complement(AtA, AtB, BtB, Atr, Btr, mu, free)
            Stot = S.sum(0)
            dth_free = -_solve(Stot + mu * np.diag(np.diag(Stot)), g.sum(0)) if free.any() else np.zeros(0)
            ds = -Xr - np.einsum("wik,k->wi", XB, dth_free)
            dth = np.zeros_like(theta)
            dth[free] = dth_free
            s_new, th_new = s + ds, theta + dth
            if res is None:
                r_new, jac_new = (np.asarray(a) for a in resjac(s_new, th_new))
            else:
                r_new, jac_new = np.asarray(res(s_new, th_new)), None
            with np.errstate(over="ignore", invalid="ignore"):  # a step that blows up is rejected below
                c_new = float(np.sum(r_new * r_new))
            if np.isfinite(c_new) and c_new <= cost:
                if jac_new is None and jac_fn is not None:
                    jac_new = np.asarray(jac_fn(s_new, th_new))
                elif jac_new is None:
                    r_new, jac_new = (np.asarray(a) for a in resjac(s_new, th_new))
                    with np.errstate(over="ignore", invalid="ignore"):
                        c_new = float(np.sum(r_new * r_new))
                rel = (cost - c_new) / max(cost, 1e-300)
                fall_prev, fall = fall, cost - c_new
                s, theta, r, jac, cost = s_new, th_new, r_new, jac_new, c_new
                mu = max(mu / 3.0, 1e-9)
                improved = True
                break
            mu *= 10.0
        if not improved or rel < tol or settled(fall, fall_prev, cost, settings):
            converged = True
            break
    if info is not None:
        info["converged"] = converged
    return s, theta, r, jac, cost


def settled(fall, fall_prev, cost: float, settings: LMSettings) -> bool:
    """LM's statistical stop (:class:`LMSettings` ``dof``): what χ² has still to fall after its last two falls
    (a geometric series of ratio ρ = fall/fall_prev, at most 0.95) is below ``eps`` of the reduced χ²."""
    if settings.dof <= 0 or fall is None or fall_prev is None or fall_prev <= 0:
        return False
    rho = min(fall / fall_prev, 0.95)
    return fall * rho / (1.0 - rho) < settings.eps * cost / settings.dof


# RK4's stages as a loop of four (the model is traced once per sub-step, not four times: the trajectory-level law
# fits' Jacobian took 4 s to trace): k_i = f(x + a_i·h·k_{i-1}), x ← x + h/6·Σ b_i k_i — the same operations in the
# same order as the four written out (0·h·k = 0 and 1·k = k exactly)
RK4_A = (0.0, 0.5, 0.5, 1.0)
RK4_B = (1.0, 2.0, 2.0, 1.0)


def _simulate(s, theta, aux, windows: ShootingWindows, model: Integrator):
    """Weighted position residuals (W, L, n) of the windows started at states ``s`` under q̈ = rhs(theta, …)."""
    tw, t0w, qw, mask, inv_sigma, steps = windows
    rhs, nsub = model.rhs, model.nsub
    n = qw.shape[-1]
    q0, v0 = s[:, :n], s[:, n:]

    def f(q, v, tt):
        return v, rhs(theta, q, v, tt, aux)

    def step(carry, x):
        h = x / nsub
        hh = h[:, None]

        def sub(_, c):  # one RK4 sub-step (a loop, not unrolled: the graph stays small to compile)
            q, v, tt = c

            def stage(i, st):  # k_i at the state moved a_i·h along k_{i-1}; the sum Σ b_i k_i kept
                kq, kv, sq, sv = st
                a, b = jnp.asarray(RK4_A, q.dtype)[i], jnp.asarray(RK4_B, q.dtype)[i]
                kq, kv = f(q + a * hh * kq, v + a * hh * kv, tt + a * h)
                return kq, kv, sq + b * kq, sv + b * kv

            zq, zv = jnp.zeros_like(q), jnp.zeros_like(v)
            _, _, sq, sv = jax.lax.fori_loop(0, 4, stage, (zq, zv, zq, zv))
            return q + hh / 6.0 * sq, v + hh / 6.0 * sv, tt + h

        q, v, tt = jax.lax.fori_loop(0, nsub, sub, carry)
        return (q, v, tt), q

    dts = jnp.diff(tw, axis=1).T  # (L-1, W)
    start = (q0, v0, t0w + tw[:, 0])
    if steps is None:
        _, qs = jax.lax.scan(step, start, dts)
    else:  # the first ``steps`` steps, the same operations as the scan's; the buffer's rest (padding) stays zero

        def body(i, c):
            carry, buf = c
            carry, q = step(carry, dts[i])
            return carry, buf.at[i].set(q)

        _, qs = jax.lax.fori_loop(0, steps, body, (start, jnp.zeros((dts.shape[0], *q0.shape), q0.dtype)))
    qs = jnp.concatenate([q0[None], qs], axis=0)
    return (jnp.swapaxes(qs, 0, 1) - qw) * inv_sigma * mask[..., None]


@functools.partial(jax.jit, static_argnames=("model",))
def _model_residuals(s, theta, aux, windows: ShootingWindows, model: Integrator):
    """The residuals of :func:`model_residuals_and_jac` alone: what a trial step of :func:`lm_windows` needs (one
    simulation instead of one per direction)."""
    return _simulate(s, theta, aux, windows, model)


def _jac(s, theta, aux, windows: ShootingWindows, model: Integrator):
    """The forward derivatives (P_loc + P_glob, W, L, n) of :func:`_simulate`'s residuals along every local and
    global direction (see :func:`model_residuals_and_jac`)."""

    def simulate(s, theta):
        return _simulate(s, theta, aux, windows, model)

    P_loc, P_glob = s.shape[1], theta.shape[0]
    ds = jnp.concatenate(
        [
            jnp.broadcast_to(jnp.eye(P_loc, dtype=s.dtype)[:, None, :], (P_loc, *s.shape)),
            jnp.zeros((P_glob, *s.shape), s.dtype),
        ],
        axis=0,
    )
    dth = jnp.concatenate([jnp.zeros((P_loc, P_glob), s.dtype), jnp.eye(P_glob, dtype=s.dtype)], axis=0)
    return jax.vmap(lambda a, b: jax.jvp(simulate, (s, theta), (a, b))[1])(ds, dth)


@functools.partial(jax.jit, static_argnames=("model",))
def _model_residuals_and_jac(s, theta, aux, windows: ShootingWindows, model: Integrator):
    """Like :func:`_residuals_and_jac` for any model q̈ = rhs(theta, q, v, t, aux) (batched over windows; t the
    absolute time: window start ``windows.t0w`` plus the window clock ``windows.tw``; ``aux`` any data the model
    needs, not differentiated — so one compiled function serves many models that differ only in data)."""
    return _simulate_and_jac(s, theta, aux, windows, model)


@functools.partial(jax.jit, static_argnames=("model",))
def _model_jac(s, theta, aux, windows: ShootingWindows, model: Integrator):
    """The forward derivatives of :func:`model_residuals_and_jac` alone: where :func:`lm_windows` has just computed
    the residuals at the point (:func:`model_residuals`, the same numbers), the simulation is not run again."""
    return _jac(s, theta, aux, windows, model)


def _simulate_and_jac(s, theta, aux, windows: ShootingWindows, model: Integrator):
    return _simulate(s, theta, aux, windows, model), _jac(s, theta, aux, windows, model)


_RAW = {"_model_residuals": _simulate, "_model_jac": _jac, "_model_residuals_and_jac": _simulate_and_jac}


# Shape classes of the windows: one compiled program serves every record whose windows fall in the same class, so a
# second file of another length finds the programs of the first in the persistent compilation cache. Windows of the
# grid run WINDOW_CHUNK (16) a call, the last call padded: one program per shooting function for every record (one
# class per multiple of 8 up to 128 windows made the 1-D records' 80 % copies compile their own, 10–30 s; calls of
# 32 and 8 served every record of 40 windows or more but made each record trace and lower two programs per
# function, warm runs included: a video pendulum's warm compiling 12.9 → 23 s). Residuals and derivatives of 100
# and 300 windows in calls of 16: a cheap formula 7.6 and 13.1 ms (calls of 32 and 8: 8.3 and 13.6; one call of
# 104 windows: 4.5 ms for 100 — ~0.5 ms a call), a 64×64 MLP force, as the LNN's f_c in the law fits, 104 and 160
# ms (77 and 150; one call of 104: 128 ms) — timings within ±20 % from run to run. Long windows (whole records,
# more than MAX_WINDOW steps) of fewer than WINDOW_CHUNK run one window a call (padding 2 whole records to 8 windows
# integrated 4× the steps). Steps: the padded steps are not integrated (the program runs the record's own number of
# steps, ``ShootingWindows.steps``, and leaves the rest of its buffer at zero), so they cost memory only: windows of
# the grid (at most MAX_WINDOW steps — set by the period each file and seed estimates, which moved them from 31 to 24
# steps on a 2-D drag record cut to 80 %) are all compiled for MAX_WINDOW steps; whole records run one a call are
# all compiled for 8192 steps (then 4× that, and so on: ~8 MB of derivatives per call), more of them for 128·4^k
# (with classes 2^k and 1.5·2^k an 80 % copy crossed one two times in three: a video pendulum's copy compiled its
# whole-record fits again, 3.4 s of XLA). A padded window is at rest (dt = 0, masked); padded windows and steps are
# cut off before the results are returned, and every real window's numbers are its own (windows are independent),
# so the padding is inert (tests/test_shape_classes.py).
WINDOW_CHUNK = 16
_LONG_STEPS = 128
_ONE_WINDOW_STEPS = 8192


def _steps_bucket(L: int, W: int) -> int:
    if L <= MAX_WINDOW and W > 1:
        return MAX_WINDOW
    k = _ONE_WINDOW_STEPS if W < WINDOW_CHUNK else _LONG_STEPS  # then powers of 4: padded steps cost memory only
    while k < L:
        k *= 4
    return k


def window_shape_class(W: int, L: int) -> tuple[tuple[int, ...], int]:
    """The shape the shooting programs are compiled for, for ``W`` windows of ``L`` steps: (the windows of each
    compiled call, the steps per window) — see the comment above."""
    if W <= 1 or (L > MAX_WINDOW and W < WINDOW_CHUNK):  # whole records: one window a call
        return (1,) * max(W, 1), _steps_bucket(L, W)
    return (WINDOW_CHUNK,) * -(-W // WINDOW_CHUNK), _steps_bucket(L, W)


def _call(fn, s, theta, aux, windows: ShootingWindows, model: Integrator):
    """``fn(s, theta, aux, windows, model)``, one of the three compiled shooting programs — from the program stored
    by an earlier process where the model's right-hand side says what it computes (``export_key``:
    :mod:`nnphd.engine.stored`), else compiled as usual."""
    key = getattr(model.rhs, "export_key", None)
    if key is None:
        return fn(s, theta, aux, windows, model)
    raw = _RAW[fn.__name__]
    return stored.run(fn.__name__, lambda *a: raw(*a, model), f"{key}|nsub={int(model.nsub)}", (s, theta, aux, windows))


def _padded_calls(fn, s, theta, aux, windows: ShootingWindows, model: Integrator, jac_axis: bool):
    """``fn`` (a compiled shooting program) over ``windows`` padded to their shape class and called once per chunk
    of it; the outputs cut back to the real windows and steps (residuals (W, L, n), or with ``jac_axis`` the
    derivatives (P, W, L, n), or both)."""
    tw, t0w, qw, mask, inv_sigma, _ = windows
    W, L = int(tw.shape[0]), int(tw.shape[1])
    chunks, Lb = window_shape_class(W, L)
    Wb = sum(chunks)
    steps = jnp.asarray(L - 1, jnp.int32)  # the padded steps are not integrated
    if (Wb, Lb) == (W, L) and len(chunks) == 1:
        return _call(fn, s, theta, aux, windows._replace(steps=steps), model)
    tw, t0w, qw, mask, s = (np.asarray(a) for a in (tw, t0w, qw, mask, s))
    tw_p = np.empty((Wb, Lb), tw.dtype)
    tw_p[:W, :L] = tw
    tw_p[:W, L:] = tw[:, -1:]  # a padded step: dt = 0, the state stays put
    tw_p[W:] = tw[-1, -1]  # a padded window: at rest
    t0_p = np.concatenate([t0w, np.repeat(t0w[-1:], Wb - W)])
    qw_p = np.zeros((Wb, Lb, qw.shape[2]), qw.dtype)
    qw_p[:W, :L] = qw
    mask_p = np.zeros((Wb, Lb), mask.dtype)
    mask_p[:W, :L] = mask
    s_p = np.concatenate([s, np.repeat(s[-1:], Wb - W, axis=0)])
    parts, i = [], 0
    for c in chunks:
        win = ShootingWindows(tw_p[i : i + c], t0_p[i : i + c], qw_p[i : i + c], mask_p[i : i + c], inv_sigma, steps)
        parts.append(_call(fn, s_p[i : i + c], theta, aux, win, model))
        i += c

    def cut(arrays, ax):
        whole = np.concatenate([np.asarray(a) for a in arrays], axis=ax) if len(arrays) > 1 else np.asarray(arrays[0])
        return whole[:, :W, :L] if ax == 1 else whole[:W, :L]

    if isinstance(parts[0], tuple):
        return cut([p[0] for p in parts], 0), cut([p[1] for p in parts], 1)
    return cut(parts, 1 if jac_axis else 0)


def model_residuals(s, theta, aux, windows: ShootingWindows, model: Integrator):
    """The residuals of :func:`model_residuals_and_jac` alone: what a trial step of :func:`lm_windows` needs (one
    simulation instead of one per direction). Compiled per shape class of the windows (:func:`window_shape_class`)."""
    return _padded_calls(_model_residuals, s, theta, aux, windows, model, False)


def model_jac(s, theta, aux, windows: ShootingWindows, model: Integrator):
    """The forward derivatives of :func:`model_residuals_and_jac` alone: where :func:`lm_windows` has just computed
    the residuals at the point (:func:`model_residuals`, the same numbers), the simulation is not run again."""
    return _padded_calls(_model_jac, s, theta, aux, windows, model, True)


def model_residuals_and_jac(s, theta, aux, windows: ShootingWindows, model: Integrator):
    """Residuals (W, L, n) and their forward derivatives (P_loc + P_glob, W, L, n) for any model
    q̈ = rhs(theta, q, v, t, aux), batched over windows (see :func:`_model_residuals_and_jac`); compiled per shape
    class of the windows (:func:`window_shape_class`), the padding cut off."""
    return _padded_calls(_model_residuals_and_jac, s, theta, aux, windows, model, False)


def pad_windows(wins, t, q, x0):
    W = len(wins)
    L = max(len(w) for w in wins)
    n = q.shape[1]
    tw = np.empty((W, L))
    qw = np.zeros((W, L, n))
    mask = np.zeros((W, L))
    for i, w in enumerate(wins):
        m = len(w)
        tw[i, :m] = t[w]
        tw[i, m:] = t[w][-1]  # dt = 0: the state stays put
        qw[i, :m] = q[w]
        mask[i, :m] = 1.0
    s0 = np.concatenate([x0[0][[w[0] for w in wins]], x0[1][[w[0] for w in wins]]], axis=1)
    return tw, qw, mask, s0


def shooting_fit(accel, params, data: ShootingData, options: ShootingOptions = ShootingOptions()) -> dict:
    """See :func:`shooting_fit_on_windows`; a fit that cannot be carried out (the model's trajectories leave the finite
    numbers, singular normal equations) or that collapses (:func:`collapsed`) is reported as ``valid: False`` with
    the reason, never raised. Such a fit is tried again on windows half and a quarter as long (on chaotic motion a
    window long against the Lyapunov time makes the fit ill-posed: nearby states part exponentially); the
    result says which length was used (``window_periods``) and why the longer ones failed (``fallbacks``)."""
    tried = []
    for periods in (WINDOW_PERIODS, WINDOW_PERIODS / 2, WINDOW_PERIODS / 4):
        try:
            with np.errstate(all="ignore"):
                out = shooting_fit_on_windows(accel, params, data, options, periods)
        except (np.linalg.LinAlgError, FloatingPointError, ValueError) as e:
            out = {"valid": False, "reason": f"the shooting fit failed ({e.__class__.__name__}: {e})"}
        out["window_periods"], out["fallbacks"] = periods, list(tried)
        if out.get("valid") or out.get("n_windows", 3) < 3:
            return out
        tried.append(f"windows of {periods:g} period: {out.get('reason', 'not valid')}")
    return out


COLLAPSE_REL = 1e-9  # a damping known better than this share of 1/period, or moved less: a degenerate fit


def collapsed(d, se_d_mean: float, d_start, period: float) -> str | None:
    """Why a fitted damping is no measurement, or None: it did not move from its start (LM took no step that
    lowered χ²) or its standard error is below :data:`COLLAPSE_REL` / period — no record of positions tells a damping
    rate to 1e-9 of its inverse period; such an error comes from a Jacobian blown up by chaotic windows (a real
    double pendulum gave d = 2e-21 ± 1.3e-12), not from the data."""
    scale = COLLAPSE_REL / (period if np.isfinite(period) and period > 0 else 1.0)
    if np.all(np.abs(np.asarray(d, float) - np.asarray(d_start, float)) <= scale):
        return "the shooting fit made no progress (the damping did not move from its start): not converged"
    if not se_d_mean > scale:
        rel = se_d_mean * scale / COLLAPSE_REL
        return f"the shooting fit collapsed (the damping's standard error {rel:.2g} of 1/period: a degenerate fit)"
    return None


def _device_windows(tw, qw, mask, inv_sigma) -> ShootingWindows:
    """The padded windows as JAX arrays, every window's clock starting at 0 (the damping probe is autonomous)."""
    tw = np.asarray(tw)  # device_put, not jnp.asarray: no small program compiled per number of windows
    return ShootingWindows(*jax.device_put((tw, np.zeros(tw.shape[0], tw.dtype), qw, mask, inv_sigma)))


def shooting_fit_on_windows(
    accel, params, data: ShootingData, options: ShootingOptions, periods: float = WINDOW_PERIODS
):
    """Multiple-shooting fit of q̈ = (1 + c) f_c(q, q̇) − diag(d) q̇ to the positions (see the module docstring).

    ``accel(params, q, qd)`` is the conservative model (batched, JAX); ``data`` the positions, velocities, times,
    trajectories, position noise and period (:class:`ShootingData`); ``options`` the weights of d in d̄, the
    bootstrap and the window cap (:class:`ShootingOptions`); ``periods`` the window length in periods. Returns the
    fitted ``c``, ``d`` (n,), ``d_mean`` (= d̄), their standard errors (``se_*``: max of jackknife over groups of
    windows and model-based), ``z`` = d̄/se(d̄), the χ² with and without d (``chi2``, ``chi2_conservative``;
    positions weighted by sigma), the window count and length, and ``bootstrap_z`` (d̄ of window-bootstrap replicas
    over se(d̄)).
    """
    segs, sigma, period = data.segs, data.sigma, data.period
    q = np.asarray(data.q, float)
    qd = np.asarray(data.qd, float)
    t = np.asarray(data.t, float)
    n = q.shape[1]
    wins = shooting_windows(segs, t, period, periods=periods)
    if len(wins) > options.max_windows:  # evenly spaced subset: bounded cost on very long records
        keep = np.unique(np.linspace(0, len(wins) - 1, options.max_windows).round().astype(int))
        wins = [wins[i] for i in keep]
    out = {"valid": False, "n_windows": len(wins)}
    if len(wins) < 3:
        out["reason"] = f"only {len(wins)} shooting windows"
        return out
    sig = np.asarray(sigma, float)
    spread = np.array([np.ptp(q[:, j]) for j in range(n)])
    sig = np.maximum(sig, 1e-3 * np.maximum(spread, 1e-12))
    tw, qw, mask, s0 = pad_windows(wins, t, q, (q, qd))
    tw = tw - tw[:, :1]  # each window on its own clock (the model is autonomous)
    dtmax = float(np.max(np.diff(tw, axis=1)))
    vmax = float(np.max(np.abs(qd)) / max(np.min(spread), 1e-12))
    nsub = int(min(8, max(1, math.ceil(dtmax * max(vmax, 2 * math.pi / period if np.isfinite(period) else 0) / 0.3))))
    inv_sigma = 1.0 / sig
    windows, model = _device_windows(tw, qw, mask, inv_sigma), Integrator(damping_rhs(accel), nsub)
    theta0 = np.zeros(1 + n)
    r0, j0 = (np.asarray(a) for a in _residuals_and_jac(params, s0, theta0, windows, model))
    bad = ~(np.all(np.isfinite(r0), axis=(1, 2)) & np.all(np.isfinite(j0), axis=(0, 2, 3)))
    out["dropped_windows"] = int(bad.sum())
    if bad.any():  # windows where the conservative model leaves the finite numbers from the data's start
        if (~bad).sum() < 3:
            out["reason"] = "the conservative model's trajectories leave the finite numbers in almost every window"
            return out
        wins = [w_ for w_, b in zip(wins, bad) if not b]
        tw, qw, mask, s0 = (a[~bad] for a in (tw, qw, mask, s0))
        windows = _device_windows(tw, qw, mask, inv_sigma)
    free_c = np.array([True] + [False] * n)
    free_all = np.ones(1 + n, dtype=bool)
    dof = int(mask.sum()) * n - len(wins) * 2 * n  # LM's statistical stop (LMSettings), less the parameters below
    s_c, th_c, _, _, chi2_c = _lm(params, model, s0, theta0, windows, free_c, LMSettings(dof=max(dof - 1, 1)))
    _s, th, r, jac, chi2 = _lm(params, model, s_c, th_c, windows, free_all, LMSettings(dof=max(dof - 1 - n, 1)))
    if not (np.isfinite(chi2) and np.all(np.isfinite(jac))):
        out["reason"] = "the conservative model's trajectories leave the finite numbers in some window"
        return out
    AtA, AtB, BtB, Atr, Btr, _ = normal_blocks(r, jac, 2 * n)
    S, g, _, _ = schur_complement(AtA, AtB, BtB, Atr, Btr, 0.0, free_all)
    Stot = S.sum(0)
    n_res = int(mask.sum()) * n
    n_par = len(wins) * 2 * n + 1 + n
    s2 = chi2 / max(n_res - n_par, 1)
    cov_model = s2 * np.linalg.pinv(Stot)
    W = len(wins)
    G = min(W, 20)
    groups = np.array_split(np.arange(W), G)
    reps = []
    for grp in groups:
        Sg, gg = S[grp].sum(0), g[grp].sum(0)
        reps.append(th + _solve(Stot - Sg, gg))
    reps = np.asarray(reps)
    # jackknife variance (G-1)/G Σ (θ_(g) − θ̄)²; np.cov with bias=True divides by G
    cov_jack = (G - 1) * np.cov(reps.T, bias=True) if G > 1 else np.zeros_like(Stot)
    w = np.mean(qd**2, axis=0) if options.kinetic_weights is None else np.asarray(options.kinetic_weights, float)
    w = w / w.sum() if w.sum() > 0 else np.full(n, 1.0 / n)
    a = np.concatenate([[0.0], w])  # d̄ = a·θ
    var_model = float(a @ cov_model @ a)
    var_jack = float(a @ cov_jack @ a)
    se_mean = math.sqrt(max(var_model, var_jack, 1e-300))
    se_d = np.sqrt(np.maximum(np.diag(cov_model), np.diag(cov_jack)))
    d_mean = float(a @ th)
    rng = np.random.default_rng(options.seed)
    zb = []
    for _ in range(options.n_boot):
        idx = rng.integers(0, W, W)
        Sb, gb = S[idx].sum(0), g[idx].sum(0)
        thb = th - _solve(Sb, gb)
        zb.append(float(a @ thb) / se_mean)
    why = collapsed(th[1:], se_mean, th_c[1:], period)
    if why is not None:
        out["reason"] = why
        return out
    out.update(
        valid=bool(np.isfinite(chi2) and np.all(np.isfinite(th))),
        c=float(th[0]),
        d=th[1:].tolist(),
        d_mean=d_mean,
        se_c=float(se_d[0]),
        se_d=se_d[1:].tolist(),
        se_d_mean=se_mean,
        se_d_mean_model=math.sqrt(max(var_model, 0.0)),
        se_d_mean_jackknife=math.sqrt(max(var_jack, 0.0)),
        z=d_mean / se_mean,
        chi2=float(chi2),
        chi2_conservative=float(chi2_c),
        n_residuals=n_res,
        reduced_chi2=float(s2),
        window_samples=int(max(len(w_) for w_ in wins)),
        window_median_samples=int(np.median([len(w_) for w_ in wins])),
        substeps=nsub,
        weights=w.tolist(),
        bootstrap_z=zb,
        jackknife_groups=G,
        rms_residual=(np.sqrt(np.sum((r * sig) ** 2, axis=(0, 1)) / mask.sum())).tolist(),
    )
    return out
