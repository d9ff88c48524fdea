"""SI for real walls (jaxdea.units): layers given by thickness, modulus and density, and damping
laws given in Pa and s (docs/theory/real_tubes.md §3–4)."""

import math

import jax
import numpy as np
import pytest

import jaxdea as jd
from jaxdea.units import (
    VACUUM_PERMITTIVITY,
    LayerSI,
    Scales,
    damping_from_si,
    layers_from_si,
    tube_from_si,
)

MU, RHO, EPS, RI = 20e3, 960.0, 4.7 * VACUUM_PERMITTIVITY, 5e-3
VHB = Scales(shear_modulus=MU, density=RHO, permittivity=EPS, inner_radius=RI)
# a silicone liner, the VHB layer, a soft encapsulation (m, Pa, kg/m³)
WALL = [LayerSI(0.2e-3, 60e3, 1100.0, jd.NeoHookean()),
        LayerSI(0.6e-3, active=True),
        LayerSI(0.3e-3, 10e3, 1000.0, jd.MooneyRivlin(0.2))]


def test_layers_by_hand():
    """fraction = t_k/Σt, shear_ratio = μ_k/μ, density_ratio = ρ_k/ρ_s; R_o = R_i + Σt."""
    layers = layers_from_si(VHB, WALL)
    np.testing.assert_allclose([float(x.fraction) for x in layers], [0.2 / 1.1, 0.6 / 1.1, 0.3 / 1.1],
                               rtol=1e-15)
    np.testing.assert_allclose([float(x.shear_ratio) for x in layers], [3.0, 1.0, 0.5], rtol=1e-15)
    np.testing.assert_allclose([float(x.density_ratio) for x in layers],
                               [1100 / 960, 1.0, 1000 / 960], rtol=1e-15)
    assert [x.active for x in layers] == [False, True, False]
    assert layers[2].material == jd.MooneyRivlin(0.2)
    tube = tube_from_si(VHB, length=0.05, voltage=3e3, lambda_i=1.1, lambda_z=1.2, layers=WALL)
    np.testing.assert_allclose(float(tube.eta), RI / (RI + 1.1e-3), rtol=1e-15)
    np.testing.assert_allclose(float(tube.length_ratio), 0.05 / (RI + 1.1e-3), rtol=1e-15)
    np.testing.assert_allclose(float(tube.voltage), math.sqrt(EPS / MU) * 3e3 / RI, rtol=1e-15)
    same = tube_from_si(VHB, outer_radius=RI + 1.1e-3, length=0.05, voltage=3e3, lambda_i=1.1,
                        lambda_z=1.2, layers=WALL)
    assert float(same.eta) == float(tube.eta)


def test_frequencies_in_hz_scale_with_every_modulus():
    """Every modulus ×4 (the scales' and each layer's) and the voltage ×2 (V̂ ∝ V/√μ held) is the
    same dimensionless tube, with c_s ×2: each frequency in Hz doubles. Every density ×2 gives
    c_s/√2. A conversion that scaled one layer's modulus or density by the wrong unit fails."""
    def hz(mu_factor, rho_factor):
        scales = VHB.replace(shear_modulus=MU * mu_factor, density=RHO * rho_factor)
        wall = [x._replace(shear_modulus=None if x.shear_modulus is None
                           else x.shear_modulus * mu_factor,
                           density=None if x.density is None else x.density * rho_factor)
                for x in WALL]
        tube = tube_from_si(scales, length=0.05, voltage=3e3 * math.sqrt(mu_factor),
                            lambda_i=1.1, lambda_z=1.2, layers=wall)
        alpha = float(jd.axial_wavenumber(tube, 1))
        return np.asarray(scales.omega_to_hz(jd.frequencies(tube, alpha, n_roots=2, n_layers=16)))

    base = hz(1.0, 1.0)
    assert np.all(np.isfinite(base))
    np.testing.assert_allclose(hz(4.0, 1.0), 2.0 * base, rtol=1e-12)
    np.testing.assert_allclose(hz(1.0, 2.0), base / math.sqrt(2.0), rtol=1e-12)
    # and the layers matter: the single VHB wall of the same radii differs
    single = tube_from_si(VHB, outer_radius=RI + 1.1e-3, length=0.05, voltage=3e3, lambda_i=1.1,
                          lambda_z=1.2)
    alone = VHB.omega_to_hz(jd.frequencies(single, float(jd.axial_wavenumber(single, 1)),
                                           n_roots=2, n_layers=16))
    assert np.max(np.abs(np.asarray(alone) / base - 1)) > 1e-2


OMEGA_SI = np.array([3.0, 300.0, 3e4])  # rad/s


@pytest.mark.parametrize("law, eta_si", [
    (jd.Prony(moduli=(26e3, 27e3, 11e3), times=(1e-3, 1e-2, 0.3)),
     lambda w: sum(g * 1j * w * t / (1 + 1j * w * t)
                   for g, t in zip((26e3, 27e3, 11e3), (1e-3, 1e-2, 0.3), strict=True))),
    (jd.FractionalKelvinVoigt(modulus=12e3, time=330e-6, order=0.32, stretch_coupling=0.1),
     lambda w: 12e3 * (1j * w * 330e-6) ** 0.32),
    (jd.KelvinVoigt(viscosity=2.5), lambda w: 1j * w * 2.5),
    (jd.Hysteretic(loss=0.2), lambda w: 0.2j * MU * np.ones_like(w)),
], ids=["prony", "fractional", "kelvin_voigt", "hysteretic"])
def test_damping_from_si_is_the_same_modulus(law, eta_si):
    """η*(ω) in Pa of the SI law, written out here, = μ η̂*(Ω) of the converted law at Ω = ωR_i/c_s."""
    hat = damping_from_si(VHB, law)
    omega = np.asarray(VHB.omega_from_si(OMEGA_SI))
    np.testing.assert_allclose(MU * np.asarray(hat.viscous_modulus(omega)), eta_si(OMEGA_SI),
                               rtol=1e-13)
    if isinstance(law, jd.FractionalKelvinVoigt):
        assert hat.order == 0.32 and hat.stretch_coupling == 0.1


def test_a_damped_layer_and_tube_in_si():
    """A LayerSI's damping and tube_from_si's damping are converted (the SI law on the tube would
    be 10^4 times too stiff)."""
    law = jd.KelvinVoigt(viscosity=2.5)
    tube = tube_from_si(VHB, outer_radius=RI / 0.85, length=0.05, damping=law)
    np.testing.assert_allclose(float(tube.damping.viscosity), 2.5 / (MU * float(VHB.time_scale)),
                               rtol=1e-15)
    wall = [WALL[0]._replace(damping=law), *WALL[1:]]
    layers = layers_from_si(VHB, wall)
    assert float(layers[0].damping.viscosity) == float(tube.damping.viscosity)


def test_gradient_in_a_layer_modulus_in_pascal():
    """d(shear_ratio)/dμ_k = 1/μ, and dΩ/dμ_k through the SI layer by jax.grad = a central
    difference."""
    grad = jax.grad(lambda g: layers_from_si(VHB, [WALL[0]._replace(shear_modulus=g), *WALL[1:]])
                    [0].shear_ratio)(60e3)
    np.testing.assert_allclose(float(grad), 1 / MU, rtol=1e-15)

    def omega(g):
        tube = tube_from_si(VHB, length=0.05, lambda_i=1.1, lambda_z=1.2,
                            layers=[WALL[0]._replace(shear_modulus=g), *WALL[1:]])
        return jd.frequencies(tube, 0.6, n_roots=1, n_layers=16)[0]

    h = 60.0
    fd = (float(omega(60e3 + h)) - float(omega(60e3 - h))) / (2 * h)
    assert abs(fd) > 1e-8
    np.testing.assert_allclose(float(jax.grad(omega)(60e3)), fd, rtol=1e-6)


@pytest.mark.parametrize("wall, match", [
    ([LayerSI(1e-3, 30e3, active=True)], r"layers\[0\].shear_modulus = 30000.0 Pa must be the "
                                         r"scales' shear_modulus"),
    ([LayerSI(1e-3, density=900.0, active=True)], r"layers\[0\].density"),
    ([LayerSI(0.5e-3, active=True), LayerSI(-0.5e-3, 30e3)], r"layers\[1\].thickness must be > 0"),
    ([LayerSI(0.5e-3, active=True), LayerSI(0.5e-3, 0.0)], r"layers\[1\].shear_modulus must be > 0"),
    ([LayerSI(0.5e-3), LayerSI(0.5e-3, 30e3)], r"active"),
    ([], r"layers must be a non-empty sequence"),
    (LayerSI(1e-3, active=True), r"layers must be a non-empty sequence"),
])
def test_bad_layers_name_the_field(wall, match):
    with pytest.raises(ValueError, match=match):
        layers_from_si(VHB, wall)


def test_bad_si_walls_name_the_parameter():
    with pytest.raises(ValueError, match=r"outer_radius = 0.007 m must equal inner_radius \+ the "
                                         r"layers' thicknesses"):
        tube_from_si(VHB, outer_radius=7e-3, length=0.05, layers=WALL)
    with pytest.raises(ValueError, match="material and damping belong to each LayerSI"):
        tube_from_si(VHB, length=0.05, layers=WALL, material=jd.NeoHookean())
    with pytest.raises(ValueError, match="outer_radius: the undeformed outer radius"):
        tube_from_si(VHB, length=0.05)
    with pytest.raises(ValueError, match="length: the undeformed length"):
        tube_from_si(VHB, outer_radius=6e-3)
    with pytest.raises(ValueError, match=r"damping.moduli and damping.times must have the same "
                                         r"length, got 1 and 2"):
        damping_from_si(VHB, jd.Prony((26e3,), (0.01, 0.1)))
    with pytest.raises(ValueError, match=r"damping.times\[1\] must be > 0 \(s\)"):
        damping_from_si(VHB, jd.Prony((26e3, 1e3), (0.01, 0.0)))
    with pytest.raises(ValueError, match=r"layers\[0\].damping.viscosity must be > 0"):
        layers_from_si(VHB, [WALL[0]._replace(damping=jd.KelvinVoigt(-1.0)), *WALL[1:]])
    with pytest.raises(ValueError, match="damping must be a damping law"):
        damping_from_si(VHB, jd.NeoHookean())
