"""A model using a third-party component: the cubic (Duffing) spring plugin.
=========================================================================

The kind ``cubic_spring`` comes from the separate distribution in
examples/plugins/cubic-spring, found through its entry point. Prints the
plugin table, the Lagrangian, and the amplitude-dependent period against
the quadrature T = 4 ∫₀ᴬ dx / √(2(V(A) − V(x))/m).
Run: .venv/bin/python examples/duffing_plugin.py
"""

import numpy as np
from scipy.integrate import quad

import lagrangian as lg

print(lg.default_registry().describe())
k, k3, mass = 1.0, 0.5, 1.0


def duffing() -> lg.Model:
    """A mass on the plugin's cubic spring."""
    m = lg.Model("duffing")
    m.add("mass", "m", "p", m=mass)
    m.add("cubic_spring", "s", ("ground", "p"), k=k, k3=k3)
    return m


m = duffing()
print(m.describe())
for A in (0.1, 1.0, 2.0):
    V = lambda x: k * x**2 / 2 + k3 * x**4 / 4  # noqa: E731
    period = 4 * quad(lambda th: A * np.cos(th) / np.sqrt(2 * (V(A) - V(A * np.sin(th))) / mass), 0, np.pi / 2)[0]
    res = m.simulate(3 * period, initial={"x_p": A}, velocity={"x_p": 0}, points=30001)
    x = res["x_p"]
    ups = np.where((x[:-1] < 0) & (x[1:] >= 0))[0]
    crossings = res.t[ups] - x[ups] * (res.t[ups + 1] - res.t[ups]) / (x[ups + 1] - x[ups])
    print(f"A = {A}: period simulated {np.diff(crossings).mean():.6f}, quadrature {period:.6f}")
