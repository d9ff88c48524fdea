"""Physics validation of jaxdea against closed forms and independent computations (theory.md §1–5).

Every case compares numbers that could fail; each tolerance is derived from the numerics in a
comment.
Numerical facts used throughout:

* the laminate (midpoint-exponential) scheme has an error c·(ĥ/N)² (theory.md §3), so halving the
  sublayer thickness divides it by 4, and Richardson 4Ω(2N) − Ω(N) over 3 leaves O(N⁻⁴);
* roots are refined to |step| ≤ 1e-15·Ω (safeguarded Newton) on a characteristic function with
  rounding noise ~1e-16, so two computations of the same discrete problem agree to ~1e-14.

Compile-time hygiene (each new static signature compiles for 10–20 s on two cores): n_roots = 3,
n_layers ∈ {30, 60} (120 in the slow tests), and omega_max / alpha always passed as Python floats
(a NumPy or JAX scalar, or omega_max=None, would be a new signature).
"""

import functools
import math

import exact_cylinder
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.optimize import brentq

import jaxdea as jd
from jaxdea.physics.dispersion import PHI, S, T, U, W, initial_basis
from jaxdea.physics.transfer import discretize, transfer_matrix

N_ROOTS = 3
SQRT3 = math.sqrt(3.0)
ACOUSTIC = jd.Fluid(density_ratio=0.13, speed_ratio=0.27)

# The paper's tube (eta = 0.85, lambda_z = 1.2) at two inflations and two voltages.
PAPER_TUBES = [(li, v) for li in (0.9, 1.1) for v in (0.0, 0.2)]
OMEGA_MAX_PAPER = 25.0  # above the first thickness mode (~18) for n <= 10, below the next (~36)


def paper_tube(lambda_i, voltage):
    return jd.Tube(lambda_i=lambda_i, lambda_z=1.2, voltage=voltage, eta=0.85)


def rel(a, b):
    return np.abs(np.asarray(a) - np.asarray(b)) / np.abs(np.asarray(b))


@functools.cache
def _roots_cached(tube, alpha, fluid, omega_max, n_layers):
    return np.asarray(jd.frequencies(tube, alpha, fluid=fluid, n_roots=N_ROOTS,
                                     omega_max=omega_max, n_layers=n_layers))


# eager discretize costs ~20 s of op-by-op dispatch on first use; jitted ~3 s
discretize_jit = jax.jit(discretize, static_argnums=1)


def roots(tube, alpha, fluid=None, omega_max=OMEGA_MAX_PAPER, n_layers=30):
    """jd.frequencies with the compile-sharing conventions (Python floats), memoised."""
    return _roots_cached(tube, float(alpha), fluid, float(omega_max), int(n_layers))


# ------------------------------------------------------------------- (a) exact hollow cylinder

# omega_max: eta = 0.85 → the third root (first thickness mode) lies in 17.8 … 20.5 for these α̂
# (20.44 at α̂ = 5, hence 22 rather than 20); eta = 0.5 → third root ≤ 8.01, the fourth well
# above 10.
EXACT_CASES = [(eta, alpha, 22.0 if eta == 0.85 else 10.0)
               for eta in (0.85, 0.5) for alpha in (0.05, 0.5, 2.0, 5.0)]


@functools.cache
def exact_roots(alpha, eta, omega_max):
    # 2000 grid steps (≤ 0.011 apart): the roots here are ≥ 0.3 apart, no sign change is missed.
    return exact_cylinder.roots(alpha, 1.0, 1.0 / eta, N_ROOTS, omega_max, 2000)


@pytest.mark.parametrize(
    "eta, alpha, omega_max, gent",
    [case + (97.2,) for case in EXACT_CASES]
    + [(0.5, 0.5, 10.0, math.inf)],
)
def test_unstretched_tube_matches_exact_cylinder(eta, alpha, omega_max, gent):
    """λ_i = λ_z = 1, V̂ = 0: the three lowest roots equal the exact incompressible hollow cylinder
    (theory.md §5(i)) up to the O(N⁻²) laminate error.

    At λ = 1 the W_11 terms drop out (they multiply λ_z² − λ_r², 1 − λ⁴λ_z², …) and W_1 = 1/2, so
    G = 97.2 and G = ∞ are the same linear problem; both paths are checked (G = ∞ in one case:
    η = 0.5, α̂ = 0.5).
    """
    ref = exact_roots(alpha, eta, omega_max)
    assert np.all(np.isfinite(ref)), "three exact roots must exist below omega_max"
    tube = jd.Tube(eta=eta, gent=gent)
    om30 = roots(tube, alpha, omega_max=omega_max, n_layers=30)
    om60 = roots(tube, alpha, omega_max=omega_max, n_layers=60)
    err30, err60 = rel(om30, ref), rel(om60, ref)
    # Observed err30 ≤ 1.2e-5 for η = 0.85 and ≤ 1.5e-4 for η = 0.5: the error is c·(ĥ/N)² with
    # ĥ = 0.176 resp. 1.0, i.e. ~32× larger for the thick tube at the same N. The brief's 1e-4 holds
    # for η = 0.85; for η = 0.5 the same constant c ≲ 0.15 gives 0.15·(1/30)² ≈ 1.7e-4 → bound 2e-4.
    bound = 1e-4 if eta == 0.85 else 2e-4
    assert np.all(err30 < bound), (err30, bound)
    # N⁻² law: err(30)/err(60) = 4(1 + O(N⁻²)); [3, 5] leaves room for the next term and for the
    # reference's own error (~1e-14, negligible above 1e-9). Roots whose N = 30 error is already
    # below 1e-9 are at the level where the reference and rounding blur the ratio: skipped.
    big = err30 > 1e-9
    assert np.any(big)
    ratio = err30[big] / err60[big]
    assert np.all((ratio > 3.0) & (ratio < 5.0)), ratio
    # Richardson extrapolation must then remove ≥ 99 % of the error: with ratio 4(1 + δ), the
    # residual is err30·|δ|/(3(1 + δ)); observed |δ| ≤ 3e-3 (ratios 3.99 … 4.003), so 1e-2·err30
    # plus the reference and root accuracy (1e-12 relative) is a bound with a ≥ 10× margin.
    rich = (4.0 * om60 - om30) / 3.0
    print(f"\neta={eta} alpha={alpha} G={gent}: err30={err30} ratio={err30 / err60} "
          f"richardson={rel(rich, ref)}")
    assert np.all(rel(rich, ref)[big] < 1e-2 * err30[big] + 1e-12), (rel(rich, ref), err30)


# ------------------------------------------------------------------- (b) long-wave bar speed


def test_long_wave_bar_speed():
    """Unstretched tube, α̂ = 1e-3: Ω/α̂ → √(E/μ) = √3 (theory.md §5(ii)).

    Expected deviation: Rayleigh–Love dispersion Ω/α̂ = √3 [1 − ν²α̂²r_g²/2], ν = 1/2,
    r_g² = (r_i² + r_o²)/2, i.e. −√3 α̂²(r_i² + r_o²)/16 = −2.6e-7 for η = 0.85, plus the N = 30
    laminate error of the bar mode, 4.1e-7 relative (= 7e-7 in Ω/α̂) in test (a) at α̂ = 0.05
    (independent of α̂ in the long-wave limit). Sum ≈ 1e-6; asserted < 2e-6. The Rayleigh–Love
    term itself is checked against the exact reference (exact_cylinder), and what remains of the
    jaxdea deviation after removing it must be laminate-sized (< 1e-6).
    """
    alpha = 1e-3
    tube = jd.Tube(eta=0.85)
    scanned = roots(tube, alpha, omega_max=22.0, n_layers=30)
    # The scan must find the bar root near 1.7e-3 (far below the uniform scan step π/ĥ/16 ≈ 1.1,
    # i.e. in the geometric first chunk) plus the
    # breathing (≈1.85) and thickness (≈17.8) modes.
    assert np.all(np.isfinite(scanned))
    assert scanned[0] < 1e-2 and 1.0 < scanned[1] < 3.0 and 15.0 < scanned[2] < 20.0
    newton = float(jd.frequency(tube, alpha, 1.6e-3, n_layers=30))  # guess 8 % low
    # Same root of the same discrete function: equal to the refinement accuracy.
    assert abs(newton - scanned[0]) < 1e-12 * scanned[0]
    speed = scanned[0] / alpha
    assert abs(speed - SQRT3) < 2e-6, speed - SQRT3
    # Subtract the Rayleigh–Love term: what remains is the laminate error (4e-7 relative).
    r_o2 = 1.0 / 0.85**2
    love = SQRT3 * (1.0 - alpha**2 * (1.0 + r_o2) / 16.0)
    assert abs(speed - love) / love < 1e-6
    exact = exact_cylinder.roots(alpha, 1.0, 1.0 / 0.85, 1)[0] / alpha
    print(f"\nbar: Omega/alpha - sqrt3 = {speed - SQRT3:.3e} (scan), newton-scan = "
          f"{newton - scanned[0]:.1e}, Love-corrected rel {abs(speed - love) / love:.2e}, "
          f"exact - sqrt3 = {exact - SQRT3:.3e}, exact vs Love {abs(exact - love) / love:.1e}")
    assert abs(exact - love) / love < 1e-11  # O(α̂⁴) ≈ 1e-12 beyond Rayleigh–Love


# ------------------------------------------------------------------- (c) Gent → neo-Hookean

C_BASE = dict(lambda_i=0.9, lambda_z=1.2, voltage=0.2, eta=0.85)


def test_gent_limit_is_neo_hookean():
    """G → ∞ equals neo-Hookean: Ω(G) − Ω(∞) = O(1/G), and G = inf is the neo-Hookean energy.

    * ``material="neo_hookean"`` vs ``gent=inf``: the roots are functions of the discretised wall
      only (base state, moduli, P̂_i: :func:`jaxdea.physics.transfer.discretize`), so the walls are compared
      leaf by leaf (same energy, different code path: rounding, 1e-13), which avoids a further
      ~15 s compile of the root solver for the static ``material``.
    * O(1/G) law, quantitatively: [Ω(G) − Ω(∞)]·G/Ω is the same at G = 97.2 and G = 1e9 up to the
      O(1/G²) term, of relative size ~(I_1 − 3)/G ≈ 0.4/97 ≈ 0.5 % → asserted within 3 %. At
      G = 1e9 the difference is ~1e-10·Ω, resolved since roots are accurate to ~1e-15·Ω.
    """
    wall_inf = discretize_jit(jd.Tube(gent=math.inf, **C_BASE), 30)
    wall_neo = discretize_jit(jd.Tube(material="neo_hookean", **C_BASE), 30)
    for leaf_inf, leaf_neo in zip(jax.tree_util.tree_leaves(wall_inf),
                                  jax.tree_util.tree_leaves(wall_neo), strict=True):
        np.testing.assert_allclose(np.asarray(leaf_neo), np.asarray(leaf_inf), rtol=1e-13,
                                   atol=1e-15)
    alpha = float(jd.axial_wavenumber(jd.Tube(**C_BASE), 2))
    om_inf = roots(jd.Tube(gent=math.inf, **C_BASE), alpha)
    om_big = roots(jd.Tube(gent=1e9, **C_BASE), alpha)
    om_gent = roots(jd.Tube(gent=97.2, **C_BASE), alpha)
    assert np.all(np.isfinite(om_inf))
    assert np.all(rel(om_big, om_inf) < 1e-8), rel(om_big, om_inf)
    slope_big = (om_big - om_inf) / om_inf * 1e9
    slope_gent = (om_gent - om_inf) / om_inf * 97.2
    print(f"\n(Omega(G) - Omega(inf))/Omega * G: G=1e9 {slope_big}, G=97.2 {slope_gent}")
    assert np.all(np.abs(slope_gent) > 1e-2)  # the Gent stiffening is visible at G = 97.2
    assert np.all(rel(slope_big, slope_gent) < 3e-2), (slope_big, slope_gent)


# ------------------------------------------------------------------- (d) V → −V symmetry


@pytest.mark.parametrize("fluid", [None, ACOUSTIC], ids=["empty", "acoustic"])
@pytest.mark.parametrize("n", [1, 3])
def test_voltage_sign_symmetry(fluid, n):
    """Only V̂² matters physically (theory.md §0): D̂_r → −D̂_r flips the signs of Φ, D̄ in the
    state vector, a similarity transform of M that leaves det C unchanged. Roots at ±V̂ agree to
    rounding (1e-13 relative: root accuracy ~1e-15, f noise ~1e-16/|f'|)."""
    tube = jd.Tube(lambda_i=0.9, lambda_z=1.2, voltage=0.25, eta=0.85)
    alpha = float(jd.axial_wavenumber(tube, n))
    plus = roots(tube, alpha, fluid=fluid)
    minus = roots(tube.replace(voltage=-0.25), alpha, fluid=fluid)
    assert np.all(np.isfinite(plus))
    print(f"\n+-V n={n} fluid={fluid is not None}: {plus}, rel diff {rel(minus, plus)}")
    assert np.all(rel(minus, plus) < 1e-13), rel(minus, plus)
    # ... and the voltage does act (so the test can fail): V̂ = 0 moves the roots by > 1e-4.
    zero = roots(tube.replace(voltage=0.0), alpha, fluid=fluid)
    assert np.max(rel(zero, plus)) > 1e-4


# ------------------------------------------------------------------- (e) Korteweg wave


def korteweg_speed2(eta, rho_f, c_f):
    """(Ω/α̂)² = 1/(ρ̂_f(1/(ρ̂_f ĉ_f²) + D̂_w)), thick-wall compliance, λ = 1, V̂ = 0 (§5(v))."""
    ri, ro = 1.0, 1.0 / eta
    dw = (1.0 / ri**2 + 1.0 / (3.0 * ro**2)) / (1.0 / ri**2 - 1.0 / ro**2)
    return 1.0 / (rho_f * (1.0 / (rho_f * c_f**2) + dw)), dw


def test_korteweg_long_wave_speed():
    """Acoustic coupling: the lowest branch is the Korteweg–Moens wave with thick-wall compliance.

    Deviations from the quasi-static formula: (1) dispersion O(α̂²r²) → 0; (2) wall inertia — the
    axial wall motion is not exactly force-free at phase speed c: relative O(ρ_s c²/E) = c²/3
    ≈ 0.023 of the *wall* share D_w/(1/K_f + D_w) ≈ 0.041 of the compliance, i.e. at most
    ~9.4e-4 (observed −1.89e-4, α̂-independent); (3) laminate error ≤ 1e-5 at N = 30 (test (a)).
    Hence |rel. error of c²| < 1e-3. The α̂-dependent part must shrink like α̂²: with e(α̂) the
    relative error, [e(0.01) − e(0.005)]/[e(0.005) − e(0.0025)] = 4 (asserted in [3, 5]).
    """
    eta = 0.85
    c2, dw = korteweg_speed2(eta, ACOUSTIC.density_ratio, ACOUSTIC.speed_ratio)
    wall_share = dw / (1.0 / (ACOUSTIC.density_ratio * ACOUSTIC.speed_ratio**2) + dw)
    inertia_bound = c2 / 3.0 * wall_share
    assert inertia_bound < 1e-3
    tube = jd.Tube(eta=eta)
    errors = {}
    for alpha in (0.01, 0.005, 0.0025):
        # omega_max = 3: reuses the compiled acoustic solver; the Korteweg root is ~0.26 α̂, found by
        # the scan's geometric first chunk.
        om = roots(tube, alpha, fluid=ACOUSTIC, omega_max=3.0)
        assert np.isfinite(om[0]) and om[0] < 0.5 * alpha
        errors[alpha] = (om[0] / alpha) ** 2 / c2 - 1.0
    print("\nKorteweg: c2_theory =", c2, "relative errors of (Omega/alpha)^2:", errors)
    for e in errors.values():
        assert abs(e) < 1e-3
    assert abs(errors[0.005]) < abs(errors[0.01])
    ratio = (errors[0.01] - errors[0.005]) / (errors[0.005] - errors[0.0025])
    assert 3.0 < ratio < 5.0, ratio


# ------------------------------------------------------------------- (f) gauge invariance

GAUGE_TUBE = jd.Tube(lambda_i=0.9, lambda_z=1.2, voltage=0.2, eta=0.85)


def general_gauge_characteristic(wall, omega, alpha, p_outer):
    """det C(Ω) for a general outer pressure P̂_o (theory.md §4): rows Φ, T̄, S̄ of the full
    transfer matrix A (reference ``expm`` path), with P̂_o(A_U/r̂_o + α̂ A_W) added to row T̄ and
    α̂ P̂_o A_U to row S̄; the inner face uses wall.pressure_inner through ``initial_basis``."""
    a = transfer_matrix(wall, omega, alpha)
    rows = jnp.stack([
        a[PHI],
        a[T] + p_outer * (a[U] / wall.r_outer + alpha * a[W]),
        a[S] + alpha * p_outer * a[U],
    ])
    return jnp.linalg.det(rows @ initial_basis(wall, omega, alpha))


_gauge_f = jax.jit(general_gauge_characteristic)


def gauge_function(wall, alpha, p_outer):
    # float(): one compiled signature for grid points and brentq's evaluations alike.
    return lambda om: float(_gauge_f(wall, float(om), alpha, float(p_outer)))


def shift_gauge(wall, p_field, p_inner):
    """Add p_field to p(r̂) in every sublayer and p_inner to P̂_i."""
    return wall._replace(coef=wall.coef._replace(p=wall.coef.p + p_field),
                         pressure_inner=wall.pressure_inner + p_inner)


def brentq_scan(wall, alpha, p_outer, omega_max=19.0, n_grid=200):
    """All sign changes of the general-gauge determinant on a uniform grid, refined by brentq.
    Grid step 19/200 ≈ 0.095, well below the root spacing of this case (≥ 0.33; jd.frequencies,
    whose Hermite scan also sees close pairs, finds the same three); 19 lies between the third root
    (≈ 17.9) and the fourth (≈ 36)."""
    f = gauge_function(wall, alpha, p_outer)
    grid = np.linspace(1e-2, omega_max, n_grid)
    vals = np.array([f(om) for om in grid])
    assert np.all(np.isfinite(vals))
    idx = np.nonzero(np.sign(vals[1:]) * np.sign(vals[:-1]) < 0)[0]
    return np.array([brentq(f, grid[k], grid[k + 1], xtol=1e-15, rtol=1e-15) for k in idx])


def brentq_near(wall, alpha, p_outer, guesses, width=1e-3):
    """brentq in [Ω(1 − width), Ω(1 + width)] around each guess (a sign change must exist)."""
    f = gauge_function(wall, alpha, p_outer)
    return np.array([brentq(f, g * (1 - width), g * (1 + width), xtol=1e-15, rtol=1e-15)
                     for g in guesses])


def test_gauge_invariance():
    """P̂_i → P̂_i + P, P̂_o → P, p(r̂) → p(r̂) + P changes no frequency (theory.md §1, §4).

    Independent path: brentq on the raw det of the reference transfer matrix (full product of
    expm), with the general-P̂_o boundary rows, vs jd.frequencies (gauge P̂_o = 0, orthonormalised
    propagation, Taylor exponentials).

    Finding: at fixed N the laminate scheme is gauge invariant only up to its own O(N⁻²) error —
    the gauge change is an r-dependent transformation of Y that does not commute with the midpoint
    exponentials. Observed |ΔΩ|/Ω at N = 30: ≤ 9.5e-7 (P = 0.3), ≤ 1.6e-6 (P = −0.5), shrinking by
    4.000 per halving of the sublayers. So the assertions are: (1) at P = 0 the two paths agree to
    1e-9 (same discrete problem; observed ~1e-13); (2) the gauge difference is below the laminate
    error level (1e-5 at N = 30) and falls like N⁻² (ratio in [3, 5]); (3) after Richardson
    extrapolation from N = 30, 60 the gauges agree to 1e-9 (observed ≤ 1.3e-11: O(N⁻⁴) residual).
    (4) the mixed gauge (erratum E7) moves the roots by > 1e-3 (observed up to 5.5 %).
    """
    alpha = float(jd.axial_wavenumber(GAUGE_TUBE, 2))
    lib = {n: roots(GAUGE_TUBE, alpha, n_layers=n) for n in (30, 60)}
    assert np.all(np.isfinite(lib[30])) and lib[30][-1] < 19.0
    walls = {n: discretize_jit(GAUGE_TUBE, n) for n in (30, 60)}
    base = brentq_scan(walls[30], alpha, 0.0)
    print(f"\ngauge P=0: raw-det brentq vs jd.frequencies {rel(base, lib[30])}")
    assert base.size == N_ROOTS and np.all(rel(base, lib[30]) < 1e-9), (base, lib[30])
    rich_lib = (4.0 * lib[60] - lib[30]) / 3.0
    for shift in (0.3, -0.5):
        shifted30 = brentq_scan(shift_gauge(walls[30], shift, shift), alpha, shift)
        assert shifted30.size == N_ROOTS
        shifted60 = brentq_near(shift_gauge(walls[60], shift, shift), alpha, shift, lib[60])
        d30, d60 = shifted30 - lib[30], shifted60 - lib[60]
        rich = (4.0 * shifted60 - shifted30) / 3.0
        print(f"gauge P={shift}: |dOmega|/Omega N=30 {np.abs(d30) / lib[30]}, "
              f"ratio N=30/N=60 {d30 / d60}, Richardson {rel(rich, rich_lib)}")
        assert np.all(np.abs(d30) < 1e-5 * lib[30])
        assert np.all((d30 / d60 > 3.0) & (d30 / d60 < 5.0))
        assert np.all(rel(rich, rich_lib) < 1e-9)
    # Mixed gauge (erratum E7): p(r̂) shifted but boundary conditions left in the P̂_o = 0 gauge.
    # A different (wrong) problem: the roots move far beyond the laminate-level differences above.
    mixed = brentq_scan(shift_gauge(walls[30], 0.3, 0.0), alpha, 0.0)
    moved = rel(mixed[:N_ROOTS], lib[30]) if mixed.size >= N_ROOTS else np.array([np.inf])
    print(f"gauge mixed (p + 0.3 only): relative shifts {moved}")
    assert np.max(moved) > 1e-3


# ------------------------------------------------------------------- (g) laminate convergence


def richardson(tube, alpha, n_coarse):
    """(4Ω(2N) − Ω(N))/3: removes the c·N⁻² laminate error, leaving O(N⁻⁴)."""
    coarse = roots(tube, alpha, n_layers=n_coarse)
    fine = roots(tube, alpha, n_layers=2 * n_coarse)
    return (4.0 * fine - coarse) / 3.0


def check_laminate_error(tube, alpha, n_coarse):
    """Relative N = 30 error against the Richardson limit; the NaN pattern (roots that do not
    exist, e.g. beyond the critical voltage) must be the same at every N."""
    om30, rich = roots(tube, alpha, n_layers=30), richardson(tube, alpha, n_coarse)
    assert np.array_equal(np.isfinite(om30), np.isfinite(rich)), (om30, rich)
    assert np.sum(np.isfinite(om30)) >= 2
    err = rel(om30, rich)
    ok = np.isfinite(om30)
    # theory.md §7: 1e-7 … 1e-5 typically, up to ~2e-4 near a critical voltage → 5e-4.
    assert np.all(err[ok] < 5e-4), (om30, rich, err)
    return om30, err


@pytest.mark.parametrize("lambda_i, voltage", PAPER_TUBES)
def test_paper_tube_laminate_error(lambda_i, voltage):
    """The paper's tube (η = 0.85, λ_z = 1.2), n = 1, 2, 3: the N = 30 roots agree with the
    Richardson limit to 5e-4 relative.

    Fast variant: Richardson from N = 30, 60 (the N⁻² law it relies on is verified in test (a); its
    residual is O(N⁻⁴), i.e. ≤ 1 % of the N = 30 error). The slow tests use N = 60, 120 (a further
    compile of ~15 s). At λ_i = 1.1, V̂ = 0.2 the tube is just below V̂_cr(n = 1) ≈ 0.2025 and
    beyond V̂_cr(n = 2, 3) ≈ 0.191, 0.175: the lowest root has left the real axis there (fewer
    roots, the same at every N).
    """
    tube = paper_tube(lambda_i, voltage)
    for n in (1, 2, 3):
        om30, err = check_laminate_error(tube, float(jd.axial_wavenumber(tube, n)), 30)
        print(f"\npaper tube lambda_i={lambda_i} V={voltage} n={n}: {om30} err30 {err}")


@pytest.mark.slow
def test_paper_tube_laminate_error_table():
    """N = 30 laminate error against Richardson from N = 60, 120, for n = 1 … 10 and the four paper
    tubes: same 5e-4 bound, and a printed table of the max and median relative error per root index
    over n (run with ``-m slow -s``)."""
    every = {k: [] for k in range(N_ROOTS)}
    print()
    for lambda_i, voltage in PAPER_TUBES:
        tube = paper_tube(lambda_i, voltage)
        per_root = {k: [] for k in range(N_ROOTS)}
        for n in range(1, 11):
            om30, err = check_laminate_error(tube, float(jd.axial_wavenumber(tube, n)), 60)
            print(f"lambda_i={lambda_i} V={voltage} n={n:2d} Omega30="
                  + " ".join(f"{w:10.6f}" for w in om30)
                  + "  err=" + " ".join(f"{e:8.1e}" for e in err))
            for k in range(N_ROOTS):
                if np.isfinite(err[k]):
                    per_root[k].append(err[k])
                    every[k].append(err[k])
        for k in range(N_ROOTS):
            e = np.array(per_root[k])
            if e.size:
                print(f"  lambda_i={lambda_i} V={voltage} root {k + 1}: max {e.max():.2e} "
                      f"median {np.median(e):.2e} ({e.size} values)")
    for k in range(N_ROOTS):
        e = np.array(every[k])
        print(f"all four tubes, root {k + 1}: max {e.max():.2e} median {np.median(e):.2e} "
              f"({e.size} values)")
