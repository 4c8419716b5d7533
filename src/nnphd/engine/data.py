"""Data sets for NNPhD: RK4 trajectories (Table I systems) and sampled phase-space points (toy systems).

Every data set is labelled with the true acceleration q̈ = f(q, q̇, t) and, since the systems are known, with the
true split f_c (conservative) and f_n (non-conservative).
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass

import jax
import jax.numpy as jnp
import numpy as np

from nnphd.engine.systems import System, get_system

__all__ = [
    "Dataset",
    "rk4_trajectory",
    "rk4_scan",
    "label",
    "trajectory_dataset",
    "gaussian_dataset",
    "pie_dataset",
    "imbalanced_dataset",
    "train_test",
]


@dataclass(frozen=True)
class Dataset:
    """Samples (q, q̇, t) with accelerations q̈; plain numpy float64 arrays of shapes (N,n), (N,n), (N,), (N,n)."""

    q: np.ndarray
    qd: np.ndarray
    t: np.ndarray
    qdd: np.ndarray
    fc: np.ndarray | None = None
    fn: np.ndarray | None = None

    def __post_init__(self):
        for name in ("q", "qd", "t", "qdd", "fc", "fn"):
            value = getattr(self, name)
            if value is not None:
                object.__setattr__(self, name, np.asarray(value, dtype=np.float64))
        N = self.t.shape[0]
        if self.t.ndim != 1:
            raise ValueError(f"t must have shape (N,), got {self.t.shape}")
        for name in ("q", "qd", "qdd", "fc", "fn"):
            value = getattr(self, name)
            if value is not None and (value.ndim != 2 or value.shape != (N, self.q.shape[1])):
                raise ValueError(f"{name} must have shape (N, n) = ({N}, {self.q.shape[-1]}), got {value.shape}")

    @property
    def n(self) -> int:
        """Degrees of freedom."""
        return self.q.shape[1]

    def __len__(self) -> int:
        return self.t.shape[0]

    def subset(self, idx) -> Dataset:
        """Rows ``idx`` (anything numpy accepts as an index: slice, integer array, boolean mask)."""
        pick = lambda a: None if a is None else a[idx]  # noqa: E731
        return Dataset(
            q=pick(self.q), qd=pick(self.qd), t=pick(self.t), qdd=pick(self.qdd), fc=pick(self.fc), fn=pick(self.fn)
        )


# ---- integration --------------------------------------------------------------------------------------------------
def rk4_scan(f: Callable, x0, dt, t0, n_steps: int):
    """Classic RK4 for q̈ = f(q, q̇, t) as one ``lax.scan`` (to be traced inside a jitted caller); returns
    ``(t (n_steps+1,), q, q̇)`` starting with x0 = (q..., q̇...)."""
    n = x0.shape[0] // 2

    def rhs(x, t):
        q, qd = x[:n], x[n:]
        return jnp.concatenate([qd, jnp.asarray(f(q, qd, t), dtype=x.dtype).reshape(n)])

    def step(x, i):
        t = t0 + i * dt
        k1 = rhs(x, t)
        k2 = rhs(x + 0.5 * dt * k1, t + 0.5 * dt)
        k3 = rhs(x + 0.5 * dt * k2, t + 0.5 * dt)
        k4 = rhs(x + dt * k3, t + dt)
        x_new = x + dt / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
        return x_new, x_new

    _, xs = jax.lax.scan(step, x0, jnp.arange(n_steps, dtype=x0.dtype))
    xs = jnp.concatenate([x0[None], xs], axis=0)
    ts = t0 + dt * jnp.arange(n_steps + 1, dtype=x0.dtype)
    return ts, xs[:, :n], xs[:, n:]


@functools.partial(jax.jit, static_argnames=("f", "n_steps"))
def _rk4(f, x0, dt, t0, n_steps):
    return rk4_scan(f, x0, dt, t0, n_steps)


def rk4_trajectory(f: Callable, x0, dt: float, n_steps: int, t0: float = 0.0):
    """Integrate q̈ = f(q, q̇, t) with classic RK4 from the state x0 = (q..., q̇...).

    ``f`` maps single samples (q (n,), q̇ (n,), t scalar) to q̈ (n,) and must be jax-traceable; it is a static
    argument of the jitted integrator, so pass the same callable (e.g. ``system.f``) to reuse the compilation.
    Returns float64 jax arrays ``(t (n_steps+1,), q (n_steps+1, n), q̇ (n_steps+1, n))``, starting with x0.
    """
    x0 = jnp.asarray(x0, dtype=jnp.float64).reshape(-1)
    if x0.shape[0] % 2:
        raise ValueError(f"x0 must have even length 2n (q then q̇), got length {x0.shape[0]}")
    n_steps = _check_count(n_steps, "n_steps")
    dt = float(dt)
    if not dt > 0:
        raise ValueError(f"dt must be > 0, got {dt}")
    return _rk4(f, x0, jnp.float64(dt), jnp.float64(t0), n_steps)


# ---- labelling ----------------------------------------------------------------------------------------------------
@functools.lru_cache(maxsize=64)
def _labeller(system: System):
    def one(q, qd, t):
        fc = system.f_c(q, qd)
        fn = system.f_n(q, qd, t)
        return fc + fn, fc, fn

    return jax.jit(jax.vmap(one))


def label(system: System | str, q, qd, t) -> Dataset:
    """Dataset at the points (q (N,n), q̇ (N,n), t (N,)) labelled with the true f, f_c and f_n."""
    system = _as_system(system)
    q = np.asarray(q, dtype=np.float64).reshape(-1, system.n)
    qd = np.asarray(qd, dtype=np.float64).reshape(-1, system.n)
    t = np.asarray(t, dtype=np.float64).reshape(-1)
    if not (q.shape[0] == qd.shape[0] == t.shape[0]):
        raise ValueError(
            f"q, qd and t must have the same number of rows, got {q.shape[0]}, {qd.shape[0]}, {t.shape[0]}"
        )
    f, fc, fn = _labeller(system)(q, qd, t)
    return Dataset(q=q, qd=qd, t=t, qdd=np.asarray(f), fc=np.asarray(fc), fn=np.asarray(fn))


def trajectory_dataset(system: System | str, x0=None, dt: float | None = None, n_steps: int | None = None) -> Dataset:
    """RK4 trajectory of the full dynamics (defaults from the system: paper N_step 300/1000/300, dt 0.1/0.1/0.05),
    labelled with the true forces; n_steps + 1 samples including the initial state."""
    system = _as_system(system)
    x0 = system.x0 if x0 is None else x0
    if len(np.ravel(x0)) != 2 * system.n:
        raise ValueError(f"x0 must have length 2n = {2 * system.n}, got {len(np.ravel(x0))}")
    t, q, qd = rk4_trajectory(
        system.f, x0, system.dt if dt is None else dt, system.n_steps if n_steps is None else n_steps
    )
    return label(system, q, qd, t)


# ---- sampled data sets --------------------------------------------------------------------------------------------
def gaussian_dataset(system: System | str, n_samples: int, seed) -> Dataset:
    """q, q̇ (each (N, n)) and t (N,) iid standard normal (paper III.C), labelled with the true forces."""
    system = _as_system(system)
    n_samples = _check_count(n_samples, "n_samples")
    rng = np.random.default_rng(seed)
    q = rng.standard_normal((n_samples, system.n))
    qd = rng.standard_normal((n_samples, system.n))
    t = rng.standard_normal(n_samples)
    return label(system, q, qd, t)


def pie_dataset(system: System | str, n_samples: int, alpha: float, seed) -> Dataset:
    """n = 1 only: (q, q̇) in the phase-plane sector of angle [0, 2πα) measured counter-clockwise from +q.

    The angle is uniform in the sector and the radius Rayleigh(1)-distributed, i.e. an isotropic standard Gaussian
    restricted to the sector; t ~ N(0, 1).  α = 0.5 gives only q̇ ≥ 0, α = 0.25 only the first quadrant.
    """
    system = _as_system(system)
    _check_1d(system)
    n_samples = _check_count(n_samples, "n_samples")
    alpha = _check_fraction(alpha, "alpha")
    rng = np.random.default_rng(seed)
    theta = 2.0 * np.pi * alpha * rng.random(n_samples)
    r = rng.rayleigh(1.0, n_samples)
    t = rng.standard_normal(n_samples)
    return label(system, (r * np.cos(theta))[:, None], (r * np.sin(theta))[:, None], t)


def imbalanced_dataset(system: System | str, n_samples: int, beta: float, seed) -> Dataset:
    """n = 1 only: Gaussian samples with a fraction round(β N)/N having q̇ > 0 and the rest q̇ < 0 (shuffled)."""
    system = _as_system(system)
    _check_1d(system)
    n_samples = _check_count(n_samples, "n_samples")
    beta = _check_fraction(beta, "beta")
    rng = np.random.default_rng(seed)
    n_pos = int(round(beta * n_samples))
    q = rng.standard_normal(n_samples)
    speed = np.abs(rng.standard_normal(n_samples))
    speed = np.where(speed == 0.0, np.finfo(np.float64).tiny, speed)  # keep the sign well defined
    sign = np.where(np.arange(n_samples) < n_pos, 1.0, -1.0)
    qd = rng.permutation(sign) * speed
    t = rng.standard_normal(n_samples)
    return label(system, q[:, None], qd[:, None], t)


def train_test(system: System | str, seed, n_train: int = 1000, n_test: int = 1000) -> tuple[Dataset, Dataset | None]:
    """Default data of a system: two independent Gaussian sets for ``data="gaussian"`` systems, and
    ``(trajectory_dataset(system), None)`` for ``data="trajectory"`` systems (seed and sizes unused there)."""
    system = _as_system(system)
    if system.data == "trajectory":
        return trajectory_dataset(system), None
    n_train = _check_count(n_train, "n_train")
    n_test = _check_count(n_test, "n_test")
    train_seed, test_seed = np.random.SeedSequence(seed).spawn(2)
    return gaussian_dataset(system, n_train, train_seed), gaussian_dataset(system, n_test, test_seed)


# ---- argument checks ----------------------------------------------------------------------------------------------
def _as_system(system) -> System:
    if isinstance(system, System):
        return system
    if isinstance(system, str):
        return get_system(system)
    raise ValueError(f"system must be a System or a catalogue name, got {type(system).__name__}")


def _check_count(value, name: str) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
        raise ValueError(f"{name} must be an integer >= 1, got {value!r}")
    return int(value)


def _check_fraction(value, name: str) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a number in [0, 1], got {value!r}") from None
    if not 0.0 <= v <= 1.0:
        raise ValueError(f"{name} must be in [0, 1], got {value!r}")
    return v


def _check_1d(system: System) -> None:
    if system.n != 1:
        raise ValueError(f"system must have n == 1 degree of freedom, got {system.name!r} with n = {system.n}")
