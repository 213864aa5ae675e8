"""The ``lagrangian`` command.

``lagrangian plugins`` lists installed plugins and the component kinds each
provides; ``lagrangian kinds`` lists every kind with its parameters;
``lagrangian integrators`` lists the integration methods;
``lagrangian bench NAME... --methods RK45,DOP853,verlet --out DIR`` runs
work–precision benchmarks and writes a CSV file and a chart per benchmark
(``lagrangian bench --list`` lists them);
``lagrangian scene SOURCE --output NAME ... --t-end T`` answers a scene with
the smallest exact model (see :mod:`lagrangian.scene`): ``SOURCE`` is a
SPICE netlist (``.cir``, ``.net``, ``.sp``, ``.spice``: its ``.tran`` and
``.ic`` are used) or a Python file ``file.py[:name]`` whose ``name`` (default
``model``, else ``build``) is a model or a function returning one.  It
prints the plan and writes the outputs as CSV (``--csv``).
"""

from __future__ import annotations

import argparse
import sys

from .errors import LagrangianError

__all__ = ["main"]


def _kinds(registry) -> str:
    lines = []
    for kind, cls in sorted(registry.kinds.items()):
        doc = (cls.__doc__ or "").strip().splitlines()[0] if cls.__doc__ else ""
        terminals = ", ".join(
            f"{name} ({domain})" if cls.terminal_domains else name
            for name, domain in zip(cls.terminals, cls.terminal_domains or cls.terminals)
        )
        lines.append(f"{kind}  [{cls.domain}; terminals: {terminals or 'none'}]  {doc}")
        for name, p in cls.parameters.items():
            default = "" if p.required else f" = {p.default!r}"
            unit = f" [{p.unit}]" if p.unit else ""
            lines.append(f"    {name}{default}{unit}: {p.doc}")
    return "\n".join(lines)


def _integrators(registry) -> str:
    lines = []
    for name, m in sorted(registry.integrators.items(), key=lambda kv: (kv[1].kind, kv[0].lower())):
        flags = [f for f in ("symplectic", "implicit", "stiff") if getattr(m, f)]
        if not m.first_order:
            flags.append("no first-order coordinates")
        order = f"order {m.order}" if m.order else "order ?"
        lines.append(f"{name}  [{m.kind}; {order}{'; ' + ', '.join(flags) if flags else ''}]  {m.description}")
        for opt, doc in (getattr(m, "options", {}) or {}).items():
            lines.append(f"    {opt}: {doc}")
    return "\n".join(lines)


def _floats(text: str | None, what: str) -> list[float] | None:
    if text is None:
        return None
    try:
        return [float(x) for x in text.split(",") if x.strip()]
    except ValueError:
        raise SystemExit(f"error: --{what} takes comma-separated numbers, got {text!r}") from None


def _bench(args, registry) -> int:
    from .bench import run

    if args.list or not args.names:
        for name, b in registry.benchmarks.items():
            why = b.unavailable(registry)
            lines = f"{name}: {b.description}" + (f"  [unavailable: {why}]" if why else "")
            print(lines)
        if not args.list:
            print("\nrun: lagrangian bench NAME... [--methods A,B] [--out DIR]  (NAME 'all' runs every available one)",
                  file=sys.stderr)
        return 0
    methods = [m.strip() for m in args.methods.split(",") if m.strip()] if args.methods else None
    results = run(args.names, methods, out=args.out, tolerances=_floats(args.tolerances, "tolerances"),
                  steps=_floats(args.steps, "steps"), repeat=args.repeat, registry=registry,
                  progress=not args.quiet, chart=not args.no_chart)
    for wp, files in results:
        print(wp.table())
        print("written: " + ", ".join(map(str, files)))
        print()
    return 0


def _pairs(items: list[str] | None, what: str) -> dict[str, float]:
    out = {}
    for item in items or []:
        for pair in item.split(","):
            if not pair.strip():
                continue
            key, sep, value = pair.partition("=")
            try:
                if not sep:
                    raise ValueError
                out[key.strip()] = float(value)
            except ValueError:
                raise SystemExit(f"error: --{what} takes name=value pairs, got {pair!r}") from None
    return out


def _load_model(source: str):
    """A model (and its netlist's initial state and span, if any) from a netlist or ``file.py[:name]``."""
    import importlib.util
    from pathlib import Path

    from .errors import ModelError
    from .model import Model

    path, _, attr = source.partition(":") if not Path(source).exists() else (source, "", "")
    file = Path(path)
    if not file.exists():
        raise ModelError(f"scene source {path!r} does not exist: give a netlist file or a Python file (file.py[:name]).")
    if file.suffix.lower() in (".cir", ".net", ".sp", ".spice", ".ckt"):
        from .netlist import read_netlist_file

        imported = read_netlist_file(file)
        span = (imported.tran.start, imported.tran.stop) if imported.tran else None
        return imported.model, imported.initial, imported.velocity, span
    if file.suffix != ".py":
        raise ModelError(f"scene source {path!r}: expected a netlist (.cir, .net, .sp, .spice) or a Python file (.py).")
    spec = importlib.util.spec_from_file_location(f"_lagrangian_scene_{file.stem}", file)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    names = [attr] if attr else ["model", "build"]
    for name in names:
        obj = getattr(module, name, None)
        if obj is None:
            continue
        model = obj() if callable(obj) and not isinstance(obj, Model) else obj
        if not isinstance(model, Model):
            raise ModelError(f"{file}:{name} is not a lagrangian Model (nor a function returning one).")
        return model, {}, {}, None
    raise ModelError(f"{file} defines none of {', '.join(names)}: name the model with {file}:NAME.")


def _scene(args) -> int:
    import csv

    import numpy as np

    from .scene import Scene

    model, initial, velocity, span = _load_model(args.source)
    initial = {**initial, **_pairs(args.initial, "initial")}
    velocity = {**velocity, **_pairs(args.velocity, "velocity")}
    t_end = args.t_end if args.t_end is not None else (span or 10.0)
    scene = Scene(model, args.output, t_end, tol=args.tol, initial=initial, velocity=velocity,
                  params=_pairs(args.param, "param"), points=args.points, method=args.method)
    print(scene.report())
    res = scene.run()
    if args.csv:
        with open(args.csv, "w", newline="") as fh:
            writer = csv.writer(fh)
            writer.writerow(["t", *res.outputs])
            for row in np.column_stack([res.t, *[res[o] for o in res.outputs]]):
                writer.writerow([repr(float(x)) for x in row])
        print(f"written: {args.csv}")
    else:
        for label in res.outputs:
            values = res[label]
            print(f"{label}: at t = {res.t[-1]:g}: {values[-1]:.10g} (min {np.min(values):.6g}, max {np.max(values):.6g})")
    return 0


def main(argv: list[str] | None = None) -> int:
    """Run the command line ``lagrangian COMMAND``; return the exit status."""
    parser = argparse.ArgumentParser(prog="lagrangian", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True)
    sub.add_parser("plugins", help="list installed plugins and the component kinds each provides")
    sub.add_parser("kinds", help="list component kinds with their parameters")
    sub.add_parser("integrators", help="list integration methods with their kind, order, flags and options")
    bench = sub.add_parser("bench", help="work–precision benchmarks: error against wall time, CSV and chart")
    bench.add_argument("names", nargs="*", help="benchmarks to run ('all': every available one)")
    bench.add_argument("--methods", help="comma-separated methods (default: the benchmark's, or all registered)")
    bench.add_argument("--tolerances", help="comma-separated rtol values for adaptive methods")
    bench.add_argument("--steps", help="comma-separated step sizes for fixed-step methods")
    bench.add_argument("--repeat", type=int, default=1, help="time each run this many times, keep the best (default 1)")
    bench.add_argument("--out", default=".", help="directory for <name>.csv and <name>.png (default: .)")
    bench.add_argument("--list", action="store_true", help="list the benchmarks and exit")
    bench.add_argument("--no-chart", action="store_true", help="write CSV only")
    bench.add_argument("--quiet", action="store_true", help="no progress bar")
    scene = sub.add_parser("scene", help="answer a question about a model with its smallest exact model")
    scene.add_argument("source", help="a netlist (.cir/.net/.sp/.spice) or file.py[:name] defining a model")
    scene.add_argument("--output", "-o", action="append", required=True,
                       help="an output: coordinate, rate (x'), T/V/D/E/L, T[component], [component]; repeat for more")
    scene.add_argument("--t-end", type=float, help="end time (default: the netlist's .tran stop, else 10)")
    scene.add_argument("--tol", type=float, default=1e-8, help="relative tolerance (default 1e-8)")
    scene.add_argument("--initial", action="append", help="initial coordinates name=value[,name=value]")
    scene.add_argument("--velocity", action="append", help="initial velocities name=value[,name=value]")
    scene.add_argument("--param", action="append", help="parameter values name=value[,name=value]")
    scene.add_argument("--points", type=int, default=1001, help="output times (default 1001)")
    scene.add_argument("--method", default="DOP853", help="integrator for nonlinear parts (default DOP853)")
    scene.add_argument("--csv", help="write the outputs to this CSV file")
    args = parser.parse_args(argv)
    try:
        from .registry import default_registry

        registry = default_registry()
        if args.command == "bench":
            return _bench(args, registry)
        if args.command == "scene":
            return _scene(args)
    except LagrangianError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 1
    text = {"plugins": registry.describe, "kinds": lambda: _kinds(registry), "integrators": lambda: _integrators(registry)}
    print(text[args.command]())
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
