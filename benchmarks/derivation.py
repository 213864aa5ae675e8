"""Deriving the equations of motion: this library against sympy.physics.mechanics.

Model: the planar n-link pendulum — point masses on massless rods, absolute
angles, gravity, every parameter symbolic: a mass ``m_k`` and a length
``l_k`` per link and ``g`` (the peer figures of ``reference/peer-performance.md``
are for these: their operation counts are reproduced); ``--shared`` uses one
``m`` and one ``l``.

- **ours**: ``lg.Model(dim=2)`` with, per link, a ``link`` with a point
  ``end``, a ``revolute`` joint (``absolute=True``; at the previous link's
  ``end``) and a ``mass`` on ``"<link>.end"``, plus ``gravity``; timed from
  the model's construction to its equations (``model.eq``: ``M`` and ``f`` of
  ``M q̈ = f`` and the solve ``A u = b``), assembly included.
- **Kane**: ``KanesMethod`` (frames oriented on N by ``q_k``, ``u_k = q̇_k``,
  ``v2pt_theory``), timed to ``mass_matrix_full`` and ``forcing_full``.
- **Lagrange**: ``LagrangesMethod`` on ``Lagrangian(N, *particles)``, timed to
  ``mass_matrix_full`` and ``forcing_full``.

Operation counts (``sympy.count_ops``) are of the n × n mass matrix plus the
n-vector forcing: ours ``M`` and ``f``; Kane's and Lagrange's ``mass_matrix``
and ``forcing`` (their ``_full`` forms add the kinematic rows ``q̇ = u``).  The
three sets of equations are checked against each other at a random state.

Every timing runs in a fresh process (``--repeat`` of them, the median
reported) after the same imports in each — ``sympy``,
``sympy.physics.mechanics`` and ``lagrangian`` with its plugins loaded — so
that one-time import costs fall outside all three timings alike.

Run: ``.venv/bin/python benchmarks/derivation.py [--repeat 5] [--sizes 2,4,6,8,10] [--shared]``.
The last line is a JSON object.
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import time


# -- the three derivations (run in a child process) ----------------------------------------------


def parameters(n: int, shared: bool):
    import sympy as sp

    if shared:
        m, l = sp.symbols("m l")
        return [m] * n, [l] * n, sp.Symbol("g")
    return list(sp.symbols(f"m:{n}")), list(sp.symbols(f"l:{n}")), sp.Symbol("g")


def ours(n: int, shared: bool):
    import lagrangian as lg

    m, l, g = parameters(n, shared)
    model = lg.Model(f"{n}-link pendulum", dim=2)
    parent = "ground"
    for k in range(n):
        model.add("link", f"L{k}", f"L{k}", points={"end": (l[k], 0)})
        model.add("revolute", f"j{k}", (parent, f"L{k}"), absolute=True,
                  **({"parent_point": (l[k - 1], 0)} if k else {}))
        model.add("mass", f"m{k}", f"L{k}.end", m=m[k])
        parent = f"L{k}"
    model.add("gravity", "g", g=g)
    eq = model.eq
    return model, eq.M, eq.f


def kane(n: int, shared: bool):
    import sympy.physics.mechanics as me

    m, l, g = parameters(n, shared)
    q, u = me.dynamicsymbols(f"q:{n}"), me.dynamicsymbols(f"u:{n}")
    N = me.ReferenceFrame("N")
    O = me.Point("O")
    O.set_vel(N, 0)
    particles, loads, kd, P = [], [], [], O
    for k in range(n):
        A = N.orientnew(f"A{k}", "Axis", [q[k], N.z])
        A.set_ang_vel(N, u[k] * N.z)
        Pk = P.locatenew(f"P{k}", l[k] * A.x)
        Pk.v2pt_theory(P, N, A)
        particles.append(me.Particle(f"pa{k}", Pk, m[k]))
        loads.append((Pk, -m[k] * g * N.y))
        kd.append(q[k].diff() - u[k])
        P = Pk
    km = me.KanesMethod(N, q_ind=q, u_ind=u, kd_eqs=kd)
    km.kanes_equations(particles, loads)
    km.mass_matrix_full, km.forcing_full  # noqa: B018 - what is timed
    return km, km.mass_matrix, km.forcing


def lagrange(n: int, shared: bool):
    import sympy.physics.mechanics as me

    m, l, g = parameters(n, shared)
    q = me.dynamicsymbols(f"q:{n}")
    N = me.ReferenceFrame("N")
    O = me.Point("O")
    O.set_vel(N, 0)
    particles, P = [], O
    for k in range(n):
        A = N.orientnew(f"A{k}", "Axis", [q[k], N.z])
        Pk = P.locatenew(f"P{k}", l[k] * A.x)
        Pk.v2pt_theory(P, N, A)
        pa = me.Particle(f"pa{k}", Pk, m[k])
        pa.potential_energy = m[k] * g * Pk.pos_from(O).dot(N.y)
        particles.append(pa)
        P = Pk
    lm = me.LagrangesMethod(me.Lagrangian(N, *particles), q, frame=N)
    lm.form_lagranges_equations()
    lm.mass_matrix_full, lm.forcing_full  # noqa: B018 - what is timed
    return lm, lm.mass_matrix, lm.forcing


METHODS = {"ours": ours, "kane": kane, "lagrange": lagrange}


def child(method: str, n: int, shared: bool, check: bool) -> dict:
    import sympy as sp
    import sympy.physics.mechanics  # noqa: F401 - the same imports for every method

    import lagrangian as lg

    lg.default_registry()  # plugin discovery: part of importing the library
    start = time.perf_counter()
    obj, M, f = METHODS[method](n, shared)
    seconds = time.perf_counter() - start
    out = {"method": method, "n": n, "seconds": seconds, "ops": int(sp.count_ops(M) + sp.count_ops(f))}
    if method == "ours":
        start = time.perf_counter()
        obj.mass_matrix, obj.forcing  # noqa: B018 - in terms of q(t), as the peers give them
        out["display_s"] = time.perf_counter() - start
    if check:
        out["values"] = values(method, obj, M, f, n, shared)
    return out


def values(method, obj, M, f, n, shared) -> list[float]:
    """``M`` and ``f`` (flattened) at one random state, in our coordinate order."""
    import random

    import sympy as sp
    import sympy.physics.mechanics as me

    rng = random.Random(7)
    m, l, g = parameters(n, shared)
    params = {s: sp.Float(rng.uniform(0.5, 1.5), 30) for s in sorted({*m, *l, g}, key=str)}
    qv = [sp.Float(rng.uniform(-3, 3), 30) for _ in range(n)]
    vv = [sp.Float(rng.uniform(-2, 2), 30) for _ in range(n)]
    if method == "ours":
        eq = obj.eq
        subs = {**params, **dict(zip(eq.sym.q, qv)), **dict(zip(eq.sym.v, vv))}
    else:
        q, u = me.dynamicsymbols(f"q:{n}"), me.dynamicsymbols(f"u:{n}")
        subs = {**params, **{qi.diff(): x for qi, x in zip(q, vv)}, **dict(zip(u, vv)), **dict(zip(q, qv))}
        M, f = M.subs(subs), f.subs(subs)
    return [float(e.xreplace(subs).evalf(30)) for e in [*M, *f]]


# -- the driver ------------------------------------------------------------------------------------


def run(method: str, n: int, shared: bool, check: bool) -> dict:
    cmd = [sys.executable, __file__, "--child", method, str(n)] + (["--shared"] if shared else []) + (["--check"] if check else [])
    proc = subprocess.run(cmd, capture_output=True, text=True, check=False)
    if proc.returncode:
        raise SystemExit(f"{method} n={n} failed:\n{proc.stderr}")
    return json.loads(proc.stdout.strip().splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="2,4,6,8,10")
    ap.add_argument("--repeat", type=int, default=5, help="fresh processes per timing (median); Lagrange: at most 3")
    ap.add_argument("--shared", action="store_true", help="one m and one l for every link")
    ap.add_argument("--child", nargs=2, metavar=("METHOD", "N"), help=argparse.SUPPRESS)
    ap.add_argument("--check", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        print(json.dumps(child(args.child[0], int(args.child[1]), args.shared, args.check)))
        return
    sizes = [int(s) for s in args.sizes.split(",")]
    print(f"planar n-link pendulum, symbolic {'m, l' if args.shared else 'm_k, l_k'}, g; median of fresh processes "
          f"(ours, Kane: {args.repeat}; Lagrange: {min(args.repeat, 3)})")
    print("ours: model construction → model.eq (M, f, A, b); Kane, Lagrange: → mass_matrix_full, forcing_full")
    header = (f"{'n':>3} {'ours s':>9} {'Kane s':>9} {'Lagrange s':>11} {'Kane/ours':>10} {'Lagr/ours':>10} "
              f"{'ops ours':>9} {'ops Kane':>9} {'ops Lagr':>9} {'display s':>10} {'max rel diff':>13}")
    print(header)
    last = None
    for n in sizes:
        rows = {}
        for method in METHODS:
            reps = args.repeat if method != "lagrange" else min(args.repeat, 3)
            runs = [run(method, n, args.shared, check=(k == 0)) for k in range(reps)]
            rows[method] = {
                "seconds": statistics.median(r["seconds"] for r in runs),
                "ops": runs[0]["ops"],
                "values": runs[0]["values"],
                "display_s": statistics.median(r.get("display_s", 0.0) for r in runs),
            }
        ref = rows["kane"]["values"]
        scale = max(1.0, max(abs(x) for x in ref))
        diff = max(abs(a - b) for method in ("ours", "lagrange") for a, b in zip(rows[method]["values"], ref)) / scale
        o, k, lgr = (rows[m]["seconds"] for m in METHODS)
        print(f"{n:>3} {o:>9.4f} {k:>9.4f} {lgr:>11.4f} {k / o:>10.1f} {lgr / o:>10.1f} {rows['ours']['ops']:>9} "
              f"{rows['kane']['ops']:>9} {rows['lagrange']['ops']:>9} {rows['ours']['display_s']:>10.4f} {diff:>13.1e}")
        last = {"n": n, "ours_s": round(o, 5), "kane_s": round(k, 5), "lagrange_s": round(lgr, 5),
                "kane_over_ours": round(k / o, 2), "lagrange_over_ours": round(lgr / o, 2),
                "ops_ours": rows["ours"]["ops"], "ops_kane": rows["kane"]["ops"], "ops_lagrange": rows["lagrange"]["ops"]}
    print(json.dumps(last))


if __name__ == "__main__":
    main()
