r"""The checks of :func:`nnphd.user.assess.assess` that train no network: on plain arrays (unit-tested on synthetic
inputs), the data-quality gate and the rules that turn the checks into a status per seed. The models (a)–(d) are
those of :mod:`nnphd.user.assess`.

Checks (all numbers in ``checks``; every threshold is a module constant)
------------------------------------------------------------------------

1. **Net power of the residual** (:func:`drift_check`, decisive for autonomous forces). With the conservative model's
   Lagrangian L and residual r = q̈ − f_c, the learned energy H = q̇·∂L/∂q̇ − L changes along the data at the rate
   P = q̇ᵀ(∂²L/∂q̇²) r, exactly. If the motion is conservative, H is *some* function of the state, and on bounded
   (periodic, quasi-periodic) motion it only oscillates, however badly the LNN fits. Drag, self-excitation or driving
   change the energy steadily or slowly. Per trajectory: ρ = |∫P dt| / ∫|P| dt (:func:`net_power_fraction`),
   m = |∫P dt| / ⟨|q̇ᵀ(∂²L/∂q̇²)q̇|⟩ (net energy change over twice the kinetic energy) and the slow ratio
   Z = range of the one-oscillation means of ∫P dt / the typical ∫|P| dt of one oscillation
   (:func:`slow_energy_ratio`: catches beats of a drive that ρ averages away). Significant: median m ≥ DRIFT_MIN
   and (median ρ ≥ RHO_MIN, or median ρ ≥ RHO_LOW and median Z ≥ Z_MIN). *Valid* when the median trajectory shows
   ≥ MIN_OSCILLATIONS oscillations of some coordinate or velocity (the argument needs recurrent motion); an invalid
   drift counts only together with a fit gap (check 3). Computed over whole trajectories; it counts as evidence
   only with ≥ 3 trajectories and usable derivatives (the spread over trajectories: a bootstrap). On single
   records blocks of a few oscillations lost the trend, so there the trajectory-level evidence (0) decides.
0. **Trajectory-level evidence** (:mod:`nnphd.engine.evidence`), from the conservative model (b): the trend of its energy
   over whole periods of the whole record (cross-checked by the per-period kinetic energy, which replaces it when
   the learned energy is not usable) and a multiple-shooting fit of the *positions* with a damping probe
   q̈ = (1 + c) f_c − D q̇. Significant (:func:`trajectory_evidence`) when both agree in sign with |z| ≥ Z_BOTH, or
   one reaches Z_ONE without the other contradicting it (|z| ≥ Z_CONTRA of opposite sign). The effect size is the
   relative energy-decay rate (per time unit and per period) and the damping d with their z.
2. **Explicit time dependence** (:func:`time_check`). Regressions (d) are fit leaving one trajectory out and
   predict it; significant when the pooled out-of-trajectory error without time features over that with them is
   ≥ TIME_GAIN_MIN, the gain is ≥ TIME_ABS_MIN of the force and the time features help on most trajectories (≥ 3
   trajectories). Another trajectory shares no state with the fitted ones, so only a common clock (a drive) can make
   t useful. Tested only where it can be (:func:`clock_testable`): ≥ CLOCK_MIN_TRAJ trajectories that overlap in
   time, or ≥ CLOCK_MANY_TRAJ trajectories; never on one trajectory (time and state are confounded along it) nor on
   trajectories at disjoint times (t would only tell them apart), and the report says why.
3. **Fit gap.** Conservative error / free-model error on the training data (gap_train; and held-out, gap_test).
   Measured: under-fitting of unusual potentials shows up in extrapolation to held-out trajectories (gap_test up to
   5.6 on Morse), not on the training data, where the LNN with its physical inductive bias beats a free MLP
   (gap_train ≤ 1 on every conservative case); drag and van der Pol leave gap_train ≈ 3–4.
4. **Capacity.** The conservative held-out error after each extra round: still falling by > STILL_FALLING means the
   LNN is not at its floor (used in the reason when inconclusive).
5. **Naive ratio** of the sweep on held-out data and the power of the UAN's f_n at λ = 0.2 — reported, not used.

Motion that does not oscillate (a throw, a fall, a coast-down, an arc of an orbit: no period,
:func:`nnphd.engine.evidence.dominant_period` is inf) is data too: the sampling gate uses 2π × the time in which its
velocity changes (:func:`motion_time_scale`) instead of a period, the record-level statistics use blocks and windows
of a fraction of the record (:func:`nnphd.engine.evidence.evidence_block`), and the status follows
:func:`_status_not_oscillating` — such a path never returns to its states, so a potential can be shaped to follow it
whatever force acts: "detected" only when both record-level statistics agree, never "none".

Status per seed (:func:`seed_status`): ``inconclusive`` if the data cannot decide (quality gate); ``detected`` if
check 2 is significant and testable, or the trajectory-level evidence (0) is significant, or check 1 is significant
with ≥ 3 trajectories and usable derivatives (and valid or gap_train ≥ GAP_MIN); otherwise ``inconclusive`` when the
derivatives are too noisy for a pointwise test, when the pointwise residual does net work that the record-level
evidence does not confirm, when the conservative model under-fits (gap_train ≥ GAP_MIN), or when no trajectory-level
statistic could be computed; else ``none``, with the 95 % upper bound on the energy-decay rate. Over seeds:
:mod:`nnphd.user.assess`.

How the thresholds were set (honestly)
--------------------------------------

The constructed cases (tests/fixtures/cases.py; conservative: anharmonic, Morse, large-amplitude pendulum, soft and eccentric
Kepler, double well, magnetic; non-conservative: drag on the anharmonic oscillator / pendulum / Kepler orbit, a drive,
van der Pol) were first run at steps=1000, width=64 and at steps=300, width=32 with every statistic printed; the
thresholds were placed in the gaps of those runs, then checked on other seeds, single trajectories and the table
script (benchmarks/trust_table.py, 24 runs at each of the two configs, none wrong). So they are tuned on these cases:

* RHO_MIN = 0.5: conservative medians ≤ 0.03 with 8 trajectories, ≤ 0.39 with one (2D rosettes); drag on the 1D
  oscillators and van der Pol ≥ 0.95; Kepler + 0.6 % drag 0.40–1.0.
* RHO_LOW = 0.25, Z_MIN = 2 (the Z route) were added for Kepler + drag at 300 steps (ρ 0.40, Z 4.0) and the
  single-trajectory drive (ρ 0.30, Z 2.1–2.2). Conservative Z ≤ 0.1 with 8 trajectories, but up to 1.2 (with ρ 0.22)
  on one eccentric Kepler trajectory: that margin is thin.
* DRIFT_MIN = 0.01 only guards the 0/0 of a near-perfect fit; it does not separate anything (a poorly fit
  conservative eccentric Kepler reached m = 0.1–0.33 with ρ ≤ 0.22; drag gives 0.2–1.0).
* GAP_MIN = 2: conservative gap_train ≤ 0.98 except where the LNN failed to train (eccentric Kepler at 300 steps,
  2.9 → inconclusive); drag on the 1D oscillators / van der Pol 2.0–5.5 at 1000 steps but 0.9–1.7 at 300 steps
  and 0.1–0.25 for Kepler + drag (the free MLP fits Kepler worse than the LNN), so the gap is not a
  detector by itself — it only backs a drift on too few oscillations and marks "inconclusive".
* TIME_GAIN_MIN = 1.3, TIME_ABS_MIN = 0.5 %: set on a first version that used one held-out split (drive ×1.45–×22,
  0.7–2.8 % of the force; conservative gains ≤ 1.0, time features always hurt). With leave-one-trajectory-out the
  drive gives ×1.9–×3.6 at steps=300, width=32 (seeds 0–3), helped on every trajectory; conservative ≤ 0.96 and on
  ≤ half of the trajectories.
* STILL_FALLING = 15 % and MIN_OSCILLATIONS = 2 are judgement, not tuned.
* The trajectory-level thresholds Z_BOTH = 3, Z_ONE = 6, Z_CONTRA = 2 are z-scores (standard errors inflated for
  correlated blocks; shooting: max of jackknife and model), set before looking at the stress set; on it
  (tests/fixtures/recordings.py, benchmarks/detect_recordings.py) the conservative recordings gave |z| ≤ 1.7 for
  both statistics and the damped ones z ≥ 4.1 (shooting) and ≥ 34 (energy).
* FIT_ERROR_RATIO = 3 and FIT_ERROR_NONE = 1.5 (a learned-energy trend against the Lagrangian's own fit error):
  measured as their comments below say.
* EFFECT_MIN = 1e-5 of the energy per period (0.001 %/period): a z-score says how sure a change is, not that it is
  physics. On exact data a learned Lagrangian's own bias can trend at a high z: one trajectory of the conservative
  Morse oscillator (benchmarks/trust_table.py, seed 0, 2026-11-27) gave an energy trend of 1.2e-7 per period at
  z = 16.9 (a "detection", confidence 0.48) and 3.8e-8 at z = 5.7; the smallest change of a detected
  non-conservative case in the stored benchmarks is 1.8e-2 per period. The floor sits between, 80× above the first
  and 1800× below the second; a real loss below it (a resonator of Q > 6·10⁵) is reported as no change. NOISE_REL_MAX = 0.3,
  MIN_SAMPLES_PER_PERIOD = 6 (per period, or per 2π·rms(q̇)/rms(q̈) without one), QDD_ERR_MAX = 50 %,
  CLOCK_MIN_TRAJ = 3 and CLOCK_MANY_TRAJ = 8 are judgement (white noise gives σ/std ≈ 1 and q̈ errors > 100 %; a
  cosine sampled every 2.9 s has 2.2 samples per period).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from nnphd.engine.evidence import percent_per_period, velocity_time_scale
from nnphd.user.result import Status

__all__ = [
    "net_power_fraction",
    "energy_net_fraction",
    "slow_energy_ratio",
    "time_design",
    "ridge_fit_predict",
    "drift_check",
    "time_check",
    "gap_check",
    "capacity_check",
    "clock_testable",
    "trajectory_evidence",
    "data_quality",
    "motion_time_scale",
    "by_learned_power",
]

# thresholds (see the module docstring for how they were set)
RHO_MIN = 0.5
RHO_LOW = 0.25
Z_MIN = 2.0
DRIFT_MIN = 0.01
MIN_OSCILLATIONS = 2.0
TIME_GAIN_MIN = 1.3
TIME_ABS_MIN = 0.005
GAP_MIN = 2.0
STILL_FALLING = 0.15
Z_BOTH = 3.0  # trajectory-level: energy trend and shooting both at least this, same sign
Z_ONE = 6.0  # or one of them at least this while the other does not contradict it
Z_CONTRA = 2.0  # a |z| of the other statistic of opposite sign above this contradicts
# effect-size floor of the record-level statistics: an energy change below this fraction per period (the trend's
# r·period; the shooting probe's 2·d·period) counts as no change, however significant (see the docstring)
EFFECT_MIN = 1e-5
# a learned-energy trend counts only when its change over the record is at least this multiple of the energy the
# residual's power moves in and out within one period (:func:`within_fit_error`). Measured (internal seeds 0, 1 of
# `detect --seed 0`; nnphd.astro.controls and the damped records of benchmarks/): conservative — the Moon about the
# Earth over a year (DE405; its Kepler energy has no trend: −1e-6 per orbit) 1.1 and 1.2 with the learned energy
# decaying at z = 8 and 10; a LAGEOS-like satellite under J2 0.39 and 0.06 (z = −414, −88), in the Earth-fixed frame
# 0.24 and 2.35 (z = 4.1); the Earth in a frame turning with Jupiter 3.7 and 3.1 — damped: a real seismometer 5.9 and
# 6.5, the camera double-pendulum look-alike 6.8 and 7.4, a real encoder pendulum 14 and 17, the string pendulum
# look-alike 42. The threshold sits in that gap, closer to the conservative side; a rotating frame reached 3.7, so it
# is no guarantee: a conservative record above it still needs a second statistic or Z_ONE to be "detected"
FIT_ERROR_RATIO = 3.0
# ... and below this multiple the trend is within a single period's fit error: it counts as no change at all (the
# Moon's 1.1, 1.2); between the two a significant trend makes a "none" "inconclusive" — the camera look-alike of a
# damped double pendulum (two 10-s takes) reached only 2.1 and 2.3 (z = 4.7, 8.8), below the rotating Earth's 3.7
FIT_ERROR_NONE = 1.5
NOISE_REL_MAX = 0.3  # positions with noise/spread above this (every coordinate): no usable dynamics
MIN_SAMPLES_PER_PERIOD = 6.0
QDD_ERR_MAX = 0.5  # estimated relative q̈ error above this (every coordinate): no pointwise test
CLOCK_MIN_TRAJ = 3
CLOCK_MANY_TRAJ = 8
N_BOOT = 200


# ------------------------------------------------------------------------------------------------------------------
# checks on plain arrays (unit-tested on synthetic inputs)


def _trapz(y, x) -> float:
    return float(np.sum(0.5 * (y[1:] + y[:-1]) * np.diff(x)))


def net_power_fraction(power, t, segs) -> tuple[np.ndarray, np.ndarray]:
    """Per segment (∫P dt, ∫|P| dt) by the trapezoid rule; ρ = |first| / second."""
    net, tot = [], []
    for s in segs:
        p, ts = np.asarray(power, float)[s], np.asarray(t, float)[s]
        net.append(_trapz(p, ts))
        tot.append(_trapz(np.abs(p), ts))
    return np.asarray(net), np.asarray(tot)


def slow_energy_ratio(power, t, segs, n_osc) -> np.ndarray:
    """Per segment: excursion of the energy averaged over one oscillation over the typical ∫|P| dt of one oscillation.

    E(t) = ∫P dt (cumulative trapezoid). The segment is cut into windows of one oscillation (len / n_osc samples);
    Z = (max − min of the window means of E) / median over windows of ∫|P| dt. A state function on periodic motion
    has equal window means (Z ≲ 1); a steady drift or a slow exchange of energy (beats of a drive) gives
    Z ~ its duration in oscillations.
    """
    out = []
    for s, k in zip(segs, np.asarray(n_osc, float)):
        p, ts = np.asarray(power, float)[s], np.asarray(t, float)[s]
        if len(s) < 6 or k < 2:
            out.append(0.0)
            continue
        e = np.concatenate([[0.0], np.cumsum(0.5 * (p[1:] + p[:-1]) * np.diff(ts))])
        w = max(3, int(round(len(s) / k)))
        nw = len(s) // w
        means = [float(np.mean(e[i * w : (i + 1) * w])) for i in range(nw)]
        tvs = [_trapz(np.abs(p[i * w : (i + 1) * w]), ts[i * w : (i + 1) * w]) for i in range(nw)]
        med = float(np.median(tvs))
        out.append((max(means) - min(means)) / med if med > 0 else 0.0)
    return np.asarray(out)


def energy_net_fraction(E, segs) -> np.ndarray:
    """Per segment |E_end − E_start| / Σ|ΔE| (the same ratio from energies instead of powers)."""
    out = []
    for s in segs:
        e = np.asarray(E, float)[s]
        tv = float(np.sum(np.abs(np.diff(e))))
        out.append(abs(e[-1] - e[0]) / tv if tv > 0 else 0.0)
    return np.asarray(out)


def drift_check(power, t, segs, scale, n_osc=None, n_boot: int = N_BOOT, seed: int = 0) -> dict:
    """Net power of a residual over trajectories (segments).

    power: P (N,) at the samples; scale: per-segment energy scale (⟨|q̇ᵀMq̇|⟩); n_osc: per-segment oscillation counts
    (None: the oscillation-based parts are skipped). Per segment: ρ = |∫P dt|/∫|P| dt, m = |∫P dt|/scale and the slow
    ratio Z (:func:`slow_energy_ratio`). ``significant``: median m ≥ DRIFT_MIN and (median ρ ≥ RHO_MIN, or median
    ρ ≥ RHO_LOW and median Z ≥ Z_MIN). ``bootstrap_fraction``: the fraction of replicas (segments resampled with
    replacement) that are significant. ``valid``: median oscillations ≥ MIN_OSCILLATIONS.
    """
    net, tot = net_power_fraction(power, t, segs)
    scale = np.maximum(np.asarray(scale, float), 1e-300)
    rho = np.where(tot > 0, np.abs(net) / np.maximum(tot, 1e-300), 0.0)
    mag = np.abs(net) / scale
    K = len(segs)
    z = slow_energy_ratio(power, t, segs, n_osc) if n_osc is not None else np.zeros(K)

    def passes(i):
        r, m, zz = np.median(rho[i]), np.median(mag[i]), np.median(z[i])
        return bool(m >= DRIFT_MIN and (r >= RHO_MIN or (r >= RHO_LOW and zz >= Z_MIN)))

    rng = np.random.default_rng(seed)
    boot = [passes(rng.integers(0, K, K)) for _ in range(n_boot)] if K > 1 else [passes(np.arange(K))]
    return {
        "rho": rho.tolist(),
        "magnitude": mag.tolist(),
        "slow_ratio": z.tolist(),
        "rho_median": float(np.median(rho)),
        "magnitude_median": float(np.median(mag)),
        "slow_ratio_median": float(np.median(z)),
        "significant": passes(np.arange(K)),
        "bootstrap_fraction": float(np.mean(boot)),
        "oscillations": None if n_osc is None else np.asarray(n_osc).tolist(),
        "valid": True if n_osc is None else bool(np.median(n_osc) >= MIN_OSCILLATIONS),
    }


def time_check(err_state, err_timed, force_norm, improved_fraction: float | None = None) -> dict:
    """Do time features help predict the conservative residual on trajectories the fit did not see?

    err_state / err_timed: out-of-sample errors of the regressions without / with time features (same norm as
    ``force_norm``); improved_fraction: the fraction of trajectories on which the time features helped. Significant:
    ratio ≥ TIME_GAIN_MIN, (err_state − err_timed) ≥ TIME_ABS_MIN·force_norm and (if given) improved_fraction > ½.
    """
    tiny = 1e-12 * max(force_norm, 1e-300)
    g = err_state / max(err_timed, tiny)
    gain = (err_state - err_timed) / max(force_norm, 1e-300)
    most = improved_fraction is None or improved_fraction > 0.5
    return {
        "gain": float(g),
        "abs_gain": float(gain),
        "improved_fraction": improved_fraction,
        "significant": bool(g >= TIME_GAIN_MIN and gain >= TIME_ABS_MIN and most),
    }


def gap_check(cons_train, free_train, cons_test, free_test) -> dict:
    """Conservative error over the best free model's, on training and held-out data."""
    g_tr = cons_train / max(free_train, 1e-300)
    g_te = cons_test / max(free_test, 1e-300)
    return {"gap_train": float(g_tr), "gap_test": float(g_te), "large": bool(g_tr >= GAP_MIN), "gap_min": GAP_MIN}


def capacity_check(errors: Sequence[float]) -> dict:
    """Errors of the conservative model after successive rounds of training: still falling?"""
    e = np.asarray(errors, float)
    drop = float(1.0 - e[-1] / e[0]) if e[0] > 0 else 0.0
    return {
        "errors": e.tolist(),
        "relative_drop": drop,
        "still_falling": bool(drop > STILL_FALLING),
        "threshold": STILL_FALLING,
    }


def _poly_features(x, degree: int) -> np.ndarray:
    """All monomials of the columns of x up to ``degree`` (including the constant)."""
    from itertools import combinations_with_replacement

    cols = [np.ones(len(x))]
    for d in range(1, degree + 1):
        for idx in combinations_with_replacement(range(x.shape[1]), d):
            cols.append(np.prod(x[:, list(idx)], axis=1))
    return np.stack(cols, axis=1)


def time_design(state, feats, degree: int = 3) -> tuple[np.ndarray, np.ndarray]:
    """Design matrices (state-only, state + time) for the time check: monomials of the state up to ``degree``, then
    the time features times (1, state)."""
    base = _poly_features(state, degree)
    lin = np.concatenate([np.ones((len(state), 1)), state], axis=1)
    timed = (feats[:, :, None] * lin[:, None, :]).reshape(len(state), -1)
    return base, np.concatenate([base, timed], axis=1)


def ridge_fit_predict(X_tr, y_tr, X_te, alpha: float = 1e-3) -> np.ndarray:
    """Ridge regression on columns scaled to unit RMS (penalty alpha·N), prediction on X_te."""
    s = np.sqrt(np.mean(X_tr**2, axis=0))
    s = np.where(s > 0, s, 1.0)
    A = X_tr / s
    coef = np.linalg.solve(A.T @ A + alpha * len(A) * np.eye(A.shape[1]), A.T @ y_tr)
    return (X_te / s) @ coef


# ------------------------------------------------------------------------------------------------------------------
# models


def clock_testable(t, segs) -> tuple[bool, str]:
    """Can explicit time dependence be told from a trajectory label? Only when the trajectories overlap in time
    (every one shares some time range with another) and there are at least CLOCK_MIN_TRAJ of them, or there are
    CLOCK_MANY_TRAJ or more."""
    K = len(segs)
    if K < 2:
        return False, "one trajectory: time and state are confounded along it"
    t = np.asarray(t, float)
    rng_ = [(float(t[s].min()), float(t[s].max())) for s in segs]
    overlaps = [
        any(i != j and min(b1, b2) > max(a1, a2) for j, (a2, b2) in enumerate(rng_)) for i, (a1, b1) in enumerate(rng_)
    ]
    if K >= CLOCK_MANY_TRAJ:
        return True, f"{K} trajectories"
    if K >= CLOCK_MIN_TRAJ and all(overlaps):
        return True, f"{K} trajectories overlapping in time"
    if not all(overlaps):
        return False, (
            f"{K} trajectories, {sum(not o for o in overlaps)} of them at times no other trajectory "
            "covers: t would only tell the trajectories apart"
        )
    return False, f"only {K} trajectories (at least {CLOCK_MIN_TRAJ} overlapping in time are needed)"


# ------------------------------------------------------------------------------------------------------------------
# trajectory-level evidence and the status of one seed


def trajectory_evidence(trend: dict, shoot: dict, replicas: tuple = ((), ())) -> dict:
    """Combine the energy trend and the shooting fit into one call: ``significant`` when both are valid, agree in
    sign (energy falls ⇔ damping d̄ > 0) and both reach Z_BOTH, or either alone reaches Z_ONE while the other does
    not contradict it (same sign or invalid); ``bound``: with no significant evidence, the 95 % upper limit on the
    decay rate |r| + 2 se of the energy trend (file units) when it is valid. ``bootstrap_fraction``: the share of
    window/block bootstrap replicas that stay significant (the two bootstraps paired replica by replica;
    ``replicas``: the z of the energy trend's and of the shooting fit's replicas)."""
    zt = trend.get("z", 0.0) if trend.get("valid") else None
    zs = shoot.get("z", 0.0) if shoot.get("valid") else None
    tiny = negligible_effect(trend, shoot)
    own = within_fit_error(trend)
    # a trend the fit error may have made: no evidence of a change, but where it is beyond one period's fit error
    # (FIT_ERROR_NONE) and significant it is no evidence of its absence either — its z is kept for the reasons
    # (:func:`_weak_evidence`: "inconclusive", never "none"), not for a detection
    undecided = own and not tiny["energy"] and fit_error_ratio(trend) >= FIT_ERROR_NONE
    zt_measured = zt  # (zeroed below where the trend does not count)
    if own:
        tiny["energy"] = True
    if tiny["energy"]:
        zt = 0.0
    if tiny["shooting"]:
        zs = 0.0

    def rule(a, b):
        if a is not None and b is not None:
            if np.sign(a) == np.sign(b) and min(abs(a), abs(b)) >= Z_BOTH:
                return True
            if abs(a) >= Z_ONE and (np.sign(a) == np.sign(b) or abs(b) < Z_CONTRA):
                return True
            if abs(b) >= Z_ONE and (np.sign(a) == np.sign(b) or abs(a) < Z_CONTRA):
                return True
            return False
        x = a if a is not None else b
        return x is not None and abs(x) >= Z_ONE

    sig = rule(zt, zs)
    bt = [] if tiny["energy"] else list(replicas[0])
    bs = [] if tiny["shooting"] else list(replicas[1])
    nb = max(len(bt), len(bs))
    reps = [
        rule(bt[i] if i < len(bt) and zt is not None else zt, bs[i] if i < len(bs) and zs is not None else zs)
        for i in range(nb)
    ]
    sign = np.sign(zt if zt is not None and (zs is None or abs(zt) >= abs(zs)) else (zs or 0.0))
    bound = None
    if trend.get("valid") and np.isfinite(trend.get("se", np.inf)):
        bound = abs(trend["rate"]) + 2 * trend["se"]
        if own:  # a trend the fit error can make: the bound is what the fit error can hide
            fe = trend["fit_error"]
            bound = max(bound, FIT_ERROR_RATIO * fe["gross_smooth"] / (fe["periods"] * trend["period"]))
    return {
        "significant": bool(sig),
        "within_fit_error": own,
        "negligible": [k for k, v in tiny.items() if v and not (k == "energy" and own)],
        "z_energy": zt_measured if undecided else zt,
        "z_shooting": zs,
        "direction": "loses energy" if sign > 0 else ("gains energy" if sign < 0 else "none"),
        "valid": zt is not None or zs is not None,
        "bootstrap_fraction": float(np.mean(reps)) if reps else None,
        "rate_bound": bound,
    }


def fit_error_ratio(trend: dict) -> float:
    """The learned energy's change over the record (|r·period|·periods) over the energy the residual's power moves
    in and out within one period (:func:`nnphd.engine.evidence.fit_error_bound`); NaN when not computed."""
    fe = trend.get("fit_error") or None
    rp = trend.get("rate_per_period", float("nan"))
    if fe is None or not np.isfinite(rp) or not fe.get("gross_smooth"):
        return float("nan")
    return float(abs(rp) * fe["periods"] / fe["gross_smooth"])


def within_fit_error(trend: dict) -> bool:
    """Is the learned energy's change over the record within what the learned Lagrangian's own fit error can make?
    The change |r·period|·periods (the trend over the median trajectory) below FIT_ERROR_RATIO × the energy the
    residual's power moves in and out within one period (``gross_smooth`` of
    :func:`nnphd.engine.evidence.fit_error_bound`). Such a trend does not count, however significant its z."""
    if not trend.get("valid") or not trend.get("oscillating", True):
        return False  # (motion that does not oscillate has its own, stricter rule: both statistics must agree)
    return bool(fit_error_ratio(trend) < FIT_ERROR_RATIO)  # (NaN: not computed, False)


def negligible_effect(trend: dict, shoot: dict) -> dict:
    """Which record-level statistic measures a change of the energy below EFFECT_MIN per period (then it counts as
    z = 0): the energy trend's |r·period|, the shooting probe's 2·|d|·period (its energy-decay rate is 2d). Only on
    oscillating motion with a finite period (a throw has none)."""
    period = trend.get("period", float("nan"))
    if not (trend.get("oscillating", True) and np.isfinite(period) and period > 0):
        return {"energy": False, "shooting": False}
    rp = trend.get("rate_per_period", float("nan"))
    d = shoot.get("d_mean", float("nan"))
    return {
        "energy": bool(trend.get("valid") and np.isfinite(rp) and abs(rp) < EFFECT_MIN),
        "shooting": bool(shoot.get("valid") and np.isfinite(d) and 2 * abs(d) * period < EFFECT_MIN),
    }


def _both_agree(traj: dict) -> bool:
    """Both record-level statistics valid, of one sign and at least Z_BOTH."""
    zt, zs = traj.get("z_energy"), traj.get("z_shooting")
    return zt is not None and zs is not None and np.sign(zt) == np.sign(zs) and min(abs(zt), abs(zs)) >= Z_BOTH


def effect_text(traj: dict, trend: dict, shoot: dict) -> str:
    """ "energy decays 3.2 %/period (r = 0.011/time unit), z = 41" from the evidence (motion that does not oscillate:
    per block of a fraction of the record, :func:`nnphd.engine.evidence.evidence_block`)."""
    parts = []
    if trend.get("valid"):
        r, rp = trend["rate"], trend.get("rate_per_period", float("nan"))
        word = "decays" if r > 0 else "grows"
        unit = "period" if trend.get("oscillating", True) else "block"
        blocks = f"{trend['n_blocks']} {unit}s" + ("" if unit == "period" else f" of {trend['period']:.3g}")
        parts.append(
            f"the learned energy {word} {percent_per_period(rp):.2g}%/{unit} (rate {abs(r):.3g} per time unit, "
            f"z = {trend['z']:.1f} over {blocks})"
        )
    if shoot.get("valid"):
        parts.append(
            f"a fit of the positions by integration over {shoot['n_windows']} windows needs damping "
            f"d = {shoot['d_mean']:.3g} ± {shoot['se_d_mean']:.2g} per time unit (z = {shoot['z']:.1f})"
        )
    if traj.get("within_fit_error"):
        fe = trend["fit_error"]
        parts.append(
            f"the learned energy changes {100 * abs(trend['rate_per_period']) * fe['periods']:.2g}% over the record, "
            f"less than {FIT_ERROR_RATIO:g}× the {100 * fe['gross_smooth']:.2g}% of it that the residual of the "
            "learned Lagrangian moves in and out within one period — its own fit error can make such a trend, "
            + (
                "so it does not count however significant"
                if fit_error_ratio(trend) < FIT_ERROR_NONE
                else f"so it is no evidence of a change, nor (beyond {FIT_ERROR_NONE:g}×) of its absence"
            )
        )
    if traj.get("negligible"):
        names = " and ".join({"energy": "the energy trend", "shooting": "the damping"}[k] for k in traj["negligible"])
        parts.append(
            f"{names} below {100 * EFFECT_MIN:g}%/period, too small to count however significant (a learned "
            "Lagrangian's own bias reaches that on exact conservative data)"
        )
    return "; ".join(parts) if parts else "no trajectory-level statistic could be computed"


def seed_status(drift, tchk, gap, cap, traj=None, quality=None, n_traj=1) -> tuple[Status, str, float]:
    """(status, reason, agreement of the bootstrap with the status) of one seed.

    Order: (1) explicit time dependence (only where the clock is testable); (2) trajectory-level evidence (energy
    trend, shooting) — decisive on single trajectories and when the force is below the derivative noise;
    (3) net power of the pointwise residual over several trajectories; then "inconclusive" when the derivatives
    are too noisy for a pointwise test or the conservative model under-fits, else "none" with the upper limit.
    """
    traj = traj or {"significant": False, "valid": False, "bootstrap_fraction": None, "rate_bound": None}
    quality = quality or {"pointwise_ok": True, "usable": True, "reason": ""}
    eff = traj.get("effect", "")
    if not quality["usable"]:
        return (Status.INCONCLUSIVE, f"the data cannot decide: {quality['reason']}", 1.0)
    if not quality.get("oscillating", True):
        return _status_not_oscillating(tchk, traj, n_traj)
    if tchk["significant"] and tchk["valid"]:
        return (
            Status.DETECTED,
            f"the force depends on t explicitly: time features cut the out-of-trajectory error of a "
            f"regression of the conservative residual x{tchk['gain']:.2f} ({100 * tchk['abs_gain']:.1f}% of the "
            f"force; better on {100 * tchk['improved_fraction']:.0f}% of {tchk['n_trajectories']} trajectories)",
            1.0,
        )
    if traj["significant"]:
        return (
            Status.DETECTED,
            f"non-conservation accumulates along the record: {eff}",
            traj["bootstrap_fraction"] or 1.0,
        )
    boot = drift["bootstrap_fraction"]
    work = (
        f"median |∫P dt|/∫|P| dt = {drift['rho_median']:.2f} over {n_traj} trajector"
        f"{'y' if n_traj == 1 else 'ies'}, net energy change {100 * drift['magnitude_median']:.1f}% of 2×kinetic"
    )
    multi_ok = n_traj >= 3 and quality["pointwise_ok"]
    if drift["significant"] and multi_ok and (drift["valid"] or gap["large"]):
        return (Status.DETECTED, f"the residual of the conservative fit does net work ({work})", boot)
    clock = f"t untested ({tchk['testable']})" if not tchk["valid"] else f"t does not help (x{tchk['gain']:.2f})"
    no_traj = (
        f"no trend along the record ({eff})"
        if traj["valid"]
        else "no trajectory-level statistic (too few oscillations or windows)"
    )
    if not quality["pointwise_ok"]:
        return (
            Status.INCONCLUSIVE,
            f"derivatives too noisy for a pointwise test ({quality['reason']}) and the "
            f"trajectory-level evidence is weak: {no_traj}",
            traj["bootstrap_fraction"] or 1.0,
        )
    if drift["significant"] and not multi_ok:
        return (Status.INCONCLUSIVE, f"the pointwise residual does net work ({work}) but {no_traj}", boot)
    if gap["large"]:
        fall = (
            "still falling with training (x" if cap["still_falling"] else "flat with training (x"
        ) + f"{1 - cap['relative_drop']:.2f} over the extra rounds)"
        return (
            Status.INCONCLUSIVE,
            f"the conservative model's training error is x{gap['gap_train']:.1f} the free "
            f"model's: under-fitting, or a non-conservative force without net power (e.g. on a limit cycle); "
            f"{no_traj}; {clock}; conservative held-out error {fall}",
            1.0 - boot,
        )
    if not traj["valid"]:
        return (
            Status.INCONCLUSIVE,
            f"a Lagrangian fits the data as well as a free model (gap x{gap['gap_train']:.2f}) "
            f"but {no_traj}, so a slow loss of energy cannot be excluded; {clock}",
            1.0,
        )
    if n_traj < 3 and drift["slow_ratio_median"] >= Z_MIN:
        return (
            Status.INCONCLUSIVE,
            f"no trend of the energy along the record ({eff}), but the learned energy swings "
            f"slowly from one oscillation to the next (slow ratio Z = {drift['slow_ratio_median']:.1f} ≥ "
            f"{Z_MIN:g}): a force without net power (a drive, beats) or a Lagrangian that does not fit this "
            f"orbit; with {n_traj} trajector{'y' if n_traj == 1 else 'ies'} the two cannot be told apart; "
            f"{clock}",
            1.0,
        )
    weak = _weak_evidence(traj)
    if weak:
        return (
            Status.INCONCLUSIVE,
            f"a Lagrangian fits the data as well as a free model (gap x{gap['gap_train']:.2f}), but {weak} — "
            f'below the rule for a detection (both ≥ {Z_BOTH:g}, or one ≥ {Z_ONE:g}) yet too strong for a "none" '
            f"({eff}); a longer record would decide; {clock}",
            1.0,
        )
    bound = traj.get("rate_bound")
    lim = f"; energy change below {bound:.2g} per time unit (95% bound)" if bound is not None else ""
    agree = traj["bootstrap_fraction"]
    return (
        Status.NONE,
        f"a Lagrangian fits the data as well as a free model (gap x{gap['gap_train']:.2f}); {no_traj}{lim}; {clock}",
        1.0 - agree if agree is not None else 1.0,
    )


def by_learned_power(status: Status, drift, tchk, gap, cap, traj=None, quality=None, n_traj=1) -> bool:
    """Is this seed's "inconclusive" owed only to the pointwise net power of the learned Lagrangian's residual — the
    slow swing of its energy (Z ≥ Z_MIN) or a net power that the record-level evidence does not confirm — on fewer
    than 3 trajectories? True when :func:`seed_status` with those statistics silenced (ρ, Z and significance of the
    drift set to nothing) says "none". Such evidence comes from the learned Lagrangian alone: on one orbit that moves
    through its states (a rotating frame, precession) its own approximation error swings its energy as much
    (measured: the Earth–Moon barycentre in a frame turning with Jupiter, DE405, Z = 2.2–3.4; a J2 satellite in the
    Earth-fixed frame, Z = 2.4) as a drive off resonance does (Z = 2.1–2.2 on one trajectory), so a fit of the
    positions decides (:func:`nnphd.user.rules.reconcile`)."""
    if status != Status.INCONCLUSIVE or n_traj >= 3:
        return False
    quiet = drift | {"rho_median": 0.0, "slow_ratio_median": 0.0, "significant": False}
    return seed_status(quiet, tchk, gap, cap, traj, quality, n_traj)[0] == Status.NONE


def _weak_evidence(traj: dict) -> str:
    """Why the record-level evidence contradicts a "none" though it is no detection, or "": one statistic (energy
    trend or shooting probe) at |z| ≥ Z_BOTH. A "none" is a claim that nothing is seen; a 4.5σ energy loss is
    something (measured: 12-s pieces of a real double pendulum gave one seed "none" with its learned energy decaying
    at z = 4.5 and the probe at z = 0.8, the other seed "detected" at z = 6.3)."""
    parts = [
        f"the {name} is at z = {z:.1f}"
        for name, z in (("energy trend", traj.get("z_energy")), ("shooting probe", traj.get("z_shooting")))
        if z is not None and abs(z) >= Z_BOTH
    ]
    return " and ".join(parts)


def _status_not_oscillating(tchk, traj, n_traj) -> tuple[Status, str, float]:
    """The status of one seed when the motion does not oscillate (a throw, a fall, a coast-down, an arc of an orbit).

    Such a path never returns to a state it has visited, so a conservative Lagrangian can shape its potential to
    follow it whatever force acts (in 1-D V(q) = E − ½q̇(q)² reproduces every monotonic motion exactly): the LNN
    can absorb a drag, and a silent record is no evidence of conservation — never "none". Measured (
    throws of 1.2 s at 60 Hz, 2 mm noise, with 7.8 % quadratic drag and without, three noise draws × two seeds;
    1-D falls with and without drag): the LNN absorbed the drag every time — both record-level statistics |z| ≤ 2.2
    with drag and without (the energy's z even negative with drag) — four throws with drag from one point gave a
    wrong "none" under the oscillation rules, and four drag-free ones a clock "detection" (the time since release
    is the state along every throw). So "detected" only when both record-level statistics agree
    (:func:`_both_agree`), else "inconclusive"."""
    eff = traj.get("effect", "")
    if traj["significant"] and _both_agree(traj):
        return (
            Status.DETECTED,
            f"non-conservation accumulates along the record: {eff}",
            traj["bootstrap_fraction"] or 1.0,
        )
    many = f"{n_traj} trajector{'y' if n_traj == 1 else 'ies'}"
    clock = ""
    if tchk.get("significant") and tchk.get("valid"):
        clock = (
            f"; time features help (x{tchk['gain']:.2f}) but the time since each trajectory began is part of its "
            "state on motion that does not return, so that is no evidence of a clock either"
        )
    return (
        Status.INCONCLUSIVE,
        f"the motion does not oscillate ({many}): it never returns to a state it has visited, so a conservative "
        f"Lagrangian can shape its potential to follow it whatever force acts (in 1-D V(q) = E − ½q̇(q)² reproduces "
        f"any monotonic motion exactly) and a drag can hide in the fitted potential; record-level evidence: "
        f"{eff if traj['valid'] else 'none could be computed'}"
        + (
            f" (with no oscillation both statistics must reach |z| ≥ {Z_BOTH:g} with one sign)"
            if traj["significant"]
            else ""
        )
        + f"{clock}; motion that oscillates (returns to its states) can decide",
        1.0,
    )


# ------------------------------------------------------------------------------------------------------------------
# can the data decide?


TIME_SCALES = {
    "oscillation": "oscillation",
    "velocity": "2π × the time in which the velocity changes by its own size (the motion does not oscillate)",
    "record": "record duration (the motion does not oscillate, and its velocity changes more slowly or its q̈ is noise)",
}


def motion_time_scale(period: float, t, qd, qdd, segs, derivative_error=None) -> tuple[float, str]:
    """(the time scale of the motion, its kind — a key of TIME_SCALES) for the sampling gate of :func:`data_quality`.

    Oscillating motion (``period`` finite, :func:`nnphd.engine.evidence.dominant_period`): the period. Motion that does
    not oscillate (a throw, a fall, a coast-down, an arc of an orbit) has no period; its time scale is 2π·τ with τ
    the time in which the velocity changes by its own size, rms(q̇)/rms(q̈) per coordinate, the smallest over the
    coordinates whose q̈ is resolved (estimated relative error ``derivative_error`` below QDD_ERR_MAX, or unknown) —
    for q = A cos ωt that is the period again — at most the median duration of a trajectory (2πτ beyond it: the
    velocity hardly changes over the record; with no resolved q̈, the duration itself)."""
    if np.isfinite(period) and period > 0:
        return float(period), "oscillation"
    t = np.asarray(t, float)
    span = float(np.median([t[s][-1] - t[s][0] for s in segs]))
    qd = np.atleast_2d(np.asarray(qd, float))
    n = qd.shape[1]
    err = [None] * n if derivative_error is None else list(derivative_error)
    cols = [j for j in range(n) if err[j] is None or not np.isfinite(err[j]) or err[j] < QDD_ERR_MAX]
    scale = 2 * np.pi * velocity_time_scale(qd, qdd, segs, cols) if cols else np.inf
    return (float(scale), "velocity") if scale < span else (span, "record")


def data_quality(period_samples: float, noise_rel, derivative_error=None, time_scale: str = "oscillation") -> dict:
    """Can these data decide at all, and can a pointwise test see anything?

    ``noise_rel`` (n,): position noise over the spread of each coordinate. ``usable`` is False when the positions
    are mostly noise (σ/std ≥ NOISE_REL_MAX for every coordinate) or the motion is sampled below
    MIN_SAMPLES_PER_PERIOD samples per time scale (derivatives, periods and integration all fail there).
    ``period_samples``: samples per time scale of the motion (:func:`motion_time_scale`), ``time_scale`` its kind:
    the oscillation period, or for motion that does not oscillate the time in which the velocity changes (×2π) or
    the record's duration. ``pointwise_ok`` is False when the estimated relative q̈ error (``derivative_error``,
    per coordinate, from nnphd.user.derivatives) exceeds QDD_ERR_MAX for every coordinate.
    """
    noise_rel = np.asarray(noise_rel, float)
    reasons, usable = [], True
    if np.all(noise_rel >= NOISE_REL_MAX):
        usable = False
        reasons.append(
            f"the positions are mostly noise (noise/spread σ/std = {np.min(noise_rel):.2f} for every "
            f"coordinate, ≥ {NOISE_REL_MAX:g})"
        )
    if period_samples < MIN_SAMPLES_PER_PERIOD:
        usable = False
        reasons.append(
            f"the motion is sampled far below its time scale ({period_samples:.1f} samples per "
            f"{TIME_SCALES[time_scale]}, at least {MIN_SAMPLES_PER_PERIOD:g} are needed)"
        )
    err = (
        None if derivative_error is None else np.asarray([np.nan if e is None else e for e in derivative_error], float)
    )
    pointwise_ok = True
    if err is not None and np.all(np.isfinite(err)) and np.all(err >= QDD_ERR_MAX):
        pointwise_ok = False
        reasons.append(f"the estimated relative error of q̈ is {100 * np.min(err):.0f}% or more for every coordinate")
    if not usable:
        pointwise_ok = False
    return {
        "usable": usable,
        "pointwise_ok": pointwise_ok,
        "reason": "; ".join(reasons),
        "noise_relative": noise_rel.tolist(),
        "samples_per_period": float(period_samples),
        "time_scale": time_scale,
        "oscillating": time_scale == "oscillation",
        "qdd_relative_error": None if err is None else [None if not np.isfinite(e) else float(e) for e in err],
        "thresholds": {
            "noise_rel_max": NOISE_REL_MAX,
            "min_samples_per_period": MIN_SAMPLES_PER_PERIOD,
            "qdd_err_max": QDD_ERR_MAX,
        },
    }
