"""Circumferential order m (theory_m.md): the 8×8 state matrix, the torsional family, boundary
conditions, order-m acoustic coupling and the characteristic function in signed Ω².

Roots here come from brentq on sign changes of the characteristic function over a grid (an
independent refinement from the library's solvers). Tolerances follow from the numerics: the
midpoint laminate N = 30 has relative root errors ~1e-6…1e-5 (theory_m.md §7b), the sixth-order
Magnus scheme at N = 8…10 ~1e-10 or better; identities hold to rounding (~1e-15).
"""

import functools
import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from exact_cylinder_m import EXACT_TABLE, roots_m
from scipy.optimize import brentq
from scipy.special import iv, ivp, jv, jvp, yv

import jaxdea as jd
from jaxdea.numerics.bessel import coupling_pair
from jaxdea.physics import characteristic as ch
from jaxdea.physics import dispersion as dp
from jaxdea.physics import state_matrix as sm
from jaxdea.physics import transfer as tr

ETA = 0.85
R_I, R_O = 1.0, 1.0 / ETA  # unstretched tube
LINEAR = jd.Tube(gent=jnp.inf)  # λ_i = λ_z = 1, V̂ = 0, neo-Hookean: the linear elastic cylinder
LOADED = jd.Tube(voltage=0.3, lambda_i=1.2, lambda_z=1.2)
MAGNUS6 = tr.laminate(8, "magnus6")
FLUID = jd.Fluid(density_ratio=0.13, speed_ratio=0.27)
LONG = dp.LONGITUDINAL_ROWS


# ------------------------------------------------------------------ helpers


@functools.partial(jax.jit, static_argnames=("layers", "family", "order"))
def _values(tube, ws, alpha, m, fluid, layers, family, order=0):
    """f(w) on a batch of w = Ω² via the solvers' builder (characteristic.problem_function)."""
    _, fun = ch.problem_function(tube, alpha, fluid, layers, order, m, family, "omega_squared")
    return jax.vmap(fun)(ws)


@functools.partial(jax.jit, static_argnames=("layers", "order"))
def _values_axisymmetric(tube, omegas, alpha, fluid, layers, order=0):
    """The 6×6 axisymmetric f(Ω) (the library's m = 0 code path)."""
    wall = tr.discretize(tube, layers)
    return jax.vmap(lambda om: dp.characteristic_on_wall(wall, om, alpha, fluid, order))(omegas)


def _brentq_roots(fun_batch, grid):
    """Every sign change of f on ``grid``, refined by brentq (f evaluated one point at a time)."""
    vals = np.asarray(fun_batch(jnp.asarray(grid)))
    assert np.all(np.isfinite(vals))
    idx = np.nonzero(np.sign(vals[1:]) * np.sign(vals[:-1]) < 0)[0]

    def one(x):
        return float(fun_batch(jnp.full(1, x))[0])

    return np.array([brentq(one, grid[k], grid[k + 1], xtol=1e-300, rtol=1e-15) for k in idx])


def roots_in_omega(tube, alpha, m, layers=30, fluid=None, family=dp.ORDER_M, omega_max=21.0,
                   n_grid=2500, order=0):
    """Roots Ω of f(Ω²) in (0, omega_max] (grid uniform in Ω)."""
    fun = lambda om: _values(tube, om * om, alpha, float(m), fluid, layers, family, order)  # noqa: E731
    return _brentq_roots(fun, np.linspace(1e-3, omega_max, n_grid))


def roots_in_w(tube, alpha, m, grid, layers=30, fluid=None, family=dp.ORDER_M):
    """Roots w = Ω² (either sign) of f(w) on ``grid``."""
    return _brentq_roots(lambda w: _values(tube, w, alpha, float(m), fluid, layers, family), grid)


@functools.partial(jax.jit, static_argnames=("n_layers",))
def wall_coefficients(tube, n_layers=6):
    """(wall, the coefficients and mid-radius of its third sublayer)."""
    wall = tr.discretize(tube, n_layers)
    coef = jax.tree_util.tree_map(lambda x: x[2], wall.coef)
    return wall, coef, wall.radii[2]


# ------------------------------------------------------------------ state matrix (§3)


def test_m0_block_is_the_axisymmetric_matrix_and_torsion_decouples():
    """M_0's block [U, W, Φ, T, S, D] equals theory.md's 6×6 M entry by entry (≤ 1e-15 of the
    largest entry) and the (V, Q) rows and columns couple to nothing else (exactly 0)."""
    _, coef, r = wall_coefficients(LOADED)
    for omega in (0.0, 0.7, 3.1):
        full = sm.state_matrix_m(coef, r, omega**2, 0.89, 0.0)
        six = sm.state_matrix(coef, r, omega, 0.89)
        scale = float(jnp.max(jnp.abs(six)))
        np.testing.assert_allclose(np.asarray(full[LONG][:, LONG]), np.asarray(six), rtol=0,
                                   atol=1e-15 * scale)
        other = np.setdiff1d(np.arange(8), [1, 5])
        assert np.all(np.asarray(full)[np.ix_([1, 5], other)] == 0.0)
        assert np.all(np.asarray(full)[np.ix_(other, [1, 5])] == 0.0)
        torsion = sm.torsion_matrix(coef, r, omega**2, 0.89)
        np.testing.assert_array_equal(np.asarray(full)[np.ix_([1, 5], [1, 5])], np.asarray(torsion))


@pytest.mark.parametrize("m", [0, 1, 3])
def test_reciprocity(m):
    """Mᵀ J + J M + J/r̂ = 0 (theory_m.md §3, Structure), J = [[0, I₄], [−I₄, 0]], at a stretched,
    voltage-loaded state with Gent stiffening: every off-diagonal sign and factor enters."""
    _, coef, r = wall_coefficients(LOADED)
    j = np.block([[np.zeros((4, 4)), np.eye(4)], [-np.eye(4), np.zeros((4, 4))]])
    for w in (0.0, 2.3, -0.4):
        mat = np.asarray(sm.state_matrix_m(coef, r, w, 0.89, float(m)))
        residual = mat.T @ j + j @ mat + j / float(r)
        assert np.max(np.abs(residual)) <= 1e-14 * np.max(np.abs(mat))


def test_closed_form_and_tensor_modulus_e():
    """e = 2W_1λ² (closed form) equals A_θrθr of the autodiff moduli tensor (theory_m.md §2), and
    differs from a and c under stretch (so swapping them is not harmless)."""
    r = jnp.linspace(1.26, 1.32, 3)  # inside the wall, away from r̂_i where λ = λ_i = λ_z
    closed = jax.jit(lambda t: tr.layer_coefficients(t, r, "closed"))(LOADED)
    tensor = jax.jit(lambda t: tr.layer_coefficients(t, r, "tensor"))(LOADED)
    np.testing.assert_allclose(np.asarray(closed.e), np.asarray(tensor.e), rtol=1e-13)
    assert np.all(np.abs(np.asarray(closed.e - closed.a)) > 0.05)
    assert np.all(np.abs(np.asarray(closed.e - closed.c)) > 0.05)


# ------------------------------------------------------------------ m = 0 inside the 8×8 path


@pytest.mark.parametrize("case", [
    (jd.Tube(voltage=0.1, lambda_i=0.9, lambda_z=1.2), 0.445, None),
    (jd.Tube(voltage=0.3, lambda_i=1.2, lambda_z=1.2), 0.89, None),
    (jd.Tube(voltage=0.1, lambda_i=0.9, lambda_z=1.2), 0.445, FLUID),
    (jd.Tube(voltage=0.2, lambda_i=1.5, lambda_z=1.2), 1.335, FLUID),
    (jd.Tube(voltage=0.1, lambda_i=0.9, lambda_z=1.2), 0.445,
     jd.Fluid(coupling="paper", bessel_order=1)),
], ids=["free-a", "free-b", "acoustic-a", "acoustic-b", "paper"])
def test_traced_m0_gives_the_longitudinal_roots(case):
    """The order-m family at a traced m = 0 has exactly the roots of the 6×6 axisymmetric path
    (≤ 1e-13 relative, N = 30): the torsional block is switched off, no torsional root appears."""
    tube, alpha, fluid = case
    order = 1 if fluid is not None and fluid.coupling == "paper" else 0
    grid = np.linspace(1e-3, 21.0, 2500)
    six = _brentq_roots(lambda om: _values_axisymmetric(tube, om, alpha, fluid, 30, order), grid)
    eight = roots_in_omega(tube, alpha, 0, layers=30, fluid=fluid, order=order)
    assert len(six) >= 2 and len(six) == len(eight)
    np.testing.assert_allclose(eight, six, rtol=1e-13)


def test_problem_function_variables():
    """problem_function: 'omega' of the longitudinal family is the axisymmetric f(Ω) bit for bit;
    of the order-m family it is f(w = Ω²)."""
    tube, alpha = jd.Tube(voltage=0.1, lambda_i=0.9, lambda_z=1.2), 0.445
    om = jnp.linspace(0.1, 5.0, 7)

    @jax.jit
    def both(om):
        wall, f6 = ch.problem_function(tube, alpha, None, 10, 0)
        ref = jax.vmap(lambda o: dp.characteristic_on_wall(wall, o, alpha, None, 0, "adaptive"))(om)
        _, f8 = ch.problem_function(tube, alpha, None, 10, 0, 2.0, dp.ORDER_M)
        _, g8 = ch.problem_function(tube, alpha, None, 10, 0, 2.0, dp.ORDER_M, "omega_squared")
        return jax.vmap(f6)(om), ref, jax.vmap(f8)(om), jax.vmap(g8)(om * om)

    f6, ref, f8, g8 = both(om)
    np.testing.assert_array_equal(np.asarray(f6), np.asarray(ref))
    np.testing.assert_array_equal(np.asarray(f8), np.asarray(g8))


# ------------------------------------------------------------------ torsional family


def _torsion_exact(alpha, n_roots):
    """Torsion of the hollow cylinder: V = Z_1(βr), σ_rθ = −βZ_2(βr) = 0 at both faces
    (β² = Ω² − α̂²), plus the rigid-like twist V ∝ r at Ω = α̂."""
    def cross(beta):
        return jv(2, beta * R_I) * yv(2, beta * R_O) - jv(2, beta * R_O) * yv(2, beta * R_I)

    grid = np.linspace(0.05, 60.0, 30000)
    vals = cross(grid)
    idx = np.nonzero(np.sign(vals[1:]) * np.sign(vals[:-1]) < 0)[0]
    betas = np.array([brentq(cross, grid[k], grid[k + 1], xtol=1e-15) for k in idx])
    return np.concatenate([[alpha], np.sqrt(betas**2 + alpha**2)])[:n_roots]


def test_torsional_family_unstretched():
    """Torsional family (2×2) of the linear tube vs the closed form: Ω = α̂ exactly (the laminate
    keeps V ∝ r, Q = 0 exactly there) and the Z_2 roots (magnus6 N = 8: ≤ 1e-9; midpoint N = 30:
    ≤ 1e-6, the O(N⁻²) laminate error)."""
    alpha = 0.534
    exact = _torsion_exact(alpha, 2)
    f_alpha = _values(LINEAR, jnp.full(1, alpha**2), alpha, 0.0, None, 30, dp.TORSIONAL)[0]
    assert abs(float(f_alpha)) < 1e-14
    for layers, tol in ((MAGNUS6, 1e-9), (30, 1e-6)):
        found = roots_in_omega(LINEAR, alpha, 0, layers=layers, family=dp.TORSIONAL, omega_max=30.0,
                               n_grid=1000)
        assert len(found) == 2
        np.testing.assert_allclose(found[1], exact[1], rtol=tol)
        np.testing.assert_allclose(found[0], alpha, rtol=1e-12)


def test_torsional_family_ignores_the_fluid():
    """An inviscid fluid does not couple to torsion: the same f with and without it (no D_m
    factor, which would add spurious zeros at D_m = 0, theory_m.md §7a)."""
    tube = jd.Tube(voltage=0.1, lambda_i=0.9, lambda_z=1.2)
    for om in (0.12017, 0.7, 5.0):
        a = dp.characteristic(tube, om, 0.445, FLUID, n_layers=10, torsional=True)
        b = dp.characteristic(tube, om, 0.445, None, n_layers=10, torsional=True)
        assert float(a) == float(b)


# ------------------------------------------------------------------ exact linear cylinder (§7b)

EXACT = EXACT_TABLE  # theory_m.md §7(b), 8 digits: the five lowest roots below Ω = 21


@pytest.mark.parametrize("key", list(EXACT), ids=[f"m{m}-a{a}" for m, a in EXACT])
def test_exact_linear_cylinder(key):
    """All roots below Ω = 21 of the order-m family of the linear tube vs the exact solution:
    the same count; midpoint N = 30 within 2e-5 relative (the laminate's O(N⁻²), ~1e-6…1e-5);
    magnus6 N = 8 within 3e-8 (the 8 digits of the table)."""
    m, alpha = key
    exact = np.array(EXACT[key])
    mid = roots_in_omega(LINEAR, alpha, m, layers=30)
    assert len(mid) == len(exact)
    err = np.abs(mid / exact - 1)
    assert np.max(err) < 2e-5
    magnus = roots_in_omega(LINEAR, alpha, m, layers=MAGNUS6)
    assert len(magnus) == len(exact)
    np.testing.assert_allclose(magnus, exact, rtol=3e-8)


def test_exact_linear_cylinder_reference_solver():
    """Against the independent exact solver tests/exact_cylinder_m.py: magnus6
    N = 8 roots of orders 1 and 4 within 1e-9."""
    for m, alpha in ((1, 0.534), (4, 1.0)):
        exact = np.asarray(roots_m(m, alpha, R_I, R_O, 5, 21.0))
        found = roots_in_omega(LINEAR, alpha, m, layers=MAGNUS6)
        np.testing.assert_allclose(found[:5], exact, rtol=1e-9)


# ------------------------------------------------------------------ gauge invariance (§7e)


@functools.partial(jax.jit, static_argnames=("layers",))
def _gauge_values(tube, ws, alpha, m, fluid, shift, layers):
    """f(w) with P̂_i → P̂_i + P, P̂_o = P and p̂(r̂) → p̂(r̂) + P (fluid p* unchanged)."""
    wall = tr.discretize(tube, layers)
    wall = wall._replace(coef=wall.coef._replace(p=wall.coef.p + shift),
                         pressure_inner=wall.pressure_inner + shift)
    return jax.vmap(lambda w: dp.characteristic_of_w(wall, w, alpha, fluid, 0, "taylor", m,
                                                     dp.ORDER_M, shift))(ws)


@pytest.mark.parametrize("case", [
    (jd.Tube(voltage=0.1, lambda_i=0.9, lambda_z=1.2), 0.445, 1, None),
    (jd.Tube(voltage=0.3, lambda_i=1.2, lambda_z=1.2), 0.89, 2, None),
    (jd.Tube(voltage=0.6, lambda_i=1.3, lambda_z=1.2), 0.89, 3, FLUID),
], ids=["m1", "m2", "m3-acoustic"])
def test_gauge_invariance(case):
    """Shifting P̂_i, P̂_o and p̂ by P = 0.3, −0.7 leaves the roots below Ω = 20 unchanged. With
    magnus6 N = 8 the discretisations of the shifted problems agree to ≤ 1e-9 (theory_m.md §7e:
    dropping the θ follower terms moves the roots by ~1e-2)."""
    tube, alpha, m, fluid = case
    grid = np.linspace(1e-3, 20.0, 2500)

    def roots(shift):
        return _brentq_roots(lambda om: _gauge_values(tube, om * om, alpha, float(m), fluid, shift,
                                                      MAGNUS6), grid)

    base = roots(0.0)
    assert len(base) >= 2
    for shift in (0.3, -0.7):
        shifted = roots(shift)
        assert len(shifted) == len(base)
        np.testing.assert_allclose(shifted, base, rtol=1e-9)


# ------------------------------------------------------------------ unstable modes (§6)


def test_signed_omega_squared():
    """λ_i = 0.95, λ_z = 1.2, η = 0.85, α̂ = 0.445, m = 2: the lowest Ω² is 0.4293 (V̂ = 0),
    0.0801 (0.06), −0.1962 (0.08), −0.5574 (0.10) (theory_m.md §6; 4 digits), found by a scan in
    signed w = Ω² with real arithmetic; the public characteristic_at_omega_squared agrees."""
    grid = np.linspace(-1.0, 1.0, 801)
    for voltage, expected in ((0.0, 0.4293), (0.06, 0.0801), (0.08, -0.1962), (0.10, -0.5574)):
        tube = jd.Tube(voltage=voltage, lambda_i=0.95, lambda_z=1.2)
        lowest = roots_in_w(tube, 0.445, 2, grid)[0]
        assert abs(lowest - expected) < 6e-5
        f = [float(dp.characteristic_at_omega_squared(tube, lowest + d, 0.445, m=2))
             for d in (-1e-3, 1e-3)]
        assert f[0] * f[1] < 0


# ------------------------------------------------------------------ long-wave bending (§7d)


def _bending_limit(fluid):
    """c0 of Ω²/α̂⁴ = c0 + c1α̂² + c2α̂⁴ through α̂ = 0.01, 0.02, 0.04 (m = 1, magnus6 N = 8)."""
    alphas = (0.01, 0.02, 0.04)
    ratios = [roots_in_w(LINEAR, a, 1, np.geomspace(1e-14, 1e-4, 300), MAGNUS6, fluid)[0] / a**4
              for a in alphas]
    return np.linalg.solve(np.array([[1.0, a**2, a**4] for a in alphas]), np.array(ratios))[0]


def test_long_wave_bending():
    """m = 1 long waves: Euler–Bernoulli Ω²/α̂⁴ → 3(r_i² + r_o²)/4 = 1.78806228 (E = 3μ), and with
    the acoustic fluid moving rigidly (added mass ρ̂_f r_i²) → (3/4)(r_o⁴ − r_i⁴)/((r_o² − r_i²)
    + ρ̂_f r_i²) = 1.33590169; the fitted limit within 1e-6 (measured ~2e-8). Checks the sign and
    the m = 1 limit B_1 → r̂_i of the order-m impedance."""
    empty = 0.75 * (R_I**2 + R_O**2)
    filled = 0.75 * (R_O**4 - R_I**4) / ((R_O**2 - R_I**2) + 0.13 * R_I**2)
    np.testing.assert_allclose(_bending_limit(None), empty, rtol=1e-6)
    np.testing.assert_allclose(_bending_limit(FLUID), filled, rtol=1e-6)


# ------------------------------------------------------------------ fluid coupling of order m (§5)


@pytest.mark.parametrize("m", [1, 2, 3, 6])
def test_coupling_pair_of_order_m(m):
    """coupling_pair(s, m) = (N_m, D_m) up to a common positive factor: N_m = J_m(x)/x^m,
    D_m = xJ_m'(x)/x^m (s = x² > 0), I_m, I_m' at x̃ = sqrt(−s) (s < 0), vs scipy."""
    for s in (-900.0, -30.0, -2.0, -1e-3, 1e-3, 2.0, 30.0, 900.0):
        n, d = (float(v) for v in coupling_pair(jnp.asarray(s), jnp.asarray(float(m))))
        x = math.sqrt(abs(s))
        if s > 0:
            n_ref, d_ref = jv(m, x) / x**m, x * jvp(m, x) / x**m
        else:
            n_ref, d_ref = iv(m, x) / x**m, x * ivp(m, x) / x**m
        assert n / n_ref > 0
        np.testing.assert_allclose(d / n, d_ref / n_ref, rtol=1e-12)


# ------------------------------------------------------------------ schemes and propagation


def _magnus_direct(step, mats, scheme):
    """The Magnus generator written out from the node matrices at one w (transfer docstring)."""
    def comm(a, b):
        return a @ b - b @ a

    if scheme == "magnus4":
        return 0.5 * step * (mats[0] + mats[1]) + (math.sqrt(3.0) / 12.0) * step**2 * comm(mats[1],
                                                                                            mats[0])
    b1 = step * mats[1]
    b2 = (math.sqrt(15.0) / 3.0) * step * (mats[2] - mats[0])
    b3 = (10.0 / 3.0) * step * (mats[2] - 2.0 * mats[1] + mats[0])
    c1 = comm(b1, b2)
    return b1 + b3 / 12.0 + comm(-20.0 * b1 - b3 + c1, b2 - comm(b1, 2.0 * b3 + c1) / 60.0) / 240.0


@pytest.mark.parametrize("scheme", ["magnus4", "magnus6"])
def test_generator_polynomial_of_order_m(scheme):
    """generator_coefficients (a polynomial in w) equals the Magnus generator formed from the 8×8
    matrices at w, for a traced m = 2 and for m = 0 (block switched off), to rounding."""
    @jax.jit
    def both(m, w):
        wall = tr.discretize(LOADED, tr.laminate(5, scheme))
        coef = jax.tree_util.tree_map(lambda x: x[1], wall.coef)
        radius = wall.radii[1]
        poly = tr.generator_coefficients(wall.step, coef, radius, 0.89, m, dp.ORDER_M)
        mats = jax.vmap(lambda c, r: sm.order_m_matrix(c, r, w, 0.89, m))(coef, radius)
        return tr.generator_of_w(poly, w), _magnus_direct(wall.step, mats, scheme)

    for m in (2.0, 0.0):
        for w in (-0.5, 3.0):
            poly, direct = both(m, w)
            np.testing.assert_allclose(np.asarray(poly), np.asarray(direct), rtol=0,
                                       atol=1e-14 * float(jnp.max(jnp.abs(direct))))


@pytest.mark.parametrize("scheme", ["midpoint", "magnus6"])
def test_orthonormalised_equals_reference_determinant(scheme):
    """f · exp(log_scale) = det(Out A S) of the full 8×8 transfer matrix (expm), and the last
    interface of propagate_basis_history_of_w is the propagated 8×4 basis."""
    @jax.jit
    def compute(w):
        wall = tr.discretize(LOADED, tr.laminate(10, scheme))
        f, log_scale = dp.characteristic_and_scale_of_w(wall, w, 0.89, FLUID, 0, "taylor", 3.0)
        ref = dp.reference_determinant_of_w(wall, w, 0.89, FLUID, 0, 3.0)
        basis = dp.initial_basis_of_w(wall, w, 0.89, FLUID, 0, 3.0)
        q, _ = tr.propagate_basis_of_w(wall, w, 0.89, basis, "expm", 3.0, dp.ORDER_M)
        qs, rs = tr.propagate_basis_history_of_w(wall, w, 0.89, basis, "expm", 3.0, dp.ORDER_M)
        return f * jnp.exp(log_scale), ref, q, qs, rs

    for w in (-0.3, 2.5, 7.0):
        scaled, ref, q, qs, rs = compute(w)
        np.testing.assert_allclose(float(scaled), float(ref), rtol=1e-9)
        assert qs.shape == (11, 8, 4) and rs.shape == (11, 4, 4)
        np.testing.assert_allclose(np.asarray(qs[-1]), np.asarray(q), atol=1e-13)


def test_vmap_over_m_is_one_program_and_equals_single_calls():
    """A batch over the traced m (0 … 4) in one jit equals one call per m (the public
    characteristic: m = 0 there is the 6×6 path, so compare zeros' signs at m = 0 only)."""
    tube, om = jd.Tube(voltage=0.1, lambda_i=0.9, lambda_z=1.2), 1.3
    batch = jax.jit(jax.vmap(lambda m: dp.characteristic(tube, om, 0.445, n_layers=10, m=m)))(
        jnp.arange(5.0))
    for m in range(1, 5):
        assert float(batch[m]) == pytest.approx(float(dp.characteristic(tube, om, 0.445, n_layers=10,
                                                                        m=m)), rel=1e-13)
    assert np.all(np.isfinite(np.asarray(batch)))


# ------------------------------------------------------------------ inputs


def test_bad_orders_raise_and_trace_to_nan():
    """m negative, non-integer, bool or a string: ValueError naming m; the paper coupling with
    m ≥ 1: ValueError naming m; torsional=True with m ≥ 1: ValueError naming torsional. Traced
    invalid m (and torsional or paper at m ≠ 0): NaN."""
    tube = jd.Tube()
    for bad in (-1, 1.5, True, "2", float("nan"), np.array([1, 2])):
        with pytest.raises(ValueError, match=r"\bm\b"):
            dp.characteristic(tube, 1.0, 0.445, m=bad)
    with pytest.raises(ValueError, match=r"\bm\b"):
        dp.characteristic(tube, 1.0, 0.445, jd.Fluid(coupling="paper", bessel_order=1), m=1)
    with pytest.raises(ValueError, match="torsional"):
        dp.characteristic(tube, 1.0, 0.445, m=2, torsional=True)
    with pytest.raises(ValueError, match="torsional"):
        dp.characteristic(tube, 1.0, 0.445, torsional="yes")
    assert np.isfinite(float(dp.characteristic(tube, 1.0, 0.445, m=2.0)))  # an integral float

    ms = jnp.array([-1.0, 1.5, jnp.inf, 2.0])
    f = jax.jit(jax.vmap(lambda m: dp.characteristic(tube, 1.0, 0.445, n_layers=6, m=m)))(ms)
    assert np.all(np.isnan(np.asarray(f[:3]))) and np.isfinite(float(f[3]))
    paper = jd.Fluid(coupling="paper", bessel_order=1)
    g = jax.jit(jax.vmap(lambda m: dp.characteristic(tube, 1.0, 0.445, paper, n_layers=6, m=m)))(
        jnp.array([0.0, 1.0]))
    assert np.isfinite(float(g[0])) and np.isnan(float(g[1]))
    h = jax.jit(jax.vmap(lambda m: dp.characteristic(tube, 1.0, 0.445, n_layers=6, m=m,
                                                     torsional=True)))(jnp.array([0.0, 1.0]))
    assert np.isfinite(float(h[0])) and np.isnan(float(h[1]))
