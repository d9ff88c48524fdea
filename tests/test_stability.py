"""The stability of a given state (jaxdea.stability): the unstable (m, n) are exactly those whose
critical voltage (an independent search in V̂, first_instability) lies below the state's voltage,
the fastest growth rate is growth_rates' of its (m, n), the answer flips at the first instability,
and the growth rate's derivative matches central differences."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxdea as jd

PAPER = jd.Tube(lambda_i=0.9, lambda_z=1.2, eta=0.85)  # V̂_cr: m = 2 at 0.0293, m = 3 at 0.0309
GRID = dict(n_max=2, m_max=4)


def test_unstable_modes_are_those_below_their_critical_voltage():
    first = jd.first_instability(PAPER, **GRID)
    critical = np.asarray(first.critical)
    voltage = 0.05
    state = jd.stability(PAPER.replace(voltage=voltage), **GRID)
    growth = np.asarray(state.growth)
    assert int(state.status) == jd.Status.CONVERGED and not bool(state.stable)
    np.testing.assert_array_equal(np.isfinite(growth), critical < voltage)
    assert np.sum(np.isfinite(growth)) >= 3  # (2, 1), (3, 1), (4, 1), (3, 2) at least
    m, n = int(state.m), int(state.n)
    assert float(state.growth_rate) == np.nanmax(growth)
    ref = jd.growth_rates(PAPER.replace(voltage=voltage), jd.axial_wavenumber(PAPER, n), m=m,
                          n_roots=1)
    np.testing.assert_allclose(float(state.growth_rate), float(ref[0]), rtol=1e-12)
    # on both sides of the first instability: stable below, and just above only its (m, n) grows
    v_first = float(first.voltage)
    below = jd.stability(PAPER.replace(voltage=0.98 * v_first), **GRID)
    assert bool(below.stable) and int(below.m) == -1 and np.isnan(float(below.growth_rate))
    above = jd.stability(PAPER.replace(voltage=1.02 * v_first), **GRID)
    assert not bool(above.stable)
    assert (int(above.m), int(above.n)) == (int(first.m), int(first.n)) == (2, 1)
    assert np.sum(np.isfinite(np.asarray(above.growth))) == 1


@pytest.mark.slow
def test_growth_rate_derivative_and_vmap():
    """d s/d(V̂, λ_i) against central differences; vmapped over voltages: the single calls."""
    batch = jax.vmap(lambda v: jd.stability(PAPER.replace(voltage=v), **GRID))(
        jnp.array([0.02, 0.05]))
    np.testing.assert_array_equal(np.asarray(batch.stable), [True, False])
    single = jd.stability(PAPER.replace(voltage=0.05), **GRID)
    np.testing.assert_allclose(np.asarray(batch.growth[1]), np.asarray(single.growth), rtol=1e-13)

    def rate(v, li):
        return jd.stability(PAPER.replace(voltage=v, lambda_i=li), **GRID).growth_rate

    grad = jax.grad(rate, argnums=(0, 1))(0.05, 0.9)
    h = 1e-6
    for i, g in enumerate(grad):
        e = np.eye(2)[i] * h
        fd = (float(rate(0.05 + e[0], 0.9 + e[1])) - float(rate(0.05 - e[0], 0.9 - e[1]))) / (2 * h)
        np.testing.assert_allclose(float(g), fd, rtol=1e-6)


@pytest.mark.parametrize("kwargs, name", [
    (dict(n_max=0), "n_max"),
    (dict(m_max=-1), "m_max"),
    (dict(m_max=1, fluid=jd.Fluid(coupling="paper", bessel_order=0)), "m_max"),
])
def test_bad_input(kwargs, name):
    with pytest.raises(ValueError, match=name):
        jd.stability(PAPER.replace(voltage=0.05), **kwargs)
