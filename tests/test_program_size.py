"""What keeps the first call's programs small gives the values of the longer forms they replace."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxdea as jd
from jaxdea.numerics import bessel
from jaxdea.physics.families import Family
from jaxdea.physics.problem import NO_ALPHA, describe
from jaxdea.physics.transfer import discretize, laminate
from jaxdea.solve import curves, roots

TUBE = jd.Tube(lambda_z=1.2, eta=0.85, gent=97.2, length_ratio=10.0, lambda_i=0.9, voltage=0.1)


@pytest.mark.parametrize("order", [0, 1, 5])
def test_triple_is_the_two_pairs(order):
    """F_ν, F_{ν+1}, F_{ν+2} in one pass (the pair's slope) equal the pairs at ν and ν + 1: bit for
    bit where both orders take the same quadrature, to rounding where ν + 1 takes another."""
    s = np.concatenate([-np.geomspace(1e-3, 1.5e5, 60), np.geomspace(1e-3, 1.5e5, 60)])
    s = s[np.sqrt(np.abs(s)) + order + 2 < bessel.RANGE]
    nu = jnp.full(s.shape, float(order))
    triple = jax.vmap(bessel._scaled_triple)(s, nu)
    low = jax.vmap(bessel._scaled_pair)(s, nu)
    high = jax.vmap(bessel._scaled_pair)(s, nu + 1.0)
    same = np.all([np.asarray(a == b) for a, b in zip(bessel._rules(s, nu), bessel._rules(s, nu + 1.0),
                                                      strict=True)], axis=0)
    assert same.any()
    for got, want in zip(triple, (low[0], low[1], high[1]), strict=True):
        got, want = np.asarray(got), np.asarray(want)
        np.testing.assert_array_equal(got[same], want[same])
        np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-14)  # near zeros of F: absolute
    np.testing.assert_array_equal(np.asarray(triple[0]), np.asarray(low[0]))  # the pair's own
    np.testing.assert_array_equal(np.asarray(triple[1]), np.asarray(low[1]))  # values, always


@pytest.mark.parametrize("order", [0.0, 2.0, 7.0])
def test_nested_rules_are_the_trapezoidal_rules(order):
    """Bessel's integral of J_ν by the one loop of nested rules (:func:`bessel._positive`, every
    element at its own level) equals the trapezoidal rule of TIERS[level] points summed directly
    (NumPy, math.fsum), each level, to rounding of the sum of the integrand's magnitudes."""
    import math

    x = np.array([3.0, 17.5, 40.0, 95.0, 180.0, 300.0])
    levels = np.arange(len(bessel.TIERS))
    s, level = (np.repeat(x**2, levels.size), np.tile(levels, x.size))
    nu = jnp.full(s.shape, order)
    got = jax.jit(lambda s, level: bessel._positive(s, nu, level, 3))(jnp.asarray(s), jnp.asarray(level))
    for k, (sk, lk) in enumerate(zip(s, level, strict=True)):
        half = bessel.TIERS[lk] // 2
        t = np.pi * np.arange(half + 1) / half
        w = np.full(half + 1, 1.0 / half)
        w[[0, -1]] *= 0.5
        xk = math.sqrt(sk)
        for j, mu in enumerate(order + np.arange(3)):
            terms = w * np.cos(mu * t - xk * np.sin(t))
            want = math.fsum(terms)
            direct = bessel._normalised([jnp.float64(want)] * 3, jnp.float64(xk), jnp.float64(order), 3)
            scale = float(np.sum(np.abs(terms)))
            ratio = float(direct[j]) / want if want != 0 else 0.0
            assert abs(float(got[j][k]) - float(direct[j])) <= 1e-14 * scale * abs(ratio) + 1e-300


def test_pair_slope_is_the_recurrence():
    """d/ds of the pair, first and second order, from the triple: dF_ν/ds = −F_{ν+1}/(4(ν+1))."""
    order, s = 1.0, jnp.array([-9000.0, -30.0, 0.5, 40.0, 2000.0])
    f = lambda s: bessel._scaled_pair(s, order)  # noqa: E731
    slope = jax.vmap(lambda s: jax.jvp(f, (s,), (1.0,))[1])(s)
    second = jax.vmap(jax.jacfwd(jax.jacfwd(f)))(s)
    vals = jax.vmap(lambda s: bessel._scaled_triple(s, order))(s)
    after = jax.vmap(lambda s: bessel._scaled_triple(s, order + 1.0))(s)[2]
    g1 = jax.vmap(jax.grad(bessel.coupling_log_factor))(s)
    want = (g1 * vals[0] - vals[1] / (4 * (order + 1)), g1 * vals[1] - vals[2] / (4 * (order + 2)))
    for got, w in zip(slope, want, strict=True):
        np.testing.assert_allclose(got, w, rtol=1e-14)
    # second derivative of F_ν (s > 0, g = 0): F_{ν+2}/(16(ν+1)(ν+2))
    pos = np.asarray(s) > 0
    np.testing.assert_allclose(np.asarray(second[0])[pos],
                               np.asarray(vals[2] / (16 * (order + 1) * (order + 2)))[pos],
                               rtol=1e-13)
    np.testing.assert_allclose(np.asarray(second[1])[pos],
                               np.asarray(after / (16 * (order + 2) * (order + 3)))[pos],
                               rtol=1e-13)


@pytest.mark.parametrize("fluid", [None, jd.Fluid(density_ratio=0.13, speed_ratio=0.27)])
def test_scan_takes_its_reference_from_its_first_point(fluid):
    """The scan's ℓ₀ from its first point (x = 0) gives the roots of the scan of g with ℓ₀ from
    an evaluation of its own (the former program)."""
    alpha = 0.445
    layers = laminate(None, None, TUBE, alpha, 4, 0)

    def both():
        wall = discretize(TUBE, layers)
        scaled = roots.scanned_function(wall, alpha, fluid, 0)
        reference = roots.Scaled.reference(scaled.scaled(jnp.zeros(()))[1])
        shared = roots.scan_roots(wall, scaled, alpha, fluid, None, 4)
        own = roots.scan_roots(wall, scaled.at(reference), alpha, fluid, None, 4)
        return shared, own

    shared, own = jax.jit(both)()
    np.testing.assert_array_equal(shared.status, own.status)
    assert np.all(shared.status == jd.Status.CONVERGED)
    np.testing.assert_allclose(shared.omega, own.omega, rtol=1e-14)


def test_collect_has_no_scatter():
    """The scan puts its candidates into the lanes' slots by gathering (XLA:CPU turns a scatter
    into a loop over the chunk: 16 of them, slower to compile and to run)."""
    layers = laminate(None, None, TUBE, 0.445, 3, 0)
    text = jax.jit(lambda t, a: roots.frequencies_unchecked(t, a, None, None, 3, layers, 0)).lower(
        TUBE, 0.445).as_text()
    signatures = [line for line in text.splitlines() if line.lstrip().startswith("}) : (")]
    assert not [line for line in signatures if f"tensor<{roots.CHUNK}x1xi32>" in line]


@pytest.mark.parametrize("case", ["acoustic", "m2_omega", "m2_omega_squared", "torsional"])
def test_scanned_slope_is_forward_mode(case):
    """The scan's (f, ℓ) and their carried slopes (f' = D det(B Q)[B Z] − f tr(QᵀZ), ℓ' = tr(QᵀZ),
    no derivative of Gram–Schmidt) equal characteristic_and_scale(_of_w) ("adaptive") and its
    forward-mode derivative in x: Ω, or w = Ω² itself for "omega_squared"."""
    from jaxdea.numerics.scalar import value_and_slope
    from jaxdea.physics.dispersion import characteristic_and_scale, characteristic_and_scale_of_w

    alpha, fluid, m, family, variable = 0.445, None, 0.0, Family.LONGITUDINAL, "omega"
    x = jnp.linspace(0.0, 6.0, 25)
    if case == "acoustic":
        fluid = jd.Fluid(density_ratio=0.13, speed_ratio=0.27)
    elif case == "torsional":
        family = Family.TORSIONAL
    else:
        m, family, fluid = 2.0, Family.ORDER_M, jd.Fluid(density_ratio=0.13, speed_ratio=0.27)
        if case == "m2_omega_squared":
            variable, x = "omega_squared", jnp.linspace(-4.0, 30.0, 25)
    wall = discretize(TUBE, laminate(None, None, TUBE, alpha, 3, m))
    if family == "longitudinal":
        def old(y):
            return characteristic_and_scale(wall, y, alpha, fluid, 0, "adaptive")
    else:
        def old(y):
            w = y if variable == "omega_squared" else y * y
            return characteristic_and_scale_of_w(wall, w, alpha, fluid, 0, "adaptive", m, family)
    new = roots.scanned_function(wall, alpha, fluid, 0, m, family, variable).scaled
    (f, log_scale), (df, dlog) = jax.jit(jax.vmap(lambda y: value_and_slope(new, y)))(x)
    (f_ref, log_ref), (df_ref, dlog_ref) = jax.jit(jax.vmap(lambda y: value_and_slope(old, y)))(x)
    scale = float(jnp.max(jnp.abs(f_ref)))
    np.testing.assert_allclose(f, f_ref, rtol=0, atol=1e-13 * scale)
    np.testing.assert_allclose(log_scale, log_ref, rtol=1e-13, atol=1e-12)
    slope = float(jnp.max(jnp.abs(df_ref)))
    np.testing.assert_allclose(df, df_ref, rtol=1e-11, atol=1e-12 * slope)
    np.testing.assert_allclose(dlog, dlog_ref, rtol=1e-11, atol=1e-12 * float(jnp.max(jnp.abs(dlog_ref))))


@pytest.mark.parametrize("m, family", [(0.0, Family.LONGITUDINAL), (2.0, Family.ORDER_M)])
def test_critical_slope_is_forward_mode(m, family):
    """g(V̂) = f(Ω = 0; V̂) of the critical-voltage search with its carried slope equals
    characteristic_at_rest on the wall at V̂ and its forward-mode derivative in V̂."""
    from jaxdea.numerics.scalar import value_and_slope
    from jaxdea.physics.dispersion import characteristic_at_rest
    from jaxdea.physics.transfer import (
        voltage_expansion,
        voltage_exponentials,
        voltage_generators,
        wall_at_voltage,
    )

    alpha, layers = 0.445, laminate(None, None, TUBE, 0.445, 3, m)
    v = jnp.linspace(0.0, 0.3, 7)

    def both(v):
        _, g, v_end = roots.critical_function(TUBE, alpha, None, layers, 0, None, m, family)
        expansion = voltage_expansion(TUBE.replace(voltage=0.0), layers)
        generators = voltage_generators(expansion, alpha, m, family, v_end)

        def old(u):
            return characteristic_at_rest(wall_at_voltage(expansion, u),
                                          voltage_exponentials(generators, u), alpha, None, 0, m,
                                          family)

        return value_and_slope(g, v), value_and_slope(old, v)

    (f, df), (f_ref, df_ref) = jax.jit(jax.vmap(both))(v)
    np.testing.assert_allclose(f, f_ref, rtol=0, atol=1e-13 * float(jnp.max(jnp.abs(f_ref))))
    np.testing.assert_allclose(df, df_ref, rtol=1e-11, atol=1e-12 * float(jnp.max(jnp.abs(df_ref))))


def _equations(jaxpr) -> int:
    """Equations of a jaxpr, those of every nested jaxpr (scan and loop bodies, branches, inner
    jits) included: the size of what JAX traces and XLA compiles."""
    from jax.extend.core import jaxprs_in_params

    return sum(1 + sum(_equations(sub) for sub in jaxprs_in_params(eq.params)) for eq in jaxpr.eqns)


FLUID = jd.Fluid()
ALPHA = 0.445
CURVE = jnp.linspace(0.2, 1.2, 200)
BUDGETS = {  # public program: (call of one traced leaf x, x, equations allowed = 1.1 × today's)
    "characteristic": (lambda v: jd.characteristic(TUBE.replace(voltage=v), 1.3, ALPHA), 0.1, 1992),
    "frequencies": (lambda v: jd.frequencies(TUBE.replace(voltage=v), ALPHA), 0.1, 5850),
    "frequencies_acoustic": (lambda v: jd.frequencies(TUBE.replace(voltage=v), ALPHA, FLUID), 0.1, 7667),
    "frequencies_m2": (lambda v: jd.frequencies(TUBE.replace(voltage=v), ALPHA, m=2), 0.1, 6307),
    "frequency": (lambda v: jd.frequency(TUBE.replace(voltage=v), ALPHA, 0.77), 0.1, 4063),
    "group_velocity": (lambda v: jd.group_velocity(TUBE.replace(voltage=v), ALPHA, 0.77), 0.1, 3012),
    "critical_voltage": (lambda e: jd.critical_voltage(TUBE.replace(eta=e), ALPHA), 0.85, 4673),
    "growth_rates_m2": (lambda v: jd.growth_rates(TUBE.replace(voltage=v), ALPHA, m=2), 0.1, 6265),
    "dispersion_curve": (lambda v: jd.dispersion_curve(TUBE.replace(voltage=v), CURVE, n_roots=4), 0.1,
                         12168),
    "mode_shape": (lambda v: jd.mode_shape(TUBE.replace(voltage=v), ALPHA, 0.77), 0.1, 5048),
    "first_instability": (lambda e: jd.first_instability(TUBE.replace(eta=e), n_max=3, m_max=8).voltage,
                          0.85, 11469),
    # a concrete call's program: the roots and the default's check on the wall of N/2 (6614 today)
    "frequencies_checked": (lambda v: _checked(TUBE.replace(voltage=v), ALPHA), 0.1, 7275),
    # a concrete default curve's program: the curve and its check at 9 points (12 726 today)
    "dispersion_curve_checked": (lambda v: _checked_curve(TUBE.replace(voltage=v)), 0.1, 13999),
}


def _checked(tube, alpha):
    layers = laminate(None, None, TUBE, ALPHA, 3)
    order = describe(TUBE, ALPHA, None, None, None).order
    _, alpha, fluid, omega_max = roots.canonical(TUBE, alpha, None, None)
    return roots.checked_frequencies_unchecked(tube, alpha, fluid, omega_max, 3, layers, order)


def _checked_curve(tube):
    layers = laminate(None, None, TUBE, CURVE, 4, checked=True)
    order = describe(TUBE, NO_ALPHA, None, None, None).order
    return curves.checked_curve_unchecked(tube, CURVE, None, 4, layers, order)


# 9-15 s to trace each
SLOW = {"frequencies_acoustic", "dispersion_curve", "dispersion_curve_checked", "first_instability"}


@pytest.mark.parametrize("name", [pytest.param(n, marks=pytest.mark.slow) if n in SLOW else n
                                  for n in BUDGETS])
def test_public_program_within_its_size_budget(name):
    """Each public program traced (not compiled) stays within 1.1× its size when the budget was set:
    a change that makes a first call slower by growing the program fails here, and one that shrinks
    it lowers the budget in the same commit."""
    call, x, budget = BUDGETS[name]
    size = _equations(jax.make_jaxpr(call)(x).jaxpr)
    assert size <= budget, f"{name}: {size} equations, budget {budget}"
    assert size > budget / 1.1 * 0.5, f"{name}: {size} equations: lower the budget ({budget})"


COMPLEX_BUDGETS = {  # the complex searches' and curves' programs: equations allowed = 1.1 × today's
    "continuation": 3571,  # 3246 today; 9348 with the first point's polish and tangent apart
    "newton": 2844,  # 2585 today; 3922 with the convergence test's evaluation after the loop
}


@pytest.mark.parametrize("name", list(COMPLEX_BUDGETS))
def test_complex_program_within_its_size_budget(name):
    """The complex programs behind `complex_dispersion_curve`/`wavenumber_curve` (the continuation,
    `complex_curves._curves`) and `complex_frequencies`/`wavenumbers` (the Newton batch,
    `wavenumbers._newton`), traced on a concrete wall with the starts as the traced leaf: each holds
    one copy of the complex evaluation, and a second one (a polish, a tangent or a test outside the
    loop) fails the budget."""
    from jaxdea.physics.characteristic import Unknown
    from jaxdea.physics.transfer import Layers, discretized
    from jaxdea.solve import complex_curves, wavenumbers

    tube = jd.Tube(voltage=0.0, lambda_i=1.0, lambda_z=1.0, eta=0.85, damping=jd.KelvinVoigt(0.05))
    problem = describe(tube, 0.15, None, None, None, 0, False, damped=True)
    wall = discretized(tube, n_layers=Layers(6, "magnus6", True))
    starts = jnp.asarray([1.0 + 0.05j, 2.0 + 0.1j, 3.0 + 0.2j, 4.0 + 0.3j])
    m = jnp.asarray(0.0)
    if name == "continuation":
        grid = jnp.linspace(0.15, 3.0, 200)
        call = lambda s: complex_curves._curves(problem, wall, None, m, grid, s,  # noqa: E731
                                                Unknown.OMEGA)
    else:
        region = (jnp.asarray(0j), jnp.asarray(10.0 + 10.0j), jnp.asarray(np.inf))
        known = jnp.full(wavenumbers.KNOWN, np.nan + 0j)
        call = lambda s: wavenumbers._newton(problem, wall, jnp.asarray(ALPHA), None, m, s,  # noqa: E731
                                             region, known, jnp.asarray(4, jnp.int32), Unknown.OMEGA)
    budget = COMPLEX_BUDGETS[name]
    size = _equations(jax.make_jaxpr(call)(starts).jaxpr)
    assert size <= budget, f"{name}: {size} equations, budget {budget}"
    assert size > budget / 1.1 * 0.5, f"{name}: {size} equations: lower the budget ({budget})"
