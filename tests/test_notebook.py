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


def test_a_chart_returned_as_a_cells_value_is_shown_once(tmp_path):
    """In a real kernel with the inline backend: a Bode chart, a Nyquist chart and mode shapes returned as the
    cell's value are drawn once (they were drawn twice: by pyplot at the end of the cell, and as the value), and once
    as well when the value is not shown (``;``) or is assigned."""
    setup = ("import lagrangian as lg\nfrom lagrangian import frequency\n"
             "m = lg.Model('rc')\n_ = m.add('voltage_source', 'V1', ('in', '0'), E=0)\n"
             "_ = m.add('resistor', 'R1', ('in', 'a'), R=1e3)\n_ = m.add('capacitor', 'C1', ('a', '0'), C=2.2e-6)\n"
             "resp = frequency.frequency_response(m, frequency.decades(1, 1e4, 30), inputs=['V1'], outputs=['v(C1)'])\n"
             "pair = lg.Model('pair')\n_ = pair.add('mass', 'm1', 'a', m=0.3)\n_ = pair.add('mass', 'm2', 'b', m=0.2)\n"
             "_ = pair.add('spring', 'k', ('a', 'b'), k=40.0)")
    cells = [setup, "resp.plot('bode')", "resp.plot('nyquist')", "resp.plot('bode');", "fig = resp.plot('bode')",
             "frequency.modes(pair).plot()"]
    nb = nbformat.v4.new_notebook(cells=[nbformat.v4.new_code_cell(c) for c in cells])
    nbclient.NotebookClient(nb, timeout=300, kernel_name="python3",
                            resources={"metadata": {"path": str(tmp_path)}}).execute()
    for cell in nb.cells[1:]:
        images = [out for out in cell.outputs if "image/png" in out.get("data", {})]
        assert len(images) == 1, (cell.source, [out.get("data", {}).keys() for out in cell.outputs])
