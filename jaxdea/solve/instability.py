"""The first instability of a tube held by its stretch or, as in a lab, by its pressure difference.

Held by ΔP̂ = (P_i − P_o)/μ, the static state moves with the voltage along the response
ΔP̂_el(λ_i) − V̂² E(λ_i) = ΔP̂ (docs/theory/axisymmetric.md Eq. 1.1): from λ_0 at V̂ = 0
(:func:`jaxdea.inner_stretch`) up to the end of the static branch λ_end, at pull-in
(:func:`jaxdea.physics.base_state.static_limit`). On that branch V̂²(λ_i) = (ΔP̂_el − ΔP̂)/E grows
monotonically, so the held state is a function of λ_i there (:func:`held_tube`), smooth up to
pull-in, where λ_i(V̂) has a square-root branch point.

An incremental mode of axial wavenumber α̂ > 0 or of order m ≥ 1 changes no cavity volume, so it
loses stability where the stretch-held tube does, f(Ω = 0; V̂, λ_i) = 0, met along the held branch:
the critical state of (m, n) is the first zero of h(λ) = f(Ω² = 0; held_tube(λ)) in (λ_0, λ_end]
(the search of :func:`jaxdea.critical_voltage`, in λ), and V̂_cr = V̂(λ_cr). Its derivatives are
implicit in λ, dλ_cr/dθ = −(∂h/∂θ)/(∂h/∂λ), and V̂_cr follows from V̂²(λ_cr).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from ..compiled import cached_jit
from ..numerics.scalar import Status, implicit_root
from ..params import Fluid, Tube, as_float, canonical, guard, mode_wavenumber, traced, validate_real, with_outer
from ..physics import characteristic
from ..physics.base_state import inner_stretch_traced, squared_voltage, static_limit
from ..physics.characteristic import Unknown
from ..physics.dispersion import check_inputs
from ..physics.state_matrix import ORDER_M
from ..physics.transfer import checked_laminate, discretize
from .roots import (
    Instability,
    Roots,
    _first_root,
    first_of_grid,
    growth_rates_unchecked,
    inaccurate_where,
    map_orders_and_modes,
    validate_max,
)
from .roots import first_instability as stretch_held_instability

N_GRID = 32  # steps of the scan over (λ_0, λ_end], as the critical-voltage search's over (0, V̂_lim]


def held_tube(tube: Tube, delta_p, lambda_i) -> Tube:
    """The state held by ΔP̂ at inner stretch λ_i: V̂ = sqrt(V̂²(λ_i)), V̂² = (ΔP̂_el − ΔP̂)/E
    (:func:`jaxdea.physics.base_state.squared_voltage`). V̂ = 0 with a zero derivative where V̂² ≤ 0
    (at λ_0, to rounding): f depends on V̂² only, so the slope of f(λ) stays finite there, where
    sqrt would give 0 · ∞."""
    v2 = squared_voltage(tube, lambda_i, delta_p)
    positive = v2 > 0
    voltage = jnp.where(positive, jnp.sqrt(jnp.where(positive, v2, 1.0)), 0.0)
    return tube.replace(lambda_i=lambda_i, voltage=voltage)


def held_stretch(tube: Tube, delta_p):
    """λ_i that ΔP̂ holds at ``tube.voltage`` (:func:`jaxdea.inner_stretch`, implicit derivatives in
    ΔP̂, V̂ and every leaf; NaN past pull-in). ``tube.lambda_i`` is ignored."""
    return inner_stretch_traced(tube.replace(lambda_i=1.0), delta_p)[0]


def held_branch(tube: Tube, delta_p):
    """(λ_0, λ_end) of the static branch held by ΔP̂ (values only: a search range)."""
    tube, delta_p = jax.lax.stop_gradient((tube, as_float(delta_p)))
    return held_stretch(tube.replace(voltage=0.0), delta_p), static_limit(tube, delta_p)[0]


def branch_walls(tube: Tube, delta_p) -> Tube:
    """``tube`` with λ_i = (λ_0, λ_end), the ends of the branch held by ΔP̂ (its thickest wall and
    its end: the discretisation chosen for both serves the branch).

    Raises:
        ValueError: a concrete ΔP̂ that holds no static state at V̂ = 0 (above the pull-in pressure).
    """
    lam0, lam_end = held_branch(tube, delta_p)
    if not traced((lam0, lam_end)) and not bool(jnp.isfinite(lam0)):
        raise ValueError(f"delta_p = {float(delta_p)!r} holds no static state at V̂ = 0 (it lies "
                         "above the pull-in pressure of the tube, jaxdea.pull_in): give a smaller "
                         "pressure difference")
    return tube.replace(lambda_i=jnp.stack([lam0, jnp.maximum(lam_end, lam0)]))


def critical_residual(tube: Tube, delta_p, alpha, m, n_layers, method="adaptive"):
    """h(λ) = f(Ω² = 0) of order m (traced; the 8×8 path, longitudinal at m = 0, fluid-free: the
    fluid's terms vanish like Ω²) at α̂ on the state held by ΔP̂ at λ_i = λ. ``method``: the
    exponential, ``"adaptive"`` for the search (values and forward-mode slopes), ``"taylor"`` for
    derivatives of any order and mode (the implicit derivatives)."""
    def h(lambda_i):
        wall = discretize(held_tube(tube, delta_p, lambda_i), n_layers)
        return characteristic.value(ORDER_M, wall, jnp.zeros_like(lambda_i), alpha, None, 0,
                                    m, Unknown.OMEGA_SQUARED, method)

    return h


def critical_stretch_unchecked(tube: Tube, delta_p, alpha, m, n_layers, branch=None):
    """(λ_cr, status): the first zero of h (:func:`critical_residual`) in (λ_0, λ_end] (values,
    traceable; ``branch`` = :func:`held_branch` if already formed). NaN with NO_ROOT where none,
    INVALID where ΔP̂ holds no static state at V̂ = 0."""
    lam0, lam_end = held_branch(tube, delta_p) if branch is None else branch
    ok = jnp.isfinite(lam0) & jnp.isfinite(lam_end) & (lam_end > lam0)
    lam0 = jnp.where(ok, lam0, 1.0)
    span = jnp.where(ok, lam_end - lam0, 1.0)
    h = critical_residual(tube, delta_p, alpha, m, n_layers)
    root = _first_root(lambda x: h(lam0 + x), span / N_GRID, span)
    return (jnp.where(ok, lam0 + root.omega, jnp.nan),
            jnp.where(ok, root.status, Status.INVALID).astype(jnp.int32))


def held_critical_voltage(tube: Tube, delta_p, alpha, m, n_layers, lambda_root):
    """V̂_cr = V̂(λ_cr) of the held tube from a solved λ_cr (values), with implicit derivatives with
    respect to the tube's leaves, ΔP̂ and α̂ where they are traced."""
    if traced((tube, delta_p, alpha, m)):
        root = jax.lax.stop_gradient(lambda_root)
        lambda_root = implicit_root(critical_residual(tube, delta_p, alpha, m, n_layers, "taylor"),
                                    lambda: (root, Status.CONVERGED), root)[0]
    return held_tube(tube, delta_p, lambda_root).voltage


@cached_jit(static_argnames=("n_max", "m_max", "n_layers"))
def _held_grid(tube, delta_p, n_max, m_max, n_layers):
    """(V̂_cr, status, s₀, λ_cr) of every (m, n), shape (m_max + 1, n_max), of the tube held by
    ΔP̂; s₀ the growth rate at V̂ = 0 (a mode unstable there has V̂_cr = 0), as
    :func:`jaxdea.solve.roots._instability_grid` for the stretch-held tube."""
    ok, tube, _, _ = guard(tube.replace(lambda_i=1.0, voltage=0.0), 1.0, None)
    delta_p = as_float(delta_p)
    ok &= jnp.isfinite(delta_p)
    delta_p = jnp.where(ok, delta_p, 0.0)
    branch = held_branch(tube, delta_p)
    at_rest = tube.replace(lambda_i=jnp.where(jnp.isfinite(branch[0]), branch[0], 1.0))

    def one(order_m, alpha):
        lam, status = critical_stretch_unchecked(tube, delta_p, alpha, order_m, n_layers, branch)
        growth = growth_rates_unchecked(at_rest, alpha, None, None, 1, n_layers, 0, order_m,
                                        ORDER_M).omega[0]
        unstable = jnp.isfinite(growth) & jnp.isfinite(branch[0])
        voltage = held_tube(tube, delta_p, lam).voltage
        return (jnp.where(unstable, 0.0, voltage), jnp.where(unstable, Status.CONVERGED, status),
                growth, jnp.where(unstable, branch[0], lam))

    voltage, status, growth, lam = map_orders_and_modes(tube, n_max, m_max, one)
    nan = lambda x: jnp.where(ok, x, jnp.nan)  # noqa: E731
    return nan(voltage), jnp.where(ok, status, Status.INVALID), nan(growth), nan(lam)


def held_instability(tube: Tube, delta_p, n_max: int, m_max: int, n_layers):
    """:func:`first_instability` of the tube held by ΔP̂ on a resolved discretisation (traceable):
    (Instability, λ_i at the first instability)."""
    tube = tube.replace(lambda_i=1.0, voltage=0.0)
    voltage, status, growth, lam = _held_grid(jax.lax.stop_gradient(tube),
                                              jax.lax.stop_gradient(as_float(delta_p)), n_max,
                                              m_max, n_layers)
    first, found, at_zero, m, n = first_of_grid(voltage, growth)
    alpha = mode_wavenumber(tube, jnp.maximum(n, 1).astype(jnp.float64))
    lam_first = jnp.where(found, lam.ravel()[first], jnp.nan)
    move = found & ~at_zero
    v = held_critical_voltage(tube, delta_p, alpha, jnp.maximum(m, 0).astype(jnp.float64), n_layers,
                              jnp.where(move, lam_first, 1.0))
    root = Roots(jnp.where(at_zero, 0.0, jnp.where(move, v, jnp.nan)),
                 jnp.where(found, Status.CONVERGED, jnp.where(jnp.all(status == Status.INVALID),
                                                              Status.INVALID, Status.NO_ROOT))
                 .astype(jnp.int32))
    return Instability(root.omega, m, n, root.status, voltage), lam_first


def first_instability(tube: Tube, n_max: int = 3, m_max: int = 8, fluid: Fluid | None = None,
                      n_layers: int | None = None, scheme: str | None = None,
                      delta_p=None, outer: Fluid | None = None) -> Instability:
    """The tube's first instability: the smallest critical voltage over every circumferential
    order 0 ≤ m ≤ m_max and axial mode 1 ≤ n ≤ n_max, and which (m, n) it belongs to.

    ``delta_p`` None: the tube held by its stretches λ_i, λ_z (:func:`jaxdea.solve.roots.first_instability`,
    each V̂_cr from :func:`jaxdea.critical_voltage`). ``delta_p`` = ΔP̂ = (P_i − P_o)/μ: the tube held
    by that pressure difference, as in a lab: λ_i follows the voltage (:func:`jaxdea.inner_stretch`;
    ``tube.lambda_i`` is ignored) and each V̂_cr is the first voltage at which the lowest Ω² of
    (m, n) reaches 0 on that path (module docstring), below pull-in at ΔP̂. The λ_i there is
    ``jaxdea.inner_stretch(tube.replace(voltage=first.voltage), delta_p)``. For the paper's tube held
    at the ΔP̂ that gives λ_i = 1.1 at V̂ = 0, the axisymmetric bulge (0, 1) comes first, at
    V̂ ≈ 0.088 with λ_i ≈ 1.5, instead of ring buckling (2, 1) at 0.106 with λ_i held at 1.1.

    ``jaxdea.pressure_difference(tube.replace(voltage=0))`` is the ΔP̂ that holds the tube's λ_i at
    V̂ = 0, and ``Scales.pressure_from_si`` converts Pa. A fluid does not change V̂_cr (its terms
    vanish like Ω²), so ``fluid`` is only validated. ``voltage`` carries implicit derivatives with
    respect to the tube's leaves and ΔP̂; vmappable.

    Args:
        tube: the :class:`~jaxdea.Tube` (``voltage`` ignored; ``lambda_i`` ignored with ``delta_p``).
        n_max: largest axial mode number (static, >= 1).
        m_max: largest circumferential order (static, >= 0).
        fluid: a :class:`~jaxdea.Fluid` or None (validated only).
        outer: a surrounding :class:`~jaxdea.Fluid` (unbounded, ``"acoustic"``) or None: the tube's own
            ``tube.outer`` (None: vacuum). Subsonic modes carry its added mass
            (docs/theory/real_tubes.md §6).
        n_layers, scheme: the discretisation (:func:`jaxdea.frequencies`).
        delta_p: None (held by its stretch) or ΔP̂, a finite real number.

    Returns:
        An instance of :class:`~jaxdea.Instability` (voltage, m, n, status, critical).

    Raises:
        ValueError: a bad input, naming it; a concrete ΔP̂ that holds no static state at V̂ = 0 (above
            the pull-in pressure).

    Examples:
        >>> tube = Tube(lambda_i=1.1, lambda_z=1.2)
        >>> held = first_instability(tube, delta_p=pressure_difference(tube.replace(voltage=0.0)))
        >>> float(held.voltage), int(held.m), int(held.n)  # ≈ (0.0882, 0, 1)
    """
    tube = with_outer(tube, outer)
    if delta_p is None:
        return stretch_held_instability(tube, n_max, m_max, fluid, n_layers, scheme)
    if not isinstance(tube, Tube):
        raise ValueError(f"tube must be a jaxdea.Tube, got {type(tube).__name__}")
    tube = tube.replace(lambda_i=1.0, voltage=0.0)  # both ignored: placeholders for the validation
    check_inputs(tube, None, fluid, n_layers, scheme)
    validate_real("delta_p", delta_p, "a finite real number (ΔP̂ = (P_i − P_o)/μ, the pressure "
                  "difference that holds the tube)")
    n_max = validate_max("n_max", n_max, 1)
    m_max = validate_max("m_max", m_max, 0)
    tube, delta_p = canonical(tube, delta_p)
    layers, short = checked_laminate(n_layers, scheme, branch_walls(tube, delta_p),
                                     mode_wavenumber(tube, n_max), m=m_max,
                                     at_rest=True)
    first, _ = held_instability(tube, delta_p, n_max, m_max, layers)
    if short is not None:
        short = jnp.any(short)
    root = inaccurate_where(short, Roots(first.voltage, first.status))
    return first._replace(status=root.status)


held_critical_stretch = cached_jit(critical_stretch_unchecked, static_argnames=("n_layers",))
"""(λ_cr, status) of one (m, n) of the tube held by ΔP̂ (:func:`critical_stretch_unchecked`),
compiled: the candidates of a design run."""
