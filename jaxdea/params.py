"""Parameters of the tube and of the fluid (pytrees) and validation of concrete inputs.

Every float field is a pytree leaf (differentiable and vmappable); discrete choices are static
metadata. Leaves are kept exactly as given (so that ``Tube(voltage=0, lambda_i=None, ...)`` works as
a ``jax.vmap`` ``in_axes`` spec); conversion to float64 happens in :func:`as_float`.
"""

from __future__ import annotations

import dataclasses
import functools
import math

import jax
import jax.numpy as jnp
import numpy as np

from .compiled import jit, materialized, serializable
from .materials import Damping, Gent, Material, NeoHookean

COUPLINGS = ("acoustic", "paper")
MATERIALS = ("gent", "neo_hookean")
GENT_MIN = 1e-6
"""Smallest Gent constant G accepted. A wall with I_1 - 3 < G that small lies within rounding of
the undeformed state, where the Gent moduli (∝ 1/G times factors that vanish there) are dominated
by the rounding of I_1: G = 1e-12 moves the frequencies by 2e-5 relative, G = 1e-300 gives NaN."""
ALPHA_MIN = 1e-12
"""Smallest axial wavenumber α̂ accepted (wavelengths up to 2π·1e12 R_i). The lowest roots scale like
Ω ∝ α̂ and the characteristic function near them like α̂²: far below this they approach the
absolute rounding floor of the root scan (measured: fluid-filled tubes lose their two lowest roots
below α̂ ≈ 1e-19, empty ones drift from α̂ ≈ 1e-33 and lose the lowest root where f(0) ∝ α̂²
underflows, α̂ < 1.5e-154). At α̂ = 1e-12 the long-wave limit Ω/α̂ is reached to rounding."""
WIDTH_MAX = 1e6
"""Largest λ_z r̂_o² accepted (r̂_o = r_o/R_i, the deformed outer radius). The stretch through the
wall depends on u = λ_z (r̂² − r̂_i²), whose rounding in float64 is about 2.2e-16·λ_z r̂_o² absolute:
the results carry that relative error (measured on the lowest roots at α̂ = 0.445, η = 0.85: 2e-11
at λ_i = 1e3, 9e-8 at 1e4, and ΔP̂ off by 0.4 % at 1e7). Below the limit it stays under 2.2e-10
(λ_i up to 1000 at λ_z = 1; finite Gent constants bound λ_i far more tightly)."""
ALPHA_THICKNESS_MAX = 150.0
"""Largest α̂ĥ accepted for concrete inputs (ĥ = h/R_i, the deformed wall thickness): the range where
the characteristic function stays finite and its roots are found. Measured with the default
discretisation (N = 384 there): at α̂ĥ = 150 the two lowest roots converge for η = 0.3, 0.85 and
0.95; at α̂ĥ = 300 a thin wall (η = 0.95, α̂ = 8.1e3) gives NaN (its sublayer exponentials pass
‖h M‖∞ = 1.1e4, at N = 512, the most the default takes), at 600 a thick one (η = 0.3) a root with
status SUSPECT."""
MAX_LAYERS = 4096
"""Most sublayers N accepted: the midpoint laminate's error ∝ N⁻² (1.4e-5 at N = 30) is below 1e-9
here and the higher-order schemes reach rounding far earlier; the memory of a solve grows ∝ N."""
MAX_ROOTS = 1000
"""Most roots K per point (``n_roots``): the search range and the memory of the root lanes grow
∝ K."""
TINY = float(np.finfo(np.float64).tiny)
"""Smallest normal float64. XLA on CPU flushes subnormal numbers to zero, so concrete values are
validated as XLA will see them (a subnormal α̂ or λ is 0 inside the solvers)."""


@dataclasses.dataclass(frozen=True)
class Tube:
    """A pre-stretched dielectric elastomer tube (all quantities dimensionless, docs/theory/axisymmetric.md §0).

    Attributes:
        voltage: V̂ = sqrt(ε/μ) V / R_i.
        lambda_i: inner circumferential stretch λ_i = r_i / R_i.
        lambda_z: axial stretch λ_z = l / L.
        eta: undeformed radius ratio η = R_i / R_o, in (0, 1).
        gent: Gent constant G >= GENT_MIN = 1e-6 (``jnp.inf`` gives the neo-Hookean limit).
        length_ratio: L / R_o (the paper uses 10); enters only :func:`jaxdea.axial_wavenumber`.
        material: the elastic energy. A static name, ``"gent"`` (W of the Gent constant ``gent``,
            the default) or ``"neo_hookean"``, or a material object (:mod:`jaxdea.materials`:
            ``MooneyRivlin``, ``GentGent``, ``Ogden``, ``Energy``) whose parameters are
            differentiable leaves. ``Gent(G)`` means ``material="gent", gent=G`` and
            ``NeoHookean()`` means ``material="neo_hookean"`` (the closed forms of those energies).
        damping: None (elastic) or a damping law of :mod:`jaxdea.materials` (``Prony``,
            ``FractionalKelvinVoigt``, ``KelvinVoigt``, ``Hysteretic``) on the relaxed base state;
            a damped tube's roots are complex (:func:`jaxdea.complex_frequencies`).
        layers: None (one active wall of ``material``) or a tuple of :class:`Layer` from the inner
            face outwards, exactly one of them active; each carries its own material and damping
            (``material``, ``gent`` and ``damping`` of the tube are then unused and must stay at
            their defaults).
        outer: None (vacuum outside) or the unbounded inviscid :class:`Fluid` around the tube
            (``coupling="acoustic"``): subsonic modes (Ω < ĉ_oα̂) carry its added mass
            (docs/theory/real_tubes.md §6). The solvers' ``outer=`` sets it.
    """

    voltage: float = 0.0
    lambda_i: float = 1.0
    lambda_z: float = 1.0
    eta: float = 0.85
    gent: float = 97.2
    length_ratio: float = 10.0
    material: object = "gent"
    damping: object = None
    layers: tuple | None = None
    outer: Fluid | None = None

    def __post_init__(self):
        material = self.material
        if isinstance(material, Gent):
            object.__setattr__(self, "gent", material.gent)
            object.__setattr__(self, "material", "gent")
        elif isinstance(material, NeoHookean):
            object.__setattr__(self, "material", "neo_hookean")

    def replace(self, **changes) -> Tube:
        """A copy with some fields changed."""
        return dataclasses.replace(self, **changes)


TUBE_FIELDS = ("voltage", "lambda_i", "lambda_z", "eta", "gent", "length_ratio")
"""The float leaves of a :class:`Tube`; a material object's parameters follow them."""


def _flatten_tube(tube: Tube):
    """Children: the float fields, then the material object if there is one; auxiliary data: the
    material's static name (or None for an object)."""
    children = [(jax.tree_util.GetAttrKey(k), getattr(tube, k)) for k in TUBE_FIELDS]
    children.append((jax.tree_util.GetAttrKey("damping"), tube.damping))
    children.append((jax.tree_util.GetAttrKey("layers"), tube.layers))
    children.append((jax.tree_util.GetAttrKey("outer"), tube.outer))
    if isinstance(tube.material, str):
        return children, (tube.material,)
    return [*children, (jax.tree_util.GetAttrKey("material"), tube.material)], (None,)


def _unflatten_tube(aux, children) -> Tube:
    (name,) = aux
    tube = object.__new__(Tube)
    for key, value in zip(TUBE_FIELDS, children, strict=False):
        object.__setattr__(tube, key, value)
    count = len(TUBE_FIELDS)
    object.__setattr__(tube, "damping", children[count])
    object.__setattr__(tube, "layers", children[count + 1])
    object.__setattr__(tube, "outer", children[count + 2])
    object.__setattr__(tube, "material", name if name is not None else children[count + 3])
    return tube


jax.tree_util.register_pytree_with_keys(Tube, _flatten_tube, _unflatten_tube)
serializable(Tube)


@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class Layer:
    """One layer of a layered wall (API.md, "Layered walls"; docs/theory/real_tubes.md §3).

    Attributes:
        fraction: the layer's share of the undeformed wall thickness R_o − R_i (the fractions of a
            tube's layers sum to 1).
        material: its energy, a material object normalised to unit shear modulus
            (:mod:`jaxdea.materials`; default ``Gent(97.2)``).
        shear_ratio: μ_k/μ, its small-strain shear modulus over the active layer's.
        density_ratio: ρ_k/ρ_s, its density over the active layer's.
        active: static; True for the one dielectric layer with compliant electrodes on its faces
            (its shear and density ratios are 1: it sets the units), False for a passive layer,
            which carries no field.
        damping: None or a damping law of :mod:`jaxdea.materials` for this layer.
    """

    fraction: float
    material: object = dataclasses.field(default_factory=Gent)
    shear_ratio: float = 1.0
    density_ratio: float = 1.0
    active: bool = dataclasses.field(default=False, metadata=dict(static=True))
    damping: object = None


@serializable
@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class Fluid:
    """An inviscid compressible fluid filling the tube.

    Attributes:
        density_ratio: ρ̂_f = ρ_f / ρ_s > 0.
        speed_ratio: ĉ_f = c_f / c_s > 0.
        coupling: static, ``"acoustic"`` (consistent, docs/theory/axisymmetric.md §4(c)) or
            ``"paper"`` (the paper's Eq. 45 follower-pressure model, docs/theory/axisymmetric.md §4(b)).
        bessel_order: static int ν ≥ 0 of the paper's coupling function (``"paper"`` only);
            ``None`` means ν = n, the axial mode number, inferred from a concrete α̂.
    """

    density_ratio: float = 0.13
    speed_ratio: float = 0.27
    coupling: str = dataclasses.field(default="acoustic", metadata=dict(static=True))
    bessel_order: int | None = dataclasses.field(default=None, metadata=dict(static=True))

    def replace(self, **changes) -> Fluid:
        """A copy with some fields changed."""
        return dataclasses.replace(self, **changes)


def require_x64() -> None:
    """Raise unless 64-bit floats are enabled: jaxdea never computes silently in float32."""
    if not jax.config.jax_enable_x64:
        raise RuntimeError(
            "jaxdea needs 64-bit floats: call jax.config.update('jax_enable_x64', True) "
            "before using it (the characteristic determinant is meaningless in float32)."
        )


def as_float(x) -> jax.Array:
    """A float64 array (a tracer stays a tracer)."""
    return jnp.asarray(x, dtype=jnp.float64)


def _canonical_leaf(x):
    """:func:`canonical` of one leaf: a tracer or JAX array as :func:`as_float`; a concrete real
    number or NumPy array as a float64 NumPy array (no device operation: converting the leaves of a
    call to JAX arrays one by one dispatched 7–8 eager operations, ≈ 0.5 ms of a 14 ms dispersion
    curve, measured); anything else (complex, an object) as :func:`as_float`, with its errors."""
    if isinstance(x, jax.core.Tracer):
        return as_float(x)
    if isinstance(x, jax.Array):
        return x if x.dtype == jnp.float64 and not x.weak_type else as_float(x)
    value = np.asarray(x)
    if value.dtype.kind in "biuf":
        return value.astype(np.float64, copy=False)
    return as_float(x)


def canonical(*trees):
    """Every leaf as a float64 array (strongly typed), so that Python floats, NumPy scalars and JAX
    arrays share one compiled program (a weak-typed float would compile separately). Concrete
    numbers become NumPy arrays, which the programs take as they take JAX arrays."""
    out = tuple(jax.tree_util.tree_map(_canonical_leaf, t) for t in trees)
    return out if len(out) > 1 else out[0]


def traced(tree) -> bool:
    """Whether any leaf of ``tree`` is a tracer (a caller's jit, grad or vmap)."""
    return any(isinstance(leaf, jax.core.Tracer) for leaf in jax.tree_util.tree_leaves(tree))


def detached(tree):
    """``jax.lax.stop_gradient(tree)`` where a leaf is traced; concrete leaves as they are (they
    carry no tangent, and stopping them dispatched an eager operation per leaf)."""
    return jax.lax.stop_gradient(tree) if traced(tree) else tree


def _concrete(x, name: str = "value"):
    """The value of x as a float64 numpy array, or None when it is traced.

    Raises:
        ValueError: naming the parameter if x is no real number (a string, complex, an object).
    """
    if isinstance(x, jax.core.Tracer):
        return None
    if x is None or isinstance(x, (str, bytes)) or np.iscomplexobj(x):
        raise ValueError(f"{name} must be a real number, got {x!r}")
    try:
        raw = np.asarray(x)
    except (TypeError, ValueError, OverflowError) as exc:
        raise ValueError(f"{name} must be a real number, got {x!r}") from exc
    if raw.dtype == np.bool_:  # True would pass as 1.0
        raise ValueError(f"{name} must be a real number, got the boolean {x!r}")
    try:
        value = raw.astype(np.float64, copy=False)
    except (TypeError, ValueError, OverflowError) as exc:
        raise ValueError(f"{name} must be a real number, got {x!r}") from exc
    return value


def _check(name, x, allowed, ok, allow_inf=False, scalar=True):
    """Raise ValueError naming the parameter when a concrete value is outside its range (or, with
    ``scalar``, is no scalar: batches go through ``jax.vmap``)."""
    v = _concrete(x, name)
    if v is None:
        return None
    if scalar and v.ndim:
        raise ValueError(f"{name} must be a scalar ({allowed}; batch with jax.vmap), got an array "
                         f"of shape {v.shape}")
    finite = np.isfinite(v) | (allow_inf & (v == np.inf))
    if not np.all(finite):
        raise ValueError(f"{name} must be finite ({allowed}), got {x!r}")
    flushed = np.where(np.abs(v) < TINY, 0.0, v)  # what XLA computes with (subnormals -> 0)
    good = ok(flushed)
    if not np.all(good):
        bad = float(np.ravel(v[~good] if v.ndim else v)[0])
        note = " (a subnormal number: XLA flushes it to 0)" if 0 < abs(bad) < TINY else ""
        raise ValueError(f"{name} must be {allowed}, got {bad!r}{note}")
    return v


def validate_broadcast(kind, values: dict) -> None:
    """Raise ValueError naming the fields when concrete array leaves do not broadcast together."""
    shapes = {k: np.shape(v) for k, v in values.items() if v is not None}
    try:
        np.broadcast_shapes(*shapes.values())
    except ValueError as exc:
        listed = ", ".join(f"{k} {s}" for k, s in shapes.items() if s)
        raise ValueError(f"the {kind} fields have shapes that do not broadcast: {listed}") from exc


def gent_limit_excess(lambda_i, lambda_z, eta):
    """max over the wall of I_1 − 3 (attained at a face; I_1 is convex in λ², docs/theory/axisymmetric.md §1);
    inf where extreme inputs overflow (such a wall is past any locking limit)."""
    with np.errstate(all="ignore"):
        excess = _face_excess(lambda_i, lambda_z, eta, np)
    return np.where(np.isfinite(excess), excess, np.inf)


def wall_constant(lambda_z, eta):
    """(η⁻² − 1)/λ_z = r̂_o² − r̂_i² (incompressibility, paper Eq. 6), as (1 − η)(1 + η)/(η² λ_z):
    accurate to a few ulp for every η in (0, 1), thin walls (η → 1) included."""
    return (1.0 - eta) * (1.0 + eta) / (eta**2 * lambda_z)


def wall_width(lambda_i, lambda_z, eta):
    """λ_z r̂_o² = λ_z (λ_i² + c), the measure of the rounding of the radii (WIDTH_MAX; numpy or
    jax.numpy, inf or NaN on overflow: too wide to resolve in float64)."""
    return lambda_z * (lambda_i**2 + wall_constant(lambda_z, eta))


def _face_excess(lambda_i, lambda_z, eta, xp):
    """max(I_1 − 3) over the two faces (``xp``: numpy or jax.numpy)."""
    ro = xp.sqrt(lambda_i**2 + wall_constant(lambda_z, eta))
    i1 = [lam**2 + 1.0 / (lam * lambda_z) ** 2 + lambda_z**2 for lam in (lambda_i, ro * eta)]
    return xp.maximum(i1[0], i1[1]) - 3.0


def admissible(tube: Tube, alpha=1.0, fluid: Fluid | None = None) -> jax.Array:
    """Traced counterpart of the validation: True where every input is inside its allowed range
    (finite; λ_i, λ_z, length_ratio, ρ̂_f, ĉ_f > 0; α̂ >= ALPHA_MIN; G >= GENT_MIN; 0 < η < 1;
    λ_z r̂_o² <= WIDTH_MAX; I_1 − 3 < G in the whole wall).

    Solvers use it under jit/vmap to return NaN with status INVALID instead of a plausible number.
    A layered wall also needs fractions > 0 summing to 1 and ratios > 0.
    """
    li, lz, eta = (as_float(x) for x in (tube.lambda_i, tube.lambda_z, tube.eta))
    g, length, v, a = (as_float(x) for x in (tube.gent, tube.length_ratio, tube.voltage, alpha))
    finite = [jnp.isfinite(x) for x in (li, lz, eta, length, v, a)]
    positive = [x > 0 for x in (li, lz, length)] + [a >= ALPHA_MIN, (eta > 0) & (eta < 1),
                                                    g >= GENT_MIN]
    ok = functools.reduce(jnp.logical_and, finite + positive) & ~jnp.isnan(g)
    ok &= wall_width(li, lz, eta) <= WIDTH_MAX  # NaN and inf fail
    locking = locking_constant(tube)
    if locking is not None:
        excess = _face_excess(li, lz, eta, jnp)
        ok &= jnp.isfinite(excess) & (excess < as_float(locking))
    if tube.layers is not None:  # fractions > 0 summing to 1, ratios > 0 (validate_wall_layers)
        fractions = [as_float(layer.fraction) for layer in tube.layers]
        ratios = [as_float(getattr(layer, k)) for layer in tube.layers
                  for k in ("shear_ratio", "density_ratio")]
        ok &= functools.reduce(jnp.logical_and, [x > 0 for x in fractions + ratios])
        ok &= jnp.abs(sum(fractions) - 1.0) <= FRACTION_SUM_TOL
    for medium in (fluid, tube.outer):
        if medium is not None:
            rho, c = as_float(medium.density_ratio), as_float(medium.speed_ratio)
            ok &= jnp.isfinite(rho) & jnp.isfinite(c) & (rho > 0) & (c > 0)
    return ok


def guard(tube: Tube, alpha, fluid: Fluid | None):
    """(ok, tube, alpha, fluid): ``ok`` from :func:`admissible`; where not ok the inputs are swapped
    for a harmless default case, so that a solver under vmap does no work on them (the caller
    returns NaN, with status INVALID, there)."""
    ok = materialized(admissible(tube, alpha, fluid))  # read by every leaf's consumers
    swap = lambda x, d: jnp.where(ok, as_float(x), d)  # noqa: E731
    outer = None if tube.outer is None else Fluid(density_ratio=1.0, speed_ratio=OUTER_SPEED_DEFAULT)
    tube = jax.tree_util.tree_map(swap, tube, Tube(material=tube.material, damping=tube.damping,
                                                    layers=tube.layers, outer=outer))
    if fluid is not None:
        default = Fluid(coupling=fluid.coupling, bessel_order=fluid.bessel_order)
        fluid = jax.tree_util.tree_map(swap, fluid, default)
    return ok, tube, swap(alpha, 1.0), fluid


def validate_tube(tube: Tube, scalar: bool = True) -> dict:
    """Validate the concrete leaves of a tube (traced leaves are skipped).

    Args:
        tube: the :class:`Tube`.
        scalar: every concrete leaf must be a scalar (the solvers: batches go through
            ``jax.vmap``); with False, arrays that broadcast together are allowed (elementwise
            helpers such as :func:`jaxdea.thickness_ratio`).

    Returns:
        ``{field: concrete float64 value, or None where traced}`` for every float field.

    Raises:
        ValueError: naming the parameter and its allowed range; for a tube too wide to resolve
            (λ_z r̂_o² > WIDTH_MAX), stating λ_z r̂_o²; past Gent locking, stating the largest
            I_1 - 3 in the wall against G.
    """
    if not isinstance(tube, Tube):
        raise ValueError(f"tube must be a jaxdea.Tube, got {type(tube).__name__}")
    validate_material(tube.material)
    validate_damping(tube.damping)
    validate_wall_layers(tube)
    validate_outer(tube.outer)
    checks = dict(
        voltage=_check("voltage", tube.voltage, "a finite real number", lambda v: np.isreal(v),
                       scalar=scalar),
        lambda_i=_check("lambda_i", tube.lambda_i, "> 0", lambda v: v > 0, scalar=scalar),
        lambda_z=_check("lambda_z", tube.lambda_z, "> 0", lambda v: v > 0, scalar=scalar),
        eta=_check("eta", tube.eta, "in the open interval (0, 1)", lambda v: (v > 0) & (v < 1),
                   scalar=scalar),
        gent=_check("gent", tube.gent, f">= {GENT_MIN!r} (inf for neo-Hookean)",
                    lambda v: v >= GENT_MIN, allow_inf=True, scalar=scalar),
        length_ratio=_check("length_ratio", tube.length_ratio, "> 0", lambda v: v > 0,
                            scalar=scalar),
    )
    if not scalar:
        validate_broadcast("Tube", checks)
    li, lz, eta, g = (checks[k] for k in ("lambda_i", "lambda_z", "eta", "gent"))
    if li is None or lz is None or eta is None:
        return checks
    with np.errstate(all="ignore"):
        width = wall_width(li, lz, eta)
    if not np.all(width <= WIDTH_MAX):
        worst = float(np.max(np.where(np.isnan(width), np.inf, width)))
        raise ValueError(
            "lambda_i, lambda_z, eta give a deformed tube too wide to resolve in float64: "
            f"lambda_z * r_o**2 must be <= {WIDTH_MAX:g} (r_o the deformed outer radius over R_i; "
            f"rounding perturbs the stretches by about 2.2e-16 * lambda_z * r_o**2), got {worst:.6e}"
        )
    locking = locking_constant(tube)
    if locking is None or isinstance(locking, jax.core.Tracer):
        return checks
    g = checks["gent"] if locking is tube.gent else np.asarray(locking, np.float64)
    if g is None:
        return checks
    excess = gent_limit_excess(li, lz, eta)
    if np.any(excess >= g):
        worst = float(np.max(excess))
        raise ValueError(
            "lambda_i, lambda_z, eta beyond the Gent locking limit: I_1 - 3 must stay below "
            f"gent = {float(np.min(g))!r} everywhere in the wall, but reaches {worst:.6g}"
        )
    return checks


def locking_constant(tube: Tube):
    """The Gent locking constant G of the tube's energy (I_1 − 3 < G in the wall), or None for an
    energy without locking: ``gent`` for ``material="gent"``, a GentGent object's own ``gent``."""
    if isinstance(tube.material, str):
        return tube.gent if tube.material == "gent" else None
    return getattr(tube.material, "gent", None)


SHEAR_RTOL = 1e-9
"""How far 2(W_1 + W_2) at rest may be from 1 (the normalisation of a material object)."""


@jax.jit
def _rest_values(material):
    """(W, 2(W_1 + W_2)) of a material at rest: compiled once per material class (an eager
    Hessian took 50–70 ms, paid at every validation)."""
    return material.energy(jnp.ones(3)), material.shear_modulus()


def validate_material(material) -> None:
    """A static name of :data:`MATERIALS` or a material object with finite parameters, an energy
    finite at rest and unit small-strain shear modulus 2(W_1 + W_2) = 1 at I_1 = I_2 = 3 (Ogden:
    Σ μ_kα_k = 2). Traced parameters are not checked.

    Raises:
        ValueError: naming ``material`` (and the parameter, or the value of 2(W_1 + W_2) at rest).
    """
    if isinstance(material, str):
        if material not in MATERIALS:
            raise ValueError(f"material must be one of {MATERIALS} or a material object "
                             f"(jaxdea.MooneyRivlin, GentGent, Ogden, Energy), got {material!r}")
        return
    if not isinstance(material, Material):
        raise ValueError("material must be a name or a material object (jaxdea.MooneyRivlin, "
                         f"GentGent, Ogden, Energy), got {type(material).__name__}")
    name = type(material).__name__
    leaves = jax.tree_util.tree_leaves(material)
    if any(isinstance(x, jax.core.Tracer) for x in leaves):
        return
    for leaf in leaves:
        value = np.asarray(leaf)
        if not (np.issubdtype(value.dtype, np.number) and np.isrealobj(value)
                and np.all(np.isfinite(value))):
            raise ValueError(f"material {name}: every parameter must be a finite real number, "
                             f"got {leaf!r}")
    fields = {f.name: getattr(material, f.name) for f in dataclasses.fields(material)}
    if "beta" in fields and not 0.0 <= float(fields["beta"]) <= 1.0:
        raise ValueError(f"material {name}: beta must be in [0, 1], got {fields['beta']!r}")
    if "gent" in fields and not float(fields["gent"]) > 0.0:
        raise ValueError(f"material {name}: gent must be > 0, got {fields['gent']!r}")
    if "mu" in fields:
        mu, alpha = tuple(fields["mu"]), tuple(fields["alpha"])
        if not mu or len(mu) != len(alpha) or any(float(a) == 0.0 for a in alpha):
            raise ValueError(f"material {name}: mu and alpha must be tuples of one length >= 1 "
                             f"with every alpha != 0, got mu={mu!r}, alpha={alpha!r}")
    values = _rest_values(material)
    if any(isinstance(x, jax.core.Tracer) for x in values):
        # concrete parameters inside a caller's jit: the call was staged, so evaluate it op by op
        # (only there: eagerly, a first validation took 1.9 s instead of 0.05 s, measured)
        with jax.ensure_compile_time_eval():
            values = _rest_values(material)
    at_rest, shear = (float(x) for x in values)
    if not math.isfinite(at_rest):
        raise ValueError(f"material {name}: the energy is not finite at rest (W = {at_rest!r})")
    if not abs(shear - 1.0) <= SHEAR_RTOL:
        raise ValueError(f"material {name} is not normalised to unit shear modulus: "
                         f"2(W_1 + W_2) at I_1 = I_2 = 3 is {shear!r}, it must be 1")


FRACTION_SUM_TOL = 1e-12
"""How far the layers' fractions may sum from 1."""


def validate_wall_layers(tube: Tube) -> None:
    """``tube.layers``: None, or a tuple of :class:`Layer` with exactly one active, fractions > 0
    summing to 1, ratios > 0 (1 for the active layer, which sets the units), normalised materials
    and valid damping; the tube's own material and damping then stay at their defaults. Traced
    values are not checked.

    Raises:
        ValueError: naming ``layers`` (and the layer and parameter) and the allowed range.
    """
    layers = tube.layers
    if layers is None:
        return
    if not isinstance(layers, tuple) or not layers or not all(isinstance(x, Layer) for x in layers):
        raise ValueError(f"layers must be None or a non-empty tuple of jaxdea.Layer, got {layers!r}")
    active = [k for k, layer in enumerate(layers) if layer.active]
    if len(active) != 1:
        raise ValueError("layers: exactly one layer must be active (the dielectric with the "
                         f"electrodes), got {len(active)}")
    if tube.material != "gent" or tube.damping is not None:
        raise ValueError("layers: give each Layer its material and damping; the tube's material and "
                         "damping must stay at their defaults with layers")
    fractions = []
    for k, layer in enumerate(layers):
        for key in ("fraction", "shear_ratio", "density_ratio"):
            value = getattr(layer, key)
            if isinstance(value, jax.core.Tracer):
                continue
            v = np.asarray(value, dtype=np.float64) if np.isrealobj(value) else np.nan
            if not (np.ndim(v) == 0 and np.isfinite(v) and v > 0):
                raise ValueError(f"layers[{k}].{key} must be a finite number > 0, got {value!r}")
            if layer.active and key != "fraction" and v != 1.0:
                raise ValueError(f"layers[{k}].{key} must be 1 for the active layer (its shear "
                                 f"modulus and density are the units), got {value!r}")
            if key == "fraction":
                fractions.append(float(v))
        if isinstance(layer.material, str):
            raise ValueError(f"layers[{k}].material must be a material object (jaxdea.Gent, "
                             f"NeoHookean, MooneyRivlin, GentGent, Ogden, Energy), got "
                             f"{layer.material!r}")
        validate_material(layer.material)
        validate_damping(layer.damping)
    if len(fractions) == len(layers) and abs(sum(fractions) - 1.0) > FRACTION_SUM_TOL:
        raise ValueError(f"layers: the fractions must sum to 1, got {sum(fractions)!r}")


_DAMPING_RANGES = {
    "moduli": (">= 0", lambda v: v >= 0), "times": ("> 0", lambda v: v > 0),
    "modulus": (">= 0", lambda v: v >= 0), "time": ("> 0", lambda v: v > 0),
    "order": ("in (0, 1]", lambda v: (v > 0) & (v <= 1)), "stretch_coupling": ("finite", np.isfinite),
    "viscosity": (">= 0", lambda v: v >= 0), "loss": (">= 0", lambda v: v >= 0),
}


def validate_damping(damping) -> None:
    """None or a damping law of :mod:`jaxdea.materials` with parameters in range (traced ones are
    not checked).

    Raises:
        ValueError: naming ``damping`` and the parameter with its allowed range.
    """
    if damping is None:
        return
    if not isinstance(damping, Damping):
        raise ValueError("damping must be None or a damping law (jaxdea.Prony, "
                         "FractionalKelvinVoigt, KelvinVoigt, Hysteretic), got "
                         f"{type(damping).__name__}")
    name = type(damping).__name__
    fields = {f.name: getattr(damping, f.name) for f in dataclasses.fields(damping)}
    if "times" in fields and len(tuple(fields["times"])) != len(tuple(fields["moduli"])):
        raise ValueError(f"damping {name}: moduli and times must have one length, got "
                         f"{fields['moduli']!r} and {fields['times']!r}")
    for key, value in fields.items():
        for leaf in jax.tree_util.tree_leaves(value):
            if isinstance(leaf, jax.core.Tracer):
                continue
            allowed, ok = _DAMPING_RANGES[key]
            v = np.asarray(leaf)
            if not (np.issubdtype(v.dtype, np.number) and np.isrealobj(v) and np.all(np.isfinite(v))
                    and np.all(ok(v))):
                raise ValueError(f"damping {name}: {key} must be {allowed}, got {value!r}")


def validate_fluid(fluid: Fluid | None, scalar: bool = True) -> None:
    """Validate a fluid (``None`` is the empty tube); ``scalar`` as in :func:`validate_tube`.

    Raises:
        ValueError: naming the parameter and its allowed range.
    """
    if fluid is None:
        return
    if not isinstance(fluid, Fluid):
        raise ValueError(f"fluid must be a jaxdea.Fluid or None, got {type(fluid).__name__}")
    if not isinstance(fluid.coupling, str) or fluid.coupling not in COUPLINGS:
        raise ValueError(f"coupling must be one of {COUPLINGS}, got {fluid.coupling!r}")
    order = fluid.bessel_order
    if order is not None and (not isinstance(order, (int, np.integer)) or isinstance(order, bool)
                              or order < 0):
        raise ValueError(f"bessel_order must be None or an integer >= 0, got {order!r}")
    checks = dict(
        density_ratio=_check("density_ratio", fluid.density_ratio, "> 0", lambda v: v > 0,
                             scalar=scalar),
        speed_ratio=_check("speed_ratio", fluid.speed_ratio, "> 0", lambda v: v > 0,
                           scalar=scalar),
    )
    if not scalar:
        validate_broadcast("Fluid", checks)


def with_outer(tube: Tube, outer: Fluid | None) -> Tube:
    """The tube in the surrounding fluid ``outer`` (the solvers' ``outer=``): the tube itself where
    ``outer`` is None.

    Raises:
        ValueError: ``outer`` given for a tube that already has an ``outer`` fluid.
    """
    if outer is None:
        return tube
    if not isinstance(tube, Tube):
        raise ValueError(f"tube must be a jaxdea.Tube, got {type(tube).__name__}")
    if tube.outer is not None:
        raise ValueError("outer: the tube already has a surrounding fluid (tube.outer); give it once")
    validate_outer(outer)
    return tube.replace(outer=outer)


OUTER_SPEED_DEFAULT = 100.0
"""ĉ_o of the stand-in outer fluid that :func:`guard` puts in place of an invalid one."""


def validate_outer(outer: Fluid | None) -> None:
    """Validate a surrounding fluid (``Tube.outer``; None is vacuum).

    Raises:
        ValueError: naming ``outer`` and the parameter: not a Fluid; a coupling other than
            ``"acoustic"`` (the paper's follower-pressure model exists only as a filling); a
            ``bessel_order``; a density or speed ratio that is not finite and > 0.
    """
    if outer is None:
        return
    if not isinstance(outer, Fluid):
        raise ValueError(f"outer must be a jaxdea.Fluid or None, got {type(outer).__name__}")
    if outer.coupling != "acoustic":
        raise ValueError("outer.coupling must be 'acoustic' (the 'paper' coupling exists only as a "
                         f"filling, fluid=...), got {outer.coupling!r}")
    if outer.bessel_order is not None:
        raise ValueError("outer.bessel_order must be None (the outer field's order is the mode's "
                         f"m), got {outer.bessel_order!r}")
    _check("outer.density_ratio", outer.density_ratio, "> 0", lambda v: v > 0)
    _check("outer.speed_ratio", outer.speed_ratio, "> 0", lambda v: v > 0)


def validate_alpha(alpha, name: str = "alpha", tube: Tube | None = None, scalar: bool = True):
    """Validate a concrete axial wavenumber: a finite real α̂ >= ALPHA_MIN (a scalar, or with
    ``scalar=False`` an array) and, with a validated concrete ``tube``, α̂ĥ <= ALPHA_THICKNESS_MAX
    (ĥ = c/(r̂_o + r̂_i) its deformed thickness, c = (η⁻² − 1)/λ_z). Returns α̂ as a numpy array, or
    None when traced."""
    value = _check(name, alpha, f">= {ALPHA_MIN!r} and finite (the axial wavenumber α̂ = α R_i)",
                   lambda v: v >= ALPHA_MIN, scalar=scalar)
    leaves = [] if tube is None else [tube.lambda_i, tube.lambda_z, tube.eta]
    if value is None or value.size == 0 or any(isinstance(x, jax.core.Tracer) for x in leaves):
        return value
    if tube is not None:
        li, lz, eta = (np.asarray(x, dtype=np.float64) for x in leaves)
        c = wall_constant(lz, eta)
        thickness = float(np.max(c / (np.sqrt(li**2 + c) + li)))
        largest = float(np.max(value))
        # 1e-9: the rounding of an α̂ computed as ALPHA_THICKNESS_MAX/ĥ by the solvers' geometry
        if largest * thickness > ALPHA_THICKNESS_MAX * (1.0 + 1e-9):
            raise ValueError(
                f"{name} must be <= {ALPHA_THICKNESS_MAX:g}/ĥ = {ALPHA_THICKNESS_MAX / thickness:.6g} "
                f"for this tube (α̂ĥ <= {ALPHA_THICKNESS_MAX:g}, ĥ = {thickness:.6g} the deformed "
                f"wall thickness over R_i: the range where the characteristic function stays finite and "
                f"its roots are found), got "
                f"{largest!r}")
    return value


def mode_wavenumber(tube: Tube, n):
    """α̂ = 2nπη/(length_ratio·λ_z) without validation (traceable; :func:`axial_wavenumber` checks)."""
    return 2.0 * math.pi * as_float(n) * as_float(tube.eta) / (as_float(tube.length_ratio)
                                                              * as_float(tube.lambda_z))


_mode_wavenumber = jit(mode_wavenumber)


def axial_wavenumber(tube: Tube, n):
    """α̂ = α R_i of the axial mode number n: α = 2nπ/l, l = λ_z L, so α̂ = 2nπη/(length_ratio·λ_z).

    Elementwise: the tube's leaves and ``n`` may be arrays that broadcast together (all of them:
    the admissibility of the tube involves every leaf). Non-integer n give the wavenumber of the
    wavelength l/n.

    Args:
        tube: the :class:`Tube` (η, λ_z and length_ratio enter).
        n: the axial mode number, > 0.

    Raises:
        ValueError: for a concrete invalid tube (naming the parameter; past Gent locking stating
            the largest I_1 − 3 against G) or n that is no finite real number > 0. Traced invalid
            inputs give NaN.
    """
    require_x64()
    fields = validate_tube(tube, scalar=False)
    count = _check("n", n, "a finite real number > 0 (the axial mode number)", lambda v: v > 0,
                   scalar=False)
    if count is not None:  # every float field: admissibility (NaN where traced) involves them all
        values = {k: getattr(tube, k) for k in fields}  # traced leaves too (their shapes count)
        validate_broadcast("axial_wavenumber argument", dict(values, n=count))
    if count is not None and all(v is not None for v in fields.values()):
        # all concrete and validated above, so admissible everywhere: the formula alone, in one
        # compiled program (the ~40 eager operations of admissible() cost ~1.5 ms a call)
        # the shape of every leaf and n, as where traced (a gent array gives one α̂ per tube)
        shape = np.broadcast_shapes(*(np.shape(v) for v in fields.values()), np.shape(count))
        return jnp.broadcast_to(_mode_wavenumber(Tube(**fields, material=tube.material), count), shape)
    n = as_float(n)
    ok = admissible(tube) & jnp.isfinite(n) & (n > 0)
    return jnp.where(ok, mode_wavenumber(tube, n), jnp.nan)


def validate_positive(name: str, x, allowed: str = "> 0") -> None:
    """Validate a concrete positive scalar argument such as α̂ or a guess."""
    _check(name, x, allowed, lambda v: v > 0)


def validate_range(name: str, x, allowed: str, ok, allow_inf: bool = False, scalar: bool = True):
    """Validate a concrete argument: a real number (an array only without ``scalar``), finite
    (``allow_inf``: +inf too) and with ``ok(value)`` true. Returns it as a numpy array, or None when
    traced.

    Raises:
        ValueError: naming the parameter, ``allowed`` stating the range.
    """
    return _check(name, x, allowed, ok, allow_inf=allow_inf, scalar=scalar)


def validate_real(name: str, x, allowed: str = "a finite real number", scalar: bool = True):
    """Validate a concrete finite real argument (e.g. Ω of :func:`jaxdea.mode_shape`, ΔP̂); traced
    values pass. Returns the value as a numpy array, or None when traced."""
    return _check(name, x, allowed, lambda v: np.isfinite(v), scalar=scalar)


def real_value(name: str, x, scalar: bool = True):
    """A concrete argument as a float64 numpy array, any real value (NaN and ±inf included), or
    None when traced; ValueError naming the parameter for strings, complex numbers, objects and
    (with ``scalar``) arrays."""
    v = _concrete(x, name)
    if v is not None and scalar and v.ndim:
        raise ValueError(f"{name} must be a scalar real number (batch with jax.vmap), got an array "
                         f"of shape {v.shape}")
    return v


def validate_count(name: str, value, low: int = 1) -> int:
    """A static integer argument (n_points, n_max, …) >= ``low``; bools and floats are refused."""
    if not isinstance(value, (int, np.integer)) or isinstance(value, bool) or value < low:
        raise ValueError(f"{name} must be an integer >= {low}, got {value!r}")
    return int(value)


def validate_layers(n_layers) -> None:
    """n_layers is None (the default discretisation) or a static integer >= 1."""
    if n_layers is None:
        return
    if hasattr(n_layers, "count") and hasattr(n_layers, "scheme"):
        n_layers = n_layers.count  # a resolved discretisation (jaxdea.physics.transfer.Layers)
    if not isinstance(n_layers, (int, np.integer)) or isinstance(n_layers, bool) or n_layers < 1:
        raise ValueError(f"n_layers must be None or an integer >= 1, got {n_layers!r}")
    if n_layers > MAX_LAYERS:
        raise ValueError(f"n_layers must be <= MAX_LAYERS = {MAX_LAYERS} (more sublayers add only "
                         f"rounding and memory), got {n_layers!r}")


def validate_roots(n_roots) -> int:
    """The static number of roots K: an integer in [1, MAX_ROOTS]."""
    count = validate_count("n_roots", n_roots)
    if count > MAX_ROOTS:
        raise ValueError(f"n_roots must be <= MAX_ROOTS = {MAX_ROOTS}, got {n_roots!r}")
    return count


def mode_number(tube: Tube, alpha) -> int:
    """The axial mode number n with α̂ = 2nπη/(length_ratio λ_z), from concrete values.

    Raises:
        ValueError: if α̂ is traced or is not an integer mode of the tube.
    """
    vals = [_concrete(x, name) for x, name in ((alpha, "alpha"), (tube.eta, "eta"),
                                             (tube.length_ratio, "length_ratio"),
                                             (tube.lambda_z, "lambda_z"))]
    if any(v is None for v in vals) or any(v.ndim for v in vals):
        raise ValueError(
            "bessel_order=None needs concrete scalar alpha and tube: pass Fluid(bessel_order=...) "
            "explicitly when alpha or the tube is traced or batched"
        )
    alpha, eta, lr, lz = (float(v) for v in vals)
    n = alpha * lr * lz / (2.0 * math.pi * eta)
    if abs(n - round(n)) > 1e-9 * max(1.0, n) or round(n) < 1:
        raise ValueError(
            f"alpha = {alpha!r} is no integer axial mode of the tube (n = {n:.6g}); "
            "pass Fluid(bessel_order=...) explicitly"
        )
    return int(round(n))
