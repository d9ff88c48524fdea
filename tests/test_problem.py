"""The static description of a problem (jaxdea.physics.families, jaxdea.physics.problem): built and
validated once, hashable, and interchangeable with the family names it replaced."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxdea as jd
from jaxdea.physics.families import Face, Family
from jaxdea.physics.problem import Problem, describe

TUBE = jd.Tube(voltage=0.1, lambda_i=0.9, lambda_z=1.2)


def test_family_is_its_old_name():
    """Equal, hashed and printed as the strings the programs were keyed on (no new compiled
    signature, the same cache keys)."""
    for family, name in ((Family.LONGITUDINAL, "longitudinal"), (Family.ORDER_M, "order_m"),
                         (Family.TORSIONAL, "torsional")):
        assert family == name and hash(family) == hash(name)
        assert repr(family) == repr(name) and f"{family}" == name
        assert Family(name) is family


@pytest.mark.parametrize("kwargs, family, face, order", [
    (dict(), Family.LONGITUDINAL, Face.EMPTY, 0),
    (dict(m=2), Family.ORDER_M, Face.EMPTY, 0),
    (dict(torsional=True), Family.TORSIONAL, Face.EMPTY, 0),
    (dict(fluid=jd.Fluid()), Family.LONGITUDINAL, Face.ACOUSTIC, 0),
    (dict(fluid=jd.Fluid(coupling="paper", bessel_order=3)), Family.LONGITUDINAL, Face.PAPER, 3),
])
def test_describe(kwargs, family, face, order):
    fluid = kwargs.pop("fluid", None)
    problem = describe(TUBE, 0.445, fluid, None, None, **kwargs)
    assert problem == Problem(family, face, order)
    assert hash(problem) == hash(Problem(family, face, order))


def test_describe_raises_as_the_solvers_did():
    with pytest.raises(ValueError, match="torsional=True exists only at m = 0"):
        describe(TUBE, 0.445, None, None, None, m=1, torsional=True)
    with pytest.raises(ValueError, match="'paper' coupling is axisymmetric"):
        describe(TUBE, 0.445, jd.Fluid(coupling="paper", bessel_order=1), None, None, m=2)
    with pytest.raises(ValueError, match="m must be an integer >= 0"):
        describe(TUBE, 0.445, None, None, None, m=1.5)


def test_traced_m_is_the_order_m_family():
    assert jax.jit(lambda m: jnp.float64(describe(TUBE, 0.445, None, None, None, m=m).family.size))(
        1.0) == 8


def test_admissible_and_safe_m():
    """An inadmissible traced m gives the state matrix order 0; the torsional family and the
    paper's coupling admit m = 0 only; the longitudinal family does not read m."""
    m = jnp.array([0.0, 1.0, 2.5, -1.0, np.nan])
    ok = Family.ORDER_M.admissible(m)
    np.testing.assert_array_equal(ok, [True, True, False, False, False])
    np.testing.assert_array_equal(Family.ORDER_M.safe_m(m, ok), [0.0, 1.0, 0.0, 0.0, 0.0])
    np.testing.assert_array_equal(Family.TORSIONAL.admissible(m), [True, False, False, False, False])
    paper = jd.Fluid(coupling="paper", bessel_order=1)
    np.testing.assert_array_equal(Family.ORDER_M.admissible(m, paper), [True] + [False] * 4)
    assert bool(Family.LONGITUDINAL.admissible(jnp.nan)) and Family.LONGITUDINAL.safe_m(3.0, True) == 0.0
    assert Family.LONGITUDINAL.arguments(2.0) == {}
    assert Family.ORDER_M.arguments(2.0) == dict(m=2.0, family=Family.ORDER_M)


def test_face_of_a_fluid_not_yet_validated():
    assert Face.of(None) is Face.EMPTY and Face.of(jd.Fluid()) is Face.ACOUSTIC
    bad = jd.Fluid(coupling="none")
    assert Face.of(bad, strict=False) is Face.EMPTY
    with pytest.raises(ValueError):
        Face.of(bad)


@pytest.mark.parametrize("call", [
    lambda: jd.frequency(jd.Tube(), None, 1.0),
    lambda: jd.frequencies(jd.Tube(), None),
    lambda: jd.critical_voltage(jd.Tube(), None),
    lambda: jd.mode_shape(jd.Tube(), None, 1.0),
], ids=["frequency", "frequencies", "critical_voltage", "mode_shape"])
def test_a_missing_alpha_is_named(call):
    """alpha=None is a user's missing α̂ (found by tests/test_fuzz.py: it raised JAX's "None is not a
    valid value for jnp.array"); solvers without an α̂ of their own pass NO_ALPHA."""
    with pytest.raises(ValueError, match="alpha must be a real number"):
        call()
