"""Inverse characterisation (jaxdea.fit): recovery of parameters from synthetic resonances made
independently (units.Scales, units.tube_from_si, frequencies), exact Jacobian against central
differences, identifiability warning, assignment of unlabelled peaks, input validation, the CSV
peak files, ``jaxdea fit`` (summary, JSON, plot, one-line errors) and the coverage of the 95 %
intervals over noisy replicates.

A VHB-like tube: μ = 1e5 Pa, ρ_s = 1000 kg/m³, ε = 4.7 ε_0, R_i = 5 mm, L = 50 mm, η = 0.85,
λ_z = 1.2, λ_i = 1, G = 97. Its voltage unit R_i sqrt(μ/ε) is 245 kV and its first instability
(m ≤ 3, n ≤ 3) is at V̂ = 0.086, 21 kV: the data at 2 and 5 kV are well below it.
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxdea as jd
from jaxdea.physics.families import Family
from jaxdea.studies.fit import (
    NAMES,
    FitStatus,
    IdentifiabilityWarning,
    dimensionless,
    fit,
    mode_roots,
    model_and_jacobian,
)
from jaxdea.units import VACUUM_PERMITTIVITY, Scales, fluid_from_si, tube_from_si

N_LAYERS = 12  # the same N for the data and the model
TRUTH = dict(shear_modulus=1e5, density=1000.0, permittivity=4.7 * VACUUM_PERMITTIVITY,
             inner_radius=5e-3, length=50e-3, eta=0.85, lambda_i=1.0, lambda_z=1.2, gent=97.0)
VOLTAGES = (2e3, 5e3)
LABELLED = [(v, m, n) for v in VOLTAGES for m in (0, 1) for n in (1, 2)]


def synthetic(points, truth=TRUTH, **wall):
    """Peaks (V, m, n) of the lowest branch in Hz, through the public SI conversions (``wall``: the
    tube's ``material`` or ``layers``, tests/test_fit_walls.py)."""
    scales = Scales(truth["shear_modulus"], truth["density"], truth["permittivity"],
                    truth["inner_radius"])
    rows = []
    for voltage, m, n in points:
        tube = tube_from_si(scales, outer_radius=truth["inner_radius"] / truth["eta"],
                            length=truth["length"], voltage=voltage, lambda_i=truth["lambda_i"],
                            lambda_z=truth["lambda_z"], gent=truth.get("gent", 97.2)).replace(**wall)
        omega = jd.frequencies(tube, jd.axial_wavenumber(tube, n), n_roots=1, m=m,
                               n_layers=N_LAYERS)[0]
        rows.append((voltage, float(scales.omega_to_hz(omega)), m, n))
    table = np.array(rows)
    return dict(voltage_V=table[:, 0], frequency_Hz=table[:, 1], m=table[:, 2].astype(int),
                n=table[:, 3].astype(int))


def split(free_names):
    free = {k: (0.5 * TRUTH[k], 1.5 * TRUTH[k]) for k in free_names}
    if "eta" in free:
        free["eta"] = (0.6, 0.95)
    fixed = {k: v for k, v in TRUTH.items() if k not in free}
    return free, fixed


GOOD = dict(voltage_V=[1e3, 2e3, 3e3, 4e3], frequency_Hz=[100.0, 110.0, 120.0, 130.0])


@pytest.mark.parametrize("change, match", [
    (dict(free={"stiffness": (1.0, 2.0)}), "stiffness"),
    (dict(free={"gent": (50.0, 150.0)}, fixed={"gent": 97.0}), "gent.*both free and fixed"),
    (dict(free={"shear_modulus": (2e5, 1e5)}), "shear_modulus.*lower < upper"),
    (dict(free={"shear_modulus": (1e5, np.inf)}), "shear_modulus.*finite"),
    (dict(fixed={"fluid_density": 1000.0}), "fluid_density.*fluid"),
    (dict(fixed={"gent": np.nan}), "gent"),
    (dict(fixed={"density": -1000.0}), "density.*\\(0, inf\\)"),
    (dict(free={"shear_modulus": (5e4, 2e5), "eta": (0.8, 1.2)}), "eta.*\\(0, 1\\)"),
    (dict(data=dict(voltage_V=GOOD["voltage_V"])), "frequency_Hz"),
    (dict(data=dict(GOOD, frequency_Hz=[100.0, np.nan, 120.0, 130.0])), "frequency_Hz.*finite"),
    (dict(data=dict(GOOD, sigma_Hz=[1.0, 1.0, 0.0, 1.0])), "sigma_Hz"),
    (dict(data=dict(GOOD, m=[0, 0, 1, 1])), "'m' and 'n'"),
    (dict(data=dict(GOOD, m=[0, 0, 1, 1], n=[1, 0, 1, 1])), "'n'"),
    (dict(data=dict(GOOD, voltage_V=[1e3, 2e3])), "voltage_V"),
    (dict(fluid="water"), "fluid"),
])
def test_bad_input_raises_naming_the_parameter(change, match):
    free, fixed = split(["shear_modulus"])
    args = dict(data=GOOD, free=free, fluid=None) | change
    with pytest.raises(ValueError, match=match):
        fixed = {k: v for k, v in fixed.items() if k not in args["free"]}
        fit(args["data"], args["free"], fixed | change.get("fixed", {}), args["fluid"],
                    n_layers=N_LAYERS)


def test_missing_parameter_raises():
    free, fixed = split(["shear_modulus"])
    del fixed["length"]
    with pytest.raises(ValueError, match="length.*neither free nor fixed"):
        fit(GOOD, free, fixed)


@pytest.mark.slow
def test_recovers_three_parameters_from_a_start_twenty_percent_off():
    data = synthetic(LABELLED)
    free, fixed = split(["shear_modulus", "lambda_i", "eta"])
    initial = dict(shear_modulus=1.2e5, lambda_i=0.8, eta=0.85 * 0.8)
    result = fit(data, free, fixed, initial=initial, n_layers=N_LAYERS, n_starts=1,
                         grid_points=1)
    assert result.status == FitStatus.CONVERGED
    for name in free:
        assert abs(result.estimate[name] / TRUTH[name] - 1.0) <= 1e-8, name
        low, high = result.interval[name]  # noise-free: rounding-wide around the estimate
        assert low < result.estimate[name] < high and high - low < 1e-8 * TRUTH[name], name
    np.testing.assert_array_equal(result.assignment, np.stack([data["m"], data["n"],
                                                               0 * data["m"]], axis=1))
    assert np.max(np.abs(result.residuals)) < 1e-9 * np.max(data["frequency_Hz"])


@pytest.mark.slow
def test_jacobian_matches_central_differences():
    """∂f/∂θ by jacfwd through the implicit derivatives against central differences of the
    global root scan (relative step 1e-5: truncation ~1e-10, rounding ~1e-13/1e-5 = 1e-8)."""
    values = jnp.array([TRUTH[k] for k in NAMES[:9]] + [0.0, 1.0, 1.0])
    voltage = jnp.array([2e3, 5e3, 2e3, 5e3, 2e3, 5e3, 2e3, 5e3])
    n = jnp.array([1.0, 1.0, 2.0, 2.0, 1.0, 1.0, 2.0, 2.0])
    for family, m in ((Family.LONGITUDINAL, jnp.zeros(8)),
                      (Family.ORDER_M, jnp.array([1.0, 1, 1, 1, 2, 2, 2, 2]))):
        roots = mode_roots(values, voltage, n, m, 1, N_LAYERS, None, None, family)
        _, f, jac = model_and_jacobian(values, voltage, n, m, roots[:, 0], N_LAYERS, None,
                                               None, family)
        hz = dimensionless(values, 0.0, 1.0)[3]
        np.testing.assert_allclose(f, roots[:, 0] * hz, rtol=1e-12)
        for i in range(9):
            h = 1e-5 * values[i]

            def f_at(x, i=i, m=m, family=family):
                shifted = values.at[i].set(x)
                scan = mode_roots(shifted, voltage, n, m, 1, N_LAYERS, None, None, family)
                return scan[:, 0] * dimensionless(shifted, 0.0, 1.0)[3]

            central = (f_at(values[i] + h) - f_at(values[i] - h)) / (2 * h)
            scale = np.max(np.abs(central)) + np.max(np.abs(f)) / abs(values[i])
            np.testing.assert_allclose(jac[:, i], central, rtol=0, atol=1e-6 * scale,
                                       err_msg=NAMES[i])


def test_determinant_derivative_is_the_cofactor_sum_at_a_decoupled_root():
    """d det(a)[ȧ] = tr(adj(a) ȧ) at a singular 4×4 of the V = 0 structure (row Φ = (0, 0, 0, x),
    rank 3: the LU's zero pivot is not the last), the adjugate from NumPy minors; a regular matrix
    matches jnp.linalg.det's derivative, and the second derivative central differences."""
    from jaxdea.physics.dispersion import determinant

    rng = np.random.default_rng(3)
    block = rng.standard_normal((3, 3))
    block[:, 2] = block[:, :2] @ np.array([0.3, -1.1])  # singular mechanical block
    a = np.zeros((4, 4))
    a[0, 3], a[1:, :3] = -0.55, block
    tangent = rng.standard_normal((4, 4))

    def adjugate(x):
        out = np.empty_like(x)
        for i in range(4):
            for j in range(4):
                minor = np.delete(np.delete(x, i, 0), j, 1)
                out[j, i] = (-1) ** (i + j) * np.linalg.det(minor)
        return out

    batch = jax.jit(jax.vmap(lambda x, t: jax.jvp(determinant, (x,), (t,))[1]))
    slopes = batch(jnp.broadcast_to(a, (8, 4, 4)), jnp.broadcast_to(tangent, (8, 4, 4)))
    np.testing.assert_allclose(slopes, np.trace(adjugate(a) @ tangent), rtol=1e-13)
    regular = rng.standard_normal((4, 4))
    np.testing.assert_allclose(jax.jvp(determinant, (regular,), (tangent,))[1],
                               jax.jvp(jnp.linalg.det, (regular,), (tangent,))[1], rtol=1e-12)
    second = jax.grad(jax.grad(lambda s: determinant(regular + s * tangent)))(0.0)
    h = 1e-4
    central = sum(c * float(np.linalg.det(regular + k * h * tangent))
                  for c, k in ((1, 1), (-2, 0), (1, -1))) / h**2
    assert abs(second - central) < 1e-6 * max(1.0, abs(central))


@pytest.mark.slow
def test_batched_jacobian_at_zero_voltage_equals_the_point_alone():
    """At V = 0 the wall is electrically decoupled: the outer-row matrix Out·Q of order m has the
    row Φ = (0, 0, 0, x), so at a root its LU puts the near-zero pivot before the last, where
    ``jnp.linalg.det``'s derivative divides by it. In a batch of 8 (m = 1, 2, 3; the second
    branch) that gave a NaN row for (m, n) = (2, 3) while the point alone was finite; the
    cofactor derivative of :func:`jaxdea.physics.dispersion.determinant` gives the same row both ways."""
    values = jnp.array([TRUTH[k] for k in NAMES[:5]] + [0.8793051947943465, 1.0386270426677653,
                                                        1.1771011315898126, TRUTH["gent"], 0.0,
                                                        1.0, 1.0])
    n = jnp.array([1.0, 2, 3, 1, 2, 3, 1, 2])
    m = jnp.array([2.0, 2, 2, 1, 1, 1, 3, 3])
    roots = mode_roots(values, jnp.zeros(8), n, m, 2, N_LAYERS, None, None, Family.ORDER_M)
    _, _, jac = model_and_jacobian(values, jnp.zeros(8), n, m, roots[:, 1], N_LAYERS, None, None,
                                   Family.ORDER_M)
    assert np.all(np.isfinite(jac))

    def alone(vals):
        tube, alpha, fluid, hz = dimensionless(vals, 0.0, 3.0)
        return jd.frequency(tube, alpha, roots[2, 1], fluid, N_LAYERS, m=2) * hz

    np.testing.assert_allclose(jac[2], jax.jacfwd(alone)(values), rtol=1e-10, atol=0.0)


@pytest.mark.slow
@pytest.mark.parametrize("names, voltages", [
    (("shear_modulus", "density", "permittivity"), VOLTAGES),  # μ, ρ_s, ε scaled together
    (("shear_modulus", "density"), (0.0,)),  # at V = 0 only μ/ρ_s enters
])
def test_rank_deficient_combination_warns_and_ratios_are_recovered(names, voltages):
    """Scaling μ, ρ_s and ε together leaves c_s = sqrt(μ/ρ_s) and V̂ ∝ sqrt(ε/μ) unchanged (at
    V = 0, μ and ρ_s alone): only those ratios are determined, they are recovered, and the
    warning names the parameters of the combination."""
    data = synthetic([(v, m, n) for v in voltages for m in (0, 1) for n in (1, 2)])
    free, fixed = split(names)
    initial = dict(shear_modulus=1.2e5, density=900.0, permittivity=TRUTH["permittivity"] * 1.1)
    with pytest.warns(IdentifiabilityWarning, match=".*".join(names)):
        result = fit(data, free, fixed, initial={k: initial[k] for k in names},
                             n_layers=N_LAYERS, n_starts=1, grid_points=1)
    est = result.estimate
    speed = est["shear_modulus"] / est["density"]
    assert abs(speed / (TRUTH["shear_modulus"] / TRUTH["density"]) - 1.0) < 1e-8
    if "permittivity" in names:
        field = est["permittivity"] / est["shear_modulus"]
        assert abs(field / (TRUTH["permittivity"] / TRUTH["shear_modulus"]) - 1.0) < 1e-8
    assert all(np.isnan(result.interval[k]).all() for k in free)


@pytest.mark.slow
def test_unlabelled_peaks_of_orders_zero_one_two_are_assigned():
    points = [(v, m, n) for v in VOLTAGES for m, n in ((0, 1), (0, 2), (1, 1), (2, 1))]
    labelled = synthetic(points)
    data = dict(voltage_V=labelled["voltage_V"], frequency_Hz=labelled["frequency_Hz"])
    free, fixed = split(["shear_modulus", "lambda_i"])
    result = fit(data, free, fixed, initial=dict(shear_modulus=0.8e5, lambda_i=1.1),
                         n_layers=N_LAYERS, m_max=2, n_max=2, n_branches=1, n_starts=2)
    expected = np.stack([labelled["m"], labelled["n"], 0 * labelled["m"]], axis=1)
    np.testing.assert_array_equal(result.assignment, expected)
    assert result.status == FitStatus.CONVERGED
    for name in free:
        assert abs(result.estimate[name] / TRUTH[name] - 1.0) <= 1e-8, name



@pytest.mark.slow
def test_covariance_is_the_inverse_normal_matrix_of_central_differences():
    """With σ given: cov = (JᵀJ)⁻¹, J = ∂r/∂θ here by central differences of the global root scan,
    and the 95 % interval is θ ± 1.959964 sqrt(cov_ii) (normal quantile)."""
    data = synthetic(LABELLED)
    data["sigma_Hz"] = 0.01 * data["frequency_Hz"]
    free, fixed = split(["shear_modulus", "lambda_i"])
    result = fit(data, free, fixed, initial=dict(shear_modulus=1.1e5, lambda_i=0.95),
                         n_layers=N_LAYERS, n_starts=1, grid_points=1)
    assert result.status == FitStatus.CONVERGED
    values = jnp.array([result.estimate.get(k, TRUTH.get(k, 1.0)) for k in NAMES[:9]]
                       + [0.0, 1.0, 1.0])
    m = data["m"]
    columns = []
    for name in result.names:
        i = NAMES.index(name)
        h = 1e-5 * values[i]
        sides = []
        for x in (values[i] + h, values[i] - h):
            shifted = values.at[i].set(x)
            f = np.empty(m.size)
            for family in (Family.LONGITUDINAL, Family.ORDER_M):
                rows = np.resize(np.flatnonzero((m == 0) == (family is Family.LONGITUDINAL)), 8)
                scan = mode_roots(shifted, jnp.asarray(data["voltage_V"][rows]),
                                          jnp.asarray(data["n"][rows], float),
                                          jnp.asarray(m[rows], float), 1, N_LAYERS, None, None,
                                          family)
                f[rows] = np.asarray(scan[:, 0]) * float(dimensionless(shifted, 0.0,
                                                                               1.0)[3])
            sides.append(f)
        columns.append((sides[0] - sides[1]) / (2 * h) / data["sigma_Hz"])
    jac = np.stack(columns, axis=1)
    np.testing.assert_allclose(result.covariance, np.linalg.inv(jac.T @ jac), rtol=1e-5)
    for i, name in enumerate(result.names):
        half = 0.5 * (result.interval[name][1] - result.interval[name][0])
        assert abs(half / (1.959964 * np.sqrt(result.covariance[i, i])) - 1) < 1e-6


@pytest.mark.slow
def test_grid_start_converges_without_an_initial_guess():
    """No ``initial``: the best of a 3 × 3 grid of starts inside wide bounds reaches the truth."""
    data = synthetic(LABELLED)
    free, fixed = split(["shear_modulus", "lambda_i"])
    result = fit(data, free, fixed, n_layers=N_LAYERS, n_starts=2, grid_points=3)
    assert result.status == FitStatus.CONVERGED
    for name in free:
        assert abs(result.estimate[name] / TRUTH[name] - 1.0) <= 1e-8, name


@pytest.mark.slow
def test_water_filled_tube_recovers_modulus_and_fluid_density():
    """Acoustic coupling: ρ̂_f = ρ_f/ρ_s, ĉ_f = c_f/c_s from the SI names (units.fluid_from_si);
    both to 1e-8 on exact peaks, with the μ–ρ_f correlation beyond 0.99 named in a warning."""
    truth = TRUTH | dict(fluid_density=1000.0, fluid_speed=1480.0)
    scales = Scales(truth["shear_modulus"], truth["density"], truth["permittivity"],
                    truth["inner_radius"])
    water = fluid_from_si(scales, truth["fluid_density"], truth["fluid_speed"])
    rows = []
    for voltage, m, n in LABELLED:
        tube = tube_from_si(scales, outer_radius=truth["inner_radius"] / truth["eta"],
                            length=truth["length"], voltage=voltage, lambda_i=truth["lambda_i"],
                            lambda_z=truth["lambda_z"], gent=truth["gent"])
        omega = jd.frequencies(tube, jd.axial_wavenumber(tube, n), water, n_roots=1, m=m,
                               n_layers=N_LAYERS)[0]
        rows.append((voltage, float(scales.omega_to_hz(omega)), m, n))
    table = np.array(rows)
    data = dict(voltage_V=table[:, 0], frequency_Hz=table[:, 1], m=table[:, 2].astype(int),
                n=table[:, 3].astype(int))
    free = dict(shear_modulus=(5e4, 2e5), fluid_density=(500.0, 2000.0))
    fixed = {k: v for k, v in truth.items() if k not in free}
    # these eight peaks determine μ and ρ_f through a combination (correlation +0.995): said
    with pytest.warns(IdentifiabilityWarning, match="shear_modulus and fluid_density"):
        result = fit(data, free, fixed, fluid="acoustic",
                     initial=dict(shear_modulus=1.2e5, fluid_density=800.0),
                     n_layers=N_LAYERS, n_starts=1, grid_points=1)
    assert result.status == FitStatus.CONVERGED
    for name in free:
        assert abs(result.estimate[name] / truth[name] - 1.0) <= 1e-8, name


# ---------------------------------------------------------------------------------------------
# bad data and starts that fit rejects before any computation


@pytest.mark.parametrize("change, match", [
    (dict(data=dict(GOOD, frequency_Hz=[100.0, -110.0, 120.0, 130.0])), "frequency_Hz.*> 0"),
    (dict(data=dict(GOOD, sigma_Hz=[1.0, np.nan, 1.0, 1.0])), "sigma_Hz.*finite"),
    (dict(data=dict(voltage_V=[1e3, 2e3], frequency_Hz=[100.0, 110.0]),
          free={"shear_modulus": (5e4, 2e5), "lambda_i": (0.8, 1.2)}), "2 rows.*more than 2"),
    (dict(initial={"shear_modulus": 3e5}), "initial\\['shear_modulus'\\].*inside"),
    (dict(initial={"shear_modulus": 1e5, "lambda_i": 1.0}), "initial.*'lambda_i'.*not a free"),
    (dict(initial={"shear_modulus": "soft"}), "initial\\['shear_modulus'\\].*real number"),
])
def test_bad_data_or_start_raises_naming_the_column_or_key(change, match):
    free = change.get("free", {"shear_modulus": (5e4, 2e5)})
    fixed = {k: v for k, v in TRUTH.items() if k not in free}
    with pytest.raises(ValueError, match=match):
        fit(change.get("data", GOOD), free, fixed, initial=change.get("initial"),
            n_layers=N_LAYERS)


# ---------------------------------------------------------------------------------------------
# CSV files


def test_peaks_round_trip_through_csv_bit_for_bit(tmp_path):
    rng = np.random.default_rng(0)
    data = dict(voltage_V=rng.uniform(0, 5e3, 7), frequency_Hz=rng.uniform(10, 500, 7),
                sigma_Hz=rng.uniform(0.1, 1, 7), m=np.array([0, 1, 2, 0, 1, 2, 0]),
                n=np.array([1, 1, 1, 2, 2, 2, 3]), branch=np.array([0, 0, 1, 0, 0, 1, 0]))
    path = jd.write_peaks(tmp_path / "peaks.csv", data)
    back = jd.read_peaks(path)
    assert list(back) == list(data)
    for name, column in data.items():
        np.testing.assert_array_equal(back[name], column, err_msg=name)
        assert back[name].dtype == (int if name in ("m", "n", "branch") else np.float64)
    assert path.read_text().splitlines()[0] == "voltage_V,frequency_Hz,sigma_Hz,m,n,branch"


def test_read_peaks_skips_comments_and_accepts_any_column_order(tmp_path):
    path = tmp_path / "peaks.csv"
    path.write_text("# peaks of tube 3\nfrequency_Hz, voltage_V\n\n41.5, 2000\n# noisy\n40.25, 5e3\n")
    peaks = jd.read_peaks(path)
    assert list(peaks) == ["voltage_V", "frequency_Hz"]
    np.testing.assert_array_equal(peaks["voltage_V"], [2000.0, 5000.0])
    np.testing.assert_array_equal(peaks["frequency_Hz"], [41.5, 40.25])


@pytest.mark.parametrize("text, match", [
    ("voltage_V,frequency_Hz\n1000,nan\n", "line 2, column 'frequency_Hz'.*'nan' is not a finite"),
    ("voltage_V,frequency_Hz\n1000,40\n2000,-41\n", "line 3, column 'frequency_Hz'.*-41 Hz.*> 0"),
    ("voltage_V,frequency_Hz,sigma_Hz\n1000,40,0\n", "column 'sigma_Hz'.*> 0"),
    ("voltage_V,frequency_Hz\n1000,forty\n", "column 'frequency_Hz'.*'forty' is not a number"),
    ("voltage_V,frequency_Hz\n1000,\n", "column 'frequency_Hz'.*'' is not a number"),
    ("voltage_V,frequency_Hz\ninf,40\n", "column 'voltage_V'.*not a finite"),
    ("voltage_V,frequency_Hz,m,n\n1000,40,0,0\n", "column 'n'.*integer >= 1"),
    ("voltage_V,frequency_Hz,m,n\n1000,40,0.5,1\n", "column 'm'.*integer >= 0"),
    ("voltage_V,frequency_Hz,mode\n1000,40,1\n", "unknown column 'mode'"),
    ("voltage_V,frequency_Hz,voltage_V\n1000,40,1\n", "'voltage_V' appears twice"),
    ("voltage_V,sigma_Hz\n1000,1\n", "missing the column 'frequency_Hz'"),
    ("voltage_V,frequency_Hz\n1000,40,3\n", "line 2: 3 fields, the header has 2"),
    ("voltage_V,frequency_Hz\n", "no data rows"),
    ("", "no header"),
])
def test_read_peaks_names_the_bad_column_and_line(tmp_path, text, match):
    path = tmp_path / "peaks.csv"
    path.write_text(text)
    with pytest.raises(ValueError, match=match):
        jd.read_peaks(path)


def test_read_peaks_of_a_missing_file_raises_value_error(tmp_path):
    with pytest.raises(ValueError, match="cannot read .*absent.csv"):
        jd.read_peaks(tmp_path / "absent.csv")


def test_fit_reads_a_csv_path(tmp_path):
    """A path is read by read_peaks: its errors name the line; its columns reach the checks."""
    free, fixed = split(["shear_modulus"])
    (tmp_path / "bad.csv").write_text("voltage_V,frequency_Hz\n1000,40\n2000,-41\n")
    with pytest.raises(ValueError, match="line 3, column 'frequency_Hz'"):
        fit(str(tmp_path / "bad.csv"), free, fixed)
    jd.write_peaks(tmp_path / "two.csv", dict(voltage_V=[1e3, 2e3], frequency_Hz=[40.0, 41.0]))
    free["lambda_i"] = (0.8, 1.2)
    with pytest.raises(ValueError, match="data has 2 rows"):
        fit(tmp_path / "two.csv", free, {k: v for k, v in fixed.items() if k != "lambda_i"})


# ---------------------------------------------------------------------------------------------
# the command line: jaxdea fit DATA.csv --config fit.toml


# The lowest m = 0 peaks of the TRUTH tube at N = N_LAYERS (synthetic(CLI_POINTS); checked against
# it by test_cli_peaks_are_the_synthetic_ones, slow tier): written out so that the default tier
# does not compile the forward solver.
CLI_POINTS = [(v, 0, n) for v in VOLTAGES for n in (1, 2)]
CLI_HZ = [286.6163852639979, 495.4180098993502, 286.6060579867368, 495.16844674470013]
CLI_CONFIG = """\
[free]
shear_modulus = {lower = 5e4, upper = 2e5, initial = 1.1e5}
lambda_i = {lower = 0.8, upper = 1.2, initial = 0.95}

[fixed]
density = 1000.0
permittivity = PERMITTIVITY
inner_radius = 5e-3
length = 50e-3
eta = 0.85
lambda_z = 1.2
gent = 97.0

[options]
n_layers = 12
n_starts = 1
grid_points = 1
""".replace("PERMITTIVITY", repr(TRUTH["permittivity"]))


def cli_peaks(labelled=True):
    table = np.array(CLI_POINTS, dtype=float)
    data = dict(voltage_V=table[:, 0], frequency_Hz=np.array(CLI_HZ))
    if labelled:
        data.update(m=table[:, 1].astype(int), n=table[:, 2].astype(int))
    return data


@pytest.mark.slow
def test_cli_peaks_are_the_synthetic_ones():
    np.testing.assert_allclose(CLI_HZ, synthetic(CLI_POINTS)["frequency_Hz"], rtol=1e-13)


@pytest.fixture(scope="module")
def cli_run(tmp_path_factory):
    """``jaxdea fit peaks.csv --config fit.toml --out out`` once: (folder, exit status, stdout)."""
    from jaxdea.apps import cli

    folder = tmp_path_factory.mktemp("fit_cli")
    jd.write_peaks(folder / "peaks.csv", cli_peaks())
    (folder / "fit.toml").write_text(CLI_CONFIG)
    import contextlib
    import io

    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        status = cli.main(["fit", str(folder / "peaks.csv"), "--config", str(folder / "fit.toml"),
                           "--out", str(folder / "out")])
    return folder, status, out.getvalue(), err.getvalue()


@pytest.mark.slow  # the first fit of a process traces the root scan: > 20 s
def test_cli_fit_recovers_the_truth_and_writes_json_and_png(cli_run):
    import json

    folder, status, out, err = cli_run
    assert status == 0, err
    json_path, png_path = folder / "out" / "peaks_fit.json", folder / "out" / "peaks_fit.png"
    assert out.splitlines()[-2:] == [str(json_path), str(png_path)]
    assert png_path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    saved = json.loads(json_path.read_text())
    assert saved["status"] == "CONVERGED" and saved["names"] == ["shear_modulus", "lambda_i"]
    for name in saved["names"]:
        assert abs(saved["estimate"][name] / TRUTH[name] - 1.0) < 1e-8, name
        low, high = saved["interval"][name]
        assert low < saved["estimate"][name] < high
    assert np.array(saved["covariance"]).shape == (2, 2)
    assert [(p["m"], p["n"], p["branch"]) for p in saved["points"]] == \
        [(m, n, 0) for _, m, n in CLI_POINTS]
    np.testing.assert_allclose([p["model_Hz"] for p in saved["points"]], CLI_HZ, rtol=1e-9)
    assert saved["unmatched"] == [] and saved["parameters"]["gent"] == 97.0
    # the summary table: a row per parameter, the assignment of each peak, the status
    assert "status CONVERGED" in out and "unmatched peaks: none" in out
    row = next(line for line in out.splitlines() if line.startswith("shear_modulus"))
    assert abs(float(row.split()[1]) / 1e5 - 1.0) < 1e-6
    assert sum("(0, 1, 0)" in line for line in out.splitlines()) == 2


@pytest.mark.slow  # the first fit of a process traces the root scan: > 20 s
def test_plot_shows_the_fitted_curves_and_the_residuals(cli_run, tmp_path):
    """The curve of each mode passes through the exact peaks at the ends of the voltage range, and
    every plotted point is a root of the fitted model (Newton from it stays there)."""
    from jaxdea.studies.fit import model_and_jacobian

    folder = cli_run[0]
    data = jd.read_peaks(folder / "peaks.csv")
    free = {"shear_modulus": (5e4, 2e5), "lambda_i": (0.8, 1.2)}
    fixed = {k: v for k, v in TRUTH.items() if k not in free}
    result = fit(data, free, fixed, initial=dict(shear_modulus=1.1e5, lambda_i=0.95),
                 n_layers=N_LAYERS, n_starts=1, grid_points=1)
    fig = jd.plot_fit(result, data, tmp_path / "fit.png", points=5)
    assert len(fig.axes) == 2 and (tmp_path / "fit.png").stat().st_size > 0
    lines = [line for line in fig.axes[0].lines if line.get_label().startswith("(m, n")]
    assert [line.get_label() for line in lines] == ["(m, n, branch) = (0, 1, 0)",
                                                    "(m, n, branch) = (0, 2, 0)"]
    values = jnp.array([result.parameters.get(k, 1.0) for k in NAMES])
    scale = float(dimensionless(values, 0.0, 1.0)[3])
    for n, line in zip((1, 2), lines, strict=True):
        voltage, hz = line.get_xydata().T
        np.testing.assert_allclose(voltage, np.linspace(2e3, 5e3, 5))
        ends = [CLI_HZ[CLI_POINTS.index((v, 0, n))] for v in VOLTAGES]
        np.testing.assert_allclose(hz[[0, -1]], ends, rtol=1e-9)
        padded = np.resize(np.arange(5), 8)
        _, f, _ = model_and_jacobian(values, jnp.asarray(voltage[padded]),
                                     jnp.asarray(np.full(8, float(n))), jnp.asarray(np.zeros(8)),
                                     jnp.asarray(hz[padded] / scale), N_LAYERS, None, None,
                                     Family.LONGITUDINAL)
        np.testing.assert_allclose(np.asarray(f)[:5], hz, rtol=1e-12)
        assert np.all(np.diff(hz) < 0)  # the voltage softens the tube
    np.testing.assert_allclose(fig.axes[1].lines[0].get_ydata(), result.residuals[data["n"] == 1])
    np.testing.assert_allclose(jd.fitted_frequencies(result, [2e3, 5e3], 0, 2),
                               [CLI_HZ[1], CLI_HZ[3]], rtol=1e-9)


def _cli(argv):
    import contextlib
    import io

    from jaxdea.apps import cli

    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        status = cli.main(argv)
    return status, out.getvalue(), err.getvalue()


@pytest.mark.parametrize("config, data, match", [
    (CLI_CONFIG, None, "cannot read .*absent.csv"),
    (None, "peaks", "cannot read .*absent.toml"),
    (CLI_CONFIG.replace("[options]", "[solver]"), "peaks", "solver: unknown key"),
    (CLI_CONFIG.replace("n_starts = 1", "n_start = 1"), "peaks", "options.n_start: unknown key"),
    (CLI_CONFIG + "m_max = -1\n", "peaks", "m_max must be an integer >= 0"),
    (CLI_CONFIG + "threshold = \"wide\"\n", "peaks", "options.threshold: expected a number"),
    (CLI_CONFIG.replace("eta = 0.85", "etta = 0.85"), "peaks", "fixed.etta: unknown key"),
    (CLI_CONFIG.replace("lambda_i = {lower", "lambda_i = {low"), "peaks",
     "free.lambda_i.low: unknown key"),
    (CLI_CONFIG.replace("initial = 0.95", "initial = 1.5"), "peaks",
     "initial\\['lambda_i'\\] = 1.5 must lie strictly inside"),
    (CLI_CONFIG.replace("eta = 0.85\n", ""), "peaks", "eta.*neither free nor fixed"),
    (CLI_CONFIG.replace("[fixed]", "[fixed\n"), "peaks", "invalid TOML"),
    (CLI_CONFIG, "nan", "line 3, column 'frequency_Hz'"),
    (CLI_CONFIG, "negative", "line 2, column 'frequency_Hz'.*> 0"),
])
def test_cli_errors_are_one_line_with_exit_status_2(tmp_path, config, data, match):
    import re

    if config is not None:
        (tmp_path / "fit.toml").write_text(config)
    if data is not None:
        peaks = cli_peaks()
        if data == "nan":
            peaks["frequency_Hz"][1] = np.nan
        elif data == "negative":
            peaks["frequency_Hz"][0] *= -1
        path = tmp_path / "peaks.csv"
        path.write_text("\n".join([",".join(peaks)] + [
            ",".join(str(peaks[k][i]) for k in peaks) for i in range(len(CLI_POINTS))]) + "\n")
    status, out, err = _cli(["fit", str(tmp_path / ("peaks.csv" if data else "absent.csv")),
                             "--config", str(tmp_path / ("fit.toml" if config else "absent.toml"))])
    assert status == 2 and out == ""
    assert len(err.splitlines()) == 1 and err.startswith("jaxdea fit: error: "), err
    assert re.search(match, err), err
    assert "Traceback" not in err
    assert not list(tmp_path.glob("*_fit.*"))


def test_cli_output_folder_that_is_a_file_is_one_line_exit_2(tmp_path):
    jd.write_peaks(tmp_path / "peaks.csv", cli_peaks())
    (tmp_path / "fit.toml").write_text(CLI_CONFIG)
    (tmp_path / "taken").write_text("")
    status, _, err = _cli(["fit", str(tmp_path / "peaks.csv"), "--config",
                           str(tmp_path / "fit.toml"), "--out", str(tmp_path / "taken")])
    assert status == 2 and len(err.splitlines()) == 1 and "cannot write into" in err


def test_cli_unknown_flag_and_missing_config_exit_2():
    status, _, err = _cli(["fit", "peaks.csv", "--config", "fit.toml", "--bogus"])
    assert status == 2 and "unrecognized arguments: --bogus" in err.splitlines()[-1]
    status, _, err = _cli(["fit", "peaks.csv"])
    assert status == 2 and "--config" in err.splitlines()[-1]


def test_config_fluid_forms_and_key_errors():
    from jaxdea.io.fit_io import parse_fit_config

    base = dict(free={"shear_modulus": [5e4, 2e5]}, fixed={"density": 1000.0})
    assert parse_fit_config(base).fluid is None
    assert parse_fit_config(base | dict(fluid="acoustic")).fluid == "acoustic"
    paper = parse_fit_config(base | dict(fluid=dict(coupling="paper", bessel_order=1))).fluid
    assert isinstance(paper, jd.Fluid) and (paper.coupling, paper.bessel_order) == ("paper", 1)
    for change, match in [
        (dict(fixed={"fluid_density": 1000.0}), "fixed.fluid_density: a fluid parameter"),
        (dict(fluid="water"), "fluid: expected"),
        (dict(fluid=dict(coupling="paper", bessel_order=-1)), "fluid.bessel_order"),
        (dict(fluid=dict(speed=1480.0)), "fluid.speed: unknown key"),
        (dict(free={"shear_modulus": [5e4]}), "free.shear_modulus: expected"),
        (dict(free={"shear_modulus": {"lower": 5e4}}), "free.shear_modulus.upper: missing"),
        (dict(free={"shear_modulus": [5e4, "2e5"]}), "free.shear_modulus: expected a number"),
        (dict(fixed={"gent": float("nan")}), "fixed.gent: expected a finite number"),
        (dict(options={"n_layers": 12.0}), "options.n_layers: expected an integer"),
    ]:
        with pytest.raises(ValueError, match=match):
            parse_fit_config(base | change)
    assert parse_fit_config(base | dict(fixed={"gent": float("inf")})).fixed["gent"] == np.inf
    with pytest.raises(ValueError, match="fixed: missing table"):
        parse_fit_config(dict(free=base["free"]))


def test_fit_help_documents_every_config_key(capsys):
    from jaxdea.apps import cli
    from jaxdea.io import fit_io

    assert cli.main(["fit", "--help"]) == 0
    out = capsys.readouterr().out
    for key in (*(f"[{k}]" for k in fit_io.TOP_KEYS if k != "fluid"), *fit_io.FREE_KEYS,
                *fit_io.FLUID_KEYS, *fit_io.OPTION_KEYS, *NAMES, "--config", "--out"):
        assert key in out, key


# ---------------------------------------------------------------------------------------------
# coverage of the 95 % intervals


@pytest.mark.slow
def test_intervals_cover_the_truth_in_most_noisy_replicates():
    """40 replicates of six m = 0 peaks with 0.5 % Gaussian noise (σ given, fixed seeds): each
    parameter's 95 % interval holds the truth in at least 90 % of them (36–40, issue 43; a
    binomial(40, 0.95) count is below 36 with probability 0.14, so the seeds are fixed)."""
    points = [(v, 0, n) for v in (1e3, 3e3, 5e3) for n in (1, 2)]
    clean = synthetic(points)
    sigma = 0.005 * clean["frequency_Hz"]
    free, fixed = split(["shear_modulus", "lambda_i"])
    covered = dict.fromkeys(free, 0)
    for seed in range(40):
        noise = np.random.default_rng(seed).standard_normal(len(points))
        data = dict(clean, frequency_Hz=clean["frequency_Hz"] + sigma * noise, sigma_Hz=sigma)
        result = fit(data, free, fixed, initial=dict(shear_modulus=1.05e5, lambda_i=0.97),
                     n_layers=N_LAYERS, n_starts=1, grid_points=1)
        assert result.status == FitStatus.CONVERGED, seed
        for name in free:
            low, high = result.interval[name]
            covered[name] += int(low <= TRUTH[name] <= high)
    for name, count in covered.items():
        assert 36 <= count <= 40, (name, count)


@pytest.mark.slow
def test_gent_interval_covers_the_truth_in_most_noisy_replicates():
    """The Gent constant's 95 % interval over 40 replicates: a strongly stiffening, inflated tube
    (G = 10, λ_i = 1.3), twelve peaks (m = 0, 1; n = 1, 2) at 2, 5, 8 kV with 0.5 % noise, μ and
    G free: G is identified (a two-sided interval inside its bounds (2, 100), about [9.1, 13.7],
    in most replicates; at λ_i = 1 it is not) but the frequencies are far from linear in G, and
    the interval (Wald on 1/G, mapped; the profile-likelihood end where it would leave the
    bounds) holds the truth in >= 36 of 40, as does μ's (issue 43)."""
    truth = dict(TRUTH, gent=10.0, lambda_i=1.3)
    points = [(v, m, n) for v in (2e3, 5e3, 8e3) for m in (0, 1) for n in (1, 2)]
    clean = synthetic(points, truth)
    sigma = 0.005 * clean["frequency_Hz"]
    free = dict(shear_modulus=(5e4, 2e5), gent=(2.0, 100.0))
    fixed = {k: v for k, v in truth.items() if k not in free}
    covered, two_sided = dict.fromkeys(free, 0), 0
    for seed in range(40):
        noise = np.random.default_rng(100 + seed).standard_normal(len(points))
        data = dict(clean, frequency_Hz=clean["frequency_Hz"] + sigma * noise, sigma_Hz=sigma)
        result = fit(data, free, fixed, initial=dict(shear_modulus=1.05e5, gent=12.0),
                     n_layers=N_LAYERS, n_starts=0)
        assert result.status == FitStatus.CONVERGED, seed
        for name in free:
            low, high = result.interval[name]
            assert free[name][0] <= low <= result.estimate[name] <= high <= free[name][1]
            covered[name] += int(low <= truth[name] <= high)
        two_sided += int(free["gent"][0] < result.interval["gent"][0]
                         and result.interval["gent"][1] < free["gent"][1])
    assert two_sided >= 30, two_sided
    for name, count in covered.items():
        assert 36 <= count <= 40, (name, count)


# ---------------------------------------------------------------------------------------------
# the shipped example


EXAMPLES = __import__("pathlib").Path(__file__).parents[1] / "examples"


def test_example_peaks_and_config_are_valid():
    from jaxdea.io.fit_io import load_fit_config

    config = load_fit_config(EXAMPLES / "fit.toml")
    peaks = jd.read_peaks(EXAMPLES / "peaks.csv")
    assert config.free == {"shear_modulus": (5e4, 2e5), "lambda_i": (0.8, 1.2)}
    assert config.initial == {"shear_modulus": 1.1e5, "lambda_i": 0.95}
    assert config.options == dict(n_layers=30, m_max=2, n_max=3) and config.fluid is None
    assert set(config.free) | set(config.fixed) == set(NAMES[:9])
    np.testing.assert_array_equal(peaks["sigma_Hz"], 0.05)
    assert peaks["m"].tolist() == [0, 0, 0, 0] and peaks["n"].tolist() == [1, 2, 1, 2]


@pytest.mark.slow
def test_example_fit_recovers_the_tube(tmp_path):
    """The example's peaks are those of μ = 100 kPa, λ_i = 1 at N = 30, rounded to 0.01 Hz."""
    status, out, err = _cli(["fit", str(EXAMPLES / "peaks.csv"), "--config",
                             str(EXAMPLES / "fit.toml"), "--out", str(tmp_path)])
    assert status == 0, err
    import json

    saved = json.loads((tmp_path / "peaks_fit.json").read_text())
    assert saved["status"] == "CONVERGED"
    for name, truth in (("shear_modulus", 1e5), ("lambda_i", 1.0)):
        low, high = saved["interval"][name]
        assert low < truth < high and abs(saved["estimate"][name] / truth - 1) < 1e-3, name
    assert max(abs(p["residual"]) for p in saved["points"]) < 0.2  # σ = 0.05 Hz, rounding 0.005
