"""The commonest step-response deck: a PULSE source into an RC, read, simulated, written back and run in ngspice.

The reference is ngspice itself (through PySpice) running the deck we
write, and the closed form of the RC charging from the pulse's edge.
"""

import math
import warnings

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from lagrangian.compare import compare_with_ngspice
from lagrangian.netlist import Transient, read_netlist

DECK = """step response
V1 in 0 PULSE(0 5 1m 1u 1u 20m 40m)
R1 in out {R}
C1 out 0 {C}
.tran 10u 30m uic
.end
"""


def test_pulse_deck_simulates_on_its_own_grid_and_agrees_with_ngspice():
    R, C = 1.5e3, 2.2e-6
    net = read_netlist(DECK.format(R=R, C=C))
    res = net.simulate()
    assert res.t[0] == 0.0 and res.t[-1] == 0.03  # 10u · 3000 is past 30m by round-off: the grid ends at 30m
    v = net.capacitor_voltage(res, "C1")
    # closed form on the pulse's top, after the 1 µs rise from t = 1 ms: v = 5 (1 − exp(−(t − t₁)/RC)),
    # t₁ ≈ 1 ms + 0.5 µs; the pulse falls at 21 ms
    tau, t1 = R * C, 1e-3 + 0.5e-6
    late = (res.t > 2e-3) & (res.t < 21e-3)
    exact = 5 * (1 - np.exp(-(res.t[late] - t1) / tau))
    assert np.max(np.abs(v[late] - exact)) < 1e-4  # the ramp's shape shifts the edge by a fraction of 1 µs
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        cmp = compare_with_ngspice(net.model, 0.03, step=1e-4, max_step=1e-6,
                                   initial={name: 0.0 for name in net.model.coordinate_names})
    assert "floor(" in cmp.netlist and "Mod" not in cmp.netlist
    assert cmp.worst_rel < 5e-4, cmp.table()  # measured 5.5e-5 at a 1 µs step cap


@settings(max_examples=40)
@given(step=st.sampled_from([1e-5, 2e-5, 1e-4, 3e-6, 7e-3, 0.1, 0.25]), count=st.integers(1, 5000))
def test_tran_grid_ends_at_its_stop_and_never_past_it(step, count):
    stop = float(f"{step * count:.12g}")  # as typed in a deck
    times = Transient(step, stop).times
    assert times[0] == 0.0 and times[-1] == stop and np.all(times <= stop)
    assert np.all(np.diff(times) > 0)
    assert math.isclose(np.median(np.diff(times)), step, rel_tol=1e-9)
