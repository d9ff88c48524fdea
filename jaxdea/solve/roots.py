"""Frequencies: zeros in Ω of the characteristic function, with status codes and exact derivatives.

Root isolation (:func:`solve_frequencies`). f(Ω) is scanned upwards from Ω = 0 in chunks of
``CHUNK`` points: Ω = 0 and geometric points Δ·64^{-9} … Δ (roots near zero, no fixed lower
limit), then uniform steps Δ. Δ resolves the oscillation of f: Δ = min(π c_min/ĥ, π ĉ_f/r̂_i)/16, with c_min
the slowest shear speed in the wall. Above the cutoffs of the shear waves along z (Ω_c = c_z α̂) and
of the fluid (ĉ_f α̂), where thickness resonances crowd, the steps are uniform in the radial phase
instead (:func:`cutoff_steps`). Each grid interval [a, b] is classified with the values *and*
autodiff slopes at its ends (Hermite data):

* a sign change of f → one root, refined by safeguarded Newton from the root of the Hermite cubic
  of the interval (:func:`jaxdea.numerics.scalar.hermite_root`);
* no sign change, but f heads towards zero at a and away from it at b (f_a f'_a < 0 < f_b f'_b) →
  f has an extremum inside, located by Illinois regula falsi on f'; if f changes
  sign there, the interval holds a pair of roots, each refined in its half.

Guarantee: a root is missed only if an interval contains more than one extremum of f (f' changes sign
at least twice within one step Δ) or three or more roots. Pairs of roots closer than any step are
found (tested down to relative gaps of 1e-9). The limits are stated in the README.

The function scanned and refined is the characteristic determinant itself, det(B A S) times a
constant (:func:`scanned_function`), not its normalised value f = det(B Q_N) of
:mod:`jaxdea.physics.dispersion`: the normalisation divides by the volume of A S, which nearly vanishes
where A S is nearly rank-deficient, and f then turns sign in a near-jump (at the inner-face waves
of a wall with large α̂ĥ, whose solution decays across it; next to the poles of the paper's
coupling). A jump next to a second root within one step hides the pair from the classification;
det(B A S) is entire and has an ordinary pair there. With the paper's coupling the grid is also
uniform in the phase of the coupling near each pole Ω_k of B̂_ν (closed form,
:func:`coupling_poles`), where the roots crowd within a few widths w_k ≪ Δ, and holds Ω_k itself,
which splits a pair straddling it into two sign changes (:func:`pole_steps`).

Derivatives. Every returned root carries implicit-function derivatives dΩ/dθ = −(∂f/∂θ)/(∂f/∂Ω)
(:func:`jaxdea.numerics.scalar.attach_implicit`, the one mechanism of every solver of the package: a
``jax.custom_jvp`` around the values of the solver), never derivatives of the iterations: the
solver is compiled once for values, and differentiating compiles only f and its derivatives.
"""

import functools
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from ..compiled import cached_jit, serializable
from ..numerics.bessel import NODES, RANGE
from ..numerics.scalar import (
    ROOT_RTOL,
    Status,
    hermite_extremum,
    hermite_root,
    lanes_from_slots,
    newton_distance,
    newton_slope,
    refuse_non_root,
    run_lanes,
    start_lanes,
    value_and_slope,
    with_implicit_derivatives,
)
from ..params import (
    Fluid,
    Tube,
    as_float,
    canonical,
    detached,
    guard,
    mode_wavenumber,
    real_value,
    require_x64,
    traced,
    validate_broadcast,
    validate_positive,
    validate_range,
    validate_roots,
    with_outer,
)
from ..physics import characteristic
from ..physics.base_state import voltage_limit
from ..physics.characteristic import Unknown
from ..physics.dispersion import carried_jvp
from ..physics.families import Face, Family
from ..physics.problem import NO_ALPHA, Problem, describe
from ..physics.state_matrix import LONGITUDINAL, ORDER_M
from ..physics.transfer import (
    AUTO_SCHEME,
    CHECKED_COUNTS,
    DEFAULT_RTOL,
    LAYER_COUNTS,
    Layers,
    Wall,
    checked_laminate,
    counted,
    discretize,
    is_graded,
    laminate,
    scheme_order,
    split_layers,
    voltage_expansion,
    voltage_exponentials,
    voltage_generators,
    wall_at_voltage,
)

CHUNK = 32  # points per scan chunk: 64 cost twice the work where one chunk holds the roots
GEOMETRIC_RATIO = 64.0
GEOMETRIC_POINTS = 10  # Δ·64^-9 ≈ 6e-17 Δ … Δ: roots near Ω = 0 (no fixed lower limit)
STEPS_PER_OSCILLATION = 16
HERMITE_FINAL = 1e-6  # _first_root: a sign change ≤ 1e-6 Δ wide …
HERMITE_FINAL_SLOPES = 1e-3  # … with end slopes equal to 1e-3 is solved by its Hermite cubic
SCALE_EXPONENT_MAX = 600.0  # |log_scale − its value at Ω = 0| is clipped here (e^600 < 1e261)
BESSEL_GRID = 1.0  # bracketing grid of the zeros of J'_ν: consecutive zeros are > 2 apart, so an
# interval holds at most one


@serializable
class Roots(NamedTuple):
    """Roots with one status code per root (see :class:`jaxdea.Status`); NaN where not converged."""

    omega: jax.Array
    status: jax.Array


def scan_step(wall: Wall, fluid: Fluid | None, family: str = LONGITUDINAL):
    """Scan step Δ = min(π c_min/ĥ, π ĉ_f/r̂_i)/16 (a sixteenth of the shortest oscillation of f)."""
    coef = wall.coef
    c_min = jnp.sqrt(family.slowest_shear(coef))
    thickness = wall.thickness
    scale = np.pi * c_min / thickness
    if fluid is not None:
        scale = jnp.minimum(scale, np.pi * as_float(fluid.speed_ratio) / wall.r_inner)
    return scale / STEPS_PER_OSCILLATION


def cutoff_steps(wall: Wall, alpha, fluid: Fluid | None, step, family: str = LONGITUDINAL):
    """next(x): the grid point after x, at most Δ = ``step`` beyond it and denser near the cutoffs.

    Above a cutoff Ω_c = c_z α̂ (c_z = sqrt(a), the speed of shear waves along z, between its
    smallest and largest value over the wall; for the fluid ĉ_f α̂) a wave family starts to
    propagate across the thickness ℓ (ĥ, or r̂_i for the fluid) with radial wavenumber
    k = sqrt(Ω² − Ω_c²)/c (c = c_min, or ĉ_f): thickness resonances at kℓ = jπ crowd at Ω_c with
    spacing ≈ c²(2j + 1)π²/(2Ω_c ℓ²), far below Δ when α̂ℓ is large. The grid is uniform in the
    phase φ = kℓ there: a step never advances φ by more than π/16 (the step Δ is π/16 of the
    oscillation far above the cutoff).
    """
    coef = wall.coef
    c_min = jnp.sqrt(family.slowest_shear(coef))
    c_z = jnp.sqrt(coef.a)
    cut = [jnp.min(c_z) * alpha, jnp.max(c_z) * alpha]
    speed = [c_min, c_min]
    length = [wall.thickness] * 2
    if fluid is not None:
        c_f = as_float(fluid.speed_ratio)
        cut.append(c_f * alpha)
        speed.append(c_f)
        length.append(wall.r_inner)
    cut, speed, length = jnp.stack(cut), jnp.stack(speed), jnp.stack(length)
    dphi = np.pi / STEPS_PER_OSCILLATION

    def next_point(x):
        phi = length * jnp.sqrt(jnp.maximum(x * x - cut * cut, 0.0)) / speed
        ahead = jnp.sqrt(cut * cut + (speed * (phi + dphi) / length) ** 2)
        return x + jnp.minimum(step, jnp.min(ahead - x))

    return next_point


@functools.cache
def bessel_derivative_zeros(order: int) -> np.ndarray:
    """The zeros j'_{ν,k} of J'_ν in [0, RANGE − ν), ascending (NumPy, computed once per ν).

    Where :func:`jaxdea.numerics.bessel.coupling_pair` is finite (x + ν < RANGE). J'_ν(x) =
    (1/2π)∫₀^{2π} sin(νt − x sin t) sin t dt and J''_ν(x) = −(1/2π)∫₀^{2π} cos(νt − x sin t) sin²t dt
    by the trapezoidal rule on 2·NODES points (exact to rounding there), sign changes on a grid of
    ``BESSEL_GRID`` from x = ν, 4 bisections (to 0.06), then Newton steps kept inside the bracket
    (quadratic: to rounding in four; a step where J'' = 0 is skipped). For ν = 0 the list starts
    with x = 0: D_0 = −s/2 + O(s²) vanishes at s = 0.
    """
    theta = 2.0 * np.pi * np.arange(2 * NODES) / (2 * NODES)
    sin_theta = np.sin(theta)

    def derivative(x):
        return np.mean(np.sin(order * theta - x[:, None] * sin_theta) * sin_theta, axis=1)

    def second(x):
        return -np.mean(np.cos(order * theta - x[:, None] * sin_theta) * sin_theta**2, axis=1)

    start = max(float(order), BESSEL_GRID)  # j'_{ν,1} > ν for ν > 0; below it J'_ν is rounding noise
    limit = RANGE - order
    grid = np.append(np.arange(start, limit, BESSEL_GRID), limit)
    values = derivative(grid)
    change = np.flatnonzero(values[:-1] * values[1:] < 0)
    lo, hi, f_lo = grid[change], grid[change + 1], values[change]
    for _ in range(4):
        mid = 0.5 * (lo + hi)
        same = derivative(mid) * f_lo > 0
        lo, hi = np.where(same, mid, lo), np.where(same, hi, mid)
    zeros = 0.5 * (lo + hi)
    for _ in range(5):
        slope = second(zeros)
        step = derivative(zeros) / np.where(slope == 0.0, np.inf, slope)
        zeros = np.clip(zeros - step, lo, hi)
    return np.concatenate([[0.0], zeros]) if order == 0 else zeros


TRACED_ORDERS = 32
"""A traced Bessel order ν (a sweep over the axial mode n with ``bessel_order=None``) takes its
poles from a table of ν = 0 … TRACED_ORDERS; above it the scan has no pole points (the plain grid)."""


@functools.cache
def _zeros_table() -> np.ndarray:
    """j'_{ν,k} for ν = 0 … TRACED_ORDERS, padded with inf, shape (TRACED_ORDERS + 1, K)."""
    rows = [bessel_derivative_zeros(nu) for nu in range(TRACED_ORDERS + 1)]
    table = np.full((len(rows), max(len(r) for r in rows)), np.inf)
    for nu, r in enumerate(rows):
        table[nu, : len(r)] = r
    return table


def coupling_poles(wall: Wall, alpha, fluid: Fluid, order):
    """(Ω_k, w_k): the poles Ω_k = ĉ_f sqrt(α̂² + (j'_{ν,k}/r̂_i)²) of the paper's coupling B̂_ν, where
    D_ν(s) = 0 at s = χ̂²r̂_i² = j'²_{ν,k} (:func:`jaxdea.numerics.bessel.coupling_pair`), and their widths
    w_k = |L/(dD_ν/dΩ)| = ρ̂_f ĉ_f² Ω_k x_k²/(r̂_i (x_k² − ν²)) (x_k = j'_{ν,k}; the factor x²/(x² − ν²)
    is 1 for ν = 0), with L = Ω²ρ̂_f r̂_i N_ν: by Bessel's equation J''_ν = −(1 − ν²/x²)J_ν where
    J'_ν = 0, and dx/dΩ = r̂_i²Ω/(ĉ_f² x). ``order``: an int, or a traced ν (:data:`TRACED_ORDERS`;
    absent poles are at +inf with width 1, which no grid point reaches)."""
    if isinstance(order, jax.core.Tracer):
        nu = jnp.asarray(order, jnp.float64)
        inside = (nu >= 0) & (nu <= TRACED_ORDERS)
        row = jnp.clip(jnp.round(nu), 0, TRACED_ORDERS).astype(jnp.int32)
        x = jnp.where(inside, jnp.asarray(_zeros_table())[row], jnp.inf)
    else:
        nu = float(order)
        x = jnp.asarray(bessel_derivative_zeros(int(order)))
    c_f = as_float(fluid.speed_ratio)
    present = jnp.isfinite(x)
    x_safe = jnp.where(present, x, 1.0 + nu)
    poles = jnp.where(present, c_f * jnp.sqrt(alpha**2 + (x_safe / wall.r_inner) ** 2), jnp.inf)
    shape = jnp.where(nu == 0, 1.0, x_safe**2 / jnp.where(nu == 0, 1.0, x_safe**2 - nu**2))
    widths = jnp.where(present, as_float(fluid.density_ratio) * c_f**2 * poles * shape / wall.r_inner,
                       1.0)
    return poles, widths


def pole_steps(next_point, poles, widths):
    """next(x) of ``next_point``, also uniform in the coupling's phase θ near every pole Ω_k.

    Columns 1 and 2 of the paper's basis are D_ν c_j + L v_j (docs/theory/axisymmetric.md §4(b)), so its
    characteristic function is a quadratic form in (D_ν, L), f = aD_ν² + bD_νL + cL², with a, b, c
    minors of the wall's transfer (varying on the scale of the step Δ). Near Ω_k the direction θ
    of (D_ν, L) turns by π within a few widths w_k (D_ν ≈ D'_ν(Ω − Ω_k), L nearly constant):
    θ = π/2 − atan((Ω − Ω_k)/w_k). In θ, f/(D_ν² + L²) = A + B cos 2θ + C sin 2θ has period π,
    so, as the grid takes 16 steps per oscillation in Ω, it takes steps of π/16 in θ: the points
    Ω_k + w_k tan(jπ/16), j = −7 … 7 (θ turns by π/16 beyond the outermost). The pole itself
    (j = 0) is one of them: there f = cL², so a pair straddling the pole (ac < 0: roots of
    a t² + b t + c of opposite signs in t = D_ν/L) leaves one sign change on either side of it.
    f is entire: a sign change of f is always a root, never a pole.
    """
    dphi = np.pi / STEPS_PER_OSCILLATION

    def next_phase_or_point(x):
        phase = jnp.arctan((x - poles) / widths)
        lattice = jnp.floor(phase / dphi)
        ahead = []
        for j in (1, 2):  # the next lattice phase, or the one after where x sits on the next
            target = (lattice + j) * dphi
            ahead.append(jnp.where(target < 0.5 * np.pi - 0.5 * dphi,
                                   poles + widths * jnp.tan(target), jnp.inf))
        ahead = jnp.where(ahead[0] > x, ahead[0], jnp.where(ahead[1] > x, ahead[1], jnp.inf))
        return jnp.minimum(next_point(x), jnp.min(ahead))

    return next_phase_or_point


def scanned_function(wall: Wall, alpha, fluid: Fluid | None, order: int, m=0.0,
                     family: str = LONGITUDINAL, variable: str = "omega", decoupled: bool = False,
                     generators=None):
    """g = det(B A S)·e^{−ℓ₀}: the characteristic determinant, unnormalised, that the scan classifies.

    det(B A S) = f e^ℓ with f = det(B Q_N) and ℓ the log-volume of the propagated basis
    (:func:`jaxdea.physics.dispersion.characteristic_and_scale`); ℓ₀ is ℓ at Ω = 0, a constant that
    keeps g in floating-point range (ℓ − ℓ₀ is clipped to ±``SCALE_EXPONENT_MAX``). g has the
    zeros and the sign of f, and it is entire in Ω. f is not: where A S is nearly rank-deficient
    (at the inner-face waves of a wall with large α̂ĥ, whose solution decays across it, and next to
    the poles of the paper's coupling) e^ℓ dips to almost zero, and f turns sign there in a
    near-jump (measured at α̂ĥ ≈ 86: e^ℓ ∝ |Ω − Ω₀| down to |Ω − Ω₀| ≈ 1e-8 Ω₀, f ≈ ±1.2e-3 on either
    side). Between grid points such a jump next to another root leaves
    f without a sign change and with two extrema (f' changes sign at the jump), which the scan's
    classification misses; g has the ordinary simple root there. ``variable``: ``"omega"`` (g(Ω))
    or ``"omega_squared"`` (g(w), w = Ω² of either sign; order m and torsional families only).
    ``decoupled`` (static, longitudinal): the 4×4 mechanical propagation of a wall whose electric
    block decouples (NaN where it does not, :func:`jaxdea.physics.dispersion.value_and_slope_on_wall`).
    ``generators``: the wall's generators at α̂ if already formed
    (:func:`jaxdea.physics.dispersion.lane_generators`).

    Returns a :class:`Scaled` (x ↦ (f, ℓ)): the scan takes ℓ₀ from its own first point, x = 0,
    instead of a separate evaluation of f at 0 (:func:`_scan_for_roots`). Its forward-mode slope
    is the carried one, f' = D det(B Q_N)[B Z] − f tr(Q_NᵀZ), ℓ' = tr(Q_NᵀZ)
    (:func:`jaxdea.physics.dispersion.scale_and_slope_on_wall` on the 6×6 path,
    :func:`jaxdea.physics.dispersion.scale_and_slope_of_w`): the same (f, ℓ) and slopes as forward mode
    through the propagation, without differentiating its Gram–Schmidt (first call, CPU seconds,
    measured with :data:`jaxdea.physics.transfer.TANGENT_UNROLL` = 1: m = 2 12.4 → 9.0, empty 5.7 → 5.0,
    acoustic 9.0 → 8.1).
    """
    if not family.carries_m and variable == "omega":
        return Scaled(characteristic.scaled(family, wall, alpha, fluid, order, 0, Unknown.OMEGA,
                                            decoupled, generators))
    ok = family.admissible(m, fluid)
    m_safe = family.safe_m(m, ok)
    carried = characteristic.scaled(family, wall, alpha, fluid, order, m_safe, Unknown(variable),
                                    decoupled, generators)

    def scaled(x):
        f, log_scale = carried(x)
        return jnp.where(ok, f, jnp.nan), log_scale

    return Scaled(scaled)


class Scaled(NamedTuple):
    """g(x) = f(x)·e^{ℓ(x) − ℓ₀} of :func:`scanned_function`, held as ``scaled``: x ↦ (f, ℓ), with
    ℓ₀ = ℓ(0) supplied by the caller. The scan evaluates f at x = 0 anyway (its first point):
    taking ℓ₀ from there, and not from an evaluation of its own, leaves one copy of f fewer in
    the compiled program (a sixth of the tracing and compilation of a first ``frequencies``)."""

    scaled: object

    @staticmethod
    def reference(log_scale):
        """ℓ₀ from ℓ(0) (0 where ℓ(0) is not finite)."""
        return jnp.where(jnp.isfinite(log_scale), log_scale, 0.0)

    @staticmethod
    def combine(f, log_scale, reference):
        """g = f·e^{ℓ − ℓ₀}, the exponent clipped to ±SCALE_EXPONENT_MAX."""
        return f * jnp.exp(jnp.clip(log_scale - reference, -SCALE_EXPONENT_MAX, SCALE_EXPONENT_MAX))

    def at(self, reference):
        """g as a function of x alone."""
        def g(x):
            return self.combine(*self.scaled(x), reference)

        return g

    def values_and_slopes(self, x, reference, first):
        """(g, g', ℓ₀) at the points ``x`` (a vector), ℓ₀ taken from x[0] = 0 where ``first``:
        the same arithmetic as ``value_and_slope`` of :meth:`at`."""
        (f, log_scale), (df, dlog_scale) = jax.vmap(lambda y: value_and_slope(self.scaled, y))(x)
        reference = jnp.where(first, self.reference(log_scale[0]), reference)
        g, dg = jax.jvp(lambda f, log_scale: self.combine(f, log_scale, reference),
                        (f, log_scale), (df, dlog_scale))
        return g, dg, reference


def default_omega_max(wall: Wall, alpha, n_roots: int, m=0.0):
    """Search limit when none is given: (n_roots + 1) thickness-mode spacings plus 3α̂ c_max, plus
    3 m c_max/r̂_i at order m (the circumferential wavenumber m/r̂ adds like α̂)."""
    coef = wall.coef
    c_max = jnp.sqrt(jnp.max(jnp.maximum(jnp.maximum(coef.a, coef.b), coef.c)))
    thickness = wall.thickness
    return ((n_roots + 1) * np.pi * c_max / thickness + 3.0 * alpha * c_max
            + 3.0 * as_float(m) * c_max / wall.r_inner)


SUBSONIC = 1.0 - 1e-12
"""The real solvers search a tube in a surrounding fluid up to SUBSONIC·ĉ_oα̂ (the sound line)."""


def sound_line(wall: Wall, alpha):
    """SUBSONIC·ĉ_oα̂ for a wall in a surrounding fluid, ∞ without one: above the sound line a mode
    radiates into the fluid (a leaky, complex root: :func:`jaxdea.complex_frequencies`), so the real
    roots of a scan lie below it (docs/theory/real_tubes.md §6)."""
    if wall.outer is None:
        return jnp.inf
    return SUBSONIC * as_float(wall.outer.speed_ratio) * alpha


def _head(step):
    """The first chunk's points before the grid: Ω = 0, then Δ·64^-9 … Δ (the grid goes on from Δ)."""
    return jnp.concatenate([jnp.zeros(1), step * GEOMETRIC_RATIO ** jnp.arange(
        -(GEOMETRIC_POINTS - 1), 1, dtype=jnp.float64)])


def _chunk(grid, head, chunk, end):
    """The points of a scan chunk: ``grid`` (the next CHUNK grid points), led by ``head`` in the
    first chunk, none beyond ``end``."""
    return jnp.minimum(jnp.where(chunk == 0, jnp.concatenate([head, grid[: CHUNK - head.size]]), grid),
                       end)


def _intervals(x0, f0, df0, x, f, df):
    """The intervals [x_{k−1}, x_k] of an ascending chunk x after a known point x0 = x_{−1}: their
    left ends' data and their kind (1: a sign change of f; 2: a hidden pair, no sign change but f
    heads towards zero at the left end and away from it at the right, f_a f'_a < 0 < f f'; 0:
    neither, or at or after the first non-finite value, which nothing is trusted beyond), and
    where the data are finite."""
    xa, fa, dfa = (jnp.concatenate([v0[None], v[:-1]]) for v0, v in ((x0, x), (f0, f), (df0, df)))
    finite = jnp.isfinite(fa) & jnp.isfinite(f) & jnp.isfinite(dfa) & jnp.isfinite(df)
    change = finite & (fa != 0) & (jnp.sign(fa) * jnp.sign(f) <= 0)
    hidden = finite & ~change & (fa * dfa < 0) & (f * df > 0) & (x > xa)
    ok = jnp.cumsum(~finite) == 0
    return xa, fa, dfa, jnp.where(ok & change, 1, jnp.where(ok & hidden, 2, 0)), finite


def _scan_for_roots(fun, step, omega_end, n_roots: int, next_point=None,
                    continuous: bool = True) -> Roots:
    """Chunked scan with Hermite classification and refinement (module docstring).

    ``next_point(x)`` gives the grid point after x (default x + step); runs of plain steps are
    laid out as base + k·step, so a uniform grid has no accumulated rounding.

    Rounds: chunks are scanned until the candidate intervals found could hold the roots still
    needed (a sign change one, a hidden pair two), then all of them are refined together by one
    call of :func:`~jaxdea.numerics.scalar.run_lanes` (a lane per root, ``n_roots + 1`` lanes); only if
    hidden pairs held no roots does a further round scan on. f and f' are evaluated at exactly two
    places (the grid chunk and the lanes), which keeps the compiled program small.

    Consistency (``continuous``, static: f continuous in Ω, every coupling but the paper's, whose
    poles change its sign): f changes sign at each simple root, so sign f'(Ω_k) = (−1)^k sign f(0)
    for the k-th candidate (the check of :mod:`jaxdea.solve.curves`). A root found with the other slope
    sign means an odd number of roots below it was not found (or a lane took another root of its
    interval than the one it bracketed): it and all above it are then SUSPECT (NaN), never
    CONVERGED with a wrong index. Where f(0) = 0 the check is off.

    ``fun``: a function of x, or a :class:`Scaled` (:func:`scanned_function`), whose reference ℓ₀
    is taken at the first point of the first chunk, x = 0, and carried to the lanes.
    """
    if isinstance(fun, Scaled):
        fvals, lane_function = fun.values_and_slopes, fun.at
    else:
        def fvals(x, reference, first):
            del first
            return (*jax.vmap(lambda x: value_and_slope(fun, x))(x), reference)

        def lane_function(reference):
            del reference
            return fun
    head = _head(step)
    max_chunks = 1_000_000
    n_lanes = n_roots + 1  # a hidden pair always fits next to n_roots − 1 taken lanes
    cost_of = jnp.array([0, 1, 2])  # lanes per candidate kind (none, sign change, hidden pair)

    def advance(carry, _):
        x, base, count = carry
        plain = base + step * (count + 1)
        special = next_point(x)
        use_plain = special >= x + step  # no cutoff nearby: stay on the uniform lattice
        new = jnp.where(use_plain, plain, special)
        carry = (new, jnp.where(use_plain, base, new), jnp.where(use_plain, count + 1, 0.0))
        return carry, new

    def grid(left, chunk):
        start = jnp.where(chunk == 0, step, left)
        if next_point is None:
            uniform = start + step * jnp.arange(1, CHUNK + 1, dtype=jnp.float64)
        else:
            _, uniform = jax.lax.scan(advance, (start, start, jnp.zeros_like(start)), None,
                                      length=CHUNK)
        return _chunk(uniform, head, chunk, omega_end)

    def scanning(left, blocked, chunk):
        return (left < omega_end) & ~blocked & (chunk < max_chunks)

    def collect(c):
        """One chunk: classify its intervals and put the candidates into free lane slots."""
        (left, f_left, df_left, blocked, chunk, f_zero, reference), slots, used, need = c
        x = grid(left, chunk)
        f, df, reference = fvals(x, reference, chunk == 0)
        f_zero = jnp.where(chunk == 0, f[0], f_zero)  # the first chunk starts at Ω = 0
        start = chunk == 0  # the first interval [0, 0] is empty
        xa, fa, dfa, kind, finite = _intervals(
            *(jnp.where(start, v[0], v0) for v, v0 in ((x, left), (f, f_left), (df, df_left))), x, f, df)
        cost = cost_of[kind]
        pos = used + jnp.cumsum(cost) - cost  # first lane slot of each candidate
        take = (kind > 0) & (pos < need)
        # each slot gathers the candidate aimed at it (at most one): XLA:CPU expands a scatter into
        # a loop over the chunk, 16 of them here, slower to compile and to run
        for side in (0, 1):
            at = jnp.where(take & (side < cost), pos + side, n_lanes)  # n_lanes: none
            hit = at[None, :] == jnp.arange(n_lanes)[:, None]  # (slot, candidate)
            found, k = jnp.any(hit, axis=1), jnp.argmax(hit, axis=1)
            values = (xa, x, fa, f, dfa, df, kind, jnp.full_like(kind, side))
            slots = tuple(jnp.where(found, w[k], v) for v, w in zip(slots, values, strict=True))
        # more candidates than needed: resume after the last one taken
        full = jnp.any((kind > 0) & ~take)
        end = jnp.where(full, jnp.max(jnp.where(take, jnp.arange(CHUNK), 0)), CHUNK - 1)
        blocked = jnp.any(~finite & (jnp.arange(CHUNK) <= end))
        used = used + jnp.sum(jnp.where(take, cost, 0))
        return (x[end], f[end], df[end], blocked, chunk + 1, f_zero, reference), slots, used, need

    def round_cond(r):
        scan, keys = r[0], r[1]
        return (jnp.sum(jnp.isfinite(keys)) < n_roots) & scanning(scan[0], scan[3], scan[4])

    def one_round(r):
        scan, keys, roots, status, slopes = r
        need = n_roots - jnp.sum(jnp.isfinite(keys))
        empty = tuple(jnp.zeros(n_lanes) for _ in range(6)) + (jnp.zeros(n_lanes, jnp.int32),) * 2
        scan, slots, _, _ = jax.lax.while_loop(
            lambda c: (c[2] < c[3]) & scanning(c[0][0], c[0][3], c[0][4]), collect,
            (scan, empty, 0, need))
        new_roots, new_keys, new_status, new_slopes = run_lanes(
            lane_function(scan[6]), lanes_from_slots(*slots), slopes=True)
        all_keys = jnp.concatenate([keys, new_keys])
        order = jnp.argsort(all_keys)[:n_roots]
        return (scan, all_keys[order], jnp.concatenate([roots, new_roots])[order],
                jnp.concatenate([status, new_status])[order],
                jnp.concatenate([slopes, new_slopes])[order])

    zero = jnp.zeros_like(step)
    blocked = ~(jnp.isfinite(step) & jnp.isfinite(omega_end) & (step > 0))
    init = ((zero, zero, zero, blocked, 0, zero, zero), jnp.full(n_roots, jnp.inf),
            jnp.full(n_roots, jnp.nan), jnp.full(n_roots, Status.NO_ROOT, jnp.int32), jnp.zeros(n_roots))
    (_, _, _, blocked, _, f_zero, _), keys, roots, status, slopes = jax.lax.while_loop(
        round_cond, one_round, init)
    missing = ~jnp.isfinite(keys)
    status = jnp.where(missing, jnp.where(blocked, Status.NOT_FINITE, Status.NO_ROOT), status)
    if continuous:  # sign f'(Ω_k) = (−1)^k sign f(0), k = 1, 2, … (the candidates in order)
        converged = status == Status.CONVERGED
        expected = -jnp.sign(f_zero) * (-1.0) ** jnp.arange(n_roots)
        wrong = converged & (jnp.sign(slopes) * expected < 0)
        suspect = jnp.cumsum(wrong) > 0
        status = jnp.where(suspect & converged, Status.SUSPECT, status)
    return Roots(jnp.where(status == Status.CONVERGED, roots, jnp.nan), status.astype(jnp.int32))


def _first_root(fun, step, end, rtol=1e-13, max_rounds=1000) -> Roots:
    """The lowest root of ``fun`` in (0, end], with f and f' evaluated at one place only.

    The chunks and the Hermite classification of :func:`_scan_for_roots` (uniform steps), but the
    first candidate interval [a, b] is refined by zooming instead of lanes: the next chunk is
    x* ± (b − a)·64^{-j}, j = 0 … CHUNK/2 − 1, clipped to [a, b], with x* the root of the interval's
    Hermite cubic (a sign change) or its stationary point (a hidden pair), and the first candidate
    among its intervals is the new [a, b]. Each round leaves a bracket of at most 64 times the
    error of x* (O((b − a)⁴)): one to three zooms reach rounding. A sign change narrower than
    ``rtol``·|x|, or narrower than ``HERMITE_FINAL``·Δ with end slopes equal to
    ``HERMITE_FINAL_SLOPES`` (its cubic is then f to rounding; never so for a hidden pair, whose end
    slopes have opposite signs), gives the root of its Hermite cubic; a hidden pair narrower than
    ``rtol``·|x|, or whose chunk holds no candidate, has no root, and the scan goes on from its
    right end. One compiled copy of
    f and f' (the lanes of :func:`_scan_for_roots` are a second one): the critical-voltage search.

    Returns a scalar :class:`Roots`: CONVERGED, NO_ROOT, NOT_FINITE (a non-finite value below the
    root or a search range that is not finite and > 0) or MAX_ITER.
    """
    fvals = jax.vmap(lambda x: value_and_slope(fun, x))
    head = _head(step)
    lattice = jnp.arange(1, CHUNK + 1, dtype=jnp.float64)
    offsets = GEOMETRIC_RATIO ** -jnp.arange(CHUNK // 2, dtype=jnp.float64)

    def points(a, b, fa, fb, dfa, dfb, kind, chunk):
        grid = _chunk(jnp.where(chunk == 0, step, a) + step * lattice, head, chunk, end)
        guess = jnp.where(kind == 1, hermite_root(a, b, fa, fb, dfa, dfb),
                          hermite_extremum(a, b, fa, fb, dfa, dfb))
        guess = jnp.where(jnp.isfinite(guess), guess, 0.5 * (a + b))
        width = (b - a) * offsets
        zoom = jnp.clip(jnp.concatenate([guess - width, (guess + width)[::-1]]), a, b)
        return jnp.where(kind == 0, grid, zoom)

    def one_round(c):
        (a, b, fa, fb, dfa, dfb, kind, chunk), rounds = c[0], c[1]
        x = points(a, b, fa, fb, dfa, dfb, kind, chunk)
        f, df = fvals(x)
        start = (kind == 0) & (chunk == 0)  # the first interval [0, 0] is empty
        xa, f_a, df_a, kinds, finite = _intervals(
            *(jnp.where(start, v[0], v0) for v, v0 in ((x, a), (f, fa), (df, dfa))), x, f, df)
        found = jnp.any(kinds > 0)
        k = jnp.where(found, jnp.argmax(kinds > 0), CHUNK - 1)
        blocked = jnp.any(~finite & (jnp.arange(CHUNK) <= k))
        lo, hi, f_lo, df_lo = xa[k], x[k], f_a[k], df_a[k]
        narrow = hi - lo <= rtol * jnp.maximum(jnp.abs(lo), jnp.abs(hi))
        # a sign change whose Hermite cubic is f to rounding: ≪ Δ wide, slopes nearly equal
        linear = (hi - lo <= HERMITE_FINAL * step) & (
            jnp.abs(df[k] - df_lo) <= HERMITE_FINAL_SLOPES * jnp.minimum(jnp.abs(df[k]), jnp.abs(df_lo)))
        converged = found & (kinds[k] == 1) & (narrow | linear)
        zoom = found & ~(narrow | linear)
        # else scan on from x_k: the right end of a hidden pair without roots, or the last point
        window = (jnp.where(zoom, lo, hi), hi, jnp.where(zoom, f_lo, f[k]), f[k],
                  jnp.where(zoom, df_lo, df[k]), df[k], jnp.where(zoom, kinds[k], 0),
                  chunk + (kind == 0))
        root = hermite_root(lo, hi, f_lo, f[k], df_lo, df[k])
        root = jnp.where(jnp.isfinite(root), root, jnp.where(jnp.abs(f_lo) <= jnp.abs(f[k]), lo, hi))
        status = jnp.where(blocked, Status.NOT_FINITE, jnp.where(converged, Status.CONVERGED,
                                                                  Status.NO_ROOT))
        done = blocked | converged | (~zoom & (hi >= end))
        return window, rounds + 1, root, status, done

    zero = jnp.zeros_like(step)
    bad = ~(jnp.isfinite(step) & jnp.isfinite(end) & (step > 0))
    init = ((zero,) * 6 + (0, 0), 0, jnp.full_like(step, jnp.nan),
            jnp.where(bad, Status.NOT_FINITE, Status.MAX_ITER), bad)
    _, _, root, status, _ = jax.lax.while_loop(lambda c: ~c[4] & (c[1] < max_rounds), one_round,
                                               init)
    return Roots(jnp.where(status == Status.CONVERGED, root, jnp.nan), status.astype(jnp.int32))


def _residual(x, tube, alpha, fluid, m, n_layers, order, unknown, family=LONGITUDINAL,
              method="taylor"):
    """The characteristic function as a function of the unknown x and of every parameter:
    unknown = "omega": f(Ω = x); "voltage": f(Ω = 0; V̂ = x), fluid-free off the axisymmetric
    family (κ ∝ Ω² vanishes there, docs/theory/order_m.md §6). ``family`` static, the order ``m`` a parameter.
    ``method="adaptive"`` for the solvers (same values, forward mode only), the default for
    derivatives of any order."""
    if unknown == "voltage":
        wall = discretize(tube.replace(voltage=x), n_layers)
        return characteristic.value(family, wall, jnp.zeros_like(x), alpha,
                                    None if family.carries_m else fluid, order, m, Unknown.OMEGA,
                                    method)
    wall = discretize(tube, n_layers)
    growth = unknown == "growth" and family.carries_m  # f at Ω = i s: Ω² = −s²
    return characteristic.value(family, wall, x, alpha, fluid, order, m,
                                Unknown.GROWTH if growth else Unknown.OMEGA, method)


class Residual(NamedTuple):
    """The characteristic function as residual(x, params) of :func:`jaxdea.numerics.scalar.attach_implicit`:
    :func:`_residual` with params = (tube, α̂, fluid, m); compared by value, so the tangent
    program of each (N, order, unknown, family) compiles once."""

    n_layers: object
    order: object
    unknown: str
    family: str

    def __call__(self, x, params):
        return _residual(x, *params, self.n_layers, self.order, self.unknown, self.family)


def one_point_at_a_time(solve, *args, along=None, vectorised=False):
    """``solve(*args)`` (a solver of one case, values only), whose ``jax.vmap`` on the CPU solves the
    points of the batch one after another (``lax.map``, like :func:`jaxdea.sweep`) instead of
    vectorising its while loops, or solves the whole batch with an engine of ``along``.

    A vectorised root search runs every point of the batch for as many chunks and iterations as
    the slowest one needs: over 200 α̂ the vectorised scan took 1.8–2.7 times as long as the same
    points one by one, and the critical voltages 1.6 times (benchmarks/vmap_idiom.py). The Newton
    of :func:`frequency` stays vectorised (``vectorised``: its points take alike few iterations,
    and the vectorised batch was twice as fast as the points one by one). A batch of points is mapped, the
    arguments that are not batched held fixed; nested vmaps map again (the body holds the same
    function). On other backends, whose vector units a batch fills, the batch is vectorised
    (``jax.vmap`` of ``solve``), as the sweep does there. ``jax.custom_batching.custom_vmap`` has
    no reverse mode: it holds the values only, inside the implicit derivatives' ``custom_jvp``
    (:func:`attach_derivatives`). Concrete arguments call ``solve`` itself (its cached program).

    ``along(in_batched)`` (optional, :func:`along_alpha`): a solver of the whole batch for the
    argument pattern ``in_batched`` (a pytree of bools per argument), or None where the batch is
    mapped; its result must be that of the points solved alone. An outer vmap maps it, batch by
    batch. ``vectorised``: a batch that ``along`` does not take is vectorised (``jax.vmap`` of
    ``solve``) on every backend, not mapped (:func:`frequency`'s Newton)."""
    if not any(isinstance(leaf, jax.core.Tracer) for leaf in jax.tree_util.tree_leaves(args)):
        return solve(*args)
    return _mapped_over_batches(solve, along, vectorised)(*args)


def _mapped_over_batches(solve, along=None, vectorised=False):
    """``custom_vmap`` of ``solve`` whose rule maps it over the batch (:func:`one_point_at_a_time`),
    or hands the batch to ``along``'s engine, or vectorises it (``vectorised``)."""
    mapped = jax.custom_batching.custom_vmap(lambda *args: solve(*args))

    @mapped.def_vmap
    def rule(axis_size, in_batched, *args):
        engine = None
        if jax.default_backend() == "cpu" and along is not None:
            engine = along(list(in_batched))
        if engine is not None:
            out = _mapped_over_batches(engine)(*args)
        elif vectorised or jax.default_backend() != "cpu":
            axes = jax.tree_util.tree_map(lambda b: 0 if b else None, list(in_batched))
            out = jax.vmap(solve, in_axes=tuple(axes))(*args)
        else:
            leaves, tree = jax.tree_util.tree_flatten(list(args))
            flags = jax.tree_util.tree_leaves(list(in_batched))

            def point(batched):
                it = iter(batched)
                return jax.tree_util.tree_unflatten(
                    tree, [next(it) if flag else leaf for leaf, flag in zip(leaves, flags, strict=True)])

            batch = [leaf for leaf, flag in zip(leaves, flags, strict=True) if flag]
            if axis_size and not any(isinstance(leaf, jax.core.Tracer) for leaf in leaves):
                # an eager vmap (concrete batch): each point through its own cached program. A
                # lax.map here is traced anew at every call (its body is a new closure), so every
                # call compiled a scan and kept its executable: 0.2-0.3 s a call, and after ~50
                # calls the process ran out of memory maps and LLVM aborted it (the slow fuzz)
                outs = [solve(*point([b[i] for b in batch])) for i in range(axis_size)]
                out = jax.tree_util.tree_map(lambda *xs: jnp.stack(xs), *outs)
            else:
                out = jax.lax.map(lambda batched: mapped(*point(batched)), batch)
        return out, jax.tree_util.tree_map(lambda _: True, out)

    return mapped


BATCH_ENGINES = {}
"""Solvers of a whole batch of α̂ with every other argument shared, by the name of the solver whose
points they solve (``"frequencies"``, ``"critical_voltage"``): ``engine(*args, **static)`` of that
solver's arguments, α̂ of shape (M,). :mod:`jaxdea.solve.curves` holds the continuation along α̂ and
registers them (it imports this module, so this module cannot import it); :func:`along_alpha`
looks them up when a batch is traced."""


def along_alpha(name, batchable=(1,), **static):
    """The ``along`` of :func:`one_point_at_a_time` for the solver ``name``: its engine of
    :data:`BATCH_ENGINES` (with the keywords ``static``) where the batched arguments are among the
    positions ``batchable`` (α̂, the second argument, by default; α̂ and the guess for
    :func:`frequency`), the tube, fluid and m shared; None (map the points) otherwise."""
    def along(in_batched):
        batched = {k for k, flags in enumerate(in_batched) if any(jax.tree_util.tree_leaves(flags))}
        if name not in BATCH_ENGINES or not batched <= set(batchable):
            return None
        return functools.partial(BATCH_ENGINES[name], **static)

    return along


def attach_derivatives(roots: Roots, params, n_layers, order, unknown="omega",
                      family=LONGITUDINAL) -> Roots:
    """``roots`` with implicit derivatives with respect to ``params`` = (tube, α̂, fluid[, m])."""
    if not traced((roots.omega, params)):  # concrete inputs carry no tangents: values as they are
        return Roots(roots.omega, roots.status)
    if len(params) == 3:
        params = (*params, 0.0)
    omega = with_implicit_derivatives(Residual(n_layers, order, unknown, family), roots.omega, params)
    return Roots(omega, roots.status)


def _problem(tube, alpha, fluid, n_layers, order, m=0.0, family=LONGITUDINAL, decoupled=False):
    """(wall, Ω ↦ (f, s)) for the Newton lanes of one case (``with_slope``): f the characteristic
    function of :func:`jaxdea.physics.characteristic.problem_function` (the adaptive exponential), s
    its forward-mode slope f', or f' + f ℓ' where the log-scale ℓ of F = f e^ℓ varies fast over the
    Newton step on f (:func:`jaxdea.numerics.scalar.newton_slope`: the step on F, continuous
    through the roots where f turns sign in a near-jump). f and f' are those of ``problem_function``
    bit for bit (:func:`jaxdea.physics.characteristic.value_and_scale` is its arithmetic plus ℓ);
    ``decoupled`` (static): on the 4×4 path of a wall without voltage (equal to rounding)."""
    wall = discretize(tube, n_layers)
    family = Family(family)
    ok = family.admissible(m, fluid)
    m_safe = family.safe_m(m, ok) if family.carries_m else 0

    def value_and_newton_slope(om):
        (f, log_scale), (df, dlog_scale) = value_and_slope(
            lambda x: characteristic.value_and_scale(family, wall, x, alpha, fluid, order, m_safe,
                                                     decoupled=decoupled),
            om)
        del log_scale
        if family.carries_m:
            f, df = jnp.where(ok, f, jnp.nan), jnp.where(ok, df, jnp.nan)
        return f, newton_slope(f, df, dlog_scale)

    return wall, value_and_newton_slope


def invalid_where(ok, roots: Roots) -> Roots:
    """NaN with status INVALID where ``ok`` is False."""
    return Roots(jnp.where(ok, roots.omega, jnp.nan),
                 jnp.where(ok, roots.status, Status.INVALID).astype(jnp.int32))


def inaccurate_where(short, roots: Roots) -> Roots:
    """INACCURATE where ``short`` (:func:`jaxdea.physics.transfer.checked_laminate`: the default
    discretisation has fewer sublayers than its rule asks for at the point) and the root converged;
    the values are kept. ``short`` None: ``roots`` as they are."""
    if short is None:
        return roots
    status = jnp.asarray(roots.status)
    short = jnp.reshape(short, jnp.shape(short) + (1,) * (status.ndim - jnp.ndim(short)))
    return Roots(roots.omega, jnp.where(short & (status == Status.CONVERGED), Status.INACCURATE,
                                        status).astype(jnp.int32))


def scan_roots(wall: Wall, fun, alpha, fluid, omega_max, n_roots: int, m=0.0,
               family=LONGITUDINAL, order=None) -> Roots:
    """The ``n_roots`` lowest roots of ``fun`` in (0, omega_max] (None: :func:`default_omega_max`)
    by the guaranteed scan on ``wall``; INVALID where the search limit is not finite and > 0.

    ``order`` (the paper's coupling only; an int or traced): the Bessel order ν; the grid is uniform in the
    coupling's phase near its poles, which are grid points (:func:`coupling_poles`,
    :func:`pole_steps`)."""
    end = default_omega_max(wall, alpha, n_roots, m) if omega_max is None else as_float(omega_max)
    ok = jnp.isfinite(end) & (end > 0)
    if Family(family) is not Family.TORSIONAL:  # an inviscid fluid leaves torsion alone: no leak
        end = jnp.minimum(end, sound_line(wall, alpha))
    step = jnp.minimum(scan_step(wall, fluid, family), end / CHUNK)
    next_point = cutoff_steps(wall, alpha, fluid, step, family)
    paper = Face.of(fluid).has_poles
    if order is not None and paper:
        next_point = pole_steps(next_point, *coupling_poles(wall, alpha, fluid, order))
    return invalid_where(ok, _scan_for_roots(fun, step, end, n_roots, next_point, continuous=not paper))


def guard_order(tube, alpha, fluid, m, family):
    """:func:`~jaxdea.params.guard` and, off the axisymmetric family, an admissible traced m."""
    ok, tube, alpha, fluid = guard(tube, as_float(alpha), fluid)
    return ok & family.admissible(m, fluid), tube, alpha, fluid


def frequencies_unchecked(tube, alpha, fluid, omega_max, n_roots, n_layers, order, m=0.0,
                          family=LONGITUDINAL, decoupled: bool = False) -> Roots:
    """The ``n_roots`` lowest roots for one case (traceable; ``order`` static, ``m`` traced).
    ``decoupled`` (static, longitudinal): the scan and its Newton steps on the 4×4 mechanical
    propagation of a wall without voltage (:func:`decoupled_choice`; NaN where the wall does not
    decouple), the same roots to rounding."""
    ok, tube, alpha, fluid = guard_order(tube, alpha, fluid, m, family)
    wall = discretize(tube, n_layers)
    fun = scanned_function(wall, alpha, fluid, order, m, family, decoupled=decoupled)
    return invalid_where(ok, scan_roots(wall, fun, alpha, fluid, omega_max, n_roots, m, family,
                                        order))


_solve_frequencies = cached_jit(frequencies_unchecked,
                                static_argnames=("n_roots", "n_layers", "order", "family",
                                                 "decoupled"))


def growth_rates_unchecked(tube, alpha, fluid, s_max, n_roots, n_layers, order, m=0.0,
                           family=ORDER_M) -> Roots:
    """The growth rates s = √(−Ω²) > 0 of one case, largest first (traceable): the roots of
    f(Ω² = −s²) in (0, s_max] by the same guaranteed scan as the frequencies (f is entire in Ω²,
    docs/theory/order_m.md §6), reversed; NaN-padded at the end. ``family``: ``ORDER_M`` (at m = 0 the
    longitudinal modes) or ``TORSIONAL`` (:attr:`~jaxdea.physics.families.Family.in_omega_squared`)."""
    ok, tube, alpha, fluid = guard_order(tube, alpha, fluid, m, family)
    wall = discretize(tube, n_layers)
    of_w = scanned_function(wall, alpha, fluid, order, m, family, "omega_squared")
    fun = Scaled(lambda s: of_w.scaled(-s * s))

    end = default_omega_max(wall, alpha, n_roots, m) if s_max is None else as_float(s_max)
    ok &= jnp.isfinite(end) & (end > 0)
    step = jnp.minimum(scan_step(wall, fluid, ORDER_M), end / CHUNK)
    found = _scan_for_roots(fun, step, end, n_roots)
    largest_first = jnp.argsort(jnp.where(jnp.isnan(found.omega), jnp.inf, -found.omega))
    return invalid_where(ok, Roots(found.omega[largest_first], found.status[largest_first]))


_solve_growth_rates = cached_jit(growth_rates_unchecked,
                                 static_argnames=("n_roots", "n_layers", "order", "family"))


def solve_each(program, problem: Problem, values, m, along=None, vectorised=False, **static):
    """``program(*values, **static)``, solved one point at a time (:func:`one_point_at_a_time`),
    with the order m (traced, detached) and the family appended where the family's programs take
    them (:attr:`~jaxdea.physics.families.Family.carries_m`; the longitudinal programs as before
    order m existed)."""
    family = problem.family
    if not family.carries_m:
        return one_point_at_a_time(functools.partial(program, **static), *values, along=along,
                                   vectorised=vectorised)

    def solve(*args):
        return program(*args[:-1], **static, **family.arguments(args[-1]))

    return one_point_at_a_time(solve, *values, detached(m), along=along, vectorised=vectorised)


def growth_rates(tube: Tube, alpha, fluid: Fluid | None = None, n_roots: int = 3, m=0,
                 torsional: bool = False, s_max=None, n_layers: int | None = None,
                 scheme: str | None = None, outer: Fluid | None = None):
    """Growth rates s = √(−Ω²) of the unstable modes of order m at α̂, largest first, NaN-padded.

    An unstable state has modes with Ω² < 0 (e^{st} growth, s > 0): zeros of the characteristic
    function continued to Ω² = −s² (entire in Ω², docs/theory/order_m.md §6), found by the guaranteed scan of
    :func:`frequencies` in s ∈ (0, s_max] (None: the frequencies' automatic limit). All NaN for a
    state that is stable at (m, α̂). :func:`frequencies` keeps returning the positive real roots
    only: past an instability its lowest root is the second branch, so check ``growth_rates`` (or
    :func:`first_instability`) before reading ``frequencies(...)[0]`` as the fundamental.
    Derivatives are implicit (ds/dθ).

    Args:
        tube, alpha, fluid, n_layers, scheme: as in :func:`frequencies`.
        n_roots: how many of the lowest-|Ω²| unstable modes to look for (static).
        m: circumferential order (int >= 0). torsional: the torsional family at m = 0.
        s_max: upper end of the search in s (None: automatic).

    Examples:
        >>> growth_rates(Tube(voltage=0.1, lambda_i=0.95, lambda_z=1.2), 0.445, m=2)  # ≈ [0.7466, nan, nan]
    """
    tube = with_outer(tube, outer)
    problem = describe(tube, alpha, fluid, n_layers, scheme, m, torsional)
    family = problem.family.in_omega_squared
    n_roots = validate_roots(n_roots)
    if s_max is not None:
        validate_positive("s_max", s_max)
    tube, alpha, fluid, s_max, m = canonical(tube, alpha, fluid, s_max, m)
    layers = laminate(n_layers, scheme, tube, alpha, n_roots, m)
    def solve(tube, alpha, fluid, s_max, m):
        return _solve_growth_rates(tube, alpha, fluid, s_max, n_roots, layers, problem.order, m,
                                   family)

    roots = one_point_at_a_time(solve, *detached((tube, alpha, fluid, s_max, m)))
    return attach_derivatives(roots, (tube, alpha, fluid, m), layers, problem.order, "growth",
                              family).omega


def solve_frequencies(tube: Tube, alpha, fluid: Fluid | None = None, n_roots: int = 3,
                      omega_max=None, n_layers: int | None = None, scheme: str | None = None, m=0,
                      torsional: bool = False, outer: Fluid | None = None) -> Roots:
    """The ``n_roots`` lowest roots in (0, omega_max] with a status per root (module docstring).

    Returns:
        An instance of :class:`Roots` (omega ascending, NaN-padded; status CONVERGED, NO_ROOT,
        NOT_FINITE, SUSPECT where a root's slope sign says that a root below it was not found, or
        INACCURATE: a root of the default discretisation at a point for which its rule asks more
        sublayers than it has, the value kept; :func:`jaxdea.physics.transfer.checked_laminate`: where the
        geometry, α̂ or m are traced, N = 16 serves every point).
    """
    tube = with_outer(tube, outer)
    problem = describe(tube, alpha, fluid, n_layers, scheme, m, torsional)
    order, family = problem.order, problem.family
    n_roots = validate_roots(n_roots)
    if omega_max is not None:
        validate_positive("omega_max", omega_max)
    tube, alpha, fluid, omega_max, m = canonical(tube, alpha, fluid, omega_max, m)
    layers, short = checked_laminate(n_layers, scheme, tube, alpha, n_roots, m)
    values = detached((tube, alpha, fluid, omega_max))
    along = None  # a batch over α̂ alone: continued along α̂ (jaxdea.solve.curves), not the paper's coupling
    if not problem.face.has_poles:
        along = along_alpha("frequencies", n_roots=n_roots, n_layers=layers, order=order,
                            family=family, decoupled=decoupled_choice(tube, family))
    decoupled = without_voltage(tube, family)
    if short is None and n_layers is None and is_graded(layers) and _concrete(values, m):
        layers, roots, short = _verified(layers, *values, n_roots, order, m, family, decoupled)
    else:
        roots = solve_each(_solve_frequencies, problem, values, m, along, n_roots=n_roots,
                           n_layers=layers, order=order, decoupled=decoupled)
    return inaccurate_where(short, attach_derivatives(roots, (tube, alpha, fluid, m), layers, order,
                                                     "omega", family))


def _concrete(*args) -> bool:
    """Whether no leaf of ``args`` is a tracer (a call outside any jit, vmap or grad of them)."""
    return not any(isinstance(x, jax.core.Tracer) for x in jax.tree_util.tree_leaves(args))


VERIFY_ROUNDS = 3
"""Refinements :func:`_verified` tries before it calls a root INACCURATE."""
VERIFY_MARGIN = 2.0
"""A refined N aims at DEFAULT_RTOL / VERIFY_MARGIN (the estimate's own spread)."""


SECANT_STEP = 1e-6
"""Relative step of the secant slope in :func:`newton_steps`."""


def newton_steps(tube, alpha, fluid, omegas, n_layers, order, m=0.0, family=LONGITUDINAL,
                 decoupled: bool = False):
    """−g(Ω)/g'(Ω) at each Ω of ``omegas`` on the laminate ``n_layers``: to first order the
    distance from Ω to that laminate's root (:func:`secant_steps`).

    g = f e^ℓ is the unnormalised determinant that the scan solves (:func:`scanned_function`; here
    :func:`jaxdea.physics.characteristic.value_and_scale`, without the carried slope), not the
    normalised f = det(B Q_N): at the inner-face waves of a wall with large α̂ĥ f turns sign in a
    near-jump (±7.1e-3 on either side of the root near Ω = 61.468 of η = 0.3 at α̂ĥ = 150), so a
    Newton step on f measures the distance to a zero of its continuous part, not to the root (it
    was −0.086 there, whatever N, and the default's root, 2e-11 relative from the converged one,
    was called INACCURATE); g has an ordinary simple root there. ``decoupled`` (static,
    longitudinal): the 4×4 mechanical path of a wall without voltage (:func:`decoupled_choice`;
    the same steps to rounding, 2–3 times cheaper)."""
    ok, tube, alpha, fluid = guard_order(tube, alpha, fluid, m, family)
    return steps_on_wall(discretize(tube, n_layers), ok, alpha, fluid, omegas, order, m, family,
                         decoupled)


def steps_on_wall(wall, ok, alpha, fluid, omegas, order, m=0.0, family=LONGITUDINAL,
                  decoupled: bool = False):
    """:func:`newton_steps` on a discretised ``wall``, for inputs already guarded (``ok``, α̂ and
    ``fluid`` of :func:`guard_order`): NaN where not ``ok``."""
    family = Family(family)
    m = family.safe_m(m, ok) if family.carries_m else 0
    fun = Scaled(lambda om: characteristic.value_and_scale(family, wall, om, alpha, fluid, order, m,
                                                           decoupled=decoupled))
    return jnp.where(ok, secant_steps(fun, omegas), jnp.nan)


def secant_steps(fun: Scaled, omegas):
    """−g(Ω)/g'(Ω) at each finite Ω of ``omegas`` (NaN elsewhere), g = f e^ℓ of ``fun``
    (:class:`Scaled`, ℓ₀ = ℓ(Ω) at each Ω: the step is a ratio of g's) and g' the secant over
    Ω(1 + SECANT_STEP): two values per Ω, no tangent program (the slope's own error, ~1e-6
    relative, is nothing to an error estimate)."""
    finite = jnp.isfinite(omegas)
    omegas = jnp.where(finite, omegas, 1.0)
    shift = SECANT_STEP * omegas
    f, log_scale = jax.vmap(fun.scaled)(jnp.concatenate([omegas, omegas + shift]))
    count = omegas.shape[0]
    value = f[:count]
    moved = Scaled.combine(f[count:], log_scale[count:], log_scale[:count])
    return jnp.where(finite, -value * shift / (moved - value), jnp.nan)


def checked_frequencies_unchecked(tube, alpha, fluid, omega_max, n_roots, n_layers, order, m=0.0,
                                  family=LONGITUDINAL, decoupled: bool = False):
    """(roots, steps): :func:`frequencies_unchecked` on ``n_layers`` (graded sixth-order Magnus)
    and :func:`newton_steps` from its roots on the :func:`companion` wall, in one program (the check
    of :func:`_verified`). The walls are discretised apart: formed together (one evaluation of the
    moduli) the program was 10 % smaller but changed the last bits of the ring and torsional roots
    (XLA fuses the shared moduli otherwise)."""
    roots = frequencies_unchecked(tube, alpha, fluid, omega_max, n_roots, n_layers, order, m, family,
                                  decoupled)
    return roots, newton_steps(tube, alpha, fluid, roots.omega, companion(n_layers), order, m, family,
                               decoupled)


def companion(layers: Layers) -> Layers:
    """The wall whose Newton steps check the roots of the graded sixth-order Magnus wall ``layers``
    (:func:`_shortfall`): N/2 sublayers from N = 16 on, where the roots converge as N⁻⁶ already,
    2N below (a checked start of 6, 8 or 12: N/2 would be far from that range)."""
    count = layers.count // 2 if layers.count >= LAYER_COUNTS[0] else 2 * layers.count
    return Layers(count, layers.scheme, True)


_solve_checked_frequencies = cached_jit(checked_frequencies_unchecked,
                                        static_argnames=("n_roots", "n_layers", "order", "family",
                                                         "decoupled"))


def _shortfall(roots: Roots, steps, layers: Layers):
    """Per root, estimated error / (DEFAULT_RTOL·Ω) of the roots of ``layers``, from the Newton
    steps ``steps`` (:func:`newton_steps`) on its :func:`companion` wall of kN sublayers.

    The graded sixth-order Magnus roots converge as Ω_N = Ω + c N⁻⁶ + … (:mod:`jaxdea.solve.accuracy`),
    so the step Ω_kN − Ω_N = (k⁻⁶ − 1)(Ω_N − Ω) to first order:

    * k = 1/2 (N ≥ 16): error ≈ |step|/63. Where N/2 is not yet asymptotic its error exceeds the
      c N⁻⁶ law, so the estimate errs high: a bound.
    * k = 2 (a checked start below 16): error ≈ |step|·64/63, the error itself up to the fine
      wall's, 1/64 of it, before the asymptotic range too (within 20 % measured at N = 6 and 8,
      tests/test_accuracy_default.py). Not a bound, so it is taken ×VERIFY_MARGIN.

    A step that is not finite gives ratio ∞; a root that did not converge, 0."""
    omega, status, steps = np.asarray(roots.omega), np.asarray(roots.status), np.asarray(steps)
    k = companion(layers).count / layers.count
    error = np.abs(steps) / abs(k ** -scheme_order(AUTO_SCHEME) - 1.0) * (VERIFY_MARGIN if k > 1 else 1.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        ratio = np.where(np.isfinite(steps), error / (DEFAULT_RTOL * np.abs(omega)), np.inf)
    return np.where(status == Status.CONVERGED, ratio, 0.0)


def refined_layers(layers: Layers, ratio):
    """The finer default discretisation that the estimated errors ``ratio`` (:func:`_shortfall`)
    ask for: N' ≥ N (VERIFY_MARGIN·max ratio)^(1/6) from :data:`CHECKED_COUNTS` (2N where a root
    was lost on the companion wall), or None where every root meets DEFAULT_RTOL or N is at its
    cap. From N = 16 on the counts are those of :data:`LAYER_COUNTS`."""
    worst = float(np.max(ratio, initial=0.0))
    if worst <= 1.0 or layers.count >= LAYER_COUNTS[-1]:
        return None
    need = 2.0 * layers.count if np.isinf(worst) else layers.count * (VERIFY_MARGIN * worst) ** (1 / 6)
    return Layers(counted(max(need, layers.count + 1), CHECKED_COUNTS), AUTO_SCHEME, True)


def _verified(layers, tube, alpha, fluid, omega_max, n_roots, order, m, family, decoupled=False):
    """(layers, roots, short): the roots of the default discretisation, checked as they are solved.

    The rule of :func:`jaxdea.physics.transfer.required_layers` sees the wall's lengths, α̂, K and m but
    not the state: a thick inflated wall (η = 0.4, λ_i = 1.3, G = 10) needs N = 38 for its 8th root
    where the rule gives 24 (1.2e-7 off; benchmarks/layer_errors_results.md). So a concrete call
    estimates the error of its roots (:func:`_shortfall`) and, where it exceeds DEFAULT_RTOL,
    solves again on N' ≥ N (VERIFY_MARGIN·ratio)^(1/6) (from :data:`LAYER_COUNTS`), at most
    VERIFY_ROUNDS times; roots still short are INACCURATE (``short``). Where the rule sufficed, the
    roots are those of N. ``decoupled``: the 4×4 propagation of a wall without voltage
    (:func:`frequencies_unchecked`)."""
    order_args = family.arguments(m)

    def solve(layers):
        return _solve_checked_frequencies(tube, alpha, fluid, omega_max, n_roots, layers, order,
                                          **order_args, decoupled=decoupled)

    layers, (roots, _), ratio = refined(solve, lambda found, layers: _shortfall(*found, layers),
                                        layers)
    short = ratio > 1.0
    return layers, roots, (short if short.any() else None)


def refined(solve, ratio_of, layers, result=None):
    """(layers, result, ratio): ``result = solve(layers)`` (given: not solved again) and its
    estimated error ratios ``ratio_of(result, layers)`` (:func:`_shortfall`), solved again on the
    finer :func:`refined_layers` while some exceed 1, at most VERIFY_ROUNDS times: the refinement
    of every checked default discretisation (:func:`_verified`,
    :func:`jaxdea.solve.curves._checked_curve`, the complex curves)."""
    result = solve(layers) if result is None else result
    ratio = ratio_of(result, layers)
    for _ in range(VERIFY_ROUNDS):
        finer = refined_layers(layers, ratio)
        if finer is None:
            break
        layers = finer
        result = solve(layers)
        ratio = ratio_of(result, layers)
    return layers, result, ratio


def decoupled_choice(tube, family):
    """The propagation of a continuation along α̂ (:func:`jaxdea.solve.curves.curve_unchecked`): the 4×4
    one (True) for a concrete V̂ = 0 of the axisymmetric family, the 6×6 one (False) for another or
    a traced V̂, each point's choice (None) off that family."""
    if family.carries_m:
        return None
    voltage = tube.voltage
    return False if isinstance(voltage, jax.core.Tracer) else bool(np.all(np.asarray(voltage) == 0))


def without_voltage(tube, family) -> bool:
    """The static ``decoupled`` flag of the single-point solvers (:func:`frequencies_unchecked`,
    :func:`follow_roots`, the sweeps' and the counter's programs): True for a concrete V̂ = 0 of the
    axisymmetric family (:func:`decoupled_choice`), whose roots they solve on the 4×4 propagation."""
    return decoupled_choice(tube, family) is True


@cached_jit(static_argnames=("n_layers", "order", "family", "decoupled"))
def follow_roots(tube, alpha, fluid, guesses, n_layers, order, m=0.0, family=LONGITUDINAL,
                 decoupled=False):
    """Safeguarded Newton from each guess on the laminate of ``n_layers`` sublayers (one lane
    per root, steps capped at a quarter of the scan step, as in :func:`jaxdea.solve_frequency`).
    ``family`` (static) and ``m`` (traced): the mode family, as in :func:`jaxdea.frequencies`;
    ``decoupled`` (static): on the 4×4 propagation of a wall without voltage (:func:`_problem`)."""
    ok, tube, alpha, fluid = guard_order(tube, alpha, fluid, m, family)
    wall, fun = _problem(tube, alpha, fluid, n_layers, order, m, family, decoupled)
    finite = jnp.isfinite(guesses) & ok
    start = jnp.where(finite, guesses, 1.0)
    nan = jnp.full_like(start, jnp.nan)
    cap = jnp.full_like(start, 0.25 * scan_step(wall, fluid, family))
    lanes = start_lanes(start, start, nan, nan, nan, nan, jnp.where(finite, 3, 0), max_step=cap,
                        pairs=False)
    roots, _, status = run_lanes(fun, lanes, with_slope=True)
    status = jnp.where(finite, status, Status.NO_ROOT)
    return jnp.where(status == Status.CONVERGED, roots, jnp.nan), status


def frequencies(tube: Tube, alpha, fluid: Fluid | None = None, n_roots: int = 3,
                omega_max=None, n_layers: int | None = None, scheme: str | None = None, m=0,
                torsional: bool = False, outer: Fluid | None = None):
    """The ``n_roots`` lowest frequencies Ω in (0, omega_max], ascending, NaN-padded.

    Every root in the range is found, including close pairs and roots near Ω = 0 (scan with Hermite
    classification, see :mod:`jaxdea.solve.roots`); derivatives are implicit. ``omega_max=None`` searches up
    to (n_roots + 1) thickness-mode spacings above α̂-scaled wave speeds. Use
    :func:`solve_frequencies` for the status of each root.

    Args:
        tube: the :class:`~jaxdea.Tube`.
        alpha: α̂ = α R_i >= 1e-12 with α̂ĥ <= 150 (ĥ = h/R_i, :data:`jaxdea.params.ALPHA_THICKNESS_MAX`;
            see :func:`jaxdea.axial_wavenumber`).
        fluid: a :class:`~jaxdea.Fluid` or None (empty tube).
        outer: a surrounding :class:`~jaxdea.Fluid` (unbounded, ``"acoustic"``) or None: the tube's own
            ``tube.outer`` (None: vacuum). Subsonic modes carry its added mass
            (docs/theory/real_tubes.md §6).
        n_roots: number of roots (static).
        omega_max: upper end of the search (None: automatic).
        n_layers: sublayers N (static), or None (default): the accurate discretisation, graded
            sixth-order Magnus sublayers with N chosen from the case for roots to ≤ 1e-8 relative
            (:func:`jaxdea.physics.transfer.laminate`; N = 16 for the paper's tube and wherever the
            geometry or α̂ are traced, more for thick walls at large α̂ĥ or a face near Gent
            locking).
        scheme: None (default: the midpoint laminate with an ``n_layers``, the graded
            ``"magnus6"`` above without), ``"midpoint"`` (the paper's laminate, error O(N⁻²);
            ``scheme="midpoint", n_layers=30`` reproduces the paper), ``"magnus4"`` or
            ``"magnus6"`` (equal sublayers, errors O(N⁻⁴), O(N⁻⁶); static, see
            :mod:`jaxdea.physics.transfer`).
        m: circumferential order (int >= 0; docs/theory/order_m.md): 0 the axisymmetric longitudinal modes,
            1 bending, 2, 3, … ovalisation and higher ring modes. May be traced (one program
            for every m >= 1 or a traced m).
        torsional: at m = 0, the torsional family (u_θ alone) instead of the longitudinal one.

    Only positive real roots are returned: an unstable state (Ω² < 0 at this (m, α̂), e.g. m = 2
    buckling under voltage) has its lowest mode in :func:`growth_rates` instead, and ``[0]`` is
    then the second branch. :func:`first_instability` gives the voltage where that begins.

    Examples:
        >>> frequencies(Tube(eta=0.85), 0.445, n_roots=3)  # ≈ [0.745, 1.910, 17.844]
        >>> frequencies(Tube(eta=0.85), 0.445, n_layers=6, scheme="magnus6")  # the wall to ≈ 1e-9
        >>> frequencies(Tube(eta=0.85), 0.445, m=2)  # ovalisation modes
    """
    tube = with_outer(tube, outer)
    return solve_frequencies(tube, alpha, fluid, n_roots, omega_max, n_layers, scheme, m,
                             torsional).omega


def _newton_from_guess(fun, guess, max_step):
    """Newton from ``guess`` (``fun``: Ω ↦ (f, the slope to step with), :func:`_problem`) with
    steps capped at ``max_step``; once two iterates bracket a sign change, safeguarded bracketed
    Newton finishes (a FREE lane of :func:`run_lanes`)."""
    one = lambda v: jnp.reshape(v, (1,))  # noqa: E731
    nan = jnp.full((1,), jnp.nan)
    lanes = start_lanes(one(guess), one(guess), nan, nan, nan, nan, jnp.array([3]),
                        max_step=one(max_step), pairs=False)
    roots, _, status = run_lanes(fun, lanes, with_slope=True)
    return roots[0], status[0]


@cached_jit(static_argnames=("n_layers", "order", "family", "decoupled"))
def _solve_frequency(tube, alpha, guess, fluid, n_layers, order, m=0.0, family=LONGITUDINAL,
                     decoupled=False):
    ok, tube, alpha, fluid = guard_order(tube, alpha, fluid, m, family)
    guess = as_float(guess)
    ok &= jnp.isfinite(guess) & (guess > 0)
    wall, fun = _problem(tube, alpha, fluid, n_layers, order, m, family, decoupled)
    guess = jnp.where(ok, guess, 1.0)
    return invalid_where(ok, Roots(*_newton_from_guess(fun, guess,
                                                       4.0 * scan_step(wall, fluid, family))))


def solve_frequency(tube: Tube, alpha, guess, fluid: Fluid | None = None,
                    n_layers: int | None = None, scheme: str | None = None, m=0,
                    torsional: bool = False, outer: Fluid | None = None) -> Roots:
    """The root reached by safeguarded Newton from ``guess``, with its status (scalar Roots;
    INACCURATE as in :func:`solve_frequencies`)."""
    tube = with_outer(tube, outer)
    problem = describe(tube, alpha, fluid, n_layers, scheme, m, torsional)
    order, family = problem.order, problem.family
    validate_positive("guess", guess)
    tube, alpha, guess, fluid, m = canonical(tube, alpha, guess, fluid, m)
    layers, short = checked_laminate(n_layers, scheme, tube, alpha, m=m)
    values = detached((tube, alpha, guess, fluid))
    along = None  # a batch over α̂ and the guess alone: the curves' lanes (jaxdea.solve.curves), any other
    if not problem.face.has_poles:  # vectorised as before
        along = along_alpha("frequency", (1, 2), n_layers=layers, order=order, family=family,
                            decoupled=decoupled_choice(tube, family))
    roots = solve_each(_solve_frequency, problem, values, m, along, True, n_layers=layers,
                       order=order, decoupled=without_voltage(tube, family))
    return inaccurate_where(short, attach_derivatives(roots, (tube, alpha, fluid, m), layers, order,
                                                     "omega", family))


def frequency(tube: Tube, alpha, guess, fluid: Fluid | None = None, n_layers: int | None = None,
              scheme: str | None = None, m=0, torsional: bool = False, outer: Fluid | None = None):
    """The root Ω reached by safeguarded Newton from ``guess``, with implicit derivatives.

    ``jax.grad``/``jax.jacfwd`` with respect to any Tube/Fluid leaf, α̂ and the ``h_over_Ri`` of
    :func:`jaxdea.with_thickness_ratio` give dΩ/dθ = −(∂f/∂θ)/(∂f/∂Ω) (exact for the discretisation).
    NaN if Newton fails (see :func:`solve_frequency` for the status). ``scheme`` as in
    :func:`frequencies`.

    Examples:
        >>> jax.grad(lambda v: frequency(Tube(voltage=v), 0.445, 0.7))(0.1)
    """
    tube = with_outer(tube, outer)
    return solve_frequency(tube, alpha, guess, fluid, n_layers, scheme, m, torsional).omega


def group_velocity(tube: Tube, alpha, omega, fluid: Fluid | None = None, n_layers: int | None = None,
                   scheme: str | None = None, m=0, torsional: bool = False, outer: Fluid | None = None):
    """dΩ/dα̂ on the branch through the root ``omega``: −(∂f/∂α̂)/(∂f/∂Ω) (implicit function theorem).

    ``omega`` must be a root (from :func:`frequency` or :func:`frequencies`), to the relative Newton
    distance |f/f_Ω|/|Ω| ≤ ``ROOT_RTOL`` = 1e-4 of the same discretisation: a concrete non-root
    raises a ValueError (a traced one gives NaN), since −f_α̂/f_Ω off a root is a plausible number
    that means nothing. The formula is exact for the discretisation. When ``omega`` carries its
    implicit derivatives, as those functions' roots do, ``jax.grad`` of the group velocity with
    respect to any leaf is exact too. The paper's coupling with ``bessel_order=None`` needs an
    integer mode α̂ and then differentiates at fixed order ν.

    Args:
        tube: the :class:`~jaxdea.Tube`.
        alpha: α̂ = α R_i >= ALPHA_MIN = 1e-12.
        omega: a root Ω > 0 at that α̂, finite (at Ω = 0 the even f has ∂f/∂Ω = 0), to the relative
            Newton distance ``ROOT_RTOL``; a concrete non-root raises ValueError, a traced one gives
            NaN.
        fluid: a :class:`~jaxdea.Fluid`, or None for the empty tube.
        outer: a surrounding :class:`~jaxdea.Fluid` (unbounded, ``"acoustic"``) or None: the tube's own
            ``tube.outer`` (None: vacuum). Subsonic modes carry its added mass
            (docs/theory/real_tubes.md §6).
        n_layers: number of sublayers N (static; use the value the root was found with).
        scheme: the propagation scheme the root was found with (:func:`frequencies`).
        m, torsional: the order the root was found with (:func:`frequencies`).

    Raises:
        ValueError: for invalid concrete inputs, naming the parameter, and for a concrete ``omega``
            that is not a root (farther than ``ROOT_RTOL`` by one Newton step). Traced invalid
            inputs and traced non-roots give NaN.

    Examples:
        >>> t = Tube(voltage=0.1, lambda_i=0.9, lambda_z=1.2)
        >>> group_velocity(t, 0.445, frequencies(t, 0.445)[0])  # ≈ 1.661
        >>> group_velocity(t, 0.445, 0.7)  # ValueError: omega = 0.7 is not a root (0.1 away)
    """
    tube = with_outer(tube, outer)
    problem = describe(tube, alpha, fluid, n_layers, scheme, m, torsional)
    validate_range("omega", omega, "a finite real number > 0 (a root of the characteristic function)",
                   lambda v: v > 0)
    tube, alpha, omega, fluid, m = canonical(tube, alpha, omega, fluid, m)
    layers = laminate(n_layers, scheme, tube, alpha, m=m)
    velocity, distance = _group_velocity(tube, alpha, omega, fluid, layers, problem.order,
                                         **problem.arguments(m))
    refuse_non_root(omega, distance)
    return velocity


@cached_jit(static_argnames=("n_layers", "order", "family"))
def _group_velocity(tube, alpha, omega, fluid, n_layers, order, m=0.0, family=LONGITUDINAL):
    """(−f_α̂/f_Ω, the relative Newton distance |f/f_Ω|/|Ω| of ``omega``): NaN velocity for invalid
    inputs and where the distance exceeds ROOT_RTOL (``omega`` no root). f, f_Ω and f_α̂ come from
    one reverse pass."""
    ok, tube, alpha, fluid = guard_order(tube, alpha, fluid, m, family)
    omega = as_float(omega)
    ok &= jnp.isfinite(omega) & (omega > 0)
    omega = jnp.where(ok, omega, 1.0)
    if not family.carries_m:
        wall = discretize(tube, n_layers)
        f = lambda om, al: characteristic.value(family, wall, om, al, fluid, order)  # noqa: E731
    else:
        f = lambda om, al: _residual(om, tube, al, fluid, m, n_layers, order, "omega",  # noqa: E731
                                     family)
    value, (f_omega, f_alpha) = jax.value_and_grad(f, argnums=(0, 1))(omega, alpha)
    distance = jnp.where(ok, newton_distance(*jax.lax.stop_gradient((value, f_omega, omega))),
                         jnp.nan)
    return jnp.where(ok & (distance <= ROOT_RTOL), -f_alpha / f_omega, jnp.nan), distance


def solve_critical_voltage(tube: Tube, alpha, fluid: Fluid | None = None,
                           n_layers: int | None = None, scheme: str | None = None, m=0,
                           torsional: bool = False, outer: Fluid | None = None):
    """(V̂_cr, status): the smallest V̂ > 0 with f(Ω = 0; V̂) = 0 (see :func:`critical_voltage`;
    INACCURATE as in :func:`solve_frequencies`)."""
    tube = with_outer(tube, outer)
    problem = describe(tube, alpha, fluid, n_layers, scheme, m, torsional)
    order, family = problem.order, problem.family
    tube, alpha, fluid, m = canonical(tube, alpha, fluid, m)
    layers, short = checked_laminate(n_layers, scheme, tube, alpha, m=m, at_rest=True)
    values = detached((tube, alpha, fluid))
    # a batch over α̂ alone: continued along α̂ (jaxdea.solve.curves); fluids (which do not change V̂_cr) mapped
    along = along_alpha("critical_voltage", n_layers=layers, family=family) if fluid is None else None
    roots = Roots(*solve_each(_solve_critical_voltage, problem, values, m, along, n_layers=layers,
                              order=order))
    return inaccurate_where(short, attach_derivatives(roots, (tube, alpha, fluid, m), layers, order,
                                                     "voltage", family))


def critical_function(tube, alpha, fluid, n_layers, order, v_end=None, m=0.0, family=LONGITUDINAL,
                      expansion=None):
    """(ok, g, v_end): g(V̂) = f(Ω = 0; V̂), whose first zero in (0, v_end] is the critical voltage
    (traceable; ``v_end`` None: the pull-in limit), and ``ok`` for the case. The wall at each V̂ is
    formed from its expansion in V̂ (``expansion``: already formed for this tube, or None); on a
    Magnus wall the generators are polynomials in V̂, formed here once
    (:func:`critical_voltage_unchecked`)."""
    ok, tube, alpha, fluid = guard_order(tube.replace(voltage=0.0), alpha, fluid, m, family)
    v_end = voltage_limit(tube) if v_end is None else as_float(v_end)

    expansion = voltage_expansion(tube, n_layers) if expansion is None else expansion
    m_safe = jnp.where(ok, as_float(m), 0.0)
    magnus = split_layers(n_layers)[1] != "midpoint"
    if magnus:  # the generators as polynomials in V̂, formed once (the midpoint laminate's are h M)
        radius = jnp.where(jnp.isfinite(v_end) & (v_end > 0), v_end, 1.0)
        generators = voltage_generators(expansion, alpha, m_safe, family, radius)

        # g' carried across the wall, not forward mode through Gram–Schmidt (first call 3.9 → 3.4
        # CPU s, first_instability 23 → 16, measured)
        carried = carried_jvp(lambda v: characteristic.at_rest_value_and_slope(
            family, lambda u: wall_at_voltage(expansion, u),
            lambda u: voltage_exponentials(generators, u), v, alpha, fluid, order, m_safe))

    def g(v):  # f(Ω = 0; V̂ = v), the wall formed from its expansion in V̂ (the same function)
        if magnus:
            return carried(v)
        wall = wall_at_voltage(expansion, v)
        # fluid-free off the axisymmetric family: κ ∝ Ω² vanishes at Ω = 0 (docs/theory/order_m.md §6)
        return characteristic.value(family, wall, jnp.zeros_like(v), alpha,
                                    None if family.carries_m else fluid, order, m_safe,
                                    Unknown.OMEGA, "at_rest")

    return ok, g, v_end


def critical_voltage_unchecked(tube, alpha, fluid, n_layers, order, n_grid=32, v_end=None, m=0.0,
                               family=LONGITUDINAL, expansion=None):
    """(V̂_cr, status) for one case (traceable); see :func:`critical_voltage`.

    :func:`_first_root` over (0, V̂_lim] with step V̂_lim/``n_grid``: the chunked scan with Hermite
    classification, the first candidate refined by zooming with the same chunk of f and f' (after a
    hidden pair that holds no roots it scans on). One compiled copy of f and f' instead of the
    scan's and the lanes' (:func:`_scan_for_roots`): tracing and compilation 4.9 → 2.7–3.3 s.
    f(Ω = 0; V̂) is a static problem: it has no thickness oscillation in V̂, so one chunk of 32
    points spans the range (n_grid 32, 128 and 512 give the same roots over every m ≤ 8, n ≤ 3 of
    random tubes, ``tests/test_missed_roots.py``); the zooms reach rounding in one to three chunks.
    ``v_end`` (optional) searches (0, v_end] instead of (0, V̂_lim] with the pull-in limit V̂_lim of
    :func:`voltage_limit` (values only: about 0.25 s of the first call's compilation, measured); a
    root above ``v_end`` is reported as NO_ROOT. On a Magnus wall (the default) the sublayer
    generators are formed once, as polynomials in V̂ (:func:`jaxdea.physics.transfer.voltage_generators`,
    on the circle of radius ``v_end``), and each V̂ sums them (one critical voltage of the paper's
    tube 2.1 → 0.8× the time of the paper's laminate; V̂_cr within 1.1e-14 of forming them at each
    V̂, measured; tests/test_core.py). ``expansion``: the wall's expansion in V̂ if already formed
    (:func:`critical_function`).
    """
    ok, g, v_end = critical_function(tube, alpha, fluid, n_layers, order, v_end, m, family,
                                     expansion)
    roots = _first_root(g, v_end / n_grid, v_end)
    empty = (v_end == 0) & (roots.status == Status.NOT_FINITE)  # no range, so no root
    return invalid_where(ok, Roots(roots.omega, jnp.where(empty, Status.NO_ROOT, roots.status)))


_solve_critical_voltage = cached_jit(critical_voltage_unchecked,
                                     static_argnames=("n_layers", "order", "n_grid", "family"))


def critical_voltage(tube: Tube, alpha, fluid: Fluid | None = None, n_layers: int | None = None,
                     scheme: str | None = None, m=0, torsional: bool = False, outer: Fluid | None = None):
    """The smallest V̂ > 0 at which the lowest frequency of order ``m`` at α̂ reaches zero.

    Solves f(Ω = 0; V̂) = 0 in V̂ directly (the tube's ``voltage`` is ignored; λ_i, λ_z fixed): scan of
    (0, V̂_lim] with Hermite classification, then zooming on the first candidate (:func:`_first_root`,
    to rounding); implicit derivatives. V̂_lim is
    the pull-in limit: the largest voltage of the static response of the tube held at its zero-voltage
    pressure difference (:func:`jaxdea.physics.base_state.voltage_limit`). Fluids do not change V̂_cr (their
    terms vanish like Ω²). NaN (status NO_ROOT) if no root below V̂_lim. ``n_layers``,
    ``scheme``, ``m`` and ``torsional`` as in :func:`frequencies`. The tube's first instability
    over every order and axial mode is :func:`first_instability`: for the paper's tube m = 2
    buckles at about a tenth of the axisymmetric (m = 0) value.
    """
    tube = with_outer(tube, outer)
    return solve_critical_voltage(tube, alpha, fluid, n_layers, scheme, m, torsional)[0]


def solve_critical_voltages(tube: Tube, n_max: int, fluid: Fluid | None = None,
                            n_layers: int | None = None, scheme: str | None = None, m=0,
                            outer: Fluid | None = None) -> Roots:
    """(V̂_cr, status) for every axial mode n = 1 … n_max in one compiled call.

    α̂_n = 2nπη/(length_ratio λ_z) (:func:`jaxdea.axial_wavenumber`); each entry as
    :func:`critical_voltage`, with implicit derivatives. A fluid does not change V̂_cr (its terms
    vanish like Ω²), so ``fluid`` is validated and otherwise not used.

    Returns:
        An instance of :class:`Roots` whose ``omega`` field holds V̂_cr, shape (n_max,).
    """
    tube = with_outer(tube, outer)
    problem = describe(tube, NO_ALPHA, fluid, n_layers, scheme, m)
    n_max = validate_max("n_max", n_max, 1)
    layers, short = checked_laminate(n_layers, scheme, canonical(tube),
                                     mode_wavenumber(canonical(tube), n_max), m=canonical(m),
                                     at_rest=True)
    return inaccurate_where(short, _critical_voltages(canonical(tube), n_max, layers,
                                                      **problem.arguments(as_float(m))))


def validate_max(name, value, low):
    if not isinstance(value, (int, np.integer)) or isinstance(value, bool) or value < low:
        raise ValueError(f"{name} must be an integer >= {low}, got {value!r}")
    return int(value)


@cached_jit(static_argnames=("n_max", "n_layers", "family"))
def _critical_voltages(tube, n_max, n_layers, m=0.0, family=LONGITUDINAL):
    alphas = mode_wavenumber(tube, jnp.arange(1, n_max + 1, dtype=jnp.float64))

    def one(alpha):
        values = jax.lax.stop_gradient((tube, alpha))
        roots = Roots(*critical_voltage_unchecked(*values, None, n_layers, 0, m=m, family=family))
        return attach_derivatives(roots, (tube, alpha, None, m), n_layers, 0, "voltage", family)

    return jax.lax.map(one, alphas)


def critical_voltages(tube: Tube, n_max: int, fluid: Fluid | None = None, n_layers: int | None = None,
                      scheme: str | None = None, m=0, outer: Fluid | None = None):
    """V̂_cr of the axial modes n = 1 … n_max at order ``m``, shape (n_max,)
    (see :func:`solve_critical_voltages`)."""
    tube = with_outer(tube, outer)
    return solve_critical_voltages(tube, n_max, fluid, n_layers, scheme, m).omega


@serializable
class Instability(NamedTuple):
    """The first instability of a tube (:func:`first_instability`).

    Attributes:
        voltage: the smallest critical voltage V̂_cr over the orders and axial modes searched
            (NaN where none of them has one below the pull-in limit), with implicit derivatives.
        m: its circumferential order (−1 where none).
        n: its axial mode number (0 where none).
        status: CONVERGED, NO_ROOT where no (m, n) loses stability below the pull-in limit, or
            INACCURATE where the default discretisation is coarser than its rule asks for
            (traced geometry: :func:`solve_frequencies`).
        critical: V̂_cr of every (m, n), shape (m_max + 1, n_max) (values only; NaN: none below
            pull-in; 0: unstable already at V̂ = 0).
    """

    voltage: jax.Array
    m: jax.Array
    n: jax.Array
    status: jax.Array
    critical: jax.Array


def map_orders_and_modes(tube, n_max: int, m_max: int, one):
    """``one(m, α̂_n)`` over every order m = 0 … m_max (traced) and axial mode n = 1 … n_max,
    by ``lax.map``; its outputs reshaped to (m_max + 1, n_max)."""
    m, n = jnp.meshgrid(jnp.arange(m_max + 1.0), jnp.arange(1.0, n_max + 1.0), indexing="ij")
    out = jax.lax.map(lambda args: one(*args), (m.ravel(), mode_wavenumber(tube, n.ravel())))
    return jax.tree_util.tree_map(lambda x: x.reshape(m_max + 1, n_max), out)


@cached_jit(static_argnames=("n_max", "m_max", "n_layers"))
def _instability_grid(tube, n_max, m_max, n_layers):
    """(V̂_cr, status, s₀) of every (m, n), m = 0 … m_max, n = 1 … n_max, shape (m_max + 1, n_max):
    one compiled search over the traced m (the 8×8 path, longitudinal at m = 0, docs/theory/order_m.md §3),
    the pull-in limit formed once. The growth rate s₀ at V̂ = 0 (the guaranteed scan of
    :func:`growth_rates`) marks a mode unstable already at V̂ = 0: its V̂_cr is 0 (a root of
    f(Ω = 0; V̂) above 0 is then where it re-stabilises or another branch crosses)."""
    ok, tube, _, _ = guard(tube.replace(voltage=0.0), 1.0, None)
    v_end = voltage_limit(tube)

    def one(order_m, alpha):
        voltage, status = critical_voltage_unchecked(tube, alpha, None, n_layers, 0, v_end=v_end,
                                                     m=order_m, family=ORDER_M)

        # unstable already at V̂ = 0? (its Ω² may still reach 0 later, from the other side)
        growth = growth_rates_unchecked(tube, alpha, None, None, 1, n_layers, 0, order_m,
                                        ORDER_M).omega[0]
        unstable = jnp.isfinite(growth)
        return (jnp.where(unstable, 0.0, voltage), jnp.where(unstable, Status.CONVERGED, status),
                growth)

    voltage, status, growth = map_orders_and_modes(tube, n_max, m_max, one)
    return (jnp.where(ok, voltage, jnp.nan), jnp.where(ok, status, Status.INVALID),
            jnp.where(ok, growth, jnp.nan))


def first_instability(tube: Tube, n_max: int = 3, m_max: int = 8, fluid: Fluid | None = None,
                      n_layers: int | None = None, scheme: str | None = None) -> Instability:
    """The tube's first instability: the smallest critical voltage over every circumferential
    order 0 ≤ m ≤ m_max and axial mode 1 ≤ n ≤ n_max, and which (m, n) it belongs to.

    Each V̂_cr is :func:`critical_voltage` of order m at α̂_n (:func:`jaxdea.axial_wavenumber`):
    the smallest V̂ at which the lowest Ω² of that (m, n) reaches 0 (λ_i, λ_z held; the tube's
    ``voltage`` is ignored; a mode unstable already at V̂ = 0, e.g. ring buckling of a tube
    squeezed to λ_i = 0.8, has V̂_cr = 0, and the fastest-growing such mode is first, with a
    zero derivative). m = 0 is the axisymmetric family the paper studies; m = 1 is Euler
    column buckling, m ≥ 2 ring (ovalisation) buckling under the pressure that holds λ_i, which
    for the paper's tube sets in about ten times below the axisymmetric value. A fluid does not
    change V̂_cr (its terms vanish like Ω²), so ``fluid`` is only validated. A state with
    ``tube.voltage`` below ``voltage`` is stable in every (m, n) searched; check a given state
    directly with :func:`growth_rates`. ``voltage`` carries implicit derivatives with respect to
    the tube's leaves (those of the (m, n) that is first); vmappable.

    Args:
        tube: the :class:`~jaxdea.Tube`.
        n_max: largest axial mode number (static, >= 1).
        m_max: largest circumferential order (static, >= 0).
        fluid: a :class:`~jaxdea.Fluid` or None (validated only).
        n_layers, scheme: the discretisation (:func:`frequencies`).

    Returns:
        An instance of :class:`Instability` (voltage, m, n, status, critical).

    Examples:
        >>> first = first_instability(Tube(lambda_i=0.9, lambda_z=1.2, eta=0.85), n_max=1)
        >>> float(first.voltage), int(first.m), int(first.n)  # ≈ (0.0293, 2, 1)
    """
    describe(tube, NO_ALPHA, fluid, n_layers, scheme)
    n_max = validate_max("n_max", n_max, 1)
    m_max = validate_max("m_max", m_max, 0)
    tube = canonical(tube)
    layers, short = checked_laminate(n_layers, scheme, tube, mode_wavenumber(tube, n_max), m=m_max,
                                     at_rest=True)
    voltage, status, growth = _instability_grid(jax.lax.stop_gradient(tube), n_max, m_max, layers)
    first, found, at_zero, m, n = first_of_grid(voltage, growth)
    alpha = mode_wavenumber(tube, jnp.maximum(n, 1).astype(jnp.float64))
    root = Roots(jnp.where(found & ~at_zero, voltage.ravel()[first], jnp.nan),
                 jnp.where(found, Status.CONVERGED, Status.NO_ROOT).astype(jnp.int32))
    root = attach_derivatives(root, (tube, alpha, None, jnp.maximum(m, 0).astype(jnp.float64)),
                             layers, 0, "voltage", ORDER_M)  # NaN (at V̂ = 0): a zero tangent
    root = inaccurate_where(short, root)  # N from the worst (m_max, n_max)
    return Instability(jnp.where(at_zero, 0.0, root.omega), m, n, root.status, voltage)


def first_of_grid(voltage, growth):
    """(flat index, found, at_zero, m, n) of the first instability of a (m_max + 1, n_max) grid of
    V̂_cr (0: unstable at V̂ = 0) and growth rates s₀ at V̂ = 0: the modes unstable at V̂ = 0 come
    first, fastest first (key −s₀ < 0), then the smallest critical voltage."""
    n_max = voltage.shape[1]
    key = jnp.where(voltage == 0.0, -growth, jnp.where(jnp.isnan(voltage), jnp.inf, voltage)).ravel()
    first = jnp.argmin(key)
    found = jnp.isfinite(key[first])
    at_zero = found & (key[first] < 0)
    return (first, found, at_zero, jnp.where(found, first // n_max, -1),
            jnp.where(found, first % n_max + 1, 0))


def phase_velocity(omega, alpha):
    """Phase velocity Ω/α̂ (in units of c_s): c_p/c_s = ω/(α c_s).

    Elementwise (arrays broadcast together). A NaN Ω (a NaN-padded root) gives NaN.

    Args:
        omega: frequencies Ω, real, NaN or finite.
        alpha: axial wavenumbers α̂ > 0, finite.

    Raises:
        ValueError: naming the parameter for a concrete Ω that is ±inf or no real number, or a
            concrete α̂ that is not a finite real number > 0. Traced invalid values give NaN.
    """
    require_x64()
    w = real_value("omega", omega, scalar=False)
    if w is not None and np.any(np.isinf(w)):
        raise ValueError(f"omega must be a real number, finite or NaN (a NaN-padded root), got "
                         f"{np.ravel(w[np.isinf(w)] if w.ndim else w)[0]!r}")
    a = validate_range("alpha", alpha, "a finite real number > 0 (the axial wavenumber)",
                       lambda v: v > 0, scalar=False)
    if w is not None and a is not None:
        validate_broadcast("phase_velocity argument", dict(omega=w, alpha=a))
    omega, alpha = as_float(omega), as_float(alpha)
    ok = jnp.isfinite(alpha) & (alpha > 0) & ~jnp.isinf(omega)
    return jnp.where(ok, omega / jnp.where(ok, alpha, 1.0), jnp.nan)
