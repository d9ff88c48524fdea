"""The fast order-m propagation (jaxdea.physics.transfer.propagate_balanced_of_w): balanced generators
D⁻¹GD, the Paterson–Stockmeyer powers as polynomials in w, and generators formed once per batch.
Every result is checked against the plain propagation with ``jax.scipy.linalg.expm`` per sublayer
(the reference) and against the full transfer matrix."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from conftest import fd_derivative

import jaxdea as jd
from jaxdea.physics import dispersion as dp
from jaxdea.physics import transfer as tr
from jaxdea.physics.state_matrix import ORDER_M

TUBE = jd.Tube(voltage=0.1, lambda_i=0.9, lambda_z=1.2)
FLUID = jd.Fluid(density_ratio=0.5, speed_ratio=0.6)
W_LINE = np.linspace(-30.0, 400.0, 301)  # Ω² from unstable states to Ω = 20


def _plain_characteristic(wall, w, alpha, fluid, m):
    """(f, log_scale) by the plain propagation: expm of the unbalanced G_k, Gram–Schmidt after
    every sublayer (the order-m path before balancing, written out)."""
    basis = dp.initial_basis_of_w(wall, w, alpha, fluid, 0, m)
    exps = tr.layer_exponentials_of_w(wall, w, alpha, "expm", m, ORDER_M)

    def step(carry, t):
        q, log_scale = carry
        q_new, log_r = tr.orthonormalize(tr.matmul_small(t, q))
        return (q_new, log_scale + log_r), None

    (q, log_scale), _ = jax.lax.scan(step, tr.orthonormalize(basis), exps)
    return jnp.linalg.det(dp.outer_conditions(wall, alpha, m) @ q), log_scale


@pytest.mark.parametrize("scheme, layers, methods", [
    ("midpoint", 30, ("taylor", "adaptive")),
    ("magnus6", 8, ("taylor", "adaptive")),
    pytest.param("midpoint", 10, ("taylor", "adaptive", "expm"), marks=pytest.mark.slow),
    pytest.param("magnus4", 10, ("taylor", "adaptive", "expm"), marks=pytest.mark.slow),
])
def test_fast_order_m_characteristic_equals_the_plain_expm_propagation(scheme, layers, methods):
    """Along Ω² ∈ [−30, 400], fluid-filled, orders 0 (traced), 1, 2, 8 and α̂ = 0.445, 8.9: f and
    log_scale of characteristic_and_scale_of_w (each exponential method) equal the plain
    propagation to 1e-12 of max|f| (measured ≤ 3e-14 of 1, the size of the difference between the
    plain path's own expm and Taylor exponentials), and f·exp(log_scale) is det(Out A S) of the
    full transfer matrix to the same bound."""
    @jax.jit
    def compare(alpha, m):
        wall = tr.discretize(TUBE, tr.laminate(layers, scheme))

        def one(w):
            plain, plain_log = _plain_characteristic(wall, w, alpha, FLUID, m)
            fast = [dp.characteristic_and_scale_of_w(wall, w, alpha, FLUID, 0, method, m)
                    for method in methods]
            ref = dp.reference_determinant_of_w(wall, w, alpha, FLUID, 0, m)
            return plain, plain_log, jnp.stack([f for f, _ in fast]), jnp.stack([s for _, s in fast]), ref

        return jax.vmap(one)(jnp.asarray(W_LINE))

    for alpha in (0.445, 8.9):
        for m in (0.0, 1.0, 2.0, 8.0):
            plain, plain_log, fast, fast_log, ref = (np.asarray(x) for x in compare(alpha, m))
            size = np.max(np.abs(plain))
            assert size > 0.05
            np.testing.assert_allclose(fast, np.broadcast_to(plain[:, None], fast.shape), rtol=0,
                                       atol=1e-12 * size)
            np.testing.assert_allclose(fast_log, np.broadcast_to(plain_log[:, None], fast.shape),
                                       rtol=0, atol=1e-12 * np.max(np.abs(plain_log)))
            np.testing.assert_allclose(fast[:, 0], ref * np.exp(-fast_log[:, 0]), rtol=0,
                                       atol=1e-12 * size)


def test_balancing_removes_the_squarings_of_the_benchmark_batch():
    """N = 30, Ω ≤ 20, orders 1 and 2: ‖G‖∞ reaches 2.2–2.4 (3 squarings), ‖D⁻¹GD‖∞ stays below
    θ = 0.336 (none). c is a power of 2 and the balanced off-diagonal blocks are both below the
    larger plain one."""
    wall = tr.discretize(TUBE, 30)
    w = np.linspace(0.05, 20.0, 400) ** 2
    for m in (1.0, 2.0):
        gens = jax.jit(tr.wall_generators, static_argnums=3)(wall, 0.89, m, ORDER_M)
        d = np.asarray(jax.jit(jax.vmap(tr.balance_diagonal, (None, 0)))(gens, jnp.asarray(w)))
        c = d[:, -1]
        assert np.all(d[:, :4] == 1.0) and np.all(d[:, 4:] == c[:, None])
        assert np.all(np.exp2(np.round(np.log2(c))) == c) and c.min() > 1.0
        g = np.asarray(gens[None, :, 0] + w[:, None, None, None] * gens[None, :, 1])
        balanced = g * (d[:, None, None, :] / d[:, None, :, None])
        plain_norm = np.abs(g).sum(-1).max(-1)
        balanced_norm = np.abs(balanced).sum(-1).max(-1)
        assert plain_norm.max() > 4 * tr.TAYLOR_THETA
        assert balanced_norm.max() < tr.TAYLOR_THETA
        larger = np.maximum(np.abs(g[..., 4:, :4]).sum(-1).max(-1),
                            np.abs(g[..., :4, 4:]).sum(-1).max(-1))
        for block in (balanced[..., 4:, :4], balanced[..., :4, 4:]):
            assert np.all(np.abs(block).sum(-1).max(-1) <= larger)


def test_exponential_of_power_polynomials_equals_expm_with_its_derivatives():
    """exp from (G, …, G⁴) as polynomials in w equals expm of scale ⊙ G(w) to 1e-14 relative, with
    and without squarings (w up to 4e4, s up to 6), and its w-derivative (forward mode, and reverse
    mode through the fixed graph) equals a central difference of expm."""
    wall = tr.discretize(TUBE, 10)
    gens = tr.wall_generators(wall, 0.89, 2.0, ORDER_M)[3]
    polys = tr.generator_powers(gens)
    d = jnp.asarray([1.0] * 4 + [8.0] * 4)
    scale = d[None, :] / d[:, None]

    reference = jax.jit(lambda w: jax.scipy.linalg.expm(scale * tr.generator_of_w(gens, w)))
    fast = jax.jit(lambda w: tr.expm_of_power_polys(polys, w, scale))
    slope = jax.jit(lambda w: jax.jvp(fast, (w,), (1.0,))[1])
    grad = jax.jit(jax.grad(lambda w: fast(w)[2, 5]))
    for w in (-20.0, 3.0, 400.0, 4.0e4):
        ref = np.asarray(reference(w))
        np.testing.assert_allclose(np.asarray(fast(w)), ref, rtol=0, atol=1e-14 * np.abs(ref).max())
        h = 1e-4 * max(abs(w), 1.0)
        fd = (np.asarray(reference(w + h)) - np.asarray(reference(w - h))) / (2.0 * h)
        dw = np.asarray(slope(w))
        np.testing.assert_allclose(dw, fd, rtol=0, atol=1e-7 * np.abs(fd).max())
        assert float(grad(w)) == pytest.approx(float(dw[2, 5]), rel=1e-12, abs=1e-14 * np.abs(dw).max())


def test_order_m_derivatives_match_central_differences():
    """dα̂ and dΩ of the public order-m characteristic (reverse and forward mode through the
    balanced, power-polynomial path) equal central differences to 1e-7."""
    def f(alpha, omega):
        return jd.characteristic(TUBE, omega, alpha, FLUID, n_layers=12, m=2)

    d_alpha, d_omega = jax.grad(f, argnums=(0, 1))(0.9, 3.1)
    fd_alpha = fd_derivative(lambda a: f(a, 3.1), 0.9, 1e-5)
    fd_omega = fd_derivative(lambda o: f(0.9, o), 3.1, 1e-5)
    assert float(d_alpha) == pytest.approx(float(fd_alpha), rel=1e-7)
    assert float(d_omega) == pytest.approx(float(fd_omega), rel=1e-7)
    slope = jax.jvp(lambda o: f(0.9, o), (3.1,), (1.0,))[1]
    assert float(slope) == pytest.approx(float(d_omega), rel=1e-12)


def _scans(jaxpr):
    """Every ``scan`` equation of a closed jaxpr, nested ones included."""
    for eqn in jaxpr.eqns:
        if eqn.primitive.name == "scan":
            yield eqn
        for param in eqn.params.values():
            for sub in param if isinstance(param, (list, tuple)) else (param,):
                inner = getattr(sub, "jaxpr", None)
                if inner is not None:
                    yield from _scans(inner if hasattr(inner, "eqns") else sub.jaxpr)


@pytest.mark.parametrize("traced_m", [False, True])
def test_a_batch_over_omega_forms_the_sublayer_generators_once(traced_m):
    """Under vmap over Ω (m fixed, concrete or traced), the scan over the N = 30 sublayers reads
    generators without the batch axis: they are formed once per batch, not once per Ω."""
    batch = 7

    def one(w, m):
        return dp._characteristic_m(TUBE, w, 0.89, None, m, 30, 0, ORDER_M)

    ws = jnp.linspace(0.5, 40.0, batch)
    if traced_m:
        jaxpr = jax.make_jaxpr(lambda w, m: jax.vmap(one, (0, None))(w, m))(ws, 2.0)
    else:
        jaxpr = jax.make_jaxpr(jax.vmap(lambda w: one(w, 2.0)))(ws)
    layer_scans = [e for e in _scans(jaxpr.jaxpr) if e.params["length"] == 30]
    assert layer_scans
    for eqn in layer_scans:
        xs = eqn.invars[eqn.params["num_consts"] + eqn.params["num_carry"]:]
        assert xs and all(batch not in v.aval.shape for v in xs), [v.aval.shape for v in xs]
