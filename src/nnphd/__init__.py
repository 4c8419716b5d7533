"""nnphd — Neural New-Physics Detector.

Splits a force field q̈ = f(q, q̇, t) into a conservative part learned by a Lagrangian neural network (LNN)
and the smallest non-conservative remainder learned by a free MLP (the UAN), after Liu et al.,
"Machine-Learning Non-Conservative Dynamics for New-Physics Detection".
"""
import jax

# Float64 is available everywhere; models choose their dtype (float64 by default, where accuracy needs it).
jax.config.update("jax_enable_x64", True)

__version__ = "0.1.0"
