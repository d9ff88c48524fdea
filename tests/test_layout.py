"""The package layout (docs/reference/layout.md): folders ranked so that imports point down, no
import cycle, no private name imported across folders, every name imported from the module that
defines it. AST only: nothing of jaxdea or JAX is imported."""

from __future__ import annotations

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "jaxdea"

RANK = {"": 0, "numerics": 1, "physics": 2, "solve": 3, "studies": 4, "io": 5, "apps": 6}
"""A module may import its own folder and lower ranks. "" is the base layer, jaxdea/*.py."""
BASE = {"__init__", "__main__", "compiled", "files", "materials", "params", "units"}
"""The modules of the base layer; the entry points __init__ (re-exports) and __main__ (``python -m
jaxdea``) may import anything."""
ENTRY_POINTS = {"jaxdea", "jaxdea.__main__", "jaxdea.units"}
"""jaxdea.units: the public path of the SI conversions, a facade of jaxdea.physics.units."""


def modules() -> dict[str, ast.Module]:
    out = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        parts = ["jaxdea", *path.relative_to(PACKAGE).with_suffix("").parts]
        out[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = ast.parse(
            path.read_text(encoding="utf-8"))
    return out


MODULES = modules()


def is_package(name: str) -> bool:
    return (PACKAGE.joinpath(*name.split(".")[1:]) / "__init__.py").exists()


def folder(name: str) -> str:
    """The folder of a module: "" for jaxdea/x.py, "solve" for jaxdea/solve/x.py."""
    parts = name.split(".")[1:]
    return parts[0] if len(parts) > 1 or (parts and is_package(name)) else ""


def imports(name: str, tree: ast.Module):
    """(imported module, name or None, line) for every import of a jaxdea module, lazy ones too."""
    here = name.split(".") if is_package(name) else name.split(".")[:-1]
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = ".".join(here[:len(here) - node.level + 1] + ([node.module] if node.module else []))
            elif (node.module or "").split(".")[0] == "jaxdea":
                base = node.module
            else:
                continue
            for alias in node.names:
                if f"{base}.{alias.name}" in MODULES:
                    yield f"{base}.{alias.name}", None, node.lineno
                else:
                    yield base, alias.name, node.lineno
        elif isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.split(".")[0] == "jaxdea":
                    yield alias.name, None, node.lineno


def edges() -> dict[str, set[str]]:
    return {name: {target for target, _, _ in imports(name, tree) if target != name and target in MODULES}
            for name, tree in MODULES.items()}


def defined(tree: ast.Module) -> set[str]:
    names = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)) and node in tree.body:
            names.add(node.name)
        elif isinstance(node, ast.Name) and isinstance(node.ctx, ast.Store):
            names.add(node.id)
    return names


def test_every_module_lives_in_a_ranked_folder_or_the_base_layer():
    misplaced = sorted(name for name in MODULES
                       if folder(name) not in RANK or (folder(name) == "" and name != "jaxdea"
                                                       and name.split(".")[-1] not in BASE))
    assert not misplaced, f"modules outside the declared layout (tools/relayout.py): {misplaced}"


def test_no_import_cycle():
    graph = edges()
    state: dict[str, int] = {}
    cycles = []

    def visit(node, stack):
        state[node] = 1
        for nxt in sorted(graph[node]):
            if nxt in ENTRY_POINTS or is_package(nxt):
                continue  # importing the package itself runs __init__: not an edge of the layout
            if state.get(nxt) == 1:
                cycles.append(stack[stack.index(nxt):] + [nxt])
            elif nxt not in state:
                visit(nxt, stack + [nxt])
        state[node] = 2

    for name in sorted(graph):
        if name not in state and name not in ENTRY_POINTS:
            visit(name, [name])
    assert not cycles, "import cycles: " + "; ".join(" -> ".join(c) for c in cycles)


def test_imports_point_down():
    upward = []
    for name, tree in MODULES.items():
        if name in ENTRY_POINTS or folder(name) not in RANK:
            continue
        for target, _, line in imports(name, tree):
            if target in ("jaxdea",) or folder(target) not in RANK:
                continue
            if RANK[folder(target)] > RANK[folder(name)] or (
                    RANK[folder(target)] == RANK[folder(name)] and folder(target) != folder(name)):
                upward.append(f"{name}:{line} imports {target}")
    assert not upward, "imports that point up: " + "; ".join(upward)


def test_no_private_name_crosses_a_folder():
    crossing = [f"{name}:{line} imports {target}.{imported}"
                for name, tree in MODULES.items() for target, imported, line in imports(name, tree)
                if imported and imported.startswith("_") and target in MODULES
                and folder(target) != folder(name)]
    assert not crossing, "private names imported across folders: " + "; ".join(crossing)


def test_units_keeps_its_public_path():
    """``jaxdea.units`` (README, docs/howto/units.md) is the moved module's names, the same objects."""
    import jaxdea
    import jaxdea.physics.units as moved
    import jaxdea.units as public

    assert jaxdea.units is public
    for name in ("Scales", "tube_from_si", "tube_to_si", "fluid_from_si", "fluid_to_si",
                 "VACUUM_PERMITTIVITY"):
        assert getattr(public, name) is getattr(moved, name), name


def test_names_are_imported_from_the_module_that_defines_them():
    """``guard`` from params, not through roots: a re-export by accident ties two modules that need
    not know each other. The package's __init__ and the facade jaxdea.units re-export."""
    borrowed = []
    for name, tree in MODULES.items():
        if name in ENTRY_POINTS:
            continue
        for target, imported, line in imports(name, tree):
            if (imported and target in MODULES and not is_package(target)
                    and imported not in defined(MODULES[target])):
                borrowed.append(f"{name}:{line} imports {imported} from {target}")
    assert not borrowed, "names imported from a module that does not define them: " + "; ".join(borrowed)
