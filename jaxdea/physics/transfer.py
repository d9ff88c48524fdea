"""Laminate discretisation of the wall and propagation across it (docs/theory/axisymmetric.md §3, paper Eqs.
42–44).

The wall is cut into N equal sublayers of thickness h = ĥ/N, and sublayer k is crossed by
T_k = exp(G_k), either ``jax.scipy.linalg.expm`` (the reference) or the equal-to-rounding
:func:`expm_taylor` (default: a degree-12 Taylor polynomial with scaling and squaring, cheap to
compile and to batch, differentiable to any order through a fixed graph). The generator G_k comes
from a scheme (:data:`SCHEMES`, static):

* ``"midpoint"`` (the paper's laminate, Eqs. 42–43, the default): G_k = h M(r̂_k) at the
  mid-radius; each sublayer is homogeneous, and the roots converge to those of the continuous wall
  as N⁻².
* ``"magnus4"``, ``"magnus6"``: the Magnus expansion of the continuous dY/dr̂ = M(r̂) Y truncated
  at order 4 (2 Gauss–Legendre nodes per sublayer) or 6 (3 nodes; Blanes, Casas & Ros 2000), with
  errors O(N⁻⁴), O(N⁻⁶): the unstretched benchmark curve meets 1e-8 relative at N = 5 with
  ``"magnus6"`` (measured 8.9e-9; the midpoint laminate has 1.1e-4 at N = 10).

Ω enters M only as −Ω² E (the inertia terms), so every scheme's G_k is a polynomial in Ω² whose
coefficients depend on the wall and α̂ alone (:func:`generator_coefficients`): they are formed once
per (wall, α̂) and each Ω costs a Horner sum, with no commutator or state matrix per Ω.

Two propagators:

* :func:`transfer_matrix`, the reference: the full product A = T_N ⋯ T_1 (``lax.scan``).
* :func:`propagate_basis`, the stable one used by the characteristic function: a 6×3 basis Y is
  carried across the sublayers and re-orthonormalised after each (Gram–Schmidt, applied twice),
  Y_k = Q_k R_k with R_k upper triangular with positive diagonal. Then A Y_0 = Q_N R_N ⋯ R_0, so
  det(B A Y_0) = det(B Q_N) ∏ det R_k with ∏ det R_k > 0: det(B Q_N) has the same zeros and sign as
  the raw determinant, and stays in [−1, 1] however much the product grows (like e^{α̂ĥ}).
  :func:`carry_basis_tangent` carries the Ω-tangent alongside in the frame of Q (Z = Ẏ R⁻¹), so a
  slope needs no derivative of Gram–Schmidt.

Mode families (static ``family``, :mod:`jaxdea.physics.state_matrix`): ``"longitudinal"`` (the 6×6 matrix
above, the default: its code path and values are those of the axisymmetric library), ``"order_m"``
(the 8×8 M_m of docs/theory/order_m.md §3 with a traced order ``m``, 8×4 basis) and ``"torsional"`` (2×2, 2×1
basis). Everything here is written for any matrix size. Every propagator also exists as a function
of w = Ω² (``…_of_w``), which may be negative (unstable states, docs/theory/order_m.md §6): the generator is a
polynomial in w with real coefficients, so no complex arithmetic is needed there.

The order-m family propagates the balanced state D⁻¹Y, D = diag(I, cI) on [displacements |
tractions] (:func:`propagate_balanced_of_w`): the inertia −wE no longer dominates ‖G‖ and the
exponentials need no squaring on the benchmark batch; with G of degree 1 in w its powers G², G³, G⁴
are polynomials in w formed once per wall (:func:`generator_powers`), so each Ω costs 2 products
of 8×8 matrices per sublayer instead of 5 + s.
"""

import math
from functools import partial
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from ..compiled import jit
from ..materials import Material
from ..params import Tube, admissible, as_float
from .base_state import (
    base_state,
    geometry,
    interface_radii,
    layer_integrals,
    layered_base_state,
    layered_pressure_difference,
    pressure_difference_unchecked,
    stretch,
    w1_at,
)
from .moduli import (
    Coefficients,
    Shear,
    closed_form_coefficients,
    coefficients,
    material_coefficients,
    push_forward_moduli,
)
from .state_matrix import (
    LONGITUDINAL,
    ORDER_M,
    family_inertia,
    family_matrix,
    inertia_matrix,
    state_matrix,
)

SCHEMES = {"midpoint": (0.5,),
           "magnus4": (0.5 - math.sqrt(3.0) / 6.0, 0.5 + math.sqrt(3.0) / 6.0),
           "magnus6": (0.5 - math.sqrt(15.0) / 10.0, 0.5, 0.5 + math.sqrt(15.0) / 10.0)}
"""The propagation schemes and their nodes in a sublayer (fractions of h from its inner face)."""


def scheme_order(scheme: str) -> int:
    """p with errors O(N⁻ᵖ): twice the number of Gauss nodes (midpoint 2, magnus4 4, magnus6 6)."""
    return 2 * len(SCHEMES[scheme])


class Layers(NamedTuple):
    """A static discretisation other than the equal-thickness midpoint laminate: ``count``
    sublayers crossed by ``scheme`` (a key of :data:`SCHEMES`), equally thick or, ``graded``,
    growing geometrically away from the inner face (:func:`breakpoints`). The equal-thickness
    midpoint laminate is the plain int N."""

    count: int
    scheme: str
    graded: bool = False


AUTO_SCHEME = "magnus6"
"""The scheme of the default, accurate discretisation (``n_layers=None``): sixth-order Magnus, graded."""
DEFAULT_RTOL = 1e-8
"""The relative accuracy of the roots that the default discretisation promises."""
LAYER_COUNTS = (16, 24, 32, 48, 64, 96, 128, 192, 256, 384, 512, 768, 1024)
"""The sublayer counts the accurate discretisation chooses from (few programs to compile)."""
TRACED_LAYERS = LAYER_COUNTS[0]
"""The accurate discretisation's N where the tube's geometry, α̂ or m are traced (inside a caller's
jit, vmap or grad of them), and its least N everywhere, so that a batch and its points alone use
the same N in the usual regime: ≤ 1e-8
(tests/test_accuracy_default.py): wherever :func:`required_layers` ≤ 16 (the paper's tube:
α̂ĥ ≤ 2 and m ≤ 13). A root at a point for which it asks more is INACCURATE
(:func:`checked_laminate`)."""
CHECKED_COUNTS = (6, 8, 12) + LAYER_COUNTS
"""The counts of a discretisation whose roots are checked as they are solved and that starts below
the rule (a concrete default :func:`jaxdea.dispersion_curve`): it starts from :data:`CHECKED_SHARE`
of the rule and refines where the check asks (issue 42, item 11). From 16 on they are
:data:`LAYER_COUNTS`."""
CHECKED_SHARE = 0.45
"""The share of :func:`required_layers` a checked discretisation starts from. The rule is
calibrated for every wall with a margin (benchmarks/layer_errors_results.md: the N that 1e-8
needs is 0.1–0.95 of it, the state unseen), so a checked curve starts lower and lets its check
(:func:`jaxdea.solve.curves._checked_curve`) refine: the unstretched 200-α̂ curve of K = 4 takes
N = 6 (3.0e-9 off the exact cylinder, 5.3 ms) instead of 16 (8.3e-12, 8.1 ms;
benchmarks/checked_curve.py)."""
CHECKED_RULE_MAX = LAYER_COUNTS[0]
"""A checked discretisation starts below the rule only where the rule's count is at most this, or
at an order m > 0 (:func:`auto_layer_count`)."""
LAYERED_SHARE = 0.75
"""The share of :func:`required_layers` a checked discretisation of a wall of two or more layers
starts from. Its sublayers are equal within each layer (:func:`layer_shares`), and the graded
single wall's error at small N partly cancels across the wall (at N = 6 the 4th root of the
paper's tube, α̂ = 1, is 3.9e-8 off on equal sublayers and 3.7e-9 graded; the sign of the error
turns near the grading's share of 0.5), which a layered wall does not have: the §7(d) sandwich
of benchmarks/real_walls.py is 1.0e-7 off at N = 6, 7.4e-9 at 8 (estimated 1.4e-8 with the
check's margin: refined) and 1.4e-9 at 12, so from :data:`CHECKED_SHARE` it was solved twice, at
6 and at 12 (first call 9.3 → 19.6 s, the curve 32 → 48 ms). From 0.75 of the rule it starts at
12 and is solved once."""
ORDER_FACTOR = 5.0
"""c of the order-m term of :func:`required_layers`, N ≥ c m ln(1 + ĥ/r̂_i)^p."""
ORDER_POWER = 0.8
"""p of the order-m term of :func:`required_layers`."""
PAPER_LAYERS = 30
"""N of the paper's laminate, taken by ``"midpoint"`` and ``"magnus4"`` given without
``n_layers``."""


def required_layers(thickness, r_inner, locking, alpha, n_roots: int = 3, m=0,
                    at_rest: bool = False, xp=np):
    """The N that graded sixth-order Magnus sublayers need for roots to ≤ 1e-8 relative (before
    rounding up to :data:`LAYER_COUNTS`): elementwise over arrays, ``xp`` NumPy for concrete values
    or ``jax.numpy`` inside a trace (:func:`checked_laminate`).

    N ≥ 4 + 1.5 max(K, 3) + 2 α̂ĥ + 2 m ĥ/r̂_i + 4 ln(1 + ĥ/r̂_i) + 9 ln(1 + ĥ/ℓ): the K lowest
    roots reach the thickness mode ≈ K/2 (phase Ωĥ/c ≲ (K + 1)π), the axial and circumferential
    wavenumbers α̂, m/r̂ add phase across ĥ, a thick wall adds the variation of 1/r̂ and a face
    near Gent locking (length ℓ, :func:`grading_length`) that of W_1. Calibrated on the measured
    errors (paper's tube, unstretched, η = 0.3 up to α̂ĥ = 86, 99 % of locking at G = 2 and 4) with
    a margin of about 10 (tests/test_accuracy_default.py). At α̂ĥ = 150 (η = 0.3, N = 384 for
    K ≤ 24) the two surface-like roots near Ω = 61.4 are ≤ 8.1e-11 off and the check of
    :func:`jaxdea.solve.roots._verified` estimates ≤ 7.5e-11 for the 17 roots in (60, 68); N = 192
    would leave 4.8e-9 (docs/howto/accuracy.md).

    High orders: also N ≥ 5 m L^0.8 with L = ln(1 + ĥ/r̂_i) (:data:`ORDER_FACTOR`,
    :data:`ORDER_POWER`): the fields of order m vary like r̂^{±m}, an exponent m L across the wall,
    and the modes of large m crowd into a face. Measured over m ≤ 100 on eleven walls and states
    (η = 0.3 … 0.95, V̂ ≤ 0.2, λ_i = 0.8 … 1.3; docs/howto/accuracy.md): the error at this N is
    ≤ 3.1e-9 (without the term: 5.4e-8 for the paper's tube at m = 100, 4.7e-7 at V̂ = 0.2, 1.6e-8
    for η = 0.5, λ_i = 0.8 at m = 8); below the first sum for m ≤ 4 on every wall, so it leaves
    their N alone.

    ``at_rest``: for the critical voltage, a root in V̂ of f(Ω = 0; V̂) (:func:`jaxdea.critical_voltage`,
    :func:`jaxdea.first_instability`), also N ≥ 18 m L^1.25: the static fields of order m vary like
    r̂^{±m} across the wall, and V̂_cr is less sensitive than Ω to the wall, so it needs more
    sublayers than the roots in Ω there. Measured: V̂_cr of m = 8 at η = 0.6 was 8.4e-7 off at
    N = 16 and of m = 6 at η = 0.3 1.1e-7 at N = 48 (the first sum); the error is (q/N)⁶ with
    q/(m L^1.25) ≤ 0.54 over the paper's tube, η = 0.3 … 0.6 and 99 % of locking (m ≤ 8), so the
    term leaves ≤ 7e-10."""
    wall = xp.log1p(thickness / r_inner)
    need = (4.0 + 1.5 * max(n_roots, 3) + 2.0 * alpha * thickness + 2.0 * m * thickness / r_inner
            + 4.0 * wall + 9.0 * xp.log1p(thickness / locking))
    need = xp.maximum(need, ORDER_FACTOR * m * wall ** ORDER_POWER)
    if at_rest:
        need = xp.maximum(need, 18.0 * m * wall ** 1.25)
    return need


def auto_layer_count(thickness, r_inner, locking, alpha, n_roots: int = 3, m=0,
                     at_rest: bool = False, checked: bool = False, share: float = CHECKED_SHARE) -> int:
    """N of the accurate discretisation (graded sixth-order Magnus) for roots to ≤ 1e-8 relative:
    :func:`required_layers` rounded up to :data:`LAYER_COUNTS` (16 at least, 1024 at most).
    ``checked``: the start of a discretisation whose roots are checked as they are solved,
    ``share`` of the rule (:data:`CHECKED_SHARE`, or :data:`LAYERED_SHARE` for a layered wall)
    rounded up to :data:`CHECKED_COUNTS` (6 at least), where the rule asks for at most
    :data:`CHECKED_RULE_MAX` (its least count, 16) or the order m is positive; elsewhere the
    rule's own count.

    The rule's margin shrinks as K grows (its 1.5K term against errors that grow like Ω_K⁶), so
    beyond its least count a start below the rule mostly fails its check and the curve is solved
    twice. Measured on 100 α̂ in [0.05, 3] (benchmarks/checked_curve.py ``--survey``, section l of
    benchmarks/README.md): the paper's tube with K = 8 started at 8 and was refined to 24, the
    rule's count (22.3 ms; now 24 at once, 15.0 ms); η = 0.3 with K = 8 went 16 → 48 (38.2 ms;
    now 48 at once, 25.6 ms). The order-m roots converge faster than the rule assumes: m = 1, 2, 4
    with K = 8 pass at 12 where the rule gives 24 (m = 2: 57 ms at 12, 123 ms at 24)."""
    need = float(required_layers(thickness, r_inner, locking, alpha, n_roots, m, at_rest))
    rule = counted(need)
    if not checked or (rule > CHECKED_RULE_MAX and not m > 0):
        return rule
    return counted(share * need, CHECKED_COUNTS)


def counted(need: float, counts=LAYER_COUNTS) -> int:
    """The least of ``counts`` ≥ ``need`` (the last one where none is)."""
    return next((c for c in counts if c >= need), counts[-1])


def _concrete_max(x):
    """max of a concrete array-like as a float, or None for a tracer (or anything non-numeric)."""
    try:
        return float(np.max(np.asarray(x, dtype=np.float64)))
    except (jax.errors.ConcretizationTypeError, jax.errors.TracerArrayConversionError, TypeError,
            ValueError):
        return None


def _wall_lengths_of(lambda_i, lambda_z, eta, gent, material):
    tube = Tube(lambda_i=lambda_i, lambda_z=lambda_z, eta=eta, gent=gent, material=material)
    geo = geometry(tube)
    ell = grading_length(tube, geo)
    locking = jnp.where(ell < geo.r_inner, ell, jnp.inf)
    ok = admissible(tube)  # a point past locking (or otherwise invalid) sets no N: it gives NaN
    return tuple(jnp.where(ok, x, jnp.nan) for x in (geo.thickness, geo.r_inner, locking))


_wall_lengths = jit(jax.vmap(_wall_lengths_of, (0, 0, 0, 0, None)), static_argnums=4)
"""The lengths of :func:`wall_lengths` for a batch of concrete tubes, compiled with jaxdea's options
(:func:`jaxdea.compiled.jit`): a first call of any solver compiles it before its own program
(0.19–0.21 s against 0.27–0.29 s with XLA's defaults, measured)."""
_material_wall_lengths = jit(jax.vmap(_wall_lengths_of, (0, 0, 0, 0, None)))
""":data:`_wall_lengths` for a material object (a pytree of parameters, traced)."""


def point_lengths(tube: Tube):
    """(ĥ, r̂_i, ℓ) at every point of a concrete tube (NumPy arrays of the leaves' broadcast shape;
    ℓ = ∞ where the locking layer is longer than r̂_i, NaN at invalid points); None if a geometric
    leaf is traced."""
    leaves = [tube.lambda_i, tube.lambda_z, tube.eta, tube.gent]
    if any(_concrete_max(x) is None for x in leaves):
        return None
    arrays = np.broadcast_arrays(*[np.asarray(x, dtype=np.float64) for x in leaves])
    try:  # inside a caller's trace the lengths are staged too: then unknown
        lengths = (_wall_lengths(*[a.ravel() for a in arrays], tube.material)
                   if isinstance(tube.material, str)
                   else _material_wall_lengths(*[a.ravel() for a in arrays], tube.material))
        return tuple(np.asarray(x).reshape(arrays[0].shape) for x in lengths)
    except (jax.errors.TracerArrayConversionError, jax.errors.ConcretizationTypeError):
        return None


def wall_lengths(tube: Tube):
    """(ĥ, r̂_i, ℓ) of a concrete tube, the largest ĥ/r̂_i and ĥ/ℓ over batched leaves
    (:func:`point_lengths`); None if a geometric leaf is traced."""
    lengths = point_lengths(tube)
    if lengths is None:
        return None
    h, r, ell = (np.ravel(x) for x in lengths)
    ok = np.isfinite(h) & np.isfinite(r) & (h > 0) & (r > 0) & ~np.isnan(ell)
    if not ok.any():
        return None
    h, r, ell = h[ok], r[ok], ell[ok]
    top = float(np.max(h))  # the worst case of every term of auto_layer_count
    locking = float(np.max(h / ell))
    return top, top / float(np.max(h / r)), top / locking if locking > 0 else math.inf


def laminate(n_layers=None, scheme=None, tube: Tube | None = None, alpha=None, n_roots: int = 3,
             m=0, at_rest: bool = False, checked: bool = False):
    """The static discretisation passed to the solvers.

    ``n_layers=None`` with ``scheme`` None or ``"magnus6"``: the accurate discretisation, graded
    sixth-order Magnus with N of :func:`auto_layer_count` from the (concrete) ``tube``, ``alpha``
    (largest over a batch), ``n_roots`` and ``m`` (:data:`TRACED_LAYERS` where they are traced):
    ``Layers(N, "magnus6", graded=True)``. An explicit ``n_layers`` keeps its meaning: the
    equal-thickness laminate of that ``scheme`` (``"midpoint"`` if None; N itself, the historical
    form, so compiled programs and their cache keys are unchanged), and ``"midpoint"``/``"magnus4"``
    without ``n_layers`` take the paper's N = 30. ``at_rest``: the N of a critical-voltage search,
    ``checked``: the start of a checked discretisation (:func:`auto_layer_count`). Validation is
    the caller's (:func:`jaxdea.params.validate_layers`, ``validate_scheme``)."""
    if isinstance(n_layers, Layers):  # already resolved (e.g. once for a whole design run)
        return n_layers
    if n_layers is None and scheme in (None, AUTO_SCHEME):
        return Layers(default_count(tube, alpha, n_roots, m, at_rest, checked), AUTO_SCHEME, True)
    n_layers = PAPER_LAYERS if n_layers is None else int(n_layers)
    scheme = "midpoint" if scheme is None else scheme
    return n_layers if scheme == "midpoint" else Layers(n_layers, scheme)


def default_count(tube, alpha, n_roots: int = 3, m=0, at_rest: bool = False,
                  checked: bool = False) -> int:
    """N of the accurate discretisation (:func:`laminate`)."""
    count = _resolved_count(tube, alpha, n_roots, m, at_rest, checked)
    return TRACED_LAYERS if count is None else count


def _resolved_count(tube, alpha, n_roots, m, at_rest, checked=False):
    """:func:`auto_layer_count` of the worst point, or None where the inputs are traced or staged."""
    alpha, m = _concrete_max(alpha), _concrete_max(m)
    lengths = None if tube is None or alpha is None or m is None else wall_lengths(tube)
    if lengths is None:
        return None
    layered = tube.layers is not None and len(tube.layers) > 1
    return auto_layer_count(*lengths, alpha, int(n_roots), m, at_rest, checked,
                            LAYERED_SHARE if layered else CHECKED_SHARE)


def checked_laminate(n_layers=None, scheme=None, tube: Tube | None = None, alpha=None,
                     n_roots: int = 3, m=0, at_rest: bool = False, checked: bool = False):
    """(:func:`laminate` of the arguments, ``short``): ``short`` says where the accurate
    discretisation has fewer sublayers than :func:`required_layers` asks for at a point of
    ``tube``, ``alpha``, ``m`` (a boolean array of their broadcast shape; the solvers make those
    roots INACCURATE), or is None where it has enough everywhere: concrete inputs below the cap of
    :data:`LAYER_COUNTS` (N is chosen for the worst point) or a discretisation given by
    ``n_layers`` or another ``scheme``.

    Traced (or staged) inputs take :data:`TRACED_LAYERS` whatever the point, so the comparison is
    staged with them: a few scalar operations per point. Invalid points (NaN lengths) are never
    short; the solvers give them NaN and INVALID. ``checked`` (a concrete call that checks its
    roots as it solves them): the start of :func:`auto_layer_count`'s checked discretisation."""
    if n_layers is not None or scheme not in (None, AUTO_SCHEME) or tube is None or alpha is None:
        return laminate(n_layers, scheme, tube, alpha, n_roots, m, at_rest), None
    count = _resolved_count(tube, alpha, n_roots, m, at_rest, checked)
    if count is None:  # staged: every point gets N = 16, the comparison is staged with them
        lengths = _wall_lengths_of(tube.lambda_i, tube.lambda_z, tube.eta, tube.gent, tube.material)
        return (Layers(TRACED_LAYERS, AUTO_SCHEME, True),
                required_layers(*lengths, alpha, n_roots, m, at_rest, jnp) > TRACED_LAYERS)
    layers = Layers(count, AUTO_SCHEME, True)
    if count < LAYER_COUNTS[-1]:
        return layers, None
    need = required_layers(*point_lengths(tube), np.asarray(alpha), n_roots, np.asarray(m),
                           at_rest)
    return layers, np.asarray(need > count)


def validate_scheme(scheme) -> None:
    """``scheme`` is None (the default discretisation) or one of :data:`SCHEMES`."""
    if scheme is None:
        return
    if not isinstance(scheme, str) or scheme not in SCHEMES:
        raise ValueError(f"scheme must be one of {', '.join(map(repr, SCHEMES))}, got {scheme!r}")


def split_layers(n_layers):
    """(N, scheme) of a static discretisation (an int or :class:`Layers`)."""
    if isinstance(n_layers, Layers):
        return n_layers.count, n_layers.scheme
    return int(n_layers), "midpoint"


def is_graded(n_layers) -> bool:
    """Whether a static discretisation has graded sublayers (:func:`breakpoints`)."""
    return isinstance(n_layers, Layers) and n_layers.graded


def grading_length(tube: Tube, geo=None):
    """ℓ = min(r̂_i, W_1/|dW_1/dr̂|) at the inner face: the length on which the wall's coefficients
    vary there.

    The coefficients of M hold 1/r̂ (the geometry and D̂_r ∝ 1/r̂: length r̂ from the axis) and the
    energy's W_1, W_11 (docs/theory/axisymmetric.md Eq. 33). Near Gent locking W_1 ∝ 1/(G − (I_1 − 3)) and
    G − (I_1 − 3) ≈ d_0 + c(r̂ − r̂_i) (I_1 is largest at the inner face: λ(r̂) tends monotonically to
    λ_z^{-1/2}, where I_1 is smallest), a boundary layer of thickness W_1/|W_1'| = d_0/c (1.6e-3 of
    a 0.52 wall at 99 % of locking, G = 4); far from locking it is long (≈ G) and ℓ = r̂_i."""
    geo = geometry(tube) if geo is None else geo
    w1, dw1 = jax.jvp(lambda r: w1_at(tube, r)[0], (geo.r_inner,), (jnp.ones_like(geo.r_inner),))
    slope = jnp.abs(dw1)
    safe = jnp.where(slope > 0, slope, 1.0)
    locking = jnp.where(slope > 0, jnp.abs(w1) / safe, jnp.inf)
    return jnp.minimum(geo.r_inner, locking)


GRADING_SHARE = 0.5
"""The share of the sublayers spent on the grading of :func:`breakpoints` (the rest equal)."""


def breakpoints(tube: Tube, count: int):
    """(r̂_0 … r̂_N, h_1 … h_N): the interfaces and thicknesses of graded sublayers.

    The interfaces x_k = r̂_k − r̂_i equidistribute
    S(x) = (1 − a) x/ĥ + a ln(1 + x/ℓ)/ln(1 + ĥ/ℓ) (S(x_k) = k/N, a = :data:`GRADING_SHARE`, ℓ of
    :func:`grading_length`): half of the sublayers are equal (the waves across the wall need them
    everywhere) and half grow geometrically from the inner face, where 1/r̂ and the locking factor
    1/(d_0 + c(r̂ − r̂_i)) change fastest, so the scheme's error constant stays bounded however close
    the inner face is to locking (measured in tests/test_accuracy_default.py). S is inverted by
    bisection (its iterations without derivatives) and one Newton step that carries them (the
    implicit-function derivative of x_k in every leaf)."""
    geo = geometry(tube)
    t = jnp.arange(count + 1) / count
    ratio = geo.thickness / grading_length(tube, geo)  # ĥ/ℓ ≥ ĥ/r̂_i > 0
    log_span = jnp.log1p(ratio)

    def share(u):  # S at x = u ĥ, and dS/du
        return ((1.0 - GRADING_SHARE) * u + GRADING_SHARE * jnp.log1p(u * ratio) / log_span,
                (1.0 - GRADING_SHARE) + GRADING_SHARE * ratio / ((1.0 + u * ratio) * log_span))

    def bisect(_, bounds):
        low, high = bounds
        mid = 0.5 * (low + high)
        below = share(mid)[0] < t
        return jnp.where(below, mid, low), jnp.where(below, high, mid)

    low, high = jax.lax.fori_loop(0, 60, bisect, jax.lax.stop_gradient(
        (jnp.zeros_like(t), jnp.ones_like(t))))
    u = jax.lax.stop_gradient(0.5 * (low + high))
    value, slope = share(u)
    u = jnp.clip(u - (value - t) / slope, 0.0, 1.0).at[0].set(0.0).at[-1].set(1.0)
    x = geo.thickness * u
    return geo.r_inner + x, jnp.diff(x)


class Wall(NamedTuple):
    """The discretised wall: Ω-independent data shared by every evaluation at one tube.

    Attributes:
        r_inner, r_outer: deformed radii r̂_i, r̂_o.
        radii: the radii where M is sampled: (N,) mid-radii (``"midpoint"``) or (N, q) the q
            Gauss nodes of each sublayer (the Magnus schemes; the shape selects the scheme).
        step: sublayer thickness h = ĥ/N, or (N,) the thicknesses of graded sublayers.
        coef: :class:`Coefficients` with arrays shaped like ``radii``.
        pressure_inner: P̂_i = ΔP̂ (gauge P̂_o = 0).
        damping: None (elastic) or the tuple of the wall's damping laws (:mod:`jaxdea.materials`;
            one per damped layer).
        damping_pattern: None, or per law the :class:`Coefficients` added per unit η* (the
            stretch coupling f_ij at the radii, 0 outside the law's layer; :func:`damping_pattern`).
        outer: None (vacuum outside) or the surrounding :class:`~jaxdea.params.Fluid` (its face rows,
            :func:`jaxdea.physics.dispersion.outer_conditions`).
    """

    r_inner: jax.Array
    r_outer: jax.Array
    radii: jax.Array
    step: jax.Array
    coef: Coefficients
    pressure_inner: jax.Array
    damping: object = None
    damping_pattern: Coefficients | None = None
    outer: object = None

    @property
    def thickness(self):
        """ĥ = N·(ĥ/N) (or Σ h_k), the deformed wall thickness (free of the cancellation of r̂_o − r̂_i)."""
        if jnp.ndim(self.step):
            return jnp.sum(self.step)
        return self.step * self.radii.shape[0]


def layer_coefficients(tube: Tube, r, moduli: str = "closed") -> Coefficients:
    """State-matrix coefficients at radii r̂ (docs/theory/axisymmetric.md §3).

    ``moduli="closed"`` (default) evaluates the corrected Eq. (33) forms with W_1, W_11 from the
    energy by autodiff (exact for every energy W(I_1)); ``"tensor"`` pushes forward the full
    autodiff Hessian of Ω(F, D_L) (docs/theory/axisymmetric.md §2), the general route, equal to rounding (tests)
    but far costlier to compile and to differentiate.
    """
    if tube.layers is not None:
        return layered_coefficients(tube, r)
    bs = base_state(tube, r)
    lz, gent = as_float(tube.lambda_z), as_float(tube.gent)
    if isinstance(tube.material, Material):
        one = partial(material_coefficients, tube.material, lam_z=lz)
        flat = jax.vmap(lambda lam, d, p: one(lam, D_r=d, p=p))(
            *(jnp.ravel(x) for x in (bs.stretch, bs.displacement, bs.pressure)))
        return jax.tree_util.tree_map(lambda x: jnp.reshape(x, jnp.shape(r)), flat)
    if moduli == "closed":
        return closed_form_coefficients(bs.stretch, lz, bs.displacement, bs.pressure, gent,
                                        tube.material)

    def one(lam, d, p):
        return coefficients(push_forward_moduli(1.0 / (lam * lz), lam, lz, d, gent, tube.material),
                            p)

    return jax.vmap(one)(bs.stretch, bs.displacement, bs.pressure)


def discretize(tube: Tube, n_layers) -> Wall:
    """Cut the wall into N equal sublayers (paper Eq. 42); ``n_layers`` is N (midpoint laminate) or
    a :class:`Layers` (then M is sampled at the scheme's Gauss nodes of each sublayer, equal or
    graded: :func:`breakpoints`). A layered wall: :func:`discretize_layers`."""
    if tube.layers is not None:
        return discretize_layers(tube, n_layers)
    count, scheme = split_layers(n_layers)
    geo = geometry(tube)
    nodes = jnp.asarray(SCHEMES[scheme])
    if is_graded(n_layers):
        edges, step = breakpoints(tube, count)
        radii = edges[:-1, None] + nodes * step[:, None]
    else:
        step = geo.thickness / count
        radii = geo.r_inner + (jnp.arange(count)[:, None] + nodes) * step
    if scheme == "midpoint":
        radii = radii[:, 0]
    damped = tube.damping is not None
    return Wall(
        geo.r_inner,
        geo.r_outer,
        radii,
        step,
        layer_coefficients(tube, radii),
        pressure_difference_unchecked(tube),
        (tube.damping,) if damped else None,
        (damping_pattern(tube.damping, stretch(tube, radii), as_float(tube.lambda_z)),)
        if damped else None,
        tube.outer,
    )


def layered_coefficients(tube: Tube, r, owner=None, edges=None, integrals=None) -> Coefficients:
    """The coefficients of a layered wall at radii r̂ (any shape), each in the layer ``owner`` (an
    integer array of r̂'s shape; None: the layer that holds r̂): μ_k times those of its material
    on the layered base state (docs/theory/real_tubes.md §3), its density ratio and whether it is
    active. Every layer's formulas are evaluated at r̂ clipped into it (finite everywhere) and
    the owner's are kept."""
    edges = interface_radii(tube) if edges is None else edges
    integrals = layer_integrals(tube, edges) if integrals is None else integrals
    lz = as_float(tube.lambda_z)
    if owner is None:
        owner = jnp.clip(jnp.searchsorted(edges, r, side="right") - 1, 0, len(tube.layers) - 1)
    coef = None
    for k, layer in enumerate(tube.layers):
        state = layered_base_state(tube, k, jnp.clip(r, edges[k], edges[k + 1]), edges, integrals)
        flat = jax.vmap(lambda lam, d, p, layer=layer: material_coefficients(
            layer.material, lam, lz, d, p, as_float(layer.shear_ratio)))(
            *(jnp.ravel(x) for x in (state.stretch, state.displacement, state.pressure)))
        flat = flat._replace(density=jnp.full_like(flat.a, as_float(layer.density_ratio)),
                             active=jnp.full_like(flat.a, 1.0 if layer.active else 0.0))
        flat = jax.tree_util.tree_map(lambda x: jnp.reshape(x, jnp.shape(r)), flat)
        coef = flat if coef is None else jax.tree_util.tree_map(
            lambda new, old, k=k: jnp.where(owner == k, new, old), flat, coef)
    return coef


def layer_shares(tube: Tube, edges, count: int):
    """(K + 1,) integer offsets c_0 = 0 < c_1 < … < c_K = N + K − 1 of the sublayers of a layered
    wall of K layers cut into N + K − 1 sublayers in all (static, whatever the fractions, which may
    be traced): layer k gets n_k = c_{k+1} − c_k ≥ 1 of them, one plus its share of N − 1 in
    proportion to its travel time across, deformed thickness × max(1, √(ρ_k/μ_k)) (a soft, slow
    layer holds shorter waves), so that every sublayer is about as fine as the single wall's N
    (docs/theory/real_tubes.md §3). One layer: N."""
    slowness = jnp.stack([jnp.maximum(1.0, jnp.sqrt(as_float(layer.density_ratio)
                                                    / as_float(layer.shear_ratio)))
                          for layer in tube.layers])
    weight = jnp.cumsum(jax.lax.stop_gradient(jnp.diff(edges) * slowness))
    weight = jnp.concatenate([jnp.zeros(1), weight / weight[-1]])
    offsets = jnp.round(weight * (count - 1)) + jnp.arange(len(tube.layers) + 1)
    return jnp.nan_to_num(offsets).astype(jnp.int32)  # invalid (NaN) walls: any split; f is NaN


def discretize_layers(tube: Tube, n_layers) -> Wall:
    """A layered wall (docs/theory/real_tubes.md §3): N + K − 1 equal-per-layer sublayers in all,
    shared among the K layers by :func:`layer_shares` (N of ``n_layers``; a static total whatever the
    fractions, which may be traced), so that no sublayer straddles an interface. Each node carries
    its layer's moduli (μ_k times those of its material, the field in the active layer only), its
    density ratio and whether it is active; U, V, W, T, Q, S pass the interfaces continuously, Φ and
    D are frozen in passive layers. The state ``Out A S`` machinery then applies unchanged."""
    count, scheme = split_layers(n_layers)
    nodes = jnp.asarray(SCHEMES[scheme])
    edges = interface_radii(tube)
    integrals = layer_integrals(tube, edges)  # once for the wall: ΔP̂ and every layer's τ̂_rr
    lz = as_float(tube.lambda_z)
    n_total = count + len(tube.layers) - 1
    offsets = layer_shares(tube, edges, count)
    index = jnp.arange(n_total)
    owner = jnp.sum(index[:, None] >= offsets[None, 1:-1], axis=1)  # the layer of each sublayer
    first, n_own = offsets[owner], (offsets[owner + 1] - offsets[owner]).astype(jnp.float64)
    step = (edges[owner + 1] - edges[owner]) / n_own
    r = edges[owner][:, None] + ((index - first)[:, None] + nodes) * step[:, None]
    if scheme == "midpoint":
        r = r[:, 0]
    inside = jnp.broadcast_to(owner.reshape((-1,) + (1,) * (r.ndim - 1)), r.shape)
    coef = layered_coefficients(tube, r, inside, edges, integrals)
    lam = stretch(tube, r)
    laws, patterns = [], []
    for k, layer in enumerate(tube.layers):
        if layer.damping is not None:
            laws.append(layer.damping)
            patterns.append(damping_pattern(layer.damping, lam, lz, (inside == k).astype(lam.dtype)))
    return Wall(edges[0], edges[-1], r, step, coef,
                layered_pressure_difference(tube, edges, integrals), tuple(laws) or None,
                tuple(patterns) or None, tube.outer)


discretized = jit(discretize, static_argnames=("n_layers",))
""":func:`discretize` as one compiled program (``n_layers`` by keyword), for the Python-level
searches that form a concrete wall themselves (:func:`jaxdea.wavenumbers`,
:func:`jaxdea.complex_frequencies`, the complex curves): op by op it took 0.09 s a wall (its
grading's loop), 4.1 s the first time in a process (every operation compiled alone); compiled,
0.3 s once per (wall structure, N) and 0.1 ms after (measured)."""


def general_form(coef: Coefficients) -> Coefficients:
    """The coefficients with their :class:`~jaxdea.physics.moduli.Shear` moduli: as given for a
    material object, equal to their partners (c, e, a, p, p, p) for an energy W(I_1)."""
    if coef.shear is not None:
        return coef
    return coef._replace(shear=Shear(coef.c, coef.e, coef.a, coef.p, coef.p, coef.p))


def damping_pattern(law, lam, lam_z, mask=None) -> Coefficients:
    """The coefficients that η* = 1 of the damping ``law`` adds at stretches λ (docs/theory/real_tubes.md
    §4): A_iiii += 2f_ii, A_ijij += f_ij, A_ijji += f_ij (i ≠ j) with f_ij = 1 + β'(λ_i² + λ_j² − 2)/2
    (β' the law's ``stretch_coupling``), so a, c, e, c_θ, e_z, a_θ and p_θ, p_z, p_θz gain f of
    their pair, b gains f_rr + f_zz, g 2(f_θθ − f_rr) and q 2f_rr. ``mask``: 1 on the nodes of the
    law's layer, 0 elsewhere (None: the whole wall)."""
    sq = [1.0 / (lam * lam_z) ** 2, lam * lam, lam_z * lam_z + 0.0 * lam]  # λ_r², λ², λ_z²
    coupling = as_float(law.stretch_coupling)
    weight = jnp.ones_like(lam) if mask is None else mask

    def f(i, j):
        return weight * (1.0 + 0.5 * coupling * (sq[i] + sq[j] - 2.0))

    zero = jnp.zeros_like(lam)
    return Coefficients(
        a=f(2, 0), b=f(0, 0) + f(2, 2), c=f(0, 2), d=zero, g=2.0 * (f(1, 1) - f(0, 0)),
        q=2.0 * f(0, 0), eps=zero, p=zero, e=f(1, 0),
        shear=Shear(c_t=f(0, 1), e_z=f(1, 2), a_t=f(2, 1), p_t=f(0, 1), p_z=f(0, 2), p_tz=f(1, 2)))


DAMPED_FIELDS = 10
"""The fields of :class:`Coefficients` that damping changes (a … e and the shear moduli)."""


def damped_wall(wall: Wall, omega) -> Wall:
    """The wall at the (complex) frequency Ω: its coefficients plus Σ_k η*_k(Ω) times each damping
    law's pattern (docs/theory/real_tubes.md §4); the wall itself where it has no damping."""
    if wall.damping is None:
        return wall
    base = general_form(wall.coef)
    head = tuple(base[:DAMPED_FIELDS])
    for law, pattern in zip(wall.damping, wall.damping_pattern, strict=True):
        eta = law.viscous_modulus(omega)
        head = jax.tree_util.tree_map(lambda c, f, eta=eta: c + eta * f, head,
                                      tuple(pattern[:DAMPED_FIELDS]))
    return wall._replace(coef=base._replace(**dict(zip(base._fields, head, strict=False))))


def shear_divisors(wall: Wall, omega):
    """(s_z, s_θ) = (c_z − εd², c_θ − εd²) of the wall at the (complex) Ω (:func:`damped_wall`),
    the divisors of every state matrix (docs/theory/real_tubes.md §2): where one vanishes, M has a
    pole and F = det(Out A S) an essential singularity."""
    coef = general_form(damped_wall(wall, omega).coef)
    ed2 = coef.eps * coef.d * coef.d
    return coef.c - ed2, coef.shear.c_t - ed2


@jit
def _vanishing_on_imaginary_axis(wall: Wall, heights):
    """Whether at Ω = iy, for each y of ``heights``, a divisor of :func:`shear_divisors` vanishes
    or has turned negative at some node: Re s ≤ 0 there with Im s = 0 to rounding (1e-9 of the
    node's elastic s)."""
    rest = jnp.abs(jnp.stack(shear_divisors(wall, 0.0)))

    def at(y):
        s = jnp.stack(shear_divisors(wall, 1j * y))
        return jnp.any((jnp.real(s) <= 0.0) & (jnp.abs(jnp.imag(s)) <= 1e-9 * rest))

    return jax.vmap(at)(heights)


VISCOUS_SAMPLES = 512
"""Heights of the imaginary axis at which :func:`viscous_singularity` samples the divisors."""


def viscous_singularity(wall: Wall, top: float) -> float:
    """y_s: the lowest height ≤ ``top`` of the imaginary axis where a damped wall's shear divisor
    vanishes at a node (:func:`shear_divisors` at Ω = iy_s; within top/VISCOUS_SAMPLES above it), or
    inf where none does (an elastic wall, hysteretic or fractional laws of order < 1; in a layered
    wall each layer's nodes with their own law).

    η*(Ω) has Im η* > 0 in Re Ω > 0 for every law (docs/theory/real_tubes.md §4), so s ≠ 0 there;
    on the imaginary axis η*(iy) is real for Kelvin–Voigt and Prony branches, and s(iy) =
    s(0) + η*(iy) f turns negative: for Kelvin–Voigt at y_s = s(0)/(η_v f), the point where the
    roots Ω_k of the higher modes accumulate (the unstretched tube: Ω² = Ω_e²(1 + iΩη_v), Ω → i/η_v
    as Ω_e → ∞). A contour that passes near it cannot be counted."""
    if wall.damping is None:
        return math.inf
    heights = np.linspace(0.0, float(top), VISCOUS_SAMPLES + 1)[1:]
    hit = np.flatnonzero(np.asarray(_vanishing_on_imaginary_axis(wall, jnp.asarray(heights))))
    return float(heights[hit[0]]) if hit.size else math.inf


def voltage_expansion(tube: Tube, n_layers) -> tuple[Wall, Wall, Wall]:
    """(W_0, W_1, W_2) with every leaf of :func:`discretize` at voltage V̂ equal to W_0 + V̂ W_1 + V̂² W_2.

    The wall is exactly quadratic in V̂ at fixed stretches: the geometry and λ(r̂) do not depend on
    it, D̂_r ∝ V̂ (Eq. 8), the coefficients of docs/theory/axisymmetric.md Eq. (33) hold V̂ through D̂_r and
    D̂_r² only, and ΔP̂ and p̂ through the electric integral ∝ V̂² (Eq. 1.1). The three terms are the Taylor
    coefficients at V̂ = 0 (forward mode, exact), so a search in V̂ (:func:`jaxdea.critical_voltage`)
    forms the base state once instead of at every V̂ (its first call: about 0.3 s less tracing and
    compilation, measured; the roots equal to rounding).
    ``tube.voltage`` is ignored.
    """
    def wall(v):
        return discretize(tube.replace(voltage=v), n_layers)

    zero = jnp.zeros((), jnp.float64)
    (w0, w1), (_, w2) = jax.jvp(lambda v: jax.jvp(wall, (v,), (jnp.ones_like(v),)), (zero,),
                                (jnp.ones_like(zero),))
    return w0, w1, jax.tree_util.tree_map(lambda x: 0.5 * x, w2)


def wall_at_voltage(expansion, voltage) -> Wall:
    """The wall of :func:`voltage_expansion` at V̂ = ``voltage``: W_0 + V̂ (W_1 + V̂ W_2)."""
    return jax.tree_util.tree_map(lambda a, b, c: a + voltage * (b + voltage * c), *expansion)


TAYLOR_DEGREE = 12
TAYLOR_BLOCK = 4  # Paterson–Stockmeyer: x², x³, x⁴, then 2 Horner products in x⁴ (5 products)
# θ: the largest ‖x‖∞ with θ^13/13! ≤ 2⁻⁵³, the truncation bound of the degree-12 polynomial
TAYLOR_THETA = (math.factorial(TAYLOR_DEGREE + 1) * 2.0**-53) ** (1.0 / (TAYLOR_DEGREE + 1))
MAX_SQUARINGS = 15  # NaN beyond ‖a‖∞ > θ·2¹⁵ ≈ 1.1e4
_TAYLOR_COEF = [1.0 / math.factorial(k) for k in range(TAYLOR_DEGREE + 1)]


def matmul_small(a, b):
    """a @ b for small matrices as a sum of outer products: XLA fuses it into one loop, several
    times faster on CPU than a batched dot of 6×6 matrices (benchmarks/)."""
    return sum(a[..., :, k : k + 1] * b[..., k : k + 1, :] for k in range(a.shape[-1]))


def _product(a, b):
    """a @ b kept as one materialised array (``optimization_barrier``).

    Without the barrier XLA:CPU fuses a chain of products into one loop that recomputes each
    earlier factor for every entry that reads it; the polynomial below ran 2.6× slower that way
    (README, Performance). Products of polynomials in x commute, so they are written with the
    newest factor on the left (also measured: 2× faster than on the right under XLA:CPU). The
    barrier did not keep XLA:CPU from recomputing a product's operands inside the forward-mode
    tangent of the product (:func:`_scaled_taylor` feeds them through a ``scan`` instead).
    """
    return jax.lax.optimization_barrier(matmul_small(a, b))


def _squarings(a):
    """s = ⌈log2(‖a‖_∞/θ)⌉ clipped to [0, MAX_SQUARINGS + 1]: ‖a/2^s‖_∞ ≤ θ."""
    norm = jnp.max(jnp.sum(jnp.abs(a), axis=-1))
    return jnp.clip(jnp.ceil(jnp.log2(jnp.maximum(norm, 1e-300) / TAYLOR_THETA)), 0, MAX_SQUARINGS + 1)


def _scaled_taylor(a):
    """(P(a/2^s), s): the degree-12 Taylor polynomial of exp at a/2^s, s = ⌈log2(‖a‖_∞/θ)⌉ ≥ 0,
    by Paterson–Stockmeyer: P = B_0 + x⁴(B_1 + x⁴(B_2 + c_12 x⁴)), B_j = Σ_{i<4} c_{4j+i} x^i.

    The powers come out of a ``scan`` (x, x², x³ as its outputs, x⁴ as its carry), so every later
    sum and product reads them, and their forward-mode tangents, as arrays. Written out, XLA:CPU
    fused the tangents of x² and of the sums with x and ẋ recomputed from the generator's
    coefficients for every entry that reads them (the barrier of :func:`_product` does not stop
    it): kernels of 101 and 190 operations per entry held most of the exponentials' time in the
    lanes of a dispersion curve (5 lanes × 16 sublayers, exponentials and tangents: 29 → 17.5 µs)."""
    s = _squarings(a)
    x = a * jnp.exp2(-s)
    eye = jnp.eye(a.shape[-1], dtype=a.dtype)
    top, lower = jax.lax.scan(lambda p, _: (_product(p, x), p), x, None, length=TAYLOR_BLOCK - 1)
    return _paterson_stockmeyer([eye, *lower, top]), s


def _paterson_stockmeyer(powers):
    """The degree-12 Taylor polynomial of exp at x from ``powers`` = [I, x, x², x³, x⁴]:
    B_0 + x⁴(B_1 + x⁴(B_2 + c_12 x⁴)), B_j = Σ_{i<4} c_{4j+i} x^i (2 more products)."""
    powers = list(powers)
    top = powers.pop()  # x^TAYLOR_BLOCK
    coef = _TAYLOR_COEF
    blocks = [sum(coef[j * TAYLOR_BLOCK + i] * powers[i] for i in range(TAYLOR_BLOCK))
              for j in range(TAYLOR_DEGREE // TAYLOR_BLOCK)]
    e = blocks[-1] + coef[TAYLOR_DEGREE] * top
    for j in range(len(blocks) - 2, -1, -1):
        e = jax.lax.optimization_barrier(blocks[j] + matmul_small(e, top))
    return e


def _expm_fixed(a):
    """:func:`expm_taylor` as one fixed graph: all ``MAX_SQUARINGS`` squarings applied under a mask
    (reverse-differentiable; its derivatives are those of :func:`expm_taylor`)."""
    e, s = _scaled_taylor(a)
    e = jax.lax.fori_loop(0, MAX_SQUARINGS, lambda i, e: jnp.where(i < s, _product(e, e), e), e)
    return jnp.where(s <= MAX_SQUARINGS, e, jnp.nan)


def expm_taylor_adaptive(a):
    """exp(a) as :func:`expm_taylor`, bit for bit, with only the s squarings it needs (a
    ``while_loop``; under ``vmap`` the largest s of the batch).

    Sublayers need few: over the benchmark batch (N = 30, Ω ≤ 20) ‖(ĥ/N) M‖∞ has median 0.55 and
    at most 2.2, so 39 % need none and none more than 3 (up to 7 on a coarse N = 10 laminate at
    Ω ≤ 36): a batch skips 12 (8) of the 15 squarings of the fixed graph. Forward-mode
    derivatives only (``jax.jvp`` passes a ``while_loop``, reverse mode does not): the root
    solvers' value-and-slope evaluations use it.
    """
    e, s = _scaled_taylor(a)
    e = jax.lax.while_loop(lambda c: c[0] < s, lambda c: (c[0] + 1.0, _product(c[1], c[1])),
                           (jnp.zeros_like(s), e))[1]
    return jnp.where(s <= MAX_SQUARINGS, e, jnp.nan)


@jax.custom_jvp
def expm_taylor(a):
    """exp(a) by scaling and squaring with a degree-12 Taylor polynomial.

    s = ⌈log2(‖a‖_∞/θ)⌉ with θ = 0.336, so the truncation error is ≤ θ¹³/13! = 2⁻⁵³ relative; the
    polynomial costs 5 products (Paterson–Stockmeyer, blocks of 4), then s squarings (0–3 at
    N = 30 and Ω ≤ 20, see :func:`expm_taylor_adaptive`). NaN if ‖a‖_∞ > θ·2^MAX_SQUARINGS
    (≈ 1.1e4). Matches ``jax.scipy.linalg.expm`` to rounding (tests).

    A value is computed with only the squarings it needs (:func:`expm_taylor_adaptive`); every
    derivative, forward or reverse and of any order, is that of the fixed graph with all
    ``MAX_SQUARINGS`` squarings under a mask (a custom JVP rule), bit-identical in value.
    """
    return expm_taylor_adaptive(a)


@expm_taylor.defjvp
def _expm_taylor_jvp(primals, tangents):
    return jax.jvp(_expm_fixed, primals, tangents)


EXPONENTIALS = {"taylor": expm_taylor, "adaptive": expm_taylor_adaptive,
                "at_rest": expm_taylor_adaptive, "expm": jax.scipy.linalg.expm}
"""The sublayer exponentials by ``method``; ``"at_rest"`` is ``"adaptive"`` at Ω = 0 only, with the
generators formed without their inertia terms (:func:`generator_coefficients`)."""


def _poly_product(p, q):
    """p(w) q(w) of matrix polynomials in w, stacked coefficients (lowest degree first)."""
    pq = jnp.einsum("iab,jbc->ijac", p, q)
    return jnp.stack([sum(pq[i, k - i] for i in range(p.shape[0]) if 0 <= k - i < q.shape[0])
                      for k in range(p.shape[0] + q.shape[0] - 1)])


def generator_powers(coefficients):
    """(G, G², …, G⁴) as polynomials in w (stacked coefficients, lowest degree first) for the
    generator G = Σ_j G_j w^j of :func:`generator_coefficients`: the powers of Paterson–Stockmeyer
    (:func:`expm_taylor`), formed once per (wall, α̂, m) instead of by 3 products per Ω."""
    powers = [coefficients]
    for _ in range(TAYLOR_BLOCK - 1):
        powers.append(_poly_product(coefficients, powers[-1]))
    return tuple(powers)


def _exp_of_power_polys(power_polys, omega_squared, scale, adaptive=True):
    """exp(a), a = scale ⊙ G(w), from the polynomials of :func:`generator_powers`, as
    :func:`expm_taylor` (the same s, polynomial and squarings, ``adaptive``: a ``while_loop`` over
    the s squarings, else the fixed masked graph) with its powers a^k = 2^{ks} x^k = scale ⊙ G^k(w)
    summed by Horner's rule (``scale`` a diagonal similarity d_j/d_i, which commutes with powers)."""
    raw = [scale * generator_of_w(p, omega_squared) for p in power_polys]
    s = _squarings(raw[0])
    eye = jnp.eye(raw[0].shape[-1], dtype=raw[0].dtype)
    e = _paterson_stockmeyer([eye] + [a * jnp.exp2(-k * s) for k, a in enumerate(raw, 1)])
    if adaptive:
        e = jax.lax.while_loop(lambda c: c[0] < s, lambda c: (c[0] + 1.0, _product(c[1], c[1])),
                               (jnp.zeros_like(s), e))[1]
    else:
        e = jax.lax.fori_loop(0, MAX_SQUARINGS, lambda i, e: jnp.where(i < s, _product(e, e), e), e)
    return jnp.where(s <= MAX_SQUARINGS, e, jnp.nan)


@jax.custom_jvp
def expm_of_power_polys(power_polys, omega_squared, scale):
    """exp(scale ⊙ G(w)) from (G, G², G³, G⁴) as polynomials in w (:func:`generator_powers`).

    Equal to :func:`expm_taylor` of scale ⊙ G(w) to rounding, with 2 matrix products before the
    squarings instead of 5. Values take only the squarings they need; derivatives (any mode and
    order) are those of the fixed graph, as for :func:`expm_taylor`."""
    return _exp_of_power_polys(power_polys, omega_squared, scale)


@expm_of_power_polys.defjvp
def _expm_of_power_polys_jvp(primals, tangents):
    return jax.jvp(lambda p, w, c: _exp_of_power_polys(p, w, c, adaptive=False), primals, tangents)


INERTIA = inertia_matrix(LONGITUDINAL)
"""E with M(r̂; Ω) = M(r̂; 0) − Ω² E: Ω enters the state matrix only through the inertia terms of
the traction rows (docs/theory/axisymmetric.md §3), the same at every radius."""


def _poly_add(*polys):
    """Σ of polynomials in w = Ω² given as coefficient lists (lowest degree first)."""
    out = [0.0] * max(len(p) for p in polys)
    for p in polys:
        for j, c in enumerate(p):
            out[j] = out[j] + c
    return out


def _poly_scale(factor, poly):
    return [factor * c for c in poly]


def _poly_commutator(p, q):
    """[p, q] of matrix polynomials in w: Σ_{i,j} w^{i+j} [p_i, q_j], every product p_i q_j and
    q_j p_i by one matrix product each way (the coefficient lists stacked), materialised (see
    :func:`_product`). One product of the stacks instead of one per pair: a value-and-slope of the
    magnus6 laminate N = 5 at 5 lanes 0.074 against 0.110 ms (measured)."""
    a, b = jnp.stack(p), jnp.stack(q)
    pq = jnp.einsum("iab,jbc->ijac", a, b)
    qp = jnp.einsum("jab,ibc->ijac", b, a)
    d = jax.lax.optimization_barrier(pq - qp)
    return [sum(d[i, k - i] for i in range(len(p)) if 0 <= k - i < len(q))
            for k in range(len(p) + len(q) - 1)]


def generator_coefficients(step, coef: Coefficients, radius, alpha, m=0, family=LONGITUDINAL,
                           at_rest: bool = False, block=None):
    """G_j (shape (P, n, n)) with G(Ω) = Σ_j G_j Ω^{2j} the sublayer's generator (:func:`layer_generator`).

    Every node has M = M_0 − Ω² E (:data:`INERTIA`), so G is a polynomial in w = Ω²: of degree 1
    for the midpoint and fourth-order schemes (h M, and h(M_1 + M_2)/2 + (√3/12) h² [M_2, M_1]
    with [M_2, M_1] = [M_2⁰, M_1⁰] − w([M_2⁰, E] + [E, M_1⁰])), and 3 for the sixth-order one
    (B_2, B_3 do not depend on w: the E terms cancel in the node differences). The coefficients
    depend on the wall and α̂ only, so a batch of Ω at one α̂ (a scan chunk, the lanes of a
    solver) forms them once, with no Ω-tangent; each Ω then costs a Horner sum.

    ``family`` (static) and ``m`` (traced, ``"order_m"`` only) select the state matrix and its E
    (:func:`jaxdea.physics.state_matrix.family_matrix`, ``family_inertia``); n = 6, 8 or 2.

    ``at_rest`` (static): G at w = 0 only (P = 1), the inertia left out: a search in V̂ at Ω = 0
    (:func:`jaxdea.critical_voltage`) forms the sixth-order generator with 6 matrix products per
    sublayer instead of 24 (its wall changes with every V̂); the same G_0, to rounding.

    ``block`` (static, a tuple of state indices): the generator of that block of the state alone,
    from the same block of every M and E; where the block decouples from the rest (the electric
    block at V̂ = 0, :func:`jaxdea.physics.dispersion.value_and_slope_on_wall`) that is the block of G.
    """
    matrix, inertia = _matrix_of_alpha(family, m, block)
    if coef.density is not None:  # a layer's ρ_k, constant across its sublayers
        inertia = (coef.density if jnp.ndim(radius) == 0 else coef.density[0]) * inertia
    minus_e = [] if at_rest else [-inertia]
    if jnp.ndim(radius) == 0:
        node = [matrix(coef, radius, alpha)]
    else:
        node = list(jax.vmap(lambda c, r: matrix(c, r, alpha))(coef, radius))
    return jnp.stack(_scheme_generator(node, step, minus_e, _poly_add, _poly_scale,
                                       _poly_commutator))


def _matrix_of_alpha(family, m=0, block=None):
    """((coef, r̂, α̂) ↦ M(r̂; Ω = 0), E) of the family (``block``: of that block of the state)."""
    if family == LONGITUDINAL:
        matrix, inertia = (lambda c, r, a: state_matrix(c, r, 0.0, a)), INERTIA
    else:
        matrix = lambda c, r, a: family_matrix(family, c, r, 0.0, a, m)  # noqa: E731
        inertia = family_inertia(family, m)
    if block is not None:
        index, full = np.asarray(block), matrix
        matrix = lambda c, r, a: full(c, r, a)[index][:, index]  # noqa: E731
        inertia = inertia[index][:, index]
    return matrix, inertia


def _scheme_generator(node, h, minus_e, add, scale, commutator):
    """The generator of a sublayer (or of all at once) as a polynomial in w = Ω² (a list, lowest
    degree first) from the state matrices at its 1, 2 or 3 Gauss nodes (midpoint, ``"magnus4"``,
    ``"magnus6"``), with M = M⁰ − wE and ``minus_e`` = [−E] ([] at rest); in the representation of
    matrix polynomials given by ``add``, ``scale`` and ``commutator`` (:func:`_magnus6_generator`)."""
    e = [h * x for x in minus_e]
    if len(node) == 1:
        return [h * node[0], *e]
    if len(node) == 2:
        # [M_2, M_1] with M_j = M_j⁰ − wE; its w² coefficient [E, E] is exactly zero
        inner = commutator([node[1], *minus_e], [node[0], *minus_e])[:2]
        return add([0.5 * h * (node[0] + node[1]), *e], scale((math.sqrt(3.0) / 12.0) * h**2, inner))
    b1 = [h * node[1], *e]
    b2 = [(math.sqrt(15.0) / 3.0) * h * (node[2] - node[0])]
    b3 = [(10.0 / 3.0) * h * (node[2] - 2.0 * node[1] + node[0])]
    return _magnus6_generator(b1, b2, b3, add, scale, commutator)


def _magnus6_generator(b1, b2, b3, add, scale, commutator):
    """The sixth-order Magnus generator from B_1 = h M_2, B_2 = (√15/3) h (M_3 − M_1),
    B_3 = (10/3) h (M_3 − 2M_2 + M_1) (node matrices M_k): B_1 + B_3/12 + [−20B_1 − B_3 + C_1,
    B_2 + C_2]/240, C_1 = [B_1, B_2], C_2 = −[B_1, 2B_3 + C_1]/60; in any representation of matrix
    polynomials given by its ``add``, ``scale`` and ``commutator`` (coefficient lists in w = Ω²,
    :func:`generator_coefficients`; stacked arrays in V̂, :func:`voltage_generators`)."""
    c1 = commutator(b1, b2)
    c2 = scale(-1.0 / 60.0, commutator(b1, add(scale(2.0, b3), c1)))
    outer = commutator(add(scale(-20.0, b1), scale(-1.0, b3), c1), add(b2, c2))
    return add(b1, scale(1.0 / 12.0, b3), scale(1.0 / 240.0, outer))


VOLTAGE_DEGREE = 4
"""Degree in V̂ of the state matrix at fixed stretches: the wall is quadratic in V̂
(:func:`voltage_expansion`) and its only divisor, the shear modulus c − εd² = 2W_1λ_r², does not
depend on V̂, so the entries hold at most (p − εd²)² (docs/theory/axisymmetric.md §3)."""


def _stacked_add(*polys):
    """Σ of matrix polynomials stacked along axis 0 (lowest degree first), of any lengths."""
    size = max(p.shape[0] for p in polys)
    return sum(jnp.pad(p, [(0, size - p.shape[0])] + [(0, 0)] * (p.ndim - 1)) for p in polys)


def _stacked_commutator(p, q):
    """[p, q] of matrix polynomials stacked along axis 0, (I, …, n, n) and (J, …, n, n): every
    product p_i q_j and q_j p_i at once (two ``einsum``), summed by degree i + j as I shifted
    rows (2.6× faster than contracting with a 0/1 tensor of the degrees, measured)."""
    pq = jnp.einsum("i...ab,j...bc->ij...ac", p, q)
    qp = jnp.einsum("j...ab,i...bc->ij...ac", q, p)
    d, size = pq - qp, p.shape[0]
    rest = [(0, 0)] * (d.ndim - 2)
    return sum(jnp.pad(d[i], [(i, size - 1 - i)] + rest) for i in range(size))


def voltage_generators(expansion, alpha, m=0, family=LONGITUDINAL, radius=1.0):
    """The at-rest generators G_k (Ω = 0) of a Magnus wall as polynomials in V̂: P of shape
    (J, N, n, n) with G_k(V̂) = Σ_j P[j, k] V̂^j, from the wall's :func:`voltage_expansion`.

    The state matrix at every node is a polynomial of degree :data:`VOLTAGE_DEGREE` in V̂; its
    coefficients come from its values at the 5 points V̂ = ρ e^{2πil/5} of the circle of radius
    ρ = ``radius`` (a discrete Fourier transform, unitary: errors of rounding relative to M on that
    circle; take ρ about the largest V̂ searched), and the scheme's commutators are taken of the
    polynomials (:func:`_stacked_commutator`), once per (tube, α̂, m): degree 8 for ``"magnus4"``,
    20 for ``"magnus6"`` (0.4 ms for the paper's tube, N = 16). A search in V̂ at Ω = 0
    (:func:`jaxdea.critical_voltage`) then forms each G_k(V̂) as a sum over the powers of V̂
    (:func:`generators_at_voltage`) instead of by 2 (6) matrix products per sublayer and V̂, each
    of them three under the forward-mode slope: a chunk of 32 values and slopes on the magnus6
    wall N = 16 costs 0.9 ms instead of 3.1 (measured); the same G_k to rounding
    (tests/test_core.py). Taylor mode (``jax.experimental.jet``) gives the same coefficients but
    its programs took 2–5 s longer to compile."""
    if family == LONGITUDINAL:
        matrix = lambda c, r: state_matrix(c, r, 0.0, alpha)  # noqa: E731
    else:
        matrix = lambda c, r: family_matrix(family, c, r, 0.0, alpha, m)  # noqa: E731

    def node_matrices(v):  # (N, q, n, n) at V̂ = v
        wall = wall_at_voltage(expansion, v)
        return jax.vmap(jax.vmap(matrix))(wall.coef, wall.radii)

    count = VOLTAGE_DEGREE + 1
    turns = np.exp(2j * np.pi * np.arange(count) / count)
    values = jax.vmap(node_matrices)(radius * jnp.asarray(turns))  # (J, N, q, n, n), complex
    power = np.arange(count)
    fourier = np.exp(-2j * np.pi * np.outer(power, power) / count) / count
    nodes = jnp.real(jnp.tensordot(jnp.asarray(fourier), values, axes=1))
    nodes = nodes / (radius ** power.astype(np.float64))[:, None, None, None, None]
    h = expansion[0].step
    h = (h if jnp.ndim(h) else jnp.full(nodes.shape[1], h))[:, None, None]
    node = [nodes[:, :, k] for k in range(nodes.shape[2])]  # (J, N, n, n) at each Gauss node
    if len(node) == 2:
        return _stacked_add(0.5 * h * (node[0] + node[1]),
                            (math.sqrt(3.0) / 12.0) * h**2 * _stacked_commutator(node[1], node[0]))
    b1 = h * node[1]
    b2 = (math.sqrt(15.0) / 3.0) * h * (node[2] - node[0])
    b3 = (10.0 / 3.0) * h * (node[2] - 2.0 * node[1] + node[0])
    return _magnus6_generator(b1, b2, b3, _stacked_add, lambda factor, p: factor * p,
                              _stacked_commutator)


def generators_at_voltage(polys, voltage):
    """G_k(V̂) of every sublayer, (N, n, n), from :func:`voltage_generators`: one contraction with
    the powers 1, V̂, …, V̂^J (a dot product; Horner's rule, elementwise, was fused by XLA:CPU into
    the exponentials' products and recomputed there: a chunk of value and slope took 1.2–1.9 ms
    instead of 0.7 for its 16 exponentials, measured)."""
    powers = [jnp.ones_like(voltage)]
    for _ in range(polys.shape[0] - 1):
        powers.append(powers[-1] * voltage)
    return jnp.tensordot(jnp.stack(powers), polys, axes=1)


def voltage_exponentials(polys, voltage):
    """T_k = exp(G_k(V̂)) at Ω = 0 (:func:`voltage_generators`), as the ``"at_rest"`` exponentials
    of :func:`layer_exponentials_of_w` (:func:`expm_taylor_adaptive`)."""
    return jax.vmap(EXPONENTIALS["at_rest"])(generators_at_voltage(polys, voltage))


def evaluate_generator(coefficients, omega):
    """G(Ω) = Σ_j G_j Ω^{2j} by Horner's rule in w = Ω² (:func:`generator_of_w`)."""
    return generator_of_w(coefficients, omega * omega)


def generator_of_w(coefficients, omega_squared):
    """G = Σ_j G_j w^j by Horner's rule, w = Ω² of either sign (real for real w)."""
    g = coefficients[-1]
    for c in coefficients[-2::-1]:
        g = c + omega_squared * g
    return jax.lax.optimization_barrier(g)


def layer_generator(step, coef: Coefficients, radius, omega, alpha, m=0, family=LONGITUDINAL):
    """G with T = exp(G) for one sublayer of thickness h = ``step`` (module docstring).

    ``radius`` (and ``coef``) hold the sublayer's nodes: a scalar, the mid-radius (G = h M, paper
    Eq. 43); 2 Gauss nodes, fourth-order Magnus G = h(M_1 + M_2)/2 + (√3/12) h² [M_2, M_1]; 3 Gauss
    nodes, the sixth-order Magnus of Blanes, Casas & Ros (2000): with B_1 = h M_2,
    B_2 = (√15/3) h (M_3 − M_1), B_3 = (10/3) h (M_3 − 2M_2 + M_1),
    G = B_1 + B_3/12 + [−20B_1 − B_3 + [B_1, B_2], B_2 − [B_1, 2B_3 + [B_1, B_2]]/60]/240.
    Formed as the polynomial in Ω² of :func:`generator_coefficients`.
    """
    return evaluate_generator(generator_coefficients(step, coef, radius, alpha, m, family), omega)


def wall_generators(wall: Wall, alpha, m=0, family=LONGITUDINAL, at_rest: bool = False,
                    block=None):
    """The coefficients of every sublayer's generator, shape (N, P, n, n)
    (:func:`generator_coefficients`; ``block``: of that block of the state): formed once per
    (wall, α̂, m), shared by every Ω."""
    return jax.vmap(partial(generator_coefficients, family=family, at_rest=at_rest, block=block),
                    (0 if jnp.ndim(wall.step) else None, 0, 0, None, None))(
        wall.step, wall.coef, wall.radii, alpha, m)


def alpha_generators(wall: Wall, m=0, family=LONGITUDINAL, at_rest: bool = False, block=None):
    """The coefficients of :func:`wall_generators` at a fixed wall as polynomials in α̂: P of shape
    (J, N, P_w, n, n) with ``wall_generators(wall, α̂, m, family, at_rest, block)`` equal to
    Σ_j α̂^j P[j] to rounding (:func:`generators_at_alpha`).

    Every family's state matrix is of degree 2 in α̂ at a fixed wall (its α̂ and α̂² = k² − m²/r̂²
    terms), M = A_0 + α̂ A_1 + α̂² A_2,
    with A_0 = M(0), A_1 = (M(1) − M(−1))/2, A_2 = (M(1) + M(−1))/2 − M(0) (one batch of three
    state matrices per node), and the scheme's commutators are taken of the polynomials in (α̂, w):
    degree 2 in α̂ for the midpoint laminate, 4 for ``"magnus4"`` and 10 for ``"magnus6"``. Along a
    dispersion curve of one tube (:func:`jaxdea.solve.curves.dispersion_curve`) the generators of every α̂
    then cost one contraction with the powers of α̂ instead of the state matrices and 24 matrix
    products per sublayer (magnus6). Measured against the generators formed at α̂ (α̂ ≤ 30 on walls
    of η = 0.3 … 0.85): G(Ω²) equal to 7e-16 to 1.1e-15 of each sublayer's largest entry."""
    matrix, inertia = _matrix_of_alpha(family, m, block)
    coef, radii = jax.tree_util.tree_map(lambda x: jnp.reshape(x, (x.shape[0], -1)),
                                         (wall.coef, wall.radii))
    at = jax.vmap(lambda a: jax.vmap(jax.vmap(lambda c, r: matrix(c, r, a)))(coef, radii))(
        jnp.array([0.0, 1.0, -1.0]))  # (3, N, q, n, n): M at α̂ = 0, ±1 at every node
    taylor = jnp.stack([at[0], 0.5 * (at[1] - at[2]), 0.5 * (at[1] + at[2]) - at[0]])
    count = taylor.shape[1]
    h = wall.step if jnp.ndim(wall.step) else jnp.full(count, wall.step)
    h = h[:, None, None]
    node = [taylor[:, :, k] for k in range(taylor.shape[2])]  # (3, N, n, n) at each node
    minus_e = [] if at_rest else [  # −E: degree 0 in α̂
        jnp.broadcast_to(-jnp.asarray(inertia), (1, count) + node[0].shape[-2:])]
    if coef.density is not None and not at_rest:  # a layer's ρ_k, constant in each sublayer
        minus_e = [minus_e[0] * coef.density[None, :, 0, None, None]]
    gen = _scheme_generator(node, h, minus_e, _bivariate_add, _bivariate_scale,
                            _bivariate_commutator)
    size = max(c.shape[0] for c in gen)
    return jnp.stack([jnp.pad(c, [(0, size - c.shape[0])] + [(0, 0)] * 3) for c in gen], axis=2)


def _bivariate_add(*polys):
    """Σ of matrix polynomials in (α̂, w): lists over the degree in w of arrays stacked over the
    degree in α̂ (:func:`alpha_generators`)."""
    out = [[] for _ in range(max(len(p) for p in polys))]
    for p in polys:
        for j, c in enumerate(p):
            out[j].append(c)
    return [_stacked_add(*c) for c in out]


def _bivariate_scale(factor, poly):
    return [factor * c for c in poly]


def _bivariate_commutator(p, q):
    """[p, q] of matrix polynomials in (α̂, w) (:func:`_bivariate_add`)."""
    out = [[] for _ in range(len(p) + len(q) - 1)]
    for i, a in enumerate(p):
        for j, b in enumerate(q):
            out[i + j].append(_stacked_commutator(a, b))
    return [_stacked_add(*c) for c in out]


def generators_at_alpha(polys, alpha):
    """The generator coefficients of every sublayer at α̂, (N, P_w, n, n), from
    :func:`alpha_generators`: one contraction with the powers 1, α̂, …, α̂^J."""
    return generators_at_voltage(polys, alpha)


def generators_at(wall: Wall, omega_squared, alpha, m=0, family=LONGITUDINAL):
    """The generators G_k of every sublayer at one point (w, α̂), (N, n, n), either of them
    complex: the scheme's formula (:func:`layer_generator`) applied to the node matrices
    M(r̂; w, α̂) themselves, for a wall whose coefficients change from point to point (a damped
    wall, η*(Ω), :func:`damped_wall`) or a point met once (a complex search).

    Equal to :func:`wall_generators` evaluated at w (and :func:`alpha_generators` at α̂) to
    rounding, for fewer products: the sixth-order scheme takes 6 matrix products per sublayer at
    the point, against 24 for its coefficients in w, which a damped wall would form again at every
    Ω. The products are batched ``einsum``s: on complex 6×6 matrices XLA:CPU ran them faster than
    :func:`matmul_small` (a value and log-slope at N = 16, 230 against 620 µs, measured); the 4×4
    and 2×2 blocks of a decoupled wall as one real product of their stacked parts
    (:func:`complex_product`)."""
    return scheme_generators(wall, node_matrices_at(wall, omega_squared, alpha, m, family))


def node_matrices_at(wall: Wall, omega_squared, alpha, m=0, family=LONGITUDINAL):
    """The state matrices M(r̂; w, α̂) at every node of the wall, shape radii.shape + (n, n)."""
    flat = jax.tree_util.tree_map(jnp.ravel, (wall.coef, wall.radii))
    matrices = jax.vmap(lambda c, r: family_matrix(family, c, r, omega_squared, alpha, m))(*flat)
    return matrices.reshape(wall.radii.shape + matrices.shape[-2:])


def scheme_generators(wall: Wall, matrices):
    """The generators of every sublayer from the node matrices (:func:`node_matrices_at`, or a
    block of them: exact where M is block-diagonal) by the wall's scheme (:func:`generators_at`)."""
    count = wall.radii.shape[0]
    h = (wall.step if jnp.ndim(wall.step) else jnp.full(count, wall.step))[:, None, None]
    if wall.radii.ndim == 1:  # the midpoint laminate: G = h M
        return h * matrices
    node = [matrices[:, k] for k in range(wall.radii.shape[1])]
    return _scheme_generator(node, h, [], _poly_add, _poly_scale, _batched_commutator)[0]


STACKED_MAX = 4
"""The largest complex matrices whose products :func:`_batched_commutator` takes stacked
(:func:`complex_product`): the 4×4 and 2×2 blocks of a decoupled wall. The 6×6 and 8×8 ones stay
complex ``einsum``s, which ran faster in the solvers (docs/performance.md)."""


def complex_product(a, b):
    """a @ b for small complex matrices as one real batched product of their stacked parts,
    [Re a; Im a] @ [Re b, Im b], recombined: on 4×4 matrices XLA:CPU runs it about twice as fast
    as a complex ``einsum`` (docs/performance.md)."""
    n = a.shape[-1]
    parts = jnp.einsum("...ab,...bc->...ac", jnp.concatenate([jnp.real(a), jnp.imag(a)], axis=-2),
                       jnp.concatenate([jnp.real(b), jnp.imag(b)], axis=-1))
    return jax.lax.complex(parts[..., :n, :n] - parts[..., n:, n:],
                           parts[..., :n, n:] + parts[..., n:, :n])


def _batched_commutator(p, q):
    """[p, q] of constant matrix polynomials (one coefficient each), batched over sublayers:
    complex matrices by :func:`complex_product`, real ones by a batched ``einsum``."""
    def product(a, b):
        if (jnp.iscomplexobj(a) or jnp.iscomplexobj(b)) and a.shape[-1] <= STACKED_MAX:
            return complex_product(jnp.asarray(a, complex), jnp.asarray(b, complex))
        return jnp.einsum("...ab,...bc->...ac", a, b)

    return [product(p[0], q[0]) - product(q[0], p[0])]


def node_matrices(wall: Wall, alpha, m=0, family=LONGITUDINAL):
    """The state matrices M(r̂; Ω = 0) at every node of the wall (its ``radii``), shape (..., n, n)."""
    if family == LONGITUDINAL:
        matrix = lambda c, r: state_matrix(c, r, 0.0, alpha)  # noqa: E731
    else:
        matrix = lambda c, r: family_matrix(family, c, r, 0.0, alpha, m)  # noqa: E731
    matrices = jax.vmap(matrix)(*jax.tree_util.tree_map(jnp.ravel, (wall.coef, wall.radii)))
    return matrices.reshape(wall.radii.shape + matrices.shape[-2:])


def layer_exponentials(wall: Wall, omega, alpha, method: str = "taylor", m=0,
                       family=LONGITUDINAL):
    """T_k = exp(G_k), shape (N, n, n) (paper Eq. 43; G_k of :func:`layer_generator`).

    ``method="expm"`` uses ``jax.scipy.linalg.expm`` (the reference); ``"taylor"`` (default)
    :func:`expm_taylor`, equal to rounding and far cheaper to compile and batch;
    ``"adaptive"`` :func:`expm_taylor_adaptive` (bit-identical to ``"taylor"``, forward mode only).
    """
    return layer_exponentials_of_w(wall, omega * omega, alpha, method, m, family)


def layer_exponentials_of_w(wall: Wall, omega_squared, alpha, method: str = "taylor", m=0,
                            family=LONGITUDINAL):
    """:func:`layer_exponentials` at w = Ω² (either sign; w = 0 for ``method="at_rest"``)."""
    if method == "at_rest":  # G at w = 0 only, formed without the inertia terms
        return jax.vmap(EXPONENTIALS[method])(wall_generators(wall, alpha, m, family, True)[:, 0])
    gens = jax.vmap(generator_of_w, (0, None))(wall_generators(wall, alpha, m, family),
                                               omega_squared)
    return jax.vmap(EXPONENTIALS[method])(gens)


def transfer_matrix(wall: Wall, omega, alpha, method: str = "expm", m=0, family=LONGITUDINAL):
    """A = T_N ⋯ T_2 T_1 with Y(r̂_o) = A Y(r̂_i) (paper Eq. 44), ordered product by ``lax.scan``.

    The reference path: ``jax.scipy.linalg.expm`` per sublayer by default.
    """
    return transfer_matrix_of_w(wall, omega * omega, alpha, method, m, family)


def transfer_matrix_of_w(wall: Wall, omega_squared, alpha, method: str = "expm", m=0,
                         family=LONGITUDINAL):
    """:func:`transfer_matrix` at w = Ω² (either sign)."""
    def multiply(acc, t):
        return t @ acc, None

    exps = layer_exponentials_of_w(wall, omega_squared, alpha, method, m, family)
    size = exps.shape[-1]
    acc, _ = jax.lax.scan(multiply, jnp.eye(size, dtype=exps.dtype), exps)  # complex for complex Ω
    return acc


def orthonormalize(y):
    """Y = Q R for an n×k Y (6×3, 8×4, 2×1): Q with orthonormal columns, R upper triangular with R_jj > 0.

    Classical Gram–Schmidt applied twice ("CGS2", stable to rounding). Returns (Q, log det R).
    A complex Y (complex Ω, :mod:`jaxdea.solve.counting`) uses the Hermitian projection u (u^H v), so
    Q^H Q = I and R_jj = ‖v_j‖ is still real and positive: det R > 0 leaves arg det unchanged.
    """
    q, _, norms = _gram_schmidt(y)
    return q, _log_det(norms)


def _log_det(norms):
    """log det R = Σ log R_jj from the norms of :func:`_gram_schmidt`."""
    logdet = 0.0
    for norm in norms:
        logdet = logdet + jnp.log(norm)
    return logdet


def _gram_schmidt(y):
    """(Q, the projection coefficients, R_jj) of :func:`orthonormalize`: column j of Y is
    Σ_{i<j} R_ij q_i + R_jj q_j with R_ij the sum of the coefficients of both passes."""
    conj = jnp.conj if jnp.iscomplexobj(y) else (lambda u: u)  # real Y: the real path

    def inner(u, v):  # u^H v as one reduction: the explicit sum of n products (slices, squeezes,
        # products, additions) held half of the operations of a value-and-slope and compiled
        # 20 % longer, for code that ran 0-15 % slower (first m = 2 frequencies 5.9 -> 4.6 s)
        return jnp.sum(conj(u) * v, axis=0)

    cols, coefficients, norms = [], [], []
    for j in range(y.shape[-1]):
        v = y[:, j]
        r = [0.0] * j
        for _ in range(2):
            for i, u in enumerate(cols):
                c = inner(u, v)
                r[i] = r[i] + c
                v = v - c * u
        norm = jnp.sqrt(jnp.real(inner(v, v)))
        cols.append(v / norm)
        coefficients.append(r)
        norms.append(norm)
    return jnp.stack(cols, axis=-1), coefficients, norms


def _right_divide(w, coefficients, norms):
    """W R⁻¹ for the R of :func:`_gram_schmidt` (its column operations applied to W)."""
    cols = []
    for r, norm in zip(coefficients, norms, strict=True):
        v = w[:, len(cols)]
        for i, c in enumerate(r):
            v = v - c * cols[i]
        cols.append(v / norm)
    return jnp.stack(cols, axis=-1)


def propagate_basis(wall: Wall, omega, alpha, basis, method: str = "taylor", m=0,
                    family=LONGITUDINAL):
    """Carry the n×k ``basis`` Y(r̂_i) (6×3; 8×4 or 2×1 for the other families) across the wall
    with re-orthonormalisation.

    A complex ``omega`` (complex T_k) promotes the basis to complex; log_scale stays real.

    Returns:
        (Q, log_scale): Q spans A·basis, and A·basis = Q·R with log det R = log_scale (R's product is
        kept only as its log-determinant, the scale factor of the characteristic function).
    """
    return propagate_basis_of_w(wall, omega * omega, alpha, basis, method, m, family)


def _advance(carry, t):
    """One sublayer of :func:`propagate_basis_of_w`: (Q, log_scale) → (Q', log_scale + log det R)
    with T Q = Q' R."""
    q, log_scale = carry
    q_new, log_r = orthonormalize(matmul_small(t, q))
    return (q_new, log_scale + log_r), None


def carry_basis(basis, exponentials):
    """(Q, log_scale) of :func:`propagate_basis_of_w` with the sublayer exponentials T_k given
    (shape (N, n, n)): ``basis`` carried across them with re-orthonormalisation."""
    (q, log_scale), _ = jax.lax.scan(_advance, orthonormalize(basis), exponentials)
    return q, log_scale


TANGENT_UNROLL = 1
"""Sublayers per iteration of :func:`carry_basis_tangent`'s scan. 2 saved 4–6 % of the benchmark
curve (section k), but once the scan's slope was carried too (:func:`jaxdea.solve.roots.scanned_function`)
it cost 0.3–0.6 s of compilation per copy of f and f' (a first ``frequencies`` at m = 2: 1.8 s),
for no measurable change of its warm time; 4 saved no more and compiled 1 s longer (measured)."""


def _flag_reduced(q, z):
    """Z − Q·triu(QᵀZ, 1): Z without its components q_i along the columns j > i (Ẏ → Ẏ − Y N with N
    strictly upper triangular, which leaves the span of every leading set of columns, det(B Y)
    and its derivative unchanged, and tr(QᵀZ) too). Where the columns of Y grow at very different
    rates (a thick wall, α̂ĥ ≫ 1) those components grow like the ratios R_ii/R_jj from sublayer to
    sublayer, and f' = D det(BQ)[BZ] − f tr(QᵀZ) became the difference of huge terms (measured at
    α̂ĥ = 150: f' wrong in every digit, the scan's roots SUSPECT); what remains,
    Q̇ + Q (diag + strictly lower part of QᵀZ, transposed), is bounded by |Q̇| and |ℓ'|."""
    a = jnp.einsum("ni,nj->ij", jnp.conj(q) if jnp.iscomplexobj(q) else q, z)  # QᵀZ (QᴴZ if complex)
    upper = jnp.triu(a, 1)
    return z - sum(q[:, i : i + 1] * upper[i][None, :] for i in range(q.shape[-1] - 1))


def carry_basis_tangent(basis, basis_dot, exponentials, exponentials_dot, with_scale=False):
    """(Q, Z) with Q of :func:`carry_basis` and Z = Ẏ R⁻¹, Ẏ the tangent of the unnormalised
    Y = T_N ⋯ T_1 · basis = Q R (real arrays; tangents of the basis and of every T_k given), up to
    columns of Q added to later columns of Z (:func:`_flag_reduced`, which changes neither
    det(B Y)' nor tr(QᵀZ)).

    Z carries the tangent in the frame of Q, Z_k = (Ṫ_k Q_{k−1} + T_k Z_{k−1}) R_k⁻¹ with the R_k of
    each re-orthonormalisation, so Gram–Schmidt is never differentiated (its forward-mode tangent
    was about 40 % of a value-and-slope of 5 lanes; :func:`jaxdea.physics.dispersion.value_and_slope_on_wall`
    turns Z into f'). Q is the same array as :func:`carry_basis` computes. ``with_scale`` (static):
    (Q, Z, log_scale) with the log_scale of :func:`carry_basis` (its slope is tr(QᵀZ))."""
    def log_det(norms):
        return _log_det(norms) if with_scale else 0.0

    def advance(carry, t):
        q, z, log_scale = carry
        t, t_dot = t
        q_new, coefficients, norms = _gram_schmidt(matmul_small(t, q))
        w = matmul_small(t_dot, q) + matmul_small(t, z)
        return (q_new, _flag_reduced(q_new, _right_divide(w, coefficients, norms)),
                log_scale + log_det(norms)), None

    q, coefficients, norms = _gram_schmidt(basis)
    start = (q, _flag_reduced(q, _right_divide(basis_dot, coefficients, norms)), log_det(norms))
    (q, z, log_scale), _ = jax.lax.scan(advance, start, (exponentials, exponentials_dot),
                                        unroll=TANGENT_UNROLL)
    return (q, z, log_scale) if with_scale else (q, z)


def propagate_basis_of_w(wall: Wall, omega_squared, alpha, basis, method: str = "taylor", m=0,
                         family=LONGITUDINAL):
    """:func:`propagate_basis` at w = Ω² (either sign; real arithmetic for real w).

    ``"order_m"`` values (``method`` ``"taylor"`` or ``"expm"``) propagate the balanced state D⁻¹Y
    (:func:`propagate_balanced_of_w`). The solvers' ``"adaptive"`` value-and-slope evaluations keep
    the plain propagation: balanced, the programs of :func:`jaxdea.first_instability` took 36 s
    instead of 23–30 s to compile (measured), for nothing at its Ω = 0."""
    w = omega_squared
    if jnp.iscomplexobj(w) and not jnp.iscomplexobj(basis):
        basis = basis.astype(jnp.result_type(basis.dtype, w))
    if family == ORDER_M and method not in ("adaptive", "at_rest"):
        return propagate_balanced_of_w(wall, w, alpha, basis, method, m, family)
    if method in ("adaptive", "at_rest"):
        # the solvers' value-and-slope evaluations (small batches: lanes, 32-point grid chunks): all
        # N exponentials at once, then the scan (fewer sequential steps; 1.2–1.5× faster there)
        return carry_basis(basis, layer_exponentials_of_w(wall, w, alpha, method, m, family))
    q0, log0 = orthonormalize(basis)
    exponential = EXPONENTIALS[method]

    def step(carry, coefficients):
        return _advance(carry, exponential(generator_of_w(coefficients, w)))

    # values: T_k formed inside the scan, so that a batch of one sublayer at a time stays in cache
    # (1.2–1.5× faster at batch 4096 than all N exponentials first; the same T_k, fused differently
    # by XLA: f equal to rounding, ≤ 4 ulp of 1, tested)
    (q, log_scale), _ = jax.lax.scan(step, (q0, log0), wall_generators(wall, alpha, m, family))
    return q, log_scale


BALANCE_LIMIT = 60
"""Largest |log2 c| of the balancing factor c (:func:`balance_diagonal`)."""


def balance_diagonal(coefficients, omega_squared):
    """d = [1, …, 1, c, …, c] (n,): the diagonal D = diag(I, cI) that balances the generators.

    The state is [displacements | tractions] (U, V, W, Φ | T, Q, S, D for order m): the inertia
    −wE lies in the lower-left block of G and grows like |w|, the compliances (δ3, 1/ε) of the
    upper-right block do not. D⁻¹GD multiplies the lower-left block by 1/c and the upper-right one
    by c; c = 2^round(log2 √(‖G_LL‖/‖G_UR‖)) (∞-norms, largest over the sublayers, bounded by
    Σ_j |w|^j ‖G_j‖ from the coefficients of :func:`wall_generators`) makes both bounds
    ≈ √(‖G_LL‖‖G_UR‖), within √2 and never above the larger one. A power of 2, so D⁻¹GD is exact;
    independent of the inputs' tangents (``stop_gradient``: the propagated subspace does not depend
    on c).
    """
    coefficients, omega_squared = jax.lax.stop_gradient((coefficients, omega_squared))
    half = coefficients.shape[-1] // 2

    def block_norm(block):  # (P,): per power of w, the largest ∞-norm over the sublayers
        return jnp.max(jnp.sum(jnp.abs(block), axis=-1), axis=(0, 2))

    powers = jnp.abs(omega_squared) ** jnp.arange(coefficients.shape[1])
    lower = jnp.sum(powers * block_norm(coefficients[:, :, half:, :half]))
    upper = jnp.sum(powers * block_norm(coefficients[:, :, :half, half:]))
    exponent = jnp.round(0.5 * jnp.log2(lower / upper))
    exponent = jnp.clip(jnp.where(jnp.isnan(exponent), 0.0, exponent), -BALANCE_LIMIT,
                        BALANCE_LIMIT)
    c = jnp.ldexp(1.0, exponent.astype(jnp.int32))  # exactly 2^exponent (exp2 is not, under XLA)
    return jnp.concatenate([jnp.ones(half), jnp.full(half, c)])


def propagate_balanced_of_w(wall: Wall, omega_squared, alpha, basis, method: str = "taylor", m=0,
                            family=ORDER_M):
    """:func:`propagate_basis_of_w` through the balanced generators D⁻¹G_kD (:func:`balance_diagonal`).

    exp(D⁻¹GD) = D⁻¹ exp(G) D, so D⁻¹ A Y_0 = ∏_k exp(D⁻¹G_kD) · D⁻¹Y_0: the balanced basis D⁻¹Y_0
    is carried across the sublayers and D Q̃_N = Q_N R̃ re-orthonormalised at the end, which gives
    the Q_N of the plain propagation (the orthonormal factor of A Y_0 with R_jj > 0 is unique) and
    log det R = Σ_k log det R̃_k + log det R̃. ‖D⁻¹GD‖∞ is 15–25× below ‖G‖∞ (the inertia term
    dominates: 2.3 → 0.15 at N = 30, Ω ≤ 20, order 1–2), so the exponentials need no squaring
    where they needed up to 3. ``"taylor"`` with G of degree 1 in w (midpoint, magnus4) takes the
    powers G², G³, G⁴ as polynomials in w (:func:`generator_powers`, :func:`expm_of_power_polys`):
    2 products of 8×8 matrices per sublayer and Ω instead of 5 + s. An order-m evaluation then
    costs 1.8× a longitudinal one (batch 4096, N = 30, benchmarks/README.md, section g).
    """
    w = omega_squared
    generators = wall_generators(wall, alpha, m, family)
    d = balance_diagonal(generators, w)
    scale = d[None, :] / d[:, None]  # (D⁻¹GD)_ij = G_ij d_j / d_i
    exponential = EXPONENTIALS[method]

    def balanced_exponential(coefficients):
        return exponential(scale * generator_of_w(coefficients, w))

    start = orthonormalize(basis / d[:, None])
    if method == "taylor" and generators.shape[1] == 2:
        # G of degree 1 in w (midpoint, magnus4): its powers as polynomials in w, once per wall
        (q, log_scale), _ = jax.lax.scan(
            lambda carry, polys: _advance(carry, expm_of_power_polys(polys, w, scale)),
            start, jax.vmap(generator_powers)(generators))
    else:
        (q, log_scale), _ = jax.lax.scan(
            lambda carry, coefficients: _advance(carry, balanced_exponential(coefficients)),
            start, generators)
    q, log_r = orthonormalize(q * d[:, None])
    return q, log_scale + log_r


def propagate_basis_history(wall: Wall, omega, alpha, basis, method: str = "taylor", m=0,
                            family=LONGITUDINAL):
    """Like :func:`propagate_basis`, keeping every interface: Q_k (N+1, n, k) and R_k (N+1, k, k)
    with T_k Q_{k−1} = Q_k R_k (k ≥ 1) and basis = Q_0 R_0 (used to recover mode shapes)."""
    return propagate_basis_history_of_w(wall, omega * omega, alpha, basis, method, m, family)


def propagate_basis_history_of_w(wall: Wall, omega_squared, alpha, basis, method: str = "taylor",
                                 m=0, family=LONGITUDINAL):
    """:func:`propagate_basis_history` at w = Ω² (either sign)."""
    def qr(y):
        q, _ = orthonormalize(y)
        return q, q.T @ y

    q0, r0 = qr(basis)

    def step(q, t):
        q_new, r_new = qr(matmul_small(t, q))
        return q_new, (q_new, r_new)

    _, (qs, rs) = jax.lax.scan(
        step, q0, layer_exponentials_of_w(wall, omega_squared, alpha, method, m, family))
    return jnp.concatenate([q0[None], qs]), jnp.concatenate([r0[None], rs])
