"""``examples/notes.ipynb`` executes headless in a real Jupyter kernel (nbclient, ipykernel): every cell runs (the
cells assert their closed forms) and every object shows itself as users see it in Jupyter."""

import json
from pathlib import Path

import pytest

nbformat = pytest.importorskip("nbformat")
nbclient = pytest.importorskip("nbclient")
pytest.importorskip("ipykernel")

NOTEBOOK = Path(__file__).resolve().parents[1] / "examples" / "notes.ipynb"


def test_the_notes_notebook_runs_in_a_kernel_and_shows_every_object(tmp_path):
    nb = nbformat.read(NOTEBOOK, as_version=4)
    nbclient.NotebookClient(nb, timeout=600, kernel_name="python3",
                            resources={"metadata": {"path": str(tmp_path)}}).execute()  # raises on a failing cell
    shown = {}
    for cell in nb.cells:
        if cell.cell_type == "code":
            kinds = [kind for out in cell.outputs for kind in out.get("data", {})]
            errors = [out for out in cell.outputs if out.output_type == "error"]
            assert not errors, cell.source
            shown[cell.source.splitlines()[-1]] = kinds
    html = {last for last, kinds in shown.items() if "text/html" in kinds}
    assert {"model", "run", "reduced", "verdict", "comparison"} <= html
    assert "image/svg+xml" in shown["analogue.model.schematic()"]
    # the Bode chart after a comparison was shown: the library left the notebook's inline backend alone
    assert "image/png" in shown["response.plot();"]
    outputs = json.dumps([c.outputs for c in nb.cells if c.cell_type == "code"])
    assert "conserved momentum" in outputs and "stable" in outputs and "ngspice" in outputs
