"""Named parameters of a case (tube, α̂, fluid): what sweeps, branch tracing and sensitivity maps
vary. One place decides the names, their meaning and the order in which they are applied.

Names: the float fields of :class:`~jaxdea.Tube` (``voltage``, ``lambda_i``, ``lambda_z``, ``eta``,
``gent``, ``length_ratio``), of :class:`~jaxdea.Fluid` (``density_ratio``, ``speed_ratio``), of the
surrounding fluid ``tube.outer`` (``outer_density_ratio``, ``outer_speed_ratio``), ``alpha``
(α̂), ``n`` (axial mode number: α̂ = 2nπη/(length_ratio·λ_z), sweeps only) and ``thickness_ratio``
(deformed h/R_i at the tube's λ_i, λ_z, set through :func:`jaxdea.with_thickness_ratio`, i.e. by η).

Order of application (so that a combination means what it says): tube leaves and the surrounding
fluid's, then ``thickness_ratio`` (h/R_i held at the final λ_i, λ_z), then fluid leaves, then ``alpha`` or ``n``
(α̂ of mode n of the final tube).
"""

from ..params import Fluid, Tube, as_float, mode_wavenumber
from .base_state import geometry, with_thickness_ratio_unchecked

TUBE_LEAVES = ("voltage", "lambda_i", "lambda_z", "eta", "gent", "length_ratio")
FLUID_LEAVES = ("density_ratio", "speed_ratio")
OUTER_LEAVES = ("outer_density_ratio", "outer_speed_ratio")
"""The surrounding fluid's leaves (``tube.outer``): ``outer_`` and the :class:`~jaxdea.Fluid` field."""
NAMES = (*TUBE_LEAVES, "thickness_ratio", *FLUID_LEAVES, *OUTER_LEAVES, "alpha", "n")


def check_names(names, fluid: Fluid | None, allow_n: bool = True, tube: Tube | None = None) -> None:
    """Raise ValueError unless every name is a parameter that can be set for this case (the
    surrounding fluid's with a ``tube`` that has one)."""
    allowed = [n for n in NAMES if allow_n or n != "n"]
    if fluid is None:
        allowed = [n for n in allowed if n not in FLUID_LEAVES]
    if tube is None or tube.outer is None:
        allowed = [n for n in allowed if n not in OUTER_LEAVES]
    for name in names:
        if name not in allowed:
            extra = " (fluid parameters need a Fluid)" if name in FLUID_LEAVES else ""
            if name in OUTER_LEAVES:
                extra = " (the surrounding fluid's parameters need outer=Fluid(...))"
            raise ValueError(f"unknown parameter {name!r}{extra}: allowed are {', '.join(allowed)}")
    if "alpha" in names and "n" in names:
        raise ValueError("give either 'alpha' or 'n' (the axial mode number), not both")
    if "eta" in names and "thickness_ratio" in names:
        raise ValueError("give either 'eta' or 'thickness_ratio' (both set the wall thickness), not both")


def get_parameter(tube: Tube, alpha, fluid: Fluid | None, name: str):
    """The current value of the named parameter (``n`` is not stored and cannot be read)."""
    if name in TUBE_LEAVES:
        return as_float(getattr(tube, name))
    if name in FLUID_LEAVES:
        return as_float(getattr(fluid, name))
    if name in OUTER_LEAVES:
        return as_float(getattr(tube.outer, name.removeprefix("outer_")))
    if name == "thickness_ratio":
        return geometry(tube).thickness
    if name == "alpha":
        return as_float(alpha)
    raise ValueError(f"cannot read parameter {name!r}")


def apply_parameters(tube: Tube, alpha, fluid: Fluid | None, values: dict):
    """(tube, alpha, fluid) with the named parameters set (module docstring for the order)."""
    tube = tube.replace(**{k: v for k, v in values.items() if k in TUBE_LEAVES})
    outer_values = {k.removeprefix("outer_"): v for k, v in values.items() if k in OUTER_LEAVES}
    if outer_values:
        tube = tube.replace(outer=tube.outer.replace(**outer_values))
    if "thickness_ratio" in values:
        tube = with_thickness_ratio_unchecked(tube, values["thickness_ratio"])
    fluid_values = {k: v for k, v in values.items() if k in FLUID_LEAVES}
    if fluid_values:
        fluid = fluid.replace(**fluid_values)
    if "alpha" in values:
        alpha = values["alpha"]
    if "n" in values:
        alpha = mode_wavenumber(tube, values["n"])
    return tube, alpha, fluid


def set_parameter(tube: Tube, alpha, fluid: Fluid | None, name: str, value):
    """(tube, alpha, fluid) with one named parameter set to ``value``."""
    return apply_parameters(tube, alpha, fluid, {name: value})
