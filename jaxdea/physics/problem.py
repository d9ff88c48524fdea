"""What is solved: one static description of a problem, built and validated once.

A :class:`Problem` holds the static part of a case: its mode :class:`~jaxdea.physics.families.Family`
(longitudinal, order m, torsional; docs/theory/order_m.md §3), its inner
:class:`~jaxdea.physics.families.Face` (empty, acoustic, paper; docs/theory/axisymmetric.md §4) and the
static Bessel order ν of the paper's coupling (API.md). The traced part (tube, α̂, fluid, m) stays
with the caller. :func:`describe` validates the public inputs and builds it; every public solver
starts there. A Problem is hashable and compared by value, a static argument of ``jit``.
"""

import dataclasses

from .dispersion import check_inputs, mode_family
from .families import Face, Family


@dataclasses.dataclass(frozen=True)
class Problem:
    """The static description of a case: ``family``, inner ``face`` and Bessel ``order`` ν."""

    family: Family
    face: Face
    order: int

    def arguments(self, m) -> dict:
        """The keywords (m, family) of the family's programs (:meth:`Family.arguments`)."""
        return self.family.arguments(m)


def describe(tube, alpha, fluid, n_layers, scheme=None, m=0, torsional=False) -> Problem:
    """Validate the public inputs (concrete values) and describe the problem.

    ``alpha`` None where a solver takes no α̂ of its own (the Bessel order is then resolved at
    α̂ = 1). The family is that of (m, torsional): concrete m = 0 longitudinal, m ≥ 1 or a traced
    m order m, torsional with ``torsional=True``.

    Raises:
        ValueError: naming the parameter, for invalid concrete inputs (the tube, α̂, fluid,
            discretisation, m, torsional, and m ≥ 1 with the paper's coupling).
    """
    order = check_inputs(tube, alpha, fluid, n_layers, scheme)
    return Problem(Family(mode_family(m, torsional, fluid)), Face.of(fluid), order)
