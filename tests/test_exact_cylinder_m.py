"""The independent order-m reference solver (exact_cylinder_m): its m = 0 reduction to the
longitudinal (exact_cylinder) and torsional families, the theory_m.md §7(b) table, the
long-wave bending limit, continuity through Ω = α, and a cross-check against a plain
(unnormalised J_m/Y_m basis, derivatives by scipy) determinant built straight from the
displacement formulas."""

import exact_cylinder
import exact_cylinder_m as ecm
import numpy as np
import pytest
from scipy.optimize import brentq
from scipy.special import iv, ivp, jv, jvp, kv, kvp, yv, yvp

A, B = 1.0, 1.0 / 0.85


@pytest.mark.parametrize("alpha", [0.445, 1.5])
def test_m0_is_the_union_of_longitudinal_and_torsional_roots(alpha):
    got = ecm.roots_m(0, alpha, A, B, n_roots=12, omega_max=21.0)
    got = got[np.isfinite(got)]
    lon = exact_cylinder.roots(alpha, A, B, n_roots=8, omega_max=21.0, n_grid=4000)
    tor = ecm.torsion_roots(alpha, A, B, n_roots=8, omega_max=21.0)
    union = np.sort(np.concatenate([lon[np.isfinite(lon)], tor[np.isfinite(tor)]]))
    assert len(got) == len(union) == 5
    np.testing.assert_allclose(got, union, rtol=1e-13, atol=0.0)
    # the rigid-like twist V ~ r at Omega = alpha exactly, then J2(βa)Y2(βb) = J2(βb)Y2(βa)
    assert abs(tor[0] - alpha) <= 1e-14 * alpha
    beta = np.sqrt(tor[1:2] ** 2 - alpha**2)
    tors = jv(2, beta * A) * yv(2, beta * B) - jv(2, beta * B) * yv(2, beta * A)
    scale = np.abs(jv(2, beta * A) * yv(2, beta * B)) + np.abs(jv(2, beta * B) * yv(2, beta * A))
    assert np.all(np.abs(tors) < 1e-12 * scale)


@pytest.mark.parametrize(("m", "alpha"), sorted(ecm.EXACT_TABLE))
def test_theory_m_table(m, alpha):
    """theory_m.md §7(b), all roots below Ω = 21, given to 8 decimals."""
    ref = np.array(ecm.EXACT_TABLE[(m, alpha)])
    got = ecm.roots_m(m, alpha, A, B, n_roots=6, omega_max=21.0)
    assert np.isnan(got[5])  # exactly five roots below 21: none missing, none spurious
    np.testing.assert_allclose(got[:5], ref, rtol=2e-8, atol=0.0)


def test_long_wave_bending_limit():
    """m = 1: Ω²/α⁴ → 3(a² + b²)/4 (Euler–Bernoulli, E = 3μ); 1.787433 at α = 0.01 per
    theory_m.md §7(d); the α² extrapolation of α = 0.02 and 0.01 hits the limit."""
    ratio = {}
    for alpha in (0.02, 0.01):
        w = ecm.roots_m(1, alpha, A, B, n_roots=1, omega_max=3.0)[0]
        ratio[alpha] = w**2 / alpha**4
    assert abs(ratio[0.01] / 1.787433 - 1.0) < 1e-4
    limit = 0.75 * (A * A + B * B)
    extrapolated = (4.0 * ratio[0.01] - ratio[0.02]) / 3.0
    assert abs(extrapolated / limit - 1.0) < 1e-5


@pytest.mark.parametrize("m", [0, 1, 2, 3])
def test_continuous_through_the_shear_cutoff(m):
    """No pole and no spurious sign change at Ω = α; m = 0 has its simple torsional zero there."""
    alpha = 1.5
    eps = np.array([-1e-3, -1e-6, -1e-9, 0.0, 1e-9, 1e-6, 1e-3])
    d = ecm.characteristic_m(alpha * (1.0 + eps), alpha, A, B, m)
    assert np.all(np.isfinite(d))
    if m == 0:
        assert d[3] == 0.0 and np.all(d[:3] * d[0] > 0.0) and np.all(d[4:] * d[0] < 0.0)
    else:
        assert np.all(d * d[3] > 0.0)
        np.testing.assert_allclose(d[1:6], d[3], rtol=1e-4)


def _plain_characteristic(w, alpha, a, b, m):
    """Unscaled J_m, Y_m (I_m, K_m) basis, u from theory_m.md §7(b), scipy derivatives."""
    b2 = w * w - alpha * alpha
    mat = np.zeros((6, 6))
    for i, r in enumerate((a, b)):
        x = alpha * r
        fs = [(iv(m, x), alpha * ivp(m, x), alpha**2 * ivp(m, x, 2)),
              (kv(m, x), alpha * kvp(m, x), alpha**2 * kvp(m, x, 2))]
        if b2 > 0:
            be = np.sqrt(b2)
            zs = [(jv(m, be * r), be * jvp(m, be * r), b2 * jvp(m, be * r, 2)),
                  (yv(m, be * r), be * yvp(m, be * r), b2 * yvp(m, be * r, 2))]
        else:
            t = np.sqrt(-b2)
            zs = [(iv(m, t * r), t * ivp(m, t * r), t * t * ivp(m, t * r, 2)),
                  (kv(m, t * r), t * kvp(m, t * r), t * t * kvp(m, t * r, 2))]
        z0 = (0.0, 0.0, 0.0)
        for j, (f, g, h) in enumerate([(fs[0], z0, z0), (fs[1], z0, z0), (z0, zs[0], z0),
                                       (z0, zs[1], z0), (z0, z0, zs[0]), (z0, z0, zs[1])]):
            u = f[1] + m * g[0] / r + alpha * h[1]
            du = f[2] + m * g[1] / r - m * g[0] / r**2 + alpha * h[2]
            v = -m * f[0] / r - g[1] - m * alpha * h[0] / r
            dv = (-m * f[1] / r + m * f[0] / r**2 - g[2] - m * alpha * h[1] / r
                  + m * alpha * h[0] / r**2)
            dw = -alpha * f[1] + b2 * h[1]
            mat[3 * i:3 * i + 3, j] = (-w * w * f[0] + 2.0 * du, dv - (m * u + v) / r, dw - alpha * u)
    return np.linalg.det(mat / np.linalg.norm(mat, axis=0))


@pytest.mark.parametrize(("m", "alpha", "b", "omega_max"), [(2, 3.0, 1.5, 12.0), (3, 0.2, 3.0, 4.0)])
def test_against_plain_determinant(m, alpha, b, omega_max):
    """Same roots as the textbook determinant (its Ω = α bracket skipped), thick walls."""
    got = ecm.roots_m(m, alpha, 1.0, b, n_roots=30, omega_max=omega_max)
    got = got[np.isfinite(got)]
    grid = np.linspace(omega_max / 2999, omega_max, 2999)
    assert np.min(np.abs(grid - alpha)) > 1e-6
    vals = np.array([_plain_characteristic(w, alpha, 1.0, b, m) for w in grid])
    ref = [brentq(_plain_characteristic, grid[k], grid[k + 1], args=(alpha, 1.0, b, m), xtol=1e-14)
           for k in range(len(grid) - 1)
           if vals[k] * vals[k + 1] < 0.0 and not grid[k] <= alpha <= grid[k + 1]]
    assert len(got) == len(ref) >= 4
    np.testing.assert_allclose(got, ref, rtol=1e-12, atol=0.0)
