"""Sliders over parameters (``Model.interact``, ``frequency.interact``): a moved slider runs the model again with
the new values, nothing derived again, and the chart shows the new run, against closed forms over decades of
values; what cannot be done is refused by name; in a Jupyter kernel the sliders show as widgets."""

from __future__ import annotations

import sys

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

import lagrangian as lg
from lagrangian.errors import ModelError, UnknownNameError
from lagrangian.frequency import decades, interact as bode_interact

pytest.importorskip("ipywidgets")


def oscillator(m=0.3, k=40.0) -> lg.Model:
    model = lg.Model("oscillator")
    model.add("mass", "m1", "p", m=m)
    model.add("spring", "k1", ("ground", "p"), k=k)
    return model


@settings(max_examples=12, deadline=None)
@given(k=st.floats(1.0, 1e4), m=st.floats(0.01, 10.0))
def test_a_moved_slider_shows_the_run_at_its_values(k, m):
    model = oscillator()
    sliders = model.interact(["k_k1", "m_m1"], t_end=0.5, initial={"x_p": 0.01}, velocity={"x_p": 0.0},
                             points=51, ranges={"k_k1": (1.0, 1e4), "m_m1": (0.01, 10.0)})
    derived = model.eq
    sliders.set(k_k1=k, m_m1=m)
    line = sliders.figure.axes[0].lines[0]
    t, x = line.get_xdata(), line.get_ydata()
    np.testing.assert_allclose(x, 0.01 * np.cos(np.sqrt(k / m) * t), rtol=0, atol=1e-9)
    assert sliders.values == {"k_k1": pytest.approx(k), "m_m1": pytest.approx(m)}
    assert model.eq is derived  # nothing derived again


def test_a_nonlinear_model_reruns_its_compiled_code():
    model = lg.Model("pendulum", dim=2)
    model.add("rod", "r", "r", m=0.3, length=0.5)
    model.add("revolute", "j", ("ground", "r"))
    model.add("gravity", "g", g=9.81)
    sliders = model.interact(["length_r"], t_end=0.4, initial={"theta_j": -1.2}, velocity={"theta_j": 0.0},
                             method="DOP853", points=41)
    derived = model.eq
    sliders.set(length_r=1.3)
    reference = model.simulate(0.4, initial={"theta_j": -1.2}, velocity={"theta_j": 0.0}, points=41,
                               params={"length_r": 1.3})
    np.testing.assert_allclose(sliders.figure.axes[0].lines[0].get_ydata(), reference["theta_j"], rtol=0, atol=1e-12)
    assert sliders.result.method == "DOP853" and model.eq is derived
    free = model.interact(["length_r"], t_end=0.4, initial={"theta_j": -1.2}, velocity={"theta_j": 0.0},
                          outputs=["E", "0.5 * theta_j"], points=41)
    assert [line.get_label() for line in free.figure.axes[0].lines] == ["E", "0.5 * theta_j"]
    np.testing.assert_allclose(free.figure.axes[0].lines[1].get_ydata(), 0.5 * free.result["theta_j"], rtol=1e-15)


def test_an_animation_follows_the_sliders():
    model = lg.Model("pendulum", dim=2)
    model.add("rod", "r", "r", m=0.3, length=0.5)
    model.add("revolute", "j", ("ground", "r"))
    model.add("gravity", "g")
    sliders = model.interact(["length_r"], t_end=0.3, initial={"theta_j": -1.0}, velocity={"theta_j": 0.0},
                             points=31, view="animation", frames=4)
    assert "data:image/png;base64" in sliders.figure.data
    sliders.set(length_r=2.0)
    assert sliders.result.animate(frames=2).position("r", 0)[1] == pytest.approx([2 * np.cos(-1.0), 2 * np.sin(-1.0), 0])


@settings(max_examples=10, deadline=None)
@given(R=st.floats(10.0, 1e5), C=st.floats(1e-9, 1e-4))
def test_a_bode_chart_follows_its_sliders(R, C):
    """An RC low-pass: v(C1)/V1 = 1/(1 + j ω R C) at every value the sliders take, derived once."""
    c = lg.Model("rc")
    c.add("voltage_source", "V1", ("in", "0"), E=0)
    c.add("resistor", "R1", ("in", "out"), R=1e3)
    c.add("capacitor", "C1", ("out", "0"), C=2.2e-6)
    bode = bode_interact(c, ["R_R1", "C_C1"], decades(0.1, 1e6, 20), outputs=["v(C1)"],
                         ranges={"R_R1": (10.0, 1e5), "C_C1": (1e-9, 1e-4)})
    bode.set(R_R1=R, C_C1=C)
    H = 1 / (1 + 2j * np.pi * bode.frequencies * R * C)
    np.testing.assert_allclose(bode.response[0, 0], H, rtol=1e-10, atol=0)
    magnitude, phase = bode.figure.axes
    np.testing.assert_allclose(magnitude.lines[0].get_ydata(), 20 * np.log10(np.abs(H)), rtol=0, atol=1e-8)
    np.testing.assert_allclose(phase.lines[0].get_ydata(), np.degrees(np.angle(H)), rtol=0, atol=1e-8)


def test_what_sliders_cannot_do_is_refused_by_name(monkeypatch):
    model = oscillator()
    with pytest.raises(UnknownNameError, match="k_k2"):
        model.interact(["k_k2"])
    with pytest.raises(ModelError, match="range .* must hold its value"):
        model.interact(["k_k1"], ranges={"k_k1": (50.0, 60.0)}, initial={"x_p": 0.01}, velocity={"x_p": 0.0})
    with pytest.raises(ModelError, match="view is 'chart' or 'animation'"):
        model.interact(["k_k1"], view="movie")
    sliders = model.interact(["m_m1"], t_end=0.2, initial={"x_p": 0.01}, velocity={"x_p": 0.0}, points=11,
                             ranges={"m_m1": (-1.0, 1.0)})
    before = sliders.figure.axes[0].lines[0].get_ydata().copy()
    sliders.set(m_m1=-0.5)  # a run the values make impossible: said in the status line, the last chart kept
    assert "parameter &#x27;m&#x27;: must be positive" in sliders.status.value
    np.testing.assert_array_equal(sliders.figure.axes[0].lines[0].get_ydata(), before)
    with pytest.raises(UnknownNameError, match="slider"):
        sliders.set(k_k1=3.0)
    monkeypatch.setitem(sys.modules, "ipywidgets", None)
    with pytest.raises(ModelError, match="pip install ipywidgets"):
        model.interact(["k_k1"])


@pytest.mark.slow
def test_sliders_and_an_animation_show_in_a_jupyter_kernel(tmp_path):
    nbformat = pytest.importorskip("nbformat")
    nbclient = pytest.importorskip("nbclient")
    pytest.importorskip("ipykernel")
    nb = nbformat.v4.new_notebook()
    nb.cells = [nbformat.v4.new_code_cell(
        "import lagrangian as lg\n"
        "m = lg.Model('oscillator')\n"
        "_ = m.add('mass', 'm1', 'p', m=0.3)\n"
        "_ = m.add('spring', 'k1', ('ground', 'p'), k=40)\n"
        "s = m.interact(['k_k1'], t_end=1, initial={'x_p': 0.01}, velocity={'x_p': 0})\n"
        "s"), nbformat.v4.new_code_cell("s.set(k_k1=120.0)\nprint(round(float(s.result['x_p'][-1]), 9))"),
        nbformat.v4.new_code_cell("s.result.animate(frames=3)")]
    nbclient.NotebookClient(nb, timeout=300, kernel_name="python3", resources={"metadata": {"path": str(tmp_path)}}).execute()
    shown = [kind for out in nb.cells[0].outputs for kind in out.get("data", {})]
    assert "application/vnd.jupyter.widget-view+json" in shown
    printed = "".join(out.get("text", "") for out in nb.cells[1].outputs)
    assert float(printed) == pytest.approx(0.01 * np.cos(np.sqrt(120 / 0.3)), abs=1e-9)
    player = "".join(out.get("data", {}).get("text/html", "") for out in nb.cells[2].outputs)
    assert player.count("data:image/png;base64") == 3 and 'type="range"' in player  # the animation's player


def test_a_models_name_is_shown_as_text_above_its_sliders():
    model = lg.Model("<img src=x onerror=alert(1)>")
    model.add("mass", "m1", "p", m=0.3)
    model.add("spring", "k1", ("ground", "p"), k=40.0)
    sliders = model.interact(["k_k1"], t_end=0.1, initial={"x_p": 0.01}, velocity={"x_p": 0.0}, points=5)
    heading = sliders.widget.children[0].value
    assert "<img" not in heading and "&lt;img src=x onerror=alert(1)&gt;" in heading
