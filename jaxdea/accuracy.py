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
the exact cylinder, also at α̂ĥ = 150). With ``rtol`` the levels double until every root meets
|error| ≤ rtol·Ω or ``max_layers`` is reached (status INACCURATE).

Near the critical voltage the lowest root behaves like sqrt(V̂_cr(N) − V̂): the laminate error of
V̂_cr is amplified by ≈ V̂_cr/(2(V̂_cr − V̂)) in Ω, and the levels see it (their V̂_cr(N) differ), so
the estimate grows accordingly; if V̂ lies above V̂_cr of some level the root vanishes there and
the status says so (NO_ROOT / MAX_ITER) instead of extrapolating across the instability.

The Magnus schemes (``scheme="magnus4"``, ``"magnus6"``, :mod:`jaxdea.transfer`) are symmetric
too, with expansions in N⁻⁴, N⁻⁶, … and N⁻⁶, N⁻⁸, …: their levels are combined as
R_j = (2^p Ω_{j+1} − Ω_j)/(2^p − 1) with p = 4, 6 (error O(N⁻⁶), O(N⁻⁸)).
"""

from typing import NamedTuple

import jax.numpy as jnp
import numpy as np

from .compiled import cached_jit, serializable
from .params import Fluid, Tube, canonical, validate_layers
from .roots import _guard_order, _order_inputs, _problem, guard, scan_step, solve_frequencies
from .state_matrix import LONGITUDINAL
from .scalar import Status, run_lanes, start_lanes
from .transfer import laminate, scheme_order


@serializable
class Estimate(NamedTuple):
    """Roots with error estimates.

    Attributes:
        omega: Richardson-extrapolated roots (n_roots,), NaN where not available.
        error: estimated absolute error of ``omega`` (conservative, see module docstring).
        status: per root: CONVERGED, NO_ROOT / NOT_FINITE / MAX_ITER (a level failed, or the root
            changed order between levels: a pair closer than the laminate error), or INACCURATE
            (``rtol`` not reached within ``max_layers``).
        levels: Ω at every laminate level, shape (n_levels, n_roots).
        n_layers: the sublayer counts of the levels, (n_levels,).
    """

    omega: np.ndarray
    error: np.ndarray
    status: np.ndarray
    levels: np.ndarray
    n_layers: np.ndarray


@cached_jit(static_argnames=("n_layers", "order", "family"))
def _follow(tube, alpha, fluid, guesses, n_layers, order, m=0.0, family=LONGITUDINAL):
    """Safeguarded Newton from each guess on the laminate of ``n_layers`` sublayers (one lane
    per root, steps capped at a quarter of the scan step, as in :func:`jaxdea.solve_frequency`).
    ``family`` (static) and ``m`` (traced): the mode family, as in :func:`jaxdea.frequencies`."""
    if family == LONGITUDINAL:  # the axisymmetric program, as before order m existed
        ok, tube, alpha, fluid = guard(tube, alpha, fluid)
    else:
        ok, tube, alpha, fluid = _guard_order(tube, alpha, fluid, m, family)
    wall, fun = _problem(tube, alpha, fluid, n_layers, order, m, family)
    finite = jnp.isfinite(guesses) & ok
    start = jnp.where(finite, guesses, 1.0)
    nan = jnp.full_like(start, jnp.nan)
    cap = jnp.full_like(start, 0.25 * scan_step(wall, fluid, family))
    lanes = start_lanes(start, start, nan, nan, nan, nan, jnp.where(finite, 3, 0), max_step=cap,
                        pairs=False)
    roots, _, status = run_lanes(fun, lanes)
    status = jnp.where(finite, status, Status.NO_ROOT)
    return jnp.where(status == Status.CONVERGED, roots, jnp.nan), status


def frequencies_with_error(tube: Tube, alpha, fluid: Fluid | None = None, n_roots: int = 3,
                           omega_max=None, n_layers: int = 30, rtol=None,
                           max_layers: int = 1920, scheme: str = "midpoint", m=0,
                           torsional: bool = False) -> Estimate:
    """The ``n_roots`` lowest roots with an error estimate each (module docstring).

    Levels N, 2N, 4N (at least three, for two Richardson values); with ``rtol`` further doublings
    until |error| ≤ rtol·Ω for every root, up to ``max_layers``. Concrete inputs only (a Python
    loop over levels; each level compiles once per static configuration).

    Args:
        tube, alpha, fluid, n_roots, omega_max: as in :func:`jaxdea.frequencies`.
        n_layers: the coarsest level N, where the roots are isolated.
        rtol: requested relative accuracy, or None for the three levels N, 2N, 4N.
        max_layers: finest level allowed.
        scheme: the propagation scheme of every level (:func:`jaxdea.frequencies`); its order p
            sets the Richardson factor 2^p.
        m, torsional: the circumferential order and family (:func:`jaxdea.frequencies`); every
            level follows the roots of that order.

    Returns:
        :class:`Estimate`.

    Example:
        >>> est = frequencies_with_error(Tube(), 0.445, rtol=1e-10)
        >>> est.omega, est.error
    """
    order, family = _order_inputs(tube, alpha, fluid, n_layers, scheme, m, torsional)
    validate_layers(max_layers)
    if max_layers < 4 * n_layers:
        raise ValueError(f"max_layers must be >= 4 * n_layers = {4 * n_layers}, got {max_layers!r}")
    if rtol is not None and not (np.isfinite(rtol) and rtol > 0):
        raise ValueError(f"rtol must be a finite number > 0, got {rtol!r}")
    first = solve_frequencies(tube, alpha, fluid, n_roots, omega_max, n_layers, scheme, m, torsional)
    tube, alpha, fluid, m = canonical(tube, alpha, fluid, m)
    order_args = () if family == LONGITUDINAL else (m, family)
    levels = [np.asarray(first.omega)]
    status = np.asarray(first.status).copy()
    layers = [int(n_layers)]
    while True:
        n = 2 * layers[-1]
        omega, stat = (np.asarray(x) for x in _follow(tube, alpha, fluid, levels[-1],
                                                      laminate(n, scheme), order, *order_args))
        status = np.where(status == Status.CONVERGED, stat, status)
        levels.append(omega)
        layers.append(n)
        if len(levels) < 3:
            continue
        value, error = _richardson(levels, scheme_order(scheme))
        converged = status == Status.CONVERGED
        met = ~converged | (error <= (rtol or np.inf) * np.abs(value))
        if rtol is None or np.all(met) or 2 * n > max_layers:
            break
    ordered = _same_order(levels)
    status = np.where((status == Status.CONVERGED) & ~ordered, Status.MAX_ITER, status)
    if rtol is not None:
        status = np.where((status == Status.CONVERGED) & (error > rtol * np.abs(value)),
                          Status.INACCURATE, status)
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
