"""Static (biasing) deformation and field of the tube (docs/theory/axisymmetric.md §1; paper Eqs. 5–8, 15–17
corrected).

All lengths are in units of R_i and stresses in units of μ. The reference gauge is P_o = 0,
P_i = ΔP̂. The elastic integral of Eq. (1.1) is rational in x = λ² for the Gent and neo-Hookean
energies and is evaluated in closed form (:func:`gent_elastic_integral`): exact up to Gent locking,
where W_1 ∝ 1/(1 − (I_1 − 3)/G) has a boundary layer at the inner face that no fixed quadrature in r̂
resolves (composite Gauss–Legendre, 16 panels of 8 nodes, gave ΔP̂ = −11.1948 for −11.2026 at 99 %
of locking, G = 4). Other energies use that quadrature (:func:`elastic_quadrature`).
"""

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from ..compiled import jit
from ..materials import Material
from ..numerics.scalar import Status, bracketed_root, implicit_root, value_and_slope
from ..params import (
    Tube,
    admissible,
    as_float,
    canonical,
    require_x64,
    validate_broadcast,
    validate_range,
    validate_real,
    validate_tube,
    wall_constant,
)
from .moduli import energy_derivatives, radial_stress_parts

GAUSS_ORDER = 8
PANELS = 16


class Geometry(NamedTuple):
    """Deformed radii r̂_i, r̂_o and thickness ĥ = r̂_o − r̂_i (computed without cancellation)."""

    r_inner: jax.Array
    r_outer: jax.Array
    thickness: jax.Array


def geometry(tube: Tube) -> Geometry:
    """r̂_i = λ_i, r̂_o = sqrt(λ_i² + c), c = (η⁻² − 1)/λ_z (paper Eqs. 5–6).

    ĥ = c/(r̂_o + r̂_i), equal to r̂_o − r̂_i but free of its cancellation: a wall much thinner than
    its radius keeps every digit (r̂_o − r̂_i loses log10(r̂_o/ĥ) of them)."""
    li, lz, eta = as_float(tube.lambda_i), as_float(tube.lambda_z), as_float(tube.eta)
    c = wall_constant(lz, eta)
    ro = jnp.sqrt(li**2 + c)
    return Geometry(li, ro, c / (ro + li))


def log_radius_ratio(geo: Geometry):
    """ln(r̂_o/r̂_i) = log1p(ĥ/r̂_i), accurate for thin walls too."""
    return jnp.log1p(geo.thickness / geo.r_inner)


def stretch(tube: Tube, r):
    """Circumferential stretch λ(r̂) = r̂ / sqrt(λ_z(r̂² − r̂_i²) + 1) (paper Eq. 5)."""
    li, lz = as_float(tube.lambda_i), as_float(tube.lambda_z)
    return r / jnp.sqrt(lz * (r**2 - li**2) + 1.0)


def electric_displacement(tube: Tube, r):
    """D̂_r(r̂) = V̂ / (r̂ ln(r̂_o/r̂_i)) (paper Eq. 8, ideal dielectric)."""
    return as_float(tube.voltage) / (r * log_radius_ratio(geometry(tube)))


def w1_at(tube: Tube, r):
    """(W_1, λ) at radii r̂ for an energy W(I_1) of a static name; for a material object, the
    stiffness Q_rz/2 (= W_1 + W_2λ² for W(I_1, I_2), docs/theory/real_tubes.md §1) in place of W_1:
    the quantity whose boundary layer near locking the grading resolves."""
    lam, lz = stretch(tube, r), as_float(tube.lambda_z)
    if isinstance(tube.material, Material):
        def pair(x):
            stretches = jnp.stack([1.0 / (x * lz), x, lz])
            return 0.5 * tube.material.derivatives(stretches)[2][0, 2]
        return jnp.reshape(jax.vmap(pair)(jnp.ravel(lam)), jnp.shape(r)), lam
    i1 = (lam * lz) ** -2 + lam**2 + lz**2
    w1, _ = jax.vmap(energy_derivatives, (0, None, None))(
        jnp.ravel(i1), as_float(tube.gent), tube.material
    )
    return jnp.reshape(w1, jnp.shape(r)), lam


def _elastic_integrand(tube: Tube, r):
    """2W_1(λ² − λ_r²)/r̂, the elastic part of the radial equilibrium integrand (docs/theory/axisymmetric.md
    1.1)."""
    if isinstance(tube.material, Material):
        lam, lz = stretch(tube, r), as_float(tube.lambda_z)
        parts = jax.vmap(lambda x: radial_stress_parts(tube.material, x, lz))(jnp.ravel(lam))
        return jnp.reshape(parts[0], jnp.shape(r)) / r
    w1, lam = w1_at(tube, r)
    lam_r = 1.0 / (lam * as_float(tube.lambda_z))
    return 2.0 * w1 * (lam**2 - lam_r**2) / r


GENT_CLOSED_MAX = 1e150
"""Largest Gent constant evaluated by :func:`gent_elastic_integral`; above it (and at G = inf) the
neo-Hookean closed form is used: the smaller pole x₋ ≈ 1/(λ_z² G) of the Gent integrand would
underflow near G = 1e300, while (I_1 − 3)/G < 1e-140 there (I_1 − 3 is bounded through WIDTH_MAX)."""


def stretch_squared_increment(tube: Tube, width):
    """(x_i, Δx) with x = λ² at r̂_i and Δx = λ²(r̂_i + width) − λ_i², free of cancellation:
    λ² = r̂²/(λ_z(r̂² − r̂_i²) + 1) gives Δx = (r̂² − r̂_i²)(1 − λ_z λ_i²)/(λ_z(r̂² − r̂_i²) + 1) with
    r̂² − r̂_i² = width (2r̂_i + width)."""
    li, lz = as_float(tube.lambda_i), as_float(tube.lambda_z)
    width = jnp.asarray(width, jnp.float64)
    s = width * (2.0 * li + width)
    x_i = li * li
    return x_i, s * (1.0 - lz * x_i) / (lz * s + 1.0)


def neo_hookean_elastic_integral(x_i, dx, lambda_z):
    """∫ (λ² − λ_r²) dr̂/r̂ over x = λ² from x_i to x_i + Δx (W_1 = 1/2):
    with dr̂/r̂ = dx/(2x(1 − λ_z x)) the integrand is −(λ_z x + 1)/(2λ_z² x²), so the integral is
    −ln(1 + Δx/x_i)/(2λ_z) − Δx/(2λ_z² x_i (x_i + Δx))."""
    lz = lambda_z
    return -jnp.log1p(dx / x_i) / (2.0 * lz) - dx / (2.0 * lz * lz * x_i * (x_i + dx))


def gent_elastic_integral(x_i, dx, lambda_z, gent):
    """∫ 2W_1(λ² − λ_r²) dr̂/r̂ for the Gent energy over x = λ² from x_i to x_i + Δx, in closed form.

    With 2W_1 = G/(G − (I_1 − 3)), I_1 = x + 1/(λ_z² x) + λ_z² and dr̂/r̂ = dx/(2x(1 − λ_z x)) the
    integrand is G(λ_z x + 1)/(2x q(x)), q(x) = λ_z²x² − Kλ_z²x + 1 = λ_z²(x − x₊)(x − x₋),
    K = G + 3 − λ_z² (q = −λ_z² x (G − (I_1 − 3)): its roots x₋ < x < x₊ are the two Gent locking
    stretches, x₊x₋ = 1/λ_z², x₊ − x₋ = √(K² − 4/λ_z²)). Partial fractions,
    (λ_z x + 1)/(λ_z² x (x − x₊)(x − x₋)) = 1/x + B₊/(x − x₊) + B₋/(x − x₋), give

        (G/2)[ln(1 − x₋Δx/(x_i(x − x₋))) + (1 + B₋) ln(1 + Δx/(x_i − x₋)) + B₊ ln(1 + Δx/(x_i − x₊))],

    1 + B₋ = −(λ_z x₋ + 1)/(λ_z(x₊ − x₋)), B₊ = (λ_z x₊ + 1)/(λ_z² x₊(x₊ − x₋)), x = x_i + Δx: the
    1/x and B₋ terms, each O(G) for large G, are combined without cancellation (the form tends
    to :func:`neo_hookean_elastic_integral` as G → ∞). Exact up to locking: the log of the distance
    to the pole resolves the boundary layer of W_1 at the inner face."""
    lz, g = lambda_z, gent
    k = g + 3.0 - lz * lz
    root = jnp.sqrt(k - 2.0 / lz) * jnp.sqrt(k + 2.0 / lz)  # x₊ − x₋, without overflow of K²
    x_plus = 0.5 * (k + root)
    x_minus = 1.0 / (lz * lz * x_plus)
    d_minus, d_plus = x_i - x_minus, x_i - x_plus
    minus_log = jnp.log1p(-x_minus * dx / (x_i * (d_minus + dx)))
    minus_pole = -(lz * x_minus + 1.0) / (lz * root) * jnp.log1p(dx / d_minus)
    plus_pole = (lz * x_plus + 1.0) / (lz * lz * x_plus * root) * jnp.log1p(dx / d_plus)
    return 0.5 * g * (minus_log + minus_pole + plus_pole)


def _elastic_integral(tube: Tube, width):
    """∫_{r̂_i}^{r̂_i + width} 2W_1(λ² − λ_r²) dr̂/r̂ (vectorised in width; the whole wall is
    width = ĥ): in closed form for the Gent and neo-Hookean energies, else by quadrature."""
    if tube.material not in ("gent", "neo_hookean"):
        return elastic_quadrature(tube, width)
    x_i, dx = stretch_squared_increment(tube, width)
    lz = as_float(tube.lambda_z)
    neo_hookean = neo_hookean_elastic_integral(x_i, dx, lz)
    if tube.material == "neo_hookean":
        return neo_hookean
    g = as_float(tube.gent)
    limit = g > GENT_CLOSED_MAX  # also G = inf
    # double where: the unused branch gets a Gent constant above I_1 − 3 of the whole wall (its
    # largest value is at r̂_i), so that its derivatives stay finite
    inner_excess = x_i + 1.0 / (lz * lz * x_i) + lz * lz - 3.0
    gent = gent_elastic_integral(x_i, dx, lz, jnp.where(limit, 2.0 * inner_excess + 1.0, g))
    return jnp.where(limit, neo_hookean, gent)


def elastic_quadrature(tube: Tube, width, panels=PANELS):
    """∫_{r̂_i}^{r̂_i + width} 2W_1(λ² − λ_r²) dr̂/r̂ by composite Gauss–Legendre (vectorised in
    width), for energies without a closed form (smooth W_1 only: no boundary layer is resolved)."""
    x, w = np.polynomial.legendre.leggauss(GAUSS_ORDER)
    r0 = geometry(tube).r_inner
    half = 0.5 * jnp.asarray(width)[..., None, None] / panels  # half a panel, not a difference
    nodes = r0 + half * (2.0 * np.arange(panels)[:, None] + 1.0 + x)  # panel k: centre (2k + 1)·half
    terms = half * w * _elastic_integrand(tube, nodes)
    return ordered_sum(jnp.reshape(terms, terms.shape[:-2] + (panels * GAUSS_ORDER,)))


def ordered_sum(terms):
    """Σ over the last axis by a fixed pairwise tree of elementwise additions.

    ``jnp.sum`` lowers to an XLA reduce whose summation order depends on how XLA vectorises the
    surrounding loops: the same point alone and inside a ``jax.vmap`` batch then differ in the last
    bit. Elementwise additions in a fixed order give bit-identical results at any batch position
    (and pairwise summation keeps the rounding error O(log n)). The tree adds the first half of the
    terms to the second half: log₂ n whole-array additions instead of one per pair, which cut the
    XLA compile time of the pull-in solve from 14.7 to 4.4 s, and a first call of
    :func:`jaxdea.critical_voltage` from 31–34 to 15.5 s."""
    while terms.shape[-1] > 1:
        half = terms.shape[-1] // 2
        pairs = terms[..., :half] + terms[..., half:2 * half]
        terms = jnp.concatenate([pairs, terms[..., 2 * half:]], axis=-1)
    return terms[..., 0]


def _electric_integral(tube: Tube, width):
    """∫_{r̂_i}^{r̂} D̂_r² dr̂/r̂ = V̂²(1/r̂_i² − 1/r̂²)/(2 ln²(r̂_o/r̂_i)), r̂ = r̂_i + width (closed form;
    1/r̂_i² − 1/r̂² = width (2r̂_i + width)/(r̂_i r̂)², free of cancellation in thin walls)."""
    geo = geometry(tube)
    r_end = geo.r_inner + width
    v = as_float(tube.voltage)
    return (v**2 * width * (2.0 * geo.r_inner + width) / (geo.r_inner * r_end) ** 2
            / (2.0 * log_radius_ratio(geo) ** 2))


def pressure_difference_unchecked(tube: Tube):
    """ΔP̂ = P̂_i − P̂_o holding the tube at (λ_i, λ_z, V̂) (docs/theory/axisymmetric.md Eq. 1.1; corrected
    paper Eq. 15); a layered wall's through its layers (:func:`layered_pressure_difference`)."""
    if tube.layers is not None:
        return layered_pressure_difference(tube)
    geo = geometry(tube)
    return _elastic_integral(tube, geo.thickness) - _electric_integral(tube, geo.thickness)


def pressure_difference(tube: Tube):
    """Static pressure difference ΔP̂ = (P_i − P_o)/μ that holds the tube at (λ_i, λ_z, V̂).

    Equation (1.1) of docs/theory/axisymmetric.md (the paper's Eq. 15 corrected, erratum E4):
    ΔP̂ = ∫ 2W_1(λ² − λ_r²) dr̂/r̂ − V̂²(1 − r̂_i²/r̂_o²)/(2 r̂_i² ln²(r̂_o/r̂_i)). A layered wall
    (``tube.layers``): the sum of each layer's elastic integral minus the field term of the active
    layer (docs/theory/real_tubes.md §3, :func:`layered_pressure_difference`).

    Examples:
        >>> float(pressure_difference(Tube(lambda_i=1.2 ** -0.5, lambda_z=1.2)))  # homogeneous
        0.0
    """
    require_x64()
    validate_tube(tube)
    return _pressure_difference(canonical(tube))


@jit
def _pressure_difference(tube: Tube):
    """ΔP̂, NaN where the (traced) tube is not admissible (never a plausible number there)."""
    return jnp.where(admissible(tube), pressure_difference_unchecked(tube), jnp.nan)


class BaseState(NamedTuple):
    """Base state sampled at radii r̂: λ, D̂_r, p̂ (gauge P̂_o = 0, P̂_i = ΔP̂)."""

    r: jax.Array
    stretch: jax.Array
    displacement: jax.Array
    pressure: jax.Array


def base_state(tube: Tube, r) -> BaseState:
    """λ(r̂), D̂_r(r̂) and the Lagrange multiplier p̂(r̂) of docs/theory/axisymmetric.md Eqs. (1.2)–(1.3).

    p̂ = 2W_1λ_r² + D̂_r² − τ̂_rr, τ̂_rr(r̂) = −ΔP̂ + ∫_{r̂_i}^{r̂} [2W_1(λ² − λ_r²) − D̂_r²] dr̂/r̂.
    """
    if tube.layers is not None:
        raise ValueError("tube: base_state is the single wall's; a layered wall's base state is "
                         "layered_base_state, layer by layer")
    r = jnp.asarray(r, jnp.float64)
    d = electric_displacement(tube, r)
    width = r - as_float(tube.lambda_i)
    tau_rr = -pressure_difference_unchecked(tube) + _elastic_integral(tube, width) - _electric_integral(
        tube, width)
    if isinstance(tube.material, Material):  # p = λ_rW_r + d² − τ_rr (docs/theory/real_tubes.md §3)
        lam, lz = stretch(tube, r), as_float(tube.lambda_z)
        radial = jax.vmap(lambda x: radial_stress_parts(tube.material, x, lz)[1])(jnp.ravel(lam))
        return BaseState(r, lam, d, jnp.reshape(radial, jnp.shape(r)) + d**2 - tau_rr)
    w1, lam = w1_at(tube, r)
    lam_r = 1.0 / (lam * as_float(tube.lambda_z))
    return BaseState(r, lam, d, 2.0 * w1 * lam_r**2 + d**2 - tau_rr)


def thickness_ratio(tube: Tube):
    """h/R_i = r̂_o − r̂_i, the deformed wall thickness over the undeformed inner radius.

    Elementwise over a tube with array fields: the result has the broadcast shape of all its float
    fields (admissibility, NaN where a traced tube is not admissible, involves every one of them).
    """
    require_x64()
    validate_tube(tube, scalar=False)  # elementwise: arrays that broadcast are fine
    # NaN where a traced tube is not admissible (concrete ones were validated above)
    return jnp.where(admissible(tube), geometry(tube).thickness, jnp.nan)


def with_thickness_ratio(tube: Tube, h_over_Ri) -> Tube:
    """The tube whose η gives the deformed thickness h/R_i at its λ_i, λ_z (differentiable).

    From (λ_i + h)² = λ_i² + (η⁻² − 1)/λ_z: η = [1 + λ_z h (2λ_i + h)]^(−1/2).
    """
    require_x64()
    if not isinstance(tube, Tube):
        raise ValueError(f"tube must be a jaxdea.Tube, got {type(tube).__name__}")
    h = validate_range("h_over_Ri", h_over_Ri, "> 0", lambda v: v > 0, scalar=False)
    li = validate_range("lambda_i", tube.lambda_i, "> 0", lambda v: v > 0, scalar=False)
    lz = validate_range("lambda_z", tube.lambda_z, "> 0", lambda v: v > 0, scalar=False)
    validate_broadcast("h_over_Ri and Tube", dict(h_over_Ri=h, lambda_i=li, lambda_z=lz))
    out = with_thickness_ratio_unchecked(tube, h_over_Ri)
    eta = None if isinstance(out.eta, jax.core.Tracer) else np.asarray(out.eta)
    if eta is not None and not np.all((eta > 0) & (eta < 1)):
        raise ValueError(f"h_over_Ri = {h_over_Ri!r} gives eta = R_i/R_o outside (0, 1) in float64 "
                         f"(got {np.ravel(eta)[0]!r}): the wall is too thick or too thin")
    validate_tube(out, scalar=False)  # the other fields, and Gent locking of the new wall
    return out


def with_thickness_ratio_unchecked(tube: Tube, h_over_Ri) -> Tube:
    """:func:`with_thickness_ratio` without validation (traced use inside solvers)."""
    h = as_float(h_over_Ri)
    li, lz = as_float(tube.lambda_i), as_float(tube.lambda_z)
    return tube.replace(eta=1.0 / jnp.sqrt(1.0 + lz * h * (2.0 * li + h)))


# ----------------------------------------------------------------------------- static response


def _voltage_factor(tube: Tube):
    """E(λ_i) with ΔP̂ = ΔP̂_el(λ_i) − V̂² E(λ_i): E = (1 − r̂_i²/r̂_o²)/(2 r̂_i² ln²(r̂_o/r̂_i)),
    1 − r̂_i²/r̂_o² = ĥ(r̂_o + r̂_i)/r̂_o²."""
    geo = geometry(tube)
    return (geo.thickness * (geo.r_outer + geo.r_inner) / geo.r_outer**2) / (
        2.0 * geo.r_inner**2 * log_radius_ratio(geo) ** 2
    )


def _layered_static_parts(tube: Tube):
    """(ΔP̂_el, E) of a layered wall at its λ_i: ΔP̂ = ΔP̂_el − V̂²E with ΔP̂_el the sum of the layers'
    elastic integrals and E = (1/r̂_a² − 1/r̂_b²)/(2 ln²(r̂_b/r̂_a)) over the active layer [r̂_a, r̂_b]
    (:func:`layered_pressure_difference`, docs/theory/real_tubes.md §3)."""
    edges = interface_radii(tube)
    a = active_index(tube)
    lo, hi = edges[a], edges[a + 1]
    factor = (hi - lo) * (hi + lo) / (lo * hi) ** 2 / (2.0 * jnp.log(hi / lo) ** 2)
    return sum(layer_integrals(tube, edges)), factor


def squared_voltage(tube: Tube, lambda_i, delta_p):
    """V̂²(λ_i) = (ΔP̂_el(λ_i) − ΔP̂)/E(λ_i) on the static response at fixed ΔP̂ (a layered wall's
    ΔP̂_el and E through its layers, :func:`_layered_static_parts`)."""
    t = tube.replace(lambda_i=lambda_i, voltage=0.0)
    if t.layers is not None:
        elastic, factor = _layered_static_parts(t)
        return (elastic - delta_p) / factor
    return (_elastic_integral(t, geometry(t).thickness) - delta_p) / _voltage_factor(t)


def _stretch_grid(lower=0.05, upper=20.0, points=400):
    return jnp.asarray(np.geomspace(lower, upper, points))


def inner_stretch(tube: Tube, delta_p=0.0):
    """λ_i of the stable static state at pressure difference ΔP̂, voltage V̂ and stretch λ_z.

    Solves ΔP̂_el(λ_i) − V̂²E(λ_i) = ΔP̂ (docs/theory/axisymmetric.md Eq. 1.1) on the branch connected to the
    unpressurised small-λ_i states: the first sign change of V̂²E + ΔP̂ − ΔP̂_el on a geometric λ_i grid
    (0.05 … 20), refined by safeguarded Newton. Beyond pull-in (no such state) the result is NaN with
    status NO_ROOT. Derivatives with respect to ΔP̂ and every tube leaf are implicit. A layered wall
    (``tube.layers``) is solved the same way on its own response (:func:`layered_pressure_difference`):
    the inverse of :func:`pressure_difference` for both.

    Returns:
        (lambda_i, status). ``tube.lambda_i`` is ignored.
    """
    require_x64()
    if not isinstance(tube, Tube):
        raise ValueError(f"tube must be a jaxdea.Tube, got {type(tube).__name__}")
    tube = tube.replace(lambda_i=1.0)  # ignored (the unknown); a placeholder for the validation
    validate_tube(tube)
    validate_real("delta_p", delta_p, "a finite real number (the pressure difference)")
    return inner_stretch_traced(*canonical(tube, delta_p))


@jit
def inner_stretch_traced(tube: Tube, delta_p):
    """:func:`inner_stretch` without the concrete validation, for callers that trace (sweeps,
    units): (λ_i, status), NaN and INVALID where the traced inputs are not admissible."""
    ok = admissible(tube) & jnp.isfinite(as_float(delta_p))
    li, status = _inner_stretch_unchecked(tube, delta_p)
    return jnp.where(ok, li, jnp.nan), jnp.where(ok, status, Status.INVALID).astype(jnp.int32)


def _inner_stretch_unchecked(tube: Tube, delta_p):
    delta_p = as_float(delta_p)
    v2 = as_float(tube.voltage) ** 2

    def residual(li):
        t = tube.replace(lambda_i=li, voltage=0.0)
        if t.layers is not None:
            elastic, factor = _layered_static_parts(t)
            return v2 * factor + delta_p - elastic
        return v2 * _voltage_factor(t) + delta_p - _elastic_integral(t, geometry(t).thickness)

    def solve():
        grid = _stretch_grid()
        vals = jax.vmap(residual)(grid)
        ok = jnp.isfinite(vals)
        down = ok[:-1] & ok[1:] & (vals[:-1] > 0) & (vals[1:] <= 0)
        j = jnp.argmax(down)
        root, status = bracketed_root(residual, grid[j], grid[j + 1], vals[j], vals[j + 1])
        return jnp.where(jnp.any(down), root, jnp.nan), jnp.where(
            jnp.any(down), status, Status.NO_ROOT
        )

    return implicit_root(residual, solve, jnp.asarray(1.0))


def pull_in(tube: Tube, delta_p=0.0):
    """Pull-in point of the static response at fixed ΔP̂: the first maximum of V̂(λ_i).

    V̂²(λ_i) = (ΔP̂_el(λ_i) − ΔP̂)/E(λ_i) (docs/theory/axisymmetric.md Eq. 1.1 solved for V̂²); the pull-in
    point is its first local maximum beyond the unpressurised state, where d(V̂²)/dλ_i = 0 (refined by
    safeguarded Newton with the autodiff second derivative). Differentiable by implicit derivatives.

    Returns:
        (lambda_i, voltage, status). ``tube.lambda_i`` and ``tube.voltage`` are ignored.
    """
    require_x64()
    if not isinstance(tube, Tube):
        raise ValueError(f"tube must be a jaxdea.Tube, got {type(tube).__name__}")
    tube = tube.replace(lambda_i=1.0, voltage=0.0)  # both ignored; placeholders for the validation
    validate_tube(tube)
    validate_real("delta_p", delta_p, "a finite real number (the pressure difference)")
    return _pull_in(*canonical(tube, delta_p))


def pull_in_unchecked(tube: Tube, delta_p):
    """:func:`pull_in` without input validation (for use inside other solvers).

    Forward-mode derivatives only: the grid's values, slopes and curvatures of V̂² in one pass (a
    jvp of a jvp), then safeguarded Newton on the slope from the grid cell where it turns negative
    (reverse-mode slopes, a jvp of a grad evaluated in four places, took 3.7 s to compile against
    2.4 s, measured)."""
    delta_p = as_float(delta_p)
    v2 = lambda li: squared_voltage(tube, li, delta_p)  # noqa: E731
    slope = lambda li: value_and_slope(v2, li)[1]  # noqa: E731

    def solve():
        grid = _stretch_grid()
        (vals, slopes), (_, curvatures) = jax.vmap(
            lambda x: jax.jvp(lambda y: value_and_slope(v2, y), (x,), (jnp.ones_like(x),)))(grid)
        ok = jnp.isfinite(slopes[:-1]) & jnp.isfinite(slopes[1:]) & (vals[:-1] > 0)
        peak = ok & (slopes[:-1] > 0) & (slopes[1:] <= 0)
        j = jnp.argmax(peak)
        root, status = bracketed_root(slope, grid[j], grid[j + 1], slopes[j], slopes[j + 1],
                                      curvatures[j], curvatures[j + 1])
        found = jnp.any(peak)
        return jnp.where(found, root, jnp.nan), jnp.where(found, status, Status.NO_ROOT)

    li, status = implicit_root(slope, solve, jnp.asarray(1.0))
    return li, jnp.sqrt(v2(li)), status


INVERSE_GOLDEN = (np.sqrt(5.0) - 1.0) / 2.0
GOLDEN_STEPS = 64  # golden-section steps of voltage_limit: the peak's bracket shrinks by 0.618^64 ≈ 4e-14


def voltage_limit(tube: Tube):
    """Largest voltage of the static response of the tube held at its zero-voltage ΔP̂.

    The pull-in voltage of :func:`pull_in` at ΔP̂ = ΔP̂(λ_i, λ_z, V̂ = 0): the first local maximum of
    V̂²(λ_i) on the λ_i grid of :func:`pull_in`, refined by golden-section search on its two grid
    cells (values only: V̂ at a maximum to rounding); where strain stiffening removes the pull-in
    maximum (Gent), the largest voltage on the grid before Gent locking. Used as the end of the
    critical-voltage search (no derivatives: a search range). Values only, so that the first call
    of :func:`jaxdea.critical_voltage` compiles no derivative of the static quadrature (with the
    Newton solve of :func:`pull_in` there, that call took 7.4 s instead of 5.7 s, measured).
    """
    tube = jax.lax.stop_gradient(tube)
    limit = static_limit(tube, pressure_difference_unchecked(tube.replace(voltage=0.0)))[1]
    if tube.layers is not None:  # stiff passive layers may remove the pull-in maximum
        return jnp.minimum(limit, LAYERED_SEARCH_END)
    return limit


LAYERED_SEARCH_END = 2.0
"""The end of a layered wall's critical-voltage search where its static response has no pull-in
maximum (stiff passive layers, e.g. a 3× encapsulation of 0.2 of the wall): V̂² then grows without
bound up to Gent locking (V̂ ≈ 1.8e7 on the λ_i grid), a range in which the search's expansion in V̂
loses every digit (NaN, NOT_FINITE). V̂ = 2 is an electric stress ε(V/h)² = 4(R_i/h)² μ, 130 μ at
η = 0.85, far beyond the breakdown of any elastomer; a critical voltage above it is not searched
(NO_ROOT)."""


def static_limit(tube: Tube, delta_p):
    """(λ_i, V̂) at the end of the static response at fixed ΔP̂ (values only: a search range).

    The first local maximum of V̂²(λ_i) (:func:`squared_voltage`) on the λ_i grid of :func:`pull_in`,
    refined by golden-section search on its two grid cells, or, where strain stiffening removes that
    maximum (Gent), the largest voltage on the grid before locking (:func:`voltage_limit`). On the
    branch from the unpressurised state up to that λ_i, V̂ grows monotonically with λ_i, so the
    state held by ΔP̂ is a function of λ_i there (:mod:`jaxdea.solve.pressure_held`).
    """
    tube, delta_p = jax.lax.stop_gradient((tube, as_float(delta_p)))
    v2 = lambda li: squared_voltage(tube, li, delta_p)  # noqa: E731
    grid = _stretch_grid()
    vals = jax.vmap(v2)(grid)
    finite = jnp.isfinite(vals)
    inner = finite[:-2] & finite[1:-1] & finite[2:] & (vals[:-2] > 0)
    peak = inner & (vals[1:-1] > vals[:-2]) & (vals[1:-1] >= vals[2:])
    j = jnp.argmax(peak) + 1  # the grid point of the first local maximum
    a, b = grid[j - 1], grid[j + 1]
    c, d = b - INVERSE_GOLDEN * (b - a), a + INVERSE_GOLDEN * (b - a)

    def golden(_, s):
        a, b, c, d, fc, fd = s
        left = fc >= fd  # the maximum lies in [a, d]: c is the new d
        a, b = jnp.where(left, a, c), jnp.where(left, d, b)
        new = jnp.where(left, b - INVERSE_GOLDEN * (b - a), a + INVERSE_GOLDEN * (b - a))
        f_new = v2(new)
        return (a, b, jnp.where(left, new, d), jnp.where(left, c, new),
                jnp.where(left, f_new, fd), jnp.where(left, fc, f_new))

    *_, c, d, fc, fd = jax.lax.fori_loop(0, GOLDEN_STEPS, golden, (a, b, c, d, v2(c), v2(d)))
    v_peak = jnp.maximum(vals[j], jnp.maximum(fc, fd))
    li_peak = jnp.where(vals[j] >= jnp.maximum(fc, fd), grid[j], jnp.where(fc >= fd, c, d))
    top = jnp.max(jnp.where(finite, vals, 0.0))
    li_top = grid[jnp.argmax(jnp.where(finite, vals, -jnp.inf))]
    found = jnp.any(peak)
    return jnp.where(found, li_peak, li_top), jnp.sqrt(jnp.where(found, v_peak, top))


@jit
def _pull_in(tube: Tube, delta_p):
    """(λ_i, V̂, status) of :func:`pull_in`; NaN and INVALID where the traced inputs are not
    admissible."""
    ok = admissible(tube) & jnp.isfinite(as_float(delta_p))
    li, v, status = pull_in_unchecked(tube, delta_p)
    nan = lambda x: jnp.where(ok, x, jnp.nan)  # noqa: E731
    return nan(li), nan(v), jnp.where(ok, status, Status.INVALID).astype(jnp.int32)


def interface_radii(tube: Tube):
    """(K + 1,) deformed radii r̂_0 = r̂_i < … < r̂_K = r̂_o of a layered wall's interfaces:
    r̂_k = √(λ_i² + (R_k² − 1)/λ_z) with R_k − R_{k−1} = fraction_k (1/η − 1)
    (docs/theory/real_tubes.md §3; incompressible, λ_z common)."""
    li, lz, eta = as_float(tube.lambda_i), as_float(tube.lambda_z), as_float(tube.eta)
    shares = jnp.cumsum(jnp.stack([as_float(layer.fraction) for layer in tube.layers]))
    shares = shares / shares[-1]  # exactly 1 at the outer face
    span = (1.0 - eta) / eta
    big = 1.0 + shares[:-1] * span
    inner = jnp.sqrt(li**2 + (big - 1.0) * (big + 1.0) / lz)
    return jnp.concatenate([li[None], inner, geometry(tube).r_outer[None]])


def _layer_quadrature(fun, start, end, panels=PANELS):
    """∫_start^end fun(r̂) dr̂ by composite Gauss–Legendre (vectorised in ``end``)."""
    x, w = np.polynomial.legendre.leggauss(GAUSS_ORDER)
    half = 0.5 * (jnp.asarray(end) - start)[..., None, None] / panels
    nodes = start + half * (2.0 * np.arange(panels)[:, None] + 1.0 + x)
    terms = half * w * fun(nodes)
    return ordered_sum(jnp.reshape(terms, terms.shape[:-2] + (panels * GAUSS_ORDER,)))


def _layer_parts(tube: Tube, k: int, r):
    """(μ_k(λW_θ − λ_rW_r), μ_kλ_rW_r) of layer k at radii r̂."""
    layer, lz = tube.layers[k], as_float(tube.lambda_z)
    lam = stretch(tube, r)
    parts = jax.vmap(lambda x: radial_stress_parts(layer.material, x, lz))(jnp.ravel(lam))
    mu = as_float(layer.shear_ratio)
    return tuple(mu * jnp.reshape(x, jnp.shape(r)) for x in parts)


def active_index(tube: Tube) -> int:
    """The index of the active layer (static)."""
    return next(k for k, layer in enumerate(tube.layers) if layer.active)


def _layered_electric(tube: Tube, r, edges):
    """∫_{r̂_a}^{r̂} D̂_r² dr̂/r̂ with r̂ clipped to the active layer [r̂_a, r̂_{a+1}]:
    V̂²(1/r̂_a² − 1/r̂²)/(2 ln²(r̂_{a+1}/r̂_a)) (D̂_r = V̂/(r̂ ln(r̂_{a+1}/r̂_a)) there, 0 elsewhere)."""
    a = active_index(tube)
    lo, hi = edges[a], edges[a + 1]
    rc = jnp.clip(r, lo, hi)
    log_ratio = jnp.log(hi / lo)
    v = as_float(tube.voltage)
    return v**2 * (rc - lo) * (rc + lo) / (lo * rc) ** 2 / (2.0 * log_ratio**2)


def layered_displacement(tube: Tube, k: int, r, edges=None):
    """D̂_r in layer k: V̂/(r̂ ln(r̂_{a+1}/r̂_a)) in the active layer, 0 in a passive one."""
    if not tube.layers[k].active:
        return jnp.zeros_like(r)
    edges = interface_radii(tube) if edges is None else edges
    return as_float(tube.voltage) / (r * jnp.log(edges[k + 1] / edges[k]))


def _layer_elastic(tube: Tube, k: int, start, end):
    """∫_start^end μ_k(λW_θ − λ_rW_r) dr̂/r̂ in layer k (vectorised in ``end``)."""
    return _layer_quadrature(lambda x: _layer_parts(tube, k, x)[0] / x, start, end)


def layer_integrals(tube: Tube, edges=None):
    """The elastic integral of each whole layer, ∫_{r̂_k}^{r̂_{k+1}} μ_k(λW_θ − λ_rW_r) dr̂/r̂ (a
    list): formed once per wall and shared by ΔP̂ and τ̂_rr of every layer."""
    edges = interface_radii(tube) if edges is None else edges
    return [_layer_elastic(tube, k, edges[k], edges[k + 1]) for k in range(len(tube.layers))]


def layered_pressure_difference(tube: Tube, edges=None, integrals=None):
    """ΔP̂ = Σ_k ∫_{r̂_k}^{r̂_{k+1}} μ_k(λW_θ − λ_rW_r) dr̂/r̂ − ∫ D̂_r² dr̂/r̂ (docs/theory/real_tubes.md
    §3: radial traction continuous through the layers); ``edges`` and ``integrals`` of
    :func:`interface_radii` and :func:`layer_integrals` where the caller has them."""
    edges = interface_radii(tube) if edges is None else edges
    integrals = layer_integrals(tube, edges) if integrals is None else integrals
    return sum(integrals) - _layered_electric(tube, edges[-1], edges)


def layered_base_state(tube: Tube, k: int, r, edges=None, integrals=None) -> BaseState:
    """λ, D̂_r and p̂ = μ_kλ_rW_r + D̂_r² − τ̂_rr at radii r̂ inside layer k of a layered wall, with
    τ̂_rr(r̂) = −ΔP̂ + ∫_{r̂_i}^{r̂} [μ(λW_θ − λ_rW_r) − D̂_r²] dr̂/r̂ (docs/theory/real_tubes.md §3;
    p̂ jumps at interfaces, τ̂_rr does not); ``edges``, ``integrals`` as for
    :func:`layered_pressure_difference`."""
    r = jnp.asarray(r, jnp.float64)
    edges = interface_radii(tube) if edges is None else edges
    integrals = layer_integrals(tube, edges) if integrals is None else integrals
    below = sum(integrals[:k], jnp.zeros(()))
    own = _layer_elastic(tube, k, edges[k], r)
    tau_rr = (-layered_pressure_difference(tube, edges, integrals) + below + own
              - _layered_electric(tube, r, edges))
    d = layered_displacement(tube, k, r, edges)
    return BaseState(r, stretch(tube, r), d, _layer_parts(tube, k, r)[1] + d**2 - tau_rr)
