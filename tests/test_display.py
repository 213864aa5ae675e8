"""Display in notebooks: every object users look at renders as HTML (escaped), and its plain repr is short."""

import math

import pytest
import re

import numpy as np
import sympy as sp

import lagrangian as lg
from lagrangian import models, routh
from lagrangian.scene import Scene


def oscillator(name="oscillator", node="p"):
    m = lg.Model(name)
    m.add("mass", "m1", node, m=0.3)
    m.add("spring", "k1", ("ground", node), k=40)
    m.add("damper", "c1", ("ground", node), c=0.05)
    return m


def short(obj):
    text = repr(obj)
    assert text.startswith("<") and text.endswith(">") and len(text) < 300 and "array(" not in text, text
    return text


def test_a_model_shows_its_components_coordinates_and_equations_in_mechanics_notation():
    m = oscillator()
    assert short(m) == "<Model 'oscillator': 3 components (m1, k1, c1)>"
    html = m._repr_html_()
    assert "<td>spring</td>" in html and "<td>x_p</td>" in html
    assert r"\dot{x}_{p}" in html and r"\ddot{q}" in html and "(t)" not in html
    assert "coordinates x_p" in short(m)


def test_names_are_escaped_and_a_model_that_cannot_be_derived_still_shows_why():
    m = lg.Model("<script>alert(1)</script>")
    m.add("spring", "k<b>", ("ground", "p"), k=40)
    html = m._repr_html_()
    assert "<script>" not in html and "&lt;script&gt;" in html and "k&lt;b&gt;" in html
    assert "not derived" in html and "inertia" in html


def test_a_result_shows_a_summary_notes_and_a_chart():
    res = oscillator().simulate(2, initial={"x_p": 0.01}, velocity={"x_p": 0})
    text = short(res)
    assert "DOP853" in text and "1001 times" in text and "x_p" in text
    html = res._repr_html_()
    assert html.count("<img") == 1 and "data:image/png;base64," in html and "energy T + V" in html
    assert re.search(r"0\.01 → ", html)


def test_a_reduced_model_shows_the_routhian_and_its_equations():
    red = routh.reduce(models.spherical_pendulum(0.3, 0.7))
    assert "theta_turn eliminated" in short(red)
    html = red._repr_html_()
    assert "$$R = " in html and r"V_{\mathrm{eff}}" in html and r"\ddot{\theta}_{tilt}" in html


@pytest.mark.slow
def test_steady_motions_and_their_stability_show_the_verdict_and_eigenvalues():
    red = routh.reduce(models.spherical_pendulum(1.0, 1.0))
    C = math.sin(0.7) ** 2 * math.sqrt(9.81 / math.cos(0.7))
    motion = next(s for s in red.steady_motions(momenta={"theta_turn": C}) if float(s.coordinates["theta_tilt"]) > 0)
    assert "theta_tilt = 0.7" in short(motion)
    stability = motion.stability()
    assert short(stability).startswith("<Stability: stable; eigenvalues")
    html = motion._repr_html_()
    omega = math.sqrt(9.81 * (3 * math.cos(0.7) + 1 / math.cos(0.7)))  # the notes' perturbation frequency
    assert "<b>stable</b>" in html and f"{omega:.6g}" in html
    l, g = sp.symbols("l g", positive=True)
    symbolic = routh.reduce(models.spherical_pendulum(1, l, g)).steady_motions(solve_for=["C_theta_turn"])[1]
    assert "give values" in symbolic._repr_html_()


def test_a_comparison_with_ngspice_shows_its_table_and_chart(tmp_path):
    import matplotlib

    from lagrangian.compare import compare_with_ngspice

    m = lg.Model("series-RLC")
    m.add("inductor", "L", ("0", "b"), L=7e-3)
    m.add("resistor", "R", ("b", "c"), R=4.7)
    m.add("capacitor", "C", ("c", "0"), C=2.2e-6)
    cmp = compare_with_ngspice(m, 1e-3, initial={"q_L": 2.2e-6}, velocity={"q_L": 0.0})
    assert "with ngspice" in short(cmp)
    previous = matplotlib.get_backend()
    matplotlib.use("svg")  # a backend of the user's: showing or charting a comparison must not switch it
    try:
        html = cmp._repr_html_()
        chart = cmp.chart(tmp_path / "cmp.png")
        assert matplotlib.get_backend() == "svg"
    finally:
        matplotlib.use(previous)
    assert html.count("<img") == 1 and "<td>i(L)</td>" in html and "wall time" in html
    assert chart.read_bytes().startswith(b"\x89PNG")


def test_a_scene_shows_its_report_and_its_result_a_chart():
    m = oscillator()
    m.add("mass", "solo", "s", m=1.0)
    m.add("spring", "ks", ("ground", "s"), k=1.0)
    scene = Scene(m, ["x_s"], t_end=1.0, initial={"x_s": 1.0}, velocity={"x_s": 0.0})
    assert "x_s" in short(scene)
    assert "dropped" in scene._repr_html_()
    res = scene.run()
    assert "x_s" in short(res) and res._repr_html_().count("<img") == 1
    assert np.allclose(res["x_s"], np.cos(res.t), atol=1e-7)



def _speaker() -> lg.Model:
    """A loudspeaker: a source, a resistor and a moving coil driving a cone on its suspension."""
    m = lg.Model("speaker")
    m.add("voltage_source", "V1", ("in", "0"), E=0)
    m.add("resistor", "Re", ("in", "a"), R=6.0)
    m.add("moving_coil", "coil", ("a", "0", "cone"), Bl=7.0)
    m.add("mass", "cone", "cone", m=0.02)
    m.add("spring", "suspension", ("ground", "cone"), k=2e3)
    return m

def test_a_model_draws_its_component_graph_with_domains_and_labels(tmp_path):
    from matplotlib.colors import to_hex

    from lagrangian.base.display import DOMAIN_COLOURS

    m = _speaker()
    ax = m.draw(path=str(tmp_path / "g.png"))
    labels = {t.get_text() for t in ax.texts if t.get_text()}
    assert {"Re\nresistor", "coil\nmoving_coil", "suspension\nspring", "cone\ncone (mass)"} <= labels
    legend = {t.get_text() for t in ax.get_legend().get_texts()}
    assert legend == {"mechanical", "electrical"}
    coil = next(t for t in ax.texts if t.get_text() == "coil\nmoving_coil")
    assert to_hex(coil.get_bbox_patch().get_facecolor()) == DOMAIN_COLOURS["electrical"]
    assert (tmp_path / "g.png").stat().st_size > 5000


def test_netlists_and_analogues_draw_as_schematics(tmp_path):
    import schemdraw.elements as elm

    from lagrangian.analogy import map_model
    from lagrangian.netlist import read_netlist
    from pathlib import Path

    deck = (Path(__file__).resolve().parents[1] / "examples" / "butterworth.cir").read_text()
    drawing = read_netlist(deck).model.schematic(path=str(tmp_path / "bw.svg"))
    count = {kind.__name__: sum(isinstance(e, kind) for e in drawing.elements)
             for kind in (elm.Resistor, elm.Capacitor, elm.Inductor2, elm.SourceV)}
    assert count == {"ResistorIEEE": 2, "Capacitor": 3, "Inductor2": 2, "SourceV": 1}
    labels = {lab.label for e in drawing.elements for lab in getattr(e, "_userlabels", [])}
    assert {"Rs", "C1", "L2", "C3", "L4", "C5", "RL", "V1"} <= labels
    assert (tmp_path / "bw.svg").read_text().startswith("<svg") or "<svg" in (tmp_path / "bw.svg").read_text()
    msd = lg.Model("msd")
    msd.add("mass", "m", "cart", m=1.0)
    msd.add("spring", "k", ("ground", "cart"), k=4.0)
    msd.add("damper", "c", ("ground", "cart"), c=0.4)
    msd.add("force", "F", "cart", F=1.0)
    analogue = map_model(msd, "force-voltage").model.schematic()
    assert [sum(isinstance(e, kind) for e in analogue.elements) for kind in
            (elm.Inductor2, elm.Capacitor, elm.Resistor, elm.SourceV)] == [1, 1, 1, 1]
    with pytest.raises(lg.ModelError, match="two-terminal"):
        speaker = lg.Model("speaker")
        speaker.add("moving_coil", "coil", ("a", "0", "cone"), Bl=7.0)
        speaker.schematic()


def _ties(drawing):
    """The dashed lines of a schematic, by label, with their ends."""
    import schemdraw.elements as elm

    return {lab.label: (e.absanchors["start"], e.absanchors["end"]) for e in drawing.elements
            if isinstance(e, elm.Line) and e.params.get("ls") == "--" for lab in getattr(e, "_userlabels", [])}


def _labelled(drawing, text):
    return [e for e in drawing.elements if any(lab.label == text for lab in getattr(e, "_userlabels", []))]


def test_two_ports_and_coupled_inductors_draw_with_their_ports_and_ties(tmp_path):
    """A loudspeaker's force–voltage analogue holds a gyrator: its two ports are drawn where its branches are (the
    coil's node to ground, the cone's mesh to ground), numbered, and tied by a dashed line naming it.  Coupled
    inductors (a netlist's K line) are tied the same way, with their coupling coefficient."""
    import schemdraw.elements as elm

    from lagrangian.analogy import map_model
    from lagrangian.netlist import read_netlist

    analogue = map_model(_speaker(), "force-voltage").model
    gyrator = next(c for c in analogue._graph.components.values() if c.kind == "gyrator")
    drawing = analogue.schematic(path=str(tmp_path / "speaker.svg"))
    ports = [_labelled(drawing, str(i)) for i in (1, 2)]
    assert all(len(p) == 1 and isinstance(p[0], elm.RBox) for p in ports)
    ties = _ties(drawing)
    assert list(ties) == [f"{gyrator.name} (gyrator)"]
    start, end = ties[f"{gyrator.name} (gyrator)"]
    centres = [(p[0].absanchors["start"] + p[0].absanchors["end"]) / 2 for p in ports]
    assert abs(start[1] - centres[0][1]) < 1e-9 and abs(end[1] - centres[1][1]) < 1e-9  # from port to port
    assert centres[0][0] < start[0] < end[0] < centres[1][0]
    deck = "transformer\nV1 in 0 SIN(0 1 50)\nR1 in a 10\nL1 a 0 7e-3\nL2 b 0 2.8e-2\nK1 L1 L2 0.98\nRL b 0 100\n.end\n"
    coupled = read_netlist(deck).model.schematic()
    (label,) = _ties(coupled)
    assert label.startswith("K1 (coupling") and "k=0.98" in label
    assert [len(_labelled(coupled, n)) for n in ("L1", "L2")] == [1, 1]


def test_names_holding_dollar_signs_are_drawn_as_written(tmp_path):
    """Names are text users give: matplotlib reads ``$…$`` as mathematics, where ``$\\nosuch{$`` fails the drawing.
    Every chart that writes a name shows it as written."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from lagrangian.frequency import decades, frequency_response

    odd = "k$\\nosuch{$"
    m = lg.Model(f"model {odd}")
    m.add("mass", "m1", "p", m=0.3)
    m.add("spring", odd, ("ground", "p"), k=40.0)
    ax = m.draw(path=str(tmp_path / "graph.png"))
    assert any(odd in t.get_text() for t in ax.texts)
    res = m.simulate(0.5, initial={"x_p": 0.01}, velocity={"x_p": 0.0}, points=11)
    anim = res.animate(tmp_path / "odd.gif", frames=2)
    assert odd in [t.get_text() for t in anim.figure(1).axes[0].get_legend().get_texts()]
    res.plot().figure.savefig(tmp_path / "run.png")
    sliders = m.interact([f"k_{odd}"], t_end=0.5, initial={"x_p": 0.01}, velocity={"x_p": 0.0}, points=11)
    sliders.figure.savefig(tmp_path / "sliders.png")
    assert odd in sliders.figure.axes[0].get_title()
    c = lg.Model("rc")
    c.add("voltage_source", "V1", ("in", "0"), E=0)
    c.add("resistor", odd, ("in", "out"), R=1e3)
    c.add("capacitor", "C1", ("out", "0"), C=2.2e-6)
    fig = frequency_response(c, decades(1, 1e4, 5), outputs=[f"i({odd})"]).plot()
    fig.savefig(tmp_path / "bode.png")
    drawing = c.schematic(path=str(tmp_path / "rc.svg"))
    assert any(getattr(lab, "label", "") == odd.replace("$", "\\$") for e in drawing.elements
               for lab in getattr(e, "_userlabels", []))
    plt.close("all")
