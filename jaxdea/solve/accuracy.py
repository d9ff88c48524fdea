"""Accuracy control: an error estimate for every root and refinement to a requested tolerance.

The laminate (N sublayers, exponential of M at each midpoint) has an error expansion in even powers
of the sublayer thickness: Ω_N = Ω + c_2 N⁻² + c_4 N⁻⁴ + … (tested: err(30)/err(60) = 3.99–4.00).
Roots are isolated once at N (:func:`jaxdea.solve_frequencies`) and then followed by safeguarded
Newton on the laminates 2N, 4N, … (a root moves by the laminate error only, far less than the
distance to its neighbours unless a pair is closer than that error). Richardson extrapolation of
consecutive levels,

    R_j = (4 Ω_{j+1} − Ω_j)/3,   error(R_j) = O(N_j⁻⁴),

gives the returned value R_last and the error estimate |R_last − R_prev|: in the asymptotic regime
R_prev's error is 16× R_last's, so the estimate exceeds the true error by about 15× (tested against
the exact cylinder, also at α̂ĥ = 150). The levels double until every root's last three levels are
in the asymptotic regime (below) and, with ``rtol``, meet |error| ≤ rtol·Ω, or until
``max_layers`` is reached (status INACCURATE).

Near the critical voltage the lowest root behaves like sqrt(V̂_cr(N) − V̂): the laminate error of
V̂_cr is amplified by ≈ V̂_cr/(2(V̂_cr − V̂)) in Ω, and the levels see it (their V̂_cr(N) differ), so
the estimate grows accordingly; if V̂ lies above V̂_cr of some level the root vanishes there and
the status says so (NO_ROOT / MAX_ITER) instead of extrapolating across the instability.

The Magnus schemes (``scheme="magnus4"``, ``"magnus6"``, :mod:`jaxdea.physics.transfer`) are symmetric
too, with expansions in N⁻⁴, N⁻⁶, … and N⁻⁶, N⁻⁸, …: their levels are combined as
R_j = (2^p Ω_{j+1} − Ω_j)/(2^p − 1) with p = 4, 6 (error O(N⁻⁶), O(N⁻⁸)).

The estimate is only as good as the expansion, which needs sublayers finer than every length on
which the wall's moduli vary. Near Gent locking W_1 ∝ 1/(1 − (I_1 − 3)/G) has a boundary layer at
the inner face far thinner than ĥ/N (1.6e-3 of a 0.52 wall at 99 % of locking), and the levels
converge more slowly than N⁻ᵖ until N resolves it (the second root of such a tube, midpoint
laminate: the differences between the levels 30, 60, …, 960 shrink by 1.67, 2.11, 2.73, 3.36; on
levels 30, 60, 120 the estimate was 0.047 against a true error of 0.023). So every root's last
three levels are checked: the observed order p_obs = log₂ ρ, ρ = d₁/d₂ with d₁ = Ω_{j+1} − Ω_j,
d₂ = Ω_{j+2} − Ω_{j+1}, must be within ORDER_SLACK of p (or d₂ at rounding level). Until it is, the
levels keep doubling, with or without ``rtol`` (the tube above: levels up to 960, Ω₂ = 2.27542
± 6.7e-4, true error 7.1e-5). A root that never gets there within ``max_layers`` is INACCURATE and
its error the conservative bound max(|R_last − R_prev|, |d₂|/(2^p − 1), |d₂|/(ρ − 1)): the whole
remaining change if the levels kept converging at least geometrically at their observed ratio ρ
(as they do while the sublayers approach a boundary layer), and infinite for ρ ≤ 1 (levels that do
not converge). Grading the sublayers towards the locking face would restore the N⁻ᵖ regime from
N = 30 there (measured with a geometric grading: ratios 3.99, 4.00, 4.00).
"""

from typing import NamedTuple

import numpy as np

from ..compiled import serializable
from ..numerics.scalar import Status
from ..params import Fluid, Tube, canonical, validate_layers, validate_roots, with_outer
from ..physics.problem import describe
from ..physics.transfer import Layers, is_graded, laminate, scheme_order, split_layers
from .roots import follow_roots, solve_frequencies, without_voltage


@serializable
class Estimate(NamedTuple):
    """Roots with error estimates.

    Attributes:
        omega: Richardson-extrapolated roots (n_roots,), NaN where not available.
        error: estimated absolute error of ``omega`` (conservative, see module docstring).
        status: per root: CONVERGED, NO_ROOT / NOT_FINITE / MAX_ITER (a level failed, or the root
            changed order between levels: a pair closer than the laminate error), or INACCURATE
            (``rtol`` not reached within ``max_layers``, or the last three levels not in the
            asymptotic regime of the scheme: then ``error`` is the conservative bound of the
            module docstring).
        levels: Ω at every laminate level, shape (n_levels, n_roots).
        n_layers: the sublayer counts of the levels, (n_levels,).
    """

    omega: np.ndarray
    error: np.ndarray
    status: np.ndarray
    levels: np.ndarray
    n_layers: np.ndarray


def frequencies_with_error(tube: Tube, alpha, fluid: Fluid | None = None, n_roots: int = 3,
                           omega_max=None, n_layers: int | None = None, rtol=None,
                           max_layers: int | None = None, scheme: str | None = None, m=0,
                           torsional: bool = False, outer: Fluid | None = None) -> Estimate:
    """The ``n_roots`` lowest roots with an error estimate each (module docstring).

    Levels N, 2N, 4N (at least three, for two Richardson values), then further doublings until
    every root's last three levels converge at the scheme's order (module docstring) and, with
    ``rtol``, |error| ≤ rtol·Ω, up to ``max_layers``; a root that gets there is CONVERGED, one that
    does not INACCURATE (with a conservative error where its order was not reached). Concrete
    inputs only (a Python loop over levels; each level compiles once per static configuration).

    Args:
        tube, alpha, fluid, n_roots, omega_max: as in :func:`jaxdea.frequencies`.
        n_layers: the coarsest level N, where the roots are isolated; None (default): the N of
            the default discretisation, whose levels are graded sixth-order Magnus walls
            (:func:`jaxdea.frequencies`), so the estimate is that of the default's roots.
        rtol: requested relative accuracy, or None (levels until the asymptotic regime only).
        max_layers: finest level allowed (None: max(1920, 4N)).
        scheme: the propagation scheme of every level (:func:`jaxdea.frequencies`); its order p
            sets the Richardson factor 2^p.
        m, torsional: the circumferential order and family (:func:`jaxdea.frequencies`); every
            level follows the roots of that order.

    Returns:
        An instance of :class:`Estimate`.

    Examples:
        >>> est = frequencies_with_error(Tube(), 0.445, rtol=1e-10)
        >>> est.omega, est.error
    """
    tube = with_outer(tube, outer)
    problem = describe(tube, alpha, fluid, n_layers, scheme, m, torsional)
    order = problem.order
    n_roots = validate_roots(n_roots)
    base = laminate(n_layers, scheme, *canonical(tube, alpha), n_roots, canonical(m))
    count, scheme = split_layers(base)
    graded = is_graded(base)

    def level(n):  # the static discretisation of the level with n sublayers
        return Layers(n, scheme, True) if graded else laminate(n, scheme)

    if max_layers is None:
        max_layers = max(1920, 4 * count)
    validate_layers(max_layers)
    if max_layers < 4 * count:
        raise ValueError(f"max_layers must be >= 4 * n_layers = {4 * count}, got {max_layers!r}")
    if rtol is not None and not (np.isfinite(rtol) and rtol > 0):
        raise ValueError(f"rtol must be a finite number > 0, got {rtol!r}")
    first = solve_frequencies(tube, alpha, fluid, n_roots, omega_max, base, None, m, torsional)
    tube, alpha, fluid, m = canonical(tube, alpha, fluid, m)
    order_args = problem.arguments(m)
    decoupled = without_voltage(tube, problem.family)  # V̂ = 0: the 4×4 propagation
    levels = [np.asarray(first.omega)]
    status = np.asarray(first.status).copy()
    layers = [count]
    while True:
        n = 2 * layers[-1]
        omega, stat = (np.asarray(x) for x in follow_roots(tube, alpha, fluid, levels[-1], level(n),
                                                      order, **order_args, decoupled=decoupled))
        status = np.where(status == Status.CONVERGED, stat, status)
        levels.append(omega)
        layers.append(n)
        if len(levels) < 3:
            continue
        value, error = _richardson(levels, scheme_order(scheme))
        asymptotic = _asymptotic(levels, scheme_order(scheme), value)
        error = np.where(asymptotic, error, _conservative_error(levels, scheme_order(scheme), error))
        converged = status == Status.CONVERGED
        met = ~converged | (asymptotic & (error <= (rtol or np.inf) * np.abs(value)))
        if np.all(met) or 2 * n > max_layers:
            break
    ordered = _same_order(levels)
    status = np.where((status == Status.CONVERGED) & ~ordered, Status.MAX_ITER, status)
    inaccurate = ~asymptotic | (error > (rtol or np.inf) * np.abs(value))
    status = np.where((status == Status.CONVERGED) & inaccurate, Status.INACCURATE, status)
    good = status == Status.CONVERGED
    return Estimate(omega=np.where(good | (status == Status.INACCURATE), value, np.nan),
                    error=np.where(good | (status == Status.INACCURATE), error, np.nan),
                    status=status.astype(np.int32), levels=np.stack(levels),
                    n_layers=np.asarray(layers))


def _richardson(levels, order=2):
    """(R_last, |R_last − R_prev|) from the last three levels (N^−order elimination)."""
    a, b, c = levels[-3:]
    factor = 2.0**order
    prev, last = (factor * b - a) / (factor - 1.0), (factor * c - b) / (factor - 1.0)
    return last, np.abs(last - prev)


ORDER_SLACK = 0.5
"""Largest |p_obs − p| of the last three levels accepted as the asymptotic regime (observed order
p_obs = log₂ of the ratio of consecutive level differences; 2^p ± 41 %)."""
ROUNDING_FLOOR = 1e-13
"""Level differences |Ω_{j+2} − Ω_{j+1}| below this fraction of |Ω| are rounding (roots are
accurate to a few 1e-15 relative): their ratio says nothing about the order, and they pass."""


def _asymptotic(levels, order, value):
    """True per root where the last three levels converge at the scheme's order p:
    |log₂(d₁/d₂) − p| ≤ ORDER_SLACK (d₁, d₂ the two last level differences, of one sign), or where
    the last two levels agree to rounding (|d₂| ≤ ROUNDING_FLOOR·|Ω|)."""
    a, b, c = levels[-3:]
    d1, d2 = b - a, c - b
    with np.errstate(all="ignore"):
        ratio = d1 / d2
        observed = np.log2(np.where(ratio > 0, ratio, np.nan))
    in_order = np.abs(observed - order) <= ORDER_SLACK  # False for NaN
    return in_order | (np.abs(d2) <= ROUNDING_FLOOR * np.abs(value))


def _conservative_error(levels, order, error):
    """max(|R_last − R_prev|, |d₂|/(2^p − 1), |d₂|/(ρ − 1)), ρ = d₁/d₂ (module docstring): the
    distance from R_last to any limit the levels reach while converging at least geometrically
    with ratio ρ; inf where ρ ≤ 1."""
    a, b, c = levels[-3:]
    d1, d2 = b - a, c - b
    with np.errstate(all="ignore"):
        ratio = d1 / d2
        tail = np.where(ratio > 1.0, np.abs(d2) / (ratio - 1.0), np.inf)
    return np.maximum(np.maximum(error, np.abs(d2) / (2.0**order - 1.0)), tail)


def _same_order(levels):
    """True per root where it is finite on every level and stays strictly between its finite
    neighbours (a root that swapped with or merged into a neighbour has no trustworthy estimate)."""
    ok = np.ones(levels[0].shape, bool)
    for omega in levels:
        finite = np.isfinite(omega)
        rising = omega[1:] > omega[:-1]
        ok &= finite
        ok[1:] &= ~finite[:-1] | rising
        ok[:-1] &= ~finite[1:] | rising
    return ok
