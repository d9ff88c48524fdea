"""Random and extreme inputs: a ValueError naming the parameter, or a finite result — never an
exception from inside JAX or a silent wrong number (small profile; the large one is marked slow)."""

import math

import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import jaxdea as jd

NAMES = ("voltage", "lambda_i", "lambda_z", "eta", "gent", "alpha", "Gent locking")
values = st.one_of(
    st.floats(-3.0, 3.0),
    st.sampled_from([0.0, -0.0, 1e-300, 1e300, math.inf, -math.inf, math.nan]),
)


def _check(voltage, lambda_i, lambda_z, eta, gent, alpha):
    tube = jd.Tube(voltage=voltage, lambda_i=lambda_i, lambda_z=lambda_z, eta=eta, gent=gent)
    try:
        f = jd.characteristic(tube, 1.0, alpha)
    except ValueError as exc:
        assert any(name in str(exc) for name in NAMES), str(exc)
        return
    # accepted inputs are physically admissible: the result is finite and scaled, or NaN only
    # where the exponential range is exceeded (reported, never a plausible wrong number)
    value = float(f)
    assert math.isnan(value) or abs(value) <= 1.0
    assert 0 < lambda_i and 0 < lambda_z and 0 < eta < 1 and gent > 0 and alpha > 0


PROFILE = dict(deadline=None, suppress_health_check=[HealthCheck.too_slow])


@settings(max_examples=40, **PROFILE)
@given(values, values, values, values, values, values)
def test_random_inputs_small_profile(voltage, lambda_i, lambda_z, eta, gent, alpha):
    _check(voltage, lambda_i, lambda_z, eta, gent, alpha)


@pytest.mark.slow
@settings(max_examples=1000, **PROFILE)
@given(values, values, values, values, values, values)
def test_random_inputs_large_profile(voltage, lambda_i, lambda_z, eta, gent, alpha):
    _check(voltage, lambda_i, lambda_z, eta, gent, alpha)


def test_traced_bad_values_give_nan_and_status():
    """Under vmap nothing is validated: a negative stretch or η ≥ 1 gives NaN and status INVALID."""
    import jax

    tubes = jd.Tube(lambda_i=jnp.array([-1.0, 1.0]), eta=jnp.array([0.85, 1.5]))
    axes = jd.Tube(voltage=None, lambda_i=0, lambda_z=None, eta=0, gent=None, length_ratio=None)
    out = jax.vmap(lambda t: jd.solve_frequencies(t, 0.445), in_axes=(axes,))(tubes)
    assert np.all(np.isnan(np.asarray(out.omega)))
    assert np.all(np.asarray(out.status) == jd.Status.INVALID)
