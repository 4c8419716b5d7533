r"""A stuck phase as evidence about the law of friction.

A body at rest off its equilibrium — q̇ = q̈ = 0 where the conservative force f_c(q) is not zero — is held there by a
force that does not vanish at zero speed: dry (Coulomb) friction's static part. Viscous friction, quadratic drag, a
Rayleigh or van der Pol term all vanish at q̇ = 0, so under any of them the body would start again towards its
equilibrium and oscillate about it: a law without a dry term cannot be the law of such a record, whatever its fit of
the swings. Measured: a dry-friction look-alike that rests its last 2.3 s 0.015 rad off the equilibrium bars viscous +
quadratic, Rayleigh and van der Pol candidates (z 6–9); a real servo drop resting 0.007 rad from the equilibrium its
swings imply bars nothing — with one drop of three periods that equilibrium is known to ±0.009 rad (z 0.8).

Rule (:func:`stuck_contradictions`): each candidate's joint trajectory-level fit gives its conservative force
f_c(q; α̂) with a covariance of α̂ (widened by the residuals' correlation time τ). A candidate whose law has no term
that stays finite as q̇ → 0 (no sign(q̇)) is contradicted by a stuck stretch at q_s when

- its conservative force there is significant: |f_c(q_s)| ≥ :data:`Z_STUCK`·se, and
- the offset from its equilibrium, |f_c(q_s)| / |∂f_c/∂q|, is at least :data:`OFFSET_MIN` rest tolerances (the
  tolerance by which the rest detector calls a stretch still: 1.5 σ + ½ quantization step) — so that the motion the
  candidate predicts from there would have been seen.

Only a rest that ends its trajectory counts (a body held before its release, or one that moves again, was held or
pushed from outside), only near a stable equilibrium of the fit (∂f_c/∂q < 0: a uniform field or a hilltop says
nothing), and only for oscillating records (``nnphd.explain.search.find_law``). A contradicted candidate is not
eligible; the stuck stretch and the force each candidate leaves unbalanced are in its row (``stuck``). Candidates with a dry term are not judged by their μ against the force at rest: static friction
may exceed the sliding friction the fit measures. One coordinate only (the rest positions are points on a line).

A second rule (:func:`stop_contradictions`) needs no offset: *a swing that stops for good*. Under a law without a dry
term an oscillation never ends (viscous friction lets it fade exponentially, quadratic drag as 1/t); dry friction
stops it in finite time within its dead band. From the last turning point before a final rest, each such candidate
is integrated on into the rest; it is contradicted when the swing it predicts there is :data:`STOP_MIN` times what was
measured (and the rest tolerance), beyond :data:`Z_STUCK` times its spread over draws of its coefficients. Measured on
the real servo drop (one drop, still from t = 2.2 s, 0.007 rad from its fitted equilibrium): from the last turning
point (t = 1.9 s, −0.061 rad) the viscous law predicts a swing of std 0.012 ± 0.002 rad over the next 0.46 s, where
the record moves 0.0014: viscous, quadratic, Rayleigh and van der Pol candidates are barred and viscous + dry friction
(the reference's two necessary terms) leads.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from nnphd.explain.trajectory import Motion

__all__ = [
    "OFFSET_MIN",
    "STOP_MIN",
    "Z_STUCK",
    "StopSettings",
    "bar_stuck",
    "holds_at_rest",
    "stop_contradictions",
    "stuck_contradictions",
]

Z_STUCK = 3.0
OFFSET_MIN = 3.0
STOP_MIN = 3.0  # the swing a law predicts into a final rest: at least this many rest tolerances (std) to contradict
N_DRAWS = 256  # draws of a candidate's coefficients for the spread of its predicted swing


@dataclass(frozen=True)
class StopSettings:
    """How a stop is judged (:func:`stop_contradictions`): the coefficients' draws are seeded with ``seed``, the
    rest window is ``window_periods`` periods long (the rest detector's), and the rests' integrations run side by
    side on ``threads`` threads (None: one per core, :func:`nnphd.explain.trajectory.default_threads`)."""

    seed: int = 0
    window_periods: float = 0.5
    threads: int | None = None


def holds_at_rest(row) -> bool:
    """Whether a law has a term that stays finite as q̇ → 0: a dry term (sign(q̇) among its family's terms or in its
    formula — a user's law)."""
    terms = row.family.terms if row.family is not None else ()
    return any("sign(" in x for x in terms) or any("sign(" in f for f in row.formula.values())


def stuck_contradictions(table, stretches, *, angles, fc_fn=None) -> dict:
    """{family key: {"q", "force", "se", "offset", "tolerance", "seconds"}} for the candidates of a trajectory-level
    ``table`` (one coordinate) that a stuck stretch contradicts (see the module docstring). ``stretches``: dicts with
    "q" (the mean position, (n,)), "seconds" (its duration) and "tolerance" (the rest tolerance, (n,));
    ``fc_fn(q, v)`` (JAX) the conservative force the table was fitted beside, if any."""
    from nnphd.explain.conservative import conservative_basis

    settings = table.settings
    if settings.get("method") != "trajectory" or not stretches or len(settings.get("names", [])) != 1:
        return {}
    center, library = (table.base.center if table.base is not None else None), settings.get("library", True)

    def columns(q):  # (n, Kc) conservative columns at the positions q (1, n), at rest
        q = np.asarray(q, float).reshape(1, -1)
        v = np.zeros_like(q)
        fc = None if fc_fn is None else np.asarray(fc_fn(q, v), float).reshape(1, -1)
        return np.asarray(conservative_basis(np, q, v, angles, fc, center, library), float)[0]

    at = []  # per stretch: the columns at the rest and their slope (the same for every row)
    for s in stretches:
        qs = np.asarray(s["q"], float).reshape(-1)
        tol = float(np.asarray(s["tolerance"], float).reshape(-1)[0])
        h = max(1e-4 * max(abs(qs[0]), 1.0), tol)
        at.append((s, qs, tol, columns(qs)[0], (columns(qs + h)[0] - columns(qs - h)[0]) / (2 * h)))
    out = {}
    for r in table.rows:
        a, cov = r.conservative, r.conservative_cov
        if r.family is None or a is None or cov is None or holds_at_rest(r):
            continue
        for s, qs, tol, B, dB in at:
            if len(B) != len(a):
                continue
            force, slope = float(B @ a), float(dB @ a)
            se = float(np.sqrt(max(B @ cov @ B, 0.0)))
            if not slope < 0:  # no stable equilibrium nearby (a uniform field, a hilltop): nothing to say
                continue
            offset = abs(force / slope)
            if abs(force) >= Z_STUCK * se and offset >= OFFSET_MIN * tol:
                out[r.key] = {
                    "q": float(qs[0]),
                    "force": force,
                    "se": se,
                    "offset": float(offset),
                    "tolerance": tol,
                    "seconds": float(s["seconds"]),
                }
                break
    return out


def _draws(mean, cov, rng, n: int) -> np.ndarray:
    """(n, K) normal draws (the mean alone where the covariance is missing or not finite)."""
    mean = np.asarray(mean, float)
    if cov is None or not np.all(np.isfinite(cov)):
        return np.repeat(mean[None], n, axis=0)
    w, V = np.linalg.eigh(0.5 * (np.asarray(cov, float) + np.asarray(cov, float).T))
    return mean[None] + (rng.standard_normal((n, len(mean))) * np.sqrt(np.maximum(w, 0.0))) @ V.T


def _compiled(fc_fn):
    """``fc_fn`` compiled (``jax.jit``), or None: :func:`_integrator` calls it four times a step on one batch shape,
    and called as it comes — an LNN's f_c, a hundred JAX operations each dispatched on its own — those calls were
    most of a stop's cost (130 ms each: 58 s of 60 on a dry-friction look-alike ending in three rests)."""
    if fc_fn is None:
        return None
    import jax

    return jax.jit(fc_fn)


def _integrator(rows, A, B, fc_fn, angles, center, library, max_steps: int):
    """``run(q0, t0, h, steps)`` → x (max_steps + 1, len(rows)·N_DRAWS), rows past ``steps`` NaN: each candidate's
    joint fit, with its coefficient draws ``A`` (conservative) and ``B`` (law), integrated from rest at q0 (time t0)
    by ``steps`` RK4 steps of h — all draws of all candidates as one batch, the whole integration one compiled
    program (compiled once for all the rests of a record: ``steps`` is data). In numpy, step by step, it was most
    of the stage: 8.9 s of a dry-friction look-alike's 43 s. The record's numbers — the draws, the families'
    parameters and speeds, the sparse laws' supports, the conservative centre and the trained force's parameters —
    are arguments of the program, not constants of it, and its steps are compiled for a power of two: a second
    record with the same candidates runs the program the first compiled (a servo drop's 80 % copy compiled it
    again, 1.6 s of XLA)."""
    import jax
    import jax.numpy as jnp

    from nnphd.explain.conservative import conservative_basis
    from nnphd.explain.families import sparse_index
    from nnphd.explain.trajectory import builtin_speeds, families_of_data, fc_parts, is_sparse

    fams = [r.family for r in rows]
    M = len(rows) * N_DRAWS
    cap = max(64, 1 << (int(max_steps) - 1).bit_length())  # the steps' class: a power of two, at least 64
    v_rms = builtin_speeds(fams)[0]
    apply, fc_params = fc_parts(fc_fn)
    fc_plain = None if apply is not None else _compiled(fc_fn)  # a plain function: its numbers stay constants
    supports = [tuple(jnp.asarray(a) for a in sparse_index(f.spec["support"])) for f in fams if is_sparse(f)]
    data = (
        [jnp.asarray(np.asarray(r.theta, float)) for r in rows],
        [jnp.asarray(a) for a in A],
        [jnp.asarray(b) for b in B],
        None if center is None else jnp.asarray(np.asarray(center, float)),
        None if v_rms is None else jnp.asarray(np.asarray(v_rms, float)),
        supports,
        fc_params,
    )

    def force(x, v, tt, data):
        thetas, A_j, B_j, centre, speeds, sparse, params = data
        fc = None
        if apply is not None:
            fc = jnp.reshape(apply(params, x, v), x.shape)
        elif fc_plain is not None:
            fc = jnp.reshape(fc_plain(x, v), x.shape)
        C = conservative_basis(jnp, x, v, angles, fc, centre, library)
        out = []
        for i, fam in enumerate(families_of_data(fams, 1, speeds, sparse)):
            sl = slice(i * N_DRAWS, (i + 1) * N_DRAWS)
            f = jnp.einsum("dk,dk->d", C[sl, 0], A_j[i])[:, None]
            f = f + jnp.einsum("dnk,dk->dn", fam.basis(jnp, thetas[i], x[sl], v[sl], tt[sl]), B_j[i])
            if fam.fixed is not None:
                f = f + fam.fixed(jnp, thetas[i], x[sl], v[sl], tt[sl])
            out.append(f)
        return jnp.concatenate(out, axis=0)

    @jax.jit
    def run(q0, t0, h, steps, data):
        x = jnp.full((M, 1), q0)
        v = jnp.zeros((M, 1), x.dtype)
        xs = jnp.full((cap + 1, M), jnp.nan, x.dtype).at[0].set(x[:, 0])

        def step(k, c):
            x, v, xs = c
            tt = jnp.full(M, t0 + k * h)
            k1v, k1x = force(x, v, tt, data), v
            k2v, k2x = force(x + h / 2 * k1x, v + h / 2 * k1v, tt + h / 2, data), v + h / 2 * k1v
            k3v, k3x = force(x + h / 2 * k2x, v + h / 2 * k2v, tt + h / 2, data), v + h / 2 * k2v
            k4v, k4x = force(x + h * k3x, v + h * k3v, tt + h, data), v + h * k3v
            x = x + h / 6 * (k1x + 2 * k2x + 2 * k3x + k4x)
            v = v + h / 6 * (k1v + 2 * k2v + 2 * k3v + k4v)
            return x, v, xs.at[k + 1].set(x[:, 0])

        return jax.lax.fori_loop(0, steps, step, (x, v, xs))[2]

    return lambda q0, t0, h, steps: run(q0, t0, h, steps, data)


def _steps(t0: float, t1: float, period: float) -> int:
    """RK4 steps from t0 to t1: 100 a period."""
    return max(int(np.ceil((t1 - t0) / (period / 100))), 1)


def _integrate(run, q0: float, t0: float, t1: float, period: float):
    """(grid (S,), x (S, len(rows)·N_DRAWS)): ``run`` (:func:`_integrator`) from rest at q0 (time t0) to t1; RK4,
    100 steps a period."""
    steps = _steps(t0, t1, period)
    h = (t1 - t0) / steps
    xs = np.asarray(run(float(q0), float(t0), float(h), steps), float)[: steps + 1]
    return t0 + h * np.arange(steps + 1), xs


def stop_contradictions(
    table,
    stretches,
    motion: Motion,
    period: float,
    *,
    angles,
    fc_fn=None,
    stop: StopSettings = StopSettings(),
) -> dict:
    r"""{family key: {"kind": "stop", …}} for the candidates of a trajectory-level ``table`` (one coordinate) without
    a dry term that a *finite-time stop* contradicts: the record swings, then rests for good, where the candidate
    predicts the swing going on.

    Viscous friction, quadratic drag and their kin only slow a swing down — under them an oscillation never ends
    (its amplitude falls exponentially or as 1/t); dry friction stops it within a dead band. So from the last turning
    point before a rest that ends its trajectory (q̇ = 0 there; the last one at least :data:`STOP_MIN` rest
    tolerances from the rest), each candidate's joint fit (its conservative force and its law, the coefficients
    drawn :data:`N_DRAWS` times from their covariances — τ-widened for the conservative part, the cross-covariance
    neglected) is integrated over the first rest window (``stop.window_periods`` of the period: the rest detector's);
    the candidate is contradicted when the standard deviation of its predicted motion there, less :data:`Z_STUCK`
    times its spread over the draws, is still :data:`STOP_MIN` times the measured one (at least the rest tolerance:
    a swing hidden below the noise or the encoder's steps is not missed motion). The true law predicts what was
    measured; a law that cannot stop a swing predicts a swing where the record is still.

    ``stretches``: dicts with "t0" (start), "traj" (its trajectory id), "seconds", "tolerance" (n,) (from
    ``nnphd.explain.search.moving_rows``); ``motion``: the whole record, rests included (its trajectory ids given);
    ``fc_fn(q, v)`` the conservative force the table was fitted beside, if any. Seeded draws (``stop.seed``):
    reproducible. The rests' integrations run side by side on ``stop.threads`` threads, with the same numbers
    whatever the number (:class:`StopSettings`)."""
    settings = table.settings
    if (
        settings.get("method") != "trajectory"
        or not stretches
        or len(settings.get("names", [])) != 1
        or not np.isfinite(period)
    ):
        return {}
    rows = [
        r
        for r in table.rows
        if r.family is not None
        and r.conservative is not None
        and r.conservative_cov is not None
        and r.beta is not None
        and not holds_at_rest(r)
    ]
    if not rows:
        return {}
    center, library = (table.base.center if table.base is not None else None), settings.get("library", True)
    seed, window_periods, threads = stop.seed, stop.window_periods, stop.threads
    N = len(motion.t)
    q, qd, t, traj = (np.asarray(a, float).reshape(N, -1) for a in (motion.q, motion.qd, motion.t, motion.traj))
    t, traj, q, qd = t[:, 0], traj[:, 0], q[:, 0], qd[:, 0]
    rng = np.random.default_rng(seed)
    A = [_draws(r.conservative, r.conservative_cov, rng, N_DRAWS) for r in rows]
    B = [_draws(r.beta, r.cov, rng, N_DRAWS) for r in rows]
    swings = [(s, w) for s in stretches if (w := _last_swing(s, q, qd, t, traj, period, window_periods)) is not None]

    if not swings:
        return {}
    max_steps = max(_steps(w["ends"][1], w["ends"][2], period) for _, w in swings)
    run = _integrator(rows, A, B, fc_fn, (bool(angles[0]),), center, library, max_steps)

    def integrate(swing):
        _, w = swing
        return _integrate(run, *w["ends"], period)

    from nnphd.explain.trajectory import map_in_threads

    # the first compiles the program; the others run it side by side
    ends = [integrate(swings[0]), *map_in_threads(integrate, swings[1:], threads)]
    out = {}
    for (s, w), (grid, xs) in zip(swings, ends):
        _judge_stop(rows, s, w, window_std(grid, xs, s["t0"]), out)
    return out


def window_std(grid, xs, t0: float) -> np.ndarray:
    """The std over the rest window (``grid`` ≥ ``t0``) of each draw's predicted motion ``xs`` (steps, draws): NaN,
    without a RuntimeWarning on the user's console, for a draw that ran away (inf or NaN on the way; :func:`_judge_stop`
    skips those)."""
    x = np.asarray(xs)[np.asarray(grid) >= t0]
    with np.errstate(invalid="ignore", over="ignore"):
        out = np.std(x, axis=0)
    return np.where(np.all(np.isfinite(x), axis=0), out, np.nan)


def _last_swing(s, q, qd, t, traj, period: float, window_periods: float) -> dict | None:
    """The last swing into the rest ``s`` (:func:`stop_contradictions`; q, qd, t, traj of one coordinate, the whole
    record): {"tol", "q_rest", "j" (the row of its last turning point), "measured" (the std over the rest window, at
    least the tolerance), "window" (its length), "ends" (q and t at the turn, the window's last time)}, or None when
    too few rows precede the rest or lie in its window, or no turning point is far enough from the rest."""
    tol = float(np.asarray(s["tolerance"], float).reshape(-1)[0])
    seg = np.flatnonzero(traj == s["traj"])
    before, rest = seg[t[seg] < s["t0"]], seg[t[seg] >= s["t0"]]
    window = min(window_periods * period, float(s["seconds"]))
    rest = rest[t[rest] <= s["t0"] + window]
    if len(before) < 3 or len(rest) < 3:
        return None
    q_rest = float(np.mean(q[rest]))
    turns = [
        j
        for j in before[1:]
        if qd[j - 1] * qd[j] <= 0 and abs(q[j] - q_rest) >= STOP_MIN * tol and s["t0"] - t[j] <= period
    ]
    if not turns:
        return None
    j = turns[-1]
    measured = max(float(np.std(q[rest])), tol)
    ends = (float(q[j]), float(t[j]), float(t[rest[-1]]))
    return {"tol": tol, "q_rest": q_rest, "j": j, "measured": measured, "window": window, "ends": ends}


def _judge_stop(rows, s, w: dict, stds, out: dict) -> None:
    """Add to ``out`` the ``rows`` not in it yet that the rest ``s`` contradicts (:func:`stop_contradictions`): w
    its last swing (:func:`_last_swing`), ``stds`` (len(rows)·N_DRAWS,) the std of each draw's predicted motion over
    the rest window."""
    for i, r in enumerate(rows):
        if r.key in out:
            continue
        d = stds[i * N_DRAWS : (i + 1) * N_DRAWS]
        if np.mean(np.isfinite(d)) < 0.9:  # the fit runs away from the turning point: nothing to judge
            continue
        d = d[np.isfinite(d)]
        m, sd = float(np.mean(d)), float(np.std(d))
        if m - Z_STUCK * sd >= STOP_MIN * w["measured"]:
            out[r.key] = {
                "kind": "stop",
                "q": float(w["q_rest"]),
                "t_turn": w["ends"][1],
                "q_turn": w["ends"][0],
                "t_rest": float(s["t0"]),
                "predicted_std": m,
                "se": sd,
                "measured_std": w["measured"],
                "tolerance": w["tol"],
                "window": float(w["window"]),
                "seconds": float(s["seconds"]),
            }


def bar_stuck(table, contradicted: dict):
    """``table`` with the ``contradicted`` families (:func:`stuck_contradictions`) not eligible, ranked again (a
    candidate the amplitude envelope preferred that is contradicted bars nothing); unchanged when none is."""
    from nnphd.explain.envelope import blocked_by_disagreement
    from nnphd.explain.table import select_law

    if not contradicted or not any(r.key in contradicted for r in table.rows):
        return table
    rows = []
    for r in table.rows:
        if r.key in contradicted and r.family is not None:
            env = None if r.envelope is None else {**r.envelope, "eligible_but_agreement": False}
            r = replace(r, significant=False, stuck=contradicted[r.key], envelope=env)
        rows.append(r)
    out = select_law(rows, table.n_eff, table.tau, table.folds, table.settings, judge=False, base=table.base)
    blocked = blocked_by_disagreement(out)
    if blocked is not None:  # as in nnphd.explain.envelope: a candidate the envelope clearly prefers bars the law
        out.law, out.ties, out.blocked = None, [], blocked
        zero = [r for r in out.rows if r.key == "none"]
        out.rows = [*zero, blocked, *(r for r in out.rows if r is not blocked and r.key != "none")]
        out.reason = (
            f"no law is claimed: the amplitude envelope clearly prefers {blocked.title}, whose windows do not reject "
            "it, but its two fits disagree on its coefficients"
        )
    offset = sorted(k for k, c in contradicted.items() if c.get("kind") != "stop")
    stop = sorted(k for k, c in contradicted.items() if c.get("kind") == "stop")
    if offset:
        c = contradicted[offset[0]]
        out.reason += (
            f"; not eligible, as the record rests {c['seconds']:.2g} s at q = {c['q']:.4g}, {c['offset']:.2g} from "
            f"the equilibrium of their fits (their conservative force there {c['force']:.3g} ± {c['se']:.2g}) and "
            f"nothing in them acts at zero speed: {', '.join(offset)}"
        )
    if stop:
        c = contradicted[stop[0]]
        out.reason += (
            f"; not eligible, as the record stops for good at t = {c['t_rest']:.4g} (its motion over the next "
            f"{c['window']:.2g} s: std {c['measured_std']:.2g}) where, from its last turning point (t = "
            f"{c['t_turn']:.4g}, q = {c['q_turn']:.4g}), they predict the swing going on (std "
            f"{c['predicted_std']:.2g} ± {c['se']:.2g}, {stop[0]}) — nothing in them stops a swing: {', '.join(stop)}"
        )
    return out
