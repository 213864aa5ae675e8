"""Fuzzing: untrusted text never runs, and bad input gets the project's own errors.

Each case is drawn from a seeded generator of structured random input
(``random.Random`` seeded with ``"<seed>:<index>"``, so a case is
reproduced from its seed and index alone) in one of four families:

- ``model``: a model built through the public API (``Model(name, **options)``
  and ``model.add(kind, name, nodes, **params)``), starting from the example
  of a registered kind (its own ``example()`` and context) and mutated:
  component and node names with C, SPICE, shell and Python metacharacters
  and payloads, parameters across decades, zero, negative, infinite, NaN,
  huge, as expression text, garbage text or code, wrong shapes, kinds, arities
  and options.  Then the outputs that turn names and values into text or
  code: the equations, ``describe()``/``latex()``, short simulations (NumPy,
  the tape, native C now and then, the exact solution), ``Result.quantity``,
  the analogy mapping (``map_model``, ``Mapped.initial``,
  ``Mapped.to_source``), the SPICE netlist writer (``spice.netlist``) and,
  rarely, ``compare_with_ngspice``.
- ``netlist``: ``read_netlist`` on SPICE decks mutated
  line by line and token by token (deleted, duplicated, swapped; numbers
  with SPICE suffixes; ``.control``/``shell`` blocks, ``{python}``
  expressions, metacharacters, very long lines), then a short run of what
  was read, its netlist written back and read again, and rarely that
  netlist run in ngspice.
- ``sizes``: sizes and exponents input can ask for: frequency grids
  (``frequency.decades``, ``frequency.sweep``, a netlist's ``.ac`` line)
  with counts over decades up to 1e15 and non-counts, unit strings with
  towers of powers and numbers beyond a float (through ``add``,
  ``initial`` and ``params``), netlists of up to 250,000 elements.
- ``signal``: expression text from a small grammar (known and unknown
  functions, singular points, huge numbers, payloads) read by
  ``lagrangian.text`` and used as a force or source in a short run and a
  SPICE netlist.

A case ends in success, a ``LagrangianError`` (or a warning): correct.
Any other exception is an *unexpected exception*; a case still running
after ``--limit`` seconds is a *hang*; a worker process that dies is a
crash (counted with the unexpected exceptions).  Every payload tries to
create the marker file ``<workdir>/EXECUTED-<index>``; the markers found
after the run are ``executed``, which must be 0.

Prints a table by family, the first failures (type, message, last frame
and the library frame it came from, and how to replay it) and, as its last
line, a JSON object ``{"cases": …, "unexpected_exceptions": …, "hangs": …,
"executed": …, ...}``.

Workers run in processes (``--jobs``; a case that crashes its worker or
cannot be interrupted is run again alone and reported); compiled code goes
to a private cache in the run's work directory, removed at the end.
``--light`` leaves out native compilation and ngspice.

Run: .venv/bin/python benchmarks/fuzz.py --cases 20000 [--jobs 2] [--seed 0]
Replay: .venv/bin/python benchmarks/fuzz.py --seed 0 --replay-case 123 [--traceback] [--shrink]
        .venv/bin/python benchmarks/fuzz.py --replay '<case JSON>' (or @file.json)
``--shrink`` reduces a failing case greedily to a smaller one with the same
failure (type and library frame).
"""

from __future__ import annotations

import argparse
import json
import logging
import math
import os
import random
import shutil
import signal
import sys
import tempfile
import threading
import time
import traceback
import warnings
from collections import Counter, defaultdict
from concurrent.futures import ProcessPoolExecutor, as_completed
from concurrent.futures.process import BrokenProcessPool
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent

#: Where each library module lives (the package's layout first, then the flat one it had).
MODULES = {
    "spice": ("lagrangian.circuits.spice", "lagrangian.spice"),
    "netlist": ("lagrangian.circuits.netlist", "lagrangian.netlist"),
    "analogy": ("lagrangian.circuits.analogy", "lagrangian.analogy"),
    "compare": ("lagrangian.circuits.compare", "lagrangian.compare"),
    "text": ("lagrangian.base.text", "lagrangian.text"),
    "codegen": ("lagrangian.numerics.codegen", "lagrangian.codegen"),
}


def lib(name: str):
    """The library module ``name`` (``"spice"``, ``"netlist"``, ...), wherever the package keeps it."""
    import importlib

    for candidate in MODULES[name]:
        try:
            return importlib.import_module(candidate)
        except ModuleNotFoundError as exc:
            if exc.name is None or not candidate.startswith(exc.name):
                raise
    raise ModuleNotFoundError(f"no module of the library provides {name!r} (tried {', '.join(MODULES[name])})")


FAMILIES = ("model", "netlist", "signal", "sizes")
WEIGHTS = (0.5, 0.3, 0.12, 0.08)

# --------------------------------------------------------------------------------------------------
# Untrusted text: metacharacters and payloads.  ``M`` is the marker path each payload tries to create.
# --------------------------------------------------------------------------------------------------


def python_payloads(m: str) -> list[str]:
    return [
        f"__import__('os').system('touch {m}')",
        f"open('{m}', 'w')",
        f"exec(\"open('{m}', 'w')\")",
        f"eval(\"__import__('os').system('touch {m}')\")",
        f"(lambda: __import__('os').system('touch {m}'))()",
        f"sin.__globals__['__builtins__']['open']('{m}', 'w')",
        f"[c for c in ().__class__.__base__.__subclasses__() if c.__name__ == 'Popen'][0](['touch', '{m}'])",
        f"x); __import__('os').system('touch {m}'); (",
        f"x\n__import__('os').system('touch {m}')\n",
        f"1 if __import__('os').system('touch {m}') else 2",
        f"k*__import__('os').system('touch {m}')",
        f"Symbol('x').__class__.__init__.__globals__['os'].system('touch {m}')",
    ]


def c_payloads(m: str) -> list[str]:
    return [
        f'p */ __attribute__((constructor)) static void x(void) {{ system("touch {m}"); }} /* \\\n#define q',
        f'*/\n#include <stdlib.h>\nstatic void __attribute__((constructor)) f(void) {{ system("touch {m}"); }}\n/*',
        f'a \\\nsystem("touch {m}");',
        f'??/\nstatic void __attribute__((constructor)) g(void) {{ system("touch {m}"); }}',
        f'"; }} __attribute__((constructor)) void h(void) {{ system("touch {m}"); }} //',
        f"*/ int lg_dims(int *o) {{ system(\"touch {m}\"); return 0; }} /*",
        f'// \\\n__attribute__((constructor)) void k(void) {{ system("touch {m}"); }}',
        '#include "/etc/passwd"',
    ]


def spice_payloads(m: str) -> list[str]:
    return [
        f"\n.control\nshell touch {m}\n.endc\n",
        f"x\r.control\rshell touch {m}\r.endc\r",
        f"n1\n.control\nshell touch {m}\n.endc\n* ",
        f" 0 1\n.control\nshell touch {m}\n.endc",
        f"\n.include {m}\n",
        f"\n.exec shell touch {m}\n",
        f"\nB1 x 0 V=shell('touch {m}')\n",
    ]


def shell_payloads(m: str) -> list[str]:
    return [f"$(touch {m})", f"`touch {m}`", f"; touch {m};", f"| touch {m}", f"&& touch {m}", f"' ; touch {m} ; '"]


METACHARACTERS = [
    "*/", "/*", "//", "\\", "\\\n", "\n", "\r", "\r\n", "\t", " ", "#include", "#define", "??/", "%s", "%n",
    "{", "}", "{0}", "{ref0}", "{tag}", "{0.__class__}", "{sense1}", ";", "$", "$(", "`", "'", '"', "|", "&",
    "\x00", "\x1b[2J", "\u202e", "\ufeff", "ñ", "İ", "ß", "∂", "𝑥", "→", "中文", "~", "~x", ".", "..", "a.b",
    ".control", ".endc", ".end", "*", "+", "=", "(", ")", ",", "-", "0", "gnd", "GND", "ground", "Ground",
    "time", "t", "pi", "E", "I", "S", "N", "O", "Q", "oo", "nan", "lambda", "None", "True", "__class__",
    "__import__", "x_p", "q_L", "1e3", "-1", "v(0)", "@", "\x7f", "\u0301",
]


def _identifier(rng: random.Random) -> str:
    first = "abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ_"
    rest = first + "0123456789"
    return rng.choice(first) + "".join(rng.choice(rest) for _ in range(rng.randint(0, 7)))


def payload(rng: random.Random, m: str, kinds: tuple[str, ...] = ("python", "c", "spice", "shell")) -> str:
    kind = rng.choice(kinds)
    pool = {"python": python_payloads, "c": c_payloads, "spice": spice_payloads, "shell": shell_payloads}[kind](m)
    return rng.choice(pool)


def name_text(rng: random.Random, m: str) -> str:
    """A name as a user, a file or a colleague might give it: plain, odd, or hostile."""
    r = rng.random()
    if r < 0.3:
        return _identifier(rng)
    if r < 0.5:
        return "".join(rng.choice(METACHARACTERS) for _ in range(rng.randint(1, 4)))
    if r < 0.8:
        return rng.choice(["", _identifier(rng)]) + payload(rng, m) + rng.choice(["", " ", "\n", _identifier(rng)])
    if r < 0.9:
        return _identifier(rng) + rng.choice(METACHARACTERS) + _identifier(rng)
    if r < 0.95:
        return rng.choice(METACHARACTERS) * rng.randint(100, 5000)
    return _identifier(rng) * rng.randint(200, 2000)


# --------------------------------------------------------------------------------------------------
# Values
# --------------------------------------------------------------------------------------------------

SPECIAL_NUMBERS = [0, 0.0, -0.0, 1, -1, 2, 1e-300, -1e-300, 5e-324, 1e-12, 1e12, 1e150, 1.0000001e150, -1e150,
                   1e300, 1e308, -1e308, math.inf, -math.inf, math.nan, 10**400, -(10**400), 2**63, 0.5, 1 / 3]
EXPRESSION_TEXT = [
    "2*k", "1/2", "3e-3", "0.3", "-1", "0", "k", "k**2", "pi", "2*pi", "sin(2*t)", "0.5*cos(3*t)", "exp(-t)",
    "Heaviside(t - 0.1)", "sqrt(2)", "sqrt(-1)", "1/0", "0/0", "0**0", "0**-1", "log(0)", "ln(-1)", "9**9**9",
    "2**1024", "2.0**1024", "10**308*10", "1e308*10", "1e999", "(1", "1 +", "", " ", "t", "x_p", "I", "E", "oo",
    "zoo", "nan", "inf", "Max(t, 1)", "min(1, 2)", "atan2(1, 0)", "atan2(0, 0)", "floor(t)", "sign(t)",
    "Abs(t - 0.5)", "tan(pi/2)", "acosh(0)", "erf(t)", "1/t", "t**-1", "sin(1/t)", "exp(1000)", "exp(t*1e6)",
    "cosh(800)", "k*x_p", "m_m", "tau", "1e-320", "-(-(-1))", "+-+1", "((((((((((1))))))))))", "1" * 400,
    "(" * 250 + "1" + ")" * 250, "sin(" * 100 + "t" + ")" * 100, "t" + "*t" * 300, "2" + "**2" * 60,
    "\u00b2", "１", "٣", "1_000", "0x10", "1j", "True", "None", "[1, 2]", "{1: 2}", "'1'", "b'1'", "f'{1}'",
    "...", "x.y", "x[0]", "x(1)", "sin(t, 1)", "sin()", "sin(*[t])", "sin(x=t)", "lambda: 1", "x := 1",
    "Piecewise((1, t < 1), (0, True))", "DiracDelta(t)", "Integral(t, t)", "Symbol('x')", "S(1)/3",
    "exp(t)**exp(t)", "t**t", "t**0.5", "(-1)**t", "(-8)**(1/3)", "pi**pi**pi", "cos(t)**2 + sin(t)**2 - 1",
]


def number(rng: random.Random, base: float | None = None) -> Any:
    if base is not None and rng.random() < 0.6:
        base = base if abs(base) < 1e300 else 1.0
        scale = 10 ** rng.uniform(-4, 4)
        value = base * scale if base else scale * rng.choice([1, -1])
        return float(f"{value:.3g}")
    if rng.random() < 0.5:
        return rng.choice(SPECIAL_NUMBERS)
    return float(f"{rng.choice([1, -1]) * 10 ** rng.uniform(-320, 308):.3g}")


def value(rng: random.Random, m: str, base: Any = None) -> Any:
    """A parameter value: a number near the example's, an odd number, text, a payload, a wrong shape."""
    numeric = base if isinstance(base, (int, float)) and not isinstance(base, bool) else None
    r = rng.random()
    if r < 0.35:
        return number(rng, numeric if numeric is not None else 1.0)
    if r < 0.55:
        return rng.choice(EXPRESSION_TEXT)
    if r < 0.7:
        return payload(rng, m, ("python",)) if rng.random() < 0.8 else payload(rng, m)
    if r < 0.75:
        return "".join(rng.choice(METACHARACTERS + list("0123456789+-*/().e")) for _ in range(rng.randint(1, 12)))
    if r < 0.8:
        return {"$symbol": rng.choice(["k", "m", "x_p", "t", "E", "I", name_text(rng, m)]),
                "assumptions": rng.choice([{}, {"positive": True}, {"real": True}, {"negative": True}])}
    if r < 0.83:
        return {"$sympy": rng.choice(["sin(t)", "t/2", "exp(-t)*cos(3*t)", "Heaviside(t - 0.5)", "1/(t + 1)", "t**3",
                                      "Max(t, 0.5)", "floor(4*t)", "sign(sin(7*t))", "sqrt(t)", "log(t + 1)"])}
    if r < 0.85:
        return {"$callable": rng.choice([0.5, 0.0, -1e3, math.nan, math.inf, "raise", "text", "array"])}
    if r < 0.93:  # shapes: vectors, matrices, mappings
        n = rng.randint(0, 4)
        vec = [number(rng, 1.0) if rng.random() < 0.8 else rng.choice(EXPRESSION_TEXT + python_payloads(m))
               for _ in range(n)]
        return rng.choice([vec, [vec, vec], [vec] * n, {name_text(rng, m): vec[:3] or [1, 0]}, {"tip": vec},
                           [[1, 0], [0]], [], [[]], {}, {"$tuple": vec}, {"$tuple": [payload(rng, m, ("python",))]},
                           {payload(rng, m, ("python",)): 1}, {"$tuple": [vec[:2], vec[:2]]}])
    return rng.choice([None, True, False, b"1".decode(), [None], {"a": None}, "1,2", "1 2", "1e3k", "10uF"])


# --------------------------------------------------------------------------------------------------
# Model cases
# --------------------------------------------------------------------------------------------------


def _jsonable(x: Any) -> Any:
    import sympy as sp

    if x is None or isinstance(x, (bool, int, float, str)):
        return x
    if isinstance(x, sp.MatrixBase):
        return _jsonable(x.tolist())
    if isinstance(x, sp.Basic):
        if x.is_Integer:
            return int(x)
        if x.is_Number:
            return float(x)
        return {"$sympy": sp.sstr(x)}
    if isinstance(x, dict):
        return {str(k): _jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_jsonable(v) for v in x]
    return repr(x)


_EXAMPLES: dict[str, dict] | None = None


def examples() -> dict[str, dict]:
    """Every registered kind's example as JSON-able data: ``{kind: {"options", "context", "main"}}``."""
    global _EXAMPLES
    if _EXAMPLES is None:
        from lagrangian import default_registry

        out = {}
        for kind, cls in sorted(default_registry().kinds.items()):
            ex = cls.example()
            out[kind] = {
                "options": _jsonable(dict(ex.options)),
                "context": [{"kind": k, "name": n, "nodes": _jsonable(nodes), "params": _jsonable(dict(p))}
                            for k, n, nodes, p in ex.context],
                "main": {"kind": kind, "name": kind[:1].upper() + "X", "nodes": _jsonable(ex.nodes),
                         "params": _jsonable(dict(ex.params))},
                "parameters": sorted(cls.parameters),
            }
        _EXAMPLES = out
    return _EXAMPLES


def _nodes_of(comps: list[dict]) -> list[str]:
    out = []
    for c in comps:
        nodes = c["nodes"] if isinstance(c["nodes"], list) else [c["nodes"]]
        for n in nodes:
            if isinstance(n, str) and n not in out and n.lower() not in ("ground", "gnd", "0", ""):
                out.append(n)
    return out


def _rename_node(comps: list[dict], old: str, new: str) -> None:
    """Rename ``old`` everywhere, points of a body (``old.point``) included."""

    def one(n):
        if n == old:
            return new
        if isinstance(n, str) and n.startswith(old + "."):
            return new + n[len(old):]
        return n

    for c in comps:
        c["nodes"] = [one(n) for n in c["nodes"]] if isinstance(c["nodes"], list) else one(c["nodes"])


def _rename_component(comps: list[dict], old: str, new: str) -> None:
    """Rename a component and every reference to it (a coupling names its inductors)."""
    for c in comps:
        if c["name"] == old:
            c["name"] = new
        for k, v in c["params"].items():
            if v == old:
                c["params"][k] = new


def draw_model(rng: random.Random, m: str, *, heavy: bool = True) -> dict:
    ex = examples()
    kinds = sorted(ex)
    kind = rng.choice(kinds)
    base = json.loads(json.dumps(ex[kind]))
    comps = base["context"] + [base["main"]]
    if rng.random() < 0.3:
        rng.shuffle(comps)
    options = base["options"]
    name = rng.choice(["model", kind]) if rng.random() < 0.5 else name_text(rng, m)
    # the values of every example across decades: most models stay valid, their outputs exercised
    for c in comps:
        for p, v in list(c["params"].items()):
            if isinstance(v, (int, float)) and not isinstance(v, bool) and rng.random() < 0.5:
                c["params"][p] = number(rng, v)
    # nasty names that keep the model whole: nodes and components renamed consistently
    if rng.random() < 0.6:
        nodes = _nodes_of(comps)
        for old in rng.sample(nodes, rng.randint(1, len(nodes))) if nodes else []:
            _rename_node(comps, old, name_text(rng, m))
    if rng.random() < 0.5:
        for c in rng.sample(comps, rng.randint(1, len(comps))):
            _rename_component(comps, c["name"], name_text(rng, m))
    for _ in range(rng.choice([0, 0, 0, 1, 1, 1, 2, 2, 3, 5])):
        op = rng.choice(["value", "value", "value", "extra", "drop", "kind", "add", "remove", "node", "arity",
                         "option", "duplicate", "name"])
        c = rng.choice(comps) if comps else None
        if c is None:
            break
        if op == "value":
            if c["params"]:
                p = rng.choice(sorted(c["params"]))
            else:
                p = rng.choice(ex.get(c["kind"], {}).get("parameters") or ["x"])
            c["params"][p] = value(rng, m, c["params"].get(p))
        elif op == "extra":
            c["params"][rng.choice([_identifier(rng), name_text(rng, m), "k", "m", "L", "C", "R"])] = value(rng, m)
        elif op == "drop" and c["params"]:
            del c["params"][rng.choice(sorted(c["params"]))]
        elif op == "kind":
            c["kind"] = rng.choice(kinds) if rng.random() < 0.8 else name_text(rng, m)
        elif op == "add" and len(comps) < 6:
            other = json.loads(json.dumps(ex[rng.choice(kinds)]["main"]))
            nodes = _nodes_of(comps) + ["ground", "0"]
            if isinstance(other["nodes"], list):
                other["nodes"] = [rng.choice(nodes) for _ in other["nodes"]]
            elif other["nodes"]:
                other["nodes"] = rng.choice(nodes)
            other["name"] = name_text(rng, m) if rng.random() < 0.5 else _identifier(rng)
            comps.append(other)
        elif op == "remove" and len(comps) > 1:
            comps.remove(c)
        elif op == "node":
            bad = rng.choice([name_text(rng, m), "", " ", None, 3, 1.5, True, [], ["a"], "ground", "0", "GND"])
            if isinstance(c["nodes"], list) and c["nodes"]:
                c["nodes"][rng.randrange(len(c["nodes"]))] = bad
            else:
                c["nodes"] = bad
        elif op == "arity":
            nodes = c["nodes"] if isinstance(c["nodes"], list) else [c["nodes"]]
            c["nodes"] = rng.choice([nodes + [rng.choice(nodes or ["p"])], nodes[:-1], [], "p", ["p", "p"]])
        elif op == "option":
            key = rng.choice(["dim", "formulation", name_text(rng, m)])
            options[key] = rng.choice([1, 2, 3, 0, 4, "2", 2.0, True, None, "charge", "flux", "Flux", name_text(rng, m)])
        elif op == "duplicate" and len(comps) > 1:
            c["name"] = rng.choice([o["name"] for o in comps if o is not c])
        elif op == "name":
            c["name"] = rng.choice([name_text(rng, m), "", None, 3, " "])
    actions = [{"do": "equations"}]
    if rng.random() < 0.2:
        actions.append({"do": "describe"})
    if rng.random() < 0.75:
        actions.append(draw_simulate(rng, m, heavy=heavy))
        if rng.random() < 0.4:
            actions.append({"do": "quantity", "text": quantity_text(rng, m)})
    if rng.random() < 0.15:
        actions.append({"do": "map", "analogy": rng.choice(["force-voltage", "force-current", "force-current",
                                                             name_text(rng, m)]),
                        "netlist": rng.random() < 0.6, "initial": {"$coord0": value(rng, m, 0.1)},
                        "to_source": quantity_text(rng, m)})
    if rng.random() < 0.4:
        actions.append(draw_netlist_action(rng, m))
    if heavy and rng.random() < 0.015:
        actions.append({"do": "ngspice", "t_end": rng.choice([0.01, 0.1, 0.5]),
                        "analogy": rng.choice([None, "force-voltage", "force-current"]),
                        "initial": {"$coord0": number(rng, 0.1)}})
    return {"family": "model", "marker": m, "name": name, "options": options, "components": comps, "actions": actions}


METHODS = ["DOP853", "DOP853", "RK45", "auto", "auto", "exact", "exact", "rk4", "Radau", "LSODA", "BDF", "RK23",
           "verlet", "implicit_midpoint", "gauss_legendre", "variational", "dopri5_c", "rk4_c", "verlet_c"]


def draw_simulate(rng: random.Random, m: str, *, heavy: bool = True) -> dict:
    native = heavy and rng.random() < 0.06
    method = rng.choice(METHODS) if rng.random() < 0.95 else rng.choice([name_text(rng, m), None, 3])
    t_end = float(f"{10 ** rng.uniform(-3, 0):.3g}")
    action = {"do": "simulate", "method": method,
              "compiled": True if native else rng.choice(["tape", "tape", "auto", False]),
              "t_end": t_end, "points": rng.randint(2, 11)}
    if rng.random() < 0.08:
        action["t_end"] = rng.choice([0, -1, math.nan, math.inf, "1", [0, 0.5], [0.5, 0], [0, 1, 2], name_text(rng, m)])
    if rng.random() < 0.05:
        action["points"] = rng.choice([0, 1, -5, 2.5, "3", None, 100000])
    if method in ("rk4", "verlet", "implicit_midpoint", "gauss_legendre", "variational", "rk4_c", "verlet_c"):
        action["step"] = t_end / rng.randint(5, 50)
        if rng.random() < 0.1:
            action["step"] = rng.choice([0, -1, math.nan, math.inf, 1e-12, "0.1"])
    elif rng.random() < 0.1:
        action[rng.choice(["rtol", "atol", "max_step"])] = rng.choice([0, -1, math.nan, math.inf, 1e-20, 1, "1e-6"])
    if rng.random() < 0.7:
        action["initial"] = {rng.choice(["$coord0", "$coord1", "$coord2"]): number(rng, 0.1)}
        if rng.random() < 0.2:
            action["initial"][rng.choice(["$coord0", name_text(rng, m)])] = value(rng, m, 0.1)
    if rng.random() < 0.4:
        action["velocity"] = {rng.choice(["$coord0", "$coord1"]): number(rng, 0.1)}
    if rng.random() < 0.2:
        action["params"] = {rng.choice(["$param0", "$param1", name_text(rng, m)]): value(rng, m, 1.0)}
    return action


def draw_netlist_action(rng: random.Random, m: str) -> dict:
    action = {"do": "netlist", "t_end": float(f"{10 ** rng.uniform(-3, 0):.3g}")}
    if rng.random() < 0.5:
        action["initial"] = {"$coord0": number(rng, 0.1)}
    if rng.random() < 0.1:
        action[rng.choice(["step", "max_step", "t_end"])] = rng.choice([0, -1, math.nan, math.inf, 1e-300, "1"])
    if rng.random() < 0.1:
        action["options"] = rng.choice([{"reltol": 1e-7}, {name_text(rng, m): 1}, {"abstol": value(rng, m, 1e-12)},
                                        {"reltol": math.nan}, {"abstol": payload(rng, m, ("python",))}])
    if rng.random() < 0.1:
        action["params"] = {"$param0": value(rng, m, 1.0)}
    return action


def quantity_text(rng: random.Random, m: str) -> Any:
    r = rng.random()
    if r < 0.3:
        return "$coord0"
    if r < 0.5:
        return "2*$coord0 + t"
    if r < 0.8:
        return rng.choice(EXPRESSION_TEXT)
    if r < 0.93:
        return payload(rng, m, ("python",))
    return rng.choice([None, 3, [1], {"x": 1}, {"$tuple": [payload(rng, m, ("python",))]},
                       {payload(rng, m, ("python",)): 1}, {"$tuple": ["$coord0", 1]}])


# --------------------------------------------------------------------------------------------------
# Netlist cases
# --------------------------------------------------------------------------------------------------

DECKS = [
    """5th-order Butterworth low-pass, 50 ohm, 1 kHz
* SIN(vo va freq td theta phase)
V1 in 0 SIN(0.1 1 800 0.25m 50 30)
Rs in n1 50
C1 n1 0 1.967u
L2 n1 n2 12.88mH ic=2m
C3 n2 0 6.366uF IC=0.2
L4 n2 n3 12.88m
+ ic=-1m            ; a continuation line
C5 n3 0 1.967u
RL n3 0 50
.options method=trap
.tran 10u 5m 0 2e-7 uic
.end
""",
    """voltage waveforms across resistors
V1 a 0 SIN(0.5 2 3 0.2 1.5 30)
R1 a 0 1
V2 b 0 PULSE(1 -2 0.1 0.05 0.1 0.2 0.5)
R2 b 0 1
V5 e 0 sin 0 1
R5 e 0 1
V6 f 0 pulse(0, 1, 0, 0, 0, 0.1, 0.25)
R6 f 0 1
V7 g 0 DC -1.5 AC 1
R7 g 0 1
.tran 10m 1 uic
.end
""",
    """current waveforms into resistors
I1 0 h PULSE(0 2 0.1 0.05 0.1 0.2 0.5)
R1 h 0 1
I2 k 0 SIN(0 1 2 0.1)
R2 k 0 1
.tran 10m 1 uic
.end
""",
    """
My Title Line
* a comment line
v1 IN 0 dc 5 ; an end-of-line comment
R1 in OUT
+ 2.2K
c1 out 0 10uF IC=1.5
R2 Out GND 1meg
.OPTIONS reltol=1e-4 method=gear noopiter
.TRAN 1u 1m 0 10n UIC
.end
Q9 nothing after .end is read
""",
    """free RLC decay
L1 a b 1 ic=0.5
C1 b 0 0.25 ic=1
R1 a 0 0.4
.tran 0.01 10 uic
.end
""",
    """.ic node voltages
R1 x 0 1
C1 x y 1
R2 y 0 1
C2 z 0 1 ic=0.5
R3 z 0 1
.ic v(x)=2 v(z)=3
.tran 0.01 1 uic
.end
""",
    """coupled tanks
L1 a 0 1m
C1 a 0 1u ic=1
L2 b 0 1m
C2 b 0 1u ic=0
K1 L1 L2 0.3
.tran 1u 1m uic
.end
""",
    """coupled coils
L1 x 0 1m
Ls a x 0.1m
C1 a 0 1u ic=1
L2 0 b 2m
C2 b 0 0.5u
Rl b 0 1k
K1 L1 L2 1
.tran 1u 1m 0 1e-7 uic
.end
""",
    """series RLC, capacitor charged to 1 V
V1 in 0 SIN(0 1 1k)
R1 in a 10
L1 a b 1m ic=0
C1 b 0 1u ic=1
.tran 10u 2m uic
.end
""",
    """RC divider
V1 in 0 PULSE(0 5 1m 1u 1u 2m 5m 3)
R1 in out 1k
C1 out 0 1u
R2 out 0 2k
.ic v(out)=1
.tran 10u 10m
.print tran v(out)
.end
""",
]

SUFFIXES = ["", "f", "p", "n", "u", "m", "k", "meg", "MEG", "Meg", "g", "t", "mil", "F", "H", "ohm", "uF", "x",
            "µ", "e", "E5", "k5", "megohm"]
MANTISSAS = ["0", "1", "-1", "+2", "1.5", ".5", "5.", "1e3", "1E-3", "1e308", "1e-320", "1e999", "-1e999", "1e",
             "--1", "1.2.3", "00001", "1" * 60, "0.000", "9" * 400, "nan", "inf", "1_0", "١", "0x1"]


def spice_number(rng: random.Random) -> str:
    return rng.choice(MANTISSAS) + rng.choice(SUFFIXES)


def spice_line(rng: random.Random, m: str) -> str:
    r = rng.random()
    nodes = ["0", "a", "b", "in", "out", "n1", "gnd", "GND", "ground", "x", "(", "=", name_text(rng, m)]
    if r < 0.4:
        letter = rng.choice("RLCVIKrlcvikDQXEBSTMabdefghjmnopqstuwxyz.*+;$")
        name = letter + rng.choice(["1", "2", "x", "", _identifier(rng), name_text(rng, m)])
        if letter in "Kk":
            body = f"{rng.choice(['L1', 'L2', 'Ls', 'l1', 'x'])} {rng.choice(['L1', 'L2', 'L4'])} {spice_number(rng)}"
        else:
            body = " ".join([rng.choice(nodes), rng.choice(nodes)] + [
                rng.choice([spice_number(rng), "ic=" + spice_number(rng), "IC", "=", "DC", "AC", "SIN(0 1 1k)",
                            f"PULSE({' '.join(spice_number(rng) for _ in range(rng.randint(0, 9)))})",
                            f"sin({spice_number(rng)}, {spice_number(rng)})", "PWL(0 0 1 1)", "EXP(0 1)",
                            "{1+1}", "'2*k'", f"{{__import__('os').system('touch {m}')}}", name_text(rng, m)])
                for _ in range(rng.randint(0, 4))])
        return f"{name} {body}"
    if r < 0.75:
        return rng.choice([
            f".tran {spice_number(rng)} {spice_number(rng)}" + rng.choice(["", " uic", f" {spice_number(rng)} uic",
                                                                          f" 0 {spice_number(rng)}", " UIC uic"]),
            f".ic v({rng.choice(nodes)})={spice_number(rng)}", ".ic v(a)", ".ic", ".ic v(0)=1", ".ic i(L1)=1",
            f".options {rng.choice(['reltol', 'method', name_text(rng, m)])}={spice_number(rng)}", ".options =",
            ".control", f"shell touch {m}", ".endc", f".include {m}", f".lib {m} x", ".param k=2", ".param x={1+1}",
            f".param p={{__import__('os').system('touch {m}')}}", ".end", ".ends", ".subckt x a b", ".model d D",
            ".op", ".ac dec 10 1 1k", ".print tran v(a)", ".save all", f".title {name_text(rng, m)}", ".title",
            ".func f(x) {x*2}", ".global gnd", ".temp 27", f".{_identifier(rng)}", ".", "..", ".TRAN 1u",
        ])
    if r < 0.85:
        return rng.choice(["+ ic=1", "+ 1k", "+", "* comment " + name_text(rng, m), "; comment", " $ x", "",
                           "   ", "\t", "\x00", "\r", "+ " + name_text(rng, m)])
    if r < 0.9:
        return "R9 a 0 " + " ".join(spice_number(rng) for _ in range(rng.randint(1000, 5000)))
    return name_text(rng, m)


def mutate_deck(rng: random.Random, text: str, m: str) -> str:
    lines = text.split("\n")
    for _ in range(rng.choice([0, 0, 1, 1, 1, 2, 2, 3, 4, 6, 10])):
        op = rng.choice(["delete", "duplicate", "swap", "insert", "insert", "token", "token", "token", "char",
                         "case", "long", "join"])
        i = rng.randrange(len(lines)) if lines else 0
        if op == "delete" and lines:
            del lines[i]
        elif op == "duplicate" and lines:
            lines.insert(i, lines[i])
        elif op == "swap" and len(lines) > 1:
            j = rng.randrange(len(lines))
            lines[i], lines[j] = lines[j], lines[i]
        elif op == "insert":
            lines.insert(i, spice_line(rng, m))
        elif op == "token" and lines:
            tokens = lines[i].split(" ")
            k = rng.randrange(len(tokens))
            how = rng.choice(["delete", "duplicate", "swap", "number", "number", "meta", "payload", "paren"])
            if how == "delete":
                del tokens[k]
            elif how == "duplicate":
                tokens.insert(k, tokens[k])
            elif how == "swap" and len(tokens) > 1:
                j = rng.randrange(len(tokens))
                tokens[k], tokens[j] = tokens[j], tokens[k]
            elif how == "number":
                tokens[k] = spice_number(rng)
            elif how == "meta":
                tokens[k] = rng.choice(METACHARACTERS)
            elif how == "payload":
                tokens[k] = rng.choice([f"{{{payload(rng, m, ('python',))}}}", payload(rng, m)])
            else:
                tokens.insert(k, rng.choice(["(", ")", "=", ",", "()", "(("]))
            lines[i] = " ".join(tokens)
        elif op == "char" and lines and lines[i]:
            k = rng.randrange(len(lines[i]) + 1)
            lines[i] = lines[i][:k] + rng.choice(METACHARACTERS) + lines[i][k:]
        elif op == "case" and lines:
            lines[i] = rng.choice([lines[i].upper(), lines[i].lower(), lines[i].swapcase()])
        elif op == "long":
            lines.insert(i, rng.choice(["*", "R1 a b ", "+ ", ""]) + "x" * rng.randint(10_000, 100_000))
        elif op == "join" and len(lines) > 1 and i + 1 < len(lines):
            lines[i:i + 2] = [lines[i] + rng.choice([" ", "", "\r"]) + lines[i + 1]]
    return "\n".join(lines)


def draw_netlist(rng: random.Random, m: str, *, heavy: bool = True) -> dict:
    deck = rng.randrange(len(DECKS))
    text = mutate_deck(rng, DECKS[deck], m)
    # the ladder's delayed sine in loop fluxes is integrated symbolically (seconds): drawn less often
    flux = (0.1 if heavy else 0.0) if deck == 0 else 0.5
    formulation = ("flux" if rng.random() < flux else "charge") if rng.random() < 0.95 else \
        rng.choice(["", "Flux", None, name_text(rng, m)])
    case = {"family": "netlist", "marker": m, "text": text, "formulation": formulation}
    if rng.random() < 0.1:
        case["name"] = name_text(rng, m)
    actions = []
    if rng.random() < 0.7:
        actions.append({"do": "run", "method": rng.choice(["auto", "auto", "exact", "DOP853", "Radau"]),
                        "compiled": rng.choice(["tape", "auto", False]), "short": rng.random() < 0.7})
        if rng.random() < 0.4:
            actions.append({"do": "probe", "element": rng.choice(["C1", "L1", "L2", "C3", "c1", "R1", name_text(rng, m)]),
                            "what": rng.choice(["capacitor_voltage", "inductor_current"])})
    if rng.random() < 0.5:
        actions.append({"do": "roundtrip", "read_back": rng.random() < 0.5,
                        "ngspice": heavy and rng.random() < 0.03})
    case["actions"] = actions
    return case


# --------------------------------------------------------------------------------------------------
# Signal cases: expression text from a grammar
# --------------------------------------------------------------------------------------------------

FUNCTION_NAMES = ["sin", "cos", "tan", "exp", "log", "ln", "sqrt", "Abs", "abs", "sign", "floor", "ceiling",
                  "Heaviside", "Min", "Max", "min", "max", "atan2", "asin", "acos", "acosh", "atanh", "erf", "erfc",
                  "cot", "sec", "csc", "sinh", "cosh", "tanh", "asinh", "atan",
                  "open", "eval", "exec", "__import__", "getattr", "Symbol", "Function", "sympify", "lambdify"]


def expression(rng: random.Random, m: str, depth: int = 0) -> str:
    r = rng.random()
    if depth >= 4 or r < 0.3:
        return rng.choice([spice_number(rng).rstrip("abcdefghijklmnopqrstuvwxyzµABCDEFGHIJKLMNOPQRSTUVWXYZ") or "1",
                           "t", "t", "pi", "k", "x_p", "E", "I", str(rng.randint(-3, 9)), "1e308", "1e-308", "0",
                           "0.5", "2", "10**30", "1e400"])
    if r < 0.55:
        op = rng.choice(["+", "-", "*", "/", "**", "*", "%", "//", "@", "<", "and", "=="])
        return f"({expression(rng, m, depth + 1)} {op} {expression(rng, m, depth + 1)})"
    if r < 0.65:
        return f"-{expression(rng, m, depth + 1)}"
    if r < 0.95:
        f = rng.choice(FUNCTION_NAMES)
        n = rng.choice([1, 1, 1, 2, 0, 3])
        return f"{f}({', '.join(expression(rng, m, depth + 1) for _ in range(n))})"
    return payload(rng, m, ("python",))


def draw_signal(rng: random.Random, m: str, *, heavy: bool = True) -> dict:
    text = expression(rng, m)
    return {"family": "signal", "marker": m, "text": text,
            "where": rng.choice(["force", "voltage", "current", "parse", "quantity"]),
            "method": rng.choice(["auto", "DOP853", "exact", "rk4_c", "Radau"]),
            "compiled": True if heavy and rng.random() < 0.05 else rng.choice(["tape", False, "auto"]),
            "t_end": rng.choice([0.1, 0.5, 1.0]), "netlist": rng.random() < 0.5}


def _count(rng: random.Random) -> Any:
    """A count as input gives it: ordinary, over decades up to 1e15, or not a count at all."""
    return rng.choice([rng.randint(1, 200), int(10 ** rng.uniform(0, 15)), 10 ** rng.uniform(0, 15), 0, -3,
                       "1e12", float("nan"), float("inf"), True, 2**70])


def unit_text(rng: random.Random) -> str:
    """A value with a unit, whose number may be a tower of powers or beyond a float."""
    exponent = rng.choice(["9", "9^9", "9^9^9", "10^10^10", "2**64", "(-2)^0.5", "-400", "1024", "1025", "0.5",
                           "3**3**3", f"{rng.randint(-5, 5)}"])
    number = rng.choice(["1", "1e400", "1e308", "0.3", "-2", "1e-320", "10"])
    unit = rng.choice(["kg", "m", "N/m", "kg*m^2", "mH", "V", "1/s", "kΩ"])
    op = rng.choice(["^", "**"])
    return rng.choice([f"{number} {unit}*{rng.choice(['9', '10'])}{op}{exponent}", f"{number} {unit}",
                       f"{number}{op}{exponent} {unit}", f"{number} {unit}{op}{exponent}"])


def draw_sizes(rng: random.Random, m: str, *, heavy: bool = True) -> dict:
    """Sizes and exponents from input: frequency grids (API, ``.ac`` lines), unit strings (``add``, ``initial``,
    ``params``), netlists of many elements."""
    where = rng.choice(["decades", "sweep", "ac-line", "units-add", "units-initial", "units-params", "elements"])
    case = {"family": "sizes", "marker": m, "where": where}
    if where in ("decades", "sweep", "ac-line"):
        case.update(points=_jsonable(_count(rng)), kind=rng.choice(["dec", "oct", "lin", "log", "dec"]),
                    start=rng.choice([1e-3, 1.0, 10.0, 0.0, -1.0]), stop=rng.choice([1e6, 1e3, 1e300, 2.0]))
    elif where.startswith("units"):
        case["text"] = unit_text(rng)
    else:
        case["count"] = rng.choice([10, 300, 3000, 250_000])
    return case


DRAW = {"model": draw_model, "netlist": draw_netlist, "signal": draw_signal, "sizes": draw_sizes}


def draw_case(seed: int, index: int, workdir: str, *, heavy: bool = True) -> dict:
    """Case ``index`` of run ``seed``; its payloads create ``<workdir>/EXECUTED-<index>`` if they ever run."""
    rng = random.Random(f"{seed}:{index}")
    family = rng.choices(FAMILIES, WEIGHTS)[0]
    case = DRAW[family](rng, os.path.join(workdir, f"EXECUTED-{index}"), heavy=heavy)
    case["index"], case["seed"] = index, seed
    return case


# --------------------------------------------------------------------------------------------------
# Running a case
# --------------------------------------------------------------------------------------------------


def decode(x: Any) -> Any:
    """JSON case data to API arguments: ``{"$symbol": ...}``, ``{"$sympy": ...}``, ``{"$callable": ...}``."""
    if isinstance(x, dict):
        if "$symbol" in x:
            import sympy as sp

            return sp.Symbol(x["$symbol"], **x.get("assumptions", {}))
        if "$sympy" in x:
            return lib("text").parse_expression(x["$sympy"], "harness")
        if "$tuple" in x:
            return tuple(decode(v) for v in x["$tuple"])
        if "$callable" in x:
            v = x["$callable"]
            if v == "raise":
                def f(t):
                    raise RuntimeError("a user's signal failed")
            elif v == "text":
                def f(t):
                    return "0.5"
            elif v == "array":
                def f(t):
                    import numpy as np

                    return np.array([t, t])
            else:
                def f(t, v=v):
                    return v
            return f
        return {k: decode(v) for k, v in x.items()}
    if isinstance(x, list):
        return [decode(v) for v in x]
    return x


def _resolve(mapping: dict | None, model) -> dict | None:
    """``$coordN`` / ``$paramN`` keys as the model's N-th coordinate / parameter name (when it has one)."""
    if mapping is None:
        return None
    out = {}
    for k, v in mapping.items():
        if isinstance(k, str) and k.startswith("$coord"):
            names = model.coordinate_names
            i = int(k[6:])
            k = names[i] if i < len(names) else "x_missing"
        elif isinstance(k, str) and k.startswith("$param"):
            names = sorted({s.name for s in model.parameters} | set(model.parameter_values))
            i = int(k[6:])
            k = names[i] if i < len(names) else "p_missing"
        out[k] = decode(v)
    return out


class Stats(Counter):
    """What each case reached: ``simulate:ok``, ``netlist:error``, ..."""


def _attempt(stats: Stats, label: str, fn, *args, **kwargs):
    """Run one step: a LagrangianError ends the step (it is a correct answer), anything else propagates."""
    from lagrangian import LagrangianError

    try:
        out = fn(*args, **kwargs)
    except LagrangianError:
        stats[f"{label}:error"] += 1
        return None
    stats[f"{label}:ok"] += 1
    return out


def run_model(case: dict, stats: Stats) -> None:
    import lagrangian as lg

    model = _attempt(stats, "build", lambda: lg.Model(decode(case["name"]), **decode(case["options"])))
    if model is None:
        return
    for c in case["components"]:
        nodes = c["nodes"]
        nodes = tuple(decode(nodes)) if isinstance(nodes, list) else decode(nodes)
        _attempt(stats, "add", model.add, c["kind"], decode(c["name"]), nodes, **decode(c["params"]))
    result = None
    for action in case["actions"]:
        do = action["do"]
        if do == "equations":
            if _attempt(stats, "equations", lambda: model.equations) is None:
                return  # nothing else can be derived
            _attempt(stats, "lagrangian", lambda: (model.lagrangian, model.rayleigh, model.coordinate_names,
                                                     model.parameter_values, model.parameters, model.first_order))
        elif do == "describe":
            _attempt(stats, "describe", lambda: (model.describe(), model.latex()))
        elif do == "simulate":
            result = simulate(model, action, stats) or result
        elif do == "quantity" and result is not None:
            _attempt(stats, "quantity", result.quantity, _coord_text(action["text"], model))
        elif do == "map":
            mapped = _attempt(stats, "map", lib("analogy").map_model, model, action["analogy"])
            if mapped is None:
                continue
            _attempt(stats, "map-initial", mapped.initial, _resolve(action.get("initial", {}), model), {})
            if "to_source" in action:
                _attempt(stats, "to_source", mapped.to_source, _coord_text(action["to_source"], mapped.model))
            if action.get("netlist"):
                _attempt(stats, "netlist", lib("spice").netlist, mapped.model, t_end=0.1)
        elif do == "netlist":
            netlist = lib("spice").netlist
            kwargs = {k: v for k, v in action.items() if k in ("t_end", "step", "max_step", "options")}
            _attempt(stats, "netlist", lambda: netlist(model, initial=_resolve(action.get("initial"), model),
                                                       params=_resolve(action.get("params"), model), **kwargs))
        elif do == "ngspice":
            _attempt(stats, "ngspice", lambda: lib("compare").compare_with_ngspice(
                model, action["t_end"], analogy=action["analogy"], initial=_resolve(action["initial"], model)))


def _coord_text(text: Any, model) -> Any:
    """Quantity text with ``$coord0`` standing for the model's first coordinate (decoded: tuples, symbols)."""
    first = model.coordinate_names[0] if model.coordinate_names else "x"
    if isinstance(text, str):
        return text.replace("$coord0", first)
    if isinstance(text, dict) and "$tuple" in text:
        return tuple(first if v == "$coord0" else decode(v) for v in text["$tuple"])
    return decode(text)


#: The evaluation budget of every run, as a service running models it did not write would set it: a legitimate
#: run of 3e8 evaluations (a 1e-12 kg mass on a 137 N/m spring for 0.7 s) takes minutes, and is refused at its pace.
#: A run stepped in Python (Radau, LSODA) pays up to about 0.1 ms per evaluation with its Jacobians, so the budget
#: keeps every legal run within the case's time limit: what still passes the limit is a hang of the library's own.
BUDGET = 1e5


def simulate(model, action: dict, stats: Stats):
    kwargs = {k: decode(v) for k, v in action.items()
              if k in ("method", "compiled", "points", "step", "rtol", "atol", "max_step")}
    t_end = decode(action["t_end"])

    def run():
        return model.simulate(t_end, initial=_resolve(action.get("initial"), model),
                              velocity=_resolve(action.get("velocity"), model),
                              params=_resolve(action.get("params"), model), max_evaluations=BUDGET, **kwargs)

    label = "simulate-native" if kwargs.get("compiled") is True else "simulate"
    return _attempt(stats, label, run)


def run_netlist(case: dict, stats: Stats) -> None:
    read_netlist = lib("netlist").read_netlist

    kwargs = {"formulation": case["formulation"]}
    if "name" in case:
        kwargs["name"] = case["name"]
    net = _attempt(stats, "read", read_netlist, case["text"], **kwargs)
    if net is None:
        return
    result = None
    for action in case["actions"]:
        if action["do"] == "run":
            opts = {"method": action["method"], "compiled": action["compiled"], "max_evaluations": BUDGET}
            tran = net.tran
            if action["short"] or tran is None or not (tran.stop - tran.start) / tran.step <= 2000:
                stop = tran.stop if tran is not None else 1e-3
                result = _attempt(stats, "simulate", net.simulate, min(stop, 1e-3) if stop > 0 else 1e-3,
                                  points=5, **opts) or result
            else:
                result = _attempt(stats, "simulate", net.simulate, **opts) or result
        elif action["do"] == "probe" and result is not None:
            _attempt(stats, "probe", getattr(net, action["what"]), result, action["element"])
        elif action["do"] == "roundtrip":
            netlist, run_transient = lib("spice").netlist, lib("spice").run_transient

            stop = net.tran.stop if net.tran is not None else 1e-3
            deck = _attempt(stats, "netlist", netlist, net.model, initial=net.initial, velocity=net.velocity,
                            t_end=stop if 0 < stop <= 1 else 1e-3)
            if deck is None:
                continue
            if action["read_back"]:
                _attempt(stats, "read-back", read_netlist, deck.text, formulation="charge")
            if action["ngspice"]:
                _attempt(stats, "ngspice", run_transient, deck)


def run_signal(case: dict, stats: Stats) -> None:
    import lagrangian as lg

    parse_expression = lib("text").parse_expression

    text, where = case["text"], case["where"]
    if where == "parse":
        _attempt(stats, "parse", parse_expression, text, "a fuzzed expression",
                 names={"x_p": lg.t**2, "k": lg.t})
        return
    if where in ("force", "quantity"):
        model = lg.Model("signal")
        model.add("mass", "m", "p", m=1.0)
        model.add("spring", "k", ("ground", "p"), k=4.0)
        if where == "force" and _attempt(stats, "add", model.add, "force", "F", "p", F=text) is None:
            return
    else:
        model = lg.Model("signal", formulation="charge" if where == "voltage" else "flux")
        kind, pname, nodes = ("voltage_source", "E", ("n1", "0")) if where == "voltage" else \
            ("current_source", "I", ("0", "n1"))
        model.add("resistor", "R", ("n1", "n2"), R=1.0)
        model.add("inductor", "L", ("n2", "0"), L=1.0)
        model.add("capacitor", "C", ("n1", "0"), C=1.0)
        if _attempt(stats, "add", model.add, kind, "S", nodes, **{pname: text}) is None:
            return
    res = _attempt(stats, "simulate", model.simulate, case["t_end"], points=5, method=case["method"],
                   compiled=case["compiled"], initial={model.coordinate_names[0]: 0.1}, max_evaluations=BUDGET)
    if where == "quantity" and res is not None:
        _attempt(stats, "quantity", res.quantity, text)
    if case["netlist"] and where in ("voltage", "current"):
        _attempt(stats, "netlist", lib("spice").netlist, model, t_end=case["t_end"])


def run_sizes(case: dict, stats: Stats) -> None:
    import lagrangian as lg
    from lagrangian import frequency

    read_netlist = lib("netlist").read_netlist
    where = case["where"]
    if where == "decades":
        _attempt(stats, "decades", frequency.decades, case["start"] or 1.0, case["stop"], decode(case["points"]))
    elif where == "sweep":
        _attempt(stats, "sweep", frequency.sweep, case["kind"], decode(case["points"]), case["start"], case["stop"])
    elif where == "ac-line":
        points = decode(case["points"])
        deck = (f"sizes\nV1 in 0 DC 0 AC 1\nR1 in out 1k\nC1 out 0 1u\n.ac {case['kind']} {points} "
                f"{case['start']:g} {case['stop']:g}\n.end\n")
        net = _attempt(stats, "read", read_netlist, deck)
        if net is not None and net.ac is not None:
            _attempt(stats, "ac", net.frequency_response)
    elif where == "elements":
        lines = ["many", "V1 a 0 DC 1", *(f"R{i} a 0 1k" for i in range(case["count"])), ".tran 1u 10u", ".end"]
        net = _attempt(stats, "read", read_netlist, "\n".join(lines))
        if net is not None and case["count"] <= 300:
            _attempt(stats, "simulate", net.simulate, 1e-5, points=3, max_evaluations=BUDGET)
    else:
        model = lg.Model("units")
        given = case["text"] if where == "units-add" else 0.3
        if _attempt(stats, "add", model.add, "mass", "m", "p", m=given) is None:
            return
        model.add("spring", "k", ("ground", "p"), k=40.0)
        run = {"units-initial": {"initial": {"x_p": case["text"]}}, "units-params": {"params": {"m_m": case["text"]}},
               "units-add": {}}[where]
        _attempt(stats, "simulate", model.simulate, 0.1, points=3, max_evaluations=BUDGET, **run)


RUN = {"model": run_model, "netlist": run_netlist, "signal": run_signal, "sizes": run_sizes}


class Hang(BaseException):
    """The time limit passed (a BaseException, so a library's ``except Exception`` cannot swallow it)."""


def _alarm(signum, frame):
    raise Hang


def _library_dirs() -> tuple[str, ...]:
    import lagrangian

    core = str(Path(lagrangian.__file__).resolve().parent)
    return core, str(ROOT / "plugins"), str(ROOT / "examples" / "plugins")


def where(exc: BaseException) -> tuple[str, str]:
    """(the last frame, the last frame in the library's own code) as ``file:line``."""
    frames = traceback.extract_tb(exc.__traceback__)
    if not frames:
        return "?", "?"
    last = f"{Path(frames[-1].filename).name}:{frames[-1].lineno}"
    dirs = _library_dirs()
    lib = "?"
    for f in reversed(frames):
        path = str(Path(f.filename).resolve())
        if path.startswith(dirs):
            lib = f"{os.path.relpath(path, ROOT)}:{f.lineno} ({f.name})"
            break
    return last, lib


def check(case: dict, limit: float) -> tuple[dict | None, Stats]:
    """Run ``case``; ``None`` when it ended correctly, else ``{"kind", "type", "message", "last", "library"}``."""
    from lagrangian import LagrangianError

    stats = Stats()
    Path(case["marker"]).parent.mkdir(parents=True, exist_ok=True)
    Path(case["marker"]).unlink(missing_ok=True)  # each run is judged by what it does itself
    previous = signal.signal(signal.SIGALRM, _alarm)
    signal.setitimer(signal.ITIMER_REAL, limit)
    outcome = None
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            RUN[case["family"]](case, stats)
    except LagrangianError:  # a step outside _attempt (the harness's own fixed set-up) refused: still correct
        pass
    except Hang as exc:
        last, lib = where(exc)
        outcome = {"kind": "hang", "type": "Hang", "message": f"no answer within {limit:g} s", "last": last,
                   "library": lib}
    except Exception as exc:  # noqa: BLE001 - every exception that reaches here is unexpected
        last, lib = where(exc)
        outcome = {"kind": "unexpected", "type": f"{type(exc).__module__}.{type(exc).__qualname__}",
                   "message": str(exc)[:500], "last": last, "library": lib}
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)
    if os.path.exists(case["marker"]):
        outcome = {"kind": "executed", "type": "Executed", "message": f"a payload created {case['marker']}",
                   "last": "?", "library": "?"}
    return outcome, stats


# --------------------------------------------------------------------------------------------------
# Workers
# --------------------------------------------------------------------------------------------------

_WORKER: dict[str, Any] = {}


#: Address space of a worker: an allocation beyond it is a MemoryError, counted as unexpected (a size the library
#: did not bound), not a machine brought down.
WORKER_MEMORY = 6 * 2**30


def _init_worker(workdir: str, heavy: bool) -> None:
    import resource

    resource.setrlimit(resource.RLIMIT_AS, (WORKER_MEMORY, resource.getrlimit(resource.RLIMIT_AS)[1]))
    os.dup2(2, 1)  # anything a library prints goes to stderr: stdout is the report's
    logging.getLogger("lagrangian").setLevel(logging.ERROR)
    logging.getLogger("PySpice").setLevel(logging.CRITICAL)
    lib("codegen").set_cache_dir(os.path.join(workdir, "cache"))  # compiled fuzz models stay out of the user's cache
    examples()
    _WORKER.update(workdir=workdir, heavy=heavy)


def _watchdog(workdir: str, index: int, seconds: float) -> threading.Timer:
    """Past ``seconds`` (a case stuck where the timer signal cannot reach: in C code), record it and end the worker."""

    def fire():
        Path(workdir, f"hard-hang-{index}").write_text(str(seconds))
        os._exit(70)

    timer = threading.Timer(seconds, fire)
    timer.daemon = True
    timer.start()
    return timer


def _work(indices: list[int], seed: int, limit: float) -> list[tuple]:
    workdir, heavy = _WORKER["workdir"], _WORKER["heavy"]
    out = []
    for index in indices:
        case = draw_case(seed, index, workdir, heavy=heavy)
        running = Path(workdir, f"running-{os.getpid()}")
        running.write_text(str(index))
        dog = _watchdog(workdir, index, 2 * limit + 10)
        start = time.perf_counter()
        try:
            outcome, stats = check(case, limit)
        finally:
            dog.cancel()
        out.append((index, case["family"], outcome, time.perf_counter() - start, dict(stats),
                    case if outcome else None))
        running.unlink(missing_ok=True)
    return out


def _run_isolated(index: int, seed: int, limit: float, workdir: str, heavy: bool) -> tuple:
    """A case suspected of crashing its worker, alone in a fresh one: its row, or a crash/hard-hang row."""
    with ProcessPoolExecutor(1, initializer=_init_worker, initargs=(workdir, heavy)) as pool:
        try:
            return pool.submit(_work, [index], seed, limit).result()[0]
        except BrokenProcessPool:
            pass
    case = draw_case(seed, index, workdir, heavy=heavy)
    if Path(workdir, f"hard-hang-{index}").exists():
        outcome = {"kind": "hang", "type": "HardHang",
                   "message": f"still running after {2 * limit + 10:g} s where the timer signal could not stop it",
                   "last": "?", "library": "?"}
    else:
        outcome = {"kind": "unexpected", "type": "WorkerCrash", "message": "the worker process died (a signal: "
                   "segmentation fault, abort, out of memory)", "last": "?", "library": "?"}
    return index, case["family"], outcome, math.nan, {}, case


def run_all(args, workdir: str) -> list[tuple]:
    indices = list(range(args.cases))
    chunks = [indices[i:i + args.chunk] for i in range(0, len(indices), args.chunk)]
    results: dict[int, tuple] = {}
    began = time.perf_counter()

    def report(rows):
        for row in rows:
            results[row[0]] = row
        bad = sum(r[2] is not None for r in results.values())
        rate = len(results) / max(time.perf_counter() - began, 1e-9)
        sys.stderr.write(f"\r{len(results)}/{args.cases} cases, {bad} failures, {rate:.1f} cases/s   ")
        sys.stderr.flush()

    pending = chunks
    while pending:
        broken = False
        with ProcessPoolExecutor(args.jobs, initializer=_init_worker, initargs=(workdir, not args.light)) as pool:
            futures = {pool.submit(_work, chunk, args.seed, args.limit): chunk for chunk in pending}
            for f in as_completed(futures):
                try:
                    report(f.result())
                except BrokenProcessPool:
                    broken = True
                except BaseException:  # the harness itself failed: stop at once rather than finish every chunk
                    pool.shutdown(wait=False, cancel_futures=True)
                    raise
        if not broken:
            break
        # a worker died: the cases it was running are run alone, then the chunks left are run again without them
        suspects = set()
        for p in Path(workdir).glob("running-*"):
            suspects.add(int(p.read_text()))
            p.unlink()
        for index in sorted(suspects - set(results)):
            report([_run_isolated(index, args.seed, args.limit, workdir, not args.light)])
        pending = [[i for i in chunk if i not in results] for chunk in pending]
        pending = [c for c in pending if c]
    sys.stderr.write("\n")
    return [results[i] for i in sorted(results)]


# --------------------------------------------------------------------------------------------------
# Shrinking (replay)
# --------------------------------------------------------------------------------------------------


def _candidates(x: Any):
    """Smaller versions of a JSON value, one change at a time."""
    if isinstance(x, str):
        if "\n" in x:
            lines = x.split("\n")
            for i in range(len(lines)):
                yield "\n".join(lines[:i] + lines[i + 1:])
        if len(x) > 1:
            yield x[: len(x) // 2]
            yield x[len(x) // 2:]
        return
    if isinstance(x, list):
        for i in range(len(x)):
            yield x[:i] + x[i + 1:]
        for i, v in enumerate(x):
            for smaller in _candidates(v):
                yield x[:i] + [smaller] + x[i + 1:]
        return
    if isinstance(x, dict):
        for k in list(x):
            if k in ("family", "marker", "index", "seed", "do", "kind", "$symbol", "$sympy", "$callable"):
                continue
            if k not in ("components", "actions", "text", "name", "nodes", "params", "options"):
                yield {kk: vv for kk, vv in x.items() if kk != k}
            for smaller in _candidates(x[k]):
                yield {**x, k: smaller}


def shrink(case: dict, outcome: dict, limit: float, budget: int = 400) -> dict:
    """Greedy reduction of ``case`` that keeps its failure (same type and library frame)."""
    key = (outcome["type"], outcome["library"])
    tries = 0
    improved = True
    while improved and tries < budget:
        improved = False
        for smaller in _candidates(case):
            tries += 1
            if tries > budget:
                break
            try:
                got, _ = check(smaller, limit)
            except Exception:  # noqa: BLE001 - the harness itself cannot run this reduction (a missing key)
                continue
            if got is not None and (got["type"], got["library"]) == key:
                case, improved = smaller, True
                break
    return case


# --------------------------------------------------------------------------------------------------
# Main
# --------------------------------------------------------------------------------------------------


def _show(x: Any, width: int = 4000) -> str:
    text = json.dumps(x, ensure_ascii=True)
    return text if len(text) <= width else text[:width] + f"... ({len(text)} characters)"


def replay(args, case: dict) -> dict:
    _init_worker(str(Path(case["marker"]).parent), True)
    outcome, stats = check(case, args.limit)
    print(f"case: {_show(case, 100000)}")
    print(f"reached: {dict(sorted(stats.items()))}")
    if outcome is None:
        print("outcome: correct (success or a LagrangianError)")
    else:
        print(f"outcome: {outcome['kind']}: {outcome['type']}: {outcome['message']}")
        print(f"  last frame {outcome['last']}; library frame {outcome['library']}")
        if args.shrink:
            small = shrink(case, outcome, args.limit)
            print(f"shrunk: {_show(small, 100000)}")
        if args.traceback and outcome["kind"] == "unexpected":
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                try:
                    RUN[case["family"]](case, Stats())
                except Exception:  # noqa: BLE001
                    traceback.print_exc(file=sys.stdout)
    bad = outcome is not None
    summary = {"cases": 1, "unexpected_exceptions": int(bad and outcome["kind"] == "unexpected"),
               "hangs": int(bad and outcome["kind"] == "hang"), "executed": int(os.path.exists(case["marker"]))}
    print(json.dumps(summary))
    return summary


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", type=int, default=500)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--jobs", type=int, default=os.cpu_count() or 1)
    parser.add_argument("--chunk", type=int, default=20, help="cases per task")
    parser.add_argument("--limit", type=float, default=20.0, help="seconds before a case counts as a hang")
    parser.add_argument("--show", type=int, default=12, help="failures to print in full")
    parser.add_argument("--light", action="store_true", help="no native compilation and no ngspice runs")
    parser.add_argument("--keep", action="store_true", help="keep the work directory (markers, compiled code)")
    parser.add_argument("--replay", metavar="CASE_JSON", help="run one printed case again (JSON text or @file)")
    parser.add_argument("--replay-case", type=int, metavar="INDEX", help="run case INDEX of --seed again")
    parser.add_argument("--shrink", action="store_true", help="with a replay: reduce a failing case")
    parser.add_argument("--traceback", action="store_true", help="with a replay: print the full traceback")
    args = parser.parse_args(argv)

    if args.replay is not None or args.replay_case is not None:
        if args.replay is not None:
            text = Path(args.replay[1:]).read_text() if args.replay.startswith("@") else args.replay
            case = json.loads(text)
        else:
            case = draw_case(args.seed, args.replay_case, tempfile.mkdtemp(prefix="lagrangian-fuzz-replay-"),
                             heavy=not args.light)
        return replay(args, case)

    workdir = tempfile.mkdtemp(prefix="lagrangian-fuzz-")
    began = time.perf_counter()
    try:
        rows = run_all(args, workdir)
        executed_files = sorted(p.name for p in Path(workdir).glob("EXECUTED-*"))
    finally:
        if not args.keep:
            shutil.rmtree(workdir, ignore_errors=True)
    wall = time.perf_counter() - began

    table = defaultdict(lambda: Counter())
    seconds = defaultdict(float)
    reached = Counter()
    for index, family, outcome, secs, stats, _ in rows:
        t = table[family]
        t["cases"] += 1
        t[outcome["kind"] if outcome else "correct"] += 1
        seconds[family] += 0.0 if math.isnan(secs) else secs
        reached.update(stats)
    print(f"{'family':<10}{'cases':>8}{'correct':>9}{'unexpected':>12}{'hangs':>7}{'executed':>10}{'ms/case':>10}")
    for family in FAMILIES:
        t = table.get(family)
        if not t:
            continue
        print(f"{family:<10}{t['cases']:>8}{t['correct']:>9}{t['unexpected']:>12}{t['hang']:>7}{t['executed']:>10}"
              f"{1000 * seconds[family] / t['cases']:>10.1f}")
    steps = sorted({k.rsplit(':', 1)[0] for k in reached})
    print("steps reached (ok / project error): " + ", ".join(f"{s} {reached[s + ':ok']}/{reached[s + ':error']}"
                                                             for s in steps))
    failures = [(r[0], r[2], r[5]) for r in rows if r[2] is not None]
    distinct: dict[tuple, list] = {}
    for index, outcome, case in failures:
        distinct.setdefault((outcome["kind"], outcome["type"], outcome["library"]), []).append((index, outcome, case))
    print(f"total {len(rows)} cases, {len(failures)} failures ({len(distinct)} distinct by type and library frame), "
          f"wall {wall:.1f} s on {args.jobs} process(es), seed {args.seed}")
    for (kind, type_, lib), group in list(distinct.items())[: args.show]:
        index, outcome, case = group[0]
        print(f"FAIL {kind} x{len(group)} [{case['family']}] {type_}: {outcome['message'][:300]!r}")
        print(f"  last frame {outcome['last']}; library frame {lib}")
        print(f"  replay: .venv/bin/python benchmarks/fuzz.py --seed {args.seed} --replay-case {index}"
              f"{' --light' if args.light else ''} --traceback --shrink")
        print(f"  input: {_show(case, 1500)}")
    hangs = sum(1 for _, o, _ in failures if o["kind"] == "hang")
    unexpected = sum(1 for _, o, _ in failures if o["kind"] == "unexpected")
    summary = {"cases": len(rows), "unexpected_exceptions": unexpected, "hangs": hangs,
               "executed": len(executed_files), "crashes": sum(1 for _, o, _ in failures if o["type"] == "WorkerCrash"),
               "distinct_failures": len(distinct), "wall_s": round(wall, 1), "seed": args.seed, "jobs": args.jobs,
               "by_family": {f: dict(table[f]) for f in FAMILIES if f in table}}
    print(json.dumps(summary))
    return summary


if __name__ == "__main__":
    main()
