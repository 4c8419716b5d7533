"""nnphd — Neural New-Physics Detector.

Splits a force field q̈ = f(q, q̇, t) into a conservative part learned by a Lagrangian neural network (LNN)
and the smallest non-conservative remainder learned by a free MLP (the UAN), after Liu et al.,
"Machine-Learning Non-Conservative Dynamics for New-Physics Detection".
"""
import os

# XLA:CPU (jax 0.10) routes small matrix products and their fusions through YNNPACK; for this model's training step
# that is 1.8-2.5x slower than the default emitters (measured: 2.5 → 1.4 ms per step at batch 32, 131 → 53 ms for the
# LNN-derivative gradient at batch 1000; see benchmarks/bench_speed.py). The flag must be set before JAX starts its
# backend; set NNPHD_KEEP_XLA_FLAGS=1 to leave XLA_FLAGS alone.
if not os.environ.get("NNPHD_KEEP_XLA_FLAGS") and "ynn_fusion_type" not in os.environ.get("XLA_FLAGS", ""):
    os.environ["XLA_FLAGS"] = (os.environ.get("XLA_FLAGS", "") + " --xla_cpu_experimental_ynn_fusion_type=").strip()

import jax  # noqa: E402

# Float64 is available everywhere; models choose their dtype (float64 by default, where accuracy needs it).
jax.config.update("jax_enable_x64", True)

__version__ = "0.1.0"
