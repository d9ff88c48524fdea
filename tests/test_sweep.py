"""Sweeps: grid results against single solves, chunking without recompilation, saved results,
failures that never stop a sweep, sensitivity maps against finite differences, memory bound."""

import os
import subprocess
import sys
import textwrap

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxdea as jd
from jaxdea.studies import sweeps as sweep_module
from jaxdea.studies.sweeps import SweepResult, sweep

TUBE = jd.Tube(lambda_i=1.1, lambda_z=1.2, eta=0.85)
VOLTAGES = np.array([0.0, 0.1, 0.2])
MODES = np.array([1, 2, 5])


@pytest.fixture(scope="module")
def grid():
    return sweep(TUBE, voltage=VOLTAGES, n=MODES, chunk_size=4, progress=False)


def test_sweep_equals_single_solves(grid):
    """Every grid point equals jaxdea.frequencies at that point (9 points in 3 chunks of 4)."""
    assert grid.omega.shape == (3, 3, 3) and grid.status.shape == (3, 3, 3)
    assert np.all(grid.status == jd.Status.CONVERGED)
    for i, v in enumerate(VOLTAGES):
        for j, n in enumerate(MODES):
            tube = TUBE.replace(voltage=float(v))
            alpha = jd.axial_wavenumber(tube, int(n))
            assert grid.alpha[i, j] == pytest.approx(float(alpha), rel=1e-15)
            np.testing.assert_allclose(grid.omega[i, j], jd.frequencies(tube, alpha), rtol=1e-13)
    np.testing.assert_allclose(grid.phase_velocity, grid.omega / grid.alpha[..., None], rtol=0)


def test_chunks_share_one_compilation(grid):
    """New values and another number of chunks reuse the compiled chunk program."""
    before = sweep_module._sweep_chunk._cache_size()
    again = sweep(TUBE.replace(lambda_i=1.05), voltage=[0.05, 0.15], n=[1, 3, 4], chunk_size=4,
                  progress=False)
    assert sweep_module._sweep_chunk._cache_size() == before
    tube = TUBE.replace(lambda_i=1.05, voltage=0.15)
    np.testing.assert_allclose(again.omega[1, 2], jd.frequencies(tube, jd.axial_wavenumber(tube, 4)),
                               rtol=1e-13)


def test_sweep_without_voltage_takes_the_decoupled_propagation():
    """A longitudinal grid whose every point is without voltage (no voltage axis, V̂ = 0) solves on
    the 4×4 mechanical propagation (its own compiled program): the roots of the same grid through a
    voltage axis [0] (the 6×6 program) to rounding, and of jaxdea.frequencies."""
    tube = TUBE.replace(voltage=0.0)
    four = sweep(tube, alpha=[0.3, 1.1], eta=[0.6, 0.85], progress=False)
    six = sweep(tube, voltage=[0.0], alpha=[0.3, 1.1], eta=[0.6, 0.85], progress=False)
    assert np.all(four.status == jd.Status.CONVERGED)
    np.testing.assert_allclose(four.omega, six.omega[0], rtol=1e-13)
    np.testing.assert_allclose(four.omega[1, 0], jd.frequencies(tube.replace(eta=0.6), 1.1),
                               rtol=1e-12)


def test_save_and_load(grid, tmp_path):
    grid.to_npz(tmp_path / "grid.npz")
    back = SweepResult.from_npz(tmp_path / "grid.npz")
    assert list(back.axes) == ["voltage", "n"]
    np.testing.assert_array_equal(back.omega, grid.omega)
    np.testing.assert_array_equal(back.status, grid.status)
    np.testing.assert_array_equal(back.alpha, grid.alpha)
    assert back.settings == grid.settings and back.settings["tube"]["lambda_z"] == 1.2
    grid.to_csv(tmp_path / "grid.csv")
    header = (tmp_path / "grid.csv").read_text().splitlines()[0].split(",")
    assert header[:6] == ["voltage", "n", "alpha_hat", "omega_1", "omega_2", "omega_3"]
    table = np.loadtxt(tmp_path / "grid.csv", delimiter=",", skiprows=1)
    assert table.shape == (9, 9)
    np.testing.assert_array_equal(table[:, 3:6], grid.omega.reshape(9, 3))  # %.17g round-trips
    np.testing.assert_array_equal(table[:, 1], np.tile(MODES, 3))


def test_progress_bar(capsys):
    sweep(TUBE, voltage=[0.0, 0.1, 0.2, 0.3], n=[1], chunk_size=4, progress=True)
    assert "jaxdea sweep" in capsys.readouterr().err
    sweep(TUBE, voltage=[0.0, 0.1, 0.2, 0.3], n=[1], chunk_size=4, progress=False)
    assert capsys.readouterr().err == ""


def test_failed_points_do_not_stop_the_sweep():
    """Locked (λ_i = 12: I_1 − 3 ≈ 143 > G), NaN and root-less points give NaN and their status."""
    res = sweep(TUBE, lambda_i=[1.1, 12.0, np.nan], n=[1, 2], omega_max=1.0, progress=False)
    assert np.all(res.status[1:] == jd.Status.INVALID) and np.all(np.isnan(res.omega[1:]))
    for j, n in enumerate((1, 2)):
        alpha = jd.axial_wavenumber(TUBE, n)
        want = jd.solve_frequencies(TUBE, alpha, omega_max=1.0)
        np.testing.assert_array_equal(res.status[0, j], want.status)
        np.testing.assert_allclose(res.omega[0, j], want.omega, rtol=1e-13)
    assert set(res.status[0].ravel()) == {jd.Status.CONVERGED, jd.Status.NO_ROOT}


def _fd_frequencies(tube, fluid, n, name, value, h):
    """Central difference of the 3 lowest frequencies of mode n in the sensitivity coordinates."""
    def at(x):
        t, f = tube, fluid
        if name in ("density_ratio", "speed_ratio"):
            f = fluid.replace(**{name: x})
        elif name != "thickness_ratio":
            t = tube.replace(**{name: x})
        t = jd.with_thickness_ratio(t, x if name == "thickness_ratio" else 0.2)  # h/R_i held
        return np.asarray(jd.frequencies(t, jd.axial_wavenumber(t, n), f))

    return (at(value + h) - at(value - h)) / (2 * h)


@pytest.mark.slow
def test_sensitivity_map_against_finite_differences():
    """dΩ/dθ for θ = (V̂, λ_i, λ_z, ρ̂_f, ĉ_f, h/R_i, G) at fixed n (α̂ follows λ_z, η) and the group
    velocity, against central differences and jaxdea.group_velocity."""
    tube, fluid = TUBE.replace(voltage=0.1), jd.Fluid()
    res = sweep(tube, fluid, thickness_ratio=[0.15, 0.2], n=[1, 3], jacobian=True, progress=False)
    assert res.jacobian.shape == (2, 2, 3, 7) and res.jacobian_names == sweep_module.SENSITIVITY
    assert np.all(res.status == jd.Status.CONVERGED)
    base = jd.with_thickness_ratio(tube, 0.2)
    values = dict(voltage=0.1, lambda_i=1.1, lambda_z=1.2, density_ratio=0.13, speed_ratio=0.27,
                  thickness_ratio=0.2, gent=97.2)
    for name, value in values.items():
        h = 1e-3 if name == "gent" else 1e-6
        fd = _fd_frequencies(tube, fluid, 3, name, value, h)
        np.testing.assert_allclose(res.derivative(name)[1, 1], fd, rtol=2e-5 if name == "gent" else 1e-6,
                                   atol=1e-9, err_msg=name)
    alpha = jd.axial_wavenumber(base, 3)
    want = [float(jd.group_velocity(base, alpha, w, fluid)) for w in res.omega[1, 1]]
    np.testing.assert_allclose(res.group_velocity[1, 1], want, rtol=1e-10)
    with pytest.raises(ValueError, match="'voltage'"):
        sweep(tube, voltage=[0.1], n=[1], progress=False).derivative("voltage")


@pytest.mark.slow
def test_paper_coupling_over_mode_numbers():
    """ν = n from the n axis, traced: one compilation for all modes, equal to the static-order solve."""
    fluid = jd.Fluid(coupling="paper")
    res = sweep(TUBE, fluid, n=[1, 3], progress=False)
    np.testing.assert_allclose(res.omega[1], jd.frequencies(TUBE, jd.axial_wavenumber(TUBE, 3), fluid),
                               rtol=1e-12)
    with pytest.raises(ValueError, match="sweep over n"):
        sweep(TUBE, fluid, alpha=[0.4], progress=False)
    with pytest.raises(ValueError, match="integers"):
        sweep(TUBE, fluid, n=[1.5], progress=False)


@pytest.mark.slow  # 80 s: compiles the pull-in limit and two critical-voltage programs
def test_critical_voltages_of_all_modes():
    """One batched call equals jaxdea.critical_voltage mode by mode."""
    got = jd.solve_critical_voltages(TUBE, 5)
    assert np.all(np.asarray(got.status) == jd.Status.CONVERGED)
    for n in (1, 4):
        want = jd.critical_voltage(TUBE, jd.axial_wavenumber(TUBE, n))
        assert float(got.omega[n - 1]) == pytest.approx(float(want), rel=1e-12)
    assert np.all(np.diff(np.asarray(got.omega)) < 0)  # shorter waves buckle at lower voltage


@pytest.mark.slow
def test_critical_voltages_derivative():
    grad = jax.jacfwd(lambda li: jd.critical_voltages(TUBE.replace(lambda_i=li), 3))(1.1)
    h = 1e-6
    fd = (jd.critical_voltages(TUBE.replace(lambda_i=1.1 + h), 3)
          - jd.critical_voltages(TUBE.replace(lambda_i=1.1 - h), 3)) / (2 * h)
    np.testing.assert_allclose(grad, fd, rtol=1e-6)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(voltage=[0.1]), "alpha=... "),
        (dict(alpha=[0.4], n=[1]), "either 'alpha' or 'n'"),
        (dict(alpha=[0.4], colour=[1.0]), "unknown parameter 'colour'"),
        (dict(alpha=[0.4], density_ratio=[0.1]), "need a Fluid"),
        (dict(alpha=np.ones((2, 2))), "axis 'alpha' must be a scalar or a 1-D array"),
        (dict(alpha=[]), "axis 'alpha' is empty"),
        (dict(alpha=[0.4], n_roots=0), "n_roots must be an integer >= 1"),
        (dict(alpha=[0.4], chunk_size=2.5), "chunk_size"),
        (dict(alpha=[0.4], omega_max=-1.0), "omega_max"),
        (dict(alpha=[0.4], jacobian=["alpha"]), "group velocity"),
        (dict(alpha=[0.4], jacobian=["hue"]), "unknown parameter 'hue'"),
    ],
)
def test_bad_sweep_arguments(kwargs, match):
    with pytest.raises(ValueError, match=match):
        sweep(TUBE, **kwargs)


def test_chunk_memory_is_bounded():
    """The compiled chunk's working memory does not depend on the number of points (one program
    for every chunk) and stays below 64 MiB at the default chunk size (N = 30, K = 3)."""
    size = sweep_module.CHUNK_SIZE
    args = ((jnp.zeros(size), jnp.ones(size)), *jax.tree_util.tree_map(jd.params.as_float, (TUBE, 1.0)),
            None, None)
    compiled = sweep_module._sweep_chunk.lower(
        *args, names=("voltage", "n"), n_roots=3, n_layers=30, order=0, jac_names=None, batch_size=1
    ).compile()
    stats = compiled.memory_analysis()
    working = stats.temp_size_in_bytes + stats.argument_size_in_bytes + stats.output_size_in_bytes
    assert working < 64 * 2**20


@pytest.mark.slow
def test_hundred_thousand_points_in_bounded_memory():
    """A 10⁵-point sweep (N = 2, K = 1) grows the peak RSS by less than 64 MiB beyond a 1024-point
    sweep of the same program: the bound is one chunk plus 20 bytes per point and root."""
    script = textwrap.dedent("""
        import resource, numpy as np, jax
        jax.config.update("jax_enable_x64", True)
        import jaxdea as jd
        from jaxdea.studies.sweeps import sweep
        run = lambda m: sweep(jd.Tube(), voltage=np.linspace(0, 0.1, m), alpha=np.linspace(0.1, 2, 100),
                              n_roots=1, n_layers=2, chunk_size=256, progress=False)
        small = run(10)
        before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
        big = run(1000)
        after = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
        assert np.all(big.status == 0) and big.omega.shape == (1000, 100, 1)
        print((after - before) / 1024)
    """)
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, check=True,
                         env=dict(os.environ, JAX_PLATFORMS="cpu"))
    assert float(out.stdout.strip().splitlines()[-1]) < 64


def test_group_velocity_through_a_zero_group_velocity_point():
    """Second branch of the driven tube (V̂ = 0.15): Ω(α̂) has a minimum near α̂ = 0.57. The implicit
    group velocity matches central differences of the branch on both sides and vanishes where Ω
    is smallest (located by bisection on its sign; Ω rises by ½Ω''δ² on both sides)."""
    tube = TUBE.replace(voltage=0.15)
    branch = lambda a: float(jd.frequency(tube, a, 1.3178))  # noqa: E731
    cg = lambda a: float(jd.group_velocity(tube, a, branch(a)))  # noqa: E731
    for a in (0.5, 0.57, 0.65):
        h = 1e-5
        fd = (branch(a + h) - branch(a - h)) / (2 * h)
        assert abs(cg(a) - fd) < 1e-8
    lo, hi = 0.5, 0.65
    assert cg(lo) < 0 < cg(hi)
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if cg(mid) < 0 else (lo, mid)
    a_zgv = 0.5 * (lo + hi)
    d = 1e-3
    rise = [branch(a_zgv + s * d) - branch(a_zgv) for s in (-1, 1)]
    assert min(rise) > 0 and abs(rise[0] - rise[1]) < 1e-2 * max(rise)  # symmetric minimum


def test_an_interrupted_sweep_keeps_the_solved_chunks(grid, monkeypatch):
    """Ctrl-C during the third chunk: SweepInterrupted (a KeyboardInterrupt) carries the 8 points
    of the first two chunks, bit-identical to the full sweep, and the ninth as NaN with status
    NOT_SOLVED, the settings marked incomplete; before the first chunk it carries no result."""
    solve, calls = sweep_module._solve_chunk, []

    def stopped_at(k):
        def chunk(*args):
            calls.append(1)
            if len(calls) == k:
                raise KeyboardInterrupt
            return solve(*args)
        return chunk

    monkeypatch.setattr(sweep_module, "_solve_chunk", stopped_at(3))
    with pytest.raises(sweep_module.SweepInterrupted) as stop:
        sweep(TUBE, voltage=VOLTAGES, n=MODES, chunk_size=4, progress=False)
    assert isinstance(stop.value, KeyboardInterrupt) and (stop.value.solved, stop.value.total) == (8, 9)
    part = stop.value.result
    flat = lambda a: a.reshape(9, *a.shape[2:])  # noqa: E731
    np.testing.assert_array_equal(flat(part.omega)[:8], flat(grid.omega)[:8])
    np.testing.assert_array_equal(flat(part.status)[:8], flat(grid.status)[:8])
    np.testing.assert_array_equal(flat(part.alpha)[:8], flat(grid.alpha)[:8])
    assert np.all(np.isnan(flat(part.omega)[8])) and np.isnan(flat(part.alpha)[8])
    assert np.all(flat(part.status)[8] == jd.Status.NOT_SOLVED)
    assert part.settings == {**grid.settings, "incomplete": True}
    calls.clear()
    monkeypatch.setattr(sweep_module, "_solve_chunk", stopped_at(1))
    with pytest.raises(sweep_module.SweepInterrupted) as stop:
        sweep(TUBE, voltage=VOLTAGES, n=MODES, chunk_size=4, progress=False)
    assert stop.value.result is None and (stop.value.solved, stop.value.total) == (0, 9)


def test_grid_size_and_memory_are_checked_before_allocating(monkeypatch):
    """10¹² points raised numpy's MemoryError (7 TiB) from the grid's columns: a grid past
    MAX_POINTS, or whose arrays need more than MEMORY_SHARE of the machine's memory, is refused
    before anything is allocated, naming the limit."""
    with pytest.raises(ValueError, match=r"the grid has 1,000,000,000,000 points \(1000000 x 1000000\); "
                                         r"a sweep takes at most MAX_POINTS = 100,000,000"):
        sweep(TUBE, voltage=np.zeros(10**6), n=np.arange(1.0, 10**6 + 1), progress=False)
    monkeypatch.setattr(sweep_module, "physical_memory", lambda: 2**30)
    need = sweep_module.sweep_bytes((10**4, 10**3), 3)
    assert need > 2**29
    with pytest.raises(ValueError, match=rf"needs about {need / 2**30:.1f} GiB, more than "
                                         r"MEMORY_SHARE = 0.5 of this machine's 1.0 GiB"):
        sweep(TUBE, voltage=np.zeros(10**4), n=np.arange(1.0, 10**3 + 1), progress=False)


def test_the_memory_estimate_bounds_the_arrays(grid):
    """sweep_bytes is an upper bound of what a sweep and its CSV hold (the grid's columns, the
    result's arrays, the CSV columns and table), within a factor 2, with and without derivatives
    and growth rates."""
    rng = np.random.default_rng(1)
    jacobian = rng.normal(size=(3, 3, 3, 2))
    cases = [(grid, None, 0),
             (SweepResult(axes=grid.axes, omega=grid.omega, status=grid.status, alpha=grid.alpha,
                          jacobian=jacobian, jacobian_names=("voltage", "gent"),
                          group_velocity=grid.omega, growth_rate=grid.omega[..., :2],
                          settings=grid.settings), 2, 2)]
    for result, names, growth in cases:
        columns = result.columns()
        held = sum(np.meshgrid(*result.axes.values(), indexing="ij")[k].nbytes
                   for k in range(len(result.axes)))
        held += sum(a.nbytes for a in (result.omega, result.status, result.status, result.alpha,
                                       result.jacobian, result.group_velocity, result.growth_rate)
                    if a is not None)
        held += sum(np.asarray(c).nbytes for c in columns.values())
        held += np.column_stack(list(columns.values())).nbytes
        estimate = sweep_module.sweep_bytes(result.shape, 3, names, growth)
        assert held <= estimate <= 2 * held, (held, estimate)
