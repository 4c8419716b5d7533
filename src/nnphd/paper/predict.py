r"""Trajectory prediction with NNPhD, an LNN alone and a black box (paper section III.B, Fig. 4).

The damped double pendulum (γ = 0.02) is integrated with RK4 for 2000 steps of 0.1 from (θ1, θ2, θ̇1, θ̇2) = (1, 0, 0, 0).
The three models are trained on the exact accelerations at t ≤ 30 with the same optimiser, learning-rate annealing,
minibatches and number of steps, then each is fed to an RK4 integrator (dt = 0.1) from the true state at t = 30 up to
t = 200 and compared with the truth:

* **NNPhD** (λ = 0.2): q̈ = f_c^NN (LNN, Eq. 3) + f_n^NN (UAN), loss L_e + λ L_b.
* **LNN**: the same LNN alone, q̈ = f_c^NN, loss L_e (no UAN, so it can only model energy-conserving motion).
* **black box**: an MLP (q, q̇) → q̈ with the LNN's widths and the UAN's LeakyReLU(0.2), loss L_e.

**The UAN without t.** The paper's UAN takes (q, q̇, t). Here the models must run to t = 200 after seeing only
t ≤ 30: a LeakyReLU network of t is piecewise linear in t and would extrapolate whatever t-dependence it picked up
in training (with standardised inputs, t = 200 is ≈ 20 training standard deviations away). Friction depends on q̇ only,
and the black box and the LNN see (q, q̇) too, so by default the UAN of this experiment sees (q, q̇) only
(``uan_time=False``); ``uan_time=True`` gives the paper's (q, q̇, t) UAN for comparison. (Measured at 2000 steps,
seeds 0–2: with t, the NNPhD energy RMSE over [30, 200] was 0.14 / 0.57 / diverged, without t 0.16 / 0.035 / 0.14.)

**Energy balance.** For the learned Lagrangian L the energy H = q̇·∂L/∂q̇ − L changes along the model's own motion
q̈ = f_c + f_n at the rate

.. math::  \dot H = \dot q^T\,\frac{\partial^2 L}{\partial\dot q^2}\,f_n

(the Euler–Lagrange equation H_vv f_c + H_vq q̇ − ∇_q L = 0 cancels everything else). f_n is an *acceleration*, so
its power needs the learned mass matrix ∂²L/∂q̇²; the bare f_n·q̇ is the power only for unit mass. We check (1) that a
numerical derivative of H along the NNPhD rollout matches this power (self-consistency of the learned energy
bookkeeping and of the integration), and (2) how the learned dissipation compares with the true one,
q̇ᵀ M(q) f_n^true = −γ q̇ᵀ M q̇, at the true test states. L is determined only up to a scale (L and αL give the same
motion), so (2) also reports the scale α of the learned energy (slope of H against the true energy).
"""

from __future__ import annotations

import functools
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from nnphd.engine.data import Dataset, rk4_scan, trajectory_dataset
from nnphd.engine.models import ModelConfig, free_force, init_free, init_lnn, lnn_accel, lnn_derivatives, lnn_energy
from nnphd.engine.systems import get_system
from nnphd.engine.train import TrainConfig, make_trainer, pnorm
from nnphd.io.progress import Progress, Stages
from nnphd.io.results import ensure_writable_dir, save_figure, write_json
from nnphd.paper.study_results import (
    MODELS,  # the three models, in the results' order
    THETA_TOL,  # rad: the θ1 error whose first crossing is reported
    Claim,
    Decomposition,
    EnergyBalance,
    EnergyTruth,
    LnnEnergyConstancy,
    ModelMetrics,
    PredictionResult,
)

LABELS = {"nnphd": "NNPhD", "lnn": "LNN", "blackbox": "black box"}


@dataclass(frozen=True)
class PredictionSettings:
    """What the prediction experiment (:func:`run_prediction`) runs: the ``seed`` (initialisation and
    minibatches), training ``steps`` of each model, NNPhD's ``lam``, the hidden ``widths`` of every network, the
    trajectory (``n_traj`` RK4 steps of ``dt``; training on t ≤ ``t_split``), whether the UAN sees t
    (``uan_time``), ``standardize``-d inputs and the loss ``p``. Checked (and normalised: integer widths and
    ``n_traj``, float λ) when the experiment starts."""

    seed: int = 0
    steps: int = 2000
    lam: float = 0.2
    widths: tuple[int, ...] = (200, 200)
    n_traj: int = 2000
    dt: float = 0.1
    t_split: float = 30.0
    uan_time: bool = False
    standardize: bool = True
    p: float | str = 1.0


# --------------------------------------------------------------------------------------------------------------------
# the three models: parameters and batched forces (f_c, f_n)


def init_model(kind: str, key, cfg: ModelConfig, uan_time: bool):
    """Initial parameters. NNPhD's LNN and UAN use the same subkeys as the LNN alone and the black box, so the three
    models start from the same networks where they share one."""
    k_lnn, k_uan = jax.random.split(key)
    if kind == "nnphd":
        uan = init_free(k_uan, cfg, n_time=1 if uan_time else 0)
        return {"lnn": init_lnn(k_lnn, cfg), "uan": uan}
    if kind == "lnn":
        return {"lnn": init_lnn(k_lnn, cfg)}
    if kind == "blackbox":
        return {"mlp": init_free(k_uan, cfg, n_time=0, widths=cfg.lnn_widths)}
    raise ValueError(f"unknown model {kind!r}; expected one of: {', '.join(MODELS)}")


def model_forces(kind: str, params, q, qd, t, cfg: ModelConfig, uan_time: bool):
    """(conservative, non-conservative) acceleration of a model for a batch q, q̇ (B, n), t (B,).

    The LNN alone has no non-conservative part; the black box has no split (its output is returned as f_n).
    """
    if kind == "nnphd":
        fc = lnn_accel(params["lnn"], q, qd, cfg)
        fn = free_force(params["uan"], q, qd, t if uan_time else None, cfg)
        return fc, fn
    if kind == "lnn":
        fc = lnn_accel(params["lnn"], q, qd, cfg)
        return fc, jnp.zeros_like(fc)
    if kind == "blackbox":
        fn = free_force(params["mlp"], q, qd, None, cfg)
        return jnp.zeros_like(fn), fn
    raise ValueError(f"unknown model {kind!r}; expected one of: {', '.join(MODELS)}")


@functools.lru_cache(maxsize=32)
def _trainer(kind: str, cfg: ModelConfig, tcfg: TrainConfig, uan_time: bool):
    """Compiled trainer of one model kind (cached: repeated runs in one process compile once)."""

    def loss(params, q, qd, t, qdd):
        fc, fn = model_forces(kind, params, q, qd, t, cfg, uan_time)
        return pnorm(fc + fn - qdd, tcfg.p), pnorm(fn, tcfg.p)

    return make_trainer(cfg, tcfg, loss_fn=loss)


@functools.lru_cache(maxsize=32)
def _accel_fn(kind: str, cfg: ModelConfig, uan_time: bool):
    """Single-sample q̈ = f(params, q, q̇, t) of a model (a stable object, so the rollout compiles once)."""

    def accel(params, q, qd, t):
        fc, fn = model_forces(kind, params, q[None], qd[None], jnp.reshape(t, (1,)), cfg, uan_time)
        return (fc + fn)[0]

    return accel


@functools.lru_cache(maxsize=32)
def _batch_forces(kind: str, cfg: ModelConfig, uan_time: bool):
    return jax.jit(lambda params, q, qd, t: model_forces(kind, params, q, qd, t, cfg, uan_time))


# --------------------------------------------------------------------------------------------------------------------
# rollout


@functools.partial(jax.jit, static_argnames=("accel", "n_steps"))
def _rk4_rollout(accel, params, x0, t0, dt, n_steps):
    # the same integrator as nnphd.engine.data.rk4_trajectory (shared code), with the model's parameters traced
    return rk4_scan(lambda q, qd, t: accel(params, q, qd, t), x0, dt, t0, n_steps)


def rollout(accel: Callable, params, q0, qd0, t0: float, dt: float, n_steps: int):
    """RK4 from the state (q0, q̇0) at time t0: ``accel(params, q, q̇, t)`` (single sample) is a static argument,
    ``params`` a traced pytree (so retrained parameters reuse the compilation).
    Returns numpy ``(t (n_steps+1,), q (n_steps+1, n), q̇ (n_steps+1, n))``, starting with the given state."""
    x0 = jnp.concatenate([jnp.asarray(q0, jnp.float64).ravel(), jnp.asarray(qd0, jnp.float64).ravel()])
    ts, q, qd = _rk4_rollout(accel, params, x0, jnp.float64(t0), jnp.float64(dt), int(n_steps))
    return np.asarray(ts), np.asarray(q), np.asarray(qd)


# --------------------------------------------------------------------------------------------------------------------
# metrics


def _rmse(a, b) -> float:
    d = np.asarray(a, float) - np.asarray(b, float)
    with np.errstate(over="ignore", invalid="ignore"):
        v = float(np.sqrt(np.mean(d * d)))
    return v if np.isfinite(v) else float("inf")


def _first_exceed(t, err, tol) -> float | None:
    bad = ~(np.abs(err) <= tol)  # NaN (a diverged rollout) counts as exceeding
    return float(t[np.argmax(bad)]) if bad.any() else None


def _energy_fn(system):
    return jax.jit(jax.vmap(system.energy))


def _rel_rms(a, b) -> float:
    """‖a − b‖_rms / ‖b‖_rms."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    return float(np.sqrt(np.mean((a - b) ** 2)) / max(np.sqrt(np.mean(b * b)), 1e-300))


def _corr(a, b) -> float:
    a, b = np.asarray(a, float), np.asarray(b, float)
    if not (np.all(np.isfinite(a)) and np.all(np.isfinite(b))) or a.std() == 0 or b.std() == 0:
        return float("nan")
    return float(np.corrcoef(a, b)[0, 1])


def _true_power(system, q, qd):
    """q̇ᵀ M(q) f_n^true: the rate of change of the true energy due to the true non-conservative force."""

    def one(qi, qdi):
        m = jax.hessian(lambda v: system.lagrangian(qi, v))(qdi)
        return qdi @ m @ system.f_n(qi, qdi, 0.0)

    return np.asarray(jax.jit(jax.vmap(one))(jnp.asarray(q), jnp.asarray(qd)))


def learned_power(lnn, q, qd, fn, cfg: ModelConfig):
    """q̇ᵀ (∂²L/∂q̇²) f_n: the rate of change of the learned energy H due to the learned f_n (batch)."""
    _, hvv, _ = lnn_derivatives(lnn, jnp.asarray(q), jnp.asarray(qd), cfg)
    return np.asarray(jnp.einsum("bi,bij,bj->b", jnp.asarray(qd), hvv, jnp.asarray(fn)))


# --------------------------------------------------------------------------------------------------------------------
# the experiment


def run_prediction(
    settings: PredictionSettings = PredictionSettings(),
    out: str | Path | None = None,
    progress: Progress | None = None,
) -> PredictionResult:
    """Train NNPhD, an LNN and a black box on t ≤ t_split of the damped double pendulum and extrapolate each with RK4.

    ``settings``: :class:`PredictionSettings`. Returns a :class:`nnphd.paper.study_results.PredictionResult`
    (settings, metrics per model, energy balance, claims, wall time; ``to_dict()`` is results.json's content); with
    ``out`` also writes results.json, prediction.png (θ1(t) and E(t)) and energy_balance.png there.
    """
    say = Stages(progress, 2 + 2 * len(MODELS))
    s, i_split = _checked_settings(settings)
    tcfg = TrainConfig(steps=s.steps, p=s.p)  # validates steps and p
    outdir = ensure_writable_dir(out) if out is not None else None
    t_start = time.perf_counter()

    sysm = get_system("double-pendulum")
    say(f"data: RK4 trajectory, {s.n_traj} steps of {s.dt:g}")
    data, train, test, cfg = _split_data(sysm, s, i_split)
    params, train_metrics, train_times = _train_models(train, cfg, tcfg, s, say)
    e_true, rolls, metrics = _roll_out(s, i_split, sysm, cfg, params, test, train_metrics, say)

    say("energy balance")
    balance, series = _energy_balance(sysm, cfg, params, rolls, test, s.uan_time, s.dt)
    lnn_const = _lnn_energy_constancy(cfg, params["lnn"], rolls["lnn"], test, e_true)
    decomposition = _decomposition(cfg, params["nnphd"], train, test, s.uan_time)
    claims = prediction_claims(metrics, lnn_const, e_true)

    results = PredictionResult(
        experiment=f"prediction (paper section III.B, Fig. 4): damped double pendulum, train t ≤ {s.t_split:g}, "
        f"extrapolate to t = {s.n_traj * s.dt:g} with RK4",
        settings=_settings(s, tcfg, cfg, sysm, len(train)),
        metrics={k: ModelMetrics.from_dict(m, f"metrics.{k}", "prediction") for k, m in metrics.items()},
        truth=EnergyTruth(
            energy_t_split=float(e_true[0]),
            energy_t_end=float(e_true[-1]),
            energy_loss=float(e_true[0] - e_true[-1]),
        ),
        lnn_energy_constancy=LnnEnergyConstancy(**lnn_const),
        decomposition=Decomposition(
            what="NNPhD's f_n (an acceleration, so independent of the scale of L) against the true "
            "friction −γq̇: rms values and ‖f_n − f_n^true‖_rms / ‖f_n^true‖_rms on the training "
            "and test states",
            **decomposition,
        ),
        energy_balance=EnergyBalance(**balance),
        claims=tuple(Claim(**c) for c in claims),
        jax_version=jax.__version__,
        train_time_s=train_times,
        wall_time_s=time.perf_counter() - t_start,
    )
    if outdir is not None:
        write_json(outdir / "results.json", results.to_dict())
        save_figure(plot_prediction(data, rolls, s.t_split), outdir / "prediction.png")
        save_figure(plot_energy_balance(series), outdir / "energy_balance.png")
    return results


def _checked_settings(settings: PredictionSettings) -> tuple[PredictionSettings, int]:
    """Check and normalise the settings of :func:`run_prediction` (integer widths and ``n_traj``, float λ); returns
    (the settings, the index of t_split)."""
    widths, lam, n_traj, dt, t_split = settings.widths, settings.lam, settings.n_traj, settings.dt, settings.t_split
    widths = tuple(int(w) for w in widths)
    if not widths or any(w < 1 for w in widths):
        raise ValueError(f"widths must be positive integers, got {widths}")
    lam = float(lam)
    if not (np.isfinite(lam) and lam > 0):
        raise ValueError(f"λ must be > 0, got {lam:g}")
    if isinstance(n_traj, bool) or int(n_traj) != n_traj:
        raise ValueError(f"n_traj must be an integer, got {n_traj!r}")
    n_traj = int(n_traj)
    i_split = int(round(t_split / dt))
    if not (1 <= i_split < n_traj) or abs(i_split * dt - t_split) > 1e-9 * max(1.0, t_split):
        raise ValueError(
            f"t_split must be a positive multiple of dt = {dt:g} inside the trajectory "
            f"(0, {n_traj * dt:g}), got {t_split:g}"
        )
    return replace(settings, widths=widths, lam=lam, n_traj=n_traj), i_split


def _split_data(sysm, settings: PredictionSettings, i_split: int) -> tuple:
    """The true trajectory, split at ``i_split`` into training and test parts, and the models' configuration
    (standardised on the training part). Returns (data, train, test, cfg)."""
    s = settings
    data = trajectory_dataset(sysm, n_steps=s.n_traj, dt=s.dt)
    train = data.subset(slice(0, i_split + 1))  # 0 ≤ t ≤ t_split
    test = data.subset(slice(i_split, None))  # t_split ≤ t ≤ t_end (starts with the state the rollouts start from)
    cfg = ModelConfig(n=sysm.n, lnn_widths=s.widths, uan_widths=s.widths)
    if s.standardize:
        cfg = cfg.standardized(train.q, train.qd, train.t)
    return data, train, test, cfg


def _train_models(train: Dataset, cfg, tcfg, settings: PredictionSettings, say) -> tuple:
    """Train the three models on the training part, from the same keys (NNPhD at ``settings.lam``, the others with
    λ = 0). Returns (parameters, training metrics, training times), each by model."""
    uan_time = settings.uan_time
    arrays = tuple(jnp.asarray(a, jnp.float64) for a in (train.q, train.qd, train.t, train.qdd))
    k_init, k_train = jax.random.split(jax.random.PRNGKey(settings.seed))
    lams = {"nnphd": settings.lam, "lnn": 0.0, "blackbox": 0.0}

    params, train_metrics, train_times = {}, {}, {}
    for kind in MODELS:
        say(f"training {LABELS[kind]} ({settings.steps} steps)")
        tm = time.perf_counter()
        p0 = init_model(kind, k_init, cfg, uan_time)
        params[kind], _ = _trainer(kind, cfg, tcfg, uan_time)(p0, arrays, jnp.float64(lams[kind]), k_train)
        fc, fn = _batch_forces(kind, cfg, uan_time)(params[kind], *arrays[:3])
        f = np.asarray(fc + fn)
        train_metrics[kind] = {
            "train_force_error": float(np.mean(np.abs(f - train.qdd))),  # L_e (p = 1) on the whole training set
            "train_force_rel_error": float(np.sqrt(np.mean((f - train.qdd) ** 2) / np.mean(train.qdd**2))),
        }
        train_times[kind] = time.perf_counter() - tm
    return params, train_metrics, train_times


def _roll_out(
    settings: PredictionSettings, i_split: int, sysm, cfg, params, test: Dataset, train_metrics, say
) -> tuple:
    """Integrate each trained model with RK4 from the true state at ``t_split`` and compare with the truth.
    Returns (the true energy on the test part, the rollouts by model, the metrics by model)."""
    uan_time, dt, t_split, n_traj = settings.uan_time, settings.dt, settings.t_split, settings.n_traj
    energy = _energy_fn(sysm)
    n_roll = n_traj - i_split
    e_true = np.asarray(energy(jnp.asarray(test.q), jnp.asarray(test.qd)))
    rolls, metrics = {}, {}
    for kind in MODELS:
        say(f"rollout of {LABELS[kind]} from t = {t_split:g} to {n_traj * dt:g}")
        ts, q, qd = rollout(_accel_fn(kind, cfg, uan_time), params[kind], test.q[0], test.qd[0], test.t[0], dt, n_roll)
        with np.errstate(all="ignore"):
            e = np.asarray(energy(jnp.asarray(q), jnp.asarray(qd)))
        rolls[kind] = {"t": ts, "q": q, "qd": qd, "E": e}
        err = q[:, 0] - test.q[:, 0]
        short = ts <= t_split + 10.0 + 1e-9
        finite = np.all(np.isfinite(q), axis=1) & np.all(np.isfinite(qd), axis=1)
        metrics[kind] = {
            "theta1_rmse_30_40": _rmse(q[short, 0], test.q[short, 0]),
            "theta1_rmse_30_200": _rmse(q[:, 0], test.q[:, 0]),
            "energy_rmse_30_200": _rmse(e, e_true),
            f"t_error_exceeds_{THETA_TOL:g}": _first_exceed(ts, err, THETA_TOL),
            "diverged_at": None if finite.all() else float(ts[np.argmin(finite)]),
            **train_metrics[kind],
        }
    return e_true, rolls, metrics


def _decomposition(cfg, nnphd_params, train: Dataset, test: Dataset, uan_time: bool) -> dict:
    """NNPhD's learned f_n against the true friction on the training and the test states (rms values, rel. error)."""
    decomposition = {}
    for name, d in (("train", train), ("test", test)):
        _, fn = _batch_forces("nnphd", cfg, uan_time)(nnphd_params, *(jnp.asarray(a) for a in (d.q, d.qd, d.t)))
        fn = np.asarray(fn)
        decomposition[f"fn_true_rms_{name}"] = float(np.sqrt(np.mean(d.fn**2)))
        decomposition[f"fn_learned_rms_{name}"] = float(np.sqrt(np.mean(fn**2)))
        decomposition[f"fn_rel_error_{name}"] = _rel_rms(fn, d.fn)
    return decomposition


def _settings(settings: PredictionSettings, tcfg, cfg, sysm, n_train: int) -> dict:
    """The "settings" entry of the results: everything the run depended on (``settings``: checked)."""
    s = settings
    widths = s.widths
    return {
        "seed": s.seed,
        "steps": tcfg.steps,
        "lambda": s.lam,
        "p": tcfg.p,
        "learning_rates": list(tcfg.lrs),
        "batch_size": tcfg.batch_size,
        "widths": list(widths),
        "lnn_activation": cfg.lnn_activation,
        "split_mass": cfg.split_mass,
        "uan_activation": f"{cfg.uan_activation}({cfg.leaky_slope:g})",
        "blackbox": f"MLP (q, q̇) → q̈, widths {list(widths)}, {cfg.uan_activation}({cfg.leaky_slope:g})",
        "uan_inputs": "(q, q̇, t)" if s.uan_time else "(q, q̇)",
        "uan_time": s.uan_time,
        "standardize": s.standardize,
        "system": sysm.name,
        "system_params": dict(sysm.params),
        "x0": list(sysm.x0),
        "dt": s.dt,
        "n_traj": s.n_traj,
        "t_split": s.t_split,
        "t_end": s.n_traj * s.dt,
        "n_train": n_train,
        "rollout": f"RK4, dt = {s.dt:g}, from the true state at t = {s.t_split:g}",
        "theta_tolerance": THETA_TOL,
    }


def _ddt(h, dt):
    """Time derivative of a uniformly sampled series: fourth-order central differences inside, second order next to
    the ends (np.gradient)."""
    h = np.asarray(h, float)
    d = np.gradient(h, dt, edge_order=2)
    if h.size >= 5:
        d[2:-2] = (h[:-4] - 8.0 * h[1:-3] + 8.0 * h[3:-1] - h[4:]) / (12.0 * dt)
    return d


def _energy_balance(sysm, cfg, params, rolls, test: Dataset, uan_time: bool, dt: float) -> dict:
    """(1) dH/dt (central differences along the NNPhD rollout) against q̇ᵀ H_vv f_n; (2) learned vs true dissipation
    at the true test states. See the module docstring."""
    lnn = params["nnphd"]["lnn"]
    r = rolls["nnphd"]
    q, qd, t = (jnp.asarray(r[k]) for k in ("q", "qd", "t"))
    _, fn = _batch_forces("nnphd", cfg, uan_time)(params["nnphd"], q, qd, t)
    h = np.asarray(lnn_energy(lnn, q, qd, cfg))
    dh = _ddt(h, dt)
    power = learned_power(lnn, q, qd, fn, cfg)
    naive = np.asarray(jnp.sum(qd * fn, axis=-1))
    inner = slice(2, -2)  # where the fourth-order stencil applies
    finite = bool(np.all(np.isfinite(h)) and np.all(np.isfinite(power)))

    # (2) learned vs true dissipation at the true test states
    tq, tqd, tt = (jnp.asarray(a) for a in (test.q, test.qd, test.t))
    _, fn_t = _batch_forces("nnphd", cfg, uan_time)(params["nnphd"], tq, tqd, tt)
    p_learned = learned_power(lnn, tq, tqd, fn_t, cfg)
    p_true = _true_power(sysm, test.q, test.qd)
    h_true_states = np.asarray(lnn_energy(lnn, tq, tqd, cfg))
    e_true_states = np.asarray(_energy_fn(sysm)(tq, tqd))
    alpha = float(np.polyfit(e_true_states, h_true_states, 1)[0])
    return {
        "what": "dH/dt of the learned energy H = q̇·∂L/∂q̇ − L (4th-order central differences along the NNPhD "
        "rollout) "
        "against the learned dissipated power q̇ᵀ(∂²L/∂q̇²)f_n; and the learned dissipation against the true "
        "−γ q̇ᵀM q̇ at the true test states (scale α of the learned energy: slope of H against the true E)",
        "rollout_finite": finite,
        "dHdt_vs_power_rel_rms": _rel_rms(dh[inner], power[inner]) if finite else float("nan"),
        "dHdt_vs_power_corr": _corr(dh[inner], power[inner]),
        "dHdt_vs_naive_fn_dot_qd_rel_rms": _rel_rms(dh[inner], naive[inner]) if finite else float("nan"),
        "mean_dHdt": float(np.mean(dh)),
        "mean_power": float(np.mean(power)),
        "learned_energy_scale_alpha": alpha,
        "learned_vs_true_power_corr": _corr(p_learned, p_true),
        "learned_vs_true_power_rel_rms": _rel_rms(p_learned, p_true),
        "learned_vs_alpha_true_power_rel_rms": _rel_rms(p_learned, alpha * p_true),
        "mean_learned_power_over_mean_true_power": float(np.mean(p_learned) / np.mean(p_true)),
    }, {"t": np.asarray(t), "dHdt": dh, "power": power}


def _lnn_energy_constancy(cfg, lnn_params, roll, test: Dataset, e_true) -> dict:
    """How constant the energy of the LNN-alone rollout is.

    The true energy function (what Fig. 4b plots) along the LNN rollout oscillates (the learned Lagrangian is not the
    true one), so its drift is measured between the means over the first and the last 10 time units and compared with
    the truth's. The LNN's own learned energy H is also reported: its range along the LNN rollout relative to its
    range along the true test trajectory (scale-free: L, hence H, is learned only up to a factor)."""
    loss = float(e_true[0] - e_true[-1])
    t, e = roll["t"], roll["E"]
    first = t <= t[0] + 10.0 + 1e-9
    last = t >= t[-1] - 10.0 - 1e-9
    drift_true = float(np.mean(e[last]) - np.mean(e[first]))
    truth_drift = float(np.mean(e_true[last]) - np.mean(e_true[first]))
    h = np.asarray(lnn_energy(lnn_params["lnn"], jnp.asarray(roll["q"]), jnp.asarray(roll["qd"]), cfg))
    h_truth = np.asarray(lnn_energy(lnn_params["lnn"], jnp.asarray(test.q), jnp.asarray(test.qd), cfg))
    finite = bool(np.all(np.isfinite(h)))
    return {
        "true_energy_loss": loss,
        "truth_window_mean_drift": truth_drift,
        "lnn_true_energy_window_mean_drift": drift_true,
        "lnn_true_energy_drift_over_truth_drift": abs(drift_true) / max(abs(truth_drift), 1e-300),
        "lnn_learned_energy_range": float(np.ptp(h)) if finite else float("inf"),
        "lnn_learned_energy_range_on_true_states": float(np.ptp(h_truth)),
        "lnn_learned_energy_range_ratio": (
            float(np.ptp(h)) / max(float(np.ptp(h_truth)), 1e-300) if finite else float("inf")
        ),
    }


CONSTANCY_TOL = 0.1  # the LNN's energy drift must stay below this fraction of the truth's energy drift


def prediction_claims(metrics, lnn_const, e_true) -> list[dict]:
    e = {k: metrics[k]["energy_rmse_30_200"] for k in MODELS}
    drift = lnn_const["lnn_true_energy_drift_over_truth_drift"]
    return [
        {
            "claim": "NNPhD energy RMSE over [30, 200] ≤ ½ × the black box's",
            "ours": f"NNPhD {e['nnphd']:.4g} vs ½ × {e['blackbox']:.4g} = {0.5 * e['blackbox']:.4g} "
            f"(ratio {e['nnphd'] / e['blackbox']:.3g})",
            "met": bool(e["nnphd"] <= 0.5 * e["blackbox"]),
        },
        {
            "claim": "NNPhD energy RMSE over [30, 200] < the LNN's",
            "ours": f"NNPhD {e['nnphd']:.4g} vs LNN {e['lnn']:.4g} (ratio {e['nnphd'] / e['lnn']:.3g})",
            "met": bool(e["nnphd"] < e["lnn"]),
        },
        {
            "claim": f"the LNN predicts (nearly) constant energy: the true energy of its rollout drifts (mean over "
            f"[30, 40] → mean over [190, 200]) by < {CONSTANCY_TOL:g} × the truth's drift",
            "ours": f"LNN drift {lnn_const['lnn_true_energy_window_mean_drift']:.4g} vs truth "
            f"{lnn_const['truth_window_mean_drift']:.4g} (fraction {drift:.3g}); its learned energy varies "
            f"{lnn_const['lnn_learned_energy_range_ratio']:.2g} × as much along its rollout as along the truth",
            "met": bool(drift < CONSTANCY_TOL),
        },
        {
            "claim": "the LNN cannot fit the training accelerations as well as NNPhD (training force error larger)",
            "ours": f"LNN {metrics['lnn']['train_force_error']:.3g} vs NNPhD {metrics['nnphd']['train_force_error']:.3g}",
            "met": bool(metrics["lnn"]["train_force_error"] > metrics["nnphd"]["train_force_error"]),
        },
    ]


# --------------------------------------------------------------------------------------------------------------------
# figures


def plot_prediction(data: Dataset, rolls: dict, t_split: float):
    """Fig. 4: (a) θ1(t), (b) the true energy function along truth and each model's rollout."""
    from nnphd.io.results import subplots

    energy = _energy_fn(get_system("double-pendulum"))
    e_data = np.asarray(energy(jnp.asarray(data.q), jnp.asarray(data.qd)))
    fig, (a, b) = subplots(1, 2, figsize=(12, 4))
    a.plot(data.t, data.q[:, 0], "k-", lw=1.2, label="truth")
    b.plot(data.t, e_data, "k-", lw=1.2, label="truth")
    for i, kind in enumerate(MODELS):
        r = rolls[kind]
        a.plot(r["t"], r["q"][:, 0], "-", color=f"C{i}", lw=0.9, alpha=0.85, label=LABELS[kind])
        b.plot(r["t"], r["E"], "-", color=f"C{i}", lw=0.9, alpha=0.85, label=LABELS[kind])
    for ax in (a, b):
        ax.axvspan(0, t_split, color="0.9", zorder=0)
        ax.set_xlabel("t")
        ax.legend(fontsize=8)
    a.set_ylabel(r"$\theta_1$")
    a.set_ylim(-1.6, 1.6)
    a.set_title(r"(a) $\theta_1(t)$ (training region shaded)")
    b.set_ylabel("energy E(q, q̇) (true energy function)")
    lo, hi = float(np.min(e_data)), float(np.max(e_data))
    b.set_ylim(lo - 0.3 * (hi - lo), hi + 0.3 * (hi - lo))
    b.set_title("(b) energy")
    fig.tight_layout()
    return fig


def plot_energy_balance(series: dict):
    from nnphd.io.results import subplots

    fig, ax = subplots(figsize=(7, 3.5))
    ax.plot(series["t"], series["dHdt"], "k-", lw=1.0, label="dH/dt (numerical, learned energy)")
    ax.plot(series["t"], series["power"], "C3--", lw=1.0, label=r"$\dot q^T (\partial^2 L/\partial\dot q^2) f_n$")
    ax.set_xlabel("t")
    ax.set_ylabel("power")
    ax.set_title("NNPhD rollout: energy balance")
    ax.legend(fontsize=8)
    fig.tight_layout()
    return fig
