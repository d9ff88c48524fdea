"""The [material] and [[layers]] tables of the sweep configuration (issue 44, "users' terms"): the
objects they build and a layered sweep through the CLI equal to the library (each bad input's
ValueError: tests/test_cli.py, BAD_WALL_CONFIGS)."""

import contextlib
import dataclasses

import numpy as np

import jaxdea as jd
from jaxdea.apps import cli
from jaxdea.io import config

LAYERED_TOML = """
[tube]
voltage = 0.02
lambda_i = 1.1
lambda_z = 1.2
eta = 0.8

[[layers]]
fraction = 0.2
shear_ratio = 3.0
material = { kind = "neo_hookean" }

[[layers]]
fraction = 0.6
active = true
material = { kind = "gent", gent = 97.2 }

[[layers]]
fraction = 0.2
shear_ratio = 3.0
[layers.material]
kind = "mooney_rivlin"
beta = 0.1

[axes]
alpha = 0.8
layer2_fraction = [0.1, 0.3]

[solver]
n_roots = 2
n_layers = 12
scheme = "magnus6"
jacobian = ["layer2_shear_ratio"]

[output]
name = "walls"
formats = ["npz"]
plot = false
"""
LAYERS = (jd.Layer(0.2, jd.NeoHookean(), shear_ratio=3.0), jd.Layer(0.6, jd.Gent(97.2), active=True),
          jd.Layer(0.2, jd.MooneyRivlin(0.1), shear_ratio=3.0))
TUBE = jd.Tube(voltage=0.02, lambda_i=1.1, lambda_z=1.2, eta=0.8, layers=LAYERS)


def test_material_and_layers_tables_build_the_objects():
    """[material] gives the material object and its parameter is an axis; [[layers]] the tuple of
    jaxdea.Layer (TOML's [layers.material] sub-table and an inline table alike)."""
    cfg = config.parse_config({"material": {"kind": "mooney_rivlin", "beta": 0.3},
                               "axes": {"alpha": 0.8, "material_beta": [0.1, 0.2]},
                               "solver": {"jacobian": ["material_beta"]}})
    assert cfg.tube == {"material": jd.MooneyRivlin(0.3)} and cfg.jacobian == ("material_beta",)
    np.testing.assert_array_equal(cfg.axes["material_beta"], [0.1, 0.2])
    ogden = config.parse_config({"material": {"kind": "ogden", "mu": [0.5, 0.5], "alpha": [2.0, 2.0]},
                                 "axes": {"alpha": 0.8}})
    assert ogden.tube["material"] == jd.Ogden((0.5, 0.5), (2.0, 2.0))
    import tomllib
    layered = config.parse_config(tomllib.loads(LAYERED_TOML))
    assert layered.tube["layers"] == LAYERS
    assert jd.Tube(**layered.tube) == TUBE


def test_layered_sweep_from_toml_equals_the_library(tmp_path):
    """The TOML above through ``jaxdea sweep``: the result equals jaxdea.sweep of the tube built in
    Python bit for bit, and its point layer2_fraction = 0.3 equals jaxdea.frequencies of the wall
    (liner 0.2, active 0.5, encapsulation 0.3) to 1e-12."""
    path = tmp_path / "walls.toml"
    path.write_text(LAYERED_TOML, encoding="utf-8")
    with contextlib.chdir(tmp_path):
        assert cli.main(["--quiet", "sweep", str(path)]) == 0
    got = jd.SweepResult.from_npz(tmp_path / "walls.npz")
    ref = jd.sweep(TUBE, alpha=0.8, layer2_fraction=np.array([0.1, 0.3]), n_roots=2, n_layers=12,
                   scheme="magnus6", jacobian=["layer2_shear_ratio"], progress=False)
    np.testing.assert_array_equal(got.omega, ref.omega)
    np.testing.assert_array_equal(got.jacobian, ref.jacobian)
    assert got.settings == ref.settings and got.settings["layers"][2]["material"] == {
        "kind": "mooney_rivlin", "beta": 0.1}
    layers = (LAYERS[0], dataclasses.replace(LAYERS[1], fraction=0.5),
              dataclasses.replace(LAYERS[2], fraction=0.3))
    by_hand = jd.frequencies(TUBE.replace(layers=layers), 0.8, n_roots=2, n_layers=12, scheme="magnus6")
    np.testing.assert_allclose(got.omega[0, 1], by_hand, rtol=1e-12)
