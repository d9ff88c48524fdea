"""Circumferential order m in the entry points built on the core: mode shapes, fluid pressure,
sweeps and the sweep config, root counting, error estimates, dispersion curves, branch tracing and
the sweep plot (theory_m.md; API.md "Circumferential order m").

Compilation dominates: every test at m = 2 shares one n_layers (N) and the default n_roots, so the
order-m programs (one for every m >= 1) are compiled once per worker."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
import scipy.special as sp

import jaxdea as jd
from jaxdea.apps.cli import LABELS, SYMBOLS, plot_sweep
from jaxdea.io.config import parse_config
from jaxdea.params import canonical
from jaxdea.physics.state_matrix import state_matrix_m
from jaxdea.physics.transfer import discretize
from jaxdea.solve.accuracy import frequencies_with_error
from jaxdea.solve.counting import CountStatus, count_roots
from jaxdea.solve.curves import dispersion_curve
from jaxdea.solve.modes import fluid_pressure, mode_shape
from jaxdea.solve.trace import BranchEnd, trace_branch
from jaxdea.studies.sweeps import sweep

jax.config.update("jax_enable_x64", True)

N = 12
ALPHA = 0.445
TUBE = jd.Tube(voltage=0.1, lambda_i=0.9, lambda_z=1.2, eta=0.85)
TUBE2 = jd.Tube(voltage=0.02, lambda_i=0.95, lambda_z=1.2, eta=0.85)  # the solvers built on the core
ALPHAS2 = np.linspace(0.445, 1.0, 6)


@pytest.fixture(scope="module")
def roots_m2():
    """Ω of order 2 of TUBE2 at every α̂ of ALPHAS2, by frequencies (one compiled program)."""
    return np.array([np.asarray(jd.frequencies(TUBE2, a, m=2, n_layers=N)) for a in ALPHAS2])


def _plain_interfaces(tube, omega, alpha, m, y0, n_layers=N):
    """Y at the interfaces from Y(r̂_i) by the plain product of expm(h M_m(r̂_k)), the full 8×8 matrix
    of theory_m.md §3 (no torsion switch, no re-orthonormalisation, no Taylor exponential)."""
    wall = discretize(canonical(tube), n_layers)
    ys = [y0]
    for k in range(n_layers):
        coef = jax.tree_util.tree_map(lambda x: x[k], wall.coef)  # noqa: B023
        mk = state_matrix_m(coef, wall.radii[k], omega**2, alpha, float(m))
        ys.append(jax.scipy.linalg.expm(wall.step * mk) @ ys[-1])
    return np.array(ys).T, wall


def _check_faces(r, fields, wall, alpha, m, p_fluid=0.0, tol=1e-9):
    u, v, w, phi, t, q, s, d = fields
    big = np.max(np.abs(fields))
    ri, p = wall.r_inner, wall.pressure_inner
    np.testing.assert_allclose(r[0], ri, rtol=1e-14)
    # outer face (P̂_o = 0): Φ = T = Q = S = 0
    assert np.max(np.abs([phi[-1], t[-1], q[-1], s[-1]])) < tol * big
    # inner face: follower pressure P̂_i (and the fluid's p* in T)
    np.testing.assert_allclose(phi[0], 0.0, atol=tol * big)
    np.testing.assert_allclose(t[0], -p * (u[0] + m * v[0]) / ri - alpha * p * w[0] - p_fluid, atol=tol * big)
    np.testing.assert_allclose(q[0], -p * (m * u[0] + v[0]) / ri, atol=tol * big)
    np.testing.assert_allclose(s[0], -alpha * p * u[0], atol=tol * big)


def test_mode_shape_order_m_boundary_conditions_and_plain_transfer():
    omega = float(jd.frequencies(TUBE, ALPHA, m=2, n_layers=N)[0])
    r, fields = mode_shape(TUBE, ALPHA, omega, n_points=N + 1, n_layers=N, m=2)
    fields = np.asarray(fields)
    assert fields.shape == (8, N + 1)
    assert np.max(np.abs(fields[:3])) == pytest.approx(1.0, abs=1e-14)
    assert abs(fields[1]).max() > 1e-2  # v̄ really present (m = 2 couples u_θ)
    ys, wall = _plain_interfaces(TUBE, omega, ALPHA, 2, jnp.asarray(fields[:, 0]))
    _check_faces(np.asarray(r), fields, wall, ALPHA, 2)
    # n_points = N + 1: the samples are the interfaces, so the fields are the plain transfer of Y(r̂_i)
    np.testing.assert_allclose(fields, ys, atol=1e-11)
    # off the root (1 %) there is no mode: refused, NaN when traced
    with pytest.raises(ValueError, match="not a root"):
        mode_shape(TUBE, ALPHA, 1.01 * omega, n_points=N + 1, n_layers=N, m=2)
    _, off = jax.jit(lambda w: mode_shape(TUBE, ALPHA, w, n_points=N + 1, n_layers=N, m=2))(
        1.01 * omega)
    assert np.all(np.isnan(np.asarray(off)))


def test_mode_shape_torsional_rigid_twist_and_stretched_tube():
    # unstretched linear tube: Ω = α̂ is an exact torsional root with Q̄ ≡ 0 and v̄ ∝ r̂ (theory_m.md §8.5)
    linear = jd.Tube(voltage=0.0, lambda_i=1.0, lambda_z=1.0, eta=0.85)
    r, f = mode_shape(linear, ALPHA, ALPHA, n_points=N + 1, n_layers=N, torsional=True)
    r, f = np.asarray(r), np.asarray(f)
    assert f.shape == (8, N + 1)
    np.testing.assert_array_equal(f[[0, 2, 3, 4, 6, 7]], 0.0)
    np.testing.assert_allclose(f[5], 0.0, atol=1e-14)
    np.testing.assert_allclose(f[1], r / r[-1], atol=1e-4)  # midpoint laminate, O(h²)
    # stretched, voltage-loaded tube: the torsional root, its faces and the plain 8×8 transfer at m = 0
    omega = float(jd.frequencies(TUBE, ALPHA, n_layers=N, torsional=True)[0])
    r, f = mode_shape(TUBE, ALPHA, omega, n_points=N + 1, n_layers=N, torsional=True)
    f = np.asarray(f)
    ys, wall = _plain_interfaces(TUBE, omega, ALPHA, 0, jnp.asarray(f[:, 0]))
    _check_faces(np.asarray(r), f, wall, ALPHA, 0)
    np.testing.assert_allclose(f, ys, atol=1e-11)


def test_fluid_pressure_order_m_is_bessel_profile_and_loads_inner_face():
    fluid = jd.Fluid()  # acoustic
    m, n_points = 2, N + 1
    # a root of the filled tube by Newton (a far cheaper program than the scan of frequencies); the
    # outer-face conditions checked below hold only at a root
    # (at this voltage the lowest order-2 mode is unstable: the first positive root is ≈ 0.965)
    omega = float(jd.frequency(TUBE, ALPHA, 1.0, fluid, m=m, n_layers=N))
    at = lambda w: abs(float(jd.characteristic(TUBE, w, ALPHA, fluid, n_layers=N, m=m)))  # noqa: E731
    assert at(omega) < 1e-10 * at(1.01 * omega)  # a converged root, not just a Newton end point
    r, fields = mode_shape(TUBE, ALPHA, omega, fluid, n_points=n_points, n_layers=N, m=m)
    r_f, p = fluid_pressure(TUBE, ALPHA, omega, fluid, n_points=n_points, n_layers=N, m=m)
    fields, r_f, p = np.asarray(fields), np.asarray(r_f), np.asarray(p)
    wall = discretize(canonical(TUBE), N)
    ri, rho, cf = float(wall.r_inner), float(fluid.density_ratio), float(fluid.speed_ratio)
    chi2 = (omega / cf) ** 2 - ALPHA**2
    if chi2 > 0:
        chi = np.sqrt(chi2)
        shape, slope = sp.jv(m, chi * r_f), chi * sp.jvp(m, chi * ri)
    else:
        chi = np.sqrt(-chi2)
        shape, slope = sp.iv(m, chi * r_f), chi * sp.ivp(m, chi * ri)
    np.testing.assert_allclose(p, p[-1] * shape / shape[-1], rtol=1e-10, atol=1e-13 * abs(p[-1]))
    assert p[0] == 0.0  # order m ≥ 1: a node on the axis
    # dp̂*/dr̂ = Ω²ρ̂_f ū at the wall, and p̂*(r̂_i) loads T̄(r̂_i)
    np.testing.assert_allclose(p[-1] * slope / shape[-1], omega**2 * rho * fields[0, 0], rtol=1e-9)
    _check_faces(np.asarray(r), fields, wall, ALPHA, m, p_fluid=p[-1])


@pytest.mark.parametrize("kwargs, name", [
    (dict(m=-1), "m"), (dict(m=1.5), "m"), (dict(m="2"), "m"), (dict(m=True), "m"),
    (dict(m=1, torsional=True), "torsional"),
])
def test_mode_shape_rejects_bad_order(kwargs, name):
    with pytest.raises(ValueError, match=name):
        mode_shape(TUBE, ALPHA, 1.0, n_layers=N, **kwargs)


def test_order_m_with_paper_coupling_is_rejected():
    paper = jd.Fluid(coupling="paper", bessel_order=0)
    with pytest.raises(ValueError, match="m"):
        mode_shape(TUBE, ALPHA, 1.0, paper, n_layers=N, m=1)
    with pytest.raises(ValueError, match="m"):
        fluid_pressure(TUBE, ALPHA, 1.0, jd.Fluid(), n_layers=N, m=-2)
    with pytest.raises(ValueError, match="m"):
        sweep(TUBE, paper, alpha=ALPHA, m=np.array([0, 1]), n_layers=N, progress=False)


def test_sweep_over_m_matches_frequencies():
    tube = jd.Tube(voltage=0.05, lambda_i=0.9, lambda_z=1.2, eta=0.85)
    alphas = np.array([0.445, 1.0])
    res = sweep(tube, m=np.array([0, 1, 2]), alpha=alphas, n_layers=N, progress=False)
    assert list(res.axes) == ["m", "alpha"] and res.omega.shape == (3, 2, 3)
    assert np.all(res.status == jd.Status.CONVERGED)
    for i, m in enumerate([0, 1, 2]):
        for j, a in enumerate(alphas):
            ref = np.asarray(jd.frequencies(tube, a, m=m, n_layers=N))
            np.testing.assert_allclose(res.omega[i, j], ref, rtol=1e-12)
    # a fixed order as a keyword (not an axis), and its settings
    fixed = sweep(tube, m=2, alpha=alphas, n_layers=N, progress=False)
    assert list(fixed.axes) == ["alpha"] and fixed.settings["m"] == 2
    np.testing.assert_allclose(fixed.omega, res.omega[2], rtol=1e-12)
    _check_plots_with_m_axis(res)


def _check_plots_with_m_axis(res):
    """plot_sweep with m as the x axis (integer ticks, its label) and as the legend's axis."""
    import tempfile
    from pathlib import Path

    with tempfile.TemporaryDirectory() as tmp:
        fig = plot_sweep(res, "m", Path(tmp) / "m.png")
        ax = fig.axes[0]
        assert ax.get_xlabel() == LABELS["m"]
        ticks = [t for t in ax.get_xticks() if ax.get_xlim()[0] <= t <= ax.get_xlim()[1]]
        assert len(ticks) >= 2 and all(t == round(t) for t in ticks)  # integer orders only
        fig = plot_sweep(res, "alpha", Path(tmp) / "alpha.png")
        labels = [t.get_text() for t in fig.axes[0].get_legend().get_texts()]
        assert f"{SYMBOLS['m']} = 2" in labels
        assert (Path(tmp) / "m.png").stat().st_size > 0 and (Path(tmp) / "alpha.png").stat().st_size > 0


@pytest.mark.parametrize("m", [np.array([0, -1]), np.array([0.5]), np.array([[1, 2]]), -1, 1.5])
def test_sweep_rejects_bad_m(m):
    with pytest.raises(ValueError, match="m"):
        sweep(TUBE, alpha=ALPHA, m=m, n_layers=N, progress=False)
    with pytest.raises(ValueError, match="torsional"):
        sweep(TUBE, alpha=ALPHA, m=1, torsional=True, n_layers=N, progress=False)


@pytest.mark.slow  # compiles the sweep with the growth-rate scan: minutes on 2 cores
def test_sweep_growth_rates_mark_the_unstable_voltages():
    """n_growth: the growth rates of a voltage sweep at m = 2 equal growth_rates point by point and
    are finite exactly above the order's critical voltage; m = 0 points stay stable below theirs."""
    tube = jd.Tube(lambda_i=0.9, lambda_z=1.2, eta=0.85)
    v_cr = float(jd.critical_voltage(tube, ALPHA, m=2, n_layers=N))  # ≈ 0.03 on the paper's tube
    voltages = np.array([0.5, 0.9, 1.1, 2.0]) * v_cr
    res = sweep(tube, m=np.array([0, 2]), voltage=voltages, alpha=ALPHA, n_layers=N, n_growth=2,
                progress=False)
    assert res.growth_rate.shape == (2, 4, 1, 2)
    np.testing.assert_array_equal(res.unstable[1, :, 0], [False, False, True, True])
    assert not np.any(res.unstable[0])  # m = 0 buckles only at ≈ 0.29
    for i, v in enumerate(voltages):
        ref = np.asarray(jd.growth_rates(tube.replace(voltage=v), ALPHA, m=2, n_roots=2, n_layers=N))
        np.testing.assert_allclose(res.growth_rate[1, i, 0], ref, rtol=1e-12)
    assert res.settings["n_growth"] == 2
    cols = res.columns()
    np.testing.assert_array_equal(cols["growth_rate_1"], res.growth_rate[..., 0].ravel())
    # without growth rates: the m = 0 program as before, and no growth columns
    plain = sweep(tube, voltage=voltages, alpha=ALPHA, n_layers=N, progress=False)
    assert plain.growth_rate is None and plain.unstable is None
    np.testing.assert_allclose(plain.omega[:, 0], res.omega[0, :, 0], rtol=1e-12)
    with pytest.raises(ValueError, match="n_growth"):
        sweep(tube, alpha=ALPHA, n_growth=-1, progress=False)
    cfg = parse_config({"axes": {"alpha": 0.445}, "solver": {"n_growth": 2}})
    assert cfg.sweep_arguments()["n_growth"] == 2
    with pytest.raises(ValueError, match="solver.n_growth"):
        parse_config({"axes": {"alpha": 0.445}, "solver": {"n_growth": -2}})


def test_config_axis_and_key_m():
    cfg = parse_config({"axes": {"m": [0, 1, 2], "alpha": 0.445}})
    np.testing.assert_array_equal(cfg.sweep_arguments()["m"], [0.0, 1.0, 2.0])
    assert "m" not in parse_config({"axes": {"alpha": 0.445}}).sweep_arguments()
    assert parse_config({"axes": {"alpha": 0.445}, "solver": {"m": 2}}).sweep_arguments()["m"] == 2
    for bad, key in [({"axes": {"m": [0, 1.5], "alpha": 0.445}}, "axes.m"),
                     ({"axes": {"alpha": 0.445}, "solver": {"m": -1}}, "solver.m"),
                     ({"axes": {"alpha": 0.445, "m": 1}, "solver": {"m": 2}}, "solver.m"),
                     ({"axes": {"alpha": 0.445}, "solver": {"m": 2, "torsional": True}}, "torsional"),
                     ({"fluid": {"coupling": "paper", "bessel_order": 0},
                       "axes": {"alpha": 0.445, "m": [0, 1]}}, "m = 1")]:
        with pytest.raises(ValueError, match=key):
            parse_config(bad)


# ------------------------------------------------ the solvers built on the core, at order m = 2
def test_count_roots_order_m_counts_the_roots_of_frequencies(roots_m2):
    f = roots_m2[0]
    assert np.all(np.isfinite(f))
    # the lowest two, from 0 (the wedge at Ω = 0), and the upper two from between the first pair
    # (m = 0 has one root in (Ω_1 + Ω_2, 3Ω_3 − Ω_2)/2 here, ≈ 1.80: the count sees the order)
    for lo, hi, expected in [(0.0, 0.5 * (f[1] + f[2]), 2),
                             (0.5 * (f[0] + f[1]), f[2] + 0.5 * (f[2] - f[1]), 2),
                             (0.5 * (f[0] + f[1]), 0.5 * (f[1] + f[2]), 1)]:
        c = count_roots(TUBE2, ALPHAS2[0], lo, hi, n_layers=N, m=2)
        assert int(c.status) == CountStatus.CERTIFIED
        assert int(c.count) == expected == np.count_nonzero((f > lo) & (f < hi))
    with pytest.raises(ValueError, match="m"):
        count_roots(TUBE2, ALPHAS2[0], 0.0, 1.0, n_layers=N, m=-1)


def test_frequencies_with_error_order_m_is_honest(roots_m2):
    est = frequencies_with_error(TUBE2, ALPHAS2[0], n_layers=N, m=2)
    assert np.all(est.status == jd.Status.CONVERGED)
    np.testing.assert_array_equal(est.n_layers, [N, 2 * N, 4 * N])
    np.testing.assert_array_equal(est.levels[0], roots_m2[0])  # level N is frequencies(m=2)
    # a reference far finer than the levels: the sixth-order Magnus scheme on 4N sublayers
    fine = np.array([float(jd.frequency(TUBE2, ALPHAS2[0], w, n_layers=4 * N, scheme="magnus6", m=2))
                     for w in est.omega])
    true_error = np.abs(est.omega - fine)
    assert np.all(true_error <= est.error)  # the bound holds
    assert np.all(est.error <= 1e-6 * fine)  # and is small
    assert np.all(np.abs(est.levels[-1] - fine) > est.error)  # below the finest level's own error
    with pytest.raises(ValueError, match="m"):
        frequencies_with_error(TUBE2, ALPHAS2[0], n_layers=N, m=-1)


def test_dispersion_curve_order_m_equals_frequencies(roots_m2):
    curve = dispersion_curve(TUBE2, ALPHAS2, n_layers=N, m=2)
    assert curve.omega.shape == roots_m2.shape
    assert np.all(np.asarray(curve.status) == jd.Status.CONVERGED)
    assert not np.all(curve.scanned)  # continuation did some of the steps
    np.testing.assert_allclose(curve.omega, roots_m2, rtol=1e-12, atol=0)
    with pytest.raises(ValueError, match="m"):
        dispersion_curve(TUBE2, ALPHAS2, n_layers=N, m=-1)


def test_trace_branch_order_m_lands_on_roots_of_order_m(roots_m2):
    b = trace_branch(TUBE2, ALPHAS2[0], roots_m2[0, 1], along="alpha", stop=ALPHAS2[-1], n_layers=N, m=2)
    k = int(b.n_points)
    assert int(b.status) == BranchEnd.REACHED_STOP and k > 3
    assert float(b.parameter[k - 1]) == ALPHAS2[-1]
    np.testing.assert_allclose(b.omega[k - 1], roots_m2[-1, 1], rtol=1e-10)
    # every point of the trace is the second root of order 2 at its α̂ (its own Newton solve)
    inner = [float(jd.frequencies(TUBE2, a, m=2, n_layers=N)[1]) for a in np.asarray(b.parameter[1:k - 1:3])]
    np.testing.assert_allclose(np.asarray(b.omega[1:k - 1:3]), inner, rtol=1e-10)
    with pytest.raises(ValueError, match="m"):
        trace_branch(TUBE2, ALPHAS2[0], 1.0, along="alpha", stop=1.0, n_layers=N, m=-1)
