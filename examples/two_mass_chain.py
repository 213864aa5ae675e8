"""Two masses in a chain, ground–k1–m1–k2–m2: normal modes from the Lagrangian.
============================================================================

Prints the equations, the normal-mode frequencies from M and the stiffness
matrix K = −∂f/∂q, and the simulated motion started in the slow mode.
Run: .venv/bin/python examples/two_mass_chain.py
"""

import numpy as np
import scipy.linalg
import sympy as sp

import lagrangian as lg



def chain() -> lg.Model:
    """The chain, unit masses and stiffnesses."""
    m = lg.Model("two-mass chain")
    m.add("mass", "m1", "a", m=1.0)
    m.add("mass", "m2", "b", m=1.0)
    m.add("spring", "k1", ("ground", "a"), k=1.0)
    m.add("spring", "k2", ("a", "b"), k=1.0)
    return m


m = chain()
print(m.describe())

q = [sp.Symbol(f"q_{n}", real=True) for n in m.coordinate_names]
M = np.array(m.eq.M, dtype=float)
K = -np.array(m.eq.f.jacobian(q), dtype=float)
w2, modes = scipy.linalg.eigh(K, M)
print("normal-mode frequencies:", np.sqrt(w2), "(closed form: sqrt((3 ∓ √5)/2) =",
      np.sqrt((3 - np.sqrt(5)) / 2), np.sqrt((3 + np.sqrt(5)) / 2), ")")
slow = modes[:, 0] / modes[0, 0]
res = m.simulate(20, initial=dict(zip(m.coordinate_names, 0.1 * slow)), velocity={"x_a": 0, "x_b": 0})
exact = 0.1 * np.cos(np.sqrt(w2[0]) * res.t)
print(f"started in the slow mode: max |x_a − 0.1 cos(ω₁t)| = {np.max(np.abs(res['x_a'] - exact)):.2e}")
