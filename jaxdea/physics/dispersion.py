"""Boundary conditions, fluid couplings and the real, pole-free characteristic function
(docs/theory/axisymmetric.md §4).

Unknowns at the inner face x = [ū_i, w̄_i, D̄_i]; Y(r̂_i) = S x. The electrodes fix Φ = 0 on both faces
and the faces carry follower pressures (gauge P̂_o = 0, P̂_i = ΔP̂), so the outer-face rows Φ, T̄, S̄
(0-based rows 2, 3, 4) of A S must be singular: det C(Ω) = 0 (paper Eq. 45 corrected, E7/E15).

Fluid couplings clear their denominator by acting on the initial basis S (docs/theory/axisymmetric.md §4(b),
(c)):

* ``acoustic``: column 1 → D_0 S⁰_{·1} − Ω²ρ̂_f N_0 e_T (the dynamic pressure p* = Ω²ρ̂_f B̂_0 ū_i);
* ``paper``: columns 1, 2 → D_ν S⁰_{·j} + Ω²ρ̂_f N_ν S¹_{·j} (Eq. 45 with ΔP̂ → ΔP̂ + P̂_f, P̂_f = Ω²ρ̂_f B̂_ν).

The characteristic function is det(B Q_N), with Q_N the orthonormalised propagated basis
(:func:`jaxdea.physics.transfer.propagate_basis`): real, finite, entire in Ω, the same zeros and sign as
det C, and |f| ≤ 1 (well scaled for Newton at any α̂ĥ).

Circumferential order m (docs/theory/order_m.md §4–§5). A static *family*
(:mod:`jaxdea.physics.state_matrix`) picks the problem: ``"longitudinal"`` (m = 0, the 6×6 system
above, its code unchanged), ``"order_m"``
(the 8×8 system with a traced order m: Y(r̂_i) = S x, x = [U_i, V_i, W_i, D_i], outer rows
Φ, T, Q, S; the acoustic fluid of order m through the U column only) and ``"torsional"``
(m = 0, (V, Q) alone, no fluid coupling). Each is a function of w = Ω² of either sign
(:func:`characteristic_of_w`; w < 0: unstable modes, docs/theory/order_m.md §6), with real arithmetic.
The root solvers evaluate it through :mod:`jaxdea.physics.characteristic`.
"""


import jax
import jax.numpy as jnp
import numpy as np

from ..compiled import cached_jit
from ..numerics.bessel import coupling_pair, outer_impedance
from ..params import (
    Fluid,
    Tube,
    as_float,
    canonical,
    guard,
    validate_real,
    with_outer,
)
from .families import Face, Family
from .problem import describe, family_of, validated_order
from .state_matrix import LONGITUDINAL, ORDER_M, TORSIONAL
from .transfer import (
    EXPONENTIALS,
    Wall,
    alpha_generators,
    carry_basis,
    carry_basis_tangent,
    discretize,
    generator_of_w,
    generators_at_alpha,
    laminate,
    propagate_basis,
    propagate_basis_of_w,
    transfer_matrix,
    transfer_matrix_of_w,
    wall_generators,
)

U, W, PHI, T, S, D = range(6)
OUTER_ROWS = np.array([PHI, T, S])
MECHANICAL = np.array([U, W, T, S])
ELECTRIC = np.array([PHI, D])
"""The two blocks of the longitudinal state that decouple at V̂ = 0 (:func:`value_and_slope_on_wall`)."""


def _unit(i):
    return jnp.zeros(6).at[i].set(1.0)


def initial_basis(wall: Wall, omega, alpha, fluid: Fluid | None = None, order: int = 0):
    """The 6×3 matrix S(Ω) with Y(r̂_i) = S [ū_i, w̄_i, D̄_i] (docs/theory/axisymmetric.md §4), denominators
    cleared."""
    p, ri = wall.pressure_inner, wall.r_inner
    col_u = _unit(U) - (p / ri) * _unit(T) - alpha * p * _unit(S)
    col_w = _unit(W) - alpha * p * _unit(T)
    col_d = _unit(D)
    if fluid is not None:
        rho, c_f = as_float(fluid.density_ratio), as_float(fluid.speed_ratio)
        s = ((omega / c_f) ** 2 - alpha**2) * ri**2  # χ̂² r̂_i²
        if Face.of(fluid) is Face.ACOUSTIC:
            n, d = coupling_pair(s, 0)
            col_u = d * col_u - omega**2 * rho * ri * n * _unit(T)
        else:  # "paper": follower pressure P̂_f on the inner face, no Ṗ term
            # (docs/theory/axisymmetric.md §4(b))
            n, d = coupling_pair(s, order)
            load = omega**2 * rho * ri * n
            col_u = d * col_u + load * (-_unit(T) / ri - alpha * _unit(S))
            col_w = d * col_w + load * (-alpha * _unit(T))
    return jnp.stack([col_u, col_w, col_d], axis=-1)


@jax.custom_jvp
def determinant(a):
    """det(a) of a small square matrix (the value of ``jnp.linalg.det``) whose derivative is
    d det(a)[ȧ] = Σ_ij C_ij ȧ_ij, with the cofactors C_ij = (−1)^{i+j} det(minor_ij): no solve and
    no division, so it is finite at a singular a (every root is one).

    ``jnp.linalg.det``'s own derivative (4×4 and larger) solves with the LU factors and handles a
    rank deficiency only in the last pivot. At V̂ = 0 the wall is electrically decoupled and the
    order-m outer-row matrix Out·Q has the row Φ = (0, 0, 0, x): partial pivoting puts that row
    last, so at a root the near-zero pivot comes before it, and the solve divides by it. Batched
    (8 points at V = 0, m = 1–3) that gave ±inf and NaN derivatives where the point alone was
    finite. Up to 3×3 ``jnp.linalg.det`` is a closed form, already division-free; derivatives of
    any order."""
    return jnp.linalg.det(a)


@determinant.defjvp
def _determinant_jvp(primals, tangents):
    (a,), (a_dot,) = primals, tangents
    n = a.shape[-1]
    if n <= 3:
        return jax.jvp(jnp.linalg.det, (a,), (a_dot,))
    # every minor in one gather and their determinants in one batched call (the n² minors sliced
    # one by one made order-m programs 40 % larger); the products summed in the order (i, j)
    keep = np.array([[k for k in range(n) if k != i] for i in range(n)])
    minors = a[..., keep[:, None, :, None], keep[None, :, None, :]]  # (..., n, n, n-1, n-1)
    signs = (-1.0) ** np.add.outer(np.arange(n), np.arange(n))
    products = signs * determinant(minors) * a_dot
    total = 0.0
    for i in range(n):
        for j in range(n):
            total = total + products[..., i, j]
    return determinant(a), total


def characteristic_and_scale(wall: Wall, omega, alpha, fluid=None, order=0, method="taylor"):
    """(f, log_scale) with det(B A S) = f · exp(log_scale); f = det(B Q_N) ∈ [−1, 1].

    ``method``: the sublayer exponential (:func:`jaxdea.physics.transfer.layer_exponentials`)."""
    q, log_scale = propagate_basis(wall, omega, alpha,
                                   initial_basis(wall, omega, alpha, fluid, order), method)
    if wall.outer is not None:
        return determinant(outer_rows_of(wall, alpha)(omega) @ q), log_scale
    return jnp.linalg.det(q[OUTER_ROWS, :]), log_scale


def decoupled_characteristic_and_scale(wall: Wall, omega, alpha, fluid=None, order=0):
    """(f, log_scale) of :func:`characteristic_and_scale` (``"adaptive"``) on the 4×4 mechanical
    propagation of a wall whose electric block decouples (V̂ = 0; NaN where it does not): the
    values of :func:`_decoupled_value_and_slope` without its slope, f = q_Φ det(B Q_m) and ℓ the
    sum of the blocks' log-scales, equal to the 6×6 values to rounding (tests)."""
    basis = initial_basis(wall, omega, alpha, fluid, order)
    block, (q_phi, log_electric) = _decoupled_generators(wall, alpha)
    exponentials = jax.vmap(EXPONENTIALS["adaptive"])(
        jax.vmap(generator_of_w, (0, None))(block, omega * omega))
    q, log_scale = carry_basis(basis[MECHANICAL, :2], exponentials)
    rows = q[2:] if wall.outer is None else outer_rows_of(wall, alpha)(omega)[1:, MECHANICAL] @ q
    ok = electric_decoupled(wall)
    return (jnp.where(ok, q_phi * determinant(rows), jnp.nan),
            jnp.where(ok, log_scale + log_electric, jnp.nan))


def outer_rows_of(wall: Wall, alpha, m=0, family: str = LONGITUDINAL, w_of=None):
    """x ↦ Out at w = ``w_of``(x) (Ω² of x = Ω by default) for a wall in a surrounding fluid
    (:func:`outer_conditions`); None without one, where the rows do not depend on x. The
    longitudinal rows (Φ, T, S) are formed from (R, L) of :func:`outer_face` directly."""
    if wall.outer is None:
        return None
    w_of = _squared if w_of is None else w_of
    if family != LONGITUDINAL:
        return lambda x: outer_conditions(wall, alpha, m, family, omega_squared=w_of(x))

    def rows(x):
        impedance, load = outer_face(wall, w_of(x), alpha, 0)
        zero, one = jnp.zeros_like(impedance), jnp.ones_like(impedance)
        return jnp.stack([jnp.stack([zero, zero, one, zero, zero, zero]),  # Φ
                          jnp.stack([load, zero, zero, impedance, zero, zero]),  # R T + L U
                          jnp.stack([zero, zero, zero, zero, one, zero])])  # S

    return rows


def characteristic_on_wall(wall: Wall, omega, alpha, fluid=None, order=0, method="taylor", m=0,
                           family=LONGITUDINAL):
    """The scaled characteristic function f(Ω) on a discretised wall (see module docstring).

    ``method="adaptive"`` gives the same values faster, differentiable in forward mode only (the
    root solvers' value-and-slope evaluations). ``family`` (static) and ``m`` (traced,
    ``"order_m"`` only): the mode family; ``"longitudinal"`` is the axisymmetric code path, the
    others :func:`characteristic_of_w` at w = Ω²."""
    if family == LONGITUDINAL:
        return characteristic_and_scale(wall, omega, alpha, fluid, order, method)[0]
    return characteristic_of_w(wall, omega * omega, alpha, fluid, order, method, m, family)


def value_and_slope_on_wall(wall: Wall, omega, alpha, fluid=None, order=0, m=0,
                            family=LONGITUDINAL, decoupled=None, generators=None):
    """(f, df/dΩ) at a real Ω: f of :func:`characteristic_on_wall` with ``method="adaptive"``,
    f' without forward mode through the propagation (the corrector lanes of
    :func:`jaxdea.solve.curves.dispersion_curve`; forward mode through Gram–Schmidt cost 3–4 values).

    f = det(B Q_N) and Y_N = Q_N R with ∏ det R_k > 0, so f = det(B Y_N)/det R and
    f' = D det(B Q_N)[B Z] − f tr(Q_Nᵀ Z), Z = Ẏ_N R⁻¹ (:func:`jaxdea.physics.transfer.carry_basis_tangent`;
    tr(R⁻¹Ṙ) = tr(QᵀẎR⁻¹) because QᵀQ̇ is skew). Only the exponentials and the basis are
    differentiated; f is the array of the forward-mode path. Longitudinal walls whose electric
    block (Φ, D) decouples from the mechanical one (U, W, T, S), as at V̂ = 0
    (:func:`electric_decoupled`, a ``lax.cond``), take the 4×4 mechanical propagation with a 4×2
    basis (:func:`_decoupled_value_and_slope`): f to rounding, 4–5 times faster. ``decoupled``
    (static, longitudinal only): True or False compiles that propagation alone (True: NaN where the
    wall does not decouple), None checks the wall. ``generators``: those of :func:`lane_generators`
    at this α̂ (formed from the wall if None)."""
    if family == LONGITUDINAL:
        return _longitudinal_value_and_slope(wall, omega, alpha, fluid, order, decoupled,
                                             generators=generators)
    full = None if generators is None else generators["full"]
    return _value_and_slope_of_w(wall, alpha, fluid, order, m, family, generators=full)(omega)


def generator_polynomials(wall: Wall, m=0, family=LONGITUDINAL, decoupled=None) -> dict:
    """The generators that :func:`value_and_slope_on_wall` forms from a wall, as polynomials in α̂
    (:func:`jaxdea.physics.transfer.alpha_generators`): ``"full"``, those of the whole state (order m,
    torsion, and a longitudinal wall unless ``decoupled`` is True), and ``"mechanical"``,
    ``"electric"`` (at rest), those of the blocks of a decoupled longitudinal wall (unless
    ``decoupled`` is False). :func:`lane_generators` evaluates them at one α̂."""
    if family != LONGITUDINAL:
        return {"full": alpha_generators(wall, m, family)}
    polys = {}
    if decoupled is None or decoupled:
        polys["mechanical"] = alpha_generators(wall, block=tuple(MECHANICAL))
        polys["electric"] = alpha_generators(wall, at_rest=True, block=tuple(ELECTRIC))
    if not decoupled:
        polys["full"] = alpha_generators(wall)
    return polys


def lane_generators(polys: dict, alpha) -> dict:
    """The generators of :func:`generator_polynomials` at α̂ (the ``generators`` argument of
    :func:`value_and_slope_on_wall`): equal to those formed from the wall, to rounding. With the
    electric block's, ``"electric_column"``: its :func:`electric_column`, which depends on α̂ alone."""
    generators = {k: generators_at_alpha(p, alpha) for k, p in polys.items()}
    if "electric" in generators:
        generators["electric_column"] = electric_column(generators["electric"])
    return generators


def electric_column(electric):
    """(q_Φ, log-scale): the column D̄ = [Φ, D] = [0, 1] of the initial basis (:func:`initial_basis`)
    carried across a decoupled wall by the electric block's exponentials at rest (``electric``: the
    generators of :func:`jaxdea.physics.transfer.wall_generators` with ``at_rest``, ``block=ELECTRIC``), with
    re-normalisation: q_Φ is its Φ entry at the outer face, the factor of f in
    :func:`_decoupled_value_and_slope`. Independent of Ω and of the fluid (the block holds no
    inertia, the column no fluid term), so the corrector lanes of a curve form it once per α̂, not
    at every evaluation (where it also ran beside the mechanical propagation on a second thread)."""
    exponentials = jax.vmap(EXPONENTIALS["adaptive"])(electric[:, 0])
    start = jnp.zeros((2, 1), exponentials.dtype).at[1, 0].set(1.0)  # rows (Φ, D) of [0, 0, 1]ᵀ
    q_d, log_scale = carry_basis(start, exponentials)
    return q_d[0, 0], log_scale


def _longitudinal_value_and_slope(wall, omega, alpha, fluid, order, decoupled, with_scale=False,
                                  generators=None):
    """:func:`value_and_slope_on_wall` of the longitudinal family (``with_scale``: of (f, ℓ), the
    log-scale of :func:`characteristic_and_scale`, whose slope is tr(QᵀZ))."""
    basis_of = lambda om: initial_basis(wall, om, alpha, fluid, order)  # noqa: E731

    def split():
        return _decoupled_value_and_slope(basis_of, wall, alpha, omega, with_scale, generators)

    def full():
        gens = wall_generators(wall, alpha) if generators is None else generators["full"]
        return _coupled_value_and_slope(basis_of, gens, omega, outer_rows_of(wall, alpha),
                                        with_scale)

    if decoupled is None:
        return jax.lax.cond(electric_decoupled(wall), split, full)
    if not decoupled:
        return full()
    ok = electric_decoupled(wall)
    return jax.tree_util.tree_map(lambda v: jnp.where(ok, v, jnp.nan), split())


def scale_and_slope_on_wall(wall: Wall, alpha, fluid=None, order=0, decoupled=True,
                            generators=None):
    """Ω ↦ (f, ℓ) of :func:`characteristic_and_scale` (longitudinal, ``"adaptive"``) whose
    forward-mode derivative is that of :func:`value_and_slope_on_wall` (ℓ' = tr(QᵀZ)): the
    function :func:`jaxdea.solve.roots.scan_roots` classifies (as ``Scaled``), on the 4×4 path of a
    decoupled wall 4–5 times cheaper than forward mode through the 6×6 propagation.
    ``generators``: as for :func:`value_and_slope_on_wall`."""
    return carried_jvp(lambda omega: _longitudinal_value_and_slope(wall, omega, alpha, fluid, order,
                                                                   decoupled, True, generators))


def scale_and_slope_of_w(wall: Wall, alpha, fluid=None, order=0, m=0, family: str = ORDER_M,
                         variable: str = "omega", generators=None):
    """x ↦ (f, ℓ) of :func:`characteristic_and_scale_of_w` (``"adaptive"``) at w = x²
    (``variable="omega"``) or w = x (``"omega_squared"``), whose forward-mode derivative is the
    carried slope of :func:`value_and_slope_on_wall` (ℓ' = tr(QᵀZ)), d/dx by the chain rule
    through w(x): the order-m and torsional function of :func:`jaxdea.solve.roots.scanned_function`,
    without forward mode through Gram–Schmidt. ``generators``: as for
    :func:`value_and_slope_on_wall`."""
    w_of = _squared if variable == "omega" else (lambda x: x)
    full = None if generators is None else generators["full"]
    return carried_jvp(_value_and_slope_of_w(wall, alpha, fluid, order, m, family, w_of, True,
                                             full))


def _value_and_slope_of_w(wall, alpha, fluid, order, m, family, w_of=None, with_scale=False,
                          generators=None):
    """x ↦ (f, f') of the order-m or torsional family at w = ``w_of``(x) (Ω² of x = Ω by default;
    ``with_scale``: ((f, ℓ), (f', ℓ'))), the outer rows and the generators formed once
    (:func:`_coupled_value_and_slope`; ``generators`` given: those)."""
    w_of = _squared if w_of is None else w_of
    out = outer_rows_of(wall, alpha, m, family, w_of) or outer_conditions(wall, alpha, m, family)
    if generators is None:
        generators = wall_generators(wall, alpha, m, family)

    def value_and_slope(x):
        basis_of = lambda y: initial_basis_of_w(wall, w_of(y), alpha, fluid, order, m, family)  # noqa: E731
        return _coupled_value_and_slope(basis_of, generators, x, out, with_scale, w_of)

    return value_and_slope


def carried_jvp(value_and_slope):
    """x ↦ value_and_slope(x)[0] as a ``jax.custom_jvp`` whose tangent is value_and_slope(x)[1]·ẋ."""
    @jax.custom_jvp
    def scaled(x):
        return value_and_slope(x)[0]

    @scaled.defjvp
    def _(primals, tangents):
        (x,), (x_dot,) = primals, tangents
        value, slope = value_and_slope(x)
        return value, jax.tree_util.tree_map(lambda d: d * x_dot, slope)

    return scaled


def electric_decoupled(wall: Wall):
    """True where every longitudinal state matrix of the wall is block-diagonal in (U, W, T, S) and
    (Φ, D), exactly, at every α̂ and Ω: where D̂_r = 0 at every node (a wall without voltage).

    Every entry of the off-diagonal blocks carries d = D̂_r/ε (δ2 = εd/s, δ4 = 2d, δ2β4;
    docs/theory/axisymmetric.md §3, real_tubes.md §2), and the entry δ4/r̂ of Φ' in U is not zero
    where d is (a passive layer has d = 0), so this is the test of the node matrices themselves
    (tests/test_core.py) read from the coefficients once: a test of the matrices at every node
    inside every corrector lane cost 2 µs of a single wall's 33 µs evaluation of 4 lanes, and 12 µs
    of a layered wall's 43 µs (its general 8×8 matrices; measured)."""
    return jnp.all(wall.coef.d == 0)


def _squared(x):
    return x * x


def _exponentials_and_tangents(generators, omega, w_of=_squared):
    """T_k = exp(G_k(w)) (the ``"adaptive"`` exponentials) at w = ``w_of``(x) (Ω² of x = Ω by
    default) and dT_k/dx (forward mode)."""
    def exponentials(om):
        return jax.vmap(EXPONENTIALS["adaptive"])(
            jax.vmap(generator_of_w, (0, None))(generators, w_of(om)))

    return jax.jvp(exponentials, (omega,), (jnp.ones_like(omega),))


def _det_and_slope(rows, rows_dot, q, z):
    """(f, f') = (det(B Q), D det(B Q)[B Z] − f tr(Qᵀ Z)) from B Q, B Z (:func:`value_and_slope_on_wall`)."""
    f, f_dot = jax.jvp(determinant, (rows,), (rows_dot,))
    return f, f_dot - f * jnp.sum(q * z)


def _outer_det_and_slope(q, z, out, out_dot=None):
    """:func:`_det_and_slope` at the outer rows B: ``out`` as a matrix, None for :data:`OUTER_ROWS`;
    ``out_dot``: dB/dx where B depends on x (a surrounding fluid), added as B' Q."""
    rows = (q[OUTER_ROWS, :], z[OUTER_ROWS, :]) if out is None else (out @ q, out @ z)
    if out_dot is not None:
        rows = (rows[0], rows[1] + out_dot @ q)
    return _det_and_slope(*rows, q, z)


def _coupled_value_and_slope(basis_of, generators, omega, out, with_scale=False, w_of=_squared):
    """The full propagation (any family): ``out`` the outer rows as a matrix, None for
    :data:`OUTER_ROWS`, or a function of x (:func:`outer_rows_of`); ``with_scale``: ((f, ℓ),
    (f', ℓ')); the generators at w = ``w_of``(x) and the slopes d/dx."""
    basis, basis_dot = jax.jvp(basis_of, (omega,), (jnp.ones_like(omega),))
    q, z, *log_scale = carry_basis_tangent(
        basis, basis_dot, *_exponentials_and_tangents(generators, omega, w_of), with_scale)
    out_dot = None
    if callable(out):
        out, out_dot = jax.jvp(out, (omega,), (jnp.ones_like(omega),))
    f, f_dot = _outer_det_and_slope(q, z, out, out_dot)
    return ((f, *log_scale), (f_dot, jnp.sum(q * z))) if with_scale else (f, f_dot)


def _decoupled_value_and_slope(basis_of, wall, alpha, omega, with_scale=False, generators=None):
    """f = q_Φ det(Q_m[T, S]) on a longitudinal wall whose state matrices are block-diagonal in
    (U, W, T, S) and (Φ, D) (so are E and every generator, exactly): Q_m from the 4×4 mechanical
    propagation of the basis columns ū, w̄, q from the electric one of the column D̄ (Ω-free: its
    block holds no inertia). The 6×3 Gram–Schmidt of the block-diagonal Y is that of its blocks,
    and det(B Q) = q_Φ (Q_T,ū Q_S,w̄ − Q_T,w̄ Q_S,ū), so f is the same to rounding, from
    exponentials of 4×4 instead of 6×6 matrices (3.4 times fewer products). ``generators``: those
    of :func:`lane_generators` (formed from the wall if None)."""
    basis, basis_dot = jax.jvp(basis_of, (omega,), (jnp.ones_like(omega),))
    block, (q_phi, log_electric) = _decoupled_generators(wall, alpha, generators)
    q, z, *log_scale = carry_basis_tangent(basis[MECHANICAL, :2], basis_dot[MECHANICAL, :2],
                                           *_exponentials_and_tangents(block, omega), with_scale)
    if wall.outer is None:
        f, f_dot = _det_and_slope(q[2:], z[2:], q, z)  # rows T, S of (U, W, T, S)
    else:  # the outer rows T, S on (U, W, T, S): they hold no Φ, D (an inviscid fluid)
        out, out_dot = jax.jvp(lambda om: outer_rows_of(wall, alpha)(om)[1:, MECHANICAL],
                               (omega,), (jnp.ones_like(omega),))
        f, f_dot = _det_and_slope(out @ q, out @ z + out_dot @ q, q, z)
    if with_scale:  # R is block-diagonal too: ℓ is the sum of the blocks' log-scales
        return (q_phi * f, log_scale[0] + log_electric), (q_phi * f_dot, jnp.sum(q * z))
    return q_phi * f, q_phi * f_dot


def _decoupled_generators(wall, alpha, generators=None):
    """(the mechanical block's generator coefficients, (q_Φ, ℓ_e) of :func:`electric_column`) of a
    decoupled wall at α̂: those of :func:`lane_generators` where given, else formed from the wall."""
    if generators is not None:
        return generators["mechanical"], generators["electric_column"]
    return (wall_generators(wall, alpha, block=tuple(MECHANICAL)),
            electric_column(wall_generators(wall, alpha, at_rest=True, block=tuple(ELECTRIC))))


def at_rest_value_and_slope(wall_of, exponentials_of, voltage, alpha, fluid=None, order=0, m=0,
                            family: str = LONGITUDINAL):
    """(f, df/dV̂) of :func:`characteristic_at_rest` on the wall ``wall_of``(V̂) with the sublayer
    exponentials ``exponentials_of``(V̂): f' = D det(B Q)[B Z] − f tr(QᵀZ) with Z carried from the
    tangents of S and of every T_k (:func:`value_and_slope_on_wall`; B is constant in V̂ in the gauge
    P̂_o = 0), without forward mode through Gram–Schmidt."""
    zero = jnp.zeros_like(voltage)
    if family == LONGITUDINAL:
        basis_of = lambda v: initial_basis(wall_of(v), zero, alpha, fluid, order)  # noqa: E731
    else:
        basis_of = lambda v: initial_basis_of_w(wall_of(v), zero, alpha, fluid, order, m, family)  # noqa: E731
    one = jnp.ones_like(voltage)
    basis, basis_dot = jax.jvp(basis_of, (voltage,), (one,))
    q, z = carry_basis_tangent(basis, basis_dot, *jax.jvp(exponentials_of, (voltage,), (one,)))
    out = None if family == LONGITUDINAL else outer_conditions(wall_of(voltage), alpha, m, family)
    return _outer_det_and_slope(q, z, out)


def reference_determinant(wall: Wall, omega, alpha, fluid=None, order=0):
    """det(B A S) from the full 6×6 transfer matrix: the unscaled reference (overflows for large α̂ĥ)."""
    a = transfer_matrix(wall, omega, alpha)
    return jnp.linalg.det(a[OUTER_ROWS, :] @ initial_basis(wall, omega, alpha, fluid, order))


def check_inputs(tube, alpha, fluid, n_layers, scheme="midpoint"):
    """The static Bessel order of the validated public inputs (:func:`jaxdea.physics.problem.describe`
    without the family; ``alpha`` None where a solver takes no α̂ of its own)."""
    return validated_order(tube, alpha, fluid, n_layers, scheme)


def characteristic(tube: Tube, omega, alpha, fluid: Fluid | None = None, n_layers: int | None = None,
                   scheme: str | None = None, m=0, torsional: bool = False, outer: Fluid | None = None):
    """The real characteristic function whose zeros in Ω are the frequencies.

    f(Ω) = det(B Q_N) (module docstring): finite, pole-free, even in Ω, |f| ≤ 1, with the zeros and
    the sign of det C(Ω) of docs/theory/axisymmetric.md §4 (paper Eq. 45 corrected). NaN if the transfer is not
    finite.

    Args:
        tube: the :class:`~jaxdea.Tube`.
        omega: Ω = ω R_i / c_s, a finite real number.
        alpha: α̂ = α R_i >= ALPHA_MIN = 1e-12 (:data:`jaxdea.params.ALPHA_MIN`), with α̂ĥ <=
            ALPHA_THICKNESS_MAX = 150 (ĥ = h/R_i the deformed wall thickness).
        fluid: a :class:`~jaxdea.Fluid`, or None for the empty tube.
        outer: a surrounding :class:`~jaxdea.Fluid` (unbounded, ``"acoustic"``) or None: the tube's own
            ``tube.outer`` (None: vacuum). Subsonic modes carry its added mass
            (docs/theory/real_tubes.md §6).
        n_layers: number of sublayers N (static), or None: the accurate discretisation
            (:func:`jaxdea.frequencies`).
        scheme: how a sublayer is crossed (static): ``"midpoint"`` (the paper's laminate, error
            O(N⁻²)), ``"magnus4"`` or ``"magnus6"`` (O(N⁻⁴), O(N⁻⁶); :mod:`jaxdea.physics.transfer`).
        m: circumferential order, an integer ≥ 0 (docs/theory/order_m.md): 0 is the axisymmetric longitudinal
            family (6×6, unchanged), m ≥ 1 the 8×8 system of order m. A traced m (e.g. under
            ``vmap`` over orders) uses the 8×8 system throughout (compiled once); at m = 0 it gives
            the longitudinal family's zeros.
        torsional: with m = 0, the torsional family (u_θ alone) instead (static).

    Raises:
        ValueError: for invalid concrete inputs, naming the parameter and its allowed range (past
            Gent locking: stating the largest I_1 − 3 in the wall against G); m not an integer ≥ 0,
            the ``"paper"`` coupling with m ≥ 1 (naming m), ``torsional=True`` with m ≥ 1 (naming
            torsional). Traced invalid inputs (under ``jit``/``vmap``) give NaN instead.

    Examples:
        >>> f = characteristic(Tube(), 1.0, 0.445)
        >>> g = characteristic(Tube(), 1.0, 0.445, m=2)
    """
    tube = with_outer(tube, outer)
    problem = describe(tube, alpha, fluid, n_layers, scheme, m, torsional)
    order, family = problem.order, problem.family
    validate_real("omega", omega)
    tube, omega, alpha, fluid = canonical(tube, omega, alpha, fluid)
    if family == LONGITUDINAL:
        return _characteristic(tube, omega, alpha, fluid, laminate(n_layers, scheme, tube, alpha, m=m),
                               order)
    return _characteristic_m(tube, omega * omega, alpha, fluid, as_float(m),
                             laminate(n_layers, scheme, tube, alpha, m=m), order, family)


def characteristic_at_omega_squared(tube: Tube, omega_squared, alpha, fluid: Fluid | None = None,
                                    n_layers: int | None = None, scheme: str | None = None, m=0,
                                    torsional: bool = False):
    """The characteristic function of :func:`characteristic` as a function of w = Ω², any sign.

    Zeros with w > 0 are the frequencies Ω = sqrt(w); zeros with w < 0 the unstable modes, with
    growth rate s = sqrt(−w) (docs/theory/order_m.md §6): f is entire in w and computed in real arithmetic
    (the generator is a polynomial in w, the fluid coupling a function of χ̂² = w/ĉ_f² − α̂²).
    Arguments and errors as :func:`characteristic`; at m = 0 (``torsional=False``) the
    longitudinal family, here formed by the order-m code at m = 0 (same zeros, other scale).

    Examples:
        >>> characteristic_at_omega_squared(Tube(voltage=0.1, lambda_i=0.95, lambda_z=1.2),
        ...                                 -0.5574, 0.445, m=2)  # ≈ 0: an unstable mode
    """
    problem = describe(tube, alpha, fluid, n_layers, scheme, m, torsional)
    order, family = problem.order, problem.family
    validate_real("omega_squared", omega_squared)
    tube, omega_squared, alpha, fluid = canonical(tube, omega_squared, alpha, fluid)
    family = ORDER_M if family == LONGITUDINAL else family
    return _characteristic_m(tube, omega_squared, alpha, fluid, as_float(m),
                             laminate(n_layers, scheme, tube, alpha, m=m), order, family)


@cached_jit(static_argnames=("n_layers", "order", "family"))
def _characteristic_m(tube, omega_squared, alpha, fluid, m, n_layers, order, family):
    """f(w) of the families ``"order_m"`` (traced m) and ``"torsional"``; NaN where traced inputs
    are inadmissible (:func:`~jaxdea.params.guard`,
    :meth:`~jaxdea.physics.families.Family.admissible`) or w not finite.

    The safe m depends on the case only, not on w: under ``vmap`` over w the sublayer generators
    (:func:`jaxdea.physics.transfer.wall_generators`) are then formed once for the whole batch."""
    ok, tube, alpha, fluid = guard(tube, as_float(alpha), fluid)
    ok &= family.admissible(m, fluid)
    m = family.safe_m(m, ok)
    omega_squared = as_float(omega_squared)
    ok &= jnp.isfinite(omega_squared)
    wall = discretize(tube, n_layers)
    f = characteristic_of_w(wall, jnp.where(ok, omega_squared, 1.0), alpha, fluid, order, "taylor",
                            m, family)
    return jnp.where(ok, f, jnp.nan)


@cached_jit(static_argnames=("n_layers", "order"))
def _characteristic(tube, omega, alpha, fluid, n_layers, order):
    """f(Ω); NaN where traced inputs are inadmissible (:func:`~jaxdea.params.guard`) or Ω is not
    finite."""
    ok, tube, alpha, fluid = guard(tube, as_float(alpha), fluid)
    omega = as_float(omega)
    ok &= jnp.isfinite(omega)
    wall = discretize(tube, n_layers)
    f = characteristic_on_wall(wall, jnp.where(ok, omega, 1.0), alpha, fluid, order)
    return jnp.where(ok, f, jnp.nan)


# ------------------------------------------------------------------ circumferential order m

U8, V8, W8, PHI8, T8, Q8, S8, D8 = range(8)
LONGITUDINAL_ROWS = np.array([U8, W8, PHI8, T8, S8, D8])
"""The 6×6 longitudinal state [ū, w̄, Φ, T̄, S̄, D̄] inside the 8-component state of order m."""
LONGITUDINAL_COLUMNS = np.array([0, 2, 3])
"""The unknowns [ū_i, w̄_i, D̄_i] among [U_i, V_i, W_i, D_i]."""


def _unit8(i):
    return jnp.zeros(8).at[i].set(1.0)


def _basis_order_m(wall: Wall, omega_squared, alpha, fluid, order, m):
    """The 8×4 S(Ω²) of docs/theory/order_m.md §4–§5 with Y(r̂_i) = S [U_i, V_i, W_i, D_i], denominators
    cleared.

    Follower pressure P̂_i at r̂_i: T = −P̂_i(U + mV)/r̂_i − α̂P̂_iW − Ṗ, Q = −P̂_i(mU + V)/r̂_i,
    S = −α̂P̂_iU, Φ = 0. Acoustic fluid (§5): Ṗ = κU, κ = Ω²ρ̂_f B̂_m, B̂_m = r̂_i N_m/D_m
    (:func:`jaxdea.numerics.bessel.coupling_pair` at s = χ̂²r̂_i², χ̂² = Ω²/ĉ_f² − α̂², order m), cleared:
    column U → D_m S_{·U} − Ω²ρ̂_f r̂_i N_m e_T. The paper's coupling (docs/theory/axisymmetric.md §4(b), order
    ν) exists at m = 0 only (NaN elsewhere).
    """
    p, ri = wall.pressure_inner, wall.r_inner
    col_u = _unit8(U8) - (p / ri) * _unit8(T8) - (m * p / ri) * _unit8(Q8) - alpha * p * _unit8(S8)
    col_v = _unit8(V8) - (m * p / ri) * _unit8(T8) - (p / ri) * _unit8(Q8)
    col_w = _unit8(W8) - alpha * p * _unit8(T8)
    col_d = _unit8(D8)
    if fluid is not None:
        rho, c_f = as_float(fluid.density_ratio), as_float(fluid.speed_ratio)
        s = (omega_squared / c_f**2 - alpha**2) * ri**2  # χ̂² r̂_i²
        if Face.of(fluid) is Face.ACOUSTIC:
            n, d = coupling_pair(s, m)
            col_u = d * col_u - omega_squared * rho * ri * n * _unit8(T8)
        else:
            n, d = coupling_pair(s, order)
            load = omega_squared * rho * ri * n
            col_u = d * col_u + load * (-_unit8(T8) / ri - alpha * _unit8(S8))
            col_w = d * col_w + load * (-alpha * _unit8(T8))
            axisymmetric = jnp.asarray(m) == 0
            col_u, col_w = (jnp.where(axisymmetric, c, jnp.nan) for c in (col_u, col_w))
    return jnp.stack([col_u, col_v, col_w, col_d], axis=-1)


def initial_basis_of_w(wall: Wall, omega_squared, alpha, fluid: Fluid | None = None, order: int = 0,
                       m=0, family: str = ORDER_M):
    """S(Ω²) with Y(r̂_i) = S x for a mode family (docs/theory/order_m.md §4), at w = ``omega_squared``.

    ``"order_m"``: 8×4 (:func:`_basis_order_m`); ``"longitudinal"``: the 6×3 of docs/theory/axisymmetric.md §4
    (the order-m basis at m = 0 restricted to [ū, w̄, Φ, T̄, S̄, D̄] and [ū_i, w̄_i, D̄_i]; equal to
    :func:`initial_basis` at w = Ω² to rounding); ``"torsional"``: 2×1, [V, Q] = [1, −P̂_i/r̂_i]
    (an inviscid fluid exerts no shear: no fluid term).
    """
    if family == TORSIONAL:
        return jnp.stack([jnp.ones_like(wall.r_inner), -wall.pressure_inner / wall.r_inner])[:, None]
    if family == LONGITUDINAL:
        full = _basis_order_m(wall, omega_squared, alpha, fluid, order, 0)
        return full[LONGITUDINAL_ROWS][:, LONGITUDINAL_COLUMNS]
    return _basis_order_m(wall, omega_squared, alpha, fluid, order, m)


def outer_face(wall: Wall, omega_squared, alpha, m=0):
    """(R, L): the surrounding fluid's face condition R T + L U = 0 at r̂_o (docs/theory/real_tubes.md
    §6): T = −p*_o, p*_o = ρ̂_oΩ² K_m(y)/(γK_m'(y)) U, times γK_m'(y)r̂_o/K_m(y): R = y K_m'(y)/K_m(y)
    (:func:`jaxdea.numerics.bessel.outer_impedance`, < 0: an added mass) and L = ρ̂_o Ω² r̂_o, with
    y = γr̂_o, γ = sqrt(α̂² − Ω²/ĉ_o²). Real for a subsonic real Ω (Ω < ĉ_oα̂), NaN above it in
    real arithmetic. A complex Ω (Re Ω ≥ 0, Ω = sqrt(w)) left of the sound line, Re Ω ≤ ĉ_oα̂,
    takes γ = sqrt(α̂² − Ω²/ĉ_o²) (principal; analytic in that half-strip); right of it the outgoing
    wave γ = ik, k = sqrt(Ω²/ĉ_o² − α̂²) (principal; analytic there), so that K_m(γr) ∝ H_m^(2)(kr)
    radiates (e^{iΩt}; a leaky mode, Im Ω > 0, grows radially: the improper sheet). The two sheets
    meet with a jump along the vertical cut Re Ω = ĉ_oα̂ (:func:`jaxdea.complex_frequencies`
    searches either side of it). A complex α̂ at a real Ω (:func:`jaxdea.wavenumbers`) takes the
    same two sheets by Re α̂ against Ω/ĉ_o: outgoing left of it (supersonic waves radiate),
    decaying right of it, with the cut Re α̂ = Ω/ĉ_o (the search's parts stop either side)."""
    fluid, ro = wall.outer, wall.r_outer
    rho, c_o = as_float(fluid.density_ratio), as_float(fluid.speed_ratio)
    y_squared = (alpha * alpha - omega_squared / (c_o * c_o)) * ro * ro
    if jnp.iscomplexobj(y_squared):
        leaky = jnp.real(jnp.sqrt(omega_squared)) > c_o * jnp.real(alpha)
        y = jnp.where(leaky, 1j * jnp.sqrt(-y_squared), jnp.sqrt(y_squared))
    else:
        y = jnp.sqrt(jnp.where(y_squared > 0, y_squared, jnp.nan))
    return outer_impedance(y, m), rho * omega_squared * ro


def outer_conditions(wall: Wall, alpha, m=0, family: str = ORDER_M, pressure_outer=0.0,
                     omega_squared=None):
    """The rows Out with Out·Y(r̂_o) = 0 (docs/theory/order_m.md §4), for an outer pressure P̂_o.

    ``"order_m"`` (4×8): e_Φ; e_T + P̂_o(e_U/r̂_o + m e_V/r̂_o + α̂ e_W); e_Q + P̂_o(m e_U + e_V)/r̂_o;
    e_S + α̂P̂_o e_U. At m = 0 the row Q is e_V instead: V is constant there (its rows are switched
    off, :func:`jaxdea.physics.state_matrix.torsion_switch`), so the determinant is the longitudinal one
    times a constant factor. ``"longitudinal"`` (3×6): the rows Φ, T̄, S̄ of docs/theory/axisymmetric.md §4;
    ``"torsional"`` (1×2): e_Q + P̂_o e_V/r̂_o. The library's gauge is P̂_o = 0 (then the plain rows
    Φ, T, Q, S); a non-zero P̂_o with P̂_i, p̂ shifted alike checks gauge invariance (§7e).

    A surrounding fluid (``wall.outer``) at w = ``omega_squared``: the row T becomes R e_T + L e_U
    (:func:`outer_face`); an inviscid fluid exerts no shear, so Q, S and the torsional row stay.
    ``omega_squared`` None (Ω = 0, where L = 0 and the row is R e_T ∝ e_T): the plain rows.
    """
    po, ro = as_float(pressure_outer), wall.r_outer
    if family == TORSIONAL:
        return jnp.stack([po / ro, jnp.ones_like(po)])[None, :]
    m_rows = 0.0 if family == LONGITUDINAL else as_float(m)
    row_t = _unit8(T8) + po * (_unit8(U8) / ro + m_rows * _unit8(V8) / ro + alpha * _unit8(W8))
    if wall.outer is not None and omega_squared is not None:
        impedance, load = outer_face(wall, omega_squared, alpha, m_rows)
        row_t = impedance * row_t + load * _unit8(U8)
    rows = jnp.stack([
        _unit8(PHI8),
        row_t,
        _unit8(Q8) + po * (m_rows * _unit8(U8) + _unit8(V8)) / ro,
        _unit8(S8) + alpha * po * _unit8(U8),
    ])
    if family == LONGITUDINAL:
        return rows[np.array([0, 1, 3])][:, LONGITUDINAL_ROWS]
    return rows.at[2].set(jnp.where(jnp.asarray(m) == 0, _unit8(V8), rows[2]))


def characteristic_and_scale_of_w(wall: Wall, omega_squared, alpha, fluid=None, order=0,
                                  method="taylor", m=0, family: str = ORDER_M, pressure_outer=0.0):
    """(f, log_scale) with det(Out A S) = f · exp(log_scale) at w = Ω² (docs/theory/order_m.md §4–§6).

    S from :func:`initial_basis_of_w`, propagated with re-orthonormalisation
    (:func:`jaxdea.physics.transfer.propagate_basis_of_w`, 8×4 basis for order m), f = det(Out Q_N) ∈ [−1, 1]
    (:func:`outer_conditions`): real for real w of either sign, entire in w, pole-free.
    """
    basis = initial_basis_of_w(wall, omega_squared, alpha, fluid, order, m, family)
    q, log_scale = propagate_basis_of_w(wall, omega_squared, alpha, basis, method, m, family)
    out = outer_conditions(wall, alpha, m, family, pressure_outer, omega_squared)
    return determinant(out @ q), log_scale


def characteristic_of_w(wall: Wall, omega_squared, alpha, fluid=None, order=0, method="taylor",
                        m=0, family: str = ORDER_M, pressure_outer=0.0):
    """The scaled characteristic function at w = Ω² (either sign) on a discretised wall.

    f(w) = det(Out Q_N) (:func:`characteristic_and_scale_of_w`); its zeros in w < 0 are the
    unstable modes (growth rate sqrt(−w)), those in w > 0 the frequencies Ω = sqrt(w).
    ``family`` is static; ``m`` may be traced (``"order_m"``)."""
    return characteristic_and_scale_of_w(wall, omega_squared, alpha, fluid, order, method, m,
                                         family, pressure_outer)[0]


def characteristic_at_rest(wall: Wall, exponentials, alpha, fluid=None, order=0, m=0,
                           family: str = LONGITUDINAL):
    """f(Ω = 0) on ``wall`` with its sublayer exponentials T_k given (N, n, n): the value of
    :func:`characteristic_on_wall` (longitudinal) or :func:`characteristic_of_w` (w = 0) with
    ``method="at_rest"``, whose T_k the critical-voltage search forms from the generators' expansion
    in V̂ (:func:`jaxdea.physics.transfer.voltage_exponentials`)."""
    zero = jnp.zeros_like(wall.r_inner)
    if family == LONGITUDINAL:
        q, _ = carry_basis(initial_basis(wall, zero, alpha, fluid, order), exponentials)
        return jnp.linalg.det(q[OUTER_ROWS, :])
    q, _ = carry_basis(initial_basis_of_w(wall, zero, alpha, fluid, order, m, family), exponentials)
    return determinant(outer_conditions(wall, alpha, m, family) @ q)


def reference_determinant_of_w(wall: Wall, omega_squared, alpha, fluid=None, order=0, m=0,
                               family: str = ORDER_M, pressure_outer=0.0):
    """det(Out A S) from the full transfer matrix (``expm`` per sublayer): the unscaled reference."""
    a = transfer_matrix_of_w(wall, omega_squared, alpha, "expm", m, family)
    basis = initial_basis_of_w(wall, omega_squared, alpha, fluid, order, m, family)
    return jnp.linalg.det(outer_conditions(wall, alpha, m, family, pressure_outer, omega_squared)
                          @ a @ basis)


def mode_family(m=0, torsional=False, fluid: Fluid | None = None) -> Family:
    """The static family of (m, torsional), validated (:func:`jaxdea.physics.problem.family_of`)."""
    return family_of(m, torsional, fluid)
