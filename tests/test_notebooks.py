"""The notebooks (jupytext percent-format .py files) execute top to bottom in a Jupyter kernel, in
their fast setting (JAXDEA_NOTEBOOK_FAST=1), as nbmake would run them; their own cells assert their
checks (gradients against central differences, blank points against critical voltages)."""

from pathlib import Path

import pytest

jupytext = pytest.importorskip("jupytext")
nbclient = pytest.importorskip("nbclient")

ROOT = Path(__file__).resolve().parent.parent
NOTEBOOKS = sorted((ROOT / "notebooks").glob("*.py"))
SLOW = {"design",  # its optax loops compile the critical-voltage and Newton programs: minutes
        "paper_reproduction",  # 200 s of the default tier (every figure grid and V̂_cr grid)
        "characterisation"}  # its fits compile the root, Jacobian and scan programs: minutes


def test_every_notebook_is_listed():
    assert {p.stem for p in NOTEBOOKS} >= {"quickstart", "paper_reproduction", "sensitivity_maps", "design",
                                             "explore"}


@pytest.mark.parametrize("path", [pytest.param(p, marks=pytest.mark.slow) if p.stem in SLOW else p
                                  for p in NOTEBOOKS], ids=lambda p: p.stem)
def test_notebook_runs(path, tmp_path, monkeypatch):
    monkeypatch.setenv("JAXDEA_NOTEBOOK_FAST", "1")
    monkeypatch.setenv("JUPYTER_PLATFORM_DIRS", "1")
    monkeypatch.setenv("JAXDEA_CACHE_DIR", str(ROOT / ".jax_cache"))  # share the tests' compilations
    monkeypatch.setenv("MPLBACKEND", "Agg")
    notebook = jupytext.read(path)
    client = nbclient.NotebookClient(notebook, timeout=900, kernel_name="python3",
                                      resources={"metadata": {"path": str(tmp_path)}})
    client.execute()
    errors = [out for cell in notebook.cells if cell.cell_type == "code"
              for out in cell.get("outputs", []) if out.get("output_type") == "error"]
    assert not errors
    assert any(cell.get("outputs") for cell in notebook.cells if cell.cell_type == "code")
