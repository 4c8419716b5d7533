r"""Loss, the jitted training loop and the λ-sweep (paper Eq. 5, appendix B).

Loss: :math:`L = L_e + \lambda L_b` with
:math:`L_e = (\tfrac{1}{Nn}\sum_i \|f_c^{NN}+f_n^{NN}-f\|_p^p)^{1/p}` and
:math:`L_b = (\tfrac{1}{Nn}\sum_i \|f_n^{NN}\|_p^p)^{1/p}` (p ≥ 1), or the squared-L2 ("mse") variant
:math:`L_e = \tfrac{1}{Nn}\sum\|\cdot\|_2^2`.

Training: Adam over a piecewise-constant learning rate (paper: {1e-2, 1e-3, 1e-4, 1e-5} × 500 steps), minibatches of
32 drawn with replacement, the whole loop one ``lax.scan`` under ``jit``. λ is a traced argument, so one compiled
trainer serves every λ (and ``vmap`` over λ trains all of them at once).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace
from functools import partial

import jax
import jax.numpy as jnp
import numpy as np
import optax

from nnphd.engine import stored
from nnphd.engine.batching import pad_rows, train_bucket
from nnphd.engine.models import ModelConfig, Params, init_nnphd, nnphd_forces
from nnphd.io.progress import Progress

PAPER_LAMBDAS: tuple[float, ...] = (0.01, 0.02, 0.05, 0.1, 0.2, 0.5, 1.0, 2.0, 5.0, 10.0, 20.0, 50.0, 100.0)
PAPER_LRS: tuple[float, ...] = (1e-2, 1e-3, 1e-4, 1e-5)

_TINY = 1e-30  # keeps the gradient of (S)^{1/p} finite when S → 0 (float64); float32 uses 1e-20


# the largest loss index: the loss is (mean |r|^p + floor)^{1/p}; from p ≈ 20 the floor 1e-30^{1/p} (1e-3 at p = 10,
# 0.03 at p = 20, 0.5 at p = 100; 1e-20^{1/p} in float32) swamps L_b, and from p ≈ 500 |r|^p leaves float64's range
# (float32's from p ≈ 50) and training gives NaN (measured on HO+LD, 200 steps). The paper uses p = 1, 2, 3.
MAX_P = 10


def parse_p(p) -> float | str:
    """Validate a loss index: a number 1 ≤ p ≤ MAX_P, or 'mse'."""
    if isinstance(p, str):
        s = p.strip().lower()
        if s == "mse":
            return "mse"
        try:
            p = float(s)
        except ValueError:
            raise ValueError(f"p must be a number ≥ 1 or 'mse', got {p!r}") from None
    p = float(p)
    if not np.isfinite(p) or p < 1:
        raise ValueError(f"p must be a number ≥ 1 or 'mse', got {p:g}")
    if p > MAX_P:
        raise ValueError(
            f"p must be at most {MAX_P} (or 'mse'), got {p:g}: larger p leave float64's range in |r|^p and the "
            "loss no longer measures the fit"
        )
    return p


def pnorm(r, p: float | str):
    """(1/(Nn) Σ |r|^p)^{1/p} over all entries of r; 'mse' gives the mean of r²."""
    if p == "mse":
        return jnp.mean(r * r)
    if p == 1:
        return jnp.mean(jnp.abs(r))
    tiny = _TINY if r.dtype == jnp.float64 else 1e-20
    return (jnp.mean(jnp.abs(r) ** p) + tiny) ** (1.0 / p)


def loss_terms(params: Params, q, qd, t, qdd, cfg: ModelConfig, p):
    """(L_e, L_b) on a batch."""
    fc, fn = nnphd_forces(params, q, qd, t, cfg)
    return pnorm(fc + fn - qdd, p), pnorm(fn, p)


@dataclass(frozen=True)
class TrainConfig:
    """Optimisation settings (defaults: the paper's)."""

    lrs: tuple[float, ...] = PAPER_LRS
    steps: int = 2000  # per λ; split evenly over the learning rates
    batch_size: int = 32
    p: float | str = 1.0

    def __post_init__(self):
        object.__setattr__(self, "p", parse_p(self.p))
        if self.steps < len(self.lrs) or int(self.steps) != self.steps:
            raise ValueError(f"steps must be an integer ≥ {len(self.lrs)}, got {self.steps}")
        if self.batch_size < 1:
            raise ValueError(f"batch_size must be ≥ 1, got {self.batch_size}")
        if not self.lrs or any(lr <= 0 for lr in self.lrs):
            raise ValueError(f"learning rates must be positive, got {self.lrs}")

    def replace(self, **kw) -> TrainConfig:
        return replace(self, **kw)

    def schedule(self):
        per = self.steps // len(self.lrs)
        bounds = {per * (i + 1): self.lrs[i + 1] / self.lrs[i] for i in range(len(self.lrs) - 1)}
        return optax.piecewise_constant_schedule(self.lrs[0], bounds)


def as_arrays(data, dtype):
    return tuple(jnp.asarray(a, dtype) for a in (data.q, data.qd, data.t, data.qdd))


def make_trainer(cfg: ModelConfig, tcfg: TrainConfig, loss_fn: Callable | None = None, export_key: str | None = None):
    """Return ``train(params, arrays, lam, key) -> (params, (L_e history, L_b history))``, jitted (the rows padded to
    their :func:`nnphd.engine.batching.train_bucket`, never drawn: a record of another length in the same bucket runs the
    same compiled program with the same numbers as unpadded).

    ``arrays`` = (q, q̇, t, q̈) of the training set. The Adam state starts fresh on every call (appendix B restarts
    the learning-rate annealing at each λ); parameters are whatever is passed in (warm start).
    ``loss_fn(params, q, qd, t, qdd) -> (L_e, L_b)`` replaces the NNPhD loss (used for the LNN-only and black-box
    baselines and constrained Lagrangians). ``export_key``: what ``loss_fn`` computes besides ``cfg`` (a text another
    process gives alike): the trainer is then stored for the next process (:mod:`nnphd.engine.stored`); without
    ``loss_fn`` the NNPhD loss is described already.
    """
    opt = optax.adam(tcfg.schedule())
    if loss_fn is None:
        loss_fn, export_key = partial(loss_terms, cfg=cfg, p=tcfg.p), "loss_terms"

    def objective(params, batch, lam):
        le, lb = loss_fn(params, *batch)
        return le + lam * lb, (le, lb)

    grad_fn = jax.value_and_grad(objective, has_aux=True)

    stored_key = None if export_key is None else f"{export_key}|{cfg!r}|{tcfg!r}"

    def train_padded(params, arrays, n_data, lam, key):
        opt_state = opt.init(params)

        def step(carry, k):
            params, opt_state = carry
            idx = jax.random.randint(k, (tcfg.batch_size,), 0, n_data)
            batch = tuple(a[idx] for a in arrays)
            (_, (le, lb)), g = grad_fn(params, batch, lam)
            updates, opt_state = opt.update(g, opt_state, params)
            return (optax.apply_updates(params, updates), opt_state), (le, lb)

        keys = jax.random.split(key, tcfg.steps)
        (params, _), hist = jax.lax.scan(step, (params, opt_state), keys)
        return params, hist

    def train(params, arrays, lam, key):
        # the rows padded to their bucket and the row count passed as data: one compiled trainer serves every record
        # of the bucket, and the minibatches (drawn below the true count) are those of the unpadded rows, bit for bit
        n_data = int(arrays[0].shape[0])
        args = (params, pad_rows(arrays, train_bucket(n_data)), jnp.asarray(n_data, jnp.int32), lam, key)
        if stored_key is None:
            return jitted(*args)
        return stored.run("train_padded", train_padded, stored_key, args)

    jitted = jax.jit(train_padded)

    return train


@partial(jax.jit, static_argnames=("cfg", "p"))
def evaluate_arrays(params: Params, q, qd, t, qdd, cfg: ModelConfig, p):
    fc, fn = nnphd_forces(params, q, qd, t, cfg)
    return pnorm(fc + fn - qdd, p), pnorm(fn, p), fc, fn


@dataclass
class Evaluation:
    L_e: float
    L_b: float
    fc: np.ndarray
    fn: np.ndarray


def evaluate(params: Params, data, cfg: ModelConfig, p) -> Evaluation:
    """L_e, L_b and the learned forces on a whole dataset."""
    le, lb, fc, fn = evaluate_arrays(params, *as_arrays(data, jnp.dtype(cfg.dtype)), cfg, p)
    return Evaluation(float(le), float(lb), np.asarray(fc), np.asarray(fn))


def alignment(pred, truth) -> float:
    """Misalignment m = (1/(nN) Σ ‖pred − truth‖²)^{1/2} (paper section III.D)."""
    d = np.asarray(pred, float) - np.asarray(truth, float)
    return float(np.sqrt(np.mean(d * d)))


def validate_lambdas(lambdas: Sequence[float]) -> tuple[float, ...]:
    lams = tuple(float(x) for x in lambdas)
    if not lams:
        raise ValueError("lambdas must not be empty")
    for x in lams:
        if not np.isfinite(x) or x <= 0:
            raise ValueError(f"λ must be > 0, got {x:g}")
    if len(set(lams)) != len(lams):
        raise ValueError(f"λ values must be distinct, got {', '.join(f'{x:g}' for x in lams)}")
    return lams


@dataclass
class SweepPoint:
    lam: float
    L_e: float  # on the evaluation set (test set if given, else the training set)
    L_b: float
    L_e_train: float
    L_b_train: float
    m_c: float | None = None
    m_n: float | None = None
    params: Params | None = None

    def row(self) -> dict:
        """The numbers of this point (no params), as in the results' tables."""
        return {k: getattr(self, k) for k in ("lam", "L_e", "L_b", "L_e_train", "L_b_train", "m_c", "m_n")}


SWEEP_MODES = ("warm", "vmap", "scratch")


@dataclass(frozen=True)
class SweepSchedule:
    """The λ values of a sweep and how they are trained (:func:`lambda_sweep`): ``lambdas`` (positive, distinct;
    stored as a tuple of floats), the ``mode`` (one of :data:`SWEEP_MODES`) and, in warm mode, whether the chain runs
    in ``descending`` order of λ (default: increasing)."""

    lambdas: tuple[float, ...] = PAPER_LAMBDAS
    mode: str = "warm"
    descending: bool = False

    def __post_init__(self):
        object.__setattr__(self, "lambdas", validate_lambdas(self.lambdas))
        if self.mode not in SWEEP_MODES:
            raise ValueError(f"mode must be one of {', '.join(SWEEP_MODES)}, got {self.mode!r}")


@dataclass(frozen=True, eq=False)
class SweepHooks:
    """How a λ-sweep resumes and reports: ``resume`` maps λ → a finished result to skip (params for
    :func:`lambda_sweep`, a :class:`SweepPoint` with params for :func:`sweep`); ``on_point`` is called for every λ
    trained (with ``(lam, params)`` in :func:`lambda_sweep`, with the :class:`SweepPoint` in :func:`sweep`);
    ``progress(done, total, message)`` after every λ."""

    resume: Mapping | None = None
    on_point: Callable | None = None
    progress: Progress | None = None


def lambda_sweep(
    train: Callable,
    params0,
    arrays,
    schedule: SweepSchedule,
    key,
    hooks: SweepHooks = SweepHooks(),
    accept: Callable | None = None,
) -> dict:
    """The one λ-sweep: train ``train`` (any model and loss, from :func:`make_trainer`) at every λ of ``schedule``;
    return λ → params.

    ``schedule.mode``:

    * ``"warm"`` — the paper's protocol (appendix B): λ in increasing order (decreasing with ``schedule.descending``),
      each run starting from the previous λ's parameters; run j draws its minibatches from the j-th of
      ``split(key, len(λ))``;
    * ``"vmap"`` — every λ from ``params0`` with the same ``key``, all in one vmapped run;
    * ``"scratch"`` — the same as ``"vmap"`` (every λ from ``params0``, same ``key``), one λ after the other (less
      memory; the same numbers up to rounding).

    ``hooks.resume`` maps λ → finished params to skip (warm mode continues from them). ``accept(lam, params)`` (warm
    mode) returns the params the chain keeps for λ and continues from (default: the new ones).
    ``hooks.on_point(lam, params)`` is called for every λ trained here; ``hooks.progress(done, total, message)``
    after every λ.
    """
    lams, mode = schedule.lambdas, schedule.mode
    on_point, progress = hooks.on_point, hooks.progress
    dtype = jax.tree_util.tree_leaves(arrays)[0].dtype
    done = dict(hooks.resume or {})
    out: dict = {}
    order = sorted(lams, reverse=schedule.descending)

    def tick(j, lam):
        if progress:
            progress(j + 1, len(order), f"λ = {lam:g}")

    if mode == "vmap":
        todo = [x for x in order if x not in done]
        if todo:
            vtrain = jax.jit(jax.vmap(train, in_axes=(None, None, 0, None)))
            pstack, _ = vtrain(params0, arrays, jnp.asarray(todo, dtype), key)
            for i, lam in enumerate(todo):
                done[lam] = jax.tree_util.tree_map(lambda a, i=i: a[i], pstack)
                if on_point:
                    on_point(lam, done[lam])
        for j, lam in enumerate(order):
            out[lam] = done[lam]
            tick(j, lam)
        return out
    keys = jax.random.split(key, len(order)) if mode == "warm" else None
    params = params0
    for j, lam in enumerate(order):
        if lam in done:
            params = done[lam]
        else:
            start = params if mode == "warm" else params0
            params, _ = train(start, arrays, jnp.asarray(lam, dtype), keys[j] if mode == "warm" else key)
            if accept is not None:
                params = accept(lam, params)
            if on_point:
                on_point(lam, params)
        out[lam] = params
        tick(j, lam)
    return out


def sweep_point(lam: float, params: Params, train_data, test_data, cfg: ModelConfig, p) -> SweepPoint:
    """The sweep's record of λ: L_e, L_b on the test set (the training set when there is none) and on the training
    set, and the misalignments m_c, m_n when the data carry the true split."""
    eval_data = test_data if test_data is not None else train_data
    ev = evaluate(params, eval_data, cfg, p)
    tr = ev if test_data is None else evaluate(params, train_data, cfg, p)
    pt = SweepPoint(lam, ev.L_e, ev.L_b, tr.L_e, tr.L_b, params=params)
    if eval_data.fc is not None:
        pt.m_c = alignment(ev.fc, eval_data.fc)
        pt.m_n = alignment(ev.fn, eval_data.fn)
    return pt


def sweep(
    train_data,
    cfg: ModelConfig,
    tcfg: TrainConfig,
    schedule: SweepSchedule = SweepSchedule(),
    seed: int = 0,
    test_data=None,
    hooks: SweepHooks = SweepHooks(),
    keep_params: bool = True,
) -> list[SweepPoint]:
    """Train NNPhD for each λ of ``schedule`` (:func:`lambda_sweep`) and record L_e(λ), L_b(λ) (and m_c, m_n when the
    data carry the true split).

    ``schedule``: see :func:`lambda_sweep`. ``hooks.resume`` maps λ → a finished :class:`SweepPoint` (with params) to
    skip (warm mode continues from its params); ``hooks.on_point(point)`` is called with every new
    :class:`SweepPoint`.
    """
    lams = schedule.lambdas
    on_point = hooks.on_point
    dtype = jnp.dtype(cfg.dtype)
    k_init, k_train = jax.random.split(jax.random.PRNGKey(seed))
    points = {lam: pt for lam, pt in (hooks.resume or {}).items() if pt.params is not None}

    def finish(lam, params):
        points[lam] = pt = sweep_point(lam, params, train_data, test_data, cfg, tcfg.p)
        if on_point:
            on_point(pt)

    lambda_sweep(
        make_trainer(cfg, tcfg),
        init_nnphd(k_init, cfg),
        as_arrays(train_data, dtype),
        schedule,
        k_train,
        SweepHooks(resume={lam: pt.params for lam, pt in points.items()}, on_point=finish, progress=hooks.progress),
    )
    out = sorted((points[lam] for lam in set(lams)), key=lambda pt: pt.lam)
    if not keep_params:
        for pt in out:
            pt.params = None
    return out
