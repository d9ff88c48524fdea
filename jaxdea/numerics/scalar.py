"""Scalar root tools shared by every solver: status codes, sign-change bracketing on a grid,
safeguarded Newton, and implicit-function derivatives.

All functions are written for one case and are jit/vmap safe: no Python control flow on values,
failures give NaN and a status code instead of an exception.
"""

import enum
import functools
from typing import NamedTuple

import jax
import jax.numpy as jnp

from ..compiled import jit, materialized

ROOT_RTOL = 1e-4
"""Largest relative distance |f/f'|/|Ω| of an ``omega`` passed as a root (mode shapes, group
velocity, tunability) from a root of the characteristic function of the discretisation it is used
with (one Newton step: the residual against its own scale). A root of any discretisation that
resolves the tube to better than 1e-4 (the paper's midpoint N = 30: about 1e-5) passes; Ω = 0.123 at
α̂ = 0.4 (no root nearby) is ≈ 0.3 away."""


def newton_distance(value, slope, x):
    """|f(x)|/(|f'(x)| |x|): the relative size of the Newton step from x to the nearest root (0 at a
    root; inf where f'x = 0; at x = 0, where f' = 0 by symmetry, 0 if |f| ≤ 1e-12 (f is normalised,
    |f| ≤ 1), else inf; NaN where f is not finite). Compared with :data:`ROOT_RTOL`."""
    size = jnp.abs(slope) * jnp.abs(x)
    at_zero = jnp.where(jnp.abs(value) <= 1e-12, 0.0, jnp.inf)
    return jnp.where(x == 0.0, at_zero, jnp.abs(value) / jnp.where(size > 0, size, 1.0)
                     + jnp.where(size > 0, 0.0, jnp.inf))


def refuse_non_root(omega, distance, case: str = "", advice: str = "") -> None:
    """ValueError where a concrete ``omega`` is farther than :data:`ROOT_RTOL` from a root
    (``distance`` of :func:`newton_distance`); nothing for traced values (the callers give NaN)."""
    if isinstance(omega, jax.core.Tracer) or isinstance(distance, jax.core.Tracer):
        return
    if not float(distance) <= ROOT_RTOL:
        raise ValueError(f"omega = {float(omega)!r} is not a root of the characteristic "
                         f"function{case} (a Newton step moves it by {float(distance):.2g} of itself, above "
                         f"{ROOT_RTOL:g}): pass a root from jaxdea.frequency or jaxdea.frequencies"
                         f"{advice}")


class Status(enum.IntEnum):
    """Status code of a solve (stored as int32 arrays)."""

    CONVERGED = 0  # a root, refined to full precision
    NO_ROOT = 1  # no (further) root in the searched range
    NOT_FINITE = 2  # a non-finite function value (overflow, expm failure, locking) stopped the search
    MAX_ITER = 3  # the iteration limit was reached before convergence
    INVALID = 4  # inputs outside their allowed range (what validation rejects, met under jit/vmap)
    INACCURATE = 5  # a root, but not to the accuracy asked for (its value kept): a tolerance of
    # accuracy.frequencies_with_error, or the default discretisation's 1e-8 at a point for which its
    # rule asks more sublayers than it has (traced inputs fix N = 16; transfer.checked_laminate)
    SUSPECT = 6  # a root whose slope sign repeats that of the root below it: a root is missing
    # between them (or one of them is not the root its interval held), so its index is unknown
    NOT_SOLVED = 7  # not computed: the run was interrupted before this point (jaxdea.sweep)


def value_and_slope(fun, x):
    """(f(x), f'(x)) with one forward-mode pass."""
    return jax.jvp(fun, (x,), (jnp.ones_like(x),))


NEWTON_SCALE_RATIO = 8.0
""":func:`newton_slope` steps on F where that step is more than this many times shorter than f's."""


def newton_slope(f, df, dlog_scale):
    """The slope that Newton steps with on f = F e^{−ℓ} (F = f e^ℓ the unnormalised determinant,
    ℓ its log-scale, f' and ℓ' their slopes): f' + f ℓ' = F' e^{−ℓ}, whose step −f/(f' + f ℓ') =
    −F/F' is Newton's on F, where that step is more than :data:`NEWTON_SCALE_RATIO` times shorter
    than the step −f/f' on f (|f' + f ℓ'| > 8 |f'|); f' itself elsewhere.

    Where e^ℓ dips to almost zero (A S nearly rank-deficient: the inner-face waves of a thick wall
    at large α̂ĥ) f turns sign in a near-jump instead of passing through zero (±7.1e-3 on either
    side of the root near Ω = 61.468 of η = 0.3 at α̂ĥ = 150, where ℓ' ≈ 1/(Ω − Ω₀)): the step
    on f points to the zero of f's continuous part, 0.086 away, and Newton from 2e-11 of that root
    went to the root below it. F has an ordinary simple root there, and its step is the shorter
    one within about 0.086/8 of the root (by 46 at Ω₀ + 0.002, by 10 at Ω₀ − 0.008). Near an
    ordinary root f → 0 and the two steps agree, so the iterations are those on f, bit for bit.
    Far from a root the steps on f and F both merely head somewhere; f's is kept unless F's is
    much shorter (a factor 6 at Ω = 0.3 of the golden file's acoustic case, whose Newton goes on
    to its root 0.768, as before, not to the nearer 0.1176). NaN ℓ' keeps f'."""
    scaled = df + f * dlog_scale
    return jnp.where(jnp.abs(scaled) > NEWTON_SCALE_RATIO * jnp.abs(df), scaled, df)


@functools.partial(jax.custom_jvp, nondiff_argnums=(0,))
def attach_implicit(residual, x, params):
    """Roots ``x`` of residual(x, params) = 0 (solved without derivatives) with the
    implicit-function derivatives ẋ = −(∂f/∂θ · θ̇)/(∂f/∂x) attached: the one mechanism of every
    solver (roots, critical voltages, the base state, design, fit through the roots).

    ``residual(y, params)`` is scalar in y (an array ``x`` holds independent roots of one
    ``params``, a pytree) and hashable: the tangent program is compiled once per residual (a
    value-equal object such as :class:`jaxdea.solve.roots.Residual` hits the cache across calls). The
    iterations that found ``x`` are never differentiated; first and higher derivatives work in
    forward and reverse mode (the rule re-attaches x, so differentiating it sees dx/dθ too)."""
    del residual, params
    return x


@attach_implicit.defjvp
def _attach_implicit_jvp(residual, primals, tangents):
    x, params = primals
    _, dparams = tangents
    x = attach_implicit(residual, x, params)
    return x, root_tangent(residual, x, params, dparams)


@jit(static_argnums=(0,))
def root_tangent(residual, x, params, dparams):
    """ẋ = −(∂f/∂θ · θ̇)/(∂f/∂x) at roots x of ``residual`` (vectorised over an array x)."""
    def one(x):
        # a NaN root (padding, a failed solve) gets a zero tangent, not NaN: under reverse mode a
        # NaN coefficient would spoil the cotangent of every other root (0 · NaN = NaN)
        found = jnp.isfinite(x)
        x = jnp.where(found, x, 1.0)
        f_x = value_and_slope(lambda y: residual(y, params), x)[1]
        _, f_dot = jax.jvp(lambda p: residual(x, p), (params,), (dparams,))
        return jnp.where(found, -f_dot / jnp.where(found, f_x, 1.0), 0.0)

    return jax.vmap(one)(x) if jnp.ndim(x) else one(x)


def with_implicit_derivatives(residual, x, params):
    """:func:`attach_implicit` of the values of ``x`` (its own derivatives dropped)."""
    return attach_implicit(residual, jax.lax.stop_gradient(x), params)


def implicit_root(fun, solve, x0):
    """A root x* of ``fun`` with implicit-function derivatives, dx*/dθ = −(∂f/∂θ)/(∂f/∂x).

    ``fun`` may close over traced parameters θ (hoisted by ``jax.closure_convert`` and passed to
    :func:`attach_implicit`); ``solve()`` returns ``(x*, status)`` (its own derivatives are never
    used: no differentiation through the iterations); ``x0`` only fixes the shape and dtype.

    Returns:
        (x*, status).
    """
    x, status = solve()
    converted, consts = jax.closure_convert(fun, x0)
    x = with_implicit_derivatives(_Converted(converted), x, tuple(consts))
    return x, jax.lax.stop_gradient(jnp.asarray(status)).astype(jnp.int32)


class _Converted(NamedTuple):
    """residual(y, consts) of a closure-converted function (hashable for :func:`attach_implicit`)."""

    fun: object

    def __call__(self, y, consts):
        return self.fun(y, *consts)


# ------------------------------------------------------------------------- vectorised lane solver
IDLE, EXTREMUM, BRACKET, FREE = 0, 1, 2, 3
PRIOR_MARGIN = 1.0 / 16.0  # a prior curvature must promise an error ≤ this share of the tolerance


class Lanes(NamedTuple):
    """State of a batch of scalar solves that share one evaluation of (f, f') per iteration.

    mode: IDLE (finished), EXTREMUM (Illinois on f' inside [a, b], then split into the root
    bracket on this lane's ``side``), BRACKET (safeguarded Newton inside [neg, pos]) or FREE
    (Newton from a guess with capped steps until two iterates bracket a sign change).
    """

    mode: jax.Array
    side: jax.Array  # EXTREMUM lanes: 0 takes [a, x_ext], 1 takes [x_ext, b]
    a: jax.Array  # original interval and f, f' at its ends
    b: jax.Array
    fa: jax.Array
    fb: jax.Array
    dfa: jax.Array
    dfb: jax.Array
    lo: jax.Array  # current bracket (EXTREMUM: on f'; BRACKET: f(lo) < 0 < f(hi))
    hi: jax.Array
    glo: jax.Array  # f' at lo, hi (EXTREMUM only; Illinois-weighted)
    ghi: jax.Array
    last: jax.Array  # Illinois: which end was kept last time
    x: jax.Array
    fx: jax.Array
    dfx: jax.Array
    step: jax.Array
    step_old: jax.Array
    max_step: jax.Array  # FREE lanes: step cap
    guess: jax.Array  # BRACKET lanes: the next point to evaluate, if finite (Hermite-cubic root)
    key: jax.Array  # sort key of the root (inf: none)
    status: jax.Array
    curvature: jax.Array  # K = |f''/(2f')| from the last two iterates; a FREE lane may start with a prior


def _hermite_cubic(a, b, fa, fb, dfa, dfb):
    """h = b − a and the coefficients c₁, c₂, c₃ of p(t) = f_a + c₁t + c₂t² + c₃t³ (:func:`hermite_root`)."""
    h = b - a
    return h, h * dfa, 3.0 * (fb - fa) - h * (2.0 * dfa + dfb), 2.0 * (fa - fb) + h * (dfa + dfb)


def hermite_root(a, b, fa, fb, dfa, dfb, iterations: int = 8):
    """The root in [a, b] of the cubic Hermite interpolant of (f, f') at a and b (f(a)·f(b) ≤ 0).

    p(t) = f_a + h f'_a t + (3(f_b − f_a) − h(2f'_a + f'_b)) t² + (2(f_a − f_b) + h(f'_a + f'_b)) t³,
    h = b − a, found by safeguarded Newton in t ∈ [0, 1] from the secant point (cheap scalar
    work). The interpolation error is O(h⁴ f⁽⁴⁾): close enough for Newton on f to converge
    quadratically from the first step. NaN where the data are not finite or have no sign change,
    or where the cubic's root is an end point (f there is already known).
    """
    h, c1, c2, c3 = _hermite_cubic(a, b, fa, fb, dfa, dfb)
    neg_at_0 = fa < 0
    t_neg, t_pos = jnp.where(neg_at_0, 0.0, 1.0), jnp.where(neg_at_0, 1.0, 0.0)
    t = jnp.where(fa != fb, fa / (fa - fb), 0.5)
    for _ in range(iterations):
        p = ((c3 * t + c2) * t + c1) * t + fa
        dp = (3.0 * c3 * t + 2.0 * c2) * t + c1
        t_neg, t_pos = jnp.where(p < 0, t, t_neg), jnp.where(p > 0, t, t_pos)
        newton = t - p / dp
        inside = (newton - t_neg) * (newton - t_pos) <= 0  # in the bracket (its end: converged)
        t = jnp.where(p == 0, t, jnp.where(inside, newton, 0.5 * (t_neg + t_pos)))
    x = a + h * t
    ok = (fa * fb <= 0) & jnp.isfinite(x) & (x != a) & (x != b) & (t > 0) & (t < 1)
    return jnp.where(ok, x, jnp.nan)


def hermite_extremum(a, b, fa, fb, dfa, dfb):
    """The stationary point in (a, b) of the cubic Hermite interpolant p of :func:`hermite_root`
    (f'(a)·f'(b) < 0): the root in (0, 1) of p'(t) = c₁ + 2c₂t + 3c₃t² by the stable
    quadratic formula; the midpoint where that is not finite or not inside."""
    h, c1, c2, c3 = _hermite_cubic(a, b, fa, fb, dfa, dfb)
    qa, qb, qc = 3.0 * c3, 2.0 * c2, c1
    root = jnp.sqrt(jnp.maximum(qb * qb - 4.0 * qa * qc, 0.0))
    q = -0.5 * (qb + jnp.where(qb >= 0, root, -root))
    t1, t2 = q / qa, qc / q
    t = jnp.where((t1 > 0) & (t1 < 1), t1, t2)
    t = jnp.where(jnp.isfinite(t) & (t > 0) & (t < 1), t, 0.5)
    return a + h * t


def _enter_bracket(lanes, mask, a, b, fa, fb, dfa, dfb):
    """Switch the masked lanes to BRACKET on [a, b] (f(a)·f(b) ≤ 0), at the end with the smaller
    |f| (its slope is known, so no extra evaluation is needed); the first point evaluated is the
    root of the Hermite cubic through both ends (:func:`hermite_root`)."""
    start_a = jnp.abs(fa) <= jnp.abs(fb)
    neg = jnp.where(fa < 0, a, b)
    pos = jnp.where(fa < 0, b, a)
    width = jnp.abs(b - a)
    upd = dict(
        mode=jnp.where(mask, BRACKET, lanes.mode),
        lo=jnp.where(mask, neg, lanes.lo),
        hi=jnp.where(mask, pos, lanes.hi),
        x=jnp.where(mask, jnp.where(start_a, a, b), lanes.x),
        fx=jnp.where(mask, jnp.where(start_a, fa, fb), lanes.fx),
        dfx=jnp.where(mask, jnp.where(start_a, dfa, dfb), lanes.dfx),
        step=jnp.where(mask, width, lanes.step),
        step_old=jnp.where(mask, 2.0 * width, lanes.step_old),
        key=jnp.where(mask, 0.5 * (a + b), lanes.key),
        guess=jnp.where(mask, hermite_root(a, b, fa, fb, dfa, dfb), lanes.guess),
    )
    return lanes._replace(**upd)


def start_lanes(a, b, fa, fb, dfa, dfb, kind, max_step=None, pairs=True):
    """Lanes for candidate intervals: kind 1 = sign change (one root), 2 = hidden pair (two lanes
    each, left and right of the extremum), 3 = FREE Newton from ``a`` (guess), 0 = nothing.

    Inputs have shape (n,); the lanes have shape (2n,) (lane 2i and 2i+1 serve candidate i). With
    ``pairs=False`` (no kind 2 among the candidates) one lane serves each candidate, shape (n,):
    every lane is then evaluated for a purpose (idle lanes cost a full evaluation under ``vmap``).
    """
    copies = 2 if pairs else 1
    rep = lambda v: jnp.repeat(jnp.asarray(v, jnp.float64), copies)  # noqa: E731
    a, b, fa, fb, dfa, dfb = map(rep, (a, b, fa, fb, dfa, dfb))
    kind = jnp.repeat(kind, copies)
    side = jnp.tile(jnp.arange(copies), kind.shape[0] // copies)
    return lanes_from_slots(a, b, fa, fb, dfa, dfb, kind, side,
                            None if max_step is None else rep(max_step))


def lanes_from_slots(a, b, fa, fb, dfa, dfb, kind, side, max_step=None, curvature=None):
    """Lanes with one slot each: the candidate's interval data, its ``kind`` (as in
    :func:`start_lanes`) and the ``side`` of a hidden pair this lane takes (0: left, 1: right).
    FREE and sign-change candidates run on their side-0 lane only. ``curvature``: a prior K for
    FREE lanes (:func:`iterate_lanes`), NaN (none) by default."""
    a, b, fa, fb, dfa, dfb = (jnp.asarray(v, jnp.float64) for v in (a, b, fa, fb, dfa, dfb))
    max_step = jnp.full_like(a, jnp.inf) if max_step is None else max_step
    mode = jnp.where((kind == 2) | ((kind == 3) & (side == 0)), jnp.where(kind == 2, EXTREMUM, FREE),
                     IDLE)
    lanes = Lanes(
        mode=mode, side=side, a=a, b=b, fa=fa, fb=fb, dfa=dfa, dfb=dfb,
        lo=a, hi=b, glo=dfa, ghi=dfb, last=jnp.zeros_like(side),
        x=a, fx=fa, dfx=dfa, step=jnp.abs(b - a), step_old=2.0 * jnp.abs(b - a),
        max_step=max_step, guess=jnp.full_like(a, jnp.nan), key=jnp.full_like(a, jnp.inf),
        status=jnp.full(a.shape, Status.NO_ROOT, jnp.int32),
        curvature=jnp.full_like(a, jnp.nan) if curvature is None else curvature,
    )
    return _enter_bracket(lanes, (kind == 1) & (side == 0), a, b, fa, fb, dfa, dfb)


def run_lanes(fun, lanes: Lanes, rtol=1e-15, max_iter=200, slopes: bool = False,
              with_slope: bool = False):
    """The roots of :func:`iterate_lanes`: ``(roots, keys, status)``, roots NaN unless converged;
    keys order them (inf = no root). ``slopes``: also f' at each lane's last evaluated point (at a
    converged lane, f' at the root to within its last step). ``with_slope`` (static): ``fun``
    returns (f, f') itself, as for :func:`iterate_lanes`."""
    lanes = iterate_lanes(fun, lanes, rtol, max_iter, with_slope)
    roots = jnp.where(lanes.status == Status.CONVERGED, lanes.x, jnp.nan)
    fallback = jnp.where(jnp.isfinite(lanes.key), lanes.key, 0.5 * (lanes.a + lanes.b))
    keys = jnp.where(lanes.status == Status.NO_ROOT, jnp.inf, fallback)
    return (roots, keys, lanes.status) + ((lanes.dfx,) if slopes else ())


def iterate_lanes(fun, lanes: Lanes, rtol=1e-15, max_iter=200, with_slope=False) -> Lanes:
    """Iterate all lanes until every one is IDLE; one vectorised (f, f') evaluation per iteration.

    BRACKET lanes follow Numerical Recipes' rtsafe (a Newton step that leaves the bracket or does
    not halve the previous step becomes a bisection): guaranteed convergence, quadratic near a
    simple root. EXTREMUM lanes use Illinois regula falsi on f'. FREE lanes take Newton steps capped
    at ``max_step`` (f is even in Ω, so iterates stay positive) and hand over to BRACKET as soon as
    two iterates bracket a sign change, unless the stopping test below already holds at the new
    iterate (the last Newton step is then applied inside the two iterates: one evaluation fewer).

    A BRACKET lane evaluates the root of the Hermite cubic of its interval first
    (:func:`hermite_root`), then goes on with Newton.

    Stopping: a step ≤ rtol·|x| (not counting the step to the Hermite guess), f = 0, a bracket
    narrower than rtol·|x|, a Newton step below the float spacing at x (the proposal is x itself),
    or a next Newton step |f/f'| that is ≤ rtol·|x| or leaves an error K·(f/f')² ≤ rtol·|x| (K =
    |f''/(2f')| from the slopes of the last two iterates, trusted where f' changed by ≤ 20 % between
    them); that step is then applied without another evaluation (quadratic convergence: the root to
    rounding, one evaluation fewer than waiting for a step below rtol·|x|). A FREE lane started with
    a finite ``curvature`` (a prior K, e.g. that of the same branch at the previous point of a
    continuation) may stop so at its first evaluation, where K·(f/f')² ≤ PRIOR_MARGIN·rtol·|x| and
    K·|f/f'| ≤ 0.05; every lane's ``curvature`` ends as the last K it measured (or its prior).

    IDLE lanes are evaluated too, at their x (their fx, dfx then hold f, f' there).
    ``with_slope`` (static): ``fun`` returns (f(x), f'(x)) itself (e.g.
    :func:`jaxdea.physics.dispersion.value_and_slope_on_wall`) instead of f alone, differentiated forward.

    Returns:
        the final lanes: status MAX_ITER where a lane was still running; x, fx, dfx the last
        iterate and f, f' at the last point evaluated.
    """
    evaluate = jax.vmap(fun if with_slope else (lambda x: value_and_slope(fun, x)))

    def cond(c):
        lanes, it = c
        return jnp.any(lanes.mode != IDLE) & (it < max_iter)

    def body(c):
        s, it = c
        # proposals
        newton = s.x - s.fx / s.dfx
        lo_, hi_ = jnp.minimum(s.lo, s.hi), jnp.maximum(s.lo, s.hi)
        use_newton = (newton > lo_) & (newton < hi_) & jnp.isfinite(newton)
        use_newton &= jnp.abs(2.0 * s.fx) <= jnp.abs(s.step_old * s.dfx)
        x_bracket = jnp.where(use_newton, newton, 0.5 * (s.lo + s.hi))
        # an exact zero, or a Newton step below the spacing of floats at x (x can be a bracket end,
        # where the strict test above would fall back to bisection): x is the root
        x_bracket = jnp.where((s.fx == 0) | (newton == s.x), s.x, x_bracket)
        from_guess = (s.mode == BRACKET) & jnp.isfinite(s.guess)
        x_bracket = jnp.where(from_guess, s.guess, x_bracket)
        secant = jnp.where(s.ghi != s.glo, s.hi - s.ghi * (s.hi - s.lo) / (s.ghi - s.glo), 0.5 * (s.lo + s.hi))
        x_extremum = jnp.where((secant > lo_) & (secant < hi_), secant, 0.5 * (s.lo + s.hi))
        fresh = jnp.isnan(s.fx)  # a FREE lane's guess has not been evaluated yet
        x_free = jnp.where(fresh, s.x,
                           jnp.abs(s.x + jnp.clip(-s.fx / s.dfx, -s.max_step, s.max_step)))
        x_new = jnp.select([s.mode == BRACKET, s.mode == EXTREMUM, s.mode == FREE],
                           [x_bracket, x_extremum, x_free], s.x)
        x_new = materialized(x_new)
        f_new, df_new = evaluate(x_new)
        f_new, df_new = materialized((f_new, df_new))
        finite = jnp.isfinite(f_new) & jnp.isfinite(df_new)
        scale = jnp.maximum(jnp.abs(x_new), 1e-3 * jnp.abs(s.b - s.a))
        tol = rtol * scale

        # BRACKET update
        in_bracket = s.mode == BRACKET
        lo = jnp.where(in_bracket & (f_new < 0), x_new, s.lo)
        hi = jnp.where(in_bracket & (f_new > 0), x_new, s.hi)
        step_new = jnp.abs(x_new - s.x)
        # the Newton step from x_new is below tol: x_new − f/f' is the root to rounding (quadratic
        # convergence), no further evaluation needed
        last_step = -f_new / df_new
        # or the step is small enough that the error left after it, ≈ K·step² with the curvature
        # K = |f''/(2f')| estimated from the slopes at x and x_new, is below tol (quadratic
        # convergence; trusted only where K·|x_new − x| ≤ 0.1, i.e. f' varies by ≤ 20 % between)
        curvature = jnp.abs(df_new - s.dfx) / (2.0 * jnp.abs(df_new) * step_new)
        trusted = (curvature * step_new <= 0.1) & (step_new > 0)
        settled = (curvature * last_step**2 <= tol) & trusted
        # a FREE lane's first evaluation, with a prior K (continuation: K of the same branch at
        # the previous α̂): finished if that K leaves an error far below tol after the step
        prior = fresh & (s.mode == FREE) & (s.curvature * last_step**2 <= PRIOR_MARGIN * tol)
        prior &= s.curvature * jnp.abs(last_step) <= 0.05
        finish_step = finite & ((jnp.abs(last_step) <= tol) | settled | prior)
        # (a step from the guess is no Newton step: its length says nothing of convergence)
        converged = in_bracket & (((step_new <= tol) & ~from_guess) | (f_new == 0)
                                  | (jnp.abs(hi - lo) <= tol) | finish_step)

        # EXTREMUM update (Illinois on f')
        in_ext = s.mode == EXTREMUM
        same = jnp.sign(df_new) == jnp.sign(s.ghi)
        e_lo = jnp.where(same, s.lo, s.hi)
        g_lo = jnp.where(same, jnp.where(s.last == 1, 0.5 * s.glo, s.glo), s.ghi)
        last = jnp.where(same, 1, -1)
        ext_done = in_ext & ((jnp.abs(x_new - e_lo) <= 1e2 * tol) | (df_new == 0))

        # FREE update
        in_free = s.mode == FREE
        # a FREE lane whose last step crossed the root finishes like a BRACKET lane when the next
        # Newton step is converged (kept inside [x, x_new]); otherwise it enters that bracket
        sign_change = in_free & (jnp.sign(f_new) * jnp.sign(s.fx) < 0)
        free_done = in_free & (((step_new <= tol) & ~fresh & ~sign_change) | (f_new == 0)
                               | finish_step)
        crossed = sign_change & ~free_done
        # read by most of the lane state below: formed once (compiled.materialized)
        last_step, curvature = materialized((last_step, curvature))
        flags = materialized(jnp.stack([converged, free_done, finish_step, ext_done, crossed, trusted,
                                        sign_change]).astype(jnp.float64)) > 0.5
        converged, free_done, finish_step, ext_done, crossed, trusted, sign_change = flags

        s = s._replace(
            lo=jnp.where(in_ext, e_lo, lo), hi=jnp.where(in_ext, x_new, hi),
            glo=jnp.where(in_ext, g_lo, s.glo), ghi=jnp.where(in_ext, df_new, s.ghi),
            last=jnp.where(in_ext, last, s.last),
            step_old=jnp.where(in_bracket | in_free, s.step, s.step_old),
            step=jnp.where(in_bracket | in_free, step_new, s.step),
        )
        x_prev, f_prev, df_prev = s.x, s.fx, s.dfx
        # converged lanes take the last Newton step (kept inside the bracket for BRACKET lanes)
        x_last = x_new + jnp.where(finish_step & (f_new != 0), last_step, 0.0)
        # (a FREE lane that finished across a sign change stays between its last two iterates)
        x_free = jnp.where(sign_change, jnp.clip(x_last, jnp.minimum(x_prev, x_new),
                                                 jnp.maximum(x_prev, x_new)), x_last)
        x_done = jnp.where(converged, jnp.clip(x_last, jnp.minimum(lo, hi), jnp.maximum(lo, hi)),
                           jnp.where(free_done, x_free, x_new))
        s = s._replace(x=x_done, fx=f_new, dfx=df_new, guess=jnp.full_like(s.guess, jnp.nan),
                       curvature=jnp.where(trusted & jnp.isfinite(curvature), curvature, s.curvature))

        # extremum found: split into the two root brackets if f changes sign there
        pair = ext_done & (jnp.sign(f_new) != jnp.sign(s.fa))
        left = s.side == 0
        s = _enter_bracket(
            s, pair,
            jnp.where(left, s.a, x_new), jnp.where(left, x_new, s.b),
            jnp.where(left, s.fa, f_new), jnp.where(left, f_new, s.fb),
            jnp.where(left, s.dfa, df_new), jnp.where(left, df_new, s.dfb),
        )
        s = _enter_bracket(s, crossed, x_prev, x_new, f_prev, f_new, df_prev, df_new)

        ok = converged | free_done
        failed = (s.mode != IDLE) & ~finite & ~pair
        status = jnp.where(ok, Status.CONVERGED, jnp.where(failed, Status.NOT_FINITE, s.status))
        key = jnp.where(free_done, x_done, s.key)
        mode = jnp.where(ok | failed | (ext_done & ~pair), IDLE, s.mode)
        return s._replace(mode=mode, status=status.astype(jnp.int32), key=key), it + 1

    lanes, _ = jax.lax.while_loop(cond, body, (lanes, 0))
    status = jnp.where(lanes.mode != IDLE, Status.MAX_ITER, lanes.status).astype(jnp.int32)
    return lanes._replace(status=status)


def bracketed_root(fun, lo, hi, f_lo, f_hi, df_lo=None, df_hi=None):
    """Root of ``fun`` in [lo, hi] (f(lo)·f(hi) ≤ 0) by one BRACKET lane of :func:`run_lanes`.

    ``df_lo``, ``df_hi``: f' at the ends where the caller has them (else evaluated here: two more
    copies of f' in the compiled program).

    Returns:
        (x, status): NaN and NO_ROOT / NOT_FINITE unless converged.
    """
    one = lambda v: jnp.reshape(jnp.asarray(v, jnp.float64), (1,))  # noqa: E731
    if df_lo is None or df_hi is None:
        df_lo, df_hi = (value_and_slope(fun, x)[1] for x in (lo, hi))
    bracketed = (jnp.sign(f_lo) * jnp.sign(f_hi) <= 0) & jnp.isfinite(f_lo) & jnp.isfinite(f_hi)
    lanes = start_lanes(one(lo), one(hi), one(f_lo), one(f_hi), one(df_lo), one(df_hi),
                        jnp.where(bracketed, 1, 0)[None], pairs=False)
    roots, _, status = run_lanes(fun, lanes)
    finite = jnp.isfinite(f_lo) & jnp.isfinite(f_hi)
    status = jnp.where(bracketed, status[0], jnp.where(finite, Status.NO_ROOT, Status.NOT_FINITE))
    return roots[0], status.astype(jnp.int32)
