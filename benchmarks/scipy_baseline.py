"""The straightforward NumPy/SciPy implementation of jaxdea's method: the baseline of the benchmarks.

This is the code a researcher would write from docs/theory/axisymmetric.md §1–4, independent of jaxdea (no
import of it): the same corrected physics and the same discretisation, in plain NumPy/SciPy loops.

* Base state (docs/theory/axisymmetric.md §1): λ(r̂) = r̂/sqrt(λ_z(r̂² − r̂_i²) + 1),
  D̂_r = V̂/(r̂ ln(r̂_o/r̂_i)),
  ΔP̂ = ∫ 2W_1(λ² − λ_r²) dr̂/r̂ − V̂²(1 − r̂_i²/r̂_o²)/(2 r̂_i² ln²(r̂_o/r̂_i)) by ``scipy.integrate.quad``,
  p̂ = 2W_1λ_r² + D̂_r² − τ̂_rr (gauge P̂_o = 0, P̂_i = ΔP̂), Gent W_1 = 1/(2[1 − (I_1 − 3)/G]),
  W_11 = 2W_1²/G.
* Closed-form moduli combinations a, b, c, d, g, q (docs/theory/axisymmetric.md §3, corrected Eq. 33) and the
  6×6 state matrix M(r̂) (corrected Eq. 40).
* Laminate (Eqs. 42–44): N equal sublayers, T_k = ``scipy.linalg.expm``((ĥ/N) M(r̂_k)) at the
  mid-radii, A = T_N ⋯ T_1 (plain 6×6 products).
* Characteristic function (docs/theory/axisymmetric.md §4): det(B A S) with B the rows Φ, T̄, S̄ at r̂_o and S
  the 6×3 initial basis (follower pressure ΔP̂ at r̂_i; the consistent acoustic fluid coupling with the
  pole-free pair N_0 = r̂_i J_0(x), D_0 = −x J_1(x), or r̂_i I_0(x̃), x̃ I_1(x̃), from
  ``scipy.special``). ``normalise=True`` returns det(B Q) with A S = Q R the QR factorisation
  (diag R > 0): the same zeros and sign, in [−1, 1]; Q is unique, so this is the very function that
  jaxdea computes by re-orthonormalising layer by layer (:func:`jaxdea.characteristic`).
* Roots: a uniform Ω grid (step Δ = min(π c_min/ĥ, π ĉ_f/r̂_i)/16, c_min the slowest shear speed),
  sign changes, ``scipy.optimize.brentq`` in each bracket, upwards until ``n_roots`` are found or
  Ω_max is passed (Ω_max = (n_roots + 1)π c_max/ĥ + 3α̂ c_max when not given).

Unlike jaxdea the scan sees sign changes only: two roots inside one grid step are missed (jaxdea
classifies each step with the slopes at its ends and finds such pairs). Only the Gent energy (and its
neo-Hookean limit G = inf) and the acoustic coupling are implemented.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import scipy.integrate
import scipy.linalg
import scipy.optimize
import scipy.special

U, W, PHI, T, S, D = range(6)
OUTER_ROWS = [PHI, T, S]


@dataclasses.dataclass(frozen=True)
class Tube:
    """Tube parameters (the fields of ``jaxdea.Tube``; any object with these attributes works)."""

    voltage: float = 0.0
    lambda_i: float = 1.0
    lambda_z: float = 1.0
    eta: float = 0.85
    gent: float = 97.2
    length_ratio: float = 10.0


@dataclasses.dataclass(frozen=True)
class Fluid:
    """Acoustic fluid: density ratio ρ̂_f and speed ratio ĉ_f (the consistent coupling only)."""

    density_ratio: float = 0.13
    speed_ratio: float = 0.27


@dataclasses.dataclass(frozen=True)
class Wall:
    """The discretised wall: radii, sublayer step and the coefficients at the N mid-radii."""

    r_inner: float
    r_outer: float
    radii: np.ndarray
    step: float
    coef: dict
    pressure_inner: float


def axial_wavenumber(tube, n) -> float:
    """α̂ = 2nπη/(length_ratio·λ_z)."""
    return 2.0 * math.pi * n * float(tube.eta) / (float(tube.length_ratio) * float(tube.lambda_z))


def gent_derivatives(i1, gent):
    """W_1 = 1/(2[1 − (I_1 − 3)/G]), W_11 = 2W_1²/G (μ = 1); neo-Hookean for G = inf."""
    if math.isinf(gent):
        return 0.5 + 0.0 * i1, 0.0 * i1
    w1 = 0.5 / (1.0 - (i1 - 3.0) / gent)
    return w1, 2.0 * w1**2 / gent


def radii(tube):
    """(r̂_i, r̂_o) = (λ_i, sqrt(λ_i² + (η⁻² − 1)/λ_z))."""
    li, lz, eta = float(tube.lambda_i), float(tube.lambda_z), float(tube.eta)
    return li, math.sqrt(li**2 + (eta**-2 - 1.0) / lz)


def _stretches(tube, r):
    li, lz = float(tube.lambda_i), float(tube.lambda_z)
    lam = r / np.sqrt(lz * (r**2 - li**2) + 1.0)
    return lam, 1.0 / (lam * lz)


def _elastic_integrand(r, tube):
    lam, lam_r = _stretches(tube, r)
    w1, _ = gent_derivatives(lam_r**2 + lam**2 + float(tube.lambda_z) ** 2, float(tube.gent))
    return 2.0 * w1 * (lam**2 - lam_r**2) / r


def _elastic_integral(tube, r_end):
    ri, _ = radii(tube)
    value, _ = scipy.integrate.quad(_elastic_integrand, ri, r_end, args=(tube,), epsabs=1e-15,
                                    epsrel=1e-14, limit=200)
    return value


def _electric_integral(tube, r_end):
    """∫_{r̂_i}^{r} D̂_r² dr̂/r̂ = V̂²(1/r̂_i² − 1/r²)/(2 ln²(r̂_o/r̂_i))."""
    ri, ro = radii(tube)
    return float(tube.voltage) ** 2 * (ri**-2 - r_end**-2) / (2.0 * math.log(ro / ri) ** 2)


def pressure_difference(tube) -> float:
    """ΔP̂ (docs/theory/axisymmetric.md Eq. 1.1)."""
    _, ro = radii(tube)
    return _elastic_integral(tube, ro) - _electric_integral(tube, ro)


def coefficients(tube, r, delta_p):
    """a, b, c, d, g, q, p at the radii r (docs/theory/axisymmetric.md §3 closed forms; p from Eq. 1.3)."""
    lz, gent = float(tube.lambda_z), float(tube.gent)
    ri, ro = radii(tube)
    lam, lam_r = _stretches(tube, r)
    w1, w11 = gent_derivatives(lam_r**2 + lam**2 + lz**2, gent)
    dr = float(tube.voltage) / (r * math.log(ro / ri))
    tau_rr = np.array([-delta_p + _elastic_integral(tube, x) - _electric_integral(tube, x) for x in r])
    p = 2.0 * w1 * lam_r**2 + dr**2 - tau_rr
    dd = dr * dr
    s = 1.0 - lam**4 * lz**2
    return dict(
        a=2 * w1 * lz**2,
        b=0.5 * (4 * w11 * (lz**2 - lam_r**2) ** 2 + 2 * w1 * (lz**2 + lam_r**2) + dd),
        c=2 * w1 * lam_r**2 + dd,
        d=dr,
        g=4 * w11 * lam_r**4 * s * (2 * lam**2 * lz**4 - lam**4 * lz**2 - 1) - 2 * w1 * lam_r**2 * s - dd,
        q=4 * w11 * lam_r**4 * (1 - lam**2 * lz**4) * s + 2 * w1 * lam_r**2 + dd,
        p=p,
    )


def discretize(tube, n_layers: int) -> Wall:
    """N equal sublayers with the coefficients at their mid-radii (paper Eq. 42)."""
    ri, ro = radii(tube)
    step = (ro - ri) / n_layers
    mid = ri + (np.arange(n_layers) + 0.5) * step
    delta_p = pressure_difference(tube)
    return Wall(ri, ro, mid, step, coefficients(tube, mid, delta_p), delta_p)


def state_matrix(coef, k, r, omega, alpha):
    """M(r̂) of docs/theory/axisymmetric.md §3 at sublayer k (ε = 1)."""
    a, b, c, d, g, q, p = (coef[x][k] for x in "abcdgqp")
    shear = c - d * d
    d1, d2, d3, d4, d5 = (p - d * d) / shear, d / shear, 1.0 / shear, 2.0 * d, c / shear
    b1, b2 = g + 2 * q + 2 * p, a - d * d - (p - d * d) ** 2 / shear
    b3, b4, b5 = q + p, p - c, 2 * b + 2 * p
    al, w2 = alpha, omega * omega
    return np.array([
        [-1 / r, -al, 0, 0, 0, 0],
        [al * d1, 0, -al * d2, 0, d3, 0],
        [d4 / r, al * d4, 0, 0, 0, -1],
        [b1 / r**2 + al**2 * b2 - w2, al * b3 / r, al**2 * d2 * b4, 0, -al * d1, -d4 / r],
        [al * b3 / r, al**2 * b5 - w2, 0, al, -1 / r, -al * d4],
        [al**2 * d2 * b4, 0, -(al**2) * d5, 0, al * d2, -1 / r],
    ], dtype=float)


def transfer_matrix(wall: Wall, omega, alpha):
    """A = T_N ⋯ T_1, T_k = expm((ĥ/N) M(r̂_k)) (paper Eqs. 43–44)."""
    a = np.eye(6)
    for k, r in enumerate(wall.radii):
        a = scipy.linalg.expm(wall.step * state_matrix(wall.coef, k, r, omega, alpha)) @ a
    return a


def fluid_pair(omega, alpha, r_inner, fluid):
    """(N_0, D_0) with B̂_0 = N_0/D_0 (docs/theory/axisymmetric.md §4(c)), up to a common positive factor."""
    chi2 = (omega / fluid.speed_ratio) ** 2 - alpha**2
    if chi2 > 0:
        x = math.sqrt(chi2) * r_inner
        return r_inner * scipy.special.j0(x), -x * scipy.special.j1(x)
    if chi2 < 0:
        x = math.sqrt(-chi2) * r_inner  # exponentially scaled I_0, I_1 (a common factor e^{−x̃})
        return r_inner * scipy.special.i0e(x), x * scipy.special.i1e(x)
    return r_inner, 0.0


def initial_basis(wall: Wall, omega, alpha, fluid=None):
    """S (6×3) with Y(r̂_i) = S [ū_i, w̄_i, D̄_i] (docs/theory/axisymmetric.md §4), the fluid denominator
    cleared."""
    p, ri = wall.pressure_inner, wall.r_inner
    s = np.zeros((6, 3))
    s[U, 0], s[T, 0], s[S, 0] = 1.0, -p / ri, -alpha * p
    s[W, 1], s[T, 1] = 1.0, -alpha * p
    s[D, 2] = 1.0
    if fluid is not None:
        n0, d0 = fluid_pair(omega, alpha, ri, fluid)
        s[:, 0] *= d0
        s[T, 0] -= omega**2 * fluid.density_ratio * n0
    return s


def characteristic_on_wall(wall: Wall, omega, alpha, fluid=None, normalise=False):
    """det(B A S), or det(B Q) with A S = Q R, diag R > 0 (``normalise``)."""
    y = transfer_matrix(wall, omega, alpha) @ initial_basis(wall, omega, alpha, fluid)
    if normalise:
        q, r = np.linalg.qr(y)
        y = q * np.sign(np.diag(r))
    return np.linalg.det(y[OUTER_ROWS, :])


def characteristic(tube, omega, alpha, fluid=None, n_layers=30, normalise=True):
    """The characteristic function at one Ω (see :func:`characteristic_on_wall`)."""
    return characteristic_on_wall(discretize(tube, n_layers), omega, alpha, fluid, normalise)


def scan_step(wall: Wall, fluid=None):
    """Δ = min(π c_min/ĥ, π ĉ_f/r̂_i)/16, c_min² = min over the wall of min(c − d², a)."""
    c = wall.coef
    c_min = math.sqrt(np.min(np.minimum(c["c"] - c["d"] ** 2, c["a"])))
    scale = math.pi * c_min / (wall.r_outer - wall.r_inner)
    if fluid is not None:
        scale = min(scale, math.pi * fluid.speed_ratio / wall.r_inner)
    return scale / 16.0


def default_omega_max(wall: Wall, alpha, n_roots):
    """(n_roots + 1)π c_max/ĥ + 3α̂ c_max, c_max² = max over the wall of max(a, b, c)."""
    c = wall.coef
    c_max = math.sqrt(np.max(np.maximum(np.maximum(c["a"], c["b"]), c["c"])))
    return (n_roots + 1) * math.pi * c_max / (wall.r_outer - wall.r_inner) + 3.0 * alpha * c_max


def frequencies(tube, alpha, fluid=None, n_roots=3, omega_max=None, n_layers=30, wall=None,
                xtol=1e-14, rtol=1e-15):
    """The ``n_roots`` lowest roots in (0, Ω_max], NaN-padded (uniform grid, sign changes, brentq).

    Returns:
        (roots, evaluations): the roots (n_roots,) and the number of characteristic evaluations.
    """
    wall = discretize(tube, n_layers) if wall is None else wall
    end = default_omega_max(wall, alpha, n_roots) if omega_max is None else omega_max
    step = scan_step(wall, fluid)
    calls = [0]

    def f(om):
        calls[0] += 1
        return characteristic_on_wall(wall, om, alpha, fluid)

    roots = []
    a = 1e-3 * step
    fa = f(a)
    while len(roots) < n_roots and a < end:
        b = min(a + step, end)
        fb = f(b)
        if fb == 0.0:
            roots.append(b)
        elif fa * fb < 0:
            roots.append(scipy.optimize.brentq(f, a, b, xtol=xtol, rtol=max(rtol, 4 * np.finfo(float).eps)))
        a, fa = b, fb
    out = np.full(n_roots, np.nan)
    out[: len(roots)] = roots[:n_roots]
    return out, calls[0]
