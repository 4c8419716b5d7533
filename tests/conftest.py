"""The tests run nnphd's low-level modules directly, as the CLI does: float64 and the XLA:CPU setting on
(:func:`nnphd.configure`). tests/test_api.py checks that a bare ``import nnphd`` changes neither, in a fresh
interpreter.

Compiled programs are cached on disk for the whole test run (one fresh folder, shared by the pytest-xdist processes,
the Dask workers the tests start and the CLI calls, removed at the end): most of the suite's time is XLA compiling
the same small programs in different processes. The cached program is the compiled one, so no number changes.
"""

import os
import shutil
import tempfile

import nnphd

_OWN_CACHE = None
if nnphd.COMPILE_CACHE_ENV not in os.environ:  # set here in the main pytest process; its xdist workers inherit it
    _OWN_CACHE = tempfile.mkdtemp(prefix="nnphd-test-jax-cache-")
    os.environ[nnphd.COMPILE_CACHE_ENV] = _OWN_CACHE
nnphd.configure()


def pytest_unconfigure(config):
    if _OWN_CACHE is not None and not hasattr(config, "workerinput"):
        shutil.rmtree(_OWN_CACHE, ignore_errors=True)
