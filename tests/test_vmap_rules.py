"""``jax.vmap`` of the solvers (jaxdea.solve.roots.one_point_at_a_time): on the CPU a batch over α̂ alone
is continued along α̂ (jaxdea.solve.curves.frequencies_along, critical_voltages_along: continuation where
the batch is ordered, the scan of each point where not), any other batch is mapped one point after
another; the values equal the points solved alone (to rounding, the standard of
tests/test_determinism.py), statuses equal, and implicit derivatives pass through the vmapped call
(forward and reverse mode), also over tube parameters, some arguments batched only, and nested
vmaps. The default run checks the frequencies and the critical voltages' values; the derivatives
of ``frequency`` and ``critical_voltage`` and forward mode are marked slow."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from conftest import fd_derivative

import jaxdea as jd
from jaxdea.numerics.scalar import Status
from jaxdea.physics.transfer import TRACED_LAYERS, Layers
from jaxdea.solve import roots

TUBE = jd.Tube(voltage=0.1, lambda_i=0.9, lambda_z=1.2)
ALPHA = np.array([0.2, 0.7, 1.5, 3.0])
N = 30  # the paper's laminate, as the other tests (one compiled program each)
RTOL = 1e-13  # alone against inside a batch: equal to rounding (tests/test_determinism.py)


def _roots(tube, alpha, **kwargs):
    return jd.solve_frequencies(tube, alpha, n_roots=2, n_layers=N, **kwargs)


def _assert_roots_equal(batched, alone):
    np.testing.assert_array_equal(np.asarray(batched.status), np.asarray(alone.status))
    np.testing.assert_allclose(np.asarray(batched.omega), np.asarray(alone.omega), rtol=RTOL, atol=0)


def _stacked(results):
    return jax.tree_util.tree_map(lambda *xs: np.stack([np.asarray(x) for x in xs]), *results)


def test_vmapped_frequencies_equal_the_points_alone():
    """Over α̂, with an invalid point (NaN α̂) in the batch: its NaN and status stay its own."""
    alpha = np.append(ALPHA, np.nan)
    batched = jax.jit(jax.vmap(lambda a: _roots(TUBE, a)))(jnp.asarray(alpha))
    alone = _stacked([_roots(TUBE, float(a)) for a in ALPHA])  # (a NaN α̂ alone raises)
    assert np.all(np.asarray(batched.status[:-1]) == Status.CONVERGED)
    assert np.all(np.asarray(batched.status[-1]) == Status.INVALID)
    assert np.all(np.isnan(np.asarray(batched.omega[-1])))
    _assert_roots_equal(jax.tree_util.tree_map(lambda x: x[:-1], batched), alone)


def test_a_batch_over_alpha_alone_is_continued_any_other_is_mapped(monkeypatch):
    """A batch over α̂ alone goes to the continuation engine (with the 4×4 propagation for a
    concrete V̂ = 0, the 6×6 one otherwise); with the tube batched too, the vmapped scan is a loop
    over the points (a scan of the batch's length) around the one-point solver, not a vectorised
    copy of its while loops. Traced only."""
    calls = []
    engine = roots.BATCH_ENGINES["frequencies"]
    monkeypatch.setitem(roots.BATCH_ENGINES, "frequencies",
                        lambda *args, **static: calls.append(static) or engine(*args, **static))
    alpha = jnp.asarray(ALPHA)
    for tube, decoupled in ((TUBE, False), (TUBE.replace(voltage=0.0), True)):
        jax.make_jaxpr(jax.vmap(lambda a, t=tube: jd.frequencies(t, a, n_roots=2, n_layers=N)))(alpha)
        assert calls[-1]["decoupled"] is decoupled
    assert len(calls) == 2
    jaxpr = jax.make_jaxpr(jax.vmap(lambda li, a: jd.frequencies(TUBE.replace(lambda_i=li), a, n_roots=2,
                                                                 n_layers=N)))(0.9 + 0.0 * alpha, alpha)
    assert len(calls) == 2
    scans = [e for e in jaxpr.jaxpr.eqns if e.primitive.name == "scan"]
    assert [e.params["length"] for e in scans] == [len(ALPHA)]
    assert all(v.aval.shape[:1] == (len(ALPHA),) for v in scans[0].outvars)


def test_a_batch_of_frequency_over_alpha_and_guess_takes_the_curves_lanes(monkeypatch):
    """frequency: a batch over α̂, the guess or both (tube and fluid shared) goes to
    jaxdea.solve.curves.frequency_along; with the tube batched too it is vectorised as before (a while
    loop over the batch, no scan of its length). Traced only."""
    calls = []
    engine = roots.BATCH_ENGINES["frequency"]
    monkeypatch.setitem(roots.BATCH_ENGINES, "frequency",
                        lambda *args, **static: calls.append(static) or engine(*args, **static))
    alpha, guess = jnp.asarray(ALPHA), jnp.full(len(ALPHA), 0.6)
    for args in ((alpha, guess), (0.7, guess), (alpha, 0.6)):
        axes = tuple(None if np.ndim(x) == 0 else 0 for x in args)
        jax.make_jaxpr(jax.vmap(lambda a, g: jd.frequency(TUBE, a, g, n_layers=N), axes))(*args)
        assert calls[-1]["decoupled"] is False
    jax.make_jaxpr(jax.vmap(lambda a, g: jd.frequency(TUBE.replace(voltage=0.0), a, g)))(alpha, guess)
    assert calls[-1]["decoupled"] is True and len(calls) == 4
    jaxpr = jax.make_jaxpr(jax.vmap(lambda li, a, g: jd.frequency(TUBE.replace(lambda_i=li), a, g,
                                                                  n_layers=N)))(0.9 + 0.0 * alpha, alpha, guess)
    assert len(calls) == 4
    programs = [e for e in jaxpr.jaxpr.eqns if e.primitive.name in ("jit", "scan")]
    assert [e.params.get("name") for e in programs] == ["_solve_frequency"]
    assert [v.aval.shape for v in programs[0].outvars] == [(len(ALPHA),)] * 2
    assert "while" in [e.primitive.name for e in programs[0].params["jaxpr"].eqns]


def test_continued_batches_equal_the_points_alone():
    """Over α̂ alone, ordered upwards, downwards and shuffled (every point scanned), with an α̂
    below ALPHA_MIN (INVALID) and a search range omega_max = 2.5 that holds 2, 1 or no roots at
    the points: the roots of the points alone inside (0, 2.5], NaN-padded with status NO_ROOT
    (the second root, continued from 2.26 at α̂ = 1 to 2.53 at α̂ = 1.2, leaves the range there:
    that step is scanned)."""
    alpha, limit = np.array([1e-13, 0.2, 0.4, 0.6, 0.8, 1.0, 1.2, 1.4, 3.0, 5.0]), 2.5
    batched = jax.jit(jax.vmap(lambda a, w: _roots(TUBE, a, omega_max=w), in_axes=(0, None)))
    alone = _stacked([_roots(TUBE, float(a)) for a in alpha[1:]])
    inside = np.asarray(alone.omega) <= limit
    assert inside.sum(axis=1).tolist() == [2, 2, 2, 2, 2, 1, 1, 1, 0]
    expected = jd.Roots(np.vstack([np.full(2, np.nan), np.where(inside, alone.omega, np.nan)]),
                        np.vstack([np.full(2, Status.INVALID),
                                   np.where(inside, alone.status, Status.NO_ROOT)]))
    for order in (np.arange(10), np.arange(10)[::-1], np.array([3, 8, 0, 5, 9, 1, 7, 4, 2, 6])):
        got = batched(jnp.asarray(alpha[order]), limit)
        _assert_roots_equal(got, jax.tree_util.tree_map(lambda x, o=order: x[o], expected))


def test_vmap_over_tube_parameters_with_some_arguments_batched():
    """in_axes over the tube's voltage and λ_i only (α̂ held), and over α̂ with a batched λ_i."""
    voltages, stretches = jnp.array([0.0, 0.05, 0.12]), jnp.array([0.9, 0.95, 1.05])
    axes = jd.Tube(voltage=0, lambda_i=0, lambda_z=None, eta=None, gent=None, length_ratio=None)
    tubes = TUBE.replace(voltage=voltages, lambda_i=stretches)
    batched = jax.vmap(lambda t: _roots(t, 0.7), in_axes=(axes,))(tubes)
    alone = _stacked([_roots(TUBE.replace(voltage=float(v), lambda_i=float(li)), 0.7)
                      for v, li in zip(voltages, stretches, strict=True)])
    _assert_roots_equal(batched, alone)
    both = jax.vmap(lambda li, a: _roots(TUBE.replace(lambda_i=li), a))(stretches, jnp.asarray(ALPHA[:3]))
    alone = _stacked([_roots(TUBE.replace(lambda_i=float(li)), float(a))
                      for li, a in zip(stretches, ALPHA[:3], strict=True)])
    _assert_roots_equal(both, alone)


def test_eager_vmap_compiles_once_and_equals_the_points_alone(caplog):
    """``jax.vmap`` outside ``jax.jit`` over the tube (the mapped path): the second and third calls
    compile nothing. Its ``lax.map`` was traced anew at every call, so every call compiled a scan
    and kept the executable: after ~50 calls LLVM ran out of memory maps and aborted the process
    (found by the slow fuzz). Each point equals the point alone bit for bit (its own program)."""
    stretches = jnp.array([0.9, 0.95, 1.05])
    solve = jax.vmap(lambda li, v: _roots(TUBE.replace(lambda_i=li, voltage=v), 0.7))
    first = solve(stretches, jnp.full(3, 0.1))
    with caplog.at_level("WARNING"), jax.log_compiles(True):
        again = [solve(stretches, jnp.full(3, v)) for v in (0.1, 0.05)]
    compiled = [r.getMessage() for r in caplog.records if "Compiling" in r.getMessage()]
    assert compiled == [], compiled
    np.testing.assert_array_equal(np.asarray(again[0].omega), np.asarray(first.omega))
    alone = _stacked([_roots(TUBE.replace(lambda_i=li, voltage=0.05), 0.7) for li in (0.9, 0.95, 1.05)])
    np.testing.assert_array_equal(np.asarray(again[1].omega), np.asarray(alone.omega))
    np.testing.assert_array_equal(np.asarray(again[1].status), np.asarray(alone.status))


def test_nested_vmap():
    """vmap over V̂ of vmap over α̂: a (3, 4) grid, each point as alone."""
    voltages = jnp.array([0.0, 0.05, 0.12])
    grid = jax.jit(jax.vmap(jax.vmap(lambda v, a: _roots(TUBE.replace(voltage=v), a), (None, 0)),
                            (0, None)))(voltages, jnp.asarray(ALPHA))
    alone = _stacked([_stacked([_roots(TUBE.replace(voltage=float(v)), float(a)) for a in ALPHA])
                      for v in voltages])
    assert grid.omega.shape == (3, len(ALPHA), 2)
    _assert_roots_equal(grid, alone)


def test_gradient_through_vmapped_frequencies():
    """jax.grad of a sum over a vmapped frequencies call with respect to V̂ and λ_i: the sum of
    the points' gradients and central finite differences."""
    alpha = jnp.asarray(ALPHA[:3])

    @jax.jit
    def total(voltage, lambda_i):
        tube = TUBE.replace(voltage=voltage, lambda_i=lambda_i)
        return jnp.sum(jax.vmap(lambda a: jd.frequencies(tube, a, n_roots=2, n_layers=N))(alpha))

    def total_alone(voltage, lambda_i):
        tube = TUBE.replace(voltage=voltage, lambda_i=lambda_i)
        return sum(jnp.sum(jd.frequencies(tube, float(a), n_roots=2, n_layers=N)) for a in ALPHA[:3])

    grad = jax.jit(jax.grad(total, argnums=(0, 1)))(0.1, 0.9)
    grad_alone = jax.grad(total_alone, argnums=(0, 1))(0.1, 0.9)
    np.testing.assert_allclose(np.asarray(grad), np.asarray(grad_alone), rtol=1e-12)
    assert float(grad[0]) == pytest.approx(fd_derivative(lambda v: total(v, 0.9), 0.1), rel=1e-6)
    assert float(grad[1]) == pytest.approx(fd_derivative(lambda li: total(0.1, li), 0.9), rel=1e-6)


@pytest.mark.slow
def test_forward_mode_and_vmap_of_the_gradient():
    """jacfwd through the vmapped call (against finite differences), and vmap over V̂ of
    jax.grad of a root (against the gradients of the points alone)."""
    alpha = jnp.asarray(ALPHA[:3])

    def roots_of(lambda_i):
        tube = TUBE.replace(lambda_i=lambda_i)
        return jax.vmap(lambda a: jd.frequencies(tube, a, n_roots=2, n_layers=N))(alpha)

    slope = jax.jit(jax.jacfwd(roots_of))(0.9)
    total = jax.jit(lambda li: jnp.sum(roots_of(li)))
    assert float(jnp.sum(slope)) == pytest.approx(fd_derivative(total, 0.9), rel=1e-6)

    def lowest(v):
        return jd.frequencies(TUBE.replace(voltage=v), 0.7, n_roots=2, n_layers=N)[0]

    voltages = jnp.array([0.0, 0.05, 0.12])
    np.testing.assert_allclose(jax.jit(jax.vmap(jax.grad(lowest)))(voltages),
                               [float(jax.grad(lowest)(float(v))) for v in voltages], rtol=1e-12)


@pytest.mark.slow
def test_vmapped_frequency_over_alpha_equals_the_points_alone():
    """Over α̂ and the guess (the curves' lanes): unordered, with an invalid α̂ and a bad guess in
    the batch (their NaN and INVALID their own), at V̂ = 0.1 (6×6) and V̂ = 0 (4×4), and over the
    guess alone with a traced tube."""
    alpha = np.array([1.5, 0.2, 3.0, 0.7, 1e-13, 0.7])
    for tube in (TUBE, TUBE.replace(voltage=0.0)):
        lowest = np.array([float(_roots(tube, float(a)).omega[0]) for a in ALPHA])
        guess = np.concatenate([lowest[[2, 0, 3, 1]] * np.array([1.02, 0.98, 1.01, 1.0]), [0.5, -1.0]])
        got = jax.jit(jax.vmap(lambda a, g, t=tube: jd.solve_frequency(t, a, g, n_layers=N)))(
            jnp.asarray(alpha), jnp.asarray(guess))
        alone = _stacked([jd.solve_frequency(tube, float(a), float(g), n_layers=N)
                          for a, g in zip(alpha[:4], guess[:4], strict=True)])
        _assert_roots_equal(jax.tree_util.tree_map(lambda x: x[:4], got), alone)
        np.testing.assert_allclose(np.asarray(got.omega[:4]), lowest[[2, 0, 3, 1]], rtol=RTOL)
        assert np.all(np.asarray(got.status[4:]) == Status.INVALID)
        assert np.all(np.isnan(np.asarray(got.omega[4:])))


@pytest.mark.slow
def test_vmapped_frequency_equals_the_points_alone_and_differentiates():
    """Newton from a guess per point (vectorised: Newton's lanes are alike, so the vectorised
    batch is the fastest path); values, statuses and the gradient through the batch."""
    guesses = np.asarray(jd.frequencies(TUBE, 0.7, n_roots=1, n_layers=N))[0] * np.array([1.0, 1.02, 0.97])

    @jax.jit
    def batched(voltage):
        tube = TUBE.replace(voltage=voltage)
        return jax.vmap(lambda g: jd.solve_frequency(tube, 0.7, g, n_layers=N))(jnp.asarray(guesses))

    roots = batched(0.1)
    alone = _stacked([jd.solve_frequency(TUBE, 0.7, float(g), n_layers=N) for g in guesses])
    _assert_roots_equal(roots, alone)
    total = lambda v: jnp.sum(batched(v).omega)  # noqa: E731
    assert float(jax.grad(total)(0.1)) == pytest.approx(fd_derivative(total, 0.1), rel=1e-6)


def test_vmapped_critical_voltages_equal_the_points_alone():
    """Over α̂ and a batched λ_i (under jit: mapped), and over α̂ alone, ordered and shuffled
    (continued along α̂ where ordered)."""
    stretches = jnp.array([0.9, 0.95, 1.05])
    batched = jax.jit(jax.vmap(lambda li, a: jd.solve_critical_voltage(
        TUBE.replace(lambda_i=li), a, n_layers=N)))(stretches, jnp.asarray(ALPHA[:3]))
    alone = _stacked([jd.solve_critical_voltage(TUBE.replace(lambda_i=float(li)), float(a), n_layers=N)
                      for li, a in zip(stretches, ALPHA[:3], strict=True)])
    assert np.all(np.asarray(batched.status) == Status.CONVERGED)
    _assert_roots_equal(batched, alone)
    over_alpha = jax.jit(jax.vmap(lambda a: jd.solve_critical_voltage(TUBE, a, n_layers=N)))
    alone = _stacked([jd.solve_critical_voltage(TUBE, float(a), n_layers=N) for a in ALPHA])
    for order in (np.arange(4), np.array([2, 0, 3, 1])):
        _assert_roots_equal(over_alpha(jnp.asarray(ALPHA[order])),
                            jax.tree_util.tree_map(lambda x, o=order: x[o], alone))


@pytest.mark.slow
def test_vmapped_critical_voltage_equals_the_points_alone_and_differentiates():
    """Over α̂ (mapped as the frequencies are): values, statuses and the gradient with respect to
    λ_i through the batch, against the points alone and finite differences."""
    alpha = jnp.asarray(ALPHA[:3])

    @jax.jit
    def batched(lambda_i):
        tube = TUBE.replace(lambda_i=lambda_i)
        return jax.vmap(lambda a: jd.solve_critical_voltage(tube, a, n_layers=N))(alpha)

    roots = batched(0.9)
    alone = _stacked([jd.solve_critical_voltage(TUBE, float(a), n_layers=N) for a in ALPHA[:3]])
    assert np.all(np.asarray(roots.status) == Status.CONVERGED)
    _assert_roots_equal(roots, alone)
    total = lambda li: jnp.sum(batched(li).omega)  # noqa: E731
    grad = float(jax.grad(total)(0.9))
    alone_grad = sum(float(jax.grad(lambda li, a=a: jd.critical_voltage(TUBE.replace(lambda_i=li), a,
                                                                        n_layers=N))(0.9))
                     for a in ALPHA[:3])
    assert grad == pytest.approx(alone_grad, rel=1e-12)
    assert grad == pytest.approx(fd_derivative(total, 0.9), rel=1e-6)


@pytest.mark.slow
def test_the_vmap_idiom_gives_the_curves_roots_on_the_peers_points():
    """``jax.jit(jax.vmap(...))`` over the 200 ordered α̂ of the GEWtool-shaped curve
    (benchmarks/vmap_idiom.py, default discretisation): ``frequencies`` equal to
    ``dispersion_curve``'s roots, ``frequency`` from 1.02× the lowest root equal to the curve's
    lowest, ``critical_voltage`` equal to the points alone (every 20th), all to 1e-13 relative
    (the solvers' tolerance is 1e-15); and reversed, the same roots. The curve on the traced
    default's wall, N = 16 (a concrete default curve starts lower, tests/test_accuracy_default.py)."""
    tube = jd.Tube(voltage=0.0, lambda_i=1.0, lambda_z=1.0, eta=0.85)
    alpha = np.linspace(0.01, 5.0, 200)
    curve = jd.dispersion_curve(tube, alpha, n_roots=4, n_layers=Layers(TRACED_LAYERS, "magnus6", True))
    assert np.all(np.asarray(curve.status) == Status.CONVERGED)
    omega = np.asarray(curve.omega)
    over = jax.jit(jax.vmap(lambda a: jd.solve_frequencies(tube, a, n_roots=4)))
    for order in (np.arange(200), np.arange(200)[::-1]):
        got = over(jnp.asarray(alpha[order]))
        assert np.all(np.asarray(got.status) == Status.CONVERGED)
        np.testing.assert_allclose(np.asarray(got.omega), omega[order], rtol=1e-13, atol=0)
    newton = jax.jit(jax.vmap(lambda a, g: jd.solve_frequency(tube, a, g)))(
        jnp.asarray(alpha), jnp.asarray(1.02 * omega[:, 0]))
    assert np.all(np.asarray(newton.status) == Status.CONVERGED)
    np.testing.assert_allclose(np.asarray(newton.omega), omega[:, 0], rtol=1e-13, atol=0)
    critical = jax.jit(jax.vmap(lambda a: jd.solve_critical_voltage(tube, a)))(jnp.asarray(alpha))
    alone = _stacked([jd.solve_critical_voltage(tube, float(a)) for a in alpha[::20]])
    _assert_roots_equal(jax.tree_util.tree_map(lambda x: x[::20], critical), alone)
