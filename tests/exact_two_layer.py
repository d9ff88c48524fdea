"""Independent reference solver: free vibrations of order m of a bonded two-layer hollow cylinder.

Exactly incompressible, linear-elastic, unstretched (λ_i = λ_z = 1, V̂ = 0), in the units of jaxdea
(the active layer has unit shear modulus and density, so unit shear speed).  Inner layer
a ≤ r ≤ c (shear modulus μ₁, density ρ₁), outer layer c ≤ r ≤ b (μ₂, ρ₂), perfectly bonded at
r = c, both faces traction-free.  Only numpy and scipy are used (no jaxdea import); the column
builders are those of tests/exact_cylinder_m.py, whose docstring has the derivation of one layer.

Derivation.  In layer k the momentum equation is −grad p + μ_k Lap u = −ρ_k Ω² u with div u = 0;
divided by μ_k it is the unit-material problem of exact_cylinder_m,

    −grad(p/μ_k) + Lap u = −Ω_k² u,        Ω_k² = ρ_k Ω² / μ_k,

so u = grad φ + curl(χ e_z) + curl curl(ψ e_z) with the same potentials, Bessel columns and
recurrences at the layer's own frequency Ω_k (β_k² = Ω_k² − α²), p/μ_k = Ω_k² φ, and the
stress is σ = μ_k (−(p/μ_k) I + grad u + grad uᵀ): the unit solver's tractions (σ_rr including
the pressure, σ_rθ, σ_rz) times μ_k.  Each layer has the single layer's six columns (its
scaling of the modified Bessel functions taken over its own radii [a, c] or [c, b], a positive
factor per column), so there are 12 unknowns and 12 conditions:

    rows 0–2   σ_rr, σ_rθ, σ_rz of layer 1 at r = a            = 0
    rows 3–5   U, V, W of layer 1 − those of layer 2 at r = c   = 0
    rows 6–8   the three tractions of layer 1 − of layer 2 at c = 0
    rows 9–11  the three tractions of layer 2 at r = b          = 0

(the angular and axial factors cos mθ, sin mθ, cos αz, sin αz are the same in both layers).  Each
column is divided by its Euclidean norm: every scaling is positive and continuous in Ω (including
Ω_k = α, where the single layer's basis is already continuous), so the zeros and the sign
changes of the normalised determinant are those of the frequency equation.

For m = 0 the torsional fields (the χ columns: only V and σ_rθ) decouple from the axisymmetric
ones (φ, ψ: V = σ_rθ = 0): :func:`characteristic_two_layer` returns the 8×8 axisymmetric
determinant there (the longitudinal family of jaxdea's m = 0, ``torsional=False``) and
:func:`torsion_two_layer` the 4×4 torsional one (V = Z_1(β_k r), σ_rθ = V' − V/r = −R Z_2).  With
μ₁ = μ₂ and ρ₁ = ρ₂ the roots are the single layer's (exact_cylinder_m.roots_m, torsion_roots),
for any c.
"""

import math

import exact_cylinder_m as ecm
import numpy as np


def _layer(omega, alpha, lo, hi, m, mu, rho):
    """(tractions, displacements), each (N, 6, 6): rows (σ_rr, σ_rθ, σ_rz) resp. (U, V, W) at
    r = lo, then at r = hi, of the six basis fields of a layer of shear modulus ``mu`` and
    density ``rho`` at the frequency ``omega`` (the unit solver at Ω_k = Ω √(ρ/μ), tractions
    times μ)."""
    omega_k = np.asarray(omega, dtype=float) * math.sqrt(rho / mu)
    sig, _, disp = ecm._columns(omega_k, alpha, lo, hi, m, displacements=True)
    return mu * sig, disp


def _matrix(omega, alpha, a, b, c, m, mu1, rho1, mu2, rho2):
    """The (N, 12, 12) matrix of the module docstring, columns normalised."""
    s1, d1 = _layer(omega, alpha, a, c, m, mu1, rho1)
    s2, d2 = _layer(omega, alpha, c, b, m, mu2, rho2)
    n = s1.shape[0]
    mat = np.zeros((n, 12, 12))
    mat[:, 0:3, 0:6] = s1[:, 0:3]
    mat[:, 3:6, 0:6] = d1[:, 3:6]
    mat[:, 3:6, 6:12] = -d2[:, 0:3]
    mat[:, 6:9, 0:6] = s1[:, 3:6]
    mat[:, 6:9, 6:12] = -s2[:, 0:3]
    mat[:, 9:12, 6:12] = s2[:, 3:6]
    return mat


_AXISYMMETRIC = ([0, 2, 3, 5, 6, 8, 9, 11], [0, 1, 4, 5, 6, 7, 10, 11])
"""m = 0: the rows (no σ_rθ, no V) and columns (no χ) of the axisymmetric block."""
_TORSIONAL = ([1, 4, 7, 10], [2, 3, 8, 9])
"""m = 0: the rows (σ_rθ, V) and columns (χ) of the torsional block."""


def _det(mat):
    return np.linalg.det(mat / np.linalg.norm(mat, axis=1)[:, None, :])


def characteristic_two_layer(omega, alpha, a, b, c, m, mu1, rho1, mu2, rho2):
    """Real, normalised frequency determinant of order m of the free-free two-layer cylinder
    (12×12; for m = 0 its 8×8 axisymmetric block, torsion excluded).  Vectorised over ``omega``.

    Args:
        omega: Dimensionless angular frequency (scalar or array), Ω > 0.
        alpha: Axial wavenumber α > 0.
        a, b: Inner and outer radius; c: the interface, a < c < b.
        m: Circumferential order, integer ≥ 0.
        mu1, rho1: Shear modulus and density of the inner layer (a ≤ r ≤ c).
        mu2, rho2: Those of the outer layer (c ≤ r ≤ b).
    """
    m = int(m)
    mat = _matrix(omega, alpha, a, b, c, m, mu1, rho1, mu2, rho2)
    if m == 0:
        mat = mat[:, _AXISYMMETRIC[0]][:, :, _AXISYMMETRIC[1]]
    d = _det(mat)
    return float(d[0]) if np.ndim(omega) == 0 else d


def torsion_two_layer(omega, alpha, a, b, c, mu1, rho1, mu2, rho2):
    """The 4×4 torsional determinant (m = 0, u_θ only): σ_rθ(a) = 0, V and σ_rθ continuous at c,
    σ_rθ(b) = 0, normalised as :func:`characteristic_two_layer`."""
    mat = _matrix(omega, alpha, a, b, c, 0, mu1, rho1, mu2, rho2)
    d = _det(mat[:, _TORSIONAL[0]][:, :, _TORSIONAL[1]])
    return float(d[0]) if np.ndim(omega) == 0 else d


def roots_two_layer(m, alpha, a, b, c, mu1, rho1, mu2, rho2, n_roots=5, omega_max=21.0,
                    n_grid=2000, max_doublings=6):
    """Lowest frequencies Ω in (0, omega_max] of the modes of order m of the two-layer cylinder
    (m = 0: the axisymmetric, longitudinal family only): sign changes of
    :func:`characteristic_two_layer` refined by brentq, the grid doubled until the number of
    sign changes repeats (exact_cylinder_m._roots).  NaN padded."""
    return ecm._roots(characteristic_two_layer, (alpha, a, b, c, int(m), mu1, rho1, mu2, rho2),
                      int(m), n_roots, omega_max, n_grid, max_doublings)


def torsion_roots_two_layer(alpha, a, b, c, mu1, rho1, mu2, rho2, n_roots=3, omega_max=21.0,
                            n_grid=2000, max_doublings=6):
    """Lowest torsional frequencies of the two-layer cylinder (sign changes of
    :func:`torsion_two_layer`).  With equal layers the first is Ω = α (rigid-like twist V ~ r)."""
    return ecm._roots(torsion_two_layer, (alpha, a, b, c, mu1, rho1, mu2, rho2), 0, n_roots,
                      omega_max, n_grid, max_doublings)
