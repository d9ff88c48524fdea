"""Order m in the root solvers: frequencies, growth rates (Ω² < 0), critical voltages of order m
and the tube's first instability (theory_m.md §6), with implicit derivatives."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from conftest import fd_derivative

import jaxdea as jd
from jaxdea.numerics.scalar import Status
from jaxdea.physics.state_matrix import ORDER_M
from jaxdea.solve import roots

PAPER = jd.Tube(voltage=0.0, lambda_i=0.9, lambda_z=1.2, eta=0.85)  # G = 97.2 (default)
OVAL = jd.Tube(voltage=0.0, lambda_i=0.95, lambda_z=1.2, eta=0.85)
N = 20


@pytest.mark.parametrize("voltage, omega_squared", [(0.0, 0.4293), (0.06, 0.0801),
                                                    (0.08, -0.1962), (0.10, -0.5574)])
def test_signed_omega_squared_of_the_ovalisation_mode(voltage, omega_squared):
    """theory_m.md §6: the lowest m = 2 mode of λ_i = 0.95 at α̂ = 0.445 (4 digits given) is a
    frequency while Ω² > 0 and a growth rate s = √(−Ω²) once Ω² < 0; never both."""
    tube = OVAL.replace(voltage=voltage)
    omega = jd.frequencies(tube, 0.445, n_roots=1, m=2, n_layers=N)[0]
    rate = jd.growth_rates(tube, 0.445, m=2, n_layers=N)
    if omega_squared > 0:
        assert abs(float(omega) ** 2 - omega_squared) < 1e-4
        assert np.all(np.isnan(rate))
    else:
        assert abs(-float(rate[0]) ** 2 - omega_squared) < 1e-4
        assert np.all(np.isnan(rate[1:]))
        assert float(omega) > 1.5  # the scan in Ω > 0 starts at the second branch


def test_the_paper_tube_buckles_far_below_its_axisymmetric_critical_voltage():
    """Critical voltages of the paper's tube (n = 1, λ_i = 0.9) by order: 0.2959 (m = 0),
    0.1976, 0.0293, 0.0309 from an independent three-dimensional analysis (4 digits)."""
    alpha = jd.axial_wavenumber(PAPER, 1)
    expected = {0: 0.2959, 1: 0.1976, 2: 0.0293, 3: 0.0309}
    for m, value in expected.items():
        v = float(jd.critical_voltage(PAPER, alpha, m=m))
        assert abs(v - value) < 6e-5, (m, v)
    first = jd.first_instability(PAPER, n_max=2, m_max=4)
    assert (int(first.m), int(first.n), int(first.status)) == (2, 1, Status.CONVERGED)
    assert float(first.voltage) == pytest.approx(float(jd.critical_voltage(PAPER, alpha, m=2)),
                                                 rel=1e-12)
    assert first.critical.shape == (5, 2)
    np.testing.assert_allclose(first.critical[:, 0],
                               [float(jd.critical_voltage(PAPER, alpha, m=m)) for m in range(5)],
                               rtol=1e-12)


@pytest.mark.parametrize("m", [1, 2, 3])
def test_the_lowest_omega_squared_changes_sign_at_the_critical_voltage(m):
    alpha = 0.445
    v_cr = float(jd.critical_voltage(OVAL, alpha, m=m, n_layers=N))
    below, above = OVAL.replace(voltage=v_cr * 0.99), OVAL.replace(voltage=v_cr * 1.01)
    assert np.all(np.isnan(jd.growth_rates(below, alpha, m=m, n_layers=N)))
    slow = float(jd.frequencies(below, alpha, n_roots=1, m=m, n_layers=N)[0])
    rate = float(jd.growth_rates(above, alpha, m=m, n_layers=N)[0])
    assert 0 < slow < 0.3 and 0 < rate < 0.3  # the same branch through Ω² = 0, either side


def test_m_zero_is_unchanged_and_the_traced_path_agrees():
    tube = PAPER.replace(voltage=0.1)
    base = jd.frequencies(tube, 0.445, n_layers=N)
    np.testing.assert_array_equal(jd.frequencies(tube, 0.445, n_layers=N, m=0), base)
    traced = roots.frequencies_unchecked(tube, 0.445, None, None, 3, N, 0, jnp.float64(0.0), ORDER_M)
    np.testing.assert_allclose(traced.omega, base, rtol=1e-12)


def test_a_traced_m_compiles_once_and_equals_single_calls():
    alpha = 0.6
    sweep = jax.jit(jax.vmap(lambda m: roots.frequencies_unchecked(
        OVAL, alpha, None, None, 2, N, 0, m, ORDER_M).omega))(jnp.arange(1.0, 4.0))
    for k, row in enumerate(sweep, start=1):
        np.testing.assert_allclose(row, jd.frequencies(OVAL, alpha, n_roots=2, m=k, n_layers=N),
                                   rtol=1e-12)


@pytest.mark.parametrize("m, fluid", [(1, None), (2, None), (2, jd.Fluid())])
def test_implicit_derivatives_of_order_m_roots(m, fluid):
    tube = OVAL.replace(voltage=0.02)
    omega0 = float(jd.frequencies(tube, 0.445, fluid, n_roots=1, m=m, n_layers=N)[0])

    def omega(v):
        return jd.frequency(tube.replace(voltage=v), 0.445, omega0, fluid, n_layers=N, m=m)

    assert float(jax.grad(omega)(0.02)) == pytest.approx(fd_derivative(omega, 0.02), rel=1e-6)
    slope = float(jd.group_velocity(tube, 0.445, omega0, fluid, n_layers=N, m=m))
    along = lambda a: jd.frequency(tube, a, omega0, fluid, n_layers=N, m=m)  # noqa: E731
    assert slope == pytest.approx(fd_derivative(along, 0.445), rel=1e-6)
    rate = lambda v: jd.growth_rates(OVAL.replace(voltage=v), 0.445, m=2, n_layers=N)[0]  # noqa: E731
    assert float(jax.grad(rate)(0.1)) == pytest.approx(fd_derivative(rate, 0.1), rel=1e-6)


def test_first_instability_derivative_and_vmap():
    def voltage(lambda_i):
        return jd.first_instability(PAPER.replace(lambda_i=lambda_i), n_max=1, m_max=3).voltage

    assert float(jax.grad(voltage)(0.9)) == pytest.approx(fd_derivative(voltage, 0.9), rel=1e-6)
    values = jax.vmap(voltage)(jnp.array([0.9, 0.95]))
    np.testing.assert_allclose(values, [float(voltage(0.9)), float(voltage(0.95))], rtol=1e-12)


def test_a_tube_unstable_at_zero_voltage_has_its_first_instability_at_zero():
    """λ_i = 0.8: ring modes already grow at V̂ = 0 (a search for f(Ω = 0; V̂) = 0 in V̂ > 0 does not
    see that): their critical voltage is 0, the first instability is V̂ = 0 at the (m, n) that
    stability() finds growing fastest, with a zero derivative; λ_i = 0.9 is stable at V̂ = 0."""
    squeezed = PAPER.replace(lambda_i=0.8)
    state = jd.stability(squeezed, n_max=1, m_max=3)
    assert not bool(state.stable)
    first = jd.first_instability(squeezed, n_max=1, m_max=3)
    assert float(first.voltage) == 0.0 and int(first.status) == Status.CONVERGED
    assert (int(first.m), int(first.n)) == (int(state.m), int(state.n))
    growing = np.isfinite(np.asarray(state.growth))
    assert growing[2, 0] and growing[3, 0]  # ring modes m = 2, 3 grow at V̂ = 0
    np.testing.assert_array_equal(np.asarray(first.critical)[growing], 0.0)
    grad = jax.grad(lambda li: jd.first_instability(PAPER.replace(lambda_i=li), n_max=1,
                                                    m_max=3).voltage)(0.8)
    assert float(grad) == 0.0
    assert bool(jd.stability(PAPER, n_max=1, m_max=3).stable)
    assert float(jd.first_instability(PAPER, n_max=1, m_max=3).voltage) > 0.02


@pytest.mark.parametrize("kwargs, name", [
    (dict(m=-1), "m must be"), (dict(m=1.5), "m must be"), (dict(m="2"), "m must be"),
    (dict(m=1, torsional=True), "torsional"), (dict(m=1, fluid=jd.Fluid(coupling="paper")), "paper"),
])
def test_bad_order_raises(kwargs, name):
    fluid = kwargs.pop("fluid", None)
    alpha = jd.axial_wavenumber(PAPER, 1)  # an axial mode: the paper's coupling needs one
    for call in (lambda: jd.frequencies(PAPER, alpha, fluid, **kwargs),
                 lambda: jd.growth_rates(PAPER, alpha, fluid, **kwargs),
                 lambda: jd.critical_voltage(PAPER, alpha, fluid, **kwargs)):
        with pytest.raises(ValueError, match=name):
            call()
    with pytest.raises(ValueError, match="m_max"):
        jd.first_instability(PAPER, m_max=-1)


def test_a_traced_invalid_m_gives_nan_and_invalid():
    out = jax.jit(lambda m: roots.frequencies_unchecked(PAPER, 0.445, None, None, 2, N, 0, m,
                                                        ORDER_M))(jnp.float64(1.5))
    assert np.all(np.isnan(out.omega)) and np.all(out.status == Status.INVALID)
