"""Complex wavenumbers at a real frequency: propagating, attenuated and evanescent waves
(API.md, "Real tubes"; docs/theory/real_tubes.md §5).

At a real Ω the characteristic function is a function of α̂ (:mod:`jaxdea.physics.characteristic`,
unknown ``alpha``): F(α̂) = det(Out A S) is entire in α̂ (the generators are polynomials in α̂, the
fluid's pair entire in χ̂² = Ω²/ĉ_f² − α̂²) and F(−α̂) = ±F(α̂) (u_z ∝ sin α̂z), so the roots come in
pairs ±α̂; the wave is reported by the root with Re α̂ ≥ 0. For a lossless tube F has real
coefficients too, so the roots are real (propagating), purely imaginary (evanescent, ±iκ) or
complex quartets.

Search and certificate. The roots are sought in bands of the box [0, α_max] × [−B, B], the first
through the real axis, each next one twice as high:

* the right part [ε, α_max] of a band (ε = 1e-3 α_max): Newton on F (the contract's analytic
  log-derivative, x ← x − 1/(d ln F/dx)) from a grid of starts over it;
* the strip [−ε, ε] of a band about the imaginary axis (above η = 1e-3 B in the first band): Newton
  from starts iκ on the axis.

Each part's roots are counted by the argument principle on its contour
(:func:`jaxdea.solve.counting.winding_count`), on the checked default's starting discretisation
where the default is taken (its zeros are the solve's to its discretisation error; the count is
taken again on the solve's wall where a root found lies next to the contour or the roots do not
meet it: :func:`search_box`); the grid of starts is refined until the distinct converged roots
match the count (certified), or the result says it is not. B starts at max(1, Ω)
and doubles until ``n_roots`` roots are certified, so the roots reported are the ``n_roots``
nearest the real axis with Re α̂ ≤ α_max. The default α_max = 2Ω/min(c_min, ĉ_f) + 4 max(1, Ω)
(c_min the slowest shear speed of the wall) holds the short waves, which travel near the
surface-wave speed; a soft mode near an instability can be slower and needs a larger one.
"""

import enum
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from ..compiled import jit, serializable
from ..numerics.scalar import Status
from ..params import (
    Fluid,
    Tube,
    as_float,
    canonical,
    traced,
    validate_count,
    validate_fluid,
    validate_positive,
    with_outer,
)
from ..physics import characteristic
from ..physics.characteristic import Unknown
from ..physics.families import Face
from ..physics.problem import NO_ALPHA, describe
from ..physics.transfer import discretized, laminate
from .counting import LANES, MIN_RELATIVE_LENGTH, CountStatus, winding_count

MAX_EVALUATIONS = 20_000
"""Evaluations of f allowed per contour count."""
NEWTON_STEPS = 40
"""Newton steps from each start."""
GRID = (8, 4)
"""Starts over a band (along Re α̂, along Im α̂); doubled when the count is not met."""
REFINEMENTS = 3
"""Doublings of the grid of starts before a part is reported uncertified."""
DOUBLINGS = 5
"""Doublings of the box height B before the search gives up on ``n_roots``."""
PAD = 32
"""Starts are padded to a multiple of PAD (one compiled Newton program per multiple)."""
SEED_PAD = 8
"""Seeds (:func:`search_box`) are padded to a multiple of SEED_PAD."""
ROOT_RTOL = 1e-10
"""Relative Newton step at which a start has converged."""


class SearchStatus(enum.IntEnum):
    """How complete the list of :func:`wavenumbers` is."""

    CERTIFIED = 0  # every root in the box was found: the argument-principle count is met
    NOT_CERTIFIED = 1  # fewer distinct roots were found than the count says the box holds
    COUNT_FAILED = 2  # the count itself failed (a zero on the contour, a non-finite value)


@serializable
class Wavenumbers(NamedTuple):
    """The roots α̂ of :func:`wavenumbers` (complex, Re α̂ ≥ 0, by |Im α̂| then Re α̂, NaN-padded),
    their ``attenuation`` |Im α̂| (per unit R_i), a per-root ``status`` (:class:`Status`:
    CONVERGED, or NO_ROOT for padding) and the search's ``certificate`` (:class:`SearchStatus`)."""

    alpha: jax.Array
    attenuation: jax.Array
    status: jax.Array
    certificate: jax.Array


def _phasor(problem, wall, fixed, fluid, m, unknown):
    def phasor(z):
        f = jax.vmap(lambda x: characteristic.winding_value(problem.family, wall, x, fixed, fluid,
                                                            problem.order, m, unknown,
                                                            problem.decoupled))(z)
        size = jnp.abs(f)
        finite = jnp.isfinite(size)
        return jnp.where(size > 0, f / jnp.where(size > 0, size, 1.0), 0.0), finite

    return phasor


HEXAGON_PIECES = (10, 10, 10, 9, 10, 9)
"""Initial pieces of the six sides of a searched region (:func:`region`; LANES samples in all)."""


def region(lo: complex, hi: complex, corner: float | None = None) -> np.ndarray:
    """The six vertices (counter-clockwise) of the searched region: the rectangle lo–hi, less the
    corner {Re x < c < Im x} where ``corner`` c lies inside it, or else the rectangle itself with
    its top and left sides halved (one counting program serves both)."""
    if corner is not None and lo.real < corner < hi.real and lo.imag < corner < hi.imag:
        return np.array([lo, complex(hi.real, lo.imag), hi, complex(corner, hi.imag),
                         complex(corner, corner), complex(lo.real, corner)])
    return np.array([lo, complex(hi.real, lo.imag), hi, complex(0.5 * (lo.real + hi.real), hi.imag),
                     complex(lo.real, hi.imag), complex(lo.real, 0.5 * (lo.imag + hi.imag))])


def inside(z, lo: complex, hi: complex, corner: float | None = None):
    """Whether z (a number or an array) lies in the searched region of :func:`region`, its boundary
    included (a corner outside the rectangle leaves it whole); traceable for a JAX array z."""
    z = z if isinstance(z, jax.Array) else np.asarray(z)
    ok = (lo.real <= z.real) & (z.real <= hi.real) & (lo.imag <= z.imag) & (z.imag <= hi.imag)
    return ok if corner is None else ok & ~((z.real < corner) & (z.imag > corner))


@jit(static_argnames=("problem", "unknown"))
def _count(problem, wall, fixed, fluid, m, vertices, size, unknown=Unknown.ALPHA):
    """Zeros of F(x) (x = α̂ at a fixed Ω, or Ω at a fixed α̂) inside the closed polygon of
    ``vertices`` (:func:`region`), refined to segments of at most ``size``/LANES: (count, status)."""
    starts = jnp.asarray(vertices, complex)
    ends = jnp.roll(starts, -1)
    count, status, _ = winding_count(_phasor(problem, wall, fixed, fluid, m, unknown), starts, ends,
                                     2.0 * np.pi, HEXAGON_PIECES, size / LANES,
                                     MIN_RELATIVE_LENGTH * size, MAX_EVALUATIONS)
    return count, status


def complex_newton(problem, wall, fixed, fluid, m, x0, unknown=Unknown.ALPHA):
    """(x, converged): Newton on F from x0 in the complex plane, x ← x − 1/(d ln F/dx) with the
    analytic log-derivative of :func:`jaxdea.physics.characteristic.value_and_log_slope`, until the
    step is below ROOT_RTOL of x (at most NEWTON_STEPS); converged also needs |f| < 1e-8 there,
    from the loop's last pass (:func:`_newton_step`: one compiled evaluation for both)."""
    def step(state):
        k, x, done, _, _ = state
        going = (k < NEWTON_STEPS) & ~done
        x_new, done_new, _, at_root = _newton_step(problem, wall, fixed, fluid, m, unknown, x, done)
        return (k + going, jnp.where(going, x_new, x), jnp.where(going, done_new, done), at_root,
                ~going)

    _, x, _, converged, _ = jax.lax.while_loop(
        lambda state: ~state[-1], step,
        (0, x0, jnp.asarray(False), jnp.asarray(False), jnp.asarray(False)))
    return x, converged


def _newton_step(problem, wall, fixed, fluid, m, unknown, x, done):
    """(x', done', settled, at_root): one step of :func:`complex_newton` where not ``done``. A
    start is done after a step that is not finite or below ROOT_RTOL of x', settled where that
    small step was taken at |f| < 1e-8; ``at_root``: done, finite and |f| < 1e-8 at x itself (a
    Newton loop's last pass, which takes no step: whether it stopped at a root)."""
    f, log_slope = characteristic.value_and_log_slope(problem.family, wall, x, fixed, fluid,
                                                      problem.order, m, unknown,
                                                      decoupled=problem.decoupled)
    dx = jnp.where(done, 0.0, 1.0 / log_slope)
    ok = jnp.isfinite(dx)
    x_new = jnp.where(ok, x - dx, x)
    small = ~done & ok & (jnp.abs(dx) <= ROOT_RTOL * jnp.abs(x_new))
    below = jnp.abs(f) < 1e-8
    return x_new, done | ~ok | small, small & below, done & jnp.isfinite(jnp.abs(x)) & below


KNOWN = 16
"""Roots already found in a region, passed to a Newton batch (NaN-padded to a multiple of KNOWN)."""
DISTINCT = 1e-7
"""Two roots closer than DISTINCT times the box size are one (:func:`_distinct`)."""


def _new_roots(x, good, region, known):
    """How many of the converged lanes (``good``) hold distinct roots (:func:`_distinct`'s rule,
    lane order) inside ``region`` = (lo, hi, corner) (:func:`inside`; corner inf for none) that are
    not among ``known``."""
    lo, hi, corner = region
    tol = DISTINCT * jnp.abs(hi - lo)
    good = good & inside(x, lo, hi, corner)
    earlier = jnp.tril((jnp.abs(x[:, None] - x[None, :]) <= tol) & good[None, :], k=-1)
    seen = jnp.any(jnp.abs(x[:, None] - known[None, :]) <= tol, axis=1)
    return jnp.sum(good & ~jnp.any(earlier, axis=1) & ~seen)


@jit(static_argnames=("problem", "unknown"))
def _newton(problem, wall, fixed, fluid, m, starts, region, known, need, unknown=Unknown.ALPHA):
    """:func:`complex_newton` from every start, one batch: (roots, converged). The batch stops
    once ``need`` distinct roots inside ``region`` (lo, hi, corner), other than ``known``, have
    settled (:func:`_newton_step`), instead of when its slowest start does: the other starts'
    roots are not needed (the grids of ``wavenumbers`` at Ω = 0.5 of a hysteretic tube: their
    slowest starts took 11–19 steps, most of the others 6–10).

    The loop's last pass evaluates f at the final x without a step: converged where done, finite
    and |f| < 1e-8 there (:func:`_newton_step`), from the same compiled evaluation as the steps
    (a second one, of f alone after the loop, took 0.4–0.7 s of the program's first compile)."""
    def step(state):
        k, x, done, good, _, _ = state
        going = (k < NEWTON_STEPS) & jnp.any(~done) & (_new_roots(x, good, region, known) < need)
        x_new, done_new, settled, at_root = jax.vmap(lambda x, done: _newton_step(
            problem, wall, fixed, fluid, m, unknown, x, done))(x, done)
        return (k + going, jnp.where(going, x_new, x), jnp.where(going, done_new, done),
                good | (going & settled), at_root, ~going)

    none = jnp.zeros(starts.shape, bool)
    _, x, _, _, converged, _ = jax.lax.while_loop(
        lambda state: ~state[-1], step, (0, starts, none, none, none, jnp.asarray(False)))
    return x, converged


def _converged(problem, wall, fixed, fluid, m, starts, pad, unknown, region, known, need):
    """The roots to which :func:`complex_newton` converged from ``starts`` (padded to a multiple of
    ``pad``: few compiled programs), the batch stopped once ``need`` distinct roots inside
    ``region`` = (lo, hi, corner or None) other than the ``known`` ones have converged."""
    padded = np.resize(starts, -(-starts.size // pad) * pad)
    lo, hi, corner = region
    known = np.asarray(known, complex)
    size = max(KNOWN, -(-known.size // KNOWN) * KNOWN)
    known = np.concatenate([known, np.full(size - known.size, np.nan + 0j)])
    region = (jnp.asarray(lo, complex), jnp.asarray(hi, complex),
              jnp.asarray(np.inf if corner is None else corner, float))
    roots, ok = _newton(problem, wall, fixed, fluid, m, jnp.asarray(padded), region,
                        jnp.asarray(known), jnp.asarray(need, jnp.int32), unknown)
    return [complex(z) for z, good in zip(np.asarray(roots), np.asarray(ok), strict=True) if good]


def _distinct(roots, scale):
    """The distinct roots (within DISTINCT of the box size) in first-found order."""
    kept = []
    for z in roots:
        if all(abs(z - k) > DISTINCT * scale for k in kept):
            kept.append(z)
    return kept


NEAR_CONTOUR = 1e-4
"""A root found within this share of the box size of a searched region's contour has its count
taken again on the solve's own wall (:func:`search_box`, ``count_wall``)."""


def _near_contour(roots, vertices, size) -> bool:
    """Whether any of ``roots`` lies within NEAR_CONTOUR·size of the polygon of ``vertices``."""
    if not roots:
        return False
    z = np.asarray(roots, complex)[:, None]
    a, b = vertices[None, :], np.roll(vertices, -1)[None, :]
    t = np.clip(((z - a) * np.conj(b - a)).real / np.abs(b - a) ** 2, 0.0, 1.0)
    return bool(np.min(np.abs(z - (a + t * (b - a)))) < NEAR_CONTOUR * size)


def search_box(problem, wall, fixed, fluid, m, lo, hi, starts_of, unknown=Unknown.ALPHA,
               seeds=(), corner=None, count_wall=None):
    """(the distinct roots x inside the box lo–hi, :class:`SearchStatus`) by Newton from the starts
    that ``starts_of(k)`` gives at refinement k, until they match the box's count (x = α̂ at the
    fixed Ω, or Ω at the fixed α̂ for ``unknown=Unknown.OMEGA``). ``corner``: the box less its
    corner {Re x < c < Im x} (:func:`region`; starts and seeds outside are dropped). ``seeds``,
    groups of guesses near the roots (e.g. the elastic roots moved by the damping, then the elastic
    roots themselves), are tried first, group by group, alone: where a group meets the count, no
    other group or grid is searched. Each batch of starts stops once the roots the count still
    needs have converged inside the region (:func:`_newton`).

    ``count_wall``: a coarser discretisation of the same wall on which the zeros are counted (the
    count is the search's main cost, and its evaluations are proportional to the sublayers), the
    roots being solved on ``wall``. The two walls' zeros differ by their discretisation errors, so
    the counts agree unless a zero lies within those errors of the contour. Where the roots found
    do not meet the coarse count, or one lies within NEAR_CONTOUR of the contour, the count is
    taken again on ``wall`` and the search goes on against it: a certificate is always that of
    ``wall``'s count or of a coarse count met by roots that are all clear of the contour."""
    vertices = region(lo, hi, corner)
    size = abs(hi - lo)
    groups = [np.asarray(group, complex) for group in seeds]
    groups = [group[inside(group, lo, hi, corner)] for group in groups]
    groups = [group for group in groups if group.size]
    attempts = groups + [np.asarray(starts_of(k), complex) for k in range(REFINEMENTS + 1)]
    found_inside, count, k = [], 0, 0
    for on in ([wall] if count_wall is None else [count_wall, wall]):
        count, status = (int(v) for v in _count(problem, on, fixed, fluid, m, vertices, size,
                                                unknown))
        if status != CountStatus.CERTIFIED:
            if on is wall:
                return [], SearchStatus.COUNT_FAILED
            continue  # the coarse count failed: count on the solve's wall
        while len(found_inside) < count and k < len(attempts):  # count 0: no Newton at all
            starts = attempts[k][inside(attempts[k], lo, hi, corner)]
            found = [z for z in _converged(problem, wall, fixed, fluid, m, starts,
                                           SEED_PAD if k < len(groups) else PAD, unknown,
                                           (lo, hi, corner), found_inside,
                                           count - len(found_inside))
                     if inside(z, lo, hi, corner)]
            found_inside = _distinct(found_inside + found, size)
            k += 1
        if len(found_inside) == count and not (on is count_wall
                                                and _near_contour(found_inside, vertices, size)):
            break
    return found_inside, (SearchStatus.CERTIFIED if len(found_inside) == count
                          else SearchStatus.NOT_CERTIFIED)


def validate_search(caller: str, tube, fixed, fluid, m, n_roots, limit) -> None:
    """The checks of a Python search of the complex plane (``caller``, ``fixed`` = (name, value)
    of the real variable, ``limit`` = (name, value or None) of its extent).

    Raises:
        ValueError: traced inputs (the search runs in Python), a bad count or limit, an invalid
            fluid or the paper's coupling (its poles), naming the parameter.
    """
    name, value = fixed
    if traced((tube, value, fluid, m)):
        raise ValueError(f"tube, {name}, fluid and m must be concrete: {caller} searches the "
                         "complex plane in Python and cannot run under jit, grad or vmap (call it "
                         f"outside, once per {name})")
    validate_count("n_roots", n_roots)
    if limit[1] is not None:
        validate_positive(*limit)
    validate_fluid(fluid)
    if Face.of(fluid).has_poles:
        raise ValueError(f"fluid: {caller} needs the 'acoustic' coupling (the 'paper' coupling "
                         "has poles), got coupling='paper'")


def wavenumbers(tube: Tube, omega, fluid: Fluid | None = None, n_roots: int = 4, m: int = 0,
                n_layers: int | None = None, scheme: str | None = None, torsional: bool = False,
                alpha_max=None, outer: Fluid | None = None) -> Wavenumbers:
    """The ``n_roots`` complex wavenumbers α̂ at the real frequency Ω nearest the real axis.

    Roots of F(α̂; Ω) (module docstring) with Re α̂ ≥ 0, ordered by |Im α̂|, then Re α̂: the
    propagating waves (real α̂) first, then attenuated and evanescent ones. For a lossless tube the
    real ones are exactly the α̂ at which :func:`jaxdea.frequencies` gives Ω, and a complex root
    comes with its conjugate (both listed). u ∝ e^{i(Ωt − α̂z)} away from the ends: |Im α̂| is the
    attenuation per unit R_i.

    Args:
        tube: the :class:`~jaxdea.Tube`.
        omega: Ω > 0, real.
        fluid: None or an ``"acoustic"`` :class:`~jaxdea.Fluid` (the paper's coupling has poles in
            α̂ and is not supported: ValueError).
        outer: a surrounding :class:`~jaxdea.Fluid` (unbounded, ``"acoustic"``) or None: the tube's own
            ``tube.outer`` (None: vacuum). Subsonic modes carry its added mass
            (docs/theory/real_tubes.md §6).
        n_roots: how many roots, an integer ≥ 1.
        m, torsional, n_layers, scheme: the family and discretisation, as for
            :func:`jaxdea.frequencies` (the default discretisation is resolved at |α̂| = the box's
            far corner).
        alpha_max: the largest Re α̂ searched (default: module docstring).

    Returns:
        An instance of :class:`Wavenumbers`; its ``certificate`` is CERTIFIED when the
        argument-principle counts of the searched box were met by the roots found.

    Raises:
        ValueError: naming the parameter, for invalid inputs, and for traced inputs (a Python
            search: call it outside ``jit``, ``grad`` and ``vmap``).

    Examples:
        >>> w = wavenumbers(Tube(voltage=0.0, lambda_i=1.0, lambda_z=1.0), 1.0, n_roots=3, m=1)
    """
    tube = with_outer(tube, outer)
    validate_search("wavenumbers", tube, ("omega", omega), fluid, m, n_roots,
                    ("alpha_max", alpha_max))
    validate_positive("omega", omega)
    problem = describe(tube, NO_ALPHA, fluid, n_layers, scheme, m, torsional, damped=True)
    tube, omega, fluid = canonical(tube, omega, fluid)
    omega = float(omega)
    m_value = as_float(float(m))
    height = max(1.0, omega)
    if alpha_max is None:
        alpha_max = default_alpha_max(problem, tube, omega, fluid)
    roots, certificate, low = [], SearchStatus.CERTIFIED, 0.0
    # every band's zeros counted on one wall: the checked default's start at the first band's
    # reach (one counting program; search_box recounts on a band's own wall where needed)
    reach = abs(complex(alpha_max, height))
    coarse = laminate(n_layers, scheme, tube, reach, m=int(m), checked=True)
    count_wall = (None if coarse == laminate(n_layers, scheme, tube, reach, m=int(m))
                  else discretized(tube, n_layers=coarse))  # a given discretisation: its own
    for _ in range(DOUBLINGS + 1):  # bands of the box, each twice as high as the last
        band, certificate = _box(problem, tube, omega, fluid, m_value, n_layers, scheme, low,
                                 height, float(alpha_max), count_wall, coarse)
        roots += band
        if certificate != SearchStatus.CERTIFIED or len(roots) >= n_roots:
            break
        low, height = height, 2.0 * height
    # by |Im α̂|, then Re α̂; of a conjugate pair the root with Im α̂ < 0 (decaying along +z) first
    roots = sorted(roots, key=lambda z: (round(abs(z.imag), 9), round(z.real, 9), z.imag))[:n_roots]
    pad = n_roots - len(roots)
    alpha = jnp.asarray(np.array(roots + [complex(np.nan, np.nan)] * pad, dtype=complex))
    status = jnp.asarray([Status.CONVERGED] * len(roots) + [Status.NO_ROOT] * pad, jnp.int32)
    if len(roots) < n_roots and certificate == SearchStatus.CERTIFIED:
        certificate = SearchStatus.NOT_CERTIFIED
    return Wavenumbers(alpha, jnp.abs(jnp.imag(alpha)), status,
                       jnp.asarray(int(certificate), jnp.int32))


SOUND_LINE_GAP = 1.0 + 1e-9
"""The searches either side of a surrounding fluid's sound line (α̂ = Ω/ĉ_o here, Ω = ĉ_oα̂ in
:func:`jaxdea.complex_frequencies`) stop at it /SOUND_LINE_GAP and start at it ·SOUND_LINE_GAP: off
its branch point and its cut (:func:`_either_side_of_the_sound_line`)."""


def _either_side_of_the_sound_line(parts, tube, omega, grid):
    """The parts of a band (((lo, hi), starts) pairs), each right part that the sound line
    α̂_s = Ω/ĉ_o of a surrounding fluid crosses cut in two at it, with the grid of starts over each
    (``grid(lo_im, hi_im, k, lo_re, hi_re)``). γ = sqrt(α̂² − Ω²/ĉ_o²) takes the outgoing sheet
    left of it (Re α̂ < α̂_s: supersonic waves radiate, :func:`jaxdea.physics.dispersion.outer_face`)
    and the decaying one right of it; the two meet with a jump along Re α̂ = α̂_s, so the argument
    principle holds on a contour inside one of them, never across (a box across it was COUNT_FAILED
    at every Ω: tests/test_outer_fluid.py)."""
    if tube.outer is None:
        return parts
    line = omega / float(tube.outer.speed_ratio)
    split = []
    for (lo, hi), starts in parts:
        if not lo.real < line < hi.real:
            split.append(((lo, hi), starts))
            continue
        left, right = line / SOUND_LINE_GAP, line * SOUND_LINE_GAP
        for a, b in ((lo.real, left), (right, hi.real)):
            split.append(((complex(a, lo.imag), complex(b, hi.imag)),
                          lambda k, a=a, b=b, lo=lo, hi=hi: grid(lo.imag, hi.imag, k, a, b)))
    return split


def default_alpha_max(problem, tube, omega, fluid) -> float:
    """The default α_max at Ω: 2Ω/min(c_min, ĉ_f) + 4 max(1, Ω) (module docstring)."""
    probe = discretized(tube, n_layers=8)
    c_min = float(jnp.sqrt(problem.family.slowest_shear(probe.coef)))
    if fluid is not None:
        c_min = min(c_min, float(fluid.speed_ratio))
    return 2.0 * omega / c_min + 4.0 * max(1.0, omega)


def _box(problem, tube, omega, fluid, m, n_layers, scheme, low, high, alpha_max, count_wall=None,
         coarse=None):
    """The roots with Re α̂ ≥ 0 and low ≤ |Im α̂| ≤ high (the band of the box [0, α_max] between
    those heights, both signs; low = 0: the band through the real axis) and its certificate, its
    zeros counted on ``count_wall`` (discretisation ``coarse``; :func:`search_box`) unless that is
    the band's own discretisation."""
    layers = laminate(n_layers, scheme, tube, abs(complex(alpha_max, high)), m=int(m))
    wall = discretized(tube, n_layers=layers)
    count_wall = None if coarse == layers else count_wall
    eps, eta = 1e-3 * alpha_max, 1e-3 * high

    def grid(lo_im, hi_im, k, lo_re=eps, hi_re=alpha_max):
        """Starts over one band (Newton stays on the real axis from it)."""
        re = np.linspace(lo_re, hi_re, GRID[0] * 2**k + 2)[1:-1]
        im = np.linspace(lo_im, hi_im, GRID[1] * 2**k + 1)
        return (re[:, None] + 1j * im[None, :]).ravel()

    def axis(lo_im, hi_im):
        def starts(k):
            return 1j * np.linspace(lo_im, hi_im, GRID[0] * 2**k + 2)[1:-1]
        return starts

    if low == 0.0:  # one band across the real axis, and the imaginary axis above and below η
        parts = [((complex(eps, -high), complex(alpha_max, high)),
                  lambda k: grid(-high, high, k)),
                 ((complex(-eps, eta), complex(eps, high)), axis(eta, high)),
                 ((complex(-eps, -high), complex(eps, -eta)), axis(-high, -eta))]
    else:
        parts = [((complex(eps, low), complex(alpha_max, high)), lambda k: grid(low, high, k)),
                 ((complex(eps, -high), complex(alpha_max, -low)), lambda k: grid(-high, -low, k)),
                 ((complex(-eps, low), complex(eps, high)), axis(low, high)),
                 ((complex(-eps, -high), complex(eps, -low)), axis(-high, -low))]
    parts = _either_side_of_the_sound_line(parts, tube, omega, grid)
    roots, status = [], SearchStatus.CERTIFIED
    for (lo, hi), starts in parts:
        found, part_status = search_box(problem, wall, omega, fluid, m, lo, hi, starts,
                                        count_wall=count_wall)
        roots += [z for z in found if z.real >= -1e-9 * abs(z)]
        status = max(status, part_status)
    return roots, SearchStatus(status)
