"""Speed benchmark of NNPhD training on this machine (CPU, float64).

Measures, in one run:
  1. our training step (hand-written LNN derivative pass + UAN, NNPhD loss, Adam) vs the same step with f_c from a
     Cranmer-style per-sample ``jax.hessian`` under ``vmap`` (``lnn_accel_reference``)   -- goal: reference/ours ≥ 3;
  2. our step vs a plain MLP step of the same widths (q, q̇, t → 200 → 200 → n, leaky_relu, same p=1 loss, Adam)
     -- goal: ours/plain ≤ 3;
  3. wall time of a full 13-λ sweep at paper settings (``ho+ld``, 2000 steps/λ, warm and vmap modes, compilation
     included; goal ≤ 20 s) and of the n=2 ``ho+mf`` warm sweep.
Steps are timed after one compiling call: each block is one jitted ``lax.scan`` of ``--reps`` steps (params and Adam
state threaded through, as in training); the reported ms/step is the median over ``--blocks`` blocks. Results: a table on stdout and benchmarks/results/speed.json.

Run:  .venv/bin/python benchmarks/bench_speed.py [--quick] [--reps 50] [--blocks 3]
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import time
from functools import partial
from pathlib import Path

import jax
import jax.numpy as jnp
import optax

import nnphd

nnphd.configure()  # float64 and the XLA:CPU setting, as the CLI

import nnphd
from nnphd.engine.models import (
    ModelConfig,
    init_nnphd,
    init_uan,
    lnn_accel_reference,
    mlp_apply,
    uan_force,
)
from nnphd.engine.train import loss_terms, pnorm
from nnphd.paper.sweep import SweepSettings, run_sweep

N, P, LAM, BATCHES = 2, 1.0, 1.0, (32, 1000)
GOAL_REF, GOAL_PLAIN, GOAL_SWEEP = 3.0, 3.0, 20.0


def machine_info() -> dict:
    try:
        cpu = next(l.split(":", 1)[1].strip() for l in open("/proc/cpuinfo") if l.startswith("model name"))
    except (OSError, StopIteration):
        cpu = "unknown"
    return {
        "nproc": len(os.sched_getaffinity(0)),
        "cpu_model": cpu,
        "jax_version": jax.__version__,
        "jax_backend": jax.default_backend(),
        "python": platform.python_version(),
        "loadavg_1min": os.getloadavg()[0],
    }


def reference_loss(params, q, qd, t, qdd, cfg, p):
    """The NNPhD loss with f_c from the per-sample jax.hessian path (original LNN code)."""
    fc, fn = lnn_accel_reference(params["lnn"], q, qd, cfg), uan_force(params["uan"], q, qd, t, cfg)
    return pnorm(fc + fn - qdd, p), pnorm(fn, p)


def plain_loss(params, q, qd, t, qdd, cfg, p):
    """A plain MLP (same widths/activation as the UAN) fitted to q̈ with the same p-loss; L_b = 0."""
    pred = mlp_apply(params, jnp.concatenate([q, qd, t[:, None]], -1), cfg.uan_activation, cfg.leaky_slope)
    return pnorm(pred - qdd, p), jnp.zeros((), qdd.dtype)


def make_step(loss_fn, opt):
    """One jitted training step: value_and_grad of L_e + λ L_b, then an Adam update (as in make_trainer)."""

    def objective(params, batch, lam):
        le, lb = loss_fn(params, *batch)
        return le + lam * lb

    @jax.jit
    def step(params, opt_state, batch, lam):
        loss, g = jax.value_and_grad(objective)(params, batch, lam)
        updates, opt_state = opt.update(g, opt_state, params)
        return optax.apply_updates(params, updates), opt_state, loss

    return step


def time_step(step, params, batch, opt, reps: int, blocks: int) -> float:
    """Median over blocks of ms/step. Each block is one jitted ``lax.scan`` over ``reps`` steps (as the trainer runs
    them, so Python dispatch is not measured); the first (compiling) call is not timed."""
    lam, opt_state = jnp.asarray(LAM), opt.init(params)

    @jax.jit
    def loop(params, opt_state):
        def body(carry, _):
            p, o, _ = step(*carry[:2], batch, lam)
            return (p, o, carry[2]), None

        return jax.lax.scan(body, (params, opt_state, jnp.zeros(())), None, length=reps)[0]

    params, opt_state, _ = jax.block_until_ready(loop(params, opt_state))
    times = []
    for _ in range(blocks):
        t0 = time.perf_counter()
        params, opt_state, _ = jax.block_until_ready(loop(params, opt_state))
        times.append((time.perf_counter() - t0) / reps * 1e3)
    return statistics.median(times)


def bench_steps(reps: int, blocks: int) -> dict:
    cfg, opt = ModelConfig(n=N), optax.adam(1e-3)
    kp, kd = jax.random.split(jax.random.PRNGKey(0))
    nnphd_params, plain_params = init_nnphd(kp, cfg), init_uan(kp, cfg)
    steps = {
        name: make_step(partial(fn, cfg=cfg, p=P), opt)
        for name, fn in (("ours", loss_terms), ("reference", reference_loss), ("plain", plain_loss))
    }
    out = {}
    for b in BATCHES:
        k = jax.random.split(kd, 4)
        batch = tuple(jax.random.normal(ki, s, jnp.float64) for ki, s in zip(k, [(b, N), (b, N), (b,), (b, N)]))
        ref_reps = reps if b < 1000 else max(5, reps // 10)
        r = {
            "ours_ms": time_step(steps["ours"], nnphd_params, batch, opt, reps, blocks),
            "reference_ms": time_step(steps["reference"], nnphd_params, batch, opt, ref_reps, blocks),
            "plain_ms": time_step(steps["plain"], plain_params, batch, opt, reps, blocks),
            "reps_per_block": {"ours": reps, "reference": ref_reps, "plain": reps},
            "blocks": blocks,
        }
        r.update(reference_over_ours=r["reference_ms"] / r["ours_ms"], ours_over_plain=r["ours_ms"] / r["plain_ms"])
        r.update(
            goal_reference_met=r["reference_over_ours"] >= GOAL_REF, goal_plain_met=r["ours_over_plain"] <= GOAL_PLAIN
        )
        out[str(b)] = r
    return out


def bench_sweeps() -> dict:
    out = {}
    for label, system, mode in (
        ("ho+ld warm", "ho+ld", "warm"),
        ("ho+ld vmap", "ho+ld", "vmap"),
        ("ho+mf warm", "ho+mf", "warm"),
    ):
        t0 = time.perf_counter()
        res = run_sweep(system, SweepSettings(steps=2000, seed=0, mode=mode))
        total = time.perf_counter() - t0
        out[label] = {"total_s": total, "sweep_only_s": res.wall_time_s, "goal_met": total <= GOAL_SWEEP}
    return out


def write_json(path: Path, obj: dict) -> None:
    """``obj`` as JSON at ``path`` (its folder made), written atomically (:func:`nnphd.io.results.write_json`)."""
    from nnphd.io.results import write_json as _write

    path.parent.mkdir(parents=True, exist_ok=True)
    _write(path, obj)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="skip the full λ-sweeps (step timings only)")
    ap.add_argument("--reps", type=int, default=50, help="steps per timed block (reference at B=1000: max(5, reps/10))")
    ap.add_argument("--blocks", type=int, default=3, help="timed blocks; the median is reported")
    args = ap.parse_args()
    if args.reps < 1 or args.blocks < 1:
        ap.error("--reps and --blocks must be ≥ 1")
    info = machine_info()
    print(
        f"machine: {info['cpu_model']}, nproc={info['nproc']}, jax {info['jax_version']} ({info['jax_backend']}), "
        f"load {info['loadavg_1min']:.2f}; n={N}, float64, widths 200-200"
    )
    steps = bench_steps(args.reps, args.blocks)
    yes = lambda ok: "yes" if ok else "NO"
    print(
        f"\n{'B':>5} {'ours ms':>9} {'ref ms':>9} {'plain ms':>9} {'ref/ours (goal ≥3)':>20} {'ours/plain (goal ≤3)':>22}"
    )
    for b, r in steps.items():
        print(
            f"{b:>5} {r['ours_ms']:>9.3f} {r['reference_ms']:>9.3f} {r['plain_ms']:>9.3f} "
            f"{r['reference_over_ours']:>11.2f} met={yes(r['goal_reference_met']):<3} "
            f"{r['ours_over_plain']:>13.2f} met={yes(r['goal_plain_met'])}"
        )
    sweeps = None if args.quick else bench_sweeps()
    if sweeps:
        print(f"\n{'13-λ sweep, 2000 steps/λ':<26} {'total s':>8} {'sweep s':>8}  goal ≤{GOAL_SWEEP:g} s")
        for label, r in sweeps.items():
            print(f"{label:<26} {r['total_s']:>8.2f} {r['sweep_only_s']:>8.2f}  met={yes(r['goal_met'])}")
    print("\n(--quick: sweeps skipped)" if args.quick else "")
    goals = {"reference_over_ours_min": GOAL_REF, "ours_over_plain_max": GOAL_PLAIN, "sweep_s_max": GOAL_SWEEP}
    path = Path(__file__).resolve().parent / "results" / "speed.json"
    write_json(
        path,
        {
            "machine": info,
            "args": vars(args),
            "goals": goals,
            "steps": steps,
            "sweeps": sweeps,
            "timestamp": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
        },
    )
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
