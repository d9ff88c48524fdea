"""Branch tracing (jaxdea.solve.trace): synthetic curves with known turning points and veerings, the real
tube against independent root solves, the critical voltage as a zero-frequency event, batching
without recompilation, and bad inputs.

Compilation dominates: all synthetic curves share one compiled continuation (a quadratic plus a
square-root term, coefficients traced), and each tube configuration is compiled once."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxdea as jd
from jaxdea.solve import trace as trace_module
from jaxdea.solve.trace import BranchEnd, continue_branch, trace_branch

PAPER = dict(lambda_z=1.2, eta=0.85)
TUBE = jd.Tube(voltage=0.1, lambda_i=0.9, **PAPER)


# ------------------------------------------------------------------------------ synthetic curves
def _synthetic(s, omega, c):
    """c = [A, B, C, D, E, F, G, H]: A s² + B Ω² + C sΩ + D s + E Ω + F + G sqrt(H − s)."""
    return (c[0] * s**2 + c[1] * omega**2 + c[2] * s * omega + c[3] * s + c[4] * omega + c[5]
            + c[6] * jnp.sqrt(c[7] - s))


@jax.jit
def _trace_synthetic(coefficients, s0, omega0, stop, max_step):
    return continue_branch(lambda s, om: _synthetic(s, om, coefficients), s0, omega0, stop,
                           max_points=64, max_step=max_step)


def _ellipse(s_c, om_c, a, b):
    """((s − s_c)/a)² + ((Ω − Ω_c)/b)² − 1."""
    return jnp.array([a**-2, b**-2, 0.0, -2 * s_c / a**2, -2 * om_c / b**2,
                      (s_c / a) ** 2 + (om_c / b) ** 2 - 1.0, 0.0, 1e6])


def _pair(c):
    """(Ω − s)(Ω − 2 + s) − c = −s² + Ω² + 2s − 2Ω − c: branches Ω = 1 ± sqrt((1 − s)² + c).
    c = ε² > 0: a veering with gap 2ε at s = 1; c = −ε² < 0: the branches reconnect through
    turning points at s = 1 ± ε, Ω = 1."""
    return jnp.array([-1.0, 1.0, 0.0, 2.0, -2.0, -c, 0.0, 1e6])


def _points(branch):
    n = int(branch.n_points)
    return np.asarray(branch.parameter[:n]), np.asarray(branch.omega[:n])


@pytest.mark.parametrize("stop, s_turn", [(2.0, 1.5), (0.0, 0.5)])
def test_ellipse_turning_point_located(stop, s_turn):
    """Lower half of the ellipse centred at (1, 3), semi-axes 0.5 (s) and 0.8 (Ω), from its bottom:
    the turning points are (1 ± 0.5, 3), whichever way the trace goes."""
    branch = _trace_synthetic(_ellipse(1.0, 3.0, 0.5, 0.8), 1.0, 2.25, stop, 0.1)
    assert int(branch.status) == BranchEnd.TURNING_POINT
    assert abs(float(branch.event_parameter) - s_turn) < 1e-10
    assert abs(float(branch.event_omega) - 3.0) < 1e-10
    s, om = _points(branch)
    assert s[-1] == branch.event_parameter and om[-1] == branch.event_omega
    # on the curve (the turning point itself is checked above: there Ω(s) is a square root, and
    # the reference formula amplifies the rounding of s to 5e-8)
    np.testing.assert_allclose(om[:-1], 3.0 - 0.8 * np.sqrt(1 - ((s[:-1] - 1) / 0.5) ** 2), rtol=0,
                               atol=1e-12)
    assert s[0] == 1.0 and abs(om[0] - 2.2) < 1e-15  # the guess 2.25 was corrected at fixed s
    assert np.all(np.diff(s) * np.sign(stop - 1.0) > 0)
    assert np.isnan(branch.slope[len(s) - 1]) and np.all(np.isfinite(branch.slope[: len(s) - 1]))
    assert np.all(np.isnan(branch.parameter[len(s):]))


@pytest.mark.parametrize("gap", [1e-3, 1e-5])
def test_veering_pair_keeps_identity(gap):
    """Both branches of a veering with gap 2ε traced through it from s = 0.5 to 1.5: every point of
    the lower trace lies on the lower branch and vice versa (the k-th root keeps its k). Tolerance:
    the expanded quadratic is rounded to ~1e-16 while |∇f| ≈ 2ε at the veering, so the roots are
    accurate to ~1e-16/ε (measured: 1.7e-13 for gap 1e-3, 5.6e-12 for gap 1e-5)."""
    eps = gap / 2
    for sign in (-1.0, 1.0):
        branch = _trace_synthetic(_pair(eps**2), 0.5, 1.0 + sign * 0.5, 1.5, 0.1)
        assert int(branch.status) == BranchEnd.REACHED_STOP
        s, om = _points(branch)
        assert s[-1] == 1.5 and s[0] == 0.5 and np.all(np.diff(s) > 0)
        np.testing.assert_allclose(om, 1.0 + sign * np.sqrt((1.0 - s) ** 2 + eps**2), rtol=0,
                                   atol=1e-15 / eps)
        assert np.any(np.abs(s - 1.0) < 10 * eps)  # the veering itself was resolved
        assert float(branch.event_parameter) == 1.5 and float(branch.event_omega) == om[-1]


def test_reconnecting_pair_turns_at_the_gap():
    """c = −ε²: the lower branch coming from s = 0.5 turns back at s = 1 − ε, Ω = 1."""
    eps = 5e-4
    branch = _trace_synthetic(_pair(-(eps**2)), 0.5, 0.5, 1.5, 0.1)
    assert int(branch.status) == BranchEnd.TURNING_POINT
    np.testing.assert_allclose(float(branch.event_parameter), 1.0 - eps, rtol=0, atol=1e-12)
    np.testing.assert_allclose(float(branch.event_omega), 1.0, rtol=0, atol=1e-12)


def test_other_ends_of_a_trace():
    """NOT_FINITE at the edge of the domain of f, MAX_POINTS, NO_START, zero frequency, stop = s0."""
    # Ω = 2 − s, but f = Ω + s − 2 + 0·sqrt(1.5 − s) is NaN beyond s = 1.5: the trace ends as close
    # to the edge as MIN_STEP allows
    edge = jnp.array([0, 0, 0, 1.0, 1.0, -2.0, 0.0, 1.5])
    branch = _trace_synthetic(edge, 0.0, 2.5, 2.0, 0.1)
    assert int(branch.status) == BranchEnd.NOT_FINITE
    s, om = _points(branch)
    assert 1.5 - 1e-8 < s[-1] <= 1.5
    np.testing.assert_allclose(om, 2.0 - s, rtol=0, atol=1e-12)
    assert np.isnan(branch.event_parameter)
    # a straight branch with tiny steps fills the 64 buffers
    branch = _trace_synthetic(_pair(0.25), 0.0, 2.0, 0.5, 1e-3)
    assert int(branch.status) == BranchEnd.MAX_POINTS and int(branch.n_points) == 64
    assert np.all(np.isfinite(branch.omega))
    # no root at all: s² + Ω² + 1 > 0
    branch = _trace_synthetic(jnp.array([1.0, 1.0, 0, 0, 0, 1.0, 0, 1e6]), 0.0, 1.0, 1.0, 0.1)
    assert int(branch.status) == BranchEnd.NO_START and int(branch.n_points) == 0
    assert np.all(np.isnan(branch.omega))
    # a circle around the origin, f even in Ω: Ω reaches 0 at s = 1 with a vertical tangent
    branch = _trace_synthetic(_ellipse(0.0, 0.0, 1.0, 1.0), 0.0, 1.0, 3.0, 0.1)
    assert int(branch.status) == BranchEnd.ZERO_FREQUENCY
    np.testing.assert_allclose(float(branch.event_parameter), 1.0, rtol=0, atol=1e-12)
    assert float(branch.event_omega) == 0.0 and float(branch.omega[int(branch.n_points) - 1]) == 0.0
    # stop at the start: the corrected start point only
    branch = _trace_synthetic(_ellipse(0.0, 0.0, 1.0, 1.0), 0.0, 1.1, 0.0, 0.1)
    assert int(branch.status) == BranchEnd.REACHED_STOP and int(branch.n_points) == 1
    assert abs(float(branch.omega[0]) - 1.0) < 1e-15


def test_vmap_of_the_core_equals_separate_calls():
    coefficients = _pair(0.25e-6)
    starts = jnp.array([0.5, 1.5])
    batched = jax.vmap(_trace_synthetic, (None, None, 0, None, None))(coefficients, 0.5, starts, 1.5,
                                                                      0.1)
    for i, om in enumerate(starts):
        one = _trace_synthetic(coefficients, 0.5, om, 1.5, 0.1)
        for name, a, b in zip(one._fields, one, batched, strict=True):
            np.testing.assert_allclose(b[i], a, rtol=1e-12, atol=1e-14, err_msg=name)


# ----------------------------------------------------------------------------------- real tubes
def test_trace_along_alpha_matches_frequencies_and_does_not_recompile():
    """Second root of the paper's tube from α̂ = 0.445 to 2: six trace points equal the second root
    of jd.frequencies at their α̂ (independent scan + Newton) to 1e-9 relative, the last point lies
    exactly at α̂ = 2, the slope equals a central difference of jd.frequencies (h = 1e-5: error
    O(h²) + O(1e-16/h) ≈ 1e-10), and new float values reuse the compiled trace."""
    roots = jd.frequencies(TUBE, 0.445)
    branch = trace_branch(TUBE, 0.445, roots[1], along="alpha", stop=2.0)
    assert int(branch.status) == BranchEnd.REACHED_STOP
    s, om = _points(branch)
    assert s[0] == 0.445 and s[-1] == 2.0 and float(branch.event_parameter) == 2.0
    branch_index = int(np.argmin(np.abs(np.asarray(roots) - om[0])))
    assert branch_index == 1
    for i in np.linspace(0, len(s) - 1, 6).astype(int):
        reference = float(jd.frequencies(TUBE, float(s[i]))[branch_index])
        np.testing.assert_allclose(om[i], reference, rtol=1e-9, err_msg=f"alpha = {s[i]}")
    i, h = len(s) // 2, 1e-5
    difference = (jd.frequencies(TUBE, float(s[i]) + h)[1] - jd.frequencies(TUBE, float(s[i]) - h)[1]) / (2 * h)
    np.testing.assert_allclose(branch.slope[i], difference, rtol=1e-8)

    before = trace_module._trace_branch._cache_size()
    tube = TUBE.replace(voltage=0.05, lambda_i=0.95, gent=60.0)
    other = trace_branch(tube, 0.6, jd.frequencies(tube, 0.6)[0], along="alpha", stop=0.3)
    assert int(other.status) == BranchEnd.REACHED_STOP and float(other.parameter[0]) == 0.6
    assert trace_module._trace_branch._cache_size() == before


def test_trace_along_voltage_ends_at_the_critical_voltage():
    """Lowest root of the n = 1 mode of Tube(λ_i = 1.1, λ_z = 1.2, η = 0.85) traced in V̂ from 0:
    Ω falls to 0 like sqrt(V̂_cr − V̂); the event is f(Ω = 0; V̂) = 0, i.e. jd.critical_voltage."""
    tube = jd.Tube(lambda_i=1.1, **PAPER)
    alpha = jd.axial_wavenumber(tube, 1)
    branch = trace_branch(tube, alpha, jd.frequencies(tube, alpha)[0], along="voltage", stop=0.4)
    assert int(branch.status) == BranchEnd.ZERO_FREQUENCY
    v_cr = float(jd.critical_voltage(tube, alpha))
    assert abs(float(branch.event_parameter) - v_cr) < 1e-9
    s, om = _points(branch)
    assert s[-1] == branch.event_parameter and om[-1] == 0.0 and np.all(om[:-1] > 0)
    assert np.all(np.diff(s) > 0) and np.all(np.diff(om) < 0)


@pytest.mark.slow
def test_vmap_over_starting_points_equals_separate_calls():
    """Two branches of the paper's tube traced in one vmapped call equal the separate calls."""
    roots = jd.frequencies(TUBE, 0.445)
    omegas, stops = jnp.stack([roots[0], roots[1]]), jnp.array([1.0, 2.0])
    batched = jax.vmap(lambda om, stop: trace_branch(TUBE, 0.445, om, along="alpha", stop=stop))(
        omegas, stops)
    for i in range(2):
        one = trace_branch(TUBE, 0.445, omegas[i], along="alpha", stop=stops[i])
        for name, a, b in zip(one._fields, one, batched, strict=True):
            np.testing.assert_allclose(b[i], a, rtol=1e-12, err_msg=name)


# A veering of the fluid-filled tube. With ρ̂_f = 0.13 the structural branch and the first cavity
# mode (Ω ≈ ĉ_f j_{1,1}/r̂_i ≈ 1.15) repel by ≈ 0.1; the gap shrinks like ρ̂_f^0.4–0.5 (0.0115 at 1e-3,
# 0.0035 at 1e-4, 0.0011 at 1e-5) and is 3.53e-4 at ρ̂_f = 1e-6, at α̂ ≈ 0.69826 (roots 1 and 2,
# Ω ≈ 1.1647 and 1.1650; found by minimising the gap of jd.frequencies(n_roots=3) on refined grids).
LIGHT_FLUID = jd.Fluid(density_ratio=1e-6, speed_ratio=0.27)
VEERING_ALPHA, VEERING_GAP = 0.698264, 3.53e-4


@pytest.mark.slow
def test_fluid_veering_keeps_identity():
    """Roots 1 and 2 of the tube filled with a very light fluid, traced from α̂ = 0.6 to 0.8 through
    the veering: each trace equals its own root of jd.frequencies at points on both sides of the
    veering and at the veering itself, to 1e-9 relative (the other root is ≥ 3.5e-4 away)."""
    def solve(alpha):
        return np.asarray(jd.frequencies(TUBE, float(alpha), LIGHT_FLUID, n_roots=3, omega_max=1.6))

    gap_roots = solve(VEERING_ALPHA)
    np.testing.assert_allclose(gap_roots[2] - gap_roots[1], VEERING_GAP, rtol=0.01)
    start = solve(0.6)
    for k in (1, 2):
        branch = trace_branch(TUBE, 0.6, start[k], LIGHT_FLUID, along="alpha", stop=0.8)
        assert int(branch.status) == BranchEnd.REACHED_STOP
        s, om = _points(branch)
        near = int(np.argmin(np.abs(s - VEERING_ALPHA)))
        index = np.unique(np.r_[np.linspace(0, len(s) - 1, 5).astype(int), near - 1, near, near + 1])
        assert np.any(s[index] < VEERING_ALPHA - 0.05) and np.any(s[index] > VEERING_ALPHA + 0.05)
        assert abs(s[near] - VEERING_ALPHA) < 1e-3
        for i in index:
            reference = solve(s[i])
            np.testing.assert_allclose(om[i], reference[k], rtol=1e-9, err_msg=f"alpha = {s[i]}")
            assert abs(om[i] - reference[3 - k]) > 3e-4


# ---------------------------------------------------------------------------------- bad inputs
@pytest.mark.parametrize("kwargs, name", [
    (dict(along="n", stop=1.0), "along"),
    (dict(along="density_ratio", stop=1.0), "along"),
    (dict(along=3, stop=1.0), "along"),
    (dict(stop=float("nan")), "stop"),
    (dict(stop=-1.0), "stop"),
    (dict(along="eta", stop=1.2), "stop"),
    (dict(stop=1.0, max_points=1), "max_points"),
    (dict(stop=1.0, max_points=2.5), "max_points"),
    (dict(stop=1.0, max_step=0.0), "max_step"),
    (dict(stop=1.0, n_layers=0), "n_layers"),
])
def test_bad_inputs_name_the_parameter(kwargs, name):
    with pytest.raises(ValueError, match=name):
        trace_branch(TUBE, 0.445, 0.7, **kwargs)


def test_bad_start_values_name_the_parameter():
    with pytest.raises(ValueError, match="omega"):
        trace_branch(TUBE, 0.445, -0.7, stop=1.0)
    with pytest.raises(ValueError, match="alpha"):
        trace_branch(TUBE, 0.0, 0.7, stop=1.0)
    with pytest.raises(ValueError, match="lambda_i"):
        trace_branch(TUBE.replace(lambda_i=-1.0), 0.445, 0.7, stop=1.0)
