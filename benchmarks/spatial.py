"""Spatial chains on spherical joints: our equations and runs against sympy.physics.mechanics' KanesMethod and PyDy.

Model: ``n`` rigid bodies hanging from one another on spherical joints (body-fixed x-y-z angles), each of mass
0.3 + 0.1 k kg, principal moments (0.02, 0.03, 0.04) kg m², centre of mass 0.25 m below its joint, the next joint
0.5 m below; gravity 9.81 m/s².  The peer is the same chain written for ``KanesMethod`` as its users write it
(frames oriented ``"Body"``, ``v2pt_theory``, generalized speeds ``u = q̇``), so that both solve the same ODE in
the same state.

- ``ops``: instructions of the straight-line program (:func:`lagrangian.tape.size`) computing the mass matrix and
  the forcing, every common subexpression once: ours against Kane's ``mass_matrix`` and ``forcing``.
- ``speed``: CPU time of a warm 5 s run at rtol = atol = 1e-8 from a tilted, spinning state, 501 points: PyDy's
  ``System.integrate`` with the ``cython`` generator (its default integrator, ``odeint``), after a first call,
  against ``Model.simulate`` with every option at its default, after a first call with ``compiled="native"``
  (the model's C library then in the cache, as on any later run; the default ``compiled="auto"`` takes it).
  The same run on the tape interpreter (nothing compiled for the model) is reported beside it.  Both peers'
  runs are checked against each other.

Run alone: ``.venv/bin/python benchmarks/spatial.py [--bodies 3]``; ``benchmarks/scale.py`` reports its ratios.
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np

G = 9.81
RTOL = 1e-8
SPAN = 5.0


def mass(k: int) -> float:
    return round(0.3 + 0.1 * k, 10)


def ours(n: int, dynamics: str = "auto"):
    import lagrangian as lg

    m = lg.Model(f"{n}-body spatial chain", dim=3, dynamics=dynamics)
    parent = "ground"
    for k in range(n):
        m.add("body", f"B{k}", f"B{k}", m=mass(k), inertia=(0.02, 0.03, 0.04), com=(0, 0, -0.25),
              points={"tip": (0, 0, -0.5)})
        m.add("spherical", f"j{k}", (parent, f"B{k}"), **({"parent_point": (0, 0, -0.5)} if k else {}))
        parent = f"B{k}"
    m.add("gravity", "g", g=G)
    return m


def kane(n: int):
    """The same chain for KanesMethod: numbers in the expressions as ours has them, but for the symbol ``g``
    (PyDy's generated code needs at least one constant)."""
    import sympy as sp
    import sympy.physics.mechanics as me

    g = sp.Symbol("g")
    N = me.ReferenceFrame("N")
    O = me.Point("O")
    O.set_vel(N, 0)
    q = me.dynamicsymbols(f"q:{3 * n}")
    u = me.dynamicsymbols(f"u:{3 * n}")
    bodies, loads = [], []
    P, F = O, N
    for k in range(n):
        A = F.orientnew(f"A{k}", "Body", q[3 * k:3 * k + 3], "xyz")
        Gk = P.locatenew(f"G{k}", -0.25 * A.z)
        Gk.v2pt_theory(P, N, A)
        bodies.append(me.RigidBody(f"b{k}", Gk, A, mass(k), (me.inertia(A, 0.02, 0.03, 0.04), Gk)))
        loads.append((Gk, -mass(k) * g * N.z))
        Pn = P.locatenew(f"P{k}", -0.5 * A.z)
        Pn.v2pt_theory(P, N, A)
        P, F = Pn, A
    km = me.KanesMethod(N, q, u, kd_eqs=[qi.diff() - ui for qi, ui in zip(q, u)])
    km.kanes_equations(bodies, loads)
    return km, g


def initial(n: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(7)
    return rng.uniform(-0.6, 0.6, 3 * n), rng.uniform(-1.0, 1.0, 3 * n)


def ops(n: int) -> dict:
    from lagrangian.tape import size

    start = time.process_time()
    model = ours(n)
    M, f = model.mass_matrix, model.forcing
    ours_s = time.process_time() - start
    start = time.process_time()
    km, g = kane(n)
    Mk, fk = km.mass_matrix.subs(g, G), km.forcing.subs(g, G)
    kane_s = time.process_time() - start
    mine, theirs = size(list(M) + list(f)), size(list(Mk) + list(fk))
    return {"ours_ops": mine, "kane_ops": theirs, "ops_ratio": mine / theirs, "ours_derive_s": ours_s,
            "kane_derive_s": kane_s}


def speed(n: int) -> dict:
    from pydy.system import System

    q0, u0 = initial(n)
    times = np.linspace(0.0, SPAN, 501)
    model = ours(n)
    names = [c.name for c in model.coordinates]
    init = dict(zip(names, q0))
    vel = dict(zip(names, u0))

    def run_ours(**kw):
        start = time.process_time()
        out = model.simulate(SPAN, initial=init, velocity=vel, rtol=RTOL, atol=RTOL, points=501, **kw)
        return out, time.process_time() - start

    run_ours(compiled="tape")
    _, tape_s = run_ours(compiled="tape")
    run_ours(compiled="native")
    res, ours_s = run_ours()
    km, g = kane(n)
    system = System(km, constants={g: G}, times=times, initial_conditions=dict(zip([*km.q, *km.u], [*q0, *u0])))
    system.generate_ode_function(generator="cython")
    system.integrate(rtol=RTOL, atol=RTOL)
    start = time.process_time()
    Y = system.integrate(rtol=RTOL, atol=RTOL)
    pydy_s = time.process_time() - start
    ours_q = np.array([res[name] for name in names]).T
    difference = float(np.abs(ours_q - Y[:, :3 * n]).max())
    return {"ours_s": ours_s, "ours_tape_s": tape_s, "pydy_cython_s": pydy_s, "speed_ratio": pydy_s / ours_s,
            "speed_ratio_tape": pydy_s / tape_s, "max_difference": difference, "method": res.method,
            "evaluated_by": res.notes[0]}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--bodies", type=int, default=3)
    args = parser.parse_args()
    out = {"bodies": args.bodies, **ops(args.bodies)}
    try:
        out.update(speed(args.bodies))
    except ImportError as exc:
        out.update(speed_ratio=None, reason=f"pydy/cython not installed ({exc}): pip install -e '.[bench]'")
    print(json.dumps(out))


if __name__ == "__main__":
    main()
