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
``lagrangian ac SOURCE [--input NAME] [--output OUT ...]`` prints the
small-signal frequency response (see :mod:`lagrangian.frequency`) of a
netlist (its ``.ac`` line and ``AC`` sources, as ngspice's ``.ac``) or of a
model, writes it as CSV (``--csv``) and a Bode chart (``--chart``), and
with ``--ngspice`` compares it with ngspice's.
``lagrangian sweep SOURCE --param k_k1=1:10:50 --param c=log:1e-3:1:20 -o x_p --out sweep.nc``
simulates a model over a grid (or ``--design random --samples N --seed S``
draws of ``uniform:LOW:HIGH``, ``loguniform:…``, ``normal:MEAN:STD``) on Dask
(see :mod:`lagrangian.sweep`: a local cluster, or ``--address`` of a
scheduler), prints a summary and writes a netCDF file and a chart.
``lagrangian simulate SOURCE --t-end 5 --param k_k=4 --initial x_p=0.1 --out run.csv``
runs a transient of a netlist or model (``--method``, ``--points``,
``--velocity``) and writes its coordinates and rates as CSV, netCDF
(``.nc``) or a chart (``.png``), or prints their final values;
``lagrangian equations SOURCE [--latex]`` prints its equations of motion;
``lagrangian convert SOURCE --out model.json`` writes a netlist or model as
a model file (:mod:`lagrangian.modelfile`), which every command reads too.
``lagrangian cache [--clear]`` shows the compiled-code cache (or empties it).
``lagrangian --version`` prints the installed version.

Errors are one line on standard error, ``lagrangian: error: <message>``,
naming the option or the input at fault and what would fix it; warnings the
library raises during a command (:class:`~lagrangian.InitialConditionWarning`,
``EnergyDriftWarning``, ``StiffnessWarning``, ``NetlistWarning``...) are one
line each, ``lagrangian: warning: <message>``.  Option values are checked
before anything runs: counts are whole numbers, written ``1000`` or ``1e3``
(``--points`` at least 2, and for ``scene`` at most
``lagrangian.limits.grid_points``; ``--repeat`` at least 1), times, step
sizes and tolerances finite and positive (tolerances below 1), method names
registered integrators.

Exit status:

- 0: success (also ``--help`` and ``--version``);
- 1: the command failed while running: an error of the library
  (:class:`~lagrangian.LagrangianError`: an unknown benchmark or output, a
  model that cannot be built...), a source that cannot be read, an
  output file or directory that cannot be written;
- 2: usage error: no command, an unknown option, a bad option value;
- 130: interrupted (Ctrl-C);
- 141: standard output was closed early (``lagrangian kinds | head -1``):
  the rest of the output is dropped without a message, and the status is
  the one a shell reports for a program ended by ``SIGPIPE`` (128 + 13).

The command owns its process, so it lets OpenBLAS's idle threads sleep at
once: ``OPENBLAS_THREAD_TIMEOUT=4`` unless the environment sets it (see
:data:`BLAS_THREAD_TIMEOUT`).
"""

from __future__ import annotations

import argparse
import os
import sys
import warnings
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path

import lazy_loader

from .base import charts
from .errors import LagrangianError, ModelError
from .cli_args import (methods as _methods, numbers as _numbers, out_problem as _out_problem,
                       output_problem as _output_problem, pairs as _pairs, positive as _positive,
                       tolerance as _tolerance, whole as _whole, write_failure as _write_failure)

# The modules a command needs, imported when it first uses them (SPEC 1): ``lagrangian --help`` loads neither
# SymPy, SciPy nor NumPy.  (lazy_loader warns that their parent packages load at once: those are empty.)
with warnings.catch_warnings():
    warnings.simplefilter("ignore", RuntimeWarning)
    _benchmarks = lazy_loader.load("lagrangian.numerics.bench")
    _model = lazy_loader.load("lagrangian.model")
    _frequency = lazy_loader.load("lagrangian.analysis.frequency")
    _sweeps = lazy_loader.load("lagrangian.analysis.sweep")
    _ac_module = lazy_loader.load("lagrangian.circuits.ac")
    _netlist = lazy_loader.load("lagrangian.circuits.netlist")
    _registry = lazy_loader.load("lagrangian.plugin.registry")
    _scenes = lazy_loader.load("lagrangian.analysis.scene")
    _c_build = lazy_loader.load("lagrangian.numerics.c_build")
    _channels = lazy_loader.load("lagrangian.analysis.channels")
    _result = lazy_loader.load("lagrangian.numerics.result")

__all__ = ["main"]

#: File suffixes read as SPICE netlists.
_NETLISTS = (".cir", ".net", ".sp", ".spice", ".ckt")

#: Exit status of a command whose standard output was closed early (128 + SIGPIPE).
EXIT_BROKEN_PIPE = 141
EXIT_USAGE = 2
EXIT_FAILURE = 1
EXIT_INTERRUPTED = 130


def _one_line(text: object) -> str:
    return " ".join(part.strip() for part in str(text).splitlines() if part.strip())


def _fail(message: str) -> int:
    print(f"lagrangian: error: {_one_line(message)}", file=sys.stderr)
    return EXIT_FAILURE


def _show_warning(message, category, filename, lineno, file=None, line=None) -> None:
    """``warnings.showwarning`` while a command runs: ``lagrangian: warning: <message>``, one line."""
    stream = file if file is not None else sys.stderr
    if stream is None:
        return
    try:
        stream.write(f"lagrangian: warning: {_one_line(message)}\n")
    except OSError:  # stderr gone: nowhere to warn (as warnings.showwarning does)
        pass


# ---------------------------------------------------------------------------
# Option values: argparse ``type=`` functions, so a bad value is a usage error naming its option
# ---------------------------------------------------------------------------


# ---------------------------------------------------------------------------
# Commands
# ---------------------------------------------------------------------------


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


def _bench(args, registry) -> int:
    if args.list or not args.names:
        for name, b in registry.benchmarks.items():
            why = b.unavailable(registry)
            lines = f"{name}: {b.description}" + (f"  [unavailable: {why}]" if why else "")
            print(lines)
        if not args.list:
            print("\nrun: lagrangian bench NAME... [--methods A,B] [--out DIR]  (NAME 'all' runs every available one)",
                  file=sys.stderr)
        return 0
    problem = _output_problem("--out", args.out, directory=True)
    if problem:
        return _fail(problem)
    try:
        results = _benchmarks.run(args.names, args.methods, out=args.out, tolerances=args.tolerances, steps=args.steps,
                      repeat=args.repeat, registry=registry, progress=not args.quiet, chart=not args.no_chart)
    except BrokenPipeError:
        raise
    except OSError as exc:
        return _fail(_write_failure("--out", args.out, exc))
    for wp, files in results:
        print(wp.table())
        print("written: " + ", ".join(map(str, files)))
        print()
    return 0


def _load_model(source: str):
    """A model (and its netlist's initial state and span, if any) from a netlist or ``file.py[:name]``."""
    import importlib.util

    path, _, attr = source.partition(":") if not Path(source).exists() else (source, "", "")
    file = Path(path)
    if not file.exists():
        raise ModelError(f"source {path!r} does not exist: give a netlist file or a Python file (file.py[:name]).")
    if file.is_dir():
        raise ModelError(f"source {path!r} is a directory: give a netlist file or a Python file (file.py[:name]).")
    try:
        if file.suffix.lower() in _NETLISTS:
            imported = _netlist.read_netlist_file(file)
            span = (imported.tran.start, imported.tran.stop) if imported.tran else None
            return imported.model, imported.initial, imported.velocity, span
        if file.suffix.lower() == ".json":
            return _model.Model.load(file), {}, {}, None
        if file.suffix != ".py":
            raise ModelError(f"source {path!r}: expected a netlist (.cir, .net, .sp, .spice), a model file (.json) or a "
                             f"Python file (.py).")
        spec = importlib.util.spec_from_file_location(f"_lagrangian_scene_{file.stem}", file)
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
    except UnicodeDecodeError as exc:
        raise ModelError(f"source {path!r} is not a text file ({exc.reason}): give a netlist or a Python file.") from exc
    except SyntaxError as exc:
        raise ModelError(f"source {path!r}, line {exc.lineno}: {exc.msg}: fix the Python file.") from exc
    except OSError as exc:
        raise ModelError(f"source {path!r} cannot be read: {exc.strerror or exc}.") from exc
    names = [attr] if attr else ["model", "build"]
    for name in names:
        obj = getattr(module, name, None)
        if obj is None:
            continue
        model = obj() if callable(obj) and not isinstance(obj, _model.Model) else obj
        if not isinstance(model, _model.Model):
            raise ModelError(f"{file}:{name} is not a lagrangian Model (nor a function returning one).")
        return model, {}, {}, None
    raise ModelError(f"{file} defines none of {', '.join(names)}: name the model with {file}:NAME.")


def _merged(dicts: list[dict[str, float]] | None) -> dict[str, float]:
    return {k: v for d in dicts or [] for k, v in d.items()}


def _scene(args) -> int:
    import csv

    import numpy as np

    if args.csv:
        problem = _output_problem("--csv", args.csv, directory=False)
        if problem:
            return _fail(problem)
    model, initial, velocity, span = _load_model(args.source)
    initial = {**initial, **_merged(args.initial)}
    velocity = {**velocity, **_merged(args.velocity)}
    t_end = args.t_end if args.t_end is not None else (span or 10.0)
    scene = _scenes.Scene(model, args.output, t_end, tol=args.tol, initial=initial, velocity=velocity,
                  params=_merged(args.param), points=args.points, method=args.method,
                  reduce={"auto": "auto", "always": True, "never": False}[args.reduce])
    print(scene.report())
    res = scene.run()
    if args.csv:
        try:
            with open(args.csv, "w", newline="") as fh:
                writer = csv.writer(fh)
                writer.writerow(["t", *res.outputs])
                for row in np.column_stack([res.t, *[res[o] for o in res.outputs]]):
                    writer.writerow([repr(float(x)) for x in row])
        except OSError as exc:
            return _fail(_write_failure("--csv", args.csv, exc))
        print(f"written: {args.csv}")
    else:
        for label in res.outputs:
            values = res[label]
            meaning = f" — {res.meanings[label]}" if label in res.meanings else ""
            print(f"{label}{meaning}: at t = {res.t[-1]:g}: {values[-1]:.10g} (min {np.min(values):.6g}, "
                  f"max {np.max(values):.6g})")
    return 0


def _ac(args) -> int:
    import csv

    import numpy as np

    for option, path in (("--csv", args.csv), ("--chart", args.chart)):
        problem = path and _output_problem(option, path, directory=False)
        if problem:
            return _fail(problem)
    path = args.source.partition(":")[0] if not Path(args.source).exists() else args.source
    net = _netlist.read_netlist_file(path) if Path(path).suffix.lower() in _NETLISTS and Path(path).is_file() else None
    model = net.model if net is not None else _load_model(args.source)[0]
    deck = net.ac if net is not None and net.ac is not None else None
    kind = args.sweep or (deck.kind if deck else "dec")
    start = args.start or (deck.start if deck else 1.0)
    stop = args.stop or (deck.stop if deck else 1e6)
    points = args.points or (deck.points if deck else 20)
    if not start < stop:
        return _fail(f"--start {start:g} Hz must be below --stop {stop:g} Hz.")
    frequencies = _frequency.sweep(kind, points, start, stop)
    kwargs = {"params": _merged(args.param), "at": _merged(args.at) or None}
    if net is not None and args.input is None:
        resp = net.frequency_response(args.output, frequencies, **kwargs)
    else:
        inputs = [args.input] if args.input else None
        resp = _frequency.frequency_response(model, frequencies, inputs=inputs, outputs=args.output, **kwargs)
        if len(resp.inputs) != 1:
            return _fail(f"model {model.name!r} has {len(resp.inputs)} inputs ({', '.join(resp.inputs) or 'none'}): "
                         f"choose one with --input.")
    print(f"{resp.model}: response to {resp.inputs[0]}, {len(frequencies)} frequencies "
          f"{frequencies[0]:g}–{frequencies[-1]:g} Hz ({kind})")
    print(f"  {'output':16} {'|H| at start':>13} {'peak |H|':>11} {'at (Hz)':>11} {'|H| at stop':>12}")
    for label in resp.outputs:
        mag = np.abs(resp[label])
        k = int(np.argmax(mag))
        print(f"  {label:16} {mag[0]:13.6g} {mag[k]:11.6g} {frequencies[k]:11.6g} {mag[-1]:12.6g}")
    for note in resp.notes:
        print(f"  note: {note}")
    if args.csv:
        try:
            with open(args.csv, "w", newline="") as fh:
                writer = csv.writer(fh)
                writer.writerow(["frequency_hz", *[f"{o} {part}" for o in resp.outputs for part in ("dB", "deg")]])
                columns = [c for o in resp.outputs for c in (resp.magnitude_db(o), resp.phase_deg(o))]
                for row in np.column_stack([frequencies, *columns]):
                    writer.writerow([repr(float(x)) for x in row])
        except OSError as exc:
            return _fail(_write_failure("--csv", args.csv, exc))
        print(f"written: {args.csv}")
    if args.chart:
        try:
            resp.plot("bode", path=args.chart)
        except OSError as exc:
            return _fail(_write_failure("--chart", args.chart, exc))
        print(f"written: {args.chart}")
    if args.ngspice:
        cmp = _ac_module.compare_ac_with_ngspice(net if net is not None else model, input=args.input or (
            None if net is not None else resp.inputs[0]), outputs=resp.outputs, start=start, stop=stop, points=points,
            sweep=kind, params=kwargs["params"], at=kwargs["at"])
        print(cmp.table())
    return 0


# ---------------------------------------------------------------------------
# The parser and main
# ---------------------------------------------------------------------------


class _Parser(argparse.ArgumentParser):
    """argparse with one-line errors, ``lagrangian: error: <message>``, and exit status 2."""

    def error(self, message: str):
        hint = "" if message.startswith("argument ") else f" (see '{self.prog} --help')"
        if message.endswith("expected one argument"):  # a value that argparse took for an option: -1e-3
            hint = " (write a value that starts with '-' as --option=VALUE)"
        self.exit(EXIT_USAGE, f"lagrangian: error: {_one_line(message)}{hint}\n")


def _version() -> str:
    try:
        return version("lagrangian")
    except PackageNotFoundError:  # pragma: no cover - running from a source tree that is not installed
        return "(not installed)"


_DESCRIPTION = ("Energy-based models of mechanisms and circuits: scenes, frequency responses and parameter sweeps of "
                "models and SPICE netlists, work-precision benchmarks, and the installed plugins.")

_EXAMPLES = """examples:
  lagrangian kinds                                     every component kind and its parameters
  lagrangian scene examples/filter.cir -o "[C1]"       a netlist's .tran with the smallest exact model
  lagrangian scene examples/machine.py:build -o x_s --t-end 5 --initial x_s=1 --csv out.csv
  lagrangian ac examples/butterworth.cir -o "v(n3)" --chart bode.png --ngspice
  lagrangian sweep examples/machine.py:build --param k_k1=1:10:50 --param c_c1=log:1e-3:1:20 -o x_p --out sweep.nc
  lagrangian bench oscillator --methods RK45,DOP853,verlet --out wp/

exit status: 0 success, 1 the command failed, 2 usage error, 130 interrupted, 141 output closed early.
'lagrangian COMMAND --help' describes each command."""


def _parser() -> _Parser:
    parser = _Parser(prog="lagrangian", description=_DESCRIPTION, epilog=_EXAMPLES,
                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--version", action="version", version=f"lagrangian {_version()}")
    sub = parser.add_subparsers(dest="command")
    sub.add_parser("plugins", help="list installed plugins and the component kinds each provides")
    sub.add_parser("kinds", help="list component kinds with their parameters")
    sub.add_parser("integrators", help="list integration methods with their kind, order, flags and options")
    bench = sub.add_parser("bench", help="work–precision benchmarks: error against wall time, CSV and chart")
    bench.add_argument("names", nargs="*", help="benchmarks to run ('all': every available one)")
    bench.add_argument("--methods", type=_methods(("auto",), single=False),
                       help="comma-separated methods (default: the benchmark's, or all registered)")
    bench.add_argument("--tolerances", type=_numbers("relative tolerance", "1e-4,1e-8", hi=1.0),
                       help="comma-separated rtol values (between 0 and 1) for adaptive methods")
    bench.add_argument("--steps", type=_numbers("step size", "0.1,0.01"),
                       help="comma-separated step sizes (> 0) for fixed-step methods")
    bench.add_argument("--repeat", type=_whole(1, "timings per run, the best is kept"), default=1,
                       help="time each run this many times, keep the best (default 1)")
    bench.add_argument("--out", default=".", help="directory for <name>.csv and <name>.png, made if missing (default: .)")
    bench.add_argument("--list", action="store_true", help="list the benchmarks and exit")
    bench.add_argument("--no-chart", action="store_true", help="write CSV only")
    bench.add_argument("--quiet", action="store_true", help="no progress bar")
    scene = sub.add_parser("scene", help="answer a question about a model with its smallest exact model")
    scene.add_argument("source", help="a netlist (.cir/.net/.sp/.spice) or file.py[:name] defining a model")
    scene.add_argument("--output", "-o", action="append", required=True,
                       help="an output: coordinate, rate (x'), T/V/D/E/L, T[component], [component]; repeat for more")
    scene.add_argument("--t-end", type=_positive("an end time", "10"),
                       help="end time, > 0 (default: the netlist's .tran stop, else 10)")
    scene.add_argument("--tol", type=_tolerance, default=1e-8, help="relative tolerance, between 0 and 1 (default 1e-8)")
    scene.add_argument("--initial", action="append", type=_pairs, help="initial coordinates name=value[,name=value]")
    scene.add_argument("--velocity", action="append", type=_pairs, help="initial velocities name=value[,name=value]")
    scene.add_argument("--param", action="append", type=_pairs, help="parameter values name=value[,name=value]")
    scene.add_argument("--points", type=_whole(2, "output times from the start to the end time", "grid_points"),
                       default=1001, help="output times, at least 2 (default 1001)")
    scene.add_argument("--method", type=_methods(("auto", "exact"), single=True), default="DOP853",
                       help="integrator for nonlinear parts (default DOP853; see 'lagrangian integrators')")
    scene.add_argument("--reduce", choices=("auto", "always", "never"), default="auto",
                       help="eliminate ignorable coordinates through the Routhian: when it pays (auto, the default), "
                            "always or never")
    scene.add_argument("--csv", help="write the outputs to this CSV file")
    ac = sub.add_parser("ac", help="small-signal frequency response of a netlist or model (ngspice's .ac)")
    ac.add_argument("source", help="a netlist (.cir/.net/.sp/.spice: its .ac line and AC sources) or file.py[:name]")
    ac.add_argument("--input", "-i", help="the source, force or prescribed motion that drives (default: the "
                                            "netlist's AC sources, or the model's only source)")
    ac.add_argument("--output", "-o", action="append",
                    help="an output: v(node), v(element), i(element), a coordinate or its rate (x'); repeat for more "
                         "(default: every node voltage of a netlist, every coordinate of a model)")
    ac.add_argument("--sweep", choices=("dec", "oct", "lin"), help="grid: per decade, per octave or linear (default: "
                                                                    "the .ac line's, else dec)")
    ac.add_argument("--points", type=_whole(1, "points per decade or octave, or in all for lin"),
                    help="points per decade or octave, or in all (default: the .ac line's, else 20)")
    ac.add_argument("--start", type=_positive("a start frequency in Hz", "10"), help="start frequency, Hz")
    ac.add_argument("--stop", type=_positive("a stop frequency in Hz", "1e6"), help="stop frequency, Hz")
    ac.add_argument("--param", action="append", type=_pairs, help="parameter values name=value[,name=value]")
    ac.add_argument("--at", action="append", type=_pairs, help="operating point: coordinate values name=value[,...]")
    ac.add_argument("--csv", help="write magnitude (dB) and phase (°) per output to this CSV file")
    ac.add_argument("--chart", help="write a Bode chart to this PNG file")
    ac.add_argument("--ngspice", action="store_true", help="also run ngspice's .ac and print the differences")
    sim = sub.add_parser("simulate", help="run a transient of a model or netlist and write or print its result")
    sim.add_argument("source", help="a netlist (.cir/.net/.sp/.spice: its .tran and .ic) or file.py[:name]")
    sim.add_argument("--t-end", type=_positive("an end time", "10"), help="end time (default: .tran stop, else 10)")
    sim.add_argument("--points", type=_whole(2, "output times from the start to the end time"), default=501,
                     help="output times (default 501)")
    sim.add_argument("--method", type=_methods(("auto", "exact"), single=True), default="auto",
                     help="integration method (default auto)")
    sim.add_argument("--initial", action="append", type=_pairs, help="initial coordinates name=value[,name=value]")
    sim.add_argument("--velocity", action="append", type=_pairs, help="initial velocities name=value[,name=value]")
    sim.add_argument("--param", action="append", type=_pairs, help="parameter values name=value[,name=value]")
    sim.add_argument("--output", action="append", help="what to report instead of every coordinate: names such as "
                     "x_p, x_p' (its rate), v(C1), i(L1), v(n3) (a node's voltage)[,…]")
    sim.add_argument("--out", help="write the result: .csv (t, coordinates, rates), .nc (netCDF) or .png (a chart)")
    conv = sub.add_parser("convert", help="write a netlist or model as a model file (JSON)")
    conv.add_argument("source", help="a netlist (.cir/.net/.sp/.spice) or file.py[:name]")
    conv.add_argument("--out", required=True, help="the model file to write (.json)")
    eqs = sub.add_parser("equations", help="print a model's or netlist's equations of motion")
    eqs.add_argument("source", help="a netlist (.cir/.net/.sp/.spice) or file.py[:name]")
    eqs.add_argument("--latex", action="store_true", help="LaTeX instead of text")
    sw = sub.add_parser("sweep", help="simulate a model over a grid or random samples of its parameters, on Dask")
    sw.add_argument("source", help="a netlist (.cir/.net/.sp/.spice) or file.py[:name] defining a model")
    sw.add_argument("--param", "-p", action="append", required=True,
                    help="NAME=VALUES: START:STOP:COUNT, log:START:STOP:COUNT, a list 1,2,5, one value, or "
                         "uniform:LOW:HIGH, loguniform:LOW:HIGH, normal:MEAN:STD; NAME(0) or NAME'(0) sweeps an "
                         "initial value or rate; repeat for more")
    sw.add_argument("--output", "-o", action="append",
                    help="an output: a coordinate, its rate (x'), T/V/D/E/h, v(element), i(element) or an expression; "
                         "repeat for more (default: every coordinate)")
    sw.add_argument("--out", help="write the results to this netCDF file")
    sw.add_argument("--chart", help="write a chart of the first output's final value against the parameters (PNG)")
    sw.add_argument("--design", choices=("grid", "zip", "random", "lhs", "sobol"),
                    help="grid (default for lists), zip, or random/lhs/sobol draws (default with distributions)")
    sw.add_argument("--samples", type=_whole(1, "random draws"), help="number of draws of a random design")
    sw.add_argument("--seed", type=_whole(0, "a seed for the draws"), help="seed of the draws (default: drawn, recorded)")
    sw.add_argument("--t-end", type=_positive("an end time", "10"), help="end time (default: .tran stop, else 10)")
    sw.add_argument("--points", type=_whole(2, "output times"), default=201, help="output times (default 201)")
    sw.add_argument("--initial", action="append", type=_pairs, help="initial coordinates name=value[,name=value]")
    sw.add_argument("--velocity", action="append", type=_pairs, help="initial velocities name=value[,name=value]")
    sw.add_argument("--method", choices=("DOP853", "dopri5"), default="DOP853", help="integrator (default DOP853)")
    sw.add_argument("--rtol", type=_tolerance, help="relative tolerance, between 0 and 1 (default 1e-9)")
    sw.add_argument("--chunk", type=_whole(1, "samples per task"), help="samples per task (default: about 8 tasks per worker)")
    sw.add_argument("--address", help="a Dask scheduler, tcp://host:8786 (default: a local cluster, one worker per core)")
    sw.add_argument("--serial", action="store_true", help="run here, without Dask")
    sw.add_argument("--quiet", action="store_true", help="no progress bar")
    cache = sub.add_parser("cache", help="show the compiled-code cache (directory, files, size) or clear it")
    cache.add_argument("--clear", action="store_true", help="delete the cached libraries (rebuilt when needed)")
    return parser


def _sweep(args) -> int:
    for option, path in (("--out", args.out), ("--chart", args.chart)):
        problem = path and _output_problem(option, path, directory=False)
        if problem:
            return _fail(problem)
    model, initial, velocity, span = _load_model(args.source)
    params = {}
    for text in args.param:
        name, eq, spec = text.partition("=")
        if not eq or not name.strip():
            return _fail(f"--param {text!r}: write NAME=VALUES, as in k_k1=1:10:50 or c=log:1e-3:1:20.")
        params[name.strip()] = _sweeps.parse_axis(spec, f"--param {name.strip()}")
    where = {"client": "serial"} if args.serial else {"address": args.address}
    ds = _sweeps.sweep(model, params, design=args.design, samples=args.samples, seed=args.seed,
                      initial={**initial, **_merged(args.initial)}, velocity={**velocity, **_merged(args.velocity)},
                      outputs=args.output, t_end=args.t_end or (span or (0.0, 10.0))[1], points=args.points,
                      method=args.method, rtol=args.rtol, chunk=args.chunk, progress=not args.quiet, **where)
    print(_sweeps.describe(ds))
    if args.out:
        try:
            ds.to_netcdf(args.out)
        except OSError as exc:
            return _fail(_write_failure("--out", args.out, exc))
        print(f"written: {args.out}")
    if args.chart:
        output = (args.output or [model.coordinate_names[0]])[0]
        try:
            _sweeps.plot(ds, output, path=args.chart)
        except OSError as exc:
            return _fail(_write_failure("--chart", args.chart, exc))
        print(f"written: {args.chart}")
    return 0


@charts.plain
def _simulation_chart(res, columns: dict | None, path: str) -> None:
    """The run's chart as a PNG file: the ``--output`` columns, or ``Result.plot``'s chart without them."""
    import matplotlib.pyplot as plt

    if columns:
        fig, ax = plt.subplots()
        for label, values in columns.items():
            ax.plot(res.t, values, label=label)
        ax.set_xlabel("t (s)")
        _result.legend(ax)
    else:
        ax = res.plot()
    ax.figure.savefig(path, dpi=110)
    plt.close(ax.figure)


def _simulate(args) -> int:
    import numpy as np

    kinds = {".csv": "csv", ".nc": "netCDF", ".png": "chart"}
    problem = args.out and _out_problem(args.out, kinds, "give a .csv, .nc or .png file")
    if problem:
        return _fail(problem)
    model, initial, velocity, span = _load_model(args.source)
    t_end = args.t_end if args.t_end is not None else (span[1] if span else 10.0)
    res = model.simulate(t_end, initial={**initial, **_merged(args.initial)},
                         velocity={**velocity, **_merged(args.velocity)}, params=_merged(args.param) or None,
                         points=args.points, method=args.method)
    print(f"{model.name}: {len(res.t)} points from t = {res.t[0]:g} to {res.t[-1]:g}, method {res.method}")
    labels = [label.strip() for group in args.output or [] for label in group.split(",") if label.strip()]
    columns = {label: _channels.output_series(model, res, label, _merged(args.param)) for label in labels} or None
    shown = columns or {name: res[name] for name in res.names}
    if not args.out:
        for name, values in shown.items():
            rate = f", {name}' = {res.velocity(name)[-1]:.10g}" if columns is None else ""
            print(f"  {name} = {values[-1]:.10g}{rate}")
        return 0
    try:
        suffix = Path(args.out).suffix.lower()
        if suffix == ".csv":
            res.to_csv(args.out, columns)
        elif suffix == ".nc":
            data = res.to_xarray()
            if columns:
                data = data.assign({label: ("time", values) for label, values in columns.items()})[list(columns)]
            data.to_netcdf(args.out)
        else:
            _simulation_chart(res, columns, args.out)
    except OSError as exc:
        return _fail(_write_failure("--out", args.out, exc))
    names = list(shown)
    if suffix == ".png" and columns is None and len(names) > _result.PLOT_SERIES:
        print(f"the chart draws the first {_result.PLOT_SERIES} of {len(names)} coordinates: --output names the ones "
              f"to draw")
    print(f"written: {args.out} ({kinds[suffix]}; final {', '.join(f'{n} = {shown[n][-1]:.6g}' for n in names[:4])}"
          f"{', …' if len(names) > 4 else ''}; max |x| {max(float(np.max(np.abs(v))) for v in shown.values()):.6g})")
    return 0


def _convert(args) -> int:
    problem = _out_problem(args.out, (".json",), "a model file is JSON: give a .json file")
    if problem:
        return _fail(problem)
    model = _load_model(args.source)[0]
    try:
        model.save(args.out)
    except OSError as exc:
        return _fail(_write_failure("--out", args.out, exc))
    print(f"written: {args.out} (model {model.name!r}: {len(model.components)} components, "
          f"coordinates {', '.join(model.coordinate_names)})")
    return 0


def _cache(args) -> int:
    """``lagrangian cache [--clear]``: the compiled-code cache (see :mod:`lagrangian.numerics.c_build`)."""
    if args.clear:
        done = _c_build.clear_cache()
        if not done["directory"].is_dir():
            print(f"{done['directory']}: nothing to clear (no such directory)")
            return 0
        left = f"; {done['left']} files left (a build running now, or not the cache's)" if done["left"] else ""
        print(f"{done['directory']}: removed {done['files']} files ({done['bytes'] / 2**20:.1f} MiB){left}")
        return 0
    usage = _c_build.cache_usage()
    print(f"directory: {usage['directory']}{'' if usage['exists'] else ' (not made yet)'}\n"
          f"files: {usage['files']} ({usage['libraries']} libraries)\nsize: {usage['bytes'] / 2**20:.1f} MiB "
          f"(bound {usage['bound'] / 2**20:.1f} MiB: lagrangian.limits.cache_bytes)")
    if usage["problem"]:
        print(f"not used: {usage['problem']}; compiled code goes to a private directory of each process instead")
    return 0


def _equations(args) -> int:
    model = _load_model(args.source)[0]
    if args.latex:
        print(model.latex())
        return 0
    print(model.describe())  # components, coordinates, the Lagrangian and the equations
    return 0


def _run(argv: list[str] | None) -> int:
    parser = _parser()
    try:
        try:
            args = parser.parse_args(argv)
        except SystemExit as exc:  # --help, --version, or a usage error already reported
            return exc.code if isinstance(exc.code, int) else (0 if exc.code is None else EXIT_USAGE)
        if args.command is None:
            parser.print_usage(sys.stderr)
            print("lagrangian: error: no command given: choose one of plugins, kinds, integrators, bench, scene, ac, sweep, "
                  "simulate, convert, equations, cache (see 'lagrangian --help')", file=sys.stderr)
            return EXIT_USAGE
        registry = _registry.default_registry()
        if args.command == "bench":
            return _bench(args, registry)
        if args.command == "scene":
            return _scene(args)
        if args.command == "ac":
            return _ac(args)
        if args.command == "sweep":
            return _sweep(args)
        if args.command == "simulate":
            return _simulate(args)
        if args.command == "equations":
            return _equations(args)
        if args.command == "convert":
            return _convert(args)
        if args.command == "cache":
            return _cache(args)
        text = {"plugins": registry.describe, "kinds": lambda: _kinds(registry),
                "integrators": lambda: _integrators(registry)}
        print(text[args.command]())
        return 0
    except LagrangianError as exc:
        return _fail(str(exc))
    except Warning as exc:  # a warning turned into an error (python -W error)
        return _fail(f"{type(exc).__name__}: {exc}")
    except KeyboardInterrupt:
        return EXIT_INTERRUPTED


def _discard_stdout() -> None:
    """Point standard output at the null device, so that flushing it at exit cannot fail again."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        try:
            os.dup2(devnull, sys.stdout.fileno())
        finally:
            os.close(devnull)
    except (OSError, ValueError, AttributeError):  # no file descriptor behind sys.stdout (output captured in-process)
        pass


#: OpenBLAS's worker threads spin for ``2**28`` cycles (about 0.1 s) waiting for work when they start and after each
#: parallel call, before they sleep; ``OPENBLAS_THREAD_TIMEOUT`` sets the exponent (4 to 30).  Measured on this
#: package's 200-section ladder (``benchmarks/coldstart.py``, 2 cores): the whole ``lagrangian simulate`` process
#: takes 0.92 s of CPU with the default and 0.70 s with 4, in the same wall time; on 600 sections the second thread
#: still shortens the run (2.9 s against 4.3 s on one thread) for 4.3 s of CPU against 5.7 s.  Set only where
#: NumPy is not yet imported (OpenBLAS reads it when it loads) and the environment does not set it; child processes
#: (Dask workers) inherit it.
BLAS_THREAD_TIMEOUT = "4"


def main(argv: list[str] | None = None) -> int:
    """Run the command line ``lagrangian COMMAND`` (``argv``, default ``sys.argv[1:]``); return the exit status.

    Errors are reported on standard error and turned into the status (see the
    module's documentation): 2 for usage errors, 1 for failures while
    running, 141 when standard output was closed early; ``SystemExit`` is
    never raised.  Warnings raised while the command runs are printed as
    ``lagrangian: warning: <message>``; the warning display and filters are
    restored on return.
    """
    if "numpy" not in sys.modules:  # see BLAS_THREAD_TIMEOUT
        os.environ.setdefault("OPENBLAS_THREAD_TIMEOUT", BLAS_THREAD_TIMEOUT)
    with warnings.catch_warnings():
        warnings.showwarning = _show_warning
        try:
            status = _run(argv)
            sys.stdout.flush()
        except BrokenPipeError:
            _discard_stdout()
            return EXIT_BROKEN_PIPE
    return status


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
