"""What a user reads and looks at: LaTeX, the text summary, and charts of a result."""

import warnings

import matplotlib

matplotlib.use("Agg")
import numpy as np
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
