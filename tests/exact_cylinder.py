"""Independent reference solver: axisymmetric longitudinal modes of a hollow cylinder.

Exactly incompressible, linear-elastic, dimensionless (shear modulus = density = 1,
so the shear speed is 1).  Inner radius ``a``, outer radius ``b``, both faces
traction-free, fields ~ cos(alpha z) exp(i Omega t).  Only numpy and scipy are used.

Derivation (Navier: -grad p + Lap u = -Omega^2 u, div u = 0,
sigma = -p I + grad u + grad u^T), with u = grad phi + curl(psi e_theta),
phi = f(r) cos(alpha z), psi = g(r) sin(alpha z):

    u_r = (f' - alpha g) cos(alpha z),   u_z = (-alpha f + g' + g / r) sin(alpha z),
    f'' + f'/r - alpha^2 f = 0                      (div u = Lap phi = 0),
    g'' + g'/r + (beta^2 - 1/r^2) g = 0,  beta^2 = Omega^2 - alpha^2,
    p = Omega^2 phi,
    sigma_rr = [-Omega^2 f + 2 f'' - 2 alpha g'] cos(alpha z),
    sigma_rz = [-2 alpha f' + (alpha^2 - beta^2) g] sin(alpha z),

where g'' + g'/r - g/r^2 = -beta^2 g was used; alpha^2 - beta^2 = 2 alpha^2 - Omega^2.
These agree with the formulas in the brief (no sign corrections were needed).
"""

import time

import numpy as np
from scipy.optimize import brentq
from scipy.special import ive, j1, jvp, kve, y1, yvp


def _phi_column(alpha, r, a, b, kind):
    """Return (f, f') of the scaled potential basis function at radius r."""
    x = alpha * r
    if kind == 0:  # I0(alpha r) * exp(-alpha b)
        e = np.exp(alpha * (r - b))
        return ive(0, x) * e, alpha * ive(1, x) * e
    e = np.exp(-alpha * (r - a))  # K0(alpha r) * exp(alpha a)
    return kve(0, x) * e, -alpha * kve(1, x) * e


def _psi_column(beta2, r, a, b, kind):
    """Return (g, g') of the scaled shear basis function at radius r.

    The basis ``g1 = J1(beta r) / beta`` and ``g2 = (pi / 2) beta Y1(beta r)``
    (continued to ``I1(t r) / t`` and ``-t K1(t r)``, t^2 = -beta^2) tends to
    ``r / 2`` and ``-1 / r`` as beta -> 0 from either side; its Wronskian is
    1 / r for every beta, and ``g2`` differs from a basis function entire in
    beta^2 only by a multiple of ``g1`` (a column operation), so the determinant
    is continuous through Omega = alpha with no pole and no spurious sign change.
    On the modified side the columns are also multiplied by the positive factors
    exp(-t b) and exp(t a) to avoid overflow.
    """
    if beta2 > 0.0:
        beta = np.sqrt(beta2)
        x = beta * r
        if kind == 0:
            return j1(x) / beta, jvp(1, x)
        return 0.5 * np.pi * beta * y1(x), 0.5 * np.pi * beta2 * yvp(1, x)
    if beta2 < 0.0:
        t = np.sqrt(-beta2)
        x = t * r
        if kind == 0:
            e = np.exp(t * (r - b))
            return ive(1, x) / t * e, (ive(0, x) - ive(1, x) / x) * e
        e = np.exp(-t * (r - a))
        k1 = kve(1, x)
        return -t * k1 * e, -beta2 * (kve(0, x) + k1 / x) * e
    if kind == 0:
        return 0.5 * r, 0.5
    return -1.0 / r, 1.0 / r**2


def characteristic(omega, alpha, a, b):
    """Real, normalised frequency determinant of the free-free hollow cylinder.

    Rows are sigma_rr(a), sigma_rz(a), sigma_rr(b), sigma_rz(b); columns are the
    coefficients of the basis I0, K0 (potential) and g1, g2 (shear, see
    ``_psi_column``), exponentially pre-scaled with ``ive``/``kve``.  Every
    column is finally divided by its Euclidean norm, so the returned value is the
    Hadamard ratio det(M) / prod_j ||M_j||, which lies in [-1, 1].  All scalings
    are positive and continuous in Omega, so the zeros and signs are those of the
    plain determinant. The function is finite for alpha b up to several hundred
    and any moderate Omega.

    Args:
        omega: Dimensionless angular frequency Omega > 0.
        alpha: Axial wavenumber alpha > 0.
        a: Inner radius.
        b: Outer radius (b > a).

    Returns:
        The normalised determinant (a float).
    """
    omega2 = omega * omega
    beta2 = omega2 - alpha * alpha
    shear = 2.0 * alpha * alpha - omega2
    m = np.empty((4, 4))
    for i, r in enumerate((a, b)):
        for kind in (0, 1):
            f, df = _phi_column(alpha, r, a, b, kind)
            d2f = alpha * alpha * f - df / r
            m[2 * i, kind] = -omega2 * f + 2.0 * d2f
            m[2 * i + 1, kind] = -2.0 * alpha * df
            g, dg = _psi_column(beta2, r, a, b, kind)
            m[2 * i, 2 + kind] = -2.0 * alpha * dg
            m[2 * i + 1, 2 + kind] = shear * g
    return float(np.linalg.det(m / np.linalg.norm(m, axis=0)))


def roots(alpha, a, b, n_roots=3, omega_max=20.0, n_grid=4000):
    """Lowest frequencies Omega in (0, omega_max] of the axisymmetric modes.

    Sign changes of ``characteristic`` are bracketed on a uniform grid of
    ``n_grid`` steps, supplemented by geometric points below the first step (to
    catch the bar mode Omega ~ sqrt(3) alpha when alpha is tiny) and refined
    with brentq. ``characteristic`` is continuous in Omega (no poles, smooth
    through the branch point Omega = alpha), so every sign change is a genuine
    root and no filtering is required. The determinant has a trivial even-order
    zero at Omega = 0 (there curl(psi) and grad(phi) coincide); it does not
    produce a sign change, but below ~1e-3 alpha its value is rounding noise, so
    the grid starts there.

    Args:
        alpha: Axial wavenumber alpha > 0.
        a: Inner radius.
        b: Outer radius.
        n_roots: Number of roots returned.
        omega_max: Upper end of the search interval.
        n_grid: Number of uniform grid steps on (0, omega_max].

    Returns:
        Array of length n_roots, ascending, NaN padded.
    """
    step = omega_max / n_grid
    low = np.geomspace(min(1e-3 * alpha, 1e-3 * step), step, 60, endpoint=False)
    grid = np.concatenate([low, np.linspace(step, omega_max, n_grid)])
    vals = np.array([characteristic(w, alpha, a, b) for w in grid])
    out = np.full(n_roots, np.nan)
    count = 0
    for k in range(len(grid) - 1):
        if count == n_roots:
            break
        if vals[k] == 0.0:
            out[count] = grid[k]
            count += 1
        elif vals[k] * vals[k + 1] < 0.0:
            out[count] = brentq(
                characteristic,
                grid[k],
                grid[k + 1],
                args=(alpha, a, b),
                xtol=1e-14,
                rtol=1e-14,
            )
            count += 1
    return out


EXACT_K = [0.05, 0.2, 0.445, 0.89, 1.335, 2.0, 4.45]
EXACT_OMEGA = [
    [0.08657022721916413, 1.8486338957717863, 17.82048238633258],
    [0.34429111509770477, 1.8589591303699176, 17.824977520807998],
    [0.744973639952476, 1.9101153225260894, 17.843896336708884],
    [1.2788470734220378, 2.2212179317304592, 17.91468008869193],
    [1.4760565776412846, 2.8867662094886257, 18.031487240328914],
    [1.5758750462777027, 4.105756971916175, 18.28806672591196],
    [2.326565844040565, 8.730416006654675, 19.949573448412533],
]


if __name__ == "__main__":
    a0, b0 = 1.0, 1.0 / 0.85
    print(f"Reference check, a = {a0}, b = {b0:.6f} (eta = 0.85)")
    worst = 0.0
    t0 = time.perf_counter()
    for k, ref in zip(EXACT_K, EXACT_OMEGA, strict=False):
        got = roots(k, a0, b0)
        rel = np.abs(got - ref) / np.abs(ref)
        worst = max(worst, rel.max())
        print(f"  alpha={k:6.3f}  " + "  ".join(f"{w:.15f}" for w in got)
              + f"  max rel err={rel.max():.2e}")
    dt = time.perf_counter() - t0
    print(f"  max rel err = {worst:.3e}  ({dt:.2f} s, {dt / len(EXACT_K):.2f} s/alpha)")

    print("Grid stability, a = 1, b = 2 (eta = 0.5), n_grid 4000 vs 8000")
    for k in (0.05, 0.5, 5.0):
        r1, r2 = roots(k, 1.0, 2.0), roots(k, 1.0, 2.0, n_grid=8000)
        diff = np.max(np.abs(r1 - r2) / r1)
        print(f"  alpha={k:5.2f}  " + "  ".join(f"{w:.12f}" for w in r1)
              + f"  max rel diff={diff:.1e}")

    k = 1e-3
    w0 = roots(k, 1.0, 2.0, n_roots=1)[0]
    print(f"Bar limit, a = 1, b = 2, alpha = {k}: Omega/alpha = {w0 / k:.10f}, "
          f"|Omega/alpha - sqrt(3)| = {abs(w0 / k - np.sqrt(3.0)):.2e}")
    w0 = roots(k, a0, b0, n_roots=1)[0]
    print(f"Bar limit, a = 1, b = 1/0.85, alpha = {k}: Omega/alpha = {w0 / k:.10f}, "
          f"|Omega/alpha - sqrt(3)| = {abs(w0 / k - np.sqrt(3.0)):.2e}")
