"""What a user reads and looks at: LaTeX, the text summary, and charts of a result."""

import warnings

import matplotlib

matplotlib.use("Agg")
import numpy as np
import pytest
import sympy as sp

import lagrangian as lg


def oscillator():
    m = lg.Model("oscillator")
    m.add("mass", "m1", "cart", m=sp.Symbol("m", positive=True))
    m.add("spring", "k1", ("ground", "cart"), k=sp.Symbol("k", positive=True))
    m.add("damper", "c1", ("ground", "cart"), c=sp.Symbol("c", positive=True))
    return m


def test_latex_round_trips_to_the_hand_derived_equation():
    m = oscillator()
    text = m.latex()
    assert text.splitlines()[0].startswith("L = ")
    assert any(line.startswith("D = ") for line in text.splitlines())
    # the equation line holds M, f and q; parse M and f back from SymPy's own objects
    assert sp.latex(m.mass_matrix) in text and sp.latex(m.forcing) in text
    x = sp.Function("x_cart", real=True)(lg.t)
    c, k, mass = sp.symbols("c k m", positive=True)
    residual = m.mass_matrix[0] * x.diff(lg.t, 2) - m.forcing[0] - (mass * x.diff(lg.t, 2) + c * x.diff(lg.t) + k * x)
    assert sp.simplify(residual) == 0


def test_describe_names_components_coordinates_and_equations():
    text = oscillator().describe()
    for word in ("m1 (mass)", "k1 (spring)", "c1 (damper)", "x_cart", "L = ", "D = "):
        assert word in text


def test_a_result_plots_each_unit_on_its_own_axes_labelled_with_it():
    """A loudspeaker's coil charge (C) and cone displacement (m): two axes, each with its series and unit (they
    shared one axes labelled "coordinate"); their rates in C/s and m/s; a single unit, one axes."""
    import matplotlib.pyplot as plt

    from lagrangian import models

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", lg.InitialConditionWarning)
        res = models.loudspeaker().simulate(0.01, points=21)
    axes = res.plot()
    assert [a.get_ylabel() for a in axes] == ["coordinate (C)", "coordinate (m)"]
    assert [[line.get_label() for line in a.get_lines()] for a in axes] == [["q_Le"], ["x_cone"]]
    np.testing.assert_array_equal(axes[1].get_lines()[0].get_ydata(), res["x_cone"])
    assert [a.get_ylabel() for a in res.plot(velocity=True)] == ["velocity (C/s)", "velocity (m/s)"]
    assert res.plot("x_cone").get_ylabel() == "coordinate (m)"
    plt.close("all")


def test_result_plots_coordinates_velocities_and_energies():
    m = lg.Model("lc", formulation="flux")
    m.add("capacitor", "C1", ("n1", "0"), C=1)
    m.add("inductor", "L1", ("n1", "0"), L=1)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", lg.InitialConditionWarning)
        res = m.simulate(2 * np.pi, initial={"lambda_n1": 1}, points=201)
    ax = res.plot()
    (line,) = ax.get_lines()
    np.testing.assert_allclose(line.get_ydata(), np.cos(res.t), atol=1e-7)  # λ = cos t
    ax = res.plot(velocity=True)
    np.testing.assert_allclose(ax.get_lines()[0].get_ydata(), -np.sin(res.t), atol=1e-7)
    ax = res.plot(energy=True)
    labels = [l.get_label() for l in ax.get_lines()]
    assert labels == ["T", "V", "T+V"]
    np.testing.assert_allclose(ax.get_lines()[2].get_ydata(), 0.5, atol=1e-7)  # ½λ²/L + ½Cλ̇² = ½


@pytest.mark.slow
def test_a_chart_of_many_coordinates_draws_the_first_and_says_so(tmp_path):
    """A 30-section ladder has 31 coordinates: the chart draws the first PLOT_SERIES with a legend and says how
    many of how many; named coordinates are drawn as asked, without a legend past PLOT_SERIES; the command line
    says what its chart holds."""
    import subprocess
    import sys

    import matplotlib.pyplot as plt

    from lagrangian.numerics.result import PLOT_SERIES

    m = lg.Model("ladder")
    m.add("voltage_source", "V1", ("n0", "0"), E=sp.sin(2 * lg.t))
    for k in range(30):
        m.add("inductor", f"L{k}", (f"n{k}", f"n{k + 1}"), L=0.3 + 0.01 * k)
        m.add("capacitor", f"C{k}", (f"n{k + 1}", "0"), C=7e-3 * (1 + 0.1 * k))
    m.add("resistor", "R", (f"n{30}", "0"), R=4.7)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", lg.InitialConditionWarning)
        res = m.simulate(1, points=11)
    assert len(res.names) == 31  # a charge per loop: the 30 inductors and the resistor
    ax = res.plot()
    assert [line.get_label() for line in ax.get_lines()] == res.names[:PLOT_SERIES]
    assert ax.get_legend() is not None and f"the first {PLOT_SERIES} of 31 coordinates" in ax.get_title()
    ax = res.plot(*res.names[:20])
    assert len(ax.get_lines()) == 20 and ax.get_legend() is None and "20 series" in ax.get_title()
    plt.close("all")
    deck = tmp_path / "ladder.cir"
    deck.write_text("ladder\nV1 n0 0 SIN(0 1 0.3)\n" + "".join(
        f"L{k} n{k} n{k + 1} 0.3\nC{k} n{k + 1} 0 7m\n" for k in range(30)) + "R n30 0 4.7\n.end\n")
    run = subprocess.run([sys.executable, "-m", "lagrangian", "simulate", str(deck), "--points", "21",
                          "--out", str(tmp_path / "all.png")], capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stderr
    assert f"the chart draws the first {PLOT_SERIES} of 31 coordinates" in run.stdout
    assert (tmp_path / "all.png").stat().st_size > 10_000 and "constrained_layout" not in run.stderr
