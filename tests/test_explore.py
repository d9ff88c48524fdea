"""The interactive explorer (jaxdea.explore): the plotted curves are those of dispersion_curve for
the sliders' values, invalid values show their message instead of raising, a click gives the mode
shape of that root, and the stability status is first_instability's."""

import importlib.util
import os
import subprocess
import sys
from types import SimpleNamespace

import numpy as np
import pytest

import jaxdea as jd
from jaxdea.apps.explore import (
    damped_roots,
    explorer_data,
    explorer_grid,
    judge_stability,
    stability_status,
    unstable_alphas,
)

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
    assert app.png()[:8] == b"\x89PNG\r\n\x1a\n"


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


def test_toggle_rows_are_labelled_and_fluid_controls_follow_the_tube(app):
    """The toggle rows say what they choose; the fluid controls are disabled for an empty tube and ν
    only acts with the paper's coupling."""
    c = app.controls
    assert c["filled"].description == "tube" and c["coupling"].description == "fluid model"
    assert app.parameters()[1] is None
    assert all(c[key].disabled for key in ("density_ratio", "speed_ratio", "coupling", "bessel_order"))
    app._holding = True  # switch the controls without solving the filled tube
    try:
        c["filled"].value = "filled"
        app._sync_controls()
        assert not any(c[key].disabled for key in ("density_ratio", "speed_ratio", "coupling"))
        assert c["bessel_order"].disabled  # the acoustic coupling has no ν
        c["coupling"].value = "paper"
        app._sync_controls()
        assert not c["bessel_order"].disabled
    finally:
        c["coupling"].value, c["filled"].value = "acoustic", "empty"
        app._holding = False
    app._sync_controls()
    assert c["density_ratio"].disabled


def test_the_outside_control_puts_the_tube_in_water(app):
    """"outside": water around the tube gives the curves of ``dispersion_curve(..., outer=water)``."""
    from jaxdea.apps.explore import outside_fluids

    water = outside_fluids()["water"]
    app.controls["outside"].value = "water"
    try:
        tube, fluid, m = app.parameters()
        assert tube.outer == water and fluid is None
        curve = jd.dispersion_curve(tube, app.data.alpha, n_roots=3)
        np.testing.assert_allclose(app.data.omega, curve.omega, rtol=1e-12)
        vacuum = jd.dispersion_curve(tube.replace(outer=None), app.data.alpha, n_roots=3)
        ratio = np.asarray(curve.omega)[:, 0] / np.asarray(vacuum.omega)[:, 0]
        assert np.all(ratio <= 1.0) and np.min(ratio) < 0.7  # the water's added mass
    finally:
        app.controls["outside"].value = "vacuum"
    assert app.parameters()[0].outer is None


def test_compiling_status_shows_once_per_kind_of_problem(app):
    kind = ("paper", False, True)  # never solved here
    app._compiling("curve", kind)
    assert "compiling (once)" in app.busy.value
    app._compiled_now("curve", kind)
    assert app.busy.value == ""
    app._compiling("curve", kind)  # compiled: nothing to say
    assert app.busy.value == ""
    assert ("curve", ("empty", False, False)) in app._compiled  # what the app solved is known compiled


def test_empty_mode_panel_draws_no_axes_and_no_legend():
    fresh = jd.explore(TUBE, stability=False)
    assert fresh.mode is None
    assert not fresh.mode_axes.axison and fresh.mode_axes.get_legend() is None
    assert "click a curve" in fresh.mode_label.value
    fresh.select(float(fresh.data.alpha[fresh.data.axial_index[0]]), 0)
    assert fresh.mode_axes.axison and fresh.mode_axes.get_legend() is not None
    assert "branch 1" in fresh.mode_label.value
    assert fresh.pick["alpha"].value == pytest.approx(fresh.mode[0]) and fresh.pick["branch"].value == 0


def test_default_view_is_not_squeezed_by_a_far_branch(app):
    """Where the highest branch lies far above the others (a thickness branch), the Ω axis shows
    the lower branches with room, not the whole of the far one."""
    app.set(voltage=0.05, lambda_i=0.9)
    omega = app.data.omega
    lower, highest = np.nanmax(omega[:, :-1]), np.nanmax(omega)
    top = app.axes[0].get_ylim()[1]
    assert lower < top
    assert highest > 2.0 * lower  # the paper's tube: the third branch near Ω ≈ 18 at small α̂
    assert top < 0.5 * highest
    speeds = app.data.phase_velocity[app.data.alpha >= 0.2 * app.data.alpha[-1]]
    assert np.nanmax(speeds[:, :-1]) < app.axes[1].get_ylim()[1] < np.nanmax(speeds)


def test_explorer_keeps_the_matplotlib_backend():
    code = ("import matplotlib; matplotlib.use('agg'); import jax; jax.config.update('jax_enable_x64', True)\n"
            "import jaxdea\n"
            "from jaxdea.apps.explore import _interactive_canvas\n"
            "from matplotlib.figure import Figure\n"
            "canvas = _interactive_canvas(Figure())\n"
            "print(matplotlib.get_backend(), canvas is not None)\n")
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120,
                         env=dict(os.environ, JAXDEA_CACHE_DIR="off"))
    assert run.returncode == 0, run.stderr
    backend, interactive = run.stdout.split()
    assert backend == "agg"
    assert interactive == str(importlib.util.find_spec("ipympl") is not None)


@pytest.mark.slow
def test_unstable_alphas_are_where_the_lowest_root_is_imaginary():
    """At m = 2, V̂ = 0.08 the ring mode's lowest root is imaginary over a band of α̂: the flags are
    those of growth_rates, and the app shades that band."""
    tube = TUBE.replace(voltage=0.08)
    alphas = np.linspace(0.05, 3.0, 12)
    flags = unstable_alphas(tube, alphas, m=2)
    expected = [bool(float(jd.growth_rates(tube, a, m=2, n_roots=1)[0]) > 0) for a in alphas]
    np.testing.assert_array_equal(flags, expected)
    assert flags.any() and not flags.all()
    assert not unstable_alphas(tube.replace(voltage=0.0), alphas[:3], m=0).any()
    marked = jd.explore(tube, alphas=alphas, n_max=1, m_max=2)
    marked.set(m=2)
    marked.wait()
    np.testing.assert_array_equal(marked.unstable, unstable_alphas(tube, marked.data.alpha, m=2))
    assert len(marked.spans) == 2 * int(marked.unstable.sum())


def test_a_layered_wall_keeps_its_layers_and_disables_g():
    """The explorer of a layered tube (a stiff liner inside the paper's wall) shows the curves of
    ``dispersion_curve`` of that layered tube, after a slider move too, and its G slider, which a
    layered wall does not use, is disabled."""
    layers = (jd.Layer(0.2, jd.NeoHookean(), shear_ratio=3.0, density_ratio=1.2),
              jd.Layer(0.8, jd.Gent(97.2), active=True))
    layered = jd.explore(TUBE.replace(layers=layers), stability=False)
    assert layered.controls["gent"].disabled and not layered.controls["voltage"].disabled
    layered.controls["voltage"].value = 0.02
    tube, fluid, m = layered.parameters()
    assert tube.layers == layers and fluid is None and float(tube.voltage) == 0.02
    curve = jd.dispersion_curve(tube, layered.data.alpha, n_roots=3)
    np.testing.assert_allclose(layered.data.omega, curve.omega, rtol=1e-12)
    single = jd.dispersion_curve(tube.replace(layers=None), layered.data.alpha, n_roots=3)
    assert np.max(np.abs(np.asarray(curve.omega) / np.asarray(single.omega) - 1)) > 1e-2


def test_damping_control_shows_the_damped_roots_at_the_axial_modes(app):
    """The damped roots at the axial modes are complex_frequencies' (hysteretic ζ = 0.2: Q ≈ 5 from
    the elastic root by continuation in ζ), marked at their Re Ω with Q listed; "none" removes them
    and disables the size; the paper's coupling shows a message and keeps the elastic curves."""
    app.set(voltage=0.05, lambda_i=0.9, lambda_z=1.2, eta=0.85, gent=97.2, filled="empty", m=0,
            outside="vacuum", damping="hysteretic ζ", damping_size=0.2)
    tube, _, _ = app.parameters()
    assert not app.controls["damping_size"].disabled and app.error is None
    damped = app.damped
    assert damped.omega.shape == (5, 3) and np.all(damped.status == 0)
    direct = jd.complex_frequencies(tube.replace(damping=jd.Hysteretic(0.2)), float(app.data.axial_alpha[0]),
                                    n_roots=3)
    np.testing.assert_allclose(damped.omega[0], np.asarray(direct.omega), rtol=1e-8)
    np.testing.assert_allclose(damped.quality_factor[0], np.asarray(direct.quality_factor), rtol=1e-8)
    assert 4.0 < damped.quality_factor[0, 0] < 6.0
    x, y = app.damped_markers.get_data()
    np.testing.assert_allclose(np.asarray(y).reshape(5, 3), damped.omega.real, rtol=0)
    np.testing.assert_allclose(np.asarray(x).reshape(5, 3)[:, 0], app.data.axial_alpha, rtol=0)
    assert "Q = Re Ω/(2 Im Ω)" in app.damping_label.value and f"{damped.quality_factor[0, 0]:.3g}" in \
        app.damping_label.value
    app.set(damping="none")
    assert app.damped is None and app.controls["damping_size"].disabled
    assert len(app.damped_markers.get_xdata()) == 0 and app.damping_label.value == ""
    app.set(filled="filled", coupling="paper", damping="Kelvin–Voigt η_v")
    assert app.data is not None and app.damped is None and "acoustic coupling" in app.message.value
    app.set(filled="empty", coupling="acoustic", damping="none")


def test_damped_roots_of_light_damping_follow_the_loss():
    """Light hysteretic loss: Im Ω is first order in ζ (Q·ζ at ζ = 1e-3 and 2e-3 agree to 1e-3) and
    Q·ζ ≥ 1, near 1 for n = 1 (1.05) and growing with n (1.8 at n = 5, measured): the loss acts on
    the wall's elastic stiffness, not on the part the axial pre-stress adds."""
    tube = TUBE.replace(voltage=0.0)
    data = explorer_data(tube)
    assert damped_roots(tube, data, "none", 0.5) is None
    products = [damped_roots(tube, data, "hysteretic ζ", loss).quality_factor[:, 0] * loss
                for loss in (1e-3, 2e-3)]
    np.testing.assert_allclose(products[0], products[1], rtol=1e-3)
    assert np.all((products[0] > 1.0) & (products[0] < 2.0)) and products[0][0] < 1.1
    assert np.all(np.diff(products[0]) > 0)
