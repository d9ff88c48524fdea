"""Incremental electro-elastic moduli from the energy by automatic differentiation (docs/theory/axisymmetric.md
§2–3).

The total energy per unit reference volume is Ω(F, D_L) = W(I_1) + I_5/2 with I_1 = tr(FᵀF) and
I_5 = D_L·(FᵀF D_L) (dimensionless, μ = ε = 1). Its second derivatives pushed forward give

    A0_piqj = F_pα F_qβ ∂²Ω/∂F_iα∂F_jβ,  Γ0_piq = F_pα F⁻¹_βq ∂²Ω/∂F_iα∂D_Lβ,
    K0_ij = F⁻¹_αi F⁻¹_βj ∂²Ω/∂D_Lα∂D_Lβ                         (paper Eqs. 20–22, 31),

evaluated at F = diag(λ_r, λ, λ_z) (order r, θ, z) and D = (D_r, 0, 0). Their combinations a, b, c,
d, g, q (docs/theory/axisymmetric.md §3, corrected Eqs. 32–33) feed the state matrix; e = A_θrθr = 2W_1λ²
(docs/theory/order_m.md §2) enters only the matrices of circumferential order m and of torsion.
"""

from typing import NamedTuple

import jax
import jax.numpy as jnp

from ..materials import ENERGIES, Material

R, T, Z = 0, 1, 2


class Moduli(NamedTuple):
    """Push-forward moduli at one point: A0 (3,3,3,3), Γ0 (3,3,3), K0 (3,3)."""

    A: jax.Array
    Gamma: jax.Array
    K: jax.Array


class Shear(NamedTuple):
    """The moduli of a general energy W(I_1, I_2) or Ogden that differ from their W(I_1) partners
    (docs/theory/real_tubes.md §1, the table of new symbols): c_θ = A_rθrθ (+ d²), e_z = A_θzθz,
    a_θ = A_zθzθ, p_θ = p + A_rθθr, p_z = p + A_rzzr, p_θz = p + A_θzzθ. For W(I_1) they equal
    c, e, a and p."""

    c_t: jax.Array
    e_z: jax.Array
    a_t: jax.Array
    p_t: jax.Array
    p_z: jax.Array
    p_tz: jax.Array


class Coefficients(NamedTuple):
    """State-matrix coefficients at one radius (docs/theory/axisymmetric.md §3); each a scalar (or batch) array.

    a = A_zrzr, b = (A_rrrr + A_zzzz − 2A_rrzz)/2, c = A_rzrz, d = Γ_rzz = D_r/ε,
    g = 2A_rrzz − 2A_θθzz + A_θθθθ − A_rrrr, q = A_rrrr − A_rrzz + A_θθzz − A_rrθθ, eps = 1/K_rr,
    p = Lagrange multiplier of the base state, e = A_θrθr = 2W_1λ² (docs/theory/order_m.md §2: enters only
    the order-m and torsional state matrices; the axisymmetric 6×6 matrix does not read it).
    ``shear``: None for an energy W(I_1) (the static names), else the :class:`Shear` moduli of a
    material object, whose a, c, e are then a_r = A_zrzr, c_z = A_rzrz, e_r = A_θrθr.
    ``density``, ``active``: None for a single wall; in a layered wall ρ_k/ρ_s and 1 (active
    layer) or 0 (passive: the Φ, D rows of M are frozen, docs/theory/real_tubes.md §3).
    """

    a: jax.Array
    b: jax.Array
    c: jax.Array
    d: jax.Array
    g: jax.Array
    q: jax.Array
    eps: jax.Array
    p: jax.Array
    e: jax.Array
    shear: Shear | None = None
    density: jax.Array | None = None
    active: jax.Array | None = None


def energy_derivatives(i1, gent_constant, material="gent"):
    """W_1 = ∂W/∂I_1 and W_11 = ∂²W/∂I_1² by autodiff; NaN where W_1 ≤ 0 (past Gent locking)."""
    w1, w11 = jax.value_and_grad(jax.grad(ENERGIES[material]))(i1, gent_constant)
    admissible = w1 > 0
    nan = jnp.nan * jnp.ones_like(i1)
    return jnp.where(admissible, w1, nan), jnp.where(admissible, w11, nan)


def electroelastic_energy(F, DL, gent_constant, material="gent"):
    """Ω(F, D_L) = W(I_1) + I_5/2 (paper Eq. 9, dimensionless)."""
    C = F.T @ F
    return ENERGIES[material](jnp.trace(C), gent_constant) + 0.5 * DL @ (C @ DL)


def push_forward_moduli(lam_r, lam, lam_z, D_r, gent_constant, material="gent") -> Moduli:
    """A0, Γ0, K0 at F = diag(λ_r, λ, λ_z), D = D_r e_r, from the energy by autodiff
    (docs/theory/axisymmetric.md §2)."""
    F = jnp.diag(jnp.stack([lam_r, lam, lam_z]))
    Finv = jnp.diag(1.0 / jnp.stack([lam_r, lam, lam_z]))
    DL = Finv @ jnp.stack([D_r, jnp.zeros_like(D_r), jnp.zeros_like(D_r)])
    energy = lambda F, DL: electroelastic_energy(F, DL, gent_constant, material)  # noqa: E731
    (hFF, hFD), (_, hDD) = jax.hessian(energy, argnums=(0, 1))(F, DL)
    w1, _ = energy_derivatives(jnp.trace(F.T @ F), gent_constant, material)
    A = jnp.einsum("pa,qb,iajb->piqj", F, F, hFF) * jnp.where(jnp.isnan(w1), jnp.nan, 1.0)
    Gamma = jnp.einsum("pa,bq,iab->piq", F, Finv, hFD)
    K = jnp.einsum("ai,bj,ab->ij", Finv, Finv, hDD)
    return Moduli(A, Gamma, K)


def coefficients(moduli: Moduli, p) -> Coefficients:
    """a, b, c, d, g, q, ε of docs/theory/axisymmetric.md §3 (corrected paper Eq. 32) and e = A_θrθr
    (docs/theory/order_m.md §2) from the tensor moduli."""
    A, Gamma, K = moduli
    return Coefficients(
        a=A[Z, R, Z, R],
        b=0.5 * (A[R, R, R, R] + A[Z, Z, Z, Z] - 2.0 * A[R, R, Z, Z]),
        c=A[R, Z, R, Z],
        d=Gamma[R, Z, Z],
        g=2.0 * A[R, R, Z, Z] - 2.0 * A[T, T, Z, Z] + A[T, T, T, T] - A[R, R, R, R],
        q=A[R, R, R, R] - A[R, R, Z, Z] + A[T, T, Z, Z] - A[R, R, T, T],
        eps=1.0 / K[R, R],
        p=p,
        e=A[T, R, T, R],
    )


def closed_form_coefficients(lam, lam_z, D_r, p, gent_constant, material="gent") -> Coefficients:
    """The closed forms of docs/theory/axisymmetric.md §3 (corrected Eq. 33) and e = 2W_1λ²
    (docs/theory/order_m.md §2) for Ω = W(I_1) + I_5/2, with W_1, W_11 from the energy by autodiff; equal to
    :func:`coefficients` of the tensor moduli (tests)."""
    lam_r = 1.0 / (lam * lam_z)
    i1 = lam_r**2 + lam**2 + lam_z**2
    w1, w11 = jnp.vectorize(lambda i: energy_derivatives(i, gent_constant, material))(i1)
    dD = D_r * D_r
    s = 1.0 - lam**4 * lam_z**2
    return Coefficients(
        a=2 * w1 * lam_z**2,
        b=0.5 * (4 * w11 * (lam_z**2 - lam_r**2) ** 2 + 2 * w1 * (lam_z**2 + lam_r**2) + dD),
        c=2 * w1 * lam_r**2 + dD,
        d=D_r,
        g=4 * w11 * lam_r**4 * s * (2 * lam**2 * lam_z**4 - lam**4 * lam_z**2 - 1)
        - 2 * w1 * lam_r**2 * s
        - dD,
        q=4 * w11 * lam_r**4 * (1 - lam**2 * lam_z**4) * s + 2 * w1 * lam_r**2 + dD,
        eps=jnp.ones_like(lam),
        p=p,
        e=2 * w1 * lam**2,
    )


def material_coefficients(material: Material, lam, lam_z, D_r, p, shear_ratio=None) -> Coefficients:
    """The coefficients of a material object at one point, from its principal-stretch derivatives
    (automatic differentiation, :meth:`jaxdea.materials.Material.derivatives`) by the
    push-forward of docs/theory/real_tubes.md §1 (Ogden 1984), with (1, 2, 3) = (r, θ, z):

        A_iijj = λ_iλ_jW_ij,  A_ijij = λ_i²Q_ij,  A_ijji = λ_i²Q_ij − λ_iW_i  (i ≠ j),

    plus the ideal dielectric's d² in A_rrrr, A_rθrθ, A_rzrz (d = D̂_r). ``p`` is the base state's
    p = λ_rW_r + d² − τ_rr of the same (unconstrained) extension (§1, pitfall). ``shear_ratio``:
    μ_k of a layer, which scales W (None: 1)."""
    lam_r = 1.0 / (lam * lam_z)
    stretches = jnp.stack([lam_r, lam, lam_z])
    w, hess, pair = material.derivatives(stretches)
    if shear_ratio is not None:
        w, hess, pair = (shear_ratio * x for x in (w, hess, pair))
    big = stretches[:, None] * stretches[None, :] * hess  # A_iijj
    dD = D_r * D_r
    a_rrrr = big[R, R] + dD
    sq = stretches * stretches
    ok = jnp.isfinite(jnp.sum(big)) & jnp.isfinite(jnp.sum(pair)) & (jnp.min(pair + jnp.eye(3)) > 0)
    nan = jnp.where(ok, 1.0, jnp.nan)
    return Coefficients(
        a=sq[Z] * pair[Z, R] * nan,
        b=0.5 * (a_rrrr + big[Z, Z] - 2.0 * big[R, Z]),
        c=sq[R] * pair[R, Z] + dD,
        d=D_r,
        g=2.0 * big[R, Z] - 2.0 * big[T, Z] + big[T, T] - a_rrrr,
        q=a_rrrr - big[R, Z] + big[T, Z] - big[R, T],
        eps=jnp.ones_like(lam),
        p=p,
        e=sq[T] * pair[T, R],
        shear=Shear(
            c_t=sq[R] * pair[R, T] + dD,
            e_z=sq[T] * pair[T, Z],
            a_t=sq[Z] * pair[Z, T],
            p_t=p + sq[R] * pair[R, T] - lam_r * w[R],
            p_z=p + sq[R] * pair[R, Z] - lam_r * w[R],
            p_tz=p + sq[T] * pair[T, Z] - lam * w[T],
        ),
    )


def radial_stress_parts(material: Material, lam, lam_z):
    """(λ_θW_θ − λ_rW_r, λ_rW_r): the elastic σ_θθ − σ_rr of the base state and the elastic part of
    its p (docs/theory/real_tubes.md §3, one layer)."""
    lam_r = 1.0 / (lam * lam_z)
    w = jax.grad(material.energy)(jnp.stack([lam_r, lam, lam_z]))
    return lam * w[T] - lam_r * w[R], lam_r * w[R]
