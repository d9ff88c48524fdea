"""Design optimisation (jaxdea.design): bad inputs, the tunability and its exact gradient against
central finite differences, and convergence of both example problems from several starts, each
optimum checked by a direct root solve (frequencies) and by critical_voltage."""

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxdea as jd
from jaxdea import design

TUBE = jd.Tube(lambda_i=1.1, lambda_z=1.2, eta=0.85)  # the paper's tube, inflated
ALPHA = jd.axial_wavenumber(TUBE, 1)


@pytest.mark.parametrize("call, name", [
    (lambda: design.design_for_frequency(TUBE, 0.0), "target"),
    (lambda: design.design_for_frequency(TUBE, -1.0), "target"),
    (lambda: design.design_for_frequency(TUBE, 0.7, n=0), "n"),
    (lambda: design.design_for_frequency(TUBE, 0.7, thickness_bounds=(1.0, 0.1)), "thickness_bounds"),
    (lambda: design.design_for_frequency(TUBE, 0.7, thickness=2.0), "thickness"),
    (lambda: design.design_for_frequency(TUBE, 0.7, operating_fraction=1.0), "operating_fraction"),
    (lambda: design.design_for_frequency(TUBE, 0.7, voltage_margin=1.2), "voltage_margin"),
    (lambda: design.design_for_frequency(TUBE, 0.7, max_steps=0), "max_steps"),
    (lambda: design.maximise_tunability(TUBE, lambda_i_bounds=(1.4, 0.9)), "lambda_i_bounds"),
    (lambda: design.maximise_tunability(TUBE, voltage_fraction=0.0), "voltage_fraction"),
    (lambda: design.maximise_tunability(TUBE, lambda_i=1.2), "lambda_i"),
    (lambda: design.maximise_tunability("tube"), "tube"),
])
def test_bad_inputs_name_the_parameter(call, name):
    with pytest.raises(ValueError, match=name):
        call()


def _objective(x, setting, kind, guess):
    aux, grad = design._evaluate(jnp.asarray(x, jnp.float64), guess, setting, kind, 30)
    return float(aux["loss"]), np.asarray(grad), aux


@pytest.mark.slow
def test_tunability_objective_gradient_matches_central_differences():
    """Loss −|dΩ/dV̂| over (x_s, x_λ): its forward-mode gradient holds second derivatives of Ω
    (through V̂_cr(λ_i) and the root); central differences of the loss, each point solved afresh."""
    setting = dict(tube=TUBE.replace(voltage=0.0), n=1.0, margin=0.8, li_lo=0.9, li_hi=1.4)
    x = np.array([1.9, 1.3])  # s = 0.66, λ_i = 1.16
    guess = float(jd.frequencies(TUBE.replace(voltage=0.1), ALPHA, n_roots=1)[0])
    loss, grad, aux = _objective(x, setting, "tunability_lambda", guess)
    omega = float(aux["omega"])
    h = 1e-4  # truncation ~ h² |L'''| ≈ 1e-8, rounding ~ 1e-15/h
    for i in range(2):
        e = np.eye(2)[i] * h
        fd = (_objective(x + e, setting, "tunability_lambda", omega)[0]
              - _objective(x - e, setting, "tunability_lambda", omega)[0]) / (2 * h)
        np.testing.assert_allclose(grad[i], fd, rtol=1e-6)
    # the tunability itself against central differences of directly solved roots in V̂
    tube = aux["tube"]
    v = float(tube.voltage)
    dv = 1e-5 * v
    roots = [float(jd.frequencies(tube.replace(voltage=v + d), ALPHA, n_roots=1)[0]) for d in (dv, -dv)]
    np.testing.assert_allclose(float(aux["tunability"]), (roots[0] - roots[1]) / (2 * dv), rtol=1e-7)
    assert loss == pytest.approx(-abs(float(aux["tunability"])), rel=1e-14)


@pytest.mark.slow
def test_tunability_function_second_derivative():
    """d/dV̂ of tunability(tube, α̂, frequency(...)) equals central differences of the tunability."""
    def t_of_v(v):
        tube = TUBE.replace(voltage=v)
        return design.tunability(tube, ALPHA, jd.frequency(tube, ALPHA, 0.75))

    v = 0.1
    h = 2e-5
    fd = (float(t_of_v(v + h)) - float(t_of_v(v - h))) / (2 * h)
    np.testing.assert_allclose(float(jax.jacfwd(t_of_v)(v)), fd, rtol=1e-6)


def _check_frequency_design(res, target, rtol):
    assert res.converged, res.status
    lowest = float(jd.frequencies(res.tube, res.alpha, n_roots=1)[0])  # direct, independent solve
    # converged to rtol at the tracked root; the direct solve agrees with it to Newton's accuracy
    assert abs(lowest / target - 1.0) <= rtol + 1e-12
    v_cr = float(jd.critical_voltage(res.tube, jd.axial_wavenumber(res.tube, 1)))
    assert res.voltage <= 0.8 * v_cr
    assert abs(res.voltage / (0.8 * v_cr) - 0.5) <= rtol + 1e-12
    assert res.alpha == pytest.approx(float(jd.axial_wavenumber(res.tube, 1)), rel=1e-14)
    assert res.n_steps == len(res.history)


@pytest.mark.slow
def test_frequency_design_converges_from_several_starts():
    target, rtol = 0.72, 1e-6
    results = [design.design_for_frequency(TUBE, target, thickness=h0, voltage_fraction=s0, rtol=rtol)
               for h0, s0 in [(0.176, 0.5), (0.1, 0.2), (0.6, 0.8)]]
    for res in results:
        _check_frequency_design(res, target, rtol)
    thickness = [r.thickness for r in results]
    # both residuals below rtol: H/R_i agrees to rtol / |d ln Ω/dH| ≈ 1e-5
    np.testing.assert_allclose(thickness, thickness[0], rtol=3e-5)


@pytest.mark.slow
def test_tunability_optimum_is_on_the_constraint_from_several_starts():
    results = [design.maximise_tunability(TUBE, voltage_fraction=s0) for s0 in (0.2, 0.5, 0.8)]
    v_cr = float(jd.critical_voltage(TUBE, ALPHA))
    for res in results:
        assert res.converged, res.status
        assert res.voltage <= 0.8 * v_cr * (1 + 1e-12)
        assert res.voltage == pytest.approx(0.8 * v_cr, rel=1e-6)  # the active constraint
        v = res.voltage
        dv = 1e-5 * v
        roots = [float(jd.frequencies(TUBE.replace(voltage=v + d), ALPHA, n_roots=1)[0])
                 for d in (dv, -dv)]
        assert res.tunability == pytest.approx((roots[0] - roots[1]) / (2 * dv), rel=1e-6)
    assert math.isclose(results[0].tunability, results[2].tunability, rel_tol=1e-6)
