"""The ``lagrangian`` command.

``lagrangian plugins`` lists installed plugins and the component kinds each
provides; ``lagrangian kinds`` lists every kind with its parameters.
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


def main(argv: list[str] | None = None) -> int:
    """Run the command line ``lagrangian COMMAND``; return the exit status."""
    parser = argparse.ArgumentParser(prog="lagrangian", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True)
    sub.add_parser("plugins", help="list installed plugins and the component kinds each provides")
    sub.add_parser("kinds", help="list component kinds with their parameters")
    args = parser.parse_args(argv)
    try:
        from .registry import default_registry

        registry = default_registry()
    except LagrangianError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 1
    print(registry.describe() if args.command == "plugins" else _kinds(registry))
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
