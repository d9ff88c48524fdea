"""Configuration of ``jaxdea sweep``: a TOML or JSON document → validated sweep settings.

:func:`parse_config` is pure (a dict in, a :class:`SweepConfig` out) and checks every key and value
before anything is computed; an error is a ValueError that names the offending key (``tube.eta``,
``axes.voltage.num``, ``fluid.coupling``, ``units.density``, …) and what is allowed there. With a
``[units]`` table (the scales of :class:`jaxdea.physics.units.Scales`) parameters may also be given in SI
units under the names of :data:`jaxdea.studies.sweeps.SI_QUANTITIES` (``voltage_V``, ``wavelength_m``, …),
converted by :mod:`jaxdea.physics.units`, and the outputs carry SI values. :func:`load_config` reads the
file (by its suffix: ``.toml`` with :mod:`tomllib`, ``.json`` with :mod:`json`). :data:`FORMAT` lists
the keys (it is the reference printed by ``jaxdea sweep --help``); ``examples/sweep.toml`` is an
example.
"""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np

from ..files import load_document
from ..materials import DAMPING_KINDS, KINDS
from ..params import (
    COUPLINGS,
    MATERIALS,
    MAX_LAYERS,
    MAX_ROOTS,
    Layer,
    Tube,
    validate_material,
    validate_wall_layers,
)
from ..physics.leaves import (
    FLUID_LEAVES,
    LAYER_LEAVES,
    NAMES,
    OUTER_LEAVES,
    TUBE_LEAVES,
    wall_hint,
    wall_names,
)
from ..physics.transfer import SCHEMES
from ..physics.units import VACUUM_PERMITTIVITY, Scales
from ..studies.sweeps import MAX_POINTS, SENSITIVITY, SI_QUANTITIES, check_size

TOP_KEYS = ("tube", "fluid", "axes", "solver", "output", "units", "outer_fluid", "material",
            "layers", "damping")
LAYER_KEYS = ("fraction", "material", "shear_ratio", "density_ratio", "active")
"""The keys of a ``[[layers]]`` table (:class:`jaxdea.Layer`)."""
TUBE_KEYS = (*TUBE_LEAVES, "thickness_ratio", "material", "delta_p")
PRESSURE_SI_KEY = "pressure_Pa"  # [tube] ΔP in Pa (with [units]): delta_p = ΔP/μ
FLUID_KEYS = (*FLUID_LEAVES, "coupling", "bessel_order")
SI_NAMES = {si_name: name for name, (si_name, *_) in SI_QUANTITIES.items()}  # SI key -> parameter
TUBE_SI_KEYS = tuple(k for k, name in SI_NAMES.items() if name in TUBE_KEYS)
FLUID_SI_KEYS = tuple(k for k, name in SI_NAMES.items() if name in FLUID_KEYS)
OUTER_PRESETS = ("water", "air", "silicone_oil")
"""``outer_fluid.preset``: :data:`jaxdea.units.WATER`, :data:`~jaxdea.units.AIR`,
:data:`~jaxdea.units.SILICONE_OIL` (SI: needs [units])."""
UNITS_KEYS = {"shear_modulus": "Pa", "density": "kg/m^3", "permittivity": "F/m",
              "relative_permittivity": "ε/ε_0", "inner_radius": "m"}
SOLVER_KEYS = ("n_roots", "n_layers", "scheme", "jacobian", "omega_max", "m", "torsional",
               "n_growth")
AXIS_NAMES = (*NAMES, "m")
OUTPUT_KEYS = ("dir", "name", "formats", "plot", "title")
LINSPACE_KEYS = ("start", "stop", "num")
FORMATS = ("csv", "npz", "netcdf")
DEFAULT_FORMATS = ("csv", "npz")
SUFFIXES = {"csv": "csv", "npz": "npz", "netcdf": "nc"}  # output format -> file suffix

FORMAT = f"""\
[tube]    fixed parameters (numbers; defaults: those of jaxdea.Tube): voltage V̂, lambda_i λ_i,
          lambda_z λ_z, eta η = R_i/R_o or thickness_ratio h/R_i, gent G (inf: neo-Hookean),
          length_ratio L/R_o; material = {' | '.join(f'"{m}"' for m in MATERIALS)};
          delta_p ΔP̂ = ΔP/μ (or {PRESSURE_SI_KEY} in Pa with [units]): the tube held by this pressure
          difference, λ_i solved at every point (jaxdea.inner_stretch), instead of lambda_i
[material] optional, the wall's energy as an object: kind = {' | '.join(f'"{k}"' for k in KINDS)}
          and its parameters (mooney_rivlin: beta; gent: gent; gent_gent: gent, beta; ogden: mu = [...],
          alpha = [...]); instead of tube.material / tube.gent
[[layers]] optional, one table per layer from the inner face outwards (a layered wall, instead of
          [material]): fraction (share of the undeformed wall, the fractions sum to 1), material =
          {{kind = ..., ...}} (as [material]; default gent, G = 97.2), shear_ratio μ_k/μ and
          density_ratio ρ_k/ρ_s (default 1), active = true for exactly one layer (the dielectric)
[damping] optional, the wall's damping law (the tube's resonances are then complex: the outputs
          hold omega_k = Re Ω, omega_imag_k = Im Ω (time factor e^{{iΩt}}, Im Ω > 0 decays) and
          quality_factor_k = Re Ω/(2 Im Ω), from jaxdea.complex_frequencies; no jacobian, n_growth,
          delta_p): kind = {' | '.join(f'"{k}"' for k in DAMPING_KINDS)};
          prony: moduli = [g_k...] (units of μ, >= 0) and times = [τ_k...] (units of R_i/c_s,
          > 0), one length;
          fractional_kelvin_voigt: modulus, time, order (in (0, 1]), stretch_coupling;
          kelvin_voigt: viscosity (units of μR_i/c_s); hysteretic: loss. With [units] also in SI:
          moduli_Pa, times_s, modulus_Pa, time_s, viscosity_Pa_s. Not with [[layers]]
[fluid]   optional (leave it out for an empty tube): density_ratio ρ̂_f, speed_ratio ĉ_f (numbers),
          coupling = {' | '.join(f'"{c}"' for c in COUPLINGS)}, bessel_order = ν (integer >= 0; paper only,
          default ν = n)
[outer_fluid] optional (leave it out for a tube in vacuum): an unbounded fluid around the tube,
          density_ratio ρ̂_o, speed_ratio ĉ_o (numbers; or {', '.join(FLUID_SI_KEYS)} with [units]),
          or preset = {' | '.join(f'"{p}"' for p in OUTER_PRESETS)} (with [units])
[axes]    the grid, in order: NAME = [v1, v2, ...] | {{start = a, stop = b, num = k}} | v (fixed);
          NAME one of {', '.join((*TUBE_LEAVES, 'thickness_ratio'))},
          {', '.join((*FLUID_LEAVES, *OUTER_LEAVES, 'alpha', 'n'))}, m (circumferential orders,
          integers >= 0), the wall's material_<parameter> (material_beta) and, with [[layers]],
          layer<k>_fraction, layer<k>_shear_ratio, layer<k>_density_ratio of a passive layer k
          (from 0, the innermost; the active layer's fraction follows: 1 − Σ the others) and
          layer<k>_material_<parameter>; with [damping], damping_<parameter> (damping_viscosity,
          damping_loss) and damping_moduli_<k>, damping_times_<k> (prony branch k, from 0);
          exactly one of alpha (α̂) and n (axial mode numbers, integers >= 1); a parameter is fixed
          in [tube]/[fluid]/[solver] or swept here, not both; the plot's x axis is the first axis
          with more than one value
[solver]  n_roots = 3 (K lowest roots per point), n_layers = N (sublayers; default: chosen for 1e-8),
          scheme = "midpoint" | "magnus4" | "magnus6" (how a sublayer is crossed; default graded magnus6),
          jacobian = false | true | [names] (dΩ/dθ and dΩ/dα̂ too), omega_max = a number
          (default: automatic), m = 0 (circumferential order, integer >= 0; or axes.m),
          torsional = false (the torsional family, m = 0 only), n_growth = 0 (growth rates
          s = sqrt(-Ω²) of the unstable modes per point, largest first; 0: none)
[output]  name = the config file's stem, formats = {json.dumps(list(DEFAULT_FORMATS))} (any of
          {', '.join(FORMATS)}: NAME.csv, NAME.npz, NAME.nc; netcdf needs pip install 'jaxdea[xarray]'),
          plot = true (NAME.png), dir = a folder relative to the config file (default: the
          current folder; --out overrides), title = a plot title
[units]   optional SI scales (numbers > 0): shear_modulus μ (Pa), density ρ_s (kg/m³),
          permittivity ε (F/m) or relative_permittivity ε/ε_0, inner_radius R_i (m). With them,
          {', '.join(TUBE_SI_KEYS)} in [tube]/[axes], {', '.join(FLUID_SI_KEYS)} in
          [fluid]/[axes] and wavelength_m (2π R_i/α̂) in [axes] replace the dimensionless names,
          and the outputs add frequency_Hz, wavelength_m and the SI value of each such axis
"""

# allowed values of each parameter: (description, test on a float64 array); +inf only for gent
RANGES = {
    "voltage": ("a finite number", lambda v: np.isfinite(v)),
    "lambda_i": ("a finite number > 0", lambda v: np.isfinite(v) & (v > 0)),
    "lambda_z": ("a finite number > 0", lambda v: np.isfinite(v) & (v > 0)),
    "eta": ("in the open interval (0, 1)", lambda v: (v > 0) & (v < 1)),
    "gent": ("> 0 (inf for neo-Hookean)", lambda v: v > 0),
    "length_ratio": ("a finite number > 0", lambda v: np.isfinite(v) & (v > 0)),
    "thickness_ratio": ("a finite number > 0", lambda v: np.isfinite(v) & (v > 0)),
    "delta_p": ("a finite number (ΔP̂ = ΔP/μ)", lambda v: np.isfinite(v)),
    "density_ratio": ("a finite number > 0", lambda v: np.isfinite(v) & (v > 0)),
    "speed_ratio": ("a finite number > 0", lambda v: np.isfinite(v) & (v > 0)),
    "outer_density_ratio": ("a finite number > 0", lambda v: np.isfinite(v) & (v > 0)),
    "outer_speed_ratio": ("a finite number > 0", lambda v: np.isfinite(v) & (v > 0)),
    "alpha": ("a finite number > 0", lambda v: np.isfinite(v) & (v > 0)),
    "n": ("integers >= 1 (axial mode numbers)", lambda v: np.isfinite(v) & (v >= 1) & (v == np.round(v))),
    "m": ("integers >= 0 (circumferential orders)",
          lambda v: np.isfinite(v) & (v >= 0) & (v == np.round(v))),
    "voltage_V": ("a finite number (V)", lambda v: np.isfinite(v)),
    "thickness_m": ("a finite number > 0 (m)", lambda v: np.isfinite(v) & (v > 0)),
    "fluid_density_kg_m3": ("a finite number > 0 (kg/m^3)", lambda v: np.isfinite(v) & (v > 0)),
    "sound_speed_m_s": ("a finite number > 0 (m/s)", lambda v: np.isfinite(v) & (v > 0)),
    "wavelength_m": ("a finite number > 0 (m)", lambda v: np.isfinite(v) & (v > 0)),
}


@dataclasses.dataclass(frozen=True)
class SweepConfig:
    """Validated settings of ``jaxdea sweep``.

    Attributes:
        tube: keyword arguments of :class:`jaxdea.Tube` (only the keys given; ``material`` a
            material object from ``[material]``, ``layers`` the :class:`jaxdea.Layer` of
            ``[[layers]]``).
        fluid: keyword arguments of :class:`jaxdea.Fluid`, or None for an empty tube.
        outer: keyword arguments of the surrounding :class:`jaxdea.Fluid` (``Tube(outer=...)``),
            or None for a tube in vacuum.
        axes: ``{name: 1-D float64 array}`` in grid order (a fixed ``tube.thickness_ratio`` comes
            last, as an axis of length 1).
        n_roots: K, roots per point.
        n_layers: sublayers N, or None (the default discretisation, chosen for 1e-8).
        scheme: the propagation scheme (``jaxdea.sweep``'s ``scheme``), or None.
        jacobian: False, True or a tuple of parameter names (``jaxdea.sweep``'s ``jacobian``).
        omega_max: upper end of each root search, or None (automatic).
        m: the fixed circumferential order (``jaxdea.sweep``'s ``m``; an axis ``m`` instead is in
            ``axes``).
        torsional: the torsional family (m = 0 only).
        n_growth: growth rates per point (``jaxdea.sweep``'s ``n_growth``; 0: none).
        delta_p: ΔP̂ = ΔP/μ of a pressure-held tube (``jaxdea.sweep``'s ``delta_p``: λ_i solved at
            every point), or None (held by its stretch λ_i).
        units: the SI scales ``{shear_modulus, density, permittivity, inner_radius}`` of the
            ``[units]`` table, or None.
        out_dir: output folder as written in the config (relative to the config file), or None.
        name: file stem of the outputs.
        formats: a subset of ("csv", "npz", "netcdf").
        plot: write ``name.png``.
        title: plot title, or None.
    """

    tube: dict
    fluid: dict | None
    axes: dict
    outer: dict | None = None
    n_roots: int = 3
    n_layers: int | None = None
    scheme: str | None = None
    jacobian: bool | tuple = False
    omega_max: float | None = None
    m: int = 0
    torsional: bool = False
    n_growth: int = 0
    delta_p: float | None = None
    units: dict | None = None
    out_dir: str | None = None
    name: str = "sweep"
    formats: tuple = DEFAULT_FORMATS
    plot: bool = True
    title: str | None = None

    @property
    def plot_axis(self) -> str:
        """The plot's abscissa: the first axis with more than one value (else the first axis)."""
        return next((k for k, v in self.axes.items() if v.size > 1), next(iter(self.axes)))

    @property
    def scales(self) -> Scales | None:
        """The :class:`jaxdea.physics.units.Scales` of ``[units]``, or None."""
        return None if self.units is None else Scales(**self.units)

    def sweep_arguments(self) -> dict:
        """Keyword arguments of :func:`jaxdea.sweep` besides ``tube`` and ``fluid``."""
        orders = {}
        if self.m or "m" in self.axes:  # m = 0 passes nothing: sweep's default, as before
            orders["m"] = self.axes.get("m", self.m)
        if self.torsional:
            orders["torsional"] = True
        if self.n_growth:
            orders["n_growth"] = self.n_growth
        if self.delta_p is not None:  # None passes nothing: sweep's default, as before
            orders["delta_p"] = self.delta_p
        axes = {k: v for k, v in self.axes.items() if k != "m"}
        return dict(n_roots=self.n_roots, n_layers=self.n_layers, scheme=self.scheme,
                    jacobian=self.jacobian if self.jacobian else None, omega_max=self.omega_max,
                    **orders, **axes)


def _fail(message: str):
    raise ValueError(f"sweep config: {message}")


def _table(data, key: str, allowed: tuple) -> dict:
    """The table at ``key`` (a dict), with every key in ``allowed``."""
    if not isinstance(data, dict):
        _fail(f"{key!r} must be a table (key = value pairs), got {data!r}" if key
              else f"the document must be a table (key = value pairs), got {type(data).__name__}")
    for k in data:
        if k not in allowed:
            _fail(f"unknown key '{f'{key}.{k}' if key else k}'; allowed: {', '.join(allowed)}")
    return data


def _is_number(x) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool)


def _integer(key: str, x, low: int, high: int | None = None, limit: str = "") -> int:
    if not isinstance(x, int) or isinstance(x, bool) or x < low:
        _fail(f"{key!r} must be an integer >= {low}, got {x!r}")
    if high is not None and x > high:
        _fail(f"{key!r} must be <= {limit} = {high:,}, got {x:,}")
    return int(x)


def _choice(key: str, x, allowed: tuple) -> str:
    if x not in allowed:
        _fail(f"{key!r} must be one of {', '.join(allowed)}, got {x!r}")
    return x


def _values(key: str, name: str, spec) -> np.ndarray:
    """An axis (or a fixed value) as a 1-D float64 array, checked against RANGES[name]."""
    if isinstance(spec, dict):
        _table(spec, key, LINSPACE_KEYS)
        for k in LINSPACE_KEYS:
            if k not in spec:
                _fail(f"{key!r} as a linspace needs start, stop and num; '{key}.{k}' is missing")
        for k in ("start", "stop"):
            if not _is_number(spec[k]) or not math.isfinite(spec[k]):
                _fail(f"'{key}.{k}' must be a finite number, got {spec[k]!r}")
        values = np.linspace(spec["start"], spec["stop"], _integer(f"{key}.num", spec["num"], 1))
    elif isinstance(spec, list):
        if not spec:
            _fail(f"{key!r} is an empty list; give at least one value")
        for i, x in enumerate(spec):
            if not _is_number(x):
                _fail(f"'{key}[{i}]' must be a number, got {x!r}")
        values = np.asarray(spec, dtype=np.float64)
    elif _is_number(spec):
        values = np.asarray([spec], dtype=np.float64)
    else:
        _fail(f"{key!r} must be a number, a list of numbers or a table {{start, stop, num}}, "
              f"got {spec!r}")
    return _in_range(key, name, values)


def _length(spec) -> int:
    """The number of values an axis spec gives (1 where it is malformed: :func:`_values` says why)."""
    if isinstance(spec, list):
        return max(len(spec), 1)
    if isinstance(spec, dict) and isinstance(spec.get("num"), int) and not isinstance(spec["num"], bool):
        return max(spec["num"], 1)
    return 1


def _range(name: str) -> tuple:
    """(description, test) of a parameter's allowed values: :data:`RANGES`, or for the wall's names
    (:func:`jaxdea.physics.leaves.wall_names`) by their field."""
    if name in RANGES:
        return RANGES[name]
    field = name.split("_", 1)[1]  # after layer<k>_ or material_
    if field == "fraction":
        return ("in the open interval (0, 1)", lambda v: (v > 0) & (v < 1))
    if field in LAYER_LEAVES or field.endswith("gent"):
        return RANGES["lambda_i"]  # a finite number > 0
    return RANGES["voltage"]  # a finite number (a material's own range: NaN points in the sweep)


def _in_range(key: str, name: str, values: np.ndarray, converted: bool = False) -> np.ndarray:
    allowed, ok = _range(name)
    bad = ~ok(values)
    if np.any(bad):
        value = float(values[bad][0])
        if converted:
            _fail(f"{key!r} gives {name} = {value!r}, which must be {allowed}")
        _fail(f"{key!r} must be {allowed}, got {value!r}")
    return values


def _si_values(key: str, si_key: str, spec, units: dict | None) -> np.ndarray:
    """An axis or fixed value given in SI units (``si_key``), converted by jaxdea.physics.units."""
    name = SI_NAMES[si_key]
    if units is None:
        _fail(f"{key!r} is in SI units ({SI_QUANTITIES[name][1]}): add a [units] table "
              "(shear_modulus, density, permittivity, inner_radius) or give "
              f"'{key.rsplit('.', 1)[0]}.{name}' (dimensionless)")
    values = _values(key, si_key, spec)
    converted = np.asarray(SI_QUANTITIES[name][3](Scales(**units), values), dtype=np.float64)
    return _in_range(key, name, converted, converted=True)


def _fixed(key: str, name: str, x, units: dict | None = None) -> float:
    if not _is_number(x):
        _fail(f"{key!r} must be a number, got {x!r}")
    if name in SI_NAMES:
        return float(_si_values(key, name, x, units)[0])
    return float(_values(key, name, x)[0])


def _parameter(table: str, key: str, seen: dict) -> str:
    """The parameter that ``table.key`` sets (an SI key sets its dimensionless parameter); each
    parameter once per table."""
    name = SI_NAMES.get(key, key)
    if name in seen:
        _fail(f"'{table}.{seen[name]}' and '{table}.{key}' set the same parameter ({name}); "
              "give one of them")
    seen[name] = key
    return name


def _parse_units(data) -> dict | None:
    """The [units] table as the fields of :class:`jaxdea.physics.units.Scales` (SI), or None."""
    if "units" not in data:
        return None
    table = _table(data["units"], "units", tuple(UNITS_KEYS))
    for k, v in table.items():
        if not _is_number(v) or not (math.isfinite(v) and v > 0):
            _fail(f"'units.{k}' must be a finite number > 0 ({UNITS_KEYS[k]}), got {v!r}")
    if "permittivity" in table and "relative_permittivity" in table:
        _fail("give either 'units.permittivity' (F/m) or 'units.relative_permittivity', not both")
    if "relative_permittivity" in table:
        table = {**table, "permittivity": table["relative_permittivity"] * VACUUM_PERMITTIVITY}
    for k in ("shear_modulus", "density", "permittivity", "inner_radius"):
        if k not in table:
            _fail(f"'units.{k}' is missing ({UNITS_KEYS[k]}); [units] needs shear_modulus, density, "
                  "permittivity (or relative_permittivity) and inner_radius")
    return {k: float(table[k]) for k in ("shear_modulus", "density", "permittivity", "inner_radius")}


def _parse_tube(data, units: dict | None = None) -> dict:
    tube, seen = {}, {}
    for k, v in _table(data, "tube", (*TUBE_KEYS, *TUBE_SI_KEYS, PRESSURE_SI_KEY)).items():
        if k == PRESSURE_SI_KEY:  # ΔP in Pa -> ΔP̂ = ΔP/μ
            if "delta_p" in seen:
                _fail(f"'tube.delta_p' and 'tube.{k}' set the same parameter (delta_p); give one")
            if units is None:
                _fail(f"'tube.{k}' is in SI units (Pa): add a [units] table (shear_modulus, "
                      "density, permittivity, inner_radius) or give 'tube.delta_p' (ΔP/μ)")
            if not _is_number(v) or not math.isfinite(v):
                _fail(f"'tube.{k}' must be a finite number (Pa), got {v!r}")
            seen["delta_p"] = k
            tube["delta_p"] = float(v) / units["shear_modulus"]
            continue
        name = _parameter("tube", k, seen)
        tube[name] = (_choice("tube.material", v, MATERIALS) if k == "material"
                      else _fixed(f"tube.{k}", k, v, units))
    if "eta" in tube and "thickness_ratio" in tube:
        _fail("give either 'tube.eta' or 'tube.thickness_ratio' (both set the wall thickness)")
    return tube


def _wrong(message: str):
    raise ValueError(message)


def _known_keys(table: dict, key: str, allowed: tuple) -> None:
    for k in table:
        if k not in allowed:
            _wrong(f"unknown key '{key}.{k}'; allowed: {', '.join(allowed)}")


def _kind(key: str, table, kinds: dict, listed: str | None = None) -> str:
    """The ``kind`` of a ``{kind = ..., parameter = value, ...}`` table, one of ``kinds``
    (ValueError naming ``key`` otherwise)."""
    quoted = ", ".join(f'"{k}"' for k in kinds)
    if not isinstance(table, dict):
        _wrong(f"{key!r} must be a table {{kind = {quoted}, parameters...}}, got {table!r}")
    if "kind" not in table:
        _wrong(f"'{key}.kind' is missing: one of {quoted}")
    kind = table["kind"]
    if kind not in kinds:
        _wrong(f"'{key}.kind' must be one of {quoted if listed is None else listed}, got {kind!r}")
    return kind


def material_from_table(key: str, table) -> object:
    """A material object of :data:`jaxdea.materials.KINDS` from a table ``{kind = ..., parameter =
    value, ...}`` (missing parameters: the class defaults), checked by
    :func:`jaxdea.params.validate_material` (finite, normalised to unit shear modulus).

    Raises:
        ValueError: naming ``key`` (``material``, ``layers[1].material``, …) and what is allowed
            (without the prefix of :func:`parse_config`: the fit configuration reads it too).
    """
    kind = _kind(key, table, KINDS, ", ".join(KINDS))
    fields = tuple(f.name for f in dataclasses.fields(KINDS[kind]))
    _known_keys(table, key, ("kind", *fields))
    params = {}
    for k in fields:
        if k not in table:
            continue
        v = table[k]
        if kind == "ogden":  # tuples of one length
            if not isinstance(v, list) or not v or not all(_is_number(x) for x in v):
                _wrong(f"'{key}.{k}' must be a non-empty list of numbers, got {v!r}")
            params[k] = tuple(float(x) for x in v)
        elif not _is_number(v):
            _wrong(f"'{key}.{k}' must be a number, got {v!r}")
        else:
            params[k] = float(v)
    material = KINDS[kind](**params)
    try:
        validate_material(material)
    except ValueError as exc:
        _wrong(f"{key!r}: {exc}")
    return material


def layers_from_tables(data) -> tuple:
    """The ``[[layers]]`` array of tables as a tuple of :class:`jaxdea.Layer`, validated as a wall
    (exactly one active, fractions > 0 summing to 1, the active layer's ratios 1).

    Raises:
        ValueError: naming the key (``layers[1].active``, …), as :func:`material_from_table`.
    """
    if not isinstance(data, list) or not data or not all(isinstance(x, dict) for x in data):
        _wrong(f"'layers' must be an array of tables ([[layers]], one per layer from the inner face "
              f"outwards), got {data!r}")
    layers = []
    for k, table in enumerate(data):
        key = f"layers[{k}]"
        _known_keys(table, key, LAYER_KEYS)
        if "fraction" not in table:
            _wrong(f"'{key}.fraction' is missing (the layer's share of the undeformed wall)")
        values = {}
        for name in ("fraction", "shear_ratio", "density_ratio"):
            if name in table:
                v = table[name]
                if not _is_number(v) or not (math.isfinite(v) and v > 0):
                    _wrong(f"'{key}.{name}' must be a finite number > 0, got {v!r}")
                values[name] = float(v)
        if "active" in table:
            if not isinstance(table["active"], bool):
                _wrong(f"'{key}.active' must be true or false, got {table['active']!r}")
            values["active"] = table["active"]
        if "material" in table:
            values["material"] = material_from_table(f"{key}.material", table["material"])
        layers.append(Layer(**values))
    try:
        validate_wall_layers(Tube(layers=tuple(layers)))
    except ValueError as exc:
        _wrong(str(exc))
    return tuple(layers)


DAMPING_KEYS = {"prony": ("moduli", "times"),
                "fractional_kelvin_voigt": ("modulus", "time", "order", "stretch_coupling"),
                "kelvin_voigt": ("viscosity",), "hysteretic": ("loss",)}
"""The parameters of each ``[damping]`` kind (dimensionless: units of μ and R_i/c_s)."""
DAMPING_SI = {"moduli": ("moduli_Pa", "Pa"), "times": ("times_s", "s"),
              "modulus": ("modulus_Pa", "Pa"), "time": ("time_s", "s"),
              "viscosity": ("viscosity_Pa_s", "Pa s")}
"""The SI key of a ``[damping]`` parameter (with ``[units]``) and its unit."""
DAMPING_RANGES = {"moduli": ("numbers >= 0", lambda v: v >= 0),
                  "times": ("numbers > 0", lambda v: v > 0),
                  "modulus": ("a number >= 0", lambda v: v >= 0),
                  "time": ("a number > 0", lambda v: v > 0),
                  "order": ("a number in (0, 1]", lambda v: 0 < v <= 1),
                  "stretch_coupling": ("a finite number", lambda v: True),
                  "viscosity": ("a number >= 0", lambda v: v >= 0),
                  "loss": ("a number >= 0", lambda v: v >= 0)}


def damping_from_table(key: str, table, units: dict | None = None) -> object:
    """A damping law of :data:`jaxdea.materials.DAMPING_KINDS` from a table ``{kind = ...,
    parameter = value, ...}`` (missing parameters: the class defaults; Prony's moduli and times
    both). Parameters in units of μ (moduli), R_i/c_s (times) and μR_i/c_s (viscosity), or with
    ``units`` (the SI scales of ``[units]``) in SI under :data:`DAMPING_SI`'s keys: g = G/μ,
    τ = t c_s/R_i, η_v = η c_s/(μ R_i), c_s = sqrt(μ/ρ_s).

    Raises:
        ValueError: naming ``key.<parameter>`` (``damping.times``) and what is allowed: an unknown
            kind or key, a value out of range, Prony's moduli and times of different lengths, an
            SI key without ``[units]``.
    """
    kind = _kind(key, table, DAMPING_KINDS)
    fields = DAMPING_KEYS[kind]
    si = {DAMPING_SI[f][0]: f for f in fields if f in DAMPING_SI}
    _known_keys(table, key, ("kind", *fields, *si))
    time = None if units is None else units["inner_radius"] * math.sqrt(
        units["density"] / units["shear_modulus"])  # R_i/c_s in s
    params = {}
    for k, v in table.items():
        if k == "kind":
            continue
        field = si.get(k, k)
        if field in params:
            _wrong(f"'{key}.{k}' and '{key}.{DAMPING_SI[field][0] if k == field else field}' set "
                   f"the same parameter; give one")
        if k in si and units is None:
            _wrong(f"'{key}.{k}' is in SI units ({DAMPING_SI[field][1]}): add a [units] table or "
                   f"give '{key}.{field}' (dimensionless)")
        many = field in ("moduli", "times")
        values = v if many else [v]
        if (many and (not isinstance(v, list) or not v)) or not all(
                _is_number(x) and math.isfinite(x) for x in values):
            wanted = "a non-empty list of finite numbers" if many else "a finite number"
            _wrong(f"'{key}.{k}' must be {wanted}, got {v!r}")
        values = [float(x) for x in values]
        if k in si:  # SI -> units of μ, R_i/c_s
            factor = {"Pa": units["shear_modulus"], "s": time,
                      "Pa s": units["shear_modulus"] * time}[DAMPING_SI[field][1]]
            values = [x / factor for x in values]
        allowed, ok = DAMPING_RANGES[field]
        if not all(ok(x) for x in values):
            _wrong(f"'{key}.{k}' must be {allowed}, got {v!r}")
        params[field] = tuple(values) if many else values[0]
    if kind == "prony":
        for field in fields:
            if field not in params:
                _wrong(f"'{key}.{field}' is missing (prony needs moduli and times, one length)")
        if len(params["moduli"]) != len(params["times"]):
            _wrong(f"'{key}.times' must have as many entries as '{key}.moduli' "
                   f"({len(params['times'])} and {len(params['moduli'])})")
    return DAMPING_KINDS[kind](**params)


def _parse_wall(data, tube: dict) -> None:
    """``[material]`` or ``[[layers]]`` into ``tube`` (its ``material`` or ``layers``)."""
    energy = [f"'tube.{k}'" for k in ("material", "gent") if k in tube]
    for table in ("material", "layers"):
        if table in data and energy:
            _fail(f"'{table}' and {' and '.join(energy)} both set the wall's energy; give one")
    if "material" in data and "layers" in data:
        _fail("'material' and 'layers' both set the wall's energy; with [[layers]] give each layer "
              "its material")
    try:
        if "material" in data:
            tube["material"] = material_from_table("material", data["material"])
        if "layers" in data:
            tube["layers"] = layers_from_tables(data["layers"])
    except ValueError as exc:
        _fail(str(exc))


def _parse_fluid(data, units: dict | None = None) -> dict:
    fluid, seen = {}, {}
    for k, v in _table(data, "fluid", (*FLUID_KEYS, *FLUID_SI_KEYS)).items():
        name = _parameter("fluid", k, seen)
        if k == "coupling":
            fluid[k] = _choice("fluid.coupling", v, COUPLINGS)
        elif k == "bessel_order":
            fluid[k] = None if v is None else _integer("fluid.bessel_order", v, 0)
        else:
            fluid[name] = _fixed(f"fluid.{k}", k, v, units)
    return fluid


def _parse_outer(data, units: dict | None = None) -> dict:
    """The [outer_fluid] table as the fields of the surrounding :class:`jaxdea.Fluid`."""
    outer, seen = {}, {}
    table = _table(data, "outer_fluid", (*FLUID_LEAVES, *FLUID_SI_KEYS, "preset"))
    if "preset" in table:
        preset = _choice("outer_fluid.preset", table.pop("preset"), OUTER_PRESETS)
        if table:
            _fail(f"'outer_fluid.preset' sets the whole fluid: remove 'outer_fluid.{next(iter(table))}'")
        if units is None:
            _fail("'outer_fluid.preset' is in SI units: add a [units] table (shear_modulus, density, "
                  "permittivity, inner_radius)")
        from ..physics import units as si

        fluid = si.fluid_from_si(Scales(**units), getattr(si, preset.upper()))
        return {k: float(getattr(fluid, k)) for k in FLUID_LEAVES}
    for k, v in table.items():
        name = _parameter("outer_fluid", k, seen)
        outer[name] = _fixed(f"outer_fluid.{k}", k, v, units)
    for k in FLUID_LEAVES:
        if k not in outer:
            _fail(f"'outer_fluid.{k}' is missing: give density_ratio and speed_ratio (or a preset)")
    return outer


def _parse_axes(data, tube: dict, fluid: dict | None, units: dict | None = None,
                outer: dict | None = None, wall: Tube | None = None) -> dict:
    if "axes" not in data:
        _fail("missing table 'axes' (the sweep grid, e.g. n = [1, 2, 3])")
    for key in data["axes"] if isinstance(data["axes"], dict) else ():
        if key not in wall_names(wall) and wall_hint(key, wall):
            _fail(f"'axes.{key}' is no parameter of this wall{wall_hint(key, wall)}")
    table = _table(data["axes"], "axes", (*AXIS_NAMES, *wall_names(wall), *SI_NAMES))
    if not table:
        _fail("'axes' is empty: give the wavenumber axis 'alpha' (α̂) or 'n' (axial mode numbers)")
    axes, seen, points = {}, {}, 1
    for key, spec in table.items():
        name = _parameter("axes", key, seen)
        points *= _length(spec)
        if points > MAX_POINTS:  # before the axis is built
            _fail(f"the grid has {points:,} points up to 'axes.{key}'; a sweep takes at most "
                  f"MAX_POINTS = {MAX_POINTS:,}: split it into several sweeps")
        if name in FLUID_LEAVES and fluid is None:
            _fail(f"'axes.{key}' is a fluid parameter: add a [fluid] table")
        if name in OUTER_LEAVES and outer is None:
            _fail(f"'axes.{key}' is a parameter of the surrounding fluid: add an [outer_fluid] table")
        given = f"'tube.{name}'" if name in tube else (f"'fluid.{name}'" if name in (fluid or {}) else "")
        if given:
            _fail(f"{given} is also a sweep axis ('axes.{key}'); give it in one place")
        axes[name] = (_si_values(f"axes.{key}", key, spec, units) if key in SI_NAMES
                      else _values(f"axes.{key}", key, spec))
    if ("alpha" in axes) == ("n" in axes):
        _fail("'axes' needs exactly one wavenumber axis: 'alpha' (α̂) or 'n' (axial mode numbers)"
              + (", not both" if "alpha" in axes else ""))
    thickness = [f"'{where}.{k}'" for where, keys in (("tube", tube), ("axes", axes))
                 for k in ("eta", "thickness_ratio") if k in keys]
    if len(thickness) > 1:
        _fail(f"{' and '.join(thickness)} both set the wall thickness; give one of them")
    if "thickness_ratio" in tube:  # h/R_i held at every point (applied after λ_i, λ_z)
        axes["thickness_ratio"] = np.asarray([tube.pop("thickness_ratio")])
    return axes


def _parse_solver(data, fluid: dict | None, outer: dict | None = None, wall: tuple = ()) -> dict:
    table = _table(data.get("solver", {}), "solver", SOLVER_KEYS)
    out = {}
    for k, high in (("n_roots", MAX_ROOTS), ("n_layers", MAX_LAYERS)):
        if k in table:
            out[k] = _integer(f"solver.{k}", table[k], 1, high, f"MAX_{k[2:].upper()}")
    if "scheme" in table:
        out["scheme"] = _choice("solver.scheme", table["scheme"], tuple(SCHEMES))
    if "m" in table:
        out["m"] = _integer("solver.m", table["m"], 0)
    if "n_growth" in table:
        out["n_growth"] = _integer("solver.n_growth", table["n_growth"], 0, MAX_ROOTS, "MAX_ROOTS")
    if "torsional" in table:
        if not isinstance(table["torsional"], bool):
            _fail(f"'solver.torsional' must be true or false, got {table['torsional']!r}")
        out["torsional"] = table["torsional"]
    if "omega_max" in table:
        v = table["omega_max"]
        if not _is_number(v) or not (math.isfinite(v) and v > 0):
            _fail(f"'solver.omega_max' must be a finite number > 0, got {v!r}")
        out["omega_max"] = float(v)
    if "jacobian" in table:
        jac = table["jacobian"]
        allowed = [n for n in NAMES if n not in ("alpha", "n")
                   and (fluid is not None or n not in FLUID_LEAVES)
                   and (outer is not None or n not in OUTER_LEAVES)] + list(wall)
        if isinstance(jac, list):
            for i, name in enumerate(jac):
                if name not in allowed:
                    _fail(f"'solver.jacobian[{i}]' = {name!r} is no parameter of this case; "
                          f"allowed: {', '.join(allowed)}")
            if len(set(jac)) != len(jac):
                _fail(f"'solver.jacobian' repeats a name: {jac}")
            jac = tuple(jac)
        elif not isinstance(jac, bool):
            _fail(f"'solver.jacobian' must be true, false or a list of parameter names "
                  f"({', '.join(allowed)}), got {jac!r}")
        out["jacobian"] = jac
    return out


def _parse_output(data, default_name: str) -> dict:
    table = _table(data.get("output", {}), "output", OUTPUT_KEYS)
    out = {"name": default_name}
    for k in ("dir", "name", "title"):
        if k in table:
            v = table[k]
            if not isinstance(v, str) or not v or (k == "name" and ("/" in v or "\\" in v)):
                what = "a file stem without folders" if k == "name" else "a non-empty string"
                _fail(f"'output.{k}' must be {what}, got {v!r}")
            out["out_dir" if k == "dir" else k] = v
    if "formats" in table:
        formats = table["formats"]
        if not isinstance(formats, list):
            _fail(f"'output.formats' must be a list of {', '.join(FORMATS)}, got {formats!r}")
        for i, f in enumerate(formats):
            _choice(f"output.formats[{i}]", f, FORMATS)
        out["formats"] = tuple(dict.fromkeys(formats))
    if "plot" in table:
        if not isinstance(table["plot"], bool):
            _fail(f"'output.plot' must be true or false, got {table['plot']!r}")
        out["plot"] = table["plot"]
    if not out.get("formats", DEFAULT_FORMATS) and not out.get("plot", True):
        _fail("'output.formats' is empty and 'output.plot' is false: nothing would be written")
    return out


def parse_config(data, default_name: str = "sweep") -> SweepConfig:
    """Validate a sweep configuration (the parsed TOML/JSON document).

    Args:
        data: the document as a dict (tables ``tube``, ``material``, ``layers`` (an array of
            tables), ``fluid``, ``axes``, ``solver``, ``output``, ``units``; :data:`FORMAT` shows
            them all).
        default_name: file stem of the outputs when ``output.name`` is absent.

    Returns:
        An instance of :class:`SweepConfig`.

    Raises:
        ValueError: "sweep config: …" naming the offending key and what is allowed there.
    """
    _table(data, "", TOP_KEYS)
    units = _parse_units(data)
    tube = _parse_tube(data.get("tube", {}), units)
    if "damping" in data and "layers" in data:
        _fail("'damping' with [[layers]]: a layered wall's damping is its layers', which the "
              "sweep config does not take yet; give [damping] with a one-material wall")
    _parse_wall(data, tube)
    if "damping" in data:
        try:
            tube["damping"] = damping_from_table("damping", data["damping"], units)
        except ValueError as exc:
            _fail(str(exc))
    delta_p = tube.pop("delta_p", None)
    fixed = set(tube)  # before a fixed thickness_ratio moves to the axes
    fluid = _parse_fluid(data["fluid"], units) if "fluid" in data else None
    outer = _parse_outer(data["outer_fluid"], units) if "outer_fluid" in data else None
    wall = Tube(material=tube.get("material", "gent"), layers=tube.get("layers"),
                damping=tube.get("damping"))
    axes = _parse_axes(data, tube, fluid, units, outer, wall)
    solver = _parse_solver(data, fluid, outer, wall_names(wall))
    if "damping" in tube:
        for name, given in (("solver.jacobian", solver.get("jacobian")),
                            ("solver.n_growth", solver.get("n_growth")),
                            ("tube.delta_p", delta_p is not None)):
            if given:
                _fail(f"'{name}' with [damping] is not supported (a damped tube's sweep gives its "
                      "complex roots alone): remove one of them")
    if delta_p is not None:
        held = "'tube.delta_p'" if "delta_p" in data.get("tube", {}) else f"'tube.{PRESSURE_SI_KEY}'"
        for where, keys in (("tube", fixed), ("axes", set(axes) - fixed)):
            for k in ("lambda_i", "thickness_ratio"):
                if k in keys:
                    _fail(f"{held} holds the tube by pressure, so λ_i follows from it at every "
                          f"point: remove '{where}.{k}' (give the wall as eta, R_i/R_o undeformed)")
        if solver.get("jacobian"):
            _fail(f"'solver.jacobian' with {held} is not supported (derivatives at fixed λ_i, not "
                  "at fixed pressure): remove one of them")
    if "m" in axes and "m" in solver:
        _fail("'solver.m' is also a sweep axis ('axes.m'); give it in one place")
    orders = axes["m"] if "m" in axes else np.asarray([solver.get("m", 0)])
    if solver.get("torsional") and np.any(orders != 0):
        _fail(f"'solver.torsional' = true needs m = 0 (the torsional family), got m = {orders.max():g}")
    try:  # the grid's memory, before anything is allocated for it
        jacobian = solver.get("jacobian", False)
        derivatives = None if not jacobian else len(jacobian) if jacobian is not True else sum(
            fluid is not None or n not in FLUID_LEAVES for n in SENSITIVITY)
        check_size([v.size for v in axes.values()], solver.get("n_roots", 3), derivatives,
                   solver.get("n_growth", 0))
    except ValueError as exc:
        _fail(str(exc))
    if fluid is not None and fluid.get("coupling") == "paper" and np.any(orders != 0):
        _fail(f"the paper coupling is axisymmetric: it needs m = 0, got m = {orders.max():g}")
    if (fluid is not None and fluid.get("coupling") == "paper" and fluid.get("bessel_order") is None
            and "n" not in axes):
        _fail("the paper coupling needs 'fluid.bessel_order' (ν), or a sweep over 'axes.n' (ν = n)")
    return SweepConfig(tube=tube, fluid=fluid, axes=axes, outer=outer, **solver, delta_p=delta_p,
                       units=units, **_parse_output(data, default_name))


def load_config(path) -> SweepConfig:
    """Read and validate a ``.toml`` or ``.json`` sweep configuration.

    Raises:
        ValueError: an unreadable file, an unknown suffix, a syntax error, a JSON key given twice,
            nesting deeper than :data:`jaxdea.files.MAX_NESTING`, or any error of
            :func:`parse_config`. A UTF-8 byte-order mark is accepted.
    """
    path = Path(path)
    if path.suffix not in (".toml", ".json"):
        _fail(f"{path}: the file must end in .toml or .json")
    try:
        data = load_document(path, path.suffix[1:])
    except ValueError as exc:
        _fail(str(exc))
    return parse_config(data, default_name=path.stem)
