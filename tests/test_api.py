"""Public API: implicit derivatives (g), batching without recompilation (h), bad inputs (i),
status codes and root isolation."""

import functools

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from conftest import fd_derivative

import jaxdea as jd
from jaxdea.numerics.scalar import Status
from jaxdea.physics.families import Family
from jaxdea.solve import roots as roots_module

PAPER = dict(lambda_z=1.2, eta=0.85)
TUBE = jd.Tube(voltage=0.1, lambda_i=0.9, **PAPER)
ALPHA = 0.445


def _omega(tube=TUBE, alpha=ALPHA, fluid=None, guess=0.72):
    return jd.frequency(tube, alpha, guess, fluid)


# (g) implicit derivatives against central finite differences (relative 1e-6): Newton converges
# to ~1e-15, so h = 6e-6 gives truncation O(h²) ~ 1e-10 and rounding O(1e-15/h) ~ 1e-10.
# All leaves are differentiated in one jacfwd call (one compilation).
FLUID = jd.Fluid()
PARAMS = dict(voltage=0.1, lambda_i=0.9, lambda_z=1.2, gent=97.2, h_over_Ri=0.17,
              density_ratio=0.13, speed_ratio=0.27, alpha=ALPHA)


def _omega_of(params, guess=0.117):
    """Ω of the Korteweg branch as a function of every design parameter (η via h/R_i)."""
    tube = jd.Tube(voltage=params["voltage"], lambda_i=params["lambda_i"],
                   lambda_z=params["lambda_z"], gent=params["gent"])
    tube = jd.with_thickness_ratio(tube, params["h_over_Ri"])
    fluid = FLUID.replace(density_ratio=params["density_ratio"],
                          speed_ratio=params["speed_ratio"])
    return jd.frequency(tube, params["alpha"], guess, fluid)


def test_every_derivative_of_frequency_matches_finite_differences():
    jac = jax.jacfwd(_omega_of)({k: jnp.asarray(v) for k, v in PARAMS.items()})
    for name, x0 in PARAMS.items():
        fd = fd_derivative(lambda x, name=name: _omega_of({**PARAMS, name: x}), x0)
        np.testing.assert_allclose(jac[name], fd, rtol=1e-6, err_msg=name)


@pytest.mark.slow
def test_reverse_mode_equals_forward_mode_and_group_velocity():
    """jax.grad (reverse, through the transpose of the implicit-derivative rule) equals jacfwd; dΩ/dα̂ equals
    group_velocity; η enters directly too (empty tube)."""
    tube = jd.Tube(voltage=0.1, lambda_i=0.9, **PAPER)
    fun = lambda eta, alpha: jd.frequency(tube.replace(eta=eta), alpha, 0.72)  # noqa: E731
    rev = jax.grad(fun, argnums=(0, 1))(0.85, ALPHA)
    fwd = jax.jacfwd(fun, argnums=(0, 1))(0.85, ALPHA)
    np.testing.assert_allclose(rev, fwd, rtol=1e-12)
    np.testing.assert_allclose(fwd[0], fd_derivative(lambda e: fun(e, ALPHA), 0.85), rtol=1e-6)
    omega = fun(0.85, ALPHA)
    np.testing.assert_allclose(jd.group_velocity(tube, ALPHA, omega), fwd[1], rtol=1e-10)


@pytest.mark.slow
def test_frequencies_derivatives_of_every_root():
    """jacfwd of all roots returned by frequencies (implicit per root) equals finite differences.
    The third root (Ω ≈ 17.9) barely moves (dΩ/dV̂ ≈ −6e-5): there the FD rounding error
    eps·Ω/h ≈ 1e-9 sets an absolute floor, hence atol = 1e-8."""
    fun = lambda v: jd.frequencies(TUBE.replace(voltage=v), ALPHA)  # noqa: E731
    jac = jax.jacfwd(fun)(0.1)
    h = 6e-6
    np.testing.assert_allclose(jac, (fun(0.1 + h) - fun(0.1 - h)) / (2 * h), rtol=1e-6,
                               atol=1e-8)


@pytest.mark.slow
def test_critical_voltage_is_a_zero_frequency_and_differentiable():
    """f(Ω = 0; V̂_cr) = 0: just below V̂_cr the lowest root vanishes like sqrt(V̂_cr − V̂), and
    dV̂_cr/dλ_i (implicit) matches finite differences."""
    tube = jd.Tube(lambda_i=1.1, **PAPER)
    alpha = jd.axial_wavenumber(tube, 1)
    v_cr, status = jd.solve_critical_voltage(tube, alpha)
    assert int(status) == 0 and 0.1 < float(v_cr) < 0.4
    near = jd.frequencies(tube.replace(voltage=float(v_cr) * (1 - 1e-4)), alpha)
    far = jd.frequencies(tube.replace(voltage=float(v_cr) * (1 - 1e-2)), alpha)
    np.testing.assert_allclose(float(near[0] / far[0]), 0.1, rtol=0.05)  # Ω² ∝ (V̂_cr − V̂)
    fun = lambda li: jd.critical_voltage(tube.replace(lambda_i=li), alpha)  # noqa: E731
    np.testing.assert_allclose(jax.jacfwd(fun)(1.1), fd_derivative(fun, 1.1), rtol=1e-6)


@pytest.mark.slow
def test_critical_voltage_same_with_fluid():
    """The fluid's terms vanish like Ω²: the same V̂_cr for the acoustic model (theory.md §4(c))."""
    tube = jd.Tube(lambda_i=1.1, **PAPER)
    alpha = jd.axial_wavenumber(tube, 1)
    np.testing.assert_allclose(jd.critical_voltage(tube, alpha, jd.Fluid()),
                               jd.critical_voltage(tube, alpha), rtol=1e-12)


# (h) batching
def test_vmap_equals_loop_and_no_recompilation():
    voltages = jnp.array([0.0, 0.05, 0.1, 0.15])
    batched = jax.vmap(lambda v: jd.solve_frequencies(TUBE.replace(voltage=v), ALPHA))(voltages)
    for i, v in enumerate(voltages):
        one = jd.solve_frequencies(TUBE.replace(voltage=float(v)), ALPHA)
        np.testing.assert_allclose(batched.omega[i], one.omega, rtol=1e-13)
        np.testing.assert_array_equal(batched.status[i], one.status)
    before = roots_module._solve_frequencies._cache_size()
    jd.frequencies(TUBE.replace(voltage=0.123, lambda_i=0.95, gent=50.0), 0.6).block_until_ready()
    assert roots_module._solve_frequencies._cache_size() == before


@pytest.mark.parametrize("case", ["empty", "acoustic", "paper", "layered"])
def test_frequencies_without_voltage_take_the_decoupled_propagation(case):
    """frequencies and frequency at a concrete V̂ = 0 solve on the 4×4 mechanical propagation
    (roots.decoupled_choice): the roots of the program that propagates the whole 6×6 state, to
    rounding, with the paper's and the acoustic coupling and on a layered wall; the 4×4 program on
    a wall with voltage gives NaN, not a wrong number."""
    from jaxdea.params import canonical
    from jaxdea.physics.problem import describe
    from jaxdea.physics.transfer import Layers

    tube, fluid = TUBE.replace(voltage=0.0), None
    if case == "acoustic":
        fluid = FLUID
    elif case == "paper":
        fluid = jd.Fluid(coupling="paper", bessel_order=1)
    elif case == "layered":
        tube = tube.replace(layers=(jd.Layer(0.2, jd.NeoHookean(), shear_ratio=3.0),
                                    jd.Layer(0.6, jd.Gent(97.2), active=True),
                                    jd.Layer(0.2, jd.NeoHookean(), shear_ratio=3.0)))
    got = np.asarray(jd.frequencies(tube, ALPHA, fluid, n_roots=3, omega_max=20.0))
    order = describe(tube, ALPHA, fluid, None, None).order
    t, a, f, om = roots_module.canonical(tube, ALPHA, fluid, 20.0)
    layers = Layers(16, "magnus6", True)
    full, four = (roots_module._solve_frequencies(t, a, f, om, 3, layers, order, decoupled=d)
                  for d in (False, True))
    assert np.all(np.asarray(full.status) == Status.CONVERGED)
    np.testing.assert_allclose(np.asarray(four.omega), np.asarray(full.omega), rtol=1e-13)
    np.testing.assert_allclose(got, np.asarray(full.omega), rtol=1e-8)
    one = float(jd.frequency(tube, ALPHA, got[1] * 1.01, fluid))
    np.testing.assert_allclose(one, got[1], rtol=1e-12)
    t, a, f, om = canonical(tube.replace(voltage=0.1), ALPHA, fluid, 20.0)
    wrong = roots_module._solve_frequencies(t, a, f, om, 3, layers, order, decoupled=True)
    assert np.all(np.isnan(np.asarray(wrong.omega)))


def test_batched_failures_do_not_stop_the_batch():
    """A traced batch with a locked and a non-finite point: NaN + status there, the rest fine."""
    tubes = TUBE.replace(voltage=jnp.array([0.1, 0.1, jnp.nan]),  # λ_i = 12: I_1 − 3 ≈ 143 > G
                         lambda_i=jnp.array([0.9, 12.0, 0.9]))
    axes = jd.Tube(voltage=0, lambda_i=0, lambda_z=None, eta=None, gent=None, length_ratio=None)
    out = jax.vmap(lambda t: jd.solve_frequencies(t, ALPHA), in_axes=(axes,))(tubes)
    assert np.all(np.asarray(out.status[0]) == Status.CONVERGED)
    np.testing.assert_allclose(out.omega[0], jd.frequencies(TUBE, ALPHA), rtol=1e-13)
    for i in (1, 2):
        assert np.all(np.isnan(np.asarray(out.omega[i])))
        assert np.all(np.asarray(out.status[i]) == Status.INVALID)


# (i) bad inputs
@pytest.mark.parametrize(
    "changes, name",
    [
        (dict(lambda_i=-1.0), "lambda_i"),
        (dict(lambda_z=0.0), "lambda_z"),
        (dict(eta=1.0), "eta"),
        (dict(eta=0.0), "eta"),
        (dict(gent=-2.0), "gent"),
        (dict(voltage=float("nan")), "voltage"),
        (dict(length_ratio=-1.0), "length_ratio"),
        (dict(lambda_i=3.0, gent=2.0), "Gent locking"),
        (dict(material="mooney"), "material"),
    ],
)
def test_bad_tube_raises_value_error_naming_the_parameter(changes, name):
    with pytest.raises(ValueError, match=name):
        jd.frequencies(TUBE.replace(**changes), ALPHA)


def test_too_wide_tube_is_rejected_and_invalid_under_jit():
    """λ_z r̂_o² > WIDTH_MAX = 1e6: the rounding of the radii (≈ 2.2e-16 λ_z r̂_o² in the stretches)
    would be silent (ΔP̂ of a neo-Hookean tube at λ_i = 1e7 was 0.4 % off, at λ_i = 6.7e7 NaN), so
    concrete inputs raise a ValueError naming the three fields and stating λ_z r̂_o², and traced
    ones give NaN with status INVALID; λ_i = 999 (λ_z r̂_o² ≈ 9.98e5) is still accepted."""
    neo = TUBE.replace(lambda_z=1.0, gent=jnp.inf)
    message = r"lambda_i, lambda_z, eta .* lambda_z \* r_o\*\*2 must be <= 1e\+06 .* got 1\.000000e\+08"
    for call in (jd.pressure_difference, jd.thickness_ratio, lambda t: jd.frequencies(t, ALPHA)):
        with pytest.raises(ValueError, match=message):
            call(neo.replace(lambda_i=1e4))
    assert np.isfinite(jd.thickness_ratio(neo.replace(lambda_i=999.0)))
    solve = jax.jit(lambda li: jd.solve_frequencies(neo.replace(lambda_i=li), ALPHA))
    out = solve(1e4)
    assert np.all(np.isnan(out.omega)) and np.all(out.status == Status.INVALID)
    assert np.all(solve(1.0).status == Status.CONVERGED)


def test_locking_message_states_the_limit():
    with pytest.raises(ValueError, match=r"I_1 - 3 must stay below gent = 2\.0.*reaches"):
        jd.characteristic(TUBE.replace(lambda_i=3.0, gent=2.0), 1.0, ALPHA)


@pytest.mark.parametrize(
    "call, name",
    [
        (lambda: jd.frequencies(TUBE, ALPHA, jd.Fluid(density_ratio=0.0)), "density_ratio"),
        (lambda: jd.frequencies(TUBE, ALPHA, jd.Fluid(speed_ratio=-1.0)), "speed_ratio"),
        (lambda: jd.frequencies(TUBE, ALPHA, jd.Fluid(coupling="bogus")), "coupling"),
        (lambda: jd.frequencies(TUBE, ALPHA, n_layers=0), "n_layers"),
        (lambda: jd.frequencies(TUBE, -0.1), "alpha"),
        (lambda: jd.frequencies(TUBE, ALPHA, n_roots=0), "n_roots"),
        (lambda: jd.frequencies(TUBE, ALPHA, omega_max=float("inf")), "omega_max"),
        (lambda: jd.frequency(TUBE, ALPHA, -1.0), "guess"),
        (lambda: jd.frequencies(TUBE, 0.5, jd.Fluid(coupling="paper")), "no integer axial mode"),
        (lambda: jd.with_thickness_ratio(TUBE, -0.2), "h_over_Ri"),
        (lambda: jd.frequencies("tube", ALPHA), "tube"),
    ],
)
def test_bad_arguments_raise_value_error(call, name):
    with pytest.raises(ValueError, match=name):
        call()


@pytest.mark.parametrize("name", ["voltage", "lambda_i", "lambda_z", "eta", "gent", "length_ratio",
                                  "density_ratio", "speed_ratio"])
def test_a_boolean_is_no_number(name):
    """Tube(voltage=True) was solved as V̂ = 1.0: every float field of Tube and Fluid refuses a
    boolean (Python's, NumPy's, an array of them), naming the field, as does a sweep axis."""
    for value in (True, np.bool_(False), np.array([True, False])):
        tube, fluid = TUBE, jd.Fluid()
        if name in ("density_ratio", "speed_ratio"):
            fluid = fluid.replace(**{name: value})
        else:
            tube = tube.replace(**{name: value})
        with pytest.raises(ValueError, match=f"^{name} must be a real number, got the boolean"):
            jd.frequencies(tube, ALPHA, fluid)
    with pytest.raises(ValueError, match=f"axis '{name}' must be a real number, got the boolean"):
        jd.sweep(TUBE, jd.Fluid(), n=[1], progress=False, **{name: [True, False]})


def test_alpha_past_the_thickness_limit_raises():
    """α̂ = 1e6 returned NaN (status NOT_FINITE) for concrete inputs: α̂ĥ must stay within
    ALPHA_THICKNESS_MAX = 150 (ĥ the deformed wall thickness), a ValueError naming alpha and the
    limit of this tube; α̂ĥ = 150 itself is accepted (tests/test_core.py solves there)."""
    from jaxdea.physics.dispersion import check_inputs

    limit = 150.0 / float(jd.thickness_ratio(TUBE))
    message = rf"alpha must be <= 150/ĥ = {limit:.6g} for this tube \(α̂ĥ <= 150"
    for alpha in (1e6, limit * (1.0 + 1e-6)):
        for call in (lambda a: jd.frequencies(TUBE, a), lambda a: jd.characteristic(TUBE, 1.0, a),
                     lambda a: jd.dispersion_curve(TUBE, np.array([0.5, a]))):
            with pytest.raises(ValueError, match=message):
                call(alpha)
    check_inputs(TUBE, limit, None, None)


def test_root_and_layer_counts_have_a_limit():
    """n_roots or n_layers of 1e8 ran out of memory inside JAX: they are refused first, naming the
    limit (MAX_ROOTS, MAX_LAYERS), in the solvers and in sweep."""
    for call, match in (
            (lambda: jd.frequencies(TUBE, ALPHA, n_roots=10**8), "n_roots must be <= MAX_ROOTS = 1000"),
            (lambda: jd.frequencies(TUBE, ALPHA, n_layers=10**8), "n_layers must be <= MAX_LAYERS = 4096"),
            (lambda: jd.dispersion_curve(TUBE, np.array([0.5]), n_roots=10**8), "MAX_ROOTS"),
            (lambda: jd.sweep(TUBE, n=[1], n_roots=10**8, progress=False), "MAX_ROOTS"),
            (lambda: jd.sweep(TUBE, n=[1], n_layers=10**8, progress=False), "MAX_LAYERS")):
        with pytest.raises(ValueError, match=match):
            call()


def test_group_velocity_refuses_an_omega_that_is_no_root():
    """Ω = 0.123 at α̂ = 0.4 is no root (a Newton step moves it by ~14 of itself): a concrete call
    raises naming omega, the distance and the tolerance (−f_α̂/f_Ω there would be a plausible
    number that means nothing)."""
    with pytest.raises(ValueError, match=r"omega = 0\.123 is not a root .* above 0\.0001\): pass a "
                                         r"root from jaxdea\.frequency"):
        jd.group_velocity(jd.Tube(lambda_z=1.2), 0.4, 0.123)


def test_group_velocity_of_a_traced_non_root_is_nan():
    """Under jit and vmap a non-root gives NaN; a root gives the number of the un-jitted call to
    rounding, with jaxdea's compiler options or the caller's (inside a caller's program XLA
    fuses differently: its program drops the Newton distance the call returns beside the
    velocity, 356 fusions against 408, and the velocity came out 1 ulp apart)."""
    from jaxdea.compiled import compiler_options

    root = float(jd.frequencies(TUBE, ALPHA, n_roots=1)[0])
    alone = float(jd.group_velocity(TUBE, ALPHA, root))
    assert np.isfinite(alone)
    for options in (compiler_options(), None):
        jitted = jax.jit(lambda w: jd.group_velocity(TUBE, ALPHA, w), compiler_options=options)
        np.testing.assert_allclose(float(jitted(root)), alone, rtol=1e-14)
        assert np.isnan(float(jitted(0.5)))
    both = jax.vmap(lambda w: jd.group_velocity(TUBE, ALPHA, w))(jnp.array([root, 0.5]))
    np.testing.assert_allclose(both[0], alone, rtol=1e-14)
    assert np.isnan(float(both[1]))


def test_group_velocity_tolerance_is_the_newton_distance():
    """The root's neighbours are accepted or refused by their relative Newton distance |f/f_Ω|/|Ω|
    (that of jaxdea.solve.modes.root_distance, here ≈ the relative offset) against ROOT_RTOL = 1e-4:
    1e-7 and 5e-5 off pass (with the velocity of the branch nearby), 2e-4 and 1e-2 off are
    refused, concretely and under jit."""
    from jaxdea.numerics.scalar import ROOT_RTOL
    from jaxdea.params import canonical
    from jaxdea.physics.transfer import laminate
    from jaxdea.solve.modes import root_distance

    root = float(jd.frequencies(TUBE, ALPHA, n_roots=1)[0])
    at_root = float(jd.group_velocity(TUBE, ALPHA, root))
    jitted = jax.jit(lambda w: jd.group_velocity(TUBE, ALPHA, w))
    tube, alpha = canonical(TUBE, ALPHA)
    distance_of = jax.jit(functools.partial(root_distance, tube, alpha, fluid=None,
                                            n_layers=laminate(None, None, tube, alpha), order=0))
    for offset, accepted in ((1e-7, True), (5e-5, True), (2e-4, False), (1e-2, False)):
        omega = root * (1 + offset)
        distance = float(distance_of(omega))
        assert distance == pytest.approx(offset, rel=2e-2)
        assert (distance <= ROOT_RTOL) == accepted
        if accepted:
            np.testing.assert_allclose(jd.group_velocity(TUBE, ALPHA, omega), at_root,
                                       rtol=10 * offset)
            assert np.isfinite(float(jitted(omega)))
        else:
            with pytest.raises(ValueError, match=r"omega = .* is not a root"):
                jd.group_velocity(TUBE, ALPHA, omega)
            assert np.isnan(float(jitted(omega)))


def test_group_velocity_of_order_m_refuses_a_non_root():
    """The order-m path (m = 1) checks the same distance: its root passes, 1e-2 off raises, and
    the compiled program behind it (what runs traced) gives NaN there."""
    from jaxdea.params import canonical
    from jaxdea.physics.transfer import laminate

    root = float(jd.frequencies(TUBE, ALPHA, n_roots=1, m=1)[0])
    assert np.isfinite(float(jd.group_velocity(TUBE, ALPHA, root, m=1)))
    with pytest.raises(ValueError, match=r"omega = .* is not a root"):
        jd.group_velocity(TUBE, ALPHA, root * 1.01, m=1)
    tube, alpha, m = canonical(TUBE, ALPHA, 1)
    layers = laminate(None, None, tube, alpha, m=m)
    for omega, finite in ((root, True), (root * 1.01, False)):
        velocity, distance = roots_module._group_velocity(tube, alpha, jnp.asarray(omega), None,
                                                          layers, 0, m, Family.ORDER_M)
        assert np.isfinite(float(velocity)) == finite and (float(distance) <= 1e-4) == finite


def test_paper_order_needs_concrete_alpha():
    fluid = jd.Fluid(coupling="paper")
    with pytest.raises(ValueError, match="bessel_order"):
        jax.jit(lambda a: jd.frequencies(TUBE, a, fluid))(ALPHA)
    n1 = jd.frequencies(TUBE, jd.axial_wavenumber(TUBE, 1), fluid)
    explicit = jd.frequencies(TUBE, jd.axial_wavenumber(TUBE, 1), fluid.replace(bessel_order=1))
    np.testing.assert_array_equal(n1, explicit)


def test_float32_is_refused():
    jax.config.update("jax_enable_x64", False)
    try:
        with pytest.raises(RuntimeError, match="jax_enable_x64"):
            jd.frequencies(jd.Tube(), 0.445)
    finally:
        jax.config.update("jax_enable_x64", True)


# root isolation
def test_scan_finds_pairs_closer_than_any_step():
    """Synthetic f with root pairs at relative gaps 1e-3 … 1e-9 inside single scan intervals,
    a root at 1e-7 near Ω = 0 and a double-ish pair: every root is found (Hermite classification)."""
    pairs = [(0.9, 1e-3), (2.3, 1e-6), (3.7, 1e-9)]
    expected = sorted([1e-7, 5.0] + [c for c, _ in pairs] + [c * (1 + g) for c, g in pairs])

    def f(x):
        val = (x - 1e-7) * (x - 5.0)
        for c, g in pairs:
            val = val * (x - c) * (x - c * (1 + g))
        return val / (1.0 + x**8)

    got = jax.jit(lambda: roots_module._scan_for_roots(f, jnp.asarray(0.25), 6.0, 8))()
    np.testing.assert_allclose(got.omega, expected, rtol=1e-12)
    assert np.all(np.asarray(got.status) == Status.CONVERGED)
    few = jax.jit(lambda: roots_module._scan_for_roots(f, jnp.asarray(0.25), 6.0, 10))()
    assert np.all(np.isnan(np.asarray(few.omega[8:])))
    assert np.all(np.asarray(few.status[8:]) == Status.NO_ROOT)


def test_paper_coupling_close_pairs_against_dense_scan():
    """The paper's coupling makes close pairs straddling its poles (theory.md §7): frequencies must
    return exactly the sign changes a 40 000-point scan of the characteristic function sees."""
    tube = jd.Tube(voltage=0.2, lambda_i=1.1, **PAPER)
    fluid = jd.Fluid(coupling="paper", bessel_order=1)
    alpha = jd.axial_wavenumber(tube, 1)
    got = jd.solve_frequencies(tube, alpha, fluid, n_roots=24, omega_max=8.0)
    grid = jnp.linspace(1e-6, 8.0, 80_001)
    vals = np.asarray(jax.jit(jax.vmap(lambda o: jd.characteristic(tube, o, alpha, fluid)))(grid))
    changes = np.nonzero(np.sign(vals[:-1]) * np.sign(vals[1:]) < 0)[0]
    found = np.asarray(got.omega)[np.isfinite(np.asarray(got.omega))]
    assert len(found) == min(24, len(changes)) and len(found) >= 16
    np.testing.assert_allclose(found, np.asarray(grid)[changes][: len(found)], atol=1e-4)
    assert np.diff(found).min() < 1e-2  # pairs closer than 1e-2 in Ω are among them


def test_roots_exactly_on_grid_points():
    """A root that falls exactly on a scan point is returned once, converged (no bisection drift)."""
    def f(x):
        return (x - 1.0) * (x - 2.5)

    got = jax.jit(lambda: roots_module._scan_for_roots(f, jnp.asarray(0.5), 4.0, 3))()
    np.testing.assert_array_equal(got.omega[:2], [1.0, 2.5])
    np.testing.assert_array_equal(got.status, [Status.CONVERGED, Status.CONVERGED, Status.NO_ROOT])


def test_scan_goes_on_after_a_hidden_candidate_without_roots():
    """An extremum of f that stays above zero looks like a hidden pair (it takes two lanes); the
    lanes find no root there, so the scan must go on to the real roots above it. And with one root
    wanted, a true pair inside one interval still gives its lower member."""
    def empty_dip(x):
        return ((x - 1.1) ** 2 + 1e-4) * (x - 3.0) * (x - 4.0) / (1.0 + x**4)  # dip in (1, 1.25)

    got = jax.jit(lambda: roots_module._scan_for_roots(empty_dip, jnp.asarray(0.25), 6.0, 2))()
    np.testing.assert_allclose(got.omega, [3.0, 4.0], rtol=1e-14)

    def pair(x):
        return ((x - 1.1) ** 2 - 1e-6) * (x - 3.0) / (1.0 + x**4)  # 1.099, 1.101 in (1, 1.25)

    got = jax.jit(lambda: roots_module._scan_for_roots(pair, jnp.asarray(0.25), 6.0, 1))()
    np.testing.assert_allclose(got.omega, [1.099], rtol=1e-14)
    assert int(got.status[0]) == Status.CONVERGED


def _close_pairs(x):
    """Roots 1e-7 and 5, and pairs at relative gaps 1e-3, 1e-6, 1e-9 inside single 0.25 steps."""
    val = (x - 1e-7) * (x - 5.0)
    for c, g in [(0.9, 1e-3), (2.3, 1e-6), (3.7, 1e-9)]:
        val = val * (x - c) * (x - c * (1 + g))
    return val / (1.0 + x**8)


FIRST_ROOT_CASES = {  # f, step, end, the lowest root in (0, end] (NaN: none), its status
    "near zero": (_close_pairs, 0.25, 6.0, 1e-7, Status.CONVERGED),
    "pair at 1e-3": (lambda x: _close_pairs(x) / (x - 1e-7), 0.25, 6.0, 0.9, Status.CONVERGED),
    "pair at 1e-9": (lambda x: (x - 3.7) * (x - 3.7 * (1 + 1e-9)) * (x - 5.0), 0.25, 6.0, 3.7,
                     Status.CONVERGED),
    "empty dip first": (lambda x: ((x - 1.1) ** 2 + 1e-4) * (x - 3.0) / (1.0 + x**4), 0.25, 6.0, 3.0,
                        Status.CONVERGED),
    "on a grid point": (lambda x: (x - 1.0) * (x - 2.5), 0.5, 4.0, 1.0, Status.CONVERGED),
    "oscillating": (lambda x: jnp.sin(7.0 * x) + 0.9, 0.01, 3.0, (np.pi + np.arcsin(0.9)) / 7.0,
                    Status.CONVERGED),
    "none in range": (lambda x: (x - 7.0) * (x - 9.0), 0.25, 6.0, np.nan, Status.NO_ROOT),
    "NaN below the root": (lambda x: jnp.where(x > 2.0, jnp.nan, 1.0) * (x - 3.0), 0.25, 6.0, np.nan,
                           Status.NOT_FINITE),
    "NaN above the root": (lambda x: jnp.where(x > 2.0, jnp.nan, 1.0) * (x - 1.5), 0.25, 6.0, 1.5,
                           Status.CONVERGED),
    "no range": (lambda x: x - 1.0, 0.0, 0.0, np.nan, Status.NOT_FINITE),
}


@pytest.mark.parametrize("case", FIRST_ROOT_CASES)
def test_first_root_by_zooming(case):
    """The single-site search of the critical voltage (_first_root) finds the lowest root of
    synthetic functions with close pairs, an empty dip below the root, a root on a grid point, many
    oscillations and non-finite regions, to 1e-13 relative (its tolerance), and agrees with the
    scan with lanes (_scan_for_roots) on every case that has a root."""
    f, step, end, root, status = FIRST_ROOT_CASES[case]
    got = jax.jit(lambda: roots_module._first_root(f, jnp.asarray(step), end))()
    assert int(got.status) == status
    if np.isnan(root):
        assert np.isnan(float(got.omega))
        return
    np.testing.assert_allclose(float(got.omega), root, rtol=1e-13)
    lanes = jax.jit(lambda: roots_module._scan_for_roots(f, jnp.asarray(step), end, 1))()
    np.testing.assert_allclose(float(got.omega), float(lanes.omega[0]), rtol=1e-13)


def test_first_root_zooms_in_a_few_chunks():
    """A simple root found in the first chunk (Δ = 2π/32) costs that chunk and two zooms, no more:
    the first around the Hermite cubic's root (off by ≤ Δ⁴/(384 cos π/6) ≈ 4.5e-6) leaves a bracket
    ≤ 64 times that, the second a bracket ≤ 1e-6 Δ with equal slopes (its cubic is f to rounding)."""
    f, calls = _counted(lambda x: jnp.sin(x) - 0.5)
    got = jax.jit(lambda: roots_module._first_root(f, jnp.asarray(2 * np.pi / 32), 6.0))()
    assert abs(float(got.omega) - np.pi / 6) <= 2 * np.spacing(np.pi / 6)
    assert len(calls) == 3


def test_hermite_extremum_of_a_cubic():
    """For a cubic f the Hermite interpolant is f itself, so its stationary point is f's: the roots
    of f' = 3x² − 2 are ±√(2/3); an interval with no sign change of f' gives the midpoint."""
    from jaxdea.numerics.scalar import hermite_extremum

    f, df = (lambda x: x**3 - 2.0 * x + 0.3), (lambda x: 3.0 * x**2 - 2.0)
    for a, b, want in [(0.1, 1.4, np.sqrt(2 / 3)), (-2.0, 0.3, -np.sqrt(2 / 3)), (1.0, 2.0, 1.5)]:
        got = float(hermite_extremum(a, b, f(a), f(b), df(a), df(b)))
        assert abs(got - want) <= 4 * abs(np.spacing(want))


def _with_slope(f):
    """x ↦ (f(x), f'(x)): the (value, slope to step with) that Newton from a guess takes."""
    return lambda x: jax.jvp(f, (x,), (jnp.ones_like(x),))


def _counted(f):
    """f with a host-side count of its evaluations (one per vectorised call)."""
    calls = []

    def g(x):
        jax.debug.callback(lambda: calls.append(1))
        return f(x)

    return g, calls


def test_newton_stops_once_its_step_is_below_the_float_spacing():
    """Every evaluated point becomes a bracket end, so a converged Newton step (below one ulp at x)
    proposes x itself, a bracket end: that must end the solve, not start bisecting a bracket of
    width ~1e-12 down to 1e-15 (which took 30–40 evaluations per root before)."""
    from jaxdea.numerics.scalar import bracketed_root

    f, calls = _counted(lambda x: x * x - 2.0)
    x, status = jax.jit(lambda: bracketed_root(f, 1.0, 2.0, -1.0, 2.0))()
    assert int(status) == Status.CONVERGED
    assert abs(float(x) - np.sqrt(2.0)) <= np.spacing(np.sqrt(2.0))
    assert len(calls) <= 2 + 7  # the two end slopes, then quadratic convergence from 1


def test_bracket_starts_at_the_hermite_cubic_root():
    """The first point of a bracket is the root of the cubic Hermite interpolant of the end data: for
    a cubic f that is its root, so one evaluation ends the solve (its Newton step is below the
    tolerance); for sin x − 1/2 on 1/16-period brackets the cubic's root is within the interpolation
    bound h⁴ max|f⁽⁴⁾|/(384 min|f'|) of π/6 (the secant point misses it by 40–130×)."""
    from jaxdea.numerics.scalar import bracketed_root, hermite_root

    cubic = lambda x: (x - 1.3) * (x * x + 0.5)  # noqa: E731  one real root, 1.3
    f, calls = _counted(cubic)
    x, status = jax.jit(lambda: bracketed_root(f, 0.25, 2.0, cubic(0.25), cubic(2.0)))()
    assert int(status) == Status.CONVERGED
    assert abs(float(x) - 1.3) <= 2 * np.spacing(1.3)
    assert len(calls) == 2 + 1  # the two end slopes, then the cubic's root
    h, root = 2 * np.pi / 16, np.pi / 6
    for a in (root - 0.9 * h, root - 0.5 * h, root - 0.1 * h):
        b = a + h  # f = sin x − 1/2: |f⁽⁴⁾| ≤ 1, f' = cos x ≥ cos b on [a, b]
        guess = float(hermite_root(a, b, np.sin(a) - 0.5, np.sin(b) - 0.5, np.cos(a), np.cos(b)))
        assert a < guess < b and abs(guess - root) <= h**4 / (384 * np.cos(b))
    # no sign change, or a root at an end: no guess
    assert np.isnan(hermite_root(0.0, 1.0, 1.0, 2.0, 0.0, 0.0))
    assert np.isnan(hermite_root(0.0, 1.0, 0.0, 2.0, 1.0, 1.0))


def test_newton_stops_once_the_predicted_error_is_below_tolerance():
    """Newton on x² − 2 from 1.5: the errors are 2.5e-3, 2.1e-6, 1.6e-12 after steps 1–3. After the
    fourth evaluation (x₃) the next step 1.6e-12 leaves K·step² ≈ 1e-24 (K = 1/(2√2), estimated
    from the slopes at x₂, x₃), so it is applied without evaluating x₄: √2 to rounding in 4
    evaluations (5 when waiting for a step below 1e-15·x). From x₂ (step 2.1e-6, K·step² ≈ 1.6e-12)
    it must not stop."""
    f, calls = _counted(lambda x: x * x - 2.0)
    root, status = jax.jit(lambda: roots_module._newton_from_guess(_with_slope(f), 1.5, jnp.inf))()
    assert int(status) == Status.CONVERGED
    assert abs(float(root) - np.sqrt(2.0)) <= np.spacing(np.sqrt(2.0))
    assert len(calls) == 4


def test_frequency_from_a_close_guess_takes_few_newton_steps():
    """Newton from a root of the coarser laminate (relative distance ~5e-6) converges in a few
    evaluations on the finer one, like Newton should (it took 36 on this case before)."""
    from jaxdea.physics.dispersion import characteristic_on_wall

    tube, alpha, coarse = jd.Tube(), 0.15, 1.8540488  # the N = 30 root, 5e-6 below N = 60's
    wall = roots_module.discretize(tube, 60)
    fun, calls = _counted(lambda om: characteristic_on_wall(wall, om, alpha))
    root, status = jax.jit(lambda: roots_module._newton_from_guess(_with_slope(fun), coarse, 4.0))()
    assert int(status) == Status.CONVERGED
    np.testing.assert_allclose(root, jd.frequency(tube, alpha, coarse, n_layers=60), rtol=1e-15)
    # a root of the N = 60 laminate (f changes sign within ±1e-12 of it), away from the guess
    f = [jd.characteristic(tube, float(root) * (1 + d), alpha, n_layers=60) for d in (-1e-12, 1e-12)]
    assert f[0] * f[1] < 0
    assert abs(float(root) / coarse - 1.0) > 1e-6
    assert len(calls) <= 6


@pytest.mark.slow
def test_second_derivative_of_a_root_against_finite_differences():
    """d²Ω/dV̂² by nested grad (and jacfwd of jacrev) equals the central difference of dΩ/dV̂: the
    implicit-derivative rule re-attaches the root to its parameters, so the second-order term
    through dΩ/dV̂ is kept (it was missing: −25.6 instead of −31.12 on this tube)."""
    tube = jd.Tube(lambda_i=1.1, lambda_z=1.2)
    alpha = jd.axial_wavenumber(tube, 1)
    guess = jd.frequencies(tube.replace(voltage=0.1), alpha, n_roots=1)[0]

    def omega(v):
        return jd.frequency(tube.replace(voltage=v), alpha, guess)

    d2 = float(jax.grad(jax.grad(omega))(0.1))
    fd = fd_derivative(jax.grad(omega), 0.1, h=1e-5)
    assert d2 == pytest.approx(fd, rel=1e-7)
    assert float(jax.jacfwd(jax.jacrev(omega))(0.1)) == pytest.approx(d2, rel=1e-12)
