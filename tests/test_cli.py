"""Command line interface: ``jaxdea sweep CONFIG``, ``jaxdea figures``, ``jaxdea table``, their help,
and the validation of sweep configurations (jaxdea.config)."""

import argparse
import json
import subprocess
import sys
import types
from pathlib import Path

import numpy as np
import pytest

import jaxdea as jd
from jaxdea import cli, config

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
    """The sweep through the CLI from a TOML file (outputs next to it, named by output.name) and
    from a JSON file (outputs in --out, named after the file)."""
    base = tmp_path_factory.mktemp("cli")
    toml_path, json_path = base / "cfg" / "grid_config.toml", base / "cfg" / "case.json"
    toml_path.parent.mkdir()
    toml_path.write_text(SWEEP_TOML, encoding="utf-8")
    json_path.write_text(json.dumps(SWEEP_DICT), encoding="utf-8")
    out_json = base / "json_out"
    codes = (cli.main(["--quiet", "sweep", str(toml_path)]),
             cli.main(["sweep", str(json_path), "--out", str(out_json), "--quiet"]))
    return codes, toml_path.parent / "grid", out_json / "case"


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
    assert cli.main(["sweep", str(toml_stem.parent / "grid_config.toml"), "--out", str(tmp_path)]) == 0
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
    ({"axes": {"n": [1]}, "output": {"formats": ["png"]}}, "'output.formats[0]' must be one of csv, npz"),
    ({"axes": {"n": [1]}, "output": {"name": "a/b"}}, "'output.name' must be a file stem without folders"),
    ({"axes": {"n": [1]}, "output": {"formats": [], "plot": False}}, "nothing would be written"),
    ([1, 2], "the document must be a table"),
]


@pytest.mark.parametrize(("data", "message"), BAD_CONFIGS, ids=[m[:40] for _, m in BAD_CONFIGS])
def test_bad_config_names_the_key_and_exits_2(tmp_path, capsys, data, message):
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(data), encoding="utf-8")
    assert cli.main(["sweep", str(path)]) == 2
    captured = capsys.readouterr()
    assert message in captured.err
    assert captured.err.startswith("jaxdea sweep: error: sweep config: ") and captured.out == ""
    assert list(tmp_path.iterdir()) == [path]  # nothing written


@pytest.mark.parametrize(("name", "text", "message"), [
    ("bad.toml", "[axes]\nn = [1, 2\n", "bad.toml is no valid TOML"),
    ("bad.json", '{"axes": ', "bad.json is no valid JSON"),
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
    assert (args["n_roots"], args["n_layers"], args["jacobian"], args["omega_max"]) == (3, 30, None, None)
    assert args["scheme"] == "midpoint"
    magnus = config.parse_config({"axes": {"alpha": [1.0]}, "solver": {"scheme": "magnus6"}})
    assert magnus.sweep_arguments()["scheme"] == "magnus6"
    gent_inf = config.parse_config({"tube": {"gent": float("inf")}, "axes": {"alpha": [1.0]}})
    assert gent_inf.tube["gent"] == np.inf


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
                *config.SOLVER_KEYS, *config.OUTPUT_KEYS, *config.LINSPACE_KEYS, *config.FORMATS):
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


@pytest.fixture
def fake_figures(monkeypatch):
    """A stand-in for jaxdea.figures (the figures themselves are tested with that module)."""
    calls = []

    def make_figures(out, quick=False, progress=True):
        calls.append(dict(out=out, quick=quick, progress=progress))
        return [out / "fig2.png", out / "fig2.csv"]

    monkeypatch.setitem(sys.modules, "jaxdea.figures",
                        types.SimpleNamespace(make_figures=make_figures))
    return calls


def test_figures_command_calls_make_figures(fake_figures, tmp_path, capsys):
    assert cli.main(["figures"]) == 0
    assert fake_figures[-1] == dict(out=Path("figures"), quick=False, progress=True)
    assert capsys.readouterr().out.splitlines() == [str(Path("figures") / "fig2.png"),
                                                    str(Path("figures") / "fig2.csv")]
    assert cli.main(["--quiet", "figures", "--out", str(tmp_path), "--quick"]) == 0
    assert fake_figures[-1] == dict(out=tmp_path, quick=True, progress=False)
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
    assert cli.main(["cache", "info"]) == 0
    assert f"{root}: 1 files" in capsys.readouterr().out
    assert cli.main(["cache", "clear"]) == 0
    assert f"removed {root}" in capsys.readouterr().out and not root.exists()
    monkeypatch.setenv("JAXDEA_CACHE_DIR", "off")
    assert cli.main(["cache", "clear"]) == 0 and "off" in capsys.readouterr().out
