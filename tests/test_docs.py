"""The documentation: the strict mkdocs build, an API page that covers ``jaxdea.__all__``, and a README
that keeps its two set-up commands and stays short."""

import html
import os
import re
import subprocess
import sys
import time
from pathlib import Path

import pytest

import jaxdea

ROOT = Path(__file__).resolve().parents[1]
FIGURES_COMMAND = "python3 -m venv .venv && .venv/bin/pip install -q . && .venv/bin/jaxdea figures"
TEST_COMMAND = (
    'python3 -m venv .venv && .venv/bin/pip install -q ".[test]" && .venv/bin/python -m pytest -q'
)
README_MAX_LINES = 250
BUILD_SECONDS_MAX = 60.0


def built_site(tmp_path, execute=False):
    """Run ``mkdocs build --strict`` into a temporary folder; return the folder and the seconds it took.
    ``execute``: run the notebooks (on their quick grids), as the published build does."""
    site = tmp_path / "site"
    env = dict(os.environ, NO_MKDOCS_2_WARNING="1", JAXDEA_DOCS_EXECUTE="1" if execute else "0",
               JAXDEA_NOTEBOOK_FAST="1", JAXDEA_CACHE_DIR=str(ROOT / ".jax_cache"))
    start = time.perf_counter()
    run = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "--config-file", str(ROOT / "mkdocs.yml"),
         "--site-dir", str(site)],
        cwd=tmp_path, env=env, capture_output=True, text=True, timeout=3600 if execute else 300,
    )
    seconds = time.perf_counter() - start
    assert run.returncode == 0, run.stdout + run.stderr
    return site, seconds


def anchored_names(page):
    """The last component of every ``jaxdea.…`` heading anchor of a page."""
    return {anchor.rsplit(".", 1)[-1] for anchor in re.findall(r'id="(jaxdea(?:\.\w+)+)"', page)}


@pytest.fixture(scope="module")
def site(tmp_path_factory):
    return built_site(tmp_path_factory.mktemp("docs"))


def test_strict_build_documents_every_public_name(site):
    site, seconds = site
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


def pages(site):
    return {p.relative_to(site).as_posix(): p.read_text(encoding="utf-8") for p in site.rglob("index.html")}


def test_examples_render_as_code_not_block_quotes(site):
    site, _ = site
    api = (site / "reference" / "api" / "index.html").read_text(encoding="utf-8")
    quoted = re.findall(r"<blockquote>.*?</blockquote>", api, re.S)
    assert not [q for q in quoted if "&gt;&gt;&gt;" in q or ">>>" in q]
    examples = re.findall(r"<pre[^>]*>.*?</pre>", api, re.S)
    assert sum("&gt;&gt;&gt;" in e for e in examples) >= 20  # every public Examples: section is code


def test_docstring_sections_parse(site):
    """No reST role left as text (an unresolved reference or a Returns line parsed as a type), and
    every attribute of TubeSI in its own row."""
    site, _ = site
    page = (site / "reference" / "api" / "index.html").read_text(encoding="utf-8")

    def text(start):  # the text of the page from an anchor on
        return html.unescape(re.sub(r"\s+", " ", re.sub(r"<[^>]+>", " ", page[page.index(start):])))

    api = text('<article')
    assert not re.search(r"(?<![\w.])(class|func|meth|attr|mod|data|exc): ?[`~\w]", api)
    assert ":class:" not in api and ":func:" not in api
    tube_si = text('id="jaxdea.units.TubeSI"')[:1500]
    for name in ("outer_radius", "lambda_i", "lambda_z", "gent"):
        assert re.search(rf"\b{name} Array\b", tube_si), name
    returns = text('id="jaxdea.units.tube_from_si"')
    returns = returns[returns.index("Returns:"):returns.index("Raises:")]
    assert "The" not in returns.split() and "Tube" in returns


def test_lists_are_not_collapsed_into_paragraphs(site):
    site, _ = site
    for name, page in pages(site).items():
        for paragraph in re.findall(r"<p>(.*?)</p>", page, re.S):
            assert not re.search(r"\n\s*(?:[-*]|\d+\.) \S", paragraph), (name, paragraph[:120])


def test_math_is_typeset_and_theory_citations_link_to_their_sections(site):
    site, _ = site
    physics = (site / "physics" / "index.html").read_text(encoding="utf-8")
    assert physics.count("<math") >= 10 and 'display="block"' in physics
    text = re.sub(r"<math.*?</math>", "", physics, flags=re.S)
    assert "$" not in re.sub(r"<[^>]+>", "", text) and "\\(" not in text
    api = (site / "reference" / "api" / "index.html").read_text(encoding="utf-8")
    links = re.findall(r'<a href="([^"]*theory/(\w+)/#([\w-]+))">docs/theory/\w+\.md', api)
    assert len(links) >= 5
    for _, name, anchor in links:
        assert f'id="{anchor}"' in (site / "theory" / name / "index.html").read_text(encoding="utf-8")
    assert not re.search(r"docs/theory/\w+\.md §\d", re.sub(r"<a [^>]*>.*?</a>", "", api, flags=re.S))


CITATION = re.compile(r"(?:docs/theory/(\w+)|\b(theory(?:_m|_next)?))\.md(?:,? (?:§|section )(\d+))?")
EARLIER = {"theory": "axisymmetric", "theory_m": "order_m", "theory_next": "real_tubes"}


def test_every_cited_theory_section_is_in_the_repository():
    """Every citation of the theory (``docs/theory/NAME.md §N``, or an earlier name that
    docs/theory/index.md maps) names a page of docs/theory and a section that page has."""
    sections = {p.stem: set(re.findall(r"(?m)^## (\d+)\. ", p.read_text(encoding="utf-8")))
                for p in (ROOT / "docs" / "theory").glob("*.md")}
    assert {"axisymmetric", "order_m", "real_tubes"} <= set(sections)
    files = [*ROOT.glob("jaxdea/**/*.py"), *ROOT.glob("docs/**/*.md"), *ROOT.glob("notebooks/*.py"),
             *ROOT.glob("benchmarks/*.py"), ROOT / "README.md"]
    cited = 0
    for path in files:
        for name, earlier, section in CITATION.findall(path.read_text(encoding="utf-8")):
            page = name or EARLIER[earlier]
            assert page in sections, f"{path.name} cites docs/theory/{page}.md, which does not exist"
            if section:
                assert section in sections[page], f"{path.name} cites {page}.md §{section}, not a section"
            cited += 1
    assert cited > 100


@pytest.mark.slow
def test_published_build_executes_the_notebooks_and_pages_render(tmp_path):
    """The build as published: every notebook executed on its quick grids (no "In [ ]" cells, the
    plotting ones with their images); screenshots of the main pages in headless Chromium are not
    blank (saved under JAXDEA_SCREENSHOTS if set)."""
    site, _ = built_site(tmp_path, execute=True)
    for notebook in sorted((ROOT / "notebooks").glob("*.py")):
        page = (site / "notebooks" / notebook.stem / "index.html").read_text(encoding="utf-8")
        assert "In&nbsp;[&nbsp;]" not in page and "In [ ]" not in page, notebook.stem
        if notebook.stem != "explore":
            assert "data:image/png" in page, f"{notebook.stem}: no plot on its page"
    from screenshots import is_blank, screenshot

    out = Path(os.environ.get("JAXDEA_SCREENSHOTS", tmp_path / "shots"))
    for page in ("physics", "theory/order_m", "reference/api", "howto/sweeps", "notebooks/quickstart",
                 "figures"):
        png = screenshot(f"file://{site}/{page}/index.html", out / f"docs_{page.replace('/', '_')}.png")
        assert not is_blank(png), page
