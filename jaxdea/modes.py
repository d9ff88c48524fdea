"""Mode shapes: the state fields across the wall for a root Ω (theory.md §3–4)."""

import functools

import jax
import jax.numpy as jnp

from .dispersion import OUTER_ROWS, check_inputs, initial_basis
from .params import Fluid, Tube, as_float, canonical
from .state_matrix import state_matrix
from .transfer import discretize, expm_taylor, propagate_basis_history


@functools.partial(jax.jit, static_argnames=("n_points", "n_layers", "order"))
def _mode_shape(tube, alpha, omega, fluid, n_points, n_layers, order):
    alpha, omega = as_float(alpha), as_float(omega)
    wall = discretize(tube, n_layers)
    qs, rs = propagate_basis_history(wall, omega, alpha,
                                     initial_basis(wall, omega, alpha, fluid, order))
    # null vector of the outer-face conditions in the last basis, then back through the R factors
    _, _, vt = jnp.linalg.svd(qs[-1][OUTER_ROWS, :])
    c_last = vt[-1]

    def back(c, r):
        return jax.scipy.linalg.solve_triangular(r, c, lower=False), c

    _, cs = jax.lax.scan(back, c_last, rs[1:], reverse=True)  # cs[k] = coefficients at interface k+1
    c0 = jax.scipy.linalg.solve_triangular(rs[1], cs[0], lower=False)
    states = jnp.einsum("kij,kj->ki", qs, jnp.concatenate([c0[None], cs]))  # (N+1, 6) interfaces
    r = jnp.linspace(wall.r_inner, wall.r_outer, n_points)
    layer = jnp.clip(jnp.floor((r - wall.r_inner) / wall.step).astype(int), 0, n_layers - 1)
    start = wall.r_inner + layer * wall.step
    coef = jax.tree_util.tree_map(lambda x: x[layer], wall.coef)
    mats = jax.vmap(state_matrix, (0, 0, None, None))(coef, wall.radii[layer], omega, alpha)
    fields = jax.vmap(lambda m, d, y: expm_taylor(d * m) @ y)(mats, r - start, states[layer])
    big = jnp.argmax(jnp.max(jnp.abs(fields[:, :2]), axis=1))
    comp = jnp.argmax(jnp.abs(fields[big, :2]))
    return r, (fields / fields[big, comp]).T


def mode_shape(tube: Tube, alpha, omega, fluid: Fluid | None = None, n_points: int = 64,
               n_layers: int = 30):
    """The state fields [ū, w̄, Φ, T̄, S̄, D̄] across the wall for the root ``omega``.

    The null vector of the outer-face conditions is carried back through the orthonormalised
    propagation (stable for any α̂ĥ) and the fields inside each sublayer follow from its exponential.
    Scaled so that max(|ū|, |w̄|) = 1 (the largest displacement entry is +1).

    Returns:
        (r, fields): radii r̂ (n_points,) from r̂_i to r̂_o and fields (6, n_points).
    """
    order = check_inputs(tube, alpha, fluid, n_layers)
    tube, alpha, omega, fluid = canonical(tube, alpha, omega, fluid)
    return _mode_shape(tube, alpha, omega, fluid, int(n_points), int(n_layers), order)
