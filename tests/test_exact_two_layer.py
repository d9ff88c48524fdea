"""Layered walls against an exact two-layer cylinder (issue 44): the independent NumPy/SciPy solver
tests/exact_two_layer.py (potentials in each layer, continuity of u and of the tractions at the
interface) reduces to the single layer's exact roots for equal layers, and jaxdea's unstretched
two-layer tubes (V̂ = 0, λ_i = λ_z = 1, neo-Hookean layers: the linear moduli μ_k = shear_ratio) meet
its roots, orders m = 0, 1, 2 and the torsional family, passive layer inside or outside.

Geometry: unstretched, r̂_i = λ_i = 1 and r̂_o = 1/η (jaxdea.physics.base_state.geometry), and the
interface at r̂ = 1 + f₁(1/η − 1), f₁ the inner layer's fraction of the wall thickness (reference
and deformed configurations coincide)."""

import exact_cylinder
import exact_cylinder_m as ecm
import exact_two_layer as e2
import numpy as np
import pytest

import jaxdea as jd
from jaxdea.physics import base_state as bs

ETA = 0.75
A, B = 1.0, 1.0 / ETA
PASSIVE = dict(shear_ratio=3.0, density_ratio=1.5)
ALPHAS = (0.534, 2.0)
N_ROOTS = 4
RTOL = 1e-8  # the accuracy the default discretisation promises (measured: ≤ 5e-11)


def _tube(passive_inside):
    """Two neo-Hookean layers, the passive one (3× stiffer, 1.5× denser) 0.4 of the wall, inside or
    outside; with the exact solver's (c, μ₁, ρ₁, μ₂, ρ₂)."""
    passive = jd.Layer(0.4, jd.NeoHookean(), **PASSIVE)
    active = jd.Layer(0.6, jd.NeoHookean(), active=True)
    layers = (passive, active) if passive_inside else (active, passive)
    inner = 0.4 if passive_inside else 0.6
    c = A + inner * (B - A)
    mats = (3.0, 1.5, 1.0, 1.0) if passive_inside else (1.0, 1.0, 3.0, 1.5)
    tube = jd.Tube(voltage=0.0, lambda_i=1.0, lambda_z=1.0, eta=ETA, layers=layers)
    return tube, (c, *mats)


@pytest.mark.parametrize("m", [0, 1, 2])
def test_equal_layers_are_the_single_layer(m):
    """The exact two-layer solver with μ₁ = μ₂, ρ₁ = ρ₂ (any interface) has the single layer's
    roots (exact_cylinder_m.roots_m; m = 0: exact_cylinder.roots and torsion_roots): unit layers
    at α̂ = 0.534, and μ = 3, ρ = 1.5 in both layers (the roots times √(μ/ρ) = √2) at α̂ = 2, to
    1e-11."""
    for alpha, c, mat, scale in ((0.534, 1.1, (1.0, 1.0), 1.0), (2.0, 1.25, (3.0, 1.5), np.sqrt(2.0))):
        if m == 0:
            single = exact_cylinder.roots(alpha, A, B, 4, 20.0, 2000)
        else:
            single = ecm.roots_m(m, alpha, A, B, n_roots=4, omega_max=20.0)
        assert np.all(np.isfinite(single))
        got = e2.roots_two_layer(m, alpha, A, B, c, *mat, *mat, n_roots=4, omega_max=20.0 * scale)
        np.testing.assert_allclose(got / scale, single, rtol=1e-11, atol=0.0)
        if m == 0:
            tor = ecm.torsion_roots(alpha, A, B, n_roots=3, omega_max=20.0)
            got = e2.torsion_roots_two_layer(alpha, A, B, c, *mat, *mat, n_roots=3,
                                             omega_max=20.0 * scale)
            assert np.all(np.isfinite(tor))
            np.testing.assert_allclose(got / scale, tor, rtol=1e-13, atol=0.0)


@pytest.mark.parametrize("passive_inside", [True, False], ids=["passive-inside", "active-inside"])
def test_interface_radius(passive_inside):
    """Unstretched: the interface lies at R = 1 + f₁(1/η − 1) and the faces at 1 and 1/η."""
    tube, (c, *_) = _tube(passive_inside)
    np.testing.assert_allclose(np.asarray(bs.interface_radii(tube)), [A, c, B], rtol=1e-14)


@pytest.mark.parametrize("m", [0, 1, 2])
@pytest.mark.parametrize("passive_inside", [True, False], ids=["passive-inside", "active-inside"])
def test_two_layers_meet_the_exact_cylinder(passive_inside, m):
    """The lowest four roots of order m (m = 0: longitudinal) at α̂ = 0.534 and 2 at the default
    discretisation, to 1e-8 (a root missed or spurious in either would shift the rest)."""
    tube, params = _tube(passive_inside)
    for alpha in ALPHAS:
        got = np.asarray(jd.frequencies(tube, alpha, n_roots=N_ROOTS, m=m))
        exact = e2.roots_two_layer(m, alpha, A, B, *params, n_roots=N_ROOTS,
                                   omega_max=1.2 * got[-1])
        np.testing.assert_allclose(got, exact, rtol=RTOL, atol=0.0)


@pytest.mark.parametrize("passive_inside", [True, False], ids=["passive-inside", "active-inside"])
def test_torsional_two_layers_meet_the_exact_cylinder(passive_inside):
    """Torsional family (m = 0, u_θ only): the lowest three roots, as above."""
    tube, params = _tube(passive_inside)
    for alpha in ALPHAS:
        got = np.asarray(jd.frequencies(tube, alpha, n_roots=3, m=0, torsional=True))
        exact = e2.torsion_roots_two_layer(alpha, A, B, *params, n_roots=3,
                                           omega_max=1.2 * got[-1])
        np.testing.assert_allclose(got, exact, rtol=RTOL, atol=0.0)
