"""jaxdea.wavenumbers: complex α̂ at a real Ω, against the public check values (theory_next.md §7e)
and the real solver both ways (the real roots are the α̂ of the dispersion curve through Ω)."""

import jax
import numpy as np
import pytest
from exact_cylinder_m import complex_root
from scipy.optimize import brentq
from scipy.special import jv, yv

import jaxdea as jd

UNSTRETCHED = jd.Tube(voltage=0.0, lambda_i=1.0, lambda_z=1.0, eta=0.85)
PAPER = jd.Tube(voltage=0.05, lambda_i=1.1, lambda_z=1.2)


def test_unstretched_tube_public_values():
    """theory_next.md §7(e): m = 1, Ω = 1, the 4 roots nearest the real axis (conjugates included),
    certified by the argument principle; their order by |Im α̂|, then Re α̂."""
    res = jd.wavenumbers(UNSTRETCHED, 1.0, n_roots=4, m=1)
    expected = [0.24345995, 1.52440015, 2.24742018 - 2.71976903j, 2.24742018 + 2.71976903j]
    np.testing.assert_allclose(np.asarray(res.alpha), expected, rtol=0, atol=2e-8)
    np.testing.assert_allclose(np.asarray(res.attenuation), np.abs(np.imag(expected)), atol=2e-8)
    assert int(res.certificate) == jd.SearchStatus.CERTIFIED
    assert np.all(np.asarray(res.status) == jd.Status.CONVERGED)


def test_evanescent_and_attenuated_roots_against_the_exact_cylinder():
    """Unstretched, V̂ = 0, m = 1, Ω = 1, the 8 roots nearest the real axis. Each mechanical root is
    a zero of the exact incompressible cylinder's determinant at complex α̂ (tests/exact_cylinder_m.py,
    secant from jaxdea's root, to 1e-9). One evanescent pair has no mechanical motion: at V̂ = 0 the
    electric block decouples, and the potential with Φ = 0 on both electrodes solves Laplace's
    equation when J_1(κa)Y_1(κb) = J_1(κb)Y_1(κa): κ = 17.8201826 (κh ≈ π)."""
    a, b = 1.0, 1.0 / 0.85
    res = jd.wavenumbers(UNSTRETCHED, 1.0, n_roots=8, m=1)
    alpha = np.asarray(res.alpha)
    assert np.all(np.isfinite(alpha)) and int(res.certificate) == jd.SearchStatus.CERTIFIED
    kappa_e = brentq(lambda k: jv(1, k * a) * yv(1, k * b) - jv(1, k * b) * yv(1, k * a), 17.0, 18.5)
    electric = np.abs(np.abs(alpha) - kappa_e) < 1e-8 * kappa_e
    assert np.sum(electric) == 2 and np.all(np.abs(alpha[electric].real) < 1e-12)
    mechanical = alpha[~electric]
    assert np.sum(np.abs(mechanical.imag) > 10.0) == 2  # the evanescent pair ±17.8878i
    for z in mechanical:
        exact = complex_root(1.0, z, a, b, 1)
        assert abs(z - exact) < 1e-9 * abs(exact), (z, exact)


def test_real_wavenumbers_invert_the_dispersion_curve():
    """The paper's tube (pre-stretched, V̂ = 0.05), m = 2: Ω₀ = the second frequency at α̂₀ = 0.445;
    the real roots of wavenumbers at Ω₀ include α̂₀, and at each real root the real solver gives
    Ω₀ back."""
    alpha0 = 0.445
    omega0 = float(jd.frequencies(PAPER, alpha0, m=2, n_roots=2)[1])
    res = jd.wavenumbers(PAPER, omega0, n_roots=6, m=2)
    alpha = np.asarray(res.alpha)
    real = alpha[np.isfinite(alpha) & (np.abs(alpha.imag) < 1e-12)].real
    assert real.size >= 1 and np.min(np.abs(real - alpha0)) < 1e-10
    for a in real:
        omega = np.asarray(jd.frequencies(PAPER, float(a), m=2, n_roots=6))
        assert np.nanmin(np.abs(omega - omega0)) < 1e-10 * omega0, (a, omega)
    assert int(res.certificate) == jd.SearchStatus.CERTIFIED


def test_filled_tube_real_root_is_the_curve_point():
    """Acoustic filling, m = 0: the α̂ at which the lowest frequency is Ω₀ comes back as a real root."""
    fluid = jd.Fluid(density_ratio=0.5, speed_ratio=2.0)
    alpha0 = 0.6
    omega0 = float(jd.frequencies(PAPER, alpha0, fluid, n_roots=1)[0])
    res = jd.wavenumbers(PAPER, omega0, fluid, n_roots=3)
    alpha = np.asarray(res.alpha)
    assert np.min(np.abs(alpha - alpha0)) < 1e-10
    assert int(res.certificate) == jd.SearchStatus.CERTIFIED


@pytest.mark.parametrize("kwargs, name", [
    (dict(omega=0.0), "omega"),
    (dict(omega=1.0, n_roots=0), "n_roots"),
    (dict(omega=1.0, fluid=jd.Fluid(coupling="paper")), "fluid"),
    (dict(omega=1.0, alpha_max=-1.0), "alpha_max"),
    (dict(omega=1.0, m=-1), "m"),
])
def test_bad_input_names_the_parameter(kwargs, name):
    with pytest.raises(ValueError, match=name):
        jd.wavenumbers(UNSTRETCHED, **kwargs)


def test_traced_input_is_refused_in_words():
    with pytest.raises(ValueError, match="omega"):
        jax.jit(lambda om: jd.wavenumbers(UNSTRETCHED, om).alpha)(1.0)


def test_roots_near_the_contour_are_recounted_on_the_solve_wall():
    """search_box's coarse count is trusted only where every root found lies farther than
    NEAR_CONTOUR × the box size from the region's contour (``_near_contour``): the distances to the
    sides of the hexagon with its viscous corner, inside and outside."""
    from jaxdea.solve.wavenumbers import NEAR_CONTOUR, _near_contour, region
    lo, hi = complex(0.02, -0.02), complex(10.0, 10.0)
    vertices = region(lo, hi, corner=4.0)
    size = abs(hi - lo)
    gap = NEAR_CONTOUR * size
    assert not _near_contour([], vertices, size)
    assert not _near_contour([5.0 + 0.01j, 2.0 + 3.0j], vertices, size)
    assert _near_contour([5.0 - 0.02j + 0.5j * gap], vertices, size)  # beside the bottom side
    assert not _near_contour([5.0 - 0.02j + 2j * gap], vertices, size)
    assert _near_contour([4.0 - 0.5 * gap + 6j], vertices, size)  # beside the corner's upright
    assert not _near_contour([4.0 - 2 * gap + 6j], vertices, size)  # in the corner, clear of it


def test_a_newton_batch_stops_once_its_roots_are_found():
    """search_box's Newton batch (wavenumbers._newton) stops once the roots the count still needs
    have converged inside the region, not when its slowest start does: from a grid over the band
    [0.05, 5] × [−1, 1] of the hysteretic tube at Ω = 0.5 (one root there, 0.2923 − 0.0075i), the
    stopped batch holds that root to 1e-12 of the batch run to the end but fewer converged starts;
    a root already known does not count; needing more roots than the box holds runs to the end."""
    import jax.numpy as jnp

    from jaxdea.params import canonical
    from jaxdea.physics.characteristic import Unknown
    from jaxdea.physics.problem import NO_ALPHA, describe
    from jaxdea.physics.transfer import Layers, discretized
    from jaxdea.solve import wavenumbers as W

    tube = UNSTRETCHED.replace(damping=jd.Hysteretic(0.05))
    problem = describe(tube, NO_ALPHA, None, None, None, 0, False, damped=True)
    tube, omega, fluid = canonical(tube, 0.5, None)
    wall = discretized(tube, n_layers=Layers(12, "magnus6", True))
    lo, hi = complex(0.05, -1.0), complex(5.0, 1.0)
    re, im = np.meshgrid(np.linspace(0.3, 4.7, 8), np.linspace(-0.8, 0.8, 4))
    starts = (re + 1j * im).ravel()
    m = jnp.asarray(0.0)

    def run(known, need):
        return W._converged(problem, wall, omega, fluid, m, starts, W.PAD, Unknown.ALPHA,
                            (lo, hi, None), known, need)

    def inside(roots):
        return W._distinct([z for z in roots if W.inside(z, lo, hi)], abs(hi - lo))

    everything = run([], 10 ** 6)  # more than the box holds: every start to its end
    stopped = run([], 1)
    assert len(inside(everything)) == 1 and len(inside(stopped)) == 1
    np.testing.assert_allclose(inside(stopped)[0], inside(everything)[0], rtol=1e-12)
    assert abs(inside(stopped)[0] - (0.29233013 - 0.00752020j)) < 1e-7
    assert len(stopped) < len(everything)
    again = run(inside(everything), 1)  # the box's one root is known: nothing stops the batch
    assert len(again) == len(everything)
