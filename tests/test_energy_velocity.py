"""jaxdea.energy_velocity: flux over energy of a mode (docs/theory/real_tubes.md §9).

Lossless tubes: v_e = group_velocity (measured agreement 1e-13 … 5e-13 relative on every case here:
empty, acoustic filling, m = 1, 2, torsional, V̂ > 0, a layered wall, a surrounding fluid). Damped
tubes: the energy balance ∂P̄/∂z = −D̄, i.e. P̄ = D̄/(2|Im α̂|) (Eq. 9.11, measured 1e-14), and the
Kelvin–Voigt limit η_v → 0."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxdea as jd
from jaxdea.physics.problem import NO_ALPHA, describe
from jaxdea.physics.transfer import discretize, laminate
from jaxdea.solve import energy as energy_module
from jaxdea.solve import wavenumbers as wavenumbers_module

TUBE = jd.Tube(voltage=0.1, lambda_i=0.9, lambda_z=1.2)
ALPHA = 0.445
LOSSLESS_RTOL = 1e-10
OMEGA_MAX = 10.0
"""Modes checked against the group velocity: below it (a mode of many radial wavelengths, e.g. the
torsional Ω ≈ 17.9, agrees to 2e-10 only, the default laminate's accuracy there)."""


def _check_lossless(tube, n_roots=2, **kw):
    omegas = np.asarray(jd.frequencies(tube, ALPHA, n_roots=n_roots, **kw))
    omegas = omegas[omegas < OMEGA_MAX]
    assert omegas.size
    for omega in omegas:
        v_g = float(jd.group_velocity(tube, ALPHA, float(omega), **kw))
        v_e = float(jd.energy_velocity(tube, ALPHA, float(omega), **kw))
        assert abs(v_e - v_g) <= LOSSLESS_RTOL * abs(v_g), (omega, v_e, v_g)


def test_equals_group_velocity_of_the_empty_tube_under_voltage():
    """V̂ = 0.1, pre-stretched: the follower pressure P̂_i ≠ 0 on the inner face (Eq. 9.7) matters
    (without it the first two modes are off by 1.3 % and 7 %)."""
    _check_lossless(TUBE)


def test_converges_in_n_points():
    """Gauss–Legendre across the wall converges spectrally: on the second mode the error against the
    group velocity is 1.7e-7, 6.9e-10, 6e-14 and 8e-15 with 3, 4, 6 and 16 nodes (measured)."""
    omega = float(jd.frequencies(TUBE, ALPHA, n_roots=2)[1])
    v_g = float(jd.group_velocity(TUBE, ALPHA, omega))
    errors = [abs(float(jd.energy_velocity(TUBE, ALPHA, omega, n_points=n)) / v_g - 1.0)
              for n in (3, 4, 6, 16)]
    assert errors[0] > 1e-8 and errors[1] < 0.1 * errors[0] and errors[2] < 1e-3 * errors[1]
    assert max(errors[2:]) < 1e-12


def test_equals_group_velocity_with_an_acoustic_filling():
    _check_lossless(TUBE, fluid=jd.Fluid())


@pytest.mark.parametrize("kw", [dict(m=1), dict(m=2), dict(torsional=True)],
                         ids=["m=1", "m=2", "torsional"])
def test_equals_group_velocity_of_order_m_and_torsion(kw):
    _check_lossless(TUBE, **kw)


def test_equals_group_velocity_of_order_m_with_a_filling():
    _check_lossless(TUBE, m=2, fluid=jd.Fluid())


def test_equals_group_velocity_of_a_layered_wall_and_a_general_material():
    layered = TUBE.replace(layers=(
        jd.Layer(0.2, jd.NeoHookean(), shear_ratio=3.0, density_ratio=1.2),
        jd.Layer(0.6, jd.Gent(97.2), active=True),
        jd.Layer(0.2, jd.MooneyRivlin(0.2), shear_ratio=2.0, density_ratio=0.8)))
    _check_lossless(layered)
    _check_lossless(layered, m=1, fluid=jd.Fluid())
    _check_lossless(jd.Tube(voltage=0.2, lambda_i=1.1, lambda_z=1.2,
                            material=jd.MooneyRivlin(0.2)), m=1)


def test_equals_group_velocity_in_a_surrounding_fluid():
    """Subsonic modes: the outer fluid's flux and energy in closed form (Eq. 9.9)."""
    _check_lossless(TUBE, outer=jd.Fluid(1.0, 50.0))
    _check_lossless(TUBE, m=1, fluid=jd.Fluid(), outer=jd.Fluid(1.0, 50.0))


def _damped_root(tube, omega, alpha0, m=0):
    """The complex α̂ of the damped tube at the real Ω by complex Newton from the lossless α̂0 (the
    roots of jaxdea.wavenumbers, without its search of the plane)."""
    layers = laminate(None, None, tube, alpha0, m=m)
    problem = describe(tube, NO_ALPHA, None, layers, None, m, damped=True)
    root, ok = jax.jit(wavenumbers_module.complex_newton, static_argnums=(0,))(
        problem, discretize(tube, layers), float(omega), None, jnp.asarray(float(m)),
        jnp.asarray(complex(alpha0)))
    assert bool(ok)
    return complex(root)


def _balance(tube, alpha, omega, m=0):
    """(P̄, D̄/(2|Im α̂|), v_e) of a damped mode (Eq. 9.11)."""
    layers = laminate(None, None, tube, abs(alpha), m=m)
    problem = describe(tube, NO_ALPHA, None, layers, None, m, damped=True)
    _, flux, _, dissipation, distance, _ = energy_module._energy_velocity(
        tube, energy_module._complex(alpha), jnp.asarray(float(omega)), None, 16, layers,
        problem.order, False, **problem.arguments(jnp.asarray(float(m))))
    assert float(distance) < 1e-8
    return float(flux), float(dissipation) / (2.0 * abs(alpha.imag))


@pytest.mark.parametrize("case", ["hysteretic, unstretched", "Kelvin-Voigt, stretched, V=0.1",
                                  "Prony, m=1"])
def test_damped_flux_balances_the_dissipation(case):
    """The z-face flux (Eqs. 9.4, 9.7) against the power the damping dissipates in the wall
    (Eq. 9.10): P̄(z) ∝ e^{2 Im α̂ z} and ∂P̄/∂z = −D̄ give P̄ = D̄/(2|Im α̂|) (measured 4e-16 … 8e-15).
    An independent check of the damped flux: different fields, different stresses."""
    tube, m = {
        "hysteretic, unstretched": (jd.Tube(voltage=0.0, lambda_i=1.0, lambda_z=1.0,
                                            damping=jd.Hysteretic(0.1)), 0),
        "Kelvin-Voigt, stretched, V=0.1": (TUBE.replace(damping=jd.KelvinVoigt(0.02)), 0),
        "Prony, m=1": (TUBE.replace(damping=jd.Prony((0.3,), (2.0,))), 1),
    }[case]
    omega = float(jd.frequencies(tube.replace(damping=None), ALPHA, n_roots=1, m=m)[0])
    alpha = _damped_root(tube, omega, ALPHA, m)
    assert alpha.imag < -1e-4  # attenuated towards +z
    flux, balance = _balance(tube, alpha, omega, m)
    assert flux > 0 and abs(flux / balance - 1.0) < 1e-10


def test_hysteretic_energy_satisfies_the_virial_identity():
    """The exact damped limit (unstretched, V̂ = 0, empty: the elastic problem with shear modulus
    1 + iζ, docs/theory/real_tubes.md §4): no face terms, no field, so the momentum balance times u*
    over the section gives 4(K̄ − Ū) = 2 Im α̂ · Im ∫[U*Ṫ_zr + V*Ṫ_zθ − W*Ṫ_zz] r̂ dr̂ (Eq. 9.12): a
    check of the stored energy Ū = Ē − K̄ of a damped mode (measured: sides 2.15e-2 K̄ (m = 0) and
    1.79e-2 K̄ (m = 1) at ζ = 0.1, agreeing to 1.2e-14 and 1.8e-14 K̄). Lossless, the same identity
    is equipartition."""
    tube = jd.Tube(voltage=0.0, lambda_i=1.0, lambda_z=1.0, damping=jd.Hysteretic(0.1))
    for m in (0, 1):
        omega = float(jd.frequencies(tube.replace(damping=None), ALPHA, n_roots=1, m=m)[0])
        alpha = _damped_root(tube, omega, ALPHA, m)
        layers = laminate(None, None, tube, abs(alpha), m=m)
        problem = describe(tube, NO_ALPHA, None, layers, None, m, damped=True)
        _, _, energy, _, _, (kinetic, axial) = energy_module._energy_velocity(
            tube, energy_module._complex(alpha), jnp.asarray(omega), None, 16, layers,
            problem.order, False, **problem.arguments(jnp.asarray(float(m))))
        left = 4.0 * (2.0 * float(kinetic) - float(energy))  # 4(K − U), U = E − K
        right = 2.0 * alpha.imag * float(axial)
        assert abs(right) > 1e-3 * float(kinetic)  # the identity is not trivially 0 = 0
        assert abs(left - right) < 1e-10 * float(kinetic), (m, left, right)


def test_kelvin_voigt_tends_to_the_lossless_group_velocity():
    """η_v → 0: v_e of the damped wave at the lossless Ω tends to the group velocity there, the
    difference in second order: 3.553e-5, 3.553e-7, 3.553e-9 at η_v = 1e-2, 1e-3, 1e-4 (measured;
    v_g = 1.66065)."""
    omega = float(jd.frequencies(TUBE, ALPHA, n_roots=1)[0])
    v_g = float(jd.group_velocity(TUBE, ALPHA, omega))
    gaps = []
    for viscosity in (1e-2, 1e-3):
        tube = TUBE.replace(damping=jd.KelvinVoigt(viscosity))
        alpha = _damped_root(tube, omega, ALPHA)
        gaps.append(abs(float(jd.energy_velocity(tube, alpha, omega)) - v_g))
    assert 0.009 < gaps[1] / gaps[0] < 0.011 and gaps[1] < 1e-6 * v_g


def test_runs_under_jit_and_vmap_and_a_traced_non_root_is_nan():
    """Along the branch through the lowest root (α̂ traced, Ω = frequency(α̂)): finite, equal to the
    concrete call; a traced Ω off the root gives NaN instead of a plausible number."""
    omega = float(jd.frequencies(TUBE, ALPHA, n_roots=1)[0])
    along = jax.jit(jax.vmap(lambda a: jd.energy_velocity(TUBE, a, jd.frequency(TUBE, a, omega))))
    values = np.asarray(along(jnp.array([0.44, ALPHA, 0.45])))
    assert np.all(np.isfinite(values))
    assert abs(values[1] - float(jd.energy_velocity(TUBE, ALPHA, omega))) < 1e-12
    assert np.isnan(float(jax.jit(lambda o: jd.energy_velocity(TUBE, ALPHA, o))(omega * 1.01)))


def test_bad_input_raises_naming_the_parameter():
    omega = float(jd.frequencies(TUBE, ALPHA, n_roots=1)[0])
    cases = [
        (dict(omega=float("nan")), "omega"), (dict(omega=-1.0), "omega"),
        (dict(alpha=float("nan")), "alpha"), (dict(alpha=-0.445 + 0.01j), "alpha"),
        (dict(alpha=complex("nan+1j")), "alpha"), (dict(alpha="0.4"), "alpha"),
        (dict(omega=omega * 1.01), "not a root"), (dict(n_points=0), "n_points"),
        (dict(fluid=jd.Fluid(coupling="paper", bessel_order=1)), "fluid"),
        (dict(outer=jd.Fluid(1.0, 50.0), alpha=0.445 + 0.001j), "outer"),
        (dict(outer=jd.Fluid(1.0, 0.5)), "outer"),
        (dict(m=1.5), "m"),
    ]
    for kw, name in cases:
        args = dict(tube=TUBE, alpha=ALPHA, omega=omega) | kw
        with pytest.raises(ValueError, match=name):
            jd.energy_velocity(**args)
