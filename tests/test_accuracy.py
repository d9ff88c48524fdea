"""Accuracy control: error estimates against exact roots, tolerance-driven refinement, thick walls
up to α̂ĥ = 150 against the exact cylinder, and the amplified error near the critical voltage."""

import exact_cylinder
import numpy as np
import pytest

import jaxdea as jd
from jaxdea.solve.accuracy import frequencies_with_error


@pytest.mark.slow
def test_error_estimate_bounds_the_true_error():
    """Unstretched tube (exact incompressible cylinder): the estimate of every root exceeds its true
    error, by about 15 (asymptotic ratio of consecutive Richardson errors, 16 − 1), never by 1000."""
    tube, alpha = jd.Tube(eta=0.85), 0.5
    exact = exact_cylinder.roots(alpha, 1.0, 1 / 0.85, 3, 22.0, 2000)
    est = frequencies_with_error(tube, alpha, n_roots=3, omega_max=22.0, n_layers=30)
    assert np.all(est.status == jd.Status.CONVERGED)
    np.testing.assert_array_equal(est.n_layers, [30, 60, 120])
    true = np.abs(est.omega - exact)
    assert np.all(true <= est.error)
    assert np.all(est.error <= 1e3 * true + 1e-13 * exact)
    assert np.all(true < 1e-11 * exact)  # N = 30 alone: up to 1.1e-5


@pytest.mark.slow
def test_tolerance_is_reached_by_doubling():
    tube, alpha = jd.Tube(eta=0.85), 0.5
    exact = exact_cylinder.roots(alpha, 1.0, 1 / 0.85, 3, 22.0, 2000)
    est = frequencies_with_error(tube, alpha, n_roots=3, omega_max=22.0, rtol=1e-12, n_layers=30)
    assert np.all(est.status == jd.Status.CONVERGED)
    assert est.n_layers[-1] > 120 and np.all(est.error <= 1e-12 * est.omega)
    assert np.all(np.abs(est.omega - exact) <= 1e-12 * exact)
    few = frequencies_with_error(tube, alpha, n_roots=3, omega_max=22.0, rtol=1e-15, max_layers=120,
                                 n_layers=30)
    assert np.all(few.status == jd.Status.INACCURATE) and np.all(np.isfinite(few.omega))


@pytest.mark.slow
def test_thick_wall_at_alpha_h_150_against_the_exact_cylinder():
    """η = 0.3 (ĥ = 2.33), α̂ĥ = 150: the raw transfer product is ~1e65 here. All 12 exact roots
    below Ω = 66 are found, including the thickness resonances crowding above the shear cutoff
    Ω = α̂ (gaps down to 0.05 against a scan step of 0.08: the scan is uniform in the radial phase
    there), and each agrees with the exact root within its error estimate."""
    tube = jd.Tube(eta=0.3)
    alpha = 150.0 / float(jd.thickness_ratio(tube))
    exact = exact_cylinder.roots(alpha, 1.0, 1 / 0.3, 13, 66.0, 16000)
    assert np.sum(np.isfinite(exact)) == 12
    est = frequencies_with_error(tube, alpha, n_roots=13, omega_max=66.0, n_layers=30)
    assert np.all(est.status[:12] == jd.Status.CONVERGED) and est.status[12] == jd.Status.NO_ROOT
    true = np.abs(est.omega[:12] - exact[:12])
    assert np.all(true <= est.error[:12]) and np.all(est.error[:12] < 1e-4 * exact[:12])


@pytest.mark.slow
def test_amplified_error_near_the_critical_voltage_is_visible():
    """V̂ = 0.999 V̂_cr: the lowest root carries the laminate error of V̂_cr amplified by
    ≈ 1/(2(1 − V̂/V̂_cr)) = 500; the levels see V̂_cr move, so its estimate is far larger (relative)
    than that of the next root and covers the change from N = 30 to the extrapolated value."""
    tube = jd.Tube(lambda_i=1.1, lambda_z=1.2)
    alpha = jd.axial_wavenumber(tube, 1)
    v_cr = float(jd.critical_voltage(tube, alpha, n_layers=30))
    est = frequencies_with_error(tube.replace(voltage=0.999 * v_cr), alpha, n_roots=3, n_layers=30)
    assert np.all(est.status == jd.Status.CONVERGED)
    rel = est.error / est.omega
    assert rel[0] > 1e3 * max(rel[1], rel[2])
    change = np.abs(est.levels[0] - est.omega) / est.omega  # the N = 30 error, ≈ 3e-3 for root 1
    assert change[0] > 1e-3 and change[0] > 300 * change[1]


@pytest.mark.slow
def test_near_critical_estimate_against_a_finer_reference():
    tube = jd.Tube(lambda_i=1.1, lambda_z=1.2)
    alpha = jd.axial_wavenumber(tube, 1)
    v_cr = float(jd.critical_voltage(tube, alpha, n_layers=30))
    for frac in (0.99, 0.999):
        t = tube.replace(voltage=frac * v_cr)
        est = frequencies_with_error(t, alpha, n_roots=2, n_layers=30)
        ref = frequencies_with_error(t, alpha, n_roots=2, n_layers=240)
        assert np.all(np.abs(est.omega - ref.omega) <= est.error)


@pytest.mark.parametrize("kwargs, name", [(dict(rtol=-1.0), "rtol"), (dict(rtol=np.nan), "rtol"),
                                          (dict(max_layers=60), "max_layers")])
def test_bad_accuracy_arguments(kwargs, name):  # max_layers < 4N, N = 16 by default
    with pytest.raises(ValueError, match=name):
        frequencies_with_error(jd.Tube(), 0.5, **kwargs)


@pytest.mark.slow
def test_magnus_levels_give_estimates_and_reach_rtol():
    """The Magnus schemes' levels (Richardson factor 2^4, 2^6) against the exact cylinder: magnus4
    from N = 6 (levels off by up to 1.4e-8) has every estimate above the true error and below 1000×
    it; magnus6 from N = 4 reaches rtol = 1e-13 (true errors ≤ 1.2e-15)."""
    tube, alpha = jd.Tube(eta=0.85), 0.5
    exact = exact_cylinder.roots(alpha, 1.0, 1 / 0.85, 3, 22.0, 2000)
    est = frequencies_with_error(tube, alpha, n_roots=3, omega_max=22.0, n_layers=6, scheme="magnus4")
    assert np.all(est.status == jd.Status.CONVERGED)
    np.testing.assert_array_equal(est.n_layers, [6, 12, 24])
    true = np.abs(est.omega - exact)
    assert np.all(true <= est.error) and np.all(est.error <= 1e3 * true + 1e-13 * exact)
    assert np.max(np.abs(est.levels[0] / exact - 1.0)) > 1e-9  # the levels alone are far coarser
    fine = frequencies_with_error(tube, alpha, n_roots=3, omega_max=22.0, n_layers=4,
                                  scheme="magnus6", rtol=1e-13)
    assert np.all(fine.status == jd.Status.CONVERGED) and np.all(fine.error <= 1e-13 * fine.omega)
    assert np.all(np.abs(fine.omega - exact) <= 1e-13 * exact)


@pytest.mark.parametrize("order", [2, 4, 6])
def test_richardson_eliminates_the_leading_term_of_each_order(order):
    """Levels Ω + c N^-p + d N^-(p+2) at N, 2N, 4N: R_last = Ω + O(N^-(p+2)) exactly as the formula
    says, and the estimate |R_last − R_prev| is 2^(p+2) − 1 times R_last's error."""
    from jaxdea.solve.accuracy import _richardson

    n, omega, c, d = 1.0, 1.7, 0.3, 0.11
    levels = [np.array([omega + c * m**-order + d * m ** -(order + 2)]) for m in (n, 2 * n, 4 * n)]
    value, error = _richardson(levels, order)
    factor = 2.0**order
    last = d * (2 * n) ** -(order + 2) * (0.25 - 1.0) / (factor - 1.0)  # R_last − Ω: the d term
    np.testing.assert_allclose(value - omega, last, rtol=1e-6)
    np.testing.assert_allclose(error, (2.0 ** (order + 2) - 1.0) * abs(last), rtol=1e-6)


def test_default_levels_are_graded_and_their_estimate_bounds_the_error():
    """Without n_layers the levels are the default's graded sixth-order walls (N, 2N, 4N from the
    default N = 16): the estimate of the default's roots, CONVERGED, bounding the error against the
    exact cylinder (true errors ~1e-14 here)."""
    tube, alpha = jd.Tube(eta=0.85), 0.5
    exact = exact_cylinder.roots(alpha, 1.0, 1 / 0.85, 3, 22.0, 2000)
    est = frequencies_with_error(tube, alpha, n_roots=3, omega_max=22.0)
    np.testing.assert_array_equal(est.n_layers, [16, 32, 64])
    np.testing.assert_array_equal(est.levels[0], np.asarray(jd.frequencies(tube, alpha, n_roots=3,
                                                                             omega_max=22.0)))
    assert np.all(est.status == jd.Status.CONVERGED)
    assert np.all(np.abs(est.omega - exact) <= est.error + 2e-14 * exact)
    assert np.all(est.error < 1e-10 * exact)
