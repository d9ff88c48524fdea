"""Layered walls held by a pressure difference (docs/theory/real_tubes.md §3): jaxdea.pressure_difference
of a layered tube is the layered ΔP̂, inner_stretch inverts it, pull_in and voltage_limit follow the
layered response, and the first instability along the held branch of a layered wall is a zero of
f(Ω = 0) there. Before, all of them used the single wall's ΔP̂ for a layered tube (a silent wrong
number: 0.0751 for 0.1014 on the tube below)."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.optimize import minimize_scalar

import jaxdea as jd
from jaxdea.physics import base_state as bs

GENT = jd.Gent(97.2)
LINED = (jd.Layer(0.3, jd.NeoHookean(), shear_ratio=2.0), jd.Layer(0.7, GENT, active=True))
"""A stiff passive liner inside an active Gent layer."""
TUBE = jd.Tube(voltage=0.05, lambda_i=1.1, lambda_z=1.2, eta=0.8, layers=LINED)
IDENTICAL = (jd.Layer(0.3, GENT), jd.Layer(0.4, GENT, active=True), jd.Layer(0.3, GENT))


def soft(i1, i2, params):
    """W = sqrt(I_1 − 2) − 1, strain softening (unit shear modulus): a pull-in maximum at fixed λ_z."""
    return jnp.sqrt(i1 - 2.0) - 1.0


SOFT_WALL = jd.Tube(voltage=0.0, lambda_i=1.1, lambda_z=1.2, eta=0.6,
                    layers=(jd.Layer(0.3, jd.NeoHookean(), shear_ratio=2.0),
                            jd.Layer(0.7, jd.Energy(fn=soft), active=True)))


def central(f, x, h=1e-5):
    return (float(f(x + h)) - float(f(x - h))) / (2 * h)


def test_pressure_difference_of_a_layered_tube_is_through_its_layers():
    got = float(jd.pressure_difference(TUBE))
    np.testing.assert_allclose(got, float(jax.jit(bs.layered_pressure_difference)(TUBE)),
                               rtol=1e-13)
    assert abs(got - float(jd.pressure_difference(TUBE.replace(layers=None)))) > 0.02
    # three identical Gent layers at V̂ = 0 are the single wall (closed form)
    same = TUBE.replace(voltage=0.0, layers=IDENTICAL)
    np.testing.assert_allclose(float(jd.pressure_difference(same)),
                               float(jd.pressure_difference(same.replace(layers=None))),
                               rtol=1e-12, atol=1e-14)
    # differentiable through the layers: λ_i and the liner's shear ratio
    grad = jax.grad(lambda x: jd.pressure_difference(TUBE.replace(lambda_i=x)))(1.1)
    np.testing.assert_allclose(float(grad), central(
        lambda x: jd.pressure_difference(TUBE.replace(lambda_i=x)), 1.1), rtol=1e-7)

    def by_liner(mu):
        liner = jd.Layer(0.3, jd.NeoHookean(), shear_ratio=mu)
        return jd.pressure_difference(TUBE.replace(layers=(liner, LINED[1])))

    np.testing.assert_allclose(float(jax.grad(by_liner)(2.0)), central(by_liner, 2.0), rtol=1e-7)


@pytest.mark.parametrize("voltage", [0.0, 0.05])
def test_inner_stretch_inverts_the_layered_pressure_difference(voltage):
    tube = TUBE.replace(voltage=voltage)
    dp = float(jax.jit(bs.layered_pressure_difference)(tube))  # not the single wall's
    li, status = jd.inner_stretch(tube.replace(lambda_i=0.7), dp)  # λ_i ignored
    assert int(status) == jd.Status.CONVERGED
    np.testing.assert_allclose(float(li), 1.1, rtol=1e-12)
    # implicit derivatives in ΔP̂ and V̂ against central differences
    by_p = lambda p: jd.inner_stretch(tube, p)[0]  # noqa: E731
    np.testing.assert_allclose(float(jax.grad(by_p)(dp)), central(by_p, dp), rtol=1e-6)
    by_v = lambda v: jd.inner_stretch(tube.replace(voltage=v), dp)[0]  # noqa: E731
    np.testing.assert_allclose(float(jax.grad(by_v)(0.07)), central(by_v, 0.07), rtol=1e-6)


def _layered_peak(tube, delta_p, start):
    """(λ_i, V̂) of the first maximum of V̂²(λ_i) = (ΔP̂_el − ΔP̂)/E at fixed ΔP̂, formed from
    bs.layered_pressure_difference alone (E = ΔP̂(V̂ = 0) − ΔP̂(V̂ = 1)), by Brent's method."""
    at = jax.jit(lambda x, v: bs.layered_pressure_difference(tube.replace(lambda_i=x, voltage=v)))

    def v2(x):
        elastic = float(at(x, 0.0))
        return (elastic - delta_p) / (elastic - float(at(x, 1.0)))

    best = minimize_scalar(lambda x: -v2(x), bracket=(start - 0.05, start, start + 0.05), tol=1e-10)
    return best.x, float(np.sqrt(-best.fun))


def test_pull_in_and_voltage_limit_of_a_layered_wall():
    dp = float(jd.pressure_difference(SOFT_WALL))
    li, v, status = jd.pull_in(SOFT_WALL, dp)
    assert int(status) == jd.Status.CONVERGED
    peak_li, peak_v = _layered_peak(SOFT_WALL, dp, float(li))
    np.testing.assert_allclose(float(v), peak_v, rtol=1e-12)
    np.testing.assert_allclose(float(li), peak_li, rtol=1e-6)
    np.testing.assert_allclose(float(jd.pressure_difference(SOFT_WALL.replace(lambda_i=li, voltage=v))),
                               dp, rtol=1e-12)
    # the end of the critical-voltage search: the pull-in at the tube's zero-voltage ΔP̂
    np.testing.assert_allclose(float(jax.jit(bs.voltage_limit)(SOFT_WALL)), float(v), rtol=1e-12)


def test_pull_in_of_a_layered_wall_derivative():
    dp = float(jd.pressure_difference(SOFT_WALL))
    by_p = lambda p: jd.pull_in(SOFT_WALL, p)[1]  # noqa: E731
    np.testing.assert_allclose(float(jax.grad(by_p)(dp)), central(by_p, dp), rtol=1e-6)


def test_held_first_instability_of_a_layered_wall_is_a_zero_on_its_held_branch():
    tube = TUBE.replace(voltage=0.0)
    layered = jax.jit(bs.layered_pressure_difference)
    dp = float(layered(tube))  # not the single wall's
    first = jd.first_instability(tube, delta_p=dp, n_max=1, m_max=0)
    assert int(first.status) == jd.Status.CONVERGED and (int(first.m), int(first.n)) == (0, 1)
    v = float(first.voltage)
    alpha = jd.axial_wavenumber(tube, 1)

    def held(voltage):
        lam, status = jd.inner_stretch(tube.replace(voltage=voltage), dp)
        assert int(status) == jd.Status.CONVERGED
        return tube.replace(voltage=voltage, lambda_i=float(lam))

    assert float(held(v).lambda_i) > 1.1  # the held tube inflates with the voltage
    below, above = (float(jd.characteristic(held((1.0 + s * 1e-6) * v), 0.0, alpha, m=0))
                    for s in (-1.0, 1.0))
    assert below * above < 0
    # the held state is on the layered response: ΔP̂ of it is the holding pressure
    np.testing.assert_allclose(float(layered(held(v))), dp, rtol=1e-12)


def test_single_wall_base_state_refuses_a_layered_tube():
    with pytest.raises(ValueError, match="layered_base_state"):
        bs.base_state(TUBE, jnp.asarray([1.2]))
