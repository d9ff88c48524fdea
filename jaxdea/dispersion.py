"""Boundary conditions, fluid couplings and the real, pole-free characteristic function (theory.md §4).

Unknowns at the inner face x = [ū_i, w̄_i, D̄_i]; Y(r̂_i) = S x. The electrodes fix Φ = 0 on both faces
and the faces carry follower pressures (gauge P̂_o = 0, P̂_i = ΔP̂), so the outer-face rows Φ, T̄, S̄
(0-based rows 2, 3, 4) of A S must be singular: det C(Ω) = 0 (paper Eq. 45 corrected, E7/E15).

Fluid couplings clear their denominator by acting on the initial basis S (theory.md §4(b), (c)):

* ``acoustic``: column 1 → D_0 S⁰_{·1} − Ω²ρ̂_f N_0 e_T (the dynamic pressure p* = Ω²ρ̂_f B̂_0 ū_i);
* ``paper``: columns 1, 2 → D_ν S⁰_{·j} + Ω²ρ̂_f N_ν S¹_{·j} (Eq. 45 with ΔP̂ → ΔP̂ + P̂_f, P̂_f = Ω²ρ̂_f B̂_ν).

The characteristic function is det(B Q_N), with Q_N the orthonormalised propagated basis
(:func:`jaxdea.transfer.propagate_basis`): real, finite, entire in Ω, the same zeros and sign as
det C, and |f| ≤ 1 (well scaled for Newton at any α̂ĥ).
"""


import jax.numpy as jnp

from .bessel import coupling_pair
from .compiled import cached_jit
from .params import (
    Fluid,
    Tube,
    as_float,
    canonical,
    guard,
    mode_number,
    require_x64,
    validate_alpha,
    validate_fluid,
    validate_layers,
    validate_real,
    validate_tube,
)
from .transfer import Wall, discretize, laminate, propagate_basis, transfer_matrix, validate_scheme

U, W, PHI, T, S, D = range(6)
OUTER_ROWS = jnp.array([PHI, T, S])


def _unit(i):
    return jnp.zeros(6).at[i].set(1.0)


def initial_basis(wall: Wall, omega, alpha, fluid: Fluid | None = None, order: int = 0):
    """The 6×3 matrix S(Ω) with Y(r̂_i) = S [ū_i, w̄_i, D̄_i] (theory.md §4), denominators cleared."""
    p, ri = wall.pressure_inner, wall.r_inner
    col_u = _unit(U) - (p / ri) * _unit(T) - alpha * p * _unit(S)
    col_w = _unit(W) - alpha * p * _unit(T)
    col_d = _unit(D)
    if fluid is not None:
        rho, c_f = as_float(fluid.density_ratio), as_float(fluid.speed_ratio)
        s = ((omega / c_f) ** 2 - alpha**2) * ri**2  # χ̂² r̂_i²
        if fluid.coupling == "acoustic":
            n, d = coupling_pair(s, 0)
            col_u = d * col_u - omega**2 * rho * ri * n * _unit(T)
        else:  # "paper": follower pressure P̂_f on the inner face, no Ṗ term (theory.md §4(b))
            n, d = coupling_pair(s, order)
            load = omega**2 * rho * ri * n
            col_u = d * col_u + load * (-_unit(T) / ri - alpha * _unit(S))
            col_w = d * col_w + load * (-alpha * _unit(T))
    return jnp.stack([col_u, col_w, col_d], axis=-1)


def characteristic_and_scale(wall: Wall, omega, alpha, fluid=None, order=0, method="taylor"):
    """(f, log_scale) with det(B A S) = f · exp(log_scale); f = det(B Q_N) ∈ [−1, 1].

    ``method``: the sublayer exponential (:func:`jaxdea.transfer.layer_exponentials`)."""
    q, log_scale = propagate_basis(wall, omega, alpha,
                                   initial_basis(wall, omega, alpha, fluid, order), method)
    return jnp.linalg.det(q[OUTER_ROWS, :]), log_scale


def characteristic_on_wall(wall: Wall, omega, alpha, fluid=None, order=0, method="taylor"):
    """The scaled characteristic function f(Ω) on a discretised wall (see module docstring).

    ``method="adaptive"`` gives the same values faster, differentiable in forward mode only (the
    root solvers' value-and-slope evaluations)."""
    return characteristic_and_scale(wall, omega, alpha, fluid, order, method)[0]


def reference_determinant(wall: Wall, omega, alpha, fluid=None, order=0):
    """det(B A S) from the full 6×6 transfer matrix: the unscaled reference (overflows for large α̂ĥ)."""
    a = transfer_matrix(wall, omega, alpha)
    return jnp.linalg.det(a[OUTER_ROWS, :] @ initial_basis(wall, omega, alpha, fluid, order))


def resolve_order(tube: Tube, alpha, fluid: Fluid | None) -> int:
    """The static Bessel order: 0 for ``acoustic``; ``bessel_order`` or the axial mode number n for
    ``paper`` (API.md)."""
    if fluid is None or fluid.coupling == "acoustic":
        return 0
    if fluid.bessel_order is not None:
        return int(fluid.bessel_order)
    return mode_number(tube, alpha)


def check_inputs(tube, alpha, fluid, n_layers, scheme="midpoint"):
    """Validate the public inputs (concrete values) and return the static Bessel order."""
    require_x64()
    validate_tube(tube)
    validate_fluid(fluid)
    validate_layers(n_layers)
    validate_scheme(scheme)
    validate_alpha(alpha)
    return resolve_order(tube, alpha, fluid)


def characteristic(tube: Tube, omega, alpha, fluid: Fluid | None = None, n_layers: int = 30,
                   scheme: str = "midpoint"):
    """The real characteristic function whose zeros in Ω are the frequencies.

    f(Ω) = det(B Q_N) (module docstring): finite, pole-free, even in Ω, |f| ≤ 1, with the zeros and
    the sign of det C(Ω) of theory.md §4 (paper Eq. 45 corrected). NaN if the transfer is not finite.

    Args:
        tube: the :class:`~jaxdea.Tube`.
        omega: Ω = ω R_i / c_s, a finite real number.
        alpha: α̂ = α R_i >= ALPHA_MIN = 1e-12 (:data:`jaxdea.params.ALPHA_MIN`).
        fluid: a :class:`~jaxdea.Fluid`, or None for the empty tube.
        n_layers: number of sublayers N (static).
        scheme: how a sublayer is crossed (static): ``"midpoint"`` (the paper's laminate, error
            O(N⁻²)), ``"magnus4"`` or ``"magnus6"`` (O(N⁻⁴), O(N⁻⁶); :mod:`jaxdea.transfer`).

    Raises:
        ValueError: for invalid concrete inputs, naming the parameter and its allowed range (past
            Gent locking: stating the largest I_1 − 3 in the wall against G). Traced invalid inputs
            (under ``jit``/``vmap``) give NaN instead.

    Example:
        >>> f = characteristic(Tube(), 1.0, 0.445)
    """
    order = check_inputs(tube, alpha, fluid, n_layers, scheme)
    validate_real("omega", omega)
    tube, omega, alpha, fluid = canonical(tube, omega, alpha, fluid)
    return _characteristic(tube, omega, alpha, fluid, laminate(n_layers, scheme), order)


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
