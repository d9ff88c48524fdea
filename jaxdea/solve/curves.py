"""Dispersion curves by continuation: the K lowest roots along a grid of α̂, each step certified.

:func:`jaxdea.frequencies` isolates the roots of every α̂ by a guaranteed scan of f(Ω) from Ω = 0
(:mod:`jaxdea.solve.roots`), which costs tens of evaluations per root. Along a curve the roots of the
next α̂ are close to a polynomial extrapolation of the previous ones, and Newton from there needs
one to three evaluations. :func:`dispersion_curve` follows the K lowest roots that way and checks every step;
a step that fails a check is solved by the scan instead, so the result is that of ``frequencies``
at every α̂ (the same roots, to the solver tolerance), only cheaper where the curve is smooth.

Step j (α̂_j, after accepted roots at up to HISTORY = 12 earlier α̂):

1. Predictor: p_k = the Lagrange polynomial through the last m_k ≤ 12 accepted (α̂, Ω_k), at α̂_j,
   of the order m_k whose last increment |P_m − P_{m−1}| is smallest for branch k (m = 1 after a
   scan: the tangent line, see below). On the benchmark's unstretched curve (200 α̂ in 0.01–5,
   4 roots) the fixed quintic (m = 6) left 67 of the 200 predictions more than 3e-9 off and the
   adaptive order 2 (measured against the converged roots).
2. Corrector: K Newton lanes from p_k (:func:`jaxdea.numerics.scalar.iterate_lanes`, FREE lanes: steps
   capped at ρ_k = ¼ of the distance from p_k to its neighbours p_{k±1}, with p_0 = 0; a lane that
   brackets a sign change finishes by safeguarded Newton), and one lane that evaluates f(0). Each
   lane starts with the curvature K_k = |f''/(2f')| its branch had at one of the last
   ``PRIOR_AGE`` = 16 steps (measured from the slopes of its last two iterates there): where the
   first Newton step δ from p_k leaves an error K_k δ² below 1/16 of the tolerance, the lane stops
   after that one evaluation (K is measured anew at least every 17th step; with 3, the curve's
   gain fell from 1.4–1.5× to 1.05×). When one lane's K expires, the step runs every lane without
   its prior (:func:`_refresh`): all lanes then measure K in the same step, instead of one extra
   evaluation per branch whose K expires at its own step. With both, that curve takes 220 (f, f')
   evaluations of its K + 1 lanes instead of 271 (182 of its 199 steps take one).
3. Checks, all required: every lane converged within ``TRACK_ITERATIONS``; 0 < Ω_1 < … < Ω_K;
   |Ω_k − p_k| ≤ ρ_k; and the signs alternate,

       sign f'(Ω_k) = (−1)^k sign f(0),   k = 1 … K.

   f is continuous and changes sign at each simple root, so the number of roots in (0, Ω_1) and
   in each gap (Ω_k, Ω_{k+1}) is even exactly when these signs alternate: a single root missed
   below Ω_K, one that came in through Ω = 0 (an unstable mode turning stable: f(0) changes
   sign), one that came down from above, or a lane that jumped to a neighbouring branch, all fail
   the test. A step that fails is tried again in two halves (the midpoint, accepted by the same
   checks, joins the history); if a half fails too, the scan of
   :func:`jaxdea.solve.roots.scan_roots` solves the step.

What the checks cannot see is an even number of new roots in one gap within one step: two roots
entering through Ω = 0, or two coming down into the same gap, between consecutive α̂. Roots of a
conservative problem (the empty tube, the acoustic coupling) move continuously with α̂ and do not
appear in pairs inside a gap, so this needs two branches that cross the same gap within one grid
step; the scan has its own limit of the same kind (two extrema of f within one scan step). The
paper's follower-pressure coupling is not conservative, and there roots are born in pairs (a pair
at Ω = 0.044 and 0.047 appears between α̂ = 0.16 and 0.17 and is gone at 0.2, on λ_i = 1.1,
λ_z = 1.2, η = 0.85, ρ̂_f = 0.13, ĉ_f = 0.27, ν = 0; continuation followed the other roots past it,
unseen by the checks): with that coupling every α̂ is scanned.

After a fallback the history restarts from the scanned roots, unless they lie within ρ_k of the
prediction (the branches were followed correctly and only a check was too strict), when the
history goes on. A restarted history is one point and the slope of each branch there,
dΩ_k/dα̂ = −(∂f/∂α̂)/(∂f/∂Ω) at the scanned roots (central differences of f, after a scan only):
the next prediction is the tangent line instead of a constant, which continues steps that a
constant sent back to the scan (on the Fig. 3 lines along n, 8 scans of 80 steps instead of 17;
on the benchmark curve 1 of 200 instead of 2). The checks are unchanged: the predictor only
decides how often they pass.

Cost: a step costs 1 evaluation of (f, f') on K + 1 lanes where the prediction is within about
1e-8 of the roots, 2 where it is good (3 or more where it is not); the scan of one α̂ costs one
or more 32-point chunks plus the lanes. The evaluations are the whole cost on the CPU: with a
polynomial in place of f the 200 steps of the benchmark's curve took 0.85 ms (predictor, checks,
history, loops), so the time is ≈ (evaluations) × (one evaluation) plus the scan of the first α̂
(≈ 4 ms there). The lanes take (f, f') from :func:`jaxdea.physics.dispersion.value_and_slope_on_wall`:
the slope without differentiating Gram–Schmidt, and at V̂ = 0 through the 4×4 mechanical block
alone (the electric one decouples); one (f, f') of the 5 lanes on that wall (N = 16) costs
≈ 0.05–0.07 ms instead of 0.3 by forward mode through the 6×6 propagation. The generators of a
curve's wall (one tube) are formed once, as polynomials in α̂
(:func:`jaxdea.physics.dispersion.generator_polynomials`): forming them at every step from the state
matrices cost about as much as the lanes' evaluations there (the benchmark's curve 24.5–25.8 →
18.6–19.9 ms, measured side by side).
:func:`dispersion_curve` compiles one of the two propagations, chosen from the concrete V̂
(``decoupled``, :func:`_omega_problem`): at V̂ = 0 the scan of the first α̂ runs on the 4×4 one
too (the log-scale's slope is tr(QᵀZ)), and the program compiles faster than one holding both.
Paths. Nothing above needs α̂ to be the abscissa: :func:`path_unchecked` runs the same steps and
checks along any path through parameter space (V̂, λ_i, h/R_i, ρ̂_f, ĉ_f, α̂ or n; the problem between
two points is the linear interpolation of their parameters), several curves packed into one path,
and :func:`critical_path_unchecked` along a path in the unknown V̂ instead of Ω: the critical voltage
is the first zero of f(Ω = 0; V̂), held by the same sign checks with K = 1 (the figures follow every
curve and every critical voltage this way). Both also report where a root found by the scan is
more than ρ_k from its prediction: the k-th root changed branch there.

Inside ``jax.vmap`` the fallback (a ``lax.cond``) turns
into a select that runs the scan at every step: vmap the curve only where few steps would succeed
anyway, and loop in Python (or use :func:`jaxdea.sweep`) otherwise.

The other way round, ``jax.vmap`` of :func:`jaxdea.frequencies` or :func:`jaxdea.critical_voltage`
over α̂ alone (the tube and the rest shared) is a curve: their batching rule
(:func:`jaxdea.solve.roots.one_point_at_a_time`) hands the batch to :func:`frequencies_along` or
:func:`critical_voltages_along`, which continue along it where it is ordered and scan each point
where it is not; every point gets the roots it gets alone, to rounding.
"""

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from ..compiled import cached_jit, serializable
from ..numerics.scalar import (
    Status,
    iterate_lanes,
    lanes_from_slots,
    newton_slope,
    start_lanes,
    value_and_slope,
)
from ..params import (
    ALPHA_MIN,
    Fluid,
    Tube,
    as_float,
    canonical,
    detached,
    guard,
    traced,
    validate_alpha,
    validate_roots,
    with_outer,
)
from ..physics import characteristic
from ..physics.base_state import voltage_limit
from ..physics.characteristic import Unknown
from ..physics.dispersion import generator_polynomials, lane_generators
from ..physics.families import Face
from ..physics.problem import NO_ALPHA, describe
from ..physics.state_matrix import LONGITUDINAL, ORDER_M
from ..physics.transfer import AUTO_SCHEME, checked_laminate, discretize, is_graded, voltage_expansion
from .roots import (
    BATCH_ENGINES,
    Roots,
    _concrete,
    _shortfall,
    attach_derivatives,
    companion,
    critical_function,
    critical_voltage_unchecked,
    decoupled_choice,
    default_omega_max,
    guard_order,
    inaccurate_where,
    invalid_where,
    refined,
    scan_roots,
    scan_step,
    scanned_function,
    steps_on_wall,
)

HISTORY = 12  # rows of the predictor (its order chosen per branch, :func:`_extrapolate`)
SHARE_OF_GAP = 0.25  # a lane may move at most this share of the distance to its neighbours
TRACK_ITERATIONS = 16  # corrector iterations before the step is handed to the scan
PRIOR_AGE = 16  # a lane's curvature serves as a prior for this many steps after it was measured
TANGENT_STEP = 1e-6  # relative steps of the central differences of the branch slopes after a scan


@serializable
class Curve(NamedTuple):
    """The K lowest roots along a grid of α̂.

    Attributes:
        alpha: the grid α̂, shape (M,).
        omega: roots, shape (M, K), ascending in each row, NaN where not found.
        status: :class:`~jaxdea.Status` per root, shape (M, K).
        scanned: shape (M,), True where the guaranteed scan solved the step (the first α̂, and
            steps whose continuation failed the checks).
    """

    alpha: jax.Array
    omega: jax.Array
    status: jax.Array
    scanned: jax.Array


def _extrapolate(hist_alpha, hist_omega, n_hist, alpha, slope=None):
    """p_k(α̂): the Lagrange polynomial through the newest m_k rows of the history (newest last),
    of the order each branch k resolves best.

    P_m is the polynomial through the newest m rows (weights w_i = Π_{j ≠ i} (α̂ − α̂_j)/(α̂_i − α̂_j)
    on them, zero on the older ones), m = 1 … n = max(``n_hist``, 1) ≤ HISTORY; the change
    e_m = |P_m − P_{m−1}| estimates the error of P_{m−1}, and p_k = P_{m_k} with m_k the m ≥ 2 of
    the smallest e_m (P_1 where n = 1): high orders where the branch is smooth on the grid, low
    ones where a step is coarse for it. With one row and a finite ``slope`` dΩ_k/dα̂ there (the
    tangent of each branch after a scan) the line through it: Ω_k + slope_k (α̂ − α̂_newest)."""
    if slope is not None:
        tangent = jnp.isfinite(slope) & (n_hist <= 1)
        line = hist_omega[-1] + jnp.where(tangent, slope, 0.0) * (alpha - hist_alpha[-1])
        return jnp.where(tangent, line, _extrapolate(hist_alpha, hist_omega, n_hist, alpha))
    size = hist_alpha.shape[0]
    n = jnp.maximum(n_hist, 1)
    row = jnp.arange(size)
    order = jnp.arange(1, size + 1)[:, None]  # m, one row of weights per order
    used = row[None, :] >= size - order  # (m, i): row i among the newest m
    w = jnp.where(used, 1.0, 0.0)
    for j in range(size):
        w = jnp.where(used & used[:, j : j + 1] & (row != j),
                      w * (alpha - hist_alpha[j]) / (hist_alpha - hist_alpha[j]), w)
    rows = jnp.where(jnp.isfinite(hist_omega), hist_omega, 0.0)
    polys = w @ rows  # (m, K): P_m
    change = jnp.abs(jnp.diff(polys, axis=0))  # e_m, m = 2 … size
    change = jnp.where(order[1:] <= n, change, jnp.inf)
    best = jnp.argmin(change, axis=0) + 1  # the index of P_{m_k}
    best = jnp.where(n <= 1, 0, best)
    return jnp.take_along_axis(polys, best[None, :], axis=0)[0]


def _expired(curvature, age):
    """Per lane: a measured prior K that is ``PRIOR_AGE`` steps old or more."""
    return jnp.isfinite(curvature) & (age >= PRIOR_AGE)


def _refresh(curvature, age):
    """True when some lane's prior K has expired: the step then runs every lane without its prior,
    so that all of them measure K together (a lane without a prior needs a second evaluation, and
    every lane is evaluated as often as the slowest one), instead of one step per branch whose
    prior expires."""
    return jnp.any(_expired(curvature, age))


def _aged(measured, curvature, age, refresh):
    """(K, age) after a step: K measured there (age 0), else the prior one step older; after a
    refresh an expired lane that measured none has none (age ``PRIOR_AGE``: it triggers no
    further refresh)."""
    fresh = jnp.isfinite(measured)
    dropped = refresh & _expired(curvature, age)
    return (jnp.where(fresh, measured, jnp.where(dropped, jnp.nan, curvature)),
            jnp.where(fresh, 0, jnp.where(dropped, PRIOR_AGE, age + 1)))


def _room(pred):
    """ρ_k = SHARE_OF_GAP · the distance from p_k to p_{k±1} (p_0 = 0; none above p_K)."""
    below = jnp.concatenate([jnp.zeros(1), pred[:-1]])
    above = jnp.concatenate([pred[1:], jnp.full(1, jnp.inf)])
    return SHARE_OF_GAP * jnp.minimum(pred - below, above - pred)


def _track(fun, pred, curvature=None):
    """(Ω, accepted, K): K corrector lanes from ``pred`` (with prior curvatures ``curvature``, see
    :func:`jaxdea.numerics.scalar.iterate_lanes`; ``fun`` gives (f, f')) and the checks of the module
    docstring; K holds the curvature each lane measured (NaN where it finished on its prior)."""
    k = pred.shape[0]
    room = _room(pred)
    x0 = jnp.concatenate([pred, jnp.zeros(1)])  # the last lane evaluates f(0)
    nan = jnp.full(k + 1, jnp.nan)
    prior = nan if curvature is None else jnp.concatenate([curvature, jnp.full(1, jnp.nan)])
    kind = jnp.concatenate([jnp.full(k, 3), jnp.zeros(1, jnp.int32)])
    lanes = lanes_from_slots(x0, x0, nan, nan, nan, nan, kind, jnp.zeros(k + 1, jnp.int32),
                             max_step=jnp.concatenate([room, jnp.full(1, jnp.inf)]), curvature=prior)
    lanes = iterate_lanes(fun, lanes, max_iter=TRACK_ITERATIONS, with_slope=True)
    omega, slope, f0 = lanes.x[:k], lanes.dfx[:k], lanes.fx[k]
    alternating = jnp.sign(f0) * (-1.0) ** jnp.arange(1, k + 1)
    ok = jnp.all(lanes.status[:k] == Status.CONVERGED) & jnp.all(jnp.isfinite(omega))
    ok &= jnp.isfinite(f0) & (f0 != 0) & jnp.all(room > 0)
    ok &= jnp.all(jnp.diff(jnp.concatenate([jnp.zeros(1), omega])) > 0)
    ok &= jnp.all(jnp.abs(omega - pred) <= room)
    ok &= jnp.all(jnp.sign(slope) == alternating)
    measured = jnp.isfinite(lanes.curvature[:k]) & (lanes.curvature[:k] != prior[:k])
    return omega, ok, jnp.where(measured, lanes.curvature[:k], jnp.nan)


def _omega_problem(problem, n_roots, m_safe, family, decoupled=None, polys=None, omega_max=None):
    """The callables of :func:`_follow` for the K lowest roots in Ω of ``problem(x, s)`` = (wall, α̂,
    fluid, Bessel order) at abscissa s near the point x of a path: (f, f') for the corrector lanes,
    f itself (the tangent's differences) and the guaranteed scan. ``decoupled`` (static,
    longitudinal): True where every wall is known to decouple (V̂ = 0): lanes and scan then take
    the 4×4 propagation alone (:func:`jaxdea.physics.dispersion.value_and_slope_on_wall`); False: the 6×6
    one alone; None: checked at each point (both compiled). ``polys``: the lanes' generators as
    polynomials in α̂ (:func:`jaxdea.physics.dispersion.generator_polynomials`), where every point has the
    same wall (a dispersion curve of one tube); None: formed from each point's wall. ``omega_max``:
    the scan's search range, as in :func:`jaxdea.frequencies` (None: automatic)."""
    def value(x, s, om):
        wall, a, fluid, order = problem(x, s)
        return characteristic.value(family, wall, om, a, fluid, order, m_safe, Unknown.OMEGA,
                                    "adaptive")

    def at(x, s):  # (f, f') for the corrector lanes
        wall, a, fluid, order = problem(x, s)
        generators = None if polys is None else lane_generators(polys, a)
        return lambda om: characteristic.value_and_slope(family, wall, om, a, fluid, order,
                                                         m_safe, decoupled, generators)

    def search(x, s):
        # the unnormalised determinant and, for the paper's coupling, points at its poles
        # (:func:`jaxdea.solve.roots.scanned_function`, :func:`jaxdea.solve.roots.pole_steps`)
        # (on a decoupled wall the 4×4 propagation: the first α̂'s scan 4× cheaper)
        wall, a, fluid, order = problem(x, s)
        generators = None if polys is None else lane_generators(polys, a)
        fun = scanned_function(wall, a, fluid, order, m_safe, family, decoupled=bool(decoupled),
                               generators=generators)
        return scan_roots(wall, fun, a, fluid, omega_max, n_roots, m_safe, family, order=order)

    return at, value, search


def _follow(at, value, search, points, abscissa, ok_points, starts, n_roots, conservative,
            limit=None):
    """The continuation of the module docstring over a path of M points (traceable).

    At abscissa s near the point x of ``points`` (a pytree with leading axis M), ``at(x, s)`` is the
    function u ↦ (f(u), f'(u)) of the unknown u (Ω on a dispersion curve) for the corrector lanes,
    ``value(x, s, u)`` is f(u) and ``search(x, s)`` the guaranteed search for the K lowest roots
    (:class:`Roots`). ``abscissa`` (M,) is the coordinate the predictor extrapolates in (α̂ on a
    dispersion curve); ``ok_points`` (M,) marks the admissible points and ``starts`` (M,) those
    where a new curve starts (solved by the search, the history dropped). ``limit(x, s)``
    (optional): the end of the search's range; a step whose roots are not all inside it is solved
    by the search (which pads the roots above it with NaN).
    Returns (Ω (M, K), status, scanned (M,), restarted (M, K)), ``restarted`` True where a root
    found by the scan is not within ρ_k of its prediction (at the first point, and where the k-th
    root left the branch it followed: a step the continuation could not follow)."""
    unknown = (jnp.full(n_roots, jnp.nan), jnp.full(n_roots, PRIOR_AGE))  # (K, its age in steps)

    def tangent(x, s, omega):
        """dΩ_k/ds = −(∂f/∂s)/(∂f/∂Ω) at the roots Ω_k (implicit function theorem): the slope of
        each branch, for the predictor after a scan (NaN where a root is missing). The partial
        derivatives by central differences of f, relative steps ``TANGENT_STEP`` (values only, one
        batch of 4K: a predictor needs a few digits, and a forward-mode pass in α̂ added 3.5 s to
        the compile time, measured)."""
        found = jnp.isfinite(omega)
        om = jnp.where(found, omega, 1.0)
        dw, ds = TANGENT_STEP * om, TANGENT_STEP * jnp.where(s != 0, jnp.abs(s), 1.0)
        shift = jnp.array([[1.0, -1.0, 0.0, 0.0], [0.0, 0.0, 1.0, -1.0]])[:, :, None]  # Ω±, s±
        points_om = jnp.ravel(om + shift[0] * dw)
        points_s = jnp.ravel(s + shift[1] * jnp.full_like(om, ds))
        f = jax.vmap(lambda w, t: value(x, t, w))(points_om, points_s)
        f = f.reshape(4, -1)
        f_omega, f_s = (f[0] - f[1]) / (2.0 * dw), (f[2] - f[3]) / (2.0 * ds)
        return jnp.where(found, -f_s / f_omega, jnp.nan)

    def follow(history, x, s):
        """Continuation to the abscissa s: the whole step; if it fails a check, the two halves of
        it (the midpoint, accepted by the same checks, joins the history). Returns (Ω, accepted,
        the history used, the last prediction, the lanes' curvatures)."""
        def attempt(c):
            hist, stage = c[:2]
            target = jnp.where(stage == 1, 0.5 * (hist[0][-1] + s), s)
            pred = _extrapolate(*hist[:3], target, hist[5])
            refresh = _refresh(*hist[3:5])
            omega, ok, measured = _track(at(x, target), pred, jnp.where(
                (hist[4] < PRIOR_AGE) & ~refresh, hist[3], jnp.nan))
            curvature = _aged(measured, *hist[3:5], refresh)
            pushed = (jnp.concatenate([hist[0][1:], target[None]]),
                      jnp.concatenate([hist[1][1:], omega[None]]), jnp.minimum(hist[2] + 1, HISTORY),
                      *curvature, hist[5])
            hist = jax.tree_util.tree_map(lambda x, y: jnp.where((stage == 1) & ok, x, y), pushed, hist)
            done = (stage != 1) & ok
            stage = jnp.where(ok | (stage == 0), stage + 1, 3)  # a failed half ends the attempts
            return hist, stage, omega, done, pred, curvature

        hist, _, omega, done, pred, curvature = jax.lax.while_loop(
            lambda c: ~c[3] & (c[1] < 3), attempt,
            (history, jnp.array(0), jnp.zeros(n_roots), jnp.array(False), jnp.zeros(n_roots),
             unknown))
        return omega, done, hist, pred, curvature

    def step(carry, inputs):
        x, s, ok, start = inputs
        s = jnp.where(ok, s, 1.0)
        tried = ok & (carry[2] > 0) & ~start
        if conservative:
            omega, accepted, carry, pred, curvature = jax.lax.cond(
                tried, lambda: follow(carry, x, s),
                lambda: (jnp.zeros(n_roots), jnp.array(False), carry, jnp.zeros(n_roots), unknown))
            if limit is not None:
                accepted &= jnp.all(omega <= limit(x, s))
        else:  # roots are born in pairs: scan every point (the prediction tells a jump)
            omega, accepted, curvature = jnp.zeros(n_roots), jnp.array(False), unknown
            pred = _extrapolate(*carry[:3], s)
        hist_s, hist_omega, n_hist = carry[:3]
        scan = ok & ~accepted
        def scanned():
            found = search(x, s)
            if not conservative:  # every point is scanned: no predictor
                return found, jnp.full(n_roots, jnp.nan)
            return found, tangent(x, s, found.omega)

        roots, slope = jax.lax.cond(scan, scanned, lambda: (
            Roots(omega, jnp.full(n_roots, Status.CONVERGED, jnp.int32)), jnp.full(n_roots, jnp.nan)))
        complete = jnp.all(roots.status == Status.CONVERGED)
        near = tried & (jnp.abs(roots.omega - pred) <= _room(pred))  # per root
        on_track = jnp.all(near)
        n_new = jnp.where(on_track, jnp.minimum(n_hist + 1, HISTORY), 1)
        n_new = jnp.where(ok & complete, n_new, 0)
        carry = (jnp.concatenate([hist_s[1:], s[None]]),
                 jnp.concatenate([hist_omega[1:], roots.omega[None]]), n_new,
                 *jax.tree_util.tree_map(lambda x, y: jnp.where(scan, x, y), unknown, curvature), slope)
        status = jnp.where(ok, roots.status, Status.INVALID).astype(jnp.int32)
        return carry, (jnp.where(ok, roots.omega, jnp.nan), status, scan, scan & ~near)

    init = (jnp.arange(HISTORY, dtype=jnp.float64), jnp.zeros((HISTORY, n_roots)), jnp.array(0),
            *unknown, jnp.full(n_roots, jnp.nan))
    _, out = jax.lax.scan(step, init, (points, abscissa, ok_points, starts))
    return out


def _family_order(ok, m, fluid, family):
    """(ok, the traced order m, zero where not admissible) of the mode family (one m for every
    point of ``ok``)."""
    admissible = family.admissible(m, fluid)
    return ok & admissible, family.safe_m(m, admissible)


def curve_unchecked(tube, alpha, fluid, n_roots, n_layers, order, m=0.0,
                    family=LONGITUDINAL, decoupled=None) -> Curve:
    """The curve for one tube (traceable; the grid ``alpha`` has shape (M,)). ``family`` (static)
    and ``m`` (traced, ``"order_m"``): the mode family, as in :func:`jaxdea.frequencies`; an
    inadmissible m gives INVALID everywhere. ``decoupled`` (static): :func:`_omega_problem`."""
    return Curve(*_along_alpha(tube, alpha, fluid, n_roots, n_layers, order, m, family, decoupled))


def _along_alpha(tube, alpha, fluid, n_roots, n_layers, order, m, family, decoupled, fresh=None,
                 omega_max=None, bounded=False):
    """(α̂, Ω, status, scanned) of :func:`curve_unchecked`, with a fresh start (a scan) at every
    point where ``fresh`` (a scalar) is True; ``bounded`` (static): the roots of a step inside the
    search range ``omega_max`` (None: :func:`jaxdea.solve.roots.default_omega_max`) or that step is
    scanned, as the frequencies are (:func:`frequencies_along`)."""
    ok_tube, tube, _, fluid = guard(tube, 1.0, fluid)
    ok_tube, m_safe = _family_order(ok_tube, m, fluid, family)
    alpha = as_float(alpha)
    ok_alpha = ok_tube & jnp.isfinite(alpha) & (alpha >= ALPHA_MIN)
    wall = discretize(tube, n_layers)
    conservative = not Face.of(fluid).has_poles
    # the wall is the same at every α̂: the lanes' generators as polynomials in α̂, formed once
    # (the state matrices and the scheme's products at every step cost as much as the lanes' evaluation)
    polys = generator_polynomials(wall, m_safe, family, decoupled)
    callables = _omega_problem(lambda _, a: (wall, a, fluid, order), n_roots, m_safe, family,
                               decoupled, polys, omega_max)
    limit = None
    if bounded:
        def limit(_, a):
            return default_omega_max(wall, a, n_roots, m_safe) if omega_max is None else omega_max
    starts = jnp.zeros(alpha.shape, bool) if fresh is None else jnp.full(alpha.shape, fresh)
    omega, status, scanned, _ = _follow(*callables, alpha, alpha, ok_alpha, starts, n_roots,
                                        conservative, limit)
    return alpha, omega, status, scanned


def ordered(alpha):
    """True where the batch ``alpha`` (M,) is finite and strictly monotone (either direction)."""
    step = jnp.diff(alpha)
    return jnp.all(jnp.isfinite(alpha)) & (jnp.all(step > 0) | jnp.all(step < 0))


def frequencies_along(tube, alpha, fluid, omega_max, m=0.0, *, n_roots, n_layers, order, family,
                      decoupled) -> Roots:
    """The roots of :func:`jaxdea.frequencies` at every α̂ of a batch (M,) of one tube and fluid
    (traceable): ``jax.vmap`` of ``frequencies`` over α̂ alone comes here
    (:func:`jaxdea.solve.roots.along_alpha`).

    Where the batch is ordered (:func:`ordered`, checked in the program) it is a dispersion curve:
    the continuation of the module docstring, with one more check, that the roots of a step lie
    inside the search range (0, omega_max] of ``frequencies`` (a step with a root above it is
    scanned, and the scan pads with NaN as ``frequencies`` does). Elsewhere every α̂ starts anew:
    the same scan as a point alone. Equal to the points solved alone to rounding (the scan of a
    continuation runs on the 4×4 propagation at V̂ = 0, ``decoupled``; tests/test_vmap_rules.py)."""
    _, omega, status, _ = _along_alpha(tube, alpha, fluid, n_roots, n_layers, order, m, family,
                                       decoupled, ~ordered(as_float(alpha)), omega_max, bounded=True)
    return Roots(omega, status)


def frequency_along(tube, alpha, guess, fluid, m=0.0, *, n_layers, order, family,
                    decoupled) -> Roots:
    """The roots of :func:`jaxdea.frequency` at every (α̂, guess) of a batch (M,) of one tube and
    fluid (traceable): ``jax.vmap`` of ``frequency`` over α̂ and the guess (either or both) comes
    here (:func:`jaxdea.solve.roots.along_alpha`).

    The same safeguarded Newton from each guess as a point alone, the points' lanes side by side
    (vectorised, as the points take alike few iterations), but each (f, f') from the lanes of a
    curve: the generators formed once as polynomials in α̂ of the one wall, the 4×4 propagation at
    V̂ = 0 (``decoupled``) and f' carried through the propagation instead of forward mode
    (:func:`jaxdea.physics.dispersion.value_and_slope_on_wall`), with the log-scale's slope ℓ' beside
    it: where f nearly jumps the lanes step on F = f e^ℓ (:func:`jaxdea.numerics.scalar.newton_slope`),
    as a point alone does. Equal to the points alone to the Newton tolerance
    (tests/test_vmap_rules.py)."""
    alpha, guess = jnp.broadcast_arrays(as_float(alpha), as_float(guess))
    ok, tube, _, fluid = guard(tube, 1.0, fluid)
    ok, m_safe = _family_order(ok, m, fluid, family)
    ok = ok & jnp.isfinite(alpha) & (alpha >= ALPHA_MIN) & jnp.isfinite(guess) & (guess > 0)
    alpha, guess = jnp.where(ok, alpha, 1.0), jnp.where(ok, guess, 1.0)
    wall = discretize(tube, n_layers)
    polys = generator_polynomials(wall, m_safe, family, decoupled)
    step = jnp.reshape(4.0 * scan_step(wall, fluid, family), (1,))  # as roots._solve_frequency

    def newton(a, x):  # one point's lane (the points' loops vectorised by the vmap below)
        generators = lane_generators(polys, a)
        nan = jnp.full((1,), jnp.nan)
        lanes = start_lanes(x[None], x[None], nan, nan, nan, nan, jnp.array([3]), max_step=step,
                            pairs=False)
        scaled = characteristic.scaled(family, wall, a, fluid, order, m_safe, Unknown.OMEGA,
                                       decoupled, generators)

        def lane(om):  # f, f' of value_and_slope, and ℓ' to step on F where f nearly jumps
            (f, _), (df, dlog_scale) = value_and_slope(scaled, om)
            return f, newton_slope(f, df, dlog_scale)

        lanes = iterate_lanes(lane, lanes, with_slope=True)
        return jnp.where(lanes.status == Status.CONVERGED, lanes.x, jnp.nan)[0], lanes.status[0]

    return invalid_where(ok, Roots(*jax.vmap(newton)(alpha, guess)))


_solve_curve = cached_jit(curve_unchecked,
                          static_argnames=("n_roots", "n_layers", "order", "family", "decoupled"))


def _slopes(values, abscissa, starts):
    """d(values)/ds along the path: the backward difference at each point, the forward one where a
    curve starts; zero where it is not finite (a repeated abscissa, a curve of one point)."""
    dv = jnp.diff(values) / jnp.diff(abscissa)
    nan = jnp.full(1, jnp.nan)
    back, ahead = jnp.concatenate([nan, dv]), jnp.concatenate([dv, nan])
    dv = jnp.where(starts | ~jnp.isfinite(back), ahead, back)
    return jnp.where(jnp.isfinite(dv), dv, 0.0)


def _path_points(leaves, abscissa, starts):
    """(points, moved) of a path: its points for :func:`_follow` (each point's leaves, their
    slopes d/ds (:func:`_slopes`) and abscissa) and moved(x, s), the leaves of the point x linearly
    interpolated to the abscissa s (x itself at its own abscissa)."""
    slopes = jax.tree_util.tree_map(lambda v: _slopes(v, abscissa, starts), leaves)

    def moved(x, s):
        point, slope, s_point = x
        return jax.tree_util.tree_map(lambda v, dv: v + (s - s_point) * dv, point, slope)

    return (leaves, slopes, abscissa), moved


def path_unchecked(tubes, alphas, fluids, abscissa, starts, orders, n_roots, n_layers, order, m=0.0,
                   family=LONGITUDINAL, decoupled=None):
    """The K lowest roots at the M points of a path through parameter space (traceable).

    Point j is the tube ``tubes`` (leaves of shape (M,)) at j, α̂ = ``alphas[j]`` and the fluid
    ``fluids`` at j (None: empty); a new curve starts where ``starts`` (M,) is True (several curves
    share one call, so one compiled program of M points serves every curve; pad with a non-finite
    abscissa, which marks a point inadmissible). ``abscissa`` (M,), ordered along each curve, is the
    coordinate the predictor extrapolates in (the swept parameter, or any smooth reparametrisation
    of it); between two points the problem is the linear interpolation of their leaves in it (the
    midpoint of a halved step, the differences of the tangent). ``order`` (static): the Bessel order of the
    paper's coupling, or ``"n"`` for the traced ``orders`` (M,) of the points (the paper's ν = n;
    every point of that coupling is scanned, so no order is interpolated). Every point gets the
    roots of :func:`jaxdea.frequencies` there, as on a dispersion curve (module docstring).
    ``decoupled`` (static): the propagations compiled (:func:`_omega_problem`). Returns
    (Ω (M, K), status, scanned, restarted) (:func:`_follow`)."""
    ok, tubes, alphas, fluids = jax.vmap(guard)(tubes, as_float(alphas), fluids)
    abscissa = as_float(abscissa)
    ok &= jnp.isfinite(abscissa)
    ok, m_safe = _family_order(ok, m, fluids, family)
    orders = as_float(orders) if order == "n" else jnp.zeros_like(abscissa)
    starts = jnp.asarray(starts, bool)
    points, moved = _path_points((tubes, alphas, fluids), abscissa, starts)
    conservative = not Face.of(fluids).has_poles

    def problem(x, s):
        tube, a, fluid = moved(x[0], s)
        return discretize(tube, n_layers), a, fluid, x[1] if order == "n" else order

    return _follow(*_omega_problem(problem, n_roots, m_safe, family, decoupled), (points, orders),
                   abscissa, ok, starts, n_roots, conservative)


solve_path = cached_jit(path_unchecked,
                         static_argnames=("n_roots", "n_layers", "order", "family", "decoupled"))


def dispersion_curve(tube: Tube, alpha, fluid: Fluid | None = None, n_roots: int = 3,
                     n_layers: int | None = None, scheme: str | None = None, m=0,
                     torsional: bool = False, outer: Fluid | None = None) -> Curve:
    """The ``n_roots`` lowest frequencies at every α̂ of a grid, by certified continuation.

    The roots at each α̂ are those of :func:`jaxdea.frequencies` (search range ``omega_max=None``),
    found by Newton from an extrapolation of the previous α̂ and checked (module docstring); the
    guaranteed scan runs at the first α̂ and where a step and its two halves fail the checks. An
    ordered grid fine enough to resolve the branches makes most steps cheap; any grid gives correct
    roots. Derivatives are implicit, as for ``frequencies``.

    Args:
        tube: the :class:`~jaxdea.Tube`.
        alpha: the grid α̂, a 1-D array of finite values >= 1e-12 (ordered for continuation).
        fluid: a :class:`~jaxdea.Fluid` or None (empty tube); the ``paper`` coupling needs an
            explicit ``bessel_order`` (one order for the whole curve).
        outer: a surrounding :class:`~jaxdea.Fluid` (unbounded, ``"acoustic"``) or None: the tube's own
            ``tube.outer`` (None: vacuum). Subsonic modes carry its added mass
            (docs/theory/real_tubes.md §6).
        n_roots: K, the number of roots at each α̂ (static).
        n_layers: sublayers N (static), or None: the accurate discretisation (:func:`jaxdea.frequencies`).
        scheme: ``"midpoint"``, ``"magnus4"`` or ``"magnus6"`` (static; :func:`jaxdea.frequencies`).
        m, torsional: circumferential order (int >= 0) and, at m = 0, the torsional family: the
            roots of that order at every α̂ (:func:`jaxdea.frequencies`).

    Returns:
        An instance of :class:`Curve` (omega, status of shape (M, K); ``scanned`` says where the scan ran).

    Raises:
        ValueError: naming the parameter, for invalid concrete inputs (as ``frequencies``; alpha
            must also be 1-D and non-empty).

    Examples:
        >>> c = dispersion_curve(Tube(), np.linspace(0.05, 5, 100), n_roots=4, n_layers=10)
        >>> c.omega.shape, int(c.scanned.sum())   # (100, 4), 1
    """
    tube = with_outer(tube, outer)
    if Face.of(fluid, strict=False).has_poles and fluid.bessel_order is None:
        raise ValueError("fluid.bessel_order must be set for a dispersion curve with the 'paper' "
                         "coupling (one Bessel order for every α̂ of the curve), got None")
    problem = describe(tube, NO_ALPHA, fluid, n_layers, scheme, m, torsional)
    order, family = problem.order, problem.family
    a = validate_alpha(alpha, "alpha", tube, scalar=False)
    if a is not None and (a.ndim != 1 or a.size == 0):
        raise ValueError(f"alpha must be a non-empty 1-D array of axial wavenumbers, got shape {a.shape}")
    n_roots = validate_roots(n_roots)
    tube, alpha, fluid, m = canonical(tube, alpha, fluid, m)
    values = detached((tube, alpha, fluid))
    # a concrete default curve checks its roots as it solves them, so it starts below the rule
    checked = n_layers is None and scheme in (None, AUTO_SCHEME) and _concrete(values, m)
    layers, short = checked_laminate(n_layers, scheme, tube, alpha, n_roots, m, checked=checked)
    # one propagation compiled, not both: V̂ = 0 decouples the electric block (a program each)
    decoupled = decoupled_choice(tube, family)

    arguments = problem.arguments(detached(m))
    if short is None and checked and is_graded(layers):
        def solve(layers):  # the curve and its check's Newton steps, in one program
            return _solve_checked_curve(*values, n_roots, layers, order, **arguments,
                                        decoupled=decoupled)

        curve, short = _checked_curve(solve, solve(layers), layers, values[1])
    else:
        curve = _solve_curve(*values, n_roots, layers, order, **arguments, decoupled=decoupled)
    curve = curve._replace(status=inaccurate_where(short, Roots(curve.omega, curve.status)).status)
    if not traced((tube, alpha, fluid, m)):
        # concrete inputs carry no tangents: the implicit derivatives would leave the values as
        # they are (tracing their attachment over the rows cost 0.4 ms a call, measured)
        return curve
    with_derivatives = jax.vmap(lambda w, s, x: attach_derivatives(Roots(w, s), (tube, x, fluid, m),
                                                                  layers, order, "omega",
                                                                  family).omega)
    # a JAX array: a NumPy grid mapped here beside a traced m or tube failed JAX's check of the
    # custom-derivative constants (AssertionError: non-canonical constant of type ndarray)
    return curve._replace(alpha=alpha, omega=with_derivatives(curve.omega, curve.status,
                                                              jnp.asarray(alpha)))


CHECKED_POINTS = 9
"""Points of a concrete default curve (evenly spread, both ends) whose roots are checked."""


def sampled_newton_steps(tube, alphas, fluid, omegas, n_layers, order, m=0.0, family=LONGITUDINAL,
                         decoupled: bool = False):
    """:func:`jaxdea.solve.roots.newton_steps` at each (α̂, its roots) of a curve's sampled points,
    on one wall: the tube is guarded without its α̂ (whose admissibility does not change the wall,
    only whether a point's steps are NaN), so the wall is formed once, not once per point (a
    guard of each point would batch the tube, and with it the wall)."""
    _, wall_tube, _, _ = guard(tube, 1.0, fluid)
    wall = discretize(wall_tube, n_layers)

    def one(a, w):
        ok, _, a, point_fluid = guard_order(tube, a, fluid, m, family)
        return steps_on_wall(wall, ok, a, point_fluid, w, order, m, family, decoupled)

    return jax.vmap(one)(alphas, omegas)


def checked_points(count: int) -> np.ndarray:
    """The indices of the CHECKED_POINTS points of a grid of ``count`` (evenly spread, both ends)."""
    return np.unique(np.round(np.linspace(0, count - 1, CHECKED_POINTS)).astype(int))


def checked_curve_unchecked(tube, alpha, fluid, n_roots, n_layers, order, m=0.0,
                            family=LONGITUDINAL, decoupled=None):
    """(curve, steps): :func:`curve_unchecked` on ``n_layers`` (graded sixth-order Magnus) and the
    Newton steps of its roots at :func:`checked_points` on the :func:`jaxdea.solve.roots.companion`
    wall (:func:`sampled_newton_steps`), in one program: the check of :func:`_checked_curve` without
    a second dispatch and a wait for the curve in between (as
    :func:`jaxdea.solve.roots.checked_frequencies_unchecked` does for ``frequencies``)."""
    curve = curve_unchecked(tube, alpha, fluid, n_roots, n_layers, order, m, family, decoupled)
    pick = checked_points(jnp.shape(alpha)[0])
    # the check's inputs behind a barrier: XLA then shares none of the curve's work with it
    tube, alpha, fluid, m, omega = jax.lax.optimization_barrier((tube, alpha, fluid, m, curve.omega))
    alpha, omega = as_float(alpha)[pick], omega[pick]
    steps = sampled_newton_steps(tube, alpha, fluid, omega, companion(n_layers), order, m, family,
                                 bool(decoupled))
    return curve, steps


_solve_checked_curve = cached_jit(checked_curve_unchecked,
                                  static_argnames=("n_roots", "n_layers", "order", "family",
                                                   "decoupled"))


def _checked_curve(solve, result, layers, alpha):
    """(curve, short): a concrete default curve checked like the points of
    :func:`jaxdea.solve_frequencies` (:func:`jaxdea.solve.roots._verified`), at CHECKED_POINTS of its
    points (the error varies smoothly along α̂): one Newton step per root on the
    :func:`jaxdea.solve.roots.companion` wall estimates its error; where some exceed 1e-8 the curve
    is solved again on the finer N they ask for; a root index still short at a checked point is
    INACCURATE along the curve. ``solve(layers)`` gives (curve, steps) on ``layers``
    (:func:`checked_curve_unchecked`), ``result`` that of the starting ``layers``: the checked count
    of :func:`jaxdea.physics.transfer.auto_layer_count` (0.45 of the rule, 6 at least), on the grid
    ``alpha``."""
    pick = checked_points(np.shape(alpha)[0])

    def ratio_of(result, layers):
        curve, steps = result
        # picked in NumPy: JAX's eager gathers cost ≈ 0.7 ms each, a tenth of the curve (measured)
        sampled = Roots(np.asarray(curve.omega)[pick], np.asarray(curve.status)[pick])
        return _shortfall(sampled, np.asarray(steps), layers)

    _, (curve, _), ratio = refined(solve, ratio_of, layers, result)
    short = np.broadcast_to(np.any(ratio > 1.0, axis=0), np.shape(curve.omega))
    return curve, (short if short.any() else None)


def critical_path_unchecked(tubes, alphas, abscissa, starts, orders, n_layers, family=ORDER_M,
                            formed=None):
    """The critical voltages V̂_cr (:func:`jaxdea.critical_voltage`) at the M points of a path
    (traceable): the tube ``tubes`` (leaves of shape (M,); their voltage is ignored), α̂ = ``alphas``
    and the circumferential order ``orders`` (M,) of each point (``family`` static), fluid-free
    (fluids do not change V̂_cr).

    The continuation of :func:`path_unchecked` in the unknown V̂ instead of Ω: V̂_cr is the first
    zero of g(V̂) = f(Ω = 0; V̂) in (0, V̂_lim] (:func:`jaxdea.solve.roots.critical_function`), so the checks
    of the module docstring with K = 1 (sign g'(V̂_cr) = −sign g(0): no zero missed below it) hold
    it; g is NaN above the pull-in limit V̂_lim, so a continued V̂_cr never passes it. A step that
    fails the checks is solved by the search of :func:`jaxdea.solve.roots.critical_voltage_unchecked`.
    ``formed`` (optional, a path whose points share one tube): (the wall's expansion in V̂, the
    pull-in limit V̂_lim) of that tube (:func:`jaxdea.physics.transfer.voltage_expansion`,
    :func:`jaxdea.physics.base_state.voltage_limit`), formed once instead of at every evaluation.
    Returns (V̂_cr (M, 1), status, scanned, restarted), as :func:`path_unchecked`."""
    orders = as_float(orders)
    ok, tubes, alphas, _ = jax.vmap(guard)(tubes.replace(voltage=jnp.zeros_like(abscissa)),
                                           as_float(alphas), None)
    abscissa = as_float(abscissa)
    ok &= jnp.isfinite(abscissa) & family.admissible(orders)
    orders = jnp.where(ok, orders, 0.0)
    starts = jnp.asarray(starts, bool)
    points, moved = _path_points((tubes, alphas), abscissa, starts)

    def problem(x, s):
        return (*moved(x[0], s), x[1])

    expansion, limit = (None, None) if formed is None else formed

    def bounded(x, s):  # g, NaN above the pull-in limit
        tube, a, m = problem(x, s)
        _, g, v_end = critical_function(tube, a, None, n_layers, 0, limit, m, family, expansion)
        return lambda v: jnp.where(v <= v_end, g(v), jnp.nan)

    def search(x, s):
        tube, a, m = problem(x, s)
        found = critical_voltage_unchecked(tube, a, None, n_layers, 0, v_end=limit, m=m, family=family,
                                           expansion=expansion)
        return Roots(found.omega[None], found.status[None])

    return _follow(lambda x, s: (lambda v: value_and_slope(bounded(x, s), v)),
                   lambda x, s, v: bounded(x, s)(v), search, (points, orders), abscissa, ok, starts,
                   1, True)


solve_critical_path = cached_jit(critical_path_unchecked, static_argnames=("n_layers", "family"))


def critical_voltages_along(tube, alpha, fluid, m=0.0, *, n_layers, family) -> Roots:
    """(V̂_cr, status) of :func:`jaxdea.critical_voltage` at every α̂ of a batch (M,) of one tube
    (traceable): ``jax.vmap`` of ``critical_voltage`` over α̂ alone comes here, fluid-free
    (:func:`jaxdea.solve.roots.along_alpha`). :func:`critical_path_unchecked` along α̂ where the batch is
    ordered (:func:`ordered`, checked in the program); elsewhere every α̂ starts anew with the
    search of a point alone. The tube's expansion in V̂ and its pull-in limit are formed once."""
    del fluid  # None: a batch with a fluid is mapped (solve_critical_voltage)
    alpha = as_float(alpha)
    _, at_rest, _, _ = guard(tube.replace(voltage=0.0), 1.0, None)  # as critical_function forms it
    formed = (voltage_expansion(at_rest, n_layers), voltage_limit(at_rest))
    tubes = jax.tree_util.tree_map(lambda v: jnp.broadcast_to(as_float(v), alpha.shape), tube)
    voltage, status, _, _ = critical_path_unchecked(
        tubes, alpha, alpha, jnp.full(alpha.shape, ~ordered(alpha)),
        jnp.broadcast_to(as_float(m), alpha.shape), n_layers, family, formed)
    return Roots(voltage[:, 0], status[:, 0])


BATCH_ENGINES.update(frequencies=frequencies_along, frequency=frequency_along,
                     critical_voltage=critical_voltages_along)
