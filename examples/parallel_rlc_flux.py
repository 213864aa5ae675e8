"""A parallel RLC driven by a current source, in node flux linkages (force–current analogy).
=========================================================================================

The node's flux linkage λ is the coordinate; its rate is the node voltage.
Prints the Lagrangian (electric co-energy minus magnetic energy) and checks
the simulated steady-state amplitude against ``|Z(jω)|``·I.
Run: .venv/bin/python examples/parallel_rlc_flux.py
"""

import numpy as np
import sympy as sp

import lagrangian as lg

R, L, C, W = 2.0, 1.0, 0.5, 1.2


def circuit() -> lg.Model:
    """The parallel RLC in node flux linkages, driven by 1 A peak at W rad/s."""
    m = lg.Model("parallel RLC", formulation="flux")
    m.add("current_source", "I1", ("0", "n1"), I=sp.sin(W * lg.t))  # drives 1 A peak into n1
    m.add("resistor", "R1", ("n1", "0"), R=R)
    m.add("inductor", "L1", ("n1", "0"), L=L)
    m.add("capacitor", "C1", ("n1", "0"), C=C)
    return m


m = circuit()
print(m.describe())
res = m.simulate(60, initial={"lambda_n1": 0}, velocity={"lambda_n1": 0}, points=6001)
v = res.velocity("lambda_n1")
z = 1 / abs(1 / R + 1 / (1j * W * L) + 1j * W * C)
print(f"steady-state voltage amplitude: simulated {np.max(np.abs(v[res.t > 40])):.6f} V, |Z|·I = {z:.6f} V")
