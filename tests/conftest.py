"""Shared test set-up: 64-bit floats and finite-difference helpers."""

import os

import jax

jax.config.update("jax_enable_x64", True)
# compiled programs are reused across test processes and runs (compilation dominates test time):
# jaxdea.configure's disk cache under .jax_cache (XLA's in xla/, jaxdea's exported programs in
# programs/) unless JAXDEA_CACHE_DIR names another root, and XLA's loop threshold, as users get them
CACHE_ROOT = os.path.join(os.path.dirname(os.path.dirname(__file__)), ".jax_cache")
os.environ.setdefault("JAXDEA_CACHE_DIR", CACHE_ROOT)

import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402

import jaxdea.compiled  # noqa: E402

jaxdea.compiled.configure()


SLOW_LIST = os.path.join(os.path.dirname(__file__), "slow.txt")
"""Tests moved to the slow tier by measured duration (one file, function or case a line)."""


def slow_entries(path=SLOW_LIST) -> list[str]:
    """The entries of :data:`SLOW_LIST`, comments and blank lines skipped."""
    with open(path, encoding="utf-8") as stream:
        return [line.strip() for line in stream if line.strip() and not line.startswith("#")]


def _listed(nodeid: str, entries: frozenset) -> bool:
    """True where ``nodeid`` is an entry, or lies in a listed file or function."""
    base = nodeid.split("[", 1)[0]
    return nodeid in entries or base in entries or nodeid.split("::", 1)[0] in entries


def pytest_ignore_collect(collection_path, config):
    """The default tier (``-m 'not slow'``) does not import the files listed whole in
    :data:`SLOW_LIST`: they may need the ``all`` extra, which the default tier does without."""
    if config.getoption("markexpr", "") != "not slow" or collection_path.suffix != ".py":
        return None
    relative = os.path.relpath(collection_path, os.path.dirname(os.path.dirname(__file__)))
    return True if relative.replace(os.sep, "/") in slow_entries() else None


@pytest.hookimpl(tryfirst=True)
def pytest_collection_modifyitems(config, items):
    """Marks the tests of :data:`SLOW_LIST` slow, before ``-m`` selects a tier."""
    entries = frozenset(slow_entries())
    for item in items:
        if _listed(item.nodeid, entries):
            item.add_marker(pytest.mark.slow)


def fd_derivative(fun, x, h=None):
    """Central difference (f(x + h) − f(x − h)) / 2h with h ~ eps^(1/3)·max(1, |x|) by default
    (truncation O(h²) and rounding O(eps/h) balanced)."""
    x = float(x)
    if h is None:
        h = 6e-6 * max(1.0, abs(x))
    return (float(fun(jnp.asarray(x + h))) - float(fun(jnp.asarray(x - h)))) / (2.0 * h)


def assert_tree_allclose(a, b, rtol=1e-12, atol=0.0):
    """allclose on every leaf of two pytrees."""
    la, lb = jax.tree_util.tree_leaves(a), jax.tree_util.tree_leaves(b)
    assert len(la) == len(lb)
    for x, y in zip(la, lb, strict=True):
        np.testing.assert_allclose(np.asarray(x), np.asarray(y), rtol=rtol, atol=atol)


@pytest.fixture(autouse=True, scope="module")
def _free_compiled_programs():
    """Each test module's compiled programs are freed after it (they are reloaded from the disk
    cache where a later module needs them): the worker processes of a test run stay a few GB."""
    yield
    jaxdea.compiled.clear_memory()



DURATIONS = os.path.join(os.path.dirname(__file__), "durations")
"""Folder of the seconds of every test of the latest run of each tier (``default.json``: the
default tier, ``slow.json``: ``-m slow``, ``all.json``: ``-m ""``), setup, call and teardown
together, slowest first: the next slow test is found by looking there (``tests/README.md``)."""
TIERS = {"not slow": "default", "slow": "slow", "": "all"}
_durations: dict = {}


def pytest_runtest_logreport(report):
    """Collects each phase's duration (on the controller process too under pytest-xdist)."""
    entry = _durations.setdefault(report.nodeid, {"seconds": 0.0, "slow": "slow" in report.keywords})
    entry["seconds"] += report.duration


def pytest_sessionfinish(session, exitstatus):
    """Writes the tier's file in :data:`DURATIONS` (atomically) after a run of a whole tier; runs of
    a few files or tests, or with ``-k``, leave it alone."""
    config = session.config
    tier = TIERS.get(config.getoption("markexpr", ""))
    if (not _durations or tier is None or getattr(config, "workerinput", None) is not None
            or config.getoption("keyword", "") or config.args not in ([], ["tests"])):
        return
    import json

    rows = sorted(({"test": k, **v, "seconds": round(v["seconds"], 2)} for k, v in _durations.items()),
                  key=lambda row: -row["seconds"])
    payload = {"tier": tier, "exit_status": int(exitstatus),
               "total_seconds": round(sum(r["seconds"] for r in rows), 1), "tests": rows}
    os.makedirs(DURATIONS, exist_ok=True)
    path = os.path.join(DURATIONS, f"{tier}.json")
    with open(path + ".tmp", "w", encoding="utf-8") as stream:
        json.dump(payload, stream, indent=0, ensure_ascii=False)
        stream.write("\n")
    os.replace(path + ".tmp", path)
