"""FLOP efficiency of one training step, against a float64 GEMM on the same machine, in one run.

For each step (one jitted value_and_grad of L_e + λ L_b and an Adam update, as the trainer runs it):

* FLOPs per step from XLA's own cost analysis (``jit(step).lower(...).compile().cost_analysis()["flops"]``);
* ms per step (median over ``--blocks`` blocks, each a jitted ``lax.scan`` of ``--reps`` steps, compile not timed);
* GFLOP/s and the percentage of the peak measured on a float64 2000×2000 @ 2000×2000 product (2·2000³ FLOPs).

Steps measured: ours (the derivative-carrying LNN pass + UAN), the reference (per-sample ``jax.hessian`` under vmap,
as the original LNN code) and a plain MLP of the same widths, at batch 32 and 1000; and ours at batch 32 with K
independent copies vmapped into one program — K = 13 λ values sharing a batch (``nnphd sweep --mode vmap``) and K = 32
seeds with their own initial weights and minibatches. Two breakdown rows say where the time goes: our gradient with
a plain SGD update instead of Adam, and Adam's update alone (batch 0: it costs the same at every batch, per
parameter, so K vmapped copies pay it K times). Everything runs under ``nnphd.configure()``: float64 and one XLA
thread (so the GEMM peak is one core's, like the step).

Run:  .venv/bin/python benchmarks/bench_flops.py [--reps 100] [--blocks 3]
Writes benchmarks/results/flops.json.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from functools import partial
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import jax
import jax.numpy as jnp
import optax
from bench_speed import machine_info, make_step, plain_loss, reference_loss, write_json

from nnphd.engine.models import ModelConfig, init_nnphd, init_uan
from nnphd.engine.train import loss_terms

N, P, GEMM_N = 2, 1.0, 2000
GOAL_BATCH32 = 0.65  # of the GEMM peak, for batch-32 work (issue 14)


def flops_of(fn, *args) -> float:
    """FLOPs of one call of ``fn`` on ``args`` from XLA's cost analysis of the compiled program."""
    ca = jax.jit(fn).lower(*args).compile().cost_analysis()
    if isinstance(ca, list | tuple):  # older jax: one dict per computation
        ca = ca[0]
    return float(ca["flops"])


def timed(fn, args, reps: int, blocks: int) -> float:
    """Median seconds per call of ``fn(*args) -> args`` over ``blocks`` blocks of a ``lax.scan`` of ``reps`` calls."""

    @jax.jit
    def loop(args):
        return jax.lax.scan(lambda c, _: (fn(*c), None), args, None, length=reps)[0]

    args = jax.block_until_ready(loop(args))
    times = []
    for _ in range(blocks):
        t0 = time.perf_counter()
        args = jax.block_until_ready(loop(args))
        times.append((time.perf_counter() - t0) / reps)
    return statistics.median(times)


def gemm_peak(blocks: int) -> dict:
    """GFLOP/s of a float64 GEMM_N³ matrix product (median of ``blocks`` runs after a compiling one)."""
    ka, kb = jax.random.split(jax.random.PRNGKey(1))
    a = jax.random.normal(ka, (GEMM_N, GEMM_N), jnp.float64)
    b = jax.random.normal(kb, (GEMM_N, GEMM_N), jnp.float64)
    mm = jax.jit(jnp.matmul)
    jax.block_until_ready(mm(a, b))
    times = []
    for _ in range(max(blocks, 7)):
        t0 = time.perf_counter()
        jax.block_until_ready(mm(a, b))
        times.append(time.perf_counter() - t0)
    flops = 2.0 * GEMM_N**3
    return {
        "n": GEMM_N,
        "flops": flops,
        "s": statistics.median(times),
        "gflops": flops / statistics.median(times) / 1e9,
    }


def _batch(key, b: int):
    k = jax.random.split(key, 4)
    return tuple(jax.random.normal(ki, s, jnp.float64) for ki, s in zip(k, [(b, N), (b, N), (b,), (b, N)]))


def cases():
    """(label, batch, copies, step(params, opt_state) -> (params, opt_state), (params, opt_state))."""
    cfg, opt = ModelConfig(n=N), optax.adam(1e-3)
    kp, kd = jax.random.split(jax.random.PRNGKey(0))
    lam = jnp.asarray(1.0)
    losses = {"ours": loss_terms, "reference": reference_loss, "plain": plain_loss}
    inits = {"ours": init_nnphd, "reference": init_nnphd, "plain": init_uan}
    for name, loss in losses.items():
        step = make_step(partial(loss, cfg=cfg, p=P), opt)
        params = inits[name](kp, cfg)
        for b in (32, 1000):
            batch = _batch(kd, b)
            yield (
                name,
                b,
                1,
                lambda p, o, step=step, batch=batch: step(p, o, batch, lam)[:2],
                (params, opt.init(params)),
            )
    # where the time of our step goes: the same gradient with a plain SGD update (one fused op per weight array), and
    # Adam's update alone (per parameter: independent of the batch, and not shared by vmapped copies)
    p0 = init_nnphd(kp, cfg)

    def objective(params, batch):
        le, lb = loss_terms(params, *batch, cfg=cfg, p=P)
        return le + lam * lb

    def sgd_step(params, o, batch):
        return jax.tree_util.tree_map(lambda w, g: w - 1e-9 * g, params, jax.grad(objective)(params, batch)), o

    g0 = jax.tree_util.tree_map(lambda w: 1e-3 * jnp.ones_like(w), p0)

    def adam_alone(params, o):
        updates, o = opt.update(g0, o, params)
        return optax.apply_updates(params, updates), o

    for b in (32, 1000):
        batch = _batch(kd, b)
        yield "breakdown: ours with SGD", b, 1, partial(sgd_step, batch=batch), (p0, opt.init(p0))
    yield "breakdown: Adam alone", 0, 1, adam_alone, (p0, opt.init(p0))
    step = make_step(partial(loss_terms, cfg=cfg, p=P), opt)
    # K λ values, one shared batch (as a vmapped λ-sweep): the copies differ only in λ and their weights
    lams = jnp.asarray([0.01, 0.02, 0.05, 0.1, 0.2, 0.5, 1.0, 2.0, 5.0, 10.0, 20.0, 50.0, 100.0])
    batch = _batch(kd, 32)
    p0 = init_nnphd(kp, cfg)
    stack = lambda tree, k: jax.tree_util.tree_map(lambda a: jnp.broadcast_to(a, (k, *a.shape)), tree)
    vstep = jax.vmap(lambda p, o, lm: step(p, o, batch, lm)[:2])
    yield "ours, 13 λ vmapped", 32, 13, lambda p, o: vstep(p, o, lams), (stack(p0, 13), stack(opt.init(p0), 13))
    # K seeds: own weights, own minibatch
    for k in (32,):
        pk = jax.vmap(lambda key: init_nnphd(key, cfg))(jax.random.split(kp, k))
        bk = jax.vmap(lambda key: _batch(key, 32))(jax.random.split(kd, k))
        sstep = jax.vmap(lambda p, o, bt: step(p, o, bt, lam)[:2])
        yield (
            f"ours, {k} seeds vmapped",
            32,
            k,
            lambda p, o, bk=bk, sstep=sstep: sstep(p, o, bk),
            (pk, jax.vmap(opt.init)(pk)),
        )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--reps", type=int, default=100, help="steps per timed block (batch 1000 reference: reps/10)")
    ap.add_argument("--blocks", type=int, default=3, help="timed blocks; the median is reported")
    args = ap.parse_args()
    if args.reps < 1 or args.blocks < 1:
        ap.error("--reps and --blocks must be ≥ 1")
    info = machine_info()
    peak = gemm_peak(args.blocks)
    print(
        f"machine: {info['cpu_model']}, nproc={info['nproc']}, jax {info['jax_version']}, load "
        f"{info['loadavg_1min']:.2f}; float64, one XLA thread; n={N}, widths 200-200\n"
        f"GEMM peak: {GEMM_N}³ float64 product {peak['s'] * 1e3:.1f} ms = {peak['gflops']:.2f} GFLOP/s\n"
    )
    print(f"{'step':<24} {'batch':>5} {'copies':>6} {'MFLOP':>9} {'ms':>9} {'GFLOP/s':>8} {'% peak':>7}")
    rows = []
    for label, b, k, fn, state in cases():
        flops = flops_of(fn, *state)
        reps = args.reps if not (label == "reference" and b == 1000) else max(5, args.reps // 10)
        s = timed(fn, state, reps, args.blocks)
        row = {
            "step": label,
            "batch": b,
            "copies": k,
            "mflop": flops / 1e6,
            "ms": s * 1e3,
            "gflops": flops / s / 1e9,
            "fraction_of_peak": flops / s / 1e9 / peak["gflops"],
            "reps_per_block": reps,
        }
        rows.append(row)
        print(
            f"{label:<24} {b:>5} {k:>6} {row['mflop']:>9.1f} {row['ms']:>9.3f} {row['gflops']:>8.2f} "
            f"{100 * row['fraction_of_peak']:>6.1f}%"
        )
    get = lambda step, b: next(r for r in rows if r["step"] == step and r["batch"] == b)
    ratios = {
        "ours_over_plain_flops_b1000": get("ours", 1000)["mflop"] / get("plain", 1000)["mflop"],
        "reference_over_ours_flops_b1000": get("reference", 1000)["mflop"] / get("ours", 1000)["mflop"],
        "best_batch32_fraction": max(
            r["fraction_of_peak"]
            for r in rows
            if r["batch"] == 32 and r["step"].startswith("ours")  # the trainer's steps
        ),
    }
    print(
        f"\nFLOPs at batch 1000: ours/plain {ratios['ours_over_plain_flops_b1000']:.2f}, reference/ours "
        f"{ratios['reference_over_ours_flops_b1000']:.2f}; best batch-32 work of ours: "
        f"{100 * ratios['best_batch32_fraction']:.1f}% of peak (goal ≥ {100 * GOAL_BATCH32:.0f}%: "
        f"{'met' if ratios['best_batch32_fraction'] >= GOAL_BATCH32 else 'NOT met'})"
    )
    path = Path(__file__).resolve().parent / "results" / "flops.json"
    write_json(
        path,
        {
            "machine": info,
            "args": vars(args),
            "gemm": peak,
            "rows": rows,
            "ratios": ratios,
            "goal_batch32_fraction": GOAL_BATCH32,
            "timestamp": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
        },
    )
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
