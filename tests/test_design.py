"""Design optimisation (jaxdea.studies.design): bad inputs, the tunability and its exact gradient against
central finite differences, the stability bound (the first instability over every order m and
axial mode n) and convergence of both example problems from several starts, each optimum checked
by a direct root solve (frequencies) and by first_instability."""

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxdea as jd
from jaxdea.studies import design
from jaxdea.units import VACUUM_PERMITTIVITY, Scales, tube_from_si, tube_to_si

TUBE = jd.Tube(lambda_i=1.1, lambda_z=1.2, eta=0.85)  # the paper's tube, inflated
ALPHA = jd.axial_wavenumber(TUBE, 1)
N = 30  # the internal objective tests run on the paper's laminate (midpoint, N = 30)


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
    (lambda: design.maximise_tunability(TUBE, m_max=-1), "m_max"),
    (lambda: design.design_for_frequency(TUBE, 0.7, n_max=0), "n_max"),
    (lambda: design.design_for_frequency(TUBE, 0.7, m_max=1.5), "m_max"),
    (lambda: design.design_for_frequency(TUBE, 0.7, hold="volume"), "hold"),
    (lambda: design.design_for_frequency(TUBE, 0.7, m=-1), "m"),
    (lambda: design.design_for_frequency(TUBE, 0.7, m=2, torsional=True), "torsional"),
    (lambda: design.maximise_tunability(TUBE, m=1.5), "m"),
])
def test_bad_inputs_name_the_parameter(call, name):
    with pytest.raises(ValueError, match=name):
        call()


def test_tunability_refuses_an_omega_that_is_no_root():
    tube = TUBE.replace(voltage=0.1)
    root = float(jd.frequencies(tube, ALPHA, n_roots=1)[0])
    assert math.isfinite(float(design.tunability(tube, ALPHA, root)))
    with pytest.raises(ValueError, match="omega = 0.5 is not a root"):
        design.tunability(tube, ALPHA, 0.5)
    assert math.isnan(float(jax.jit(lambda w: design.tunability(tube, ALPHA, w))(0.5)))


def test_candidates_are_the_modes_near_the_first_instability():
    grid = np.array([[0.30, 0.28], [0.20, 0.19], [0.030, 0.0315], [0.031, np.nan]])
    cands = design._candidates(grid)  # within 5 % of 0.030: (2, 1), (3, 1), (2, 2); padded
    assert np.asarray(cands.m).tolist() == [2.0, 3.0, 2.0, 2.0]
    assert np.asarray(cands.n).tolist() == [1.0, 1.0, 2.0, 1.0]
    assert design._candidates(np.full((2, 2), np.nan)) is None


def _objective(x, setting, kind, guess, candidates):
    aux, grad = design._evaluate(jnp.asarray(x, jnp.float64), guess, setting, kind, N, "midpoint",
                                 candidates)
    return float(aux["loss"]), np.asarray(grad), aux


@pytest.mark.slow
def test_bound_is_the_first_instability_and_refreshes_when_overtaken():
    """The candidate bound equals first_instability; a run that tracked only the axisymmetric mode
    is not confirmed, and the refresh brings in the (m, n) that buckles first."""
    setting = dict(tube=TUBE.replace(voltage=0.0), n=1.0, margin=0.8, li_lo=0.0, li_hi=1.0)
    setting = jax.tree_util.tree_map(lambda v: jnp.asarray(v, jnp.float64), setting)
    first = jd.first_instability(TUBE, n_max=3, m_max=8, n_layers=N)
    bound = design._Bound(setting, "tunability", N, "midpoint", 8, 3)
    x = [1.0]
    assert bound.refresh(x)
    assert bound.first == pytest.approx(float(first.voltage), rel=1e-13)
    assert bound.mode == (int(first.m), int(first.n)) == (2, 1)
    guess = float(jd.frequencies(TUBE.replace(voltage=0.05), ALPHA, n_roots=1)[0])
    _, _, aux = _objective(x, setting, "tunability", guess, bound.candidates)
    assert float(aux["critical_voltage"]) == pytest.approx(float(first.voltage), rel=1e-12)
    assert bound.confirmed(x, aux)
    axisymmetric = design.Candidates(jnp.zeros(4), jnp.ones(4))  # (0, 1) only, the paper's bound
    _, _, aux = _objective(x, setting, "tunability", guess, axisymmetric)
    assert float(aux["critical_voltage"]) == pytest.approx(
        float(jd.critical_voltage(TUBE, ALPHA, n_layers=N)), rel=1e-12)
    assert not bound.confirmed(x, aux)
    assert (2.0, 1.0) in zip(np.asarray(bound.candidates.m).tolist(),
                             np.asarray(bound.candidates.n).tolist(), strict=True)


@pytest.mark.slow
def test_tunability_objective_gradient_matches_central_differences():
    """Loss −|dΩ/dV̂| over (x_s, x_λ): its forward-mode gradient holds second derivatives of Ω
    (through V̂_cr(λ_i) and the root); central differences of the loss, each point solved afresh."""
    setting = dict(tube=TUBE.replace(voltage=0.0), n=1.0, margin=0.8, li_lo=0.9, li_hi=1.4)
    x = np.array([1.9, 1.3])  # s = 0.66, λ_i = 1.16
    bound = design._Bound(setting, "tunability_lambda", N, "midpoint", 8, 3)
    assert bound.refresh(x)
    cands = bound.candidates  # several (m, n) near the first instability; the gradient of the min
    guess = float(jd.frequencies(TUBE.replace(voltage=0.05), ALPHA, n_roots=1)[0])
    loss, grad, aux = _objective(x, setting, "tunability_lambda", guess, cands)
    omega = float(aux["omega"])
    h = 1e-4  # truncation ~ h² |L'''| ≈ 1e-8, rounding ~ 1e-15/h
    for i in range(2):
        e = np.eye(2)[i] * h
        fd = (_objective(x + e, setting, "tunability_lambda", omega, cands)[0]
              - _objective(x - e, setting, "tunability_lambda", omega, cands)[0]) / (2 * h)
        np.testing.assert_allclose(grad[i], fd, rtol=1e-6)
    # the tunability itself against central differences of directly solved roots in V̂
    tube = aux["tube"]
    v = float(tube.voltage)
    dv = 1e-5 * v
    roots = [float(jd.frequencies(tube.replace(voltage=v + d), ALPHA, n_roots=1, n_layers=N)[0])
             for d in (dv, -dv)]
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
    first = jd.first_instability(res.tube, n_max=3, m_max=8)  # independent of the run's candidates
    v_first = float(first.voltage)
    assert res.critical_voltage == pytest.approx(v_first, rel=1e-9)
    assert res.unstable_mode == (int(first.m), int(first.n))
    assert res.voltage <= 0.8 * v_first
    assert abs(res.voltage / (0.8 * v_first) - 0.5) <= rtol + 1e-12
    assert res.alpha == pytest.approx(float(jd.axial_wavenumber(res.tube, 1)), rel=1e-14)
    assert res.n_steps == len(res.history)


@pytest.mark.slow
def test_frequency_design_converges_from_several_starts():
    """Ω = 0.72 with L/R_o held (α̂ follows the wall). With the default hold="length" (L/R_i held,
    α̂ fixed) this tube's lowest Ω stays above about 0.75 over the allowed thicknesses, so the target
    is out of reach there."""
    target, rtol = 0.72, 1e-6
    results = [design.design_for_frequency(TUBE, target, thickness=h0, voltage_fraction=s0, rtol=rtol,
                                           hold="length_ratio")
               for h0, s0 in [(0.176, 0.5), (0.1, 0.2), (0.6, 0.8)]]
    for res in results:
        _check_frequency_design(res, target, rtol)
    thickness = [r.thickness for r in results]
    # both residuals below rtol: H/R_i agrees to rtol / |d ln Ω/dH| ≈ 1e-5
    np.testing.assert_allclose(thickness, thickness[0], rtol=3e-5)
    # ring buckling bounds the voltage far below the axisymmetric V̂_cr of the mode
    assert results[0].unstable_mode == (2, 1)
    v_axisymmetric = float(jd.critical_voltage(results[0].tube, results[0].alpha))
    assert results[0].critical_voltage < 0.7 * v_axisymmetric


@pytest.mark.slow
def test_frequency_design_with_the_axisymmetric_bound_only():
    """m_max = 0, n_max = 1: the bound is the designed mode's own V̂_cr (the paper's constraint);
    L/R_o held, as the target needs (previous test)."""
    res = design.design_for_frequency(TUBE, 0.72, m_max=0, n_max=1, hold="length_ratio")
    assert res.converged, res.status
    assert res.unstable_mode == (0, 1)
    v_cr = float(jd.critical_voltage(res.tube, res.alpha))
    assert res.critical_voltage == pytest.approx(v_cr, rel=1e-9)
    assert abs(res.voltage / (0.8 * v_cr) - 0.5) <= 1e-6 + 1e-12
    assert float(jd.frequencies(res.tube, res.alpha, n_roots=1)[0]) == pytest.approx(0.72, rel=1e-6)


@pytest.mark.slow
def test_tunability_optimum_is_on_the_constraint_from_several_starts():
    results = [design.maximise_tunability(TUBE, voltage_fraction=s0) for s0 in (0.2, 0.5, 0.8)]
    v_first = float(jd.first_instability(TUBE, n_max=3, m_max=8).voltage)
    for res in results:
        assert res.converged, res.status
        assert res.unstable_mode == (2, 1)
        assert res.voltage <= 0.8 * v_first * (1 + 1e-12)
        assert res.voltage == pytest.approx(0.8 * v_first, rel=1e-6)  # the active constraint
        v = res.voltage
        dv = 1e-5 * v
        roots = [float(jd.frequencies(TUBE.replace(voltage=v + d), ALPHA, n_roots=1)[0])
                 for d in (dv, -dv)]
        assert res.tunability == pytest.approx((roots[0] - roots[1]) / (2 * dv), rel=1e-6)
    assert math.isclose(results[0].tunability, results[2].tunability, rel_tol=1e-6)


# a silicone-like tube in SI (issue 43): R_i = 4 mm, R_o = 7 mm, L = 60 mm, μ = 60 kPa
SILICONE = Scales(shear_modulus=60e3, density=1070.0, permittivity=2.8 * VACUUM_PERMITTIVITY,
                  inner_radius=4e-3)
LENGTH = 60e-3
SI_TUBE = dict(lambda_i=1.1, lambda_z=1.2, gent=35.0)


RING_TARGET_HZ = 240.0  # (2, 1) at 0.4 V̂_first: 229.0 Hz with R_o = 7 mm, 244.6 Hz with 6 mm


@pytest.mark.slow
def test_silicone_160_hz_design_converges():
    """The 160 Hz target on which adam, holding L/R_o as it then did, stopped at MAX_STEPS after 500
    steps 0.42 % off (measured; issue 43: 0.31 %) converges by Newton on the scalar constraint in a
    few steps; an independent solve of the result on a finer laminate rings at 160 Hz."""
    tube = tube_from_si(SILICONE, outer_radius=7e-3, length=LENGTH, **SI_TUBE)
    target = float(SILICONE.hz_to_omega(160.0))
    res = design.design_for_frequency(tube, target, hold="length_ratio")
    assert res.converged, res.status
    assert res.n_steps <= 15
    assert abs(res.omega / target - 1.0) <= 1e-6
    assert abs(res.voltage_fraction - 0.5) <= 1e-6
    assert res.tube.length_ratio == pytest.approx(float(tube.length_ratio), rel=1e-15)
    finer = float(jd.frequencies(res.tube, res.alpha, n_roots=1, n_layers=64, scheme="magnus6")[0])
    assert float(SILICONE.omega_to_hz(finer)) == pytest.approx(160.0, rel=2e-6)


@pytest.mark.slow
def test_ring_mode_design_holds_the_length_in_si():
    """The ring mode (2, 1) designed under the first instability, the tube's length held at 60 mm:
    its SI description, rebuilt with tube_from_si and solved independently on a finer laminate,
    rings at the target below 0.8 V̂_first."""
    tube = tube_from_si(SILICONE, outer_radius=7e-3, length=LENGTH, **SI_TUBE)
    target = float(SILICONE.hz_to_omega(RING_TARGET_HZ))
    res = design.design_for_frequency(tube, target, m=2)
    assert res.converged, res.status
    assert res.n_steps <= 15
    si = tube_to_si(SILICONE, res.tube)
    assert float(si.length) == pytest.approx(LENGTH, rel=1e-13)
    assert not 6.9e-3 < float(si.outer_radius) < 7.1e-3  # the wall did change
    rebuilt = tube_from_si(SILICONE, outer_radius=float(si.outer_radius), length=LENGTH,
                           voltage=float(si.voltage), **SI_TUBE)
    alpha = jd.axial_wavenumber(rebuilt, 1)
    assert float(alpha) == pytest.approx(res.alpha, rel=1e-13)
    finer = float(jd.frequencies(rebuilt, alpha, n_roots=1, m=2, n_layers=64, scheme="magnus6")[0])
    assert float(SILICONE.omega_to_hz(finer)) == pytest.approx(RING_TARGET_HZ, rel=2e-6)
    first = jd.first_instability(rebuilt, n_max=3, m_max=8)
    assert res.critical_voltage == pytest.approx(float(first.voltage), rel=1e-8)
    assert res.voltage == pytest.approx(0.4 * float(first.voltage), rel=2e-6)
    slope = float(jd.tunability(res.tube, res.alpha, res.omega, m=2))
    assert res.tunability == pytest.approx(slope, rel=1e-9)


def test_a_target_beyond_the_walls_stable_at_rest_stops_at_them():
    """The paper's tube at λ_i = 0.9 asked for Ω = 0.8 (n = 1): thinner walls raise Ω towards it, but
    walls thinner than about η = 0.9 buckle at V̂ = 0 (ring modes). The run reports
    UNSTABLE_AT_REST with the last iterate that the full (m, n) grid finds stable at rest: the
    first instability of its tube at V̂ = 0 is its critical_voltage (> 0, to 1e-9), its voltage is
    within the margin, its Ω short of the target and the lowest root there. (Before, the run stopped
    as NOT_FINITE at a wall that buckles at rest, η = 0.94, reporting the stale bound 0.0033 of the
    modes it tracked.)"""
    paper = jd.Tube(lambda_z=1.2, eta=0.85, lambda_i=0.9)
    res = design.design_for_frequency(paper, 0.8, n=1)
    assert res.status == design.DesignStatus.UNSTABLE_AT_REST
    assert not res.converged
    first = jd.first_instability(res.tube.replace(voltage=0.0), n_max=3, m_max=8)
    assert float(first.voltage) > 0.0
    np.testing.assert_allclose(float(first.voltage), res.critical_voltage, rtol=1e-9)
    assert (int(first.m), int(first.n)) == res.unstable_mode
    assert 0.0 < res.voltage <= 0.8 * res.critical_voltage * (1 + 1e-12)
    assert res.omega < 0.8
    np.testing.assert_allclose(res.omega, float(jd.frequencies(res.tube, res.alpha, n_roots=1)[0]),
                               rtol=1e-12)
