"""Layered walls (API.md "Layered walls", docs/theory/real_tubes.md §3, §7): identical layers equal
the single wall, one active layer alone equals the single wall under voltage, the layered base
state against closed forms, the long-wave limits of layers of different stiffness and density,
per-layer damping, gradients in layer parameters and the errors of bad layers."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxdea as jd
from jaxdea.physics import base_state as bs

GENT = jd.Gent(97.2)
IDENTICAL = (jd.Layer(0.3, GENT), jd.Layer(0.4, GENT, active=True), jd.Layer(0.3, GENT))
SANDWICH = (jd.Layer(0.2, jd.NeoHookean(), shear_ratio=3.0, density_ratio=1.2),
            jd.Layer(0.6, GENT, active=True),
            jd.Layer(0.2, jd.NeoHookean(), shear_ratio=3.0, density_ratio=0.8))
"""The layered wall of docs/theory/real_tubes.md §7(d)."""


@pytest.mark.parametrize("m, exact", [(0, [0.76809635, 1.97691521]), (2, [0.28907297, 1.94597245])])
def test_identical_layers_are_the_single_wall(m, exact):
    """§7(b): three identical Gent layers (middle active, V̂ = 0, λ_i = 0.9, λ_z = 1.2, α̂ = 0.445)
    give the published roots and the single wall's, to 1e-9."""
    tube = jd.Tube(voltage=0.0, lambda_i=0.9, lambda_z=1.2, eta=0.85, layers=IDENTICAL)
    got = np.asarray(jd.frequencies(tube, 0.445, n_roots=2, m=m))
    single = np.asarray(jd.frequencies(tube.replace(layers=None), 0.445, n_roots=2, m=m))
    np.testing.assert_allclose(got, exact, rtol=1e-8)
    np.testing.assert_allclose(got, single, rtol=1e-9)


@pytest.mark.parametrize("m, torsional, fluid", [(0, False, jd.Fluid()), (1, False, None),
                                                 (0, True, None)])
def test_one_active_layer_is_the_single_wall_under_voltage(m, torsional, fluid):
    """A wall of one active layer, Gent, at V̂ = 0.1 and a stretch, is the single wall (its base
    state by quadrature through the layer, the field of the active layer; the same 48 equal
    sixth-order sublayers), to 1e-9."""
    tube = jd.Tube(voltage=0.1, lambda_i=1.1, lambda_z=1.2, eta=0.75,
                   layers=(jd.Layer(1.0, GENT, active=True),))
    kw = dict(n_roots=3, m=m, torsional=torsional, n_layers=48, scheme="magnus6")  # equal sublayers
    got = np.asarray(jd.frequencies(tube, 0.7, fluid, **kw))
    single = np.asarray(jd.frequencies(tube.replace(layers=None), 0.7, fluid, **kw))
    np.testing.assert_allclose(got, single, rtol=1e-9)


def test_layered_pressure_has_the_field_of_the_active_layer_only():
    """Identical Gent layers at V̂ = 0.2: ΔP̂ = the single wall's elastic integral (closed form)
    − V̂²(1/r̂_a² − 1/r̂_b²)/(2 ln²(r̂_b/r̂_a)) over the active layer [r̂_a, r̂_b], to 1e-12; the
    radial stress is continuous at the interfaces while p̂ is not where μ_k jumps."""
    tube = jd.Tube(voltage=0.2, lambda_i=1.1, lambda_z=1.2, eta=0.75, layers=IDENTICAL)
    edges = np.asarray(bs.interface_radii(tube))
    elastic = float(bs.pressure_difference_unchecked(tube.replace(layers=None, voltage=0.0)))
    a, b = edges[1], edges[2]
    electric = 0.2**2 * (1 / a**2 - 1 / b**2) / (2 * np.log(b / a) ** 2)
    np.testing.assert_allclose(float(jax.jit(bs.layered_pressure_difference)(tube)),
                               elastic - electric, rtol=1e-12)
    soft = tube.replace(layers=SANDWICH)
    edges = bs.interface_radii(soft)
    for k in (0, 1):  # τ_rr = μλ_rW_r + d² − p on both sides of interface k + 1
        r = edges[k + 1]
        sides = []
        for layer in (k, k + 1):
            state = bs.layered_base_state(soft, layer, jnp.asarray([r]))
            radial = bs._layer_parts(soft, layer, jnp.asarray([r]))[1]
            sides.append(float((radial + state.displacement**2 - state.pressure)[0]))
        np.testing.assert_allclose(sides[0], sides[1], rtol=1e-12, atol=1e-13)


def _long_wave(tube, m, alphas, power):
    """Ω²/α̂^power at small α̂, extrapolated to α̂ → 0 linearly in α̂² (two points)."""
    values = [float(jd.frequencies(tube, a, n_roots=1, m=m)[0]) ** 2 / a**power for a in alphas]
    (a1, a2), (v1, v2) = alphas, values
    return v1 + (v2 - v1) * a1**2 / (a1**2 - a2**2)


def test_long_wave_bar_of_layers_of_different_stiffness_and_density():
    """§7(d): m = 0, empty, λ = 1: (Ω/α̂)² → Σ3μ_kA_k/Σρ_kA_k = 5.42816779 (the layers of
    §7(d): liner and encapsulation 3× stiffer, densities 1.2 and 0.8), to 1e-6."""
    tube = jd.Tube(voltage=0.0, lambda_i=1.0, lambda_z=1.0, eta=0.85, layers=SANDWICH)
    np.testing.assert_allclose(_long_wave(tube, 0, (0.01, 0.02), 2), 5.42816779, rtol=1e-6)


def test_long_wave_bending_of_a_layered_wall():
    """§7(d): m = 1, empty: Ω²/α̂⁴ → E I/(ρA) = 3.24431634 (E I = Σ3μ_kπ(r_{k+1}⁴ − r_k⁴)/4), to 2e-5
    (bending at α̂ ≤ 0.04 is ill-conditioned, pitfall 6)."""
    tube = jd.Tube(voltage=0.0, lambda_i=1.0, lambda_z=1.0, eta=0.85, layers=SANDWICH)
    np.testing.assert_allclose(_long_wave(tube, 1, (0.02, 0.04), 4), 3.24431634, rtol=2e-5)


def test_per_layer_damping_of_identical_layers_is_the_damped_wall():
    """Three identical layers each with KV η_v = 0.1 (at rest) give the single damped wall's
    complex frequencies, and the §7(c) values, to 1e-9."""
    kv = jd.KelvinVoigt(0.1)
    layers = tuple(jd.Layer(f, GENT, active=k == 1, damping=kv) for k, f in enumerate((0.3, 0.4, 0.3)))
    tube = jd.Tube(voltage=0.0, lambda_i=1.0, lambda_z=1.0, eta=0.85, layers=layers)
    got = np.asarray(jd.complex_frequencies(tube, 1.0, n_roots=2, omega_max=2.5).omega)
    np.testing.assert_allclose(got, [1.34893014 + 0.09139831j, 2.34343182 + 0.27846065j], rtol=3e-9)


def test_gradient_in_a_layer_parameter():
    """dΩ/dμ_liner through the implicit derivative of jd.frequencies equals a central
    difference."""
    def lowest(mu):
        layers = (jd.Layer(0.2, jd.NeoHookean(), shear_ratio=mu), jd.Layer(0.8, GENT, active=True))
        tube = jd.Tube(voltage=0.05, lambda_i=1.05, lambda_z=1.1, eta=0.8, layers=layers)
        return jd.frequencies(tube, 0.6, n_roots=1, n_layers=12, scheme="magnus6")[0]

    grad = float(jax.grad(lowest)(2.0))
    h = 1e-5
    fd = (float(lowest(2.0 + h)) - float(lowest(2.0 - h))) / (2 * h)
    np.testing.assert_allclose(grad, fd, rtol=1e-6)
    assert abs(grad) > 1e-3


@pytest.mark.parametrize("layers, message", [
    ((jd.Layer(0.5, GENT, active=True), jd.Layer(0.4, GENT)), "the fractions must sum to 1, got 0.9"),
    ((jd.Layer(0.5, GENT), jd.Layer(0.5, GENT)), "exactly one layer must be active"),
    ((jd.Layer(0.5, GENT, active=True), jd.Layer(0.5, GENT, active=True)),
     "exactly one layer must be active"),
    ((jd.Layer(1.0, GENT, active=True, shear_ratio=2.0),), r"layers\[0\].shear_ratio must be 1"),
    ((jd.Layer(0.5, GENT, active=True), jd.Layer(0.5, GENT, density_ratio=0.0)),
     r"layers\[1\].density_ratio must be a finite number > 0"),
    ((jd.Layer(1.0, "gent", active=True),), r"layers\[0\].material must be a material object"),
    ((jd.Layer(1.0, jd.Ogden((1.0,), (1.0,)), active=True),), "not normalised"),
    ([jd.Layer(1.0, GENT, active=True)], "must be None or a non-empty tuple"),
])
def test_bad_layers_are_named(layers, message):
    tube = jd.Tube(voltage=0.0, lambda_i=1.0, lambda_z=1.0, layers=layers)
    with pytest.raises(ValueError, match=message):
        jd.frequencies(tube, 0.5)


def test_traced_bad_fractions_give_nan_and_invalid():
    """Under jit, fractions that do not sum to 1 give NaN and INVALID, never a rescaled wall."""
    def lowest(f):
        layers = (jd.Layer(f, GENT, active=True), jd.Layer(0.5, GENT))
        tube = jd.Tube(voltage=0.0, lambda_i=1.0, lambda_z=1.0, layers=layers)
        res = jd.solve_frequencies(tube, 0.5, n_roots=1, n_layers=8, scheme="magnus6")
        return res.omega[0], res.status[0]

    omega, status = jax.jit(lowest)(0.7)
    assert np.isnan(float(omega)) and int(status) == jd.Status.INVALID
    omega, status = jax.jit(lowest)(0.5)
    assert np.isfinite(float(omega)) and int(status) == jd.Status.CONVERGED


def _ring_stiffness(fractions, moduli, eps):
    """(D, R): the plane-strain bending stiffness per unit length D = Σ_k 4μ_k ∫ (y − y_n)² dy of a
    thin layered ring (E'_k = 4μ_k incompressible; y from the inner face, wall thickness eps) about
    its neutral surface y_n = Σ μ_k ∫ y dy / Σ μ_k h_k, and the neutral radius R = 1 + y_n."""
    y = eps * np.concatenate([[0.0], np.cumsum(fractions)])
    stiff = sum(mu * (y[k + 1] - y[k]) for k, mu in enumerate(moduli))
    yn = sum(mu * (y[k + 1] ** 2 - y[k] ** 2) / 2 for k, mu in enumerate(moduli)) / stiff
    d = sum(4 * mu * ((y[k + 1] - yn) ** 3 - (y[k] - yn) ** 3) / 3 for k, mu in enumerate(moduli))
    return d, 1.0 + yn


def _buckling_pressure(tube, m, alpha=1e-3):
    """−ΔP̂ at the λ_i < 1 where Ω² = 0 first becomes a root of order m (the stretch-held tube under
    net external pressure, λ_z = 1, V̂ = 0): a sign change of f(Ω² = 0) in λ_i refined by brentq,
    ΔP̂ the layered wall's (base_state.layered_pressure_difference)."""
    from scipy.optimize import brentq

    from jaxdea.physics import dispersion as dp

    def f(li):
        return float(dp.characteristic_at_omega_squared(tube.replace(lambda_i=li), 0.0, alpha, m=m))

    eps = 1.0 / tube.eta - 1.0
    grid = 1.0 - np.geomspace(1e-2, 30.0, 30) * eps**2  # strains around (h/R)²
    vals = [f(x) for x in grid]
    k = next(k for k in range(len(grid) - 1) if vals[k] * vals[k + 1] < 0)
    li = brentq(f, grid[k + 1], grid[k], xtol=1e-15, rtol=1e-15)
    return -float(bs.layered_pressure_difference(tube.replace(lambda_i=li)))


@pytest.mark.parametrize("walls", [
    ((0.4, 0.6), (3.0, 1.0), (1.5, 1.0)),
    ((0.6, 0.4), (1.0, 3.0), (1.0, 1.5)),
    ((0.2, 0.6, 0.2), (3.0, 1.0, 0.5), (1.2, 1.0, 0.8)),
], ids=["passive-inside", "active-inside", "sandwich"])
def test_thin_ring_buckling_of_a_layered_wall(walls):
    """Thin-wall limit: a long (α̂ = 1e-3), unstretched, layered ring under net external pressure
    buckles in order m = 2, 3 at the hydrostatic-pressure ring load p_cr = (m² − 1)D/R³ (Lévy; D
    the composite plane-strain bending stiffness about the neutral surface, R its radius). The
    error is O(h/R): within 3e-3 at h/R = 0.005, and the linear extrapolation from h/R = 0.01 and
    0.005 within 1e-4."""
    fractions, moduli, densities = walls
    active = moduli.index(1.0)
    layers = tuple(jd.Layer(f, jd.NeoHookean(), shear_ratio=mu, density_ratio=rho, active=k == active)
                   for k, (f, mu, rho) in enumerate(zip(fractions, moduli, densities, strict=True)))
    for m in (2, 3):
        ratios = []
        for eps in (0.01, 0.005):
            tube = jd.Tube(voltage=0.0, lambda_i=1.0, lambda_z=1.0, eta=1.0 / (1.0 + eps), layers=layers)
            d, radius = _ring_stiffness(fractions, moduli, eps)
            ratios.append(_buckling_pressure(tube, m) * radius**3 / ((m * m - 1) * d))
        assert abs(ratios[1] - 1.0) < 3e-3
        assert abs(2.0 * ratios[1] - ratios[0] - 1.0) < 1e-4
