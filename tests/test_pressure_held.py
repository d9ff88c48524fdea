"""A tube held by its pressure difference, as in a lab (jaxdea.solve.instability, the designs with
``delta_p``): the first instability along the held static branch against independent growth-rate
scans of the stretch-held tube at the λ_i that ``inner_stretch`` gives, its derivatives against
central differences, the held tunability against a difference quotient along the branch, and a
held design checked by direct solves."""

import math

import jax
import numpy as np
import pytest

import jaxdea as jd
from jaxdea.studies import design

TUBE = jd.Tube(lambda_i=1.1, lambda_z=1.2)  # the paper's tube, inflated to λ_i = 1.1 at V̂ = 0
HELD = float(jd.pressure_difference(TUBE.replace(voltage=0.0)))  # the ΔP̂ that holds it there
GRID = dict(n_max=1, m_max=2)


def held(voltage, tube=TUBE, delta_p=HELD):
    """The stretch-held tube at the λ_i that ΔP̂ holds at ``voltage`` (jaxdea.inner_stretch)."""
    lam, status = jd.inner_stretch(tube.replace(voltage=voltage), delta_p)
    assert int(status) == jd.Status.CONVERGED
    return tube.replace(voltage=voltage, lambda_i=float(lam))


@pytest.fixture(scope="module")
def first():
    return jd.first_instability(TUBE, delta_p=HELD, **GRID)


def test_held_first_instability_is_where_the_held_state_starts_to_grow(first):
    assert int(first.status) == jd.Status.CONVERGED
    v = float(first.voltage)
    # held by its stretch at λ_i = 1.1 the paper's tube buckles in (2, 1) at 0.106; held by its
    # pressure it inflates as the voltage rises and bulges axisymmetrically (0, 1) first, lower
    assert (int(first.m), int(first.n)) == (0, 1)
    stretch = jd.first_instability(TUBE, **GRID)
    assert v < float(stretch.voltage)
    alpha = jd.axial_wavenumber(TUBE, 1)
    # independent: the stretch-held solvers at the λ_i inner_stretch gives, along the held branch
    for fraction in (0.5, 0.9, 0.99):
        for m in range(3):
            rates = jd.growth_rates(held(fraction * v), alpha, m=m, n_roots=1)
            assert np.isnan(rates[0]), (fraction, m)
    rate = jd.growth_rates(held(1.01 * v), alpha, m=0, n_roots=1)[0]
    assert np.isfinite(rate) and rate > 0
    # and the lowest frequency of (0, 1) vanishes there: f(Ω = 0) changes sign within 1e-6 of V̂
    # (Ω² falls linearly to zero: Ω at 1 − 1e-4 is sqrt(1/10) of Ω at 1 − 1e-3)
    lowest = [float(jd.frequencies(held((1.0 - gap) * v), alpha, n_roots=1)[0])
              for gap in (1e-3, 1e-4)]
    assert lowest[1] / lowest[0] == pytest.approx(math.sqrt(0.1), rel=0.05)
    assert changes_sign(v, alpha, 0)


def changes_sign(v, alpha, m, gap=1e-6):
    """f(Ω = 0) of order m of the held tube changes sign between (1 ∓ gap) V̂."""
    below, above = (float(jd.characteristic(held((1.0 + s * gap) * v), 0.0, alpha, m=m))
                    for s in (-1.0, 1.0))
    return below * above < 0


def test_every_held_critical_voltage_is_a_zero_on_the_held_branch(first):
    alpha = jd.axial_wavenumber(TUBE, 1)
    critical = np.asarray(first.critical)
    assert critical.shape == (3, 1) and np.all(np.isfinite(critical))
    for m in range(3):
        assert changes_sign(float(critical[m, 0]), alpha, m), m


def test_held_first_instability_derivatives_match_central_differences(first):
    def voltage(eta, delta_p):
        return jd.first_instability(TUBE.replace(eta=eta), delta_p=delta_p, **GRID).voltage

    eta = float(TUBE.eta)
    d_eta, d_p = jax.grad(voltage, argnums=(0, 1))(eta, HELD)
    h = 1e-5
    fd_eta = (float(voltage(eta + h, HELD)) - float(voltage(eta - h, HELD))) / (2 * h)
    fd_p = (float(voltage(eta, HELD + h)) - float(voltage(eta, HELD - h))) / (2 * h)
    assert float(d_eta) == pytest.approx(fd_eta, rel=1e-6)
    assert float(d_p) == pytest.approx(fd_p, rel=1e-6)


def test_held_tunability_is_the_derivative_along_the_held_branch():
    alpha = jd.axial_wavenumber(TUBE, 1)

    def omega(v):
        return float(jd.frequencies(held(v), alpha, n_roots=1, m=2)[0])

    v, h = 0.03, 1e-5
    tube = held(v)
    slope = float(design.tunability(tube, alpha, omega(v), m=2, delta_p=HELD))
    assert slope == pytest.approx((omega(v + h) - omega(v - h)) / (2 * h), rel=1e-6)
    # held by its stretch the same state tunes differently (λ_i does not follow)
    fixed = float(design.tunability(tube, alpha, omega(v), m=2))
    assert abs(fixed - slope) > 1e-3 * abs(slope)


@pytest.mark.parametrize("call, name", [
    (lambda: jd.first_instability(TUBE, delta_p=math.nan), "delta_p"),
    (lambda: jd.first_instability(TUBE, delta_p="1"), "delta_p"),
    (lambda: jd.first_instability(TUBE, delta_p=50.0), "delta_p"),
    (lambda: design.design_for_frequency(TUBE, 0.7, delta_p=math.inf), "delta_p"),
    (lambda: design.maximise_tunability(TUBE, delta_p=HELD, lambda_i_bounds=(1.0, 1.3)),
     "lambda_i_bounds"),
])
def test_bad_pressure_inputs_name_the_parameter(call, name):
    with pytest.raises(ValueError, match=name):
        call()


def test_held_design_reaches_its_target_under_its_own_first_instability():
    res = design.design_for_frequency(TUBE, 0.72, delta_p=HELD, **GRID)
    assert res.status == design.DesignStatus.CONVERGED
    tube = res.tube
    # λ_i is the one the pressure holds at the design's voltage and wall
    lam = float(jd.inner_stretch(tube, HELD)[0])
    assert float(tube.lambda_i) == pytest.approx(lam, rel=1e-12)
    # the target, by a direct solve of the stretch-held tube at that λ_i
    alpha = jd.axial_wavenumber(tube, 1)
    assert float(jd.frequencies(tube, alpha, n_roots=1)[0]) == pytest.approx(0.72, rel=2e-6)
    # the voltage sits at s_op · margin of the held tube's own first instability
    own = jd.first_instability(tube, delta_p=HELD, **GRID)
    assert float(own.voltage) == pytest.approx(res.critical_voltage, rel=1e-9)
    assert float(tube.voltage) == pytest.approx(0.5 * 0.8 * float(own.voltage), rel=2e-6)
    assert res.unstable_mode == (int(own.m), int(own.n))
