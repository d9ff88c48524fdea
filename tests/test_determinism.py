"""Determinism: the same inputs give bit-identical outputs across calls, processes, batch positions,
chunk sizes and grids (``np.testing.assert_array_equal``, NaN compared as equal).

What holds bit for bit (tested):

* the same call twice in a process, and in a fresh process that compiles everything anew;
* a point at any position inside a ``jax.vmap`` batch of other points (same batch size; the
  batches here vary the tube too: a batch of ``frequencies`` or ``critical_voltage`` over α̂ alone
  is continued along α̂, and there a point's last bits depend on its neighbours, equal to rounding,
  tests/test_vmap_rules.py);
* ``jaxdea.sweep`` of a grid with any ``chunk_size`` (points solved one after another,
  ``batch_size=1``, the CPU default), and the same point inside different grids.

What does not (XLA on CPU; measured, checked to agree to RTOL = 1e-13, README "Numerics"):

* a point alone against the same point inside a ``jax.vmap`` batch (even of size 1 for the group
  velocity), and a sweep with ``batch_size`` > 1 against ``batch_size=1``: results differ in the
  last bits (characteristic ~3e-15 relative, group velocity ~2e-15, roots ~6e-15). XLA:CPU always
  contracts a·b + c into fused multiply-adds inside a fused loop (no flag turns this off), and
  which products end up in the same fusion as their sums depends on the shapes (a batch dimension
  changes the fusion and vectorisation decisions); reductions over small axes (``jnp.sum``,
  ``jnp.dot``, ``jnp.linalg.norm``) are also vectorised in a shape-dependent order. The quadrature
  of the base state (jaxdea/physics/base_state.py) sums in a fixed order; the remaining differences
  come from the fusion of the state matrix into the sublayer exponential and from the Gram–Schmidt
  dot products (jaxdea/physics/transfer.py).

The default run checks each property on the configurations the other tests compile (n_layers = 30,
n_roots = 2 or 3, sweeps in chunks of 4); the rest is marked slow.
"""

import json
import os
import subprocess
import sys
import textwrap

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxdea as jd

TUBE = jd.Tube(voltage=0.1, lambda_i=0.9, lambda_z=1.2)
POINT = (0.13, 1.05, 0.7)  # V̂, λ_i, α̂ of the point followed through batches
RTOL = 1e-13  # agreement where bit identity does not hold (reported, see module docstring)

# the small case, computed here and in fresh processes (same source, executed in both)
CASE = textwrap.dedent('''
    import jax
    import numpy as np
    import jaxdea as jd

    def compute(with_fluid=False):
        tube = jd.Tube(voltage=0.13, lambda_i=1.05, lambda_z=1.2)
        fluid = jd.Fluid() if with_fluid else None
        out = {}
        out["characteristic"] = jd.characteristic(tube, 1.3, 0.7, fluid)
        roots = jd.solve_frequencies(tube, 0.7, fluid)
        out["frequencies"], out["status"] = roots.omega, roots.status
        out["group_velocity"] = jd.group_velocity(tube, 0.7, roots.omega[0], fluid)
        if with_fluid:
            out["dfdv"] = jax.grad(lambda v: jd.frequency(tube.replace(voltage=v), 0.7,
                                                          roots.omega[0], fluid))(0.13)
        return {k: [float(x).hex() for x in np.ravel(np.asarray(v, dtype=np.float64))]
                for k, v in out.items()}
''')


def _compute(with_fluid=False):
    namespace = {}
    exec(CASE, namespace)  # noqa: S102 - the same source as the subprocess
    return namespace["compute"](with_fluid)


def _in_fresh_process(with_fluid=False, cache=False):
    """The case in a new Python process: compiled from scratch (no persistent cache) unless
    ``cache``, in which case the cache of this test run is used."""
    env = dict(os.environ, JAXDEA_CACHE_DIR="off")
    cache_dir = jax.config.jax_compilation_cache_dir if cache else None
    script = "\n".join([
        "import jax",
        "jax.config.update('jax_enable_x64', True)",
        f"jax.config.update('jax_compilation_cache_dir', {cache_dir!r})" if cache_dir else "",
        "import jaxdea",
        "jaxdea.configure(cache=False)  # XLA's loop threshold, as the test process has it",
        CASE,
        "import json",
        f"print(json.dumps(compute({with_fluid!r})))",
    ])
    done = subprocess.run([sys.executable, "-c", script], env=env, capture_output=True, text=True,
                          timeout=900, check=False)
    assert done.returncode == 0, done.stderr[-3000:]
    return json.loads(done.stdout.strip().splitlines()[-1])


# --------------------------------------------------------------------------- runs and processes
def test_same_call_twice_in_one_process():
    first, second = _compute(), _compute()
    assert first == second
    calls = [
        lambda: jd.pressure_difference(TUBE),
        lambda: jd.sweep(TUBE, voltage=[0.0, 0.1], alpha=[0.445], n_roots=2, chunk_size=4,
                         batch_size=1, progress=False).omega,
    ]
    _assert_calls_repeat(calls)


def test_python_numpy_and_jax_inputs_give_the_same_bits():
    """Inputs as Python floats, NumPy values or JAX arrays (float64, or weakly typed) are one case:
    canonical() makes concrete numbers float64 NumPy arrays (no device operation), keeps float64
    JAX arrays and converts the others, and the roots and curves come out bit-identical."""
    from jaxdea.params import canonical

    tube, *values = canonical(TUBE, 0.5, np.float32(2.0), 3, np.arange(3))
    assert all(type(v) is np.ndarray and v.dtype == np.float64 for v in (tube.voltage, *values))
    same = jnp.asarray(0.445, jnp.float64)
    assert canonical(same) is same
    weak = canonical(jnp.asarray(0.445))  # a weakly typed float: converted, strongly typed
    assert weak.dtype == jnp.float64 and not weak.weak_type
    as_jax = jax.tree_util.tree_map(lambda x: jnp.asarray(x, jnp.float64), TUBE)
    grid = np.linspace(0.3, 0.6, 4)

    def solve(tube, alpha, grid):
        return (jd.frequencies(tube, alpha, n_roots=2, n_layers=30),
                jd.dispersion_curve(tube, grid, n_roots=2, n_layers=30))

    first = solve(TUBE, 0.445, grid)
    for args in ((as_jax, jnp.asarray(0.445), jnp.asarray(grid)), (TUBE, np.float64(0.445), list(grid))):
        got = solve(*args)
        for x, y in zip(jax.tree_util.tree_leaves(first), jax.tree_util.tree_leaves(got), strict=True):
            assert isinstance(x, jax.Array) and isinstance(y, jax.Array)
            np.testing.assert_array_equal(np.asarray(x), np.asarray(y))


def _assert_calls_repeat(calls):
    for call in calls:
        a, b = call(), call()
        for x, y in zip(jax.tree_util.tree_leaves(a), jax.tree_util.tree_leaves(b), strict=True):
            np.testing.assert_array_equal(np.asarray(x), np.asarray(y))


@pytest.mark.slow
def test_same_call_twice_slow_solvers():
    _assert_calls_repeat([lambda: jd.critical_voltage(TUBE, 0.445),
                          lambda: jd.inner_stretch(TUBE, 0.01),
                          lambda: jd.frequency(TUBE, 0.445, 0.7),
                          lambda: jd.mode_shape(TUBE, 0.445, float(jd.frequencies(TUBE, 0.445)[0]))])


def test_another_process_gives_the_same_bits():
    """A new process (loading the compiled programs of this test run from the persistent cache):
    the same bits as this process."""
    assert _in_fresh_process(cache=True) == _compute()


@pytest.mark.slow
def test_fresh_process_gives_the_same_bits():
    """A new process that compiles everything from scratch, with and without a fluid and for an
    implicit derivative: the same bits as this process."""
    assert _in_fresh_process() == _compute()
    here = _compute(with_fluid=True)
    assert _in_fresh_process(with_fluid=True) == here
    assert _in_fresh_process(with_fluid=True, cache=True) == here


# ------------------------------------------------------------------------------ vmap batches
def _batch(n, position, seed):
    """n random points with POINT at ``position``."""
    rng = np.random.default_rng(seed)
    v, li, a = rng.uniform(0.0, 0.2, n), rng.uniform(0.8, 1.2, n), rng.uniform(0.1, 3.0, n)
    v[position], li[position], a[position] = POINT
    return tuple(jnp.asarray(x) for x in (v, li, a))


def _characteristic(v, li, a):
    return jd.characteristic(TUBE.replace(voltage=v, lambda_i=li), 1.3, a)


def _frequencies(v, li, a):
    return jd.frequencies(TUBE.replace(voltage=v, lambda_i=li), a)


GUESS = 0.75  # Newton's start for the root of each point whose group velocity is batched


def _group_velocity(v, li, a):
    """The group velocity at the root that Newton reaches from GUESS (a non-root gives NaN)."""
    tube = TUBE.replace(voltage=v, lambda_i=li)
    return jd.group_velocity(tube, a, jd.frequency(tube, a, GUESS))


FUNCTIONS = {"characteristic": _characteristic, "frequencies": _frequencies,
             "group_velocity": _group_velocity}


SLOW = {"frequencies"}  # compiles the vmapped solver
CASES = [pytest.param(n, marks=pytest.mark.slow) if n in SLOW else n for n in sorted(FUNCTIONS)]


@pytest.mark.parametrize("name", CASES)
def test_batch_positions_are_bit_identical(name):
    """The point at the first, a middle and the last position of batches of other points (size
    5, different neighbours each time): the same bits."""
    batched = jax.vmap(FUNCTIONS[name])
    got = [np.asarray(batched(*_batch(5, pos, seed))[pos]) for pos, seed in ((0, 1), (2, 2), (4, 3))]
    assert np.all(np.isfinite(got[0])), got[0]  # numbers, not NaN compared with NaN
    for other in got[1:]:
        np.testing.assert_array_equal(other, got[0])


@pytest.mark.parametrize("name", CASES)
def test_alone_and_batched_agree_to_rounding(name):
    """Alone against inside a batch of 5 (and, slow, of 1): equal to rounding only, not bit for
    bit (module docstring; README "Numerics")."""
    fn = FUNCTIONS[name]
    alone = np.asarray(fn(*POINT))
    assert np.all(np.isfinite(alone)), alone  # assert_allclose takes NaN as equal to NaN
    np.testing.assert_allclose(np.asarray(jax.vmap(fn)(*_batch(5, 2, 6))[2]), alone, rtol=RTOL, atol=0)


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(FUNCTIONS))
def test_alone_and_in_a_batch_of_one_agree_to_rounding(name):
    fn = FUNCTIONS[name]
    np.testing.assert_allclose(np.asarray(jax.vmap(fn)(*_batch(1, 0, 6))[0]), np.asarray(fn(*POINT)),
                               rtol=RTOL, atol=0)


# ------------------------------------------------------------------------------------- sweeps
GRID = dict(voltage=[0.0, 0.05, 0.1], alpha=[0.2, 0.7])


def _sweep(**kwargs):
    res = jd.sweep(TUBE, n_roots=2, progress=False, **(GRID | kwargs))
    return res


def _assert_same(a, b):
    for name in ("omega", "status", "alpha"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)


def test_sweep_is_bit_identical_across_chunk_sizes():
    """chunk_size 1 and 4 (a 6-point grid: chunks of 1; 4 + 2 padded)."""
    _assert_same(_sweep(chunk_size=4, batch_size=1), _sweep(chunk_size=1, batch_size=1))


@pytest.mark.slow
def test_sweep_is_bit_identical_with_one_padded_chunk():
    _assert_same(_sweep(chunk_size=32, batch_size=1), _sweep(chunk_size=4, batch_size=1))


def test_same_point_in_different_grids():
    """A point inside grids of other sizes and values (same axes) gives the same bits, also
    when it is padded into the last chunk, and the same bits as jaxdea.frequencies."""
    full = _sweep(chunk_size=4, batch_size=1)
    small = jd.sweep(TUBE, voltage=[0.05], alpha=[0.7, 2.5, 0.2], n_roots=2, chunk_size=4,
                     batch_size=1, progress=False)
    other = jd.sweep(TUBE, voltage=[0.3, 0.05], alpha=[0.7], n_roots=2, chunk_size=1,
                     batch_size=1, progress=False)
    np.testing.assert_array_equal(small.omega[0, 0], full.omega[1, 1])
    np.testing.assert_array_equal(small.omega[0, 2], full.omega[1, 0])
    np.testing.assert_array_equal(other.omega[1, 0], full.omega[1, 1])
    direct = jd.frequencies(TUBE.replace(voltage=0.05), 0.7, n_roots=2)
    np.testing.assert_array_equal(np.asarray(direct), full.omega[1, 1])


@pytest.mark.slow
def test_sweep_with_jacobian_is_bit_identical_across_chunk_sizes():
    runs = [_sweep(chunk_size=c, batch_size=1, jacobian=("voltage", "lambda_i")) for c in (1, 4)]
    _assert_same(*runs)
    np.testing.assert_array_equal(runs[0].jacobian, runs[1].jacobian)
    np.testing.assert_array_equal(runs[0].group_velocity, runs[1].group_velocity)


@pytest.mark.slow
@pytest.mark.parametrize("batch", [2, 4])
def test_sweep_batch_sizes_agree_to_rounding(batch):
    """batch_size > 1 vectorises the points of a chunk: equal to batch_size=1 to rounding only
    (module docstring)."""
    reference = _sweep(chunk_size=4, batch_size=1)
    got = _sweep(chunk_size=4, batch_size=batch)
    np.testing.assert_array_equal(got.status, reference.status)
    np.testing.assert_allclose(got.omega, reference.omega, rtol=RTOL, atol=0)

