"""Roots the scan used to miss, checked against independent computations.

* Pairs of the paper's coupling that straddle the poles of B̂_ν (Ω_k = ĉ_f sqrt(α̂² + (j'_{ν,k}/r̂_i)²),
  zeros of J'_ν from SciPy), confirmed by sign changes of the full-transfer determinant
  det(B A S) (``expm`` per sublayer, no orthonormalisation) and by the argument principle.
* The pair of face waves of a wall with α̂ĥ ≈ 86, confirmed by the argument principle.
* A campaign of random tubes: ``frequencies`` against ``count_roots`` over (0, Ω_hi).
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.special import jnp_zeros, jvp

import jaxdea
import jaxdea as jd
from jaxdea import Fluid, Status, Tube
from jaxdea.numerics.bessel import RANGE, coupling_pair
from jaxdea.params import gent_limit_excess
from jaxdea.physics.dispersion import reference_determinant
from jaxdea.physics.transfer import discretize, laminate
from jaxdea.solve import roots
from jaxdea.solve.counting import CountStatus, count_roots_unchecked
from jaxdea.solve.roots import (
    bessel_derivative_zeros,
    coupling_poles,
    critical_voltage_unchecked,
    frequencies_unchecked,
)

PAPER_TUBE = Tube(lambda_i=1.8252549, lambda_z=1.2, eta=0.85, gent=2.0, voltage=0.1)
PAPER_FLUID = Fluid(density_ratio=0.13, speed_ratio=0.27, coupling="paper")
# lowest roots of the independent converged reference (five digits)
PAPER_REFERENCE = np.array([0.29765, 0.29843, 0.79769])
THIN_BOX = 1e-4  # half-height of the counting box: the paper's coupling is not conservative and
# has complex pairs about 2e-3 off the real axis next to its poles, inside the default box


@pytest.mark.parametrize("order", [0, 1, 2, 3, 11, 32])
def test_bessel_derivative_zeros_match_scipy(order):
    """Every zero, none spurious: at ν = 32 rounding noise of J'_ν below x = ν once gave false zeros,
    and at ν = 11 the last zero before the end of the table was once missed."""
    zeros = bessel_derivative_zeros(order)
    positive = zeros[1:] if order == 0 else zeros
    if order == 0:
        assert zeros[0] == 0.0  # D_0 = −s/2 vanishes at s = 0
    np.testing.assert_allclose(positive, jnp_zeros(order, positive.size), rtol=0, atol=1e-12)
    assert np.all(np.abs(jvp(order, positive, 1)) < 1e-12)
    # every zero up to where the coupling is finite (x + ν < RANGE), none missed: their spacing
    # tends to π from below, never below 2
    assert positive[-1] > RANGE - order - np.pi and np.all(np.diff(positive) > 2.0)


def test_paper_pairs_straddling_poles():
    alpha = jaxdea.axial_wavenumber(PAPER_TUBE, 1)
    roots = jaxdea.solve_frequencies(PAPER_TUBE, alpha, PAPER_FLUID, n_roots=5)
    omega = np.asarray(roots.omega)
    assert np.all(np.asarray(roots.status) == Status.CONVERGED)
    np.testing.assert_allclose(omega[:3], PAPER_REFERENCE, rtol=0, atol=2e-5)

    # each pair straddles a pole of B̂_1 (closed form with SciPy's zeros of J'_1)
    wall = discretize(PAPER_TUBE, laminate(None, None, PAPER_TUBE, alpha))  # the roots' discretisation
    r_inner = float(wall.r_inner)
    poles = 0.27 * np.sqrt(float(alpha) ** 2 + (jnp_zeros(1, 2) / r_inner) ** 2)
    code_poles, widths = (np.asarray(v)[:2] for v in coupling_poles(wall, alpha, PAPER_FLUID, 1))
    np.testing.assert_allclose(code_poles, poles, rtol=1e-13)
    # the widths |L/(dD_1/dΩ)| against central differences of the code's Bessel pair
    def pair(omega):
        s = ((omega / 0.27) ** 2 - float(alpha) ** 2) * r_inner**2
        n, d = coupling_pair(jnp.asarray(s), 1)
        return float(n) * omega**2 * 0.13 * r_inner, float(d)

    for pole, width in zip(poles, widths, strict=True):
        h = 1e-6 * pole
        slope = (pair(pole + h)[1] - pair(pole - h)[1]) / (2 * h)
        assert abs(pair(pole)[1]) < 1e-12 * abs(pair(pole)[0])
        np.testing.assert_allclose(width, abs(pair(pole)[0] / slope), rtol=1e-7)
    assert omega[0] < poles[0] < omega[1] and omega[2] < poles[1] < omega[3]

    # every root is a sign change of the full-transfer determinant (independent of the scaling)
    det = jax.jit(jax.vmap(lambda x: reference_determinant(wall, x, alpha, PAPER_FLUID, 1)))
    below, above = np.asarray(det(jnp.asarray(omega * (1 - 1e-9)))), np.asarray(
        det(jnp.asarray(omega * (1 + 1e-9))))
    assert np.all(below * above < 0)

    # and nothing is missed: the argument principle counts exactly these four below 0.9
    assert omega[3] < 0.9 < omega[4]
    count = jaxdea.count_roots(PAPER_TUBE, alpha, 0.0, 0.9, PAPER_FLUID, height=THIN_BOX)
    assert int(count.status) == CountStatus.CERTIFIED and int(count.count) == 4


def test_face_wave_pair_at_large_alpha_h():
    tube = Tube(lambda_i=0.9, lambda_z=1.2, eta=0.3, voltage=0.1, gent=97.2)
    alpha, n_layers = 40.0, 20  # α̂ĥ ≈ 86; this N used to lose the pair
    assert 80 < alpha * float(discretize(tube, n_layers).thickness) < 90
    roots = jaxdea.solve_frequencies(tube, alpha, None, n_roots=4, n_layers=n_layers)
    omega = np.asarray(roots.omega)
    assert np.all(np.asarray(roots.status) == Status.CONVERGED)
    # the pair of face waves (converged reference ≈ 46.7812, 46.7871), then 48.0514
    assert 46.77 < omega[0] < omega[1] < 46.80 and abs(omega[2] - 48.0514) < 1e-3
    for n, hi in ((2, 0.5 * (omega[1] + omega[2])), (3, 0.5 * (omega[2] + omega[3]))):
        count = jaxdea.count_roots(tube, alpha, 0.0, hi, None, n_layers=n_layers)
        assert int(count.status) == CountStatus.CERTIFIED and int(count.count) == n


CAMPAIGN_LAYERS = 10  # the scan and the count see the same laminate, whatever N
CAMPAIGN_ROOTS = 6


def _tubes_at_rest(rng, n_cases, stretch_range):
    """Tubes at V̂ = 0 with λ_i ∈ ``stretch_range``, λ_z ∈ [1, 1.5], η ∈ [0.3, 0.95], G above
    I_1 − 3 in the wall (or ∞, neo-Hookean)."""
    lambda_i = rng.uniform(*stretch_range, n_cases)
    lambda_z = rng.uniform(1.0, 1.5, n_cases)
    eta = rng.uniform(0.3, 0.95, n_cases)
    excess = gent_limit_excess(lambda_i, lambda_z, eta)
    gent = np.where(rng.uniform(size=n_cases) < 0.25, np.inf,
                    np.maximum(2.0, excess * rng.uniform(1.05, 3.0, n_cases)))
    return Tube(voltage=jnp.zeros(n_cases), lambda_i=jnp.asarray(lambda_i),
                lambda_z=jnp.asarray(lambda_z), eta=jnp.asarray(eta), gent=jnp.asarray(gent),
                length_ratio=jnp.full(n_cases, 10.0))


def _random_tubes(n_cases, seed):
    """Tubes of :func:`_tubes_at_rest` with λ_i ∈ [0.7, 1.8] at V̂ = u·V̂_cr(α̂), u ∈ [0, 0.9] (0
    where no V̂_cr below pull-in), and α̂ ∈ [0.1, 5] (log-uniform)."""
    rng = np.random.default_rng(seed)
    tubes = _tubes_at_rest(rng, n_cases, (0.7, 1.8))
    alpha = jnp.asarray(np.exp(rng.uniform(np.log(0.1), np.log(5.0), n_cases)))
    share = rng.uniform(0.0, 0.9, n_cases)
    layers = laminate(CAMPAIGN_LAYERS, "midpoint")
    critical, _ = jax.jit(jax.vmap(
        lambda t, a: critical_voltage_unchecked(t, a, None, layers, 0)))(tubes, alpha)
    voltage = jnp.where(jnp.isfinite(critical), critical * share, 0.0)
    return tubes.replace(voltage=voltage), alpha


def _campaign(fluid, order, n_cases, seed, sequential=False):
    """(roots, count) per case: the CAMPAIGN_ROOTS + 1 lowest roots, and the count in
    (0, (Ω_6 + Ω_7)/2), which must be 6 when the scan missed nothing below Ω_7.

    ``sequential``: the counts one tube after another (``lax.map``) instead of vmapped. A vmapped
    ``while_loop`` runs every tube until the slowest is done; with the paper's thin box the count
    takes Ω_hi/δ evaluations (25–58 k per tube, ~60 µs each), so that lockstep did 1.7 times the
    work. The roots stay vmapped (cheap) and use the same laminate as the count either way."""
    tubes, alpha = _random_tubes(n_cases, seed)
    layers = laminate(CAMPAIGN_LAYERS, "midpoint")
    height = THIN_BOX if fluid is not None and fluid.coupling == "paper" else None

    def roots_of(tube, a):
        return frequencies_unchecked(tube, a, fluid, None, CAMPAIGN_ROOTS + 1, layers, order)

    def count_of(tube, a, roots):
        hi = 0.5 * (roots.omega[CAMPAIGN_ROOTS - 1] + roots.omega[CAMPAIGN_ROOTS])
        return count_roots_unchecked(tube, a, 0.0, hi, fluid, layers, order, height)

    @jax.jit
    def solve(tubes, alpha):
        if sequential:
            roots = jax.vmap(roots_of)(tubes, alpha)
            return roots, jax.lax.map(lambda x: count_of(*x), (tubes, alpha, roots))

        def one(tube, a):
            roots = roots_of(tube, a)
            return roots, count_of(tube, a, roots)

        return jax.vmap(one)(tubes, alpha)

    roots, (count, status, _) = solve(tubes, alpha)
    return tubes, alpha, roots, np.asarray(count), np.asarray(status)


def _check_campaign(fluid, order, n_cases, seed, sequential=False):
    tubes, alpha, roots, count, count_status = _campaign(fluid, order, n_cases, seed, sequential)
    status = np.asarray(roots.status)
    solved = np.all(status == Status.CONVERGED, axis=1) & (count_status == CountStatus.CERTIFIED)
    assert solved.mean() >= 0.9, (status, count_status)
    # a disagreement names its tubes: (index, tube, α̂, the 7 roots, the count)
    keys = ("lambda_i", "lambda_z", "eta", "gent", "voltage")
    cases = [(int(i), {k: float(getattr(tubes, k)[i]) for k in keys}, float(alpha[i]),
              np.asarray(roots.omega[i]).tolist(), int(count[i]))
             for i in np.flatnonzero(solved & (count != CAMPAIGN_ROOTS))]
    np.testing.assert_array_equal(count[solved], CAMPAIGN_ROOTS, err_msg=repr(cases))


def test_campaign_paper_coupling():
    """A few random tubes at V̂ = 0 through the public calls of the first test (the same compiled
    programs); the slow campaign below covers 100 tubes per fluid model."""
    rng = np.random.default_rng(1)
    for _ in range(4):
        tube = Tube(lambda_i=rng.uniform(0.7, 1.8), lambda_z=rng.uniform(1.0, 1.5),
                    eta=rng.uniform(0.3, 0.95), gent=np.inf)
        alpha = jaxdea.axial_wavenumber(tube, 1)
        roots = jaxdea.solve_frequencies(tube, alpha, PAPER_FLUID, n_roots=5)
        assert np.all(np.asarray(roots.status) == Status.CONVERGED)
        hi = 0.5 * float(roots.omega[3] + roots.omega[4])
        count = jaxdea.count_roots(tube, alpha, 0.0, hi, PAPER_FLUID, height=THIN_BOX)
        assert int(count.status) == CountStatus.CERTIFIED and int(count.count) == 4


@pytest.mark.parametrize("coupling, n_cases", [(None, 34), ("acoustic", 33), ("paper", 33)])
def test_campaign_hundred_random_tubes(coupling, n_cases):
    """The default tier's campaign: 100 random tubes in all (thick and thin walls, G from 2 to ∞,
    V̂ up to 0.9 V̂_cr, α̂ 0.1–5), split over the three fluid models; the scan's 6 lowest roots
    against the certified count (other tubes than the slow campaign's)."""
    fluid = None if coupling is None else Fluid(coupling=coupling,
                                                bessel_order=1 if coupling == "paper" else None)
    _check_campaign(fluid, 1 if coupling == "paper" else 0, n_cases, seed=5)


# the slow campaign: 1000 tubes, 334 fluid-free, 333 acoustic, 333 paper; the paper's (the thin box
# makes its count ~100 times dearer, ~2 s per tube) in 9 parts of 37 so that xdist spreads them
SLOW_CAMPAIGN = ([("paper", 37, part) for part in range(9)]
                 + [(None, 334, 0), ("acoustic", 333, 0)])


@pytest.mark.slow
@pytest.mark.parametrize("coupling, n_cases, part", SLOW_CAMPAIGN,
                         ids=[f"{c}-{n}-part{p}" for c, n, p in SLOW_CAMPAIGN])
def test_campaign_random_tubes(coupling, n_cases, part):
    """The slow campaign: 1000 random tubes (the default tier's regimes, other seeds: every part
    draws its own tubes), the scan's 6 lowest roots against the certified count."""
    fluid = None if coupling is None else Fluid(coupling=coupling,
                                                bessel_order=1 if coupling == "paper" else None)
    seed = (2, ["paper", None, "acoustic"].index(coupling), part)
    _check_campaign(fluid, 1 if coupling == "paper" else 0, n_cases, seed, sequential=True)


def test_traced_bessel_order_of_a_sweep_over_n_matches_single_calls():
    """A sweep over n with the paper's coupling traces ν = n: its poles come from the table of
    zeros (TRACED_ORDERS) and the roots equal those of frequencies with the static order."""
    tube = jd.Tube(voltage=0.1, lambda_i=0.9, lambda_z=1.2, eta=0.85, length_ratio=10.0)
    fluid = jd.Fluid(density_ratio=0.13, speed_ratio=0.27, coupling="paper")
    modes = np.array([1, 2, 3])
    res = jd.sweep(tube, fluid, n=modes, n_roots=2, n_layers=10, progress=False)
    assert np.all(res.status == jd.Status.CONVERGED)
    for i, n in enumerate(modes):
        ref = jd.frequencies(tube, jd.axial_wavenumber(tube, int(n)), fluid, n_roots=2, n_layers=10)
        np.testing.assert_allclose(res.omega[i], np.asarray(ref), rtol=1e-13)
    table = roots._zeros_table()
    for nu in (0, 5, roots.TRACED_ORDERS):
        z = roots.bessel_derivative_zeros(nu)
        np.testing.assert_array_equal(table[nu, : len(z)], z)
        assert np.all(np.isinf(table[nu, len(z):]))


def _critical_grids(tubes, n_grids):
    """V̂_cr of every m ≤ 8, n ≤ 3 of each tube, for each scan density ``n_grid`` (N = 10)."""
    layers = laminate(CAMPAIGN_LAYERS, "midpoint")

    def grid(tube, n_grid):
        def one(m, alpha):
            return critical_voltage_unchecked(tube, alpha, None, layers, 0, n_grid=n_grid, m=m,
                                              family=roots.ORDER_M)[0]

        return roots.map_orders_and_modes(tube, 3, 8, one)

    return [np.asarray(jax.jit(jax.vmap(lambda t, g=g: grid(t, g)))(tubes)) for g in n_grids]


@pytest.mark.parametrize("n_cases", [pytest.param(2, id="default"),
                                     pytest.param(24, id="slow", marks=pytest.mark.slow)])
def test_critical_voltage_scan_density(n_cases):
    """f(Ω = 0; V̂) does not oscillate in V̂: the default chunk of 32 points over (0, V̂_lim] finds
    the same lowest root as a 16 times denser scan, for every order m ≤ 8 and mode n ≤ 3."""
    tubes = _tubes_at_rest(np.random.default_rng(5), n_cases, (0.85, 1.4))  # most (m, n) buckle
    default, dense = _critical_grids(tubes, (32, 512))
    assert np.isfinite(dense).sum() >= 10 * n_cases  # most (m, n) have a V̂_cr below pull-in
    np.testing.assert_array_equal(np.isnan(default), np.isnan(dense))
    np.testing.assert_allclose(default, dense, rtol=1e-11)


def test_scan_marks_roots_whose_slope_sign_breaks_the_alternation_suspect():
    """f changes sign at each simple root, so sign f'(Ω_k) = (−1)^k sign f(0). A function that turns
    sign without a root (a jump, as the paper's poles do, or a solver failure) gives a "root" whose
    slope has the wrong sign: it and every root above it (their index is unknown) are SUSPECT and
    NaN, where the bare scan returned the jump at 1.449 as CONVERGED. With the check off (the
    paper's coupling, whose poles turn the sign) the same roots come back CONVERGED, and on a
    continuous f nothing changes."""
    jump = lambda x: jnp.where(x < 1.5, -1.0 - x, 4.0 - x)  # noqa: E731  no root below 4, slope −1
    flagged = roots._scan_for_roots(jump, 0.1, 6.0, 2)
    np.testing.assert_array_equal(flagged.status, [Status.SUSPECT, Status.SUSPECT])
    assert np.all(np.isnan(flagged.omega))
    bare = roots._scan_for_roots(jump, 0.1, 6.0, 2, continuous=False)
    np.testing.assert_array_equal(bare.status, [Status.CONVERGED, Status.CONVERGED])
    assert 1.4 < float(bare.omega[0]) < 1.5 and float(bare.omega[1]) == pytest.approx(4.0, rel=1e-14)
    quartic = lambda x: (x - 1.0) * (x - 2.0) * (x - 3.0) * (x + 1.0)  # noqa: E731
    plain = roots._scan_for_roots(quartic, 0.1, 5.0, 3)
    np.testing.assert_array_equal(plain.status, [Status.CONVERGED] * 3)
    np.testing.assert_allclose(plain.omega, [1.0, 2.0, 3.0], rtol=1e-14)
