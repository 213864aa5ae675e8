"""Random RLC networks read from decks and run from SPICE's starting states, against ngspice running the same deck:
with ``uic`` (elements at their ``ic=`` values, capacitors across the source moved where it puts them) and without
(the DC operating point).

The generator: nodes 1…n, each joined by a resistor to an earlier node or ground (so every node has a path to
ground and no node is reached by capacitors alone), then capacitors and inductors between random pairs (inductors
never closing a loop of inductors and the source: node fluxes cannot hold a flux trapped in one), one source
between node 1 and ground (a voltage source, DC or sine, or a current source), and values drawn over decades.
Every capacitor voltage and inductor current is compared with ngspice's at ngspice's own time points (tight
tolerances on both sides); a deck ngspice gives up on (its "timestep too small") is left out, having nothing to
be compared with."""

import math
import warnings

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, example, given, settings
from hypothesis import strategies as st

from lagrangian.netlist import NetlistWarning, read_netlist
from lagrangian.spice import NgspiceError, run_transient

pytest.importorskip("PySpice.Spice.NgSpice.Shared")


def _decade(lo: float, hi: float):
    return st.floats(math.log10(lo), math.log10(hi)).map(lambda e: float(f"{10 ** e:.3g}"))


def _start(size: float):
    """An initial value as a user writes one: zero, or a few per cent to all of ``size``, either sign."""
    return st.one_of(st.just(0.0), st.tuples(st.sampled_from([-1.0, 1.0]), st.floats(0.02, 1.0)).map(
        lambda x: x[0] * x[1] * size))


@st.composite
def networks(draw):
    n = draw(st.integers(2, 4))
    lines, caps, coils = [], [], []
    for k in range(1, n + 1):
        lines.append(f"R{k} {k} {draw(st.integers(0, k - 1))} {draw(_decade(100, 1e4)):g}")
    group = list(range(n + 1))  # union-find over inductors and the source: no loop of them

    def root(a):
        while group[a] != a:
            a = group[a]
        return a

    source = draw(st.sampled_from(["dc", "sin", "current"]))
    if source != "current":
        group[root(1)] = root(0)
    for k in range(draw(st.integers(1, 4))):
        a, b = draw(st.sampled_from([(i, j) for i in range(n + 1) for j in range(i + 1, n + 1)]))
        if draw(st.booleans()) and root(a) != root(b):
            group[root(a)] = root(b)
            coils.append(f"L{k} {b} {a} {draw(_decade(1e-3, 1e-1)):g} ic={draw(_start(2e-3)):.3g}")
        else:
            caps.append(f"C{k} {b} {a} {draw(_decade(1e-7, 1e-5)):g} ic={draw(_start(2.0)):.3g}")
    amplitude = draw(st.floats(0.5, 5))
    lines.append({"dc": f"V1 1 0 DC {amplitude:.3g}", "sin": f"V1 1 0 SIN(0 {amplitude:.3g} 500)",
                  "current": f"I1 0 1 DC {amplitude * 1e-3:.3g}"}[source])
    uic = draw(st.booleans())
    text = "\n".join(["random network", *lines, *caps, *coils, ".options reltol=1e-7 abstol=1e-12 vntol=1e-9",
                      f".tran 1u 4m 0 0.25u{' uic' if uic else ''}", ".end", ""])
    # the sizes a difference is measured against where an element's own swing is small: the source's voltage and
    # the current it drives through the smallest resistor (or the source's current and its drop on the largest)
    volts = amplitude if source != "current" else amplitude * 1e-3 * 1e4
    return text, max(volts, 2.0), max(volts, 2.0) / 100


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(networks())
@example(("capacitors across the source\nR1 1 0 470\nR2 2 1 1e3\nV1 1 0 SIN(0 2 500)\nC0 1 0 2.2e-06 ic=1.5\n"
          "C1 2 0 1e-06 ic=-0.7\nC2 1 2 4.7e-07 ic=0.3\nL3 2 0 0.01 ic=1e-3\n"
          ".options reltol=1e-7 abstol=1e-12 vntol=1e-9\n.tran 1u 4m 0 0.25u uic\n.end\n", 2.0, 0.02))
@pytest.mark.slow
def test_random_networks_start_and_run_as_ngspice_runs_the_same_deck(case):
    text, volts, amps = case
    with warnings.catch_warnings():  # a capacitor moved to where the source puts it is said, not an error
        warnings.simplefilter("ignore", NetlistWarning)
        net = read_netlist(text, formulation="flux")
    model = net.model
    probes = {name: ("v", *comp.nodes) if comp.kind == "capacitor" else ("i", name.lower())
              for name, comp in model.components.items() if comp.kind in ("capacitor", "inductor")}
    try:
        spice = run_transient(text, {name: tuple("0" if n == "ground" else n for n in probe) for name, probe in probes.items()})
    except NgspiceError:  # ngspice gives up on a few drawn decks ("timestep too small"): nothing to compare with
        assume(False)
    keep = spice.time > 0
    res = net.simulate(t_eval=spice.time[keep], rtol=1e-11, atol=1e-14)
    for name, comp in model.components.items():
        if name not in probes:
            continue
        ours = net.capacitor_voltage(res, name) if comp.kind == "capacitor" else net.inductor_current(res, name)
        theirs = spice.quantities[name][keep]
        size = max(float(np.max(np.abs(theirs))), volts if comp.kind == "capacitor" else amps)
        # ngspice's own error (trapezoidal steps of 0.25 µs over 4 ms, a resonance of 3e4 rad/s drifting in phase)
        # reaches 1e-4 of the swing where ours agrees with the matrix exponential to 1e-10: 1e-3 is its margin
        assert float(np.max(np.abs(ours - theirs))) <= 1e-3 * size, (name, text)
