"""Complex frequencies at a real wavenumber: the resonances of a damped tube, with their quality
factors (API.md, "Real tubes"; docs/theory/real_tubes.md §4–§5).

A damped tube (``Tube(damping=...)``) adds η*(Ω)(L + Lᵀ) to the incremental stress on the relaxed
base state, so the characteristic function F(Ω) = det(Out A(Ω) S) of
:mod:`jaxdea.physics.characteristic` (unknown ``omega``) is complex. It is analytic in Re Ω > 0
(entire for hysteretic damping; Prony poles, the fractional branch cut and, for Kelvin–Voigt and
Prony, the essential singularity where the damped shear modulus vanishes lie on the imaginary
axis: docs/theory/real_tubes.md §5). With the time factor e^{iΩt} a decaying mode has Im Ω > 0
and the quality factor Q = Re Ω/(2 Im Ω).

Search and certificate: the roots are sought in boxes [ε, Ω_max] × [−δ, Ω_max] of the Ω plane
(δ = ε = 0.02 min(1, Ω_max): the real roots of an elastic tube lie inside, the imaginary axis, where
Prony's relaxation roots and poles lie, outside; modes with Q < 1/2 above the box are not sought,
nor those of the corner Re Ω < y_s/2 < Im Ω where the wall's damped shear modulus vanishes at iy_s,
the point where the roots of ever higher modes gather, nor, in a surrounding fluid's leaky sheet,
those of the corner Re Ω < Ω_b/2 < Im Ω of a box reaching Ω_b, where the radiation condition leaves
the range of the outer Bessel functions: :func:`_box`),
each counted by the argument principle (on the checked default's starting discretisation, and
again on the solve's own where the roots found do not meet that count or one lies next to the
contour) and searched by complex Newton on the analytic log-derivative
(:func:`jaxdea.solve.wavenumbers.search_box`), from the elastic roots moved by the damping
first. Without ``omega_max`` the first box reaches 1.25 × the highest of the ``n_roots`` elastic
frequencies (``damping=None``) and the next boxes extend it, each as wide again as the last, until
``n_roots`` roots are certified.
"""

import dataclasses
import functools
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from ..compiled import serializable
from ..numerics.scalar import Status
from ..params import Fluid, Tube, as_float, canonical, guard, validate_alpha, with_outer
from ..physics import characteristic
from ..physics.characteristic import Unknown
from ..physics.problem import describe
from ..physics.transfer import discretize, discretized, laminate, viscous_singularity
from .roots import frequencies
from .wavenumbers import (
    GRID,
    SOUND_LINE_GAP,
    SearchStatus,
    complex_newton,
    search_box,
    validate_search,
)

EXTENSIONS = 3
"""Boxes added to the right when fewer than ``n_roots`` roots lie below the default Ω_max."""
MARGIN = 0.02
"""ε = δ = MARGIN · min(1, Ω_max): the box's distance from the imaginary axis and below the real
axis."""
VISCOUS_SHARE = 0.5
"""κ: a box's contour keeps κy_s from the viscous singularity iy_s of the damped wall
(:func:`_box`); the corner it leaves out, Re Ω < κy_s < Im Ω, holds only modes with Q < 1/2."""
LEAKY_SHARE = 0.5
"""A box right of the sound line, [Ω_a, Ω_b] × [−δ, Ω_b], leaves out the corner
Re Ω < LEAKY_SHARE·Ω_b < Im Ω (modes with Q < 1/2 only; :func:`_box`). On the leaky sheet the outer
argument y = γr̂_o (:func:`jaxdea.physics.dispersion.outer_face`) depends on u = Ω/(ĉ_oα̂) alone and
turns towards the negative real axis as Im u/Re u grows: |arg y| reaches
:data:`jaxdea.numerics.bessel.ARG_MAX` = 0.9π, beyond which the Bessel ratio is NaN, at
Im Ω/Re Ω = 2.75 just right of the sound line and 3.07 far from it. With the corner at Ω_b/2 and
boxes no wider than Ω_b ≤ :data:`LEAKY_RATIO`·Ω_a, every point of the contour and of the region has
Im Ω/Re Ω ≤ max(Ω_b/(2Ω_a), 2) ≤ 2.5: inside that range (before, the first leaky box of an
unstretched tube in water-like fluid reached Im Ω = 2.9 Re Ω at its left side and its count
failed: COUNT_FAILED, tests/test_outer_fluid.py)."""
LEAKY_RATIO = 5.0
"""The widest box right of the sound line spans [Ω_a, LEAKY_RATIO·Ω_a] (:data:`LEAKY_SHARE`)."""


@serializable
class ComplexRoots(NamedTuple):
    """The roots Ω of :func:`complex_frequencies` (complex, ascending in Re Ω, NaN-padded), their
    ``quality_factor`` Re Ω/(2 Im Ω) (inf for a real root), a per-root ``status`` (:class:`Status`:
    CONVERGED, or NO_ROOT for padding) and the search's ``certificate`` (:class:`SearchStatus`)."""

    omega: jax.Array
    quality_factor: jax.Array
    status: jax.Array
    certificate: jax.Array


def complex_frequencies(tube: Tube, alpha, fluid: Fluid | None = None, n_roots: int = 3, m: int = 0,
                        omega_max=None, n_layers: int | None = None, scheme: str | None = None,
                        torsional: bool = False, outer: Fluid | None = None) -> ComplexRoots:
    """The ``n_roots`` complex frequencies Ω with the lowest Re Ω at the real wavenumber α̂.

    Roots of F(Ω; α̂) (module docstring) with Re Ω > 0, ascending in Re Ω: every root in the
    searched boxes is found (the argument-principle counts are met: ``certificate`` CERTIFIED).
    For an elastic tube they are the real :func:`jaxdea.frequencies`. Decaying modes have
    Im Ω > 0 (time factor e^{iΩt}).

    Args:
        tube: the :class:`~jaxdea.Tube`, damped (``damping=``) or not.
        alpha: α̂ > 0, real.
        fluid: None or an ``"acoustic"`` :class:`~jaxdea.Fluid` (the paper's coupling is not
            supported: ValueError).
        outer: a surrounding :class:`~jaxdea.Fluid` (unbounded, ``"acoustic"``) or None: the tube's own
            ``tube.outer`` (None: vacuum). Subsonic modes carry its added mass
            (docs/theory/real_tubes.md §6).
        n_roots: how many roots, an integer ≥ 1.
        m, torsional, n_layers, scheme: the family and discretisation, as for
            :func:`jaxdea.frequencies`.
        omega_max: the largest Re Ω searched (default: module docstring).

    Returns:
        An instance of :class:`ComplexRoots`.

    Raises:
        ValueError: naming the parameter, for invalid inputs, and for traced inputs (a Python
            search: call it outside ``jit``, ``grad`` and ``vmap``).

    Examples:
        >>> tube = Tube(voltage=0.0, lambda_i=1.0, lambda_z=1.0, damping=KelvinVoigt(0.1))
        >>> roots = complex_frequencies(tube, 1.0, n_roots=2)
    """
    tube = with_outer(tube, outer)
    validate_search("complex_frequencies", tube, ("alpha", alpha), fluid, m, n_roots,
                    ("omega_max", omega_max))
    validate_alpha(alpha, tube=tube)
    problem = describe(tube, alpha, fluid, n_layers, scheme, m, torsional, damped=True)
    tube, alpha, fluid = canonical(tube, alpha, fluid)
    alpha = float(alpha)
    m_value = as_float(float(m))
    layers = laminate(n_layers, scheme, tube, alpha, n_roots, int(m))
    wall = discretized(tube, n_layers=layers)
    coarse = laminate(n_layers, scheme, tube, alpha, n_roots, int(m), checked=True)
    count_wall = None if coarse == layers else discretized(tube, n_layers=coarse)
    elastic = np.asarray(frequencies(_elastic(tube), alpha, fluid, n_roots, omega_max,
                                     n_layers=n_layers, scheme=scheme, m=m, torsional=torsional))
    if omega_max is None:
        top = float(np.nanmax(elastic)) if np.isfinite(elastic).any() else 4.0
        edges = [1.25 * top * (k + 1) for k in range(EXTENSIONS + 1)]
    else:
        edges = [float(omega_max)]
    seeds = _seeds(tube, elastic[np.isfinite(elastic)])
    roots, certificate, low = [], SearchStatus.CERTIFIED, 0.0
    line = _below_the_sound_line(tube, alpha)
    for high in _split_at_the_sound_line(edges, tube, alpha):
        leaky = line is not None and low > line
        found, certificate = _box(problem, wall, count_wall, alpha, fluid, m_value, low, high,
                                  [[z for z in group if low < z.real <= high] for group in seeds],
                                  leaky)
        roots += found
        if certificate != SearchStatus.CERTIFIED or len(roots) >= n_roots:
            break
        low = high * SOUND_LINE_GAP ** 2 if high == _below_the_sound_line(tube, alpha) else high
    roots = sorted(roots, key=lambda z: (z.real, z.imag))[:n_roots]
    pad = n_roots - len(roots)
    omega = jnp.asarray(np.array(roots + [complex(np.nan, np.nan)] * pad, dtype=complex))
    status = jnp.asarray([Status.CONVERGED] * len(roots) + [Status.NO_ROOT] * pad, jnp.int32)
    if len(roots) < n_roots and certificate == SearchStatus.CERTIFIED and omega_max is None:
        certificate = SearchStatus.NOT_CERTIFIED
    return ComplexRoots(omega, quality_factor(omega), status, jnp.asarray(int(certificate), jnp.int32))


ROOT_OFFSET = 1e-12
"""Relative offset from a root at which its implicit derivative is taken when F rounds to exactly 0
there (infinite log-derivatives)."""


def _below_the_sound_line(tube, alpha):
    """ĉ_oα̂/SOUND_LINE_GAP for a tube in a surrounding fluid (None without one): just left of the
    cut Re Ω = ĉ_oα̂ between the subsonic and the leaky sheet
    (:func:`jaxdea.physics.dispersion.outer_face`)."""
    if tube.outer is None:
        return None
    return float(tube.outer.speed_ratio) * alpha / SOUND_LINE_GAP


def _split_at_the_sound_line(edges, tube, alpha):
    """The right edges of the boxes, with one just left of the sound line where it falls inside
    (the next box starts just right of it): the argument principle holds on a contour inside one
    sheet, never across the cut. Right of it no box is wider than LEAKY_RATIO times its left
    edge (:data:`LEAKY_SHARE`)."""
    line = _below_the_sound_line(tube, alpha)
    if line is None or line >= edges[-1]:
        return edges
    right = sorted({*(e for e in edges if e > line * SOUND_LINE_GAP ** 2)})
    split, low = [], line * SOUND_LINE_GAP ** 2
    for edge in right:
        while edge > LEAKY_RATIO * low:
            low *= LEAKY_RATIO
            split.append(low)
        split.append(edge)
        low = edge
    return [e for e in edges if e < line] + [line] + split


def quality_factor(omega):
    """Q = Re Ω/(2 Im Ω) (inf for a real Ω; NaN for NaN)."""
    omega = jnp.asarray(omega)
    im = jnp.imag(omega)
    return jnp.where(im == 0, jnp.inf, jnp.real(omega) / (2.0 * jnp.where(im == 0, 1.0, im)))


def _elastic(tube: Tube) -> Tube:
    """The tube without its damping laws (the tube's and every layer's)."""
    layers = tube.layers
    if layers is not None:
        layers = tuple(dataclasses.replace(layer, damping=None) for layer in layers)
    return tube.replace(damping=None, layers=layers)


SEED_STEPS = 30
"""Newton steps of the scalar relation Ω² = Ω_e²(1 + η*(Ω)) behind each seed (:func:`_seeds`)."""


def _seeds(tube: Tube, elastic) -> tuple:
    """Guesses of the damped roots from the elastic ones Ω_e, in two groups that
    :func:`jaxdea.solve.wavenumbers.search_box` tries one after the other: first the root of

        Ω² = Ω_e²(1 + η*(Ω))

    for the tube's law, by scalar Newton from Ω_e √(1 + η*(Ω_e)) (the relation is exact for the
    unstretched, unbiased, empty tube, docs/theory/real_tubes.md §4; η* evaluated at Ω rather than
    at Ω_e, which is only its first order: for Kelvin–Voigt η_v = 0.05 and Ω_e = 35.6 the damped
    root is 16.2 + 31.7i, the first order gave 43.9 + 25.7i and complex Newton on the wall took 17
    steps from it), then Ω_e itself. Where the layers carry the damping: Ω_e alone."""
    elastic = np.asarray(elastic, dtype=complex)
    if tube.damping is None:
        return ([complex(z) for z in elastic],)
    eta = lambda z: np.asarray(tube.damping.viscous_modulus(z), dtype=complex)  # noqa: E731
    square = elastic ** 2
    z = elastic * np.sqrt(1.0 + eta(elastic))
    with np.errstate(all="ignore"):
        for _ in range(SEED_STEPS):
            h = 1e-7 * np.abs(z)
            slope = 2.0 * z - square * (eta(z + h) - eta(z - h)) / (2.0 * h)
            step = (z * z - square * (1.0 + eta(z))) / slope
            new = z - step
            keep = np.isfinite(new) & (new.real > 0)  # Prony's poles and the fractional cut: Re Ω = 0
            z = np.where(keep, new, z)
            if not np.any(keep & (np.abs(step) > 1e-13 * np.abs(z))):
                break
    return [complex(v) for v in z if np.isfinite(v)], [complex(v) for v in elastic]


def _box(problem, wall, count_wall, alpha, fluid, m, low, high, seeds=(), leaky=False):
    """The roots with low < Re Ω ≤ high and −δ ≤ Im Ω ≤ high (module docstring), and the box's
    certificate; ``seeds`` (groups of guesses) are tried first, group by group, the roots solved
    on ``wall`` and counted on ``count_wall`` (the checked default's starting discretisation, or
    None: ``wall``; :func:`jaxdea.solve.wavenumbers.search_box` says when ``wall``'s own count is
    taken instead).

    Where the damped wall's shear divisor vanishes at iy_s on the imaginary axis inside the box's
    height (:func:`jaxdea.physics.transfer.viscous_singularity`) and the box reaches left of
    κy_s (κ = VISCOUS_SHARE), the corner {Re Ω < κy_s < Im Ω} (Q < 1/2) is left out: the contour
    (:func:`jaxdea.solve.wavenumbers.region`) keeps κy_s from the singularity. A ``leaky`` box
    (right of a surrounding fluid's sound line) leaves out {Re Ω < LEAKY_SHARE·high < Im Ω}
    (:data:`LEAKY_SHARE`), the lower of the two corners where both apply."""
    margin = MARGIN * min(1.0, high)
    left = max(low, margin)
    lo, hi = complex(left, -margin), complex(high, high)

    def starts(k):
        re = np.linspace(left, high, GRID[0] * 2**k + 2)[1:-1]
        im = np.linspace(0.0, high, GRID[1] * 2**k + 1)
        return (re[:, None] + 1j * im[None, :]).ravel()

    corner = VISCOUS_SHARE * viscous_singularity(wall, high)
    if leaky:
        corner = min(corner, LEAKY_SHARE * high)
    found, status = search_box(problem, wall, alpha, fluid, m, lo, hi, starts, Unknown.OMEGA,
                               seeds=seeds, corner=corner, count_wall=count_wall)
    return [z for z in found if z.real > low], SearchStatus(status)


def solve_complex_frequency(tube: Tube, alpha, guess, fluid: Fluid | None = None, m: int = 0,
                            n_layers: int | None = None, scheme: str | None = None,
                            torsional: bool = False, outer: Fluid | None = None):
    """(Ω, status): the complex root nearest ``guess`` by Newton on F(Ω; α̂) (the analytic
    log-derivative), traceable, with implicit derivatives of Re Ω and Im Ω in the tube's leaves
    (damping and material parameters, layers), α̂ and the fluid:

        dΩ = −(∂ ln F/∂θ · dθ)/(∂ ln F/∂Ω),

    both log-derivatives carried across the wall
    (:func:`jaxdea.physics.characteristic.value_and_log_slope_along`).
    Use it to differentiate a root of :func:`complex_frequencies` (its ``omega`` as the guess).
    ``status`` is CONVERGED, MAX_ITER or INVALID (a traced invalid tube: Ω NaN).

    Examples:
        >>> tube = Tube(voltage=0.0, lambda_i=1.0, lambda_z=1.0, damping=KelvinVoigt(0.1))
        >>> jax.grad(lambda v: solve_complex_frequency(
        ...     tube.replace(damping=KelvinVoigt(v)), 1.0, 1.349 + 0.091j)[0].imag)(0.1)
    """
    tube = with_outer(tube, outer)
    problem = describe(tube, alpha, fluid, n_layers, scheme, m, torsional, damped=True)
    layers = laminate(n_layers, scheme, tube, alpha, 1, m)
    tube, alpha, fluid = canonical(tube, alpha, fluid)
    guess = jnp.asarray(guess, jnp.complex128)
    return _complex_root(problem, layers, tube, alpha, fluid, as_float(m), guess)


def _pieces_of(problem, layers, m):
    def pieces(args):
        tube, alpha, fluid, omega = args
        of = characteristic.block_pieces if problem.decoupled else characteristic.pieces
        return of(problem.family, discretize(tube, layers), omega, alpha, fluid, problem.order, m,
                  Unknown.OMEGA)
    return pieces


@functools.partial(jax.custom_jvp, nondiff_argnums=(0, 1))
def _complex_root(problem, layers, tube, alpha, fluid, m, guess):
    ok, tube, alpha, fluid = guard(tube, alpha, fluid)
    wall = discretize(tube, layers)
    x, converged = complex_newton(problem, wall, alpha, fluid, m, guess, Unknown.OMEGA)
    status = jnp.where(~ok, Status.INVALID, jnp.where(converged, Status.CONVERGED, Status.MAX_ITER))
    return jnp.where(ok, x, jnp.nan), status.astype(jnp.int32)


@_complex_root.defjvp
def _complex_root_jvp(problem, layers, primals, tangents):
    tube, alpha, fluid, m, guess = primals
    omega, status = _complex_root(problem, layers, tube, alpha, fluid, m, guess)
    pieces = _pieces_of(problem, layers, m)
    inputs = (tube, alpha, fluid)
    leaves, tree = jax.tree_util.tree_flatten(inputs)

    zeros = [jnp.zeros_like(x) for x in leaves]

    def along(tangent_inputs, omega_dot, at):
        return characteristic.value_and_log_slope_along(pieces, (*inputs, at), (*tangent_inputs,
                                                                                 omega_dot))[1]

    # a root that rounds to F = 0 exactly has infinite log-derivatives (their ratio NaN): there,
    # both are taken a relative ROOT_OFFSET off the root (dΩ/dθ changes by that much)
    at_root = along(jax.tree_util.tree_unflatten(tree, zeros), jnp.ones_like(omega), omega)
    at = jnp.where(jnp.isfinite(at_root), omega,
                   omega + ROOT_OFFSET * jnp.maximum(1.0, jnp.abs(omega)))
    along_omega = jnp.where(jnp.isfinite(at_root), at_root,
                            along(jax.tree_util.tree_unflatten(tree, zeros), jnp.ones_like(omega),
                                  at))
    # dΩ/dθ_i leaf by leaf, from the primals only (forward mode, one-hot tangents): the tangent out
    # is then a plain linear combination of the tangents in, which reverse mode transposes exactly
    # (a transpose of the carried wall tangent itself gave wrong cotangents under jit, measured)
    tangent = jnp.zeros_like(omega)
    for i, leaf_dot in enumerate(jax.tree_util.tree_leaves(tangents[:3])):
        one_hot = [jnp.ones_like(x) if j == i else z for j, (x, z) in enumerate(zip(leaves, zeros,
                                                                                    strict=True))]
        along_i = along(jax.tree_util.tree_unflatten(tree, one_hot), jnp.zeros_like(omega), at)
        tangent = tangent + (-along_i / along_omega) * leaf_dot
    status_dot = np.zeros(np.shape(status), jax.dtypes.float0)
    return (omega, status), (tangent, status_dot)
