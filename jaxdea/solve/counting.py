"""Root counting by the argument principle: how many frequencies lie in an interval (certificate).

:func:`count_roots` returns the number of zeros of the characteristic function of the same
discretisation (same ``n_layers`` laminate) in (ω_lo, ω_hi), independently of the scan of
:mod:`jaxdea.solve.roots`, so that ``frequencies`` can be checked: the two agree when the scan missed
nothing.

Method. F(Ω) = det(B A S)(Ω) (docs/theory/axisymmetric.md §4) is entire in Ω: the state matrix is polynomial in
Ω, the laminate exponentials are entire, and the fluid couplings enter through N_ν, D_ν, entire in
s = χ̂² r̂_i² = (Ω²/ĉ_f² − α̂²) r̂_i² (:mod:`jaxdea.numerics.bessel`). By the argument principle the number of
zeros inside a closed contour Γ is

    Z = (1/2π) Δ_Γ arg F,

the total change of arg F once around Γ. Γ is the rectangle [ω_lo, ω_hi] × [−δ, δ] of the complex Ω
plane; for ω_lo = 0 its left side is the wedge |Im Ω| = Re Ω ≤ δ through Ω = 0, which separates
each root Ω₁ > 0 from its mirror −Ω₁ (F is even) and keeps the imaginary axis outside. F has real
coefficients, F(Ω̄) = conj F(Ω), so the lower half mirrors the upper one and

    Z = (1/π) Δ arg F along ω_hi → ω_hi + iδ → ω_lo + s + iδ → ω_lo   (s = δ if ω_lo = 0, else 0)

(the upper half of Γ, from the real axis back to it; ``symmetric=False`` integrates all of Γ, twice
the work, the same count). arg F is evaluated stably for any α̂ĥ: the complex 6×3 basis is
propagated and re-orthonormalised after every sublayer (Gram–Schmidt with conjugates,
:func:`jaxdea.physics.transfer.orthonormalize`); R_k has a real positive diagonal, so
arg det(B A S) = arg det(B Q_N) and |det(B Q_N)| ≤ 1. The Bessel pair for complex s carries a
positive factor too (:func:`jaxdea.numerics.bessel.coupling_pair`), which leaves the argument exact.

The zeros of the conservative problem in Ω² are real and F is even in Ω, so the zeros near the real
Ω axis are real; zeros at Ω² < 0 (unstable modes beyond V̂_cr) lie on the imaginary axis, outside Γ.
A non-real zero inside the box would be counted, with its conjugate, making the count larger than
the number of real roots that the scan looks for: the laminate is not exactly self-adjoint and the
paper's follower-pressure coupling is not conservative, so such zeros are possible in principle;
the box is thin (below) to make them unlikely. The paper's coupling has them: complex pairs about
2e-3 off the real axis next to the poles of B̂_ν (measured on random tubes, ĉ_f = 0.27, ν = 1), inside
the default box; count its roots with a ``height`` below that (1e-4: the count then agrees with the
scan). None was met with the fluid-free tube or the acoustic coupling.

Box and sampling. Δ = min(``scan_step``, (ω_hi − ω_lo)/16) (a sixteenth of the shortest oscillation
of f, :func:`jaxdea.solve.roots.scan_step`), δ = Δ/2 (``height`` overrides). The contour is sampled
adaptively by bisection: a segment [a, b] with midpoint m is accepted when it is at most Δ long and
the principal increments Δ₁ = arg(F_m/F_a), Δ₂ = arg(F_b/F_m) satisfy |Δ₁|, |Δ₂| ≤ π/4 and
|Δ₁ − Δ₂| ≤ π/8 (the phase is nearly linear across it); otherwise both halves are refined. Samples
are therefore at most δ apart and consecutive phases differ by at most π/4.

Guarantee and limits. The count is exact when every accepted increment is the true one, i.e. arg F
does not turn by an extra multiple of 2π between samples. A real zero lies at least δ from the top
side, where it turns arg F by at most 2 arctan(1/2) ≈ 0.93 rad between samples δ apart; hiding a
full turn needs about six zeros within ~δ of one point of the contour, or a zero much closer to the
contour than the spacing of the samples around it (only at the ends: a root at ω_lo or ω_hi). That
case is refined down to segments of h_min = 1e-11 max(ω_hi, δ): a root farther than ~10 h_min from
an end is counted on its correct side (tested at 1e-10 relative), and a root within about h_min of
an end (within rounding of it: whether it lies inside is undecidable) stops the count with status
``ZERO_ON_CONTOUR``: move the end by more than h_min. The same holds at the vertex Ω = 0 of the
wedge (V̂ = V̂_cr to rounding). This is a sampling certificate, not interval arithmetic: like the
scan it assumes that F does not vary on scales far below the sample spacing without showing it at
the samples. Any failure is reported, never a count: a non-finite value (``NOT_FINITE``), the
evaluation or buffer budget (``BUDGET_EXHAUSTED``), inputs out of range under jit (``INVALID``);
``count`` is −1 then.

Implementation. One ``lax.while_loop`` over a fixed-size stack of pending segments: each iteration
evaluates arg F at the midpoints of up to ``LANES`` segments (one vmapped evaluator, one compiled
program per static configuration), accumulates accepted increments and pushes the halves of the
rest (depth first, so the stack stays ≈ ``LANES`` × depth). Where fewer than ``LANES`` segments are
pending (P of them, the last iterations, refining next to a root), each is cut into q + 1 equal
parts (q the largest odd number ≤ LANES/P) and the q points evaluated at once; its (q + 1)/2
pairs of parts are then accepted or split by the rule above, as the same bisection would have met
them levels deeper (the rule is only applied to shorter segments, never relaxed). A count then
takes fewer iterations of the evaluator, whose cost is the same for any number of lanes in use
(14 → 11 on a damped box of :func:`jaxdea.complex_frequencies`, 568 → 646 evaluations). jit- and
vmap-compatible. Cost: one
complex evaluation per δ of contour plus a few per root near the top side; 125–1900 evaluations
(0.1–4 s after compilation on two CPU cores) for the cases of tests/test_counting.py.
"""

import enum
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from ..compiled import cached_jit, serializable
from ..params import Fluid, Tube, as_float, canonical, validate_positive, with_outer
from ..physics import characteristic
from ..physics.problem import describe
from ..physics.state_matrix import LONGITUDINAL
from ..physics.transfer import discretize, laminate
from .roots import guard_order, scan_step, without_voltage

LANES = 64  # midpoints evaluated per iteration (one vmapped call)
STACK = 4096  # pending segments held at most
MAX_PHASE = np.pi / 4  # bound on the phase increment between consecutive samples
MAX_CURVATURE = np.pi / 8  # bound on |Δ₁ − Δ₂| within an accepted segment
MIN_RELATIVE_LENGTH = 1e-11  # h_min / max(ω_hi, δ)
STEPS_PER_BOX = 16  # Δ ≤ (ω_hi − ω_lo)/16


class CountStatus(enum.IntEnum):
    """Status of :func:`count_roots` (int32 arrays; NOT_FINITE and INVALID as in :class:`Status`)."""

    CERTIFIED = 0  # the phase was resolved everywhere on the contour: the count is exact
    ZERO_ON_CONTOUR = 1  # a zero on or within h_min of the contour (a root at ω_lo or ω_hi)
    NOT_FINITE = 2  # a non-finite value of the characteristic function on the contour
    BUDGET_EXHAUSTED = 3  # max_evaluations or the segment stack ran out before the phase was resolved
    INVALID = 4  # inputs outside their allowed range (met under jit/vmap)


@serializable
class RootCount(NamedTuple):
    """(count, status): zeros in (ω_lo, ω_hi), −1 unless status is CERTIFIED."""

    count: jax.Array
    status: jax.Array


def _contour(lo, hi, height, symmetric: bool):
    """Corners of the sides (start, end) in order, and the count's divisor (π or 2π).

    Upper half (symmetric): ω_hi → ω_hi + iδ → ω_lo + s + iδ → ω_lo, with s = δ for ω_lo = 0 (the
    45° wedge |Im Ω| = Re Ω through Ω = 0, which keeps the imaginary axis outside) and s = 0 else;
    full: the mirror image added, counter-clockwise from ω_lo. Returns (starts, ends, divisor,
    pieces): ``pieces`` is the static number of initial segments per side (LANES points in all).
    """
    corner = lo + jnp.where(lo == 0, height, 0.0)
    top_right, top_left = hi + 1j * height, corner + 1j * height
    if symmetric:
        starts, ends = [hi + 0j, top_right, top_left], [top_right, top_left, lo + 0j]
        return jnp.stack(starts), jnp.stack(ends), np.pi, (2, LANES - 7, 2)
    low_left, low_right = jnp.conj(top_left), jnp.conj(top_right)
    starts = [low_left, low_right, top_right, top_left, lo + 0j]
    ends = [low_right, top_right, top_left, lo + 0j, low_left]
    return jnp.stack(starts), jnp.stack(ends), 2.0 * np.pi, (28, 2, 27, 1, 1)


def _initial_points(pieces):
    """(side, τ) of the initial samples: side k cut into pieces[k] equal parts, ends included."""
    side = np.concatenate([np.full(p + 1, k) for k, p in enumerate(pieces)])
    tau = np.concatenate([np.linspace(0.0, 1.0, p + 1) for p in pieces])
    assert side.size == LANES
    return jnp.asarray(side, jnp.int32), jnp.asarray(tau)


def _phase_count(phasor, lo, hi, height, symmetric, max_evaluations):
    """Winding count of the function whose unit phasor F/|F| (and a finiteness flag) is
    ``phasor(z)`` for z of shape (LANES,), over the contour of :func:`_contour` (module docstring).

    Returns:
        (count, status, evaluations).
    """
    starts, ends, divisor, pieces = _contour(lo, hi, height, symmetric)
    return winding_count(phasor, starts, ends, divisor, pieces, 2.0 * height,
                         MIN_RELATIVE_LENGTH * jnp.maximum(jnp.abs(hi), height), max_evaluations)


def winding_count(phasor, starts, ends, divisor, pieces, h_max, h_min, max_evaluations):
    """Zeros inside the closed polygon with sides ``starts`` → ``ends``: the winding of the unit
    phasor F/|F| (with a finiteness flag) that ``phasor(z)`` gives for z of shape (LANES,), divided
    by ``divisor``/2π (π for the symmetric half-contour of :func:`_contour`). Sides are cut into
    ``pieces`` (static, LANES points in all) and refined by bisection as the module docstring says,
    to segments of at most ``h_max`` and at least ``h_min``.

    Returns:
        (count, status, evaluations).
    """
    lengths = jnp.abs(ends - starts)
    side0, tau0 = _initial_points(pieces)
    lane = jnp.arange(LANES)

    def point(side, tau):
        return starts[side] * (1.0 - tau) + ends[side] * tau  # exact at τ = 0 and τ = 1

    def body(state):
        ta, tb, sd, ua, ub, n, total, evals, status, first = state
        start = jnp.maximum(n - LANES, 0)
        popped = n - start  # P segments, the top of the stack
        take = lambda v: jax.lax.dynamic_slice_in_dim(v, start, LANES)  # noqa: E731
        pa, pb, ps, pua, pub = (take(v) for v in (ta, tb, sd, ua, ub))
        # q interior points per popped segment (q odd, P q <= LANES): the lanes that P < LANES
        # segments leave idle evaluate points of the next levels of their bisection
        q = jnp.maximum(LANES // jnp.maximum(popped, 1), 1)
        q = jnp.where(first, 1, q - 1 + q % 2)
        owner, j = lane // q, lane % q + 1
        valid = jnp.where(first, True, owner < popped)
        owner = jnp.minimum(owner, LANES - 1)

        def at(segment, k):  # τ of point k = 0 … q + 1 of a popped segment (its ends exact)
            a, b = pa[segment], pb[segment]
            inner = jnp.where(2 * k == q + 1, 0.5 * (a + b), a + (b - a) * (k / (q + 1)))
            return jnp.where(k == 0, a, jnp.where(k == q + 1, b, inner))

        side = jnp.where(first, side0, ps[owner])
        tau = jnp.where(first, tau0, jnp.where(valid, at(owner, j), 0.0))
        um, finite = phasor(point(side, tau))
        bad = valid & ~finite
        zero = valid & finite & (um == 0)
        um = jnp.where(finite & (um != 0), um, 1.0)

        # refinement: each popped segment is (q + 1)/2 pairs of sub-segments [a, b] with their
        # midpoints m evaluated (q = 1: the segment itself), each accepted or split in halves
        pairs = (q + 1) // 2
        segment, k = jnp.minimum(lane // pairs, LANES - 1), lane % pairs
        valid_pair = ~first & (lane // pairs < popped)

        def phase_at(k_point):  # the phasor at point k_point of ``segment``
            inner = um[jnp.clip(segment * q + k_point - 1, 0, LANES - 1)]
            return jnp.where(k_point == 0, pua[segment],
                             jnp.where(k_point == q + 1, pub[segment], inner))

        qa, qm, qb = (at(segment, 2 * k + d) for d in (0, 1, 2))
        va, vm, vb = (phase_at(2 * k + d) for d in (0, 1, 2))
        qs = ps[segment]
        d1 = jnp.angle(vm * jnp.conj(va))
        d2 = jnp.angle(vb * jnp.conj(vm))
        length = (qb - qa) * lengths[qs]
        accept = (valid_pair & (length <= h_max) & (jnp.abs(d1) <= MAX_PHASE)
                  & (jnp.abs(d2) <= MAX_PHASE) & (jnp.abs(d1 - d2) <= MAX_CURVATURE))
        split = valid_pair & ~accept
        too_short = split & (0.5 * length < h_min)
        total = total + jnp.sum(jnp.where(accept, d1 + d2, 0.0))

        # segments to push: halves of the split ones, or (first pass) consecutive initial samples
        init_ok = jnp.concatenate([side0[1:] == side0[:-1], jnp.zeros(LANES + 1, bool)])
        rotate = lambda v: jnp.concatenate([v[1:], v[:1]])  # noqa: E731
        first_segments = (tau0, rotate(tau0), side0, um, rotate(um))
        halves = (jnp.concatenate([qa, qm]), jnp.concatenate([qm, qb]), jnp.concatenate([qs, qs]),
                  jnp.concatenate([va, vm]), jnp.concatenate([vm, vb]))
        pad = lambda v: jnp.concatenate([v, v])  # noqa: E731
        new = [jnp.where(first, pad(f), h) for f, h in zip(first_segments, halves, strict=True)]
        push = jnp.where(first, init_ok, jnp.concatenate([split, split]))
        base = jnp.where(first, 0, start)
        slot = jnp.where(push, base + jnp.cumsum(push) - 1, STACK)  # STACK: dropped
        n_new = base + jnp.sum(push)
        ta, tb, sd, ua, ub = (buf.at[slot].set(v, mode="drop")
                              for buf, v in zip((ta, tb, sd, ua, ub), new, strict=True))

        status = jnp.where(n_new > STACK, CountStatus.BUDGET_EXHAUSTED, status)
        status = jnp.where(jnp.any(zero | too_short), CountStatus.ZERO_ON_CONTOUR, status)
        status = jnp.where(jnp.any(bad), CountStatus.NOT_FINITE, status)
        evals = evals + jnp.sum(valid)
        return ta, tb, sd, ua, ub, n_new, total, evals, status, jnp.asarray(False)

    def cond(state):
        n, evals, status, first = state[5], state[7], state[8], state[9]
        return (status == CountStatus.CERTIFIED) & (first | ((n > 0) & (evals < max_evaluations)))

    zeros = jnp.zeros(STACK)
    init = (zeros, zeros, jnp.zeros(STACK, jnp.int32), zeros + 0j, zeros + 0j, jnp.asarray(0),
            jnp.asarray(0.0), jnp.asarray(0), jnp.asarray(CountStatus.CERTIFIED, jnp.int32),
            jnp.asarray(True))
    state = jax.lax.while_loop(cond, body, init)
    n, total, evals, status = state[5], state[6], state[7], state[8]
    status = jnp.where((status == CountStatus.CERTIFIED) & (n > 0), CountStatus.BUDGET_EXHAUSTED, status)
    winding = total / divisor
    count = jnp.round(winding)
    # the accepted samples close the contour, so the winding is an integer up to rounding
    status = jnp.where((status == CountStatus.CERTIFIED) & (jnp.abs(winding - count) > 1e-6),
                       CountStatus.ZERO_ON_CONTOUR, status)
    count = jnp.where(status == CountStatus.CERTIFIED, count, -1).astype(jnp.int32)
    return count, status.astype(jnp.int32), evals


def default_height(wall, fluid, lo, hi, family=LONGITUDINAL):
    """δ = min(scan_step, (ω_hi − ω_lo)/16)/2 (module docstring)."""
    return 0.5 * jnp.minimum(scan_step(wall, fluid, family), (hi - lo) / STEPS_PER_BOX)


def count_roots_unchecked(tube, alpha, omega_lo, omega_hi, fluid, n_layers: int, order: int,
                          height=None, max_evaluations=65536, symmetric: bool = True, m=0.0,
                          family=LONGITUDINAL, decoupled: bool = False):
    """(count, status, evaluations) for one case (traceable; see :func:`count_roots`).

    ``family`` (static) and ``m`` (traced, ``"order_m"``): the mode family (docs/theory/order_m.md); off the
    axisymmetric family F(Ω) = f(w = Ω²) of the 8×8 system, entire and even in Ω as well.
    Inputs outside their range (an inadmissible m included) give count −1 with status INVALID (no
    exception). ``decoupled`` (static): a longitudinal wall without voltage, whose zeros are those
    of its mechanical block (:func:`jaxdea.physics.characteristic.winding_value`: the electric factor
    turns the phase by a constant), counted on the 4×4 propagation alone (NaN, so no count, where
    the wall does not decouple).
    """
    lo, hi = as_float(omega_lo), as_float(omega_hi)
    ok, tube, alpha, fluid = guard_order(tube, alpha, fluid, m, family)
    m_safe = family.safe_m(m, ok)
    ok &= jnp.isfinite(lo) & jnp.isfinite(hi) & (lo >= 0) & (hi > lo)
    lo, hi = jnp.where(ok, lo, 0.0), jnp.where(ok, hi, 1.0)
    wall = discretize(tube, n_layers)
    delta = default_height(wall, fluid, lo, hi, family) if height is None else as_float(height)
    ok &= jnp.isfinite(delta) & (delta > 0) & (delta < hi - lo)
    delta = jnp.where(ok, delta, 1.0)

    def phasor(z):
        f = jax.vmap(lambda om: characteristic.winding_value(family, wall, om, alpha, fluid, order,
                                                             m_safe, decoupled=decoupled))(z)
        size = jnp.abs(f)
        finite = jnp.isfinite(size)
        return jnp.where(size > 0, f / jnp.where(size > 0, size, 1.0), 0.0), finite

    count, status, evals = _phase_count(phasor, lo, hi, delta, symmetric, max_evaluations)
    return (jnp.where(ok, count, -1).astype(jnp.int32),
            jnp.where(ok, status, CountStatus.INVALID).astype(jnp.int32), evals)


@cached_jit(static_argnames=("n_layers", "order", "symmetric", "default", "family", "decoupled"))
def _count_roots(tube, alpha, omega_lo, omega_hi, fluid, height, max_evaluations, n_layers, order,
                 symmetric, default, m=0.0, family=LONGITUDINAL, decoupled=False):
    return count_roots_unchecked(tube, alpha, omega_lo, omega_hi, fluid, n_layers, order,
                                 None if default else height, max_evaluations, symmetric, m, family,
                                 decoupled)


def count_roots(tube: Tube, alpha, omega_lo, omega_hi, fluid: Fluid | None = None,
                n_layers: int | None = None, height=None, max_evaluations: int = 65536,
                symmetric: bool = True, scheme: str | None = None, m=0,
                torsional: bool = False, outer: Fluid | None = None) -> RootCount:
    """The number of frequencies in (omega_lo, omega_hi), by the argument principle.

    Counts the zeros of det(B A S)(Ω), the characteristic function of the ``n_layers`` laminate
    (docs/theory/axisymmetric.md §4), inside the box [ω_lo, ω_hi] × [−δ, δ] of the complex Ω plane:
    Z = (1/2π) Δ_Γ arg det(B A S) (module docstring: method, guarantee and limits). With the same
    ``n_layers``, ``count`` equals the number of roots :func:`jaxdea.frequencies` returns in the
    interval when the scan misses none.

    Args:
        tube: the :class:`~jaxdea.Tube`.
        alpha: α̂ = α R_i > 0.
        omega_lo, omega_hi: the interval, 0 ≤ ω_lo < ω_hi (open: its ends must not be roots).
        fluid: a :class:`~jaxdea.Fluid` or None (empty tube).
        outer: a surrounding :class:`~jaxdea.Fluid` (unbounded, ``"acoustic"``) or None: the tube's own
            ``tube.outer`` (None: vacuum). Subsonic modes carry its added mass
            (docs/theory/real_tubes.md §6).
        n_layers: sublayers N (static), or None: the accurate discretisation (:func:`jaxdea.frequencies`).
        height: half-height δ of the box; None: min(scan_step, (ω_hi − ω_lo)/16)/2.
        max_evaluations: budget of complex evaluations of the characteristic function (traced: a
            new value does not recompile).
        symmetric: integrate the upper half of the box only, using F(Ω̄) = conj F(Ω) (static; False
            integrates the whole rectangle: twice the cost, the same count).
        scheme: the propagation scheme (static; :func:`jaxdea.frequencies`): the roots counted
            are those of that discretisation.
        m: circumferential order (int >= 0; :func:`jaxdea.frequencies`): the roots of order m are
            counted. torsional: the torsional family at m = 0.

    Returns:
        An instance of :class:`RootCount` (count, status): int32 arrays; count −1 unless status is
        ``CountStatus.CERTIFIED``.

    Raises:
        ValueError: for concrete inputs out of range, naming the parameter.

    Examples:
        >>> count_roots(Tube(), 0.445, 0.5, 3.0)  # RootCount(count=2, status=0)
    """
    tube = with_outer(tube, outer)
    problem = describe(tube, alpha, fluid, n_layers, scheme, m, torsional)
    validate_positive("omega_hi", omega_hi)
    lo, hi = (np.asarray(v, dtype=np.float64) if not isinstance(v, jax.core.Tracer) else None
              for v in (omega_lo, omega_hi))
    if lo is not None and (lo.ndim or not np.isfinite(lo) or lo < 0):
        raise ValueError(f"omega_lo must be a finite real number >= 0, got {omega_lo!r}")
    if lo is not None and hi is not None and not hi > lo:
        raise ValueError(f"omega_hi must be > omega_lo = {float(lo)!r}, got {omega_hi!r}")
    if height is not None:
        validate_positive("height", height, "> 0 (the half-height δ of the box)")
        if lo is not None and hi is not None and not float(height) < float(hi - lo):
            raise ValueError(f"height must be < omega_hi - omega_lo = {float(hi - lo)!r}, got {height!r}")
    if (not isinstance(max_evaluations, (int, np.integer)) or isinstance(max_evaluations, bool)
            or max_evaluations < LANES):
        raise ValueError(f"max_evaluations must be an integer >= {LANES}, got {max_evaluations!r}")
    tube, alpha, fluid, omega_lo, omega_hi, m = canonical(tube, alpha, fluid, omega_lo, omega_hi, m)
    default = height is None
    height = as_float(1.0 if default else height)
    args = (tube, alpha, omega_lo, omega_hi, fluid, height, jnp.asarray(max_evaluations),
            laminate(n_layers, scheme, tube, alpha, m=m), problem.order, bool(symmetric), default)
    count, status, _ = _count_roots(*args, **problem.arguments(m),
                                    decoupled=without_voltage(tube, problem.family))
    return RootCount(count, status)
