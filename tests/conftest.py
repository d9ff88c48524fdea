"""Shared test set-up: 64-bit floats and finite-difference helpers."""

import os

import jax

jax.config.update("jax_enable_x64", True)
# compiled programs are reused across test processes and runs (compilation dominates test time):
# XLA's in .jax_cache/xla, jaxdea's executables (jaxdea.compiled) in .jax_cache/executables unless
# JAXDEA_CACHE_DIR names another root
CACHE_ROOT = os.path.join(os.path.dirname(os.path.dirname(__file__)), ".jax_cache")
os.environ.setdefault("JAXDEA_CACHE_DIR", CACHE_ROOT)
jax.config.update("jax_compilation_cache_dir", os.path.join(CACHE_ROOT, "xla"))
jax.config.update("jax_persistent_cache_min_compile_time_secs", 1.0)

import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402

import jaxdea.compiled  # noqa: E402


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

