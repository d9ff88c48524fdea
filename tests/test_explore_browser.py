"""The explorer as a user meets it: served by voila, driven in headless Chromium. Moving the V̂ slider
redraws the plot; a click on the lowest curve at the tube's first axial mode shows that root's mode
shape (the plot changes and the mode line names it); the hysteretic damping button lists the quality
factors of the damped roots. Screenshots are saved (JAXDEA_SCREENSHOTS, else
the test's folder). Slow: a kernel starts, imports JAX and compiles the curve and mode-shape programs."""

import json
import os
import socket
import subprocess
import sys
import time
import urllib.request
from pathlib import Path

import numpy as np
import pytest

pytestmark = pytest.mark.slow

ROOT = Path(__file__).resolve().parents[1]
TUBE = dict(voltage=0.05, lambda_i=0.9, lambda_z=1.2, eta=0.85)
CELLS = ["import jax\njax.config.update('jax_enable_x64', True)\nimport jaxdea as jd",
         f"app = jd.explore(jd.Tube(**{TUBE!r}), stability=False)\napp"]


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture(scope="module")
def voila(tmp_path_factory):
    pytest.importorskip("voila")
    pytest.importorskip("ipympl")
    folder = tmp_path_factory.mktemp("voila")
    notebook = {"cells": [{"cell_type": "code", "metadata": {}, "source": c, "outputs": [],
                           "execution_count": None} for c in CELLS],
                "metadata": {"kernelspec": {"name": "python3", "display_name": "Python 3",
                                            "language": "python"}},
                "nbformat": 4, "nbformat_minor": 5}
    (folder / "explore.ipynb").write_text(json.dumps(notebook), encoding="utf-8")
    port = free_port()
    env = dict(os.environ, PYTHONPATH=str(ROOT), JUPYTER_PLATFORM_DIRS="1",
               JAXDEA_CACHE_DIR=str(ROOT / ".jax_cache"))
    server = subprocess.Popen([sys.executable, "-m", "voila", "explore.ipynb", "--no-browser", f"--port={port}",
                               "--Voila.ip=127.0.0.1", "--VoilaConfiguration.http_keep_alive_timeout=600"],
                              cwd=folder, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.STDOUT)
    url = f"http://127.0.0.1:{port}/"
    try:
        for _ in range(120):
            try:
                urllib.request.urlopen(url, timeout=2).close()  # noqa: S310 (loopback)
                break
            except OSError:
                time.sleep(0.5)
        yield url
    finally:
        server.terminate()
        server.wait(timeout=30)


def wait_for(condition, timeout=300.0, step=0.5):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        value = condition()
        if value:
            return value
        time.sleep(step)
    raise AssertionError("timed out")


def curve_point(voltage: float, canvas_size) -> tuple[float, float]:
    """Where the lowest branch at α̂_1 lies on the canvas (CSS pixels from its top-left corner): the
    same app built here, laid out as the kernel lays it out."""
    import jax

    jax.config.update("jax_enable_x64", True)
    import jaxdea as jd

    app = jd.explore(jd.Tube(**{**TUBE, "voltage": voltage}), stability=False)
    app.png()  # lay the figure out
    d = app.data
    row = d.axial_index[0]
    x, y = app.axes[0].transData.transform((d.alpha[row], d.omega[row, 0]))
    width, height = app.figure.bbox.width, app.figure.bbox.height
    return x / width * canvas_size["width"], (1.0 - y / height) * canvas_size["height"]


def test_slider_and_click_in_the_browser(voila, tmp_path):
    from screenshots import driver, is_blank
    from selenium.webdriver.common.action_chains import ActionChains
    from selenium.webdriver.common.by import By

    shots = Path(os.environ.get("JAXDEA_SCREENSHOTS", tmp_path))
    shots.mkdir(parents=True, exist_ok=True)
    browser = driver(1500, 1100)
    try:
        browser.get(voila)
        canvas = wait_for(lambda: browser.find_elements(By.CSS_SELECTOR, ".jupyter-matplotlib canvas"),
                          timeout=600)[0]
        wait_for(lambda: "order" in browser.page_source and canvas.size["width"] > 300, timeout=300)
        time.sleep(2.0)
        browser.save_screenshot(str(shots / "explorer_start.png"))
        before = canvas.screenshot_as_png
        assert not is_blank(shots / "explorer_start.png")

        slider = next(s for s in browser.find_elements(By.CSS_SELECTOR, ".widget-slider")
                      if s.find_element(By.CSS_SELECTOR, "label").text.strip() == "V̂")
        readout = slider.find_element(By.CSS_SELECTOR, ".widget-readout")
        start = float(readout.text)
        handle = slider.find_element(By.CSS_SELECTOR, ".noUi-handle")
        ActionChains(browser).click_and_hold(handle).move_by_offset(25, 0).release().perform()
        moved = wait_for(lambda: float(readout.text) != start and float(readout.text), timeout=30)
        wait_for(lambda: canvas.screenshot_as_png != before, timeout=300)  # redrawn for the new V̂
        time.sleep(2.0)
        after_slider = canvas.screenshot_as_png
        browser.save_screenshot(str(shots / "explorer_slider.png"))

        x, y = curve_point(float(moved), canvas.size)
        mode = browser.find_element(By.XPATH, "//*[contains(text(), 'mode shape:')]")
        assert "click a curve" in mode.text
        ActionChains(browser).move_to_element_with_offset(
            canvas, x - canvas.size["width"] / 2, y - canvas.size["height"] / 2).click().perform()
        wait_for(lambda: "branch 1" in browser.find_element(
            By.XPATH, "//*[contains(text(), 'mode shape:')]").text, timeout=300)
        text = browser.find_element(By.XPATH, "//*[contains(text(), 'mode shape:')]").text
        import jax

        jax.config.update("jax_enable_x64", True)
        import jaxdea as jd

        tube = jd.Tube(**{**TUBE, "voltage": float(moved)})
        alpha = float(text.split("α̂ = ")[1].split(",")[0])
        np.testing.assert_allclose(alpha, float(jd.axial_wavenumber(tube, 1)), rtol=1e-3)
        wait_for(lambda: canvas.screenshot_as_png != after_slider, timeout=60)  # the mode panel drawn
        time.sleep(1.0)
        browser.save_screenshot(str(shots / "explorer_mode.png"))

        after_mode = canvas.screenshot_as_png  # the damping control: the damped roots and their Q
        browser.find_element(By.XPATH, "//button[normalize-space()='hysteretic ζ']").click()
        listed = wait_for(lambda: [e.text for e in browser.find_elements(  # the innermost last
            By.XPATH, "//*[contains(., 'branch 1:') and contains(., 'Q = Re')]")][-1:], timeout=300)
        quality = [float(q) for q in listed[-1].split("branch 1:")[1].split("\n")[0].split(",")]
        assert len(quality) == 5 and all(10.0 < q < 60.0 for q in quality)  # ζ = 0.05: Q·ζ ≈ 1 to 2
        wait_for(lambda: canvas.screenshot_as_png != after_mode, timeout=60)  # the marks drawn
        time.sleep(1.0)
        browser.save_screenshot(str(shots / "explorer_damping.png"))
    finally:
        browser.quit()
