"""The characteristic function: one contract for every family, unknown and dtype.

A case is a :class:`~jaxdea.physics.problem.Problem` (family, inner face, Bessel order ν) on a
discretised wall, with one unknown x and the other variable fixed (:class:`Unknown`):

* ``omega``: x = Ω at a fixed α̂ (frequencies);
* ``omega_squared``: x = w = Ω² of either sign at a fixed α̂ (w < 0: unstable modes);
* ``growth``: x = s with Ω = i s, w = −s² (growth rates);
* ``alpha``: x = α̂ at a fixed Ω (wavenumbers).

With Y = A S the initial basis carried across the wall (A = T_N ⋯ T_1) and Out the outer-face
rows, F(x) = det(Out A S) is the characteristic determinant (docs/theory/axisymmetric.md §4,
docs/theory/order_m.md §4–§6): entire in Ω², polynomial in α̂ through the generators, pole-free with
the fluid's denominators cleared. The library evaluates the scaled

    f(x) = det(Out Q_N),   A S = Q_N R,   F = f · det R,   det R > 0,

(the basis re-orthonormalised after every sublayer, :func:`jaxdea.physics.transfer.carry_basis`):
|f| ≤ 1, the zeros of F, the sign of F for real x and the argument of F for complex x.

Generic in dtype: a real x gives the real f of the solvers; a complex x (complex Ω, complex α̂)
the complex f. f is not analytic in a complex x (R comes from Hermitian Gram–Schmidt), but the
log-derivative of F is, and it is what a complex Newton step needs:

    d ln F/dx = tr((Out Q_N)⁻¹ (Out' Q_N + Out Z)),   Z = Y' R⁻¹,

with Z carried in the frame of Q (:func:`jaxdea.physics.transfer.carry_basis_tangent`), so the
re-orthonormalisation is never differentiated. x ← x − 1/(d ln F/dx) is Newton's step on F
(:func:`value_and_log_slope`). For real x, f' = f (d ln F/dx − d ln det R/dx).

The real-Ω capabilities of the solvers (polynomials in α̂ and w, the decoupled electric block, the
4×4 mechanical path: :func:`jaxdea.physics.dispersion.value_and_slope_on_wall`) evaluate this same
f, to rounding; :func:`value` is the one entry for values. The complex searches of a wall without
voltage take its decoupled blocks too (:func:`block_pieces`, ``decoupled``), in any dtype.
"""

import enum

import jax
import jax.numpy as jnp

from ..params import Fluid, Tube
from . import dispersion
from .dispersion import (
    ELECTRIC,
    MECHANICAL,
    characteristic_of_w,
    characteristic_on_wall,
    determinant,
    initial_basis_of_w,
    outer_conditions,
)
from .families import Family
from .transfer import (
    EXPONENTIALS,
    Wall,
    carry_basis,
    carry_basis_tangent,
    damped_wall,
    discretize,
    generators_at,
    node_matrices_at,
    scheme_generators,
)


class Unknown(enum.StrEnum):
    """The unknown x of the characteristic function, the other variable fixed (module docstring)."""

    OMEGA = "omega"
    OMEGA_SQUARED = "omega_squared"
    GROWTH = "growth"
    ALPHA = "alpha"

    def point(self, x, fixed):
        """(w, α̂) = (Ω², α̂) at x; ``fixed`` is α̂, or Ω for ``alpha``."""
        if self is Unknown.ALPHA:
            return fixed * fixed, x
        if self is Unknown.OMEGA:
            return x * x, fixed
        if self is Unknown.GROWTH:
            return -x * x, fixed
        return x, fixed

    def frequency(self, x, fixed):
        """Ω at x (complex where the unknown is): x, the fixed Ω, i s, or √w (principal root,
        i√(−w) for real w < 0, the growth rates' Ω)."""
        if self is Unknown.ALPHA:
            return fixed
        if self is Unknown.OMEGA:
            return x
        if self is Unknown.GROWTH:
            return 1j * x
        return jnp.sqrt(x.astype(jnp.result_type(x, jnp.complex128)))


def value(family: Family, wall: Wall, x, fixed, fluid=None, order: int = 0, m=0,
          unknown: Unknown = Unknown.OMEGA, method: str = "taylor", decoupled: bool = False):
    """f(x) = det(Out Q_N) (module docstring), real for real x, complex for complex x.

    ``family``, ``order``, ``unknown``, ``method`` (the sublayer exponential,
    :data:`jaxdea.physics.transfer.EXPONENTIALS`) and ``decoupled`` are static; ``m`` may be traced
    (``order_m``). A real Ω, w or s takes the solvers' code path of the family (the 6×6
    longitudinal system in Ω, the order-m and torsional systems in w); x = α̂, a damped wall or a
    complex x the generators formed at the point (:func:`pieces`; ``decoupled``: its blocks,
    :func:`block_pieces`)."""
    family, unknown = Family(family), Unknown(unknown)
    if unknown is Unknown.ALPHA or wall.damping is not None or jnp.iscomplexobj(x):
        if decoupled:
            f = 1.0
            for basis, exponentials, out in block_pieces(family, wall, x, fixed, fluid, order, m,
                                                         unknown, method):
                f = f * determinant(out @ carry_basis(basis, exponentials)[0])
            return f
        basis, exponentials, out = pieces(family, wall, x, fixed, fluid, order, m, unknown, method)
        q, _ = carry_basis(basis, exponentials)
        return determinant(out @ q)
    if unknown is Unknown.OMEGA and not family.carries_m:
        return characteristic_on_wall(wall, x, fixed, fluid, order, method)
    w, alpha = unknown.point(x, fixed)
    return characteristic_of_w(wall, w, alpha, fluid, order, method, m, family)


def value_and_scale(family: Family, wall: Wall, x, fixed, fluid=None, order: int = 0, m=0,
                    unknown: Unknown = Unknown.OMEGA, method: str = "adaptive",
                    decoupled: bool = False):
    """(f, ℓ) with F = f e^ℓ at a real Ω (``omega``) or w (``omega_squared``): the arithmetic of
    :func:`value` (f equal to it bit for bit), ℓ = log det R beside it, no slope (the error check of
    :func:`jaxdea.solve.roots.newton_steps`, which needs the entire F where f turns sign in a
    near-jump). ``decoupled`` (static; the longitudinal family in Ω): the 4×4 mechanical path of a
    wall whose electric block decouples
    (:func:`jaxdea.physics.dispersion.decoupled_characteristic_and_scale`, equal to rounding)."""
    family, unknown = Family(family), Unknown(unknown)
    if unknown is Unknown.OMEGA and not family.carries_m:
        if decoupled:
            return dispersion.decoupled_characteristic_and_scale(wall, x, fixed, fluid, order)
        return dispersion.characteristic_and_scale(wall, x, fixed, fluid, order, method)
    w, alpha = unknown.point(x, fixed)
    return dispersion.characteristic_and_scale_of_w(wall, w, alpha, fluid, order, method, m, family)


def value_and_log_slope(family: Family, wall: Wall, x, fixed, fluid=None, order: int = 0, m=0,
                        unknown: Unknown = Unknown.OMEGA, method: str = "adaptive",
                        decoupled: bool = False):
    """(f, d ln F/dx) at x, real or complex (module docstring).

    f is the value of :func:`value` (the same zeros, sign and argument as F); d ln F/dx is the
    analytic log-derivative of F = det(Out A S), so that x − 1/(d ln F/dx) is Newton's step on F
    at a complex x too. Only the sublayer exponentials, the initial basis and the outer rows are
    differentiated (forward mode, tangent 1 in x), never the re-orthonormalisation. ``method``:
    the sublayer exponential (:data:`jaxdea.physics.transfer.EXPONENTIALS`); the default
    ``"adaptive"`` takes only the squarings it needs under the tangent too (forward mode only;
    ``"taylor"`` carries the tangent of all its masked squarings, 2× the exponentials' cost).
    ``decoupled``: the blocks of :func:`block_pieces`."""
    family, unknown = Family(family), Unknown(unknown)
    x = jnp.asarray(x, dtype=jnp.result_type(x, jnp.float64))
    of = block_pieces if decoupled else pieces
    return value_and_log_slope_along(
        lambda y: of(family, wall, y, fixed, fluid, order, m, unknown, method), x,
        jnp.ones_like(x))


def value_and_log_slope_along(pieces_of, primal, tangent):
    """(f, d ln F[tangent]) for (S, T_k, Out) = ``pieces_of(primal)`` (:func:`pieces` of whatever
    ``primal`` holds: x, or the tube and α̂ at a fixed x), the derivative of ln F = ln det(Out A S)
    along ``tangent``: tr((Out Q_N)⁻¹(Out' Q_N + Out Z)), Z carried across the wall in the frame
    of Q (:func:`jaxdea.physics.transfer.carry_basis_tangent`). ``pieces_of`` may give a tuple of
    such triples instead, the blocks of a decoupled wall (:func:`block_pieces`): F is the product
    of their determinants, ln F the sum."""
    primals, tangents = jax.jvp(pieces_of, (primal,), (tangent,))
    if not isinstance(primals[0], tuple):
        primals, tangents = (primals,), (tangents,)
    f, log_slope = 1.0, 0.0
    for (basis, exponentials, out), (basis_dot, exponentials_dot, out_dot) in zip(
            primals, tangents, strict=True):
        q, z = carry_basis_tangent(basis, basis_dot, exponentials, exponentials_dot)
        outer_q = out @ q
        f = f * determinant(outer_q)
        log_slope = log_slope + jnp.trace(jnp.linalg.solve(outer_q, out_dot @ q + out @ z))
    return f, log_slope


def value_and_slope(family: Family, wall: Wall, omega, alpha, fluid=None, order: int = 0, m=0,
                    decoupled=None, generators=None):
    """(f, df/dΩ) at a real Ω, the slope carried across the wall (no forward mode through
    Gram–Schmidt): the solvers' corrector lanes. The longitudinal family takes the 4×4 mechanical
    path where the electric block decouples (``decoupled``), and ``generators`` (those of
    :func:`jaxdea.physics.dispersion.lane_generators` at this α̂) spare forming them
    (:func:`jaxdea.physics.dispersion.value_and_slope_on_wall`). f equals :func:`value` to rounding."""
    return dispersion.value_and_slope_on_wall(wall, omega, alpha, fluid, order, m, Family(family),
                                              decoupled, generators)


def scaled(family: Family, wall: Wall, alpha, fluid=None, order: int = 0, m=0,
           unknown: Unknown = Unknown.OMEGA, decoupled: bool = False, generators=None):
    """x ↦ (f, ℓ) with F = f e^ℓ (ℓ = log det R) at a real Ω (``omega``) or w (``omega_squared``),
    whose forward-mode slope is the carried one (f' and ℓ' = tr(QᵀZ)): the function the root scan
    classifies (:func:`jaxdea.solve.roots.scanned_function`). ``decoupled`` and ``generators``: as
    for :func:`value_and_slope` (the longitudinal family in Ω)."""
    family, unknown = Family(family), Unknown(unknown)
    if not family.carries_m and unknown is Unknown.OMEGA:
        return dispersion.scale_and_slope_on_wall(wall, alpha, fluid, order, decoupled, generators)
    return dispersion.scale_and_slope_of_w(wall, alpha, fluid, order, m, family, unknown.value,
                                           generators)


def at_rest_value_and_slope(family: Family, wall_of, exponentials_of, voltage, alpha, fluid=None,
                            order: int = 0, m=0):
    """(f, df/dV̂) at Ω = 0 on the wall ``wall_of``(V̂) with the sublayer exponentials
    ``exponentials_of``(V̂), the slope carried across the wall: the critical-voltage search
    (:func:`jaxdea.physics.dispersion.at_rest_value_and_slope`)."""
    return dispersion.at_rest_value_and_slope(wall_of, exponentials_of, voltage, alpha, fluid, order,
                                              m, Family(family))


def pieces(family: Family, wall: Wall, x, fixed, fluid, order, m, unknown: Unknown,
           method: str = "taylor"):
    """(S, T_k, Out) at x: the initial basis, the sublayer exponentials (N, n, n) and the outer
    rows, in the dtype of x (analytic in x: the generators are formed at the point from the node
    matrices, polynomial in w and α̂, with η*(Ω) of a damped wall,
    :func:`jaxdea.physics.transfer.generators_at`)."""
    w, alpha = unknown.point(x, fixed)
    wall = damped_wall(wall, unknown.frequency(x, fixed))
    exponentials = jax.vmap(EXPONENTIALS[method])(generators_at(wall, w, alpha, m, family))
    basis = initial_basis_of_w(wall, w, alpha, fluid, order, m, family)
    out = outer_conditions(wall, alpha, m, family, omega_squared=w)
    dtype = jnp.result_type(x, exponentials, basis, out, jnp.float64)
    return basis.astype(dtype), exponentials.astype(dtype), out.astype(dtype)


def winding_value(family: Family, wall: Wall, x, fixed, fluid=None, order: int = 0, m=0,
                  unknown: Unknown = Unknown.OMEGA, decoupled: bool = False):
    """A function with the zeros of F in x and the same winding around any contour that avoids
    them, for the argument principle (:func:`jaxdea.solve.counting.winding_count`): :func:`value`,
    but for x = Ω on a decoupled wall (``decoupled``, :func:`block_pieces`) the mechanical block's
    det(Out_m A_m S_m) alone. The electric factor det(Out_e A_e S_e) does not depend on Ω (the
    electric block's state matrix, its initial column D̄ and its row Φ hold α̂ and the permittivity,
    not Ω, and damping changes the mechanical moduli only), and it is not zero at a real α̂ (the
    potential's problem alone, Φ = 0 on both electrodes, has no solution but 0), so it turns the
    phase of F by a constant and counts nothing; leaving it out spares its exponentials."""
    unknown = Unknown(unknown)
    if not (decoupled and unknown is Unknown.OMEGA):
        return value(family, wall, x, fixed, fluid, order, m, unknown, decoupled=decoupled)
    (basis, exponentials, out), = block_pieces(family, wall, x, fixed, fluid, order, m, unknown,
                                               electric=False)
    return determinant(out @ carry_basis(basis, exponentials)[0])


def block_pieces(family: Family, wall: Wall, x, fixed, fluid, order, m, unknown: Unknown,
                 method: str = "taylor", electric: bool = True):
    """The pieces of :func:`pieces` as two blocks, ((S_m, T_m, Out_m), (S_e, T_e, Out_e)), for a
    longitudinal wall whose state matrices are block-diagonal in (U, W, T, S) and (Φ, D) (no
    voltage; a damped wall too: η* changes the mechanical moduli only): the mechanical 4×4
    propagation of the basis columns ū, w̄ with the rows T, S, and the electric 2×2 one of the
    column D̄ with the row Φ. Y stays block-diagonal, so Gram–Schmidt acts on each block and
    F = det(Out_m A_m S_m)·det(Out_e A_e S_e) (the column D̄ and the row Φ moved first together:
    the same sign), from 4×4 and 2×2 exponentials instead of 6×6 (the real solvers' decoupled path,
    :func:`jaxdea.physics.dispersion.value_and_slope_on_wall`, in any dtype). NaN where the wall
    does not decouple (an entry of the node matrices' off-diagonal blocks not exactly 0, as
    :func:`jaxdea.physics.dispersion.electric_decoupled` tests them). ``electric=False`` (static):
    the mechanical block alone, a tuple of one (:func:`winding_value`)."""
    w, alpha = unknown.point(x, fixed)
    wall = damped_wall(wall, unknown.frequency(x, fixed))
    matrices = node_matrices_at(wall, w, alpha, m, family)
    ok = (jnp.all(matrices[..., MECHANICAL[:, None], ELECTRIC] == 0)
          & jnp.all(matrices[..., ELECTRIC[:, None], MECHANICAL] == 0))
    basis = initial_basis_of_w(wall, w, alpha, fluid, order, m, family)
    out = outer_conditions(wall, alpha, m, family, omega_squared=w)
    blocks = []
    for index, columns, rows in ((MECHANICAL, slice(0, 2), slice(1, 3)),
                                 (ELECTRIC, slice(2, 3), slice(0, 1)))[:2 if electric else 1]:
        exponentials = jax.vmap(EXPONENTIALS[method])(
            scheme_generators(wall, matrices[..., index[:, None], index]))
        block = (basis[index][:, columns], exponentials, out[rows][:, index])
        dtype = jnp.result_type(x, *block, jnp.float64)
        blocks.append(tuple(jnp.where(ok, b, jnp.nan).astype(dtype) for b in block))
    return tuple(blocks)


def problem_function(tube: Tube, alpha, fluid: Fluid | None, n_layers, order: int, m=0,
                     family: Family = Family.LONGITUDINAL, variable: str = "omega"):
    """(wall, f) with f the characteristic function of one case, for the root solvers (traceable).

    :func:`value` for one public case: the wall is discretised once and f evaluates with the
    adaptive exponential (values and forward-mode slopes). ``variable="omega"``: f(Ω) (even in Ω);
    ``"omega_squared"``: f(w), w = Ω² of either sign (unstable modes). ``family`` and ``order``
    static, ``m`` traced (``"order_m"``); where m is inadmissible
    (:meth:`~jaxdea.physics.families.Family.admissible`) f is
    NaN.
    """
    if variable not in ("omega", "omega_squared"):
        raise ValueError(f"variable must be 'omega' or 'omega_squared', got {variable!r}")
    wall = discretize(tube, n_layers)
    family = Family(family)
    if family is Family.LONGITUDINAL and variable == "omega":
        return wall, lambda om: value(family, wall, om, alpha, fluid, order, 0, Unknown.OMEGA,
                                      "adaptive")
    ok = family.admissible(m, fluid)
    m_safe = family.safe_m(m, ok)

    def of_w(w):
        f = value(family, wall, w, alpha, fluid, order, m_safe, Unknown.OMEGA_SQUARED, "adaptive")
        return jnp.where(ok, f, jnp.nan)

    if variable == "omega_squared":
        return wall, of_w
    return wall, lambda om: of_w(om * om)
