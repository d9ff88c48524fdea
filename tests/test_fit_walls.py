"""fit with a wall of its own (issue 44, users' terms): a Mooney–Rivlin tube and a layered tube
are fitted with their material and layers fixed, or with a wall parameter free (β, a liner's shear
ratio: item 3), the estimate recovers the truth, and fitted_frequencies rebuilds the wall from the
result's settings; the errors of a bad wall and of bad wall names."""

import jax.numpy as jnp
import numpy as np
import pytest
from test_fit import N_LAYERS, synthetic

import jaxdea as jd
from jaxdea.studies import fit as fit_module
from jaxdea.studies.fit import FitStatus, fit, fitted_frequencies
from jaxdea.units import VACUUM_PERMITTIVITY

TRUTH = dict(shear_modulus=1e5, density=1000.0, permittivity=4.7 * VACUUM_PERMITTIVITY,
             inner_radius=5e-3, length=50e-3, eta=0.85, lambda_i=1.0, lambda_z=1.2)
POINTS = [(v, m, n) for v in (2e3, 5e3) for m in (0, 1) for n in (1, 2)]
MOONEY = jd.MooneyRivlin(0.3)
SANDWICH = (jd.Layer(0.2, jd.NeoHookean(), shear_ratio=3.0), jd.Layer(0.6, jd.Gent(97.2), active=True),
            jd.Layer(0.2, jd.NeoHookean(), shear_ratio=3.0))


@pytest.mark.parametrize("wall", [dict(material=MOONEY), dict(layers=SANDWICH)],
                         ids=["mooney_rivlin", "layers"])
def test_fit_with_its_wall_recovers_the_truth(wall):
    """Exact peaks of the wall: μ and λ_i from starts 20 % off to 1e-8, no parameter gent, and
    fitted_frequencies (its wall rebuilt from the settings) gives the peaks to 1e-9."""
    data = synthetic(POINTS, TRUTH, **wall)
    free = {"shear_modulus": (5e4, 2e5), "lambda_i": (0.7, 1.3)}
    fixed = {k: v for k, v in TRUTH.items() if k not in free}
    result = fit(data, free, fixed, initial=dict(shear_modulus=1.2e5, lambda_i=0.8),
                 n_layers=N_LAYERS, n_starts=0, **wall)
    assert result.status == FitStatus.CONVERGED
    for name in free:
        assert abs(result.estimate[name] / TRUTH[name] - 1.0) <= 1e-8, name
    assert "gent" not in result.parameters
    again = fitted_frequencies(result, data["voltage_V"], data["m"], data["n"])
    np.testing.assert_allclose(again, data["frequency_Hz"], rtol=1e-9)


GOOD = dict(voltage_V=[1e3, 2e3, 3e3, 4e3], frequency_Hz=[100.0, 110.0, 120.0, 130.0])
FREE = {"shear_modulus": (5e4, 2e5)}
FIXED = {k: v for k, v in TRUTH.items() if k != "shear_modulus"}


@pytest.mark.parametrize("wall, fixed, match", [
    (dict(material=MOONEY), dict(FIXED, gent=97.2), "'gent' is the Gent constant of the default wall"),
    (dict(material=jd.Gent(50.0)), FIXED, "material=Gent\\(G\\): leave material out"),
    (dict(material=jd.MooneyRivlin(1.5)), FIXED, "beta must be in \\[0, 1\\]"),
    (dict(layers=SANDWICH[:2]), FIXED, "the fractions must sum to 1"),
    (dict(layers=SANDWICH, material=MOONEY), FIXED, "the tube's material and damping must stay"),
])
def test_bad_wall_raises_naming_it(wall, fixed, match):
    with pytest.raises(ValueError, match=match):
        fit(GOOD, FREE, fixed, n_layers=N_LAYERS, **wall)


def test_a_wall_needs_no_gent():
    """Without gent the problem of a Mooney–Rivlin wall validates; the wall's settings round-trip."""
    wall = fit_module._wall(MOONEY, None)
    problem, _ = fit_module._validate(GOOD, FREE, FIXED, None, wall)
    assert problem.base[fit_module.NAMES.index("gent")] == jd.Tube.gent
    for tube in (wall, fit_module._wall(None, SANDWICH)):
        settings = jd.studies.sweeps.wall_settings(tube)
        assert jd.studies.sweeps.wall_from_settings(settings) == tube


def test_fit_config_tables_build_the_wall():
    """[material] and [[layers]] of ``jaxdea fit``'s configuration give fit's material and layers."""
    from jaxdea.io import fit_io

    base = {"free": {"shear_modulus": [5e4, 2e5]}, "fixed": {"density": 1000.0}}
    config = fit_io.parse_fit_config(dict(base, material={"kind": "mooney_rivlin", "beta": 0.3}))
    assert config.material == MOONEY and config.layers is None
    tables = [{"fraction": 0.2, "material": {"kind": "neo_hookean"}, "shear_ratio": 3.0},
              {"fraction": 0.6, "active": True, "material": {"kind": "gent", "gent": 97.2}},
              {"fraction": 0.2, "material": {"kind": "neo_hookean"}, "shear_ratio": 3.0}]
    assert fit_io.parse_fit_config(dict(base, layers=tables)).layers == SANDWICH
    for bad, match in ((dict(base, material={"kind": "rubber"}), "'material.kind' must be one of"),
                       (dict(base, layers=[{"fraction": 1.0}]), "exactly one layer must be active"),
                       (dict(base, layers=tables, material={"kind": "neo_hookean"}),
                        "material, layers: both set the wall's energy")):
        with pytest.raises(ValueError, match=match):
            fit_io.parse_fit_config(bad)


# ------------------------------------------------------------------ free wall parameters (item 3)

LINER = (jd.Layer(0.2, jd.NeoHookean(), shear_ratio=3.0), jd.Layer(0.8, jd.Gent(97.2), active=True))
"""A 2-layer wall: a stiff passive liner inside the dielectric (its shear ratio is fitted)."""
FREE_WALLS = [  # (name, truth, true wall, start wall, bounds, μ free too)
    ("material_beta", 0.3, dict(material=MOONEY), dict(material=jd.MooneyRivlin(0.1)), (0.0, 1.0),
     True),
    # μ and the liner's ratio together are correlated at -0.999 on these peaks (a stiffness scale):
    # μ held, the ratio alone free
    ("layer0_shear_ratio", 3.0, dict(layers=LINER),
     dict(layers=(jd.Layer(0.2, jd.NeoHookean(), shear_ratio=2.0), LINER[1])), (0.5, 10.0), False),
]


@pytest.mark.parametrize("name, truth, true_wall, start_wall, bounds, with_mu", FREE_WALLS,
                         ids=[w[0] for w in FREE_WALLS])
def test_fit_frees_a_wall_parameter(name, truth, true_wall, start_wall, bounds, with_mu):
    """A wall parameter free (with μ for β), its start 0.1 (β) or 2.0 (liner ratio) off its truth:
    exact peaks give both to 1e-8 (the wall parameter to 1e-6 at least); peaks with 0.1 % noise
    and that σ give 95 % intervals that hold the truth; the settings carry the fitted wall."""
    data = synthetic(POINTS, TRUTH, **true_wall)
    free = dict({"shear_modulus": (5e4, 2e5)} if with_mu else {}, **{name: bounds})
    fixed = {k: v for k, v in TRUTH.items() if k not in free}
    initial = dict(shear_modulus=1.2e5) if with_mu else {}
    result = fit(data, free, fixed, initial=initial, n_layers=N_LAYERS, n_starts=0, **start_wall)
    assert result.status == FitStatus.CONVERGED
    assert result.names == tuple(free)
    assert abs(result.estimate[name] - truth) <= 1e-6 * truth, result.estimate
    if with_mu:
        assert abs(result.estimate["shear_modulus"] / TRUTH["shear_modulus"] - 1.0) <= 1e-8
    assert result.parameters[name] == result.estimate[name]
    settings = result.settings["material"] if name.startswith("material_") \
        else result.settings["layers"][0]
    assert settings[name.rsplit("_", 1)[-1] if name.startswith("material_") else "shear_ratio"] \
        == pytest.approx(result.estimate[name], rel=1e-12)
    rng = np.random.default_rng(0)
    sigma = 1e-3 * data["frequency_Hz"]
    noisy = dict(data, frequency_Hz=data["frequency_Hz"] + sigma * rng.standard_normal(sigma.size),
                 sigma_Hz=sigma)
    result = fit(noisy, free, fixed, initial=initial, n_layers=N_LAYERS, n_starts=0, **start_wall)
    assert result.status == FitStatus.CONVERGED
    for key in free:
        value = truth if key == name else TRUTH[key]
        low, high = result.interval[key]
        assert low < value < high, (key, result.estimate[key], result.interval[key])
        assert high - low < 0.5 * (free[key][1] - free[key][0])  # an informative interval


@pytest.mark.parametrize("name, wall", [("material_beta", dict(material=MOONEY)),
                                        ("layer0_shear_ratio", dict(layers=LINER)),
                                        ("layer0_fraction", dict(layers=LINER))])
def test_wall_parameter_jacobian_matches_central_differences(name, wall):
    """The Jacobian column of a wall parameter (jacfwd through the implicit root derivative)
    against central differences of the model's f, h = 1e-5 · value, to 1e-6 relative."""
    tube = fit_module._wall(wall.get("material"), wall.get("layers"))
    value = float(jd.physics.leaves.get_parameter(tube, None, None, name))
    base = np.array([TRUTH.get(k, 1.0) for k in fit_module.NAMES] + [value])
    base[fit_module.NAMES.index("gent")] = jd.Tube.gent
    voltage, n, m = np.array([2e3, 5e3]), np.array([1.0, 2.0]), np.array([1.0, 1.0])
    args = (jnp.asarray(voltage), jnp.asarray(n), jnp.asarray(m))
    family = fit_module.Family.ORDER_M
    roots = fit_module.mode_roots(jnp.asarray(base), *args, 1, N_LAYERS, None, None, family,
                                  wall=tube, wall_leaves=(name,))[:, 0]

    def model(values):
        return fit_module.model_and_jacobian(jnp.asarray(values), *args, roots, N_LAYERS, None,
                                             None, family, wall=tube, wall_leaves=(name,))

    _, f, jac = model(base)
    h = 1e-5 * value
    up, down = base.copy(), base.copy()
    up[-1] += h
    down[-1] -= h
    difference = (np.asarray(model(up)[1]) - np.asarray(model(down)[1])) / (2.0 * h)
    assert np.all(np.abs(difference) > 1e-3 * np.asarray(f) / value)  # the column is not ~0
    np.testing.assert_allclose(np.asarray(jac)[:, -1], difference, rtol=1e-6)


@pytest.mark.parametrize("wall, free, match", [
    (dict(material=MOONEY), {"material_gamma": (0.0, 1.0)},
     "unknown parameter 'material_gamma' \\(the tube's MooneyRivlin has no scalar parameter "
     "'gamma'\\).*known: .*material_beta"),
    ({}, {"material_beta": (0.0, 1.0)}, "'material_beta' \\(material_ names need a material object"),
    (dict(layers=LINER), {"layer2_shear_ratio": (1.0, 5.0)},
     "'layer2_shear_ratio' \\(the tube has 2 layers.*known: .*layer0_shear_ratio, "
     "layer0_density_ratio"),
    (dict(layers=LINER), {"layer1_shear_ratio": (1.0, 5.0)}, "'layer1_shear_ratio' \\(the active"),
    (dict(material=MOONEY), {"layer0_fraction": (0.1, 0.3)}, "'layer0_fraction' \\(layer names "
     "need a layered wall, layers=...\\)"),
    (dict(material=MOONEY), {"material_beta": (0.0, 1.5)},
     "free\\['material_beta'\\] bounds must keep the wall valid.*at 1.5, .*beta must be in"),
    (dict(layers=LINER), {"layer0_shear_ratio": (0.0, 5.0)},
     "free\\['layer0_shear_ratio'\\] bounds.*shear_ratio must be a finite number > 0"),
    (dict(layers=LINER), {"layer0_fraction": (0.1, 1.0)},
     "free\\['layer0_fraction'\\] bounds.*fraction must be a finite number > 0"),
])
def test_bad_wall_parameter_names_are_named(wall, free, match):
    with pytest.raises(ValueError, match=match):
        fit(GOOD, dict(FREE, **free), FIXED, n_layers=N_LAYERS, **wall)


def test_a_wall_parameter_cannot_be_fixed():
    with pytest.raises(ValueError, match="fixed\\['material_beta'\\]: a wall parameter is held at its "
                                         "value on material="):
        fit(GOOD, FREE, dict(FIXED, material_beta=0.3), n_layers=N_LAYERS, material=MOONEY)


def test_fit_config_frees_wall_parameters():
    """[free] of ``jaxdea fit``'s configuration names the wall's parameters of its [material] or
    [[layers]] (no initial needed for them); without that wall the name is unknown, listing the
    allowed keys."""
    from jaxdea.io import fit_io

    base = {"free": {"shear_modulus": {"lower": 5e4, "upper": 2e5, "initial": 1e5},
                     "material_beta": [0.0, 1.0]}, "fixed": {"density": 1000.0}}
    config = fit_io.parse_fit_config(dict(base, material={"kind": "mooney_rivlin", "beta": 0.1}))
    assert config.free["material_beta"] == (0.0, 1.0)
    assert config.initial == {"shear_modulus": 1e5}
    tables = [{"fraction": 0.2, "material": {"kind": "neo_hookean"}, "shear_ratio": 2.0},
              {"fraction": 0.8, "active": True, "material": {"kind": "gent", "gent": 97.2}}]
    layered = dict(base, free={"layer0_shear_ratio": [0.5, 10.0]}, layers=tables)
    assert fit_io.parse_fit_config(layered).free == {"layer0_shear_ratio": (0.5, 10.0)}
    with pytest.raises(ValueError, match="free.material_beta: unknown key \\(allowed: .*gent"):
        fit_io.parse_fit_config(base)
