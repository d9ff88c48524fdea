"""Accuracy near Gent locking.

The Gent W_1 = 1/(2[1 − (I_1 − 3)/G]) grows without bound as I_1 − 3 → G at the inner face (the
most stretched or most compressed radius of the wall): the base-state integrals of theory.md
Eqs. (1.1)–(1.2) have a boundary layer there, of width (G − (I_1 − 3))/|dI_1/dr̂| (1.6e-3 of a
0.52 wall at 99 % of locking in the tube below). They are checked against an independent adaptive
quadrature (scipy.integrate.quad of the integrand in r̂, with the wall split geometrically towards
r̂_i) at 90 %, 99 % and 99.9 % of locking, in compression (λ_i < λ_z^{-1/2}) and in inflation.
"""

import warnings

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy import integrate

import jaxdea as jd
from jaxdea.physics import base_state as bs

LAMBDA_Z, ETA, GENT, VOLTAGE = 1.2, 0.75, 4.0, 0.05
FRACTIONS = (0.9, 0.99, 0.999)


def locking_stretch(fraction, inflated=False, lambda_z=LAMBDA_Z, gent=GENT):
    """λ_i with I_1 − 3 = fraction·G at the inner face: x = λ_i² solves
    λ_z² x² − K λ_z² x + 1 = 0, K = fraction·G + 3 − λ_z² (I_1 = x + 1/(λ_z² x) + λ_z²)."""
    k = fraction * gent + 3.0 - lambda_z**2
    root = np.sqrt(k * k - 4.0 / lambda_z**2)
    x = 0.5 * (k + root) if inflated else 2.0 / (lambda_z**2 * (k + root))
    return float(np.sqrt(x))


def tube_at(fraction, inflated=False):
    return jd.Tube(gent=GENT, lambda_i=locking_stretch(fraction, inflated), lambda_z=LAMBDA_Z,
                   eta=ETA, voltage=VOLTAGE)


def reference_integral(tube, r_end, integrand_of_w1=None):
    """∫_{r̂_i}^{r̂_end} [2W_1(λ² − λ_r²) − D̂_r²] dr̂/r̂ by scipy.integrate.quad on 40 pieces graded
    geometrically towards r̂_i (each to 1.2e-14 relative, their error estimates below 1e-13 in all), in
    float64, from the textbook integrand (paper Eqs. 5, 8; theory.md Eq. 1.1). With
    ``integrand_of_w1(I_1 − 3, G)`` in place of 2W_1 and without the electric term."""
    li, lz, g, v = (float(x) for x in (tube.lambda_i, tube.lambda_z, tube.gent, tube.voltage))
    ro = float(bs.geometry(tube).r_outer)
    log_ratio = np.log(ro / li)

    def integrand(r):
        lam = r / np.sqrt(lz * (r * r - li * li) + 1.0)
        lam_r = 1.0 / (lam * lz)
        excess = lam_r**2 + lam**2 + lz**2 - 3.0
        if integrand_of_w1 is not None:
            return integrand_of_w1(excess, g) * (lam**2 - lam_r**2) / r
        w1 = 0.5 / (1.0 - excess / g)
        d = v / (r * log_ratio)
        return (2.0 * w1 * (lam**2 - lam_r**2) - d * d) / r

    cuts = li + (r_end - li) * np.concatenate([[0.0], np.geomspace(1e-7, 1.0, 40)])
    total, size, error = 0.0, 0.0, 0.0
    for a, b in zip(cuts[:-1], cuts[1:]):
        with warnings.catch_warnings():  # near locking the integrand's own rounding, ~1e-13
            warnings.simplefilter("ignore", integrate.IntegrationWarning)  # relative, is reached
            value, err = integrate.quad(integrand, a, b, epsabs=0.0, epsrel=1.2e-14, limit=200)
        total, size, error = total + value, size + abs(value), error + err
    assert error <= 1e-13 * size
    return total


@pytest.mark.parametrize("inflated", [False, True], ids=["compressed", "inflated"])
@pytest.mark.parametrize("fraction", FRACTIONS)
def test_pressure_difference_near_locking(fraction, inflated):
    """ΔP̂ (Eq. 1.1) to 1e-12 relative up to 99.9 % of locking (the fixed composite Gauss–Legendre
    rule it replaced was off by 7e-4 relative at 99 % in compression)."""
    tube = tube_at(fraction, inflated)
    excess = jd.params.gent_limit_excess(tube.lambda_i, LAMBDA_Z, ETA)
    np.testing.assert_allclose(excess / GENT, fraction, rtol=1e-9)
    ro = float(bs.geometry(tube).r_outer)
    np.testing.assert_allclose(float(jd.pressure_difference(tube)), reference_integral(tube, ro),
                               rtol=1e-12)


@pytest.mark.parametrize("fraction", FRACTIONS)
def test_base_state_pressure_near_locking(fraction):
    """p̂(r̂) = 2W_1λ_r² + D̂_r² − τ̂_rr (Eqs. 1.2–1.3) inside the boundary layer and beyond, with
    τ̂_rr(r̂) = −ΔP̂ + ∫_{r̂_i}^{r̂} f dr̂ from the reference quadrature."""
    tube = tube_at(fraction)
    geo = bs.geometry(tube)
    li, ro, lz = float(geo.r_inner), float(geo.r_outer), LAMBDA_Z
    r = li + (ro - li) * np.array([1e-4, 1e-3, 1e-2, 0.1, 0.5, 1.0])
    state = jax.jit(bs.base_state)(tube, jnp.asarray(r))
    dp = reference_integral(tube, ro)
    lam = r / np.sqrt(lz * (r * r - li * li) + 1.0)
    lam_r = 1.0 / (lam * lz)
    w1 = 0.5 / (1.0 - (lam_r**2 + lam**2 + lz**2 - 3.0) / GENT)
    d = VOLTAGE / (r * np.log(ro / li))
    tau = np.array([-dp + reference_integral(tube, x) for x in r])
    expected = 2.0 * w1 * lam_r**2 + d * d - tau
    np.testing.assert_allclose(np.asarray(state.pressure), expected, rtol=1e-12)


def test_pressure_difference_derivatives_near_locking():
    """jax.grad of ΔP̂ at 99.9 % of locking: ∂/∂G against the quadrature of
    ∂(2W_1)/∂G = −(I_1 − 3)/(G − (I_1 − 3))², ∂/∂λ_i against central differences."""
    tube = tube_at(0.999)
    ro = float(bs.geometry(tube).r_outer)
    d_gent = jax.grad(lambda g: jd.pressure_difference(tube.replace(gent=g)))(GENT)
    expected = reference_integral(tube, ro, lambda e, g: -e / (g - e) ** 2)
    np.testing.assert_allclose(float(d_gent), expected, rtol=1e-11)
    li = float(tube.lambda_i)
    d_li = jax.grad(lambda x: jd.pressure_difference(tube.replace(lambda_i=x)))(li)
    h = 1e-7 * li
    dp = [float(jd.pressure_difference(tube.replace(lambda_i=li + s * h))) for s in (1, -1)]
    np.testing.assert_allclose(float(d_li), (dp[0] - dp[1]) / (2 * h), rtol=1e-6)


def test_pressure_difference_batched_near_locking():
    """jax.vmap over λ_i at 90 %, 99 %, 99.9 % of locking equals the single calls."""
    stretches = jnp.asarray([locking_stretch(f) for f in FRACTIONS])
    tube = tube_at(0.9)
    batched = jax.vmap(lambda li: jd.pressure_difference(tube.replace(lambda_i=li)))(stretches)
    single = [float(jd.pressure_difference(tube.replace(lambda_i=li))) for li in stretches]
    np.testing.assert_allclose(np.asarray(batched), single, rtol=1e-14)


@pytest.mark.parametrize("gent", [97.2, 1e8, 1e140, 1e160, np.inf])
def test_pressure_difference_large_gent(gent):
    """The closed form keeps every digit for large G (its O(G) terms are combined without
    cancellation) and meets the neo-Hookean form above GENT_CLOSED_MAX and at G = inf."""
    tube = jd.Tube(gent=gent, lambda_i=0.5, lambda_z=LAMBDA_Z, eta=ETA, voltage=VOLTAGE)
    ro = float(bs.geometry(tube).r_outer)
    np.testing.assert_allclose(float(jd.pressure_difference(tube)), reference_integral(tube, ro),
                               rtol=1e-13)


# ------------------------------------------------------------------------------ error estimates
def _estimate_of(levels, order=2):
    """(value, error, asymptotic) of frequencies_with_error's last three levels."""
    from jaxdea.solve.accuracy import _asymptotic, _conservative_error, _richardson

    levels = [np.array([x]) for x in levels]
    value, error = _richardson(levels, order)
    asymptotic = _asymptotic(levels, order, value)
    error = np.where(asymptotic, error, _conservative_error(levels, order, error))
    return value[0], error[0], bool(asymptotic[0])


@pytest.mark.parametrize("order", [2, 4, 6])
def test_asymptotic_levels_keep_the_richardson_estimate(order):
    """Levels Ω + c N^-p + d N^-(p+2) (observed order within ORDER_SLACK of p): the estimate is
    |R_last − R_prev| as before, above the true error (by 2^(p+2) − 1)."""
    from jaxdea.solve.accuracy import _richardson

    omega, c, d = 2.3, -0.4, 0.3
    levels = [omega + c * n**-order + d * n ** -(order + 2) for n in (4, 8, 16)]
    value, error, asymptotic = _estimate_of(levels, order)
    assert asymptotic and abs(value - omega) <= error < 2.0 ** (order + 2) * abs(value - omega)
    assert error == _richardson([np.array([x]) for x in levels], order)[1][0]


@pytest.mark.parametrize("width", [30.0, 300.0, 3000.0])
def test_preasymptotic_levels_get_a_conservative_bound(width):
    """A boundary layer of width ĥ/K: levels Ω − c/(N(N + K)), which converge like N⁻¹ while
    N ≪ K and like N⁻² beyond (observed ratios rising from 2 to 4 with N, as near Gent locking).
    Triples N, 2N, 4N inside the layer (4N ≤ K) are not asymptotic, those far beyond it are; the
    error bounds the true error of every triple."""
    omega, c = 2.2755, 60.0 * (60.0 + width) * 0.1
    seen_asymptotic = False
    for n in (15, 30, 60, 120, 240):
        levels = [omega - c / (m * (m + width)) for m in (n, 2 * n, 4 * n)]
        value, error, asymptotic = _estimate_of(levels)
        assert not (asymptotic and 4 * n <= width)
        assert abs(value - omega) <= error
        seen_asymptotic |= asymptotic
    assert seen_asymptotic == (width == 30.0)  # 4N up to 960: beyond K = 30 only


@pytest.mark.parametrize("power", [0.5, 1.2, 3.0])
def test_levels_of_another_order_get_a_conservative_bound(power):
    """Levels Ω + c N^-q with q ≠ 2: not asymptotic, and the error bounds the true error, where
    |R_last − R_prev| = |d₂||4 − ρ|/3 alone does not for ratios ρ = 2^q < 2 (q = 0.5)."""
    from jaxdea.solve.accuracy import _richardson

    omega, c = 0.212, 0.05
    levels = [omega + c * n**-power for n in (30, 60, 120)]
    value, error, asymptotic = _estimate_of(levels)
    assert not asymptotic and abs(value - omega) <= error < 10 * abs(value - omega)
    _, plain = _richardson([np.array([x]) for x in levels])
    assert (plain[0] < abs(value - omega)) == (power < 1.0)


def test_levels_that_do_not_converge_have_no_finite_bound():
    """Differences that do not shrink (ratio ≤ 1) or change sign: infinite error."""
    for levels in ([1.0, 1.1, 1.25], [1.0, 1.1, 1.05]):
        _, error, asymptotic = _estimate_of(levels)
        assert not asymptotic and error == np.inf
    _, error, asymptotic = _estimate_of([1.0, 1.0 + 1e-15, 1.0 + 2e-15])  # rounding: passes
    assert asymptotic and error < 1e-14


LOCKED = dict(gent=4.0, lambda_i=0.35890249, lambda_z=LAMBDA_Z, eta=ETA, voltage=VOLTAGE)


@pytest.mark.slow
def test_error_estimate_near_locking_is_honest():
    """99 % of locking, acoustic fluid, n = 2 (about 2 min). The midpoint levels 30, 60, 120
    converge at ratios 2.0 (root 1), 1.7 (root 2), 1.5 (root 3) instead of 4: the levels double
    until the observed order is within ORDER_SLACK of 2 (960 here), and every error bounds the
    distance to a reference, the sixth-order Magnus scheme on 960 sublayers (within 1e-6 of 480
    sublayers; a midpoint laminate graded geometrically towards r̂_i agrees to 2e-8). Stopped at
    240 sublayers the roots are INACCURATE, with conservative errors that still bound it."""
    tube, fluid = jd.Tube(**LOCKED), jd.Fluid(density_ratio=0.13, speed_ratio=0.27)
    alpha = float(jd.axial_wavenumber(tube, 2))
    est = jd.frequencies_with_error(tube, alpha, fluid, n_roots=3, n_layers=30)
    reference = [[float(jd.frequency(tube, alpha, w, fluid, n_layers=n, scheme="magnus6"))
                  for w in est.omega] for n in (480, 960)]
    np.testing.assert_allclose(reference[0], reference[1], rtol=1e-6)
    levels = est.levels[:3]
    ratios = (levels[1] - levels[0]) / (levels[2] - levels[1])
    assert np.all(ratios < 2.0 ** 1.5)  # not the N⁻² regime
    assert est.n_layers[-1] > 120 and np.all(est.status == jd.Status.CONVERGED)
    assert np.all(np.abs(est.omega - reference[1]) <= est.error)
    assert abs(levels[0][1] - reference[1][1]) > 0.1  # root 2 at N = 30: the layer is unresolved
    short = jd.frequencies_with_error(tube, alpha, fluid, n_roots=3, max_layers=240, n_layers=30)
    np.testing.assert_array_equal(short.n_layers, [30, 60, 120, 240])
    assert np.all(short.status == jd.Status.INACCURATE)
    assert np.all(np.abs(short.omega - reference[1]) <= short.error)
    assert np.all(np.isfinite(short.error))


@pytest.mark.slow
def test_default_levels_near_locking_converge_at_sixth_order():
    """The same tube without n_layers: the graded sixth-order levels (96, 192, 384) are in the
    asymptotic regime at once (CONVERGED, errors below 1e-8), and each estimate bounds the distance
    to the roots followed on a graded wall of 1536 sublayers."""
    tube, fluid = jd.Tube(**LOCKED), jd.Fluid(density_ratio=0.13, speed_ratio=0.27)
    alpha = float(jd.axial_wavenumber(tube, 2))
    est = jd.frequencies_with_error(tube, alpha, fluid, n_roots=3)
    assert est.n_layers[0] == 96 and np.all(est.status == jd.Status.CONVERGED)
    assert np.all(est.error < 1e-8 * est.omega)
    from jaxdea.params import canonical
    from jaxdea.physics.dispersion import check_inputs
    from jaxdea.physics.transfer import Layers
    from jaxdea.solve.accuracy import _follow

    order = check_inputs(tube, alpha, fluid, None, None)
    fine, status = _follow(*canonical(tube, alpha, fluid), jnp.asarray(est.omega),
                           Layers(1536, "magnus6", True), order)  # 4× the finest level
    assert np.all(np.asarray(status) == jd.Status.CONVERGED)
    assert np.all(np.abs(est.omega - np.asarray(fine)) <= np.maximum(est.error, 1e-12 * est.omega))
