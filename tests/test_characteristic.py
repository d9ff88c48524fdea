"""The one characteristic-function contract (jaxdea.physics.characteristic): every family and
unknown, real and complex, against the unscaled reference determinant det(Out A S) (expm per
sublayer), finite differences, the public complex-wavenumber check values (theory_next.md §7e) and
the real solver."""

import jax
import numpy as np
import pytest

import jaxdea as jd
from jaxdea.physics import characteristic as ch
from jaxdea.physics.dispersion import reference_determinant_of_w
from jaxdea.physics.families import Family
from jaxdea.physics.transfer import discretize, laminate

UNSTRETCHED = jd.Tube(lambda_i=1.0, lambda_z=1.0, voltage=0.0, eta=0.85)
PAPER = jd.Tube(lambda_i=1.1, lambda_z=1.2, voltage=0.05, eta=0.85)
LAYERS = laminate(24, "magnus6")  # one laminate: the tests share their compiled programs
ACOUSTIC = jd.Fluid(density_ratio=0.9, speed_ratio=0.8)
CASES = [(Family.LONGITUDINAL, 0.0), (Family.ORDER_M, 1.0), (Family.ORDER_M, 2.0),
         (Family.TORSIONAL, 0.0)]
POINTS = [(ch.Unknown.OMEGA, 1.3 + 0.2j, 0.445), (ch.Unknown.OMEGA_SQUARED, 1.7 - 0.3j, 0.445),
          (ch.Unknown.GROWTH, 0.4 + 0.9j, 0.445), (ch.Unknown.ALPHA, 2.2 + 2.7j, 1.0)]


_reference = jax.jit(lambda wall, w, alpha, fluid, m, family: reference_determinant_of_w(
    wall, w, alpha, fluid, 0, m, family), static_argnums=5)
value = jax.jit(ch.value, static_argnums=(0, 5, 7))
value_and_log_slope = jax.jit(ch.value_and_log_slope, static_argnums=(0, 5, 7))


def reference(family, wall, x, fixed, fluid, m, unknown):
    """F(x) = det(Out A S) with the plain transfer matrix (expm per sublayer), no scaling."""
    w, alpha = unknown.point(x, fixed)
    return complex(_reference(wall, w, alpha, fluid, m, family))


@pytest.mark.parametrize("family, m", CASES)
@pytest.mark.parametrize("unknown, x, fixed", POINTS)
def test_log_slope_is_the_analytic_derivative_of_the_determinant(family, m, unknown, x, fixed):
    """d ln F/dx against central differences of det(Out A S) along the real and the imaginary
    axis: equal there only for an analytic F, and the contract's slope matches both."""
    wall = discretize(PAPER, LAYERS)
    f, log_slope = value_and_log_slope(family, wall, x, fixed, None, 0, m, unknown)
    h = 1e-5
    f0 = reference(family, wall, x, fixed, None, m, unknown)
    along_real = (reference(family, wall, x + h, fixed, None, m, unknown)
                  - reference(family, wall, x - h, fixed, None, m, unknown)) / (2 * h) / f0
    along_imag = (reference(family, wall, x + 1j * h, fixed, None, m, unknown)
                  - reference(family, wall, x - 1j * h, fixed, None, m, unknown)) / (2j * h) / f0
    for fd in (along_real, along_imag):
        assert abs(complex(log_slope) - fd) < 1e-8 * max(1.0, abs(fd)), (log_slope, fd)
    # the scaled value keeps F's argument (det R > 0) and |f| <= 1
    assert abs(np.angle(complex(f) / f0)) < 1e-12
    assert abs(complex(f)) <= 1.0 + 1e-12


@pytest.mark.parametrize("family, m", CASES)
def test_lossless_function_reflects_in_the_real_axis(family, m):
    """A lossless tube: f(x̄) = conj f(x) (Schwarz reflection) and the same for d ln F/dx."""
    wall = discretize(PAPER, LAYERS)
    for unknown, x, fixed in POINTS:
        f, s = value_and_log_slope(family, wall, x, fixed, None, 0, m, unknown)
        g, t = value_and_log_slope(family, wall, np.conj(x), fixed, None, 0, m, unknown)
        assert abs(complex(g) - np.conj(complex(f))) < 1e-14
        assert abs(complex(t) - np.conj(complex(s))) < 1e-11 * abs(complex(s))


@pytest.mark.parametrize("family, m", CASES)
def test_value_in_alpha_equals_value_in_omega(family, m):
    """x = α̂ (generators as polynomials in α̂) against x = Ω (generators formed at α̂), at the
    same real point: two routes to one f."""
    wall = discretize(PAPER, LAYERS)
    for omega, alpha in ((0.7, 0.445), (2.3, 1.9)):
        by_alpha = value(family, wall, alpha, omega, None, 0, m, ch.Unknown.ALPHA)
        by_omega = value(family, wall, omega, alpha, None, 0, m, ch.Unknown.OMEGA)
        assert abs(float(by_alpha) - float(by_omega)) < 1e-13


def newton(family, wall, x, fixed, fluid, m, unknown, steps=30):
    """Complex Newton on F with the contract's log-slope; (root, steps taken, |f| there)."""
    x = complex(x)
    for k in range(steps):
        f, log_slope = value_and_log_slope(family, wall, x, fixed, fluid, 0, m, unknown)
        step = 1.0 / complex(log_slope)
        x -= step
        if abs(step) < 1e-14 * abs(x):
            return x, k + 1, abs(complex(f))
    return x, steps, abs(complex(f))


def test_complex_wavenumbers_of_the_unstretched_tube():
    """theory_next.md §7(e): lossless, unstretched, m = 1, Ω = 1, the roots in α̂ nearest the real
    axis: 0.24345995, 1.52440015 (propagating), 2.24742018 ± 2.71976903i, found by Newton on the
    contract from nearby starts in a few quadratic steps. The real ones are checked once more with
    the real solver: Ω = 1 is a frequency of the tube at those α̂."""
    wall = discretize(UNSTRETCHED, laminate(24, "magnus6"))
    expected = (0.24345995, 1.52440015, 2.24742018 + 2.71976903j, 2.24742018 - 2.71976903j)
    for start, want in zip((0.2 + 0.1j, 1.4 - 0.2j, 2.0 + 2.5j, 2.0 - 2.5j), expected, strict=True):
        root, steps, size = newton(Family.ORDER_M, wall, start, 1.0, None, 1.0, ch.Unknown.ALPHA)
        assert abs(root - want) < 1e-8, (root, want)
        assert steps <= 8 and size < 1e-14
    for want in expected[:2]:
        omega = jd.frequencies(UNSTRETCHED, want, m=1, n_roots=4)
        assert np.min(np.abs(np.asarray(omega) - 1.0)) < 1e-7


def test_complex_newton_with_a_fluid_beyond_the_series_range():
    """A filled tube at α̂ = 10, where the fluid's Bessel pair leaves its series (|χ̂² r̂_i²| > 64) and
    carries a positive, non-analytic factor: Newton in α̂ from 10 + 0.3i still converges
    quadratically to the real α̂ at which the real solver gives the frequency."""
    wall = discretize(PAPER, laminate(24, "magnus6"))
    fast = jd.Fluid(density_ratio=0.9, speed_ratio=3.0)
    omega = float(jd.frequencies(PAPER, 10.0, fast, n_roots=1, n_layers=laminate(24, "magnus6"))[0])
    w, alpha = ch.Unknown.ALPHA.point(10.0, omega)
    s = (w / 3.0**2 - alpha**2) * float(wall.r_inner) ** 2
    assert abs(s) > 64.0
    root, steps, size = newton(Family.LONGITUDINAL, wall, 10.0 + 0.3j, omega, fast, 0.0,
                               ch.Unknown.ALPHA)
    assert abs(root - 10.0) < 1e-10 and steps <= 8, (root, steps)


def test_contract_value_is_the_public_characteristic():
    """value() on a real Ω against jaxdea.characteristic (its own jit, guard and family choice)."""
    layers = LAYERS
    wall = discretize(PAPER, layers)
    for family, m in CASES:
        public = jd.characteristic(PAPER, 1.1, 0.445, n_layers=layers, m=int(m),
                                   torsional=family is Family.TORSIONAL)
        f = value(family, wall, 1.1, 0.445, None, 0, m)
        assert float(f) == pytest.approx(float(public), rel=1e-12, abs=1e-15)


@pytest.mark.parametrize("family, m", [(Family.LONGITUDINAL, 0.0), (Family.ORDER_M, 2.0)])
def test_log_slope_with_a_fluid_is_analytic_beyond_the_series_range(family, m):
    """At α̂ = 8 + 6.7i, Ω = 4 the fluid's pair comes from Bessel's integrals and carries a positive,
    non-analytic factor c (jaxdea.numerics.bessel): the reference F = c F_a with F_a analytic.
    Differences along x and along ix then give d ln c/dx + L and L − i d ln c/dy, so the analytic
    L is the real part of the second and the imaginary part of the first."""
    wall = discretize(PAPER, laminate(24, "magnus6"))
    x, omega, h = 8.0 + 6.7j, 4.0, 1e-5
    w, alpha = ch.Unknown.ALPHA.point(x, omega)
    assert abs((w / 0.8**2 - alpha**2) * float(wall.r_inner) ** 2) > 64.0
    _, log_slope = value_and_log_slope(family, wall, x, omega, ACOUSTIC, 0, m, ch.Unknown.ALPHA)

    def ref(y):
        return reference(family, wall, y, omega, ACOUSTIC, m, ch.Unknown.ALPHA)

    along_real = (ref(x + h) - ref(x - h)) / (2 * h) / ref(x)
    along_imag = (ref(x + 1j * h) - ref(x - 1j * h)) / (2j * h) / ref(x)
    assert abs(along_real - along_imag) > 0.1  # the factor is there and is not analytic
    analytic = along_imag.real + 1j * along_real.imag
    assert abs(complex(log_slope) - analytic) < 1e-7 * abs(analytic), (log_slope, analytic)
