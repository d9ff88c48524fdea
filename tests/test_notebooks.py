"""The notebooks (jupytext percent-format .py files) execute top to bottom in a Jupyter kernel, in
their fast setting (JAXDEA_NOTEBOOK_FAST=1), as nbmake would run them; their own cells assert their
checks (gradients against central differences, blank points against critical voltages). The kernel keeps
its own matplotlib backend (the library never sets one), so the plots show inline."""

from pathlib import Path

import pytest

jupytext = pytest.importorskip("jupytext")
nbclient = pytest.importorskip("nbclient")

ROOT = Path(__file__).resolve().parent.parent
NOTEBOOKS = sorted((ROOT / "notebooks").glob("*.py"))
PLOTTING = {"quickstart", "paper_reproduction", "sensitivity_maps", "design", "characterisation"}
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
    monkeypatch.delenv("MPLBACKEND", raising=False)  # the kernel's own (inline) backend, as a user has
    notebook = jupytext.read(path)
    client = nbclient.NotebookClient(notebook, timeout=900, kernel_name="python3",
                                      resources={"metadata": {"path": str(tmp_path)}})
    client.execute()
    errors = [out for cell in notebook.cells if cell.cell_type == "code"
              for out in cell.get("outputs", []) if out.get("output_type") == "error"]
    assert not errors
    assert any(cell.get("outputs") for cell in notebook.cells if cell.cell_type == "code")
    images = [out for cell in notebook.cells if cell.cell_type == "code" for out in cell.get("outputs", [])
              if "image/png" in out.get("data", {})]
    stray = [text for cell in notebook.cells if cell.cell_type == "code" for out in cell.get("outputs", [])
             for text in [out.get("data", {}).get("text/plain", "")]
             if text.startswith(("Text(", "<matplotlib.legend.Legend", "[Text("))]
    assert not stray, stray  # a plotting cell shows its figure, not the repr of its last call
    if path.stem in PLOTTING:
        assert len(images) >= 1, f"{path.name} shows no plot inline"
