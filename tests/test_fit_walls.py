"""fit with a wall of its own (issue 44, users' terms): a Mooney–Rivlin tube and a layered tube
are fitted with their material and layers fixed, the estimate recovers the truth, and
fitted_frequencies rebuilds the wall from the result's settings; the errors of a bad wall."""

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
