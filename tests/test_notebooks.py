"""Execute every notebook in notebooks/ end to end, as a user would run it (the gallery's
notebooks, whose pictures and physical facts are checked too, in test_gallery.py)."""

from __future__ import annotations

from pathlib import Path

import nbclient  # test dependencies (pip install ".[test]"): missing, this module fails
import nbformat
import pytest

NOTEBOOKS = sorted((Path(__file__).resolve().parent.parent / "notebooks").glob("*.ipynb"))
GALLERY_PREFIX = "gallery_"
CELL_TIMEOUT_S = 600


def execute(path, workdir):
    """Runs the notebook at `path` in the directory `workdir` (so that the files it writes stay
    out of the work tree), asserts that no cell raised, and returns the executed notebook."""
    nb = nbformat.read(path, as_version=4)
    client = nbclient.NotebookClient(
        nb,
        timeout=CELL_TIMEOUT_S,
        kernel_name="python3",
        resources={"metadata": {"path": str(workdir)}},
    )
    client.execute()
    errors = [
        out
        for cell in nb.cells
        if cell.cell_type == "code"
        for out in cell.get("outputs", [])
        if out.get("output_type") == "error"
    ]
    assert not errors, errors
    return nb


TUTORIALS = [p for p in NOTEBOOKS if not p.name.startswith(GALLERY_PREFIX)]


@pytest.mark.parametrize("path", TUTORIALS, ids=[p.name for p in TUTORIALS])
def test_notebook_executes(path, tmp_path):
    execute(path, tmp_path)


def test_there_are_notebooks():
    assert TUTORIALS, "notebooks/ holds no tutorial .ipynb"
    assert len(TUTORIALS) < len(NOTEBOOKS), "notebooks/ holds no gallery_*.ipynb"
