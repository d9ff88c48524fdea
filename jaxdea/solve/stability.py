"""Stability of a given state: is the tube at its voltage stable in every order m and axial mode n,
and if not, which (m, n) grows fastest (docs/theory/order_m.md §6)?

A state is unstable in (m, n) where the characteristic function of order m at α̂_n has a zero at
Ω² = −s² < 0: the mode grows like e^{st}. :func:`stability` scans every (m, n) of the grid for its
largest growth rate s (:func:`jaxdea.growth_rates`, one compiled search over the traced m), so it
answers at the tube's own voltage what :func:`jaxdea.first_instability` answers as a voltage: for λ_i
and λ_z held, the state is stable exactly when ``tube.voltage`` lies below the first instability.
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp

from ..compiled import cached_jit, serializable
from ..numerics.scalar import Status
from ..params import Fluid, Tube, canonical, mode_wavenumber, with_outer
from ..physics.problem import NO_ALPHA, describe
from ..physics.state_matrix import ORDER_M
from ..physics.transfer import laminate
from .roots import (
    Roots,
    attach_derivatives,
    growth_rates_unchecked,
    map_orders_and_modes,
    validate_max,
)


@serializable
class Stability(NamedTuple):
    """The stability of a state (:func:`stability`).

    Attributes:
        stable: True where no (m, n) searched has a growth rate.
        m: the circumferential order of the fastest-growing mode (−1 where stable).
        n: its axial mode number (0 where stable).
        growth_rate: its growth rate s = √(−Ω²) (NaN where stable), with implicit derivatives
            with respect to the tube's and fluid's leaves.
        status: CONVERGED; INVALID where an input is out of range (then ``stable`` is False and
            every number NaN).
        growth: the largest growth rate of every (m, n), shape (m_max + 1, n_max) (values only;
            NaN: stable in that (m, n)).
    """

    stable: jax.Array
    m: jax.Array
    n: jax.Array
    growth_rate: jax.Array
    status: jax.Array
    growth: jax.Array


@cached_jit(static_argnames=("n_max", "m_max", "n_layers", "order"))
def _growth_grid(tube, fluid, n_max, m_max, n_layers, order):
    """(largest s, status) of every (m, n), m = 0 … m_max, n = 1 … n_max, shape (m_max + 1, n_max):
    ``lax.map`` over (m, α̂_n) of the growth-rate scan of order m (traced; at m = 0 the longitudinal
    modes through the 8×8 system, docs/theory/order_m.md §3)."""
    def one(order_m, alpha):
        roots = growth_rates_unchecked(tube, alpha, fluid, None, 1, n_layers, order, order_m,
                                       ORDER_M)
        return roots.omega[0], roots.status[0]

    return map_orders_and_modes(tube, n_max, m_max, one)


def stability(tube: Tube, n_max: int = 3, m_max: int = 8, fluid: Fluid | None = None,
              n_layers: int | None = None, scheme: str | None = None, outer: Fluid | None = None) -> Stability:
    """Is the state ``tube`` (at its own voltage) stable in every order 0 ≤ m ≤ m_max and axial
    mode 1 ≤ n ≤ n_max, and if not, which (m, n) grows fastest?

    For each (m, n) the largest growth rate s = √(−Ω²) of order m at α̂_n
    (:func:`jaxdea.axial_wavenumber`) by the guaranteed scan of :func:`jaxdea.growth_rates`; the
    state is unstable where any exists, and the (m, n) with the largest s is the one that fails
    first. With λ_i and λ_z held this agrees with :func:`jaxdea.first_instability`: stable exactly
    when ``tube.voltage`` < ``first_instability(tube).voltage`` (tested on both sides).
    The growth rate carries implicit derivatives; vmappable.

    Args:
        tube: the :class:`~jaxdea.Tube` (the state: its voltage is used).
        n_max: largest axial mode number (static, >= 1).
        m_max: largest circumferential order (static, >= 0; the ``"paper"`` coupling needs 0).
        fluid: a :class:`~jaxdea.Fluid` or None (it changes the growth rates, not their existence).
        outer: a surrounding :class:`~jaxdea.Fluid` (unbounded, ``"acoustic"``) or None: the tube's own
            ``tube.outer`` (None: vacuum). Subsonic modes carry its added mass
            (docs/theory/real_tubes.md §6).
        n_layers, scheme: the discretisation (:func:`jaxdea.frequencies`).

    Returns:
        An instance of :class:`Stability` (stable, m, n, growth_rate, status, growth).

    Raises:
        ValueError: invalid concrete inputs, naming the parameter; the ``"paper"`` coupling with
            m_max >= 1 (naming m_max: that model is axisymmetric).

    Examples:
        >>> s = stability(Tube(voltage=0.05, lambda_i=0.9, lambda_z=1.2, eta=0.85), n_max=1)
        >>> bool(s.stable), int(s.m), int(s.n)  # (False, 2, 1): ovalisation grows fastest
    """
    tube = with_outer(tube, outer)
    problem = describe(tube, NO_ALPHA, fluid, n_layers, scheme)
    order = problem.order
    n_max = validate_max("n_max", n_max, 1)
    m_max = validate_max("m_max", m_max, 0)
    if problem.face.has_poles and m_max > 0:
        raise ValueError(f"m_max must be 0 with the 'paper' coupling (an axisymmetric model), got "
                         f"{m_max}")
    tube, fluid = canonical(tube, fluid)
    layers = laminate(n_layers, scheme, tube, mode_wavenumber(tube, n_max), m=m_max)
    growth, status = _growth_grid(*jax.lax.stop_gradient((tube, fluid)), n_max, m_max, layers, order)
    invalid = jnp.any(status == Status.INVALID)
    flat = jnp.where(jnp.isnan(growth), -jnp.inf, growth).ravel()
    fastest = jnp.argmax(flat)
    unstable = jnp.isfinite(flat[fastest]) & ~invalid
    m = jnp.where(unstable, fastest // n_max, -1)
    n = jnp.where(unstable, fastest % n_max + 1, 0)
    alpha = mode_wavenumber(tube, jnp.maximum(n, 1).astype(jnp.float64))
    root = Roots(jnp.where(unstable, flat[fastest], jnp.nan),
                 jnp.where(unstable, Status.CONVERGED, Status.NO_ROOT).astype(jnp.int32))
    root = attach_derivatives(root, (tube, alpha, fluid, jnp.maximum(m, 0).astype(jnp.float64)),
                             layers, order, "growth", ORDER_M)
    return Stability(~unstable & ~invalid, m, n, root.omega,
                     jnp.where(invalid, Status.INVALID, Status.CONVERGED).astype(jnp.int32),
                     jnp.where(invalid, jnp.nan, growth))
