"""SweepResult as an xarray Dataset and a netCDF file, and its SI outputs (with_units)."""

import json
import math
import sys

import numpy as np
import pytest

import jaxdea as jd
from jaxdea.studies.sweeps import SweepResult
from jaxdea.units import VACUUM_PERMITTIVITY, Scales

xr = pytest.importorskip("xarray")

# a VHB 4910-like elastomer: μ = 20 kPa, ρ_s = 960 kg/m³, ε = 4.7 ε_0, R_i = 5 mm
MU, RHO, EPS, RI = 20e3, 960.0, 4.7 * 8.8541878188e-12, 5e-3
VHB = Scales(shear_modulus=MU, density=RHO, permittivity=4.7 * VACUUM_PERMITTIVITY, inner_radius=RI)
SETTINGS = {
    "tube": {"voltage": 0.0, "lambda_i": 0.9, "lambda_z": 1.2, "eta": 0.85, "gent": 97.2,
             "length_ratio": 10.0},
    "material": "gent", "n_roots": 2, "omega_max": None, "n_layers": 8, "scheme": "magnus4",
    "torsional": False, "fluid": {"density_ratio": 0.13, "speed_ratio": 0.27},
    "coupling": "acoustic", "bessel_order": None, "n_growth": 2,
}


@pytest.fixture(scope="module")
def result():
    """A synthetic result over voltage (2) x n (3), 2 roots, a 2-name jacobian and 2 growth rates
    (no solve: the layout is what is tested)."""
    rng = np.random.default_rng(7)
    shape = (2, 3)
    status = np.zeros((*shape, 2), np.int32)
    status[1, 2, 1] = jd.Status.NO_ROOT
    omega = rng.uniform(0.1, 2.0, (*shape, 2))
    omega[1, 2, 1] = np.nan
    growth = np.full((*shape, 2), np.nan)
    growth[1, 0, 0] = 0.031
    return SweepResult(
        axes={"voltage": np.array([0.0, 0.2]), "n": np.array([1.0, 2.0, 3.0])},
        omega=omega, status=status, alpha=rng.uniform(0.4, 1.4, shape),
        jacobian=rng.normal(size=(*shape, 2, 2)), jacobian_names=("voltage", "lambda_i"),
        group_velocity=rng.normal(size=(*shape, 2)), growth_rate=growth, settings=SETTINGS)


def test_dataset_has_named_dimensions_variables_and_settings(result):
    ds = result.to_xarray()
    assert tuple(ds["omega"].dims) == ("voltage", "n", "root")
    assert tuple(ds["growth_rate"].dims) == ("voltage", "n", "growth")
    np.testing.assert_array_equal(ds["voltage"], [0.0, 0.2])
    np.testing.assert_array_equal(ds["n"], [1.0, 2.0, 3.0])
    np.testing.assert_array_equal(ds["root"], [1, 2])
    np.testing.assert_array_equal(ds["growth"], [1, 2])
    np.testing.assert_array_equal(ds["omega"], result.omega)
    np.testing.assert_array_equal(ds["status"], result.status)
    assert ds["status"].dtype == np.int32 and ds["status"].attrs["flag_meanings"].split()[1] == "no_root"
    np.testing.assert_array_equal(ds["alpha_hat"], result.alpha)
    np.testing.assert_array_equal(ds["group_velocity"], result.group_velocity)
    np.testing.assert_array_equal(ds["d_omega_d_lambda_i"], result.jacobian[..., 1])
    np.testing.assert_array_equal(ds["d_omega_d_voltage"], result.jacobian[..., 0])
    np.testing.assert_array_equal(ds["unstable"], [[False, False, False], [True, False, False]])
    assert float(ds["omega"].sel(voltage=0.2, n=3.0, root=1)) == result.omega[1, 2, 0]
    attrs = ds.attrs
    assert (attrs["n_layers"], attrs["scheme"], attrs["coupling"], attrs["n_growth"]) == (8, "magnus4",
                                                                                          "acoustic", 2)
    assert attrs["tube_lambda_z"] == 1.2 and attrs["fluid_speed_ratio"] == 0.27
    assert "tube_voltage" not in attrs  # swept, not fixed
    assert "omega_max" not in attrs and "bessel_order" not in attrs  # None is left out
    assert attrs["torsional"] == 0
    assert "1: no_root" in attrs["status_meaning"]
    assert json.loads(attrs["settings_json"]) == SETTINGS
    assert not any(k.endswith("_Hz") or k.endswith("_V") for k in ds.variables)  # no units given


def test_netcdf_round_trip(result, tmp_path):
    pytest.importorskip("netCDF4")
    path = tmp_path / "grid.nc"
    result.with_units(VHB).to_netcdf(path)
    with xr.open_dataset(path) as back:
        back.load()
    assert list(back.dims) == ["voltage", "n", "root", "growth"]
    np.testing.assert_array_equal(back["omega"], result.omega)  # NaN included
    np.testing.assert_array_equal(back["status"], result.status)
    np.testing.assert_array_equal(back["growth_rate"], result.growth_rate)
    np.testing.assert_array_equal(back["n"], [1.0, 2.0, 3.0])
    np.testing.assert_allclose(back["voltage_V"], [0.0, 0.2 * RI * math.sqrt(MU / EPS)], rtol=1e-14)
    assert back["frequency_Hz"].attrs["units"] == "Hz"
    assert back.attrs["scheme"] == "magnus4" and back.attrs["units_inner_radius"] == RI
    assert json.loads(back.attrs["settings_json"])["units"]["shear_modulus"] == MU
    assert back["unstable"].dtype == bool and bool(back["unstable"][1, 0])


def test_si_values_by_hand(result, tmp_path):
    """f = Ω c_s/(2π R_i) with c_s = sqrt(μ/ρ_s), V = V̂ R_i sqrt(μ/ε), Λ = 2π R_i/α̂ and
    σ = s c_s/R_i, written out here (not through jaxdea.units)."""
    si = result.with_units(VHB)
    c_s = math.sqrt(MU / RHO)
    assert c_s / (2 * math.pi * RI) == pytest.approx(145.29, abs=0.005)  # Ω = 1 is 145.29 Hz
    hz = result.omega * c_s / (2 * math.pi * RI)
    np.testing.assert_allclose(si.frequency_hz, hz, rtol=1e-14)
    np.testing.assert_allclose(si.wavelength_m, 2 * math.pi * RI / result.alpha, rtol=1e-14)
    np.testing.assert_allclose(si.growth_rate_per_s, result.growth_rate * c_s / RI, rtol=1e-14)
    ds = si.to_xarray()
    np.testing.assert_allclose(ds["frequency_Hz"], hz, rtol=1e-14)
    np.testing.assert_allclose(ds["voltage_V"], [0.0, 0.2 * RI * math.sqrt(MU / EPS)], rtol=1e-14)
    assert ds["voltage_V"].dims == ("voltage",)
    si.to_csv(tmp_path / "grid.csv")
    header = (tmp_path / "grid.csv").read_text().splitlines()[0].split(",")
    assert header[:4] == ["voltage", "n", "voltage_V", "alpha_hat"]
    assert {"wavelength_m", "frequency_Hz_1", "frequency_Hz_2", "growth_rate_per_s_2"} <= set(header)
    table = np.loadtxt(tmp_path / "grid.csv", delimiter=",", skiprows=1)
    np.testing.assert_allclose(table[:, header.index("frequency_Hz_1")], hz[..., 0].ravel(), rtol=1e-14)
    np.testing.assert_allclose(table[:, header.index("voltage_V")], [0, 0, 0, *[21922.58] * 3], rtol=1e-6)
    si.to_npz(tmp_path / "grid.npz")
    with np.load(tmp_path / "grid.npz") as data:
        np.testing.assert_allclose(data["frequency_Hz"], hz, rtol=1e-14)
    back = SweepResult.from_npz(tmp_path / "grid.npz")
    assert back.scales == Scales(MU, RHO, 4.7 * VACUUM_PERMITTIVITY, RI)
    np.testing.assert_array_equal(back.frequency_hz, si.frequency_hz)


@pytest.mark.parametrize(("changes", "name"), [({"shear_modulus": -1.0}, "shear_modulus"),
                                                ({"density": 0.0}, "density"),
                                                ({"inner_radius": math.inf}, "inner_radius"),
                                                ({"permittivity": "a lot"}, "permittivity")])
def test_with_units_rejects_bad_scales(result, changes, name):
    with pytest.raises(ValueError, match=name):
        result.with_units(VHB.replace(**changes))
    with pytest.raises(ValueError, match="Scales"):
        result.with_units({"shear_modulus": MU})


def test_missing_xarray_names_the_extra(result, monkeypatch, tmp_path):
    monkeypatch.setitem(sys.modules, "netCDF4", None)
    with pytest.raises(ImportError, match=r"pip install 'jaxdea\[xarray\]'"):
        result.to_netcdf(tmp_path / "grid.nc")
    monkeypatch.setitem(sys.modules, "xarray", None)
    with pytest.raises(ImportError, match=r"pip install 'jaxdea\[xarray\]'"):
        result.to_xarray()
    assert list(tmp_path.iterdir()) == []
