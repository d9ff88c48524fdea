"""The 6×6 state matrix M(r̂; Ω, α̂) of the incremental axisymmetric motion (theory.md §3).

dY/dr̂ = M Y with Y = [ū, w̄, Φ, T̄, S̄, D̄] (paper Eq. 40 with errata E11–E14 corrected).
"""

import jax.numpy as jnp

from .moduli import Coefficients


def state_matrix(coef: Coefficients, r, omega, alpha):
    """M(r̂) of theory.md §3 for one radius (coefficients evaluated there).

    δ1 = (p − εd²)/(c − εd²), δ2 = εd/(c − εd²), δ3 = 1/(c − εd²), δ4 = 2d, δ5 = εc/(c − εd²),
    β1 = g + 2q + 2p, β2 = a − εd² − (p − εd²)²/(c − εd²), β3 = q + p, β4 = p − c, β5 = 2b + 2p.
    """
    a, b, c, d, g, q, eps, p = coef
    shear = c - eps * d * d  # = 2 W_1 λ_r² > 0
    d1 = (p - eps * d * d) / shear
    d2 = eps * d / shear
    d3 = 1.0 / shear
    d4 = 2.0 * d
    d5 = eps * c / shear
    b1 = g + 2.0 * q + 2.0 * p
    b2 = a - eps * d * d - (p - eps * d * d) ** 2 / shear
    b3 = q + p
    b4 = p - c
    b5 = 2.0 * b + 2.0 * p
    al, w2, zero = alpha, omega * omega, jnp.zeros_like(r * alpha * omega * a)
    rows = [
        [-1.0 / r, -al, zero, zero, zero, zero],
        [al * d1, zero, -al * d2, zero, d3, zero],
        [d4 / r, al * d4, zero, zero, zero, -1.0 + zero],
        [b1 / r**2 + al**2 * b2 - w2, al * b3 / r, al**2 * d2 * b4, zero, -al * d1, -d4 / r],
        [al * b3 / r, al**2 * b5 - w2, zero, al + zero, -1.0 / r, -al * d4],
        [al**2 * d2 * b4, zero, -(al**2) * d5, zero, al * d2, -1.0 / r],
    ]
    return jnp.stack([jnp.stack([jnp.broadcast_to(x, zero.shape) for x in row], -1) for row in rows], -2)
