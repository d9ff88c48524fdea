"""Dispersion curves by certified continuation (jaxdea.solve.curves): the same roots as jd.frequencies at
every α̂, continuation where it is safe, the scan where a check fails."""

import exact_cylinder
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxdea as jd
from jaxdea.numerics.scalar import iterate_lanes, lanes_from_slots
from jaxdea.physics.dispersion import value_and_slope_on_wall
from jaxdea.physics.transfer import AUTO_SCHEME, TRACED_LAYERS, Layers, discretize, laminate
from jaxdea.solve.curves import PRIOR_AGE, _aged, _extrapolate, _refresh, _track


def per_alpha(tube, alphas, fluid, n_roots, n_layers):
    """The reference: jd.frequencies (the guaranteed scan) at each α̂ separately."""
    return np.array([np.asarray(jd.frequencies(tube, float(a), fluid, n_roots=n_roots,
                                               n_layers=n_layers)) for a in alphas])


def rule(tube, alphas, n_roots=3):
    """The rule's wall over the grid, the wall of ``jd.frequencies`` at these α̂: a continued curve
    equals the scan on one discretisation (a concrete default curve starts lower and checks its
    roots, tests/test_accuracy_default.py)."""
    return laminate(None, None, tube, np.asarray(alphas), n_roots)


def assert_same_roots(curve, reference, rtol=1e-12):
    omega = np.asarray(curve.omega)
    np.testing.assert_array_equal(np.isnan(omega), np.isnan(reference))
    np.testing.assert_allclose(omega, reference, rtol=rtol)


def test_unstretched_curve_is_continued_and_equals_the_scan():
    """200 α̂ × 3 roots of the unstretched empty tube: the scan runs on a few of the 200 α̂ (the
    first, and steps near α̂ → 0 where the lowest root moves by more than a quarter of its distance
    to Ω = 0); every root equals jd.frequencies at its α̂ to 1e-12 (on every 5th α̂)."""
    alphas = np.linspace(0.025, 5.0, 200)
    wall = rule(jd.Tube(), alphas)
    curve = jd.dispersion_curve(jd.Tube(), alphas, n_layers=wall)
    assert curve.omega.shape == (200, 3) and curve.status.shape == (200, 3)
    assert np.all(np.asarray(curve.status) == jd.Status.CONVERGED)
    scanned = np.asarray(curve.scanned)
    assert scanned[0] and scanned.sum() <= 6
    np.testing.assert_array_equal(curve.alpha, alphas)
    reference = per_alpha(jd.Tube(), alphas[::5], None, 3, wall)
    assert_same_roots(curve._replace(omega=curve.omega[::5]), reference)


def test_fluid_veering_and_descending_grid():
    """Tube filled with a very light fluid through the veering of gap 3.5e-4 (test_trace): the
    continued roots equal the scan at every α̂, on an ascending and a descending grid."""
    tube = jd.Tube(lambda_i=1.1, lambda_z=1.2, eta=0.85)
    fluid = jd.Fluid(density_ratio=1e-6, speed_ratio=0.27)
    alphas = np.linspace(0.6, 0.8, 41)
    reference = per_alpha(tube, alphas, fluid, 3, None)
    for order in (slice(None), slice(None, None, -1)):
        curve = jd.dispersion_curve(tube, alphas[order], fluid, n_roots=3)
        assert_same_roots(curve, reference[order], rtol=1e-11)
        assert 1 <= np.asarray(curve.scanned).sum() < 41  # continued where it could be


def test_fig3_line_along_n_and_a_coarse_grid():
    """Steps of whole axial modes (Fig. 3, n = 1..20) and a grid of 6 α̂ over [0.1, 8]: the checks
    send the steps that continuation cannot follow to the scan, and every root equals the scan."""
    tube = jd.Tube(lambda_i=1.1, lambda_z=1.2, voltage=0.2)
    fluid = jd.Fluid()
    for alphas in (np.asarray(jd.axial_wavenumber(tube, np.arange(1, 21))), np.linspace(0.1, 8, 6)):
        wall = rule(tube, alphas)
        curve = jd.dispersion_curve(tube, alphas, fluid, n_layers=wall)
        assert_same_roots(curve, per_alpha(tube, alphas, fluid, 3, wall), rtol=1e-11)


def test_tangent_predictor_after_a_scan():
    """The history after a scan is one point and the slope of each branch there: the predictor is
    the tangent line (a constant before), the line through the Lagrange rows once two are known,
    and the constant where a slope is missing."""
    hist_alpha = jnp.arange(6.0)
    hist_omega = jnp.arange(12.0).reshape(6, 2)
    slope = jnp.array([2.0, jnp.nan])
    line = _extrapolate(hist_alpha, hist_omega, 1, 5.5, slope)
    np.testing.assert_allclose(line, [10.0 + 2.0 * 0.5, 11.0])  # tangent; constant without a slope
    np.testing.assert_allclose(_extrapolate(hist_alpha, hist_omega, 2, 5.5, slope),
                               _extrapolate(hist_alpha, hist_omega, 2, 5.5))  # secant: 11, 12


def test_tangent_predictor_continues_the_first_axial_modes():
    """Fig. 3 line (λ_i = 0.9, V̂ = 0): with the branch slopes dΩ/dα̂ = −f_α̂/f_Ω at the scanned
    roots, the steps n = 1 → 2 → … are continued (the constant predictor sent n = 2..5 to the scan);
    the roots still equal jd.frequencies."""
    tube = jd.Tube(lambda_z=1.2, lambda_i=0.9)
    alphas = np.asarray(jd.axial_wavenumber(tube, np.arange(1, 21)))
    curve = jd.dispersion_curve(tube, alphas, n_roots=3, n_layers=2, scheme="magnus6")
    scanned = np.asarray(curve.scanned)
    assert scanned[0] and scanned.sum() <= 2, scanned
    reference = np.array([np.asarray(jd.frequencies(tube, a, n_roots=3, n_layers=2, scheme="magnus6"))
                          for a in alphas])
    assert_same_roots(curve, reference)


def _case(alpha=0.445, n_layers=30):
    wall = discretize(jd.Tube(), n_layers)
    fun = lambda om: value_and_slope_on_wall(wall, om, jnp.asarray(alpha))  # noqa: E731  (f, f')
    return fun, np.asarray(jd.frequencies(jd.Tube(), alpha, n_roots=4, n_layers=n_layers))


def test_checks_accept_the_branches_and_refuse_shifted_ones():
    """_track from predictions 1e-3 off the roots: accepted, the roots to 1e-13. From the roots
    of the next branches (a lane per branch jumped, or a root came in below): every lane converges
    and the order and distance checks pass, but the signs of f(0), f'(Ω_k) do not alternate."""
    fun, roots = _case()
    track = jax.jit(lambda pred: _track(fun, pred)[:2])
    omega, ok = track(jnp.asarray(roots[:3] * (1 + 1e-3)))
    assert bool(ok)
    np.testing.assert_allclose(omega, roots[:3], rtol=1e-13)
    for lanes in ([1, 2, 3], [0, 2, 3]):  # lanes on the next branches; a root between lanes missing
        omega, ok = track(jnp.asarray(roots[lanes]))
        np.testing.assert_allclose(omega, roots[lanes], rtol=1e-13)
        assert not bool(ok)
    _, ok = track(jnp.asarray(roots[:3] + np.array([0.0, 0.4, 0.0]) * (roots[2] - roots[1])))
    assert not bool(ok)  # a lane that must move by more than a quarter of the gap


def test_a_prior_curvature_finishes_a_lane_at_its_first_evaluation():
    """f(x) = x² − 2 from x0 = √2(1 + 1e-9): with the true K = |f''/(2f')| = 1/(2√2) as a prior,
    the Newton step from x0 leaves an error K·δ² ≈ 7e-19, so the lane finishes after one
    evaluation, at √2 to rounding. Without a prior, or with a start 1e-3 off (K·δ² ≈ 7e-7 > tol),
    it needs more; the lanes report the curvature they measured (what continuation carries on)."""
    fun = lambda x: x * x - 2.0  # noqa: E731
    root, k_true = np.sqrt(2.0), 1.0 / (2.0 * np.sqrt(2.0))

    @jax.jit
    def run(x0, prior, iterations):
        one = lambda v: jnp.reshape(jnp.asarray(v, jnp.float64), (1,))  # noqa: E731
        nan = one(jnp.nan)
        lanes = lanes_from_slots(one(x0), one(x0), nan, nan, nan, nan, jnp.array([3]),
                                 jnp.array([0]), curvature=one(prior))
        return iterate_lanes(fun, lanes, max_iter=iterations)

    done = run(root * (1 + 1e-9), k_true, 1)
    assert int(done.status[0]) == jd.Status.CONVERGED
    np.testing.assert_allclose(done.x[0], root, rtol=2e-16)
    assert int(run(root * (1 + 1e-9), np.nan, 1).status[0]) == jd.Status.MAX_ITER
    assert int(run(root * (1 + 1e-3), k_true, 1).status[0]) == jd.Status.MAX_ITER
    measured = run(root * (1 + 1e-3), np.nan, 20)
    assert int(measured.status[0]) == jd.Status.CONVERGED
    np.testing.assert_allclose(measured.curvature[0], k_true, rtol=1e-2)


def test_paper_coupling_scans_every_alpha():
    """The paper's coupling is not conservative: a pair of roots straddles its pole Ω = ĉ_f α̂
    (j'_{0,1} = 0) at every α̂ (invisible to the sign checks of continuation), so every α̂ is
    scanned and the pair is found."""
    tube = jd.Tube(lambda_i=1.1, lambda_z=1.2, eta=0.85)
    fluid = jd.Fluid(coupling="paper", bessel_order=0)
    alphas = np.linspace(0.05, 0.25, 9)
    curve = jd.dispersion_curve(tube, alphas, fluid)
    assert np.all(np.asarray(curve.scanned))
    reference = per_alpha(tube, alphas, fluid, 3, None)
    assert_same_roots(curve, reference, rtol=1e-11)
    pole = float(fluid.speed_ratio) * alphas
    assert np.all(reference[:, 0] < pole) and np.all(pole < reference[:, 1])  # the pair is there
    assert np.all(reference[:, 1] < 1.05 * pole)
    with pytest.raises(ValueError, match="bessel_order"):
        jd.dispersion_curve(tube, alphas, jd.Fluid(coupling="paper"))


def test_implicit_derivatives_match_frequency():
    """d/dV̂ and d/dα̂-free leaves: the gradient of one continued root equals that of jd.frequency
    (implicit derivatives, exact for the laminate) at the same point, and central differences."""
    alphas = np.linspace(0.3, 1.5, 13)
    wall = rule(jd.Tube(lambda_i=1.1, lambda_z=1.2, voltage=0.1), alphas)  # jd.frequency's

    def root(v, j, k):
        tube = jd.Tube(lambda_i=1.1, lambda_z=1.2, voltage=v)
        return jd.dispersion_curve(tube, alphas, n_layers=wall).omega[j, k]

    def single(v, j, w):
        return jd.frequency(jd.Tube(lambda_i=1.1, lambda_z=1.2, voltage=v), alphas[j], w)

    v = 0.1
    for j, k in ((4, 0), (12, 2)):
        g = float(jax.grad(root)(v, j, k))
        ref = float(jax.grad(single)(v, j, float(root(v, j, k))))
        np.testing.assert_allclose(g, ref, rtol=1e-12)
        # fourth-order central difference: truncation 2e-11 (root 0 is strongly curved in V̂),
        # rounding ≈ 1e-14/h from the roots' last digits
        h = 1e-4
        fd = (8 * (float(root(v + h, j, k)) - float(root(v - h, j, k)))
              - (float(root(v + 2 * h, j, k)) - float(root(v - 2 * h, j, k)))) / (12 * h)
        np.testing.assert_allclose(g, fd, rtol=1e-9, atol=2e-10)


def test_traced_invalid_inputs_give_nan_and_status():
    """Under jit: an inadmissible tube gives NaN and INVALID everywhere; a NaN α̂ only its row,
    and the rows after it equal the untraced curve on the traced default's wall (the history
    restarts with a scan)."""
    alphas = jnp.linspace(0.3, 1.5, 7)
    good = jd.dispersion_curve(jd.Tube(eta=0.5), alphas,
                               n_layers=Layers(TRACED_LAYERS, AUTO_SCHEME, True))
    run = jax.jit(lambda eta, a: jd.dispersion_curve(jd.Tube(eta=eta), a))
    bad = run(1.5, alphas)
    assert np.all(np.isnan(bad.omega)) and np.all(np.asarray(bad.status) == jd.Status.INVALID)
    holed = run(0.5, alphas.at[3].set(jnp.nan))
    assert np.all(np.isnan(holed.omega[3])) and np.all(np.asarray(holed.status[3]) == jd.Status.INVALID)
    keep = np.r_[0:3, 4:7]
    np.testing.assert_allclose(holed.omega[keep], good.omega[keep], rtol=1e-13)
    assert bool(holed.scanned[4])


@pytest.mark.parametrize("kwargs, name", [
    (dict(alpha=np.ones((2, 2))), "alpha"),
    (dict(alpha=np.array([])), "alpha"),
    (dict(alpha=np.array([0.5, -1.0])), "alpha"),
    (dict(alpha=np.array([0.5, np.inf])), "alpha"),
    (dict(n_roots=0), "n_roots"),
    (dict(n_layers=0), "n_layers"),
    (dict(tube=jd.Tube(eta=1.2)), "eta"),
])
def test_bad_inputs_name_the_parameter(kwargs, name):
    args = dict(tube=jd.Tube(), alpha=np.array([0.5, 1.0]))
    args.update(kwargs)
    with pytest.raises(ValueError, match=name):
        jd.dispersion_curve(**args)


@pytest.mark.slow
@pytest.mark.parametrize("seed", range(8))
def test_random_tubes_fluids_and_grids_equal_the_scan(seed):
    """Random tube (neo-Hookean or Gent, λ_i, λ_z ∈ [0.8, 2], η ∈ [0.3, 0.95], V̂ ≤ 0.15), empty or
    filled (ρ̂_f ∈ [0.05, 2], ĉ_f ∈ [0.1, 3]), grid of 20–120 α̂ over up to [0.01, 9], ascending or
    descending, K ≤ 5, N ∈ {8, 12, 20}: the curve equals jd.frequencies at every α̂ (to 1e-12)."""
    rng = np.random.default_rng(1000 + seed)
    gent = rng.random() < 0.4
    tube = jd.Tube(lambda_i=rng.uniform(0.8, 2.0), lambda_z=rng.uniform(0.8, 2.0),
                   eta=rng.uniform(0.3, 0.95), voltage=rng.uniform(0, 0.15),
                   material="gent" if gent else "neo_hookean",
                   gent=rng.uniform(20, 100) if gent else 97.2)
    fluid = (jd.Fluid(density_ratio=rng.uniform(0.05, 2), speed_ratio=rng.uniform(0.1, 3))
             if rng.random() < 0.6 else None)
    lo = rng.uniform(0.01, 1.0)
    alphas = np.linspace(lo, lo + rng.uniform(0.5, 8.0), int(rng.integers(20, 121)))
    if rng.random() < 0.3:
        alphas = alphas[::-1].copy()
    k, n = int(rng.integers(1, 6)), int(rng.choice([8, 12, 20]))
    try:
        jd.pressure_difference(tube)
    except ValueError:
        pytest.skip("past Gent locking")
    curve = jd.dispersion_curve(tube, alphas, fluid, n_roots=k, n_layers=n)
    assert_same_roots(curve, per_alpha(tube, alphas, fluid, k, n))


def test_root_entering_and_leaving_through_zero():
    """λ_i = 1.5 at V̂ = 0.095: V̂_cr(α̂) rises from 0.084 (α̂ → 0) to 0.107 (α̂ = 3), so the lowest
    mode is unstable (Ω² < 0, no real root) below α̂ ≈ 0.8 and its root comes in through Ω = 0 above.
    Ascending, the new root appears below the followed ones (f(0) changes sign: the check fails,
    the scan finds it); descending, it leaves through 0. Both equal the scan at every α̂."""
    tube = jd.Tube(lambda_i=1.5, lambda_z=1.2, eta=0.85, voltage=0.095)
    alphas = np.linspace(0.3, 2.0, 35)
    wall = rule(tube, alphas)
    reference = per_alpha(tube, alphas, None, 3, wall)
    assert np.min(reference[:, 0]) < 0.1  # a root just come in through Ω = 0 (0.071 at α̂ = 0.93)
    assert reference[0, 1] > 10 > 3 > reference[-1, 1]  # one real root more at α̂ = 2 than at 0.3
    for order in (slice(None), slice(None, None, -1)):
        curve = jd.dispersion_curve(tube, alphas[order], n_roots=3, n_layers=wall)
        assert_same_roots(curve, reference[order], rtol=1e-11)
        assert np.asarray(curve.scanned).sum() < 35


def test_benchmark_curve_meets_the_exact_cylinder_and_the_scan():
    """The benchmark's GEWtool-shaped curve (the unstretched tube η = 0.85, 200 α̂ in 0.01–5, the 4
    lowest roots, default discretisation, no accuracy arguments): every root CONVERGED, the scan
    at the first α̂ only, the roots those of jd.frequencies (the scan) on the same wall (the
    checked start, 6 sublayers) at every 4th α̂ to 1e-12, and those of the exact incompressible
    cylinder at every 10th α̂ to the promised 1e-8 (measured 3.3e-9)."""
    tube = jd.Tube(voltage=0.0, lambda_i=1.0, lambda_z=1.0, eta=0.85)
    alphas = np.linspace(0.01, 5.0, 200)
    curve = jd.dispersion_curve(tube, alphas, n_roots=4)
    assert np.all(np.asarray(curve.status) == jd.Status.CONVERGED)
    scanned = np.asarray(curve.scanned)
    assert scanned[0] and scanned.sum() == 1
    start = laminate(None, None, tube, alphas, 4, checked=True)
    assert start == Layers(6, AUTO_SCHEME, True)
    assert_same_roots(curve._replace(omega=curve.omega[::4]),
                      per_alpha(tube, alphas[::4], None, 4, start))
    omega = np.asarray(curve.omega)
    for alpha, row in zip(alphas[::10], omega[::10], strict=True):
        exact = exact_cylinder.roots(alpha, 1.0, 1 / 0.85, 4, 1.3 * row[-1] + 0.5, 2000)
        np.testing.assert_allclose(row, exact, rtol=1e-8)


def test_predictor_order_adapts_to_each_branch():
    """_extrapolate one step ahead of 12 rows (step 0.25): sin α̂ takes the highest order (5.8e-8
    off, the fixed quintic 1.9e-4); a cubic is reproduced to rounding; |α̂ − 2.1|, linear on the
    newest rows, is extrapolated exactly (order 12 through the kink: 27 off); ``n_hist`` caps
    the order (6 rows: the quintic's 1.9e-4)."""
    alpha = jnp.arange(12) * 0.25
    target = 3.0
    branches = jnp.stack([jnp.sin(alpha), 1 + alpha - 0.5 * alpha**2 + 0.1 * alpha**3,
                          jnp.abs(alpha - 2.1)], axis=1)
    exact = np.array([np.sin(target), 1 + target - 0.5 * target**2 + 0.1 * target**3, 0.9])
    error = np.abs(np.asarray(_extrapolate(alpha, branches, 12, target)) - exact)
    assert error[0] < 1e-7 and error[1] < 1e-14 and error[2] < 1e-14
    capped = np.abs(np.asarray(_extrapolate(alpha, branches, 6, target)) - exact)
    assert 1e-4 < capped[0] < 3e-4 and capped[1] < 1e-14


def test_expired_curvature_refreshes_every_lane():
    """One lane's K expired (PRIOR_AGE steps old): the step runs every lane without its prior;
    afterwards a lane that measured K has it at age 0, an unexpired one that did not keeps its K
    one step older, and an expired one that did not has none (age PRIOR_AGE, which triggers no
    further refresh). Without an expired K the priors age by one."""
    k = jnp.array([0.3, 0.2, jnp.nan])
    age = jnp.array([PRIOR_AGE, 3, PRIOR_AGE])
    assert bool(_refresh(k, age))
    assert not bool(_refresh(k, jnp.array([PRIOR_AGE - 1, 3, PRIOR_AGE])))  # a missing K: none
    new_k, new_age = _aged(jnp.array([0.31, jnp.nan, 0.5]), k, age, True)
    np.testing.assert_array_equal(new_k, [0.31, 0.2, 0.5])
    np.testing.assert_array_equal(new_age, [0, 4, 0])
    new_k, new_age = _aged(jnp.array([jnp.nan, jnp.nan, 0.5]), k, age, True)
    np.testing.assert_array_equal(new_k, [np.nan, 0.2, 0.5])
    np.testing.assert_array_equal(new_age, [PRIOR_AGE, 4, 0])
    assert not bool(_refresh(new_k, new_age))
    kept_k, kept_age = _aged(jnp.full(3, jnp.nan), k, jnp.array([2, 3, PRIOR_AGE]), False)
    np.testing.assert_array_equal(kept_k, k)
    np.testing.assert_array_equal(kept_age, [3, 4, PRIOR_AGE + 1])


# ----------------------------------------------------------------------------- paths of any parameter


def test_paths_along_voltage_and_speed_ratio_equal_the_scan_at_every_point():
    """Curves along V̂ (to V̂_cr, abscissa t with V̂ = V̂_cr(1 − (1 − t)²)), along ĉ_f (log abscissa)
    and along α̂ through fractional n, packed into one padded path of the figures: each point equals
    jd.frequencies there (1e-10), most points are continued, the padding stays out."""
    from jaxdea.apps import figures

    tube = figures.PAPER_TUBE.replace(lambda_i=0.9)
    fluid = jd.Fluid(density_ratio=0.13, speed_ratio=0.27)
    n_layers = 12
    v_cr = float(jd.critical_voltage(tube, jd.axial_wavenumber(tube, 2), fluid, n_layers=n_layers))
    voltages, t = figures.voltage_path(v_cr, v_cr, 24)
    speeds = np.geomspace(0.05, 1.5, 20)
    modes = np.linspace(1.0, 4.0, 13)
    curves = [(dict(voltage=voltages, lambda_i=0.9, n=2.0, speed_ratio=0.27), t),
              (dict(voltage=0.1, lambda_i=0.9, n=1.0, speed_ratio=speeds), np.log(speeds)),
              (dict(voltage=0.0, lambda_i=0.9, n=modes, speed_ratio=0.27), modes)]
    solved = figures.solve_curves(n_layers, fluid, curves)
    for (values, _), sol in zip(curves, solved, strict=True):
        size = len(sol.omega)
        points = {k: np.broadcast_to(v, size) for k, v in values.items()}
        reference = []
        for j in range(size):
            t_j = tube.replace(voltage=float(points["voltage"][j]))
            a_j = jd.axial_wavenumber(t_j, float(points["n"][j]))
            f_j = fluid.replace(speed_ratio=float(points["speed_ratio"][j]))
            reference.append(float(jd.frequencies(t_j, a_j, f_j, n_roots=1, n_layers=n_layers)[0]))
        np.testing.assert_allclose(sol.omega, reference, rtol=1e-10)
        np.testing.assert_allclose(sol.alpha, [jd.axial_wavenumber(tube, n) for n in points["n"]],
                                   rtol=1e-14)
        assert np.all(sol.status == jd.Status.CONVERGED) and not sol.jumps.any()
    assert np.all(np.diff(solved[0].omega[-6:]) < 0)  # falling towards Ω = 0 at V̂_cr


def test_empty_tube_paths_run_on_the_acoustic_program_and_equal_the_empty_tube():
    """The figures solve the empty tube as a massless acoustic fluid (figures.MASSLESS_FLUID): no
    program of its own is compiled, and every root equals jd.frequencies of the empty tube
    (1e-11: the fluid's column scale D_0 > 0 is taken out by the orthonormalisation)."""
    from jaxdea.apps import figures
    from jaxdea.solve.curves import solve_path

    tube = figures.PAPER_TUBE.replace(lambda_i=0.9)
    n_layers = 12
    voltages = np.linspace(0.0, 0.025, 9)
    modes = np.linspace(1.0, 3.0, 9)
    curves = [(dict(voltage=voltages, lambda_i=0.9, n=2.0), voltages),
              (dict(voltage=0.01, lambda_i=0.9, n=modes), modes)]
    figures.solve_curves(n_layers, jd.Fluid(), curves[:1])  # the acoustic coupling's program
    programs = solve_path._cache_size()
    solved = figures.solve_curves(n_layers, None, curves)
    assert solve_path._cache_size() == programs
    for (values, _), sol in zip(curves, solved, strict=True):
        points = {k: np.broadcast_to(v, len(sol.omega)) for k, v in values.items()}
        reference = [float(jd.frequencies(tube.replace(voltage=float(v)), jd.axial_wavenumber(tube, float(n)),
                                          n_roots=1, n_layers=n_layers)[0])
                     for v, n in zip(points["voltage"], points["n"], strict=True)]
        np.testing.assert_allclose(sol.omega, reference, rtol=1e-11)
        assert np.all(sol.status == jd.Status.CONVERGED)


def test_path_marks_a_root_that_changes_branch():
    """Past V̂_cr the lowest root of mode n = 1 is imaginary: along V̂ beyond it the lowest real root
    is another branch's, found by the scan and marked as a jump (the step before it continues)."""
    from jaxdea.apps import figures

    tube = figures.PAPER_TUBE.replace(lambda_i=1.1)
    n_layers = 12
    v_cr = float(jd.critical_voltage(tube, jd.axial_wavenumber(tube, 1), n_layers=n_layers))
    voltages = np.linspace(0.0, 1.3 * v_cr, 28)  # no point at V̂_cr itself (a root at Ω = 0)
    sol, = figures.solve_curves(n_layers, None, [(dict(voltage=voltages, lambda_i=1.1, n=1.0), voltages)])
    past = voltages >= v_cr
    first_past = int(np.argmax(past))
    assert sol.jumps[first_past] and not sol.jumps[:first_past].any()
    alpha = float(jd.axial_wavenumber(tube, 1))
    direct = [float(jd.frequencies(tube.replace(voltage=float(v)), alpha, n_roots=1, n_layers=n_layers)[0])
              for v in voltages[first_past - 1:first_past + 2]]
    np.testing.assert_allclose(sol.omega[first_past - 1:first_past + 2], direct, rtol=1e-10)


def test_paper_coupling_path_takes_the_order_of_each_mode():
    """The paper's coupling along whole n takes ν = n at each point (every point scanned): the roots
    of jd.frequencies with Fluid(coupling="paper") (ν = n by default) there."""
    from jaxdea.apps import figures

    fluid = jd.Fluid(density_ratio=0.13, speed_ratio=0.27, coupling="paper")
    modes = np.arange(1.0, 5.0)
    sol, = figures.solve_curves(12, fluid, [(dict(voltage=0.05, lambda_i=0.9, n=modes), modes)])
    tube = figures.PAPER_TUBE.replace(lambda_i=0.9, voltage=0.05)
    direct = [float(jd.frequencies(tube, jd.axial_wavenumber(tube, int(n)), fluid, n_roots=1,
                                   n_layers=12)[0]) for n in modes]
    np.testing.assert_allclose(sol.omega, direct, rtol=1e-10)


def test_critical_voltages_along_a_path_equal_the_search_at_every_point():
    """V̂_cr by continuation along λ_i (m = 0 and 2) and along fractional n (m = 1): each point is
    jd.critical_voltage there (1e-11); only the start of each curve is searched from V̂ = 0."""
    from jaxdea.apps import figures

    n_layers = 12
    stretches = np.linspace(0.9, 1.3, 9)
    modes = np.linspace(1.0, 3.0, 9)
    curves = [(dict(lambda_i=stretches, n=1.0, m=0.0), stretches),
              (dict(lambda_i=stretches, n=1.0, m=2.0), stretches),
              (dict(lambda_i=1.0, n=modes, m=1.0), modes)]
    solved = figures.critical_curves(n_layers, curves)
    for (values, _), v_cr in zip(curves, solved, strict=True):
        points = {k: np.broadcast_to(v, len(v_cr)) for k, v in values.items()}
        direct = []
        for li, n, m in zip(points["lambda_i"], points["n"], points["m"], strict=True):
            tube = figures.PAPER_TUBE.replace(lambda_i=float(li))
            direct.append(float(jd.critical_voltage(tube, jd.axial_wavenumber(tube, float(n)), m=int(m),
                                                    n_layers=n_layers)))
        np.testing.assert_allclose(v_cr, direct, rtol=1e-11)
    grid = figures.critical_voltage_grid(figures.PAPER_TUBE, n_layers, lambda_i=stretches[:3],
                                         m=np.array([0.0, 2.0]))
    np.testing.assert_allclose(grid, np.stack([solved[0][:3], solved[1][:3]], axis=1), rtol=1e-11)


def test_static_propagation_equals_the_checked_one():
    """dispersion_curve compiles one propagation, chosen from the concrete voltage (V̂ = 0: the
    decoupled 4×4 one, lanes and scan; else the 6×6 one): the roots and scanned steps of the program
    that checks the wall at every point and compiles both."""
    from jaxdea.params import canonical
    from jaxdea.physics.transfer import laminate
    from jaxdea.solve.curves import curve_unchecked

    alphas = np.linspace(0.05, 4.0, 24)
    layers = laminate(8, "magnus6")
    checked = jax.jit(lambda t, a: curve_unchecked(t, a, None, 3, layers, 0))
    for tube in (jd.Tube(voltage=0.0, lambda_i=1.0, lambda_z=1.0, eta=0.85), jd.Tube(voltage=0.15)):
        curve = jd.dispersion_curve(tube, alphas, n_roots=3, n_layers=8, scheme="magnus6")
        t, a, _ = canonical(tube, alphas, 0.0)
        reference = checked(t, a)
        np.testing.assert_array_equal(np.asarray(curve.scanned), np.asarray(reference.scanned))
        assert_same_roots(curve, np.asarray(reference.omega))
