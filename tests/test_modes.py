"""Mode shapes and the acoustic pressure field in the cavity (jaxdea.solve.modes, theory.md §3–4).

All fluid cases share one compiled root finder and one compiled mode solver (same static
configuration, new float values): the float leaves of Tube/Fluid and α̂, Ω are traced.
"""

import functools

import exact_cylinder
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy import special

import jaxdea as jd
from jaxdea.numerics.bessel import _switch, coupling_log_factor, coupling_pair
from jaxdea.params import canonical
from jaxdea.physics.transfer import discretize
from jaxdea.solve import modes
from jaxdea.solve.modes import fluid_pressure

TUBE = jd.Tube(voltage=0.1, lambda_i=0.9, lambda_z=1.2)
N_POINTS = 401  # fine enough for 4th-order finite differences of p̂*(r̂) (h = r̂_i/400)

# (fluid, α̂): the paper's light, very compressible fluid at the n = 1 wavenumber, a water-like fluid
# (ρ̂_f, ĉ_f of water in VHB) at a short wave (χ̂²r̂_i² = −117: the e^{−x̃}-scaled integral branch of
# the Bessel pair), and a slow fluid whose third root is a nearly rigid-wall cavity mode (D_0 ≈ 0).
SETUPS = {
    "light": (jd.Fluid(), 0.445),
    "water": (jd.Fluid(density_ratio=1.04, speed_ratio=324.25), 12.0),
    "slow": (jd.Fluid(density_ratio=0.13, speed_ratio=0.1), 3.0),
}
# (setup, root index, expected branch of s = χ̂²r̂_i²)
ROOTS = [
    ("light", 0, "negative series"),  # subsonic fluid-loaded (Korteweg) wave, I_0 profile
    ("light", 1, "positive series"),  # J_0 profile
    ("light", 2, "positive series"),
    ("water", 0, "negative integral"),
    ("slow", 2, "positive series"),  # near the second rigid-wall cavity resonance
]


@functools.cache
def _roots(name):
    fluid, alpha = SETUPS[name]
    return np.asarray(jd.frequencies(TUBE, alpha, fluid, n_roots=3))


@functools.cache
def _solution(name, index):
    """(fluid, α̂, Ω, χ̂², r_wall, fields, r_fluid, p) at one root."""
    fluid, alpha = SETUPS[name]
    omega = float(_roots(name)[index])
    r, y = jd.mode_shape(TUBE, alpha, omega, fluid, n_points=N_POINTS)
    r_f, p = fluid_pressure(TUBE, alpha, omega, fluid, n_points=N_POINTS)
    chi2 = (omega / float(fluid.speed_ratio)) ** 2 - alpha**2
    return fluid, alpha, omega, chi2, np.asarray(r), np.asarray(y), np.asarray(r_f), np.asarray(p)


def _branch(s):
    side = "positive" if s > 0 else "negative"
    return f"{side} {'series' if abs(s) <= float(_switch(0.0)) else 'integral'}"


def _derivatives(p, h):
    """4th-order central p′, p″ at the interior points 2..n−3."""
    d1 = (p[:-4] - 8 * p[1:-3] + 8 * p[3:-1] - p[4:]) / (12 * h)
    d2 = (-p[:-4] + 16 * p[1:-3] - 30 * p[2:-2] + 16 * p[3:-1] - p[4:]) / (12 * h * h)
    return d1, d2


def _wall_slope(p, h):
    """4th-order one-sided dp/dr̂ at the last point (r̂_i)."""
    return (25 * p[-1] - 48 * p[-2] + 36 * p[-3] - 16 * p[-4] + 3 * p[-5]) / (12 * h)


@pytest.mark.parametrize("name, index, branch", ROOTS)
def test_fluid_pressure_solves_helmholtz_on_the_expected_branch(name, index, branch):
    """p̂*″ + p̂*′/r̂ + χ̂² p̂* = 0 in the cavity (finite differences, r̂ ≥ 0.05 r̂_i), regular on the
    axis, and the case lies on the Bessel branch it is meant to cover."""
    _, _, _, chi2, _, _, r, p = _solution(name, index)
    assert _branch(chi2 * r[-1] ** 2) == branch
    d1, d2 = _derivatives(p, r[1] - r[0])
    inner = r[2:-2]
    residual = (d2 + d1 / inner + chi2 * p[2:-2])[inner >= 0.05 * r[-1]]
    assert np.max(np.abs(residual)) <= 1e-7 * abs(chi2) * np.max(np.abs(p))
    axis_slope = _wall_slope(p[::-1], r[0] - r[1])  # one-sided dp/dr̂ at r̂ = 0
    assert np.all(np.isfinite(p)) and abs(axis_slope) <= 1e-8 * np.max(np.abs(d1))


@pytest.mark.parametrize("name, index, branch", ROOTS)
def test_fluid_pressure_satisfies_euler_at_the_wall(name, index, branch):
    """ρ_f ü = −grad p* gives dp̂*/dr̂(r̂_i) = +Ω²ρ̂_f ū_i (the sign of B̂_0 = J_0/(χ̂ J_0′), theory.md
    §4(c)); the opposite sign fails, and p̂*(r̂_i) = Ω²ρ̂_f B̂_0 ū_i with B̂_0 from scipy."""
    fluid, _, omega, chi2, _, y, r, p = _solution(name, index)
    rho, u_i = float(fluid.density_ratio), y[0, 0]
    h, chi = r[1] - r[0], np.sqrt(abs(chi2))
    slope = _wall_slope(p, h)
    wall = omega**2 * rho * u_i
    truncation = (chi * h) ** 4 * chi  # of the one-sided 4th-order stencil, relative to max|p̂*|
    np.testing.assert_allclose(slope, wall, rtol=0, atol=(1e-9 + truncation) * np.max(np.abs(p)))
    if abs(u_i) > 1e-3:
        assert abs(slope + wall) > abs(wall)  # −Ω²ρ̂_f ū_i is inconsistent
    x = np.sqrt(abs(chi2)) * r[-1]
    if chi2 > 0:
        b0 = -special.j0(x) / (np.sqrt(chi2) * special.j1(x))
    else:
        b0 = special.i0e(x) / (np.sqrt(-chi2) * special.i1e(x))
    np.testing.assert_allclose(p[-1], omega**2 * rho * b0 * u_i, rtol=1e-9)


@pytest.mark.parametrize("name, index, branch", ROOTS)
def test_inner_traction_carries_the_fluid_pressure(name, index, branch):
    """At r̂_i: Φ = 0, T̄ = −(P̂_i/r̂_i)ū − α̂P̂_i w̄ − p̂*(r̂_i) (follower pressure + acoustic load,
    dispersion.initial_basis), S̄ = −α̂P̂_i ū; at r̂_o: Φ = T̄ = S̄ = 0; displacements scaled to a +1
    maximum."""
    _, alpha, _, _, r_wall, y, r, p = _solution(name, index)
    assert r[0] == 0.0 and r[-1] == pytest.approx(r_wall[0], rel=1e-15)
    pi = float(jd.pressure_difference(TUBE))
    u, w, phi, t, s, _ = y[:, 0]
    scale = np.max(np.abs(y[:, 0]))
    np.testing.assert_allclose(t, -pi / r_wall[0] * u - alpha * pi * w - p[-1], rtol=0, atol=1e-12 * scale)
    np.testing.assert_allclose([phi, s + alpha * pi * u], 0.0, atol=1e-12 * scale)
    np.testing.assert_allclose(y[2:5, -1], 0.0, atol=1e-8 * np.max(np.abs(y)))
    assert np.max(np.abs(y[:2])) == 1.0 and np.max(y[:2]) == 1.0
    assert abs(p[-1]) > 1e-4 * scale  # dropping −p̂*(r̂_i) would miss the tolerance by ≥ 1e8


def test_fluid_pressure_shares_the_mode_shape_program():
    """fluid_pressure after mode_shape with the same static settings compiles nothing new."""
    _solution("light", 0)
    before = modes._solve_mode._cache_size()
    fluid, alpha = SETUPS["light"]
    tube = TUBE.replace(voltage=0.05)
    omega = jd.frequencies(tube, alpha * 1.1, fluid, n_roots=1)[0]
    fluid_pressure(tube, alpha * 1.1, omega, fluid, n_points=N_POINTS)
    assert modes._solve_mode._cache_size() == before


def test_a_non_root_omega_raises_or_gives_nan():
    """Ω = 0.123 at α̂ = 0.4 is no root: a concrete call raises naming omega, a traced one gives NaN
    fields; a root passes, and so does the root of a finer laminate (relative distance ~1e-5)."""
    tube = jd.Tube(voltage=0.1, lambda_i=0.9, lambda_z=1.2)
    with pytest.raises(ValueError, match="omega = 0.123 is not a root"):
        jd.mode_shape(tube, 0.4, 0.123)
    with pytest.raises(ValueError, match="not a root"):
        jd.mode_shape(tube, 0.4, 0.123, m=2)
    r, fields = jax.jit(lambda w: jd.mode_shape(tube, 0.4, w))(0.123)
    assert np.all(np.isnan(np.asarray(fields)))
    root = float(jd.frequencies(tube, 0.4, n_roots=1, n_layers=30)[0])
    fine = float(jd.frequencies(tube, 0.4, n_roots=1, scheme="magnus6", n_layers=8)[0])
    assert 1e-7 < abs(fine / root - 1) < 1e-4  # the midpoint N = 30 laminate's error
    for w in (root, fine):
        assert np.all(np.isfinite(np.asarray(jd.mode_shape(tube, 0.4, w, n_layers=30)[1])))
    # the distance is the Newton step relative to Ω: 1e-3 off the root is 1e-3 away
    d = modes.root_distance(*canonical(tube, 0.4, root * (1 + 1e-3)), None, 30, 0)
    assert float(d) == pytest.approx(1e-3, rel=1e-2)


@pytest.mark.parametrize("zero", [3.8317059702075125, 10.173468135062722])  # j_{1,1}, j_{1,3}
def test_fluid_pressure_at_a_rigid_wall_cavity_resonance(zero):
    """At Ω with J_1(χ̂r̂_i) = 0 (D_0 = 0, not a root) the profile is still finite, the wall does not
    move radially and p̂* ∝ J_0(χ̂r̂) (scipy), also on the large-argument integral branch (j_{1,3})."""
    fluid, alpha = SETUPS["light"]
    ri = float(TUBE.lambda_i)
    chi = zero / ri
    omega = float(fluid.speed_ratio) * np.hypot(chi, alpha)
    # not a root, so not through the public functions (they refuse it): the same pieces, unmasked
    tube, a, w, f = canonical(TUBE, alpha, omega, fluid)
    wall = discretize(tube, 30)
    states, coefficients = modes._interface_solution(wall, w, a, f, 0)
    _, fields = modes._wall_fields(tube, wall, states, w, a, N_POINTS)
    scale = modes._displacement_scale(fields)
    y = np.asarray(fields / scale).T
    r, p = modes._cavity_pressure(wall, w, a, f, coefficients[0], N_POINTS)
    r, p = np.asarray(r), np.asarray(p / scale)
    assert np.all(np.isfinite(p)) and np.max(np.abs(p)) > 1e-3
    assert abs(float(y[0, 0])) < 1e-12
    np.testing.assert_allclose(p, p[0] * special.j0(chi * r), rtol=0, atol=1e-12 * np.max(np.abs(p)))


def test_coupling_log_factor_recovers_true_bessel_values():
    """e^{−g(s)} N_0(s) is J_0(√s) or I_0(√−s) on both sides of the series/integral switch."""
    s = np.array([-400.0, -65.0, -63.0, -1.0, 0.0, 2.0, 63.0, 65.0, 400.0])  # switch at |s| = 64
    n, g = jax.jit(jax.vmap(lambda x: (coupling_pair(x, 0)[0], coupling_log_factor(x))))(s)
    true = np.where(s >= 0, special.j0(np.sqrt(np.abs(s))), special.i0(np.sqrt(np.abs(s))))
    np.testing.assert_allclose(np.asarray(n) * np.exp(-np.asarray(g)), true, rtol=1e-11, atol=1e-14)


def test_fluid_pressure_rejects_models_without_a_pressure_field():
    with pytest.raises(ValueError, match="fluid=None"):
        fluid_pressure(TUBE, 0.445, 1.0, None)
    with pytest.raises(ValueError, match="paper.*follower pressure"):
        fluid_pressure(TUBE, 0.445, 1.0, jd.Fluid(coupling="paper", bessel_order=0))
    with pytest.raises(ValueError, match="speed_ratio"):
        fluid_pressure(TUBE, 0.445, 1.0, jd.Fluid(speed_ratio=-1.0))


def _exact_fields(omega, alpha, a, b, r):
    """Linear incompressible hollow cylinder, free faces (tests/exact_cylinder.py): u_r, u_z,
    σ_rr, σ_rz of the null vector of its 4×4 determinant at radii r."""
    beta2 = omega**2 - alpha**2
    shear = 2 * alpha**2 - omega**2

    def columns(x):
        rows = np.empty((4, 4))
        for kind in (0, 1):
            f, df = exact_cylinder._phi_column(alpha, x, a, b, kind)
            g, dg = exact_cylinder._psi_column(beta2, x, a, b, kind)
            d2f = alpha**2 * f - df / x
            rows[:, kind] = [df, -alpha * f, -omega**2 * f + 2 * d2f, -2 * alpha * df]
            rows[:, 2 + kind] = [-alpha * g, dg + g / x, -2 * alpha * dg, shear * g]
        return rows  # rows: u_r, u_z, σ_rr, σ_rz

    m = np.concatenate([columns(a)[2:], columns(b)[2:]])
    norms = np.linalg.norm(m, axis=0)
    coef = np.linalg.svd(m / norms)[2][-1] / norms
    return np.stack([columns(x) @ coef for x in r], axis=1)


def test_mode_shape_equals_exact_linear_cylinder():
    """λ = λ_z = 1, V̂ = 0, neo-Hookean, bar and breathing modes at α̂ = 0.445: ū, w̄, T̄, S̄ equal the
    exact linear solution at its exact root (theory.md §5(i)), Φ = D̄ = 0, and the difference is the
    laminate error: it falls like N⁻² (N = 30 → 60)."""
    k = exact_cylinder.EXACT_K.index(0.445)
    tube = jd.Tube(lambda_i=1.0, lambda_z=1.0, eta=0.85, gent=jnp.inf)
    for omega in exact_cylinder.EXACT_OMEGA[k][:2]:
        errors = []
        for n_layers in (30, 60):
            r, y = jd.mode_shape(tube, 0.445, omega, n_points=N_POINTS, n_layers=n_layers)
            r, y = np.asarray(r), np.asarray(y)
            exact = _exact_fields(omega, 0.445, 1.0, 1.0 / 0.85, r)
            exact = exact / exact[np.unravel_index(np.argmax(np.abs(exact[:2])), exact[:2].shape)]
            errors.append(np.max(np.abs(y[[0, 1, 3, 4]] - exact)))
            np.testing.assert_allclose(y[[2, 5]], 0.0, atol=1e-12)
        assert errors[0] < 1e-4  # measured 5.5e-6 (bar), 3.5e-5 (breathing)
        assert 3.8 < errors[0] / errors[1] < 4.2  # measured 4.00, 4.00


def test_named_fields_are_one_layout_for_a_concrete_and_a_traced_m():
    """A concrete m = 0 (6 rows) and a traced m = 0 (8 rows, vmapped with m = 2) give the same
    named fields: ū, w̄, Φ, T̄, S̄, D̄ equal to rounding, v̄ = Q̄ = 0; the ring mode has v̄ ≠ 0."""
    alpha = 0.445
    omega0 = float(jd.frequencies(TUBE, alpha, n_roots=1)[0])
    omega2 = float(jd.frequencies(TUBE, alpha, n_roots=1, m=2)[0])
    concrete = jd.mode_shape(TUBE, alpha, omega0)
    assert concrete.fields.shape == (6, 64)
    traced = jax.vmap(lambda m, om: jd.mode_shape(TUBE, alpha, om, m=m))(
        jnp.array([0, 2]), jnp.array([omega0, omega2]))
    assert traced.fields.shape == (2, 8, 64)
    for name in ("u", "w", "phi", "T", "S", "D"):
        np.testing.assert_allclose(traced.field(name)[0], concrete.field(name), rtol=1e-7, atol=1e-9,
                                   err_msg=name)
    for name in ("v", "Q"):
        assert not np.any(concrete.field(name)) and np.max(np.abs(traced.field(name)[0])) < 1e-9
    assert np.max(np.abs(traced.v[1])) > 0.1
    with pytest.raises(ValueError, match="name must be one of"):
        concrete.field("x")
