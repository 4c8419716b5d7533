"""The tests run nnphd's low-level modules directly, as the CLI does: float64 and the XLA:CPU setting on
(:func:`nnphd.configure`). tests/test_api.py checks that a bare ``import nnphd`` changes neither, in a fresh
interpreter.

Compiled programs are cached on disk for the whole test run (one fresh folder, shared by the pytest-xdist processes,
the Dask workers the tests start and the CLI calls, removed at the end): most of the suite's time is XLA compiling
the same small programs in different processes. The cached program is the compiled one, so no number changes.

The user's cache folder ($XDG_CACHE_HOME: the key that signs nnphd's caches) is a fresh one of the test run too, so
the tests neither read nor write the real ~/.cache, and run where it is not writable.
"""

import os
import shutil
import tempfile

import nnphd
from nnphd.engine import stored

_OWN_CACHE = _OWN_HOME = None
if "NNPHD_TEST_CACHE_HOME" not in os.environ:  # the main pytest process; its xdist workers inherit it
    _OWN_HOME = tempfile.mkdtemp(prefix="nnphd-test-cache-home-")
    os.environ["NNPHD_TEST_CACHE_HOME"] = os.environ["XDG_CACHE_HOME"] = _OWN_HOME
if nnphd.COMPILE_CACHE_ENV not in os.environ:  # set here in the main pytest process; its xdist workers inherit it
    _OWN_CACHE = tempfile.mkdtemp(prefix="nnphd-test-jax-cache-")
    os.environ[nnphd.COMPILE_CACHE_ENV] = _OWN_CACHE
nnphd.configure()


def pytest_configure(config):
    # the fast tier (-m "not slow", the README's test command) compiles hundreds of small programs once each: storing
    # them for another process (nnphd.engine.stored) would cost it ~30 s and save nothing; tests/test_stored_programs.py
    # checks the store itself, and the slow tier (CI: every tier shares one cache) runs the end-to-end runs with it
    if (config.option.markexpr or "").replace(" ", "") == "notslow":
        os.environ.setdefault(stored.ENV, "0")


# pytest-xdist hands out whole modules (``--dist loadfile``) in the order of the collection (dev.py turns off its
# reordering by number of tests, which sent a module of one long test — the README's commands, 210 s — last, to run
# while the other worker sat idle): the longest modules first, so the last ones to start are short. The longest
# modules of each tier, longest first, as dev.py's durations showed them on 2 cores (a rough order is all it needs;
# the modules not named follow in their usual order).
LONGEST = {
    "slow": ("test_law_verdict", "test_unlike", "test_readme", "test_detect_recordings", "test_reproduce",
             "test_predict", "test_adaptive", "test_batch", "test_detect_file", "test_declared_field", "test_markers",
             "test_studies", "test_parallel", "test_api", "test_shape_classes", "test_symbolic", "test_trust"),
    "not slow": ("test_models", "test_train", "test_periodic", "test_shape_classes", "test_systems",
                 "test_alongside", "test_strategy_objects", "test_model_files", "test_laws", "test_api"),
}  # fmt: skip


def pytest_collection_modifyitems(config, items):
    longest = LONGEST.get(" ".join((config.option.markexpr or "").split()), ())
    rank = {m: i for i, m in enumerate(longest)}
    items.sort(key=lambda it: rank.get(it.nodeid.split("::")[0].rsplit("/", 1)[-1].removesuffix(".py"), len(rank)))


def pytest_unconfigure(config):
    if not hasattr(config, "workerinput"):
        for own in (_OWN_CACHE, _OWN_HOME):
            if own is not None:
                shutil.rmtree(own, ignore_errors=True)
