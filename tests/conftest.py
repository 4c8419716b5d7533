"""The tests run nnphd's low-level modules directly, as the CLI does: float64 and the XLA:CPU setting on
(:func:`nnphd.configure`). tests/test_api.py checks that a bare ``import nnphd`` changes neither, in a fresh
interpreter."""

import nnphd

nnphd.configure()
