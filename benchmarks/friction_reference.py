"""Independent reference for the friction law of each real recording: a whole-trajectory ODE fit of the positions.

    .venv/bin/python benchmarks/friction_reference.py [file.csv ...] [--json out.json] [--cubic]
    .venv/bin/python benchmarks/friction_reference.py --lookalikes offset-rest,sensor-20hz,...   # known truth

``--lookalikes`` fits constructed look-alikes of tests/fixtures/friction.py (seed 0) instead of the recordings, with
their true law beside (results/friction_reference_lookalikes.json): where this independent fit cannot tell two
families apart either, a tie of nnphd's is the record's limit, not the ranking's.  The two-coordinate look-alike
``throw-2d`` is fitted with the projectile model below.

``--cubic`` adds a cubic term − g q'^3 (the cubic of nnphd's Rayleigh family) to the friction library: 16 subsets
instead of 8 (results/friction_reference_cubic.json holds that run for the two string pendulums).

Reads every CSV in ``data/real/`` and ``../shared/data/real/servo_sts3250_drop.csv`` (header ``t,<coord>[,traj]``;
the coordinate is an angle when its name starts with ``theta``/``phi``/``angle``) with its own CSV reader, not
nnphd's, and fits the one-degree-of-freedom model

    pendulum (angle):   q'' = -a sin(q - q0)              - c q' - d tanh(q'/eps) - e |q'| q'
    spring  (other):    q'' = -a (q - q0) - b (q - q0)^3  - c q' - d tanh(q'/eps) - e |q'| q'

(viscous c, dry/Coulomb d, quadratic/aerodynamic e; a, q0, b free; eps = 1.5 % of the rms speed of the record,
fixed) to the measured POSITIONS - nothing is differentiated except for starting guesses.

A CSV with two coordinate columns (``t,x,y[,traj]``, y up) is a body in flight (a thrown ball), fitted with the
projectile model, the same three friction terms in their isotropic two-dimensional form (v = (x', y'), |v| its norm)

    projectile (x, y):  x'' =    - c x' - d tanh(|v|/eps) x'/|v| - e |v| x'
                        y'' = -G - c y' - d tanh(|v|/eps) y'/|v| - e |v| y'

(gravity G free like a; eps = 1.5 % of the rms speed |v|; ``--cubic`` adds - g |v|^2 v).  The record does not
oscillate, so it has no period and no windows: each trajectory is one window, integrated from its own fitted state
(x, y, x', y') over its whole length (single shooting, again with forward sensitivities), and the residuals are
the x and the y position residuals (R is their rms over both coordinates).  Starting guesses: the state from a cubic
in time per coordinate, G and a drag rate k (drag = -k v) from the constant acceleration and the mean velocity of a
quadratic, k converted to each term at the rms speed s (c = k, d = k s, e = k / s).  Subsets, repairs and decision
rules are the oscillators'; the JSON entry has the same keys (``model`` "projectile", ``period_s`` null,
``windows`` the trajectories, ``continuity_gap_full`` 0, and ``gravity`` in place of a, q0, b in the parameters).

Fit: multiple shooting.  Each trajectory is cut into windows of about two periods; every window starts from its own
fitted state (q, q') and is integrated with ``scipy.integrate.solve_ivp`` (RK45, all windows of a record in one
vectorized system, with forward sensitivity equations for an exact Jacobian); the parameters are shared by all
windows and trajectories.  ``scipy.optimize.least_squares`` (trf; c, d, e >= 0, and generous upper bounds on every
parameter that keep trial points integrable) minimises the position residuals plus continuity residuals (end state of
a window minus the start state of the next, weighted so that the windows join into one continuous trajectory), so the
result is a whole-trajectory fit.  The reported residual is the rms of the
position residuals only, over every fitted sample.

Several trajectories in a file (``traj`` column) get their own windows and initial states, shared parameters.
Angles are unwrapped per trajectory.  A record that ends at rest (stuck) is fitted only up to where it stops: rows
after which the position never again moves by more than max(3 quanta, 1 % of the record's largest swing) within a
quarter period are excluded (the smooth tanh cannot hold a stuck state and such rows carry no friction information).

Every subset of {c, d, e} is fitted, the empty one (no damping) included, each started from data-derived guesses
(a from the period, q0 from the median, the damping from the decay of the swing envelope, converted to each term by
the usual equivalent-viscous relations) and, for two or three terms, also from the best fit with one term fewer;
finally any fit that ended worse than one of its subsets (a local minimum) is refitted from that subset's solution.

Decision rules (R = rms position residual over the fitted samples, F = the full model {c, d, e}):

* a term is **necessary** if dropping it from the full model makes the residual R(F minus term) >= 1.2 x R(F);
* the **best** subset is the smallest subset with R < 1.2 x R(F) (fewest terms; ties: lowest R).  Every term of the
  best subset is needed in the sense that dropping it gives R >= 1.2 x R(F); when two terms can stand in for each
  other (e.g. c and e over a narrow range of amplitudes) neither is "necessary" by the first rule, and the best
  subset names the one that fits better.

and, weighing the residuals by their number (``information`` in the JSON): each subset's IC
n_eff·log(R²/R(F)²) + k·log(n_eff) — a Gaussian fit's BIC, n_eff the position residuals over the correlation time
(1 + ρ)/(1 − ρ) of the full model's (ρ their lag-one correlation: white noise counts every residual, a smooth
misfit few) — its best subset and the best rival that is neither a subset nor a superset of it, with their ΔIC
(≥ 6: the record tells them apart).  The 1.2x rule does not see that over 2401 samples an rms 0.8 % higher is
38 noise variances; the IC does, where the residuals are the noise's (on a real record a model misfit leaves a
correlated residual, ρ large, few n_eff).

Writes ``benchmarks/results/friction_reference.json`` (per record: the rules' outcome, the parameters of the full and
the best model, R of every subset, the fitted rows and windows, the quantum of the positions) and prints a markdown
table.  Runtime: about 80 s of CPU for the six records (two minutes on a busy two-core machine).
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # small dense SVDs: threads only contend on a shared machine
os.environ.setdefault("OMP_NUM_THREADS", "1")

import argparse
import csv
import glob
import itertools
import json
import math
import sys
import time

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import least_squares

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SHARED = os.path.join(ROOT, "..", "shared", "data", "real")
DATA = os.path.join(ROOT, "data", "real")
OUT = os.path.join(ROOT, "benchmarks", "results", "friction_reference.json")

TERMS = ("c", "d", "e")  # with --cubic also "g" (a cubic term g q'^3: the Rayleigh family's)
PHYS = ("a", "q0", "b", "c", "d", "e", "g")  # sensitivity order
PHYS2 = ("gravity", "c", "d", "e", "g")  # the projectile's (two coordinates), in its sensitivity order
RTOL = 1e-6  # solve_ivp relative tolerance (the data are good to ~1e-3 of their range)
MAX_RHS = 40_000  # right-hand-side calls allowed for one integration of all windows
MAX_NFEV = 60  # least-squares evaluations per fit
METHOD = "RK45"  # explicit; DOP853 takes as many steps here (the tanh kinks limit the step, not the order)
RATIO = 1.2  # the necessity / adequacy threshold on the rms residual
EPS_FRAC = 0.015  # eps of the tanh = this fraction of the rms speed
PERIODS_PER_WINDOW = 2.0
MAX_WINDOWS = 40  # per trajectory
ANGLE_PREFIXES = ("theta", "phi", "angle", "alpha", "q_ang")


# ---- data ---------------------------------------------------------------------------------------------------------
def read_columns(path):
    """(coordinate names, [(t, Q), ...]) from a CSV with a header ``t,<coord>...[,traj]``: one (t, Q) per ``traj``
    value (all rows when there is no such column), sorted by time, Q of shape (rows, coordinates)."""
    with open(path, newline="") as f:
        reader = csv.reader(f)
        header = [h.strip() for h in next(reader)]
        rows = [r for r in reader if r and any(c.strip() for c in r)]
    coords = [h for h in header if h not in ("t", "traj")]
    it, iq = header.index("t"), [header.index(h) for h in coords]
    itr = header.index("traj") if "traj" in header else None
    groups: dict[str, list] = {}
    for r in rows:
        groups.setdefault(r[itr].strip() if itr is not None else "1", []).append(
            [float(r[it])] + [float(r[i]) for i in iq]
        )
    trajs = []
    for rs in groups.values():
        a = np.array(rs, dtype=float)
        a = a[np.argsort(a[:, 0], kind="stable")]
        trajs.append((a[:, 0], a[:, 1:]))
    return coords, trajs


def read_record(path):
    """(coordinate name, is_angle, [(t, q), ...]) from a CSV with one coordinate column; rows grouped by ``traj``."""
    coords, trajs = read_columns(path)
    if len(coords) != 1:
        raise ValueError(f"{path}: expected one coordinate column, got {coords}")
    name = coords[0]
    is_angle = name.lower().startswith(ANGLE_PREFIXES)
    return name, is_angle, [(t, np.unwrap(Q[:, 0]) if is_angle else Q[:, 0]) for t, Q in trajs]


def quantum(q):
    """Smallest position step of the record (its quantisation, or the noise scale when not quantised)."""
    d = np.abs(np.diff(q))
    d = d[d > 1e-12]
    return float(np.min(d)) if d.size else 0.0


def period_estimate(trajs, qstep):
    """Median full period from the crossings of each trajectory's median level, with hysteresis (a crossing counts
    once the coordinate is a margin beyond the level, so noise near the level does not add crossings)."""
    periods = []
    for t, q in trajs:
        x = q - np.median(q)
        h = max(3 * qstep, 0.05 * np.percentile(np.abs(x), 95))
        flips, state = [], 0
        for ti, xi in zip(t, x):
            if xi > h and state <= 0:
                if state < 0:
                    flips.append(ti)
                state = 1
            elif xi < -h and state >= 0:
                if state > 0:
                    flips.append(ti)
                state = -1
        if len(flips) >= 3:
            periods.append(2 * np.median(np.diff(flips)))
    if not periods:
        return float(max(np.ptp(t) for t, _ in trajs))
    return float(np.median(periods))


def trim_rest(t, q, period, qstep, swing):
    """Index after which the trajectory stays at rest (see the module docstring); len(t) if it never stops."""
    thr = max(3 * qstep, 0.01 * swing)
    w = max(3, int(round(0.25 * period / np.median(np.diff(t)))))
    n = len(t)
    if n <= 2 * w:
        return n
    moving = np.array([np.ptp(q[i : i + w]) > thr for i in range(0, n - w + 1)])
    last = np.nonzero(moving)[0]
    if last.size == 0:
        return n
    end = int(last[-1]) + w
    return n if end >= n - 1 else end


def local_velocity(t, q, i, half):
    """Slope of a quadratic fitted to q around sample i (a starting guess only)."""
    lo, hi = max(0, i - half), min(len(t), i + half + 1)
    if hi - lo < 3:
        lo, hi = max(0, i - 1), min(len(t), i + 2)
    tt = t[lo:hi] - t[i]
    deg = 2 if hi - lo >= 4 else 1
    p = np.polyfit(tt, q[lo:hi], deg)
    return float(p[-2])


# ---- model --------------------------------------------------------------------------------------------------------
class Record:
    """One recording prepared for multiple shooting."""

    def __init__(self, path):
        self.path = path
        self.name, self.pendulum, trajs = read_record(path)
        self.model = "pendulum" if self.pendulum else "spring"
        allq = np.concatenate([q for _, q in trajs])
        self.qstep = quantum(allq)
        self.period = period_estimate(trajs, self.qstep)
        swing = max(np.ptp(q) for _, q in trajs)
        self.trimmed = []
        self.trajs = []
        for t, q in trajs:
            end = trim_rest(t, q, self.period, self.qstep, swing)
            self.trimmed.append(len(t) - end)
            self.trajs.append((t[:end], q[:end]))
        self.n_rows = sum(len(t) for t, _ in trajs)
        # windows: (trajectory, first sample, end sample (exclusive), duration to integrate)
        self.windows = []
        for j, (t, _) in enumerate(self.trajs):
            span = t[-1] - t[0]
            k = int(min(MAX_WINDOWS, max(1, round(span / (PERIODS_PER_WINDOW * self.period)))))
            edges = np.searchsorted(t, t[0] + span * np.arange(k + 1) / k)
            edges[-1] = len(t)
            edges = np.unique(edges)
            for w in range(len(edges) - 1):
                i0, i1 = int(edges[w]), int(edges[w + 1])
                last = w == len(edges) - 2
                t_end = t[i1 - 1] if last else t[i1]
                self.windows.append((j, i0, i1, float(t_end - t[i0]), last))
        self.K = len(self.windows)
        # the samples of every window, as (window, local time); continuity targets
        taus, owner, qdata = [], [], []
        for k, (j, i0, i1, _, _) in enumerate(self.windows):
            t, q = self.trajs[j]
            taus.append(t[i0:i1] - t[i0])
            owner.append(np.full(i1 - i0, k))
            qdata.append(q[i0:i1])
        self.tau = np.concatenate(taus)
        self.owner = np.concatenate(owner)
        self.qdata = np.concatenate(qdata)
        self.tau_u, self.tau_inv = np.unique(self.tau, return_inverse=True)
        self.n = self.qdata.size
        self.t_end = np.array([w[3] for w in self.windows])
        self.cont = [k for k, w in enumerate(self.windows) if not w[4]]  # windows followed by another
        dt = np.concatenate([np.diff(t) for t, _ in self.trajs])
        speeds = np.concatenate([np.gradient(q, t) for t, q in self.trajs])
        self.vrms = float(np.sqrt(np.mean(speeds**2)))
        self.eps = EPS_FRAC * self.vrms
        self.omega = 2 * math.pi / self.period
        self.dt = float(np.median(dt))
        n_per_window = self.n / self.K
        self.wcont = 10.0 * math.sqrt(n_per_window)
        half = max(1, int(round(0.04 * self.period / self.dt)))
        self.init_states = []
        for j, i0, _, _, _ in self.windows:
            t, q = self.trajs[j]
            self.init_states.append((q[i0], local_velocity(t, q, i0, half)))
        self.init_states = np.array(self.init_states)
        self.amp = float(max(np.max(np.abs(q - np.median(q))) for _, q in self.trajs))
        self.a0 = self.omega**2 * ((1 + self.amp**2 / 16) ** 2 if self.pendulum else 1.0)

    # ---- integration of all windows at once, with sensitivities to PHYS + (q_k, v_k) ---------------------------
    def simulate(self, phys, sens):
        """Integrate every window from its state in ``self._x_states``; sensitivities to the parameters named in
        ``sens`` (a subset of PHYS, in PHYS order) and to the window's own initial (q, q').  Returns the states and
        sensitivities at the data samples (component, sample) and at each window's end (component, window); the
        components are q, q', dq/d(sens..., q_k, v_k), dq'/d(sens..., q_k, v_k)."""
        a, q0, b, c, d, e, gc = phys
        K, eps = self.K, self.eps
        ns = len(sens)
        m = ns + 2  # sensitivity columns
        pend = self.pendulum
        forcing = [PHYS.index(p) for p in sens]
        calls = [0]

        def rhs(_, y):
            calls[0] += 1
            if calls[0] > MAX_RHS:  # a trial point far off (stiff or escaping): report a failed step instead
                raise FloatingPointError("too many steps")
            Y = y.reshape(2 + 2 * m, K)
            q, v = Y[0], Y[1]
            Sq, Sv = Y[2 : 2 + m], Y[2 + m :]
            u = q - q0
            if pend:
                s, ds = np.sin(u), np.cos(u)
                cub, dcub = 0.0, 0.0
            else:
                s, ds = u, 1.0
                cub, dcub = u**3, 3 * u**2
            th = np.tanh(v / eps) if d else 0.0
            av = np.abs(v)
            g = -a * s - b * cub - c * v - d * th - e * av * v - gc * v**3
            gq = -a * ds - b * dcub
            gv = -c - (d / eps) * (1 - th**2) - 2 * e * av - 3 * gc * v**2
            dSv = gq * Sq + gv * Sv
            for i, j in enumerate(forcing):
                if j == 0:
                    dSv[i] -= s
                elif j == 1:
                    dSv[i] -= gq
                elif j == 2:
                    dSv[i] -= cub
                elif j == 3:
                    dSv[i] -= v
                elif j == 4:
                    dSv[i] -= np.tanh(v / eps) if not d else th
                elif j == 5:
                    dSv[i] -= av * v
                else:
                    dSv[i] -= v**3
            return np.concatenate([v[None], g[None], Sv, dSv]).ravel()

        y0 = np.zeros((2 + 2 * m, K))
        y0[0], y0[1] = self._x_states[:, 0], self._x_states[:, 1]
        y0[2 + ns] = 1.0  # dq/dq_k
        y0[2 + m + ns + 1] = 1.0  # dv/dv_k
        T = float(self.t_end.max())
        sol = solve_ivp(rhs, (0.0, T), y0.ravel(), method=METHOD, rtol=RTOL, atol=self._atol(m), dense_output=True)
        if not sol.success:
            raise RuntimeError(sol.message)
        Yu = sol.sol(self.tau_u).reshape(2 + 2 * m, K, -1)  # (comp, window, tau)
        Ydata = Yu[:, self.owner, self.tau_inv]  # (comp, sample)
        Yend = sol.sol(self.t_end).reshape(2 + 2 * m, K, K)[:, np.arange(K), np.arange(K)]  # (comp, window)
        return Ydata, Yend

    def _atol(self, m):
        """Absolute tolerances: 1e-4 of a quantum-or-noise scale on q, scaled by omega on q', and on the
        sensitivities in the units of each parameter's effect."""
        K = self.K
        sq = 1e-3 * max(self.qstep, 1e-6 * np.ptp(self.qdata))
        scale = np.ones(2 + 2 * m)
        scale[1] = self.omega
        scale[2 : 2 + m] = 1.0
        scale[2 + m :] = self.omega
        return np.repeat(sq * scale, K)

    # ---- least squares --------------------------------------------------------------------------------------------
    def fit(self, terms, start):
        """Fit the model with the friction terms ``terms`` from ``start`` (dict of PHYS values, optional states)."""
        free = ["a", "q0"] + ([] if self.pendulum else ["b"]) + [p for p in TERMS if p in terms]
        fixed = {p: 0.0 for p in PHYS}
        fixed.update({p: start[p] for p in ("a", "q0", "b") if p in start})
        nf = len(free)
        states0 = start.get("states", self.init_states)
        x0 = np.concatenate(
            [
                [max(start.get(p, 0.0), 0.0) if p in TERMS else start.get(p, 0.0) for p in free],
                np.asarray(states0).ravel(),
            ]
        )
        lo = np.full(x0.size, -np.inf)
        hi = np.full(x0.size, np.inf)
        a0, A = self.a0, self.amp
        limits = {  # generous: far beyond anything that still oscillates; they keep trial points integrable
            "a": (1e-3 * a0, 1e3 * a0),
            "b": (-0.5 * a0 / A**2, 10 * a0 / A**2),
            "c": (0.0, 10 * self.omega),
            "d": (0.0, 2 * a0 * A),
            "e": (0.0, 12 / A),
            "g": (0.0, 10 / (self.omega * A**2)),
        }
        for i, p in enumerate(free):
            if p in limits:
                lo[i], hi[i] = limits[p]
        x0 = np.clip(x0, lo, hi)
        cache = {}
        vscale = 1.0 / self.omega
        n, K = self.n, self.K
        cont = np.array(self.cont, dtype=int)
        nxt = cont + 1
        w = self.wcont

        def evaluate(x):
            key = x.tobytes()
            if key in cache:
                return cache[key]
            phys = dict(fixed)
            phys.update(dict(zip(free, x[:nf])))
            self._x_states = x[nf:].reshape(K, 2)
            try:
                with np.errstate(over="raise", invalid="raise"):
                    Yd, Ye = self.simulate([phys[p] for p in PHYS], free)
            except (RuntimeError, FloatingPointError, ValueError):
                cache.clear()
                cache[key] = None
                return None
            m = nf + 2
            r_data = Yd[0] - self.qdata
            st = self._x_states
            r_cq = w * (Ye[0, cont] - st[nxt, 0])
            r_cv = w * vscale * (Ye[1, cont] - st[nxt, 1])
            r = np.concatenate([r_data, r_cq, r_cv])
            J = np.zeros((r.size, x.size))
            for i in range(nf):
                J[:n, i] = Yd[2 + i]
                J[n : n + cont.size, i] = w * Ye[2 + i, cont]
                J[n + cont.size :, i] = w * vscale * Ye[2 + m + i, cont]
            own = self.owner
            J[np.arange(n), nf + 2 * own] = Yd[2 + nf]
            J[np.arange(n), nf + 2 * own + 1] = Yd[2 + nf + 1]
            rc = np.arange(cont.size)
            J[n + rc, nf + 2 * cont] = w * Ye[2 + nf, cont]
            J[n + rc, nf + 2 * cont + 1] = w * Ye[2 + nf + 1, cont]
            J[n + rc, nf + 2 * nxt] -= w
            J[n + cont.size + rc, nf + 2 * cont] = w * vscale * Ye[2 + m + nf, cont]
            J[n + cont.size + rc, nf + 2 * cont + 1] = w * vscale * Ye[2 + m + nf + 1, cont]
            J[n + cont.size + rc, nf + 2 * nxt + 1] -= w * vscale
            cache.clear()
            cache[key] = (r, J)
            return cache[key]

        big = None

        def fun(x):
            out = evaluate(x)
            if out is None:
                nonlocal big
                if big is None:
                    big = np.full(n + 2 * len(self.cont), 1e6 * (np.ptp(self.qdata) + 1))
                return big
            return out[0]

        def jac(x):
            out = evaluate(x)
            if out is None:
                return np.eye(n + 2 * len(self.cont), x.size)
            return out[1]

        res = _least_squares(fun, jac, x0, lo, hi)
        x = res.x
        out = evaluate(x)
        params = dict(fixed)
        params.update(dict(zip(free, x[:nf])))
        if out is None:
            rms, gap, rho = float("inf"), float("inf"), float("nan")
        else:
            r = out[0]
            rms = float(np.sqrt(np.mean(r[:n] ** 2)))
            gap = float(np.max(np.abs(r[n:]))) / w if r.size > n else 0.0
            rho = lag_one(r[:n], self.owner)
        return {
            "params": {p: float(params[p]) for p in PHYS},
            "states": x[nf:].reshape(K, 2).copy(),
            "rms": rms,
            "rho": rho,
            "continuity_gap": gap,
            "nfev": int(res.nfev),
        }


def lag_one(r, owner) -> float:
    """The lag-one correlation of position residuals ``r`` ((sample,) or (coordinate, sample)) between successive
    samples of the same window (``owner``: each sample's window), clipped to [0, 0.95]: white noise gives ~0, a
    smooth misfit (a model that misses the record) near 1."""
    r = np.atleast_2d(r)
    same = owner[1:] == owner[:-1]
    num = float(np.sum(r[:, 1:][:, same] * r[:, :-1][:, same]))
    return float(np.clip(num / max(float(np.sum(r * r)), 1e-300), 0.0, 0.95))


def information(entry) -> dict:
    """Can the record tell the subsets apart? Each subset's IC n_eff·log(R²/R_full²) + k·log(n_eff) from its rms
    position residual R (n residuals; n_eff = n (1 − ρ)/(1 + ρ), ρ the full model's lag-one correlation: white
    noise counts every residual, a smooth misfit few) — the BIC of a Gaussian fit, which the 1.2x rms rule above
    does not weigh by the number of samples: over 2401 samples R 0.79 % higher is Δχ² ≈ 38 noise variances.
    Returns {"ic": {subset: ΔIC to the best}, "best", "runner_up" (the best subset that is neither a subset nor a
    superset of it), "delta_ic_runner_up", "n_eff", "rho"}."""
    n = entry["rows_fitted"] * (2 if entry["model"] == "projectile" else 1)
    full = entry["rms"][label(TERMS)]
    subs = [tuple(x for x in S.strip("{}").split(",") if x) for S in entry["rms"]]
    rho = entry.get("rho", {}).get(label(TERMS), 0.0)
    rho = 0.0 if rho is None or not np.isfinite(rho) else rho
    n_eff = n * (1 - rho) / (1 + rho)
    ic = {S: n_eff * math.log(entry["rms"][label(S)] ** 2 / full**2) + len(S) * math.log(n_eff) for S in subs}
    order = sorted(subs, key=lambda S: ic[S])
    best = order[0]
    rival = next((S for S in order[1:] if not (set(S) <= set(best) or set(best) <= set(S))), None)
    return {
        "ic": {label(S): round(ic[S] - ic[best], 2) for S in order},
        "best": label(best),
        "runner_up": label(rival) if rival is not None else None,
        "delta_ic_runner_up": round(ic[rival] - ic[best], 2) if rival is not None else None,
        "n_eff": round(n_eff, 1),
        "rho": round(rho, 3),
    }


def _least_squares(fun, jac, x0, lo, hi):
    """The reference's one optimiser setting, for both models: trust-region reflective within the bounds, scaled by
    the Jacobian, tolerances tight enough that the subsets' rms values compare to 1e-6."""
    return least_squares(fun, x0, jac=jac, bounds=(lo, hi), method="trf", x_scale="jac", max_nfev=MAX_NFEV,
                         ftol=1e-8, xtol=1e-8, gtol=1e-10)  # fmt: skip


# ---- two coordinates: a projectile ------------------------------------------------------------------------------
class Projectile:
    """A record of a body in flight, two coordinates (x, y), y up: one window (single shooting) per trajectory.

    Same interface as :class:`Record` for :func:`fit_record` and :func:`main`; its parameters are PHYS2."""

    model = "projectile"
    pendulum = False
    period = None

    def __init__(self, path):
        self.path = path
        coords, self.trajs = read_columns(path)
        if len(coords) != 2:
            raise ValueError(f"{path}: expected two coordinate columns (x, y), got {coords}")
        self.name = ",".join(coords)
        self.qstep = min(quantum(Q[:, i]) for _, Q in self.trajs for i in range(2))
        self.trimmed = [0] * len(self.trajs)
        self.n_rows = sum(len(t) for t, _ in self.trajs)
        self.K = len(self.trajs)
        self.tau = np.concatenate([t - t[0] for t, _ in self.trajs])
        self.owner = np.concatenate([np.full(len(t), k) for k, (t, _) in enumerate(self.trajs)])
        self.qdata = np.concatenate([Q for _, Q in self.trajs]).T  # (coordinate, sample)
        self.tau_u, self.tau_inv = np.unique(self.tau, return_inverse=True)
        self.n = self.tau.size
        self.t_end = np.array([t[-1] - t[0] for t, _ in self.trajs])
        self.span = float(self.t_end.max())
        speeds = np.concatenate([np.linalg.norm(np.gradient(Q, t, axis=0), axis=1) for t, Q in self.trajs])
        self.vrms = float(np.sqrt(np.mean(speeds**2)))
        self.eps = EPS_FRAC * self.vrms
        # starting guesses from a quadratic in time per coordinate and trajectory: the initial state from a cubic,
        # gravity and a drag rate k (drag = -k v) from the mean acceleration against the mean velocity
        states, ks, gs = [], [], []
        for t, Q in self.trajs:
            tt = t - t[0]
            cub = [np.polyfit(tt, Q[:, i], 3) for i in range(2)]
            states.append([cub[0][3], cub[1][3], cub[0][2], cub[1][2]])
            quad = [np.polyfit(tt - tt.mean(), Q[:, i], 2) for i in range(2)]
            acc = np.array([2 * quad[0][0], 2 * quad[1][0]])
            vm = np.array([quad[0][1], quad[1][1]])
            k = -acc[0] / vm[0] if abs(vm[0]) > 0.1 * np.linalg.norm(vm) else 0.0
            ks.append(k)
            gs.append(-acc[1] - k * vm[1])
        self.init_states = np.array(states)
        self.k0 = max(float(np.median(ks)), 0.01 / self.span)
        self.g0 = max(float(np.median(gs)), 1e-3 * self.vrms / self.span)

    def guesses(self):
        """Gravity, and the drag rate k expressed as each friction term at the rms speed s (c = k, d = k s, ...)."""
        s, k = self.vrms, self.k0
        return {"gravity": self.g0}, {"c": k, "d": k * s, "e": k / s, "g": k / s**2}

    def simulate(self, phys, sens):
        """Integrate every trajectory from its state in ``self._x_states`` (K, 4: x, y, x', y'), with sensitivities
        to the parameters named in ``sens`` (a subset of PHYS2, in PHYS2 order) and to the initial state.  Returns
        (1 + m, 4, sample): the state, then its derivative by each of the m = len(sens) + 4 columns."""
        G, c, d, e, gc = phys
        K, eps = self.K, self.eps
        ns = len(sens)
        m = ns + 4
        forcing = [PHYS2.index(p) for p in sens]
        calls = [0]

        def rhs(_, y):
            calls[0] += 1
            if calls[0] > MAX_RHS:
                raise FloatingPointError("too many steps")
            Y = y.reshape(1 + m, 4, K)
            v = Y[0, 2:]
            s = np.sqrt(v[0] ** 2 + v[1] ** 2)
            u = s / eps
            th = np.tanh(u)
            small = u < 1e-4
            sg = np.where(small, eps, s)
            h = np.where(small, (1 - u * u / 3) / eps, th / sg)  # tanh(s/eps)/s
            hp = np.where(small, -2 / (3 * eps**3), (u * (1 - th * th) - th) / sg**3)  # h'(s)/s
            k = c + d * h + e * s + gc * s * s  # the drag is -k(s) v
            q = d * hp + e / np.maximum(s, 1e-300) + 2 * gc  # k'(s)/s
            F = -k * v
            F[1] -= G
            J00, J01, J11 = -k - q * v[0] ** 2, -q * v[0] * v[1], -k - q * v[1] ** 2  # dF/dv
            S = Y[1:]
            dS = np.empty_like(S)
            dS[:, :2] = S[:, 2:]
            dS[:, 2] = J00 * S[:, 2] + J01 * S[:, 3]
            dS[:, 3] = J01 * S[:, 2] + J11 * S[:, 3]
            for i, j in enumerate(forcing):
                if j == 0:
                    dS[i, 3] += -1.0
                else:
                    dS[i, 2:] -= (1.0, h, s, s * s)[j - 1] * v
            return np.concatenate([np.concatenate([v, F])[None], dS]).ravel()

        y0 = np.zeros((1 + m, 4, K))
        y0[0] = self._x_states.T
        for i in range(4):
            y0[1 + ns + i, i] = 1.0
        sq = 1e-3 * max(self.qstep, 1e-6 * np.ptp(self.qdata))
        atol = np.zeros((1 + m, 4, K))
        atol[:, :2], atol[:, 2:] = sq, sq / self.span
        sol = solve_ivp(
            rhs, (0.0, self.span), y0.ravel(), method=METHOD, rtol=RTOL, atol=atol.ravel(), dense_output=True
        )
        if not sol.success:
            raise RuntimeError(sol.message)
        Yu = sol.sol(self.tau_u).reshape(1 + m, 4, K, -1)
        return Yu[:, :, self.owner, self.tau_inv]

    def fit(self, terms, start):
        """Fit gravity and the friction terms ``terms`` from ``start`` (dict of PHYS2 values, optional states)."""
        free = ["gravity"] + [p for p in TERMS if p in terms]
        nf = len(free)
        states0 = start.get("states", self.init_states)
        x0 = np.concatenate(
            [
                [max(start.get(p, 0.0), 0.0) if p in TERMS else start.get(p, self.g0) for p in free],
                np.asarray(states0).ravel(),
            ]
        )
        lo = np.full(x0.size, -np.inf)
        hi = np.full(x0.size, np.inf)
        T, s = self.span, self.vrms
        acc = max(self.g0, s / T)
        limits = {  # generous; they keep trial points integrable
            "gravity": (1e-3 * acc, 1e3 * acc),
            "c": (0.0, 100 / T),
            "d": (0.0, 100 * acc),
            "e": (0.0, 100 / (T * s)),
            "g": (0.0, 100 / (T * s * s)),
        }
        for i, p in enumerate(free):
            lo[i], hi[i] = limits[p]
        x0 = np.clip(x0, lo, hi)
        n, K = self.n, self.K
        cache = {}
        big = np.full(2 * n, 1e6 * (np.ptp(self.qdata) + 1))

        def evaluate(x):
            key = x.tobytes()
            if key in cache:
                return cache[key]
            phys = dict.fromkeys(PHYS2, 0.0)
            phys.update(dict(zip(free, x[:nf])))
            self._x_states = x[nf:].reshape(K, 4)
            try:
                with np.errstate(over="raise", invalid="raise"):
                    Yd = self.simulate([phys[p] for p in PHYS2], free)
            except (RuntimeError, FloatingPointError, ValueError):
                cache.clear()
                cache[key] = None
                return None
            r = (Yd[0, :2] - self.qdata).ravel()  # x residuals, then y residuals
            J = np.zeros((2 * n, x.size))
            for i in range(nf):
                J[:, i] = Yd[1 + i, :2].ravel()
            rows = np.arange(n)
            for coord in range(2):
                for comp in range(4):
                    J[coord * n + rows, nf + 4 * self.owner + comp] = Yd[1 + nf + comp, coord]
            cache.clear()
            cache[key] = (r, J)
            return cache[key]

        def fun(x):
            out = evaluate(x)
            return big if out is None else out[0]

        def jac(x):
            out = evaluate(x)
            return np.eye(2 * n, x.size) if out is None else out[1]

        res = _least_squares(fun, jac, x0, lo, hi)
        x = res.x
        out = evaluate(x)
        params = dict.fromkeys(PHYS2, 0.0)
        params.update(dict(zip(free, x[:nf])))
        rms = float("inf") if out is None else float(np.sqrt(np.mean(out[0] ** 2)))
        rho = float("nan") if out is None else lag_one(out[0].reshape(2, n), self.owner)
        return {
            "params": {p: float(params[p]) for p in PHYS2},
            "states": x[nf:].reshape(K, 4).copy(),
            "rms": rms,
            "rho": rho,
            "continuity_gap": 0.0,
            "nfev": int(res.nfev),
        }


def load_record(path):
    """A :class:`Projectile` for a CSV with two coordinate columns, else a :class:`Record` (one coordinate)."""
    coords, _ = read_columns(path)
    return Projectile(path) if len(coords) == 2 else Record(path)


def guesses(rec):
    """Data-derived starting values: a from the period, q0 from the median, damping from the envelope decay."""
    if rec.model == "projectile":
        return rec.guesses()
    q0 = float(np.median(np.concatenate([q for _, q in rec.trajs])))
    amps, decays = [], []
    for t, q in rec.trajs:
        x = q - q0
        w = max(3, int(round(0.5 * rec.period / rec.dt)))
        env = np.array([np.ptp(x[i : i + w]) / 2 for i in range(0, max(1, len(x) - w), max(1, w // 2))])
        tt = t[0] + np.arange(env.size) * max(1, w // 2) * rec.dt
        ok = env > 3 * rec.qstep
        if ok.sum() >= 3:
            p = np.polyfit(tt[ok], np.log(env[ok]), 1)
            decays.append(-p[0])
            amps.append(float(np.median(env[ok])))
    gamma = max(float(np.median(decays)) if decays else 0.01 * rec.omega, 1e-3 * rec.omega)
    A = float(np.median(amps)) if amps else float(np.ptp(rec.qdata) / 2)
    w0 = rec.omega
    a = w0**2
    if rec.pendulum:  # the period lengthens with amplitude: T ~ T0 (1 + A^2/16)
        a *= (1 + A**2 / 16) ** 2
    c_eq = 2 * gamma
    equiv = {
        "c": c_eq,
        "d": c_eq * math.pi * w0 * A / 4,
        "e": c_eq * 3 * math.pi / (8 * w0 * max(A, 1e-12)),
        "g": c_eq * 4 / (3 * (w0 * max(A, 1e-12)) ** 2),  # the same energy loss per period at amplitude A
    }
    return {"a": a, "q0": q0, "b": 0.0}, equiv


def subsets():
    for k in range(0, len(TERMS) + 1):
        yield from itertools.combinations(TERMS, k)


def fit_record(rec):
    base, equiv = guesses(rec)
    fits = {}

    def better(S, res):
        if S not in fits or res["rms"] < fits[S]["rms"] * (1 - 1e-6):
            fits[S] = res

    def start_from(src, S, share=1.0):
        st = dict(src["params"]) if src else dict(base)
        st["states"] = src["states"] if src else rec.init_states
        for p in TERMS:
            if p not in S:
                st[p] = 0.0
            elif not src or st.get(p, 0.0) <= 0.0:
                st[p] = share * equiv[p]
        return st

    for S in subsets():
        cands = [start_from(None, S, 1.0 / max(1, len(S)))]
        below = [T for T in fits if set(T) < set(S) and len(T) == len(S) - 1]
        if len(S) >= 2 and below:  # and from the best fit with one term fewer
            cands.append(start_from(fits[min(below, key=lambda T: fits[T]["rms"])], S, 0.1))
        for st in cands:
            better(S, rec.fit(S, st))
    # repair: a superset must not end worse than a subset (local minima); refit from the subset's solution
    for _ in range(2):
        changed = False
        for S in subsets():
            for T in subsets():
                if set(T) < set(S) and fits[T]["rms"] < fits[S]["rms"] * (1 - 1e-4):
                    old = fits[S]["rms"]
                    better(S, rec.fit(S, start_from(fits[T], S, 0.02)))
                    changed |= fits[S]["rms"] < old
        if not changed:
            break
    return fits


def decide(fits):
    full = fits[TERMS]["rms"]
    necessary = [p for p in TERMS if fits[tuple(x for x in TERMS if x != p)]["rms"] >= RATIO * full]
    adequate = [S for S in fits if fits[S]["rms"] < RATIO * full]
    best = min(adequate, key=lambda S: (len(S), fits[S]["rms"]))
    return necessary, best


def label(S):
    return "{" + ",".join(S) + "}" if S else "{}"


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("files", nargs="*")
    ap.add_argument("--json", default=OUT)
    ap.add_argument(
        "--cubic", action="store_true", help="also a cubic term g q'^3 (write the result to another --json)"
    )
    ap.add_argument(
        "--lookalikes",
        default="",
        help="name,name,...: fit these constructed look-alikes (tests/fixtures/friction.py, seed 0) instead, "
        "their truth beside (default --json: results/friction_reference_lookalikes.json)",
    )
    args = ap.parse_args()
    global TERMS
    if args.cubic:
        TERMS = ("c", "d", "e", "g")
    truths = {}
    if args.lookalikes:
        files, truths = _lookalike_files(args.lookalikes.split(","))
        if args.json == OUT:
            args.json = OUT.replace(".json", "_lookalikes.json")
    else:
        files = args.files or (
            [os.path.join(SHARED, "servo_sts3250_drop.csv")] + sorted(glob.glob(os.path.join(DATA, "*.csv")))
        )
    results = []
    t_all = time.time()
    for path in files:
        t0 = time.time()
        rec = load_record(path)
        fits = fit_record(rec)
        necessary, best = decide(fits)
        full = fits[TERMS]
        entry = {
            "file": os.path.relpath(os.path.abspath(path), ROOT).replace(os.sep, "/"),
            "coordinate": rec.name,
            "model": rec.model,
            "rows": rec.n_rows,
            "rows_fitted": rec.n,
            "rows_trimmed_at_rest": rec.trimmed,
            "trajectories": len(rec.trajs),
            "windows": rec.K,
            "period_s": rec.period,
            "position_quantum": rec.qstep,
            "eps": rec.eps,
            "necessary": [p for p in TERMS if p in necessary],
            "best_subset": list(best),
            "full_params": full["params"],
            "best_params": fits[best]["params"],
            "rms": {label(S): fits[S]["rms"] for S in subsets()},
            "rho": {label(S): fits[S].get("rho") for S in subsets()},
            "continuity_gap_full": full["continuity_gap"],
            "rule": f"necessary: R(full minus term) >= {RATIO} R(full); best: fewest terms with R < {RATIO} R(full)",
            "seconds": round(time.time() - t0, 1),
        }
        entry["information"] = information(entry)
        if path in truths:  # a look-alike: its name and the true law in this script's names (c, d, e)
            entry["file"], entry["truth"] = truths[path]
        for k in ("b",) * rec.pendulum + ("g",) * ("g" not in TERMS):
            entry["full_params"].pop(k)
            entry["best_params"].pop(k)
        results.append(entry)
        print(
            f"{entry['file']}: {entry['seconds']} s, necessary {entry['necessary']}, best {label(best)}",
            file=sys.stderr,
        )
    os.makedirs(os.path.dirname(os.path.abspath(args.json)), exist_ok=True)
    with open(args.json, "w") as f:
        json.dump({"recordings": results, "seconds": round(time.time() - t_all, 1)}, f, indent=1)
    print_table(results)


def _lookalike_files(names):
    """Write the look-alikes (seed 0) as CSV in a temporary folder, the coordinate named ``theta`` when it is an
    angle and ``x`` otherwise (this script's model choice: a spring for the 20 Hz torsion sensor in degrees).
    Returns (paths, {path: (name, truth)}), the truth as c (viscous), d (dry), e (quadratic)."""
    import tempfile

    sys.path.insert(0, ROOT)
    from tests.fixtures.friction import make

    folder = tempfile.mkdtemp(prefix="lookalikes-")
    paths, truths = [], {}
    for name in names:
        rec = make(name, seed=0)
        if len(rec.coords) not in (1, 2):
            raise SystemExit(f"error: {name} has {len(rec.coords)} coordinates; this reference fits one or two")
        path = rec.write_csv(os.path.join(folder, f"{name}.csv"))
        if len(rec.coords) == 1:
            coord = "theta" if rec.angles else "x"
            with open(path) as fh:
                lines = fh.read().splitlines()
            lines[0] = lines[0].replace(rec.coords[0], coord, 1)
            with open(path, "w") as fh:
                fh.write("\n".join(lines) + "\n")
        tc = rec.truth["coefficients"]
        truths[path] = (f"lookalike:{name}", {"c": tc.get("gamma", 0.0), "d": tc.get("mu", 0.0), "e": tc.get("c", 0.0)})
        paths.append(path)
    return paths, truths


def print_table(results):
    subs = list(subsets())
    print(
        f"| file | model | rows fitted | necessary | best | best params (a, q0, b | gravity, {', '.join(TERMS)}) | "
        + " | ".join(f"rms {label(S)}" for S in subs)
        + " | IC: best, runner-up (ΔIC), n_eff |"
    )
    print("|" + "---|" * (7 + len(subs)))
    for e in results:
        p = e["best_params"]
        ps = ", ".join(f"{k}={p[k]:.4g}" for k in ("a", "q0", "b", "gravity", *TERMS) if k in p)
        if "truth" in e:
            ps += " (truth " + ", ".join(f"{k}={x:.4g}" for k, x in e["truth"].items() if x) + ")"
        rms = " | ".join(f"{e['rms'][label(S)]:.3g}" for S in subs)
        nec = label(e["necessary"])
        inf = e.get("information") or {}
        ic = f"{inf.get('best')}, {inf.get('runner_up')} ({inf.get('delta_ic_runner_up')}), {inf.get('n_eff')}"
        print(
            f"| {os.path.basename(e['file'])} | {e['model']} | {e['rows_fitted']} | {nec} | {label(e['best_subset'])}"
            f" | {ps} | {rms} | {ic} |"
        )


if __name__ == "__main__":
    main()
