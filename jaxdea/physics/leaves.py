"""Named parameters of a case (tube, α̂, fluid): what sweeps, branch tracing and sensitivity maps
vary. One place decides the names, their meaning and the order in which they are applied.

Names: the float fields of :class:`~jaxdea.Tube` (``voltage``, ``lambda_i``, ``lambda_z``, ``eta``,
``gent``, ``length_ratio``), of :class:`~jaxdea.Fluid` (``density_ratio``, ``speed_ratio``), of the
surrounding fluid ``tube.outer`` (``outer_density_ratio``, ``outer_speed_ratio``), ``alpha``
(α̂), ``n`` (axial mode number: α̂ = 2nπη/(length_ratio·λ_z), sweeps only) and ``thickness_ratio``
(deformed h/R_i at the tube's λ_i, λ_z, set through :func:`jaxdea.with_thickness_ratio`, i.e. by η).

Names of the wall (:func:`wall_names`, for a tube that has them): ``material_<field>``, a scalar
parameter of the tube's material object (``material_beta`` of ``MooneyRivlin``; ``material_alpha0``,
the first exponent of an ``Ogden``, whose μ_0 follows so that the term keeps its share μ_0α_0/2 of
the unit shear modulus); and per layer k
(0 the innermost, as ``tube.layers[k]``) ``layer<k>_fraction``, ``layer<k>_shear_ratio``,
``layer<k>_density_ratio`` (passive layers only: the active layer sets the units) and
``layer<k>_material_<field>``; and of the tube's damping law (``tube.damping``,
:func:`damping_names`) ``damping_<field>`` (``damping_viscosity``, ``damping_loss``) and
``damping_<field>_<i>`` for the i-th entry of a tuple field (``damping_moduli_0``,
``damping_times_1`` of ``Prony``). The fractions keep summing to 1: the active layer absorbs every
change, f_active = 1 − Σ f_passive, so its own fraction is not a name (a wall held at η: a thicker
encapsulation makes the dielectric thinner).

Order of application (so that a combination means what it says): tube leaves and the surrounding
fluid's, then ``thickness_ratio`` (h/R_i held at the final λ_i, λ_z), then fluid leaves, then ``alpha`` or ``n``
(α̂ of mode n of the final tube).
"""

import dataclasses
import re

from ..params import Fluid, Tube, as_float, mode_wavenumber
from .base_state import geometry, with_thickness_ratio_unchecked

TUBE_LEAVES = ("voltage", "lambda_i", "lambda_z", "eta", "gent", "length_ratio")
FLUID_LEAVES = ("density_ratio", "speed_ratio")
OUTER_LEAVES = ("outer_density_ratio", "outer_speed_ratio")
"""The surrounding fluid's leaves (``tube.outer``): ``outer_`` and the :class:`~jaxdea.Fluid` field."""
NAMES = (*TUBE_LEAVES, "thickness_ratio", *FLUID_LEAVES, *OUTER_LEAVES, "alpha", "n")
LAYER_LEAVES = ("fraction", "shear_ratio", "density_ratio")
"""The float fields of a :class:`~jaxdea.Layer` that a passive layer's names ``layer<k>_...`` set."""
_LAYER_NAME = re.compile(r"layer(\d+)_(.+)")


def material_fields(material) -> tuple:
    """The scalar parameters of a material object that are names (its ``parameter_names``: the
    fields holding one real number, and Ogden's exponents ``alpha<k>``, set at a fixed share
    μ_kα_k/2 of the shear modulus; a user's ``Energy`` params pytree is not); () for a static name."""
    if isinstance(material, str) or not hasattr(material, "parameter_names"):
        return ()
    return material.parameter_names()


def damping_fields(damping) -> dict:
    """{name: (field, index or None)} of a damping law's parameters (module docstring):
    ``damping_<field>`` of a scalar field, ``damping_<field>_<i>`` of entry i of a tuple field;
    {} for None."""
    if damping is None:
        return {}
    out = {}
    for f in dataclasses.fields(damping):
        value = getattr(damping, f.name)
        if isinstance(value, (tuple, list)):
            out.update({f"damping_{f.name}_{i}": (f.name, i) for i in range(len(value))})
        else:
            out[f"damping_{f.name}"] = (f.name, None)
    return out


def damping_names(damping) -> tuple:
    """The names of a damping law's parameters (:func:`damping_fields`), () for None."""
    return tuple(damping_fields(damping))


def with_damping(tube: Tube, values: dict) -> Tube:
    """The tube with the named damping parameters of ``values`` set (other names ignored)."""
    fields = damping_fields(tube.damping)
    changes = {}
    for name, value in values.items():
        if name in fields:
            field, index = fields[name]
            if index is None:
                changes[field] = value
            else:
                entries = list(changes.get(field, getattr(tube.damping, field)))
                entries[index] = value
                changes[field] = tuple(entries)
    if not changes:
        return tube
    return tube.replace(damping=dataclasses.replace(tube.damping, **changes))


def wall_names(tube: Tube | None) -> tuple:
    """The names of the wall's own parameters for this tube (module docstring): the tube's material
    object's, then each passive layer's and each layer's material's, then the damping law's."""
    if tube is None:
        return ()
    names = [f"material_{f}" for f in material_fields(tube.material)]
    for k, layer in enumerate(tube.layers or ()):
        if not layer.active:
            names += [f"layer{k}_{f}" for f in LAYER_LEAVES]
        names += [f"layer{k}_material_{f}" for f in material_fields(layer.material)]
    return tuple(names) + damping_names(getattr(tube, "damping", None))


def wall_hint(name, tube) -> str:
    """Why ``name`` is no parameter of this tube's wall, in words ('' when it is not a wall name)."""
    match = _LAYER_NAME.fullmatch(name)
    if name.startswith("damping_"):
        if tube is None or tube.damping is None:
            return " (damping_ names need a damping law, e.g. damping=jaxdea.Prony(...))"
        return (f" (the tube's {type(tube.damping).__name__} has the parameters "
                f"{', '.join(damping_names(tube.damping))})")
    if name.startswith("material_"):
        if tube is None or isinstance(tube.material, str):
            return " (material_ names need a material object on the tube, e.g. MooneyRivlin)"
        return f" (the tube's {type(tube.material).__name__} has no scalar parameter {name[9:]!r})"
    if match is None:
        return ""
    layers = () if tube is None else tube.layers or ()
    k = int(match.group(1))
    if not layers:
        return " (layer names need a layered wall, Tube(layers=...))"
    if k >= len(layers):
        return f" (the tube has {len(layers)} layers: k from 0 to {len(layers) - 1})"
    if layers[k].active and match.group(2) in LAYER_LEAVES:
        return (" (the active layer's fraction follows the others, 1 − Σ f_passive, and its "
                "ratios are 1: set a passive layer's)")
    return ""


def check_names(names, fluid: Fluid | None, allow_n: bool = True, tube: Tube | None = None) -> None:
    """Raise ValueError unless every name is a parameter that can be set for this case (the
    surrounding fluid's with a ``tube`` that has one)."""
    allowed = [n for n in NAMES if allow_n or n != "n"] + list(wall_names(tube))
    if fluid is None:
        allowed = [n for n in allowed if n not in FLUID_LEAVES]
    if tube is None or tube.outer is None:
        allowed = [n for n in allowed if n not in OUTER_LEAVES]
    for name in names:
        if name not in allowed:
            extra = " (fluid parameters need a Fluid)" if name in FLUID_LEAVES else ""
            if name in OUTER_LEAVES:
                extra = " (the surrounding fluid's parameters need outer=Fluid(...))"
            extra = extra or wall_hint(name, tube)
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
    if name.startswith("material_"):
        return as_float(tube.material.parameter(name.removeprefix("material_")))
    if name.startswith("damping_"):
        field, index = damping_fields(tube.damping)[name]
        value = getattr(tube.damping, field)
        return as_float(value if index is None else value[index])
    match = _LAYER_NAME.fullmatch(name)
    if match is not None:
        layer, field = tube.layers[int(match.group(1))], match.group(2)
        if field.startswith("material_"):
            return as_float(layer.material.parameter(field.removeprefix("material_")))
        return as_float(getattr(layer, field))
    if name == "alpha":
        return as_float(alpha)
    raise ValueError(f"cannot read parameter {name!r}")


def apply_parameters(tube: Tube, alpha, fluid: Fluid | None, values: dict):
    """(tube, alpha, fluid) with the named parameters set (module docstring for the order)."""
    tube = tube.replace(**{k: v for k, v in values.items() if k in TUBE_LEAVES})
    tube = with_wall(tube, values)
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


def with_wall(tube: Tube, values: dict) -> Tube:
    """The tube with the wall's named parameters of ``values`` set (:func:`wall_names`; other names
    ignored). A passive layer's new fraction is taken from the active layer: f_active = 1 − Σ
    f_passive."""
    tube = with_damping(tube, values)
    material = {k.removeprefix("material_"): v for k, v in values.items()
                if k.startswith("material_")}
    if material:
        tube = tube.replace(material=tube.material.with_parameters(**material))
    per_layer = {}
    for name, value in values.items():
        match = _LAYER_NAME.fullmatch(name)
        if match is not None:
            per_layer.setdefault(int(match.group(1)), {})[match.group(2)] = value
    if not per_layer:
        return tube
    layers = list(tube.layers)
    for k, changes in per_layer.items():
        material = {f.removeprefix("material_"): v for f, v in changes.items()
                    if f.startswith("material_")}
        fields = {f: v for f, v in changes.items() if not f.startswith("material_")}
        if material:
            fields["material"] = layers[k].material.with_parameters(**material)
        layers[k] = dataclasses.replace(layers[k], **fields)
    if any("fraction" in changes for changes in per_layer.values()):
        active = next(k for k, layer in enumerate(layers) if layer.active)
        passive = sum(as_float(layer.fraction) for layer in layers if not layer.active)
        layers[active] = dataclasses.replace(layers[active], fraction=1.0 - passive)
    return tube.replace(layers=tuple(layers))
