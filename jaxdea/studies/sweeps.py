"""Sweeps: the K lowest frequencies (and optionally their derivatives) over a grid of parameters.

A grid is the Cartesian product of 1-D axes named after the parameters of :mod:`jaxdea.physics.leaves`
(any Tube or Fluid float field, ``thickness_ratio`` h/R_i, and ``alpha`` α̂ or ``n`` the axial mode
number; the wall's material and layer parameters, ``material_beta``, ``layer2_fraction``, …). Its
points are solved in fixed-size chunks by one jit-compiled, vmapped program: memory is bounded by
the chunk (plus the result arrays), and every chunk reuses the same compilation. Points that fail
(no root, non-finite transfer, inputs past Gent locking or out of range) give NaN and their status
(:class:`jaxdea.Status`) without stopping the sweep.

Scale-out: with several JAX devices each chunk is split along its points over a 1-D
:class:`jax.sharding.Mesh` of the devices, and every device runs the one-device chunk program on its
block (so the numbers do not depend on the devices); with ``client=`` a Dask
``distributed.Client`` the chunks become tasks on the cluster's workers (each worker compiles the
chunk program once and reuses it), gathered back in grid order.

Derivatives (``jacobian=``) come from the implicit function theorem at each root,
dΩ/dθ = −(∂f/∂θ)/(∂f/∂Ω), with ∂f by forward-mode autodiff of the characteristic function f: the
partial derivatives are taken in the coordinates named (e.g. (V̂, λ_i, λ_z, ρ̂_f, ĉ_f, h/R_i, G):
dΩ/dλ_i at fixed h/R_i, with η following). On a grid over ``n`` the wavenumber α̂ of mode n follows
λ_z and η; on a grid over ``alpha`` α̂ is held. The group velocity dΩ/dα̂ = −f_α̂/f_Ω comes with them.

A result is written as CSV, NPZ or netCDF (:meth:`SweepResult.to_xarray`, extra ``jaxdea[xarray]``);
with scales (:meth:`SweepResult.with_units`) the outputs also carry SI values: f in Hz, V in volts,
lengths in m (:data:`SI_QUANTITIES`, converted by :mod:`jaxdea.physics.units`).
"""

from __future__ import annotations

import dataclasses
import importlib.util
import json
import math
import os
import re

import jax
import jax.numpy as jnp
import numpy as np
from jax.sharding import Mesh, NamedSharding
from jax.sharding import PartitionSpec as P

from ..compiled import cached_jit
from ..files import atomic_write
from ..materials import DAMPING_KINDS, KINDS, Energy
from ..numerics.scalar import Status
from ..params import (
    MAX_ROOTS,
    Fluid,
    Layer,
    Tube,
    as_float,
    guard,
    real_value,
    require_x64,
    validate_fluid,
    validate_layers,
    validate_positive,
    validate_roots,
    with_outer,
)
from ..physics import characteristic
from ..physics.base_state import inner_stretch_traced
from ..physics.families import Face
from ..physics.leaves import FLUID_LEAVES, TUBE_LEAVES, apply_parameters, check_names, get_parameter
from ..physics.problem import family_of
from ..physics.state_matrix import LONGITUDINAL
from ..physics.transfer import AUTO_SCHEME, discretize, is_graded, laminate, split_layers, validate_scheme
from ..physics.units import Scales, fluid_from_si, fluid_to_si
from ..solve.roots import frequencies_unchecked, growth_rates_unchecked, without_voltage

SENSITIVITY = ("voltage", "lambda_i", "lambda_z", "density_ratio", "speed_ratio", "thickness_ratio",
               "gent")
CHUNK_SIZE = 32

SI_QUANTITIES = {
    "voltage": ("voltage_V", "V", lambda s, x: s.voltage_to_si(x), lambda s, x: s.voltage_from_si(x)),
    "thickness_ratio": ("thickness_m", "m", lambda s, x: s.length_to_si(x),
                        lambda s, x: s.length_from_si(x)),
    "density_ratio": ("fluid_density_kg_m3", "kg/m^3",
                      lambda s, x: fluid_to_si(s, Fluid(density_ratio=x, speed_ratio=1.0)).fluid_density,
                      lambda s, x: fluid_from_si(s, x, s.shear_speed).density_ratio),
    "speed_ratio": ("sound_speed_m_s", "m/s", lambda s, x: s.speed_to_si(x),
                    lambda s, x: s.speed_from_si(x)),
    "alpha": ("wavelength_m", "m", lambda s, x: s.wavelength_to_si(x),
              lambda s, x: s.wavelength_from_si(x)),
}
"""The parameters with an SI counterpart: ``{name: (SI name, unit, to_si(scales, x), from_si(scales, x))}``
(α̂ ↔ the axial wavelength 2π R_i/α̂). The SI name is the config key and the output column."""
SCALE_FIELDS = ("shear_modulus", "density", "permittivity", "inner_radius")
MAX_POINTS = 10**8
"""Most grid points of one sweep (at a few ms a point on a CPU, days of computing)."""
MEMORY_SHARE = 0.5
"""The share of the machine's physical memory a sweep's arrays may take (:func:`check_size`)."""
XARRAY_EXTRA = "pip install 'jaxdea[xarray]'"


@dataclasses.dataclass(frozen=True)
class SweepResult:
    """Frequencies over a grid.

    Attributes:
        axes: the grid axes, ``{name: 1-D array}`` in grid order.
        omega: Ω, shape (*grid_shape, n_roots), ascending per point, NaN where no root.
        status: :class:`jaxdea.Status` per root, same shape (int32).
        alpha: α̂ at each grid point, shape grid_shape.
        jacobian: dΩ/dθ, shape (*grid_shape, n_roots, len(jacobian_names)), or None.
        jacobian_names: the coordinates θ of ``jacobian``.
        group_velocity: dΩ/dα̂ per root (with the jacobian), or None.
        growth_rate: s = √(−Ω²) of the unstable modes (Ω² < 0) per point, largest first,
            NaN-padded (all NaN: stable at that point), shape (*grid_shape, n_growth), or None
            (``n_growth=0``).
        settings: the fixed parameters and solver settings (JSON-serialisable dict).
        lambda_i: with ``delta_p`` (a pressure-held tube) the inner stretch λ_i solved at every
            point from ΔP̂ (:func:`jaxdea.inner_stretch`), shape grid_shape; else None.
        omega_imag: a damped tube's (``tube.damping``) Im Ω per root (time factor e^{iΩt}: a
            decaying mode has Im Ω > 0; ``omega`` is then Re Ω, ascending), shape of ``omega``;
            else None.
        quality_factor: a damped tube's Q = Re Ω/(2 Im Ω) per root; else None.
    """

    axes: dict
    omega: np.ndarray
    status: np.ndarray
    alpha: np.ndarray
    jacobian: np.ndarray | None = None
    jacobian_names: tuple = ()
    group_velocity: np.ndarray | None = None
    growth_rate: np.ndarray | None = None
    settings: dict = dataclasses.field(default_factory=dict)
    lambda_i: np.ndarray | None = None
    omega_imag: np.ndarray | None = None
    quality_factor: np.ndarray | None = None

    @property
    def shape(self) -> tuple:
        """The grid shape."""
        return self.alpha.shape

    @property
    def unstable(self) -> np.ndarray | None:
        """True where the point has an unstable mode (a finite growth rate), shape grid_shape;
        None without growth rates (``n_growth=0``)."""
        if self.growth_rate is None:
            return None
        return np.any(np.isfinite(self.growth_rate), axis=-1)

    @property
    def phase_velocity(self) -> np.ndarray:
        """Ω/α̂ per root, shape (*grid_shape, n_roots)."""
        return self.omega / self.alpha[..., None]

    def derivative(self, name: str) -> np.ndarray:
        """dΩ/d``name`` per root, shape (*grid_shape, n_roots)."""
        if self.jacobian is None or name not in self.jacobian_names:
            raise ValueError(f"no derivative with respect to {name!r}: computed for "
                             f"{self.jacobian_names or 'nothing'} (pass jacobian=... to sweep)")
        return self.jacobian[..., self.jacobian_names.index(name)]

    def columns(self) -> dict:
        """One flat column per quantity, one row per grid point (the CSV layout)."""
        grids = np.meshgrid(*self.axes.values(), indexing="ij")
        cols = {name: g.ravel() for name, g in zip(self.axes, grids, strict=True)}
        si_axes = self._si_axes()
        if si_axes:  # the SI value of each such axis, after the axes
            si_values = [si_axes[k][1] if k in si_axes else v for k, v in self.axes.items()]
            for name, g in zip(self.axes, np.meshgrid(*si_values, indexing="ij"), strict=True):
                if name in si_axes:
                    cols[si_axes[name][0]] = g.ravel()
        cols["alpha_hat"] = self.alpha.ravel()
        if self.lambda_i is not None:
            cols["lambda_i"] = self.lambda_i.ravel()
        if self.scales is not None:
            cols["wavelength_m"] = self.wavelength_m.ravel()
        k = self.omega.shape[-1]
        flat = lambda a: a.reshape(-1, k)  # noqa: E731
        for j in range(k):
            cols[f"omega_{j + 1}"] = flat(self.omega)[:, j]
        if self.omega_imag is not None:  # a damped tube: omega_j is Re Ω
            for j in range(k):
                cols[f"omega_imag_{j + 1}"] = flat(self.omega_imag)[:, j]
            for j in range(k):
                cols[f"quality_factor_{j + 1}"] = flat(self.quality_factor)[:, j]
        if self.scales is not None:
            for j in range(k):
                cols[f"frequency_Hz_{j + 1}"] = flat(self.frequency_hz)[:, j]
        for j in range(k):
            cols[f"status_{j + 1}"] = flat(self.status)[:, j]
        if self.group_velocity is not None:
            for j in range(k):
                cols[f"group_velocity_{j + 1}"] = flat(self.group_velocity)[:, j]
        for m, name in enumerate(self.jacobian_names):
            for j in range(k):
                cols[f"d_omega_{j + 1}/d_{name}"] = flat(self.jacobian[..., m])[:, j]
        if self.growth_rate is not None:
            growth = self.growth_rate.reshape(-1, self.growth_rate.shape[-1])
            for j in range(growth.shape[1]):
                cols[f"growth_rate_{j + 1}"] = growth[:, j]
            if self.scales is not None:
                growth = self.growth_rate_per_s.reshape(growth.shape)
                for j in range(growth.shape[1]):
                    cols[f"growth_rate_per_s_{j + 1}"] = growth[:, j]
        return cols

    @property
    def scales(self) -> Scales | None:
        """The :class:`jaxdea.physics.units.Scales` of the SI outputs (:meth:`with_units`), or None."""
        units = self.settings.get("units")
        return None if units is None else Scales(**units)

    def with_units(self, scales: Scales) -> SweepResult:
        """A copy whose outputs also carry SI values with these scales: f in Hz
        (:attr:`frequency_hz`), the wavelength in m, growth rates in 1/s and the SI value of every
        axis in :data:`SI_QUANTITIES` (``voltage_V``, ``thickness_m``, ...).

        Raises:
            ValueError: ``scales`` is no :class:`jaxdea.physics.units.Scales` or has a value that is not
                finite and > 0 (naming it).
        """
        if not isinstance(scales, Scales):
            raise ValueError(f"scales must be a jaxdea.physics.units.Scales, got {type(scales).__name__}")
        units = {}
        for name in SCALE_FIELDS:
            value = real_value(name, getattr(scales, name))
            if value is None or not (math.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be a finite number > 0, got {getattr(scales, name)!r}")
            units[name] = float(value)
        return dataclasses.replace(self, settings={**self.settings, "units": units})

    def _si(self, values, to_si):
        return np.asarray(to_si(self.scales, values))

    def _si_axes(self) -> dict:
        """``{axis: (SI name, SI values, unit)}`` of the axes with an SI counterpart (α̂ aside: its
        wavelength is :attr:`wavelength_m`); empty without units."""
        if self.scales is None:
            return {}
        return {name: (SI_QUANTITIES[name][0], self._si(values, SI_QUANTITIES[name][2]),
                       SI_QUANTITIES[name][1])
                for name, values in self.axes.items() if name in SI_QUANTITIES and name != "alpha"}

    @property
    def frequency_hz(self) -> np.ndarray | None:
        """f = Ω c_s/(2π R_i) in Hz per root (:meth:`with_units`), or None without units."""
        return None if self.scales is None else self._si(self.omega, Scales.omega_to_hz)

    @property
    def wavelength_m(self) -> np.ndarray | None:
        """The axial wavelength 2π R_i/α̂ in m at each point, or None without units."""
        return None if self.scales is None else self._si(self.alpha, SI_QUANTITIES["alpha"][2])

    @property
    def growth_rate_per_s(self) -> np.ndarray | None:
        """Growth rates s c_s/R_i in 1/s, or None (no growth rates or no units)."""
        if self.scales is None or self.growth_rate is None:
            return None
        return self._si(self.growth_rate, Scales.omega_to_si)

    def to_csv(self, path) -> None:
        """Write one row per grid point (axes, α̂, Ω_k, status_k, derivatives, growth rates); header
        line first. The file is replaced whole or not at all (:mod:`jaxdea.files`)."""
        cols = self.columns()
        table = np.column_stack(list(cols.values()))
        fmt = ["%d" if name.startswith("status") else "%.17g" for name in cols]
        with atomic_write(path) as tmp:
            np.savetxt(tmp, table, delimiter=",", header=",".join(cols), comments="", fmt=fmt)

    def to_npz(self, path) -> None:
        """Save everything (read back with :meth:`from_npz`); ``.npz`` is appended to a path
        without it, as :func:`numpy.savez` does. Replaced whole or not at all."""
        arrays = {f"axis:{name}": np.asarray(v) for name, v in self.axes.items()}
        arrays.update(omega=self.omega, status=self.status, alpha=self.alpha,
                      settings=np.array(json.dumps(self.settings)),
                      axis_order=np.array(json.dumps(list(self.axes))),
                      jacobian_names=np.array(json.dumps(list(self.jacobian_names))))
        if self.jacobian is not None:
            arrays.update(jacobian=self.jacobian, group_velocity=self.group_velocity)
        if self.growth_rate is not None:
            arrays.update(growth_rate=self.growth_rate)
        if self.lambda_i is not None:
            arrays.update(lambda_i=self.lambda_i)
        if self.omega_imag is not None:
            arrays.update(omega_imag=self.omega_imag, quality_factor=self.quality_factor)
        if self.scales is not None:  # SI values beside (recomputed by from_npz's result)
            arrays.update(frequency_Hz=self.frequency_hz, wavelength_m=self.wavelength_m)
            arrays.update({si_name: values for si_name, values, _ in self._si_axes().values()})
            if self.growth_rate is not None:
                arrays.update(growth_rate_per_s=self.growth_rate_per_s)
        if not hasattr(path, "write") and not str(path).endswith(".npz"):
            path = f"{path}.npz"
        with atomic_write(path) as tmp:
            np.savez(tmp, **arrays)

    def to_xarray(self):
        """The result as an :class:`xarray.Dataset` (extra ``jaxdea[xarray]``).

        Dimensions: the axes in grid order (coordinates: their values; with units also the SI
        values, e.g. ``voltage_V`` along ``voltage``), ``root`` (1…K) and, with growth rates,
        ``growth`` (1…n_growth). Variables: ``omega``, ``status`` (CF ``flag_values`` /
        ``flag_meanings``), ``alpha_hat``, with the jacobian ``group_velocity`` and
        ``d_omega_d_NAME`` per parameter, with growth rates ``growth_rate`` and ``unstable``, with
        units ``frequency_Hz``, ``wavelength_m`` (and ``growth_rate_per_s``). Attributes: the
        settings (``n_layers``, ``scheme``, ``coupling``, the fixed ``tube_*`` / ``fluid_*`` values,
        ``units_*``, …) and all of them as JSON in ``settings_json``.

        Raises:
            ImportError: xarray is not installed (naming the extra).
        """
        try:
            import xarray as xr
        except ImportError as err:
            raise ImportError(f"SweepResult.to_xarray needs xarray: {XARRAY_EXTRA}") from err
        dims = tuple(self.axes)
        roots = (*dims, "root")
        k = self.omega.shape[-1]
        coords = {name: (name, np.asarray(values)) for name, values in self.axes.items()}
        coords["root"] = ("root", np.arange(1, k + 1))
        for name, (si_name, values, unit) in self._si_axes().items():
            coords[si_name] = (name, values, {"units": unit})
        dimensionless = {"units": "1"}
        data = {
            "omega": (roots, self.omega, {"long_name": "frequency Omega = omega R_i/c_s", **dimensionless}),
            "status": (roots, self.status, {
                "long_name": "status of each root",
                "flag_values": np.array([s.value for s in Status], dtype=np.int32),
                "flag_meanings": " ".join(s.name.lower() for s in Status)}),
            "alpha_hat": (dims, self.alpha, {"long_name": "axial wavenumber alpha R_i", **dimensionless}),
        }
        if self.omega_imag is not None:
            data["omega_imag"] = (roots, self.omega_imag, {
                "long_name": "Im Omega of a damped tube (time factor exp(i Omega t); omega is "
                             "Re Omega)", **dimensionless})
            data["quality_factor"] = (roots, self.quality_factor, {
                "long_name": "quality factor Q = Re Omega/(2 Im Omega)", **dimensionless})
        if self.lambda_i is not None:
            data["lambda_i"] = (dims, self.lambda_i, {
                "long_name": "inner stretch held by the pressure difference delta_p", **dimensionless})
        if self.group_velocity is not None:
            data["group_velocity"] = (roots, self.group_velocity,
                                      {"long_name": "dOmega/dalpha_hat", **dimensionless})
            for name in self.jacobian_names:
                data[f"d_omega_d_{name}"] = (roots, self.derivative(name),
                                             {"long_name": f"dOmega/d{name}", **dimensionless})
        if self.growth_rate is not None:
            coords["growth"] = ("growth", np.arange(1, self.growth_rate.shape[-1] + 1))
            data["growth_rate"] = ((*dims, "growth"), self.growth_rate, {
                "long_name": "growth rate s = sqrt(-Omega^2), largest first (NaN: none)",
                **dimensionless})
            data["unstable"] = (dims, self.unstable, {"long_name": "an unstable mode at the point"})
        if self.scales is not None:
            data["frequency_Hz"] = (roots, self.frequency_hz,
                                    {"long_name": "frequency f = Omega c_s/(2 pi R_i)", "units": "Hz"})
            data["wavelength_m"] = (dims, self.wavelength_m,
                                    {"long_name": "axial wavelength 2 pi R_i/alpha_hat", "units": "m"})
            if self.growth_rate is not None:
                data["growth_rate_per_s"] = ((*dims, "growth"), self.growth_rate_per_s,
                                             {"long_name": "growth rate s c_s/R_i", "units": "1/s"})
        return xr.Dataset(data, coords=coords, attrs=self._attributes())

    def to_netcdf(self, path) -> None:
        """Write :meth:`to_xarray` as a netCDF-4 file (extra ``jaxdea[xarray]``; read it back with
        ``xarray.open_dataset``), whole or not at all.

        Raises:
            ImportError: xarray or netCDF4 is not installed (naming the extra).
        """
        if importlib.util.find_spec("netCDF4") is None:
            raise ImportError(f"SweepResult.to_netcdf needs netCDF4: {XARRAY_EXTRA}")
        dataset = self.to_xarray()
        with atomic_write(path) as tmp:
            dataset.to_netcdf(tmp, engine="netcdf4")

    def _attributes(self) -> dict:
        """The settings as netCDF attributes (numbers and strings; None left out, booleans as
        0/1), the fixed tube and fluid values as ``tube_*`` / ``fluid_*`` (swept ones left out)."""
        swept = {*self.axes, *(("eta",) if "thickness_ratio" in self.axes else ())}
        attrs = {}
        for key, value in self.settings.items():
            if isinstance(value, dict):
                attrs.update({f"{key}_{k}": v for k, v in value.items()
                              if v is not None and not (key in ("tube", "fluid") and k in swept)
                              and f"{key}_{k}" not in swept})
            elif key == "layers":  # layer<k>_<field>, as the sweep names them
                follows = any(re.fullmatch(r"layer\d+_fraction", name) for name in self.axes)
                for k, layer in enumerate(value):
                    if layer["active"] and follows:  # 1 − Σ f_passive at each point, not fixed
                        swept.add(f"layer{k}_fraction")
                    for field, v in layer.items():
                        for sub, x in (v.items() if isinstance(v, dict) else [(None, v)]):
                            name = f"layer{k}_{field}" if sub is None else f"layer{k}_{field}_{sub}"
                            if name not in swept:
                                attrs[name] = int(x) if isinstance(x, bool) else x
            elif value is not None:
                attrs[key] = int(value) if isinstance(value, bool) else value
        attrs["status_meaning"] = ", ".join(f"{s.value}: {s.name.lower()}" for s in Status)
        attrs["settings_json"] = json.dumps(self.settings)
        return attrs

    @classmethod
    def from_npz(cls, path) -> SweepResult:
        """Load a result saved by :meth:`to_npz`."""
        with np.load(path) as data:
            order = json.loads(str(data["axis_order"]))
            return cls(
                axes={name: data[f"axis:{name}"] for name in order},
                omega=data["omega"], status=data["status"], alpha=data["alpha"],
                jacobian=data["jacobian"] if "jacobian" in data else None,
                jacobian_names=tuple(json.loads(str(data["jacobian_names"]))),
                group_velocity=data["group_velocity"] if "group_velocity" in data else None,
                growth_rate=data["growth_rate"] if "growth_rate" in data else None,
                settings=json.loads(str(data["settings"])),
                lambda_i=data["lambda_i"] if "lambda_i" in data else None,
                omega_imag=data["omega_imag"] if "omega_imag" in data else None,
                quality_factor=data["quality_factor"] if "quality_factor" in data else None,
            )

    def __repr__(self) -> str:
        axes = ", ".join(f"{k}[{len(v)}]" for k, v in self.axes.items())
        ok = int(np.sum(self.status == Status.CONVERGED))
        return (f"SweepResult({axes}; {self.omega.shape[-1]} roots per point, "
                f"{ok}/{self.status.size} converged)")


def _point(values, tube, alpha, fluid, omega_max, n_roots, n_layers, order, jac_names, m=0.0,
           family=LONGITUDINAL, n_growth=0, decoupled=False):
    """Roots (and derivatives, and growth rates) at one grid point; ``values`` maps axis names to
    scalars (the circumferential order from the axis ``m`` if there is one, else ``m``; ``family``
    static; ``decoupled``: the roots on the 4×4 propagation of a grid without voltage,
    :func:`jaxdea.solve.roots.frequencies_unchecked`). Outputs: Ω, status, α̂, [growth rates,]
    [dΩ/dα̂, jacobian]."""
    point = apply_parameters(tube, alpha, fluid, values)
    nu = values["n"] if order == "n" else order
    m = values.get("m", m)
    roots = frequencies_unchecked(*point, omega_max, n_roots, n_layers, nu, m, family, decoupled)
    alpha_point = as_float(point[1])
    growth = ()
    if n_growth:  # the scan in Ω² = −s² (the 8×8 path at m = 0: docs/theory/order_m.md §6)
        growth = (growth_rates_unchecked(*point, None, n_growth, n_layers, nu, as_float(m),
                                         family.in_omega_squared).omega,)
    if jac_names is None:
        return roots.omega, roots.status, alpha_point, *growth
    held = {k: v for k, v in values.items() if k == "n"}  # α̂ of mode n follows the tube

    def residual(x):  # x = [Ω, δα̂, θ...]: f at the point moved by θ, α̂ shifted by δα̂
        moved = dict(zip(jac_names, x[2:], strict=True), **held)
        t, a, f = apply_parameters(*point, moved)
        _, t, a, f = guard(t, as_float(a) + x[1], f)
        return characteristic.value(family, discretize(t, n_layers), x[0], a, f, nu, m)

    theta = [get_parameter(*point, name) for name in jac_names]

    def derivatives(omega):
        x = jnp.stack([omega, jnp.zeros_like(omega), *theta])
        grad = jax.jacfwd(residual)(jnp.where(jnp.isfinite(x), x, 0.0))
        d = -grad[1:] / grad[0]
        return jnp.where(jnp.isfinite(omega), d, jnp.nan)

    d = jax.vmap(derivatives)(roots.omega)  # (n_roots, 1 + len(jac_names))
    jac = (d[:, 1:],) if jac_names else ()  # no zero-size outputs (lax.map cannot batch them)
    return roots.omega, roots.status, alpha_point, *growth, d[:, 0], *jac


@cached_jit(static_argnames=("names", "n_roots", "n_layers", "order", "jac_names",
                                             "batch_size", "family", "n_growth", "decoupled"))
def _sweep_chunk(columns, tube, alpha, fluid, omega_max, names, n_roots, n_layers, order, jac_names,
                 batch_size, m=0.0, family=LONGITUDINAL, n_growth=0, decoupled=False):
    """One chunk of grid points (columns: one array per axis): ``lax.map`` over the points,
    ``batch_size`` of them vectorised at a time. ``family`` (static) and ``m`` (traced, the fixed
    order when there is no axis ``m``): the mode family; the longitudinal program is unchanged.
    ``n_growth`` (static): growth rates per point (0: none). ``decoupled`` (static): the roots on
    the 4×4 propagation (a longitudinal grid whose every point is without voltage)."""
    def one(vals):
        values = dict(zip(names, vals, strict=True))
        if not (family.carries_m or n_growth):  # the longitudinal program as before order m existed
            return _point(values, tube, alpha, fluid, omega_max, n_roots, n_layers, order, jac_names,
                          decoupled=decoupled)
        return _point(values, tube, alpha, fluid, omega_max, n_roots, n_layers, order, jac_names,
                      m, family, n_growth, decoupled)

    return jax.lax.map(one, columns, batch_size=batch_size if batch_size > 1 else None)


def _solve_chunk(cols, base, omega_max, static, devices):
    """Ω, status, α̂ (and derivatives) of the points ``cols`` (one NumPy column per axis, all of the
    chunk length) as NumPy arrays.

    On several devices the chunk (padded with its last point to a multiple of their count) is laid
    out with a :class:`~jax.sharding.NamedSharding` over the 1-D mesh of the devices, split along its
    points, and every device runs the one-device program :func:`_sweep_chunk` on its own block
    (asynchronous dispatch: the blocks run at the same time); the outputs are assembled with the same
    sharding. The same compiled program on every device makes the numbers bit-identical to the
    one-device sweep (a ``shard_map`` of it was measured 1 ulp off at some points: XLA compiles the
    partitioned module differently).
    """
    count = len(cols[0])
    if len(devices) == 1:
        out = _sweep_chunk(tuple(jax.device_put(c, devices[0]) for c in cols), *base, omega_max,
                           **static)
        return [np.asarray(o)[:count] for o in out]
    pad = -count % len(devices)
    cols = tuple(np.concatenate([c, np.repeat(c[-1:], pad)]) for c in cols)
    sharding = NamedSharding(Mesh(np.array(devices), ("points",)), P("points"))
    arrays = jax.device_put(cols, sharding)
    static = dict(static, batch_size=min(static["batch_size"], len(cols[0]) // len(devices)))
    if "m" in static:  # the fixed order: a traced scalar, on each device with its block
        static = dict(static, m=np.float64(static["m"]))
    shards = [{shard.device: shard.data for shard in a.addressable_shards} for a in arrays]
    blocks = [_sweep_chunk(tuple(by_device[d] for by_device in shards), *base, omega_max, **static)
              for d in devices]  # block k of the mesh lies on devices[k]
    out = [jax.make_array_from_single_device_arrays((len(cols[0]), *parts[0].shape[1:]), sharding,
                                                    list(parts))
           for parts in zip(*blocks, strict=True)]
    return [np.asarray(o)[:count] for o in out]


def _remote_chunk(cols, base, omega_max, static):
    """A chunk solved in a Dask worker on all the worker's devices (64-bit floats switched on there
    first: the worker is a fresh process)."""
    jax.config.update("jax_enable_x64", True)
    if static["batch_size"] is None:  # the default of sweep, for the worker's backend
        static = dict(static, batch_size=1 if jax.default_backend() == "cpu" else len(cols[0]))
    base = jax.tree_util.tree_map(as_float, base)
    omega_max = None if omega_max is None else as_float(omega_max)
    return _solve_chunk(cols, base, omega_max, static, jax.devices())


def _devices(devices):
    """The devices a sweep runs on: all of the default backend's (None), the first k (an int), or
    the given sequence of distinct :class:`jax.Device`."""
    available = jax.devices()
    if devices is None:
        return available
    if isinstance(devices, (int, np.integer)) and not isinstance(devices, bool):
        if not 1 <= devices <= len(available):
            raise ValueError(f"devices must be between 1 and {len(available)} (the JAX devices), "
                             f"got {devices}")
        return available[: int(devices)]
    try:
        chosen = list(devices)
    except TypeError:
        chosen = None
    if not chosen or not all(isinstance(d, jax.Device) for d in chosen) or len(set(chosen)) < len(chosen):
        raise ValueError("devices must be None (all), an integer count or a non-empty sequence of "
                         f"distinct jax.Device, got {devices!r}")
    return chosen


def _axis(name, values):
    arr = real_value(f"axis {name!r}", values, scalar=False)
    if arr is None:
        raise ValueError(f"axis {name!r} must be concrete values (sweep is not traceable)")
    if arr.ndim > 1:
        raise ValueError(f"axis {name!r} must be a scalar or a 1-D array, got shape {arr.shape}")
    if arr.size == 0:
        raise ValueError(f"axis {name!r} is empty")
    return np.atleast_1d(arr)


def sweep_bytes(shape, n_roots: int, n_jacobian: int | None = None, n_growth: int = 0) -> int:
    """Estimated peak memory in bytes of a sweep over a grid of ``shape`` and of writing it: the
    grid's columns, the result arrays (Ω, status, α̂, growth rates, dΩ/dα̂ and ``n_jacobian``
    derivatives per root), and the CSV table of :meth:`SweepResult.to_csv` (its columns and the
    stacked table, float64)."""
    points, axes, k = math.prod(shape), len(shape), int(n_roots)
    derivatives = 0 if n_jacobian is None else k * (1 + n_jacobian)
    result = 8 + 12 * k + 8 * n_growth + 8 * derivatives  # the status once more as int32
    columns = axes + 1 + 2 * k + n_growth + derivatives
    return points * (8 * axes + result + 16 * columns)


def physical_memory() -> int | None:
    """The machine's physical memory in bytes, or None where the OS does not say."""
    try:
        return os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (AttributeError, ValueError, OSError):
        return None


def check_size(shape, n_roots: int, n_jacobian: int | None = None, n_growth: int = 0) -> None:
    """Refuse a grid of more than :data:`MAX_POINTS` points, or one whose arrays
    (:func:`sweep_bytes`) would take more than :data:`MEMORY_SHARE` of the physical memory, before
    anything is allocated.

    Raises:
        ValueError: naming the grid size or the memory and the limit.
    """
    points = math.prod(int(n) for n in shape)
    grid = " x ".join(str(int(n)) for n in shape)
    if points > MAX_POINTS:
        raise ValueError(f"the grid has {points:,} points ({grid}); a sweep takes at most "
                         f"MAX_POINTS = {MAX_POINTS:,}: split it into several sweeps")
    need, memory = sweep_bytes(shape, n_roots, n_jacobian, n_growth), physical_memory()
    if memory is not None and need > MEMORY_SHARE * memory:
        raise ValueError(f"the grid of {points:,} points ({grid}) needs about {need / 2**30:.1f} GiB, "
                         f"more than MEMORY_SHARE = {MEMORY_SHARE:g} of this machine's "
                         f"{memory / 2**30:.1f} GiB of memory: split it into several sweeps")


class SweepInterrupted(KeyboardInterrupt):
    """Ctrl-C (KeyboardInterrupt) stopped :func:`sweep`.

    Attributes:
        result: the :class:`SweepResult` of the points solved before it (the others NaN with status
            NOT_SOLVED, ``settings["incomplete"]`` True), or None if none was.
        solved: how many grid points were solved.
        total: the grid points.
    """

    def __init__(self, result, solved: int, total: int):
        super().__init__(f"sweep interrupted after {solved} of {total} points")
        self.result, self.solved, self.total = result, solved, total


def _grid_layers(n_layers, scheme, tube, fluid, grids, n_roots, m):
    """The static discretisation of a sweep: with ``n_layers=None`` the accurate discretisation's N
    (:func:`jaxdea.physics.transfer.laminate`) for the worst point of the grid (largest α̂ĥ, ĥ/r̂_i, m and
    closeness to locking)."""
    if n_layers is not None or scheme not in (None, AUTO_SCHEME):
        return laminate(n_layers, scheme)
    values = {k: np.asarray(v, np.float64) for k, v in grids.items() if k != "m"}
    alpha = values.pop("alpha", np.asarray(1.0)) if "n" not in values else None
    points, alpha_of_points, _ = apply_parameters(tube, alpha, fluid, values)
    orders = grids.get("m", m)
    return laminate(None, scheme, points, alpha_of_points, n_roots, orders)


def sweep(tube: Tube, fluid: Fluid | None = None, *, n_roots: int = 3, omega_max=None,
          n_layers: int | None = None, scheme: str | None = None, jacobian=None, chunk_size: int = CHUNK_SIZE,
          batch_size=None, progress=None, devices=None, client=None, m=0, torsional: bool = False,
          n_growth: int = 0, delta_p=None, outer: Fluid | None = None, **axes) -> SweepResult:
    """The ``n_roots`` lowest frequencies over the grid spanned by ``axes``.

    Args:
        tube: the base :class:`~jaxdea.Tube`; grid axes override its fields.
        fluid: a :class:`~jaxdea.Fluid` or None.
        outer: a surrounding :class:`~jaxdea.Fluid` (unbounded, ``"acoustic"``) or None: the tube's own
            ``tube.outer`` (None: vacuum). Subsonic modes carry its added mass
            (docs/theory/real_tubes.md §6).
        n_roots: K, roots per point (static).
        omega_max: upper end of each root search (None: automatic, see :func:`jaxdea.frequencies`).
        n_layers: sublayers N (static), or None: the accurate discretisation for the grid's
            worst point (:func:`jaxdea.frequencies`).
        scheme: ``"midpoint"``, ``"magnus4"`` or ``"magnus6"`` (static; :func:`jaxdea.frequencies`).
        jacobian: None (no derivatives), True (the sensitivity set (V̂, λ_i, λ_z, ρ̂_f, ĉ_f, h/R_i,
            G), fluid names dropped for an empty tube), or a sequence of parameter names. With it
            come the group velocities dΩ/dα̂.
        chunk_size: points per compiled chunk (memory ∝ chunk_size; one compilation for all chunks;
            the progress bar moves once per chunk).
        batch_size: points of a chunk solved side by side with ``vmap`` (the rest in sequence).
            None: 1 on CPU, where a vmapped root search runs as long as its slowest point and one
            point already vectorises its scan (batches of 8 and 32 measured no faster), else
            ``chunk_size`` (accelerators).
        progress: None (a tqdm bar once the run takes more than 2 s), True (always) or False.
        devices: the JAX devices that share each chunk: None (all devices of the default backend),
            an integer k (the first k) or a sequence of :class:`jax.Device`. With more than one, a
            chunk holds ``chunk_size`` points per device and is split along its points
            (``jax.sharding``); the numbers are those of the one-device sweep.
        client: a Dask ``distributed.Client`` (extra ``jaxdea[dask]``): the chunks are sent as
            tasks to its workers, each solving on all its own devices (``devices`` must then be
            None), and gathered in grid order. None: solve in this process.
        m: the circumferential order (docs/theory/order_m.md): an integer >= 0 (a fixed order, not an axis;
            0 the axisymmetric longitudinal family, as :func:`jaxdea.frequencies`), or a 1-D array
            of integers >= 0: a grid axis ``m`` (one compiled program for every order; at m = 0 the
            longitudinal family's roots through the order-m system).
        torsional: the torsional family (u_θ alone) instead; only with m = 0 (static).
        n_growth: growth rates s = √(−Ω²) of the unstable modes per point (static, >= 0; 0: none),
            largest first, as :func:`jaxdea.growth_rates` (searched up to the frequencies'
            automatic limit); ``SweepResult.growth_rate`` and ``.unstable``. ``frequencies`` lists
            only the positive real roots: past an instability its first column is the second
            branch, and ``unstable`` says so.
        delta_p: None (the tube held by its stretch: λ_i of ``tube`` or of an axis, at every
            voltage), or ΔP̂ = (P_i − P_o)/μ, a finite number: the tube held by this pressure
            difference, as in a lab. At every point λ_i is then the stable static state of
            ΔP̂_el(λ_i) − V̂² E(λ_i) = ΔP̂ (docs/theory/axisymmetric.md Eq. 1.1;
            :func:`jaxdea.inner_stretch`), so λ_i follows the voltage; ``SweepResult.lambda_i``
            holds it. ``jaxdea.pressure_difference(tube.replace(voltage=0))`` is the pressure that
            holds the tube's λ_i at V̂ = 0; ``Scales.pressure_from_si`` converts Pa. Past pull-in
            (no static state) a point is NaN, status INVALID. Not with an axis ``lambda_i`` or
            ``thickness_ratio`` (the deformed wall depends on λ_i: give ``eta``) or ``jacobian``.
        **axes: ``name=values`` grid axes (1-D arrays, or scalars for a fixed value) over the names
            of :mod:`jaxdea.physics.leaves`; exactly one of ``alpha`` / ``n`` is required. The
            wall's names (:func:`jaxdea.physics.leaves.wall_names`) are axes and jacobian names
            too: ``material_beta`` (a scalar parameter of the tube's material object),
            ``layer2_fraction``, ``layer2_shear_ratio``, ``layer2_density_ratio`` of a passive layer
            (k from 0, the innermost) and ``layer1_material_gent`` of any layer's material. A
            passive layer's fraction is taken from the active layer (f_active = 1 − Σ f_passive, η
            held): a point where it reaches 0 is NaN, status INVALID.

    Returns:
        An instance of :class:`SweepResult` with Ω of shape (*grid_shape, n_roots) in the order of ``axes``.

    Raises:
        ValueError: an unknown or repeated axis, a missing ``alpha``/``n``, bad settings, an
            order m that is not an integer >= 0 (or with ``torsional=True`` or the paper coupling
            not 0), naming m; a grid past :data:`MAX_POINTS` or the memory limit of
            :func:`check_size` (before anything is allocated). Values of the other axes are not
            validated point by point: an invalid point gives NaN, status INVALID.
        SweepInterrupted: Ctrl-C (a KeyboardInterrupt) during the solve; its ``result`` holds
            the points solved before it, the others NaN with status NOT_SOLVED and
            ``settings["incomplete"]`` True.

    Examples:
        >>> res = sweep(Tube(lambda_z=1.2), voltage=np.linspace(0, 0.2, 5), n=np.arange(1, 11))
        >>> res.omega.shape  # (5, 10, 3)
        >>> sweep(Tube(lambda_z=1.2), m=np.arange(4), alpha=0.445).omega.shape  # (4, 1, 3)
        >>> held = jd.pressure_difference(Tube(lambda_i=1.1, lambda_z=1.2))  # ΔP̂ at V̂ = 0
        >>> sweep(Tube(lambda_z=1.2), delta_p=held, voltage=[0, 0.2], n=1).lambda_i  # λ_i grows
    """
    tube = with_outer(tube, outer)
    require_x64()
    if not isinstance(tube, Tube):
        raise ValueError(f"tube must be a jaxdea.Tube, got {type(tube).__name__}")
    validate_fluid(fluid)  # its static choices and, when concrete, its values
    # the tube's values are not range-checked (an invalid value gives NaN and status INVALID at
    # every point, as on an axis), but they must be real scalars; fields set by an axis are not
    # used (placeholders NaN)
    overridden = set(axes) | ({"eta"} if "thickness_ratio" in axes else set())
    unused = {}
    for name in TUBE_LEAVES:
        try:
            real_value(name, getattr(tube, name))
        except ValueError:
            if name not in overridden:
                raise
            unused[name] = math.nan
    tube = tube.replace(**unused)
    if progress is not None and not isinstance(progress, bool):
        raise ValueError(f"progress must be None, True or False, got {progress!r}")
    validate_layers(n_layers)
    validate_scheme(scheme)
    auto_batch = batch_size is None  # with a client, chosen in each worker for its own backend
    if batch_size is None:
        batch_size = 1 if jax.default_backend() == "cpu" else chunk_size
    for name, value, low in (("n_roots", n_roots, 1), ("chunk_size", chunk_size, 1),
                             ("batch_size", batch_size, 1), ("n_growth", n_growth, 0)):
        if not isinstance(value, (int, np.integer)) or isinstance(value, bool) or value < low:
            raise ValueError(f"{name} must be an integer >= {low}, got {value!r}")
    validate_roots(n_roots)
    if n_growth > MAX_ROOTS:
        raise ValueError(f"n_growth must be <= MAX_ROOTS = {MAX_ROOTS}, got {n_growth!r}")
    m_axis, family = _orders(m, torsional, fluid)
    check_names(list(axes), fluid, tube=tube)
    if m_axis is not None:
        axes = {"m": m_axis, **axes}
    if "alpha" not in axes and "n" not in axes:
        raise ValueError("give the wavenumber axis: alpha=... (α̂) or n=... (axial mode numbers)")
    axes = {name: v if name == "m" else _axis(name, v) for name, v in axes.items()}
    jac_names = _jacobian_names(jacobian, fluid, tube)
    delta_p = _check_pressure(delta_p, axes, jac_names)
    if omega_max is not None:
        validate_positive("omega_max", omega_max, "a finite number > 0")
        omega_max = float(omega_max)
    order = _order(fluid, axes)
    if tube.damping is not None:
        return _complex_sweep(tube, fluid, axes, n_roots, omega_max, n_layers, scheme, m_axis, m,
                              torsional, progress, jacobian=jac_names, n_growth=n_growth,
                              delta_p=delta_p, client=client)

    if client is not None:
        if devices is not None:
            raise ValueError("devices must be None with a Dask client (each worker uses its own)")
        _check_client(client)
        devices = ()
    else:
        devices = _devices(devices)

    shape = tuple(len(v) for v in axes.values())
    total = math.prod(shape)
    check_size(shape, n_roots, len(jac_names) if jac_names is not None else None, n_growth)
    per_device = -(-total // max(len(devices), 1))
    size = min(int(chunk_size), 1 << (per_device - 1).bit_length())  # power of two ≤ chunk_size
    # at least 2 (the last point repeated): XLA removes a loop of one trip and fuses its body with
    # what surrounds it, so chunks of 1 gave implicit derivatives 6e-14 from every other chunk size
    size = max(size, 2)
    size *= max(len(devices), 1)  # points per chunk, a multiple of the device count
    grids = [g.ravel() for g in np.meshgrid(*axes.values(), indexing="ij")]
    names = tuple(axes)
    held = None
    if delta_p is not None:  # a column λ_i(point) beside the axes, solved from ΔP̂
        held = _held_stretch(tube, names, grids, delta_p)
        names, grids = (*names, "lambda_i"), [*grids, held]
        tube = tube.replace(lambda_i=1.0)  # replaced at every point
    layers = _grid_layers(n_layers, scheme, tube, fluid, dict(zip(names, grids, strict=True)),
                          n_roots, m)
    static = dict(names=names, n_roots=int(n_roots), n_layers=layers, order=order,
                  jac_names=jac_names, batch_size=min(int(batch_size), size))
    if family.carries_m or n_growth:  # the longitudinal program is called as before order m
        static.update(m=float(0 if m_axis is not None else m), family=family, n_growth=int(n_growth))
    if "voltage" not in names and without_voltage(tube, family):
        static.update(decoupled=True)  # no point has voltage: the 4×4 propagation (3× faster)
    starts = range(0, total, size)

    def chunk(start):  # every chunk has ``size`` points, the last one padded with its last point
        stop = min(start + size, total)
        return tuple(np.concatenate([g[start:stop], np.repeat(g[stop - 1], size - (stop - start))])
                     for g in grids)

    outputs = None
    solved = np.zeros(total, dtype=bool)
    bar = _progress_bar(total, progress)
    if client is None:
        base = jax.tree_util.tree_map(as_float, (tube, 1.0, fluid))
        w = None if omega_max is None else as_float(omega_max)
        results = ((start, _solve_chunk(chunk(start), base, w, static, devices)) for start in starts)
    else:
        base = jax.tree_util.tree_map(np.asarray, (tube, 1.0, fluid))
        static = dict(static, batch_size=None) if auto_batch else static
        results = _on_dask(client, [chunk(start) for start in starts], starts, base, omega_max, static)
    interrupted = False
    try:
        for start, out in results:
            stop = min(start + size, total)
            if outputs is None:
                outputs = [np.empty((total, *o.shape[1:]), o.dtype) for o in out]
            for buf, o in zip(outputs, out, strict=True):
                buf[start:stop] = o[: stop - start]
            solved[start:stop] = True
            bar.update(stop - start)
    except KeyboardInterrupt:
        interrupted = True
        results.close()  # a Dask run cancels its remaining tasks
    finally:
        bar.close()
    if interrupted and outputs is None:
        raise SweepInterrupted(None, 0, total)
    if interrupted:  # the points not reached: NaN, status NOT_SOLVED
        for buf in outputs:
            buf[~solved] = Status.NOT_SOLVED if np.issubdtype(buf.dtype, np.integer) else np.nan
    omega, status, alpha = outputs[:3]
    k = 4 if n_growth else 3  # the first output after the growth rates
    reshape = lambda a: a.reshape(*shape, *a.shape[1:])  # noqa: E731
    settings = _settings(tube, fluid, n_roots, omega_max, layers, m_axis, m, torsional)
    if delta_p is not None:
        settings["delta_p"] = delta_p
        settings["tube"]["lambda_i"] = None  # not fixed: solved from ΔP̂ at every point
    if n_growth:
        settings["n_growth"] = int(n_growth)
    if interrupted:
        settings["incomplete"] = True
    result = SweepResult(
        axes=axes, omega=reshape(omega), status=reshape(status).astype(np.int32),
        alpha=reshape(alpha),
        jacobian=None if jac_names is None else (
            reshape(outputs[k + 1]) if jac_names else np.empty((*shape, n_roots, 0))),
        jacobian_names=jac_names or (),
        group_velocity=None if jac_names is None else reshape(outputs[k]),
        growth_rate=reshape(outputs[3]) if n_growth else None,
        settings=settings,
        lambda_i=None if held is None else held.reshape(shape),
    )
    if interrupted:
        raise SweepInterrupted(result, int(solved.sum()), total)
    return result


def _complex_sweep(tube, fluid, axes, n_roots, omega_max, n_layers, scheme, m_axis, m, torsional,
                   progress, **unsupported):
    """:func:`sweep` of a damped tube (``tube.damping``): at every point the ``n_roots`` complex
    roots of :func:`jaxdea.complex_frequencies` (lowest Re Ω, certified), ``omega`` = Re Ω,
    ``omega_imag`` = Im Ω (e^{iΩt}: Im Ω > 0 decays) and ``quality_factor`` Q = Re Ω/(2 Im Ω)
    (docs/theory/real_tubes.md §4–§5); a point whose search is not certified has its roots
    SUSPECT (one may be missing below them). A Python loop (the search is not traceable); one
    discretisation for the grid (:func:`_grid_layers` of the undamped tube). A point whose search
    raises (an invalid value) is NaN, status INVALID.

    Raises:
        ValueError: naming ``tube.damping`` and the option, for ``jacobian``, ``n_growth``,
            ``delta_p`` or ``client`` (not with complex roots); an invalid damping law.
    """
    from ..params import validate_damping
    from ..solve.complex_frequencies import complex_frequencies

    validate_damping(tube.damping)
    for name, value in unsupported.items():
        if value:
            raise ValueError(f"tube.damping: a damped tube's sweep (complex roots) does not take "
                             f"{name}; remove it or sweep the undamped tube")
    shape = tuple(len(v) for v in axes.values())
    total = math.prod(shape)
    check_size(shape, n_roots)
    grids = dict(zip(axes, (g.ravel() for g in np.meshgrid(*axes.values(), indexing="ij")),
                     strict=True))
    named = {k: v for k, v in grids.items() if k != "m"}
    layers = _grid_layers(n_layers, scheme, tube.replace(damping=None), fluid, named, n_roots, m)
    omega = np.full((total, n_roots), complex(np.nan, np.nan))
    status = np.full((total, n_roots), int(Status.INVALID), np.int32)
    alpha = np.full(total, np.nan)
    bar = _progress_bar(total, progress)
    try:
        for i in range(total):
            point, a, fl = apply_parameters(tube, None, fluid,
                                            {k: float(v[i]) for k, v in named.items()})
            order = int(grids["m"][i]) if "m" in grids else int(m)
            try:
                alpha[i] = float(a)
                roots = complex_frequencies(point, alpha[i], fl, n_roots, m=order,
                                            omega_max=omega_max, n_layers=layers,
                                            torsional=torsional)
            except ValueError:
                bar.update(1)
                continue
            omega[i] = np.asarray(roots.omega)
            status[i] = np.asarray(roots.status)
            if int(roots.certificate) != 0:  # not every root in the box was found: indices unknown
                status[i] = np.where(status[i] == Status.CONVERGED, int(Status.SUSPECT), status[i])
            bar.update(1)
    finally:
        bar.close()
    settings = _settings(tube, fluid, n_roots, omega_max, layers, m_axis, m, torsional)
    settings.update(wall_settings(tube))  # the damping law (and the material) as JSON
    reshape = lambda a: a.reshape(*shape, *a.shape[1:])  # noqa: E731
    with np.errstate(divide="ignore", invalid="ignore"):
        quality = np.where(omega.imag == 0, np.inf, omega.real / (2.0 * omega.imag))
    return SweepResult(axes=axes, omega=reshape(omega.real), status=reshape(status),
                       alpha=reshape(alpha), settings=settings, omega_imag=reshape(omega.imag),
                       quality_factor=reshape(quality))


def _check_pressure(delta_p, axes, jac_names):
    """ΔP̂ as a float, or None; ValueError naming ``delta_p`` (or the clashing option)."""
    if delta_p is None:
        return None
    value = real_value("delta_p", delta_p)
    if value is None or not math.isfinite(value):
        raise ValueError("delta_p must be None (held by stretch) or a finite real number (ΔP̂ = "
                         f"ΔP/μ, the pressure difference that holds the tube), got {delta_p!r}")
    for name in ("lambda_i", "thickness_ratio"):
        if name in axes:
            raise ValueError(f"axis {name!r} with delta_p: λ_i follows from the pressure difference "
                             "at every point (give the wall as eta, the undeformed R_i/R_o)")
    if jac_names is not None:
        raise ValueError("jacobian with delta_p is not supported: the derivatives would be at "
                         "fixed λ_i, not at fixed pressure (sweep with jacobian=None)")
    return float(value)


@cached_jit(static_argnames=("names",))
def _held_stretch_points(tube, names, columns, delta_p):
    """λ_i of every point (vmapped :func:`jaxdea.physics.base_state.inner_stretch`; NaN past pull-in)."""
    def one(vals):
        point = apply_parameters(tube, 1.0, None, dict(zip(names, vals, strict=True)))[0]
        return inner_stretch_traced(point.replace(lambda_i=1.0), delta_p)[0]

    return jax.vmap(one)(columns)


def _held_stretch(tube, names, grids, delta_p):
    """The column λ_i (NumPy, one per point) of a pressure-held sweep."""
    columns = tuple(np.asarray(g, np.float64) for g in grids)
    keep = tuple(k for k in names if k not in ("alpha", "n", "m") and k not in FLUID_LEAVES)
    cols = tuple(c for k, c in zip(names, columns, strict=True) if k in keep)
    base = jax.tree_util.tree_map(as_float, tube)
    return np.asarray(_held_stretch_points(base, keep, cols, as_float(delta_p)))


def _orders(m, torsional, fluid):
    """(the axis ``m`` as a float64 array or None, the static family) of sweep's ``m``: a scalar is
    a fixed order (its family from :func:`jaxdea.physics.problem.family_of`), a 1-D array an axis of
    the order-m family (traced m; each value validated by ``family_of``)."""
    if np.ndim(m) == 0:
        return None, family_of(m, torsional, fluid)
    values = np.asarray(m)
    if values.ndim != 1 or values.size == 0:
        raise ValueError(f"m must be an integer >= 0 or a non-empty 1-D array of them, got {m!r}")
    if values.dtype == object or not np.issubdtype(values.dtype, np.number):
        raise ValueError(f"m must hold integers >= 0 (the circumferential order), got {m!r}")
    for value in values:
        family_of(value.item(), torsional, fluid)
    return values.astype(np.float64), family_of(0, torsional, fluid).in_omega_squared


def _check_client(client):
    try:
        from distributed import Client
    except ImportError as err:  # pragma: no cover - a client cannot exist without distributed
        raise ValueError("client needs Dask: pip install 'jaxdea[dask]'") from err
    if not isinstance(client, Client):
        raise ValueError(f"client must be a distributed.Client or None, got {type(client).__name__}")


def _on_dask(client, chunks, starts, base, omega_max, static):
    """Yield (start, outputs) per chunk as the workers finish them (any order: the caller places
    each chunk at its start)."""
    from distributed import as_completed

    futures = client.map(_remote_chunk, chunks, base=base, omega_max=omega_max, static=static,
                         pure=False)
    start_of = {f.key: start for f, start in zip(futures, starts, strict=True)}
    try:
        for future in as_completed(futures):
            yield start_of[future.key], future.result()
    finally:
        client.cancel(futures)


def _jacobian_names(jacobian, fluid, tube=None):
    if jacobian is None or jacobian is False:
        return None
    if jacobian is True:
        return tuple(n for n in SENSITIVITY if fluid is not None or n not in FLUID_LEAVES)
    try:
        names = (jacobian,) if isinstance(jacobian, str) else tuple(jacobian)
    except TypeError:
        names = None
    if names is None or not all(isinstance(n, str) for n in names):
        raise ValueError("jacobian must be None, True, a parameter name or a sequence of names, "
                         f"got {jacobian!r}")
    check_names(names, fluid, allow_n=False, tube=tube)
    if "alpha" in names:
        raise ValueError("jacobian: dΩ/dα̂ is the group velocity, returned with every jacobian; "
                         "drop 'alpha' from the names")
    if len(set(names)) != len(names):
        raise ValueError(f"jacobian names repeat: {names}")
    return names


def _order(fluid, axes):
    """The Bessel order: static int, or "n" (the paper's ν = n read from the n axis, traced)."""
    if not Face.of(fluid).has_poles:
        return 0
    if fluid.bessel_order is not None:
        return int(fluid.bessel_order)
    if "n" not in axes:
        raise ValueError("the paper coupling with bessel_order=None uses ν = n: sweep over n=... "
                         "(axial mode numbers), or set Fluid(bessel_order=...)")
    n = axes["n"]
    if np.any(n != np.round(n)) or np.any(n < 1):
        raise ValueError(f"n must hold integers >= 1 for the paper coupling (ν = n), got {n}")
    return "n"


def _settings(tube, fluid, n_roots, omega_max, layers, m_axis=None, m=0, torsional=False):
    leaf = lambda x: float(np.asarray(x)) if np.ndim(x) == 0 else np.asarray(x).tolist()  # noqa: E731
    count, scheme = split_layers(layers)
    out = {"tube": {k: leaf(getattr(tube, k)) for k in TUBE_LEAVES},
           "material": material_settings(tube.material),
           "n_roots": int(n_roots), "omega_max": omega_max, "n_layers": count,
           "scheme": scheme, "graded": is_graded(layers)}
    if tube.layers is not None:
        out["layers"] = wall_settings(tube)["layers"]
    if m_axis is None and int(m) != 0:
        out["m"] = int(m)
    if torsional:
        out["torsional"] = True
    if fluid is not None:
        out["fluid"] = {k: leaf(getattr(fluid, k)) for k in FLUID_LEAVES}
        out["coupling"] = fluid.coupling
        out["bessel_order"] = fluid.bessel_order
    return out


def material_settings(material):
    """A material as JSON: its static name, or ``{"kind": ..., parameter: value, ...}`` (the kinds of
    :data:`jaxdea.materials.KINDS`; a user's ``Energy`` as ``{"kind": "energy", "fn": its name,
    "params": ...}``)."""
    if isinstance(material, str):
        return material
    if isinstance(material, Energy):
        params = jax.tree_util.tree_map(lambda x: np.asarray(x).tolist(), material.params)
        return {"kind": "energy", "fn": getattr(material.fn, "__qualname__", repr(material.fn)),
                "params": params}
    kind = next(k for k, cls in KINDS.items() if type(material) is cls)
    return {"kind": kind, **{f.name: np.asarray(getattr(material, f.name)).tolist()
                             for f in dataclasses.fields(material)}}


def wall_settings(tube: Tube | None) -> dict:
    """``{"material": ..., "layers": [...]}`` of a tube's wall as JSON (:func:`material_settings`;
    ``layers`` only for a layered wall); {} for None."""
    if tube is None:
        return {}
    out = {"material": material_settings(tube.material)}
    if tube.layers is not None:
        leaf = lambda x: float(np.asarray(x))  # noqa: E731
        out["layers"] = [{"fraction": leaf(layer.fraction), "material": material_settings(layer.material),
                          "shear_ratio": leaf(layer.shear_ratio),
                          "density_ratio": leaf(layer.density_ratio), "active": layer.active}
                         for layer in tube.layers]
    if getattr(tube, "damping", None) is not None:
        out["damping"] = damping_settings(tube.damping)
    return out


def damping_settings(damping) -> dict:
    """A damping law as JSON: ``{"kind": ..., parameter: value, ...}`` (:data:`DAMPING_KINDS`)."""
    kind = next(k for k, cls in DAMPING_KINDS.items() if type(damping) is cls)
    return {"kind": kind, **{f.name: np.asarray(getattr(damping, f.name)).tolist()
                             for f in dataclasses.fields(damping)}}


def damping_from_settings(value: dict):
    """The damping law of :func:`damping_settings`."""
    params = {k: tuple(v) if isinstance(v, list) else v for k, v in value.items() if k != "kind"}
    return DAMPING_KINDS[value["kind"]](**params)


def wall_from_settings(settings: dict) -> Tube | None:
    """The wall (a :class:`~jaxdea.Tube` carrying the material and layers) of settings written by
    :func:`wall_settings`; None where they name none. A user's ``Energy`` cannot be rebuilt."""
    def material(value):
        if isinstance(value, str):
            return value
        if value.get("kind") not in KINDS:
            raise ValueError(f"the settings' material {value!r} cannot be rebuilt (a user's Energy "
                             "function is not stored): pass the material again")
        params = {k: tuple(v) if isinstance(v, list) else v for k, v in value.items() if k != "kind"}
        return KINDS[value["kind"]](**params)

    if "material" not in settings and "layers" not in settings:
        return None
    layers = settings.get("layers")
    if layers is not None:
        layers = tuple(Layer(**{**layer, "material": material(layer["material"])}) for layer in layers)
    damping = settings.get("damping")
    return Tube(material=material(settings.get("material", "gent")), layers=layers,
                damping=None if damping is None else damping_from_settings(damping))


class _NoBar:
    def update(self, n):
        pass

    def close(self):
        pass


def _progress_bar(total, progress):
    if progress is False:
        return _NoBar()
    from tqdm.auto import tqdm

    return tqdm(total=total, unit="pt", desc="jaxdea sweep", delay=0.0 if progress else 2.0,
                leave=bool(progress))

