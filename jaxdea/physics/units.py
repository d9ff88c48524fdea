"""SI units ↔ the dimensionless variables of jaxdea (docs/theory/axisymmetric.md §0).

jaxdea computes with lengths / R_i (undeformed inner radius), stresses and pressures / μ (shear
modulus), time / (R_i/c_s) with the shear-wave speed c_s = sqrt(μ/ρ_s), potentials / (R_i sqrt(μ/ε)):

    Ω = ω R_i/c_s,  f = Ω c_s/(2π R_i),  α̂ = α R_i,  V̂ = sqrt(ε/μ) V/R_i,  P̂ = P/μ,
    ĉ = c/c_s,  ρ̂_f = ρ_f/ρ_s,  ĉ_f = c_f/c_s,  D̂ = D/sqrt(με).

:class:`Scales` holds (μ, ρ_s, ε, R_i) and converts single quantities both ways; :func:`tube_from_si`,
:func:`fluid_from_si` and their inverses convert whole parameter sets. Everything is written with
``jax.numpy``: it accepts Python floats, NumPy and JAX arrays, is differentiable (``jax.grad`` with
respect to a modulus or a radius) and vmappable (a :class:`Scales` is a pytree). The conversions are
plain scalings, so a NaN (e.g. a NaN-padded root of :func:`jaxdea.frequencies`) stays NaN; the
scales and the physical inputs of the constructors are validated when concrete (``ValueError`` naming
the parameter).

Worked example (a VHB 4910-like acrylic tube filled with water; μ = 20 kPa, ρ_s = 960 kg/m³,
ε = 4.7 ε_0, R_i = 5 mm, R_o = R_i/0.85, L = 10 R_o, λ_i = 0.9, λ_z = 1.2, G = 97.2, V = 5 kV):

    >>> import jax
    >>> jax.config.update("jax_enable_x64", True)
    >>> import jaxdea as jd
    >>> from jaxdea.physics.units import VACUUM_PERMITTIVITY, Scales, fluid_from_si, tube_from_si
    >>> vhb = Scales(shear_modulus=20e3, density=960.0, permittivity=4.7 * VACUUM_PERMITTIVITY,
    ...              inner_radius=5e-3)
    >>> r_o = 5e-3 / 0.85
    >>> tube = tube_from_si(vhb, outer_radius=r_o, length=10 * r_o, voltage=5e3, lambda_i=0.9,
    ...                     lambda_z=1.2, gent=97.2)
    >>> water = fluid_from_si(vhb, fluid_density=1000.0, sound_speed=1480.0)
    >>> alpha = jd.axial_wavenumber(tube, 1)           # α̂ = 0.44506 (wavelength 70.6 mm)
    >>> omega = jd.frequencies(tube, alpha, water)[0]   # Ω = 0.19627
    >>> f_hz = vhb.omega_to_hz(omega)                   # 28.52 Hz

Here c_s = 4.5644 m/s (so Ω = 1 is 145.29 Hz), the voltage unit R_i sqrt(μ/ε) is 109.61 kV and
V̂ = 0.045615, ρ̂_f = 1.0417, ĉ_f = 324.25, ΔP̂ = −0.019847 (−396.9 Pa). The lowest frequency of the
axial mode n = 1 of the water-filled tube is Ω = 0.19627, f = 28.52 Hz (the fluid-loaded Korteweg
wave, phase speed 0.4410 c_s = 2.013 m/s; n_layers = 60 changes Ω by 2.5e-6 relative). Empty, the
same tube's lowest frequency is Ω = 0.76908, 111.74 Hz (the bar wave); filled with air
(ρ_f = 1.2 kg/m³, c_f = 343 m/s) it is 111.51 Hz.
"""

from __future__ import annotations

import dataclasses
import math
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from ..materials import FractionalKelvinVoigt, Gent, Hysteretic, KelvinVoigt, Prony
from ..params import (
    TINY,
    Fluid,
    Layer,
    Tube,
    require_x64,
    validate_broadcast,
    validate_damping,
    validate_fluid,
    validate_material,
    validate_tube,
    validate_wall_layers,
)
from .base_state import inner_stretch_traced

VACUUM_PERMITTIVITY = 8.8541878188e-12
"""ε_0 in F/m (CODATA 2022)."""

_TWO_PI = 2.0 * math.pi
_DB_PER_NEPER = 20.0 / math.log(10.0)  # dB of an amplitude ratio of e


def _number(name: str, x):
    """x as a float64 array; ValueError naming the parameter if it is no real number."""
    require_x64()
    if isinstance(x, (str, bytes, complex)) or (hasattr(x, "dtype") and jnp.iscomplexobj(x)):
        raise ValueError(f"{name} must be a real number, got {x!r}")
    try:
        return jnp.asarray(x, dtype=jnp.float64)
    except (TypeError, ValueError, OverflowError) as exc:
        raise ValueError(f"{name} must be a real number, got {x!r}") from exc


def _checked(name: str, x, allowed: str, ok, allow_inf: bool = False):
    """x as a float64 array; a concrete value outside ``ok`` raises ValueError naming the parameter
    (traced values are passed through: under ``jit``/``vmap`` they are the caller's business)."""
    out = _number(name, x)
    if isinstance(out, jax.core.Tracer):
        return out
    v = np.asarray(out)
    finite = np.isfinite(v) | (allow_inf & (v == np.inf))
    if not np.all(finite):
        raise ValueError(f"{name} must be finite and {allowed}, got {x!r}")
    good = ok(np.where(np.abs(v) < TINY, 0.0, v))  # as XLA sees it: subnormals flushed to 0
    if not np.all(good):
        bad = float(np.ravel(v[~good] if v.ndim else v)[0])
        note = " (a subnormal number: XLA flushes it to 0)" if 0 < abs(bad) < TINY else ""
        raise ValueError(f"{name} must be {allowed}, got {bad!r}{note}")
    return out


def _positive(name: str, x, unit: str = ""):
    return _checked(name, x, f"> 0{' (' + unit + ')' if unit else ''}", lambda v: v > 0)


def _positive_or_nan(name: str, x, unit: str = ""):
    """x as a float64 array: concrete values must be NaN (a NaN-padded result passes through) or
    finite and > 0 (the argument of a reciprocal conversion: 0 or a sign would give a meaningless
    wavelength)."""
    out = _number(name, x)
    if isinstance(out, jax.core.Tracer):
        return out
    v = np.asarray(out)
    bad = ~np.isnan(v) & ~(np.isfinite(v) & (v >= TINY))
    if np.any(bad):
        raise ValueError(f"{name} must be finite and > 0{' (' + unit + ')' if unit else ''} "
                         f"(or NaN), got {float(np.ravel(v[bad] if v.ndim else v)[0])!r}")
    return out


def _check_scales(scales) -> None:
    if not isinstance(scales, Scales):
        raise ValueError(f"scales must be a jaxdea.physics.units.Scales, got {type(scales).__name__}")


def _derived(name: str, value, inputs: str, allowed: str, ok) -> None:
    """A concrete parameter derived from SI inputs (e.g. η = R_i/R_o) must be in its range after
    rounding; the ValueError names the inputs it came from."""
    if isinstance(value, jax.core.Tracer):
        return
    v = np.asarray(value)
    with np.errstate(invalid="ignore"):
        good = ok(np.where(np.abs(v) < TINY, 0.0, v))  # as XLA sees it
    if not np.all(good):
        bad = float(np.ravel(v[~good] if v.ndim else v)[0])
        raise ValueError(f"{inputs} give {name} = {bad!r} in float64, which must be {allowed}")


_FIELDS = ("shear_modulus", "density", "permittivity", "inner_radius")


@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class Scales:
    """The material and size scales that make jaxdea's variables dimensionless (docs/theory/axisymmetric.md §0).

    A pytree (every field a differentiable, vmappable leaf). Fields are kept as given (so a
    ``Scales`` can serve as a ``jax.vmap`` ``in_axes`` spec); they are validated (positive, finite)
    whenever a conversion uses them with concrete values.

    Attributes:
        shear_modulus: μ in Pa (the small-strain shear modulus of the elastomer).
        density: ρ_s in kg/m³ (the elastomer's mass density).
        permittivity: ε in F/m (absolute; e.g. ``4.7 * VACUUM_PERMITTIVITY``).
        inner_radius: R_i in m (undeformed inner radius, the length scale).

    Examples:
        >>> vhb = Scales(20e3, 960.0, 4.7 * VACUUM_PERMITTIVITY, 5e-3)
        >>> vhb.omega_to_hz(1.0)    # c_s/(2π R_i) = 145.3 Hz
    """

    shear_modulus: float
    density: float
    permittivity: float
    inner_radius: float

    def _values(self):
        """(μ, ρ_s, ε, R_i) as float64 arrays, validated when concrete (positive, finite, and
        array fields of shapes that broadcast together)."""
        values = (_positive("shear_modulus", self.shear_modulus, "Pa"),
                  _positive("density", self.density, "kg/m^3"),
                  _positive("permittivity", self.permittivity, "F/m"),
                  _positive("inner_radius", self.inner_radius, "m"))
        validate_broadcast("Scales", {k: None if isinstance(v, jax.core.Tracer) else v
                                      for k, v in zip(_FIELDS, values, strict=True)})
        return values

    def _argument(self, name: str, x, positive: bool = False):
        """The argument of a conversion as a float64 array (ValueError naming it if it is no real
        number, if ``positive`` and a concrete value is neither > 0 nor NaN, or if its shape does
        not broadcast with the fields)."""
        out = _positive_or_nan(name, x) if positive else _number(name, x)
        if isinstance(out, jax.core.Tracer):
            return out
        shapes = {}
        for field in _FIELDS:
            value = getattr(self, field)
            if not isinstance(value, jax.core.Tracer):
                try:  # the shape alone (no cast: a complex field would warn, then fail by name)
                    shapes[field] = np.shape(value)
                except (TypeError, ValueError):
                    pass  # not a number: refused by _values with its name
        try:
            np.broadcast_shapes(np.shape(out), *shapes.values())
        except ValueError as exc:
            fields = ", ".join(f"{k} {v}" for k, v in shapes.items() if v)
            raise ValueError(f"{name} of shape {np.shape(out)} does not broadcast with the Scales "
                             f"fields ({fields})") from exc
        return out

    def replace(self, **changes) -> Scales:
        """A copy with some fields changed."""
        return dataclasses.replace(self, **changes)

    # derived scales
    @property
    def shear_speed(self):
        """c_s = sqrt(μ/ρ_s) in m/s, the speed unit (Ω/α̂ and dΩ/dα̂ are in units of c_s)."""
        mu, rho, _, _ = self._values()
        return jnp.sqrt(mu / rho)

    @property
    def time_scale(self):
        """R_i/c_s in s, the time unit (Ω = ω R_i/c_s)."""
        return _positive("inner_radius", self.inner_radius, "m") / self.shear_speed

    @property
    def voltage_scale(self):
        """R_i sqrt(μ/ε) in V, the voltage unit (V̂ = V/(R_i sqrt(μ/ε)))."""
        mu, _, eps, ri = self._values()
        return ri * jnp.sqrt(mu / eps)

    # lengths
    def length_to_si(self, length):
        """A length ℓ = ℓ̂ R_i in m (e.g. a radius r̂ of :func:`jaxdea.mode_shape` or ū)."""
        return self._argument("length", length) * self._values()[3]

    def length_from_si(self, length):
        """ℓ̂ = ℓ/R_i from a length in m."""
        return self._argument("length", length) / self._values()[3]

    # frequencies
    def omega_to_si(self, omega):
        """The angular frequency ω = Ω c_s/R_i in rad/s."""
        return self._argument("omega", omega) / self.time_scale

    def omega_from_si(self, omega):
        """Ω = ω R_i/c_s from an angular frequency ω in rad/s."""
        return self._argument("omega", omega) * self.time_scale

    def omega_to_hz(self, omega):
        """The frequency f = Ω c_s/(2π R_i) in Hz of a dimensionless Ω."""
        return self.omega_to_si(omega) / _TWO_PI

    def hz_to_omega(self, frequency):
        """Ω = 2π f R_i/c_s from a frequency f in Hz."""
        return _TWO_PI * self._argument("frequency", frequency) * self.time_scale

    # wavenumbers and speeds
    def wavenumber_to_si(self, alpha):
        """The axial wavenumber α = α̂/R_i in rad/m."""
        return self._argument("alpha", alpha) / self._values()[3]

    def wavenumber_from_si(self, alpha):
        """α̂ = α R_i from a wavenumber α in rad/m."""
        return self._argument("alpha", alpha) * self._values()[3]

    def attenuation_to_db_per_m(self, attenuation):
        """The attenuation |Im α|·20 log10(e) in dB/m of a dimensionless |Im α̂| (the ``attenuation``
        of :func:`jaxdea.wavenumbers`): the amplitude falls by that many dB per metre along z."""
        return _DB_PER_NEPER * self.wavenumber_to_si(self._argument("attenuation", attenuation))

    def wavelength_to_si(self, alpha):
        """The axial wavelength 2π/α = 2π R_i/α̂ in m of a dimensionless α̂ > 0 (NaN stays NaN)."""
        return _TWO_PI / self.wavenumber_to_si(self._argument("alpha", alpha, positive=True))

    def wavelength_from_si(self, wavelength):
        """α̂ = 2π R_i/Λ from a wavelength Λ > 0 in m (NaN stays NaN)."""
        return _TWO_PI * self._values()[3] / self._argument("wavelength", wavelength, positive=True)

    def speed_to_si(self, speed):
        """A speed c = ĉ c_s in m/s: a phase speed Ω/α̂ or a group velocity dΩ/dα̂."""
        return self._argument("speed", speed) * self.shear_speed

    def speed_from_si(self, speed):
        """ĉ = c/c_s from a speed in m/s."""
        return self._argument("speed", speed) / self.shear_speed

    # stresses and electrical quantities
    def pressure_to_si(self, pressure):
        """A pressure or stress P = P̂ μ in Pa (e.g. :func:`jaxdea.pressure_difference`)."""
        return self._argument("pressure", pressure) * self._values()[0]

    def pressure_from_si(self, pressure):
        """P̂ = P/μ from a pressure or stress in Pa."""
        return self._argument("pressure", pressure) / self._values()[0]

    def voltage_to_si(self, voltage):
        """The voltage V = V̂ R_i sqrt(μ/ε) in V."""
        return self._argument("voltage", voltage) * self.voltage_scale

    def voltage_from_si(self, voltage):
        """V̂ = sqrt(ε/μ) V/R_i from a voltage in V."""
        return self._argument("voltage", voltage) / self.voltage_scale

    def displacement_field_to_si(self, displacement):
        """An electric displacement D = D̂ sqrt(με) in C/m²."""
        mu, _, eps, _ = self._values()
        return self._argument("displacement", displacement) * jnp.sqrt(mu * eps)

    def displacement_field_from_si(self, displacement):
        """D̂ = D/sqrt(με) from an electric displacement in C/m²."""
        mu, _, eps, _ = self._values()
        return self._argument("displacement", displacement) / jnp.sqrt(mu * eps)


class TubeSI(NamedTuple):
    """A tube in SI units (the keyword arguments of :func:`tube_from_si`).

    Attributes:
        outer_radius: R_o in m (undeformed).
        length: L in m (undeformed).
        voltage: V in V.
        lambda_i: the inner stretch λ_i (dimensionless).
        lambda_z: the axial stretch λ_z (dimensionless).
        gent: the Gent constant G (dimensionless).
    """

    outer_radius: jax.Array
    length: jax.Array
    voltage: jax.Array
    lambda_i: jax.Array
    lambda_z: jax.Array
    gent: jax.Array


class FluidSI(NamedTuple):
    """A fluid in SI units: ``fluid_density`` ρ_f in kg/m³ and ``sound_speed`` c_f in m/s."""

    fluid_density: jax.Array
    sound_speed: jax.Array


class LayerSI(NamedTuple):
    """One layer of a wall in SI units (:func:`layers_from_si`), from the inner face outwards.

    Attributes:
        thickness: its undeformed thickness in m (> 0).
        shear_modulus: its small-strain shear modulus μ_k in Pa, or None for the scales' μ (the
            active layer's, which sets the units).
        density: its mass density ρ_k in kg/m³, or None for the scales' ρ_s.
        material: its energy, a material object normalised to unit shear modulus
            (:mod:`jaxdea.materials`; dimensionless, passed through).
        active: True for the one dielectric layer with electrodes on its faces.
        damping: None or a damping law of :mod:`jaxdea.materials` with SI values
            (:func:`damping_from_si`).
    """

    thickness: jax.Array
    shear_modulus: jax.Array | None = None
    density: jax.Array | None = None
    material: object = Gent()
    active: bool = False
    damping: object = None


WATER = FluidSI(fluid_density=998.2, sound_speed=1482.0)
"""Water at 20 °C (ρ = 998.2 kg/m³, c = 1482 m/s): ``fluid_from_si(scales, WATER)``."""
AIR = FluidSI(fluid_density=1.204, sound_speed=343.2)
"""Air at 20 °C and 1 atm (ρ = 1.204 kg/m³, c = 343.2 m/s)."""
SILICONE_OIL = FluidSI(fluid_density=960.0, sound_speed=985.0)
"""A 50 cSt polydimethylsiloxane oil at 25 °C (ρ ≈ 960 kg/m³, c ≈ 985 m/s; grades differ by a few
per cent), the usual bath of DEA tests."""


def tube_from_si(scales: Scales, outer_radius=None, length=None, voltage=0.0, lambda_i=None,
                 lambda_z=1.0, gent=97.2, material="gent", pressure=None, layers=None,
                 damping=None) -> Tube:
    """The dimensionless :class:`~jaxdea.Tube` of a tube given in SI units (docs/theory/axisymmetric.md §0).

    η = R_i/R_o, length_ratio = L/R_o, V̂ = sqrt(ε/μ) V/R_i; the stretches and G are dimensionless
    already and are passed through. A tube held by a pressure difference, as in a lab, is given by
    ``pressure`` ΔP = P_i − P_o in Pa instead of λ_i: λ_i is then the stable static state at
    ΔP̂ = ΔP/μ and the voltage, the root of ΔP̂_el(λ_i) − V̂² E(λ_i) = ΔP̂
    (docs/theory/axisymmetric.md Eq. 1.1, :func:`jaxdea.inner_stretch`), so it follows the voltage.
    Concrete inputs are validated as the solvers validate a Tube:
    positive and finite, the material, and the Gent locking limit of the resulting wall (the
    message states the largest I_1 - 3 against G).

    A layered wall is given by ``layers``, a sequence of :class:`LayerSI` from the inner face
    outwards (:func:`layers_from_si`): R_o = R_i + Σ thickness_k, and the scales are the active
    layer's (μ, ρ_s, ε).

    Args:
        scales: the :class:`Scales` (R_i is ``scales.inner_radius``).
        outer_radius: undeformed outer radius R_o > R_i in m; with ``layers`` it may be left out
            (None), and if given it must equal R_i + Σ thickness_k.
        length: undeformed length L > 0 in m (enters only :func:`jaxdea.axial_wavenumber`).
        voltage: V in V (any finite value; only V² matters).
        lambda_i: inner circumferential stretch r_i/R_i > 0 (default 1; not with ``pressure``).
        lambda_z: axial stretch l/L > 0.
        gent: Gent constant G > 0 (``inf`` for neo-Hookean).
        material: the energy, as in :class:`~jaxdea.Tube`: a static name or a material object
            (dimensionless; not with ``layers``).
        pressure: None (held by its stretch ``lambda_i``) or the pressure difference ΔP in Pa
            (finite) that holds the tube; differentiable, and NaN past pull-in when traced.
        layers: None (one active wall) or a sequence of :class:`LayerSI`.
        damping: None or a damping law of :mod:`jaxdea.materials` with SI values (Pa, s:
            :func:`damping_from_si`); not with ``layers`` (give each :class:`LayerSI` its own).

    Returns:
        An instance of :class:`~jaxdea.Tube`.

    Raises:
        ValueError: naming the parameter, for concrete values out of range (e.g. R_o ≤ R_i, a
            wall past Gent locking), ``lambda_i`` and ``pressure`` both given, or a pressure
            with no stable static state at that voltage (past pull-in).

    Examples:
        >>> tube = tube_from_si(vhb, outer_radius=5e-3 / 0.85, length=0.0588, voltage=5e3)
        >>> held = tube_from_si(vhb, 5e-3 / 0.85, 0.0588, voltage=5e3, pressure=-397.0)
        >>> float(held.lambda_i)  # ≈ 0.9: the pressure of the worked example at 5 kV
    """
    _check_scales(scales)
    _, _, _, ri = scales._values()
    if layers is not None:
        if not (isinstance(material, str) and material == "gent") or damping is not None:
            raise ValueError("material and damping belong to each LayerSI when layers are given: "
                             "leave the tube's at their defaults")
        wall = _thicknesses(layers)
        inner_to_outer = ri + sum(wall)
        if outer_radius is not None:
            r_o = _positive("outer_radius", outer_radius, "m")
            if not any(isinstance(x, jax.core.Tracer) for x in (r_o, inner_to_outer)) and not \
                    np.allclose(r_o, inner_to_outer, rtol=1e-9, atol=0.0):
                raise ValueError(f"outer_radius = {outer_radius!r} m must equal inner_radius + the "
                                 f"layers' thicknesses = {float(np.ravel(inner_to_outer)[0])!r} m "
                                 "(or be left out)")
        outer_radius = inner_to_outer
        layers = layers_from_si(scales, layers)
    elif outer_radius is None:
        raise ValueError("outer_radius: the undeformed outer radius R_o in m is required (or "
                         "layers, whose thicknesses give it)")
    if length is None:
        raise ValueError("length: the undeformed length L in m is required")
    if not isinstance(material, str):
        validate_material(material)
    if damping is not None:
        damping = damping_from_si(scales, damping)
    r_o = _positive("outer_radius", outer_radius, "m")
    length = _positive("length", length, "m")
    v = _checked("voltage", voltage, "a real number (V)", lambda x: np.isreal(x))
    if pressure is not None and lambda_i is not None:
        raise ValueError("give lambda_i (a tube held by its stretch) or pressure (held by a "
                         "pressure difference, λ_i solved), not both")
    if pressure is not None:
        pressure = _checked("pressure", pressure, "a real number (Pa)", np.isreal)
    lambda_i = _positive("lambda_i", 1.0 if lambda_i is None else lambda_i)
    lambda_z = _positive("lambda_z", lambda_z)
    gent = _checked("gent", gent, "> 0 (inf for neo-Hookean)", lambda x: x > 0, allow_inf=True)
    concrete = lambda x: None if isinstance(x, jax.core.Tracer) else x  # noqa: E731
    validate_broadcast("tube_from_si", dict(
        inner_radius=concrete(ri), outer_radius=concrete(r_o), length=concrete(length),
        voltage=concrete(v), lambda_i=concrete(lambda_i), lambda_z=concrete(lambda_z),
        gent=concrete(gent)))
    if not isinstance(r_o, jax.core.Tracer) and not isinstance(ri, jax.core.Tracer):
        if np.any(np.asarray(r_o) <= np.asarray(ri)):
            raise ValueError(f"outer_radius must be > inner_radius = {float(np.min(ri))!r} m, "
                             f"got {outer_radius!r}")
    eta, length_ratio, v_hat = ri / r_o, length / r_o, scales.voltage_from_si(v)
    _derived("eta", eta, "inner_radius and outer_radius", "in the open interval (0, 1)",
             lambda x: (x > 0) & (x < 1))
    _derived("length_ratio", length_ratio, "length and outer_radius", "finite and > 0",
             lambda x: np.isfinite(x) & (x > 0))
    _derived("voltage", v_hat, "voltage and the scales", "finite", np.isfinite)
    tube = Tube(voltage=v_hat, lambda_i=lambda_i, lambda_z=lambda_z, eta=eta, gent=gent,
                length_ratio=length_ratio, material=material, layers=layers, damping=damping)
    validate_tube(tube, scalar=False)  # the material, and Gent locking of the wall
    if pressure is None:
        return tube
    delta_p = scales.pressure_from_si(pressure)
    lambda_i = _held_stretch(tube, delta_p)
    if not isinstance(lambda_i, jax.core.Tracer) and not np.all(np.isfinite(lambda_i)):
        raise ValueError(f"pressure = {float(np.ravel(pressure)[0])!r} Pa has no stable static "
                         f"state at voltage = {voltage!r} V (ΔP̂ = {float(np.ravel(delta_p)[0])!r}: "
                         "past pull-in, jaxdea.pull_in): the pressure must lie below the pull-in "
                         "pressure")
    tube = tube.replace(lambda_i=lambda_i)
    validate_tube(tube, scalar=False)  # Gent locking at the solved stretch
    return tube


def _held_stretch(tube: Tube, delta_p):
    """λ_i held by ΔP̂ (:func:`jaxdea.physics.base_state.inner_stretch`), elementwise over array leaves."""
    def one(voltage, lambda_z, eta, gent, length_ratio, dp):
        t = tube.replace(voltage=voltage, lambda_i=1.0, lambda_z=lambda_z, eta=eta, gent=gent,
                         length_ratio=length_ratio)
        return inner_stretch_traced(t, dp)[0]

    leaves = [jnp.asarray(getattr(tube, k), jnp.float64)
              for k in ("voltage", "lambda_z", "eta", "gent", "length_ratio")]
    return jnp.vectorize(one)(*leaves, delta_p)


def tube_to_si(scales: Scales, tube: Tube) -> TubeSI:
    """The SI description of a dimensionless tube: R_o = R_i/η, L = length_ratio·R_o, V = V̂ R_i sqrt(μ/ε).

    ``tube_from_si(scales, **tube_to_si(scales, tube)._asdict())`` gives back ``tube``.
    """
    _check_scales(scales)
    validate_tube(tube, scalar=False)
    _, _, _, ri = scales._values()
    eta = _checked("eta", tube.eta, "in the open interval (0, 1)", lambda v: (v > 0) & (v < 1))
    r_o = ri / eta
    return TubeSI(
        outer_radius=r_o,
        length=_positive("length_ratio", tube.length_ratio) * r_o,
        voltage=scales.voltage_to_si(tube.voltage),
        lambda_i=_number("lambda_i", tube.lambda_i),
        lambda_z=_number("lambda_z", tube.lambda_z),
        gent=_number("gent", tube.gent),
    )


def fluid_from_si(scales: Scales, fluid_density, sound_speed=None, coupling: str = "acoustic",
                  bessel_order: int | None = None) -> Fluid:
    """The dimensionless :class:`~jaxdea.Fluid`: ρ̂_f = ρ_f/ρ_s, ĉ_f = c_f/c_s (docs/theory/axisymmetric.md §0),
    for a filling (``fluid=``) or a surrounding fluid (``outer=``).

    Args:
        scales: the :class:`Scales` (ρ_s and c_s = sqrt(μ/ρ_s) come from it).
        fluid_density: ρ_f > 0 in kg/m³ (water ≈ 1000, air ≈ 1.2), or a :class:`FluidSI` such as
            the presets :data:`WATER`, :data:`AIR`, :data:`SILICONE_OIL` (then no ``sound_speed``).
        sound_speed: c_f > 0 in m/s (water ≈ 1480, air ≈ 343).
        coupling: ``"acoustic"`` (consistent, default) or ``"paper"`` (docs/theory/axisymmetric.md §4).
        bessel_order: the ``"paper"`` coupling's Bessel order, as in :class:`~jaxdea.Fluid`.

    Raises:
        ValueError: naming the parameter, for concrete values that are not positive and finite.

    Examples:
        >>> water = fluid_from_si(vhb, fluid_density=1000.0, sound_speed=1480.0)
    """
    _check_scales(scales)
    if isinstance(fluid_density, FluidSI):
        if sound_speed is not None:
            raise ValueError("sound_speed: give a FluidSI preset alone, or fluid_density and "
                             "sound_speed")
        fluid_density, sound_speed = fluid_density
    elif sound_speed is None:
        raise ValueError("sound_speed: the fluid's sound speed in m/s is required (or give a "
                         "FluidSI such as jaxdea.units.WATER)")
    _, rho_s, _, _ = scales._values()
    density_ratio = _positive("fluid_density", fluid_density, "kg/m^3") / rho_s
    speed_ratio = scales.speed_from_si(_positive("sound_speed", sound_speed, "m/s"))
    positive = lambda x: np.isfinite(x) & (x > 0)  # noqa: E731
    _derived("density_ratio", density_ratio, "fluid_density and density", "finite and > 0",
             positive)
    _derived("speed_ratio", speed_ratio, "sound_speed and the scales (shear_modulus, density)",
             "finite and > 0", positive)
    fluid = Fluid(density_ratio=density_ratio, speed_ratio=speed_ratio, coupling=coupling,
                  bessel_order=bessel_order)
    validate_fluid(fluid, scalar=False)  # coupling, bessel_order, shapes
    return fluid


def fluid_to_si(scales: Scales, fluid: Fluid) -> FluidSI:
    """ρ_f = ρ̂_f ρ_s and c_f = ĉ_f c_s of a dimensionless fluid (inverse of :func:`fluid_from_si`)."""
    _check_scales(scales)
    if fluid is None or not isinstance(fluid, Fluid):
        raise ValueError(f"fluid must be a jaxdea.Fluid, got {type(fluid).__name__}")
    validate_fluid(fluid, scalar=False)
    _, rho_s, _, _ = scales._values()
    return FluidSI(fluid_density=_number("density_ratio", fluid.density_ratio) * rho_s,
                   sound_speed=scales.speed_to_si(fluid.speed_ratio))


def _thicknesses(layers) -> list:
    """The layers' thicknesses in m, validated (a non-empty sequence of :class:`LayerSI`)."""
    if isinstance(layers, LayerSI) or not isinstance(layers, (list, tuple)) or not layers or \
            not all(isinstance(x, LayerSI) for x in layers):
        raise ValueError("layers must be a non-empty sequence of jaxdea.units.LayerSI, from the "
                         f"inner face outwards, got {layers!r}")
    return [_positive(f"layers[{k}].thickness", x.thickness, "m") for k, x in enumerate(layers)]


def layers_from_si(scales: Scales, layers) -> tuple:
    """The :class:`~jaxdea.Layer` tuple of a wall given in SI (docs/theory/real_tubes.md §3):
    fraction_k = t_k/Σt, shear_ratio = μ_k/μ, density_ratio = ρ_k/ρ_s, damping by
    :func:`damping_from_si`.

    The scales (μ, ρ_s) are the active layer's, since it sets the units: its ``shear_modulus`` and
    ``density`` are None or equal to the scales' (to 1e-9).

    Args:
        scales: the :class:`Scales`.
        layers: a sequence of :class:`LayerSI` from the inner face outwards, exactly one active.

    Raises:
        ValueError: naming the layer and field (``layers[2].shear_modulus``), for values that are not
            positive and finite, an active layer whose modulus or density is not the scales', or a
            wall that is not valid (:class:`~jaxdea.Layer`: exactly one active layer).

    Examples:
        >>> vhb = Scales(20e3, 960.0, 4.7 * VACUUM_PERMITTIVITY, 5e-3)
        >>> wall = layers_from_si(vhb, [LayerSI(0.8e-3, active=True),
        ...                             LayerSI(0.2e-3, shear_modulus=60e3, density=1100.0,
        ...                                     material=jd.NeoHookean())])
        >>> wall[1].shear_ratio, wall[1].fraction   # 3.0, 0.2
    """
    _check_scales(scales)
    thickness = _thicknesses(layers)
    mu, rho_s, _, _ = scales._values()
    total = sum(thickness)
    out = []
    for k, (layer, t) in enumerate(zip(layers, thickness, strict=True)):
        name = f"layers[{k}]"
        if not isinstance(layer.active, bool):
            raise ValueError(f"{name}.active must be True or False, got {layer.active!r}")
        ratios = []
        for field, unit, scale in (("shear_modulus", "Pa", mu), ("density", "kg/m^3", rho_s)):
            value = getattr(layer, field)
            if value is None:
                ratios.append(jnp.ones_like(scale))
                continue
            value = _positive(f"{name}.{field}", value, unit)
            ratio = value / scale
            if layer.active and not any(isinstance(x, jax.core.Tracer) for x in (ratio,)) and \
                    not np.allclose(ratio, 1.0, rtol=1e-9, atol=0.0):
                raise ValueError(f"{name}.{field} = {float(np.ravel(value)[0])!r} {unit} must be "
                                 f"the scales' {field} ({float(np.ravel(scale)[0])!r} {unit}) or "
                                 "None: the active layer sets the units")
            ratios.append(jnp.ones_like(ratio) if layer.active else ratio)
        damping = None if layer.damping is None else damping_from_si(scales, layer.damping,
                                                                      name=f"{name}.damping")
        out.append(Layer(fraction=t / total, material=layer.material, shear_ratio=ratios[0],
                         density_ratio=ratios[1], active=layer.active, damping=damping))
    out = tuple(out)
    validate_wall_layers(Tube(layers=out))
    return out


def damping_from_si(scales: Scales, law, name: str = "damping"):
    """A damping law with SI values made dimensionless (docs/theory/real_tubes.md §4): moduli over
    μ (Pa), times over R_i/c_s (s), a Kelvin–Voigt viscosity over μR_i/c_s (Pa s); a fractional
    order, a stretch coupling and a hysteretic loss are dimensionless and pass through. So
    η*(ω) in Pa over μ is the dimensionless η*(Ω) at Ω = ωR_i/c_s.

    Args:
        scales: the :class:`Scales`.
        law: :class:`~jaxdea.Prony` (``moduli`` in Pa, ``times`` in s),
            :class:`~jaxdea.FractionalKelvinVoigt` (``modulus`` in Pa, ``time`` in s),
            :class:`~jaxdea.KelvinVoigt` (``viscosity`` in Pa s) or :class:`~jaxdea.Hysteretic`.

    Raises:
        ValueError: naming the parameter (``damping.times``), for a law of another type or values
            out of range (:func:`jaxdea.params.validate_damping`).

    Examples:
        >>> vhb_branches = damping_from_si(vhb, jd.Prony(moduli=(26e3, 27e3, 11e3),
        ...                                              times=(0.01, 0.1, 1.0)))
    """
    _check_scales(scales)
    mu, _, _, _ = scales._values()
    t = scales.time_scale
    modulus = lambda field, x: _positive(f"{name}.{field}", x, "Pa") / mu  # noqa: E731
    time = lambda field, x: _positive(f"{name}.{field}", x, "s") / t  # noqa: E731
    if isinstance(law, Prony):
        for field in ("moduli", "times"):
            if not isinstance(getattr(law, field), (tuple, list)):
                raise ValueError(f"{name}.{field} must be a tuple, got {getattr(law, field)!r}")
        if len(law.moduli) != len(law.times):
            raise ValueError(f"{name}.moduli and {name}.times must have the same length, got "
                             f"{len(law.moduli)} and {len(law.times)}")
        out = Prony(moduli=tuple(modulus(f"moduli[{k}]", g) for k, g in enumerate(law.moduli)),
                    times=tuple(time(f"times[{k}]", x) for k, x in enumerate(law.times)))
    elif isinstance(law, FractionalKelvinVoigt):
        out = FractionalKelvinVoigt(modulus=modulus("modulus", law.modulus),
                                    time=time("time", law.time), order=law.order,
                                    stretch_coupling=law.stretch_coupling)
    elif isinstance(law, KelvinVoigt):
        out = KelvinVoigt(viscosity=_positive(f"{name}.viscosity", law.viscosity, "Pa s")
                          / (mu * t))
    elif isinstance(law, Hysteretic):
        out = law
    else:
        raise ValueError(f"{name} must be a damping law of jaxdea.materials (Prony, "
                         "FractionalKelvinVoigt, KelvinVoigt, Hysteretic), got "
                         f"{type(law).__name__}")
    try:
        validate_damping(out)
    except ValueError as exc:
        raise ValueError(f"{name}: {exc}") from exc
    return out
