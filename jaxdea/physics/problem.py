"""What is solved: one static description of a problem, built and validated once.

A :class:`Problem` holds the static part of a case: its mode :class:`~jaxdea.physics.families.Family`
(longitudinal, order m, torsional; docs/theory/order_m.md §3), its inner
:class:`~jaxdea.physics.families.Face` (empty, acoustic, paper; docs/theory/axisymmetric.md §4) and the
static Bessel order ν of the paper's coupling (API.md). The traced part (tube, α̂, fluid, m) stays
with the caller. :func:`describe` validates the public inputs and builds it; every public solver
starts there. A Problem is hashable and compared by value, a static argument of ``jit``.
"""

import dataclasses

import jax
import numpy as np

from ..params import (
    ALPHA_MIN,
    Fluid,
    Tube,
    mode_number,
    require_x64,
    validate_alpha,
    validate_fluid,
    validate_layers,
    validate_tube,
)
from .families import Face, Family
from .transfer import validate_scheme


@dataclasses.dataclass(frozen=True)
class Problem:
    """The static description of a case: ``family``, inner ``face`` and Bessel ``order`` ν;
    ``decoupled``: the electric block decouples (a longitudinal wall without voltage), so the
    searches of complex roots propagate the mechanical and electric blocks apart
    (:func:`jaxdea.physics.characteristic.block_pieces`)."""

    family: Family
    face: Face
    order: int
    decoupled: bool = False

    def arguments(self, m) -> dict:
        """The keywords (m, family) of the family's programs (:meth:`Family.arguments`)."""
        return self.family.arguments(m)


NO_ALPHA = object()
"""The ``alpha`` of :func:`describe` for a solver that takes no α̂ of its own (a curve, a critical
voltage over modes): None there is a user's missing α̂, an error that names it."""


def describe(tube, alpha, fluid, n_layers, scheme=None, m=0, torsional=False,
             damped: bool = False) -> Problem:
    """Validate the public inputs (concrete values) and describe the problem.

    ``alpha`` :data:`NO_ALPHA` where a solver takes no α̂ of its own (the Bessel order is then
    resolved at α̂ = 1); None is a missing α̂ (ValueError). The family is that of (m, torsional):
    concrete m = 0 longitudinal, m ≥ 1 or a traced m order m, torsional with ``torsional=True``.

    Raises:
        ValueError: naming the parameter, for invalid concrete inputs (the tube, α̂, fluid,
            discretisation, m, torsional, and m ≥ 1 with the paper's coupling), and for a damped
            tube unless ``damped`` (the solvers of complex roots).
    """
    if alpha is None:
        raise ValueError(f"alpha must be a real number >= {ALPHA_MIN!r} (the axial wavenumber "
                         "α̂ = α R_i), got None")
    alpha = None if alpha is NO_ALPHA else alpha
    order = validated_order(tube, alpha, fluid, n_layers, scheme)
    if not damped and getattr(tube, "damping", None) is not None:
        raise ValueError(
            "tube.damping: a damped tube has complex frequencies; this solver finds real roots of "
            "the elastic tube. Use jaxdea.complex_frequencies (complex Omega at a real alpha) or "
            "jaxdea.wavenumbers (complex alpha at a real Omega), or tube.replace(damping=None)")
    family = family_of(m, torsional, fluid)
    return Problem(family, Face.of(fluid), order,
                   damped and family is Family.LONGITUDINAL and _no_voltage(tube))


def _no_voltage(tube) -> bool:
    """Whether the tube's V̂ is concrete and 0 at every point (its electric block decouples)."""
    voltage = tube.voltage
    if isinstance(voltage, jax.core.Tracer):
        return False
    try:
        return bool(np.all(np.asarray(voltage) == 0))
    except (TypeError, ValueError, jax.errors.ConcretizationTypeError):
        return False


def bessel_order(tube: Tube, alpha, fluid: Fluid | None) -> int:
    """The static Bessel order: 0 for ``acoustic``; ``bessel_order`` or the axial mode number n for
    ``paper`` (API.md)."""
    if not Face.of(fluid).has_poles:
        return 0
    if fluid.bessel_order is not None:
        return int(fluid.bessel_order)
    return mode_number(tube, alpha)


def validated_order(tube, alpha, fluid, n_layers, scheme="midpoint"):
    """Validate the public inputs (concrete values) and return the static Bessel order; ``alpha``
    None where a solver takes no α̂ of its own (the order is then resolved at α̂ = 1)."""
    require_x64()
    validate_tube(tube)
    validate_fluid(fluid)
    validate_layers(n_layers)
    validate_scheme(scheme)
    if alpha is None:
        return bessel_order(tube, 1.0, fluid)
    validate_alpha(alpha, tube=tube)
    return bessel_order(tube, alpha, fluid)


def family_of(m=0, torsional=False, fluid: Fluid | None = None) -> Family:
    """The static family of (m, torsional), validating concrete inputs (API.md, order m).

    Concrete m = 0: ``"longitudinal"`` (``"torsional"`` with ``torsional=True``); concrete m ≥ 1 or
    a traced m: ``"order_m"`` (``"torsional"`` with ``torsional=True``, NaN where m ≠ 0).

    Raises:
        ValueError: m not an integer ≥ 0 (naming m); ``torsional`` not a bool or True with m ≥ 1
            (naming torsional); the paper's coupling with m ≥ 1 (naming m).
    """
    if not isinstance(torsional, (bool, np.bool_)):
        raise ValueError(f"torsional must be True or False, got {torsional!r}")
    bad = f"m must be an integer >= 0 (the circumferential order), got {m!r}"
    if isinstance(m, (bool, np.bool_, str)):
        raise ValueError(bad)
    if isinstance(m, jax.core.Tracer):
        return Family.TORSIONAL if torsional else Family.ORDER_M
    try:
        value = np.asarray(m)
    except Exception as err:
        raise ValueError(bad) from err
    if (value.ndim or value.dtype == bool or not np.issubdtype(value.dtype, np.number)
            or np.iscomplexobj(value) or not np.isfinite(value) or value < 0
            or value != np.round(value)):
        raise ValueError(bad)
    if torsional and value != 0:
        raise ValueError(f"torsional=True exists only at m = 0 (the torsional family), got m = {m!r}")
    if Face.of(fluid).has_poles and value != 0:
        raise ValueError(f"the 'paper' coupling is axisymmetric: it needs m = 0, got m = {m!r}")
    if torsional:
        return Family.TORSIONAL
    return Family.LONGITUDINAL if value == 0 else Family.ORDER_M
