"""Constrained-form Lagrangians (paper section III.A.3): L = Σ_k c_k φ_k(q, q̇) with given features φ_k and learnable
coefficients c, trained jointly with the UAN.

Built-in feature sets (:data:`FEATURE_SETS`) are the paper's:

* ``double-pendulum``: L = c1 cos θ1 + c2 cos θ2 + c3 θ̇1² + c4 θ̇2² + c5 θ̇1 θ̇2 cos(θ1 − θ2)
* ``kepler`` (Neptune, GW): L = c1 ẋ² + c2 ẏ² + c3 / √(x² + y²)

A catalogue system names its set in :attr:`nnphd.engine.systems.System.feature_set`.

Any other set is a mapping name → function(q, q̇) → scalar (see :func:`feature_lagrangian`). The overall scale of c is
not identifiable (L and αL give the same motion); :meth:`FeatureLagrangian.normalized` divides by a reference term.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from functools import cached_property

import jax
import jax.numpy as jnp
import numpy as np

from nnphd.engine.models import ModelConfig, accel_from_lagrangian, init_uan, uan_force
from nnphd.engine.train import TrainConfig, make_trainer, pnorm


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


@dataclass
class ConstrainedFit:
    coefs: np.ndarray
    fc: np.ndarray  # learned conservative acceleration on the data
    fn: np.ndarray  # UAN output on the data
    L_e: float
    L_b: float


@dataclass
class ConstrainedModel:
    """A constrained Lagrangian L = c·φ with a UAN, set up on a data set: the initial parameters, the loss for
    :func:`nnphd.engine.train.make_trainer`, and :meth:`fit` to read a trained state (see :func:`train_constrained`)."""

    params0: dict
    loss: Callable
    forces: Callable
    coefs: Callable
    arrays: tuple
    cfg: ModelConfig
    tcfg: TrainConfig
    key: jax.Array  # the minibatch key of the training run

    def trainer(self):
        return make_trainer(self.cfg, self.tcfg, loss_fn=self.loss)

    @cached_property
    def _forces_and_loss(self):  # compiled once per model: fit() is called for every λ of a sweep
        return jax.jit(lambda params, q, qd, t, qdd: (self.forces(params, q, qd, t), self.loss(params, q, qd, t, qdd)))

    def fit(self, params) -> ConstrainedFit:
        (fc, fn), (le, lb) = self._forces_and_loss(params, *self.arrays)
        return ConstrainedFit(np.asarray(self.coefs(params)), np.asarray(fc), np.asarray(fn), float(le), float(lb))


@dataclass(frozen=True, eq=False)
class ConstrainedScaling:
    """Optional scaling of a constrained model for a faint remainder (all None = the paper's setup, unchanged):

    * ``c_init`` — starting coefficients (default all ones);
    * ``coef_scale`` — scalar or per-coefficient array s_c: the coefficients are trained as c = c_init + s_c·θ with θ
      starting at 0, so Adam's steps on c are s_c times the learning rate (Adam's step size does not depend on the
      size of the gradient, so without this c cannot be resolved below ~the last learning rate, 1e-5);
    * ``uan_scale`` — the UAN's output is multiplied by it, so f_n starts at and is resolved on that scale instead
      of O(1) (set it to the size of the remainder when f_n is many orders smaller than f).

    :func:`constrained_model` checks the values against the feature set."""

    c_init: Sequence[float] | np.ndarray | None = None
    coef_scale: float | Sequence[float] | np.ndarray | None = None
    uan_scale: float | None = None


def constrained_model(
    data,
    fl: FeatureLagrangian,
    steps: int = 2000,
    seed: int = 0,
    p: float | str = 1.0,
    cfg: ModelConfig | None = None,
    *,
    scaling: ConstrainedScaling = ConstrainedScaling(),
) -> ConstrainedModel:
    """L = c·φ with a UAN on ``data``, set up for training (paper: Adam {1e-2…1e-5}, 2000 steps); c starts at 1
    unless ``scaling`` (:class:`ConstrainedScaling`, for a faint remainder) says otherwise.

    ``L_e``, ``L_b``, ``fc``, ``fn`` and ``coefs`` are always in the data's units.
    """
    n = data.q.shape[1]
    cfg = cfg or ModelConfig(n=n)
    tcfg = TrainConfig(steps=steps, p=p)
    n_c = len(fl.names)
    c_init, coef_scale, uan_scale = scaling.c_init, scaling.coef_scale, scaling.uan_scale
    if c_init is not None:
        c_init = np.asarray(c_init, dtype=np.float64)
        if c_init.shape != (n_c,) or not np.all(np.isfinite(c_init)):
            raise ValueError(f"c_init must be {n_c} finite numbers (one per feature), got {c_init!r}")
    if coef_scale is not None:
        coef_scale = np.broadcast_to(np.asarray(coef_scale, dtype=np.float64), (n_c,)).copy()
        if not np.all(np.isfinite(coef_scale) & (coef_scale > 0)):
            raise ValueError(f"coef_scale must be positive and finite, got {coef_scale!r}")
    if uan_scale is not None:
        uan_scale = float(uan_scale)
        if not (np.isfinite(uan_scale) and uan_scale > 0):
            raise ValueError(f"uan_scale must be positive and finite, got {uan_scale!r}")
    dt = jnp.dtype(cfg.dtype)  # the coefficients, the data and the UAN all train in the model's precision
    c_start = jnp.ones(n_c, dt) if c_init is None else jnp.asarray(c_init, dt)

    if coef_scale is None:

        def coefs(params):
            return params["c"]
    else:
        s_c = jnp.asarray(coef_scale, dt)

        def coefs(params):
            return c_start + s_c * params["dc"]

    def forces(params, q, qd, t):
        fn = uan_force(params["uan"], q, qd, t, cfg)
        if uan_scale is not None:
            fn = uan_scale * fn
        return fl.accel(coefs(params), q, qd, cfg.guard_eps), fn

    def loss(params, q, qd, t, qdd):
        fc, fn = forces(params, q, qd, t)
        return pnorm(fc + fn - qdd, tcfg.p), pnorm(fn, tcfg.p)

    k_init, k_train = jax.random.split(jax.random.PRNGKey(seed))
    if coef_scale is None:
        params = {"c": c_start, "uan": init_uan(k_init, cfg)}
    else:
        params = {"dc": jnp.zeros(n_c, c_start.dtype), "uan": init_uan(k_init, cfg)}
    arrays = tuple(jnp.asarray(a, dt) for a in (data.q, data.qd, data.t, data.qdd))
    return ConstrainedModel(params, loss, forces, coefs, arrays, cfg, tcfg, k_train)


def train_constrained(data, fl: FeatureLagrangian, lam: float = 0.2, **model_kw) -> ConstrainedFit:
    """Train L = c·φ jointly with the UAN on ``data`` at one λ (paper: λ = 0.2); ``model_kw`` (steps, seed, p, cfg,
    scaling) as :func:`constrained_model`."""
    cm = constrained_model(data, fl, **model_kw)
    params, _ = cm.trainer()(cm.params0, cm.arrays, lam, cm.key)
    return cm.fit(params)
