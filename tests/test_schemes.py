"""Higher-order propagation schemes (jaxdea.transfer.SCHEMES): Magnus expansions of order 4 and 6
converge to the continuous wall, the limit of the paper's midpoint laminate, at their order."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from conftest import fd_derivative

import jaxdea as jd
from jaxdea.dispersion import characteristic_and_scale, characteristic_on_wall, reference_determinant
from jaxdea.scalar import value_and_slope
from jaxdea.transfer import discretize, laminate, layer_generator

TUBE = jd.Tube(lambda_z=1.2, lambda_i=1.1, voltage=0.1, eta=0.8)
FLUID = jd.Fluid(density_ratio=0.5, speed_ratio=0.6)
ALPHA = 1.3


@pytest.fixture(scope="module")
def seeds():
    return np.asarray(jd.frequencies(TUBE, ALPHA, FLUID, n_roots=3, n_layers=30))


def roots(seeds, n_layers, scheme="midpoint"):
    """Plain Newton (6 steps, autodiff slope) on the discretised wall from ``seeds``."""
    def newton(x):
        wall = discretize(TUBE, laminate(n_layers, scheme))

        def step(_, x):
            f, df = value_and_slope(lambda w: characteristic_on_wall(wall, w, ALPHA, FLUID), x)
            return x - f / df

        return jax.lax.fori_loop(0, 6, step, x)

    return np.asarray(jax.jit(jax.vmap(newton))(seeds))


@pytest.fixture(scope="module")
def continuum(seeds):
    """The roots of the continuous wall, independently of the Magnus code: the midpoint laminate's
    Richardson extrapolation (4Ω(240) − Ω(120))/3 (its error is O(N⁻⁴), ≈ 1e-13 here)."""
    return (4.0 * roots(seeds, 240) - roots(seeds, 120)) / 3.0


@pytest.mark.parametrize("scheme, layers, order", [("magnus4", (4, 8), 4), ("magnus6", (3, 6), 6)])
def test_schemes_converge_to_the_continuous_wall_at_their_order(seeds, continuum, scheme, layers,
                                                                 order):
    """Fluid-filled, stretched tube under voltage: halving the sublayers divides the error of every
    root by 2^order (measured 16.0–16.2 for magnus4, 63.8–65.3 for magnus6; the midpoint laminate
    gives 4.0), so the Magnus generators are right to their order and share the laminate's limit."""
    coarse, fine = (np.abs(roots(seeds, n, scheme) / continuum - 1.0) for n in layers)
    ratio = coarse / fine
    assert np.all((ratio > 0.8 * 2**order) & (ratio < 1.25 * 2**order)), ratio
    if scheme == "magnus6":
        assert np.max(fine) < 2e-11  # 6 sublayers: the wall to 1e-11 (midpoint: 8e-6 at N = 8)


def test_magnus_generator_reduces_to_the_midpoint_one_for_a_homogeneous_layer():
    """Equal moduli at every node (a homogeneous sublayer, radius-independent up to the 1/r̂ terms
    frozen here): the commutators vanish and G = h M exactly."""
    @jax.jit
    def generators():
        wall = discretize(TUBE, 4)
        coef = jax.tree_util.tree_map(lambda x: x[0], wall.coef)
        mid = layer_generator(wall.step, coef, wall.radii[0], 2.0, ALPHA)
        return mid, [layer_generator(wall.step, jax.tree_util.tree_map(lambda x, q=q: jnp.full(q, x), coef),
                                     jnp.full(q, wall.radii[0]), 2.0, ALPHA) for q in (2, 3)]

    mid, magnus = generators()
    for g in magnus:
        np.testing.assert_allclose(g, mid, rtol=1e-14, atol=1e-15)


def test_magnus_characteristic_equals_the_expm_reference():
    """f·exp(log scale) of the stable 6×3 propagation (Taylor exponential) equals det(B A S) of the
    full product of jax.scipy.linalg.expm on the same Magnus generators, to 1e-12."""
    @jax.jit
    @jax.vmap
    def both(omega):
        wall = discretize(TUBE, laminate(5, "magnus6"))
        f, log_scale = characteristic_and_scale(wall, omega, ALPHA, FLUID)
        return f * jnp.exp(log_scale), reference_determinant(wall, omega, ALPHA, FLUID)

    value, ref = both(np.array([0.3, 1.7, 4.2]))
    np.testing.assert_allclose(value, ref, rtol=1e-12)


def test_magnus_roots_have_implicit_derivatives():
    """dΩ/dV̂ with scheme="magnus6": the implicit derivative equals a central difference."""
    def omega(v):
        return jd.frequency(TUBE.replace(voltage=v), ALPHA, 1.56, FLUID, n_layers=6, scheme="magnus6")

    np.testing.assert_allclose(jax.grad(omega)(0.1), fd_derivative(omega, 0.1), rtol=1e-7)


@pytest.mark.slow
def test_sweep_and_curve_with_a_scheme_equal_frequencies():
    """The scheme reaches every solver: sweep and dispersion_curve give frequencies' roots."""
    alphas = np.linspace(0.4, 2.0, 9)
    reference = np.array([np.asarray(jd.frequencies(TUBE, a, FLUID, n_layers=6, scheme="magnus6"))
                          for a in alphas])
    swept = jd.sweep(TUBE, FLUID, n_layers=6, scheme="magnus6", alpha=alphas[::4], progress=False)
    np.testing.assert_allclose(swept.omega, reference[::4], rtol=1e-12)
    assert swept.settings["scheme"] == "magnus6"
    curve = jd.dispersion_curve(TUBE, alphas, FLUID, n_layers=6, scheme="magnus6")
    np.testing.assert_allclose(curve.omega, reference, rtol=1e-12)
    midpoint = np.asarray(jd.frequencies(TUBE, alphas[0], FLUID, n_layers=6))
    assert np.max(np.abs(midpoint / reference[0] - 1.0)) > 1e-5  # a different discretisation


@pytest.mark.parametrize("call", [
    lambda: jd.characteristic(TUBE, 1.0, ALPHA, scheme="rk4"),
    lambda: jd.frequencies(TUBE, ALPHA, scheme="Magnus6"),
    lambda: jd.frequency(TUBE, ALPHA, 1.0, scheme=None),
    lambda: jd.dispersion_curve(TUBE, [1.0, 2.0], scheme="magnus8"),
    lambda: jd.sweep(TUBE, alpha=[1.0], scheme="euler", progress=False),
])
def test_unknown_scheme_is_a_value_error(call):
    with pytest.raises(ValueError, match="scheme must be one of 'midpoint', 'magnus4', 'magnus6'"):
        call()
