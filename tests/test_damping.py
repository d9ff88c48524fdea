"""Damping and complex frequencies (API.md "Real tubes", docs/theory/real_tubes.md §4–§5).

The exact limit (§4): an unstretched, unloaded, empty single wall of any normalised material with
damping law η* is the linear incompressible cylinder of shear modulus 1 + η*(Ω), so every root
satisfies Ω² = Ω_e²(1 + η*(Ω)) with Ω_e a root of the elastic exact cylinder (tests/exact_cylinder_m.py,
Bessel functions, independent of the state-space method)."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from exact_cylinder_m import roots_m

import jaxdea as jd
from jaxdea.physics import transfer

ETA = 0.85
REST = dict(voltage=0.0, lambda_i=1.0, lambda_z=1.0, eta=ETA)


def elastic_exact(m, alpha, n):
    """The n lowest roots of the exact incompressible cylinder (a = 1, b = 1/η)."""
    return np.asarray(roots_m(m, alpha, 1.0, 1.0 / ETA, n_roots=n))


def test_kelvin_voigt_public_values():
    """docs/theory/real_tubes.md §7(c): KV η_v = 0.1, m = 0, α̂ = 1: Ω = 1.34893014 + 0.09139831i and
    2.34343182 + 0.27846065i, and both equal [iΩ_e²η_v + √(4Ω_e² − Ω_e⁴η_v²)]/2 with Ω_e the
    longitudinal roots of the exact cylinder, to 1e-9."""
    tube = jd.Tube(**REST, damping=jd.KelvinVoigt(viscosity=0.1))
    res = jd.complex_frequencies(tube, 1.0, n_roots=2, omega_max=2.5, m=0)
    assert int(res.certificate) == jd.SearchStatus.CERTIFIED
    got = np.asarray(res.omega)
    np.testing.assert_allclose(got, [1.34893014 + 0.09139831j, 2.34343182 + 0.27846065j],
                               rtol=3e-9)
    exact = elastic_exact(0, 1.0, 3)  # m = 0 holds the torsional root Ω_e = α̂ too
    longitudinal = exact[np.abs(exact - 1.0) > 1e-6][:2]
    expected = (1j * longitudinal**2 * 0.1 + np.sqrt(4 * longitudinal**2 - longitudinal**4 * 0.01)) / 2
    np.testing.assert_allclose(got, expected, rtol=1e-9)
    np.testing.assert_allclose(res.quality_factor, got.real / (2 * got.imag), rtol=1e-14)


def test_kelvin_voigt_roots_beside_the_viscous_singularity():
    """KV η_v = 0.1, m = 1, α̂ = 1: the shear modulus 1 + iΩη_v vanishes at Ω = i/η_v = 10i, where the
    roots of the higher modes accumulate (docs/theory/real_tubes.md §5). The searched boxes reach past
    it, so the search leaves out the corner Re Ω < 5 < Im Ω (Q < 1/2) and must still find the
    two strongly damped roots above it (Q ≈ 0.24) and certify the count: the five roots equal
    [iΩ_e²η_v + √(4Ω_e² − Ω_e⁴η_v²)]/2 over every underdamped elastic root Ω_e of the exact
    cylinder (Ω_eη_v < 2), to 1e-9. Before the corner was left out the contour passed 0.02 from
    the singularity and the search was not certified."""
    tube = jd.Tube(**REST, damping=jd.KelvinVoigt(viscosity=0.1))
    wall = transfer.discretized(tube, n_layers=transfer.laminate(
        None, None, tube, 1.0, 5, 1))
    top = 40.0
    assert 10.0 <= transfer.viscous_singularity(wall, top) <= 10.0 + top / 512
    # a layered wall finds it in its Kelvin–Voigt layer beside a fractional one (whose s(iy) is
    # never real), and a hysteretic wall has none
    mixed = tube.replace(damping=None, layers=(
        jd.Layer(0.3, jd.NeoHookean(), damping=jd.FractionalKelvinVoigt(0.3, 0.5, 0.32)),
        jd.Layer(0.7, jd.Gent(97.2), active=True, damping=jd.KelvinVoigt(0.1))))
    layered = transfer.discretized(mixed, n_layers=transfer.Layers(16, "magnus6", True))
    assert 10.0 <= transfer.viscous_singularity(layered, top) <= 10.0 + top / 512
    hysteretic = transfer.discretized(tube.replace(damping=jd.Hysteretic(0.2)),
                                      n_layers=transfer.Layers(16, "magnus6", True))
    assert transfer.viscous_singularity(hysteretic, top) == np.inf
    elastic = elastic_exact(1, 1.0, 10)
    elastic = elastic[elastic * 0.1 < 2.0]
    assert elastic.size == 5 and elastic[-1] > 17.0  # three low modes and two past 10 (overdamped side)
    exact = (1j * elastic**2 * 0.1 + np.sqrt(4 * elastic**2 - elastic**4 * 0.01)) / 2
    exact = np.sort_complex(exact)
    res = jd.complex_frequencies(tube, 1.0, n_roots=5, m=1)
    assert int(res.certificate) == jd.SearchStatus.CERTIFIED
    np.testing.assert_allclose(np.asarray(res.omega), exact, rtol=1e-9)
    assert np.all(np.asarray(res.quality_factor)[3:] < 0.5)


def test_an_inflated_kelvin_voigt_tube_is_certified_past_its_singularity():
    """An inflated, biased Kelvin–Voigt tube whose damped shear divisor vanishes on the imaginary
    axis between 26.2i and 32.6i (η_v = 0.0185): asking for 5 roots reaches past it. The search had
    returned nothing (COUNT_FAILED); now it is certified, its first four roots are those of the
    search for four (whose box stays below the singularity) and each root is a fixed point of
    complex Newton on F (an independent solve from the root)."""
    tube = jd.Tube(eta=0.7125, lambda_i=1.169, lambda_z=1.233, voltage=0.01126,
                   damping=jd.KelvinVoigt(0.0185))
    four = jd.complex_frequencies(tube, 1.488, n_roots=4)
    five = jd.complex_frequencies(tube, 1.488, n_roots=5)
    assert int(four.certificate) == int(five.certificate) == jd.SearchStatus.CERTIFIED
    assert np.all(np.asarray(five.status) == 0)
    np.testing.assert_allclose(np.asarray(five.omega)[:4], np.asarray(four.omega), rtol=1e-10)
    for z in np.asarray(five.omega):
        again, status = jd.solve_complex_frequency(tube, 1.488, complex(z) * (1 + 1e-3))
        assert int(status) == 0
        assert abs(complex(again) - z) <= 1e-9 * abs(z)


def test_hysteretic_order_one():
    """§7(c): hysteretic ζ = 0.2, m = 1, α̂ = 1: Ω = Ω_e√(1 + 0.2i) for the two lowest elastic roots
    (0.64437036 + 0.06380524i first), found without an omega_max."""
    tube = jd.Tube(**REST, damping=jd.Hysteretic(loss=0.2))
    res = jd.complex_frequencies(tube, 1.0, n_roots=2, m=1)
    assert int(res.certificate) == jd.SearchStatus.CERTIFIED
    expected = elastic_exact(1, 1.0, 2) * np.sqrt(1 + 0.2j)
    np.testing.assert_allclose(np.asarray(res.omega), expected, rtol=1e-9)
    np.testing.assert_allclose(res.omega[0], 0.64437036 + 0.06380524j, rtol=1e-8)


@pytest.mark.parametrize("law", [
    jd.Prony(moduli=(1.7, 1.7), times=(40.0, 400.0)),
    jd.Prony(moduli=(0.5,), times=(0.8,)),
    jd.FractionalKelvinVoigt(modulus=0.3, time=0.5, order=0.32),
], ids=["Prony VHB-like", "Prony one branch", "fractional KV"])
def test_every_root_satisfies_the_exact_relation(law):
    """Each root Ω has √(Ω²/(1 + η*(Ω))) equal to a root of the elastic exact cylinder (the §4
    relation, for frequency-dependent η*), m = 2, to 1e-9; the roots decay (Im Ω > 0)."""
    tube = jd.Tube(**REST, damping=law)
    res = jd.complex_frequencies(tube, 0.7, n_roots=3, m=2)
    assert int(res.certificate) == jd.SearchStatus.CERTIFIED
    omega = np.asarray(res.omega)
    assert np.all(omega.imag > 0)
    eta_star = np.asarray(law.viscous_modulus(jnp.asarray(omega)))
    elastic = np.sqrt(omega**2 / (1 + eta_star))
    exact = elastic_exact(2, 0.7, 6)
    for z in elastic:
        assert np.nanmin(np.abs(exact - z)) <= 1e-9 * abs(z), (z, exact)


@pytest.mark.parametrize("law", [
    jd.KelvinVoigt(0.05),
    jd.Prony(moduli=(1.7, 1.8, 0.7), times=(0.5, 5.0, 50.0)),
    jd.FractionalKelvinVoigt(modulus=0.3, time=0.5, order=0.32),
    jd.Hysteretic(0.05),
], ids=["KV", "Prony", "fractional KV", "hysteretic"])
def test_seeds_solve_the_exact_relation(law):
    """complex_frequencies' first seeds (``_seeds``) from elastic roots Ω_e solve
    Ω² = Ω_e²(1 + η*(Ω)) to 1e-12 with Re Ω > 0, also where η*(Ω_e)Ω_e is not small (Ω_e up to 36,
    the benchmark's fourth root); for Kelvin–Voigt they are the closed-form root
    [iΩ_e²η_v + √(4Ω_e² − Ω_e⁴η_v²)]/2. The elastic roots themselves come second."""
    from jaxdea.solve.complex_frequencies import _seeds
    elastic = np.array([0.745, 1.91, 17.84, 35.62])
    first, second = _seeds(jd.Tube(**REST, damping=law), elastic)
    first = np.asarray(first)
    np.testing.assert_array_equal(np.asarray(second), elastic)
    eta_star = np.asarray(law.viscous_modulus(jnp.asarray(first)))
    np.testing.assert_allclose(first**2, elastic**2 * (1 + eta_star), rtol=1e-12)
    assert np.all(first.real > 0) and np.all(first.imag > 0)
    if isinstance(law, jd.KelvinVoigt):
        v = law.viscosity
        closed = (1j * elastic**2 * v + np.sqrt(4 * elastic**2 - elastic**4 * v**2 + 0j)) / 2
        np.testing.assert_allclose(first, closed, rtol=1e-12)


def test_an_elastic_tube_gives_its_real_frequencies():
    """Without damping complex_frequencies returns the real roots of jd.frequencies (a loaded
    tube, acoustic fluid), to 1e-10, with Q = inf."""
    tube = jd.Tube(voltage=0.1, lambda_i=1.1, lambda_z=1.2, eta=0.8)
    fluid = jd.Fluid()
    real = np.asarray(jd.frequencies(tube, 0.6, fluid, n_roots=3))
    res = jd.complex_frequencies(tube, 0.6, fluid, n_roots=3)
    np.testing.assert_allclose(np.asarray(res.omega).real, real, rtol=1e-10)
    assert np.max(np.abs(np.asarray(res.omega).imag)) <= 1e-10 * real.max()


def test_damping_on_a_loaded_tube_lowers_q_with_viscosity():
    """On a stretched, voltage-loaded tube the complex root tends to the elastic root as the
    viscosity vanishes (η_v = 1e-4: Re Ω to 1e-7, Im Ω ≈ η_v Ω_e²·k small and positive), and a
    larger viscosity gives a lower Q."""
    tube = jd.Tube(voltage=0.1, lambda_i=1.1, lambda_z=1.2, eta=0.8)
    elastic = float(jd.frequencies(tube, 0.6, n_roots=1)[0])
    q = []
    for eta_v in (1e-4, 1e-2):
        res = jd.complex_frequencies(tube.replace(damping=jd.KelvinVoigt(eta_v)), 0.6, n_roots=1,
                                     omega_max=1.2 * elastic)
        z = complex(res.omega[0])
        assert z.imag > 0
        q.append(float(res.quality_factor[0]))
        if eta_v == 1e-4:
            assert abs(z.real - elastic) <= 1e-7 * elastic
    assert q[1] < q[0] / 50


def test_real_solvers_refuse_a_damped_tube():
    tube = jd.Tube(**REST, damping=jd.KelvinVoigt(0.1))
    with pytest.raises(ValueError, match="tube.damping: .*complex_frequencies"):
        jd.frequencies(tube, 1.0)


@pytest.mark.parametrize("law, message", [
    (jd.KelvinVoigt(-0.1), "viscosity must be >= 0"),
    (jd.Prony((1.0, 2.0), (1.0,)), "moduli and times must have one length"),
    (jd.Prony((1.0,), (0.0,)), r"times must be > 0"),
    (jd.FractionalKelvinVoigt(order=1.5), r"order must be in \(0, 1\]"),
    (jd.Hysteretic(float("nan")), "loss must be >= 0"),
    ("viscous", "damping must be None or a damping law"),
])
def test_bad_damping_is_named(law, message):
    with pytest.raises(ValueError, match=message):
        jd.complex_frequencies(jd.Tube(**REST, damping=law), 1.0)


def test_traced_inputs_are_refused():
    tube = jd.Tube(**REST, damping=jd.KelvinVoigt(0.1))
    with pytest.raises(ValueError, match="must be concrete"):
        jax.jit(lambda a: jd.complex_frequencies(tube, a).omega)(1.0)


def test_implicit_derivatives_of_a_complex_root():
    """solve_complex_frequency's implicit derivatives: dΩ/dη_v of the unstretched KV tube equals the
    derivative of the exact root [iΩ_e²η_v + √(4Ω_e² − Ω_e⁴η_v²)]/2 (Re and Im by jax.grad, to
    1e-8 with Ω_e of the exact cylinder), and dΩ/dV̂ on a loaded damped tube equals a central
    difference of the root."""
    base = jd.Tube(**REST)

    def root(eta_v):
        tube = base.replace(damping=jd.KelvinVoigt(eta_v))
        return jd.solve_complex_frequency(tube, 1.0, 1.349 + 0.091j, n_layers=24, scheme="magnus6")[0]

    exact = elastic_exact(0, 1.0, 3)
    we = exact[np.abs(exact - 1.0) > 1e-6][0]
    expected = (1j * we**2 + 0.5 * (-2 * we**4 * 0.1) / np.sqrt(4 * we**2 - we**4 * 0.01)) / 2
    got = complex(jax.grad(lambda v: root(v).real)(0.1), jax.grad(lambda v: root(v).imag)(0.1))
    assert abs(got - expected) <= 1e-8 * abs(expected)

    loaded = jd.Tube(voltage=0.1, lambda_i=1.1, lambda_z=1.2, eta=0.8, damping=jd.Prony((0.5,), (0.8,)))
    guess = complex(jd.complex_frequencies(loaded, 0.6, n_roots=1).omega[0])

    def loaded_root(v):
        return jd.solve_complex_frequency(loaded.replace(voltage=v), 0.6, guess)[0]

    grad = complex(jax.grad(lambda v: loaded_root(v).real)(0.1),
                   jax.grad(lambda v: loaded_root(v).imag)(0.1))
    h = 1e-6
    fd = complex(loaded_root(0.1 + h) - loaded_root(0.1 - h)) / (2 * h)
    assert abs(grad - fd) <= 1e-6 * abs(fd)
    status = jd.solve_complex_frequency(loaded, 0.6, guess)[1]
    assert int(status) == jd.Status.CONVERGED


@pytest.mark.parametrize("case", ["kelvin_voigt", "prony_filled", "hysteretic_in_water", "layered",
                                  "voltage"])
def test_the_blocks_of_a_wall_without_voltage_equal_the_full_state(case):
    """The complex searches of a longitudinal wall without voltage propagate its mechanical and
    electric blocks apart (characteristic.block_pieces, Problem.decoupled): f and d ln F/dx equal
    the 6×6 propagation's at complex Ω and complex α̂ (to rounding: 1e-13 of max |f|, 1e-12 of the
    log-derivative), damped, filled, in a surrounding fluid and layered; a wall with voltage gives
    NaN, never a wrong value. describe() decouples exactly the longitudinal walls without voltage."""
    from jaxdea.params import canonical
    from jaxdea.physics import characteristic as ch
    from jaxdea.physics.characteristic import Unknown
    from jaxdea.physics.families import Family
    from jaxdea.physics.problem import describe

    fluid = None
    tube = jd.Tube(voltage=0.0, lambda_i=1.1, lambda_z=1.2, eta=0.7, damping=jd.KelvinVoigt(0.05))
    if case == "prony_filled":
        tube, fluid = jd.Tube(voltage=0.0, damping=jd.Prony((0.8,), (0.5,))), jd.Fluid()
    elif case == "hysteretic_in_water":
        tube = jd.Tube(voltage=0.0, eta=0.85, damping=jd.Hysteretic(0.1),
                       outer=jd.Fluid(density_ratio=0.7, speed_ratio=3.5))
    elif case == "layered":
        tube = jd.Tube(voltage=0.0, layers=(
            jd.Layer(0.3, jd.NeoHookean(), shear_ratio=2.0),
            jd.Layer(0.7, jd.Gent(97.2), active=True, damping=jd.KelvinVoigt(0.03))))
    elif case == "voltage":
        tube = tube.replace(voltage=0.05)
    assert describe(tube, 0.8, fluid, None, damped=True).decoupled == (case != "voltage")
    assert not describe(tube, 0.8, fluid, None, m=1, damped=True).decoupled
    tube, _, fluid = canonical(tube, 0.8, fluid)
    wall = transfer.discretized(tube, n_layers=transfer.Layers(12, "magnus6", True))
    for unknown, xs, fixed in ((Unknown.OMEGA, [0.7 + 0.05j, 1.9 + 0.3j, 3.0 + 1.0j], 0.8),
                               (Unknown.ALPHA, [0.5 + 0.01j, 1.5 - 0.7j, 0.05 + 2.0j], 1.3)):
        def both(x, decoupled, unknown=unknown, fixed=fixed):
            return ch.value_and_log_slope(Family.LONGITUDINAL, wall, x, fixed, fluid, 0, 0.0,
                                          unknown, decoupled=decoupled)

        xs = jnp.asarray(xs)
        f_ref, slope_ref = jax.jit(jax.vmap(lambda x: both(x, False)))(xs)
        f, slope = jax.jit(jax.vmap(lambda x: both(x, True)))(xs)
        value = jax.jit(jax.vmap(lambda x, unknown=unknown, fixed=fixed: ch.value(
            Family.LONGITUDINAL, wall, x, fixed, fluid, 0, 0.0, unknown, decoupled=True)))(xs)
        winding = jax.jit(jax.vmap(lambda x, unknown=unknown, fixed=fixed: ch.winding_value(
            Family.LONGITUDINAL, wall, x, fixed, fluid, 0, 0.0, unknown, True)))(xs)
        if case == "voltage":
            assert np.all(np.isnan(np.asarray(f))) and np.all(np.isnan(np.asarray(value)))
            assert np.all(np.isnan(np.asarray(winding)))
            continue
        scale = float(jnp.max(jnp.abs(f_ref)))
        assert scale > 1e-3
        np.testing.assert_allclose(f, f_ref, rtol=0, atol=1e-13 * scale)
        np.testing.assert_allclose(value, f_ref, rtol=0, atol=1e-13 * scale)
        np.testing.assert_allclose(slope, slope_ref, rtol=1e-12)
        # the argument principle's function (the roots' count): at x = Ω the mechanical block
        # alone, F over an electric factor that is one nonzero constant in Ω; at x = α̂, f itself
        factor = np.asarray(f_ref) / np.asarray(winding)
        if unknown is Unknown.OMEGA:
            np.testing.assert_allclose(factor, factor[0], rtol=1e-12)
            assert 1e-3 < abs(factor[0]) <= 1.0 + 1e-12
        else:
            np.testing.assert_allclose(factor, 1.0, rtol=1e-12)


def _scaled(law, s):
    """The damping law with its moduli (or loss) times s."""
    if isinstance(law, jd.KelvinVoigt):
        return jd.KelvinVoigt(law.viscosity * s)
    if isinstance(law, jd.Hysteretic):
        return jd.Hysteretic(law.loss * s)
    if isinstance(law, jd.Prony):
        return jd.Prony(tuple(g * s for g in law.moduli), law.times)
    return jd.FractionalKelvinVoigt(law.modulus * s, law.time, law.order)


def _damped(tube, law):
    """The tube with ``law`` on its wall (a layered wall: on its active layer)."""
    import dataclasses

    if tube.layers is None:
        return tube.replace(damping=law)
    return tube.replace(layers=tuple(dataclasses.replace(layer, damping=law) if layer.active
                                     else layer for layer in tube.layers))


def test_campaign_elastic_roots_continued_in_the_damping_are_found():
    """A campaign over random stretched, biased, damped tubes (the four laws; m = 0, 1, 2; a
    liner, a filling or a surrounding fluid at random): each elastic root of ``frequencies`` is
    continued in the damping scale s = 0.05 … 1 (20 steps of complex Newton on a finer wall of 48
    sublayers, independent of the search's boxes and grid), and every continued root below the
    highest root ``complex_frequencies`` returned is among them (1e-6), every returned root
    CONVERGED, the search's count met wherever it found all roots asked."""
    from jaxdea.params import canonical
    from jaxdea.physics import characteristic as ch
    from jaxdea.physics.characteristic import Unknown
    from jaxdea.physics.problem import describe

    rng = np.random.default_rng(2026)
    step = jax.jit(lambda family, order, wall, x, a, f, m: ch.value_and_log_slope(
        family, wall, x, a, f, order, m, Unknown.OMEGA), static_argnums=(0, 1))
    for case in range(10):
        m = int(rng.integers(0, 3))
        tube = jd.Tube(eta=float(rng.uniform(0.5, 0.9)), lambda_i=float(rng.uniform(0.9, 1.15)),
                       lambda_z=float(rng.uniform(1.0, 1.25)),
                       voltage=float(rng.choice([0.0, rng.uniform(0.0, 0.04)])))
        if rng.random() < 0.4:
            tube = tube.replace(layers=(
                jd.Layer(0.25, jd.NeoHookean(), shear_ratio=float(rng.uniform(0.5, 3.0))),
                jd.Layer(0.75, jd.Gent(97.2), active=True)))
        fluid = jd.Fluid() if rng.random() < 0.3 else None
        if rng.random() < 0.25:
            tube = tube.replace(outer=jd.Fluid(density_ratio=float(rng.uniform(0.5, 1.5)),
                                               speed_ratio=float(rng.uniform(3.0, 8.0))))
        law = [jd.KelvinVoigt(float(rng.uniform(0.005, 0.05))),
               jd.Hysteretic(float(rng.uniform(0.02, 0.2))),
               jd.Prony((float(rng.uniform(0.2, 1.5)),), (float(rng.uniform(0.2, 3.0)),)),
               jd.FractionalKelvinVoigt(float(rng.uniform(0.02, 0.2)), float(rng.uniform(0.1, 1.0)),
                                        float(rng.uniform(0.2, 0.9)))][int(rng.integers(0, 4))]
        alpha = float(rng.uniform(0.2, 2.5))
        found = jd.complex_frequencies(_damped(tube, law), alpha, fluid, n_roots=3, m=m)
        omega = np.asarray(found.omega)
        finite = np.isfinite(omega)
        assert finite.any() and np.all(np.asarray(found.status)[finite] == jd.Status.CONVERGED)
        if finite.all():
            assert int(found.certificate) == jd.SearchStatus.CERTIFIED, case
        top = np.max(omega[finite].real)
        for z in np.asarray(jd.frequencies(tube, alpha, fluid, n_roots=3, m=m)):
            if not np.isfinite(z):
                continue
            z = complex(z)
            for s in np.linspace(0.05, 1.0, 20):
                damped = _damped(tube, _scaled(law, s))
                problem = describe(damped, alpha, fluid, None, m=m, damped=True)
                t, a, f = canonical(damped, alpha, fluid)
                wall = transfer.discretized(t, n_layers=transfer.Layers(48, "magnus6", True))
                for _ in range(40):
                    dz = -1.0 / complex(step(problem.family, problem.order, wall, z, a, f,
                                             float(m))[1])
                    z += dz
                    if abs(dz) < 1e-13 * abs(z):
                        break
                assert abs(dz) < 1e-10 * abs(z), (case, s, z)
            if z.real <= top * (1 + 1e-9):
                assert np.min(np.abs(omega[finite] - z)) < 1e-6 * abs(z), (case, z, omega)


def _dissipation_over_mass(tube, alpha, omega, m, damped):
    """D/M of the elastic mode shape (mode_shape on N = 256, 4001 radii): the first-order shift
    δ(Ω²) = η*·D/M of a small damping η* (docs/theory/real_tubes.md §4: the increment gains
    η*(L + Lᵀ), so the stiffness form gains η* ∫ ½|L + Lᵀ|² dv over the damped layers, and the
    mass form is ∫ ρ_k |u|² dv; the electroelastic problem without damping is self-adjoint). With
    u_r = U cos mθ cos αz, u_θ = V sin mθ cos αz, u_z = W cos mθ sin αz, averaged over θ and z:
    ½|L + Lᵀ|² ∝ 2(U'² + ((U + mV)/r)² + α²W²) + (V' − (V + mU)/r)² + (W' − αU)² + (mW/r + αV)²
    and |u|² ∝ U² + V² + W². Each layer is differentiated and integrated on its own radii (U' jumps
    at an interface between materials), its ends closed by linear extrapolation (second order)."""
    from scipy.integrate import trapezoid

    from jaxdea.params import canonical
    from jaxdea.physics.base_state import interface_radii

    shape = jd.mode_shape(tube, alpha, omega, n_points=4001, n_layers=256, scheme="magnus6", m=m)
    r = np.asarray(shape.r)
    fields = [np.asarray(x) for x in (shape.u, shape.v if m else 0.0 * shape.u, shape.w)]
    layers = tube.layers or (jd.Layer(1.0, jd.Gent(), active=True),)
    edges = (np.asarray(interface_radii(canonical(tube, alpha, None)[0])) if tube.layers
             else np.array([r[0], r[-1]]))

    def integral(x, y, lo, hi):  # ∫_lo^hi y dr from samples inside [lo, hi]
        ends = [y[0] + (y[1] - y[0]) * (lo - x[0]) / (x[1] - x[0]),
                y[-1] + (y[-1] - y[-2]) * (hi - x[-1]) / (x[-1] - x[-2])]
        return (trapezoid(y, x) + 0.5 * (x[0] - lo) * (ends[0] + y[0])
                + 0.5 * (hi - x[-1]) * (y[-1] + ends[1]))

    dissipation = mass = 0.0
    for k, layer in enumerate(layers):
        inside = (r >= edges[k]) & (r <= edges[k + 1])
        x = r[inside]
        u, v, w = (f[inside] for f in fields)
        du, dv, dw = (np.gradient(f, x, edge_order=2) for f in (u, v, w))
        strain = (2.0 * (du**2 + ((u + m * v) / x) ** 2 + (alpha * w) ** 2)
                  + (dv - (v + m * u) / x) ** 2 + (dw - alpha * u) ** 2
                  + (m * w / x + alpha * v) ** 2)
        mass += float(layer.density_ratio) * integral(x, (u**2 + v**2 + w**2) * x,
                                                      edges[k], edges[k + 1])
        if k in damped:
            dissipation += integral(x, strain * x, edges[k], edges[k + 1])
    return dissipation / mass


@pytest.mark.parametrize("case", ["paper's tube, V=0.05, Kelvin-Voigt",
                                  "three Gent layers, the middle one damped",
                                  "sandwich, the stiff liner damped", "hysteretic, m=2"])
def test_small_damping_is_the_first_order_perturbation_of_the_mode_shape(case):
    """Im Ω of a small damping against the first-order perturbation of the elastic mode, an
    independent route through mode_shape (issue "damping"): δ(Ω²) = η*(Ω)·D/M
    (:func:`_dissipation_over_mass`), so Im Ω/η_v → D/(2M) for Kelvin–Voigt (η* = iΩη_v) and
    Im Ω/ζ → D/(2Ω_e M) for hysteretic damping (η* = iζ). Measured: 5e-9 … 5e-8 at η_v, ζ = 1e-5
    (the second-order terms and mode_shape's own error). A damping applied to the wrong layers,
    scaled by a layer's shear ratio or missing a strain component moves the ratio by O(1)."""
    import dataclasses

    alpha, small = 0.445, 1e-5
    paper = jd.Tube(voltage=0.05, lambda_i=0.9, lambda_z=1.2, eta=0.85)
    law, m, damped = jd.KelvinVoigt(small), 0, (0,)
    if case.startswith("three Gent"):
        tube, damped = paper.replace(voltage=0.0, layers=(
            jd.Layer(0.3, jd.Gent(97.2)), jd.Layer(0.4, jd.Gent(97.2), active=True),
            jd.Layer(0.3, jd.Gent(97.2)))), (1,)
    elif case.startswith("sandwich"):
        tube = paper.replace(layers=(
            jd.Layer(0.2, jd.NeoHookean(), shear_ratio=3.0, density_ratio=1.2),
            jd.Layer(0.6, jd.Gent(97.2), active=True),
            jd.Layer(0.2, jd.NeoHookean(), shear_ratio=3.0, density_ratio=0.8)))
    elif case.startswith("hysteretic"):
        tube, law, m = paper, jd.Hysteretic(small), 2
    else:
        tube = paper
    if tube.layers is None:
        damped_tube = tube.replace(damping=law)
    else:
        damped_tube = tube.replace(layers=tuple(
            dataclasses.replace(layer, damping=law) if k in damped else layer
            for k, layer in enumerate(tube.layers)))
    elastic = np.asarray(jd.frequencies(tube, alpha, n_roots=2, m=m))
    damped_roots = np.asarray(jd.complex_frequencies(damped_tube, alpha, n_roots=2, m=m).omega)
    np.testing.assert_allclose(damped_roots.real, elastic, rtol=1e-8)
    for omega_e, omega in zip(elastic, damped_roots, strict=True):
        ratio = _dissipation_over_mass(tube, alpha, omega_e, m, damped) / 2.0
        if isinstance(law, jd.Hysteretic):
            ratio /= omega_e
        assert omega.imag > 0
        assert omega.imag / small == pytest.approx(ratio, rel=1e-6)
