"""Build hooks: the API reference lists every name of ``jaxdea.__all__``, grouped by the module that
defines it (read from ``jaxdea/__init__.py`` without importing the package), and the docstrings'
reST cross-references become links."""

from __future__ import annotations

import ast
import html
import os
import re
from pathlib import Path

MARKER = "<!-- public API of jaxdea -->"
ROLE = re.compile(r":(?:func|class|meth|attr|data|mod|exc):<code>~?([\w.]+)</code>")
ANCHOR = re.compile(r'id="(jaxdea\.[\w.]+)"')
SECTION_TITLES = {
    "params": "Parameters",
    "materials": "Materials and damping laws",
    "dispersion": "Characteristic function",
    "roots": "Frequencies, critical voltages and growth rates",
    "stability": "Stability of a state",
    "curves": "Dispersion curves",
    "trace": "Branch tracing",
    "sweeps": "Sweeps",
    "accuracy": "Accuracy control",
    "counting": "Root counting",
    "wavenumbers": "Complex wavenumbers",
    "complex_frequencies": "Complex frequencies (damping)",
    "modes": "Mode shapes",
    "energy": "Energy velocity",
    "base_state": "Static state",
    "design": "Design",
    "explore": "Interactive explorer",
    "fit": "Inverse characterisation",
    "fit_io": "Inverse characterisation: files, plots, command line",
    "scalar": "Status codes",
    "units": "Units",
}


def public_names_by_module(init_file: Path) -> dict[str, list[str]]:
    """Map each module of the package to the names of ``__all__`` it defines, in import order; a
    public submodule maps to itself."""
    tree = ast.parse(init_file.read_text(encoding="utf-8"))
    exported: list[str] = []
    for node in tree.body:
        if isinstance(node, ast.Assign) and any(
            isinstance(target, ast.Name) and target.id == "__all__" for target in node.targets
        ):
            exported = list(ast.literal_eval(node.value))
    source: dict[str, str] = {}
    for node in tree.body:
        if isinstance(node, ast.ImportFrom) and node.level == 1:
            for alias in node.names:
                name = alias.asname or alias.name
                source[name] = alias.name if node.module is None else node.module
    groups: dict[str, list[str]] = {}
    for name in sorted(exported, key=lambda n: list(source).index(n) if n in source else len(source)):
        groups.setdefault(source.get(name, name), []).append(name)
    return groups


def api_markdown(init_file: Path) -> str:
    """One section per defining module, one mkdocstrings block per public name."""
    lines = []
    for module, names in public_names_by_module(init_file).items():
        lines += [f"## {SECTION_TITLES.get(module.rsplit('.', 1)[-1], module)}", ""]
        for name in names:
            path = f"jaxdea.{module}" if name == module else f"jaxdea.{module}.{name}"
            lines += [f"::: {path}", "    options:", "      heading_level: 3", ""]
    return "\n".join(lines)


def on_config(config):
    """The notebooks run at build time on their quick grids (``JAXDEA_NOTEBOOK_FAST=1``, unless the
    environment says otherwise), sharing one compile cache; ``JAXDEA_DOCS_EXECUTE=0`` shows them
    unexecuted (a fast build: the docs test of the default tier)."""
    os.environ.setdefault("JAXDEA_NOTEBOOK_FAST", "1")
    if os.environ.get("JAXDEA_DOCS_EXECUTE") == "0":
        config["plugins"]["mkdocs-jupyter"].config["execute"] = False
    return config


def on_page_markdown(markdown, page, config, files):
    if MARKER not in markdown:
        return markdown
    init_file = Path(config["config_file_path"]).parent / "jaxdea" / "__init__.py"
    return markdown.replace(MARKER, api_markdown(init_file))


def resolve_roles(page_html: str) -> str:
    """Docstring cross-references written as reST roles (``:func:`name```) become code, linked to
    the entry of the same name on the page where there is one."""
    anchors: dict[str, str] = {}
    for anchor in sorted(ANCHOR.findall(page_html), key=len, reverse=True):
        anchors[anchor.rsplit(".", 1)[-1]] = anchor  # the shortest path of a name wins

    def link(match):
        name = match.group(1)
        short = name.rsplit(".", 1)[-1]
        code = f"<code>{short if name.startswith('jaxdea.') else name}</code>"
        return f'<a href="#{anchors[short]}">{code}</a>' if short in anchors else code

    return ROLE.sub(link, page_html)


def on_page_content(html, page, config, files):
    html = resolve_roles(html) if ":<code>" in html else html
    html = typeset_math(html) if 'class="arithmatex"' in html else html
    return link_theory(html, page, Path(config["docs_dir"])) if "docs/theory/" in html else html


# ----------------------------------------------------------------------------- math and theory

MATH = re.compile(r'<(span|div) class="arithmatex">(.*?)</\1>', re.S)
THEORY_CITATION = re.compile(r"docs/theory/(\w+)\.md(?:(?:,? (?:§|section )|#)(\d+))?")


def typeset_math(page_html: str) -> str:
    """Each formula that ``pymdownx.arithmatex`` marked (``\\(…\\)`` inline, ``\\[…\\]`` display) becomes
    MathML (latex2mathml), which browsers typeset natively: no script, no network."""
    from latex2mathml.converter import convert

    def mathml(match):
        tag, body = match.groups()
        latex = html.unescape(body.strip())
        display = tag == "div"
        latex = latex[2:-2] if latex[:2] in ("\\(", "\\[") else latex
        return convert(latex, display="block" if display else "inline")

    return MATH.sub(mathml, page_html)


def section_anchors(theory_file: Path) -> dict[str, str]:
    """{section number: heading anchor} of a theory page (``## N. Title``), as the toc extension
    writes the anchors."""
    from markdown.extensions.toc import slugify

    anchors = {}
    for line in theory_file.read_text(encoding="utf-8").splitlines():
        match = re.match(r"^## (\d+)\. (.*)$", line)
        if match:
            anchors[match.group(1)] = slugify(f"{match.group(1)}. {match.group(2)}", "-")
    return anchors


def link_theory(page_html: str, page, docs_dir: Path) -> str:
    """Citations ``docs/theory/NAME.md §N`` (docstrings, pages) become links to that section of the
    theory page; outside tags only (text, code spans)."""
    from mkdocs.utils import get_relative_url

    anchors = {f.stem: section_anchors(f) for f in (docs_dir / "theory").glob("*.md")}

    def link(match):
        name, section = match.groups()
        if name not in anchors:
            return match.group(0)
        target = get_relative_url(f"theory/{name}/", page.url)
        anchor = anchors[name].get(section or "", "")
        return f'<a href="{target}{"#" + anchor if anchor else ""}">{match.group(0)}</a>'

    parts = re.split(r"(<[^>]*>)", page_html)
    inside_link = False
    for k, part in enumerate(parts):
        if part.startswith("<a ") or part == "<a>":
            inside_link = True
        elif part == "</a>":
            inside_link = False
        elif not part.startswith("<") and not inside_link and "docs/theory/" in part:
            parts[k] = THEORY_CITATION.sub(link, part)
    return "".join(parts)
