"""The main job: ``make_figures`` writes every figure and its CSV; the numbers in the CSVs are those of
direct solves, blank points are exactly the points past the critical voltage.

The quick run compiles the three sweep programs and the critical-voltage solver (minutes on two
cores): slow tier. In the default run the paper-reproduction notebook (tests/test_notebooks.py)
drives the same figure functions in their quick setting."""

import csv
import math

import numpy as np
import pytest

import jaxdea as jd
from jaxdea import figures
from jaxdea.params import gent_limit_excess

EXPECTED = ["static_response", "fig2_voltage_empty", "fig3_modes_empty", "fig4_modes_critical_empty",
            "fig5_voltage_fluid", "fig6_modes_fluid", "fig7_modes_critical_fluid", "fig8_speed_ratio",
            "fig9_density_ratio", "fig10_thickness_ratio", "comparison_couplings"]


def test_locking_stretch_is_where_i1_reaches_gent():
    lock = figures.locking_stretch(figures.PAPER_TUBE)
    excess = gent_limit_excess(lock, 1.2, 1.0)  # inner face: λ = λ_i (η = 1 makes r_o = r_i)
    assert float(excess) == pytest.approx(97.2, rel=1e-12)


@pytest.fixture(scope="module")
def written(tmp_path_factory):
    out = tmp_path_factory.mktemp("figures")
    paths = figures.make_figures(out, quick=True, progress=False)
    return out, paths


def rows(out, name):
    with open(out / f"{name}.csv") as fh:
        return list(csv.DictReader(fh))


@pytest.mark.slow
def test_every_figure_has_a_png_and_its_csv(written):
    out, paths = written
    assert sorted(p.name for p in paths) == sorted(f"{n}.{ext}" for n in EXPECTED for ext in ("png", "csv"))
    for name in EXPECTED:
        assert (out / f"{name}.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        assert len(rows(out, name)) > 0


@pytest.mark.slow
def test_csv_values_are_direct_solves(written):
    out, _ = written
    table = rows(out, "fig6_modes_fluid")
    solved = [r for r in table if r["status"] == "converged"]
    assert {r["coupling"] for r in solved} == {"acoustic", "paper"}
    for r in (solved[0], solved[-1]):
        tube = figures.PAPER_TUBE.replace(lambda_i=float(r["lambda_i"]), voltage=float(r["voltage"]))
        alpha = jd.axial_wavenumber(tube, int(r["n"]))
        fluid = jd.Fluid(**figures.PAPER_FLUID, coupling=r["coupling"])
        direct = float(jd.frequencies(tube, alpha, fluid, n_roots=1)[0])
        assert float(r["alpha_hat"]) == pytest.approx(float(alpha), rel=1e-14)
        assert float(r["omega"]) == pytest.approx(direct, rel=1e-10)
        assert float(r["phase_velocity"]) == pytest.approx(direct / float(alpha), rel=1e-10)


@pytest.mark.slow
def test_blank_points_are_exactly_those_past_the_critical_voltage(written):
    out, _ = written
    table = rows(out, "fig3_modes_empty")
    for r in table:
        past = float(r["voltage"]) >= float(r["v_critical"])
        assert (r["status"] == "past critical") == past
        assert math.isnan(float(r["omega"])) == (past or r["status"] != "converged")
    assert any(r["status"] == "past critical" for r in table)  # V̂ = 0.2 buckles λ_i = 1.1 modes
    r = next(r for r in table if r["lambda_i"] == "1.1" and r["n"] == "1")
    tube = figures.PAPER_TUBE.replace(lambda_i=1.1)
    v_cr = float(jd.critical_voltage(tube, jd.axial_wavenumber(tube, 1)))
    assert float(r["v_critical"]) == pytest.approx(v_cr, rel=1e-10)


@pytest.mark.slow
def test_static_response_ends_at_gent_locking(written):
    out, _ = written
    table = rows(out, "static_response")
    for dp in {r["delta_p"] for r in table}:
        volt = np.array([float(r["voltage"]) for r in table if r["delta_p"] == dp])
        volt = volt[np.isfinite(volt)]
        assert np.all(np.diff(volt) > 0)  # monotonic: no pull-in maximum at fixed λ_z
        assert all(math.isnan(float(r["pull_in_voltage"])) for r in table)
