"""SI ↔ dimensionless conversions (jaxdea.units, theory.md §0)."""

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxdea as jd
from jaxdea.units import (
    VACUUM_PERMITTIVITY,
    Scales,
    fluid_from_si,
    fluid_to_si,
    tube_from_si,
    tube_to_si,
)

MU, RHO, EPS, RI = 20e3, 960.0, 4.7 * VACUUM_PERMITTIVITY, 5e-3
VHB = Scales(shear_modulus=MU, density=RHO, permittivity=EPS, inner_radius=RI)
VALUES = np.array([1e-6, 0.3, 1.0, 17.8, 2.5e4])  # dimensionless values over many decades

# (to SI, from SI) for every single-quantity conversion
PAIRS = [
    ("length_to_si", "length_from_si"),
    ("omega_to_si", "omega_from_si"),
    ("omega_to_hz", "hz_to_omega"),
    ("wavenumber_to_si", "wavenumber_from_si"),
    ("wavelength_to_si", "wavelength_from_si"),
    ("speed_to_si", "speed_from_si"),
    ("pressure_to_si", "pressure_from_si"),
    ("voltage_to_si", "voltage_from_si"),
    ("displacement_field_to_si", "displacement_field_from_si"),
]


@pytest.mark.parametrize("to_si, from_si", PAIRS)
def test_single_quantities_round_trip(to_si, from_si):
    """dimensionless → SI → dimensionless and SI → dimensionless → SI to 1e-14 (NumPy input)."""
    there = getattr(VHB, to_si)(VALUES)
    np.testing.assert_allclose(getattr(VHB, from_si)(there), VALUES, rtol=1e-14)
    si = VALUES * 3.7
    np.testing.assert_allclose(getattr(VHB, to_si)(getattr(VHB, from_si)(si)), si, rtol=1e-14)


def test_closed_forms_by_hand():
    """c_s = sqrt(μ/ρ_s), f = Ω c_s/(2πR_i), V = V̂ R_i sqrt(μ/ε), P = P̂μ, α = α̂/R_i, c = ĉ c_s."""
    c_s = math.sqrt(20e3 / 960.0)  # 4.5643546… m/s
    np.testing.assert_allclose(VHB.shear_speed, 4.564354645876384, rtol=1e-15)
    np.testing.assert_allclose(VHB.omega_to_hz(1.0), c_s / (2 * math.pi * 5e-3), rtol=1e-15)
    np.testing.assert_allclose(VHB.omega_to_hz(1.0), 145.28792078313680, rtol=1e-14)
    np.testing.assert_allclose(VHB.time_scale, 5e-3 / c_s, rtol=1e-15)
    np.testing.assert_allclose(VHB.voltage_from_si(5e3), math.sqrt(EPS / MU) * 5e3 / RI, rtol=1e-15)
    np.testing.assert_allclose(VHB.voltage_from_si(5e3), 0.0456150648, rtol=1e-9)
    np.testing.assert_allclose(VHB.pressure_to_si(0.25), 5e3, rtol=1e-15)
    np.testing.assert_allclose(VHB.wavenumber_to_si(0.5), 100.0, rtol=1e-15)
    np.testing.assert_allclose(VHB.wavelength_to_si(2 * math.pi), RI, rtol=1e-15)
    # an attenuation |Im α̂| = 0.5 (per R_i = 5 mm): the amplitude e^{-100 z/m}, over 1 cm a factor
    # e^{-1}; in dB, 20 log10 of the amplitude ratio
    db = float(VHB.attenuation_to_db_per_m(0.5))
    np.testing.assert_allclose(10.0 ** (-db * 0.01 / 20.0), math.exp(-1.0), rtol=1e-14)
    # long-wave bar speed of the unstretched tube, Ω/α̂ → sqrt(3) (theory.md §5(ii)): sqrt(E/ρ_s)
    np.testing.assert_allclose(VHB.speed_to_si(math.sqrt(3.0)), math.sqrt(3 * MU / RHO), rtol=1e-15)
    np.testing.assert_allclose(VHB.displacement_field_to_si(1.0), math.sqrt(MU * EPS), rtol=1e-15)


def test_tube_and_fluid_round_trip_and_values():
    r_o = RI / 0.85
    tube = tube_from_si(VHB, outer_radius=r_o, length=10 * r_o, voltage=5e3, lambda_i=0.9,
                        lambda_z=1.2, gent=97.2)
    for got, want in [(tube.eta, 0.85), (tube.length_ratio, 10.0), (tube.lambda_i, 0.9),
                      (tube.lambda_z, 1.2), (tube.gent, 97.2)]:
        np.testing.assert_allclose(got, want, rtol=1e-15)
    back = tube_to_si(VHB, tube)
    for got, want in zip(back, [r_o, 10 * r_o, 5e3, 0.9, 1.2, 97.2], strict=True):
        np.testing.assert_allclose(got, want, rtol=1e-14)
    again = tube_from_si(VHB, **back._asdict())
    for name in ("voltage", "lambda_i", "lambda_z", "eta", "gent", "length_ratio"):
        np.testing.assert_allclose(getattr(again, name), getattr(tube, name), rtol=1e-14, err_msg=name)
    neo = tube_from_si(VHB, outer_radius=r_o, length=1.0, gent=np.inf, material="neo_hookean")
    assert neo.material == "neo_hookean" and np.isinf(neo.gent)

    water = fluid_from_si(VHB, fluid_density=1000.0, sound_speed=1480.0)
    np.testing.assert_allclose(water.density_ratio, 1000.0 / RHO, rtol=1e-15)
    np.testing.assert_allclose(water.speed_ratio, 1480.0 / math.sqrt(MU / RHO), rtol=1e-15)
    assert water.coupling == "acoustic"
    np.testing.assert_allclose(fluid_to_si(VHB, water), [1000.0, 1480.0], rtol=1e-14)
    paper = fluid_from_si(VHB, 1.2, 343.0, coupling="paper", bessel_order=1)
    assert (paper.coupling, paper.bessel_order) == ("paper", 1)


def test_worked_example_of_the_module_docstring():
    """The numbers quoted in jaxdea.units' docstring (water-filled VHB tube, mode n = 1)."""
    r_o = RI / 0.85
    tube = tube_from_si(VHB, outer_radius=r_o, length=10 * r_o, voltage=5e3, lambda_i=0.9,
                        lambda_z=1.2, gent=97.2)
    water = fluid_from_si(VHB, fluid_density=1000.0, sound_speed=1480.0)
    alpha = jd.axial_wavenumber(tube, 1)
    np.testing.assert_allclose(alpha, 0.44506, rtol=1e-5)
    np.testing.assert_allclose(VHB.wavelength_to_si(alpha), 0.0706, rtol=1e-3)
    np.testing.assert_allclose(VHB.voltage_scale, 109.61e3, rtol=1e-4)
    np.testing.assert_allclose(water.speed_ratio, 324.25, rtol=1e-5)
    omega = jd.frequencies(tube, alpha, water)[0]
    np.testing.assert_allclose(omega, 0.19627, rtol=1e-4)
    np.testing.assert_allclose(VHB.omega_to_hz(omega), 28.52, rtol=1e-3)


BAD_SCALES = [
    (dict(shear_modulus=-1.0), "shear_modulus"),
    (dict(density=0.0), "density"),
    (dict(permittivity=np.inf), "permittivity"),
    (dict(inner_radius=np.nan), "inner_radius"),
    (dict(shear_modulus=np.array([1.0, -2.0])), "shear_modulus"),
]


@pytest.mark.parametrize("changes, name", BAD_SCALES)
def test_bad_scales_raise_value_error_naming_the_parameter(changes, name):
    with pytest.raises(ValueError, match=name):
        VHB.replace(**changes).omega_to_hz(1.0)


@pytest.mark.parametrize(
    "call, name",
    [
        (lambda: tube_from_si(VHB, outer_radius=RI, length=0.1), "outer_radius"),
        (lambda: tube_from_si(VHB, outer_radius=-1.0, length=0.1), "outer_radius"),
        (lambda: tube_from_si(VHB, outer_radius=0.01, length=0.0), "length"),
        (lambda: tube_from_si(VHB, outer_radius=0.01, length=0.1, voltage=np.nan), "voltage"),
        (lambda: tube_from_si(VHB, outer_radius=0.01, length=0.1, lambda_i=0.0), "lambda_i"),
        (lambda: tube_from_si(VHB, outer_radius=0.01, length=0.1, lambda_z=np.inf), "lambda_z"),
        (lambda: tube_from_si(VHB, outer_radius=0.01, length=0.1, gent=-3.0), "gent"),
        (lambda: fluid_from_si(VHB, fluid_density=0.0, sound_speed=343.0), "fluid_density"),
        (lambda: fluid_from_si(VHB, fluid_density=1.2, sound_speed=np.inf), "sound_speed"),
        (lambda: VHB.omega_to_hz("fast"), "omega"),
        (lambda: VHB.voltage_from_si(1j), "voltage"),
        (lambda: tube_to_si(VHB, jd.Tube(eta=1.5)), "eta"),
    ],
)
def test_bad_inputs_raise_value_error_naming_the_parameter(call, name):
    with pytest.raises(ValueError, match=name):
        call()


def test_nan_values_pass_through_conversions():
    """A NaN-padded root converts to NaN (conversions are scalings, not validations)."""
    out = VHB.omega_to_hz(jnp.array([0.5, jnp.nan]))
    assert np.isfinite(out[0]) and np.isnan(out[1])


def test_vmap_and_grad():
    """Scales is a pytree: vmap over a modulus equals a loop; exact derivatives by jax.grad:
    ∂f/∂μ = f/(2μ), ∂f/∂R_i = −f/R_i, ∂V̂/∂V = 1/(R_i sqrt(μ/ε)), ∂η/∂R_o = −R_i/R_o²."""
    moduli = jnp.array([10e3, 20e3, 1e6])
    batched = jax.vmap(lambda mu: VHB.replace(shear_modulus=mu).omega_to_hz(0.7))(moduli)
    loop = [VHB.replace(shear_modulus=float(mu)).omega_to_hz(0.7) for mu in moduli]
    np.testing.assert_allclose(batched, loop, rtol=1e-15)
    in_axes = Scales(shear_modulus=None, density=None, permittivity=None, inner_radius=0)
    stacked = VHB.replace(inner_radius=jnp.array([1e-3, 5e-3]))
    np.testing.assert_allclose(jax.vmap(lambda s: s.hz_to_omega(100.0), in_axes=(in_axes,))(stacked),
                               [VHB.replace(inner_radius=x).hz_to_omega(100.0) for x in (1e-3, 5e-3)],
                               rtol=1e-15)
    tubes = jax.vmap(lambda v: tube_from_si(VHB, 0.006, 0.06, voltage=v))(jnp.array([0.0, 1e3, 5e3]))
    np.testing.assert_allclose(tubes.voltage, VHB.voltage_from_si(np.array([0.0, 1e3, 5e3])), rtol=1e-15)

    f = VHB.omega_to_hz(0.7)
    d_mu = jax.grad(lambda s: s.omega_to_hz(0.7))(VHB)
    np.testing.assert_allclose(d_mu.shear_modulus, f / (2 * MU), rtol=1e-14)
    np.testing.assert_allclose(d_mu.inner_radius, -f / RI, rtol=1e-14)
    np.testing.assert_allclose(jax.grad(VHB.voltage_from_si)(5e3), 1 / VHB.voltage_scale, rtol=1e-14)
    d_eta = jax.grad(lambda r_o: tube_from_si(VHB, r_o, 0.06).eta)(0.006)
    np.testing.assert_allclose(d_eta, -RI / 0.006**2, rtol=1e-14)
    np.testing.assert_allclose(jax.jit(lambda s: s.omega_to_hz(0.7))(VHB), f, rtol=1e-15)
