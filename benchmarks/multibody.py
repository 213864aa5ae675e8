"""Rigid-body dynamics against Pinocchio: build, one evaluation of the accelerations, and a 5 s run.

Pinocchio (PyPI ``pin``) computes the accelerations of a kinematic tree by Featherstone's articulated-body
algorithm (``pinocchio.aba``) in C++; we derive the equations symbolically and compile them.  Both are given the
same models, in the same coordinates, so that both solve the same ODE in the same state:

- **planar chain of n links** (``--planar 10,20,50,100``): uniform rods of 1 kg and 0.5 m (as ``examples/pendulums.py``
  writes its n-link pendulum: ``rod`` bodies on ``revolute`` joints, relative angles, ``dim=2``), gravity 9.81
  m/s² along −y.  Pinocchio: ``JointModelRZ`` joints in the x-y plane, each rod a body of mass m, centre of mass
  (L/2, 0, 0) and inertia diag(0, mL²/12, mL²/12) about it, ``model.gravity.linear = (0, −9.81, 0)``.  Start:
  the first rod 0.3 rad from hanging, the others within ±0.1 rad of straight, rates within ±0.2 rad/s
  (a swing whose 5 s run is well conditioned: a livelier start makes the long chains chaotic, so that no
  tolerance the runs can reach bounds the error of either).
- **spatial chain of n bodies on spherical joints** (``--spatial 5,10,30``): ``benchmarks/spatial.py``'s chain
  (body-fixed x-y-z angles; its masses, inertias and offsets), started as the planar chain is (the first angle
  0.3 rad, the others within ±0.1 rad, rates within ±0.2 rad/s: ``spatial.py``'s livelier start makes 30 bodies
  chaotic within the 5 s run, where no tolerance bounds either run's error).  Pinocchio: each spherical joint a chain
  ``JointModelRX``, ``JointModelRY``, ``JointModelRZ`` with massless bodies between them, so that its
  coordinates are the same three angles (R = R_x(α) R_y(β) R_z(γ)).

Before anything is timed both right-hand sides are compared at 5 random states: the largest relative difference
of the joint accelerations (max |a_ours − a_pin| / max |a_pin|) must be below 1e-10 (``agreement_max_rel``).

Figures (CPU time, ``time.process_time``; ours and Pinocchio interleaved, best of ``--repeat``):

- ``build_s``: ours, a cold build in a fresh process with an empty compiled-code cache (``LAGRANGIAN_CACHE_DIR``
  a new temporary directory): the model's components, the derivation, a first ``simulate(1e-6, points=2)`` with
  default options and one with ``compiled="native"`` (C source and its compilation): the process's own CPU time
  plus that of the C compiler it runs.  The runtime library (the tape interpreter and the stepping loops, the same
  for every model, built once per machine by ``make setup``) is built in that process first and reported apart
  (``runtime_once_s``).  A build still running after ``--timeout`` s is stopped and reported as ``null``.
  Pinocchio: building its ``Model`` and ``Data`` in this process.
- ``rhs_us``: one evaluation of the accelerations called from Python at random states: ours the model's native
  library through ctypes (``CompiledModel.rhs``, as ``benchmarks/rhs.py`` times it), Pinocchio
  ``pinocchio.aba(model, data, q, v, tau)``; a Python loop of many calls divided by their number, nothing
  subtracted.  Beside them, the same evaluations in a loop in compiled code: our ``lg_rhs`` called from a C loop
  (``rhs_c_us``) and Pinocchio's ``abaInParallel`` with one thread over a batch of states (``aba_cpp_us``).
- ``run_s``: a 5 s run, output at 501 points, at equal error: ours ``Model.simulate`` with every option at its
  default (DOP853 stepped in C, rtol 1e-9, atol 1e-12), after a first call; Pinocchio
  ``scipy.integrate.solve_ivp(method="DOP853")`` over ``aba``, at the loosest tolerance (rtol from 1e-6 down by
  half decades to 1e-12, atol = 1e-3 rtol) whose error is no larger than ours (or than ``reference_spread``
  below, where ours is smaller than that).  Errors (``*_run_error``): the largest difference of the angles at the
  output points against ours at rtol 1e-12 (atol at its default, 1e-12: a tighter one is below the rounding noise
  of the long chains' accelerations, where the steps shrink without end).  ``reference_spread``: the same
  difference between that reference and Pinocchio + ``solve_ivp`` at rtol = atol = 1e-12, how far two tight
  solutions agree (an error below it is not resolved).
- ratios: ``rhs_vs_pinocchio`` (ours ÷ Pinocchio's time per evaluation in compiled loops: our ``lg_rhs`` in a C
  loop against ``abaInParallel``), ``call_vs_pinocchio`` (the same called from Python), ``run_vs_pinocchio_scipy`` (Pinocchio's run
  time ÷ ours); summaries ``rhs_vs_pinocchio_worst`` (the largest over the sizes), ``run_vs_pinocchio_scipy_worst``
  (the smallest), ``build_exponent`` (least-squares slope of log build_s against log n over the planar sizes).
- ``linearize_s``: ours, ``frequency.linearize`` of the built model about its hanging rest, in the build's process
  (forward derivatives through the recursion's steps; ``linearize_worst_s``, the largest over the sizes).

**MuJoCo** (``mujoco``, the ``bench`` extra) gets the same models in MJCF: hinge joints, a spatial body turned by
three hinges about its x, y and z axes in that order (MuJoCo's R = R_x(α) R_y(β) R_z(γ), the same coordinates).  Its
accelerations (``mj_forward``'s ``qacc``) must agree with ours to 1e-10 (``mujoco_agreement_rel``); then
``mujoco_rhs_us``: one ``mj_forward`` from Python; ``mujoco_c_us``: an RK4 step of ``mujoco.rollout`` in C divided
by its 4 evaluations; ``mujoco_run_s``: the 5 s run with its RK4 in C (``rollout``) at the longest step (0.01 s
halved up to eight times: every step divides the output spacing) whose error is no larger than ours.  Ratios
``rhs_vs_mujoco`` (our C loop ÷ its), ``run_vs_mujoco`` (its run ÷ ours), and their worst over the sizes.

Without Pinocchio or MuJoCo installed (``pip install pin mujoco``) their figures are ``null`` and ours are still
measured.

Prints a table and, as its last line, a JSON object.

Run: ``.venv/bin/python benchmarks/multibody.py [--planar 10,20,50,100] [--spatial 5,10,30] [--repeat 5] [--timeout 300]``
"""

from __future__ import annotations

import argparse
import ctypes
import json
import math
import os
import pickle
import shutil
import signal
import subprocess
import sys
import tempfile
import time
import warnings

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import spatial  # noqa: E402  (the spatial chain: benchmarks/spatial.py)

G = 9.81
SPAN = 5.0
POINTS = 501
LINK_M, LINK_L = 1.0, 0.5  # the planar chain's rods
REFERENCE = {"rtol": 1e-12, "atol": 1e-12}
STATES = 5  # random states of the agreement check
AGREEMENT = 1e-10
RTOLS = [10 ** (-k / 2) for k in range(12, 25)]  # 1e-6 … 1e-12, Pinocchio's tolerances tried in turn


# -- the models ----------------------------------------------------------------------------------------------------


def planar_ours(n: int):
    from lagrangian import models

    return models.pendulum_chain(n, m=LINK_M, length=LINK_L, g=G)


def planar_pinocchio(n: int):
    import pinocchio as pin

    model = pin.Model()
    I = LINK_M * LINK_L**2 / 12
    rod = pin.Inertia(LINK_M, np.array([LINK_L / 2, 0.0, 0.0]), np.diag([0.0, I, I]))
    parent = 0
    for k in range(n):
        place = pin.SE3(np.eye(3), np.array([LINK_L if k else 0.0, 0.0, 0.0]))
        parent = model.addJoint(parent, pin.JointModelRZ(), place, f"j{k}")
        model.appendBodyToJoint(parent, rod, pin.SE3.Identity())
    model.gravity.linear = np.array([0.0, -G, 0.0])
    return model, model.createData()


def spatial_pinocchio(n: int):
    import pinocchio as pin

    model = pin.Model()
    parent = 0
    for k in range(n):
        place = pin.SE3(np.eye(3), np.array([0.0, 0.0, -0.5 if k else 0.0]))
        parent = model.addJoint(parent, pin.JointModelRX(), place, f"j{k}_alpha")
        parent = model.addJoint(parent, pin.JointModelRY(), pin.SE3.Identity(), f"j{k}_beta")
        parent = model.addJoint(parent, pin.JointModelRZ(), pin.SE3.Identity(), f"j{k}_gamma")
        body = pin.Inertia(spatial.mass(k), np.array([0.0, 0.0, -0.25]), np.diag([0.02, 0.03, 0.04]))
        model.appendBodyToJoint(parent, body, pin.SE3.Identity())
    model.gravity.linear = np.array([0.0, 0.0, -G])
    return model, model.createData()


def planar_mujoco(n: int) -> str:
    """The planar chain in MJCF: hinge joints about z, each rod's inertia about its centre of mass (none about its
    own axis: a trillionth, which the planar motion never reads)."""
    I = LINK_M * LINK_L**2 / 12
    body = ""
    for k in reversed(range(n)):
        body = (f'<body pos="{LINK_L if k else 0.0} 0 0"><joint type="hinge" axis="0 0 1"/>'
                f'<inertial pos="{LINK_L / 2} 0 0" mass="{LINK_M}" diaginertia="1e-12 {I!r} {I!r}"/>{body}</body>')
    return _mjcf(f"0 {-G} 0", body)


def spatial_mujoco(n: int) -> str:
    """The spatial chain in MJCF: three hinges about the body's x, y and z axes at its joint (MuJoCo turns a body by
    its joints in their order, R = R_x(α) R_y(β) R_z(γ)), each body's inertia about its centre of mass."""
    body = ""
    for k in reversed(range(n)):
        hinges = "".join(f'<joint type="hinge" axis="{a}"/>' for a in ("1 0 0", "0 1 0", "0 0 1"))
        body = (f'<body pos="0 0 {-0.5 if k else 0.0}">{hinges}<inertial pos="0 0 -0.25" mass="{spatial.mass(k)!r}" '
                f'diaginertia="0.02 0.03 0.04"/>{body}</body>')
    return _mjcf(f"0 0 {-G}", body)


def _mjcf(gravity: str, body: str) -> str:
    return (f'<mujoco><option gravity="{gravity}" integrator="RK4" timestep="0.01"/>'
            f"<worldbody>{body}</worldbody></mujoco>")


MODELS = {"planar": (planar_ours, planar_pinocchio), "spatial": (spatial.ours, spatial_pinocchio)}
MUJOCO = {"planar": planar_mujoco, "spatial": spatial_mujoco}
#: MuJoCo's RK4 steps tried in turn, longest first: 0.01 s halved eight times (each divides the output spacing)
STEPS = [0.01 / 2**k for k in range(9)]


def start(kind: str, n: int) -> tuple[np.ndarray, np.ndarray]:
    """The run's initial angles and rates."""
    if kind == "spatial":  # as the planar chain's: spatial.initial's livelier start makes 30 bodies chaotic in 5 s
        rng = np.random.default_rng(3)
        q0 = rng.uniform(-0.1, 0.1, 3 * n)
        q0[0] = 0.3
        return q0, rng.uniform(-0.2, 0.2, 3 * n)
    rng = np.random.default_rng(3)
    q0 = rng.uniform(-0.1, 0.1, n)
    q0[0] = -math.pi / 2 + 0.3
    return q0, rng.uniform(-0.2, 0.2, n)


def rest(kind: str, n: int) -> dict:
    """The chain at rest, hanging: the operating point of its linearization (``linearize_s``)."""
    return {"theta_j0": -math.pi / 2} if kind == "planar" else {}


def random_states(kind: str, n: int, count: int, seed: int) -> np.ndarray:
    """Rows ``(q, q̇)`` at random (the spatial angles away from the gimbal lock at β = ±π/2)."""
    rng = np.random.default_rng(seed)
    dof = n if kind == "planar" else 3 * n
    span = math.pi if kind == "planar" else 1.0
    return np.hstack([rng.uniform(-span, span, (count, dof)), rng.uniform(-2.0, 2.0, (count, dof))])


def cpu(mark: os.times_result) -> tuple[float, float]:
    """CPU seconds of this process and of its finished child processes (the C compiler)."""
    return mark.user + mark.system, mark.children_user + mark.children_system


# -- our cold build, in a child process ------------------------------------------------------------------------------


def child_build(kind: str, n: int, out: str) -> dict:
    """The cold build, timed in this fresh process (imports and the plugin registry before the clock starts); the
    built model is pickled to ``out`` (with its derivation) for the timings that follow, which load it with this
    process's cache and its native library rather than derive it again."""
    import lagrangian as lg
    from lagrangian import codegen, frequency

    warnings.simplefilter("ignore", lg.InitialConditionWarning)
    lg.default_registry()
    before = cpu(os.times())
    codegen.runtime()  # model-independent, built once per machine (make setup)
    after = cpu(os.times())
    runtime_s = sum(after) - sum(before)
    q0, v0 = start(kind, n)
    marks = [(time.process_time(), os.times())]
    model = MODELS[kind][0](n)
    model.eq  # the derivation
    marks.append((time.process_time(), os.times()))
    names = model.coordinate_names
    run = dict(initial=dict(zip(names, q0)), velocity=dict(zip(names, v0)), points=2)
    first = model.simulate(1e-6, **run)  # default options: the tapes, the tape interpreter
    marks.append((time.process_time(), os.times()))
    native = model.simulate(1e-6, compiled="native", **run)  # C source and its compilation
    marks.append((time.process_time(), os.times()))
    own = [b[0] - a[0] for a, b in zip(marks, marks[1:])]
    cc = [cpu(b[1])[1] - cpu(a[1])[1] for a, b in zip(marks, marks[1:])]
    began = time.process_time()
    linear = frequency.linearize(model, rest(kind, n))  # (through the recursion: the closed form is never derived)
    linearize_s = time.process_time() - began
    lowest = float(np.sqrt(np.min(np.abs(np.linalg.eigvals(np.linalg.solve(linear.M, linear.K))))))
    with open(out, "wb") as fh:
        pickle.dump(model, fh)
    return {"linearize_s": linearize_s, "lowest_rad_s": lowest, "build_s": sum(own) + sum(cc), "own_s": sum(own), "cc_s": sum(cc), "derive_s": own[0] + cc[0],
            "first_run_s": own[1] + cc[1], "native_s": own[2] + cc[2], "runtime_once_s": runtime_s,
            "first_by": first.notes[0] if first.notes else "", "native_by": native.notes[0] if native.notes else ""}


def cold_build(kind: str, n: int, timeout: float, cache: str, out: str) -> dict:
    """Run :func:`child_build` in a fresh process with the empty cache ``cache``; ``{"error": ...}`` on failure."""
    env = {**os.environ, "LAGRANGIAN_CACHE_DIR": cache}
    began = time.perf_counter()
    proc = subprocess.Popen([sys.executable, __file__, "--child", kind, str(n), out], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env=env, start_new_session=True)
    try:
        stdout, stderr = proc.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)  # the child and the C compiler it may be running
        proc.communicate()
        return {"error": f"timed out after {timeout:g} s"}
    if proc.returncode:
        return {"error": (stderr.strip().splitlines() or [f"exit status {proc.returncode}"])[-1]}
    return {**json.loads(stdout.strip().splitlines()[-1]), "wall_s": time.perf_counter() - began}


# -- timing helpers ----------------------------------------------------------------------------------------------------

DRIVER_C = r"""
typedef int (*rhs_fn)(const void *ctx, double t, const double *y, double *dy);
/* calls f at the states Y (nstates rows of dim), cycling; the last result in out */
int bench_fn(rhs_fn f, const void *ctx, long calls, const double *Y, long nstates, long dim, double *out) {
    int rc = 0;
    for (long k = 0; k < calls; k++) rc |= f(ctx, 0.0, Y + (k % nstates) * dim, out);
    return rc;
}
"""


class CLoop:
    """Our compiled ``lg_rhs`` called in a loop in C (the way the stepping loops call it)."""

    def __init__(self, compiled, workdir: str):
        from lagrangian import codegen

        src, lib = os.path.join(workdir, "driver.c"), os.path.join(workdir, "driver.so")
        with open(src, "w") as fh:
            fh.write(DRIVER_C)
        subprocess.run([codegen.compiler(), *codegen.FLAGS, "-o", lib, src], check=True)
        self.dll, self.compiled = ctypes.CDLL(lib), compiled
        self.dll.bench_fn.argtypes = [ctypes.c_void_p] * 2 + [ctypes.c_long, ctypes.c_void_p, ctypes.c_long,
                                                              ctypes.c_long, ctypes.c_void_p]

    def __call__(self, Y: np.ndarray, calls: int) -> float:
        Y = np.ascontiguousarray(Y)
        out = np.zeros(Y.shape[1])
        began = time.process_time()
        rc = self.dll.bench_fn(self.compiled._rhs_ptr, self.compiled._ctx, calls, Y.ctypes.data, Y.shape[0],
                               Y.shape[1], out.ctypes.data)
        seconds = time.process_time() - began
        if rc:
            raise RuntimeError("lg_rhs failed in the C loop")
        return seconds / calls * 1e6


def per_call_us(f, states: np.ndarray, calls: int) -> float:
    """CPU µs per call of ``f(y)`` over ``calls`` calls cycling through ``states``."""
    k = len(states)
    began = time.process_time()
    for i in range(calls):
        f(states[i % k])
    return (time.process_time() - began) / calls * 1e6


def best_cpu(f) -> tuple[float, object]:
    began = time.process_time()
    out = f()
    return time.process_time() - began, out


# -- one model, one size ---------------------------------------------------------------------------------------------


def measure(kind: str, n: int, args, pin, mj=None) -> dict:
    out: dict = {"kind": kind, "n": n, "dof": n if kind == "planar" else 3 * n, "notes": []}
    dof = out["dof"]
    scratch = tempfile.mkdtemp(prefix="lg-multibody-")
    try:
        cache = os.path.join(scratch, "cache")
        os.mkdir(cache)
        pickled = os.path.join(scratch, "model.pickle")
        print(f"[{kind} {n}] our cold build (timeout {args.timeout:g} s) ...", file=sys.stderr, flush=True)
        built = cold_build(kind, n, args.timeout, cache, pickled)
        out["build"] = built
        if "error" in built:
            out["notes"].append(f"{kind} {n}: our build: {built['error']}")
            model = None
        else:
            from lagrangian import codegen

            codegen.set_cache_dir(cache)  # the native library the child built
            with open(pickled, "rb") as fh:
                model = pickle.load(fh)
        measured = compare(kind, n, dof, model, args, pin, scratch, mj)
        out["notes"] += measured.pop("notes")
        out.update(measured)
    finally:
        shutil.rmtree(scratch, ignore_errors=True)
    return out


def agreement(kind: str, n: int, dof: int, ours_rhs, theirs) -> float:
    """The largest relative difference of the accelerations, ours against ``theirs(y)``, at random states."""
    worst = 0.0
    for y in random_states(kind, n, STATES, seed=5):
        a, b = ours_rhs(y)[dof:], np.array(theirs(y))
        worst = max(worst, float(np.max(np.abs(a - b)) / np.max(np.abs(b))))
    return worst


def with_mujoco(kind: str, n: int, dof: int, out: dict, ours_rhs, q0, v0, reference, args, mj) -> None:
    """MuJoCo's figures into ``out``: agreement of the accelerations, one ``mj_forward`` from Python, an RK4 step's
    share per evaluation in C (``rollout``), and a 5 s RK4 run at the longest step whose error is no larger than
    ours (``run_error``)."""
    from mujoco import rollout

    m = mj.MjModel.from_xml_string(MUJOCO[kind](n))
    d = mj.MjData(m)
    if m.nv != dof:
        raise RuntimeError(f"{kind} {n}: MuJoCo's model has {m.nv} degrees of freedom, not {dof}")

    def forward(y):
        d.qpos[:], d.qvel[:] = y[:dof], y[dof:]
        mj.mj_forward(m, d)
        return d.qacc

    worst = agreement(kind, n, dof, ours_rhs, forward)
    out["mujoco_agreement_rel"] = worst
    if not worst <= AGREEMENT:
        out["notes"].append(f"{kind} {n}: MuJoCo's accelerations DISAGREE, relative difference {worst:.2e}")
    states = random_states(kind, n, 64, seed=11)
    per_call_us(forward, states, 200)
    out["mujoco_rhs_us"] = min(per_call_us(forward, states, 2000) for _ in range(args.repeat))
    spec = mj.mjtState.mjSTATE_FULLPHYSICS
    start = np.zeros(mj.mj_stateSize(m, spec))
    d.qpos[:], d.qvel[:], d.time = q0, v0, 0.0
    mj.mj_getState(m, d, start, spec)

    def run(dt):
        m.opt.timestep = dt
        steps = int(round(SPAN / dt))
        state, _ = rollout.rollout(m, d, start[None, :], nstep=steps)
        every = int(round((SPAN / (POINTS - 1)) / dt))
        q = state[0, every - 1::every, 1:1 + dof]
        return np.vstack([q0, q]), steps

    calls = 2000
    m.opt.timestep = 1e-3
    out["mujoco_c_us"] = min(best_cpu(lambda: rollout.rollout(m, d, start[None, :], nstep=calls))[0]
                             for _ in range(args.repeat)) / (4 * calls) * 1e6  # (an RK4 step: 4 evaluations)
    if reference is None:
        return
    target = max(out["run_error"], out.get("reference_spread", 0.0))
    for dt in STEPS:
        q, steps = run(dt)
        error = float(np.max(np.abs(q - reference)))
        if error <= target:
            break
    else:
        out["notes"].append(f"{kind} {n}: MuJoCo's RK4 did not reach the error {target:.1e} at a step of {STEPS[-1]:.1e} s")
    out.update(mujoco_step=dt, mujoco_run_error=error,
               mujoco_run_s=min(best_cpu(lambda: run(dt))[0] for _ in range(args.repeat)))


def compare(kind: str, n: int, dof: int, model, args, pin, scratch: str, mj=None) -> dict:
    out: dict = {"notes": []}
    states = random_states(kind, n, 64, seed=11)
    q0, v0 = start(kind, n)
    ours_rhs = compiled = None
    if model is not None:
        compiled = model.numeric().compile("native")
        out["ours_evaluated_by"] = compiled.describe()
        ours_rhs = (lambda c: lambda y: c.rhs(0.0, y))(compiled)
    pin_model = pin_data = None
    if pin is not None:
        build = MODELS[kind][1]
        pin_model, pin_data = build(n)
        out["pin_build_s"] = min(best_cpu(lambda: build(n))[0] for _ in range(args.repeat))
        tau = np.zeros(dof)
        pin_rhs = (lambda m, d: lambda y: pin.aba(m, d, y[:dof], y[dof:], tau))(pin_model, pin_data)

    # agreement of the accelerations
    if ours_rhs is not None and pin is not None:
        worst = agreement(kind, n, dof, ours_rhs, pin_rhs)
        out["agreement_rel"] = worst
        if not worst <= AGREEMENT:
            out["notes"].append(f"{kind} {n}: accelerations DISAGREE, relative difference {worst:.2e} > {AGREEMENT:g}")

    # one evaluation: Python loops, then the loops in compiled code
    print(f"[{kind} {n}] right-hand side ...", file=sys.stderr, flush=True)
    funcs = {}
    if ours_rhs is not None:
        funcs["ours"] = ours_rhs
    if pin is not None:
        funcs["pin"] = pin_rhs
    for f in funcs.values():
        per_call_us(f, states, 200)  # warm-up
    slowest = max([per_call_us(f, states, 500) for f in funcs.values()] or [1.0])
    calls = int(min(max(0.1e6 / slowest, 500), 200000))  # about 0.1 s a batch
    timings: dict[str, list] = {k: [] for k in funcs}
    c_loop = CLoop(compiled, scratch) if compiled is not None else None
    if c_loop is not None:
        timings["ours_c"] = []
    if pin is not None:
        pool = pin.ModelPool(pin_model, 1)
        batch = int(min(max(calls, 1000), 100000))
        Q = np.ascontiguousarray(np.resize(states[:, :dof], (batch, dof)).T)
        V = np.ascontiguousarray(np.resize(states[:, dof:], (batch, dof)).T)
        T = np.zeros((dof, batch))
        pin.abaInParallel(1, pool, Q, V, T)
        timings["pin_cpp"] = []
    for _ in range(args.repeat):  # interleaved
        for name, f in funcs.items():
            timings[name].append(per_call_us(f, states, calls))
        if c_loop is not None:
            timings["ours_c"].append(c_loop(states, 10 * calls))
        if pin is not None:
            seconds, _ = best_cpu(lambda: pin.abaInParallel(1, pool, Q, V, T))
            timings["pin_cpp"].append(seconds / batch * 1e6)
    best = {k: min(v) for k, v in timings.items()}
    out.update(rhs_us=best.get("ours"), pin_rhs_us=best.get("pin"), rhs_c_us=best.get("ours_c"),
               pin_aba_cpp_us=best.get("pin_cpp"))

    # a 5 s run at equal error
    print(f"[{kind} {n}] runs ...", file=sys.stderr, flush=True)
    t_eval = np.linspace(0.0, SPAN, POINTS)
    reference = ours_run = None
    if model is not None:
        names = model.coordinate_names
        run = dict(initial=dict(zip(names, q0)), velocity=dict(zip(names, v0)), points=POINTS)

        def ours_run():
            res = model.simulate(SPAN, **run)
            return np.array([res[name] for name in names]).T, res

        ref = model.simulate(SPAN, **run, **REFERENCE)
        reference = np.array([ref[name] for name in names]).T
        q, res = ours_run()  # the first call (warm-up)
        out["run_error"] = float(np.max(np.abs(q - reference)))
        out["ours_run_by"] = f"{res.method}, {res.notes[0] if res.notes else ''}"
    if pin is not None:
        from scipy.integrate import solve_ivp

        tau = np.zeros(dof)

        def f(t, y):
            return np.concatenate([y[dof:], pin.aba(pin_model, pin_data, y[:dof], y[dof:], tau)])

        def pin_run(rtol, atol=None):
            sol = solve_ivp(f, (0.0, SPAN), np.concatenate([q0, v0]), method="DOP853", t_eval=t_eval, rtol=rtol,
                            atol=rtol * 1e-3 if atol is None else atol)
            if not sol.success:
                raise RuntimeError(sol.message)
            return sol.y[:dof].T, sol

        if reference is not None:
            q, _ = pin_run(REFERENCE["rtol"], REFERENCE["atol"])
            out["reference_spread"] = float(np.max(np.abs(q - reference)))
            target = max(out["run_error"], out["reference_spread"])  # (a smaller error is not resolved)
            if out["reference_spread"] > out["run_error"]:
                out["notes"].append(f"{kind} {n}: our error {out['run_error']:.1e} is below the reference spread "
                                    f"{out['reference_spread']:.1e}: Pinocchio's run is held to the spread")
            for rtol in RTOLS:  # loosest first: the first whose error is no larger than ours
                q, sol = pin_run(rtol)
                error = float(np.max(np.abs(q - reference)))
                if error <= target:
                    break
            else:
                out["notes"].append(f"{kind} {n}: Pinocchio + solve_ivp did not reach the error {target:.1e} "
                                    f"at rtol {RTOLS[-1]:.0e}")
            out.update(pin_rtol=rtol, pin_run_error=error, pin_nfev=int(sol.nfev))
        else:
            out.update(pin_rtol=1e-9, pin_run_error=None)
            out["notes"].append(f"{kind} {n}: Pinocchio's run at rtol 1e-9, atol 1e-12 (our defaults): without our "
                                f"model no reference, its error not measured")
    runs: dict[str, list] = {}
    for _ in range(args.repeat):  # interleaved
        if model is not None:
            runs.setdefault("ours", []).append(best_cpu(ours_run)[0])
        if pin is not None:
            runs.setdefault("pin", []).append(best_cpu(lambda: pin_run(out["pin_rtol"]))[0])
    out.update(run_s=min(runs["ours"]) if "ours" in runs else None, pin_run_s=min(runs["pin"]) if "pin" in runs else None)
    if mj is not None and ours_rhs is not None:
        print(f"[{kind} {n}] MuJoCo ...", file=sys.stderr, flush=True)
        here = os.getcwd()
        os.chdir(scratch)  # (MuJoCo writes its warnings, an RK4 step too long to be stable, to MUJOCO_LOG.TXT here)
        try:
            with_mujoco(kind, n, dof, out, ours_rhs, q0, v0, reference, args, mj)
        finally:
            os.chdir(here)
    return out


# -- report ----------------------------------------------------------------------------------------------------------


def ratio(a, b):
    return None if a is None or b is None else a / b


def fmt(x, spec: str) -> str:
    width = spec.split(".")[0]
    return "n/a".rjust(int(width) if width.isdigit() else 0) if x is None else format(x, spec)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--planar", default="10,20,50,100", help="planar chain sizes (links), comma-separated; '' for none")
    ap.add_argument("--spatial", default="5,10,30", help="spatial chain sizes (bodies), comma-separated; '' for none")
    ap.add_argument("--repeat", type=int, default=5, help="timings per figure (the best is reported)")
    ap.add_argument("--timeout", type=float, default=300.0, help="seconds allowed to each of our cold builds")
    ap.add_argument("--child", nargs=3, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        kind, n, out = args.child
        print(json.dumps(child_build(kind, int(n), out)))
        return
    import lagrangian as lg

    warnings.simplefilter("ignore", lg.InitialConditionWarning)
    try:
        import pinocchio as pin
    except ImportError as exc:
        pin = None
        print(f"pinocchio is not importable ({exc}): its figures are null (pip install pin)")
    began = time.perf_counter()
    sizes = [("planar", int(s)) for s in args.planar.split(",") if s.strip()]
    sizes += [("spatial", int(s)) for s in args.spatial.split(",") if s.strip()]
    try:
        import mujoco as mj
    except ImportError as exc:
        mj = None
        print(f"mujoco is not importable ({exc}): its figures are null (pip install mujoco)")
    results = [measure(kind, n, args, pin, mj) for kind, n in sizes]

    print(f"Pinocchio {getattr(pin, '__version__', 'not installed')} against ours; CPU time, best of {args.repeat}; "
          f"run: {SPAN:g} s, {POINTS} points")
    head = (f"{'model':8} {'n':>3} {'dof':>4} | {'build s':>8} {'pin':>8} | {'rhs µs':>7} {'pin':>7} {'÷':>5} "
            f"{'C loop':>7} {'pin C++':>7} {'÷':>5} | {'run s':>7} {'pin':>7} {'÷':>5} {'error':>8} {'pin err':>8} "
            f"{'pin rtol':>8} {'spread':>8} | {'agree':>7}")
    print(head)
    print("-" * len(head))
    figures: dict = {}
    notes: list[str] = []
    for r in results:
        b = r["build"]
        key = f"{r['kind']}{r['n']}"
        r["rhs_ratio"], r["run_ratio"] = ratio(r["rhs_c_us"], r["pin_aba_cpp_us"]), ratio(r["pin_run_s"], r["run_s"])
        r["call_ratio"] = ratio(r["rhs_us"], r["pin_rhs_us"])
        print(f"{r['kind']:8} {r['n']:>3} {r['dof']:>4} | {fmt(b.get('build_s'), '8.2f')} "
              f"{fmt(r.get('pin_build_s'), '8.1e')} | {fmt(r['rhs_us'], '7.2f')} {fmt(r['pin_rhs_us'], '7.2f')} "
              f"{fmt(r['call_ratio'], '5.2f')} {fmt(r['rhs_c_us'], '7.3f')} {fmt(r['pin_aba_cpp_us'], '7.3f')} "
              f"{fmt(r['rhs_ratio'], '5.2f')} | "
              f"{fmt(r['run_s'], '7.3f')} {fmt(r['pin_run_s'], '7.3f')} {fmt(r['run_ratio'], '5.1f')} "
              f"{fmt(r.get('run_error'), '8.1e')} {fmt(r.get('pin_run_error'), '8.1e')} {fmt(r.get('pin_rtol'), '8.0e')} "
              f"{fmt(r.get('reference_spread'), '8.1e')} | "
              f"{fmt(r.get('agreement_rel'), '7.0e')}")
        notes += r["notes"]
        if "error" not in b:
            notes.append(f"{key}: our build {b['build_s']:.2f} s = derivation {b['derive_s']:.2f} + first run "
                         f"{b['first_run_s']:.2f} ({b['first_by']}) + native {b['native_s']:.2f} s; of which C compiler "
                         f"{b['cc_s']:.2f} s; wall {b['wall_s']:.1f} s with the process start")
        figures.update({
            f"{key}_build_s": b.get("build_s"), f"{key}_pinocchio_build_s": r.get("pin_build_s"),
            f"{key}_rhs_us": r["rhs_us"], f"{key}_pinocchio_rhs_us": r["pin_rhs_us"],
            f"{key}_rhs_c_us": r["rhs_c_us"], f"{key}_pinocchio_aba_cpp_us": r["pin_aba_cpp_us"],
            f"{key}_run_s": r["run_s"], f"{key}_pinocchio_run_s": r["pin_run_s"],
            f"{key}_run_error": r.get("run_error"), f"{key}_pinocchio_run_error": r.get("pin_run_error"),
            f"{key}_pinocchio_rtol": r.get("pin_rtol"), f"{key}_reference_spread": r.get("reference_spread"),
            f"{key}_rhs_vs_pinocchio": r["rhs_ratio"], f"{key}_call_vs_pinocchio": r["call_ratio"],
            f"{key}_run_vs_pinocchio_scipy": r["run_ratio"], f"{key}_agreement_rel": r.get("agreement_rel"),
            f"{key}_build_derive_s": b.get("derive_s"), f"{key}_build_cc_s": b.get("cc_s"),
            f"{key}_linearize_s": b.get("linearize_s"),
        })
        if "error" in b:
            figures[f"{key}_build_note"] = b["error"]
    if mj is not None:
        print(f"\nMuJoCo {mj.__version__} against ours (RK4 at the longest step, halving 0.01 s, whose error is no larger "
              f"than ours; an evaluation in C: an RK4 step of rollout ÷ 4)")
        print(f"{'model':8} {'n':>3} | {'rhs µs':>7} {'mujoco':>7} | {'C loop':>7} {'mujoco':>7} {'÷':>5} | {'run s':>7} "
              f"{'mujoco':>7} {'÷':>5} {'step':>8} {'error':>8} | {'agree':>7}")
        for r in results:
            key = f"{r['kind']}{r['n']}"
            r["mujoco_rhs_ratio"] = ratio(r["rhs_c_us"], r.get("mujoco_c_us"))
            r["mujoco_run_ratio"] = ratio(r.get("mujoco_run_s"), r["run_s"])
            print(f"{r['kind']:8} {r['n']:>3} | {fmt(r['rhs_us'], '7.2f')} {fmt(r.get('mujoco_rhs_us'), '7.2f')} | "
                  f"{fmt(r['rhs_c_us'], '7.3f')} {fmt(r.get('mujoco_c_us'), '7.3f')} {fmt(r['mujoco_rhs_ratio'], '5.2f')} | "
                  f"{fmt(r['run_s'], '7.3f')} {fmt(r.get('mujoco_run_s'), '7.3f')} {fmt(r['mujoco_run_ratio'], '5.1f')} "
                  f"{fmt(r.get('mujoco_step'), '8.1e')} {fmt(r.get('mujoco_run_error'), '8.1e')} | "
                  f"{fmt(r.get('mujoco_agreement_rel'), '7.0e')}")
            figures.update({f"{key}_{k}": r.get(k) for k in ("mujoco_rhs_us", "mujoco_c_us", "mujoco_run_s", "mujoco_step",
                                                              "mujoco_run_error", "mujoco_agreement_rel")})
            figures.update({f"{key}_rhs_vs_mujoco": r["mujoco_rhs_ratio"], f"{key}_run_vs_mujoco": r["mujoco_run_ratio"]})
        mj_runs = [r["mujoco_run_ratio"] for r in results if r.get("mujoco_run_ratio") is not None]
        mj_rhs = [r["mujoco_rhs_ratio"] for r in results if r.get("mujoco_rhs_ratio") is not None]
        figures.update(run_vs_mujoco_worst=min(mj_runs) if mj_runs else None,
                       rhs_vs_mujoco_worst=max(mj_rhs) if mj_rhs else None, mujoco_version=mj.__version__)
    rhs_ratios = [r["rhs_ratio"] for r in results if r["rhs_ratio"] is not None]
    run_ratios = [r["run_ratio"] for r in results if r["run_ratio"] is not None]
    planar = [(r["n"], r["build"]["build_s"]) for r in results if r["kind"] == "planar" and "build_s" in r["build"]]
    exponent = float(np.polyfit(np.log([n for n, _ in planar]), np.log([s for _, s in planar]), 1)[0]) if len(planar) > 1 else None
    agreement = [r["agreement_rel"] for r in results if "agreement_rel" in r]
    runtime = next((r["build"]["runtime_once_s"] for r in results if "runtime_once_s" in r["build"]), None)
    linearize = [r["build"]["linearize_s"] for r in results if r["build"].get("linearize_s") is not None]
    figures.update(linearize_worst_s=max(linearize) if linearize else None)
    figures.update(rhs_vs_pinocchio_worst=max(rhs_ratios) if rhs_ratios else None,
                   run_vs_pinocchio_scipy_worst=min(run_ratios) if run_ratios else None, build_exponent=exponent,
                   agreement_max_rel=max(agreement) if agreement else None,
                   agreement_ok=all(a <= AGREEMENT for a in agreement) if agreement else None,
                   runtime_once_s=runtime, pinocchio_version=getattr(pin, "__version__", None),
                   wall_s=time.perf_counter() - began)
    for note in notes:
        print("note:", note)
    print("build: ours cold (fresh process, empty cache: derivation, first run, native compilation, C compiler "
          f"included; the runtime library apart: {fmt(runtime, '.2f')} s once per machine), Pinocchio Model + Data "
          "in-process; rhs: per call from Python (ours CompiledModel.rhs via ctypes, Pinocchio pinocchio.aba), C loop "
          "and pin C++: the same in compiled loops (our lg_rhs, abaInParallel with 1 thread); ÷: ours/Pinocchio "
          "(rhs_vs_pinocchio: the compiled loops'); "
          "run: ours Model.simulate defaults, Pinocchio solve_ivp DOP853 on aba at the loosest tolerance with an "
          "error no larger than ours; ÷ run: Pinocchio/ours; error: max angle difference from ours at rtol 1e-12 "
          "(rad); spread: that reference against Pinocchio + solve_ivp at rtol = atol = 1e-12")
    print(json.dumps(figures))


if __name__ == "__main__":
    main()
