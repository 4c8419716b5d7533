"""Constrained-form Lagrangians (paper section III.A.3): L = Σ_k c_k φ_k(q, q̇) with given features φ_k and learnable
coefficients c, trained jointly with the UAN.

Built-in feature sets (:data:`FEATURE_SETS`) are the paper's:

* ``double-pendulum``: L = c1 cos θ1 + c2 cos θ2 + c3 θ̇1² + c4 θ̇2² + c5 θ̇1 θ̇2 cos(θ1 − θ2)
* ``kepler`` (Neptune, GW): L = c1 ẋ² + c2 ẏ² + c3 / √(x² + y²)

Any other set is a mapping name → function(q, q̇) → scalar (see :func:`feature_lagrangian`). The overall scale of c is
not identifiable (L and αL give the same motion); :meth:`FeatureLagrangian.normalized` divides by a reference term.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Mapping

import jax
import jax.numpy as jnp
import numpy as np

from .models import ModelConfig, accel_from_lagrangian, init_uan, uan_force
from .train import TrainConfig, make_trainer, pnorm


@dataclass(frozen=True, eq=False)
class FeatureLagrangian:
    names: tuple[str, ...]
    fns: tuple[Callable, ...]  # each (q, q̇) → scalar, single sample, jax.numpy
    reference: int = 0  # index of the term the coefficients are normalised by

    def features(self, q, qd):
        return jnp.stack([f(q, qd) for f in self.fns])

    def value(self, c, q, qd):
        return c @ self.features(q, qd)

    def accel(self, c, q, qd, eps: float = 1e-6):
        """Euler–Lagrange acceleration of L = c·φ for a batch (B, n) (autodiff; the features are cheap)."""
        return jax.vmap(lambda a, b: accel_from_lagrangian(lambda x, y: self.value(c, x, y), a, b, eps))(q, qd)

    def normalized(self, c) -> np.ndarray:
        c = np.asarray(c, float)
        return c / c[self.reference]

    def formula(self, c, digits: int = 5) -> str:
        c = self.normalized(c)
        return "L ∝ " + " + ".join(f"{v:.{digits}g}·{n}" for v, n in zip(c, self.names))


def feature_lagrangian(terms: Mapping[str, Callable], reference: str | None = None) -> FeatureLagrangian:
    """A feature Lagrangian from name → function(q, q̇)."""
    if not terms:
        raise ValueError("terms must name at least one feature")
    names = tuple(terms)
    ref = names.index(reference) if reference is not None else 0
    return FeatureLagrangian(names, tuple(terms.values()), ref)


FEATURE_SETS: dict[str, FeatureLagrangian] = {
    "double-pendulum": feature_lagrangian(
        {
            "cos(θ1)": lambda q, qd: jnp.cos(q[0]),
            "cos(θ2)": lambda q, qd: jnp.cos(q[1]),
            "θ̇1²": lambda q, qd: qd[0] ** 2,
            "θ̇2²": lambda q, qd: qd[1] ** 2,
            "θ̇1θ̇2cos(θ1−θ2)": lambda q, qd: qd[0] * qd[1] * jnp.cos(q[0] - q[1]),
        },
        reference="θ̇2²",
    ),
    "kepler": feature_lagrangian(
        {
            "ẋ²": lambda q, qd: qd[0] ** 2,
            "ẏ²": lambda q, qd: qd[1] ** 2,
            "1/r": lambda q, qd: 1.0 / jnp.sqrt(q[0] ** 2 + q[1] ** 2),
        }
    ),
}
SYSTEM_FEATURES = {"double-pendulum": "double-pendulum", "neptune": "kepler", "gw": "kepler"}


@dataclass
class ConstrainedFit:
    coefs: np.ndarray
    fc: np.ndarray  # learned conservative acceleration on the data
    fn: np.ndarray  # UAN output on the data
    L_e: float
    L_b: float


def train_constrained(
    data,
    fl: FeatureLagrangian,
    lam: float = 0.2,
    steps: int = 2000,
    seed: int = 0,
    p: float | str = 1.0,
    cfg: ModelConfig | None = None,
) -> ConstrainedFit:
    """Train L = c·φ jointly with the UAN on ``data`` (paper: λ = 0.2, Adam {1e-2…1e-5}, 2000 steps); c starts at 1."""
    n = data.q.shape[1]
    cfg = cfg or ModelConfig(n=n)
    tcfg = TrainConfig(steps=steps, p=p)

    def forces(params, q, qd, t):
        return fl.accel(params["c"], q, qd, cfg.guard_eps), uan_force(params["uan"], q, qd, t, cfg)

    def loss(params, q, qd, t, qdd):
        fc, fn = forces(params, q, qd, t)
        return pnorm(fc + fn - qdd, tcfg.p), pnorm(fn, tcfg.p)

    k_init, k_train = jax.random.split(jax.random.PRNGKey(seed))
    params = {"c": jnp.ones(len(fl.names)), "uan": init_uan(k_init, cfg)}
    arrays = tuple(jnp.asarray(a) for a in (data.q, data.qd, data.t, data.qdd))
    params, _ = make_trainer(cfg, tcfg, loss_fn=loss)(params, arrays, lam, k_train)
    fc, fn = jax.jit(forces)(params, *arrays[:3])
    le, lb = loss(params, *arrays)
    return ConstrainedFit(np.asarray(params["c"]), np.asarray(fc), np.asarray(fn), float(le), float(lb))
