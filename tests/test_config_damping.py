"""The sweep config's [damping] table (issue 45, item 5): parsed into the damping law, bad entries
named, and a damped sweep's outputs (Re Ω, Im Ω, Q) equal to complex_frequencies."""

import math

import numpy as np
import pytest

import jaxdea as jd
from jaxdea.io.config import parse_config
from jaxdea.io.fit_io import parse_fit_config

BASE = {"tube": {"lambda_i": 1.0, "lambda_z": 1.0, "voltage": 0.0}, "axes": {"alpha": 1.0}}
UNITS = {"shear_modulus": 5e4, "density": 1000.0, "permittivity": 4.16e-11, "inner_radius": 5e-3}


def _config(damping, **extra):
    return parse_config({**BASE, "damping": damping, **extra})


@pytest.mark.parametrize("table, law", [
    ({"kind": "prony", "moduli": [1.7, 1.8, 0.7], "times": [0.1, 0.6, 4.0]},
     jd.Prony(moduli=(1.7, 1.8, 0.7), times=(0.1, 0.6, 4.0))),
    ({"kind": "kelvin_voigt", "viscosity": 0.05}, jd.KelvinVoigt(0.05)),
    ({"kind": "hysteretic", "loss": 0.2}, jd.Hysteretic(0.2)),
    ({"kind": "fractional_kelvin_voigt", "modulus": 0.3, "time": 2.0, "order": 0.4},
     jd.FractionalKelvinVoigt(modulus=0.3, time=2.0, order=0.4)),
])
def test_damping_table_is_the_law(table, law):
    assert _config(table).tube["damping"] == law


def test_damping_in_si_units():
    """G/μ, t c_s/R_i, η c_s/(μ R_i), c_s = sqrt(μ/ρ_s) = sqrt(50) m/s, R_i/c_s = 7.07e-4 s."""
    time = UNITS["inner_radius"] / math.sqrt(UNITS["shear_modulus"] / UNITS["density"])
    config = _config({"kind": "prony", "moduli_Pa": [8.5e4, 3.5e4], "times_s": [1e-3, 1e-2]},
                     units=UNITS)
    np.testing.assert_allclose(config.tube["damping"].moduli, (1.7, 0.7), rtol=1e-15)
    np.testing.assert_allclose(config.tube["damping"].times, (1e-3 / time, 1e-2 / time),
                               rtol=1e-15)
    config = _config({"kind": "kelvin_voigt", "viscosity_Pa_s": 10.0}, units=UNITS)
    assert config.tube["damping"].viscosity == pytest.approx(10.0 / (5e4 * time), rel=1e-15)


@pytest.mark.parametrize("table, extra, match", [
    ({"kind": "prony", "moduli": [1.0, 2.0], "times": [0.5]}, {}, "'damping.times' must have as many"),
    ({"kind": "prony", "moduli": [-1.0], "times": [0.5]}, {}, "'damping.moduli' must be numbers >= 0"),
    ({"kind": "prony", "moduli": [1.0], "times": [0.0]}, {}, "'damping.times' must be numbers > 0"),
    ({"kind": "prony", "moduli": [1.0]}, {}, "'damping.times' is missing"),
    ({"kind": "prony", "moduli": [1.0], "times": "fast"}, {}, "'damping.times' must be a non-empty"),
    ({"kind": "maxwell"}, {}, "'damping.kind' must be one of"),
    ({"viscosity": 0.1}, {}, "'damping.kind' is missing"),
    ({"kind": "kelvin_voigt", "viscosity": 0.1, "loss": 0.1}, {}, "unknown key 'damping.loss'"),
    ({"kind": "kelvin_voigt", "viscosity": -0.1}, {}, "'damping.viscosity' must be a number >= 0"),
    ({"kind": "fractional_kelvin_voigt", "order": 1.5}, {}, "'damping.order' must be a number in"),
    ({"kind": "prony", "moduli": [1.0], "times_s": [1e-3]}, {}, "'damping.times_s' is in SI units"),
    ({"kind": "kelvin_voigt", "viscosity": 0.1}, {"solver": {"jacobian": True}},
     "'solver.jacobian' with \\[damping\\]"),
    ({"kind": "kelvin_voigt", "viscosity": 0.1}, {"solver": {"n_growth": 1}},
     "'solver.n_growth' with \\[damping\\]"),
])
def test_bad_damping_entries_name_the_key(table, extra, match):
    with pytest.raises(ValueError, match=match):
        _config(table, **extra)


def test_damping_with_layers_is_refused():
    layers = [{"fraction": 0.5, "active": True}, {"fraction": 0.5, "shear_ratio": 0.1}]
    with pytest.raises(ValueError, match="'damping' with \\[\\[layers\\]\\]"):
        _config({"kind": "kelvin_voigt", "viscosity": 0.1}, layers=layers)


def test_fit_config_takes_damping_and_its_names():
    config = parse_fit_config({
        "damping": {"kind": "prony", "moduli": [1.7, 0.7], "times": [0.1, 4.0]},
        "free": {"damping_moduli_0": [0.1, 10.0], "damping_times_1": [0.5, 50.0]},
        "fixed": {"shear_modulus": 5e4}})
    assert config.damping == jd.Prony(moduli=(1.7, 0.7), times=(0.1, 4.0))
    assert config.free == {"damping_moduli_0": (0.1, 10.0), "damping_times_1": (0.5, 50.0)}
    with pytest.raises(ValueError, match="free.damping_times_2: unknown key"):
        parse_fit_config({"damping": {"kind": "prony", "moduli": [1.7], "times": [0.1]},
                          "free": {"damping_times_2": [0.1, 1.0]}, "fixed": {}})
    with pytest.raises(ValueError, match="'damping.moduli' must be numbers >= 0"):
        parse_fit_config({"damping": {"kind": "prony", "moduli": [-1.0], "times": [0.1]},
                          "free": {}, "fixed": {}})


def test_damped_sweep_equals_complex_frequencies(tmp_path):
    """A sweep with [damping] writes Re Ω, Im Ω and Q per root, those of direct
    jaxdea.complex_frequencies calls at each point; the CSV carries omega_imag_k and
    quality_factor_k."""
    law = {"kind": "kelvin_voigt", "viscosity": 0.05}
    config = _config(law, axes={"n": [1, 2]}, tube={**BASE["tube"], "length_ratio": 20.0},
                     solver={"n_roots": 2})
    tube = jd.Tube(**config.tube)
    result = jd.sweep(tube, None, progress=False, **config.sweep_arguments())
    assert result.omega_imag.shape == result.omega.shape == (2, 2)
    for i, n in enumerate((1, 2)):
        alpha = float(result.alpha[i])
        assert alpha == pytest.approx(2 * n * math.pi * tube.eta / (20.0 * tube.lambda_z))
        direct = jd.complex_frequencies(tube, alpha, n_roots=2)
        np.testing.assert_allclose(result.omega[i], np.real(direct.omega), rtol=1e-8)
        np.testing.assert_allclose(result.omega_imag[i], np.imag(direct.omega), rtol=1e-7)
        np.testing.assert_allclose(result.quality_factor[i], direct.quality_factor, rtol=1e-7)
    assert np.all(result.omega_imag > 0)
    assert result.settings["damping"] == {"kind": "kelvin_voigt", "viscosity": 0.05}
    path = tmp_path / "damped.csv"
    result.to_csv(path)
    header = path.read_text().splitlines()[0].split(",")
    assert {"omega_1", "omega_imag_1", "quality_factor_2"} <= set(header)
    back = jd.SweepResult.from_npz(result.to_npz(tmp_path / "damped") or tmp_path / "damped.npz")
    np.testing.assert_array_equal(back.quality_factor, result.quality_factor)


def test_jaxdea_sweep_with_damping_in_si_writes_the_complex_columns(tmp_path, capsys):
    """``jaxdea sweep`` of a [damping] config in SI units: the CSV holds omega_k (Re Ω),
    omega_imag_k, quality_factor_k and frequency_Hz_k = Re Ω c_s/(2π R_i), equal to
    complex_frequencies of the converted law."""
    from jaxdea.apps import cli

    time = UNITS["inner_radius"] / math.sqrt(UNITS["shear_modulus"] / UNITS["density"])
    config = tmp_path / "damped.toml"
    config.write_text(
        "[tube]\nlambda_i = 1.0\nlambda_z = 1.0\nvoltage = 0.0\nlength_ratio = 20.0\n"
        "[damping]\nkind = \"kelvin_voigt\"\n"
        f"viscosity_Pa_s = {0.05 * UNITS['shear_modulus'] * time!r}\n"
        "[units]\n" + "".join(f"{k} = {v!r}\n" for k, v in UNITS.items())
        + "[axes]\nalpha = 1.0\n[solver]\nn_roots = 2\n[output]\nformats = [\"csv\"]\nplot = false\n")
    assert cli.main(["sweep", str(config), "--out", str(tmp_path), "--quiet"]) == 0
    lines = (tmp_path / "damped.csv").read_text().splitlines()
    row = dict(zip(lines[0].split(","), (float(x) for x in lines[1].split(",")), strict=True))
    direct = jd.complex_frequencies(jd.Tube(lambda_i=1.0, lambda_z=1.0, voltage=0.0,
                                            length_ratio=20.0, damping=jd.KelvinVoigt(0.05)),
                                    1.0, n_roots=2)
    for j in range(2):
        assert row[f"omega_{j + 1}"] == pytest.approx(float(np.real(direct.omega[j])), rel=1e-8)
        assert row[f"omega_imag_{j + 1}"] == pytest.approx(float(np.imag(direct.omega[j])), rel=1e-7)
        assert row[f"quality_factor_{j + 1}"] == pytest.approx(float(direct.quality_factor[j]),
                                                               rel=1e-7)
        assert row[f"frequency_Hz_{j + 1}"] == pytest.approx(
            row[f"omega_{j + 1}"] / (2 * math.pi * time), rel=1e-12)
