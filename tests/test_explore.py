"""The interactive explorer (jaxdea.explore): the plotted curves are those of dispersion_curve for
the sliders' values, invalid values show their message instead of raising, a click gives the mode
shape of that root, and the stability status is first_instability's."""

import os
import subprocess
import sys
from types import SimpleNamespace

import numpy as np
import pytest

import jaxdea as jd
from jaxdea.explore import explorer_data, explorer_grid, judge_stability, stability_status

pytest.importorskip("ipywidgets")

TUBE = jd.Tube(voltage=0.05, lambda_i=0.9, lambda_z=1.2, eta=0.85)


@pytest.fixture(scope="module")
def app():
    return jd.explore(TUBE, stability=False)


def test_import_does_not_need_ipywidgets():
    code = ("import sys; sys.modules['ipywidgets'] = None\n"
            "import jax; jax.config.update('jax_enable_x64', True)\n"
            "import jaxdea\n"
            "try:\n    jaxdea.explore()\nexcept ImportError as e:\n    print(e)\n")
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120,
                         env=dict(os.environ, JAXDEA_CACHE_DIR="off"))
    assert run.returncode == 0, run.stderr
    assert "pip install jaxdea[explore]" in run.stdout


def test_grid_holds_the_axial_modes():
    grid, n, axial, rows = explorer_grid(TUBE, np.linspace(0.05, 3.0, 20), 4)
    assert grid.shape == (24,) and np.all(np.diff(grid) > 0)
    np.testing.assert_array_equal(n, [1, 2, 3, 4])
    np.testing.assert_allclose(axial, 2 * np.pi * n * 0.85 / (10 * 1.2), rtol=1e-14)
    np.testing.assert_array_equal(grid[rows], axial)


def test_stability_judgement():
    assert judge_stability(0.0293, 2, 1, 0.1).unstable
    assert not judge_stability(0.0293, 2, 1, 0.02).unstable
    assert judge_stability(0.0293, 2, 1, 0.0293).unstable  # V̂ ≥ V̂_first
    assert judge_stability(0.0, 3, 1, 0.0).text.startswith("UNSTABLE at every V̂")
    nothing = judge_stability(float("nan"), -1, 0, 0.2, n_max=2, m_max=1)
    assert not nothing.unstable and "m ≤ 1, n ≤ 2" in nothing.text


def test_sliders_redraw_the_dispersion_curve(app):
    app.controls["voltage"].value = 0.08
    app.controls["lambda_i"].value = 0.95
    tube, fluid, m = app.parameters()
    assert (float(tube.voltage), float(tube.lambda_i), fluid, m) == (0.08, 0.95, None, 0)
    curve = jd.dispersion_curve(TUBE.replace(voltage=0.08, lambda_i=0.95), app.data.alpha, n_roots=3)
    expected = np.asarray(curve.omega)
    assert np.all(np.isfinite(expected))
    np.testing.assert_allclose(app.data.omega, expected, rtol=1e-12)
    np.testing.assert_allclose(app.data.phase_velocity, expected / app.data.alpha[:, None], rtol=1e-12)
    for k, line in enumerate(app.lines):  # what is drawn
        np.testing.assert_allclose(line.get_xdata(), app.data.alpha, rtol=0)
        np.testing.assert_allclose(line.get_ydata(), expected[:, k], rtol=1e-12)
    markers = np.asarray(app.markers.get_ydata()).reshape(-1, 3)  # the axial modes n = 1 … 5
    np.testing.assert_allclose(markers, expected[app.data.axial_index], rtol=1e-12)
    np.testing.assert_allclose(app.data.alpha[app.data.axial_index],
                               jd.axial_wavenumber(TUBE, np.arange(1, 6)), rtol=1e-14)
    assert app.image.value[:8] == b"\x89PNG\r\n\x1a\n"


def test_invalid_values_show_the_message(app):
    app.controls["gent"].value = 0.1  # the paper's tube is past Gent locking at G = 0.1
    assert app.data is None and "Gent locking" in app.error
    assert "Gent locking" in app.message.value
    assert all(len(line.get_xdata()) == 0 for line in app.lines)
    app.set(gent=97.2, filled="filled", coupling="paper", m=1)  # the paper's coupling needs m = 0
    assert app.data is None and "axisymmetric" in app.error and "axisymmetric" in app.message.value
    app.set(filled="empty", coupling="acoustic", m=0)
    assert app.error is None and app.message.value == ""
    np.testing.assert_allclose(app.data.omega, explorer_data(app.parameters()[0]).omega, rtol=1e-12)


def test_click_shows_the_mode_shape(app):
    d = app.data
    row = d.axial_index[0]
    event = SimpleNamespace(inaxes=app.axes[0], xdata=d.alpha[row] + 0.01, ydata=d.omega[row, 1])
    app.on_click(event)  # the click lands next to branch 2 at α̂_1
    assert app.selection == (d.alpha[row], 1)
    alpha, omega, r, fields = app.mode
    assert (alpha, omega) == (d.alpha[row], d.omega[row, 1])
    r_ref, fields_ref = jd.mode_shape(app.parameters()[0], alpha, omega)
    np.testing.assert_allclose(r, r_ref, rtol=1e-12)
    np.testing.assert_allclose(fields, fields_ref, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(app.mode_lines[0].get_ydata(), fields_ref[0], rtol=1e-9, atol=1e-12)
    assert tuple(app.picked.get_data()[1]) == (omega,)
    app.controls["voltage"].value = 0.06  # the selection follows the new parameters
    assert app.mode[1] == app.data.omega[row, 1] != omega


@pytest.mark.slow
def test_stability_status_is_the_first_instability():
    app = jd.explore(TUBE.replace(voltage=0.1), m_max=3)
    first = jd.first_instability(TUBE, n_max=3, m_max=3)
    app.wait()  # the first-instability solve runs in the background
    assert (app.status.m, app.status.n) == (int(first.m), int(first.n)) == (2, 1)
    assert app.status == stability_status(TUBE.replace(voltage=0.1), m_max=3)
    np.testing.assert_allclose(app.status.voltage, float(first.voltage), rtol=1e-12)
    assert app.status.unstable and "UNSTABLE" in app.status_label.value
    assert app.axes[0].get_facecolor()[:3] != (1.0, 1.0, 1.0)
    app.controls["voltage"].value = 0.02  # below V̂_first = 0.0293: no new first_instability solve
    assert not app.status.unstable and "stable" in app.status_label.value
    assert app.axes[0].get_facecolor()[:3] == (1.0, 1.0, 1.0)
    app.controls["lambda_i"].value = 1.1  # a new wall: curves at once, the status once solved
    np.testing.assert_allclose(app.data.omega, explorer_data(app.parameters()[0], alphas=app.alphas).omega,
                               rtol=1e-12)
    app.wait()
    assert app.status == stability_status(TUBE.replace(voltage=0.02, lambda_i=1.1), m_max=3)
    assert "solving" not in app.status_label.value


@pytest.mark.slow
def test_order_m_in_a_filled_tube():
    app = jd.explore(TUBE, jd.Fluid(), stability=False)
    app.controls["m"].value = 2
    fluid = jd.Fluid()
    curve = jd.dispersion_curve(TUBE, app.data.alpha, fluid, n_roots=3, m=2)
    np.testing.assert_allclose(app.data.omega, np.asarray(curve.omega), rtol=1e-12)
    alpha, omega, r, fields = app.select(1.0, 0)
    assert fields.shape[0] == 8
    _, fields_ref = jd.mode_shape(TUBE, alpha, omega, fluid, m=2)
    np.testing.assert_allclose(fields, fields_ref, rtol=1e-9, atol=1e-12)
