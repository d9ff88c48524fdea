"""Curves of complex roots by continuation (API.md, "Real tubes"; docs/theory/real_tubes.md §5):
complex α̂ against a real Ω grid (:func:`wavenumber_curve`: every wave's attenuation against
frequency) and complex Ω against a real α̂ grid (:func:`complex_dispersion_curve`: a damped tube's
resonances and quality factors against wavenumber).

The roots at the grid's first point come from the certified search (:func:`jaxdea.wavenumbers`,
:func:`jaxdea.complex_frequencies`). Each is then continued along the grid as a branch, its column
keeping its identity, in one compiled scan. Between grid points p_a → p_b a branch x(p) (F(x; p) = 0)
advances by sub-steps of the fraction h of the interval:

* predictor: x + (dx/dp) Δp + x'' Δp²/2, dx/dp = −(∂ ln F/∂p)/(∂ ln F/∂x) from both analytic
  log-derivatives of one evaluation of the characteristic contract's pieces (at the first point
  taken a relative 1e-6 off the root: at the root F is rounding noise, or exactly 0), x'' the
  difference of the tangents at the last two accepted points over their distance (third-order
  accurate);
* corrector: Newton on F in x at the new p (at most CORRECTOR_STEPS steps), stopped at a step
  ≤ STEP_RTOL|x| or where the error a step leaves, K δ² with the branch's measured contraction K,
  is below a hundredth of that (:func:`_corrector`; the roots move by ≤ 1e-13 relative against
  full convergence, measured); a wavenumber is continued as s = α̂² (F is even in α̂), in which a
  wave that cuts on through α̂ = 0 is smooth;
* acceptance: Newton converged and its correction is at most JUMP × the predicted move (the
  predictor is accurate to higher order, so a larger correction means the corrector fell onto another
  branch) plus a rounding allowance.

An accepted sub-step doubles h (at most the rest of the interval), a refused one halves it; after
MAX_HALVINGS halvings in a row the branch ends there: NaN and status MAX_ITER from that point on.
That happens where a branch cannot be continued, e.g. at a turning point of a lossless tube, where
two real waves meet and go on as a complex pair: :func:`jaxdea.wavenumbers` past that point gives
the pair.

The first point's roots are polished on the curve's own wall. The predictor's tangent comes from
the same evaluation as the corrector's last Newton step (both log-derivatives of one evaluation of
the pieces), so a sub-step costs its Newton steps alone. The benchmark's curves
(benchmarks/complex_curves.py) take 1.6 and 2.0 evaluations per grid interval, their branches
evaluated together (3.0 and 3.1 with the tangent predictor and full convergence, 5.0 and 5.2 with
two evaluations for the tangent).

Discretisation. Without ``n_layers`` and ``scheme``, a curve starts from the checked count of
:func:`jaxdea.physics.transfer.auto_layer_count` (below the rule where it asks for its least
count, 16, or m > 0) and is checked as the elastic default curve is
(:func:`jaxdea.solve.curves._checked_curve`): a Newton step of each root on the companion wall at 9
of the grid's points estimates its error; where it exceeds 1e-8 (relative to |Ω|, or to
max(|α̂|, 1) for a wavenumber) the curve is continued again on the finer N it asks for, and a branch
still short is INACCURATE. The unstretched tube's Kelvin–Voigt curve of 200 α̂ and 4 roots
(benchmarks/complex_curves.py) runs on N = 6 instead of 16, ≤ 1.2e-9 off the exact relation.
"""

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from ..compiled import jit, serializable
from ..numerics.scalar import Status
from ..params import Fluid, Tube, as_float, canonical, validate_alpha, with_outer
from ..physics import characteristic
from ..physics.characteristic import Unknown
from ..physics.problem import NO_ALPHA, describe
from ..physics.transfer import AUTO_SCHEME, discretized, laminate
from .complex_frequencies import complex_frequencies, quality_factor
from .curves import CHECKED_POINTS
from .roots import Roots, _shortfall, companion, refined
from .wavenumbers import default_alpha_max, validate_search, wavenumbers

CORRECTOR_STEPS = 30
"""Newton steps of the corrector."""
JUMP = 0.25
"""Largest Newton correction, as a fraction of the predicted move, of an accepted sub-step."""
MAX_HALVINGS = 10
"""Halvings of a sub-step in a row before a branch ends."""
STEP_RTOL = 1e-11
"""Relative Newton step at which the corrector has converged."""
FIRST_RTOL = 1e-5
"""Largest relative move of the first point's root when it is polished on the curve's wall (the
search's wall may have another N: the two differ by the discretisation error, ≤ 1e-8)."""
EARLY_SHARE = 1e-2
"""A corrector stops after a step whose predicted remaining error K δ² is this share of STEP_RTOL
(:func:`_corrector`)."""
NOISE = 1e-13
"""Steps below this relative size are rounding noise: no contraction is measured from them."""
OFFSET = 1e-6
"""Where the first point's polish gives no finite tangent, its slopes are taken at
x + OFFSET·max(1, |x|): at a root that rounds to F = 0 exactly both log-derivatives are infinite
and their ratio NaN (met on a hysteretic tube's curve)."""


@serializable
class WavenumberCurve(NamedTuple):
    """:func:`wavenumber_curve`: ``alpha`` (K, n_roots) complex α̂ along the Ω grid, each column one
    branch (ordered as :func:`jaxdea.wavenumbers` orders them at the first Ω), its ``attenuation``
    |Im α̂|, a per-point ``status`` (:class:`Status`: CONVERGED; NO_ROOT for a column the first
    search did not fill; MAX_ITER from where a branch could not be continued) and the first
    search's ``certificate`` (:class:`jaxdea.SearchStatus`)."""

    omega: jax.Array
    alpha: jax.Array
    attenuation: jax.Array
    status: jax.Array
    certificate: jax.Array


@serializable
class ComplexCurve(NamedTuple):
    """:func:`complex_dispersion_curve`: ``omega`` (K, n_roots) complex Ω along the α̂ grid, each
    column one branch (ascending in Re Ω at the first α̂), its ``quality_factor`` Re Ω/(2 Im Ω), a
    per-point ``status`` (as :class:`WavenumberCurve`) and the first search's ``certificate``."""

    alpha: jax.Array
    omega: jax.Array
    quality_factor: jax.Array
    status: jax.Array
    certificate: jax.Array


def _pieces_of(problem, wall, fluid, m, unknown):
    """The contract's pieces at (x, p) = point: x the continued variable (Ω, or s = α̂² for the
    unknown α̂, module docstring), p the grid's variable (forward mode only: the ``"adaptive"``
    exponentials)."""
    def pieces_of(point):
        x = jnp.sqrt(point[0]) if unknown is Unknown.ALPHA else point[0]
        of = characteristic.block_pieces if problem.decoupled else characteristic.pieces
        return of(problem.family, wall, x, point[1], fluid, problem.order, m, unknown, "adaptive")

    return pieces_of


def _log_slopes(pieces_of, x, p):
    """(∂ ln F/∂x, ∂ ln F/∂p) at (x, p), from one evaluation of the pieces (both tangents share
    its primal: the exponentials, the carried basis)."""
    point = jnp.stack([x, jnp.asarray(p, x.dtype)])
    directions = jnp.eye(2, dtype=x.dtype)
    slopes = jax.vmap(lambda d: characteristic.value_and_log_slope_along(pieces_of, point, d)[1])(
        directions)
    return slopes[0], slopes[1]


def _corrector(pieces_of, x0, p, contraction=jnp.inf, off_root=False):
    """(x, dx/dp, converged, contraction): Newton on F(x; p) from x0, x ← x − 1/(∂ ln F/∂x), and
    the tangent dx/dp = −(∂ ln F/∂p)/(∂ ln F/∂x) from the same evaluation as the last step (taken
    within that step of the root: the next predictor's, at no further evaluation).

    Converged where a step δ is ≤ STEP_RTOL|x|, or where the error it leaves, K δ² by Newton's
    quadratic convergence, is ≤ EARLY_SHARE · STEP_RTOL|x| for the branch's ``contraction`` K
    (|δ_k|/|δ_{k−1}|² of its last two successive steps, measured anew whenever a corrector takes
    two; ∞ until then): one evaluation instead of two when the predictor was close.

    ``off_root`` (traced bool): where the converged step's tangent is not finite (F rounds to 0
    exactly at the root, so both log-derivatives are infinite), one more evaluation, OFFSET off the
    root, gives it (module docstring), x unchanged: the first point's polish, whose tangent has no
    secant to stand in for it."""
    def step(state):
        k, x, _, _, small, last, contraction, _ = state
        offset = small  # converged already: this evaluation is the tangent's, off the root
        at = jnp.where(offset, x + OFFSET * jnp.maximum(1.0, jnp.abs(x)), x)
        slope_x, slope_p = _log_slopes(pieces_of, at, p)
        dx = 1.0 / slope_x
        finite = jnp.isfinite(jnp.abs(dx))
        x_new = jnp.where(finite & ~offset, x - dx, x)
        size = jnp.abs(dx)
        measured = (k > 0) & (last > NOISE * jnp.abs(x_new)) & ~offset
        contraction = jnp.where(measured & finite, size / jnp.where(measured, last, 1.0) ** 2,
                                contraction)
        small = offset | (size <= STEP_RTOL * jnp.abs(x_new)) | (
            contraction * size * size <= EARLY_SHARE * STEP_RTOL * jnp.abs(x_new))
        return (k + 1, x_new, -slope_p / slope_x, finite | offset, small,
                jnp.where(offset, last, size), contraction, offset)

    def going(state):
        k, _, tangent, finite, small, _, _, tried = state
        retangent = small & off_root & ~jnp.isfinite(jnp.abs(tangent)) & ~tried
        return ((k < CORRECTOR_STEPS) & finite & ~small) | retangent

    nan = jnp.full_like(x0, jnp.nan)
    zero = jnp.zeros(jnp.shape(x0), jnp.float64)
    _, x, tangent, _, small, _, contraction, _ = jax.lax.while_loop(
        going, step, (0, x0, nan, jnp.asarray(True), jnp.asarray(False), zero,
                      jnp.asarray(contraction, jnp.float64), jnp.asarray(False)))
    return x, tangent, small & jnp.isfinite(jnp.abs(x)), contraction


def _continue(pieces_of, grid, start):
    """One branch along the grid from its root ``start`` at grid[0] (polished on this wall by the
    corrector: NO_ROOT where that fails or moves it by more than FIRST_RTOL): (x at each grid
    point, status).

    The predictor's dx/dp = −(∂ ln F/∂p)/(∂ ln F/∂x) takes both log-derivatives from the same
    pieces: at a root F is rounding noise, and only their ratio within one evaluation is exact
    (two evaluations gave dα̂/dΩ = −0.57 + 0.19i against 0.60 − 0.02i). They come from the
    corrector's last Newton step (:func:`_corrector`); where that ratio is not finite (F exactly 0
    there) the secant through the last two accepted points stands in, and at the first point the
    ratio taken OFFSET off the root.

    The first point's polish is the scan's first sub-step (from grid[0] to itself: no move), and
    its tangent off the root one more pass of the same corrector loop, so the program holds one
    copy of the evaluation: with a corrector loop and a log-slope evaluation of their own for
    these two, the curves' first calls took 3.6 and 2.4 s longer (caches off,
    benchmarks/first_calls.py)."""
    def advance(carry, p_next):
        x, tangent, p, back, contraction, alive, first = carry

        def cond(state):
            t = state[0]
            return (t < 1.0) & (state[-1] <= MAX_HALVINGS)

        def body(state):
            t, h, x, tangent, back, contraction, halvings = state
            h = jnp.minimum(h, 1.0 - t)
            here, there = p + t * (p_next - p), p + (t + h) * (p_next - p)
            span = (here - back[1]).astype(x.dtype)
            secant = (x - back[0]) / span
            finite = jnp.isfinite(jnp.abs(tangent))
            slope = jnp.where(finite, tangent, secant)
            # the second derivative from the tangents at the last two accepted points
            curvature = (tangent - back[2]) / span
            curvature = jnp.where(finite & jnp.isfinite(jnp.abs(curvature)), curvature, 0.0)
            step = (there - here).astype(x.dtype)
            move = slope * step + 0.5 * curvature * step * step
            predicted = x + move
            corrected, new_tangent, converged, measured = _corrector(pieces_of, predicted, there,
                                                                     contraction, first)
            # the first point: the search's root, polished on this wall, moves by ≤ FIRST_RTOL
            allowance = jnp.where(first, FIRST_RTOL, 1e-9) * jnp.maximum(1.0, jnp.abs(x))
            good = (converged & jnp.isfinite(jnp.abs(move))
                    & (jnp.abs(corrected - predicted) <= JUMP * jnp.abs(move) + allowance))
            # after the first point no secant is needed before a corrector ran, nor a curvature
            newest = jax.tree_util.tree_map(
                lambda later, at_first: jnp.where(first, at_first, later),
                (x, jnp.asarray(here, back[1].dtype), tangent), (corrected, back[1], back[2]))
            back = jax.tree_util.tree_map(lambda new, old: jnp.where(good, new, old), newest, back)
            t = jnp.where(good, jnp.where(h >= 1.0 - t, 1.0, t + h), t)
            x = jnp.where(good, corrected, x)
            tangent = jnp.where(good, new_tangent, tangent)
            contraction = jnp.where(converged, measured, contraction)
            h = jnp.where(good, 2.0 * h, 0.5 * h)
            # a first point refused is refused again: the branch ends at once
            halvings = jnp.where(good, 0, jnp.where(first, MAX_HALVINGS + 1, halvings + 1))
            return t, h, x, tangent, back, contraction, halvings

        start = (jnp.where(alive, 0.0, 1.0), jnp.asarray(1.0), x, tangent, back, contraction,
                 jnp.asarray(0))
        t, _, x_end, tangent, back, contraction, _ = jax.lax.while_loop(cond, body, start)
        alive = alive & (t >= 1.0)
        x_end = jnp.where(alive, x_end, jnp.nan)
        return (x_end, tangent, p_next, back, contraction, alive, jnp.asarray(False)), (x_end, alive)

    nan = jnp.full_like(start, jnp.nan)
    back = (start, grid[0] - (grid[1] - grid[0]), nan)  # the first sub-step: no move
    carry = (start, nan, grid[0], back, jnp.asarray(jnp.inf, jnp.float64), jnp.asarray(True),
             jnp.asarray(True))
    _, (xs, ok) = jax.lax.scan(advance, carry, grid)
    status = jnp.where(ok, Status.CONVERGED, jnp.where(ok[0], Status.MAX_ITER, Status.NO_ROOT))
    return xs, status.astype(jnp.int32)


@jit(static_argnames=("problem", "unknown"))
def _newton_steps(problem, wall, fluid, m, grid, xs, unknown):
    """Newton's step 1/(∂ ln F/∂x) on ``wall`` at every x of xs (P, n), row i at grid[i] (x = α̂
    itself for the unknown α̂): to first order the distance from x to that wall's root."""
    def step(x, p):
        x = jnp.where(jnp.isfinite(x), x, 1.0)
        return 1.0 / characteristic.value_and_log_slope(problem.family, wall, x, p, fluid,
                                                        problem.order, m, unknown,
                                                        decoupled=problem.decoupled)[1]

    return jax.vmap(lambda row, p: jax.vmap(lambda x: step(x, p))(row))(xs, grid)


def _checked(problem, tube, layers, fluid, m, grid, starts, unknown, checked):
    """(x (K, n), status): every branch continued (:func:`_curves`) on the wall ``layers``; where
    ``checked`` (the default discretisation, started at :func:`jaxdea.physics.transfer.laminate`'s
    checked count), checked and refined like the elastic default curve
    (:func:`jaxdea.solve.curves._checked_curve`): at CHECKED_POINTS of the grid one Newton step
    per root on the :func:`jaxdea.solve.roots.companion` wall estimates its error
    (:func:`jaxdea.solve.roots._shortfall`, relative to |Ω|, or to max(|α̂|, 1) for a wavenumber,
    which may pass through 0 at a cut-on); where some exceed 1e-8 the curve is continued again on
    the finer N they ask for (:func:`jaxdea.solve.roots.refined_layers`), at most VERIFY_ROUNDS
    times; a branch still short at a checked point is INACCURATE where it converged."""
    m = as_float(float(m))
    grid, starts = jnp.asarray(grid), jnp.asarray(starts, jnp.complex128)
    pick = np.unique(np.round(np.linspace(0, grid.shape[0] - 1, CHECKED_POINTS)).astype(int))

    def solve(layers):
        return _curves(problem, discretized(tube, n_layers=layers), fluid, m, grid, starts, unknown)

    if not checked:
        return solve(layers)

    def ratio_of(curve, layers):
        sampled = np.asarray(curve[0])[pick]
        steps = np.asarray(_newton_steps(problem, discretized(tube, n_layers=companion(layers)),
                                         fluid, m, grid[pick], jnp.asarray(sampled), unknown))
        scale = sampled if unknown is not Unknown.ALPHA else np.where(
            np.abs(sampled) >= 1.0, sampled, 1.0)
        return _shortfall(Roots(scale, np.asarray(curve[1])[pick]), steps, layers)

    _, (x, status), ratio = refined(solve, ratio_of, layers)
    short = np.any(ratio > 1.0, axis=0)[None, :]
    return x, jnp.where(short & (status == Status.CONVERGED), Status.INACCURATE,
                        status).astype(jnp.int32)


@jit(static_argnames=("problem", "unknown"))
def _curves(problem, wall, fluid, m, grid, starts, unknown):
    """Every branch from ``starts`` along ``grid``: (x (K, n), status (K, n)). Wavenumbers are
    continued in s = α̂² (F is even in α̂: F(α̂) = F(−α̂), so F(√s) is analytic in s) and reported
    as α̂ = √s, Re α̂ ≥ 0: a wave that cuts on passes through α̂ = 0, where α̂(Ω) has a
    square-root branch point and s(Ω) does not."""
    pieces_of = _pieces_of(problem, wall, fluid, m, unknown)
    squared = unknown is Unknown.ALPHA
    xs, status = jax.vmap(lambda x0: _continue(pieces_of, grid, x0))(
        starts * starts if squared else starts)
    return (jnp.sqrt(xs) if squared else xs).T, status.T


def _grid(name: str, values) -> np.ndarray:
    """A 1-D, finite, positive, strictly monotone grid (ValueError naming ``name``)."""
    if isinstance(values, jax.core.Tracer):
        raise ValueError(f"{name} must be concrete: the first point's search runs in Python "
                         "(call it outside jit, grad and vmap)")
    try:
        grid = np.asarray(values, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} must be a 1-D array of real numbers, got {values!r}") from exc
    if grid.ndim != 1 or grid.size < 1:
        raise ValueError(f"{name} must be a non-empty 1-D array, got shape {grid.shape}")
    if not np.all(np.isfinite(grid)) or not np.all(grid > 0):
        raise ValueError(f"{name} must be finite and > 0, got {grid!r}")
    steps = np.diff(grid)
    if grid.size > 1 and not (np.all(steps > 0) or np.all(steps < 0)):
        raise ValueError(f"{name} must be strictly increasing or strictly decreasing (a curve is "
                         "continued point to point)")
    return grid


def wavenumber_curve(tube: Tube, omegas, fluid: Fluid | None = None, n_roots: int = 4, m: int = 0,
                     n_layers: int | None = None, scheme: str | None = None,
                     torsional: bool = False, alpha_max=None,
                     outer: Fluid | None = None) -> WavenumberCurve:
    """Complex wavenumbers α̂ against a real frequency grid, by continuation (module docstring).

    The ``n_roots`` roots of :func:`jaxdea.wavenumbers` at ``omegas[0]`` (certified), each followed
    along ``omegas`` as a branch: a propagating wave stays real, an attenuated one keeps its
    |Im α̂| = attenuation per unit R_i (``units.Scales.attenuation_to_db_per_m`` in SI). A damped
    tube (``damping=``) gives every wave an attenuation.

    Args:
        tube, fluid, outer, n_roots, m, torsional, n_layers, scheme, alpha_max: as for
            :func:`jaxdea.wavenumbers`. The default discretisation is resolved for the largest
            |α̂| expected (the first roots, the default α_max at the grid's largest Ω), started
            below the rule and checked (module docstring).
        omegas: the real Ω grid, 1-D, > 0, strictly monotone.

    Returns:
        An instance of :class:`WavenumberCurve`.

    Raises:
        ValueError: naming the parameter, as :func:`jaxdea.wavenumbers`, and for a grid that is not
            1-D, finite, positive and monotone.

    Examples:
        >>> damped = Tube(voltage=0.0, lambda_i=1.0, lambda_z=1.0, damping=Hysteretic(0.05))
        >>> curve = wavenumber_curve(damped, np.linspace(0.5, 2.0, 100), n_roots=2)
        >>> curve.attenuation[:, 0]   # the first wave's |Im α̂| against Ω
    """
    tube = with_outer(tube, outer)
    grid = _grid("omegas", omegas)
    validate_search("wavenumber_curve", tube, ("omega", float(grid[0])), fluid, m, n_roots,
                    ("alpha_max", alpha_max))
    start = wavenumbers(tube, float(grid[0]), fluid, n_roots, m, n_layers, scheme, torsional,
                        alpha_max)
    problem = describe(tube, NO_ALPHA, fluid, n_layers, scheme, m, torsional, damped=True)
    tube, fluid = canonical(tube, fluid)
    reach = (default_alpha_max(problem, tube, float(np.max(grid)), fluid) if alpha_max is None
             else float(alpha_max))
    finite = np.abs(np.asarray(start.alpha))[np.isfinite(np.abs(np.asarray(start.alpha)))]
    reach = max([reach, *finite])  # the check refines where the branches reach farther
    checked = n_layers is None and scheme in (None, AUTO_SCHEME)
    layers = laminate(n_layers, scheme, tube, reach, n_roots, int(m), checked=checked)
    alpha, status = _checked(problem, tube, layers, fluid, m, grid, start.alpha, Unknown.ALPHA,
                             checked)
    return WavenumberCurve(jnp.asarray(grid), alpha, jnp.abs(jnp.imag(alpha)), status,
                           start.certificate)


def complex_dispersion_curve(tube: Tube, alphas, fluid: Fluid | None = None, n_roots: int = 3,
                             m: int = 0, omega_max=None, n_layers: int | None = None,
                             scheme: str | None = None, torsional: bool = False,
                             outer: Fluid | None = None) -> ComplexCurve:
    """Complex frequencies Ω against a real wavenumber grid, by continuation (module docstring):
    the resonances of a damped tube with their quality factors along a dispersion curve.

    The ``n_roots`` roots of :func:`jaxdea.complex_frequencies` at ``alphas[0]`` (certified), each
    followed along ``alphas`` as a branch.

    Args:
        tube, fluid, outer, n_roots, m, torsional, n_layers, scheme, omega_max: as for
            :func:`jaxdea.complex_frequencies`. The default discretisation is resolved for the
            grid's largest α̂, started below the rule and checked (module docstring).
        alphas: the real α̂ grid, 1-D, > 0, strictly monotone.

    Returns:
        An instance of :class:`ComplexCurve`.

    Raises:
        ValueError: naming the parameter, as :func:`jaxdea.complex_frequencies`, and for a grid that
            is not 1-D, finite, positive and monotone.

    Examples:
        >>> damped = Tube(voltage=0.0, lambda_i=1.0, lambda_z=1.0, damping=KelvinVoigt(0.05))
        >>> curve = complex_dispersion_curve(damped, np.linspace(0.2, 3.0, 100), n_roots=2)
        >>> curve.quality_factor[:, 0]   # Q of the lowest resonance against α̂
    """
    tube = with_outer(tube, outer)
    grid = _grid("alphas", alphas)
    validate_search("complex_dispersion_curve", tube, ("alpha", float(grid[0])), fluid, m,
                    n_roots, ("omega_max", omega_max))
    for a in (grid[0], grid[-1]):
        validate_alpha(float(a), tube=tube)
    start = complex_frequencies(tube, float(grid[0]), fluid, n_roots, m, omega_max, n_layers,
                                scheme, torsional)
    problem = describe(tube, float(grid[0]), fluid, n_layers, scheme, m, torsional, damped=True)
    tube, fluid = canonical(tube, fluid)
    checked = n_layers is None and scheme in (None, AUTO_SCHEME)
    layers = laminate(n_layers, scheme, tube, float(np.max(grid)), n_roots, int(m),
                      checked=checked)
    omega, status = _checked(problem, tube, layers, fluid, m, grid, start.omega, Unknown.OMEGA,
                             checked)
    return ComplexCurve(jnp.asarray(grid), omega, quality_factor(omega), status, start.certificate)
