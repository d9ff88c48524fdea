"""Files and plots of the inverse characterisation (:func:`jaxdea.fit`), and ``jaxdea fit``.

Peaks are a CSV table (:func:`read_peaks`, :func:`write_peaks`) with one row per measured peak and
the columns ``voltage_V`` (V), ``frequency_Hz`` (Hz, > 0), optional ``sigma_Hz`` (the standard
deviation of the peak, Hz, > 0) and optional labels ``m`` (≥ 0), ``n`` (≥ 1), ``branch`` (≥ 0);
lines starting with ``#`` are comments. :func:`write_fit` saves a :class:`jaxdea.FitResult` as
JSON, :func:`plot_fit` draws the data against the fitted curves f(V) of the identified modes with
the residuals below.

``jaxdea fit DATA.csv --config fit.toml [--out DIR]`` reads the free parameters, fixed values, the
fluid and the options of :func:`jaxdea.fit` from a TOML document (:data:`FORMAT`,
:func:`load_fit_config`), prints a summary and writes DATA_fit.json and DATA_fit.png
(:func:`run_fit`). Every error is a ValueError naming the file, column, row or key.
"""

from __future__ import annotations

import dataclasses
import json
import math
import warnings
from pathlib import Path

import numpy as np

from ..files import load_document, save_figure, write_text, write_together
from ..studies.fit import (
    LOAD_COLUMNS,
    NAMES,
    UNITS,
    FitQualityWarning,
    FitResult,
    IdentifiabilityWarning,
    fit,
    fitted_frequencies,
)
from ..studies.peaks import read_peaks
from .config import damping_from_table, layers_from_tables, material_from_table

TOP_KEYS = ("free", "fixed", "fluid", "options", "outer_fluid", "material", "layers", "damping")
OUTER_KEYS = ("preset", "fluid_density", "sound_speed")
OUTER_PRESETS = ("water", "air", "silicone_oil")
FREE_KEYS = ("lower", "upper", "initial")
FLUID_KEYS = ("coupling", "bessel_order")
OPTION_KEYS = ("n_layers", "scheme", "m_max", "n_max", "n_branches", "torsional", "threshold",
               "outlier_sigma", "max_unmatched", "n_starts", "grid_points", "max_iterations",
               "max_reassignments")

FORMAT = f"""\
fluid = "acoustic"   optional, before the tables (leave it out for an empty tube); or a table
          [fluid] coupling = "acoustic" | "paper", bessel_order = ν (integer >= 0; paper only)
[free]    the parameters to estimate (SI units): NAME = [lower, upper] or
          NAME = {{lower = a, upper = b, initial = x}} (initial strictly inside the bounds; for every
          free parameter or for none)
[fixed]   every other parameter: NAME = value (gent = inf: neo-Hookean)
          NAME one of {', '.join(NAMES[:5])} (Pa, kg/m^3, F/m, m, m),
          {', '.join(NAMES[5:9])} (and fluid_density, fluid_speed with a fluid);
          pressure (Pa, P_i - P_o, any finite value) instead of lambda_i for a tube held by its
          pressure (lambda_i follows from it at every voltage); a peak column pressure_Pa,
          lambda_i or lambda_z replaces the parameter of that name (several loadings)
[material] optional, the wall's material (fixed; then gent is no parameter): kind = "neo_hookean" |
          "mooney_rivlin" | "gent_gent" | "ogden" and its parameters (as in jaxdea sweep's config)
[[layers]] optional, one table per layer from the inner face outwards (instead of [material]):
          fraction, material = {{kind = ..., ...}}, shear_ratio, density_ratio, active = true for
          the dielectric (μ, density, permittivity are its own); gent is no parameter
          [free] may also name the wall's own parameters (their start is the wall's value; no
          initial needed): material_<field> (material_beta of mooney_rivlin), layer<k>_shear_ratio,
          layer<k>_density_ratio, layer<k>_fraction (passive layers) and layer<k>_material_<field>
[damping] optional, the wall's damping law (not with [[layers]]), in units of μ and R_i/c_s:
          kind = "prony" (moduli = [...], times = [...]) | "fractional_kelvin_voigt" (modulus,
          time, order, stretch_coupling) | "kelvin_voigt" (viscosity) | "hysteretic" (loss), as
          [damping] of jaxdea sweep's config. Each peak is then the complex root near it: the
          peaks may carry width_Hz (half-power width) or quality_factor columns, with
          sigma_width_Hz or sigma_quality_factor when sigma_Hz is given; [free] may name
          damping_moduli_<k>, damping_times_<k> (prony branch k, from 0), damping_viscosity,
          damping_loss, damping_modulus, damping_time, damping_order (bounds > 0; the start is
          the table's value)
[outer_fluid] optional: the known fluid around the tube, preset = "water" | "air" | "silicone_oil"
          or fluid_density (kg/m^3) and sound_speed (m/s)
[options] of jaxdea.fit: n_layers, scheme (default: the accurate graded magnus6 laminate; n_layers
          alone: equal midpoint sublayers), m_max = 2, n_max = 3, n_branches = 2, torsional = false
          (the modes unlabelled peaks may be assigned to), threshold = 0.1 (|log f_model - log f_data| beyond
          which a peak is an outlier without sigma_Hz), outlier_sigma = 5 (with sigma_Hz),
          max_unmatched = 0.25, n_starts = 3 (0 with initial values: those alone),
          grid_points = 3, max_iterations = 100, max_reassignments = 10
"""


# --------------------------------------------------------------------------------------- result


def model_frequency(result: FitResult, data) -> np.ndarray:
    """f_model in Hz per data point: f_data + r σ (NaN where the peak is unmatched)."""
    f = np.asarray(data["frequency_Hz"], dtype=np.float64)
    sigma = np.asarray(data["sigma_Hz"], dtype=np.float64) if "sigma_Hz" in data else 1.0
    return f + np.asarray(result.residuals) * sigma


def _plain(x):
    """JSON-ready: NaN and ±inf as null, arrays as lists."""
    if isinstance(x, dict):
        return {str(k): _plain(v) for k, v in x.items()}
    if isinstance(x, (list, tuple, np.ndarray)):
        return [_plain(v) for v in (x.tolist() if isinstance(x, np.ndarray) else x)]
    if isinstance(x, (float, np.floating)):
        return float(x) if math.isfinite(x) else None
    if isinstance(x, np.integer):
        return int(x)
    return x


def write_fit(result: FitResult, data, path, warnings_=()) -> Path:
    """Save a fit as JSON: status, iterations, the estimates, 95 % intervals, units, covariance and
    correlation (in ``names`` order), every parameter value, the model settings, χ², dof, χ²/dof,
    the unmatched fraction, the parameters stopped on a bound and one record per
    peak (voltage_V, frequency_Hz, sigma_Hz, model_Hz, residual, m, n, branch, torsional, and the
    peak's pressure_Pa, lambda_i, lambda_z where the data has them, width_residual with peak
    widths (:attr:`jaxdea.FitResult.width_residuals`); m = n = branch = −1
    for an unmatched peak, whose model_Hz and residual are null). NaN and ±inf are written as null.

    Examples:
        >>> result = jd.fit(peaks, free, fixed)
        >>> write_fit(result, peaks, "peaks_fit.json")
        >>> estimate = json.load(open("peaks_fit.json"))["estimate"]
        >>> estimate["shear_modulus"], estimate["lambda_i"]
    """
    voltage = np.asarray(data["voltage_V"], dtype=np.float64)
    model = model_frequency(result, data)
    sigma = np.asarray(data["sigma_Hz"], dtype=np.float64) if "sigma_Hz" in data else None
    points = []
    torsional = _torsional(result)
    loads = {k: np.asarray(data[k], dtype=np.float64) for k in LOAD_COLUMNS if k in data}
    for i in range(voltage.size):
        m, n, branch = (int(x) for x in result.assignment[i])
        points.append(dict(voltage_V=voltage[i], frequency_Hz=float(data["frequency_Hz"][i]),
                           sigma_Hz=None if sigma is None else sigma[i], model_Hz=model[i],
                           residual=result.residuals[i], m=m, n=n, branch=branch,
                           torsional=bool(torsional[i]), **{k: v[i] for k, v in loads.items()},
                           **({} if result.width_residuals is None else
                              dict(width_residual=result.width_residuals[i]))))
    document = dict(
        status=result.status.name, iterations=int(result.iterations), names=list(result.names),
        estimate=result.estimate, interval=result.interval,
        units={k: UNITS.get(k, "") for k in result.names}, covariance=result.covariance,
        correlation=result.correlation, parameters=result.parameters, settings=result.settings,
        unmatched=[int(i) for i in np.flatnonzero(result.assignment[:, 0] < 0)],
        chi2=result.chi2, dof=result.dof, chi2_per_dof=result.chi2_per_dof,
        unmatched_fraction=result.unmatched_fraction, at_bound=result.at_bound,
        warnings=list(warnings_), points=points)
    path = Path(path)
    write_text(path, json.dumps(_plain(document), indent=1) + "\n")
    return path


def _torsional(result: FitResult) -> np.ndarray:
    """The torsional flag of every peak (all False for a result without one)."""
    rows = result.assignment.shape[0]
    return np.zeros(rows, bool) if result.torsional is None else np.asarray(result.torsional, bool)


def identified_modes(result: FitResult) -> list:
    """The distinct (m, n, branch) of the matched peaks, sorted; a torsional mode as
    (0, n, branch, "torsional")."""
    matched = result.assignment[:, 0] >= 0
    torsional = _torsional(result)
    return sorted({tuple(int(x) for x in row) + (("torsional",) if t else ())
                   for row, t in zip(result.assignment[matched], torsional[matched], strict=True)})


def plot_fit(result: FitResult, data, path=None, points: int = 41):
    """Data against the fitted model: f(V) of every identified mode (m, n, branch) as a curve of
    ``points`` voltages over the data's range (:func:`jaxdea.fitted_frequencies` at the fitted
    parameters), the peaks as markers in the colour of their mode (unmatched ones as grey
    crosses), and the residuals (f_model − f_data)/σ (Hz without σ) against V in a panel below.

    Returns:
        The matplotlib Figure (Agg canvas; no pyplot state is touched), saved to ``path`` if given.
        Its first axes hold one line per mode, labelled "(m, n, branch) = (…)", whose data are the
        voltages and the model frequencies.

    Examples:
        >>> fig = plot_fit(result, peaks, "peaks_fit.png")
        >>> fig.axes[0].lines[0].get_xydata()           # (V, f_model in Hz) of the first mode
    """
    from matplotlib import colormaps
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    voltage = np.asarray(data["voltage_V"], dtype=np.float64)
    frequency = np.asarray(data["frequency_Hz"], dtype=np.float64)
    low, high = float(voltage.min()), float(voltage.max())
    if low == high:
        low, high = min(0.0, low), (high if high > 0 else 1.0)
    grid = np.linspace(low, high, points)
    torsional = _torsional(result)
    names = [k for k in LOAD_COLUMNS if k in data]
    loads = np.stack([np.asarray(data[k], dtype=np.float64) for k in names], axis=1) \
        if names else np.zeros((voltage.size, 0))
    groups = []  # (mode, loading) of the matched peaks: one curve each
    for mode in identified_modes(result):
        own = np.all(result.assignment == np.array(mode[:3]), axis=1) & (
            torsional == (len(mode) == 4))
        for load in np.unique(loads[own], axis=0):
            groups.append((mode, load, own & np.all(loads == load, axis=1)))
    cmap = colormaps["tab10"]
    fig = Figure(figsize=(7, 6.5), layout="constrained")
    FigureCanvasAgg(fig)
    top, bottom = fig.subplots(2, 1, sharex=True, height_ratios=(3, 1.3))
    for k, (mode, load, own) in enumerate(groups):
        color = cmap(k % 10)
        curve = fitted_frequencies(result, grid, mode[0], mode[1], mode[2],
                                   torsional=len(mode) == 4,
                                   **{name: value for name, value in zip(names, load, strict=True)})
        where = "".join(f", {name} = {value:.6g}" for name, value in zip(names, load, strict=True))
        top.plot(grid, curve, color=color, label=f"(m, n, branch) = {mode}{where}")
        top.plot(voltage[own], frequency[own], "o", color=color, markersize=4,
                 label="_nolegend_")
        bottom.plot(voltage[own], result.residuals[own], "o", color=color, markersize=4)
    unmatched = result.assignment[:, 0] < 0
    if np.any(unmatched):
        top.plot(voltage[unmatched], frequency[unmatched], "x", color="0.5",
                 label="unmatched peaks")
    bottom.axhline(0.0, color="k", linewidth=0.8)
    top.set_ylabel("frequency f (Hz)")
    bottom.set_ylabel(r"$(f_{model} - f)/\sigma$" if "sigma_Hz" in data
                      else r"$f_{model} - f$ (Hz)")
    bottom.set_xlabel("voltage V (V)")
    if groups or np.any(unmatched):
        top.legend(fontsize="small", frameon=False)
    estimates = ", ".join(f"{k} = {v:.4g}" for k, v in result.estimate.items())
    top.set_title(f"fit: {result.status.name.lower()}, {result.iterations} iterations\n"
                  f"{estimates}", fontsize="medium")
    for ax in (top, bottom):
        ax.grid(alpha=0.3)
    if path is not None:
        save_figure(fig, path, dpi=120)
    return fig


# ------------------------------------------------------------------------------ configuration


@dataclasses.dataclass(frozen=True)
class FitConfig:
    """Validated settings of ``jaxdea fit``: the arguments of :func:`jaxdea.fit`."""

    free: dict
    fixed: dict
    fluid: object
    initial: dict | None
    options: dict
    outer: tuple | None = None
    material: object = None
    layers: tuple | None = None
    damping: object = None


def _number(key, x, allow_inf=False):
    if isinstance(x, bool) or not isinstance(x, (int, float)):
        raise ValueError(f"{key}: expected a number, got {x!r}")
    if not (math.isfinite(x) or (allow_inf and x == math.inf)):
        raise ValueError(f"{key}: expected a finite number, got {x!r}")
    return float(x)


def _table(key, x, allowed):
    if not isinstance(x, dict):
        raise ValueError(f"{key}: expected a table, got {x!r}")
    for name in x:
        if name not in allowed:
            where = f"{key}.{name}" if key else name
            raise ValueError(f"{where}: unknown key (allowed: {', '.join(allowed)})")
    return x


def parse_fit_config(data) -> FitConfig:
    """Check a ``jaxdea fit`` configuration (a dict, as read from TOML; :data:`FORMAT`).

    Raises:
        ValueError: naming the offending key (``free.shear_modulus``, ``options.m_max``, …).
    """
    _table("", data, TOP_KEYS)
    for key in ("free", "fixed"):
        if key not in data:
            raise ValueError(f"{key}: missing table [{key}]")
    fluid = data.get("fluid")
    if isinstance(fluid, dict):
        _table("fluid", fluid, FLUID_KEYS)
        if fluid.get("coupling", "acoustic") not in ("acoustic", "paper"):
            raise ValueError(f"fluid.coupling: expected \"acoustic\" or \"paper\", got "
                             f"{fluid['coupling']!r}")
        order = fluid.get("bessel_order")
        if order is not None and (isinstance(order, bool) or not isinstance(order, int)
                                  or order < 0):
            raise ValueError(f"fluid.bessel_order: expected an integer >= 0, got {order!r}")
        from ..params import Fluid

        fluid = Fluid(coupling=fluid.get("coupling", "acoustic"), bessel_order=order)
    elif fluid is not None and fluid not in ("acoustic", "paper"):
        raise ValueError(f"fluid: expected \"acoustic\", \"paper\" or a table, got {fluid!r}")
    known = NAMES if fluid is not None else NAMES[:-2]
    if "material" in data and "layers" in data:
        raise ValueError("material, layers: both set the wall's energy; with [[layers]] give each "
                         "layer its material")
    material = material_from_table("material", data["material"]) if "material" in data else None
    layers = layers_from_tables(data["layers"]) if "layers" in data else None
    damping = damping_from_table("damping", data["damping"]) if "damping" in data else None
    if damping is not None and layers is not None:
        raise ValueError("damping, layers: a layered wall's damping is its layers', which fit does "
                         "not take yet; give [damping] with a one-material wall")
    walls = _wall_names(material, layers, damping)  # the wall's parameters that [free] may name
    free, initial = {}, {}
    for name, spec in _table("free", data["free"], NAMES + walls).items():
        key = f"free.{name}"
        if name not in known and name not in walls:
            raise ValueError(f"{key}: a fluid parameter needs fluid = \"acoustic\" or [fluid]")
        if isinstance(spec, dict):
            _table(key, spec, FREE_KEYS)
            for bound in ("lower", "upper"):
                if bound not in spec:
                    raise ValueError(f"{key}.{bound}: missing")
            bounds = (spec["lower"], spec["upper"])
            if "initial" in spec:
                initial[name] = _number(f"{key}.initial", spec["initial"])
        elif isinstance(spec, list) and len(spec) == 2:
            bounds = spec
        else:
            raise ValueError(f"{key}: expected [lower, upper] or {{lower, upper, initial}}, "
                             f"got {spec!r}")
        free[name] = tuple(_number(f"{key}", b) for b in bounds)
    fixed = {}
    for name, value in _table("fixed", data["fixed"], NAMES).items():
        if name not in known:
            raise ValueError(f"fixed.{name}: a fluid parameter needs fluid = \"acoustic\" or "
                             f"[fluid]")
        fixed[name] = _number(f"fixed.{name}", value, allow_inf=name == "gent")
    options = dict(_table("options", data.get("options", {}), OPTION_KEYS))
    for name, value in options.items():
        if name in ("threshold", "outlier_sigma", "max_unmatched"):
            options[name] = _number(f"options.{name}", value)
        elif name == "scheme":
            if not isinstance(value, str):
                raise ValueError(f"options.scheme: expected a string, got {value!r}")
        elif name == "torsional":
            if not isinstance(value, bool):
                raise ValueError(f"options.torsional: expected true or false, got {value!r}")
        elif isinstance(value, bool) or not isinstance(value, int):
            raise ValueError(f"options.{name}: expected an integer, got {value!r}")
    if initial and len(initial) != len(free):
        missing = [k for k in free if k not in initial and k not in walls]
        if missing:
            raise ValueError(f"free.{missing[0]}.initial: needed when another free parameter has "
                             f"one")
    return FitConfig(free, fixed, fluid, initial or None, options, _outer_fluid(data), material,
                     layers, damping)


def _wall_names(material, layers, damping=None) -> tuple:
    """The names of the wall parameters that [free] may name (:func:`jaxdea.physics.leaves.wall_names`
    of the [material] or [[layers]] wall and the [damping] law; () for the default Gent wall)."""
    if material is None and layers is None and damping is None:
        return ()
    from ..params import Tube
    from ..physics.leaves import wall_names

    return wall_names(Tube(material="gent" if material is None else material, layers=layers,
                           damping=damping))


def _outer_fluid(data) -> tuple | None:
    """(ρ_o kg/m³, c_o m/s) of the [outer_fluid] table (a preset of :mod:`jaxdea.units` or both
    numbers), or None."""
    if "outer_fluid" not in data:
        return None
    table = _table("outer_fluid", data["outer_fluid"], OUTER_KEYS)
    if "preset" in table:
        if len(table) > 1:
            raise ValueError("outer_fluid.preset: sets the whole fluid; remove "
                             f"outer_fluid.{next(k for k in table if k != 'preset')}")
        if table["preset"] not in OUTER_PRESETS:
            raise ValueError(f"outer_fluid.preset: expected one of {', '.join(OUTER_PRESETS)}, got "
                             f"{table['preset']!r}")
        from ..physics import units

        return tuple(float(x) for x in getattr(units, table["preset"].upper()))
    values = []
    for key in ("fluid_density", "sound_speed"):
        if key not in table:
            raise ValueError(f"outer_fluid.{key}: missing (or give outer_fluid.preset)")
        value = _number(f"outer_fluid.{key}", table[key])
        if value <= 0:
            raise ValueError(f"outer_fluid.{key}: expected a number > 0, got {value!r}")
        values.append(value)
    return tuple(values)


def load_fit_config(path) -> FitConfig:
    """Read and check a ``jaxdea fit`` configuration from a TOML file (:func:`parse_fit_config`)."""
    path = Path(path)
    data = load_document(path, "toml")
    try:
        return parse_fit_config(data)
    except ValueError as exc:
        raise ValueError(f"{path}: {exc}") from None


# ------------------------------------------------------------------------------------ command


def summary(result: FitResult, data, source="data", caught=()) -> str:
    """The text ``jaxdea fit`` prints: status, estimates ± 95 % half-widths with the intervals,
    and the assignment of every peak (unmatched ones listed)."""
    rows = result.assignment.shape[0]
    lines = [f"fit of {rows} peaks from {source}: {len(result.names)} free parameters, status "
             f"{result.status.name}, {result.iterations} iterations, chi2/dof "
             f"{result.chi2_per_dof:.4g}, {100 * result.unmatched_fraction:.0f} % unmatched", "",
             f"{'parameter':<16}{'estimate':>14}{'± 95 %':>12}   {'95 % interval':<30}unit"]
    for name in result.names:
        value, (low, high) = result.estimate[name], result.interval[name]
        interval = f"[{low:.6g}, {high:.6g}]"
        lines.append(f"{name:<16}{value:>14.7g}{0.5 * (high - low):>12.3g}   {interval:<30}"
                     f"{UNITS.get(name, '')}")
    model = model_frequency(result, data)
    residual = "(f_model - f)/σ" if "sigma_Hz" in data else "f_model - f (Hz)"
    lines += ["", f"{'peak':>4} {'voltage_V':>12} {'frequency_Hz':>14} {'model_Hz':>14} "
              f"{residual:>16}  (m, n, branch)"]
    for i in range(rows):
        label = tuple(int(x) for x in result.assignment[i])
        text = "unmatched" if label[0] < 0 else f"{label}"
        lines.append(f"{i:>4} {data['voltage_V'][i]:>12.6g} {data['frequency_Hz'][i]:>14.7g} "
                     f"{model[i]:>14.7g} {result.residuals[i]:>16.3g}  {text}")
    unmatched = np.flatnonzero(result.assignment[:, 0] < 0)
    lines.append("unmatched peaks: " + (", ".join(str(i) for i in unmatched) if unmatched.size
                                        else "none"))
    lines += [f"warning: {message}" for message in caught]
    return "\n".join(lines)


def run_fit(data_path, config_path, out=None):
    """``jaxdea fit``: read the peaks and the configuration, fit, write DATA_fit.json
    (:func:`write_fit`) and DATA_fit.png (:func:`plot_fit`) into ``out`` (default: the current
    folder), both or neither (:func:`jaxdea.files.write_together`).

    Returns:
        (result, summary text, written paths).

    Raises:
        ValueError: a bad file, key or value (one line, naming it).
    """
    config = load_fit_config(config_path)
    data = read_peaks(data_path)
    data_path = Path(data_path)
    folder = Path(out) if out is not None else Path()
    paths = [folder / f"{data_path.stem}_fit.json", folder / f"{data_path.stem}_fit.png"]
    try:  # before the fit: a bad folder fails at once
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ValueError(f"cannot write into {folder}: {exc.strerror or exc}") from None
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", IdentifiabilityWarning)
        warnings.simplefilter("always", FitQualityWarning)
        result = fit(data, config.free, config.fixed, config.fluid, initial=config.initial,
                     outer=config.outer, material=config.material, layers=config.layers,
                     damping=config.damping, **config.options)
    messages = [str(w.message) for w in caught
                if issubclass(w.category, (IdentifiabilityWarning, FitQualityWarning))]
    try:  # both or neither
        write_together([(paths[0], lambda tmp: write_fit(result, data, tmp, messages)),
                        (paths[1], lambda tmp: plot_fit(result, data, tmp))])
    except OSError as exc:
        raise ValueError(f"cannot write into {folder}: {exc.strerror or exc}") from None
    return result, summary(result, data, data_path.name, messages), paths
