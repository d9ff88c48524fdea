"""The documentation: the strict mkdocs build, an API page that covers ``jaxdea.__all__``, and a README
that keeps its two set-up commands and stays short."""

import html
import os
import re
import subprocess
import sys
import time
from pathlib import Path

import jaxdea

ROOT = Path(__file__).resolve().parents[1]
FIGURES_COMMAND = "python3 -m venv .venv && .venv/bin/pip install -q . && .venv/bin/jaxdea figures"
TEST_COMMAND = (
    'python3 -m venv .venv && .venv/bin/pip install -q ".[test]" && .venv/bin/python -m pytest -q'
)
README_MAX_LINES = 250
BUILD_SECONDS_MAX = 60.0


def built_site(tmp_path):
    """Run ``mkdocs build --strict`` into a temporary folder; return the folder and the seconds it took."""
    site = tmp_path / "site"
    env = dict(os.environ, NO_MKDOCS_2_WARNING="1")
    start = time.perf_counter()
    run = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "--config-file", str(ROOT / "mkdocs.yml"),
         "--site-dir", str(site)],
        cwd=tmp_path, env=env, capture_output=True, text=True, timeout=300,
    )
    seconds = time.perf_counter() - start
    assert run.returncode == 0, run.stdout + run.stderr
    return site, seconds


def anchored_names(page):
    """The last component of every ``jaxdea.…`` heading anchor of a page."""
    return {anchor.rsplit(".", 1)[-1] for anchor in re.findall(r'id="(jaxdea(?:\.\w+)+)"', page)}


def test_strict_build_documents_every_public_name(tmp_path):
    site, seconds = built_site(tmp_path)
    assert seconds < BUILD_SECONDS_MAX
    api = (site / "reference" / "api" / "index.html").read_text(encoding="utf-8")
    missing = set(jaxdea.__all__) - anchored_names(api)
    assert not missing, f"public names without an API entry: {sorted(missing)}"
    for notebook in sorted((ROOT / "notebooks").glob("*.py")):
        page = site / "notebooks" / notebook.stem / "index.html"
        assert page.is_file(), f"notebook {notebook.name} has no page"
        title = next(line[4:] for line in notebook.read_text(encoding="utf-8").splitlines()
                     if line.startswith("# # "))
        assert title in html.unescape(page.read_text(encoding="utf-8"))


def test_readme_keeps_its_two_commands_and_stays_short():
    readme = (ROOT / "README.md").read_text(encoding="utf-8").splitlines()
    assert len(readme) <= README_MAX_LINES
    assert readme.count(FIGURES_COMMAND) == 1
    assert readme.count(TEST_COMMAND) == 1
    assert TEST_COMMAND in (ROOT / ".ci" / "run").read_text(encoding="utf-8")


def test_readme_links_point_to_files():
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    targets = re.findall(r"\]\(([^)#\s]+)(?:#[^)]*)?\)", readme)
    local = [target for target in targets if "://" not in target]
    assert local
    missing = [target for target in local if not (ROOT / target).exists()]
    assert not missing, missing
