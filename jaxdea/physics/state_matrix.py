"""State matrices M(r̂; Ω, α̂) of the incremental motion, one per mode family.

* ``"longitudinal"`` (circumferential order m = 0, axisymmetric, u_θ = 0): the 6×6 matrix of
  docs/theory/axisymmetric.md §3, Y = [ū, w̄, Φ, T̄, S̄, D̄] (paper Eq. 40 with errata E11–E14 corrected).
* ``"order_m"`` (order m ≥ 1, with m a traced value): the 8×8 matrix M_m of docs/theory/order_m.md §3,
  Y = [U, V, W, Φ, T, Q, S, D]; at m = 0 its (V, Q) rows are switched off (:func:`order_m_matrix`),
  so that it carries the longitudinal family alone.
* ``"torsional"`` (m = 0, u_θ alone): the decoupled (V, Q) block of M_0 (docs/theory/order_m.md §3,
  Structure), Y = [V, Q].

dY/dr̂ = M Y; Ω enters only through −Ω² in the inertia entries (:func:`family_inertia`).
"""

import jax.numpy as jnp
import numpy as np

from .families import Family
from .moduli import Coefficients

LONGITUDINAL, ORDER_M, TORSIONAL = Family.LONGITUDINAL, Family.ORDER_M, Family.TORSIONAL
FAMILIES = tuple(Family)
"""The static mode families (:class:`jaxdea.physics.families.Family`): which state matrix, basis
and boundary rows a problem uses."""


def state_matrix(coef: Coefficients, r, omega, alpha):
    """M(r̂) of docs/theory/axisymmetric.md §3 for one radius (coefficients evaluated there).

    δ1 = (p − εd²)/(c − εd²), δ2 = εd/(c − εd²), δ3 = 1/(c − εd²), δ4 = 2d, δ5 = εc/(c − εd²),
    β1 = g + 2q + 2p, β2 = a − εd² − (p − εd²)²/(c − εd²), β3 = q + p, β4 = p − c, β5 = 2b + 2p.
    """
    if coef.shear is not None:
        return _block(general_matrix(coef, r, omega * omega, alpha, 0.0), LONGITUDINAL_INDICES)
    a, b, c, d, g, q, eps, p = coef.a, coef.b, coef.c, coef.d, coef.g, coef.q, coef.eps, coef.p
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


def _combinations(coef: Coefficients):
    """(δ1 … δ5, β1 … β6) of docs/theory/order_m.md §3 (β1 … β5 as docs/theory/axisymmetric.md §3; β6 = e − εd²
    − (p − εd²)²/(c − εd²))."""
    a, b, c, d, g, q, eps, p, e = coef[:9]
    shear = c - eps * d * d  # = 2 W_1 λ_r² > 0
    d1 = (p - eps * d * d) / shear
    deltas = (d1, eps * d / shear, 1.0 / shear, 2.0 * d, eps * c / shear)
    twist = (p - eps * d * d) ** 2 / shear
    betas = (g + 2.0 * q + 2.0 * p, a - eps * d * d - twist, q + p, p - c, 2.0 * b + 2.0 * p,
             e - eps * d * d - twist)
    return deltas, betas


def state_matrix_m(coef: Coefficients, r, omega_squared, alpha, m):
    """M_m(r̂) of docs/theory/order_m.md §3, the 8×8 matrix of order m, entry by entry; Y = [U, V, W, Φ, T, Q,
    S, D].

    U' = −(U + mV)/r̂ − α̂W;  V' = mδ1U/r̂ + δ1V/r̂ − mδ2Φ/r̂ + δ3Q;  W' = α̂δ1U − α̂δ2Φ + δ3S;
    Φ' = δ4(U + mV)/r̂ + α̂δ4W − D/ε;
    T' = [(β1 + m²β6)/r̂² + α̂²β2 − Ω²]U + m(β1 + β6)V/r̂² + α̂β3W/r̂ + k²δ2β4Φ − mδ1Q/r̂ − α̂δ1S − δ4D/r̂;
    Q' = m(β1 + β6)U/r̂² + [(m²β1 + β6)/r̂² + α̂²a − Ω²]V + mα̂(β3 + p)W/r̂ + mδ2β4Φ/r̂² + mT/r̂
         − (1 + δ1)Q/r̂ − mδ4D/r̂;
    S' = α̂β3U/r̂ + mα̂(β3 + p)V/r̂ + (α̂²β5 + m²e/r̂² − Ω²)W + α̂T − S/r̂ − α̂δ4D;
    D' = k²δ2β4U + mδ2β4V/r̂² − k²δ5Φ + mδ2Q/r̂ + α̂δ2S − D/r̂,   k² = α̂² + m²/r̂².

    ``omega_squared`` is w = Ω², of either sign (w < 0: unstable states, docs/theory/order_m.md §6); ``m`` may
    be traced. At m = 0 the (V, Q) rows and columns decouple (torsion) and the other 6×6 block is
    :func:`state_matrix` (tests).
    """
    if coef.shear is not None:
        return general_matrix(coef, r, omega_squared, alpha, m)
    (d1, d2, d3, d4, d5), (b1, b2, b3, b4, b5, b6) = _combinations(coef)
    a, e, p, eps = coef.a, coef.e, coef.p, coef.eps
    al, w = alpha, omega_squared
    zero = jnp.zeros_like(r * al * w * m * a)
    k2 = al**2 + (m / r) ** 2
    n = m / r  # m/r̂
    rows = [
        [-1.0 / r, -n, -al, zero, zero, zero, zero, zero],
        [n * d1, d1 / r, zero, -n * d2, zero, d3, zero, zero],
        [al * d1, zero, zero, -al * d2, zero, zero, d3, zero],
        [d4 / r, n * d4, al * d4, zero, zero, zero, zero, -1.0 / eps],
        [(b1 + m * m * b6) / r**2 + al**2 * b2 - w, n * (b1 + b6) / r, al * b3 / r, k2 * d2 * b4,
         zero, -n * d1, -al * d1, -d4 / r],
        [n * (b1 + b6) / r, (m * m * b1 + b6) / r**2 + al**2 * a - w, n * al * (b3 + p),
         n * d2 * b4 / r, n, -(1.0 + d1) / r, zero, -n * d4],
        [al * b3 / r, n * al * (b3 + p), al**2 * b5 + n * n * e - w, zero, al + zero, zero, -1.0 / r,
         -al * d4],
        [k2 * d2 * b4, n * d2 * b4 / r, zero, -k2 * d5, zero, n * d2, al * d2, -1.0 / r],
    ]
    return jnp.stack([jnp.stack([jnp.broadcast_to(x, zero.shape) for x in row], -1) for row in rows], -2)


def torsion_matrix(coef: Coefficients, r, omega_squared, alpha):
    """The torsional 2×2 block of M_0 (docs/theory/order_m.md §3, Structure), Y = [V, Q]:

    V' = δ1V/r̂ + δ3Q,  Q' = (β6/r̂² + α̂²a − Ω²)V − (1 + δ1)Q/r̂.
    """
    if coef.shear is not None:
        return _block(general_matrix(coef, r, omega_squared, alpha, 0.0), TORSION_ROWS)
    (d1, _, d3, _, _), betas = _combinations(coef)
    zero = jnp.zeros_like(r * alpha * omega_squared * coef.a)
    rows = [[d1 / r, d3], [betas[5] / r**2 + alpha**2 * coef.a - omega_squared, -(1.0 + d1) / r]]
    return jnp.stack([jnp.stack([x + zero for x in row], -1) for row in rows], -2)


TORSION_ROWS = (1, 5)
"""Rows V', Q' of M_m: switched off at m = 0 in the order-m family (:func:`order_m_matrix`)."""
LONGITUDINAL_INDICES = (0, 2, 3, 4, 6, 7)
"""Rows and columns U, W, Φ, T, S, D of M_m: at m = 0 the longitudinal 6×6 matrix."""


def _block(matrix, indices):
    index = jnp.asarray(indices)
    return matrix[..., index[:, None], index[None, :]]


def general_matrix(coef: Coefficients, r, omega_squared, alpha, m):
    """M_m(r̂) for general moduli (a material object's :class:`~jaxdea.physics.moduli.Shear`
    moduli), docs/theory/real_tubes.md §2, entry by entry; Y = [U, V, W, Φ, T, Q, S, D].

    One set of δ's per shear pair, s_θ = c_θ − εd², s_z = c_z − εd²:
    δ1θ = (p_θ − εd²)/s_θ, δ2θ = εd/s_θ, δ3θ = 1/s_θ, δ5θ = εc_θ/s_θ, β4θ = p_θ − c_θ,
    β6 = e_r − εd² − (p_θ − εd²)²/s_θ (and the z set with c_z, p_z, a_r → β2);
    δ4 = 2d; β1 = g + 2q + 2p, β3 = q + p, β5 = 2b + 2p; X = (m²/r̂²)δ2θβ4θ + α̂²δ2zβ4z.
    In a layered wall Ω² is weighted by the layer's density ratio ρ_k and a passive layer's Φ', D'
    rows are zero (``coef.density``, ``coef.active``). For W(I_1) it is :func:`state_matrix_m`
    entry for entry (tests)."""
    sh = coef.shear
    a_r, b, c_z, d, g, q, eps, p, e_r = coef[:9]
    ed2 = eps * d * d
    s_t, s_z = sh.c_t - ed2, c_z - ed2
    d1t, d2t, d3t, d5t = (sh.p_t - ed2) / s_t, eps * d / s_t, 1.0 / s_t, eps * sh.c_t / s_t
    d1z, d2z, d3z, d5z = (sh.p_z - ed2) / s_z, eps * d / s_z, 1.0 / s_z, eps * c_z / s_z
    b4t, b4z = sh.p_t - sh.c_t, sh.p_z - c_z
    b6 = e_r - ed2 - (sh.p_t - ed2) ** 2 / s_t
    b2 = a_r - ed2 - (sh.p_z - ed2) ** 2 / s_z
    b1, b3, b5, d4 = g + 2.0 * q + 2.0 * p, q + p, 2.0 * b + 2.0 * p, 2.0 * d
    al = alpha
    w = omega_squared if coef.density is None else coef.density * omega_squared
    zero = jnp.zeros_like(r * al * w * m * a_r)
    n = m / r
    x = n * n * d2t * b4t + al * al * d2z * b4z
    rows = [
        [-1.0 / r, -n, -al, zero, zero, zero, zero, zero],
        [n * d1t, d1t / r, zero, -n * d2t, zero, d3t, zero, zero],
        [al * d1z, zero, zero, -al * d2z, zero, zero, d3z, zero],
        [d4 / r, n * d4, al * d4, zero, zero, zero, zero, -1.0 / eps],
        [(b1 + m * m * b6) / r**2 + al**2 * b2 - w, n * (b1 + b6) / r, al * b3 / r, x,
         zero, -n * d1t, -al * d1z, -d4 / r],
        [n * (b1 + b6) / r, (m * m * b1 + b6) / r**2 + al**2 * sh.a_t - w, n * al * (b3 + sh.p_tz) ,
         n * d2t * b4t / r, n, -(1.0 + d1t) / r, zero, -n * d4],
        [al * b3 / r, n * al * (b3 + sh.p_tz), al**2 * b5 + n * n * sh.e_z - w, zero, al + zero, zero,
         -1.0 / r, -al * d4],
        [x, n * d2t * b4t / r, zero, -n * n * d5t - al * al * d5z, zero, n * d2t, al * d2z, -1.0 / r],
    ]
    if coef.active is not None:  # a passive layer's Φ', D' rows are frozen (real_tubes.md §3)
        rows[3] = [coef.active * v for v in rows[3]]
        rows[7] = [coef.active * v for v in rows[7]]
    return jnp.stack([jnp.stack([jnp.broadcast_to(v, zero.shape) for v in row], -1) for row in rows], -2)


def torsion_switch(m):
    """(8,) row mask of the order-m family: 1, except 0 on the rows V', Q' where m = 0.

    At m = 0 every entry of those rows outside the (V, Q) block vanishes and so does every (V, Q)
    column entry outside them (docs/theory/order_m.md §3), so zeroing the rows leaves V and Q constant across
    the wall and the longitudinal 6×6 block untouched: the order-m family at m = 0 is the
    longitudinal family (times a constant factor, :func:`jaxdea.physics.dispersion.outer_conditions`).
    """
    on = jnp.where(jnp.asarray(m) == 0, 0.0, 1.0)
    return jnp.ones(8).at[jnp.asarray(TORSION_ROWS)].set(on)


def order_m_matrix(coef: Coefficients, r, omega_squared, alpha, m):
    """M_m of :func:`state_matrix_m` with the rows V', Q' zeroed where m = 0 (:func:`torsion_switch`)."""
    keep = torsion_switch(m)[:, None]
    return jnp.where(keep > 0, state_matrix_m(coef, r, omega_squared, alpha, m), 0.0)


_INERTIA = {LONGITUDINAL: ((3, 0), (4, 1)), ORDER_M: ((4, 0), (5, 1), (6, 2)), TORSIONAL: ((1, 0),)}


def inertia_matrix(family: str):
    """E with M(r̂; Ω) = M(r̂; 0) − Ω² E (a NumPy constant): ones at (traction row, displacement
    column) — longitudinal (T̄, ū), (S̄, w̄); order m (T, U), (Q, V), (S, W); torsional (Q, V)."""
    size = Family(family).size
    e = np.zeros((size, size))
    for i, j in _INERTIA[family]:
        e[i, j] = 1.0
    return e


def family_inertia(family: str, m=0):
    """E of the family's pipeline matrix (:func:`family_matrix`): :func:`inertia_matrix`, with the
    (Q, V) entry of the order-m family switched off where m = 0."""
    e = inertia_matrix(family)
    if family != ORDER_M:
        return e
    return jnp.asarray(e) * torsion_switch(m)[:, None]


def family_matrix(family: str, coef: Coefficients, r, omega_squared, alpha, m=0):
    """The state matrix of a family at w = ``omega_squared`` (``m`` used by ``"order_m"`` only):
    ``"longitudinal"`` :func:`state_matrix` as M(0) − wE, ``"order_m"`` :func:`order_m_matrix`,
    ``"torsional"`` :func:`torsion_matrix`."""
    if family == LONGITUDINAL:
        if coef.density is not None:  # a layer's ρ_k weights its inertia (as in general_matrix)
            omega_squared = jnp.asarray(coef.density * omega_squared)[..., None, None]
        return state_matrix(coef, r, 0.0, alpha) - omega_squared * inertia_matrix(LONGITUDINAL)
    if family == ORDER_M:
        return order_m_matrix(coef, r, omega_squared, alpha, m)
    if family == TORSIONAL:
        return torsion_matrix(coef, r, omega_squared, alpha)
    raise ValueError(f"family must be one of {FAMILIES}, got {family!r}")
