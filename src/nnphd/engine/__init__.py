"""The engine: systems and their data, the networks (LNN, UAN), training and the λ-sweep, the verdict.

Lowest layer: imports only :mod:`nnphd.io` and itself (never explain/, user/, paper/, astro/ or the CLI).
"""
