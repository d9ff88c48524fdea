"""Higher-order propagation schemes (jaxdea.physics.transfer.SCHEMES): Magnus expansions of order 4 and 6
converge to the continuous wall, the limit of the paper's midpoint laminate, at their order."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from conftest import fd_derivative

import jaxdea as jd
from jaxdea.numerics.scalar import value_and_slope
from jaxdea.physics.dispersion import characteristic_and_scale, characteristic_on_wall, reference_determinant
from jaxdea.physics.transfer import discretize, laminate, layer_generator

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


def _direct_generator(step, coef, radius, omega, alpha):
    """The scheme's generator from the state matrices at Ω itself (the formulas of
    jaxdea.physics.transfer.layer_generator written out, with no polynomial in Ω²)."""
    from math import sqrt

    from jaxdea.physics.state_matrix import state_matrix

    m = jax.vmap(state_matrix, (0, 0, None, None))(coef, radius, omega, alpha)
    comm = lambda a, b: a @ b - b @ a  # noqa: E731
    if radius.shape[0] == 1:
        return step * m[0]
    if radius.shape[0] == 2:
        return 0.5 * step * (m[0] + m[1]) + sqrt(3.0) / 12.0 * step**2 * comm(m[1], m[0])
    b1, b2 = step * m[1], sqrt(15.0) / 3.0 * step * (m[2] - m[0])
    b3 = 10.0 / 3.0 * step * (m[2] - 2.0 * m[1] + m[0])
    c1 = comm(b1, b2)
    return b1 + b3 / 12.0 + comm(-20.0 * b1 - b3 + c1, b2 - comm(b1, 2.0 * b3 + c1) / 60.0) / 240.0


@pytest.mark.parametrize("scheme", ["midpoint", "magnus4", "magnus6"])
def test_generator_polynomial_in_omega_squared_equals_the_direct_formula(scheme):
    """G(Ω) formed once per α̂ as a polynomial in Ω² (jaxdea.physics.transfer.generator_coefficients)
    equals the scheme's formula evaluated on M(Ω) at every node, for real Ω up to 40 and complex Ω
    (root counting), on a stretched tube under voltage, to rounding."""
    wall = discretize(TUBE, laminate(4, scheme))
    for omega in (0.0, 0.7, 3.1, 12.0, 40.0, 2.0 + 0.5j):
        for k in range(4):
            coef = jax.tree_util.tree_map(lambda x, k=k: x[k], wall.coef)  # the nodes of sublayer k
            new = layer_generator(wall.step, coef, wall.radii[k], omega, ALPHA)
            nodes = jax.tree_util.tree_map(jnp.atleast_1d, (coef, wall.radii[k]))
            ref = _direct_generator(wall.step, *nodes, omega, ALPHA)
            np.testing.assert_allclose(new, ref, rtol=0, atol=1e-14 * np.max(np.abs(ref)))


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


@pytest.mark.slow
def test_critical_voltage_with_a_scheme_is_a_zero_frequency_of_that_scheme():
    """V̂_cr with scheme="magnus6" is the zero of f(Ω = 0; V̂) of the magnus6 wall (f changes sign
    across it, not across the midpoint laminate's V̂_cr 1.3e-6 away), with implicit derivatives."""
    tube = TUBE.replace(voltage=0.0)
    v_cr = float(jd.critical_voltage(tube, ALPHA, n_layers=6, scheme="magnus6"))

    def f(v, scheme):
        return float(jd.characteristic(tube.replace(voltage=v), 0.0, ALPHA, n_layers=6, scheme=scheme))

    assert f(v_cr * (1 - 1e-9), "magnus6") * f(v_cr * (1 + 1e-9), "magnus6") < 0
    assert f(v_cr * (1 - 1e-9), "midpoint") * f(v_cr * (1 + 1e-9), "midpoint") > 0

    def v_of_eta(eta):
        return jd.critical_voltage(tube.replace(eta=eta), ALPHA, n_layers=6, scheme="magnus6")

    np.testing.assert_allclose(jax.grad(v_of_eta)(0.8), fd_derivative(v_of_eta, 0.8), rtol=1e-7)


@pytest.mark.slow
def test_count_roots_and_tunability_with_a_scheme_see_that_discretisation():
    """count_roots(scheme=...) counts the roots of that scheme's wall: with ω_hi between the third
    root of magnus6 and that of the midpoint laminate (N = 6, 1e-4 apart), the counts differ as
    the roots do. tunability(scheme=...) equals a central difference of that scheme's root."""
    r6, rm = (np.asarray(jd.frequencies(TUBE, ALPHA, FLUID, n_roots=3, n_layers=6, scheme=s))
              for s in ("magnus6", "midpoint"))
    hi = 0.5 * (r6[2] + rm[2])
    counts = [int(jd.count_roots(TUBE, ALPHA, 0.0, hi, FLUID, n_layers=6, scheme=s).count)
              for s in ("magnus6", "midpoint")]
    assert counts == [int(np.sum(r6 < hi)), int(np.sum(rm < hi))]
    assert counts[0] != counts[1]

    def omega(v):
        return jd.frequency(TUBE.replace(voltage=v), ALPHA, r6[0], FLUID, n_layers=6, scheme="magnus6")

    slope = jd.tunability(TUBE, ALPHA, omega(0.1), FLUID, n_layers=6, scheme="magnus6")
    np.testing.assert_allclose(slope, fd_derivative(omega, 0.1), rtol=1e-7)


@pytest.mark.slow
def test_trace_and_critical_voltages_with_a_scheme():
    """trace_branch(scheme=...) lands on that scheme's root at its stop; critical_voltages equals
    critical_voltage mode by mode; magnus6's V̂_cr converges at sixth order (N = 3 → 6 divides the
    error by ≈ 64) to the midpoint laminate's Richardson limit (N = 120, 240), measured error
    8.5e-11 at N = 6 (the midpoint laminate at N = 240: 8.0e-8)."""
    omega = np.asarray(jd.frequencies(TUBE, ALPHA, FLUID, n_roots=2, n_layers=6, scheme="magnus6"))
    branch = jd.trace_branch(TUBE, ALPHA, omega[1], FLUID, along="alpha", stop=2.0, n_layers=6,
                             scheme="magnus6")
    end = int(branch.n_points) - 1
    assert int(branch.status) == jd.BranchEnd.REACHED_STOP and float(branch.parameter[end]) == 2.0
    at_stop = np.asarray(jd.frequencies(TUBE, 2.0, FLUID, n_roots=2, n_layers=6, scheme="magnus6"))
    np.testing.assert_allclose(float(branch.omega[end]), at_stop[1], rtol=1e-10)

    tube = TUBE.replace(voltage=0.0)
    many = np.asarray(jd.critical_voltages(tube, 2, n_layers=6, scheme="magnus6"))
    single = [float(jd.critical_voltage(tube, jd.axial_wavenumber(tube, n), n_layers=6, scheme="magnus6"))
              for n in (1, 2)]
    np.testing.assert_allclose(many, single, rtol=1e-13)

    coarse, fine = (float(jd.critical_voltage(tube, ALPHA, n_layers=n, scheme="magnus6")) for n in (3, 6))
    mid = [float(jd.critical_voltage(tube, ALPHA, n_layers=n)) for n in (120, 240)]
    limit = (4.0 * mid[1] - mid[0]) / 3.0
    assert abs(fine / limit - 1.0) < 1e-9
    assert 0.8 * 64 < (coarse - limit) / (fine - limit) < 1.25 * 64


@pytest.mark.slow
def test_design_with_a_scheme_meets_the_target_on_that_discretisation():
    """design_for_frequency(scheme="magnus6", n_layers=6): the design's lowest root, solved directly
    on the same discretisation, is the target. L/R_o held (the case's setting when it was written):
    with the default, L/R_i held, 0.72 lies below every Ω the thickness range reaches at s_op
    (0.7555 at the end of the compromise), and the design rightly ends MAX_STEPS."""
    tube = jd.Tube(lambda_i=1.1, lambda_z=1.2)
    res = jd.design_for_frequency(tube, 0.72, rtol=1e-6, n_layers=6, scheme="magnus6",
                                  hold="length_ratio")
    assert res.converged, res.status
    lowest = float(jd.frequencies(res.tube, res.alpha, n_roots=1, n_layers=6, scheme="magnus6")[0])
    assert abs(lowest / 0.72 - 1.0) <= 1e-6 + 1e-12
    assert res.omega == pytest.approx(lowest, rel=1e-12)


@pytest.mark.parametrize("call", [
    lambda: jd.characteristic(TUBE, 1.0, ALPHA, scheme="rk4"),
    lambda: jd.frequencies(TUBE, ALPHA, scheme="Magnus6"),
    lambda: jd.frequency(TUBE, ALPHA, 1.0, scheme="none"),
    lambda: jd.dispersion_curve(TUBE, [1.0, 2.0], scheme="magnus8"),
    lambda: jd.sweep(TUBE, alpha=[1.0], scheme="euler", progress=False),
    lambda: jd.critical_voltage(TUBE, ALPHA, scheme="magnus5"),
    lambda: jd.critical_voltages(TUBE, 2, scheme="Midpoint"),
    lambda: jd.count_roots(TUBE, ALPHA, 0.0, 1.0, scheme="rk4"),
    lambda: jd.trace_branch(TUBE, ALPHA, 1.0, along="alpha", stop=2.0, scheme="rk4"),
    lambda: jd.tunability(TUBE, ALPHA, 1.0, scheme="rk4"),
    lambda: jd.design_for_frequency(TUBE, 0.7, scheme="rk4"),
    lambda: jd.maximise_tunability(TUBE, scheme="rk4"),
])
def test_unknown_scheme_is_a_value_error(call):
    with pytest.raises(ValueError, match="scheme must be one of 'midpoint', 'magnus4', 'magnus6'"):
        call()
