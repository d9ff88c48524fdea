"""fit with peak widths: a damped tube's Prony parameters from the frequencies and half-power widths
(or quality factors) of several resonances (issue 45, item 5).

The model of a peak is the complex root Ω near it (time factor e^{iΩt}, Im Ω > 0 decays):
f = Re Ω c_s/(2π R_i), Δf = 2 Im Ω c_s/(2π R_i), Q = f/Δf. Every fit here shares one compiled
program (eight m = 0 peaks, one discretisation), built by the module fixture.
"""

import json
import warnings

import numpy as np
import pytest

import jaxdea as jd
from jaxdea.io.fit_io import write_fit
from jaxdea.studies import fit as F
from jaxdea.studies.peaks import read_peaks, write_peaks

FIXED = dict(shear_modulus=5e4, density=1000.0, permittivity=4.16e-11, inner_radius=5e-3,
             length=5e-2, eta=0.85, lambda_i=1.0, lambda_z=1.2, gent=97.2)
MODULI = (1.7, 1.8, 0.7)  # VHB-like, in units of μ
TIMES = (0.1, 0.6, 4.0)  # units of R_i/c_s; the resonances' periods 2π/Ω span ~0.7 to 5
TRUTH = dict(damping_moduli_0=1.7, damping_moduli_1=1.8, damping_moduli_2=0.7,
             damping_times_0=0.1, damping_times_1=0.6, damping_times_2=4.0)
FREE = {**{f"damping_moduli_{i}": (0.01, 20.0) for i in range(3)},
        **{f"damping_times_{i}": (0.01, 20.0) for i in range(3)}}  # starts ≥ 1e-3 of the span inside
N = np.array([1, 2, 3, 4, 6, 8, 11, 14])  # α̂ = 0.52 n: Ω from ~1.2 to ~9.5
START = jd.Prony(moduli=(1.7 * 1.3, 1.8 * 0.75, 0.7 * 1.25), times=(0.1 * 0.7, 0.6 * 1.3, 4.0 * 0.8))


def _peaks(**columns):
    return dict(voltage_V=np.zeros(N.size), m=np.zeros(N.size, int), n=N, **columns)


@pytest.fixture(scope="module")
def exact():
    """(f, Δf) in Hz of the eight peaks at the truth, Ω, the problem and labels (one compiled
    program for every test)."""
    return _exact()


def _exact():
    wall = F._wall(None, None, jd.Prony(moduli=MODULI, times=TIMES))
    problem, labels = F._validate(_peaks(frequency_Hz=np.ones(N.size), width_Hz=np.ones(N.size)),
                                  FREE, FIXED, None, wall)
    theta = np.array(list(TRUTH.values()))
    problem = problem._replace(n_layers=F._discretisation(problem, [theta], (int(N.max()), 0, 1),
                                                          None, None))
    omega = F._seed(problem, theta, labels)
    _, model, _ = F._evaluate(problem, theta, labels, omega)
    return model[:, 0], model[:, 1], omega, problem, labels


def _fit(data, **options):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        result = jd.fit(data, FREE, FIXED, damping=START, **options)
    return result, [str(w.message) for w in caught]


def test_model_is_the_complex_root_of_complex_frequencies(exact):
    """The continued root of each peak is the root of the certified search (the same mode), and
    Δf = 2 Im Ω c_s/(2πR_i), Q = Re Ω/(2 Im Ω)."""
    f, width, omega, _, _ = exact
    scale = np.sqrt(FIXED["shear_modulus"] / FIXED["density"]) / (2 * np.pi * FIXED["inner_radius"])
    np.testing.assert_allclose(f, omega.real * scale, rtol=1e-13)
    np.testing.assert_allclose(width, 2 * omega.imag * scale, rtol=1e-13)
    tube = jd.Tube(voltage=0.0, lambda_i=1.0, lambda_z=1.2, eta=0.85, gent=97.2,
                   length_ratio=5e-2 * 0.85 / 5e-3, damping=jd.Prony(moduli=MODULI, times=TIMES))
    alpha = 2 * np.pi * 1 * 5e-3 / (1.2 * 5e-2)
    roots = jd.complex_frequencies(tube, alpha, n_roots=1)
    np.testing.assert_allclose(complex(roots.omega[0]), omega[0], rtol=1e-8)
    assert 1.0 < float(roots.quality_factor[0]) < 10.0  # VHB-like: low Q
    np.testing.assert_allclose(float(roots.quality_factor[0]), f[0] / width[0], rtol=1e-8)


def test_noise_free_widths_recover_the_prony_set(exact):
    f, width, *_ = exact
    result, _ = _fit(_peaks(frequency_Hz=f, width_Hz=width))
    assert result.status == jd.FitStatus.CONVERGED
    for name, value in TRUTH.items():
        assert result.estimate[name] == pytest.approx(value, rel=1e-8), name
    assert np.all(np.abs(result.width_residuals) < 1e-6)
    assert result.dof == 2 * N.size - len(FREE)


def test_fitted_frequencies_of_a_damped_fit_are_re_omega(exact, tmp_path):
    """fitted_frequencies of a damped fit continue the elastic root to the complex one: Re Ω in
    Hz, the data's frequencies at the noise-free estimate; write_fit records the widths'
    residuals."""
    f, width, *_ = exact
    data = _peaks(frequency_Hz=f, width_Hz=width)
    result, _ = _fit(data)
    assert result.settings["damping"]["kind"] == "prony"
    model = jd.fitted_frequencies(result, np.zeros(N.size), 0, N)
    np.testing.assert_allclose(model, f, rtol=1e-8)
    document = json.loads(write_fit(result, data, tmp_path / "fit.json").read_text())
    assert abs(document["points"][0]["width_residual"]) < 1e-6


def test_noise_free_quality_factors_recover_the_prony_set(exact):
    f, width, *_ = exact
    q = f / width
    result, _ = _fit(_peaks(frequency_Hz=f, quality_factor=q, sigma_Hz=np.full(N.size, 0.5),
                            sigma_quality_factor=np.full(N.size, 0.05)))
    for name, value in TRUTH.items():
        assert result.estimate[name] == pytest.approx(value, rel=1e-8), name


def test_noisy_widths_give_intervals_that_cover_the_truth(exact):
    """One realisation (seed 0) of 0.1 % noise on the frequencies and 0.5 % on the widths, σ
    given: every 95 % interval holds the truth, and no parameter is flagged unidentifiable. Not
    every realisation covers all six (seeds 0–6 measured: 0, 1, 2, 5, 6 do; 3 and 4 miss five and
    two, where χ² at the truth lies 16 and 8 above the minimum: the noise itself). At 1 % on the
    widths τ_2 = 4 (Ωτ_2 from 6 to 38: the data see its branch mostly as the stiffness g_2 and
    the loss g_2/(Ωτ_2)) is weakly determined: its interval reaches (3.2, 18) for seed 0."""
    f, width, *_ = exact
    rng = np.random.default_rng(0)
    sigma_f, sigma_w = 0.001 * f, 0.005 * width
    data = _peaks(frequency_Hz=f + sigma_f * rng.standard_normal(N.size), sigma_Hz=sigma_f,
                  width_Hz=width + sigma_w * rng.standard_normal(N.size), sigma_width_Hz=sigma_w)
    result, messages = _fit(data)
    assert result.status == jd.FitStatus.CONVERGED
    assert not messages
    for name, value in TRUTH.items():
        low, high = result.interval[name]
        assert low < value < high, (name, low, high)
        assert high - low < 2 * value, name
    assert result.chi2_per_dof < 2.0


def test_width_jacobian_matches_central_differences(exact):
    """∂Δf/∂θ and ∂Q/∂θ (implicit derivatives through the complex root) against central
    differences of the model, relative step 1e-6."""
    _, _, omega, problem, labels = exact
    theta = np.array(list(TRUTH.values()))
    for kind in ("width", "quality"):
        p = problem._replace(width_kind=kind)
        _, _, jac = F._evaluate(p, theta, labels, omega)
        for k in range(theta.size):
            h = 1e-6 * theta[k]
            up, down = theta.copy(), theta.copy()
            up[k] += h
            down[k] -= h
            diff = (F._evaluate(p, up, labels, omega)[1][:, 1]
                    - F._evaluate(p, down, labels, omega)[1][:, 1]) / (2 * h)
            np.testing.assert_allclose(jac[:, 1, k], diff, rtol=1e-6,
                                       atol=1e-6 * np.abs(jac[:, 1]).max(), err_msg=f"{kind} {k}")


def test_widths_on_an_undamped_tube_raise():
    data = _peaks(frequency_Hz=np.linspace(200.0, 2000.0, N.size), width_Hz=np.full(N.size, 50.0))
    with pytest.raises(ValueError, match="width_Hz.*needs? a damping law"):
        jd.fit(data, {"shear_modulus": (1e4, 1e5)}, {k: v for k, v in FIXED.items()
                                                     if k != "shear_modulus"})


@pytest.mark.parametrize("columns, match", [
    (dict(width_Hz=50.0, quality_factor=5.0), "both given"),
    (dict(sigma_width_Hz=1.0), "'sigma_width_Hz' needs the column 'width_Hz'"),
    (dict(width_Hz=-1.0), "'width_Hz' must be > 0"),
    (dict(width_Hz=50.0, sigma_Hz=1.0), "'sigma_width_Hz' is needed"),
    (dict(quality_factor=5.0, sigma_quality_factor=0.1), "'sigma_Hz' is needed"),
])
def test_bad_width_columns_raise(columns, match):
    data = _peaks(frequency_Hz=np.linspace(200.0, 2000.0, N.size),
                  **{k: np.full(N.size, v) for k, v in columns.items()})
    with pytest.raises(ValueError, match=match):
        jd.fit(data, FREE, FIXED, damping=START)


def test_bad_damping_names_and_bounds_raise():
    data = _peaks(frequency_Hz=np.linspace(200.0, 2000.0, N.size), width_Hz=np.full(N.size, 50.0))
    with pytest.raises(ValueError, match="damping_moduli_3.*Prony has the parameters"):
        jd.fit(data, {"damping_moduli_3": (0.1, 1.0)}, FIXED, damping=START)
    with pytest.raises(ValueError, match=r"free\['damping_times_0'\] bounds"):
        jd.fit(data, {"damping_times_0": (0.0, 1.0)}, FIXED, damping=START)
    with pytest.raises(ValueError, match="damping_ names need a damping law"):
        jd.fit(data, {"damping_viscosity": (0.1, 1.0)}, FIXED)
    unlabelled = {k: v for k, v in data.items() if k not in ("m", "n")}
    with pytest.raises(ValueError, match="needs the labels"):
        jd.fit(unlabelled, FREE, FIXED, damping=START)


def test_peak_table_carries_widths(tmp_path):
    data = _peaks(frequency_Hz=np.array([1.5, 2.5] * 4), width_Hz=np.full(N.size, 0.25),
                  sigma_Hz=np.full(N.size, 0.1), sigma_width_Hz=np.full(N.size, 0.01))
    back = read_peaks(write_peaks(tmp_path / "peaks.csv", data))
    for name in ("width_Hz", "sigma_width_Hz"):
        np.testing.assert_array_equal(back[name], data[name])
    (tmp_path / "bad.csv").write_text("voltage_V,frequency_Hz,quality_factor\n0,10,-2\n")
    with pytest.raises(ValueError, match="quality_factor.*must be > 0"):
        read_peaks(tmp_path / "bad.csv")


def test_jaxdea_fit_with_a_damping_table_and_width_columns(exact, tmp_path):
    """``jaxdea fit`` of a peak table with width columns and a fit TOML with [damping] and the
    damping names in [free]: the noise-free truth back, both files written."""
    from jaxdea.io.fit_io import run_fit

    f, width, *_ = exact
    peaks = write_peaks(tmp_path / "peaks.csv", _peaks(frequency_Hz=f, width_Hz=width))
    config = tmp_path / "fit.toml"
    config.write_text(
        "[damping]\nkind = \"prony\"\n"
        f"moduli = {list(START.moduli)!r}\ntimes = {list(START.times)!r}\n"
        "[free]\n" + "".join(f"{k} = {list(v)!r}\n" for k, v in FREE.items())
        + "[fixed]\n" + "".join(f"{k} = {v!r}\n" for k, v in FIXED.items()))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result, report, paths = run_fit(peaks, config, tmp_path)
    for name, value in TRUTH.items():
        assert result.estimate[name] == pytest.approx(value, rel=1e-8), name
    assert all(path.exists() for path in paths)
    assert "damping_times_2" in report
