"""The ``lagrangian`` command.

``lagrangian plugins`` lists installed plugins and the component kinds each
provides; ``lagrangian kinds`` lists every kind with its parameters;
``lagrangian integrators`` lists the integration methods;
``lagrangian bench NAME... --methods RK45,DOP853,verlet --out DIR`` runs
work–precision benchmarks and writes a CSV file and a chart per benchmark
(``lagrangian bench --list`` lists them).
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
    args = parser.parse_args(argv)
    try:
        from .registry import default_registry

        registry = default_registry()
        if args.command == "bench":
            return _bench(args, registry)
    except LagrangianError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 1
    text = {"plugins": registry.describe, "kinds": lambda: _kinds(registry), "integrators": lambda: _integrators(registry)}
    print(text[args.command]())
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
