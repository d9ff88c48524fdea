#!/usr/bin/env python3
"""Move jaxdea's modules into the concept layout (issue 42, item 5), as a re-runnable script.

Two steps, each idempotent (a second run changes nothing), each meant for a commit of its own:

    python3 tools/relayout.py renames   # content: private names made public, names imported from
                                        # their defining module, the fit <-> fit_io cycle broken
    python3 tools/relayout.py move      # git mv into the folders, package __init__ files, every
                                        # import and textual reference rewritten; nothing else
    python3 tools/relayout.py check     # exit 1 if either step still has work to do

Run from the repository root (or pass ``--root``), on a clean working tree. Stdlib only; ``--ruff``
names a ruff binary that re-sorts the rewritten import blocks (``ruff check --select I --fix``).

The layout follows the import graph of the modules (AST, lazy imports included), and
``tests/test_layout.py`` enforces it: the base layer (``jaxdea/*.py``: compiled, files, params,
units) <- numerics <- physics <- solve <- studies <- io <- apps; no cycles; no private name imported
across folders. A module of ``jaxdea/`` the table does not know stops the run (add it to MOVES or
BASE first).
"""

from __future__ import annotations

import argparse
import ast
import re
import subprocess
import sys
from pathlib import Path

PACKAGE = "jaxdea"

# ----------------------------------------------------------------------------------- the layout

BASE = ("__init__", "__main__", "compiled", "files", "params")
"""Modules that stay in jaxdea/ itself: the lowest layer (compiled: jit and the program cache;
files: atomic writes; params: Tube/Fluid and validation) plus the package's entry points (__init__
re-exports the public names; __main__ is ``python -m jaxdea``). ``jaxdea.units``, the public path of
the SI conversions, stays too after the move, as a facade of ``physics.units`` (an entry point:
the conversions hold a tube by its pressure through the base state, so they rank in physics)."""

FACADES = {"units": "jaxdea.physics.units"}
"""Public module paths kept after the move: jaxdea/<short>.py re-exports the moved module (written
by ``move``; an entry point of tests/test_layout.py). Text outside the package keeps the public
path."""

MOVES = {
    # numerics: knows nothing of tubes (imports the base layer at most)
    "scalar": "numerics.scalar",          # status enum, implicit derivatives, scalar lanes
    "bessel": "numerics.bessel",          # entire Bessel combinations
    # physics: the tube, its base state and its characteristic function
    "materials": "physics.materials",
    "moduli": "physics.moduli",
    "base_state": "physics.base_state",
    "state_matrix": "physics.state_matrix",
    "leaves": "physics.leaves",           # parameter names read from/applied to a tube (base_state)
    "units": "physics.units",             # SI <-> dimensionless (pressure-held λ_i: base_state)
    "transfer": "physics.transfer",       # builds the wall from the base state: physics until split
    "dispersion": "physics.dispersion",
    # solve: roots, curves and everything that finds or certifies them
    "roots": "solve.roots",
    "curves": "solve.curves",
    "trace": "solve.trace",
    "counting": "solve.counting",
    "accuracy": "solve.accuracy",
    "stability": "solve.stability",
    "modes": "solve.modes",
    # studies: many solves for one question
    "sweeps": "studies.sweeps",
    "design": "studies.design",
    "fit": "studies.fit",
    "peaks": "studies.peaks",             # the peak table fit reads (split from fit_io by `renames`)
    # io: the files and configurations that run studies and keep their results
    "config": "io.config",
    "fit_io": "io.fit_io",
    # apps: command line, figures, explorer
    "cli": "apps.cli",
    "figures": "apps.figures",
    "explore": "apps.explore",
    "plotstyle": "apps.plotstyle",
}

FOLDERS = {
    "numerics": "Numerical building blocks that know nothing of tubes: scalar root lanes with implicit\n"
                "derivatives, Bessel combinations. Imports the base layer only.",
    "physics": "The tube: materials, moduli, base state, state matrices, the wall's discretisation and\n"
               "propagation, the characteristic function. Imports numerics and the base layer.",
    "solve": "Roots of the characteristic function: frequencies, growth rates, critical voltages,\n"
             "curves, branch tracing, root counting, accuracy estimates, mode shapes, stability.\n"
             "Imports physics, numerics and the base layer.",
    "studies": "Many solves for one question: sweeps, design, inverse characterisation (fit) and the\n"
               "peak table it reads. Imports solve and below.",
    "io": "The files that drive studies and keep their results: the sweep configuration, the fit's\n"
          "files, summary and runner. Imports studies and below.",
    "apps": "Applications: the command line, the paper's figures and their style, the interactive\n"
            "explorer. Imports anything below.",
}

# ------------------------------------------------------------------------- step 1: the renames

RENAMES = {
    # (defining module, private name): public name. Every other module, test, benchmark and doc
    # follows; each new name was checked unused in the files that change (run() checks again).
    ("roots", "_guard_order"): "guard_order",
    ("roots", "_order_inputs"): "order_inputs",
    ("roots", "_with_derivatives"): "attach_derivatives",  # `with_derivatives` is a local in curves
    ("roots", "_validate_max"): "validate_max",
    ("roots", "_growth_family"): "growth_family",
    ("base_state", "_squared_voltage"): "squared_voltage",
    ("base_state", "_w1"): "w1_at",
    ("curves", "_solve_path"): "solve_path",
    ("curves", "_solve_critical_path"): "solve_critical_path",
}

REIMPORTS = {
    # (module imported from, name): (module that defines it, the name there). Applied to every
    # `from ... import` of the package, tests, benchmarks and notebooks.
    ("roots", "guard"): ("params", "guard"),
    ("modes", "ROOT_RTOL"): ("scalar", "ROOT_RTOL"),
    ("roots", "_problem"): ("dispersion", "problem_function"),  # roots._problem only forwards to it
}

SPLITS = {
    # new module: (old module, names moved, docstring). Breaks the fit <-> fit_io cycle: fit reads a
    # peak table from a path, fit_io writes results and runs `jaxdea fit`.
    "peaks": ("fit_io", ("COLUMNS", "LABELS", "LABEL_LOW", "LABEL_MAX", "NUMBER", "read_peaks", "_cell",
                         "write_peaks"),
              "The measured-peaks table of the inverse characterisation (:func:`jaxdea.fit`): a CSV file of\n"
              "``voltage_V``, ``frequency_Hz`` and optional ``sigma_Hz``, ``m``, ``n``, ``branch`` columns.\n"),
}

LITERAL_EDITS = {
    # file: [(old, new)]: content edits that make a file independent of the layout, before the move
    "docs/hooks.py": [
        ('lines += [f"## {SECTION_TITLES.get(module, module)}", ""]',
         'lines += [f"## {SECTION_TITLES.get(module.rsplit(\'.\', 1)[-1], module)}", ""]'),
    ],
    "jaxdea/fit.py": [
        ("from .peaks import read_peaks  # the CSV reader imports this module",
         "from .peaks import read_peaks"),
    ],
    "tests/test_figures.py": [
        ('for path in sorted((Path(figures.__file__).parent).glob("*.py")):',
         'for path in sorted(Path(jd.__file__).parent.rglob("*.py")):'),
    ],
}

# ------------------------------------------------------------------------------------- helpers

TEXT_GLOBS = ("jaxdea/**/*.py", "tests/**/*.py", "tests/**/*.md", "benchmarks/**/*.py", "benchmarks/**/*.md",
              "docs/**/*.md", "docs/**/*.py", "notebooks/**/*.py", "examples/**/*", "README.md",
              "mkdocs.yml", "pyproject.toml", ".ci/*")
"""Files whose references follow the move (CHANGELOG.md is history and is left alone)."""

IDENT = re.compile(r"[A-Za-z_]\w*")


class Fail(SystemExit):
    def __init__(self, message):
        super().__init__(f"relayout: {message}")


def git(root, *args, check=True):
    return subprocess.run(["git", *args], cwd=root, check=check, text=True, capture_output=True).stdout


def text_files(root: Path):
    seen = set()
    tracked = set(git(root, "ls-files").splitlines())
    for pattern in TEXT_GLOBS:
        for path in sorted(root.glob(pattern)):
            rel = path.relative_to(root).as_posix()
            if path.is_file() and rel not in seen and (rel in tracked or rel.startswith(f"{PACKAGE}/")):
                seen.add(rel)
                try:
                    path.read_text(encoding="utf-8")
                except UnicodeDecodeError:
                    continue
                yield path


def module_files(root: Path) -> dict[str, Path]:
    """{dotted module name: path} of every module of the package, as it is on disk now."""
    out = {}
    for path in sorted((root / PACKAGE).rglob("*.py")):
        parts = list(path.relative_to(root).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = path
    return out


def old_name(short):
    return f"{PACKAGE}.{short}"


def new_name(short):
    if short in BASE:
        return old_name(short)
    return f"{PACKAGE}.{MOVES[short]}"


def final_module(name: str, known: set[str]) -> str:
    """The name a module (or a package) has in the layout; loud on a jaxdea module the table lacks."""
    if name == PACKAGE or not name.startswith(PACKAGE + "."):
        return name
    short = name[len(PACKAGE) + 1:]
    if short in MOVES:
        return new_name(short)
    if short in BASE or short in FOLDERS or name in FINAL_NAMES:
        return name
    if name in known:
        raise Fail(f"unknown module {name}: add it to MOVES or BASE in tools/relayout.py")
    return None  # not a module (an attribute of the package)


FINAL_NAMES = {new_name(s) for s in MOVES} | {f"{PACKAGE}.{f}" for f in FOLDERS} | {old_name(b) for b in BASE}


def is_package(name):
    return name == PACKAGE or name[len(PACKAGE) + 1:] in FOLDERS


def relative(importer: str, target: str) -> str:
    """``from <this> import`` of ``target`` (a module or package) inside module ``importer``."""
    here = importer.split(".") if is_package(importer) else importer.split(".")[:-1]
    there = target.split(".")
    common = 0
    while common < min(len(here), len(there)) and here[common] == there[common]:
        common += 1
    return "." * (len(here) - common + 1) + ".".join(there[common:])


def resolve(importer: str, level: int, module: str | None) -> str:
    here = importer.split(".") if is_package(importer) else importer.split(".")[:-1]
    base = here[:len(here) - level + 1]
    return ".".join(base + ([module] if module else []))


def shadowed_names(root: Path) -> set[str]:
    """Module names the package also exports as something else (``jaxdea.fit`` is the function)."""
    tree = ast.parse((root / PACKAGE / "__init__.py").read_text(encoding="utf-8"))
    out = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module:
            out.update(a.asname or a.name for a in node.names)
    return out & (set(MOVES) | set(BASE))


def import_text(indent: str, module: str, names: list[str], width: int = 112) -> str:
    line = f"{indent}from {module} import {', '.join(names)}"
    if len(line) <= width:
        return line
    body = "".join(f"{indent}    {n},\n" for n in names)
    return f"{indent}from {module} import (\n{body}{indent})"


def alias_text(alias: ast.alias) -> str:
    return alias.name if alias.asname is None else f"{alias.name} as {alias.asname}"


def replace_spans(text: str, spans: list[tuple[int, int, str]]) -> str:
    for start, end, new in sorted(spans, reverse=True):
        text = text[:start] + new + text[end:]
    return text


def node_span(text: str, node) -> tuple[int, int]:
    lines = text.splitlines(keepends=True)
    starts = [0]
    for line in lines:
        starts.append(starts[-1] + len(line))

    def at(lineno, col):  # ast columns count UTF-8 bytes
        return starts[lineno - 1] + len(lines[lineno - 1].encode("utf-8")[:col].decode("utf-8"))

    return at(node.lineno, node.col_offset), at(node.end_lineno, node.end_col_offset)


def write(path: Path, text: str, changed: list):
    if path.read_text(encoding="utf-8") != text:
        path.write_text(text, encoding="utf-8")
        changed.append(path)


# ------------------------------------------------------------------------------- step 1: renames

def split_module(root: Path, new: str, changed: list):
    old, names, doc = SPLITS[new]
    source_path, target_path = root / PACKAGE / f"{old}.py", root / PACKAGE / f"{new}.py"
    moved_target = root / PACKAGE / (MOVES[new].replace(".", "/") + ".py")
    if target_path.exists() or moved_target.exists():
        return  # done before
    if not source_path.exists():
        raise Fail(f"{source_path} missing: cannot split {new} out of it")
    text = source_path.read_text(encoding="utf-8")
    tree = ast.parse(text)
    lines = text.splitlines(keepends=True)
    body = tree.body
    take, blocks = set(), []
    for k, node in enumerate(body):
        bound = (node.name if isinstance(node, (ast.FunctionDef, ast.ClassDef)) else
                 node.targets[0].id if isinstance(node, ast.Assign) and isinstance(node.targets[0], ast.Name)
                 else None)
        if bound not in names:
            continue
        first = min([node.lineno] + [d.lineno for d in getattr(node, "decorator_list", [])])
        last = node.end_lineno
        following = body[k + 1] if k + 1 < len(body) else None
        if (isinstance(following, ast.Expr) and isinstance(following.value, ast.Constant)
                and isinstance(following.value.value, str)):  # an attribute docstring
            last = following.end_lineno
            take.add(k + 1)
        take.add(k)
        blocks.append((bound, first, last, isinstance(node, (ast.FunctionDef, ast.ClassDef))))
    missing = set(names) - {b[0] for b in blocks}
    if missing:
        raise Fail(f"{old}.py does not define {sorted(missing)}: update SPLITS")
    used_moved = set()
    for k, node in enumerate(body):
        if k not in take:
            used_moved |= {n.id for n in ast.walk(node) if isinstance(n, ast.Name)} & set(names)
    moved_ids = {n.id for b in blocks for n in ast.walk(ast.parse("".join(lines[b[1] - 1:b[2]])))
                 if isinstance(n, ast.Name)} | {
        n.value.id for b in blocks for n in ast.walk(ast.parse("".join(lines[b[1] - 1:b[2]])))
        if isinstance(n, ast.Attribute) and isinstance(n.value, ast.Name)}
    # the new module: its docstring, the imports its code uses, the blocks in their order
    imports, future = [], False
    for node in body:
        if isinstance(node, ast.ImportFrom) and node.module == "__future__":
            future = True
        elif isinstance(node, ast.Import):
            kept = [a for a in node.names if (a.asname or a.name.split(".")[0]) in moved_ids]
            if kept:
                imports.append(f"import {', '.join(alias_text(a) for a in kept)}")
        elif isinstance(node, ast.ImportFrom):
            kept = [a for a in node.names if (a.asname or a.name) in moved_ids]
            if kept:
                imports.append(import_text("", "." * node.level + (node.module or ""),
                                           [alias_text(a) for a in kept]))
    parts = [f'"""{doc}"""\n\n']
    if future:
        parts.append("from __future__ import annotations\n\n")
    std = [i for i in imports if not i.startswith("from .")]
    local = [i for i in imports if i.startswith("from .")]
    parts.append("\n".join(std) + "\n\n" + "\n".join(local) + "\n")
    previous_def = True
    for _, first, last, is_def in blocks:
        chunk = "".join(lines[first - 1:last])
        parts.append("\n\n" + chunk if (is_def or previous_def) else chunk)
        previous_def = is_def
    new_text = "".join(parts).rstrip("\n") + "\n"
    # the old module: the blocks and the section comments right above them removed
    drop = set()
    for _, first, last, _ in blocks:
        start = first
        while start > 1 and (lines[start - 2].strip() == "" or lines[start - 2].lstrip().startswith("# ---")):
            start -= 1
        drop.update(range(start, last + 1))
    kept_lines = [line for n, line in enumerate(lines, 1) if n not in drop]
    rest = "".join(kept_lines)
    rest = re.sub(r"\n{4,}", "\n\n\n", rest)
    rest = re.sub(r"\n\n+(?=(?:def|class|@)\b|@)", "\n\n\n", rest)
    # unused imports of the old module removed, the moved names it still uses imported
    tree2 = ast.parse(rest)
    used = {n.id for n in ast.walk(tree2) if isinstance(n, ast.Name)} | {
        n.value.id for n in ast.walk(tree2) if isinstance(n, ast.Attribute) and isinstance(n.value, ast.Name)}
    spans = []
    for node in tree2.body:
        if isinstance(node, (ast.Import, ast.ImportFrom)) and getattr(node, "module", "") != "__future__":
            kept = [a for a in node.names if (a.asname or a.name.split(".")[0]) in used]
            if len(kept) == len(node.names):
                continue
            start, end = node_span(rest, node)
            if not kept:
                end += 1 if rest[end:end + 1] == "\n" else 0
                spans.append((start, end, ""))
            elif isinstance(node, ast.Import):
                spans.append((start, end, f"import {', '.join(alias_text(a) for a in kept)}"))
            else:
                spans.append((start, end, import_text("", "." * node.level + (node.module or ""),
                                                      [alias_text(a) for a in kept])))
    rest = replace_spans(rest, spans)
    if used_moved:
        last = [n for n in ast.parse(rest).body if isinstance(n, ast.ImportFrom) and n.level][-1]
        end = node_span(rest, last)[1] + 1
        rest = rest[:end] + import_text("", f".{new}", sorted(used_moved)) + "\n" + rest[end:]
    imports_end = node_span(rest, [n for n in ast.parse(rest).body
                                   if isinstance(n, (ast.Import, ast.ImportFrom))][-1])[1] + 1
    if rest[imports_end:imports_end + 1] != "\n":
        rest = rest[:imports_end] + "\n" + rest[imports_end:]
    target_path.write_text(new_text, encoding="utf-8")
    changed.append(target_path)
    write(source_path, rest, changed)
    for name in names:
        REIMPORTS.setdefault((old, name), (new, name))


def rename_identifiers(root: Path, changed: list):
    """Private names made public: word-boundary renames in the package, tests, benchmarks, docs."""
    pattern = {private: public for (_, private), public in RENAMES.items()}
    defining = {private: module for (module, private) in RENAMES}
    regex = re.compile(r"(?<![\w])(" + "|".join(map(re.escape, pattern)) + r")(?!\w)")
    modules = module_files(root)
    for (module, private), public in RENAMES.items():
        path = modules.get(old_name(module)) or modules.get(new_name(module))
        if path is None:
            raise Fail(f"RENAMES: module {module} not found")
        text = path.read_text(encoding="utf-8")
        if not re.search(rf"^(?:def {private}\b|{private} = )", text, re.M) and not re.search(
                rf"^(?:def {public}\b|{public} = )", text, re.M):
            raise Fail(f"RENAMES: {module} defines neither {private} nor {public}")
    for path in text_files(root):
        text = path.read_text(encoding="utf-8")
        hits = set(regex.findall(text))
        if not hits:
            continue
        for private in hits:
            public = pattern[private]
            if re.search(rf"(?<![\w.]){public}(?!\w)", text):
                raise Fail(f"{path}: renaming {private} -> {public} would clash with an existing "
                           f"`{public}` (of {defining[private]}?); choose another name in RENAMES")
        write(path, regex.sub(lambda m: pattern[m.group(1)], text), changed)


def reimport(root: Path, changed: list):
    """``from .roots import guard`` -> ``from .params import guard`` (and the same absolute)."""
    table = {}
    for (src, name), (dst, new) in REIMPORTS.items():
        table.setdefault(src, {})[name] = (dst, new)
    for path in text_files(root):
        if path.suffix != ".py":
            continue
        text = path.read_text(encoding="utf-8")
        tree = ast.parse(text)
        me = module_of(root, path)
        spans, renamed = [], {}
        for node in ast.walk(tree):
            if not isinstance(node, ast.ImportFrom) or not node.module:
                continue
            absolute = resolve(me, node.level, node.module) if node.level else node.module
            if not absolute.startswith(PACKAGE + "."):
                continue
            src = next((s for s in table if absolute in (old_name(s), new_name(s))), None)
            if src is None or not any(a.name in table[src] for a in node.names):
                continue
            indent = " " * node.col_offset
            stay = [alias_text(a) for a in node.names if a.name not in table[src]]
            moved = {}
            for a in node.names:
                if a.name in table[src]:
                    dst, new = table[src][a.name]
                    local = a.asname or a.name
                    if a.asname is None and new != a.name:
                        renamed[a.name] = new
                        local = new
                    moved.setdefault(dst, []).append(new if local == new else f"{new} as {local}")
            out = []
            if stay:
                out.append(import_text(indent, text[slice(*node_span(text, node))].split()[1], stay))
            for dst, names in moved.items():
                target = old_name(dst) if (root / PACKAGE / f"{dst}.py").exists() else new_name(dst)
                out.append(import_text(indent, relative(me, target) if node.level else target, names))
            spans.append((*node_span(text, node), ("\n").join(out).lstrip()))
        if spans:
            text = replace_spans(text, spans)
            for old, new in renamed.items():
                text = re.sub(rf"(?<![\w.]){re.escape(old)}(?!\w)", new, text)
            write(path, text, changed)


def module_of(root: Path, path: Path) -> str:
    rel = path.relative_to(root)
    if rel.parts[0] != PACKAGE:
        return "__outside__"
    parts = list(rel.with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def literal_edits(root: Path, changed: list):
    for rel, edits in LITERAL_EDITS.items():
        path = root / rel
        if not path.exists():
            raise Fail(f"LITERAL_EDITS: {rel} missing")
        text = path.read_text(encoding="utf-8")
        for old, new in edits:
            if old in text:
                text = text.replace(old, new)
            elif new not in text:
                raise Fail(f"LITERAL_EDITS: {rel} has neither the old nor the new text of {old!r}")
        write(path, text, changed)


def sort_imports(root: Path, changed: list, ruff: str | None):
    if ruff and changed:
        py = sorted({p.relative_to(root).as_posix() for p in changed if p.suffix == ".py" and p.exists()})
        subprocess.run([ruff, "check", "--select", "I", "--fix", "--quiet", *py], cwd=root, check=False)


def renames(root: Path, changed: list, ruff: str | None):
    for new in SPLITS:
        split_module(root, new, changed)
    for new, (old, names, _) in SPLITS.items():
        for name in names:
            REIMPORTS.setdefault((old, name), (new, name))
    rename_identifiers(root, changed)
    reimport(root, changed)
    literal_edits(root, changed)
    sort_imports(root, changed, ruff)


# ---------------------------------------------------------------------------------- step 2: move

def check_modules(root: Path):
    """Every module is in the table: loud on one it does not know."""
    for name, path in module_files(root).items():
        short = name[len(PACKAGE) + 1:] if name != PACKAGE else "__init__"
        if path.name == "__init__.py" and short in FOLDERS:
            continue
        if "." not in short and (short in BASE or short in MOVES):
            continue
        if name in FINAL_NAMES:
            continue
        raise Fail(f"unknown module {name} ({path.relative_to(root)}): add it to MOVES or BASE in "
                   "tools/relayout.py")
    for short in MOVES:
        old = root / PACKAGE / f"{short}.py"
        new = root / PACKAGE / (MOVES[short].replace(".", "/") + ".py")
        if old.exists() and new.exists() and short not in FACADES:
            raise Fail(f"both {old.relative_to(root)} and {new.relative_to(root)} exist")
        if not old.exists() and not new.exists():
            raise Fail(f"MOVES names {short}, but neither {old.relative_to(root)} nor "
                       f"{new.relative_to(root)} exists (run `renames` first, or drop it from MOVES)")


def rewrite_package_imports(root: Path, path: Path, changed: list):
    """Relative imports of one module, resolved where it is now, written for where it goes."""
    known = set(module_files(root))
    text = path.read_text(encoding="utf-8")
    me = module_of(root, path)
    short = me[len(PACKAGE) + 1:] if me != PACKAGE else "__init__"
    destination = final_module(me, known) if me != PACKAGE else PACKAGE
    if path.name == "__init__.py" and me != PACKAGE:
        destination = me
    spans = []
    for node in ast.walk(ast.parse(text)):
        if not isinstance(node, ast.ImportFrom) or node.level == 0:
            continue
        start, end = node_span(text, node)
        original = text[start:end]
        absolute = resolve(me, node.level, node.module)
        if node.module is not None:
            target = final_module(absolute, known)
            if target is None:
                raise Fail(f"{path}: cannot resolve `{original.splitlines()[0]}`")
            head = re.match(r"from\s+[.\w]+\s+import", original)
            spans.append((start, start + head.end(), f"from {relative(destination, target)} import"))
            continue
        groups: dict[str, list[str]] = {}
        for alias in node.names:
            full = f"{absolute}.{alias.name}"
            target = final_module(full, known | {full} if full in known else known)
            if target is None:  # an attribute of the package (`from . import Tube`)
                package = final_module(absolute, known)
                groups.setdefault(package, []).append(alias_text(alias))
            else:
                package, _, leaf = target.rpartition(".")
                groups.setdefault(package, []).append(
                    leaf if alias.asname is None and leaf == alias.name else
                    f"{leaf} as {alias.asname or alias.name}")
        indent = " " * node.col_offset
        lines = [import_text(indent, relative(destination, package), names)
                 for package, names in groups.items()]
        spans.append((start, end, "\n".join(lines).lstrip()))
    new_text = replace_spans(text, spans)
    del short
    write(path, new_text, changed)


def rewrite_text(root: Path, path: Path, changed: list, shadowed: set[str], notes: list):
    """Absolute and textual references: jaxdea.roots -> jaxdea.solve.roots, jaxdea/roots.py -> ..."""
    text = path.read_text(encoding="utf-8")
    inside = (root / PACKAGE) in path.parents
    olds = sorted((m for m in MOVES if inside or m not in FACADES), key=len, reverse=True)
    names = "|".join(map(re.escape, olds))

    def dotted(match):
        short, after = match.group(1), match.group(2)
        prefix = text[max(0, match.start() - 12):match.start()]
        is_module = (short not in shadowed or after.startswith(".") or after.startswith(":")
                     or re.search(r"(?:import\s+|from\s+|:mod:`~?)$", prefix))
        if not is_module:
            notes.append(f"{path.relative_to(root)}: `jaxdea.{short}` left as is (the public "
                         f"function jaxdea.{short})")
            return match.group(0)
        return f"{new_name(short)}{after}"

    new_text = re.sub(rf"(?<![\w.]){PACKAGE}\.({names})(?!\w)(\.?)", dotted, text)
    new_text = re.sub(rf"(?<![\w/]){PACKAGE}/({names})\.py\b",
                      lambda m: new_name(m.group(1)).replace(".", "/") + ".py", new_text)

    def from_package(match):  # from jaxdea import roots as R, compiled
        indent, names_text, tail = match.group(1), match.group(2), match.group(3)
        aliases = [a.strip() for a in names_text.split(",") if a.strip()]
        groups: dict[str, list[str]] = {}
        for alias in aliases:
            leaf = alias.split()[0]
            if leaf in olds and leaf not in shadowed:
                package = new_name(leaf).rpartition(".")[0]
            else:
                package = PACKAGE
            groups.setdefault(package, []).append(alias)
        if list(groups) == [PACKAGE]:
            return match.group(0)
        return "\n".join(f"{indent}from {package} import {', '.join(a)}{(tail or '') if k == 0 else ''}"
                         for k, (package, a) in enumerate(groups.items()))

    new_text = re.sub(rf"^([ \t]*)from {PACKAGE} import ([\w ,]+?)([ \t]*#.*)?$", from_package, new_text,
                      flags=re.M)
    if re.search(rf"^[ \t]*from {PACKAGE} import \([^)]*\b(?:{names})\b", new_text, re.M):
        raise Fail(f"{path}: a parenthesised `from {PACKAGE} import (...)` names a moved module; "
                   "write it on one line")
    for match in re.finditer(rf"\bjd\.({names})\.\w", new_text):
        if match.group(1) not in shadowed:
            raise Fail(f"{path}: `{match.group(0)}` reaches a moved module through the package: "
                       f"import it from {new_name(match.group(1))}")
    write(path, new_text, changed)


def pyproject_packages(root: Path, changed: list):
    """Nothing to do for hatch: ``packages = ["jaxdea"]`` ships the subpackages (checked: the wheel
    holds jaxdea/numerics … jaxdea/apps). Listing them as dotted names would name paths that do not
    exist."""
    del root, changed


def move(root: Path, changed: list, ruff: str | None):
    check_modules(root)
    for short, _ in SPLITS.items():
        if not (root / PACKAGE / f"{short}.py").exists() and not (
                root / PACKAGE / (MOVES[short].replace(".", "/") + ".py")).exists():
            raise Fail(f"{PACKAGE}/{short}.py missing: run `renames` (and commit it) first")
    shadowed = shadowed_names(root)
    notes: list[str] = []
    for path in sorted((root / PACKAGE).rglob("*.py")):
        rewrite_package_imports(root, path, changed)
    for path in text_files(root):
        rewrite_text(root, path, changed, shadowed, notes)
    pyproject_packages(root, changed)
    for folder, doc in FOLDERS.items():
        init = root / PACKAGE / folder / "__init__.py"
        if not init.exists():
            init.parent.mkdir(exist_ok=True)
            init.write_text(f'"""{doc}"""\n', encoding="utf-8")
            git(root, "add", init.relative_to(root).as_posix())
            changed.append(init)
    for short, dotted in MOVES.items():
        old = root / PACKAGE / f"{short}.py"
        new = root / PACKAGE / (dotted.replace(".", "/") + ".py")
        if old.exists() and not new.exists():
            git(root, "mv", old.relative_to(root).as_posix(), new.relative_to(root).as_posix())
            changed.append(new)
    for short, target in FACADES.items():
        old = root / PACKAGE / f"{short}.py"
        if not old.exists():
            old.write_text(facade_text(short, target), encoding="utf-8")
            git(root, "add", old.relative_to(root).as_posix())
            changed.append(old)
    sort_imports(root, changed, ruff)
    for note in sorted(set(notes)):
        print("note:", note)


def facade_text(short: str, target: str) -> str:
    """jaxdea/<short>.py of a public path kept after the move (:data:`FACADES`)."""
    return (f'"""The public path of :mod:`{target}` (its names, re-exported)."""\n\n'
            f"from {target} import *  # noqa: F403\n")


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("step", choices=("renames", "move", "check"))
    parser.add_argument("--root", type=Path, default=Path.cwd())
    parser.add_argument("--ruff", help="a ruff binary: re-sort the import blocks the run rewrote")
    args = parser.parse_args(argv)
    root = args.root.resolve()
    if not (root / PACKAGE / "__init__.py").exists():
        raise Fail(f"{root} is not the repository root (no {PACKAGE}/__init__.py)")
    changed: list[Path] = []
    if args.step == "renames":
        renames(root, changed, args.ruff)
    elif args.step == "move":
        move(root, changed, args.ruff)
    else:
        pending = [s for s in MOVES if (root / PACKAGE / f"{s}.py").exists()
                   and not (s in FACADES and (root / PACKAGE / (MOVES[s].replace(".", "/") + ".py")).exists())]
        if pending:
            print("not moved yet:", ", ".join(pending))
            return 1
        print("layout applied")
        return 0
    for path in sorted({p.relative_to(root).as_posix() for p in changed}):
        print("changed:", path)
    print(f"{args.step}: {len(set(changed))} files changed")
    return 0


if __name__ == "__main__":
    sys.exit(main())
