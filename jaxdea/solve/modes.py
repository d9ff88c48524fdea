"""Mode shapes: the state fields across the wall and the acoustic pressure in the cavity for a root Ω
(docs/theory/axisymmetric.md §3–4).

One solve serves both public functions (:func:`mode_shape`, :func:`fluid_pressure`):

1. the initial basis S(Ω) (:func:`jaxdea.physics.dispersion.initial_basis`, denominators cleared) is carried
   across the wall with re-orthonormalisation, T_k Q_{k−1} = Q_k R_k, S = Q_0 R_0
   (:func:`jaxdea.physics.transfer.propagate_basis_history`);
2. the null vector c_N of the outer-face rows (Φ, T̄, S̄) of Q_N is carried back, c_{k−1} = R_k⁻¹ c_k
   (triangular solves: stable for any α̂ĥ), giving the state Y_k = Q_k c_k at every interface and the
   coefficients x = R_0⁻¹ c_0 of the columns of S, Y(r̂_i) = S x;
3. inside sublayer k the fields are exp[(r̂ − r̂_{k−1}) M(r̂_k)] Y_{k−1}; all of them are divided by
   the displacement entry of largest modulus (so max(|ū|, |w̄|) = 1 and that entry is +1).

The consistent acoustic coupling (docs/theory/axisymmetric.md §4(c)) writes the ū column of S as
D_0 S⁰_{·1} − Ω²ρ̂_f r̂_i N_0 e_T̄, so with c_u = x_0:

    ū_i = D_0 c_u,   p̂*(r̂_i) = Ω²ρ̂_f B̂_0 ū_i = Ω²ρ̂_f r̂_i N_0 c_u,

and no division by D_0 (zero at the rigid-wall cavity resonances) or by N_0 is ever needed.
"""


from typing import NamedTuple

import jax
import jax.numpy as jnp

from ..compiled import cached_jit
from ..numerics.bessel import coupling_log_factor, coupling_pair, scaled_k
from ..numerics.scalar import ROOT_RTOL, newton_distance, refuse_non_root, value_and_slope
from ..params import (
    Fluid,
    Tube,
    admissible,
    as_float,
    canonical,
    validate_count,
    validate_positive,
    validate_real,
    with_outer,
)
from ..physics.characteristic import problem_function
from ..physics.dispersion import (
    OUTER_ROWS,
    U,
    W,
    initial_basis,
    initial_basis_of_w,
    outer_conditions,
)
from ..physics.families import Face
from ..physics.problem import describe
from ..physics.state_matrix import LONGITUDINAL, family_matrix, state_matrix
from ..physics.transfer import (
    Wall,
    discretize,
    expm_taylor,
    is_graded,
    laminate,
    layer_coefficients,
    propagate_basis_history,
    split_layers,
)


def root_distance(tube, alpha, omega, fluid, n_layers, order, m=0.0, family=LONGITUDINAL):
    """|f(Ω)|/(|f'(Ω)| |Ω|): the relative size of the Newton step from Ω to the nearest root (0 at a
    root; at Ω = 0, where f' = 0 by symmetry, 0 if |f| ≤ 1e-12 (f is normalised, |f| ≤ 1), else
    inf)."""
    _, f = problem_function(tube, alpha, fluid, n_layers, order, m, family)
    return newton_distance(*value_and_slope(f, omega), omega)


def _interface_solution(wall: Wall, omega, alpha, fluid, order, m=0.0, family=LONGITUDINAL):
    """States Y_k (N+1, n) at the interfaces r̂_i = r̂_0 < … < r̂_N = r̂_o and the coefficients
    x (k,) of the initial basis, Y_0 = S x (module docstring, steps 1–2). Unnormalised.

    ``family`` (static) and ``m`` (traced, ``"order_m"``): the basis, propagation and outer rows of
    that family (docs/theory/order_m.md §4), n × k = 6 × 3, 8 × 4 or 2 × 1."""
    if not family.carries_m:
        basis = initial_basis(wall, omega, alpha, fluid, order)
        qs, rs = propagate_basis_history(wall, omega, alpha, basis)
        # null vector of the outer-face conditions in the last basis, then back through the R factors
        rows = (qs[-1][OUTER_ROWS, :] if wall.outer is None
                else outer_conditions(wall, alpha, 0, family, omega_squared=omega * omega) @ qs[-1])
        _, _, vt = jnp.linalg.svd(rows)
    else:
        w = omega * omega
        basis = initial_basis_of_w(wall, w, alpha, fluid, order, m, family)
        qs, rs = propagate_basis_history(wall, omega, alpha, basis, "taylor", m, family)
        _, _, vt = jnp.linalg.svd(outer_conditions(wall, alpha, m, family, omega_squared=w)
                                  @ qs[-1])

    def back(c, r):
        return jax.scipy.linalg.solve_triangular(r, c, lower=False), c

    c_0, cs = jax.lax.scan(back, vt[-1], rs[1:], reverse=True)  # cs[k]: coefficients at interface k+1
    states = jnp.einsum("kij,kj->ki", qs, jnp.concatenate([c_0[None], cs]))
    return states, jax.scipy.linalg.solve_triangular(rs[0], c_0, lower=False)


def _midpoints(tube: Tube, wall: Wall):
    """(interfaces r̂_0 … r̂_N, mid-radii, coefficients there) of any discretisation: the wall's own
    for the equal midpoint laminate, else the sublayers' mid-radii (Magnus nodes, graded walls)."""
    count = wall.radii.shape[0]
    if jnp.ndim(wall.step):
        edges = wall.r_inner + jnp.concatenate([jnp.zeros(1), jnp.cumsum(wall.step)])
    else:
        edges = wall.r_inner + jnp.arange(count + 1) * wall.step
    if wall.radii.ndim == 1:
        return edges, wall.radii, wall.coef
    mids = 0.5 * (edges[:-1] + edges[1:])
    return edges, mids, layer_coefficients(tube, mids)


def _wall_fields(tube: Tube, wall: Wall, states, omega, alpha, n_points: int, m=0.0,
                 family=LONGITUDINAL):
    """Radii (n_points,) from r̂_i to r̂_o and the fields (n_points, n) there (module docstring,
    step 3), unnormalised; inside a sublayer, the exponential of the state matrix of ``family``
    (order ``m``) at its mid-radius from the state at its nearer interface (exact at the
    interfaces, which carry the scheme's accuracy; the midpoint laminate is exact throughout)."""
    edges, mids, mid_coef = _midpoints(tube, wall)
    count = mids.shape[0]
    r = jnp.linspace(wall.r_inner, wall.r_outer, n_points)
    layer = jnp.clip(jnp.searchsorted(edges, r, side="right") - 1, 0, count - 1)
    # from the nearer interface of the sublayer (exactly the interface states at r̂_i, r̂_o and at
    # every interface sampled: the crossing by the midpoint exponential is the scheme's only there)
    after = r - edges[layer] > edges[layer + 1] - r
    start = jnp.where(after, edges[layer + 1], edges[layer])
    base = jnp.where(after[:, None], states[layer + 1], states[layer])
    coef = jax.tree_util.tree_map(lambda x: x[layer], mid_coef)
    if not family.carries_m:
        mats = jax.vmap(state_matrix, (0, 0, None, None))(coef, mids[layer], omega, alpha)
    else:
        mats = jax.vmap(lambda c, rad: family_matrix(family, c, rad, omega * omega, alpha, m))(
            coef, mids[layer])
    return r, jax.vmap(lambda m, d, y: expm_taylor(d * m) @ y)(mats, r - start, base)


def _displacement_scale(fields, displacements=slice(U, W + 1)):
    """The displacement entry (ū or w̄) of largest modulus over the sampled fields (n_points, 6)
    (``displacements``: the columns of the displacements, e.g. ū, v̄, w̄ of order m).

    A direction without displacement (below 1e-13 of the largest field: e.g. the electrical
    direction that is least singular at a non-root Ω of a tube at V̂ = 0, where the electrical
    problem decouples) is scaled by its entry of largest modulus instead: finite, never 0/0."""
    big = jnp.argmax(jnp.max(jnp.abs(fields[:, displacements]), axis=1))
    comp = jnp.argmax(jnp.abs(fields[big, displacements]))
    displacement = fields[big, displacements][comp]
    flat = jnp.ravel(fields)
    largest = flat[jnp.argmax(jnp.abs(flat))]
    return jnp.where(jnp.abs(displacement) > 1e-13 * jnp.abs(largest), displacement, largest)


def _cavity_pressure(wall: Wall, omega, alpha, fluid: Fluid, c_u, n_points: int, m=None):
    """Radii (n_points,) from 0 to r̂_i and p̂*(r̂) = Ω²ρ̂_f r̂_i c_u · N_0(χ̂²r̂²) e^{g(χ̂²r̂_i²) − g(χ̂²r̂²)}.

    With an order ``m`` (None: the axisymmetric code, order 0): the same with N_m, times
    (r̂/r̂_i)^m, i.e. p̂*(r̂_i) J_m(χ̂r̂)/J_m(χ̂r̂_i) (N_m ∝ J_m(x)/x^m, docs/theory/order_m.md §5).

    N_0(s) e^{−g(s)} is J_0(sqrt(s)) (s ≥ 0) or I_0(sqrt(−s)) (s < 0) (:func:`coupling_log_factor`),
    and the basis column carries N_0(χ̂²r̂_i²) with its own factor e^{g(χ̂²r̂_i²)}, so this is
    p̂*(r̂_i) J_0(χ̂r̂)/J_0(χ̂r̂_i) with p̂*(r̂_i) = Ω²ρ̂_f r̂_i N_0 c_u (docs/theory/axisymmetric.md §4(c)),
    computed without dividing by J_0(χ̂r̂_i); g(χ̂²r̂_i²) − g(χ̂²r̂²) ≤ 0 for r̂ ≤ r̂_i, so nothing overflows.
    """
    rho, c_f = as_float(fluid.density_ratio), as_float(fluid.speed_ratio)
    ri = wall.r_inner
    chi2 = (omega / c_f) ** 2 - alpha**2  # χ̂²
    r = jnp.linspace(0.0, ri, n_points)
    s = chi2 * r**2
    if m is None:
        n = jax.vmap(lambda x: coupling_pair(x, 0)[0])(s)
        ratio = jnp.exp(coupling_log_factor(chi2 * ri**2) - coupling_log_factor(s))
        return r, omega**2 * rho * ri * c_u * n * ratio
    n = jax.vmap(lambda x: coupling_pair(x, m)[0])(s)
    ratio = jnp.exp(coupling_log_factor(chi2 * ri**2) - coupling_log_factor(s))
    return r, omega**2 * rho * ri * c_u * n * ratio * (r / ri) ** m


@cached_jit(static_argnames=("n_points", "n_layers", "order", "family"))
def _solve_mode(tube, alpha, omega, fluid, n_points, n_layers, order, m=0.0, family=LONGITUDINAL):
    """(r, fields (n, n_points), r_f, p, distance) in the normalisation of :func:`mode_shape`; r_f, p
    are the cavity radii and acoustic pressure for the ``acoustic`` coupling, None otherwise; NaN
    where ``omega`` is farther than ROOT_RTOL from a root (``distance``: :func:`root_distance`).

    ``family`` (static) ``"longitudinal"``: the 6 fields of docs/theory/axisymmetric.md §3 (the axisymmetric
    code); ``"order_m"`` (traced ``m``) and ``"torsional"``: the 8 fields [ū, v̄, w̄, Φ, T̄, Q̄, S̄, D̄] of
    docs/theory/order_m.md §1 (torsional: v̄, Q̄ only, the others 0)."""
    alpha, omega = as_float(alpha), as_float(omega)
    wall = discretize(tube, n_layers)
    if not family.carries_m:
        states, coefficients = _interface_solution(wall, omega, alpha, fluid, order)
        r, fields = _wall_fields(tube, wall, states, omega, alpha, n_points)
        scale = _displacement_scale(fields)
        order_ok = True
    else:
        order_ok = family.admissible(m, fluid)
        m = family.safe_m(m, order_ok)
        states, coefficients = _interface_solution(wall, omega, alpha, fluid, order, m, family)
        r, fields = _wall_fields(tube, wall, states, omega, alpha, n_points, m, family)
        if family.size < 8:  # its rows (torsional: V, Q) into the 8 fields
            rows = jnp.array(family.order_m_rows)
            fields = jnp.zeros((n_points, 8), fields.dtype).at[:, rows].set(fields)
        scale = _displacement_scale(fields, slice(0, 3))
    r_f = p = None
    if Face.of(fluid).has_pressure:
        if family.moves_fluid:  # order 0 (the axisymmetric code) or m
            order_m = m if family.carries_m else None
            r_f, p = _cavity_pressure(wall, omega, alpha, fluid, coefficients[0], n_points, order_m)
        else:  # an inviscid fluid exerts no shear: a torsional mode leaves it at rest
            r_f, p = jnp.linspace(0.0, wall.r_inner, n_points), jnp.zeros(n_points)
        p = p / scale
    # traced inputs outside their range give NaN (concrete ones were validated by the callers), and
    # so does an omega that is no root: its "shape" would look plausible and mean nothing
    distance = root_distance(tube, alpha, omega, fluid, n_layers, order, m, family)
    ok = admissible(tube, alpha, fluid) & jnp.isfinite(omega) & order_ok
    ok &= distance <= ROOT_RTOL
    nan = lambda x: None if x is None else jnp.where(ok, x, jnp.nan)  # noqa: E731
    return nan(r), nan((fields / scale).T), nan(r_f), nan(p), distance


def _check_mode_arguments(omega, n_points) -> None:
    """Ω must be a finite real scalar (a root; batches go through ``jax.vmap``) and ``n_points`` a
    static integer >= 1."""
    validate_real("omega", omega, "a finite real number (a root of the characteristic function)")
    validate_count("n_points", n_points)


def _describe(layers) -> str:
    count, scheme = split_layers(layers)
    return f"{scheme}{', graded' if is_graded(layers) else ''}, N = {count}"


def _solve(tube, alpha, omega, fluid, n_points, n_layers, scheme, m, torsional):
    """Validate, then :func:`_solve_mode` (the axisymmetric program unchanged for m = 0); a
    concrete ``omega`` that is no root raises (a traced one gives NaN fields)."""
    problem = describe(tube, alpha, fluid, n_layers, scheme, m, torsional)
    _check_mode_arguments(omega, n_points)
    tube, alpha, omega, fluid, m = canonical(tube, alpha, omega, fluid, m)
    layers = laminate(n_layers, scheme, tube, alpha, m=m)
    out = _solve_mode(tube, alpha, omega, fluid, int(n_points), layers, problem.order,
                      **problem.arguments(as_float(m)))
    refuse_non_root(omega, out[-1], f" of this case (order m = {m if problem.family.reads_m else 0}, "
                    f"{_describe(layers)})", " of the same tube, α̂, fluid and order")
    return out[:-1]


ROWS_6 = {"u": 0, "v": None, "w": 1, "phi": 2, "T": 3, "Q": None, "S": 4, "D": 5}
ROWS_8 = {"u": 0, "v": 1, "w": 2, "phi": 3, "T": 4, "Q": 5, "S": 6, "D": 7}
"""Rows of the fields: the longitudinal state [ū, w̄, Φ, T̄, S̄, D̄] (docs/theory/axisymmetric.md §3)
and the order-m state [ū, v̄, w̄, Φ, T̄, Q̄, S̄, D̄] (docs/theory/order_m.md §1)."""


class ModeShape(NamedTuple):
    """What :func:`mode_shape` returns: ``(r, fields)``, with the fields by name as well.

    ``fields`` has the rows of the family's state (API.md): 6 for the longitudinal family at a
    concrete m = 0, 8 otherwise. The names are the same for every family, concrete or traced m:
    ``u, v, w`` (ū, v̄, w̄), ``phi`` (Φ), ``T, Q, S, D`` (T̄, Q̄, S̄, D̄); v̄ and Q̄ are zero where the
    state has no such row (a longitudinal mode has no u_θ)."""

    r: jax.Array
    fields: jax.Array

    def field(self, name: str) -> jax.Array:
        """The named field (shape of ``r``, batch axes included)."""
        rows = ROWS_6 if self.fields.shape[-2] == 6 else ROWS_8
        if name not in rows:
            raise ValueError(f"name must be one of {', '.join(rows)}, got {name!r}")
        row = rows[name]
        return jnp.zeros_like(self.fields[..., 0, :]) if row is None else self.fields[..., row, :]

    u = property(lambda self: self.field("u"))
    v = property(lambda self: self.field("v"))
    w = property(lambda self: self.field("w"))
    phi = property(lambda self: self.field("phi"))
    T = property(lambda self: self.field("T"))
    Q = property(lambda self: self.field("Q"))
    S = property(lambda self: self.field("S"))
    D = property(lambda self: self.field("D"))


def mode_shape(tube: Tube, alpha, omega, fluid: Fluid | None = None, n_points: int = 64,
               n_layers: int | None = None, m=0, torsional: bool = False, scheme: str | None = None,
               outer: Fluid | None = None):
    """The state fields [ū, w̄, Φ, T̄, S̄, D̄] across the wall for the root ``omega``
    ([ū, v̄, w̄, Φ, T̄, Q̄, S̄, D̄] for order m ≥ 1, a traced m or ``torsional=True``).

    Y = [ū, w̄, Φ, T̄, S̄, D̄] is the state of docs/theory/axisymmetric.md §3 (u_r = R_i ū cos αz, u_z = R_i w̄
    sin αz, Ṫ_rr = μ T̄ cos αz, …). The null vector of the outer-face conditions (docs/theory/axisymmetric.md
    §4) is carried back through the orthonormalised propagation (stable for any α̂ĥ) and the fields inside each
    sublayer follow from its exponential (module docstring). Scaled so that max(|ū|, |w̄|) = 1 over
    the ``n_points`` samples, the displacement entry of largest modulus being +1; the acoustic
    pressure of :func:`fluid_pressure` with the same ``n_points`` uses the same scale.

    ``omega`` must be a root of the characteristic function of the same case and laminate, to a
    relative Newton distance |f/f'|/|Ω| ≤ ``ROOT_RTOL`` = 1e-4 (a root from another discretisation
    that resolves the tube passes): a concrete non-root raises a ValueError, a traced one gives NaN
    fields. A mode without displacement (at V̂ = 0 the electrical problem decouples) is scaled so
    that its entry of largest modulus is +1.

    Circumferential order m (docs/theory/order_m.md §1): u_r = R_i ū cos mθ cos αz, u_θ = R_i v̄ sin mθ cos αz,
    u_z = R_i w̄ cos mθ sin αz, Ṫ_rθ = μ Q̄ sin mθ cos αz, the others as for m = 0; the 8 fields
    are scaled so that max(|ū|, |v̄|, |w̄|) = 1. ``torsional=True`` (m = 0): the torsional mode
    (u_θ alone), as 8 fields with only v̄ and Q̄ non-zero. A traced m (e.g. under ``vmap``) gives
    8 fields at every m (at m = 0 the longitudinal mode with v̄ = Q̄ = 0).

    Args:
        tube: the :class:`~jaxdea.Tube`.
        alpha: α̂ = α R_i > 0.
        omega: a root Ω of the characteristic function (e.g. from :func:`jaxdea.frequencies`).
        fluid: a :class:`~jaxdea.Fluid`, or None for the empty tube.
        outer: a surrounding :class:`~jaxdea.Fluid` (unbounded, ``"acoustic"``) or None: the tube's own
            ``tube.outer`` (None: vacuum). Subsonic modes carry its added mass
            (docs/theory/real_tubes.md §6).
        n_points: number of radii sampled across the wall (static).
        n_layers, scheme: the discretisation (static; :func:`jaxdea.frequencies`, default the
            accurate one): use the one the root was found with. The states at the sublayer
            interfaces have the scheme's accuracy; inside a sublayer the fields follow from the
            exponential of M at its mid-radius.
        m: circumferential order, an integer ≥ 0 (the order the root was found with).
        torsional: with m = 0, the torsional family (static).

    Returns:
        An instance of :class:`ModeShape`, ``(r, fields)``, with the radii r̂ (n_points,) from r̂_i
        to r̂_o and the fields (6, n_points) for m = 0 (longitudinal), (8, n_points) otherwise; the
        same named fields (``.u``, ``.v``, ``.w``, ``.phi``, ``.T``, ``.Q``, ``.S``, ``.D``) for
        every family.

    Raises:
        ValueError: for invalid concrete inputs, naming the parameter (m not an integer ≥ 0,
            ``torsional=True`` with m ≥ 1, the ``"paper"`` coupling with m ≥ 1, an ``omega`` that
            is not a root).

    Examples:
        >>> import jaxdea as jd
        >>> tube = jd.Tube(voltage=0.1, lambda_i=0.9, lambda_z=1.2)
        >>> omega = jd.frequencies(tube, 0.445)[0]
        >>> r, (u, w, phi, t, s, d) = jd.mode_shape(tube, 0.445, omega)
        >>> omega2 = jd.frequencies(tube, 0.445, m=2)[0]
        >>> r, (u, v, w, phi, t, q, s, d) = jd.mode_shape(tube, 0.445, omega2, m=2)
        >>> jd.mode_shape(tube, 0.445, omega).w  # by name: the same for every family
    """
    tube = with_outer(tube, outer)
    r, fields, _, _ = _solve(tube, alpha, omega, fluid, n_points, n_layers, scheme, m, torsional)
    return ModeShape(r, fields)


def fluid_pressure(tube: Tube, alpha, omega, fluid: Fluid, n_points: int = 64,
                   n_layers: int | None = None, m=0, scheme: str | None = None,
                   outer: Fluid | None = None):
    """The acoustic excess pressure p̂*(r̂) in the cavity for the root ``omega`` (docs/theory/axisymmetric.md
    §4(c)).

    The fluid field of the consistent acoustic coupling, p* = μ p̂*(r̂) cos αz with

        p̂*(r̂) = A J_0(χ̂ r̂),  χ̂² = Ω²/ĉ_f² − α̂²  (A I_0(χ̃ r̂), χ̃² = −χ̂², when χ̂² < 0),

    regular on the axis, solves the Helmholtz equation p̂*'' + p̂*'/r̂ + χ̂² p̂* = 0 and, from
    ρ_f ü = −grad p*, dp̂*/dr̂ = Ω²ρ̂_f ū (so p̂*(r̂_i) = Ω²ρ̂_f B̂_0 ū_i, B̂_0 = J_0(x)/(χ̂ J_0'(x)),
    x = χ̂ r̂_i). It is the −Ṗ̂ = −p̂*(r̂_i) load in the inner-face traction T̄(r̂_i) of
    :func:`mode_shape`. Computed in the normalisation of :func:`mode_shape` with the same
    ``n_points`` (max(|ū|, |w̄|) = 1 over the wall, same sign), from the coefficient of the ū column
    of the initial basis, p̂*(r̂_i) = Ω²ρ̂_f r̂_i N_0 c_u (module docstring): finite also where
    D_0 = 0 (rigid-wall cavity resonance, ū_i = 0) or J_0(x) = 0 (pressure node at the wall).

    In SI units the pressure is μ p̂* per unit of the displacement scale R_i (see
    :mod:`jaxdea.physics.units`): a mode with largest displacement δ has pressure μ (δ/R_i) p̂*.

    Order m (docs/theory/order_m.md §5): p* = μ p̂*(r̂) cos mθ cos αz with p̂*(r̂) = A J_m(χ̂ r̂) (A I_m(χ̃ r̂)
    when χ̂² < 0), p̂*(r̂_i) = Ω²ρ̂_f B̂_m ū_i, in the normalisation of ``mode_shape(..., m=m)``;
    computed as p̂*(r̂_i) J_m(χ̂r̂)/J_m(χ̂r̂_i) without that division (0 on the axis for m ≥ 1).

    Args:
        tube: the :class:`~jaxdea.Tube`.
        alpha: α̂ = α R_i > 0.
        omega: a root Ω of the fluid-filled tube (e.g. ``frequencies(tube, alpha, fluid)``).
        fluid: a :class:`~jaxdea.Fluid` with ``coupling="acoustic"``.
        outer: a surrounding :class:`~jaxdea.Fluid` (unbounded, ``"acoustic"``) or None: the tube's own
            ``tube.outer`` (None: vacuum). Subsonic modes carry its added mass
            (docs/theory/real_tubes.md §6).
        n_points: number of radii sampled in the cavity and across the wall (static).
        n_layers, scheme: the discretisation (static; use the one the root was found with).
        m: circumferential order, an integer ≥ 0 (the order the root was found with).

    Returns:
        (r, p): radii r̂ (n_points,) from 0 (the axis) to r̂_i and p̂*(r̂) (n_points,).

    Raises:
        ValueError: if ``fluid`` is None or uses the ``"paper"`` coupling (the paper's model has no
            pressure field: the fluid acts only as a follower pressure on the inner face,
            docs/theory/axisymmetric.md §4(b)), or for invalid concrete inputs, naming the parameter.

    Examples:
        >>> import jaxdea as jd
        >>> from jaxdea.solve.modes import fluid_pressure
        >>> tube, fluid = jd.Tube(lambda_i=0.9, lambda_z=1.2), jd.Fluid()
        >>> omega = jd.frequencies(tube, 0.445, fluid)[0]
        >>> r, p = fluid_pressure(tube, 0.445, omega, fluid)
    """
    tube = with_outer(tube, outer)
    if fluid is None:
        raise ValueError("fluid must be a jaxdea.Fluid: the empty tube (fluid=None) has no fluid pressure")
    if isinstance(fluid, Fluid) and Face.of(fluid, strict=False).has_poles:
        raise ValueError(
            "coupling='paper' has no fluid pressure field: the paper's model (docs/theory/axisymmetric.md "
            "§4(b)) loads the inner face with an Ω-dependent follower pressure P̂_f only; use "
            "coupling='acoustic'"
        )
    _, _, r, p = _solve(tube, alpha, omega, fluid, n_points, n_layers, scheme, m, False)
    return r, p


def outer_pressure(tube: Tube, alpha, omega, fluid: Fluid | None = None, n_points: int = 64,
                   extent=4.0, n_layers: int | None = None, m=0, scheme: str | None = None,
                   outer: Fluid | None = None):
    """The acoustic excess pressure p̂*_o(r̂) in the surrounding fluid for the subsonic root ``omega``
    (docs/theory/real_tubes.md §6), in the normalisation of :func:`mode_shape`:

        p̂*_o(r̂) = −T̄(r̂_o) K_m(γr̂)/K_m(γr̂_o),  γ = sqrt(α̂² − Ω²/ĉ_o²),

    the field that decays away from the tube (Helmholtz, radiation condition), equal to −T̄ at the
    outer face (the face condition) and with dp̂*_o/dr̂ = ρ̂_oΩ²ū at r̂_o (the fluid's momentum).

    Args:
        tube, alpha, omega, fluid, n_layers, scheme, m: as for :func:`mode_shape` (``omega`` a
            root of the tube in its surrounding fluid).
        outer: the surrounding :class:`~jaxdea.Fluid`, or None for the tube's own ``tube.outer``.
        n_points: number of radii (static).
        extent: the field is sampled on r̂_o ≤ r̂ ≤ r̂_o + extent/γ (its decay lengths), > 0.

    Returns:
        (r, p): radii r̂ (n_points,) from r̂_o outwards and p̂*_o(r̂) (n_points,).

    Raises:
        ValueError: without a surrounding fluid, for a supersonic ``omega`` (Ω ≥ ĉ_oα̂: a leaky mode,
            whose field grows radially), and for invalid concrete inputs, naming the parameter.
    """
    tube = with_outer(tube, outer)
    if tube.outer is None:
        raise ValueError("outer: the tube has no surrounding fluid (outer=None, tube.outer=None)")
    validate_positive("extent", extent)
    speed = as_float(tube.outer.speed_ratio)
    gamma_squared = as_float(alpha) ** 2 - (as_float(omega) / speed) ** 2
    if not isinstance(gamma_squared, jax.core.Tracer) and not gamma_squared > 0:
        raise ValueError(f"omega must be subsonic, below the sound line speed_ratio * alpha = "
                         f"{float(speed * as_float(alpha))!r}, got {float(omega)!r}")
    shape = mode_shape(tube, alpha, omega, fluid, n_points, n_layers, m, False, scheme)
    gamma = jnp.sqrt(gamma_squared)
    r_outer = shape.r[-1]
    r = r_outer + as_float(extent) / gamma * jnp.linspace(0.0, 1.0, n_points)
    decay = scaled_k(gamma * r, m) / scaled_k(gamma * r_outer, m) * jnp.exp(-gamma * (r - r_outer))
    return r, -shape.T[-1] * decay
