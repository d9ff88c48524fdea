"""Argument-principle root counts (jaxdea.solve.counting) against frequencies, sign changes and synthetic
functions with known zeros, in every regime where a scan could miss roots.

Compilation dominates: the counts share three static configurations (empty tube, acoustic fluid,
paper coupling ν = 1) and the scans one (n_roots = 24) per fluid model.
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy import special
from scipy.optimize import brentq

import jaxdea as jd
from jaxdea.numerics.bessel import coupling_pair
from jaxdea.params import canonical, gent_limit_excess
from jaxdea.physics.dispersion import OUTER_ROWS, characteristic_and_scale, initial_basis
from jaxdea.physics.transfer import discretize, transfer_matrix
from jaxdea.solve.counting import (
    LANES,
    CountStatus,
    RootCount,
    _count_roots,
    _phase_count,
    count_roots,
)

PAPER = dict(lambda_z=1.2, eta=0.85)
N_ROOTS = 24  # one compiled scan per fluid model; larger than every count below
SOFT = jd.Tube(lambda_i=1.1, **PAPER)  # V̂_cr(n = 1) = 0.2025 (README)
PAPER_TUBE = jd.Tube(voltage=0.2, lambda_i=1.1, **PAPER)
PAPER_FLUID = jd.Fluid(coupling="paper", bessel_order=1)
ALPHA_1 = float(jd.axial_wavenumber(SOFT, 1))  # the same for PAPER_TUBE (same η, λ_z)


def scan_count(tube, alpha, lo, hi, fluid=None):
    """Roots of jd.frequencies in (lo, hi), with n_roots larger than the count (never saturated)."""
    roots = jd.solve_frequencies(tube, alpha, fluid, n_roots=N_ROOTS, omega_max=hi)
    omega = np.asarray(roots.omega)
    assert np.all(np.isin(np.asarray(roots.status), [jd.Status.CONVERGED, jd.Status.NO_ROOT]))
    assert np.isnan(omega[-1])  # not saturated: every root below hi is among them
    return int(np.sum((omega > lo) & (omega < hi)))


def certified(tube, alpha, lo, hi, fluid=None, **kwargs):
    count, status = count_roots(tube, alpha, lo, hi, fluid, **kwargs)
    assert int(status) == CountStatus.CERTIFIED
    return int(count)


def gent_tube(gent, fraction):
    """λ_z = 1 and λ_i chosen so that max(I_1 − 3) over the wall is ``fraction`` of G."""
    li = brentq(lambda lam: float(gent_limit_excess(lam, 1.0, 0.85)) - fraction * gent, 1.0, 3.0)
    return jd.Tube(gent=gent, lambda_i=li, lambda_z=1.0, eta=0.85, voltage=0.05)


def critical_tube(factor):
    return SOFT.replace(voltage=factor * float(jd.critical_voltage(SOFT, ALPHA_1)))


THICK = jd.Tube(eta=0.3)
THICK_ALPHA = 150.0 / float(jd.thickness_ratio(THICK))  # α̂ĥ = 150
TRACE_TUBE = jd.Tube(voltage=0.1, lambda_i=0.9, **PAPER)

# (tube, α̂, ω_lo, ω_hi, fluid, number of roots measured); each count equals the scan's
REGIMES = {
    # 2 surface-like roots near 61.4 and the thickness resonances crowding above the cutoff 64.3
    "thick wall, alpha h = 150": (THICK, THICK_ALPHA, 60.0, 68.0, None, 17),
    "0.999 V_cr: lowest root 0.044": (lambda: critical_tube(0.999), ALPHA_1, 0.0, 3.0, None, 2),
    "0.999 V_cr, acoustic: lowest 0.028": (lambda: critical_tube(0.999), ALPHA_1, 0.0, 3.0,
                                           jd.Fluid(), 6),
    "1.000001 V_cr: unstable root on the imaginary axis, outside": (
        lambda: critical_tube(1.000001), ALPHA_1, 0.0, 3.0, None, 1),
    "Gent G = 3 at 95 % of locking": (lambda: gent_tube(3.0, 0.95), 0.445, 0.0, 20.0, None, 2),
    "Gent G = 2 at 99 % of locking": (lambda: gent_tube(2.0, 0.99), 0.445, 0.0, 20.0, None, 1),
    "Gent G = 5 at 90 % of locking": (lambda: gent_tube(5.0, 0.90), 0.445, 0.0, 20.0, None, 2),
    "paper coupling: pairs at its poles, gaps down to 1.2e-3": (PAPER_TUBE, ALPHA_1, 0.0, 8.0,
                                                                PAPER_FLUID, 22),
    "acoustic veering, gap 3.5e-4": (TRACE_TUBE, 0.698264, 0.0, 1.6,
                                     jd.Fluid(density_ratio=1e-6, speed_ratio=0.27), 3),
    "long waves alpha = 1e-3, acoustic": (SOFT, 1e-3, 0.0, 0.03, jd.Fluid(), 2),
    "long waves alpha = 1e-4, acoustic": (SOFT, 1e-4, 0.0, 0.003, jd.Fluid(), 2),
    "long waves alpha = 1e-4, empty, wide": (SOFT, 1e-4, 0.0, 3.0, None, 2),
    "slow fluid c_f = 0.05": (SOFT, ALPHA_1, 0.0, 3.0, jd.Fluid(speed_ratio=0.05), 23),
    "slow fluid c_f = 0.1": (SOFT, ALPHA_1, 0.0, 3.0, jd.Fluid(speed_ratio=0.1), 13),
}


# the default tier; the near-critical regimes (70 s each: the V̂_cr solve compiles) run with -m slow
FAST = ("thick wall, alpha h = 150", "acoustic veering, gap 3.5e-4", "slow fluid c_f = 0.05",
        "long waves alpha = 1e-4, empty, wide")


@pytest.mark.parametrize("name", [n if n in FAST else pytest.param(n, marks=pytest.mark.slow)
                                  for n in REGIMES])
def test_count_equals_frequencies(name):
    """The winding number equals the number of roots jd.frequencies returns in the interval and
    the number measured when this test was written."""
    tube, alpha, lo, hi, fluid, expected = REGIMES[name]
    tube = tube() if callable(tube) else tube
    count = certified(tube, alpha, lo, hi, fluid)
    assert count == scan_count(tube, alpha, lo, hi, fluid) == expected


def test_count_sees_a_pair_closer_than_1e_5():
    """The paper coupling with ρ̂_f = 1e-5 has a real pair at Ω ≈ 0.467631, 0.467635 (relative gap
    6.7e-6, two sign changes on a grid of step 1e-8): the count sees 2 around it, 1 up to its
    midpoint and 0 between its members, with the default box (δ ≈ 1.9e-7) and with the box of the
    whole interval (0, 1) (δ = 0.024, 1e5 times the gap). The scan of jd.frequencies misses this
    pair (and 19 more roots of this tube below 1): its Hermite classification sees one extremum of f
    per step where the pair makes three."""
    fluid = PAPER_FLUID.replace(density_ratio=1e-5)
    grid = jnp.linspace(0.46762, 0.46766, 4001)
    f = np.asarray(jax.jit(jax.vmap(lambda om: jd.characteristic(PAPER_TUBE, om, ALPHA_1, fluid)))(grid))
    change = np.nonzero(np.sign(f[:-1]) != np.sign(f[1:]))[0]
    assert change.size == 2
    p1, p2 = np.asarray(grid)[change]
    assert (p2 - p1) / p2 < 1e-5
    assert certified(PAPER_TUBE, ALPHA_1, 0.46762, 0.46766, fluid) == 2
    assert certified(PAPER_TUBE, ALPHA_1, 0.46762, 0.5 * (p1 + p2), fluid) == 1
    assert certified(PAPER_TUBE, ALPHA_1, p1 + 2e-8, p2 - 2e-8, fluid) == 0
    wide = certified(PAPER_TUBE, ALPHA_1, 0.0, 1.0, fluid)
    assert wide == certified(PAPER_TUBE, ALPHA_1, 0.0, 0.46762, fluid) + 2 + certified(
        PAPER_TUBE, ALPHA_1, 0.46766, 1.0, fluid)


def test_synthetic_zeros_pairs_near_zero_and_complex():
    """F(z) = ∏(z − z_k) on (0, 6) with δ = 0.05: a root at 1e-7, pairs at relative gaps 1e-5 and
    1e-9, a conjugate pair 3.7 ± 0.01i inside the box (counted, both), zeros outside (−0.5, 7,
    1.5 ± 0.2i, ±0.03i on the imaginary axis, outside the 45° wedge through 0): 8 in all; the full
    rectangle gives the same count as its upper half. A vertical side 1.8e-5 from a close pair."""
    zeros = jnp.array([1e-7, 0.9, 0.9 * (1 + 1e-5), 2.3, 2.3 * (1 + 1e-9), 3.7 + 0.01j, 3.7 - 0.01j,
                       5.0, -0.5, 7.0, 1.5 + 0.2j, 1.5 - 0.2j, 0.03j, -0.03j])

    def phasor(z):
        f = jnp.prod(z[:, None] - zeros[None, :], axis=1)
        return f / jnp.abs(f), jnp.isfinite(f)

    for symmetric in (True, False):
        count, status, evals = jax.jit(_phase_count, static_argnums=(0, 4))(
            phasor, 0.0, 6.0, 0.05, symmetric, 10_000)
        assert int(status) == CountStatus.CERTIFIED and int(count) == 8, symmetric
        assert int(evals) < 2000
    count, status, _ = jax.jit(_phase_count, static_argnums=(0, 4))(phasor, 0.9 * (1 - 2e-5), 2.0,
                                                                      0.05, True, 10_000)
    assert (int(count), int(status)) == (2, CountStatus.CERTIFIED)


def test_empty_interval_and_interval_ends():
    """No root in (0.8, 1.8) → 0. An end within rounding of a root is reported, never guessed; an
    end 1e-10 away from it counts the root on the correct side."""
    tube = jd.Tube()
    roots = np.asarray(jd.frequencies(tube, 0.445, n_roots=N_ROOTS, omega_max=3.0))
    assert certified(tube, 0.445, 0.8, 1.8) == 0
    root = float(roots[1])
    assert certified(tube, 0.445, 0.5, root * (1 + 1e-10)) == 2
    assert certified(tube, 0.445, 0.5, root * (1 - 1e-10)) == 1
    assert certified(tube, 0.445, root * (1 - 1e-10), 2.5) == 1
    for lo, hi in ((0.5, root), (root, 2.5)):
        assert tuple(map(int, count_roots(tube, 0.445, lo, hi))) == (-1, CountStatus.ZERO_ON_CONTOUR)


@pytest.mark.parametrize("case", ["empty", "acoustic", "layered"])
def test_count_without_voltage_is_that_of_the_mechanical_block(case):
    """count_roots at a concrete V̂ = 0 counts the zeros of the mechanical block alone
    (characteristic.winding_value): the count, status and number of evaluations of the full 6×6
    determinant (decoupled=False), and the number of roots frequencies finds in the interval."""
    tube, fluid = jd.Tube(voltage=0.0, lambda_i=0.9, lambda_z=1.2, eta=0.85), None
    if case == "acoustic":
        fluid = jd.Fluid()
    elif case == "layered":
        tube = tube.replace(layers=(jd.Layer(0.2, jd.NeoHookean(), shear_ratio=3.0),
                                    jd.Layer(0.6, jd.Gent(97.2), active=True),
                                    jd.Layer(0.2, jd.NeoHookean(), shear_ratio=3.0)))
    got = count_roots(tube, 0.445, 0.1, 3.0, fluid, n_layers=16, scheme="magnus6")
    from jaxdea.physics.transfer import Layers

    args = (*canonical(tube, 0.445, 0.1, 3.0, fluid, 1.0), jnp.asarray(65536))
    full, four = (_count_roots(*args, n_layers=Layers(16, "magnus6"), order=0, symmetric=True,
                               default=True, decoupled=d) for d in (False, True))
    assert int(got.status) == CountStatus.CERTIFIED
    assert tuple(map(int, four)) == tuple(map(int, full))
    assert (int(got.count), int(got.status)) == tuple(map(int, full[:2]))
    roots = np.asarray(jd.frequencies(tube, 0.445, fluid, n_roots=12, omega_max=3.0,
                                      n_layers=16, scheme="magnus6"))
    assert int(got.count) == int(np.sum((roots > 0.1) & (roots < 3.0))) > 0


def test_failures_are_reported():
    """Non-finite values (the Bessel integrals beyond their range, x = Ω r̂_i/ĉ_f > 470), a spent
    budget, and inputs out of range met under jit give count −1 and their status."""
    slow = jd.Fluid(speed_ratio=0.1)
    got = count_roots(SOFT, ALPHA_1, 0.0, 60.0, slow)
    assert isinstance(got, RootCount)
    assert tuple(map(int, got)) == (-1, CountStatus.NOT_FINITE)
    got = count_roots(SOFT, ALPHA_1, 0.0, 30.0, max_evaluations=LANES)
    assert tuple(map(int, got)) == (-1, CountStatus.BUDGET_EXHAUSTED)
    run = lambda tube, lo, hi: _count_roots(  # noqa: E731
        *canonical(tube, ALPHA_1, lo, hi, None, 1.0), jnp.asarray(65536), n_layers=30, order=0,
        symmetric=True, default=True)[:2]
    assert tuple(map(int, run(SOFT, 2.0, 1.0))) == (-1, CountStatus.INVALID)
    locked = SOFT.replace(gent=0.05)  # I_1 − 3 = 0.22 beyond G
    assert tuple(map(int, run(locked, 0.0, 1.0))) == (-1, CountStatus.INVALID)


@pytest.mark.parametrize("kwargs, name", [
    (dict(omega_lo=-1.0), "omega_lo"),
    (dict(omega_lo=float("nan")), "omega_lo"),
    (dict(omega_hi=0.0), "omega_hi"),
    (dict(omega_lo=2.0, omega_hi=1.0), "omega_hi"),
    (dict(height=0.0), "height"),
    (dict(height=5.0), "height"),
    (dict(n_layers=0), "n_layers"),
    (dict(alpha=-0.1), "alpha"),
    (dict(max_evaluations=10), "max_evaluations"),
    (dict(tube=jd.Tube(gent=0.5, lambda_i=1.5)), "gent"),
    (dict(fluid=jd.Fluid(speed_ratio=-1.0)), "speed_ratio"),
])
def test_bad_inputs_name_the_parameter(kwargs, name):
    args = dict(tube=jd.Tube(), alpha=0.445, omega_lo=0.0, omega_hi=3.0) | kwargs
    with pytest.raises(ValueError, match=name):
        count_roots(**args)


def test_complex_characteristic_has_the_argument_of_det_bas():
    """At complex Ω the stable f = det(B Q_N) has the argument of the plain holomorphic det(B A S)
    (Taylor 6×6 product, α̂ĥ small enough for it) and |f| e^{log_scale} = |det(B A S)|; on the real
    axis the complex evaluation equals the real one. Paper coupling ν = 1: complex Bessel pair,
    both fluid columns and the complex Gram–Schmidt at once."""
    wall = discretize(PAPER_TUBE, 30)

    def both(om):
        f, log_scale = characteristic_and_scale(wall, om, ALPHA_1, PAPER_FLUID, 1)
        a = transfer_matrix(wall, om, ALPHA_1, method="taylor")
        basis = initial_basis(wall, om, ALPHA_1, PAPER_FLUID, 1).astype(a.dtype)
        return f, log_scale, jnp.linalg.det(a[OUTER_ROWS, :] @ basis)

    omega = jnp.array([0.3 + 0.02j, 1.234 - 0.1j, 7.0 + 0.5j, 18.0 + 0.01j, 0.5 + 0j])
    f, log_scale, ref = (np.asarray(v) for v in jax.jit(jax.vmap(both))(omega))
    np.testing.assert_allclose(np.angle(f / ref), 0.0, atol=1e-9)
    np.testing.assert_allclose(np.abs(f) * np.exp(log_scale), np.abs(ref), rtol=1e-9)
    assert np.all(np.abs(f) <= 1.0)
    real = jd.characteristic(PAPER_TUBE, 0.5, ALPHA_1, PAPER_FLUID, n_layers=30)
    np.testing.assert_allclose(f[-1], float(real), rtol=1e-12)


@pytest.mark.parametrize("order", [0, 1, 3])
def test_complex_bessel_pair_matches_scipy(order):
    """(N_ν, D_ν) at complex s = χ̂² r̂_i² is (J_ν(x)/x^ν, x J_ν'(x)/x^ν), x = sqrt(s), times a
    positive factor: the argument of N_ν and the direction of the pair (series and integral
    branches, both half planes)."""
    rng = np.random.default_rng(order)
    values = rng.uniform(-4000, 4000, 40) + 1j * rng.uniform(-300, 300, 40)
    values = np.concatenate([values, [30 + 5j, -30 + 2j, 100j, -70 - 1e-3j, 64.5 + 0.1j, 63.9 - 0.1j]])
    for s in values:
        n, d = (complex(v) for v in coupling_pair(jnp.asarray(s), order))
        x = np.sqrt(s)
        n_ref, d_ref = special.jv(order, x) / x**order, x * special.jvp(order, x) / x**order
        assert abs(np.angle(n / n_ref)) < 1e-10, (order, s)
        assert abs(n * d_ref - d * n_ref) < 1e-10 * (abs(n) * abs(d_ref) + abs(d) * abs(n_ref))


@pytest.mark.slow
def test_paper_coupling_order_3_against_dense_sign_changes():
    """Paper coupling ν = 3 at mode n = 3, (0, 8): the count equals the sign changes of f on an
    80 000-point grid (15, all real roots); the scan of jd.frequencies returned 13 of them when this
    was written (it missed the pair 7.4837, 7.4984, relative gap 2e-3) and never more."""
    alpha = float(jd.axial_wavenumber(PAPER_TUBE, 3))
    fluid = jd.Fluid(coupling="paper", bessel_order=3)
    grid = jnp.linspace(1e-6, 8.0, 80_001)
    f = np.asarray(jax.jit(jax.vmap(lambda om: jd.characteristic(PAPER_TUBE, om, alpha, fluid)))(grid))
    changes = int(np.sum(np.sign(f[:-1]) * np.sign(f[1:]) < 0))
    assert certified(PAPER_TUBE, alpha, 0.0, 8.0, fluid) == changes == 15
    assert scan_count(PAPER_TUBE, alpha, 0.0, 8.0, fluid) <= 15


@pytest.mark.slow
def test_full_rectangle_equals_upper_half():
    """The reflection argument: integrating the whole rectangle (twice the work) gives the counts of
    the upper half, including the wedge at ω_lo = 0 above V̂_cr."""
    cases = [(PAPER_TUBE, ALPHA_1, 0.0, 8.0, PAPER_FLUID), (critical_tube(1.000001), ALPHA_1, 0.0,
                                                            3.0, None),
             (critical_tube(0.999), ALPHA_1, 0.0, 3.0, None), (SOFT, ALPHA_1, 0.5, 3.0, None)]
    for tube, alpha, lo, hi, fluid in cases:
        assert certified(tube, alpha, lo, hi, fluid, symmetric=False) == certified(
            tube, alpha, lo, hi, fluid)
