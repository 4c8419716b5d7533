r"""The data-quality study (paper section III.D, Fig. 6).

**Data-quality study** (:func:`data_quality_study`). HO+CD (q̈ = −q − ½ sgn q̇) with 10³ samples in a phase-plane pie
of angular fraction α, trained at λ = 10 → L_e(α); HO+LD (q̈ = −q − ½q̇) with a fraction β of the samples at q̇ > 0,
trained at λ = 0.5 → m_c(β), m_n(β). p = 1. Each grid point is one training run of 2000 steps from the same
initialisation (no λ-sweep: the paper trains "with λ = 10" / "λ = 0.5" directly); all grid points are trained in one
``jax.vmap`` over the data sets. The model is the same for every grid point: the inputs are *not* standardised per
data set (the toy data are order one already, and a per-α standardisation would give each α a differently scaled
network, and break the vmap).

*Which data L_e and m are measured on.* The paper's reading of Fig. 6a — "when α ≤ 0.5 … L_e is nearly zero,
revealing no sign of non-conservation", because on q̇ > 0 alone the damping looks like a constant conservative
force — only holds on the data's own distribution (on the full plane the conservative model of a half-plane is
wrong by the full damping on the other half). So the primary numbers are on a held-out test set drawn from the same
distribution as the training set (same α or β, another seed); L_e on the training set itself and, for contrast,
L_e and m on a full (balanced) Gaussian test set are reported beside them. m_c, m_n follow the paper's formula
(rms over samples and components, :func:`nnphd.engine.train.alignment`).

The two grids are cached in ``out`` (out/alpha.json, out/beta.json, :mod:`nnphd.io.cache`): a repeated call with
the same settings loads them (flag ``cached``) instead of training.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from nnphd.engine.data import Dataset, gaussian_dataset, imbalanced_dataset, pie_dataset
from nnphd.engine.models import ModelConfig, init_nnphd
from nnphd.engine.systems import get_system
from nnphd.engine.train import TrainConfig, alignment, as_arrays, evaluate, make_trainer
from nnphd.engine.verdict import MIN_RATIO
from nnphd.io.cache import Cache
from nnphd.io.progress import Progress
from nnphd.io.results import ensure_writable_dir, write_results
from nnphd.paper.figures import plot_fig6
from nnphd.paper.lambda_p import ALIGN_TOL, NEAR_ZERO_FRACTION, RESULT_FORMAT
from nnphd.paper.study_results import AlphaRow, BetaRow, Claim, DataQualityGrid, DataQualityResult
from nnphd.parallel import Unit, UnitsFailed, run_units

__all__ = ["DQ_GRID", "DataQualitySettings", "data_quality_study"]

DQ_GRID: tuple[float, ...] = tuple(i / 8 for i in range(9))  # α and β grid: 0, 0.125, …, 1
DQ_LAM_ALPHA = 10.0
DQ_LAM_BETA = 0.5
DQ_P = 1.0


@dataclass(frozen=True)
class DataQualitySettings:
    """What a data-quality study (:func:`data_quality_study`) runs: training ``steps`` per data set, the ``seed``,
    the pie coverages ``alphas`` and imbalances ``betas`` (in [0, 1]) and the sample sizes ``n_train``, ``n_test``.
    Checked when the study starts."""

    steps: int = 2000
    seed: int = 0
    alphas: Sequence[float] = DQ_GRID
    betas: Sequence[float] = DQ_GRID
    n_train: int = 1000
    n_test: int = 1000


def _stack(datasets: Sequence[Dataset]):
    arrs = [as_arrays(d, jnp.float64) for d in datasets]
    return tuple(jnp.stack([a[i] for a in arrs]) for i in range(4))


def _train_grid(train_sets: Sequence[Dataset], lam: float, cfg: ModelConfig, tcfg: TrainConfig, seed: int):
    """Train one NNPhD per data set at the same λ, from the same initialisation and minibatch keys, in one vmap."""
    k_init, k_train = jax.random.split(jax.random.PRNGKey(seed))
    params0 = init_nnphd(k_init, cfg)
    train = make_trainer(cfg, tcfg)
    vtrain = jax.jit(jax.vmap(train, in_axes=(None, 0, None, None)))
    pstack, _ = vtrain(params0, _stack(train_sets), jnp.asarray(lam, jnp.float64), k_train)
    return [jax.tree_util.tree_map(lambda a, i=i: a[i], pstack) for i in range(len(train_sets))]


def _dq_grid_run(kind: str, grid, steps: int, seed: int, n_train: int, n_test: int, path: Path | None) -> dict:
    if kind == "alpha":
        system, lam, make = "ho+cd", DQ_LAM_ALPHA, pie_dataset
    else:
        system, lam, make = "ho+ld", DQ_LAM_BETA, imbalanced_dataset
    sysm = get_system(system)
    cfg = ModelConfig(n=1)
    tcfg = TrainConfig(steps=steps, p=DQ_P)
    settings = {
        "kind": kind,
        "system": system,
        "system_params": dict(sysm.params),
        "lam": lam,
        "p": DQ_P,
        "grid": list(grid),
        "steps": steps,
        "seed": seed,
        "n_train": n_train,
        "n_test": n_test,
        "learning_rates": list(tcfg.lrs),
        "batch_size": tcfg.batch_size,
        "model": asdict(cfg),
        "standardize": False,
        "training": "from scratch at fixed λ, all grid points in one vmap",
        "format": RESULT_FORMAT,
    }
    cache = Cache(path.parent if path is not None else None, settings)
    cached = cache.load(path.name) if path is not None else None
    if cached is not None:
        cached["cached"] = True
        return cached
    s_train, s_test, s_full = np.random.SeedSequence(seed).spawn(3)
    # the same seeds for every grid point (common random numbers: only α or β changes between data sets)
    trains = [make(sysm, n_train, g, s_train) for g in grid]
    tests = [make(sysm, n_test, g, s_test) for g in grid]
    full = gaussian_dataset(sysm, n_test, s_full)
    t0 = time.perf_counter()
    params = _train_grid(trains, lam, cfg, tcfg, seed)
    wall = time.perf_counter() - t0
    rows = []
    for g, prm, tr, te in zip(grid, params, trains, tests):
        e_te, e_tr, e_full = (evaluate(prm, d, cfg, DQ_P) for d in (te, tr, full))
        row = {
            "alpha" if kind == "alpha" else "beta": g,
            "L_e": e_te.L_e,
            "L_b": e_te.L_b,
            "L_e_train": e_tr.L_e,
            "L_e_full": e_full.L_e,
            "fn_size": float(
                np.mean(np.abs(te.fn))
            ),  # ‖f_n‖₁ on the evaluation data (the L_e a Lagrangian-only model would leave if it fits f_c exactly)
            "m_c": alignment(e_te.fc, te.fc),
            "m_n": alignment(e_te.fn, te.fn),
            "m_c_train": alignment(e_tr.fc, tr.fc),
            "m_n_train": alignment(e_tr.fn, tr.fn),
            "m_c_full": alignment(e_full.fc, full.fc),
            "m_n_full": alignment(e_full.fn, full.fn),
            # robust companions of m_c, m_n (rms): the median |f^NN − f^PHY| over the test samples
            "m_c_median": float(np.median(np.abs(e_te.fc - te.fc))),
            "m_n_median": float(np.median(np.abs(e_te.fn - te.fn))),
            "frac_qd_pos": float(np.mean(tr.qd[:, 0] > 0)),
        }
        rows.append(row)
    res = cache.save(
        {
            "settings": settings,
            "table": rows,
            "train_wall_time_s": wall,
            "evaluated_on": (
                "L_e, L_b, m_c, m_n: held-out test set from the same distribution as the "
                "training set (same α/β, other seed); *_train: the training set; *_full: a "
                "full N(0,1) Gaussian test set"
            ),
        },
        path.name if path is not None else "results.json",
    )
    res["cached"] = False
    return res


def _dq_claims(alpha_rows: Sequence[AlphaRow], beta_rows: Sequence[BetaRow]) -> list[Claim]:
    claims = []
    lo = [r for r in alpha_rows if r.alpha <= 0.5]
    hi = [r for r in alpha_rows if r.alpha > 0.5]
    if lo:
        worst = max(lo, key=lambda r: r.L_e)
        tol = NEAR_ZERO_FRACTION * max(r.fn_size for r in lo) if any(r.fn_size > 0 for r in lo) else None
        tol = NEAR_ZERO_FRACTION * 0.5 if tol is None else tol
        claims.append(
            Claim(
                claim=f"HO+CD, λ=10: L_e nearly zero for α ≤ 0.5 (≤ {NEAR_ZERO_FRACTION:g}× ‖f_n‖₁ = {tol:.3g}): "
                "on q̇ ≥ 0 the damping looks like a constant conservative force",
                ours=f"max L_e = {worst.L_e:.3g} at α={worst.alpha:g}; "
                + ", ".join(f"α={r.alpha:g}: {r.L_e:.3g}" for r in lo),
                met=bool(worst.L_e <= tol),
            )
        )
    if lo and hi:
        med_lo = float(np.median([r.L_e for r in lo]))
        med_hi = float(np.median([r.L_e for r in hi]))
        claims.append(
            Claim(
                claim=f"HO+CD, λ=10: L_e jumps past α = 0.5 (median L_e over α > 0.5 ≥ {MIN_RATIO:g}× median over "
                "α ≤ 0.5, the verdict's statistic)",
                ours=f"median {med_hi:.3g} vs {med_lo:.3g}: ×{med_hi / max(med_lo, 1e-300):.3g}",
                met=bool(med_hi >= MIN_RATIO * med_lo),
            )
        )
        mn_hi = min(r.L_e for r in hi)
        mx_lo = max(r.L_e for r in lo)
        claims.append(
            Claim(
                claim=f"HO+CD, λ=10: every α > 0.5 has L_e ≥ {MIN_RATIO:g}× every α ≤ 0.5 (strict reading)",
                ours=f"min over α > 0.5 = {mn_hi:.3g}, max over α ≤ 0.5 = {mx_lo:.3g}: ×{mn_hi / max(mx_lo, 1e-300):.3g}",
                met=bool(mn_hi >= MIN_RATIO * mx_lo),
            )
        )
    if beta_rows:
        half = [r for r in beta_rows if r.beta == 0.5]
        if half and len(beta_rows) > 1:
            bc = min(beta_rows, key=lambda r: r.m_c)
            bn = min(beta_rows, key=lambda r: r.m_n)
            claims.append(
                Claim(
                    claim="HO+LD, λ=0.5: misalignment m_c, m_n is smallest at β = 0.5 (balanced data)",
                    ours=f"argmin m_c: β={bc.beta:g} ({bc.m_c:.3g}); argmin m_n: β={bn.beta:g} ({bn.m_n:.3g})",
                    met=bool(bc.beta == 0.5 and bn.beta == 0.5),
                )
            )
        if half:
            h = half[0]
            claims.append(
                Claim(
                    claim=f"HO+LD, λ=0.5: nearly zero misalignment at β = 0.5 (m_c, m_n ≤ {ALIGN_TOL:g})",
                    ours=f"m_c = {h.m_c:.3g}, m_n = {h.m_n:.3g}",
                    met=bool(max(h.m_c, h.m_n) <= ALIGN_TOL),
                )
            )
    return claims


def _check_grid(values, name: str) -> tuple[float, ...]:
    try:
        vals = tuple(float(v) for v in values)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be numbers in [0, 1], got {values!r}") from None
    if not vals:
        raise ValueError(f"{name} must not be empty")
    for v in vals:
        if not (0.0 <= v <= 1.0):
            raise ValueError(f"{name} must be numbers in [0, 1], got {v:g}")
    return tuple(sorted(set(vals)))


def data_quality_study(
    settings: DataQualitySettings = DataQualitySettings(),
    out: str | Path | None = None,
    progress: Progress | None = None,
    workers: int | None = 1,
    scheduler: str | None = None,
) -> DataQualityResult:
    """Fig. 6: L_e(α) of HO+CD at λ=10 on pie-shaped data, m_c(β), m_n(β) of HO+LD at λ=0.5 on imbalanced data.

    Returns a :class:`nnphd.paper.study_results.DataQualityResult`: ``alpha`` and ``beta`` (the two grids: their
    tables and settings), ``claims`` (claim, ours, met), ``cached``, ``settings`` and ``wall_time_s``; ``to_dict()``
    is results.json's content. With ``out``: writes results.json and fig6.png, and caches the two grids in
    out/alpha.json, out/beta.json (a repeated call with the same settings loads them). The two grids are units of
    :func:`nnphd.parallel.run_units` (``workers``: 1 here, None one process per core; ``scheduler``).
    ``settings``: :class:`DataQualitySettings`.
    """
    t0 = time.perf_counter()
    steps, seed, n_train, n_test = settings.steps, settings.seed, settings.n_train, settings.n_test
    if isinstance(steps, bool) or int(steps) != steps or steps < 4:
        raise ValueError(f"steps must be an integer ≥ 4, got {steps!r}")
    if isinstance(seed, bool) or int(seed) != seed or seed < 0:
        raise ValueError(f"seed must be an integer ≥ 0, got {seed!r}")
    steps, seed = int(steps), int(seed)
    al = _check_grid(settings.alphas, "alphas")
    be = _check_grid(settings.betas, "betas")
    outdir = ensure_writable_dir(out) if out is not None else None
    units = [
        Unit(
            kind,
            _dq_grid_run,
            dict(
                kind=kind,
                grid=g,
                steps=steps,
                seed=seed,
                n_train=n_train,
                n_test=n_test,
                path=outdir / f"{kind}.json" if outdir else None,
            ),
        )  # fmt: skip
        for kind, g in (("alpha", al), ("beta", be))
    ]
    finished: list[str] = []

    def report(o) -> None:  # the progress of the two grids
        finished.append(o.key)
        if progress:
            progress(len(finished), 2, "done" if len(finished) == 2 else f"{o.key} done")

    if progress:
        progress(0, 2, f"HO+CD pie coverage ({len(al)} α at λ={DQ_LAM_ALPHA:g}), HO+LD imbalance ({len(be)} β)")
    outs = run_units(units, workers, scheduler, on_outcome=report)
    bad = [o for o in outs.values() if not o.ok]
    if bad:
        raise UnitsFailed(f"the {bad[0].key} grid failed: {bad[0].error}")
    # the grids as trained or cached (JSON), checked
    ares = DataQualityGrid.from_dict(outs["alpha"].value, "alpha", "data-quality study")
    bres = DataQualityGrid.from_dict(outs["beta"].value, "beta", "data-quality study")
    result = DataQualityResult(
        settings={
            "steps": steps,
            "seed": seed,
            "alphas": list(al),
            "betas": list(be),
            "p": DQ_P,
            "lam_alpha": DQ_LAM_ALPHA,
            "lam_beta": DQ_LAM_BETA,
            "n_train": n_train,
            "n_test": n_test,
            "alpha_system": "ho+cd",
            "beta_system": "ho+ld",
            "standardize": False,
            "training": "from scratch at fixed λ (no sweep), one vmap over the grid, same init",
            "align_tol": ALIGN_TOL,
        },
        alpha=ares,
        beta=bres,
        claims=tuple(_dq_claims(ares.table, bres.table)),
        wall_time_s=0.0,  # of this call (small when both grids come from the cache): set by write_results
        jax_version=jax.__version__,
    )
    return write_results(outdir, result, {"fig6.png": plot_fig6}, t0)
