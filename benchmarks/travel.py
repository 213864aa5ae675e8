"""Models that travel: pickling, model files, FMI export and python-control, each checked by the receiving side.

- ``pickle_roundtrip_ok``: a model, a result, a sweep dataset, a frequency response, a transfer function, a
  linearization, a reduced model and every error of ``lagrangian.errors`` pickle and unpickle (``pickle`` and
  ``cloudpickle``), the unpickled model simulating bit for bit as the original.
- ``file_roundtrip_models``: the models of ``lagrangian.models``, of the examples (each function annotated to return
  a model whose arguments all have defaults) and of the examples' netlists, saved as model files and loaded back
  with identical equations (every entry of the mass matrix and the forcing the same, by
  ``lagrangian.identity.is_zero`` of the difference); ``file_roundtrip_failed`` names any that is not.
- ``fmu_models``, ``fmu_max_rel_error``: FMPy's run of the exported FMU (CVode, rtol 1e-12) against
  ``Model.simulate`` (the exact solution for linear models, DOP853 at rtol 1e-13 otherwise), the largest difference
  relative to each state's peak; ``fmu_validation_problems``: what ``fmpy.validation.validate_fmu`` finds.
- ``fmu_export_s``: ``to_fmu`` of the double pendulum, its compiled library cached (best of 5).
- ``control_bode_max_rel_error``: python-control's frequency response of ``LinearModel.to_control()`` against ours
  (mass–spring–damper, loudspeaker over 1–2000 Hz, a 20-section ladder).

Run: ``.venv/bin/python benchmarks/travel.py``; the last line is a JSON object of the figures.
"""

from __future__ import annotations

import importlib.util
import inspect
import json
import pickle
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

import lagrangian as lg
from lagrangian import models
from lagrangian.identity import is_zero

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"


def pickles() -> bool:
    import cloudpickle

    from lagrangian import errors, routh
    from lagrangian.frequency import frequency_response, linearize, transfer_function

    model = models.double_pendulum(0.3, 0.2)
    start = {"initial": {"theta_j1": -1.0, "theta_j2": -1.2}, "velocity": {"theta_j1": 0.0, "theta_j2": 0.0}}
    res = model.simulate(2.0, points=101, **start)
    rlc = models.rlc_ladder(5)
    lin = linearize(rlc, outputs=["i(L1)"])
    objects = [model, res, frequency_response(lin, [1.0, 10.0]), transfer_function(rlc, "V1", "i(L1)"), lin,
               routh.reduce(models.spherical_pendulum())]
    objects += [cls.__new__(cls) for cls in _errors(errors.LagrangianError)]
    for dumps, loads in ((pickle.dumps, pickle.loads), (cloudpickle.dumps, pickle.loads)):
        for obj in objects:
            loads(dumps(obj))
        again = loads(dumps(model)).simulate(2.0, points=101, **start)
        if not all(np.array_equal(res[n], again[n]) for n in res.names):
            return False
    return True


def _errors(cls):
    out = [cls]
    for sub in cls.__subclasses__():
        out += _errors(sub)
    return out


#: Builders that take arguments, called as their example calls them.
_CALLED = {
    "coupled_tanks_modes": [("tanks", ("charge",)), ("tanks", ("flux", 2e3))],
    "impulses": [("rhombus", (0.3, 0.25))],
    "isolator_transmissibility": [("isolator", (0.3,))],
    "pendulums": [("simple_pendulum", (0.8,)), ("chain", (5,))],
    "solenoid": [("plunger", ("flux",))],
}


def _builders():
    """Every model the project ships to try: ``lagrangian.models``, the examples' builders, the examples' netlists."""
    out = {f"models.{name}": getattr(models, name) for name in models.__all__ if name != "rlc_ladder"}
    out["models.rlc_ladder(10)"] = lambda: models.rlc_ladder(10)
    sys.path.insert(0, str(EXAMPLES))
    for path in sorted(EXAMPLES.glob("*.py")):
        spec = importlib.util.spec_from_file_location(f"_example_{path.stem}", path)
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        for name, fn in vars(module).items():
            if not inspect.isfunction(fn) or fn.__module__ != module.__name__:
                continue
            signature = inspect.signature(fn)
            returns = str(signature.return_annotation)
            if "Model" in returns and all(p.default is not p.empty for p in signature.parameters.values()):
                out[f"{path.stem}.{name}"] = fn
        for name, args in _CALLED.get(path.stem, ()):  # builders the example calls with arguments
            out[f"{path.stem}.{name}{args}"] = (lambda fn=getattr(module, name), args=args: fn(*args))
    from lagrangian.circuits.netlist import read_netlist_file

    for path in sorted(EXAMPLES.glob("*.cir")):
        out[path.name] = (lambda p=path: read_netlist_file(p).model)
    return out


def files() -> tuple[int, list[str]]:
    ok, failed = 0, []
    with tempfile.TemporaryDirectory() as where:
        for label, build in _builders().items():
            try:
                model = build()
                path = Path(where) / "m.json"
                model.save(path)
                loaded = lg.load(path)
                a, b = model.eq, loaded.eq
                same = all(is_zero(x - y) for x, y in zip(list(a.M) + list(a.f), list(b.M) + list(b.f)))
                same = same and a.M.shape == b.M.shape and a.names == b.names
            except lg.LagrangianError as exc:
                failed.append(f"{label}: {exc}")
                continue
            if same:
                ok += 1
            else:
                failed.append(f"{label}: equations differ")
    return ok, failed


def fmus() -> dict:
    from fmpy import simulate_fmu
    from fmpy.validation import validate_fmu

    cases = {
        "double pendulum": (models.double_pendulum(0.3, 0.2), 5.0,
                            {"initial": {"theta_j1": -1.0, "theta_j2": -1.2}, "velocity": {"theta_j1": 0.0, "theta_j2": 0.0}}),
        "loudspeaker": (models.loudspeaker(E=2.0), 0.05, {}),
        "rlc ladder": (models.rlc_ladder(10, E=1.0), 5.0, {}),
    }
    errors, problems, export = {}, 0, None
    with tempfile.TemporaryDirectory() as where:
        for label, (model, t_end, start) in cases.items():
            path = Path(where) / f"{label.replace(' ', '_')}.fmu"
            model.to_fmu(path, **start)
            problems += len(validate_fmu(str(path)))
            linear = model._linear(None)
            ours = model.simulate(t_end, points=501, method="exact" if linear else "DOP853",
                                  **({} if linear else {"rtol": 1e-13, "atol": 1e-15}), **start)
            names = [n for n in ours.names] + [f"{n}'" for n in ours.names]
            theirs = simulate_fmu(str(path), stop_time=t_end, output_interval=t_end / 500, relative_tolerance=1e-12,
                                  output=names)
            worst = 0.0
            for n in names:
                mine = ours[n] if not n.endswith("'") else ours.velocity(n[:-1])
                peak = max(float(np.max(np.abs(mine))), 1e-300)
                worst = max(worst, float(np.max(np.abs(np.interp(ours.t, theirs["time"], theirs[n]) - mine))) / peak)
            errors[label] = worst
        dp = cases["double pendulum"]
        dp[0].to_fmu(Path(where) / "warm.fmu", **dp[2])
        times = []
        for k in range(5):
            began = time.perf_counter()
            dp[0].to_fmu(Path(where) / f"dp{k}.fmu", **dp[2])
            times.append(time.perf_counter() - began)
        export = min(times)
    return {"fmu_models": len(errors), "fmu_max_rel_error": errors, "fmu_validation_problems": problems,
            "fmu_export_s": export}


def bode() -> float:
    from lagrangian.frequency import decades, frequency_response, linearize

    msd = lg.Model("msd")
    msd.add("mass", "m", "p", m=0.3)
    msd.add("spring", "k", ("ground", "p"), k=40.0)
    msd.add("damper", "c", ("ground", "p"), c=0.5)
    msd.add("force", "F", "p", F=0)
    cases = [(msd, ["F"], ["x_p"], decades(0.01, 100, 50)),
             (models.loudspeaker(), ["E"], ["i(Le)"], decades(1, 2000, 50)),
             (models.rlc_ladder(20), ["V1"], ["i(L1)"], decades(1e-3, 10, 50))]
    worst = 0.0
    for model, inputs, outputs, f in cases:
        lin = linearize(model, inputs=inputs, outputs=outputs)
        ours = frequency_response(lin, f).H[0, 0]
        theirs = np.array([complex(lin.to_control()(2j * np.pi * fk)) for fk in f])
        worst = max(worst, float(np.max(np.abs(theirs - ours) / np.abs(ours))))
    return worst


def main() -> None:
    figures = {"pickle_roundtrip_ok": pickles()}
    ok, failed = files()
    figures.update(file_roundtrip_models=ok, file_roundtrip_failed=failed)
    figures.update(fmus())
    figures["control_bode_max_rel_error"] = bode()
    print(f"{'figure':32} value")
    for key, value in figures.items():
        print(f"{key:32} {value}")
    print(json.dumps(figures, default=float))


if __name__ == "__main__":
    main()
