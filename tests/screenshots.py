"""Headless Chromium for the tests that look at what a user sees: screenshots of pages and a WebDriver
session (Debian's ``chromium`` and ``chromium-driver``; the tests skip without them)."""

from __future__ import annotations

import shutil
import subprocess
import tempfile
from pathlib import Path

import pytest

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
CHROMEDRIVER = shutil.which("chromedriver")
FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
         "--disable-background-networking", "--disable-component-update", "--disable-sync",
         "--hide-scrollbars"]


def need_chromium():
    if CHROMIUM is None:
        pytest.skip("headless Chromium is not installed (apt-get install chromium chromium-driver)")


def driver(width: int = 1400, height: int = 1000):
    """A headless Chromium WebDriver session (selenium), its own profile folder."""
    need_chromium()
    webdriver = pytest.importorskip("selenium.webdriver")
    if CHROMEDRIVER is None:
        pytest.skip("chromedriver is not installed (apt-get install chromium-driver)")
    options = webdriver.ChromeOptions()
    options.binary_location = CHROMIUM
    for flag in FLAGS:
        options.add_argument(flag)
    options.add_argument(f"--user-data-dir={tempfile.mkdtemp(prefix='jaxdea-chromium-')}")
    options.add_argument(f"--window-size={width},{height}")
    service = webdriver.ChromeService(executable_path=CHROMEDRIVER)
    return webdriver.Chrome(options=options, service=service)


def screenshot(url: str, path: Path, width: int = 1280, height: int = 1600) -> Path:
    """A screenshot of ``url`` (the top ``height`` pixels) as PNG at ``path``."""
    need_chromium()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="jaxdea-chromium-") as profile:
        subprocess.run([CHROMIUM, *FLAGS, f"--user-data-dir={profile}", f"--window-size={width},{height}",
                        "--virtual-time-budget=5000", f"--screenshot={path}", url],
                       capture_output=True, timeout=120, check=False)
    assert path.is_file(), f"no screenshot of {url}"
    return path


def is_blank(path: Path) -> bool:
    """True for an image of one colour (a page that did not render)."""
    from PIL import Image

    with Image.open(path) as image:
        low, high = zip(*image.convert("RGB").getextrema(), strict=True)
    return max(high) - min(low) < 10
