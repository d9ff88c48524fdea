"""Curves of complex roots by continuation (jaxdea.wavenumber_curve, jaxdea.complex_dispersion_curve;
docs/theory/real_tubes.md §5): each point against an independent certified search, exact damped
relations of the unstretched tube, and the lossless limit against jaxdea.frequencies."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxdea as jd
from jaxdea.physics.transfer import Layers

UNSTRETCHED = jd.Tube(voltage=0.0, lambda_i=1.0, lambda_z=1.0)


def test_wavenumber_curve_equals_the_certified_search_at_every_checked_point():
    """A hysteretic tube (ζ = 0.05): the continued branches at Ω = 1.25 and 2.0 are the roots of
    jaxdea.wavenumbers there (an independent search of the plane), to 1e-9; at Ω = 2 the branches
    have changed order (the first search's first wave is now the third least attenuated), which the
    curve keeps as branch identity."""
    tube = UNSTRETCHED.replace(damping=jd.Hysteretic(0.05))
    grid = np.linspace(0.5, 2.0, 41)
    curve = jd.wavenumber_curve(tube, grid, n_roots=3)
    assert np.all(np.asarray(curve.status) == jd.Status.CONVERGED)
    assert int(curve.certificate) == jd.SearchStatus.CERTIFIED
    for k in (20, 40):
        found = np.asarray(jd.wavenumbers(tube, float(grid[k]), n_roots=3).alpha)
        for z in np.asarray(curve.alpha[k]):
            assert np.min(np.abs(found - z)) < 1e-9 * abs(z)
    np.testing.assert_array_equal(curve.attenuation, np.abs(np.imag(curve.alpha)))
    assert np.all(np.imag(curve.alpha[:, 0]) < 0)  # the first wave decays along +z throughout


def test_lossless_wavenumber_curve_inverts_frequencies():
    """A stretched, biased lossless tube: the propagating branch stays real (|Im α̂| < 1e-12) and
    at every point jaxdea.frequencies at that α̂ has the grid's Ω among its roots, to 1e-10."""
    tube = jd.Tube(voltage=0.05, lambda_i=1.1, lambda_z=1.2, eta=0.8)
    grid = np.linspace(0.4, 1.2, 17)
    curve = jd.wavenumber_curve(tube, grid, n_roots=2)
    real = [j for j in range(2) if abs(complex(curve.alpha[0, j]).imag) < 1e-12]
    assert real, "no propagating wave at the first Ω"
    j = real[0]
    assert np.all(np.asarray(curve.status[:, j]) == jd.Status.CONVERGED)
    assert np.max(np.abs(np.imag(curve.alpha[:, j]))) < 1e-12
    for k in range(0, 17, 4):
        roots = np.asarray(jd.frequencies(tube, float(np.real(curve.alpha[k, j])), n_roots=4))
        assert np.nanmin(np.abs(roots - grid[k])) < 1e-10 * grid[k]


def test_complex_dispersion_curve_is_the_exact_kelvin_voigt_relation():
    """Unstretched, unbiased, empty tube with Kelvin–Voigt damping (η_v = 0.05), m = 1: every
    modulus is μ(1 + iΩη_v), so each continued root satisfies Ω² = Ω_e²(1 + iΩη_v), i.e.
    Ω = [iΩ_e²η_v + √(4Ω_e² − Ω_e⁴η_v²)]/2, with Ω_e the elastic dispersion_curve at the same α̂
    on the same laminate: to 1e-10 along 30 α̂. The quality factor is Re Ω/(2 Im Ω)."""
    eta_v = 0.05
    tube = UNSTRETCHED.replace(damping=jd.KelvinVoigt(eta_v))
    grid = np.linspace(0.3, 3.0, 30)
    wall = Layers(16, "magnus6", True)
    curve = jd.complex_dispersion_curve(tube, grid, n_roots=2, m=1, n_layers=wall)
    assert np.all(np.asarray(curve.status) == jd.Status.CONVERGED)
    elastic = np.asarray(jd.dispersion_curve(UNSTRETCHED, grid, n_roots=2, m=1, n_layers=wall).omega)
    exact = _kelvin_voigt(elastic, eta_v)
    np.testing.assert_allclose(curve.omega, exact, rtol=1e-10)
    np.testing.assert_allclose(curve.quality_factor,
                               np.real(exact) / (2 * np.imag(exact)), rtol=1e-9)


def _kelvin_voigt(elastic, eta_v):
    """The damped roots Ω of Ω² = Ω_e²(1 + iΩη_v) with Re Ω > 0 (decaying: Im Ω > 0)."""
    return (1j * elastic**2 * eta_v + np.sqrt(4 * elastic**2 - elastic**4 * eta_v**2)) / 2


def test_default_complex_curves_meet_the_promised_accuracy():
    """The default discretisation of a complex curve starts below the rule and is checked
    (complex_curves._checked): the Kelvin–Voigt curve of the unstretched tube (m = 1) is the exact
    relation with Ω_e of the elastic curve on a fine laminate (N = 64) to 1e-8, and the hysteretic
    wavenumber curve equals the same curve continued on N = 64 to 1e-8 (relative to max(|α̂|, 1))."""
    eta_v = 0.05
    grid = np.linspace(0.3, 3.0, 30)
    fine = Layers(64, "magnus6", True)
    curve = jd.complex_dispersion_curve(UNSTRETCHED.replace(damping=jd.KelvinVoigt(eta_v)), grid,
                                        n_roots=2, m=1)
    assert np.all(np.asarray(curve.status) == jd.Status.CONVERGED)
    elastic = np.asarray(jd.dispersion_curve(UNSTRETCHED, grid, n_roots=2, m=1, n_layers=fine).omega)
    np.testing.assert_allclose(curve.omega, _kelvin_voigt(elastic, eta_v), rtol=1e-8)
    tube = UNSTRETCHED.replace(damping=jd.Hysteretic(0.05))
    omegas = np.linspace(0.5, 2.0, 21)
    waves = jd.wavenumber_curve(tube, omegas, n_roots=3)
    reference = jd.wavenumber_curve(tube, omegas, n_roots=3, n_layers=fine)
    assert np.all(np.asarray(waves.status) == jd.Status.CONVERGED)
    scale = np.maximum(np.abs(np.asarray(reference.alpha)), 1.0)
    assert np.max(np.abs(np.asarray(waves.alpha) - np.asarray(reference.alpha)) / scale) < 1e-8


def test_a_complex_curve_short_at_its_start_is_refined(monkeypatch):
    """η = 0.6, V̂ = 0.1, m = 2, four roots with Kelvin–Voigt damping: the checked start (N = 8)
    leaves the roots more than 1e-8 off, so the check continues the curve again on a finer wall,
    whose roots are within 1e-8 of N = 48's."""
    from jaxdea.solve import complex_curves

    walls = []
    continued = complex_curves._curves

    def spy(problem, wall, *args, **kwargs):
        walls.append(int(wall.radii.shape[0]))
        return continued(problem, wall, *args, **kwargs)

    monkeypatch.setattr(complex_curves, "_curves", spy)
    tube = jd.Tube(eta=0.6, voltage=0.1, damping=jd.KelvinVoigt(0.02))
    grid = np.linspace(0.5, 1.5, 20)
    curve = jd.complex_dispersion_curve(tube, grid, n_roots=4, m=2)
    assert len(walls) >= 2 and walls[1] > walls[0], walls
    coarse = jd.complex_dispersion_curve(tube, grid, n_roots=4, m=2,
                                         n_layers=Layers(walls[0], "magnus6", True))
    fine = jd.complex_dispersion_curve(tube, grid, n_roots=4, m=2,
                                       n_layers=Layers(48, "magnus6", True))
    assert np.all(np.asarray(curve.status) == jd.Status.CONVERGED)
    error = np.abs(np.asarray(curve.omega) - np.asarray(fine.omega)) / np.abs(fine.omega)
    assert np.max(error) < 1e-8
    assert np.max(np.abs(np.asarray(coarse.omega) - np.asarray(fine.omega))
                  / np.abs(fine.omega)) > 1e-8  # the start alone was short


@pytest.mark.parametrize("grid, match", [
    ([1.0, 0.5, 2.0], "strictly increasing or strictly decreasing"),
    ([0.5, -1.0], "finite and > 0"),
    ([[0.5, 1.0]], "1-D"),
    ([], "non-empty"),
    ([0.5, np.nan], "finite and > 0"),
])
def test_bad_grids_name_the_parameter(grid, match):
    tube = UNSTRETCHED.replace(damping=jd.KelvinVoigt(0.05))
    with pytest.raises(ValueError, match="omegas must .*" + match):
        jd.wavenumber_curve(tube, grid)
    with pytest.raises(ValueError, match="alphas must .*" + match):
        jd.complex_dispersion_curve(tube, grid)


def test_traced_grids_and_the_paper_coupling_are_refused():
    tube = UNSTRETCHED.replace(damping=jd.KelvinVoigt(0.05))
    with pytest.raises(ValueError, match="omegas must be concrete"):
        jax.jit(lambda g: jd.wavenumber_curve(tube, g).alpha)(jnp.linspace(0.5, 1.0, 3))
    with pytest.raises(ValueError, match="coupling"):
        jd.complex_dispersion_curve(tube, [0.5, 1.0], jd.Fluid(coupling="paper"))


def test_continued_curves_are_the_searched_roots_on_random_damped_tubes():
    """A campaign: three random stretched, biased, damped tubes (Kelvin–Voigt, hysteretic, Prony;
    m = 0, 1, 2), each continued along 40 α̂ on its checked default discretisation (second-order
    predictor, early-stopped corrector): every point converged, and at the middle and last α̂ each
    root is one of an independent certified search's (jaxdea.complex_frequencies), to 1e-8."""
    rng = np.random.default_rng(7)
    laws = [jd.KelvinVoigt(0.03), jd.Hysteretic(0.05), jd.Prony((0.8,), (0.5,))]
    for m, law in enumerate(laws):
        tube = jd.Tube(eta=float(rng.uniform(0.4, 0.9)), lambda_i=float(rng.uniform(0.9, 1.2)),
                       lambda_z=float(rng.uniform(1.0, 1.3)), voltage=float(rng.uniform(0.0, 0.05)),
                       damping=law)
        grid = np.linspace(0.3, 2.5, 40)
        curve = jd.complex_dispersion_curve(tube, grid, n_roots=3, m=m)
        assert np.all(np.asarray(curve.status) == jd.Status.CONVERGED), (m, law)
        for k in (20, 39):
            found = jd.complex_frequencies(tube, float(grid[k]), n_roots=3, m=m)
            assert int(found.certificate) == jd.SearchStatus.CERTIFIED
            for z in np.asarray(curve.omega[k]):
                assert np.min(np.abs(np.asarray(found.omega) - z)) < 1e-8 * abs(z), (m, law, k, z)



START = 0.75 + 1e-12  # a start 1e-12 from the root x = p = 0.75 of F(x; p) = x − p


@jax.custom_jvp
def _poisoned_p(x, p):
    """p, whose derivative along p is NaN at x = START alone (as where F rounds to 0 there)."""
    return p


@_poisoned_p.defjvp
def _poisoned_p_jvp(primals, tangents):
    x, p = primals
    return p, jnp.where((x == START) & (tangents[1] != 0), jnp.nan, tangents[1])


def _pieces_of_a_line(point):
    """The contract's pieces of F(x; p) = x − p (a 2×1 basis, one identity exponential, the outer
    row (F, 0)); its p-derivative is NaN at x = START."""
    x, p = point[0], point[1]
    basis = jnp.asarray([[1.0], [0.0]], point.dtype)
    return basis, jnp.eye(2, dtype=point.dtype)[None], jnp.stack([x - _poisoned_p(x, p),
                                                                   0.0 * x])[None, :]


def test_first_point_tangent_is_taken_off_the_root_where_it_is_not_finite():
    """A corrector that converges in one step from START, whose tangent dx/dp is not finite there,
    returns a NaN tangent; the first point's polish (``off_root``) takes it by one more evaluation
    OFFSET off the root, x unchanged: dx/dp = 1 for F = x − p."""
    from jaxdea.solve import complex_curves

    start = jnp.asarray(START + 0.0j)
    x, tangent, converged, _ = complex_curves._corrector(_pieces_of_a_line, start, 0.75,
                                                         off_root=jnp.asarray(True))
    assert bool(converged) and abs(complex(x) - 0.75) < 1e-15
    assert abs(complex(tangent) - 1.0) < 1e-9
    x_plain, tangent, converged, _ = complex_curves._corrector(_pieces_of_a_line, start, 0.75)
    assert bool(converged) and complex(x_plain) == complex(x)
    assert not np.isfinite(complex(tangent))
