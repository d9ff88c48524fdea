"""Pipeline stages against closed forms and independent computations."""

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from conftest import fd_derivative
from scipy import integrate, special

import jaxdea as jd
from jaxdea.numerics import bessel
from jaxdea.numerics.bessel import RANGE, _switch, coupling_log_factor, coupling_pair
from jaxdea.physics import base_state as bs
from jaxdea.physics import transfer
from jaxdea.physics.dispersion import characteristic_and_scale, reference_determinant
from jaxdea.physics.moduli import closed_form_coefficients, coefficients, push_forward_moduli
from jaxdea.physics.state_matrix import state_matrix
from jaxdea.physics.transfer import discretize, layer_exponentials

PAPER = dict(lambda_z=1.2, eta=0.85)


@pytest.mark.parametrize(
    "lam, lam_z, d, gent",
    [(1.0, 1.0, 0.0, jnp.inf), (0.9, 1.2, 0.3, 97.2), (1.3, 0.8, 1.1, 5.0), (1.6, 1.5, 0.7, 2.2)],
)
def test_autodiff_moduli_equal_closed_forms(lam, lam_z, d, gent):
    """A0, Γ0, K0 by autodiff of the energy give theory.md §2's components and §3's a…q."""
    lam_r = 1.0 / (lam * lam_z)
    mod = push_forward_moduli(jnp.asarray(lam_r), jnp.asarray(lam), jnp.asarray(lam_z),
                              jnp.asarray(d), jnp.asarray(gent))
    i1 = lam_r**2 + lam**2 + lam_z**2
    w1 = 0.5 / (1.0 - (i1 - 3.0) / gent)
    w11 = 2.0 * w1**2 / gent
    np.testing.assert_allclose(mod.A[0, 0, 0, 0], 2 * w1 * lam_r**2 + 4 * w11 * lam_r**4 + d * d,
                               rtol=1e-13)
    np.testing.assert_allclose(mod.A[1, 1, 2, 2], 4 * w11 * lam**2 * lam_z**2, rtol=1e-13,
                               atol=1e-15)
    np.testing.assert_allclose(mod.A[0, 2, 0, 2], 2 * w1 * lam_r**2 + d * d, rtol=1e-13)
    np.testing.assert_allclose(mod.A[0, 2, 2, 0], 0.0, atol=1e-14)
    np.testing.assert_allclose(mod.Gamma[0, 0, 0], 2 * d, atol=1e-14)
    np.testing.assert_allclose(mod.Gamma[2, 0, 2], d, atol=1e-14)
    np.testing.assert_allclose(mod.K, np.eye(3), atol=1e-14)
    auto = coefficients(mod, 0.37)
    closed = closed_form_coefficients(jnp.asarray(lam), lam_z, jnp.asarray(d), 0.37, gent)
    # W(I_1) of a single wall: no separate shear moduli, no layer density or active flag
    assert all(getattr(c, k) is None for c in (auto, closed) for k in ("shear", "density", "active"))
    for name, x, y in zip(auto._fields[:9], auto[:9], closed[:9], strict=True):
        np.testing.assert_allclose(x, y, rtol=1e-12, atol=1e-14, err_msg=name)


def test_linear_elastic_coefficients():
    """λ = λ_z = 1, V = 0, neo-Hookean: a = c = q = 1, b = 1, g = 0, d = 0 (theory.md §3)."""
    one = jnp.asarray(1.0)
    c = coefficients(push_forward_moduli(one, one, one, 0.0 * one, jnp.inf), 1.0)
    np.testing.assert_allclose([c.a, c.b, c.c, c.q, c.g, c.d], [1, 1, 1, 1, 0, 0], atol=1e-14)


def _bessel_reference(order, s):
    """(J_ν, x J_ν') (s > 0) or e^{−x̃}(I_ν, x̃ I_ν') (s < 0) from scipy, x = sqrt(|s|)."""
    x = np.sqrt(abs(s))
    if s > 0:
        return np.array([special.jv(order, x), x * special.jvp(order, x)])
    return np.array([special.ive(order, x),
                     x * 0.5 * (special.ive(order - 1, x) + special.ive(order + 1, x))])


def _tier_edges(order):
    """s just below and above each quadrature's reach (x + ν + 2 = K − 12 K^{1/3}), both signs."""
    x = np.array([bessel._tier_limit(k) for k in bessel.TIERS]) - order - 2.0
    x = np.concatenate([x - 1e-9, x + 1e-9, [90.0 - 1e-9, 90.0 + 1e-9]])
    x = x[(x > 0) & (x + order < RANGE)]
    return np.concatenate([x**2, -(x**2)])


@pytest.mark.parametrize("order", [0, 1, 3, 10, 25, 32, 40])
def test_bessel_pair_matches_scipy(order):
    """(N_ν, D_ν) has the direction of (J_ν, x J_ν') / (I_ν, x I_ν') from scipy on both sides of
    the series/integral switch, at every quadrature's edge and up to the end of the range;
    sin(angle) ≤ 1e-10 (series cancellation ≲ 1e4·eps)."""
    sw = float(_switch(order))
    top = (RANGE - order - 0.5) ** 2
    s_values = np.concatenate([np.linspace(-4000, 4000, 401), sw * np.array([0.99, 1.01]),
                               -sw * np.array([0.99, 1.01]), [1e-6, -1e-6], _tier_edges(order),
                               np.linspace(-top, top, 41)])
    got = jax.jit(jax.vmap(lambda s: coupling_pair(s, order)))(s_values)
    for s, n, d in zip(s_values, *(np.asarray(g) for g in got), strict=True):
        if s == 0:
            continue
        ref = _bessel_reference(order, s)
        ref = ref / np.hypot(*ref)
        got = np.array([n, d]) / np.hypot(n, d)
        assert abs(got[0] * ref[1] - got[1] * ref[0]) < 1e-10, (order, s)
        assert got @ ref > 0  # the same positive factor: no flipped sign


def test_bessel_pair_nan_beyond_its_range():
    """x + ν ≥ RANGE: NaN (the largest quadrature is no longer exact), finite just below."""
    for order in (0, 7):
        x = np.array([RANGE - order - 1e-6, RANGE - order + 1e-6])
        n, d = (np.asarray(v) for v in
                jax.vmap(lambda s, order=order: coupling_pair(s, order))(np.concatenate([x**2, -(x**2)])))
        assert np.all(np.isfinite(n[[0, 2]])) and np.all(np.isfinite(d[[0, 2]]))
        assert np.all(np.isnan(n[[1, 3]])) and np.all(np.isnan(d[[1, 3]]))
    assert np.isnan(coupling_pair(jnp.asarray(RANGE**2 + 1.0), 0)[0])  # a scalar alike


@pytest.mark.parametrize("order", [0, 2])
def test_bessel_pair_derivatives(order):
    """d/ds and d²/ds² of the true values e^{−g}(N_ν, D_ν) (custom JVP: dF_ν/ds = −F_{ν+1}/(4(ν+1)))
    against scipy: N = 2^ν ν! J_ν(x)/x^ν gives dN/ds = −2^ν ν! J_{ν+1}(x)/(2 x^{ν+1}) and
    d²N/ds² = 2^ν ν! J_{ν+2}(x)/(4 x^{ν+2}) (I for s < 0), on the series, the quadratures and the
    e^{−x̃}-scaled branch."""
    c = 2.0**order * math.factorial(order)

    def true_pair(s):
        n, d = coupling_pair(s, order)
        return jnp.stack([n, d]) * jnp.exp(-coupling_log_factor(s))

    for s in (-9000.0, -300.0, -70.0, -30.0, 5.0, 70.0, 2000.0, 60000.0):
        x = math.sqrt(abs(s))
        if s > 0:
            slope_n = -c * special.jv(order + 1, x) / (2 * x ** (order + 1))
            curvature_n = c * special.jv(order + 2, x) / (4 * x ** (order + 2))
        else:
            slope_n = -c * special.iv(order + 1, x) / (2 * x ** (order + 1))
            curvature_n = c * special.iv(order + 2, x) / (4 * x ** (order + 2))
        jac = jax.jacfwd(true_pair)(s)
        np.testing.assert_allclose(jac[0], slope_n, rtol=1e-11, err_msg=str(s))
        np.testing.assert_allclose(jax.grad(jax.grad(lambda s: true_pair(s)[0]))(s), curvature_n,
                                   rtol=1e-10, err_msg=str(s))
        # D = ν F_ν − (s/2) F_{ν+1}/(ν+1), F_μ = 2^μ μ! J_μ(x)/x^μ (I_μ for s < 0), F_μ' = −F_{μ+1}/(4(μ+1))
        bessel_fn = special.jv if s > 0 else special.iv
        f = [2.0**mu * math.factorial(mu) * bessel_fn(mu, x) / x**mu for mu in (order, order + 1,
                                                                                order + 2)]
        slope_d = (-order * f[1] / (4 * (order + 1)) - f[1] / (2 * (order + 1))
                   + s * f[2] / (8 * (order + 1) * (order + 2)))
        np.testing.assert_allclose(jac[1], slope_d, rtol=1e-10, err_msg=str(s))


def test_bessel_pair_does_not_depend_on_its_batch():
    """Each element takes its own quadrature: an element's bits are the same whatever the other
    elements of its batch need (series only, or up to the largest rule), also one vmap level up."""
    fn = jax.jit(jax.vmap(lambda s: coupling_pair(s, 1)))
    probe = np.array([30.0, 900.0, -200.0])
    neighbours = ([1.0, 2.0, 3.0], [-9000.0, 1e5, 4.0e3], [150.0**2, -50.0, 60.0])
    runs = [np.asarray(fn(np.concatenate([probe, n]))) [:, :3] for n in neighbours]
    assert np.all(np.isfinite(runs[0]))
    for other in runs[1:]:
        np.testing.assert_array_equal(other, runs[0])
    nested = jax.jit(jax.vmap(jax.vmap(lambda s: coupling_pair(s, 1))))(
        np.stack([np.concatenate([probe, n]) for n in neighbours]))
    for row in np.asarray(nested).transpose(1, 0, 2):
        np.testing.assert_allclose(row[:, :3], runs[0], rtol=1e-15, atol=0)


def test_bessel_pair_entire_through_zero():
    """D_0 = −s/2 + O(s²) and N_0 = 1 at s = 0 (the χ̂² = 0 limit of theory.md §4(c))."""
    n, d = coupling_pair(jnp.asarray(0.0), 0)
    assert float(n) == 1.0 and float(d) == 0.0
    np.testing.assert_allclose(jax.grad(lambda s: coupling_pair(s, 0)[1])(0.0), -0.5, rtol=1e-14)
    n1, d1 = coupling_pair(jnp.asarray(0.0), 2)
    np.testing.assert_allclose(float(n1) / float(d1), 0.5, rtol=1e-14)  # B_ν → r̂_i/ν


def test_pressure_difference_independent_quadrature():
    """ΔP̂ of Eq. (1.1) against scipy.integrate.quad of the same integrand (Gent, V ≠ 0)."""
    tube = jd.Tube(voltage=0.2, lambda_i=0.9, **PAPER)
    ri, ro, lz, g = 0.9, float(bs.geometry(tube).r_outer), 1.2, 97.2

    def integrand(r):
        lam = r / np.sqrt(lz * (r * r - ri * ri) + 1.0)
        lam_r = 1.0 / (lam * lz)
        w1 = 0.5 / (1.0 - (lam_r**2 + lam**2 + lz**2 - 3.0) / g)
        d = 0.2 / (r * np.log(ro / ri))
        return (2 * w1 * (lam**2 - lam_r**2) - d * d) / r

    ref, _ = integrate.quad(integrand, ri, ro, epsabs=1e-14, epsrel=1e-13)
    np.testing.assert_allclose(jd.pressure_difference(tube), ref, rtol=1e-12)


def _thin_wall_decimal(li, lz, eta, v):
    """(ĥ, ΔP̂) of a neo-Hookean wall in 50-digit decimal arithmetic: ĥ = r̂_o − r̂_i, ΔP̂ with the
    elastic integral by the midpoint rule (relative error O(ĥ²)) and the electric part in closed
    form, V̂²(1/r̂_i² − 1/r̂_o²)/(2 ln²(r̂_o/r̂_i)) (theory.md Eq. 1.1)."""
    from decimal import Decimal, localcontext

    with localcontext() as ctx:
        ctx.prec = 50
        li, lz, eta, v = (Decimal(float(x)) for x in (li, lz, eta, v))
        ro = (li * li + (1 / (eta * eta) - 1) / lz).sqrt()
        h = ro - li
        rm = li + h / 2
        lam2 = rm * rm / (lz * (rm * rm - li * li) + 1)
        elastic = h * (lam2 - 1 / (lam2 * lz * lz)) / rm
        electric = v * v * (1 / (li * li) - 1 / (ro * ro)) / (2 * (ro / li).ln() ** 2)
        return float(h), float(elastic - electric)


@pytest.mark.parametrize("eta", [1 - 1e-6, 1 - 1e-9, 1 - 1e-12])
def test_thin_wall_geometry_and_pressure_keep_every_digit(eta):
    """η → 1: ĥ and ΔP̂ against 50-digit decimal arithmetic. ĥ = c/(r̂_o + r̂_i) and
    ln(r̂_o/r̂_i) = log1p(ĥ/r̂_i) keep every digit, where r̂_o − r̂_i and ln(r̂_o/r̂_i) lose
    log10(r̂_o/ĥ) of them (1e-7 relative at ĥ ≈ 1e-9: the ΔP̂ of this test was off by 2e-7)."""
    li, lz = 1.2, 1.1
    for v in (0.0, 1e-3):
        tube = jd.Tube(voltage=v, lambda_i=li, lambda_z=lz, eta=eta, gent=jnp.inf)
        h, dp = _thin_wall_decimal(li, lz, eta, v)
        np.testing.assert_allclose(jd.thickness_ratio(tube), h, rtol=1e-14)
        np.testing.assert_allclose(jd.pressure_difference(tube), dp, rtol=1e-11)


def test_homogeneous_state_has_no_pressure():
    """λ_i = λ_z^{-1/2}, V = 0: uniaxial tension, ΔP̂ = 0 (theory.md §1, erratum E16)."""
    tube = jd.Tube(lambda_i=1.2**-0.5, **PAPER)
    assert abs(float(jd.pressure_difference(tube))) < 1e-15


def test_base_state_equilibrium_and_boundary_values():
    """τ_rr = 2W_1λ_r² + D² − p satisfies dτ_rr/dr + (τ_rr − τ_θθ)/r = 0, τ_rr(r_i) = −ΔP̂ and
    τ_rr(r_o) = 0 (gauge P_o = 0)."""
    tube = jd.Tube(voltage=0.25, lambda_i=1.1, **PAPER)
    geo = bs.geometry(tube)
    r = jnp.linspace(geo.r_inner, geo.r_outer, 41)

    def stresses(r):
        st = bs.base_state(tube, r)
        lam_r = 1.0 / (st.stretch * 1.2)
        i1 = lam_r**2 + st.stretch**2 + 1.44
        w1 = 0.5 / (1.0 - (i1 - 3.0) / 97.2)
        return (2 * w1 * lam_r**2 + st.displacement**2 - st.pressure,
                2 * w1 * st.stretch**2 - st.pressure)

    tau_rr, tau_tt = jax.jit(stresses)(r)
    dtau = jax.jit(jax.vmap(jax.grad(lambda x: stresses(x[None])[0][0])))(r)
    np.testing.assert_allclose(dtau + (tau_rr - tau_tt) / r, 0.0, atol=1e-12)
    np.testing.assert_allclose(tau_rr[0], -jd.pressure_difference(tube), rtol=1e-13)
    np.testing.assert_allclose(tau_rr[-1], 0.0, atol=1e-13)


def test_inner_stretch_inverts_pressure_difference():
    """λ_i(ΔP̂, λ_z, V̂) reproduces ΔP̂; its implicit derivative matches central differences."""
    tube = jd.Tube(voltage=0.05, **PAPER)
    li, status = jd.inner_stretch(tube, 0.01)
    assert int(status) == 0
    np.testing.assert_allclose(jd.pressure_difference(tube.replace(lambda_i=li)), 0.01, atol=1e-14)
    li0, _ = jd.inner_stretch(tube.replace(voltage=0.0), 0.0)
    np.testing.assert_allclose(li0, 1.2**-0.5, rtol=1e-13)
    grad = jax.grad(lambda v: jd.inner_stretch(tube.replace(voltage=v), 0.01)[0])(0.05)
    fd = fd_derivative(lambda v: jd.inner_stretch(tube.replace(voltage=v), 0.01)[0], 0.05)
    np.testing.assert_allclose(grad, fd, rtol=1e-6)


def test_neo_hookean_pressure_closed_form():
    """λ_z = 1, neo-Hookean, V = 0: ΔP̂ = ln(λ_i/λ_o) + 1/(2λ_o²) − 1/(2λ_i²) (Eq. 1.1 integrated
    with dr/r = dλ/(λ − λ³))."""
    for li in (0.7, 1.0, 1.5, 3.0):
        tube = jd.Tube(lambda_i=li, lambda_z=1.0, eta=0.85, gent=jnp.inf)
        lo = float(bs.geometry(tube).r_outer) * 0.85
        exact = np.log(li / lo) + 0.5 / lo**2 - 0.5 / li**2
        np.testing.assert_allclose(jd.pressure_difference(tube), exact, rtol=1e-13, atol=1e-15)


@pytest.mark.slow
def test_static_response_without_pull_in():
    """At fixed λ_z the ideal-dielectric neo-Hookean tube has no pull-in at ΔP̂ = 0: V̂²(λ_i) rises
    monotonically to ln(1/η)/E(∞) with E(∞) = 2λ_z/(η⁻² − 1) (both limits in closed form), so
    pull_in reports NO_ROOT, and the critical-voltage search ends at that supremum."""
    tube = jd.Tube(gent=jnp.inf, lambda_z=1.0, eta=0.85)
    li, v, status = jd.pull_in(tube, 0.0)
    assert int(status) == int(jd.Status.NO_ROOT) and np.isnan(float(v))
    grid = jnp.asarray(np.geomspace(0.5, 20.0, 200))
    v2 = np.asarray(jax.jit(jax.vmap(lambda x: bs.squared_voltage(tube, x, 0.0)))(grid))
    assert np.all(np.diff(v2) > 0)
    sup = np.log(1 / 0.85) * (0.85**-2 - 1.0) / 2.0
    assert v2[-1] < sup and abs(v2[-1] / sup - 1) < 0.01
    np.testing.assert_allclose(float(bs.voltage_limit(tube.replace(lambda_i=1.0))) ** 2,
                               v2[-1], rtol=1e-12)


def test_taylor_exponential_matches_expm():
    """The branch-free exponential equals jax.scipy.linalg.expm on real sublayer matrices,
    from a thin wall at low Ω to α̂ = 60 (‖hM‖ ≈ 10³)."""
    for tube, omega, alpha in [(jd.Tube(), 0.5, 0.445), (jd.Tube(voltage=0.2, lambda_i=1.1,
                               **PAPER), 18.0, 2.0), (jd.Tube(eta=0.3), 30.0, 60.0)]:
        exps = jax.jit(lambda t, o, a, m: layer_exponentials(discretize(t, 30), o, a, m),
                       static_argnums=3)
        a, b = exps(tube, omega, alpha, "taylor"), exps(tube, omega, alpha, "expm")
        scale = jnp.max(jnp.abs(b), axis=(1, 2), keepdims=True)
        np.testing.assert_allclose(a / scale, b / scale, atol=1e-12)
        # the solvers' adaptive squaring count: the same bits, values and Ω-slopes
        np.testing.assert_array_equal(exps(tube, omega, alpha, "adaptive"), a)
        slope = jax.jit(lambda t, o, a, m: jax.jvp(
            lambda x: layer_exponentials(discretize(t, 30), x, a, m), (o,), (1.0,))[1],
            static_argnums=3)
        np.testing.assert_array_equal(slope(tube, omega, alpha, "adaptive"),
                                      slope(tube, omega, alpha, "taylor"))


def test_squaring_counts_quoted_in_the_docstring():
    """expm_taylor_adaptive's docstring: over the benchmark batch (N = 30, Ω ∈ [0.05, 20], mode
    n = 2) ‖(ĥ/N) M‖∞ has median ≈ 0.55 and max ≈ 2.2, so 39 % of the sublayers need no squaring
    and none more than 3; on the N = 10 laminate of the curve (Ω ≤ 36) up to 7."""
    def squarings(tube, n_layers, omegas, alpha):
        wall = discretize(tube, n_layers)
        mats = jax.vmap(lambda o: jax.vmap(state_matrix, (0, 0, None, None))(
            wall.coef, wall.radii, o, alpha))(omegas)
        norm = np.asarray(jnp.max(jnp.sum(jnp.abs(wall.step * mats), axis=-1), axis=-1))
        chosen = jax.jit(jax.vmap(jax.vmap(lambda a: transfer._scaled_taylor(a)[1])))
        count = chosen(wall.step * mats)
        return norm, np.asarray(count)  # the squarings the exponential itself chooses

    tube = jd.Tube(voltage=0.1, lambda_i=0.9, lambda_z=1.2)
    norm, s = squarings(tube, 30, jnp.linspace(0.05, 20.0, 2048), jd.axial_wavenumber(tube, 2))
    assert 0.5 < np.median(norm) < 0.6 and 2.1 < norm.max() < 2.3
    assert s.max() == 3 and 0.37 < np.mean(s == 0) < 0.41
    _, s = squarings(jd.Tube(), 10, jnp.linspace(0.0, 36.0, 512), 2.5)
    assert s.max() == 7


def test_taylor_exponential_derivatives_and_layouts():
    """expm_taylor: values with only the squarings needed equal the fixed masked graph bit for bit;
    its derivatives (forward, reverse, second order) equal those of jax.scipy.linalg.expm; the value
    layout (exponential inside the scan) and the solvers' layout (all exponentials first) give the
    same characteristic function to rounding."""
    rng = np.random.default_rng(3)
    for norm in (0.05, 0.3, 2.0, 40.0):  # 0 to 7 squarings
        a = jnp.asarray(rng.standard_normal((6, 6)))
        a = a * norm / jnp.max(jnp.sum(jnp.abs(a), axis=1))
        np.testing.assert_array_equal(jax.jit(transfer.expm_taylor)(a), jax.jit(transfer._expm_fixed)(a))
        w = jnp.asarray(rng.standard_normal((6, 6)))

        def loss(x, expm, w=w):
            return jnp.sum(w * expm(x))

        g = jax.grad(loss)(a, transfer.expm_taylor)
        g_ref = jax.grad(loss)(a, jax.scipy.linalg.expm)
        scale = float(jnp.max(jnp.abs(g_ref)))
        np.testing.assert_allclose(g / scale, g_ref / scale, atol=1e-12)
        h = jax.jvp(lambda x: jax.grad(loss)(x, transfer.expm_taylor), (a,), (w,))[1]
        h_ref = jax.jvp(lambda x: jax.grad(loss)(x, jax.scipy.linalg.expm), (a,), (w,))[1]
        scale = float(jnp.max(jnp.abs(h_ref)))
        np.testing.assert_allclose(h / scale, h_ref / scale, atol=1e-11)
    tube = jd.Tube(voltage=0.1, lambda_i=0.9, **PAPER)
    wall = discretize(tube, 30)
    omegas = jnp.linspace(0.05, 20.0, 64)
    ref = jax.jit(jax.vmap(lambda o: characteristic_and_scale(wall, o, 0.7, None, 0,
                                                              "taylor")))(omegas)
    for method in ("adaptive", "expm"):
        got = jax.jit(jax.vmap(lambda o, m=method: characteristic_and_scale(wall, o, 0.7, None, 0,
                                                                             m)))(omegas)
        # the same exponentials bit for bit, fused differently by XLA: equal to rounding; the plain
        # expm per sublayer is the reference every faster path must match to 1e-12
        tol = 4 * np.finfo(float).eps if method == "adaptive" else 1e-12
        np.testing.assert_allclose(got[0], ref[0], rtol=0, atol=tol)


@pytest.mark.parametrize("fluid", [None, jd.Fluid(), jd.Fluid(coupling="paper", bessel_order=1)])
def test_stable_characteristic_equals_reference_determinant(fluid):
    """det(B A S) from the plain 6×6 expm product equals f·exp(log_scale) of the re-orthonormalised
    propagation (same zeros and sign), where the product is well conditioned."""
    tube = jd.Tube(voltage=0.15, lambda_i=0.95, **PAPER)
    wall = discretize(tube, 30)
    for omega in (0.3, 1.234, 7.0):
        f, log_scale = characteristic_and_scale(wall, omega, 0.89, fluid, 1)
        ref = reference_determinant(wall, omega, 0.89, fluid, 1)
        np.testing.assert_allclose(f * jnp.exp(log_scale), ref, rtol=1e-9)
        assert abs(float(f)) <= 1.0


@pytest.mark.parametrize("case", ["coupled", "at_rest_voltage", "acoustic", "paper", "midpoint",
                                  "thick", "order_m", "torsional"])
def test_value_and_slope_on_wall_equals_forward_mode(case):
    """value_and_slope_on_wall (the continuation's lanes) gives the value of characteristic_on_wall
    ("adaptive", to rounding; the expm reference to 1e-12) and its forward-mode slope, through the
    coupled 6×6 (8×8, 2×2) propagation or, without voltage, the decoupled 4×4 one."""
    from jaxdea.numerics.scalar import value_and_slope
    from jaxdea.physics.dispersion import characteristic_on_wall, electric_decoupled, value_and_slope_on_wall
    from jaxdea.physics.state_matrix import LONGITUDINAL, ORDER_M, TORSIONAL

    tube, fluid, order, layers, m, family = jd.Tube(voltage=0.15, lambda_i=0.95, **PAPER), None, 0, \
        transfer.Layers(16, "magnus6", graded=True), 0.0, LONGITUDINAL
    alpha, omegas = 0.89, jnp.linspace(0.05, 4.0, 23)
    if case == "at_rest_voltage":
        tube = jd.Tube(voltage=0.0, lambda_i=1.2, lambda_z=1.1, eta=0.7, gent=6.0)
    elif case == "acoustic":
        tube, fluid = jd.Tube(voltage=0.0, **PAPER), jd.Fluid()
    elif case == "paper":
        tube, fluid, order = jd.Tube(voltage=0.0, **PAPER), jd.Fluid(coupling="paper", bessel_order=1), 1
    elif case == "midpoint":
        tube, layers = jd.Tube(voltage=0.0, **PAPER), 30
    elif case == "thick":  # α̂ĥ ≈ 30: growth e^{α̂ĥ} across the wall, and its Ω-derivative
        tube, layers, alpha = jd.Tube(voltage=0.0, eta=0.3), transfer.Layers(64, "magnus6", True), 20.0
    elif case == "order_m":
        m, family = 2.0, ORDER_M
    elif case == "torsional":
        family = TORSIONAL
    wall = discretize(tube, layers)
    if family == LONGITUDINAL:
        assert bool(electric_decoupled(wall)) == (case != "coupled")

    def on_wall(x, method):
        return characteristic_on_wall(wall, x, alpha, fluid, order, method, m, family)

    f, df = jax.jit(jax.vmap(lambda o: value_and_slope_on_wall(wall, o, alpha, fluid, order, m,
                                                                 family)))(omegas)
    f_ref, df_ref = jax.jit(jax.vmap(lambda o: value_and_slope(lambda x: on_wall(x, "adaptive"),
                                                               o)))(omegas)
    f_expm = jax.jit(jax.vmap(lambda o: on_wall(o, "expm")))(omegas)
    scale = float(jnp.max(jnp.abs(f_ref)))
    np.testing.assert_allclose(f, f_ref, rtol=0, atol=1e-13 * scale)
    np.testing.assert_allclose(f, f_expm, rtol=0, atol=1e-12 * scale)
    # f' = D det(BQ)[BZ] − f tr(QᵀZ): rounding relative to |f'| and to |f| (the two terms)
    np.testing.assert_allclose(df, df_ref, rtol=1e-11, atol=1e-13 * scale)


@pytest.mark.parametrize("voltage", [0.0, 0.05])
@pytest.mark.parametrize("wall_kind", ["gent", "mooney_rivlin", "layered", "damped"])
def test_electric_decoupled_reads_the_node_matrices_from_the_coefficients(wall_kind, voltage):
    """electric_decoupled (D̂_r = 0 at every node) agrees with the test of the node matrices
    themselves: every entry of their (U, W, T, S)–(Φ, D) blocks exactly 0, at several α̂ (0 too),
    for the closed-form 6×6 matrix and the general 8×8 one (a Mooney–Rivlin wall, a layered wall
    with passive layers, a damped wall), with and without voltage."""
    from jaxdea.physics.dispersion import ELECTRIC, MECHANICAL, electric_decoupled
    from jaxdea.physics.transfer import node_matrices

    tube = jd.Tube(voltage=voltage, **PAPER)
    if wall_kind == "mooney_rivlin":
        tube = tube.replace(material=jd.MooneyRivlin(0.3))
    elif wall_kind == "layered":
        tube = tube.replace(layers=(jd.Layer(0.2, jd.NeoHookean(), shear_ratio=3.0),
                                    jd.Layer(0.6, jd.Gent(97.2), active=True),
                                    jd.Layer(0.2, jd.MooneyRivlin(0.2), shear_ratio=0.5)))
    elif wall_kind == "damped":
        tube = tube.replace(damping=jd.KelvinVoigt(viscosity=0.05))
    wall = discretize(tube, transfer.Layers(8, "magnus6", graded=True))
    for alpha in (0.0, 0.89, 5.0):
        nodes = node_matrices(wall, alpha)
        blocks = (jnp.all(nodes[..., MECHANICAL[:, None], ELECTRIC] == 0)
                  & jnp.all(nodes[..., ELECTRIC[:, None], MECHANICAL] == 0))
        assert bool(electric_decoupled(wall)) == bool(blocks) == (voltage == 0.0)


def _scanned_case(case):
    """(wall, fluid, order, α̂) of the scan's and the lanes' propagation tests: the paper's tube at
    V̂ = 0 (graded magnus6, N = 16, α̂ = 0.89) unless ``case`` changes it."""
    tube, fluid, order, layers, alpha = jd.Tube(voltage=0.0, **PAPER), None, 0, \
        transfer.Layers(16, "magnus6", graded=True), 0.89
    if case == "at_rest_voltage":
        tube = jd.Tube(voltage=0.0, lambda_i=1.2, lambda_z=1.1, eta=0.7, gent=6.0)
    elif case == "acoustic":
        fluid = jd.Fluid()
    elif case == "paper":
        fluid, order = jd.Fluid(coupling="paper", bessel_order=1), 1
    elif case == "thick":
        tube, layers, alpha = jd.Tube(voltage=0.0, eta=0.3), transfer.Layers(64, "magnus6", True), 20.0
    elif case == "coupled":
        tube = jd.Tube(voltage=0.15, lambda_i=0.95, **PAPER)
    elif case == "layered":  # a stiff liner and a soft encapsulation around the Gent DE layer
        tube = tube.replace(layers=(jd.Layer(0.2, jd.NeoHookean(), shear_ratio=3.0, density_ratio=1.2),
                                    jd.Layer(0.5, jd.Gent(97.2), active=True),
                                    jd.Layer(0.3, jd.MooneyRivlin(0.2), shear_ratio=0.5)))
        return transfer.discretized(tube, n_layers=layers), fluid, order, alpha  # compiled: 1 s
    return discretize(tube, layers), fluid, order, alpha


@pytest.mark.parametrize("case", ["at_rest_voltage", "acoustic", "thick"])
def test_lane_generators_give_the_walls_values(case):
    """The curves' lanes take the generators as polynomials in α̂ and the electric block's column
    once per α̂ (lane_generators, electric_column): (f, f') and the scan's (f, ℓ) with its slopes
    equal those formed from the wall at every evaluation, to rounding."""
    from jaxdea.numerics.scalar import value_and_slope
    from jaxdea.physics.dispersion import (
        generator_polynomials,
        lane_generators,
        scale_and_slope_on_wall,
        value_and_slope_on_wall,
    )

    wall, fluid, _, alpha = _scanned_case(case)
    omegas = jnp.linspace(0.05, 6.0, 25)
    generators = lane_generators(generator_polynomials(wall, decoupled=True), alpha)
    assert set(generators) == {"mechanical", "electric", "electric_column"}
    lanes = [jax.jit(jax.vmap(lambda o, g=g: value_and_slope_on_wall(wall, o, alpha, fluid, 0,
                                                                       decoupled=True, generators=g)))(omegas)
             for g in (None, generators)]
    scans = [jax.jit(jax.vmap(lambda o, g=g: value_and_slope(
        scale_and_slope_on_wall(wall, alpha, fluid, 0, True, g), o)))(omegas) for g in (None, generators)]
    scale = float(jnp.max(jnp.abs(lanes[0][0])))
    for got, ref in ((lanes[1][0], lanes[0][0]), (scans[1][0][0], scans[0][0][0])):
        np.testing.assert_allclose(got, ref, rtol=0, atol=1e-13 * scale)
    for got, ref in ((lanes[1][1], lanes[0][1]), (scans[1][1][0], scans[0][1][0])):
        np.testing.assert_allclose(got, ref, rtol=1e-11, atol=1e-13 * scale)
    np.testing.assert_allclose(scans[1][0][1], scans[0][0][1], rtol=1e-13, atol=1e-12)  # ℓ


@pytest.mark.parametrize("case", ["at_rest_voltage", "acoustic", "paper", "thick", "coupled"])
def test_scale_and_slope_on_wall_equals_forward_mode(case):
    """The scan's (f, ℓ) with the carried slope (scale_and_slope_on_wall, ℓ' = tr(QᵀZ)) equals
    characteristic_and_scale ("adaptive") and its forward-mode slope; decoupled=True on a wall that
    does not decouple gives NaN, never a wrong value."""
    from jaxdea.numerics.scalar import value_and_slope
    from jaxdea.physics.dispersion import scale_and_slope_on_wall

    wall, fluid, order, alpha = _scanned_case(case)
    omegas = jnp.linspace(0.0, 6.0, 25)
    ref = jax.jit(jax.vmap(lambda o: value_and_slope(
        lambda x: characteristic_and_scale(wall, x, alpha, fluid, order, "adaptive"), o)))(omegas)
    for decoupled in (True, False):
        got = jax.jit(jax.vmap(lambda o, d=decoupled: value_and_slope(
            scale_and_slope_on_wall(wall, alpha, fluid, order, d), o)))(omegas)
        if decoupled and case == "coupled":
            assert np.all(np.isnan(np.asarray(got[0][0])))
            continue
        (f, log_scale), (df, dlog) = got
        (f_ref, log_ref), (df_ref, dlog_ref) = ref
        scale = float(jnp.max(jnp.abs(f_ref)))
        np.testing.assert_allclose(f, f_ref, rtol=0, atol=1e-13 * scale)
        np.testing.assert_allclose(log_scale, log_ref, rtol=1e-13, atol=1e-12)
        np.testing.assert_allclose(df, df_ref, rtol=1e-11, atol=1e-13 * scale)
        np.testing.assert_allclose(dlog, dlog_ref, rtol=1e-11, atol=1e-12)


@pytest.mark.parametrize("case", ["at_rest_voltage", "acoustic", "paper", "thick", "coupled",
                                  "layered"])
def test_decoupled_value_and_scale_equals_the_full_propagation(case):
    """The check's 4×4 values (f, ℓ) of a wall without voltage (decoupled_characteristic_and_scale,
    the Newton steps of a checked curve) equal the 6×6 characteristic_and_scale ("adaptive"); a
    wall that does not decouple gives NaN, never a wrong value."""
    from jaxdea.physics.dispersion import decoupled_characteristic_and_scale

    wall, fluid, order, alpha = _scanned_case(case)
    omegas = jnp.linspace(0.0, 6.0, 25)
    f_ref, log_ref = jax.jit(jax.vmap(
        lambda o: characteristic_and_scale(wall, o, alpha, fluid, order, "adaptive")))(omegas)
    f, log_scale = jax.jit(jax.vmap(
        lambda o: decoupled_characteristic_and_scale(wall, o, alpha, fluid, order)))(omegas)
    if case == "coupled":
        assert np.all(np.isnan(np.asarray(f))) and np.all(np.isnan(np.asarray(log_scale)))
        return
    scale = float(jnp.max(jnp.abs(f_ref)))
    assert scale > 1e-3  # f (|f| ≤ 1) not vanishingly small on the grid: the test can fail
    np.testing.assert_allclose(f, f_ref, rtol=0, atol=1e-13 * scale)
    np.testing.assert_allclose(log_scale, log_ref, rtol=1e-13, atol=1e-12)


def test_carried_slope_is_forward_mode_on_a_thick_wall():
    """α̂ĥ ≈ 150, whose basis columns grow at rates e^{±α̂ r} apart: the slope carried across the
    wall without differentiating Gram–Schmidt (the scan's and the corrector lanes') equals forward
    mode through the propagation, near the roots too (it lost every digit there before its
    components along earlier columns were removed at each sublayer)."""
    from jaxdea.physics.dispersion import scale_and_slope_on_wall

    tube = jd.Tube(eta=0.3)
    alpha = 150.0 / float(jd.thickness_ratio(tube))
    wall = discretize(tube, 60)
    carried = scale_and_slope_on_wall(wall, alpha, decoupled=False)

    @jax.jit
    def both(om):
        one = jnp.ones_like(om)
        forward = jax.jvp(lambda o: characteristic_and_scale(wall, o, alpha, None, 0, "adaptive"),
                          (om,), (one,))
        return jax.jvp(carried, (om,), (one,)), forward

    for om in (5.0, 20.0, 61.3996, 61.4698, 64.3028):
        ((f, log_scale), (df, dlog)), ((f_ref, log_ref), (df_ref, dlog_ref)) = both(om)
        assert float(f) == pytest.approx(float(f_ref), rel=1e-12, abs=1e-14)
        assert float(log_scale) == pytest.approx(float(log_ref), rel=1e-13)
        assert float(df) == pytest.approx(float(df_ref), rel=1e-8, abs=1e-12 * abs(float(df_ref)))
        assert float(dlog) == pytest.approx(float(dlog_ref), rel=1e-10)


def test_characteristic_stays_finite_for_thick_walls():
    """α̂ĥ ≈ 150: the raw 6×6 product grows like e^{α̂ĥ} (its 3×3 determinant is ~1e190, the
    difference of far larger products: noise), while the scaled function stays in [−1, 1]; the
    lowest root found is a genuine sign change."""
    tube = jd.Tube(eta=0.3)
    alpha = 150.0 / float(jd.thickness_ratio(tube))
    wall = discretize(tube, 60)
    f, log_scale = jax.jit(characteristic_and_scale)(wall, 20.0, alpha)
    assert np.isfinite(float(f)) and abs(float(f)) <= 1 and float(log_scale) > 100
    assert abs(float(jax.jit(reference_determinant)(wall, 20.0, alpha))) > 1e100
    roots = jd.solve_frequencies(tube, alpha, n_roots=3, n_layers=60)
    assert np.all(np.asarray(roots.status) == 0)
    om = float(roots.omega[0])
    f = jax.jit(jax.vmap(lambda o: characteristic_and_scale(wall, o, alpha)[0]))
    lo, hi = f(jnp.asarray([om * (1 - 1e-9), om * (1 + 1e-9)]))
    assert float(lo) * float(hi) < 0


def test_state_matrix_linear_elastic_rows():
    """λ = 1, V = 0: M reduces to the classical incompressible equations (theory.md §3 check):
    β1 = 4, β3 = 2, β5 = 4, δ1 = δ3 = 1 with p = 1."""
    one = jnp.asarray(1.0)
    c = coefficients(push_forward_moduli(one, one, one, 0.0 * one, jnp.inf), 1.0)
    m = state_matrix(c, 1.3, 0.7, 0.4)
    np.testing.assert_allclose(m[3, 0], 4 / 1.3**2 - 0.49, rtol=1e-14)
    np.testing.assert_allclose(m[4, 0], 0.4 * 2 / 1.3, rtol=1e-14)
    np.testing.assert_allclose(m[4, 1], 0.16 * 4 - 0.49, rtol=1e-14)
    np.testing.assert_allclose([m[1, 0], m[1, 4]], [0.4, 1.0], rtol=1e-14)


def test_thickness_ratio_round_trip_and_gradient():
    tube = jd.Tube(lambda_i=1.1, **PAPER)
    t2 = jd.with_thickness_ratio(tube, 0.3)
    np.testing.assert_allclose(jd.thickness_ratio(t2), 0.3, rtol=1e-14)
    g = jax.grad(lambda h: jd.thickness_ratio(jd.with_thickness_ratio(tube, h)))(0.3)
    np.testing.assert_allclose(g, 1.0, rtol=1e-13)


def test_axial_wavenumber():
    tube = jd.Tube(lambda_z=1.2, eta=0.85, length_ratio=10.0)
    np.testing.assert_allclose(jd.axial_wavenumber(tube, 3), 6 * np.pi * 0.85 / 12.0, rtol=1e-15)
    # concrete inputs (validated, then the formula alone) and traced ones (with the admissibility
    # mask, inside a jit): the same bits, for arrays that broadcast too
    many = tube.replace(eta=np.array([0.8, 0.85]), lambda_z=1.3)
    for t, n in ((tube, np.arange(1, 21)), (many, np.array([1.0, 2.5]))):
        traced = jax.jit(jd.axial_wavenumber)(t, n)
        np.testing.assert_array_equal(jd.axial_wavenumber(t, n), traced)


def test_mode_shape_satisfies_boundary_conditions():
    """Φ = 0 on both faces, follower-pressure tractions at r̂_i, zero tractions at r̂_o, and the
    fields agree with the plain transfer-matrix propagation."""
    tube = jd.Tube(voltage=0.2, lambda_i=0.9, **PAPER)
    alpha = jd.axial_wavenumber(tube, 1)
    omega = jd.frequencies(tube, alpha)[1]
    r, y = jd.mode_shape(tube, alpha, omega, n_points=31)
    p = jd.pressure_difference(tube)
    u, w, phi, t, s, _ = y[:, 0]
    np.testing.assert_allclose([phi, t + p / r[0] * u + alpha * p * w, s + alpha * p * u],
                               0.0, atol=1e-10)
    np.testing.assert_allclose(y[2:5, -1], 0.0, atol=1e-8)
    assert np.isclose(float(jnp.max(jnp.abs(y[:2]))), 1.0)
    from jaxdea.physics.transfer import laminate, transfer_matrix
    wall = discretize(tube, laminate(None, None, tube, alpha))  # the default discretisation
    a = transfer_matrix(wall, omega, alpha)
    np.testing.assert_allclose(a @ y[:, 0], y[:, -1], atol=1e-8)


def test_wall_coefficients_tensor_route_equals_closed_route():
    """The default closed forms (W_1, W_11 by autodiff) and the full tensor push-forward of the
    autodiff Hessian give the same sublayer coefficients on a Gent wall near its locking limit."""
    from jaxdea.physics.transfer import layer_coefficients

    tube = jd.Tube(voltage=0.3, lambda_i=1.6, lambda_z=1.5, eta=0.7, gent=6.0)
    r = jnp.linspace(1.6, float(bs.geometry(tube).r_outer), 7)
    closed = jax.jit(lambda t: layer_coefficients(t, r, "closed"))(tube)
    tensor = jax.jit(lambda t: layer_coefficients(t, r, "tensor"))(tube)
    for name, x, y in zip(closed._fields, closed, tensor, strict=True):
        if x is None or y is None:  # a single wall's layer fields (density, active): unset on both
            assert x is None and y is None, name
            continue
        np.testing.assert_allclose(x, y, rtol=1e-12, atol=1e-14, err_msg=name)


@pytest.mark.parametrize("scheme", ["midpoint", "magnus6"])
def test_wall_is_quadratic_in_the_voltage(scheme):
    """voltage_expansion: W_0 + V̂ W_1 + V̂² W_2 equals the wall discretised at V̂ (every leaf), on a
    Gent wall near locking and at voltages up to 0.6, so the critical-voltage search, which forms
    the wall from the expansion, solves the same f(0; V̂)."""
    tube = jd.Tube(voltage=0.0, lambda_i=1.6, lambda_z=1.5, eta=0.7, gent=6.0)
    layers = transfer.laminate(7, scheme)
    expansion = jax.jit(lambda t: transfer.voltage_expansion(t, layers))(tube)
    for v in (0.05, 0.3, 0.6):
        direct = jax.jit(lambda t: discretize(t, layers))(tube.replace(voltage=v))
        expanded = transfer.wall_at_voltage(expansion, v)
        for x, y in zip(jax.tree_util.tree_leaves(expanded), jax.tree_util.tree_leaves(direct),
                        strict=True):
            scale = float(jnp.max(jnp.abs(y)))
            np.testing.assert_allclose(x, y, rtol=0, atol=1e-13 * scale)
    # the electric terms are there: W_1 (D̂_r) and W_2 (D̂_r², p̂, ΔP̂) are not zero
    assert float(jnp.max(jnp.abs(expansion[1].coef.d))) > 0.1
    assert abs(float(expansion[2].pressure_inner)) > 1e-3


@pytest.mark.parametrize("layers", [transfer.Layers(9, "magnus6", graded=True),
                                    transfer.Layers(7, "magnus4")])
@pytest.mark.parametrize("m", [0, 3])
def test_voltage_generators_equal_the_direct_ones(layers, m):
    """The at-rest generators of a Magnus wall as polynomials in V̂ (voltage_generators) equal those
    formed at each V̂ from the wall (wall_generators, at_rest), on a Gent wall near locking, at
    voltages inside and beyond the radius of the expansion's circle."""
    from jaxdea.physics.state_matrix import LONGITUDINAL, ORDER_M

    tube = jd.Tube(voltage=0.0, lambda_i=1.6, lambda_z=1.5, eta=0.7, gent=6.0)
    family = LONGITUDINAL if m == 0 else ORDER_M
    expansion = jax.jit(lambda t: transfer.voltage_expansion(t, layers))(tube)
    polys = jax.jit(lambda e: transfer.voltage_generators(e, 0.8, float(m), family, 0.5))(expansion)
    for v in (0.0, 0.05, 0.3, 0.6):
        direct = jax.jit(lambda e, v: transfer.wall_generators(
            transfer.wall_at_voltage(e, v), 0.8, float(m), family, True)[:, 0])(expansion, v)
        expanded = transfer.generators_at_voltage(polys, v)
        np.testing.assert_allclose(expanded, direct, rtol=0,
                                   atol=1e-13 * float(jnp.max(jnp.abs(direct))))


@pytest.mark.parametrize("layers", [None, transfer.Layers(7, "magnus4"), 30])
@pytest.mark.parametrize("what", ["longitudinal", "mechanical", "electric", "order_m"])
def test_alpha_generators_equal_the_direct_ones(layers, what):
    """The generators of a fixed wall as polynomials in α̂ (alpha_generators, the lanes of a
    dispersion curve) equal those formed at each α̂ from the wall (wall_generators): G(Ω²) to 1e-14
    of each sublayer's largest entry (7e-16 to 1.1e-15 measured), for every scheme, family and block,
    on the paper's tube and on a thick wall up to α̂ = 30 (its default N = 192, where the terms of
    degree 10 in α̂ are largest)."""
    from jaxdea.physics.dispersion import ELECTRIC, MECHANICAL
    from jaxdea.physics.state_matrix import ORDER_M

    kwargs = {"longitudinal": {}, "mechanical": dict(block=tuple(MECHANICAL)),
              "electric": dict(at_rest=True, block=tuple(ELECTRIC)),
              "order_m": dict(m=3.0, family=ORDER_M)}[what]
    for tube, top in ((jd.Tube(voltage=0.1, lambda_i=0.9, **PAPER), 5.0),
                      (jd.Tube(voltage=0.1, lambda_i=0.9, lambda_z=1.2, eta=0.3, gent=97.2), 30.0)):
        laminate = transfer.laminate(layers, None, tube, top, 3)
        wall = jax.jit(lambda t, laminate=laminate: discretize(t, laminate))(tube)
        polys = jax.jit(lambda w: transfer.alpha_generators(w, **kwargs))(wall)

        @jax.jit
        def error(alpha, omega, wall=wall, polys=polys):
            g, h = (jax.vmap(transfer.generator_of_w, (0, None))(x, omega**2) for x in (
                transfer.wall_generators(wall, alpha, **kwargs),
                transfer.generators_at_alpha(polys, alpha)))
            return jnp.max(jnp.abs(h - g) / jnp.max(jnp.abs(g), axis=(-2, -1), keepdims=True))

        for alpha in (0.01, 0.37 * top, top):
            for omega in (0.0, 0.6 * top, 1.3 * top):
                assert float(error(alpha, omega)) < 1e-14, (tube.eta, alpha, omega)


@pytest.mark.parametrize("m", [0, 2, 8])
def test_critical_voltage_equals_the_direct_search(m):
    """The critical-voltage search with the generators' expansion in V̂ (the Magnus schemes) finds
    the V̂_cr of the same search forming every generator from the wall at each V̂, to 1e-13."""
    from jaxdea.physics.base_state import voltage_limit
    from jaxdea.physics.dispersion import characteristic_of_w, characteristic_on_wall
    from jaxdea.physics.state_matrix import LONGITUDINAL, ORDER_M
    from jaxdea.solve.roots import _first_root, critical_voltage_unchecked

    family = LONGITUDINAL if m == 0 else ORDER_M
    for tube in (jd.Tube(voltage=0.0, lambda_i=0.9, **PAPER),
                 jd.Tube(voltage=0.0, lambda_i=1.6, lambda_z=1.5, eta=0.7, gent=6.0)):
        alpha = jd.axial_wavenumber(tube, 1)
        layers = transfer.laminate(None, None, tube, alpha, m=m, at_rest=True)

        def direct(tube, alpha, layers=layers):
            v_end = voltage_limit(tube)
            expansion = transfer.voltage_expansion(tube, layers)

            def g(v):
                wall = transfer.wall_at_voltage(expansion, v)
                if family == LONGITUDINAL:
                    return characteristic_on_wall(wall, jnp.zeros_like(v), alpha, None, 0, "at_rest")
                return characteristic_of_w(wall, jnp.zeros_like(v), alpha, None, 0, "at_rest",
                                           float(m), family)

            return _first_root(g, v_end / 32, v_end)

        expected = jax.jit(direct)(tube, alpha)
        got = jax.jit(lambda t, a, layers=layers: critical_voltage_unchecked(
            t, a, None, layers, 0, m=float(m), family=family))(tube, alpha)
        assert int(got.status) == int(expected.status) == jd.Status.CONVERGED
        np.testing.assert_allclose(got.omega, expected.omega, rtol=1e-13)


def test_bracketed_root_with_given_end_slopes():
    """bracketed_root with the caller's end slopes gives the root it finds by evaluating them."""
    from jaxdea.numerics.scalar import bracketed_root

    fun = lambda x: jnp.cos(x) - x  # noqa: E731
    lo, hi = 0.2, 1.4
    own = jax.jit(lambda: bracketed_root(fun, lo, hi, fun(lo), fun(hi)))()
    given = jax.jit(lambda: bracketed_root(fun, lo, hi, fun(lo), fun(hi), -jnp.sin(lo) - 1.0,
                                           -jnp.sin(hi) - 1.0))()
    assert int(own[1]) == int(given[1]) == 0
    np.testing.assert_allclose(given[0], 0.7390851332151607, rtol=1e-15)
    np.testing.assert_allclose(own[0], given[0], rtol=1e-15)


def test_pull_in_of_a_softening_wall(monkeypatch):
    """A strain-softening energy W = sqrt(I_1 − 2) − 1 (W_1 falls as the wall stretches) has a
    pull-in maximum at fixed λ_z, unlike Gent and neo-Hookean walls: pull_in (Newton on the slope)
    finds dV̂²/dλ_i = 0 there, with implicit derivatives equal to central differences, and
    voltage_limit (golden-section search on values only) reaches the same voltage."""
    from jaxdea import materials

    monkeypatch.setitem(materials.ENERGIES, "soft", lambda i1, g: jnp.sqrt(i1 - 2.0) - 1.0)
    tube = jd.Tube(lambda_z=1.2, eta=0.6, material="soft", lambda_i=1.0)
    dp0 = float(jax.jit(bs.pressure_difference_unchecked)(tube.replace(voltage=0.0)))
    pull = jax.jit(bs.pull_in_unchecked)
    li, v, status = pull(tube, dp0)
    assert int(status) == 0 and 1.2 < float(li) < 2.5 and float(v) > 0.1
    slope = jax.jit(jax.grad(lambda x: bs.squared_voltage(tube, x, dp0)))(li)
    curvature = jax.jit(jax.grad(jax.grad(lambda x: bs.squared_voltage(tube, x, dp0))))(li)
    assert abs(float(slope)) < 1e-12 * abs(float(curvature)) and float(curvature) < 0
    np.testing.assert_allclose(jax.jit(bs.voltage_limit)(tube), v, rtol=1e-14)
    grad = jax.jit(jax.grad(lambda p: pull(tube, p)[0]))(dp0)
    np.testing.assert_allclose(grad, fd_derivative(lambda p: pull(tube, p)[0], dp0), rtol=1e-6)
