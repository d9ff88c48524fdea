"""Command line interface: ``jaxdea sweep CONFIG``, ``jaxdea figures``, ``jaxdea table``, their help,
and the validation of sweep configurations (jaxdea.io.config)."""

import argparse
import contextlib
import json
import math
import os
import subprocess
import sys
import types
from pathlib import Path

import numpy as np
import pytest

import jaxdea as jd
from jaxdea.apps import cli
from jaxdea.io import config

ROOT = Path(__file__).resolve().parent.parent

# one compiled configuration shared by every sweep test (fluid, jacobian, N = 8, K = 2, 2 x 2 points)
SWEEP_TOML = """
[tube]
lambda_i = 0.95
lambda_z = 1.2
eta = 0.8
gent = 60.0

[fluid]
density_ratio = 0.2
speed_ratio = 0.3
coupling = "acoustic"

[axes]
voltage = { start = 0.0, stop = 0.15, num = 2 }
n = [1, 3]

[solver]
n_roots = 2
n_layers = 8
jacobian = true

[output]
name = "grid"
formats = ["csv", "npz"]
plot = true
"""
SWEEP_DICT = {
    "tube": {"lambda_i": 0.95, "lambda_z": 1.2, "eta": 0.8, "gent": 60.0},
    "fluid": {"density_ratio": 0.2, "speed_ratio": 0.3, "coupling": "acoustic", "bessel_order": None},
    "axes": {"voltage": {"start": 0.0, "stop": 0.15, "num": 2}, "n": [1, 3]},
    "solver": {"n_roots": 2, "n_layers": 8, "jacobian": True},
    "output": {"formats": ["csv", "npz"], "plot": True},
}


@pytest.fixture(scope="module")
def library_result():
    """The same sweep through the library."""
    tube = jd.Tube(lambda_i=0.95, lambda_z=1.2, eta=0.8, gent=60.0)
    fluid = jd.Fluid(density_ratio=0.2, speed_ratio=0.3)
    return jd.sweep(tube, fluid, n_roots=2, n_layers=8, jacobian=True, progress=False,
                    voltage=np.linspace(0.0, 0.15, 2), n=np.array([1.0, 3.0]))


@pytest.fixture(scope="module")
def cli_runs(tmp_path_factory):
    """The sweep through the CLI from a TOML file (outputs in the current folder, not the
    config's, named by output.name) and from a JSON file (outputs in --out, named after the
    file)."""
    base = tmp_path_factory.mktemp("cli")
    toml_path, json_path = base / "cfg" / "grid_config.toml", base / "cfg" / "case.json"
    toml_path.parent.mkdir()
    (base / "work").mkdir()
    toml_path.write_text(SWEEP_TOML, encoding="utf-8")
    json_path.write_text(json.dumps(SWEEP_DICT), encoding="utf-8")
    out_json = base / "json_out"
    with contextlib.chdir(base / "work"):
        codes = (cli.main(["--quiet", "sweep", str(toml_path)]),
                 cli.main(["sweep", str(json_path), "--out", str(out_json), "--quiet"]))
    assert not list(toml_path.parent.glob("grid.*"))  # nothing next to the config
    return codes, base / "work" / "grid", out_json / "case"


def test_sweep_from_toml_and_json_matches_the_library(cli_runs, library_result):
    codes, toml_stem, json_stem = cli_runs
    assert codes == (0, 0)
    ref = library_result
    assert np.all(ref.status == jd.Status.CONVERGED)
    for stem in (toml_stem, json_stem):
        got = jd.SweepResult.from_npz(stem.with_suffix(".npz"))
        assert list(got.axes) == ["voltage", "n"]
        np.testing.assert_array_equal(got.axes["voltage"], [0.0, 0.15])
        np.testing.assert_array_equal(got.omega, ref.omega)
        np.testing.assert_array_equal(got.status, ref.status)
        np.testing.assert_array_equal(got.jacobian, ref.jacobian)
        assert got.jacobian_names == ref.jacobian_names
        assert got.settings == ref.settings
        # the CSV holds the same numbers (%.17g round-trips float64 exactly)
        header = stem.with_suffix(".csv").read_text().splitlines()[0].split(",")
        table = np.loadtxt(stem.with_suffix(".csv"), delimiter=",", skiprows=1)
        cols = ref.columns()
        assert header == list(cols)
        assert "d_omega_2/d_density_ratio" in header
        np.testing.assert_array_equal(table, np.column_stack(list(cols.values())))


# the same sweep with the voltage axis in volts for a VHB 4910-like tube (μ = 20 kPa,
# ρ_s = 960 kg/m³, ε = 4.7 ε_0, R_i = 5 mm), written as CSV, NPZ and netCDF
MU, RHO, EPS_R, RI = 20e3, 960.0, 4.7, 5e-3
VOLTAGE_UNIT = RI * math.sqrt(MU / (EPS_R * 8.8541878188e-12))  # R_i sqrt(μ/ε) = 109.61 kV
UNITS_TOML = SWEEP_TOML.replace("voltage = { start = 0.0, stop = 0.15, num = 2 }",
                                f"voltage_V = [0.0, {0.15 * VOLTAGE_UNIT!r}]").replace(
    'formats = ["csv", "npz"]', 'formats = ["csv", "npz", "netcdf"]') + f"""
[units]
shear_modulus = {MU}
density = {RHO}
relative_permittivity = {EPS_R}
inner_radius = {RI}
"""


@pytest.fixture(scope="module")
def units_run(tmp_path_factory):
    pytest.importorskip("xarray")
    pytest.importorskip("netCDF4")
    base = tmp_path_factory.mktemp("units")
    (base / "vhb.toml").write_text(UNITS_TOML, encoding="utf-8")
    with contextlib.chdir(base):
        return cli.main(["--quiet", "sweep", "vhb.toml"]), base / "grid"


def test_sweep_with_units_gives_hertz_and_volts(units_run, library_result):
    """The worked VHB example: f = Ω c_s/(2π R_i) with c_s = sqrt(μ/ρ_s), V = V̂ R_i sqrt(μ/ε), by
    hand; the frequencies equal the dimensionless sweep's."""
    code, stem = units_run
    assert code == 0
    assert VOLTAGE_UNIT == pytest.approx(109.61e3, rel=1e-4)
    hertz_per_omega = math.sqrt(MU / RHO) / (2 * math.pi * RI)
    assert hertz_per_omega == pytest.approx(145.29, abs=0.005)
    got = jd.SweepResult.from_npz(stem.with_suffix(".npz"))
    np.testing.assert_allclose(got.axes["voltage"], [0.0, 0.15], rtol=1e-15)
    np.testing.assert_allclose(got.omega, library_result.omega, rtol=1e-12)
    header = stem.with_suffix(".csv").read_text().splitlines()[0].split(",")
    table = np.loadtxt(stem.with_suffix(".csv"), delimiter=",", skiprows=1)
    column = lambda name: table[:, header.index(name)]  # noqa: E731
    np.testing.assert_allclose(column("voltage_V"), [0.0, 0.0, 0.15 * VOLTAGE_UNIT, 0.15 * VOLTAGE_UNIT],
                               rtol=1e-14)
    for k in (1, 2):
        np.testing.assert_allclose(column(f"frequency_Hz_{k}"), column(f"omega_{k}") * hertz_per_omega,
                                   rtol=1e-14)
    # the lowest root at V̂ = 0, n = 1 is a few Hz: Ω ~ 0.1 of the fluid-loaded tube
    assert 1.0 < column("frequency_Hz_1")[0] < 145.29
    np.testing.assert_allclose(column("wavelength_m"), 2 * math.pi * RI / column("alpha_hat"), rtol=1e-14)


def test_sweep_writes_netcdf(units_run, library_result):
    import xarray as xr

    code, stem = units_run
    assert code == 0
    with xr.open_dataset(stem.with_suffix(".nc")) as ds:
        ds.load()
    assert tuple(ds["omega"].dims) == ("voltage", "n", "root")
    np.testing.assert_allclose(ds["omega"], library_result.omega, rtol=1e-12)
    np.testing.assert_array_equal(ds["status"], library_result.status)
    np.testing.assert_array_equal(ds["n"], [1.0, 3.0])
    np.testing.assert_allclose(ds["voltage_V"], [0.0, 0.15 * VOLTAGE_UNIT], rtol=1e-14)
    np.testing.assert_allclose(ds["d_omega_d_density_ratio"], library_result.derivative("density_ratio"),
                               rtol=1e-9)
    np.testing.assert_allclose(ds["frequency_Hz"],
                               library_result.omega * math.sqrt(MU / RHO) / (2 * math.pi * RI), rtol=1e-12)
    assert (ds.attrs["n_layers"], ds.attrs["coupling"], ds.attrs["tube_eta"]) == (8, "acoustic", 0.8)
    assert ds.attrs["units_density"] == RHO and ds.attrs["units_inner_radius"] == RI


def test_plot_with_units_has_hertz_and_volt_axes(library_result, tmp_path):
    from jaxdea.units import VACUUM_PERMITTIVITY, Scales

    scales = Scales(MU, RHO, EPS_R * VACUUM_PERMITTIVITY, RI)
    fig = cli.plot_sweep(library_result.with_units(scales), "voltage", tmp_path / "si.png")
    labels = {child.get_ylabel() or child.get_xlabel() for child in fig.axes[0].child_axes}
    assert labels == {"frequency $f$ (Hz)", "voltage_V (V)"}
    plain = cli.plot_sweep(library_result, "voltage", tmp_path / "plain.png")
    assert plain.axes[0].child_axes == []


def test_sweep_writes_a_png_plot(cli_runs):
    from matplotlib.image import imread

    _, toml_stem, json_stem = cli_runs
    for stem in (toml_stem, json_stem):
        png = stem.with_suffix(".png")
        assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        height, width, _ = imread(png).shape
        assert width > 400 and height > 300


def test_sweep_prints_the_written_paths(tmp_path, capsys, cli_runs):
    _, toml_stem, _ = cli_runs
    config_path = toml_stem.parent.parent / "cfg" / "grid_config.toml"
    assert cli.main(["sweep", str(config_path), "--out", str(tmp_path)]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].startswith("sweep voltage[2] x n[2]: 2 roots per point, 8/8 converged")
    assert lines[1:] == [str(tmp_path / f"grid.{ext}") for ext in ("csv", "npz", "png")]


BAD_CONFIGS = [
    ({"fluid": {"densty_ratio": 0.1}, "axes": {"n": [1]}},
     "unknown key 'fluid.densty_ratio'; allowed: density_ratio, speed_ratio, coupling, bessel_order"),
    ({"axis": {"n": [1]}}, "unknown key 'axis'; allowed: tube, fluid, axes, solver, output"),
    ({"tube": {"lambda": 1.0}, "axes": {"n": [1]}}, "unknown key 'tube.lambda'"),
    ({"tube": {"eta": 1.5}, "axes": {"n": [1]}}, "'tube.eta' must be in the open interval (0, 1), got 1.5"),
    ({"tube": {"gent": "big"}, "axes": {"n": [1]}}, "'tube.gent' must be a number"),
    ({"tube": {"material": "rubber"}, "axes": {"n": [1]}}, "'tube.material' must be one of gent, neo_hookean"),
    ({"axes": {"voltage": {"start": 0, "stop": 1, "num": 0}, "n": [1]}},
     "'axes.voltage.num' must be an integer >= 1, got 0"),
    ({"axes": {"voltage": {"start": 0, "num": 3}, "n": [1]}}, "'axes.voltage.stop' is missing"),
    ({"axes": {"voltage": {"start": 0, "stop": 1, "num": 3, "step": 1}, "n": [1]}},
     "unknown key 'axes.voltage.step'; allowed: start, stop, num"),
    ({"axes": {"voltage": [0.0, "x"], "n": [1]}}, "'axes.voltage[1]' must be a number"),
    ({"axes": {"voltage": []}}, "'axes.voltage' is an empty list"),
    ({"axes": {"volts": [0.0], "n": [1]}}, "unknown key 'axes.volts'; allowed: voltage, lambda_i"),
    ({"axes": {"n": [1, 2.5]}}, "'axes.n' must be integers >= 1 (axial mode numbers), got 2.5"),
    ({"axes": {"alpha": [0.0, 1.0]}}, "'axes.alpha' must be a finite number > 0, got 0.0"),
    ({"axes": {"voltage": [0.0]}}, "'axes' needs exactly one wavenumber axis: 'alpha' (α̂) or 'n'"),
    ({"axes": {"alpha": [1.0], "n": [1]}}, "not both"),
    ({"tube": {}}, "missing table 'axes'"),
    ({"axes": {"density_ratio": [0.1], "n": [1]}},
     "'axes.density_ratio' is a fluid parameter: add a [fluid] table"),
    ({"tube": {"voltage": 0.1}, "axes": {"voltage": [0.0], "n": [1]}},
     "'tube.voltage' is also a sweep axis ('axes.voltage')"),
    ({"tube": {"eta": 0.8}, "axes": {"thickness_ratio": [0.2], "n": [1]}},
     "'tube.eta' and 'axes.thickness_ratio' both set the wall thickness"),
    ({"fluid": {"coupling": "papr"}, "axes": {"n": [1]}}, "'fluid.coupling' must be one of acoustic, paper"),
    ({"fluid": {"bessel_order": -1}, "axes": {"n": [1]}}, "'fluid.bessel_order' must be an integer >= 0"),
    ({"fluid": {"coupling": "paper"}, "axes": {"alpha": [1.0]}}, "needs 'fluid.bessel_order'"),
    ({"axes": {"n": [1]}, "solver": {"n_layers": 0}}, "'solver.n_layers' must be an integer >= 1, got 0"),
    ({"axes": {"n": [1]}, "solver": {"n_roots": 2.0}}, "'solver.n_roots' must be an integer >= 1"),
    ({"axes": {"n": [1]}, "solver": {"jacobian": "yes"}}, "'solver.jacobian' must be true, false or a list"),
    ({"axes": {"n": [1]}, "solver": {"jacobian": ["voltage", "speed_ratio"]}},
     "'solver.jacobian[1]' = 'speed_ratio' is no parameter of this case"),
    ({"axes": {"n": [1]}, "solver": {"omega_max": -1}}, "'solver.omega_max' must be a finite number > 0"),
    ({"axes": {"n": [1]}, "solver": {"scheme": "rk4"}},
     "'solver.scheme' must be one of midpoint, magnus4, magnus6, got 'rk4'"),
    ({"axes": {"n": [1]}, "output": {"formats": ["png"]}},
     "'output.formats[0]' must be one of csv, npz, netcdf"),
    ({"units": {"shear": 1.0}, "axes": {"n": [1]}}, "unknown key 'units.shear'; allowed: shear_modulus"),
    ({"units": {"density": -960.0}, "axes": {"n": [1]}},
     "'units.density' must be a finite number > 0 (kg/m^3), got -960.0"),
    ({"units": {"inner_radius": "5 mm"}, "axes": {"n": [1]}}, "'units.inner_radius' must be a finite number"),
    ({"units": {"shear_modulus": 2e4, "density": 960.0, "inner_radius": 5e-3}, "axes": {"n": [1]}},
     "'units.permittivity' is missing"),
    ({"axes": {"voltage_V": [0.0, 1e3], "n": [1]}}, "'axes.voltage_V' is in SI units (V): add a [units] table"),
    ({"units": {"shear_modulus": 2e4, "density": 960.0, "permittivity": 4e-11, "inner_radius": 5e-3},
      "axes": {"voltage": [0.0], "voltage_V": [1e3], "n": [1]}},
     "'axes.voltage' and 'axes.voltage_V' set the same parameter (voltage)"),
    ({"units": {"shear_modulus": 2e4, "density": 960.0, "permittivity": 4e-11, "inner_radius": 5e-3},
      "axes": {"wavelength_m": [0.0]}}, "'axes.wavelength_m' must be a finite number > 0 (m), got 0.0"),
    ({"axes": {"n": [1]}, "output": {"name": "a/b"}}, "'output.name' must be a file stem without folders"),
    ({"axes": {"n": [1]}, "output": {"formats": [], "plot": False}}, "nothing would be written"),
    ([1, 2], "the document must be a table"),
]


MOONEY = {"kind": "mooney_rivlin", "beta": 0.2}
PASSIVE = {"fraction": 0.2, "material": {"kind": "neo_hookean"}, "shear_ratio": 3.0}
ACTIVE = {"fraction": 0.8, "active": True}


def _wall(axes=None, **tables):
    """A config of the wall ``tables`` on the grid α̂ = 0.8 (and ``axes``)."""
    return {"axes": {"alpha": 0.8, **(axes or {})}, **tables}


BAD_WALL_CONFIGS = [  # [material] and [[layers]] (issue 44)
    (_wall(material={"kind": "rubber"}),
     "'material.kind' must be one of gent, neo_hookean, mooney_rivlin, gent_gent, ogden, got 'rubber'"),
    (_wall(material={"beta": 0.2}), "'material.kind' is missing"),
    (_wall(material="mooney_rivlin"), "'material' must be a table {kind = "),
    (_wall(material={**MOONEY, "bta": 0.2}), "unknown key 'material.bta'; allowed: kind, beta"),
    (_wall(material={**MOONEY, "beta": "x"}), "'material.beta' must be a number, got 'x'"),
    (_wall(material={**MOONEY, "beta": 1.5}),
     "'material': material MooneyRivlin: beta must be in [0, 1], got 1.5"),
    (_wall(material={"kind": "ogden", "mu": [1.0], "alpha": [3.0]}),
     "material Ogden is not normalised to unit shear modulus"),
    (_wall(material={"kind": "ogden", "mu": 1.0}), "'material.mu' must be a non-empty list of numbers"),
    (_wall(tube={"gent": 50.0}, material=MOONEY), "'material' and 'tube.gent' both set the wall's energy"),
    (_wall(material=MOONEY, layers=[ACTIVE]), "'material' and 'layers' both set the wall's energy"),
    (_wall(layers=ACTIVE), "'layers' must be an array of tables ([[layers]]"),
    (_wall(layers=[{"active": True}]), "'layers[0].fraction' is missing"),
    (_wall(layers=[PASSIVE, {**ACTIVE, "thickness": 1.0}]),
     "unknown key 'layers[1].thickness'; allowed: fraction, material, shear_ratio, density_ratio, active"),
    (_wall(layers=[{**PASSIVE, "shear_ratio": -1.0}, ACTIVE]),
     "'layers[0].shear_ratio' must be a finite number > 0, got -1.0"),
    (_wall(layers=[PASSIVE, {**ACTIVE, "active": "yes"}]), "'layers[1].active' must be true or false"),
    (_wall(layers=[{**PASSIVE, "material": {"kind": "vhb"}}, ACTIVE]),
     "'layers[0].material.kind' must be one of gent"),
    (_wall(layers=[PASSIVE, {**ACTIVE, "fraction": 0.5}]), "layers: the fractions must sum to 1, got 0.7"),
    (_wall(layers=[PASSIVE, {**ACTIVE, "active": False}]), "exactly one layer must be active"),
    (_wall(layers=[{**PASSIVE, "active": True}, ACTIVE]),
     "exactly one layer must be active (the dielectric with the electrodes), got 2"),
    (_wall(layers=[PASSIVE, {**ACTIVE, "shear_ratio": 2.0}]),
     "layers[1].shear_ratio must be 1 for the active layer"),
    (_wall({"layer1_fraction": [0.5]}, layers=[PASSIVE, ACTIVE]),
     "'axes.layer1_fraction' is no parameter of this wall (the active layer's fraction follows"),
    (_wall({"layer2_fraction": [0.5]}, layers=[PASSIVE, ACTIVE]),
     "'axes.layer2_fraction' is no parameter of this wall (the tube has 2 layers: k from 0 to 1)"),
    (_wall({"material_beta": [0.5]}),
     "'axes.material_beta' is no parameter of this wall (material_ names need a material object"),
    (_wall({"layer0_fraction": [0.0]}, layers=[PASSIVE, ACTIVE]),
     "'axes.layer0_fraction' must be in the open interval (0, 1), got 0.0"),
    (_wall(layers=[PASSIVE, ACTIVE], solver={"jacobian": ["layer1_fraction"]}),
     "'solver.jacobian[0]' = 'layer1_fraction' is no parameter of this case; allowed: voltage"),
]


@pytest.mark.parametrize(("data", "message"), BAD_CONFIGS + BAD_WALL_CONFIGS,
                         ids=[m[:40] for _, m in BAD_CONFIGS + BAD_WALL_CONFIGS])
def test_bad_config_names_the_key_and_exits_2(tmp_path, capsys, data, message):
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(data), encoding="utf-8")
    assert cli.main(["sweep", str(path)]) == 2
    captured = capsys.readouterr()
    assert message in captured.err
    assert captured.err.startswith("jaxdea sweep: error: sweep config: ") and captured.out == ""
    assert list(tmp_path.iterdir()) == [path]  # nothing written


@pytest.mark.parametrize(("name", "text", "message"), [
    ("bad.toml", "[axes]\nn = [1, 2\n", "bad.toml: invalid TOML"),
    ("bad.json", '{"axes": ', "bad.json: invalid JSON"),
    ("missing.toml", None, "cannot read"),
    ("config.yaml", "axes: {n: [1]}\n", "the file must end in .toml or .json"),
])
def test_unreadable_config_exits_2(tmp_path, capsys, name, text, message):
    path = tmp_path / name
    if text is not None:
        path.write_text(text, encoding="utf-8")
    assert cli.main(["sweep", str(path)]) == 2
    assert message in capsys.readouterr().err


def test_parse_config_defaults_and_derived_axes():
    cfg = config.parse_config({"tube": {"thickness_ratio": 0.2, "lambda_i": 1.1},
                               "axes": {"n": 2, "voltage": {"start": 0.0, "stop": 0.3, "num": 4}}},
                              default_name="stem")
    assert cfg.tube == {"lambda_i": 1.1} and cfg.fluid is None
    assert list(cfg.axes) == ["n", "voltage", "thickness_ratio"]  # the fixed h/R_i comes last
    np.testing.assert_array_equal(cfg.axes["voltage"], np.linspace(0.0, 0.3, 4))
    np.testing.assert_array_equal(cfg.axes["thickness_ratio"], [0.2])
    assert cfg.plot_axis == "voltage"  # the first axis with more than one value
    assert (cfg.name, cfg.formats, cfg.plot, cfg.out_dir) == ("stem", ("csv", "npz"), True, None)
    args = cfg.sweep_arguments()
    assert (args["n_roots"], args["n_layers"], args["jacobian"], args["omega_max"]) == (3, None, None, None)
    assert args["scheme"] is None  # the default discretisation
    magnus = config.parse_config({"axes": {"alpha": [1.0]}, "solver": {"scheme": "magnus6"}})
    assert magnus.sweep_arguments()["scheme"] == "magnus6"
    gent_inf = config.parse_config({"tube": {"gent": float("inf")}, "axes": {"alpha": [1.0]}})
    assert gent_inf.tube["gent"] == np.inf


def test_si_values_in_the_config_are_converted_by_hand():
    """[units] with fixed SI values: V̂ = V sqrt(ε/μ)/R_i, h/R_i, ρ̂_f = ρ_f/ρ_s, ĉ_f = c_f/sqrt(μ/ρ_s),
    α̂ = 2π R_i/Λ, written out here."""
    eps = 4.2e-11
    cfg = config.parse_config({
        "units": {"shear_modulus": MU, "density": RHO, "permittivity": eps, "inner_radius": RI},
        "tube": {"voltage_V": 3000.0, "thickness_m": 1e-3, "lambda_i": 0.9},
        "fluid": {"fluid_density_kg_m3": 1000.0, "sound_speed_m_s": 1480.0},
        "axes": {"wavelength_m": [0.05, 0.1]}})
    assert cfg.units == {"shear_modulus": MU, "density": RHO, "permittivity": eps, "inner_radius": RI}
    assert cfg.tube["voltage"] == pytest.approx(3000.0 * math.sqrt(eps / MU) / RI, rel=1e-14)
    assert cfg.tube["voltage"] == pytest.approx(0.027495, abs=1e-6)
    assert cfg.tube["lambda_i"] == 0.9 and "voltage_V" not in cfg.tube
    np.testing.assert_allclose(cfg.axes["thickness_ratio"], [0.2], rtol=1e-14)
    assert cfg.fluid["density_ratio"] == pytest.approx(1000.0 / RHO, rel=1e-14)
    assert cfg.fluid["speed_ratio"] == pytest.approx(1480.0 / math.sqrt(MU / RHO), rel=1e-14)
    np.testing.assert_allclose(cfg.axes["alpha"], [2 * math.pi * RI / 0.05, 2 * math.pi * RI / 0.1],
                               rtol=1e-14)
    assert list(cfg.axes) == ["alpha", "thickness_ratio"]
    assert cfg.scales.inner_radius == RI


def test_netcdf_without_xarray_fails_before_computing(tmp_path, monkeypatch, capsys):
    path = tmp_path / "nc.json"
    path.write_text(json.dumps({"axes": {"n": [1]}, "output": {"formats": ["netcdf"]}}), encoding="utf-8")
    monkeypatch.setitem(sys.modules, "netCDF4", None)
    assert cli.main(["sweep", str(path)]) == 2
    err = capsys.readouterr().err
    assert err == ("jaxdea sweep: error: output format netcdf needs xarray and netCDF4: "
                   "pip install 'jaxdea[xarray]'\n")
    assert list(tmp_path.iterdir()) == [path]


def test_example_config_is_valid():
    cfg = config.load_config(ROOT / "examples" / "sweep.toml")
    assert cfg.fluid is not None and cfg.plot and set(cfg.formats) == {"csv", "npz"}
    assert cfg.plot_axis == list(cfg.axes)[0]
    assert "n" in cfg.axes or "alpha" in cfg.axes


@pytest.mark.slow
def test_example_config_runs(tmp_path):
    example = ROOT / "examples" / "sweep.toml"
    assert cli.main(["--quiet", "sweep", str(example), "--out", str(tmp_path)]) == 0
    cfg = config.load_config(example)
    ref = jd.sweep(jd.Tube(**cfg.tube), jd.Fluid(**cfg.fluid), progress=False, **cfg.sweep_arguments())
    got = jd.SweepResult.from_npz(tmp_path / f"{cfg.name}.npz")
    np.testing.assert_array_equal(got.omega, ref.omega)
    assert (tmp_path / f"{cfg.name}.png").stat().st_size > 0


def _subcommand_parsers():
    parser = cli.build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return parser, sub.choices


def test_help_lists_every_command_and_option(capsys):
    assert cli.main(["--help"]) == 0
    out = capsys.readouterr().out
    parser, commands = _subcommand_parsers()
    for name in commands:
        assert f"    {name} " in out
    for action in parser._actions:
        for option in action.option_strings:
            assert option in out
    assert "examples:" in out


@pytest.mark.parametrize("command", ["sweep", "figures", "table"])
def test_subcommand_help_is_complete(capsys, command):
    assert cli.main([command, "--help"]) == 0
    out = capsys.readouterr().out
    sub = _subcommand_parsers()[1][command]
    assert sub.description.split()[0] in out
    for action in sub._actions:
        for option in action.option_strings:
            assert option in out
        if action.help is not None and action.help != argparse.SUPPRESS:
            assert action.help.split()[0] in out
    assert "example" in out and f"jaxdea {command}" in out


def test_sweep_help_documents_every_config_key(capsys):
    assert cli.main(["sweep", "--help"]) == 0
    out = capsys.readouterr().out
    for key in (*(f"[{k}]" for k in config.TOP_KEYS), *config.TUBE_KEYS, *config.FLUID_KEYS,
                *config.SOLVER_KEYS, *config.OUTPUT_KEYS, *config.LINSPACE_KEYS, *config.FORMATS,
                *config.UNITS_KEYS, *config.SI_NAMES):
        assert key in out, key


def test_table_help_describes_the_cases(capsys):
    assert cli.main(["table", "--help"]) == 0
    out = capsys.readouterr().out
    assert "η = 0.85" in out and "--n-layers" in out


def test_rejects_zero_layers(capsys):
    assert cli.main(["table", "--n-layers", "0"]) == 2
    assert "--n-layers must be >= 1" in capsys.readouterr().err


def test_usage_error_exits_2(capsys):
    assert cli.main(["sweep"]) == 2
    assert "CONFIG" in capsys.readouterr().err
    assert cli.main(["nonsense"]) == 2


def _error_cases(tmp_path):
    """(arguments, environment, what the message says) of command-line errors of every command."""
    a_file = tmp_path / "file.txt"
    a_file.write_text("not a folder", encoding="utf-8")
    config = tmp_path / "ok.json"
    config.write_text(json.dumps({"axes": {"n": [1]}}), encoding="utf-8")
    (tmp_path / "folder.toml").mkdir()
    cases = [
        ([], {}, "the following arguments are required: COMMAND"),
        (["nonsense"], {}, "invalid choice: 'nonsense'"),
        (["--bogus", "table"], {}, "unrecognized arguments: --bogus"),
        (["sweep"], {}, "the following arguments are required: CONFIG"),
        (["sweep", str(config), "--bogus"], {}, "unrecognized arguments: --bogus"),
        (["sweep", str(tmp_path / "missing.toml")], {}, "cannot read"),
        (["sweep", str(tmp_path / "folder.toml")], {}, "cannot read"),
        (["sweep", str(config), "--out", str(a_file)], {}, f"{a_file} is a file, not a folder"),
        (["sweep", str(config), "--out", str(a_file / "sub")], {}, f"cannot write into {a_file / 'sub'}"),
        (["figures", "--out", str(a_file)], {}, f"{a_file} is a file, not a folder"),
        (["figures", "--out", str(a_file / "sub")], {}, f"cannot write into {a_file / 'sub'}"),
        (["figures", "--quick=yes"], {}, "ignored explicit argument 'yes'"),
        (["figures", "--out"], {}, "argument --out: expected one argument"),
        (["table", "--n-layers", "x"], {}, "argument --n-layers: invalid int value: 'x'"),
        (["table", "--n-layers", "0"], {}, "--n-layers must be >= 1"),
        (["table", "extra"], {}, "unrecognized arguments: extra"),
        (["cache"], {}, "the following arguments are required: action"),
        (["cache", "wipe"], {}, "invalid choice: 'wipe'"),
        (["cache", "clear"], {"JAXDEA_CACHE_DIR": str(a_file)}, f"{a_file} is not a jaxdea cache"),
        (["cache", "clear"], {"JAXDEA_CACHE_DIR": str(tmp_path)}, f"{tmp_path} is not a jaxdea cache"),
    ]
    if "fit" in _subcommand_parsers()[1]:
        cases += [
            (["fit", str(tmp_path / "peaks.csv")], {}, "the following arguments are required: --config"),
            (["fit", str(tmp_path / "peaks.csv"), "--config", str(tmp_path / "missing.toml")], {},
             "missing.toml"),
            (["fit", "peaks.csv", "--config", "fit.toml", "--bogus"], {}, "unrecognized arguments: --bogus"),
        ]
    return cases


def test_every_command_error_is_one_line_with_status_2(tmp_path, monkeypatch, capsys, fake_figures):
    """Bad options, missing files and unusable output folders of every command: exit status 2, one
    line on stderr naming the problem, no traceback, nothing on stdout, no computation."""
    cases = _error_cases(tmp_path)
    commands = {argv[0] for argv, _, _ in cases if argv and not argv[0].startswith("-")}
    assert set(_subcommand_parsers()[1]) <= commands
    for argv, env, message in cases:
        with monkeypatch.context() as patch:
            for key, value in env.items():
                patch.setenv(key, value)
            assert cli.main(argv) == 2, argv
        captured = capsys.readouterr()
        assert captured.err.count("\n") == 1 and captured.err.endswith("\n"), (argv, captured.err)
        assert message in captured.err, (argv, captured.err)
        assert "Traceback" not in captured.err and captured.out == "", argv
    assert fake_figures == []  # figures failed before computing anything
    assert (tmp_path / "file.txt").read_text(encoding="utf-8") == "not a folder"


def test_figures_into_a_file_fails_fast_in_a_fresh_process(tmp_path):
    a_file = tmp_path / "file.txt"
    a_file.write_text("x", encoding="utf-8")
    proc = subprocess.run([sys.executable, "-m", "jaxdea", "figures", "--out", str(a_file / "figs")],
                          capture_output=True, text=True, timeout=120, cwd=tmp_path,
                          env={**os.environ, "JAXDEA_CACHE_DIR": "off"})
    assert proc.returncode == 2
    assert proc.stderr.splitlines() == [
        f"jaxdea figures: error: cannot write into {a_file / 'figs'}: Not a directory"]


@pytest.fixture
def fake_figures(monkeypatch):
    """A stand-in for jaxdea.apps.figures (the figures themselves are tested with that module)."""
    calls = []

    def make_figures(out, quick=False, progress=True):
        calls.append(dict(out=out, quick=quick, progress=progress))
        return [out / "fig2.png", out / "fig2.csv"]

    monkeypatch.setitem(sys.modules, "jaxdea.apps.figures",
                        types.SimpleNamespace(make_figures=make_figures))
    return calls


def test_figures_command_calls_make_figures(fake_figures, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)  # the default --out figures is created here
    assert cli.main(["figures"]) == 0
    assert (tmp_path / "figures").is_dir()
    assert fake_figures[-1] == dict(out=Path("figures"), quick=False, progress=True)
    assert capsys.readouterr().out.splitlines() == [str(Path("figures") / "fig2.png"),
                                                    str(Path("figures") / "fig2.csv")]
    assert cli.main(["--quiet", "figures", "--out", str(tmp_path / "quick"), "--quick"]) == 0
    assert fake_figures[-1] == dict(out=tmp_path / "quick", quick=True, progress=False)
    assert cli.main(["figures", "--quiet"]) == 0  # --quiet after the command works too
    assert fake_figures[-1]["progress"] is False


def test_python_dash_m_runs_the_cli(tmp_path):
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"axes": {"n": [0]}}), encoding="utf-8")
    proc = subprocess.run([sys.executable, "-m", "jaxdea", "sweep", str(bad)], capture_output=True,
                          text=True, timeout=120, cwd=tmp_path)
    assert proc.returncode == 2
    assert "'axes.n' must be integers >= 1" in proc.stderr and "Traceback" not in proc.stderr


def test_cache_info_and_clear(tmp_path, monkeypatch, capsys):
    root = tmp_path / "cache"
    monkeypatch.setenv("JAXDEA_CACHE_DIR", str(root))
    (root / "programs").mkdir(parents=True)
    (root / "programs" / "entry.jaxexport").write_bytes(b"x" * 2000)
    (root / "mine.txt").write_text("the user's")
    assert cli.main(["cache", "info"]) == 0
    assert f"{root}: 1 files" in capsys.readouterr().out
    assert cli.main(["cache", "clear"]) == 2  # no marker: not jaxdea's folder, nothing deleted
    assert "is not a jaxdea cache" in capsys.readouterr().err
    assert (root / "programs" / "entry.jaxexport").exists()
    (root / "mine.txt").unlink()
    from jaxdea import compiled

    assert compiled.claim_root(root) is None  # only jaxdea's folders: marked as its cache
    assert cli.main(["cache", "clear"]) == 0
    assert f"removed jaxdea's cache at {root}" in capsys.readouterr().out and not root.exists()
    monkeypatch.setenv("JAXDEA_CACHE_DIR", "off")
    assert cli.main(["cache", "clear"]) == 0 and "off" in capsys.readouterr().out


def test_help_says_what_jaxdea_does_and_that_only_the_square_of_the_voltage_matters(capsys):
    assert cli.main(["--help"]) == 0
    out = " ".join(capsys.readouterr().out.split())
    assert "Axisymmetric dispersion" not in out
    assert "every circumferential order m" in out and "stability" in out
    assert "Negative voltages are accepted: only V² enters the physics" in out


def test_quiet_keeps_the_fit_report(monkeypatch, capsys, tmp_path):
    """--quiet drops progress, not results: the fit's table of estimates is still printed."""
    from jaxdea.io import fit_io

    report = "parameter  estimate  95 % interval"
    monkeypatch.setattr(fit_io, "run_fit", lambda data, config, out: (None, report, [tmp_path / "x.json"]))
    assert cli.main(["--quiet", "fit", "peaks.csv", "--config", "fit.toml"]) == 0
    out = capsys.readouterr().out
    assert report in out and "x.json" in out


def test_table_marks_rows_past_the_first_instability_and_imaginary_lowest_roots(monkeypatch, capsys):
    """The rule of every figure (V̂ ≥ V̂_first) marks table rows; where V̂ ≥ V̂_cr(n) the lowest root is
    imaginary and the row says that Ω_1 is the next branch."""
    import types

    roots = types.SimpleNamespace(omega=np.array([0.5, 0.9, 1.2]), status=np.zeros(3, int))
    rows = [(li, v, 1, 0.445, "empty", roots) for li in (0.9, 1.1) for v in (0.0, 0.2)]
    monkeypatch.setattr(cli, "paper_table", lambda n_layers, log=None: rows)
    monkeypatch.setattr(cli, "table_stability", lambda rows, n_layers: (
        {0.9: (0.0293, 2, 1), 1.1: (0.1062, 2, 1)}, {(0.9, 1): 0.2959, (1.1, 1): 0.1976}))
    assert cli.main(["table"]) == 0
    captured = capsys.readouterr()
    lines = [line for line in captured.out.splitlines() if line.lstrip().startswith("empty")]
    assert len(lines) == 4
    stable_09, past_09, stable_11, past_11 = lines
    assert "UNSTABLE" not in stable_09 and "UNSTABLE" not in stable_11
    assert "UNSTABLE" in past_09 and "V̂_first = 0.0293" in past_09 and "imaginary" not in past_09
    assert "UNSTABLE" in past_11 and "lowest root imaginary (V̂ ≥ V̂_cr = 0.1976)" in past_11
    assert "compiling" in captured.err  # progress on stderr, the table on stdout
    assert cli.main(["--quiet", "table"]) == 0
    assert capsys.readouterr().err == ""


# --------------------------------------------------------------- hostile inputs, interrupts, full disk

FIT_TOML = "[free]\nshear_modulus = [5e4, 2e5]\n[fixed]\ndensity = 1000.0\n"


def _hostile_inputs(tmp_path):
    """(arguments, what the one-line error says) for inputs that raised a traceback (or were
    misread) before any computation."""
    def write(name, text):
        (tmp_path / name).write_text(text, encoding="utf-8")
        return str(tmp_path / name)

    fit_config = write("fit.toml", FIT_TOML)
    return [
        (["sweep", write("deep.json", '{"axes": ' + "[" * 50_000 + "]" * 50_000 + "}")],
         "nest deeper than 64 levels"),
        (["sweep", write("deep.toml", "[axes]\nn = " + "[" * 5000 + "]" * 5000 + "\n")],
         "nest deeper than 64 levels"),
        (["sweep", write("twice.json", '{"axes": {"n": [1]}, "axes": {"n": [0]}}')],
         "the key 'axes' appears twice in one table"),
        (["sweep", write("huge.toml", "[axes]\nn = [1]\nvoltage = {start = 0, stop = 0.1, "
                                      "num = 1000000000000}\n")],
         "the grid has 1,000,000,000,000 points up to 'axes.voltage'; a sweep takes at most "
         "MAX_POINTS = 100,000,000"),
        (["sweep", write("roots.toml", "[axes]\nn = [1]\n[solver]\nn_roots = 100000000\n")],
         "'solver.n_roots' must be <= MAX_ROOTS = 1,000, got 100,000,000"),
        (["sweep", write("layers.toml", "[axes]\nn = [1]\n[solver]\nn_layers = 100000000\n")],
         "'solver.n_layers' must be <= MAX_LAYERS = 4,096"),
        (["fit", write("label.csv", "voltage_V,frequency_Hz,m\n1000,40,1e20\n"), "--config",
          fit_config], "label.csv, line 2, column 'm': 1e20, must be an integer >= 0 and <= 2147483647"),
        (["fit", write("long.csv", "voltage_V,frequency_Hz\n1000," + "4" * 140_000 + "\n"),
          "--config", fit_config], "long.csv, line 2: field larger than field limit (131072)"),
        (["fit", write("under.csv", "voltage_V,frequency_Hz\n1000,2_86.62\n"), "--config",
          fit_config], "'2_86.62' is not a number"),
        (["fit", write("ok.csv", "voltage_V,frequency_Hz\n1000,40\n"), "--config",
          write("deep_fit.toml", "[free]\nshear_modulus = " + "[" * 5000 + "]" * 5000 + "\n")],
         "nest deeper than 64 levels"),
    ]


def test_hostile_inputs_are_one_line_with_status_2(tmp_path, capsys, monkeypatch):
    """Each input that raised RecursionError, OverflowError, _csv.Error, MemoryError or a JAX
    out-of-memory error, or that was silently misread (a repeated JSON key, 2_86.62): exit status
    2, one line naming the problem and the limit, nothing computed or written."""
    monkeypatch.chdir(tmp_path)
    cases = _hostile_inputs(tmp_path)
    inputs = set(tmp_path.iterdir())
    for argv, message in cases:
        assert cli.main(argv) == 2, argv
        captured = capsys.readouterr()
        assert captured.err.count("\n") == 1 and message in captured.err, (argv, captured.err)
        assert captured.out == ""
    assert set(tmp_path.iterdir()) == inputs


def test_a_byte_order_mark_is_accepted(tmp_path):
    """Excel's "CSV UTF-8" and some editors start a file with a byte-order mark: configs and peak
    tables are read as without it."""
    for name, text in (("a.json", json.dumps(SWEEP_DICT)), ("a.toml", SWEEP_TOML)):
        (tmp_path / name).write_bytes(b"\xef\xbb\xbf" + text.encode())
        cfg = config.load_config(tmp_path / name)
        assert cfg.n_roots == 2 and list(cfg.axes) == ["voltage", "n"]


def hand_result(omega_shift=0.0, status=None):
    """A SweepResult of voltage[2] x n[2] built by hand (the CLI's writing without a solve)."""
    omega = np.arange(8.0).reshape(2, 2, 2) + 1.0 + omega_shift
    return jd.SweepResult(axes={"voltage": np.array([0.0, 0.15]), "n": np.array([1.0, 3.0])},
                          omega=omega, status=np.zeros((2, 2, 2), np.int32) if status is None else status,
                          alpha=np.array([[0.4, 1.2], [0.4, 1.2]]),
                          settings=dict(tube=dict(lambda_i=0.95, lambda_z=1.2, eta=0.8, gent=60.0)))


@pytest.fixture
def previous_run(tmp_path, monkeypatch):
    """A config in tmp_path and the outputs of a previous run of it: (config, {name: bytes})."""
    monkeypatch.chdir(tmp_path)
    path = tmp_path / "grid.toml"
    path.write_text(SWEEP_TOML, encoding="utf-8")
    monkeypatch.setattr(jd, "sweep", lambda *a, **k: hand_result())
    assert cli.main(["--quiet", "sweep", str(path)]) == 0
    return path, {p.name: p.read_bytes() for p in tmp_path.glob("grid.*") if p != path}


def test_a_full_disk_keeps_the_previous_outputs(previous_run, monkeypatch, capsys):
    """A full disk while writing the set grid.csv, grid.npz, grid.png (here: a file-size limit
    below the PNG's size) leaves all three from the previous run, byte for byte, and no
    temporary; one line, exit status 2."""
    import resource
    import signal

    config_path, before = previous_run
    assert sorted(before) == ["grid.csv", "grid.npz", "grid.png"]
    capsys.readouterr()
    monkeypatch.setattr(jd, "sweep", lambda *a, **k: hand_result(omega_shift=0.5))
    soft, hard = resource.getrlimit(resource.RLIMIT_FSIZE)
    previous = signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
    resource.setrlimit(resource.RLIMIT_FSIZE, (len(before["grid.png"]) // 2, hard))
    try:
        status = cli.main(["--quiet", "sweep", str(config_path)])
    finally:
        resource.setrlimit(resource.RLIMIT_FSIZE, (soft, hard))
        signal.signal(signal.SIGXFSZ, previous)
    err = capsys.readouterr().err
    assert status == 2 and err.count("\n") == 1
    assert "cannot write into .: File too large (the previous files are unchanged)" in err
    folder = config_path.parent
    assert sorted(p.name for p in folder.iterdir()) == sorted([config_path.name, *before])
    assert {name: (folder / name).read_bytes() for name in before} == before


@pytest.mark.parametrize("signal_name, status", [("SIGINT", 130), ("SIGTERM", 143)])
def test_an_interrupted_sweep_saves_the_solved_points_apart(previous_run, monkeypatch, capsys,
                                                          signal_name, status):
    """Ctrl-C (or SIGTERM) during the solve: the points solved so far go to grid.partial.* (the
    others NaN with status NOT_SOLVED, the settings marked incomplete), the previous grid.* stay
    as they were, one line on stderr, exit status 130 (143); the next complete run removes the
    partial files."""
    import os
    import signal

    from jaxdea.studies.sweeps import SweepInterrupted

    config_path, before = previous_run
    capsys.readouterr()
    status_array = np.zeros((2, 2, 2), np.int32)
    status_array[1] = jd.Status.NOT_SOLVED
    partial = hand_result(omega_shift=0.5, status=status_array)
    partial.omega[1] = np.nan
    partial.settings["incomplete"] = True

    def interrupted(*args, **kwargs):  # as jaxdea.sweep meets an interrupt between two chunks
        try:
            if signal_name == "SIGTERM":  # as a batch system's time limit sends it
                os.kill(os.getpid(), signal.SIGTERM)
            raise KeyboardInterrupt
        except KeyboardInterrupt:
            raise SweepInterrupted(partial, 2, 4) from None

    monkeypatch.setattr(jd, "sweep", interrupted)
    assert cli.main(["--quiet", "sweep", str(config_path)]) == status
    captured = capsys.readouterr()
    assert captured.err == (f"jaxdea sweep: interrupted by {signal_name}: 2 of 4 points solved, "
                            "written to grid.partial.* (the others NaN, status 7 not solved)\n")
    folder = config_path.parent
    assert captured.out.splitlines() == [f"grid.partial.{ext}" for ext in ("csv", "npz", "png")]
    assert {name: (folder / name).read_bytes() for name in before} == before
    saved = jd.SweepResult.from_npz(folder / "grid.partial.npz")
    np.testing.assert_array_equal(saved.status, status_array)
    np.testing.assert_array_equal(saved.omega, partial.omega)
    assert saved.settings["incomplete"] is True
    table = np.loadtxt(folder / "grid.partial.csv", delimiter=",", skiprows=1)
    np.testing.assert_array_equal(table[2:, -2:], 7)  # status_1, status_2 of the unsolved points
    monkeypatch.setattr(jd, "sweep", lambda *a, **k: hand_result())
    assert cli.main(["--quiet", "sweep", str(config_path)]) == 0
    assert sorted(p.name for p in folder.iterdir()) == sorted([config_path.name, *before])


def test_an_interrupt_before_any_point_or_while_writing_changes_nothing(previous_run, monkeypatch,
                                                                        capsys):
    """Ctrl-C before a point is solved, or while the outputs are written: no file changes, no
    temporary is left, one line, exit status 130."""
    from jaxdea.studies.sweeps import SweepInterrupted

    config_path, before = previous_run
    folder = config_path.parent
    capsys.readouterr()

    def nothing_solved(*args, **kwargs):
        raise SweepInterrupted(None, 0, 4)

    def interrupted_plot(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(jd, "sweep", nothing_solved)
    assert cli.main(["--quiet", "sweep", str(config_path)]) == 130
    assert capsys.readouterr().err == ("jaxdea sweep: interrupted by SIGINT: 0 of 4 points solved; "
                                       "no file was written\n")
    monkeypatch.setattr(jd, "sweep", lambda *a, **k: hand_result(omega_shift=0.5))
    monkeypatch.setattr(cli, "plot_sweep", interrupted_plot)
    assert cli.main(["--quiet", "sweep", str(config_path)]) == 130
    captured = capsys.readouterr()
    assert captured.err == f"jaxdea sweep: interrupted by SIGINT: {cli.INTERRUPTED}\n"
    assert captured.out == ""
    assert sorted(p.name for p in folder.iterdir()) == sorted([config_path.name, *before])
    assert {name: (folder / name).read_bytes() for name in before} == before


def test_an_unexpected_error_is_still_one_line(tmp_path, monkeypatch, capsys):
    """An exception no check foresaw (here MemoryError from the solve) is one line with its type,
    exit status 2, not a traceback."""
    path = tmp_path / "grid.toml"
    path.write_text(SWEEP_TOML, encoding="utf-8")

    def out_of_memory(*args, **kwargs):
        raise MemoryError("Unable to allocate 7.28 TiB for an array")

    monkeypatch.setattr(jd, "sweep", out_of_memory)
    assert cli.main(["sweep", str(path), "--out", str(tmp_path)]) == 2
    assert capsys.readouterr().err == ("jaxdea sweep: error: unexpected MemoryError: Unable to "
                                       "allocate 7.28 TiB for an array\n")
