"""Independent reference solver: free vibrations of order m of a hollow cylinder.

Exactly incompressible, linear-elastic, unstretched, dimensionless (shear modulus =
density = 1, shear speed 1).  Inner radius ``a``, outer radius ``b``, both faces
traction-free.  Fields of circumferential order m >= 0 and axial wavenumber alpha:

    u_r = U(r) cos(m theta) cos(alpha z),   u_theta = V(r) sin(m theta) cos(alpha z),
    u_z = W(r) cos(m theta) sin(alpha z),   p = P(r) cos(m theta) cos(alpha z),

times exp(i Omega t).  Only numpy and scipy are used (no jaxdea import).

Derivation (Navier: -grad p + Lap u = -Omega^2 u, div u = 0,
sigma = -p I + grad u + grad u^T).  With

    u = grad phi + curl(chi e_z) + curl curl(psi e_z),
    phi = f(r) cos(m theta) cos(alpha z),  chi = g(r) sin(m theta) cos(alpha z),
    psi = h(r) cos(m theta) sin(alpha z),

div u = Lap phi, so Lap phi = 0; Lap grad phi = grad Lap phi = 0 and the vector
Laplacian commutes with curl, so the momentum equation holds with p = Omega^2 phi and
(Lap + Omega^2)(chi, psi) = 0.  Hence (beta^2 = Omega^2 - alpha^2)

    f'' + f'/r - (m^2/r^2 + alpha^2) f = 0    ->  f in {I_m(alpha r), K_m(alpha r)},
    g'' + g'/r - (m^2/r^2 - beta^2) g = 0     ->  g, h in {J_m(beta r), Y_m(beta r)}
                                                  ({I_m, K_m}(t r), t^2 = -beta^2 > 0),

and, from curl(A e_z) = (A_theta / r, -A_r, 0), curl curl(psi e_z) = grad(psi_z) - Lap psi e_z:

    U = f' + m g / r + alpha h',   V = -m f / r - g' - m alpha h / r,
    W = -alpha f + beta^2 h,       P = Omega^2 f,
    sigma_rr     = [-P + 2 U']                    cos(m theta) cos(alpha z),
    sigma_rtheta = [V' - (m U + V) / r]           sin(m theta) cos(alpha z),
    sigma_rz     = [W' - alpha U]                 cos(m theta) sin(alpha z).

(These agree with theory_m.md section 7(b); no sign corrections were needed.)

Basis, continuous through Omega = alpha.  With the radial functions normalised as

    Jh_n = J_n(beta r) / beta^n        (= I_n(t r) / t^n    for beta^2 = -t^2 < 0),
    Yh_n = (pi/2) beta^n Y_n(beta r)   (= -t^n K_n(t r)     for beta^2 = -t^2 < 0),

Jh_n is entire in beta^2 and Yh_n is entire in beta^2 up to the term
beta^(2n) ln|beta| Jh_n (A&S 9.1.11, 9.6.11), which is subtracted near beta = 0
(a column operation).  Both families obey Z'' + Z'/r + (beta^2 - n^2/r^2) Z = 0 and

    Jh_n' - n Jh_n / r = -beta^2 Jh_{n+1},   Jh_n' + n Jh_n / r = Jh_{n-1},
    Yh_n' - n Yh_n / r = -Yh_{n+1},          Yh_n' + n Yh_n / r = beta^2 Yh_{n-1}.

At beta = 0 the chi and psi columns are dependent (both reduce to the same planar
harmonic field), so the psi columns are replaced by the column combinations

    (h - alpha g)[Jh_m] / beta^2:  U = V = -alpha Jh_{m+1},         W = Jh_m,
    (h + alpha g)[Yh_m] / beta^2:  U = alpha Yh_{m-1}, V = -U,      W = Yh_m    (m >= 1),

and for m = 0 (where the chi field is pure torsion, V = -g') by
g[Jh_0] / beta^2 -> V = Jh_1;  h[Jh_0] / beta^2 -> U = -alpha Jh_1, W = Jh_0;
g[Yh_0] -> V = Yh_1;  h[Yh_0] -> U = -alpha Yh_1, W = beta^2 Yh_0.
In every case the determinant is the plain one divided by beta^4 > 0: no pole and no
spurious sign change at Omega = alpha, so no bracket needs excluding; a genuine zero
there (the m = 0 rigid twist V ~ r at Omega = alpha) is a simple sign change.  The phi
columns use the same two families at beta^2 = -alpha^2, i.e. I_m(alpha r) / alpha^m and
-alpha^m K_m(alpha r).  All tractions are written with the recurrences (``_columns``), so
no matrix entry is a difference of nearly equal numbers.  Omega = 0 is a trivial zero of
order Omega^4 (phi and psi columns coincide in the static limit).

Checks (``python tests/exact_cylinder_m.py`` and tests/test_exact_cylinder_m.py): m = 0
gives the union of exact_cylinder.roots and ``torsion_roots`` to ~1e-15; the
theory_m.md section 7(b) table to its 8 decimals; its 7(f) large-alpha roots (m = 2,
alpha = 40, 80, 160) to 8 decimals; the m = 1 bending limit; a plain J_m/Y_m determinant
with scipy derivatives to ~1e-13.
"""

import math
import time

import numpy as np
from scipy.optimize import brentq
from scipy.special import digamma, iv, ive, jv, kv, kve, yv

_SERIES = 1e-6  # |beta^2| b^2 below this: power series in beta^2
_LOGSUB = 1.0  # |beta^2| b^2 below this: unscaled functions, log term subtracted


def _series(kind, n, beta2, r):
    """Power series (4 terms) of Jh_n or of Yh_n minus its beta^(2n) ln|beta| Jh_n term."""
    x = r / 2.0
    jh = sum((-beta2) ** k * x ** (n + 2 * k) / (math.factorial(k) * math.factorial(n + k))
             for k in range(4))
    if kind == "J":
        return jh
    val = -0.5 * sum(math.factorial(n - k - 1) / math.factorial(k) * x ** (2 * k - n) * beta2**k
                     for k in range(n))
    val = val + beta2**n * np.log(x) * jh
    val = val - 0.5 * sum(
        (-1.0) ** k * (digamma(k + 1.0) + digamma(n + k + 1.0)) * x ** (n + 2 * k)
        * beta2 ** (n + k) / (math.factorial(k) * math.factorial(n + k)) for k in range(4))
    return val


def _radial(kind, n, beta2, r, a, b):
    """Value of Jh_n ("J") or Yh_n ("Y") at radius r for an array of beta^2.

    Scaling per regime (the same for every n and r, so it is a positive column factor):
    oscillatory beta^2 b^2 >= 1: none; modified t b >= 1: exp(-t b) for Jh, exp(t a) for Yh;
    small |beta^2| b^2 < 1: none, and Yh_n -> Yh_n - beta^(2n) ln|beta| Jh_n.
    """
    beta2 = np.asarray(beta2, dtype=float)
    out = np.empty_like(beta2)
    q = beta2 * b * b
    osc, mod = q >= _LOGSUB, q <= -_LOGSUB
    ser = np.abs(q) < _SERIES
    small = ~(osc | mod | ser)
    if osc.any():
        be = np.sqrt(beta2[osc])
        if kind == "J":
            out[osc] = jv(n, be * r) / be**n
        else:
            out[osc] = 0.5 * np.pi * be**n * yv(n, be * r)
    if mod.any():
        t = np.sqrt(-beta2[mod])
        if kind == "J":
            out[mod] = ive(n, t * r) * np.exp(t * (r - b)) / t**n
        else:
            out[mod] = -(t**n) * kve(n, t * r) * np.exp(-t * (r - a))
    if small.any():
        b2 = beta2[small]
        s = np.sqrt(np.abs(b2))
        pos = b2 > 0
        jh = np.where(pos, jv(n, s * r), iv(n, s * r)) / s**n
        if kind == "J":
            out[small] = jh
        else:
            yh = np.where(pos, 0.5 * np.pi * s**n * yv(n, s * r), -(s**n) * kv(n, s * r))
            out[small] = yh - b2**n * np.log(s) * jh
    if ser.any():
        out[ser] = _series(kind, n, beta2[ser], r)
    return out


def _family(kind, beta2, r, a, b, ns, analytic=False):
    """{n: Z_n(r)} of the family Jh ("J") or Yh ("Y") at the parameter beta^2 (an array);
    ``analytic``: complex and unscaled (:func:`_radial_complex`)."""
    if analytic:
        return {n: _radial_complex(kind, n, beta2, r) for n in ns}
    return {n: _radial(kind, n, beta2, r, a, b) for n in ns}


def _columns(omega, alpha, a, b, m, analytic=False, displacements=False):
    """Tractions (sigma_rr, sigma_rtheta, sigma_rz at a, then at b) of the six basis fields.

    Every traction is written with the recurrences of the module docstring so that no
    entry is a difference of nearly equal terms (e.g. sigma_rtheta of the (psi - alpha chi)
    column is alpha beta^2 Jh_{m+2}, not V' - (m U + V) / r evaluated numerically), which
    matters for the long-wave bending mode (Omega ~ alpha^2).  With s the parameter of the
    family (s = -alpha^2 for phi, s = beta^2 otherwise) and R = s for Jh, R = 1 for Yh:

      phi[Z_m]:   U = m Z_m/r - R Z_{m+1},  V = -m Z_m/r,  W = -alpha Z_m,  P = Omega^2 Z_m,
                  f'' = m(m-1) Z_m/r^2 + alpha^2 Z_m + R Z_{m+1}/r;
      chi[Z_m]:   U = m Z_m/r,  V = -(m Z_m/r - R Z_{m+1}),  W = 0;
      (psi - alpha chi)[Jh_m]/beta^2 and (psi + alpha chi)[Yh_m]/beta^2: see below.

    ``analytic``: complex arithmetic with the unscaled functions of :func:`_radial_complex` (a
    complex α̂; the tractions are then analytic in α̂).

    Returns an array (N, 6, 6) of tractions and (N, 6) of the Euclidean norm of each
    column's (U, V, W, tractions) at both faces.
    """
    dtype = complex if analytic else float
    omega = np.atleast_1d(np.asarray(omega, dtype=dtype))
    om2 = omega * omega
    s = om2 - alpha * alpha
    n = omega.size
    sphi = np.full(n, -alpha * alpha, dtype=dtype)
    sig = np.zeros((n, 6, 6), dtype=dtype)
    disp = np.zeros((n, 6, 6), dtype=dtype)
    zero = np.zeros(n, dtype=dtype)
    family = lambda kind, beta2, r, a, b, ns: _family(kind, beta2, r, a, b, ns, analytic)  # noqa: E731
    for i, r in enumerate((a, b)):
        cols = []  # each: (U, V, W, sigma_rr, sigma_rtheta, sigma_rz)
        for kind in ("J", "Y"):  # phi: I_m(alpha r) / alpha^m and -alpha^m K_m(alpha r)
            z = family(kind, sphi, r, a, b, (m, m + 1))
            rr = -alpha * alpha if kind == "J" else 1.0
            du = m * z[m] / r - rr * z[m + 1]
            d2f = m * (m - 1) * z[m] / r**2 + alpha * alpha * z[m] + rr * z[m + 1] / r
            cols.append((du, -m * z[m] / r, -alpha * z[m],
                         -om2 * z[m] + 2.0 * d2f,
                         -2.0 * m * (-rr * z[m + 1] + (m - 1) * z[m] / r) / r,
                         -2.0 * alpha * du))
        if m == 0:
            for kind in ("J", "Y"):  # chi[Jh_0] / beta^2 and chi[Yh_0]: V = Z_1
                z = family(kind, s, r, a, b, (1, 2))
                rr = s if kind == "J" else 1.0
                cols.append((zero, z[1], zero, zero, -rr * z[2], zero))
            z = family("J", s, r, a, b, (0, 1))  # psi[Jh_0] / beta^2: U = -alpha Z_1, W = Z_0
            cols.append((-alpha * z[1], zero, z[0], -2.0 * alpha * (z[0] - z[1] / r), zero,
                         (alpha * alpha - s) * z[1]))
            z = family("Y", s, r, a, b, (0, 1))  # psi[Yh_0]: U = -alpha Z_1, W = beta^2 Z_0
            cols.append((-alpha * z[1], zero, s * z[0], -2.0 * alpha * (s * z[0] - z[1] / r),
                         zero, (alpha * alpha - s) * z[1]))
        else:
            for kind in ("J", "Y"):  # chi[Z_m]
                z = family(kind, s, r, a, b, (m, m + 1))
                rr = s if kind == "J" else 1.0
                cols.append((m * z[m] / r, -(m * z[m] / r - rr * z[m + 1]), zero,
                             2.0 * m * (-rr * z[m + 1] + (m - 1) * z[m] / r) / r,
                             -2.0 * rr * z[m + 1] / r - 2.0 * m * (m - 1) * z[m] / r**2
                             + s * z[m],
                             -alpha * m * z[m] / r))
            # (psi - alpha chi)[Jh_m] / beta^2: U = V = -alpha Jh_{m+1}, W = Jh_m
            z = family("J", s, r, a, b, (m, m + 1, m + 2))
            cols.append((-alpha * z[m + 1], -alpha * z[m + 1], z[m],
                         -2.0 * alpha * (z[m] - (m + 1) * z[m + 1] / r),
                         alpha * s * z[m + 2],
                         m * z[m] / r + (alpha * alpha - s) * z[m + 1]))
            # (psi + alpha chi)[Yh_m] / beta^2: U = -V = alpha Yh_{m-1}, W = Yh_m
            z = family("Y", s, r, a, b, (max(m - 2, 0), m - 1, m, 1))
            srt = alpha * z[1] if m == 1 else -alpha * s * z[m - 2]
            cols.append((alpha * z[m - 1], -alpha * z[m - 1], z[m],
                         2.0 * alpha * ((m - 1) * z[m - 1] / r - z[m]),
                         srt,
                         (s - alpha * alpha) * z[m - 1] - m * z[m] / r))
        for j, (u, v, w, srr, srt, srz) in enumerate(cols):
            sig[:, 3 * i, j], sig[:, 3 * i + 1, j], sig[:, 3 * i + 2, j] = srr, srt, srz
            disp[:, 3 * i, j], disp[:, 3 * i + 1, j], disp[:, 3 * i + 2, j] = u, v, w
    norm = np.sqrt(np.sum(np.abs(sig)**2, axis=1) + np.sum(np.abs(disp)**2, axis=1))
    if displacements:
        return sig, norm, disp
    return sig, norm


def characteristic_m(omega, alpha, a, b, m):
    """Real, normalised frequency determinant of order m of the free-free hollow cylinder.

    The 6x6 determinant of (sigma_rr, sigma_rtheta, sigma_rz) at r = a and r = b over the
    basis described in the module docstring, each column divided by the Euclidean norm of
    its displacements and tractions at both faces (so the value lies in [-1, 1]).  All
    scalings are positive, and the basis is continuous through Omega = alpha, so the zeros
    and sign changes are those of the frequency equation.  Vectorised over ``omega``.

    Args:
        omega: Dimensionless angular frequency (scalar or array), Omega > 0.
        alpha: Axial wavenumber alpha > 0.
        a: Inner radius.
        b: Outer radius (b > a).
        m: Circumferential order, integer >= 0.

    Returns:
        A float (scalar omega) or an array of floats.
    """
    m = int(m)
    sig, norm = _columns(omega, alpha, a, b, m)
    d = np.linalg.det(sig / norm[:, None, :])
    return float(d[0]) if np.ndim(omega) == 0 else d


def characteristic_m_outer(omega, alpha, a, b, m, rho_o, c_o):
    """:func:`characteristic_m` with an unbounded acoustic fluid outside (density ``rho_o``, sound
    speed ``c_o`` in units of the solid's; subsonic: Omega < c_o alpha). The fluid pressure
    p = A K_m(gamma r) (Helmholtz: gamma^2 = alpha^2 - Omega^2/c_o^2), with rho_o Omega^2 u_r = dp/dr
    at r = b, loads the outer face: sigma_rr(b) = -p(b) = -rho_o Omega^2 K_m/(gamma K_m') U(b), and
    sigma_rtheta = sigma_rz = 0 (inviscid). Scalar ``omega``; scipy's ``kve``."""
    m = int(m)
    sig, norm, disp = _columns(omega, alpha, a, b, m, displacements=True)
    gamma = math.sqrt(alpha * alpha - omega * omega / (c_o * c_o))
    y = gamma * b
    k_prime = -0.5 * (kve(m - 1, y) + kve(m + 1, y))  # K_m'(y) e^y
    sig[:, 3, :] += rho_o * omega * omega * kve(m, y) / (gamma * k_prime) * disp[:, 3, :]
    return float(np.linalg.det(sig / norm[:, None, :])[0])


def _torsion(omega, alpha, a, b):
    """Normalised 2x2 determinant of sigma_rtheta = V' - V/r = -R Z_2 for V = Z_1."""
    om = np.atleast_1d(np.asarray(omega, dtype=float))
    beta2 = om * om - alpha * alpha
    mat = np.empty((om.size, 2, 2))
    nrm = np.zeros((om.size, 2))
    for i, r in enumerate((a, b)):
        for j, (kind, fac) in enumerate((("J", beta2), ("Y", 1.0))):
            v = _radial(kind, 1, beta2, r, a, b)
            mat[:, i, j] = -fac * _radial(kind, 2, beta2, r, a, b)
            nrm[:, j] += v * v + mat[:, i, j] ** 2
    d = np.linalg.det(mat / np.sqrt(nrm)[:, None, :])
    return float(d[0]) if np.ndim(omega) == 0 else d


def _grid(omega_max, n_grid, alpha, b, m):
    """Uniform grid plus geometric points below its first step.

    The lowest point is 1e-3 alpha, except for m = 1, where it is min(0.1 b alpha^2,
    0.1 alpha), below the long-wave bending mode Omega ~ sqrt(3 (a^2 + b^2) / 4) alpha^2
    (>= 0.87 b alpha^2).  Far below alpha^2 the determinant has a trivial zero of order
    Omega^4 at Omega = 0 (the phi and psi columns coincide in the static limit) and its
    value there is rounding noise; no mode of any order lies that low.  Known limit: for
    m >= 2 and alpha ~ 1e-3 the noise reaches ~b alpha^2 > 1e-3 alpha (thin walls), which
    shows up as an unstable sign-change count (RuntimeError in ``_roots``), not as roots.
    """
    step = omega_max / n_grid
    lo = min(0.1 * b * alpha * alpha, 0.1 * alpha) if m == 1 else 1e-3 * alpha
    low = np.geomspace(lo, step, 80, endpoint=False) if lo < step else np.empty(0)
    return np.concatenate([low, np.linspace(step, omega_max, n_grid)])


def _scan(fun, args, grid, n_roots):
    vals = fun(grid, *args)
    out = []
    for k in range(len(grid) - 1):
        if len(out) == n_roots:
            break
        if vals[k] == 0.0:
            out.append(grid[k])
        elif vals[k] * vals[k + 1] < 0.0:
            out.append(brentq(lambda w: float(fun(w, *args)), grid[k], grid[k + 1],
                              xtol=1e-15, rtol=1e-15, maxiter=200))
    return np.array(out), int(np.sum(vals[:-1] * vals[1:] < 0.0) + np.sum(vals == 0.0))


def _roots(fun, args, m, n_roots, omega_max, n_grid, max_doublings):
    """Roots on a scan grid, doubled until the number of sign changes is unchanged."""
    alpha, b = args[0], args[2]
    found, count = _scan(fun, args, _grid(omega_max, n_grid, alpha, b, m), n_roots)
    for _ in range(max_doublings):
        n_grid *= 2
        found2, count2 = _scan(fun, args, _grid(omega_max, n_grid, alpha, b, m), n_roots)
        stable = count2 == count
        found, count = found2, count2
        if stable:
            break
    else:
        raise RuntimeError("root count not stable under grid refinement")
    out = np.full(n_roots, np.nan)
    out[: len(found)] = found
    return out


def roots_m(m, alpha, a, b, n_roots=5, omega_max=21.0, n_grid=2000, max_doublings=6):
    """Lowest frequencies Omega in (0, omega_max] of the modes of order m.

    Sign changes of ``characteristic_m`` on a uniform grid of ``n_grid`` steps (plus
    geometric points below the first step, see ``_grid``; for m = 1 they reach below the
    long-wave bending mode Omega ~ alpha^2) are refined with brentq.  The grid is doubled
    until the total number of sign changes below ``omega_max`` repeats (a missed close
    pair, or rounding noise, would show up as a changed count; RuntimeError if it never
    settles).  The determinant is continuous in Omega (including Omega = alpha), so every
    sign change is a root; Omega = 0 is a trivial even-order zero and is not reported.
    Accuracy: ~1e-14 relative in general; the m = 1 bending root loses digits as alpha
    -> 0 (near-static, near-rigid determinant; rounding noise ~ alpha^-5): spread of
    Omega^2/alpha^4 over brentq brackets, a = 1, b = 1/0.85: 5e-10 at alpha = 0.04,
    4e-9 at 0.02, 1e-7 at 0.01, 3e-6 at 0.005, 6e-5 at 0.0025, 2e-3 at 0.001.

    Args:
        m: Circumferential order (>= 0).
        alpha: Axial wavenumber alpha > 0.
        a: Inner radius.
        b: Outer radius.
        n_roots: Number of roots returned.
        omega_max: Upper end of the search interval.
        n_grid: Initial number of uniform grid steps.
        max_doublings: Maximum number of grid doublings.

    Returns:
        Array of length n_roots, ascending, NaN padded.
    """
    return _roots(characteristic_m, (alpha, a, b, int(m)), int(m), n_roots, omega_max,
                  n_grid, max_doublings)


def torsion_roots(alpha, a, b, n_roots=3, omega_max=21.0, n_grid=2000, max_doublings=6):
    """Lowest torsional (m = 0, u_theta only) frequencies; the first is Omega = alpha exactly.

    V = Z_1(beta r) (Jh_1 = J_1(beta r)/beta, Yh_1 = (pi/2) beta Y_1(beta r), continued to
    I_1/t, -t K_1), sigma_rtheta = V' - V/r = -beta^2 Jh_2, resp. -Yh_2, at r = a, b.  The
    2x2 determinant has a simple zero at beta = 0 (rigid-like twist V ~ r); above it,
    J_2(beta a) Y_2(beta b) - J_2(beta b) Y_2(beta a) = 0.
    """
    return _roots(_torsion, (alpha, a, b), 0, n_roots, omega_max, n_grid, max_doublings)


EXACT_TABLE = {  # theory_m.md section 7(b): a = 1, b = 1/0.85
    (1, 0.534): [0.27304509, 1.22366123, 2.72102485, 17.86345744, 18.01774454],
    (1, 1.5): [0.98534049, 1.97940334, 3.72491886, 17.95486789, 18.21048515],
    (2, 0.534): [0.26753475, 1.96497658, 4.17829830, 17.92863525, 18.32878359],
    (2, 1.5): [0.69877963, 2.53032586, 4.92738770, 18.00555853, 18.52888065],
    (3, 0.534): [0.64836308, 2.82967936, 5.79768505, 18.04544640, 18.81858430],
    (3, 1.5): [0.87100773, 3.23062751, 6.37125587, 18.11397749, 19.01639974],
}


if __name__ == "__main__":
    a0, b0 = 1.0, 1.0 / 0.85
    t0 = time.perf_counter()
    for (m0, k), ref in EXACT_TABLE.items():
        got = roots_m(m0, k, a0, b0)
        rel = np.abs(got - ref) / np.array(ref)
        print(f"m={m0} alpha={k}: " + " ".join(f"{w:.12f}" for w in got)
              + f"  max rel={rel.max():.2e}")
    print(f"({time.perf_counter() - t0:.2f} s)")


def _radial_complex(kind, n, beta2, r):
    """Jh_n = J_n(βr)/β^n or Yh_n = (π/2) β^n Y_n(βr) at complex β² (principal β), unscaled:
    the same two solutions as :func:`_radial`, analytic in β² off the negative real axis."""
    be = np.sqrt(np.asarray(beta2, dtype=complex))
    if kind == "J":
        return jv(n, be * r) / be**n
    return 0.5 * np.pi * be**n * yv(n, be * r)


def determinant_complex(omega, alpha, a, b, m):
    """The unnormalised 6x6 traction determinant of :func:`characteristic_m` at a complex α̂ (and
    Ω): analytic in α̂ away from the cuts of the principal square roots (β² ≤ 0, α̂² ≥ 0 real),
    with the zeros of the frequency equation (theory_next.md §5, complex wavenumbers)."""
    sig, _ = _columns(omega, complex(alpha), a, b, m, analytic=True)
    return complex(np.linalg.det(sig[0]))


def complex_root(omega, alpha0, a, b, m, tol=1e-13, steps=60):
    """A complex wavenumber of the exact cylinder near ``alpha0`` by the secant method on
    :func:`determinant_complex`."""
    x0, x1 = complex(alpha0), complex(alpha0) * (1 + 1e-6)
    f0, f1 = determinant_complex(omega, x0, a, b, m), determinant_complex(omega, x1, a, b, m)
    for _ in range(steps):
        x2 = x1 - f1 * (x1 - x0) / (f1 - f0)
        if abs(x2 - x1) < tol * abs(x2):
            return x2
        x0, f0, x1, f1 = x1, f1, x2, determinant_complex(omega, x2, a, b, m)
    raise RuntimeError("secant did not converge")


def determinant_outer_complex(omega, alpha, a, b, m, rho_o, c_o):
    """The unnormalised determinant of :func:`characteristic_m_outer` at a complex Ω right of the
    sound line (Re Ω > c_o α): the outgoing wave p = A H_m^(2)(kr), k = sqrt(Ω²/c_o² − α²)
    (principal), written as K_m(γr) with γ = ik (K_m(ix) ∝ H_m^(2)(x)), SciPy's principal-branch
    ``kv`` at complex argument: a leaky mode (Im Ω > 0) grows radially."""
    m = int(m)
    sig, _, disp = _columns(complex(omega), complex(alpha), a, b, m, analytic=True,
                            displacements=True)
    gamma = 1j * np.sqrt(complex(omega) ** 2 / c_o**2 - alpha**2)
    y = gamma * b
    k_prime = -0.5 * (kv(m - 1, y) + kv(m + 1, y))
    sig[:, 3, :] += rho_o * complex(omega) ** 2 * kv(m, y) / (gamma * k_prime) * disp[:, 3, :]
    return complex(np.linalg.det(sig[0]))


def leaky_root(guess, alpha, a, b, m, rho_o, c_o, tol=1e-14, steps=80):
    """A leaky complex frequency of the exact cylinder in an unbounded fluid near ``guess``, by the
    secant method on :func:`determinant_outer_complex`."""
    def f(w):
        return determinant_outer_complex(w, alpha, a, b, m, rho_o, c_o)

    x0, x1 = complex(guess), complex(guess) * (1 + 1e-6)
    f0, f1 = f(x0), f(x1)
    for _ in range(steps):
        x2 = x1 - f1 * (x1 - x0) / (f1 - f0)
        if abs(x2 - x1) < tol * abs(x2):
            return x2
        x0, f0, x1, f1 = x1, f1, x2, f(x2)
    raise RuntimeError("secant did not converge")
