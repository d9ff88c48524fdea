"""The on-disk cache of compiled programs (jaxdea.compiled): a fresh process loads them without
tracing and gets the same bits; what it cannot key (tracers, debugging) goes through jax.jit;
a damaged entry is compiled anew."""

import os
import subprocess
import sys
import textwrap

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxdea.compiled import cached_jit


def _scaled(x, n):
    return x * n


def _entries(root):
    folder = root / "executables"
    return sorted(folder.iterdir()) if folder.exists() else []


@pytest.fixture
def cache(tmp_path, monkeypatch):
    monkeypatch.setenv("JAXDEA_CACHE_DIR", str(tmp_path))
    return tmp_path


def test_key_separates_static_arguments_and_argument_types(cache):
    fun = cached_jit(_scaled, static_argnames="n")
    x = jnp.arange(3.0)
    np.testing.assert_array_equal(fun(x, 2), 2 * x)
    np.testing.assert_array_equal(fun(x, n=2), 2 * x)  # the same program
    assert len(_entries(cache)) == 1 and fun._cache_size() == 1
    fun(x, 3)
    fun(jnp.arange(4.0), 3)
    fun(jnp.arange(3, dtype=jnp.float32), 3)
    fun(np.float64(1.5), 3)
    fun(1.5, 3)  # a weakly typed Python float: another program than the float64 scalar
    assert len(_entries(cache)) == 6 and fun._cache_size() == 6


def test_damaged_entry_is_compiled_anew(cache):
    x = jnp.arange(3.0)
    cached_jit(_scaled, static_argnames="n")(x, 2)
    (entry,) = _entries(cache)
    entry.write_bytes(b"not a program")
    fresh = cached_jit(_scaled, static_argnames="n")  # a new process holds nothing in memory
    np.testing.assert_array_equal(fresh(x, 2), 2 * x)
    assert _entries(cache) == [entry] and entry.stat().st_size > 1000
    again = cached_jit(_scaled, static_argnames="n")
    np.testing.assert_array_equal(again(x, 2), 2 * x)  # loads the rewritten entry
    assert again._jit._cache_size() == 0


def test_entry_that_fails_to_run_is_compiled_anew(cache):
    """An entry that loads but fails on its first run (here the program of another argument shape
    under this key; in the wild, an executable that XLA:CPU re-serialised from JAX's cache) is
    deleted and the program compiled anew."""
    x3, x4 = jnp.arange(3.0), jnp.arange(4.0)
    fun = cached_jit(_scaled, static_argnames="n")
    fun(x3, 2)
    (entry,) = _entries(cache)
    wrong = fun._entry(fun._key((x4, 2), {})[0])
    wrong.write_bytes(entry.read_bytes())
    fresh = cached_jit(_scaled, static_argnames="n")
    np.testing.assert_array_equal(fresh(x4, 2), 2 * x4)
    assert fresh.counts == {"loaded": 0, "compiled": 1}
    again = cached_jit(_scaled, static_argnames="n")
    np.testing.assert_array_equal(again(x4, 2), 2 * x4)
    assert again.counts == {"loaded": 1, "compiled": 0}


def test_transformations_and_debugging_go_through_jit(cache):
    """Tracers and jax.debug_nans: jax.jit, nothing stored (arrays committed to other devices, the
    blocks of a sharded sweep, are the third case: tests/test_scaleout.py)."""
    fun = cached_jit(_scaled, static_argnames="n")
    np.testing.assert_array_equal(jax.vmap(lambda x: fun(x, 2))(jnp.arange(3.0)), [0.0, 2.0, 4.0])
    assert float(jax.grad(lambda x: fun(x, 3))(1.0)) == 3.0
    with jax.debug_nans(True):
        np.testing.assert_array_equal(fun(jnp.ones(2), 2), [2.0, 2.0])
    assert _entries(cache) == [] and fun.counts == {"loaded": 0, "compiled": 0}


def test_off_writes_nothing(tmp_path, monkeypatch):
    monkeypatch.setenv("JAXDEA_CACHE_DIR", "off")
    fun = cached_jit(_scaled, static_argnames="n")
    np.testing.assert_array_equal(fun(jnp.ones(2), 2), [2.0, 2.0])
    assert fun._jit._cache_size() == 1 and not any(tmp_path.iterdir())


FRESH_PROCESS = textwrap.dedent("""
    import jax
    jax.config.update("jax_enable_x64", True)
    import jaxdea as jd
    from jaxdea import dispersion, roots
    # every program into JAX's cache, however fast it compiled (the third process reads them there)
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.0)
    tube = jd.Tube(voltage=0.1, lambda_i=0.9, lambda_z=1.2)
    f = jd.characteristic(tube, 1.3, 0.445, n_layers=8)
    omega = jd.frequencies(tube, 0.445, n_roots=2, n_layers=8)
    programs = (dispersion._characteristic, roots._solve_frequencies)
    counts = [(p.counts["loaded"], p.counts["compiled"], p._jit._cache_size()) for p in programs]
    slope = jax.grad(lambda v: jd.characteristic(tube.replace(voltage=v), 1.3, 0.445, n_layers=8))(0.1)
    print(repr(float(f)), *map(repr, map(float, omega)), repr(float(slope)))
    print(counts)
""")


def test_a_fresh_process_loads_the_programs_without_tracing(cache):
    """Two fresh processes: the first compiles and stores ``characteristic`` and ``frequencies``,
    the second loads them (nothing traced by jax.jit) and prints the same bits; a gradient (tracers)
    is compiled by jax.jit in both, equal too. A third, with the entries deleted, takes the programs
    from JAX's persistent cache and writes none."""
    env = dict(os.environ, JAXDEA_CACHE_DIR=str(cache))

    def run():
        out = subprocess.run([sys.executable, "-c", FRESH_PROCESS], env=env, capture_output=True,
                             text=True, timeout=600)
        assert out.returncode == 0, out.stderr
        values, counts = out.stdout.splitlines()
        return values, counts

    first, compiled = run()
    stored = _entries(cache)
    second, loaded = run()
    assert compiled == "[(0, 1, 0), (0, 1, 0)]"  # each compiled once, jax.jit's cache unused
    assert loaded == "[(1, 0, 0), (1, 0, 0)]", "a program was traced where it could be loaded"
    assert second == first  # f, the two roots and the gradient, to the last bit
    assert len(stored) == 2 and _entries(cache) == stored
    # programs that JAX's own cache supplies are not written (such entries failed to run)
    for entry in stored:
        entry.unlink()
    third, from_xla = run()
    assert from_xla == "[(0, 1, 0), (0, 1, 0)]" and third == first and _entries(cache) == []


def test_compiler_options_on_top_level_programs_only():
    """jaxdea.compiled.jit: a top-level call runs the program compiled with COMPILER_OPTIONS, a
    call inside a caller's trace (tracers, or concrete arguments staged into a jit) the plain
    jax.jit, as JAX requires (options on a nested jit raise); the values agree."""
    from jaxdea.compiled import jit

    fun = jit(_scaled, static_argnames="n")
    plain, calls = fun._nested, []
    fun._nested = lambda *a, **k: calls.append(1) or plain(*a, **k)
    x = jnp.arange(3.0)
    np.testing.assert_array_equal(fun(x, 2), 2 * x)
    assert not calls
    np.testing.assert_array_equal(jax.jit(lambda y: fun(y, 2))(x), 2 * x)  # tracers
    np.testing.assert_array_equal(jax.jit(lambda: fun(x, 3))(), 3 * x)  # concrete, staged
    assert float(jax.grad(lambda y: fun(y, 3))(1.0)) == 3.0
    assert len(calls) == 3
    with pytest.raises(ValueError, match="compiler_options"):  # why the plain jit is needed
        jax.jit(lambda: fun._top(x, 3))()
