"""Branch tracing: pseudo-arclength continuation of one dispersion branch Ω(s) along a parameter s.

A branch is a connected curve of the zero set of f(s, Ω) = 0, with f the characteristic function of
:mod:`jaxdea.physics.dispersion` and s any named parameter of :mod:`jaxdea.physics.leaves`
(α̂, V̂, λ_i, h/R_i, ρ̂_f, …). Following a curve instead of re-solving at every s keeps the identity of
a mode through veerings, where two branches come within a tiny gap and "the k-th root" jumps from
one to the other.

Coordinates. The trace runs in scaled coordinates x = (x_s, x_Ω),

    s = s_0 + S x_s,    Ω = Ω_ref + W x_Ω,    S = stop − s_0  (signed: stop is at x_s = 1),
    W = |Ω_0| + min(|dΩ/ds|_0 · |S|, 100 |Ω_0|),

so that the traced range is the unit interval in x_s and the frequency moves by O(1) in x_Ω. |Ω_0|
makes steps and tolerances relative to the frequency (a flat branch is still resolved to its own
size); |dΩ/ds|_0·|S| is the change the start tangent predicts over the whole range (a steep branch
is not squeezed onto a few points); the cap stops a start close to a vertical tangent (f_Ω ≈ 0)
from flattening the rest of the trace. Step lengths h, the corrector distance and the tangent
angle are measured in x.

Tangent. With g = ∇_x f = (S f_s, W f_Ω), the unit tangent of the level curve is

    t = σ (g_Ω, −g_s) / |g|,

with the orientation σ = ±1 fixed once at the start so that t_s > 0 (towards ``stop``). t is a
continuous function of g along a simple branch, and consecutive roots in Ω of a simple branch
family have f_Ω of alternating sign: a step that lands on a neighbouring branch shows up as
t_new · t_old < 0. A turning point (ds/dσ = 0, f_Ω = 0 with f_s ≠ 0) is where t_s changes sign.

Step. Predictor x_p = x + h t; corrector: Newton on the 2×2 system

    f(x) = 0,    t · (x − x_p) = 0,

with ∇f by forward-mode autodiff (two tangents, one primal). The step is accepted if the corrector
converges (|Δx|∞ ≤ 1e-10, then the last update is applied: quadratic convergence puts the point at
rounding level) within ``CORRECTOR_ITERATIONS``, |x − x_p| ≤ κh (κ = ``DISTANCE_RATIO``) and
t_new · t_old ≥ cos θ_max (θ_max = ``MAX_ANGLE_DEGREES``); otherwise h is halved. After an easy step
(≤ ``EASY_ITERATIONS`` iterations, turning angle ≤ θ_max/2) h grows by ``GROWTH`` up to
``max_step``. h < ``MIN_STEP`` ends the trace (STEP_TOO_SMALL, or NOT_FINITE when the last attempt
met a non-finite f: the trace then ends as close to the edge of the finite region as MIN_STEP
allows: near a hard edge the accepted steps shrink geometrically, a few dozen points).

Events (the trace ends at the first one, see :class:`BranchEnd`):

1. ``stop``: when the predictor (or the corrected point) would pass x_s = 1, the step is shortened
   to x_p = x + ((1 − x_s)/t_s) t and corrected at fixed s = stop (second equation x_s = 1).
2. Turning point, t_s < 0 after a step from a to b: the point with f = 0 and f_Ω = 0 (t_s ∝ f_Ω).
   It is found on the arc between a and b, parametrised by the chord, x(τ) = the root of
   {f(x) = 0, (b − a)·(x − a − τ(b − a)) = 0} (the same corrector, unique for a step that turns by
   less than θ_max), by Illinois regula falsi on t_s(x(τ)) from t_s(a) > 0 > t_s(b), until
   |t_s| ≤ 1e-14 or the τ-bracket is below 1e-12. Newton on the augmented system {f, f_Ω} would
   need the second derivatives of the characteristic function, whose forward-over-forward program
   takes about three times as long to compile (22 s against 7 s for f and ∇f, measured); the
   converged point satisfies the same two equations.
3. Zero frequency, Ω changed sign after a step: f is even in Ω, so the branch meets Ω = 0 with a
   vertical tangent and continues into its mirror image −Ω(s). s* is located by Newton on
   f(s, 0) = 0 (the corrector with second equation Ω = 0) and the trace ends at (s*, 0).

f and ∇f are evaluated in one place (the corrector) for the start, the steps and the events, so the
compiled program holds one copy of the characteristic function and its tangent.

Limits. The orientation test catches a jump to an adjacent branch; a step that skipped two branches
(same orientation) is caught only by the distance and angle tests, which is why steps are capped
at ``max_step`` of the range. An exact crossing (∇f = 0) has no tangent: the trace creeps towards
it and ends with STEP_TOO_SMALL (or MAX_POINTS). Veerings are followed down to gaps of order
MIN_STEP·W (tested to relative gaps of 1e-5).

Everything runs in one ``jax.lax.while_loop`` with fixed-size buffers, so a trace is jit-compiled
once per static configuration (``along``, ``max_points``, ``n_layers``, coupling) and works under
``jax.vmap``. The continuation core :func:`continue_branch` works on any scalar f(s, Ω).
"""

import enum
import math
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from ..compiled import cached_jit, serializable
from ..numerics.scalar import NEWTON_SCALE_RATIO
from ..params import (
    Fluid,
    Tube,
    as_float,
    canonical,
    validate_alpha,
    validate_fluid,
    validate_positive,
    validate_real,
    validate_tube,
    with_outer,
)
from ..physics import characteristic
from ..physics.leaves import FLUID_LEAVES, check_names, get_parameter, set_parameter
from ..physics.problem import describe
from ..physics.state_matrix import LONGITUDINAL
from ..physics.transfer import Layers, discretize, laminate
from .roots import scan_step

DEFAULT_MAX_STEP = 0.1  # scaled arclength: at least ten points between the start and ``stop``
MIN_STEP = 1e-10  # scaled arclength below which the trace gives up
GROWTH = 1.5  # step growth after an easy step
DISTANCE_RATIO = 0.3  # κ: accepted corrector distance |x − x_p| ≤ κ h
MAX_ANGLE_DEGREES = 20.0  # θ_max: largest accepted turn of the tangent per step
CORRECTOR_ITERATIONS = 6  # a step's corrector must converge within this many iterations
EASY_ITERATIONS = 3  # ... and within this many for the step to grow
START_ITERATIONS = 60  # Newton at fixed s_0 for the start (capped steps)
EVENT_ITERATIONS = 40  # corrector iterations for a point of an event (turning point, Ω = 0)
LOCATE_ITERATIONS = 100  # regula falsi steps locating a turning point before giving up (NaN event)
TOLERANCE = 1e-10  # Newton stops when |Δx|∞ ≤ TOLERANCE (the last update is still applied)
ATTEMPTS_PER_POINT = 64  # safety cap on step attempts: ATTEMPTS_PER_POINT · max_points
OMEGA_SCALE_CAP = 100.0  # W ≤ (1 + OMEGA_SCALE_CAP)|Ω_0|

_COS_MAX_ANGLE = math.cos(math.radians(MAX_ANGLE_DEGREES))
_COS_EASY_ANGLE = math.cos(math.radians(0.5 * MAX_ANGLE_DEGREES))


class BranchEnd(enum.IntEnum):
    """Why a trace ended (``Branch.status``, stored as int32)."""

    REACHED_STOP = 0  # the last point lies exactly at s = stop
    TURNING_POINT = 1  # ds/dσ changed sign; the last point is the turning point (f = f_Ω = 0)
    ZERO_FREQUENCY = 2  # Ω reached 0; the last point is (s*, 0) with f(s*, 0) = 0
    STEP_TOO_SMALL = 3  # the step fell below MIN_STEP (e.g. an exact crossing of two branches)
    NOT_FINITE = 4  # f was not finite just ahead (locking, exponential range, invalid parameter)
    MAX_POINTS = 5  # the buffers are full before any other event
    NO_START = 6  # Newton at fixed s_0 did not converge from ``omega`` (or ∇f = 0 there)


@serializable
class Branch(NamedTuple):
    """A traced branch; arrays have length ``max_points``, NaN after the last point.

    Attributes:
        parameter: s at each point (the first is s_0; after REACHED_STOP the last is ``stop``).
        omega: Ω at each point (roots of f to rounding).
        slope: dΩ/ds = −f_s/f_Ω at each point (NaN at the vertical tangent of a TURNING_POINT or
            ZERO_FREQUENCY end point).
        n_points: number of points (int32).
        status: a :class:`BranchEnd` code (int32).
        event_parameter: s at the end event (``stop``, the turning point or the zero frequency);
            NaN if the trace ended otherwise or the event could not be located.
        event_omega: Ω at that event (0 for ZERO_FREQUENCY), NaN likewise.
    """

    parameter: jax.Array
    omega: jax.Array
    slope: jax.Array
    n_points: jax.Array
    status: jax.Array
    event_parameter: jax.Array
    event_omega: jax.Array


class _State(NamedTuple):
    """Carry of the continuation loop (scaled quantities as in the module docstring)."""

    parameter: jax.Array  # (max_points,) buffers
    omega: jax.Array
    slope: jax.Array
    n_points: jax.Array
    s: jax.Array  # current point
    om: jax.Array
    tangent: jax.Array  # (2,) unit tangent at the current point, in x
    omega_scale: jax.Array  # W
    orientation: jax.Array  # σ
    step: jax.Array  # h
    land_next: jax.Array  # the last corrected point passed stop: land on it next
    started: jax.Array
    status: jax.Array  # a BranchEnd, or _RUNNING / _LOCATE_TURN / _LOCATE_ZERO while looping
    attempts: jax.Array
    event_start: jax.Array  # (2,) x before and after the step that crossed an event
    event_end: jax.Array
    bracket: jax.Array  # (2,) chord positions τ_a < τ_b of the turning point (regula falsi)
    bracket_values: jax.Array  # (2,) t_s at τ_a (> 0) and τ_b (< 0)
    kept_side: jax.Array  # Illinois: +1 if τ_a was replaced last, −1 if τ_b, 0 at first
    locate_count: jax.Array  # regula falsi steps so far
    event_parameter: jax.Array
    event_omega: jax.Array


_RUNNING, _LOCATE_TURN, _LOCATE_ZERO = -1, -2, -3
_E_S = np.array([1.0, 0.0])  # NumPy constants: importing jaxdea starts no JAX backend
_E_OMEGA = np.array([0.0, 1.0])
_EYE = np.eye(2)


def _value_and_gradient(fun, x, scaled=False):
    """(f(x), ∇f(x)) for a scalar f of x ∈ R² by forward mode: two tangents, the primal once.

    ``fun`` may return (f, ℓ), ℓ the log-scale of F = f e^ℓ (:func:`_trace_branch`): the gradient
    is then ∇f, or, where ``scaled`` (the start correction), ∇f + f∇ℓ = e^{−ℓ}∇F where
    ‖∇f + f∇ℓ‖ > NEWTON_SCALE_RATIO ‖∇f‖, so that Newton steps on F where f turns sign in a
    near-jump, as the root solvers' lanes do (:func:`jaxdea.numerics.scalar.newton_slope`); near an
    ordinary root, ∇f. Only the start: along the trace the same rule fired at a veering (∇f ≈ 0
    between two close roots of a light-fluid tube) and moved the points of
    tests/test_trace.py::test_fluid_veering_keeps_identity."""
    value, gradient = jax.vmap(lambda v: jax.jvp(fun, (x,), (v,)), out_axes=(None, 0))(_EYE)
    if not isinstance(value, tuple):
        return value, gradient
    (f, _), (df, dlog_scale) = value, gradient
    use_scale, scaled = scaled, df + f * dlog_scale
    jumps = use_scale & (jnp.linalg.norm(scaled) > NEWTON_SCALE_RATIO * jnp.linalg.norm(df))
    return f, jnp.where(jumps, scaled, df)


def _correct(fun, x_pred, normal, max_iter, max_omega_step, omega_scale, scaled=False):
    """Newton on {f(x) = 0, normal · (x − x_pred) = 0} from x_pred (2×2, Cramer's rule); updates
    capped so that |ΔΩ| = W|Δx_Ω| ≤ max_omega_step. ``scaled``: Newton on F where f nearly jumps
    (:func:`_value_and_gradient`; the start correction).

    Returns:
        (x, iterations, converged, finite, ∇f): ∇f at the last evaluated point, one update before x
        (which differs from it by at most TOLERANCE).
    """
    def cond(c):
        _, it, done, *_ = c
        return ~done & (it < max_iter)

    def body(c):
        x, it, *_ = c
        f, g = _value_and_gradient(fun, x, scaled)
        r = normal @ (x - x_pred)
        det = g[0] * normal[1] - g[1] * normal[0]
        delta = jnp.stack([(-f * normal[1] + g[1] * r) / det, (-g[0] * r + normal[0] * f) / det])
        cap = max_omega_step / (omega_scale * jnp.abs(delta[1]))
        delta = delta * jnp.minimum(1.0, jnp.where(jnp.isnan(cap), 1.0, cap))
        finite = jnp.isfinite(f) & jnp.all(jnp.isfinite(g)) & jnp.all(jnp.isfinite(delta))
        converged = finite & (jnp.max(jnp.abs(delta)) <= TOLERANCE)
        x = jnp.where(finite, x + delta, x)
        return x, it + 1, converged | ~finite, converged, finite, g

    init = (x_pred, jnp.int32(0), jnp.bool_(False), jnp.bool_(False), jnp.bool_(True),
            jnp.full(2, jnp.nan))
    x, it, _, converged, finite, g = jax.lax.while_loop(cond, body, init)
    return x, it, converged, finite, g


def continue_branch(fun, s0, omega0, stop, max_points: int, max_step=DEFAULT_MAX_STEP,
                    max_omega_step=jnp.inf) -> Branch:
    """Pseudo-arclength continuation of the zero set of a scalar f(s, Ω) (module docstring).

    jit/vmap safe: no Python control flow on values, failures give a :class:`BranchEnd` status.
    f and ∇f are evaluated at one place only (the corrector), for tracing and for locating events
    alike, which keeps the compiled program small.

    Args:
        fun: f(s, Ω) → scalar, differentiable by forward-mode autodiff; or → (f, ℓ) with ℓ the
            log-scale of F = f e^ℓ, Newton then stepping on F where f nearly jumps
            (:func:`_value_and_gradient`).
        s0: start value of the parameter s.
        omega0: guess of the root at s0; corrected by Newton at fixed s0 first.
        stop: the trace goes from s0 towards ``stop`` (either direction).
        max_points: length of the buffers (static).
        max_step: largest step in the scaled arclength (the range s0 → stop has length 1 in s).
        max_omega_step: cap on each Newton update of Ω (guards the start correction against
            overshooting into another root when the guess is rough).

    Returns:
        An instance of :class:`Branch`.
    """
    s0, omega0, stop, max_step, max_omega_step = map(as_float, (s0, omega0, stop, max_step,
                                                                max_omega_step))
    span = stop - s0
    span_safe = jnp.where(span != 0, span, 1.0)

    def point(x, w):
        return s0 + span_safe * x[0], omega0 + w * x[1]

    def coords(s, om, w):
        return jnp.stack([(s - s0) / span_safe, (om - omega0) / w])

    def tangent_of(g, sigma):
        return sigma * jnp.stack([g[1], -g[0]]) / jnp.linalg.norm(g)

    def slope_of(g, w):
        return -(g[0] / span_safe) / (g[1] / w)

    def body(st: _State) -> _State:
        w = st.omega_scale
        x = coords(st.s, st.om, w)
        t = st.tangent
        tracing, first = st.status == _RUNNING, ~st.started
        turning, zeroing = st.status == _LOCATE_TURN, st.status == _LOCATE_ZERO

        # ---- what to solve: a step, the start, a point of the turning chord, or f(s, 0) = 0
        remaining = 1.0 - x[0]
        land = tracing & st.started & (st.land_next | (st.step * t[0] >= remaining))
        h = jnp.where(land, remaining / t[0], st.step)
        x_step = jnp.where(st.started, x + h * t, x)
        x_step = jnp.where(land, x_step.at[0].set(1.0), x_step)
        a, b = st.event_start, st.event_end
        chord = b - a
        (tau_a, tau_b), (phi_a, phi_b) = st.bracket, st.bracket_values
        tau = (tau_a * phi_b - tau_b * phi_a) / (phi_b - phi_a)  # regula falsi
        tau = jnp.where(jnp.isfinite(tau) & (tau > tau_a) & (tau < tau_b), tau, 0.5 * (tau_a + tau_b))
        x_zero = coords(st.s, jnp.zeros_like(st.om), w)[1]
        s_guess = jnp.where(jnp.abs(a[1] - x_zero) <= jnp.abs(b[1] - x_zero), a[0], b[0])
        x_pred = jnp.where(turning, a + tau * chord,
                           jnp.where(zeroing, jnp.stack([s_guess, x_zero]), x_step))
        normal = jnp.where(turning, chord,
                           jnp.where(zeroing, _E_OMEGA, jnp.where(st.started & ~land, t, _E_S)))
        max_iter = jnp.where(turning | zeroing, EVENT_ITERATIONS,
                             jnp.where(first, START_ITERATIONS, CORRECTOR_ITERATIONS))
        xc, iters, converged, finite, g = _correct(lambda y: fun(*point(y, w)), x_pred, normal,
                                                   max_iter, max_omega_step, w, first)
        s_c, om_c = point(xc, w)
        t_new = tangent_of(g, st.orientation)
        solved = converged & finite

        # ---- start: W, the orientation and the first point
        slope0 = slope_of(g, w)
        w0 = jnp.abs(om_c) + jnp.minimum(jnp.abs(slope0 * span), OMEGA_SCALE_CAP * jnp.abs(om_c))
        w0 = jnp.where(jnp.isfinite(w0) & (w0 > 0), w0, 1.0)
        g0 = jnp.stack([g[0], g[1] * w0 / w])
        sigma0 = jnp.where(g0[1] >= 0, 1.0, -1.0)
        start_ok = first & solved & (jnp.linalg.norm(g0) > 0)

        # ---- a step of the trace
        cos_turn = t_new @ t
        ok = (tracing & st.started & solved & (jnp.linalg.norm(xc - x_pred) <= DISTANCE_RATIO * h)
              & (cos_turn >= _COS_MAX_ANGLE) & (~land | (t_new[0] > 0)))
        overshoot = ok & ~land & (xc[0] > 1.0)
        zero = ok & ~land & ~overshoot & (om_c * st.omega[0] <= 0)
        turn = ok & ~land & ~overshoot & ~zero & (t_new[0] < 0)
        accept = ok & ~overshoot & ~zero & ~turn
        easy = (iters <= EASY_ITERATIONS) & (cos_turn >= _COS_EASY_ANGLE)
        rejected = tracing & st.started & ~ok
        step = jnp.where(first, 0.25 * max_step,
                         jnp.where(rejected, 0.5 * st.step,
                                   jnp.where(accept & easy, jnp.minimum(GROWTH * st.step, max_step),
                                             st.step)))

        # ---- locating a turning point: Illinois step on t_s along the chord
        phi = t_new[0]
        near = jnp.linalg.norm(xc - a) <= 2.0 * jnp.linalg.norm(chord) + 1e3 * TOLERANCE
        located_turn = turning & solved & near
        replace_a = phi > 0
        new_tau = jnp.where(replace_a, jnp.stack([tau, tau_b]), jnp.stack([tau_a, tau]))
        halve = jnp.where(replace_a, st.kept_side == 1, st.kept_side == -1)
        new_phi = jnp.where(replace_a, jnp.stack([phi, phi_b * jnp.where(halve, 0.5, 1.0)]),
                            jnp.stack([phi_a * jnp.where(halve, 0.5, 1.0), phi]))
        turn_done = located_turn & ((jnp.abs(phi) <= 1e-14) | (new_tau[1] - new_tau[0] <= 1e-12))
        turn_failed = turning & (~located_turn | (st.locate_count >= LOCATE_ITERATIONS))
        zero_done = zeroing & solved & near
        zero_failed = zeroing & ~zero_done

        # ---- store a point
        store = jnp.where(first, start_ok, accept | turn_done | zero_done)
        s_store = jnp.where(first, s0, jnp.where(land, stop, s_c))
        om_store = jnp.where(zero_done, 0.0, om_c)
        slope_store = jnp.where(first, slope0,
                                jnp.where(turn_done | zero_done, jnp.nan, slope_of(g, w)))
        n = st.n_points
        n_new = n + store.astype(jnp.int32)
        status = jnp.select(
            [first & ~start_ok, first & (span == 0), first, land & ok, zero, turn,
             rejected & (step < MIN_STEP) & ~finite, rejected & (step < MIN_STEP),
             accept & (n_new >= max_points), turn_done | turn_failed, zero_done | zero_failed],
            [BranchEnd.NO_START, BranchEnd.REACHED_STOP, _RUNNING, BranchEnd.REACHED_STOP,
             _LOCATE_ZERO, _LOCATE_TURN, BranchEnd.NOT_FINITE, BranchEnd.STEP_TOO_SMALL,
             BranchEnd.MAX_POINTS, BranchEnd.TURNING_POINT, BranchEnd.ZERO_FREQUENCY],
            st.status,
        ).astype(jnp.int32)
        event = zero | turn
        located = turn_done | zero_done
        reached = (land & ok) | (first & start_ok & (span == 0))
        return _State(
            parameter=jnp.where(store, st.parameter.at[n].set(s_store), st.parameter),
            omega=jnp.where(store, st.omega.at[n].set(om_store), st.omega),
            slope=jnp.where(store, st.slope.at[n].set(slope_store), st.slope),
            n_points=n_new,
            s=jnp.where(store, s_store, st.s), om=jnp.where(store, om_store, st.om),
            tangent=jnp.where(first, tangent_of(g0, sigma0), jnp.where(accept, t_new, t)),
            omega_scale=jnp.where(first, w0, w), orientation=jnp.where(first, sigma0, st.orientation),
            step=step, land_next=overshoot, started=jnp.bool_(True), status=status,
            attempts=st.attempts + 1,
            event_start=jnp.where(event, x, st.event_start),
            event_end=jnp.where(event, xc, st.event_end),
            bracket=jnp.where(turn, jnp.array([0.0, 1.0]), jnp.where(turning, new_tau, st.bracket)),
            bracket_values=jnp.where(turn, jnp.stack([t[0], t_new[0]]),
                                     jnp.where(turning, new_phi, st.bracket_values)),
            kept_side=jnp.where(turn, 0, jnp.where(turning, jnp.where(replace_a, 1, -1),
                                                    st.kept_side)),
            locate_count=st.locate_count + turning.astype(jnp.int32),
            event_parameter=jnp.where(located, s_c, jnp.where(reached, stop, st.event_parameter)),
            event_omega=jnp.where(located, om_store, jnp.where(reached, om_c, st.event_omega)),
        )

    def cond(st: _State):
        return (st.status < 0) & (st.attempts < ATTEMPTS_PER_POINT * max_points)

    nan_buffer = jnp.full(max_points, jnp.nan)
    nan2 = jnp.full(2, jnp.nan)
    init = _State(
        parameter=nan_buffer, omega=nan_buffer, slope=nan_buffer, n_points=jnp.int32(0),
        s=s0, om=omega0, tangent=_E_S, omega_scale=jnp.where(omega0 != 0, jnp.abs(omega0), 1.0),
        orientation=jnp.ones(()), step=0.25 * max_step, land_next=jnp.bool_(False),
        started=jnp.bool_(False), status=jnp.int32(_RUNNING), attempts=jnp.int32(0),
        event_start=nan2, event_end=nan2, bracket=nan2, bracket_values=nan2,
        kept_side=jnp.int32(0), locate_count=jnp.int32(0), event_parameter=jnp.full((), jnp.nan),
        event_omega=jnp.full((), jnp.nan),
    )
    st = jax.lax.while_loop(cond, body, init)
    status = jnp.select([st.status == _LOCATE_TURN, st.status == _LOCATE_ZERO, st.status < 0],
                        [BranchEnd.TURNING_POINT, BranchEnd.ZERO_FREQUENCY, BranchEnd.STEP_TOO_SMALL],
                        st.status).astype(jnp.int32)
    return Branch(st.parameter, st.omega, st.slope, st.n_points, status, st.event_parameter,
                  st.event_omega)


# ------------------------------------------------------------------------------------- the tube
@cached_jit(static_argnames=("along", "max_points", "n_layers", "order", "family"))
def _trace_branch(tube, alpha, omega, fluid, stop, max_step, along, max_points, n_layers, order,
                  m=0.0, family=LONGITUDINAL):
    alpha = as_float(alpha)
    s0 = get_parameter(tube, alpha, fluid, along)
    wall0 = discretize(tube, n_layers)
    wall_is_fixed = along == "alpha" or along in FLUID_LEAVES
    # off the axisymmetric family: f is NaN where the (traced) order m is inadmissible (NO_START)
    ok = family.admissible(m, fluid)
    m_safe = family.safe_m(m, ok)

    def residual(s, om):
        t, a, fl = set_parameter(tube, alpha, fluid, along, s)
        wall = wall0 if wall_is_fixed else discretize(t, n_layers)
        # (f, ℓ): f that of characteristic.value bit for bit, ℓ for Newton on F where f nearly jumps
        f, log_scale = characteristic.value_and_scale(family, wall, om, as_float(a), fl, order,
                                                      m_safe, method="taylor")
        return jnp.where(ok, f, jnp.nan), log_scale

    return continue_branch(residual, s0, omega, stop, max_points, max_step,
                           4.0 * scan_step(wall0, fluid, family))


def _validate_finite(name, x):
    validate_real(name, x, "a finite real number")


def trace_branch(tube: Tube, alpha, omega, fluid: Fluid | None = None, *, along: str = "alpha",
                 stop, max_points: int = 256, max_step=None, n_layers: int | None = None,
                 scheme: str | None = None, m=0, torsional: bool = False, outer: Fluid | None = None) -> Branch:
    """Follow the dispersion branch through the root ``omega`` along the parameter ``along``.

    The branch is the curve f(Ω; s) = 0 through (s_0, Ω_0), with f the characteristic function of
    the tube (:func:`jaxdea.characteristic`, N = ``n_layers``) whose parameter ``along`` is set to s
    (:func:`jaxdea.physics.leaves.set_parameter`; s_0 is its present value). ``omega`` is first corrected by
    Newton at fixed s_0; the trace then goes by pseudo-arclength continuation (module docstring of
    :mod:`jaxdea.solve.trace`: predictor x + h t with t = σ rot(∇f)/|∇f|, corrector Newton on
    {f = 0, t·(x − x_p) = 0}) towards ``stop`` and ends at the first event: s = stop (landed on
    exactly), a turning point (f = f_Ω = 0), Ω = 0 (f(s*, 0) = 0, e.g. the critical voltage), a
    step below MIN_STEP, a non-finite f, or full buffers. The identity of the mode is kept through
    veerings: a step that lands on the neighbouring branch reverses the tangent and is refused.

    No derivatives flow through the trace (inputs are ``stop_gradient``-ed); differentiate
    :func:`jaxdea.frequency` at a traced point instead. jit/vmap safe: under a trace, failures give
    NaN and a status, never an exception.

    Args:
        tube: the :class:`~jaxdea.Tube`.
        alpha: α̂ = α R_i > 0.
        omega: a root Ω_0 > 0 of the branch at s_0 (e.g. from :func:`jaxdea.frequencies`).
        fluid: a :class:`~jaxdea.Fluid` or None. The paper coupling's Bessel order is static: it
            stays that of the start (pass ``bessel_order`` explicitly to trace along α̂).
        outer: a surrounding :class:`~jaxdea.Fluid` (unbounded, ``"acoustic"``) or None: the tube's own
            ``tube.outer`` (None: vacuum). Subsonic modes carry its added mass
            (docs/theory/real_tubes.md §6).
        along: the parameter s, any name of :data:`jaxdea.physics.leaves.NAMES` except ``"n"`` (static).
        stop: where to stop (a value of s; the trace may go up or down).
        max_points: buffer length, ≥ 2 (static).
        max_step: largest step of the scaled arclength, in which the range s_0 → stop has length 1
            (None: 0.1, i.e. at least ten points on a straight branch).
        n_layers: sublayers N (static), or None: the accurate discretisation (:func:`jaxdea.frequencies`).
        scheme: the propagation scheme (static; :func:`jaxdea.frequencies`).
        m, torsional: the circumferential order (int >= 0; fixed along the trace) and, at m = 0,
            the torsional family (:func:`jaxdea.frequencies`): the branch of that order.

    Returns:
        An instance of :class:`Branch`: ``parameter``, ``omega``, ``slope`` (dΩ/ds), NaN-padded to
        ``max_points``; ``n_points``; ``status`` (:class:`BranchEnd`); ``event_parameter``, ``event_omega``.

    Raises:
        ValueError: naming the parameter, for concrete bad inputs (``along``, ``stop`` not finite or
            outside the valid range of ``along``, ``omega`` ≤ 0, ``max_points`` < 2, ``max_step`` ≤ 0,
            and every check of :func:`jaxdea.characteristic`).

    Examples:
        >>> tube = Tube(voltage=0.1, lambda_i=0.9, lambda_z=1.2)
        >>> branch = trace_branch(tube, 0.445, frequencies(tube, 0.445)[1], along="alpha", stop=2.0)
        >>> k = int(branch.n_points)  # 24 points, status REACHED_STOP, last Ω(2.0) ≈ 3.8956
        >>> alphas, omegas = branch.parameter[:k], branch.omega[:k]
    """
    tube = with_outer(tube, outer)
    problem = describe(tube, alpha, fluid, n_layers, scheme, m, torsional)
    if not isinstance(along, str):
        raise ValueError(f"along must be a parameter name (str), got {along!r}")
    try:
        check_names([along], fluid, allow_n=False, tube=tube)
    except ValueError as exc:
        raise ValueError(f"along = {along!r}: {exc}") from exc
    validate_positive("omega", omega, "> 0 (a root of the branch to follow)")
    _validate_finite("stop", stop)
    if not isinstance(max_points, (int, np.integer)) or isinstance(max_points, bool) or max_points < 2:
        raise ValueError(f"max_points must be an integer >= 2, got {max_points!r}")
    if max_step is None:
        max_step = DEFAULT_MAX_STEP
    validate_positive("max_step", max_step, "> 0 (scaled arclength; the range to stop has length 1)")
    if not isinstance(stop, jax.core.Tracer):
        end_tube, end_alpha, end_fluid = set_parameter(tube, alpha, fluid, along, stop)
        try:
            validate_tube(end_tube)
            validate_fluid(end_fluid)
            validate_alpha(end_alpha)
        except ValueError as exc:
            raise ValueError(f"stop = {stop!r} is outside the valid range of {along!r}: {exc}") from exc
    args = jax.lax.stop_gradient(canonical(tube, alpha, omega, fluid, stop, max_step))
    layers = laminate(n_layers, scheme, tube, alpha, m=m)
    if not isinstance(stop, jax.core.Tracer) and isinstance(layers, Layers) and layers.graded:
        end = laminate(n_layers, scheme, end_tube, end_alpha, m=m)  # the finer of the two ends
        layers = max(layers, end, key=lambda x: x.count)
    static = dict(along=along, max_points=int(max_points), n_layers=layers,
                  order=problem.order)
    return _trace_branch(*args, **problem.arguments(jax.lax.stop_gradient(canonical(m))), **static)
