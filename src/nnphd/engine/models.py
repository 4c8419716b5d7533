r"""The NNPhD model: a Lagrangian neural network (LNN) for f_c plus a free MLP (the UAN) for f_n.

LNN (paper Eq. 3):

.. math::  \ddot q = (\nabla_{\dot q}\nabla_{\dot q}^T L)^{-1}\,[\nabla_q L - (\nabla_{\dot q}\nabla_q^T L)\,\dot q]

with :math:`L = L_{NN}(q, \dot q) + \tfrac12 a\,\dot q\cdot\dot q` (the paper's *split trick*, appendix C "Tricks to boost LNN training") and hidden units
that are half softplus, half quadratic (the *activation trick*).

The derivatives are computed by a hand-written pass over the whole batch at once (:func:`lnn_derivatives`): the
primal and the n+1 directions :math:`e_{\dot q_j}` and :math:`(\dot q, 0)` are pushed forward together (one matrix
product per layer), one backward pass gives :math:`\partial L/\partial h_l` and :math:`\nabla_z L`, and the second
derivatives follow exactly from :math:`\nabla_z^2 L = \sum_l J_l^T \mathrm{diag}(g_l\odot\sigma_l'')J_l`.
:func:`lnn_accel_reference` is the plain per-sample ``jax.hessian`` version (as in Cranmer et al.'s LNN code), kept
as the reference in tests and benchmarks.

Angles: ``ModelConfig.periodic`` lists the coordinates that are angles. The LNN then sees them through the periodic
embedding :math:`\varphi(q) = (q_{\bar P}, \sin q_P, \cos q_P)` (:func:`embed_periodic`), so L is 2π-periodic in
each of them and unwrapped angles of any size (±100 rad) stay in the range the network was trained on. With
:math:`L(q,\dot q) = F(\varphi(q), \dot q)`: :math:`\partial^2 L/\partial\dot q^2` is unchanged,
:math:`(\partial^2 L/\partial\dot q\,\partial q)\,\dot q = (\partial^2 F/\partial\dot q\,\partial\varphi)\,J_\varphi\dot q`
(only the first derivative of φ enters) and :math:`\nabla_q L = J_\varphi^T \nabla_\varphi F`.

Both paths finish in :func:`euler_lagrange_solve`, which guards the solve against a singular mass matrix with a
Tikhonov-regularised solve :math:`x = (H^2 + \varepsilon^2 I)^{-1} H\,r` (H is symmetric). For a well-conditioned H
(smallest singular value σ) the relative change is ≤ (ε/σ)², and for a singular H the output stays bounded by
|r|/(2ε) instead of becoming inf/NaN.
"""

from __future__ import annotations

import operator
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace

import jax
import jax.numpy as jnp
import numpy as np

Params = dict


# --------------------------------------------------------------------------------------------------------------------
# configuration


@dataclass(frozen=True)
class ModelConfig:
    """Architecture of an NNPhD model (defaults: the paper's appendix B, "Neural network training details")."""

    n: int
    lnn_widths: tuple[int, ...] = (200, 200)
    lnn_activation: str = "softplus+quadratic"  # half softplus, half quadratic units (activation trick)
    split_mass: float = 1.0  # a in L = L_NN + a/2 q̇·q̇ (split trick); 0 disables it
    uan_widths: tuple[int, ...] = (200, 200)
    uan_activation: str = "leaky_relu"
    leaky_slope: float = 0.2
    guard_eps: float = 1e-6  # ε of the guarded (Tikhonov) solve
    dtype: str = "float64"
    lnn_out_scale: float = 0.1  # std multiplier of the LNN output layer at init: L_NN small, so L ≈ a/2 q̇² at init
    # input standardisation: the networks see (x − shift)/scale for x = (q, q̇, t) (length 2n+1); None = identity.
    # Set from the training data with :func:`standardized`; folded into the first layer, so L stays a function of
    # the raw (q, q̇) and Eq. (3) is unchanged.
    input_shift: tuple[float, ...] | None = None
    input_scale: tuple[float, ...] | None = None
    # indices of coordinates that are angles: the LNN sees (sin q_i, cos q_i) instead of q_i (see embed_periodic).
    # Stored sorted. With input standardisation, the shift/scale of these q columns is not used by the LNN (sin/cos
    # are already O(1)); the q̇ columns and the other q columns are standardised as usual. The UAN is unchanged.
    periodic: tuple[int, ...] = ()

    def __post_init__(self):
        if self.n < 1:
            raise ValueError(f"n must be ≥ 1, got {self.n}")
        if not self.lnn_widths or any(w < 1 for w in self.lnn_widths):
            raise ValueError(f"lnn_widths must be positive integers, got {self.lnn_widths}")
        if not self.uan_widths or any(w < 1 for w in self.uan_widths):
            raise ValueError(f"uan_widths must be positive integers, got {self.uan_widths}")
        if self.dtype not in ("float32", "float64"):
            raise ValueError(f"dtype must be 'float32' or 'float64', got {self.dtype!r}")
        _activation_groups(self.lnn_activation, 2)  # validates the name
        object.__setattr__(self, "periodic", _check_periodic(self.periodic, self.n))

    def replace(self, **kw) -> ModelConfig:
        return replace(self, **kw)

    def standardized(self, q, qd, t) -> ModelConfig:
        """This config with input standardisation set from data (per-column mean and std; std 0 → 1)."""
        x = np.concatenate([np.asarray(q, float), np.asarray(qd, float), np.asarray(t, float)[:, None]], axis=1)
        mu, sd = x.mean(axis=0), x.std(axis=0)
        sd = np.where((sd > 0) & (sd > 1e-12 * np.abs(mu)), sd, 1.0)  # per column, relative: units must not matter
        return replace(self, input_shift=tuple(float(v) for v in mu), input_scale=tuple(float(v) for v in sd))


def _check_periodic(periodic, n: int) -> tuple[int, ...]:
    """Validate periodic-coordinate indices (integers in 0..n−1, no repeats); return them as a sorted tuple."""
    if isinstance(periodic, (str, bytes)) or not hasattr(periodic, "__iter__"):
        raise ValueError(f"periodic must be a sequence of coordinate indices, got {periodic!r}")
    out = []
    for i in periodic:
        if isinstance(i, (bool, np.bool_)):
            raise ValueError(f"periodic indices must be integers, got {i!r} in {tuple(periodic)!r}")
        try:
            j = operator.index(i)
        except TypeError:
            raise ValueError(f"periodic indices must be integers, got {i!r} in {tuple(periodic)!r}") from None
        if not 0 <= j < n:
            raise ValueError(f"periodic index {j} out of range for n = {n} coordinates (valid: 0..{n - 1})")
        out.append(j)
    if len(set(out)) != len(out):
        raise ValueError(f"periodic indices must be unique, got {tuple(out)!r}")
    return tuple(sorted(out))


def _periodic_split(periodic: tuple[int, ...], n: int) -> tuple[np.ndarray, np.ndarray]:
    """(non-periodic indices, periodic indices), both ascending, as static integer arrays."""
    per = np.asarray(periodic, dtype=int)
    rest = np.asarray([i for i in range(n) if i not in set(periodic)], dtype=int)
    return rest, per


def embed_periodic(q, periodic=()):
    r"""The periodic embedding φ(q) = [q_nonperiodic..., sin q_p..., cos q_p...] of q (..., n) → (..., n + len(P)).

    Both index groups are in ascending order (``periodic`` is sorted first). With ``periodic = ()`` q is returned
    unchanged. This is exactly the q part of the LNN input for ``ModelConfig(periodic=...)``; free networks can feed
    ``concatenate([embed_periodic(q, cfg.periodic), q̇, ...])`` to see the same embedding.
    """
    q = jnp.asarray(q)
    periodic = _check_periodic(periodic, q.shape[-1])
    if not periodic:
        return q
    rest, per = _periodic_split(periodic, q.shape[-1])
    qp = q[..., per]
    return jnp.concatenate([q[..., rest], jnp.sin(qp), jnp.cos(qp)], axis=-1)


# --------------------------------------------------------------------------------------------------------------------
# activations with their first and second derivatives


def _softplus(x):
    return jax.nn.softplus(x), jax.nn.sigmoid(x), jax.nn.sigmoid(x) * (1.0 - jax.nn.sigmoid(x))


def _quadratic(x):
    return 0.5 * x * x, x, jnp.ones_like(x)


def _tanh(x):
    t = jnp.tanh(x)
    return t, 1.0 - t * t, -2.0 * t * (1.0 - t * t)


_ACTS: dict[str, Callable] = {"softplus": _softplus, "quadratic": _quadratic, "tanh": _tanh}
LNN_ACTIVATIONS = ("softplus+quadratic", "softplus", "quadratic", "tanh")


def _activation_groups(name: str, width: int) -> list[tuple[Callable, int, int]]:
    """Split a layer of `width` units into contiguous groups (activation, start, stop)."""
    if name == "softplus+quadratic":
        half = (width + 1) // 2
        return [(_softplus, 0, half), (_quadratic, half, width)]
    if name in _ACTS:
        return [(_ACTS[name], 0, width)]
    raise ValueError(f"unknown LNN activation {name!r}; expected one of: {', '.join(LNN_ACTIVATIONS)}")


def _act_with_derivs(name: str, a):
    """σ(a), σ'(a), σ''(a) for a layer pre-activation a (..., width)."""
    groups = [(fn, lo, hi) for fn, lo, hi in _activation_groups(name, a.shape[-1]) if hi > lo]
    if len(groups) == 1:
        return groups[0][0](a)
    outs = [fn(a[..., lo:hi]) for fn, lo, hi in groups]
    return tuple(jnp.concatenate([o[i] for o in outs], axis=-1) for i in range(3))


# --------------------------------------------------------------------------------------------------------------------
# initialisation


def init_mlp(key, sizes, dtype="float64", out_scale=1.0) -> list:
    """Layers of an MLP with fan-ins ``sizes[:-1]``: weights N(0, 1/fan_in) (the last layer's × ``out_scale``),
    zero biases, in ``dtype``."""
    layers = []
    keys = jax.random.split(key, len(sizes) - 1)
    for i, (k, fan_in, fan_out) in enumerate(zip(keys, sizes[:-1], sizes[1:])):
        std = 1.0 / float(np.sqrt(fan_in))  # a Python float: a NumPy float64 would promote float32 weights
        if i == len(sizes) - 2:
            std *= float(out_scale)
        w = std * jax.random.normal(k, (fan_in, fan_out), dtype=dtype)
        layers.append({"w": w, "b": jnp.zeros((fan_out,), dtype)})
    return layers


def _first_layer(layers: list, cfg: ModelConfig, cols: slice) -> list:
    """Fold (x − shift)/scale of the input columns ``cols`` into the first layer's weights and bias."""
    if cfg.input_shift is None:
        return layers
    mu = jnp.asarray(cfg.input_shift, layers[0]["w"].dtype)[cols]
    sd = jnp.asarray(cfg.input_scale, layers[0]["w"].dtype)[cols]
    w = layers[0]["w"] / sd[:, None]
    return [{"w": w, "b": layers[0]["b"] - mu @ w}, *layers[1:]]


_Z = slice(0, -1)  # (q, q̇) columns of (q, q̇, t)


def _lnn_first_layer(layers: list, cfg: ModelConfig) -> list:
    """Fold the input standardisation into the LNN's first layer, whose input is [φ(q), q̇] (see embed_periodic).

    The non-periodic q and the q̇ columns get their (x − shift)/scale; the sin/cos columns are left as they are
    (the shift/scale of a periodic q column is not used). Without periodic coordinates this is ``_first_layer``.
    """
    if cfg.input_shift is None or not cfg.periodic:
        return _first_layer(layers, cfg, _Z)
    n, n_per = cfg.n, len(cfg.periodic)
    dt = layers[0]["w"].dtype
    rest, _ = _periodic_split(cfg.periodic, n)
    cols = np.concatenate([rest, np.arange(n, 2 * n)])
    keep = np.concatenate([np.arange(n - n_per), np.arange(n + n_per, 2 * n + n_per)])  # rows of those columns
    mu = np.zeros(2 * n + n_per)
    sd = np.ones(2 * n + n_per)
    mu[keep] = np.asarray(cfg.input_shift, float)[cols]
    sd[keep] = np.asarray(cfg.input_scale, float)[cols]
    w = layers[0]["w"] / jnp.asarray(sd, dt)[:, None]
    return [{"w": w, "b": layers[0]["b"] - jnp.asarray(mu, dt) @ w}, *layers[1:]]


def lnn_input_size(cfg: ModelConfig) -> int:
    """Fan-in of the LNN's first layer: 2n plus one per periodic coordinate (each q_p becomes sin, cos)."""
    return 2 * cfg.n + len(cfg.periodic)


def init_lnn(key, cfg: ModelConfig) -> list:
    sizes = (lnn_input_size(cfg), *cfg.lnn_widths, 1)
    return init_mlp(key, sizes, jnp.dtype(cfg.dtype), cfg.lnn_out_scale)


def init_free(key, cfg: ModelConfig, n_time: int = 1, widths: Sequence[int] | None = None) -> list:
    """A free MLP for :func:`free_force`: inputs [φ(q), q̇] and ``n_time`` time columns (0: none), hidden
    ``widths`` (default the UAN's), output n, in ``cfg.dtype``."""
    sizes = (lnn_input_size(cfg) + n_time, *(cfg.uan_widths if widths is None else widths), cfg.n)
    return init_mlp(key, sizes, jnp.dtype(cfg.dtype))


def widen_inputs(layers: list, n_extra: int) -> list:
    """``layers`` of an MLP with ``n_extra`` more inputs after its own, whose first-layer weights are zero: the same
    function of the inputs it had, whatever the new ones hold (see
    :func:`nnphd.user.scaling.padded_time_features`)."""
    if n_extra <= 0:
        return layers
    w = layers[0]["w"]
    return [{**layers[0], "w": jnp.concatenate([w, jnp.zeros((n_extra, w.shape[1]), w.dtype)])}, *layers[1:]]


def init_uan(key, cfg: ModelConfig) -> list:
    return init_free(key, cfg)


def init_nnphd(key, cfg: ModelConfig) -> Params:
    k1, k2 = jax.random.split(key)
    return {"lnn": init_lnn(k1, cfg), "uan": init_uan(k2, cfg)}


# --------------------------------------------------------------------------------------------------------------------
# Euler–Lagrange solve shared by every path


def euler_lagrange_solve(grad_q, hess_vv, mixed_qd, eps: float = 1e-6):
    r"""q̈ = H_vv⁻¹ (∇_q L − (∂²L/∂q̇∂q) q̇), batched over leading axes; guarded (see module doc).

    grad_q: (..., n); hess_vv: (..., n, n); mixed_qd: (..., n) = (∂²L/∂q̇∂q) q̇.
    """
    rhs = grad_q - mixed_qd
    h = 0.5 * (hess_vv + jnp.swapaxes(hess_vv, -1, -2))
    n = h.shape[-1]
    eye = jnp.eye(n, dtype=h.dtype)
    b = jnp.einsum("...ij,...j->...i", h, rhs)
    e2 = eps * eps
    if n == 1:  # closed forms for n ≤ 2: a batched LU of tiny matrices costs more than the whole network on CPU
        return b / (h[..., 0, :] ** 2 + e2)
    if n == 2:
        h00, h01, h11 = h[..., 0, 0], h[..., 0, 1], h[..., 1, 1]
        a00 = h00 * h00 + h01 * h01 + e2
        a01 = h01 * (h00 + h11)
        a11 = h01 * h01 + h11 * h11 + e2
        det = a00 * a11 - a01 * a01
        x0 = (a11 * b[..., 0] - a01 * b[..., 1]) / det
        x1 = (a00 * b[..., 1] - a01 * b[..., 0]) / det
        return jnp.stack([x0, x1], axis=-1)
    a = h @ h + e2 * eye
    return jnp.linalg.solve(a, b[..., None])[..., 0]


def lagrangian_derivatives(lagrangian: Callable, q, qd):
    """∇_q L, ∂²L/∂q̇², (∂²L/∂q̇∂q) q̇ of a scalar L(q, q̇) at one sample, by autodiff (jax.hessian)."""
    n = q.shape[-1]
    z = jnp.concatenate([q, qd])

    def lz(z):
        return lagrangian(z[:n], z[n:])

    g = jax.grad(lz)(z)
    h = jax.hessian(lz)(z)
    return g[:n], h[n:, n:], h[n:, :n] @ qd


def accel_from_lagrangian(lagrangian: Callable, q, qd, eps: float = 1e-6):
    """Acceleration of a given Lagrangian L(q, q̇) (single sample, autodiff) through :func:`euler_lagrange_solve`."""
    gq, hvv, mix = lagrangian_derivatives(lagrangian, q, qd)
    return euler_lagrange_solve(gq, hvv, mix, eps)


# --------------------------------------------------------------------------------------------------------------------
# LNN: hand-written derivative pass


def lnn_value(lnn: list, q, qd, cfg: ModelConfig):
    """Lagrangian L(q, q̇) = L_NN([φ(q), q̇]) + a/2 q̇·q̇ for a batch (B, n) → (B,); φ = :func:`embed_periodic`."""
    h = jnp.concatenate([embed_periodic(q, cfg.periodic), qd], axis=-1)
    lnn = _lnn_first_layer(lnn, cfg)
    for layer in lnn[:-1]:
        h = _act_with_derivs(cfg.lnn_activation, h @ layer["w"] + layer["b"])[0]
    out = (h @ lnn[-1]["w"] + lnn[-1]["b"])[..., 0]
    return out + 0.5 * cfg.split_mass * jnp.sum(qd * qd, axis=-1)


def _mm(x, w):
    """(S, B, i) @ (i, o) as one 2-D matrix product (XLA:CPU is much slower on the 3-D form and its gradient)."""
    s, b, i = x.shape
    return (x.reshape(s * b, i) @ w).reshape(s, b, w.shape[1])


def lnn_derivatives(lnn: list, q, qd, cfg: ModelConfig):
    r"""(∇_q L, ∂²L/∂q̇², (∂²L/∂q̇∂q) q̇) for a batch q, q̇ of shape (B, n), by the hand-written pass.

    For an MLP with pre-activations :math:`a_l` and :math:`g_l = \partial L/\partial h_l`, the Hessian is exactly

    .. math::  \nabla_z^2 L = \sum_l J_l^T\,\mathrm{diag}(g_l \odot \sigma_l''(a_l))\,J_l,\qquad J_l = \partial a_l/\partial z,

    because every :math:`a_l` is linear in the previous layer. So only the products :math:`J_l u` along the m = n+1
    directions u ∈ {e_{q̇_1}, …, e_{q̇_n}, (q̇, 0)} are pushed forward (one stacked matrix product per layer, with the
    primal), one backward pass gives g_l and ∇_z L, and the second derivatives are contractions over units.

    Periodic coordinates (``cfg.periodic``): the network input is z = [φ(q), q̇] with φ(q) = [q_rest, sin q_P,
    cos q_P] (:func:`embed_periodic`), of size d = 2n + |P|. ∂²L/∂q̇² is unchanged; the direction (q̇, 0) becomes
    (J_φ q̇, 0) = (q̇_rest, cos q_P·q̇_P, −sin q_P·q̇_P, 0), which gives (∂²L/∂q̇∂q) q̇ exactly (φ'' never enters);
    and ∇_q L = J_φᵀ ∇_φ L, i.e. ∂L/∂q_p = cos q_p ∂L/∂(sin q_p) − sin q_p ∂L/∂(cos q_p).
    """
    n = q.shape[-1]
    bsz = q.shape[0]
    dt = q.dtype
    periodic = cfg.periodic
    if periodic:
        rest, per = _periodic_split(periodic, n)
        sin_p, cos_p = jnp.sin(q[:, per]), jnp.cos(q[:, per])
        phi = jnp.concatenate([q[:, rest], sin_p, cos_p], axis=-1)  # (B, n + |P|)
        vp = qd[:, per]
        phi_dot = jnp.concatenate([qd[:, rest], cos_p * vp, -sin_p * vp], axis=-1)  # J_φ q̇
    else:
        phi, phi_dot = q, qd
    nq = phi.shape[-1]  # n + |P|
    d = nq + n
    z = jnp.concatenate([phi, qd], axis=-1)  # (B, d)
    e_v = jnp.concatenate([jnp.zeros((n, nq), dt), jnp.eye(n, dtype=dt)], axis=-1)  # (n, d)
    tan = jnp.concatenate(
        [jnp.broadcast_to(e_v[:, None, :], (n, bsz, d)), jnp.concatenate([phi_dot, jnp.zeros_like(qd)], -1)[None]],
        axis=0,
    )  # (m, B, d)
    lnn = _lnn_first_layer(lnn, cfg)
    hidden = lnn[:-1]
    x = jnp.concatenate([z[None], tan], axis=0)  # (m+1, B, in): primal and tangents
    cache = []
    for layer in hidden:
        pre = _mm(x, layer["w"])
        s0, s1, s2 = _act_with_derivs(cfg.lnn_activation, pre[0] + layer["b"])
        adot = pre[1:]  # J_l u for each direction: (m, B, width)
        cache.append((s1, s2, adot))
        x = jnp.concatenate([s0[None], s1[None] * adot], axis=0)
    w_out = lnn[-1]["w"][:, 0]
    g = jnp.broadcast_to(w_out, (bsz, w_out.shape[0]))  # ∂L/∂h_D
    hess = 0.0
    for layer, (s1, s2, adot) in zip(reversed(hidden), reversed(cache)):
        weighted = adot * (g * s2)[None]  # (m, B, width)
        hess = hess + jnp.sum(weighted[:n, None] * adot[None], axis=-1)  # (n, m, B): u_i^T J^T diag(c) J u_j
        g = (g * s1) @ layer["w"].T
    if periodic:  # ∇_q L = J_φᵀ ∇_φ L
        n_rest = n - len(periodic)
        g_rest, g_sin, g_cos = g[:, :n_rest], g[:, n_rest : nq - len(periodic)], g[:, nq - len(periodic) : nq]
        g_per = cos_p * g_sin - sin_p * g_cos
        grad_q = jnp.zeros((bsz, n), dt).at[:, rest].set(g_rest).at[:, per].set(g_per)
    else:
        grad_q = g[:, :n]
    hess = jnp.moveaxis(hess, -1, 0)  # (B, n, m)
    hess_vv = hess[:, :, :n] + cfg.split_mass * jnp.eye(n, dtype=dt)
    mixed = hess[:, :, n]
    return grad_q, hess_vv, mixed


def lnn_accel(lnn: list, q, qd, cfg: ModelConfig):
    """f_c^NN(q, q̇) for a batch (B, n) → (B, n), hand-written derivative pass."""
    return euler_lagrange_solve(*lnn_derivatives(lnn, q, qd, cfg), cfg.guard_eps)


def lnn_accel_reference(lnn: list, q, qd, cfg: ModelConfig):
    """Same as :func:`lnn_accel` with per-sample ``jax.hessian`` under ``vmap`` (the original LNN approach)."""

    def one(qi, qdi):
        lag = lambda a, b: lnn_value(lnn, a[None], b[None], cfg)[0]  # noqa: E731
        return accel_from_lagrangian(lag, qi, qdi, cfg.guard_eps)

    return jax.vmap(one)(q, qd)


def lnn_energy(lnn: list, q, qd, cfg: ModelConfig):
    """H = q̇·∂L/∂q̇ − L for a batch (B, n) → (B,)."""

    def lsum(qd_):
        return jnp.sum(lnn_value(lnn, q, qd_, cfg))

    dl_dqd = jax.grad(lsum)(qd)
    return jnp.sum(qd * dl_dqd, axis=-1) - lnn_value(lnn, q, qd, cfg)


# --------------------------------------------------------------------------------------------------------------------
# UAN and the black box


def mlp_apply(layers: list, x, activation: str = "leaky_relu", slope: float = 0.2):
    act = {
        "leaky_relu": lambda a: jax.nn.leaky_relu(a, slope),
        "tanh": jnp.tanh,
        "softplus": jax.nn.softplus,
        "relu": jax.nn.relu,
    }[activation]
    for layer in layers[:-1]:
        x = act(x @ layer["w"] + layer["b"])
    return x @ layers[-1]["w"] + layers[-1]["b"]


def _fold_free(layers: list, cfg: ModelConfig, n_time: int) -> list:
    """The input standardisation of :func:`free_force` folded into the first layer: (x − shift)/scale on the
    non-periodic q, on q̇ and on a single time column; sin/cos columns and time features are left as they are."""
    if cfg.input_shift is None:
        return layers
    if not cfg.periodic and n_time <= 1:
        return _first_layer(layers, cfg, slice(0, 2 * cfg.n + n_time))
    n, n_per = cfg.n, len(cfg.periodic)
    dt = layers[0]["w"].dtype
    rest, _ = _periodic_split(cfg.periodic, n)
    m = 2 * n + n_per + n_time
    cols = np.concatenate([rest, np.arange(n, 2 * n + (n_time == 1))])  # the input_shift entries used
    keep = np.concatenate([np.arange(n - n_per), np.arange(n + n_per, 2 * n + n_per + (n_time == 1))])
    mu, sd = np.zeros(m), np.ones(m)
    mu[keep] = np.asarray(cfg.input_shift, float)[cols]
    sd[keep] = np.asarray(cfg.input_scale, float)[cols]
    w = layers[0]["w"] / jnp.asarray(sd, dt)[:, None]
    return [{"w": w, "b": layers[0]["b"] - jnp.asarray(mu, dt) @ w}, *layers[1:]]


def free_force(layers: list, q, qd, t, cfg: ModelConfig):
    """The one free MLP (the UAN, the black box, the checks' free models): a batch q, q̇ (B, n) and ``t`` — (B,) one
    time column, (B, k) time features, or None for no time input — → (B, n). Angles enter as (sin, cos) like the
    LNN (``cfg.periodic``); ``cfg.input_shift``/``input_scale`` are folded into the first layer; the activation is
    ``cfg.uan_activation`` (slope ``cfg.leaky_slope``). Initialise with :func:`init_free`."""
    cols = [embed_periodic(q, cfg.periodic) if cfg.periodic else q, qd]
    if t is not None:
        cols.append(t[:, None] if t.ndim == 1 else t)
    n_time = 0 if t is None else cols[-1].shape[-1]
    x = jnp.concatenate(cols, axis=-1)
    return mlp_apply(_fold_free(layers, cfg, n_time), x, cfg.uan_activation, cfg.leaky_slope)


def uan_force(uan: list, q, qd, t, cfg: ModelConfig):
    """f_n^NN(q, q̇, t) for a batch: q, q̇ (B, n), t (B,) → (B, n) (:func:`free_force` with one time column)."""
    return free_force(uan, q, qd, t, cfg)


def nnphd_forces(params: Params, q, qd, t, cfg: ModelConfig):
    """(f_c^NN, f_n^NN) for a batch."""
    return lnn_accel(params["lnn"], q, qd, cfg), uan_force(params["uan"], q, qd, t, cfg)


@dataclass(frozen=True)
class Model:
    """Convenience wrapper: a config and its parameters (a pytree)."""

    cfg: ModelConfig
    params: Params = field(repr=False)

    @classmethod
    def init(cls, cfg: ModelConfig, seed: int = 0) -> Model:
        return cls(cfg, init_nnphd(jax.random.PRNGKey(seed), cfg))

    def forces(self, q, qd, t):
        return nnphd_forces(self.params, q, qd, t, self.cfg)
