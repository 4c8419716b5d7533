"""nnphd — Neural New-Physics Detector.

Splits a force field q̈ = f(q, q̇, t) into a conservative part learned by a Lagrangian neural network (LNN)
and the smallest non-conservative remainder learned by a free MLP (the UAN), after Liu et al.,
"Machine-Learning Non-Conservative Dynamics for New-Physics Detection".

    import nnphd
    model = nnphd.NNPhD(seed=0).fit(nnphd.Trajectories(t, q, traj=ids, names=["x"]))

Importing nnphd changes nothing in your session (JAX's float64 switch, XLA_FLAGS, the matplotlib backend): the
API computes in float64 inside its own calls. :func:`configure` sets the process-wide settings the command line and
the tests use.
"""

from __future__ import annotations

import os

__version__ = "0.1.0"

__all__ = ["Law", "NNPhD", "Trajectories", "Verdict", "__version__", "configure", "load"]

XLA_FLAG = "--xla_cpu_experimental_ynn_fusion_type="
ONE_THREAD_FLAGS = "--xla_cpu_multi_thread_eigen=false"


def configure(x64: bool = True, fast_cpu: bool = True, one_thread: bool = True) -> None:
    """Process-wide settings for nnphd's own programs (the CLI, the tests, the benchmarks, the Dask workers).

    ``x64``: turn on JAX float64 everywhere (the low-level modules, e.g. :mod:`nnphd.user.assess`, expect it).
    ``fast_cpu``: add ``--xla_cpu_experimental_ynn_fusion_type=`` to XLA_FLAGS — XLA:CPU (jax 0.10) routes small
    matrix products through YNNPACK, 1.8–2.5× slower for these models (benchmarks/bench_speed.py).
    ``one_thread``: one XLA thread (no Eigen thread pool). Eigen splits a matrix product's sums differently with
    more threads, which changes the last bits and, after thousands of training steps, the 5th digit; with one
    thread here and in every Dask worker (:mod:`nnphd.parallel`) the same seed gives the same numbers whatever the
    number of workers. More cores are used through workers; one sweep alone is as fast as with the Eigen pool on
    2 cores (``nnphd sweep --steps 500``: 16.0 and 21.4 s against 19.0 and 20.8 s, alternating runs).
    The XLA flags only take effect if JAX has not started its backend yet; NNPHD_KEEP_XLA_FLAGS=1 vetoes both.
    """
    flags = os.environ.get("XLA_FLAGS", "")
    if not os.environ.get("NNPHD_KEEP_XLA_FLAGS"):
        if one_thread and "multi_thread_eigen" not in flags:
            flags += " " + ONE_THREAD_FLAGS
        if fast_cpu and "ynn_fusion_type" not in flags:  # last: a flag after its empty value would be lost
            flags += " " + XLA_FLAG
        if flags.strip():
            os.environ["XLA_FLAGS"] = flags.strip()
    if x64:
        import jax

        jax.config.update("jax_enable_x64", True)


def __getattr__(name: str):  # the API loads on first use, so `import nnphd` stays light and inert
    if name in ("Law", "NNPhD", "Trajectories", "Verdict", "load"):
        from nnphd import api

        return getattr(api, name)
    raise AttributeError(f"module 'nnphd' has no attribute {name!r}")


def __dir__():
    return sorted(__all__)
