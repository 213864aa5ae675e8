"""Scenes: the minimal model answers exactly what the full model answers, and refuses what is not exact.

Each reduction kind is checked against the full model simulated tightly (agreement 1e-10 on the
requested outputs), and each has a case where it must not apply.
"""

from __future__ import annotations

import math
import re
import subprocess
import sys
import warnings

import numpy as np
import pytest
import sympy as sp
from hypothesis import given, settings
from hypothesis import strategies as st

import lagrangian as lg
from lagrangian.scene import Scene

TIGHT = {"rtol": 1e-13, "atol": 1e-15}


def full_run(model, span, scene_kwargs, **extra):
    return model.simulate(span, initial=scene_kwargs.get("initial"), velocity=scene_kwargs.get("velocity"),
                          t_eval=np.linspace(0, span, scene_kwargs.get("points", 1001)), **TIGHT, **extra)


def chain_and_solo(n=6):
    """A chain of n masses on springs, and, elsewhere, a lone oscillator; a shaker drives two more oscillators."""
    m = lg.Model("machine")
    for i in range(1, n + 1):
        m.add("mass", f"m{i}", f"p{i}", m=1 + 0.1 * i)
        m.add("spring", f"k{i}", (f"p{i - 1}" if i > 1 else "ground", f"p{i}"), k=1 + 0.3 * i)
    m.add("spring", "cubic_free", ("p1", "p3"), k=0.5)
    m.add("mass", "solo", "s", m=2)
    m.add("spring", "ks", ("ground", "s"), k=8)
    m.add("damper", "cs", ("ground", "s"), c=0.3)
    m.add("prescribed_motion", "shaker", "sh", position=sp.sin(3 * lg.t) / 10)
    m.add("mass", "a", "pa", m=1)
    m.add("spring", "ka", ("sh", "pa"), k=5)
    m.add("mass", "b", "pb", m=1)
    m.add("spring", "kb", ("sh", "pb"), k=2)
    return m


def state(model, seed=1):
    rng = np.random.default_rng(seed)
    eq = model.eq
    return {"initial": {n: float(rng.uniform(-0.5, 0.5)) for n in eq.names},
            "velocity": {eq.names[i]: float(rng.uniform(-0.5, 0.5)) for i in eq.inertial}}


@pytest.fixture(scope="module")
def machine():
    model = chain_and_solo()
    return model, state(model)


def test_pruning_keeps_only_what_influences_the_outputs(machine):
    model, start = machine
    scene = Scene(model, ["x_s", "T[solo]"], 8, tol=1e-12, **start)
    plan = scene.plan
    assert [p.coordinates for p in plan.parts] == [["x_s"]]
    assert plan.before["coordinates"] == 9 and plan.after["coordinates"] == 1
    assert plan.after["operations"] < plan.before["operations"]
    for name in ("m1", "k3", "cubic_free", "a", "kb"):
        assert "the outputs do not depend on" in plan.dropped[name]
    assert set(plan.kept) == {"solo", "ks", "cs"}
    assert "shaker" in plan.held
    res = scene.run()
    ref = full_run(model, 8, start)
    assert np.max(np.abs(res["x_s"] - ref["x_s"])) < 1e-10
    assert np.max(np.abs(res["T[solo]"] - 0.5 * 2 * ref.v["x_s"] ** 2)) < 1e-10
    assert "dropped 'm1'" in scene.report() and "part 1: x_s" in scene.report()


def test_parts_cut_off_by_a_prescribed_motion_are_simulated_separately(machine):
    model, start = machine
    scene = Scene(model, ["x_pa", "x_pb", "x_p6"], 8, **start)
    parts = [p.coordinates for p in scene.plan.parts]
    assert sorted(parts) == sorted([["x_pa"], ["x_pb"], [f"x_p{i}" for i in range(1, 7)]])
    assert all(p.method == "exact" for p in scene.plan.parts)  # each part is linear time-invariant
    res = scene.run()
    ref = full_run(model, 8, start)
    for name in ("x_pa", "x_pb", "x_p6"):
        assert np.max(np.abs(res[name] - ref[name])) < 1e-10, name


def test_a_weak_coupling_is_kept_and_only_offered_with_its_effect():
    """Two equal oscillators and a spring 1000 times weaker between them: over the beat time the energy
    moves from one to the other, so cutting the coupling would be wrong — the scene keeps it."""
    m = lg.Model("weakly coupled")
    for i in (1, 2):
        m.add("mass", f"m{i}", f"p{i}", m=1)
        m.add("spring", f"k{i}", ("ground", f"p{i}"), k=1)
    m.add("spring", "kc", ("p1", "p2"), k=1e-3)
    start = {"initial": {"x_p1": 1.0, "x_p2": 0.0}, "velocity": {"x_p1": 0.0, "x_p2": 0.0}}
    scene = Scene(m, ["x_p1"], 1600, points=4001, **start)
    assert [p.coordinates for p in scene.plan.parts] == [["x_p1", "x_p2"]]
    (offer,) = scene.plan.offers
    assert offer.component == "kc" and offer.would_drop == ["x_p2"]
    # by hand: normal modes ω₁ = 1, ω₂ = √(1 + 2κ); x₁ = cos(Δ t/2) cos(ω̄ t): the envelope at t = π/Δ is 0
    w2 = math.sqrt(1 + 2e-3)
    t = np.linspace(0, 1600, 4001)
    x1 = 0.5 * (np.cos(t) + np.cos(w2 * t))
    assert offer.estimated_error == pytest.approx(np.max(np.abs(x1 - np.cos(t))), rel=1e-3)
    assert offer.estimated_error > 0.5  # not negligible at all
    res = scene.run()
    assert np.max(np.abs(res["x_p1"] - x1)) < 1e-9
    assert "offered, not applied: drop 'kc'" in scene.report()


def spherical():
    model = lg.Model("spherical pendulum", dim=3)
    model.add("link", "yoke", "yoke")
    model.add("revolute", "turn", ("ground", "yoke"), axis=(0, 0, 1))
    model.add("link", "arm", "arm", points={"bob": (0, 0, -1)})
    model.add("revolute", "tilt", ("yoke", "arm"), axis=(1, 0, 0))
    model.add("mass", "bob", "arm.bob", m=1)
    model.add("gravity", "g", g=9.81)
    return model


SPH = {"initial": {"theta_turn": 0.2, "theta_tilt": 0.9}, "velocity": {"theta_turn": 1.7, "theta_tilt": -0.4}}


def test_ignorable_coordinates_not_asked_for_are_never_integrated():
    model = spherical()
    scene = Scene(model, ["theta_tilt", "E"], 5, tol=1e-13, reduce=True, **SPH)
    (part,) = scene.plan.parts
    assert part.eliminated == ["theta_turn"] and part.reconstructed == [] and part.integrated == ["theta_tilt"]
    res = scene.run()
    assert res.parts[0][1].names == ["theta_tilt"]  # φ was not integrated
    ref = full_run(model, 5, SPH)
    assert np.max(np.abs(res["theta_tilt"] - ref["theta_tilt"])) < 1e-10
    assert np.max(np.abs(res["E"] - ref.E)) < 1e-10  # E needs φ̇: evaluated from ∂R/∂C


@pytest.mark.slow
def test_a_reduction_is_done_only_when_it_pays_and_the_report_says_why(monkeypatch):
    """reduce="auto": over a few swings integrating φ costs less than eliminating it, so the part is integrated
    as it is (the report gives both estimates) and that run, made while planning, is the scene's; over many, φ is
    eliminated.  Both agree with the full model."""
    model = spherical()
    short = Scene(model, ["theta_tilt"], 5, tol=1e-11, **SPH)
    (part,) = short.plan.parts
    assert part.eliminated == [] and part.integrated == ["theta_turn", "theta_tilt"]
    found = re.search(r"theta_turn ignorable, not eliminated: the part as it is ran in ([0-9.e+]+) evaluations of "
                      r"(\d+) operations \(about [0-9.e-]+ s\), less than the Routhian's about ([0-9.e-]+) s of "
                      r"symbolic work \(break-even 4e\+05 evaluations; reduce=True forces it\)", short.report())
    assert found, short.report()
    # the same run as the full model's at the scene's settings, step for step
    same = model.simulate(5, initial=SPH["initial"], velocity=SPH["velocity"], t_eval=short.grid, rtol=1e-11, atol=1e-14)
    assert float(found[1]) == pytest.approx(same.nfev, rel=1e-3)
    assert float(found[3]) == pytest.approx(2e-3 * int(found[2]), rel=0.05)  # REDUCE_SECONDS · ops · 1²
    with monkeypatch.context() as patch:  # run() returns the planning run: nothing is integrated again
        patch.setattr(lg.Model, "simulate", lambda *a, **k: pytest.fail("integrated again"))
        res = short.run()
    assert np.array_equal(res["theta_tilt"], same["theta_tilt"])
    ref = full_run(model, 5, SPH)
    assert np.max(np.abs(res["theta_tilt"] - ref["theta_tilt"])) < 1e-9
    assert np.array_equal(short.run()["theta_tilt"], same["theta_tilt"])  # a second run integrates, to the same
    span = 3000.0
    long = Scene(model, ["theta_tilt"], span, tol=1e-11, points=301, **SPH)
    assert long.plan.parts[0].eliminated == ["theta_turn"]
    ref = model.simulate(span, initial=SPH["initial"], velocity=SPH["velocity"], t_eval=np.linspace(0, span, 301), **TIGHT)
    # over 3,000 s the two runs drift apart with the tolerance (rtol 1e-11 against 1e-13), not with the reduction
    assert np.max(np.abs(long.run()["theta_tilt"] - ref["theta_tilt"])) < 1e-6
    never = Scene(model, ["theta_tilt"], span, tol=1e-11, points=301, reduce=False, **SPH)
    assert never.plan.parts[0].eliminated == [] and "(reduce=False)" in never.report()
    with pytest.raises(lg.ModelError, match="reduce must be 'auto', True or False"):
        Scene(model, ["theta_tilt"], 5, reduce="yes", **SPH)


def test_a_run_made_while_planning_warns_when_the_scene_runs():
    """A part run as it is while planning (reduce="auto" declined) says what its run says when the scene runs:
    here the velocity not given, set to zero, once."""
    model = spherical()
    scene = Scene(model, ["theta_tilt"], 2, tol=1e-9, initial=SPH["initial"], velocity={"theta_turn": 1.7})
    with warnings.catch_warnings(record=True) as planning:
        warnings.simplefilter("always")
        assert scene.plan.parts[0].eliminated == []
    assert not planning
    with pytest.warns(lg.InitialConditionWarning, match="theta_tilt'") as running:
        res = scene.run()
    assert len([w for w in running if issubclass(w.category, lg.InitialConditionWarning)]) == 1
    ref = model.simulate(2, initial=SPH["initial"], velocity={"theta_turn": 1.7, "theta_tilt": 0.0},
                         t_eval=scene.grid, **TIGHT)
    assert np.max(np.abs(res["theta_tilt"] - ref["theta_tilt"])) < 1e-7


def test_ignorable_coordinates_asked_for_are_reconstructed():
    model = spherical()
    scene = Scene(model, ["theta_turn", "theta_turn'"], 5, tol=1e-12, reduce=True, **SPH)
    (part,) = scene.plan.parts
    assert part.reconstructed == ["theta_turn"]
    res = scene.run()
    ref = full_run(model, 5, SPH)
    assert np.max(np.abs(res["theta_turn"] - ref["theta_turn"])) < 1e-10
    assert np.max(np.abs(res["theta_turn'"] - ref.v["theta_turn"])) < 1e-10


def test_a_coordinate_cyclic_in_T_but_driven_by_a_torque_is_not_eliminated():
    model = spherical()
    model.add("body_torque", "motor", "yoke", tau=(0, 0, 0.2))
    scene = Scene(model, ["theta_tilt"], 3, tol=1e-12, **SPH)
    (part,) = scene.plan.parts
    assert part.eliminated == [] and set(part.integrated) == {"theta_turn", "theta_tilt"}
    res = scene.run()
    ref = full_run(model, 3, SPH)
    assert np.max(np.abs(res["theta_tilt"] - ref["theta_tilt"])) < 1e-10


def test_a_part_of_only_ignorable_coordinates_moves_uniformly():
    m = lg.Model("drift", dim=2)
    m.add("mass", "puck", "p", m=3)
    m.add("mass", "bob", "b", m=1)
    m.add("spring", "k", ("ground", "b"), k=1)
    start = {"initial": {"x_p": 1, "y_p": 2, "x_b": 0.1, "y_b": 0}, "velocity": {"x_p": 0.5, "y_p": -1, "x_b": 0, "y_b": 0.2}}
    scene = Scene(m, ["x_p", "y_p", "x_b"], 4, **start)
    methods = {tuple(p.coordinates): p.method for p in scene.plan.parts}
    assert methods[("x_p",)] == methods[("y_p",)] == "uniform"  # independent, and each moves uniformly
    res = scene.run()
    assert np.allclose(res["x_p"], 1 + 0.5 * res.t, atol=1e-14) and np.allclose(res["y_p"], 2 - res.t, atol=1e-14)
    assert np.max(np.abs(res["x_b"] - 0.1 * np.cos(res.t))) < 1e-10


@pytest.mark.slow
def test_linear_electromechanical_network_is_solved_exactly():
    """A moving-coil loudspeaker: RL coil driven by a sine, mass–spring–damper cone."""
    m = lg.Model("loudspeaker")
    m.add("voltage_source", "V1", ("n1", "0"), E=sp.sin(200 * lg.t))
    m.add("resistor", "Re", ("n1", "n2"), R=6)
    m.add("inductor", "Le", ("n2", "n3"), L=0.5e-3)
    m.add("moving_coil", "coil", ("n3", "0", "cone"), Bl=7)
    m.add("mass", "Mms", "cone", m=0.02)
    m.add("spring", "Kms", ("ground", "cone"), k=2000)
    m.add("damper", "Rms", ("ground", "cone"), c=1.5)
    zero = {"initial": {"q_Le": 0, "x_cone": 0}, "velocity": {"q_Le": 0, "x_cone": 0}}
    scene = Scene(m, ["x_cone", "[Le]'"], 0.2, points=2001, **zero)
    (part,) = scene.plan.parts
    assert part.method == "exact"
    res = scene.run()
    ref = m.simulate(0.2, t_eval=np.linspace(0, 0.2, 2001), rtol=1e-13, atol=1e-16, method="Radau", **zero)
    assert np.max(np.abs(res["x_cone"] - ref["x_cone"])) < 1e-10 * max(1.0, np.max(np.abs(ref["x_cone"])))
    current = ref.quantity(m.assembly.views["electrical"].branch_value("Le").diff(lg.t))
    assert np.max(np.abs(res["[Le]'"] - current)) < 1e-9


def test_nonlinear_part_is_integrated_and_says_so():
    model = spherical()
    scene = Scene(model, ["theta_tilt"], 1, **SPH)
    (part,) = scene.plan.parts
    assert part.method == "DOP853" and "nonlinear" in part.why


def test_outputs_are_lazy_and_bad_requests_are_clear(machine):
    model, start = machine
    scene = Scene(model, ["x_s", "V"], 2, **start)
    res = scene.run()
    assert res.computed == {}
    _ = res["x_s"]
    assert list(res.computed) == ["x_s"]  # V not computed until read
    assert [p.coordinates for p in scene.plan.parts][0][0] == "x_p1"  # V needs the whole chain
    with pytest.raises(lg.UnknownNameError, match="x_z"):
        Scene(model, ["x_z"], 1)
    with pytest.raises(lg.UnknownNameError, match="component 'nope'"):
        Scene(model, ["T[nope]"], 1)
    with pytest.raises(lg.ModelError, match="at least one output"):
        Scene(model, [], 1)
    with pytest.raises(lg.ModelError, match="tol"):
        Scene(model, ["x_s"], 1, tol=2)
    with pytest.raises(lg.UnknownNameError, match="scene output"):
        res["x_p3"]


def test_zero_valued_components_vanish_with_a_note():
    m = lg.Model("osc")
    m.add("mass", "m", "p", m=1)
    m.add("spring", "k", ("ground", "p"), k=1)
    m.add("damper", "c", ("ground", "p"), c=0)
    m.add("force", "F", "p", F=0)
    plan = Scene(m, ["x_p"], 1, initial={"x_p": 1}, velocity={"x_p": 0}).plan
    assert plan.dropped == {"c": "contributes nothing (c = 0)", "F": "contributes nothing (F = 0)"}


@pytest.mark.slow
def test_command_line_scene_reduce_option(tmp_path):
    source = tmp_path / "sph.py"
    source.write_text(
        "import lagrangian as lg\n"
        "def build():\n"
        "    m = lg.Model('spherical pendulum', dim=3)\n"
        "    m.add('link', 'yoke', 'yoke')\n"
        "    m.add('revolute', 'turn', ('ground', 'yoke'), axis=(0, 0, 1))\n"
        "    m.add('link', 'arm', 'arm', points={'bob': (0, 0, -1)})\n"
        "    m.add('revolute', 'tilt', ('yoke', 'arm'), axis=(1, 0, 0))\n"
        "    m.add('mass', 'bob', 'arm.bob', m=0.3)\n"
        "    m.add('gravity', 'g', g=9.81)\n"
        "    return m\n"
    )
    proc = subprocess.run([sys.executable, "-m", "lagrangian", "scene", f"{source}:build", "-o", "theta_tilt", "--t-end", "2",
                           "--initial", "theta_tilt=0.9", "--velocity", "theta_turn=1.7,theta_tilt=0", "--points", "11",
                           "--reduce", "always"], capture_output=True, text=True, cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert "eliminated through the Routhian: theta_turn" in proc.stdout


@pytest.mark.slow
def test_command_line_scene(tmp_path):
    source = tmp_path / "machine.py"
    source.write_text(
        "import lagrangian as lg\n"
        "def build():\n"
        "    m = lg.Model('m')\n"
        "    for i in (1, 2, 3):\n"
        "        m.add('mass', f'm{i}', f'p{i}', m=1)\n"
        "        m.add('spring', f'k{i}', ('ground' if i == 1 else f'p{i-1}', f'p{i}'), k=1)\n"
        "    m.add('mass', 'solo', 's', m=1)\n"
        "    m.add('spring', 'ks', ('ground', 's'), k=4)\n"
        "    return m\n"
    )
    out = tmp_path / "out.csv"
    proc = subprocess.run([sys.executable, "-m", "lagrangian", "scene", f"{source}:build", "-o", "x_s", "-o", "T[solo]", "-o", "V[ks]",
                           "--t-end", "3", "--initial", "x_s=1", "--velocity", "x_s=0", "--csv", str(out)],
                          capture_output=True, text=True, cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert "part 1: x_s" in proc.stdout and "dropped 'm1'" in proc.stdout
    data = np.loadtxt(out, delimiter=",", skiprows=1)
    assert np.max(np.abs(data[:, 1] - np.cos(2 * data[:, 0]))) < 1e-10
    assert np.max(np.abs(data[:, 2] + data[:, 3] - 2.0)) < 1e-9  # the oscillator's energy ½ k x₀² = 2
    bad = subprocess.run([sys.executable, "-m", "lagrangian", "scene", str(tmp_path / "none.py"), "-o", "x"],
                         capture_output=True, text=True)
    assert bad.returncode == 1 and "does not exist" in bad.stderr


def test_events_make_their_part_hybrid_and_are_dropped_where_they_cannot_matter():
    from lagrangian import impulse

    m = lg.Model("ball and oscillator")
    m.add("mass", "m", "ball", m=1)
    m.add("gravity", "g", g=9.81)
    m.add("mass", "mo", "p", m=1)
    m.add("spring", "k", ("ground", "p"), k=4)
    start = {"initial": {"x_ball": 1.0, "x_p": 0.2}, "velocity": {"x_ball": 0.0, "x_p": 0.0}}
    bounce = impulse.ground("ball", e=0.5)
    scene = Scene(m, ["x_ball"], 1.5, tol=1e-10, events=[bounce], points=301, **start)
    (part,) = scene.plan.parts
    assert part.coordinates == ["x_ball"] and part.method == "hybrid"
    res = scene.run()
    # by hand: first impact at √(2h/g), rebound e·√(2gh), second impact 2e√(2h/g) later
    t1 = math.sqrt(2 / 9.81)
    (impacts,) = [r.impacts for _, r in res.parts]
    assert impacts[0].time == pytest.approx(t1, abs=1e-9)
    after = res.t > t1
    first = after & (res.t < t1 + 2 * 0.5 * t1)
    v1 = 0.5 * math.sqrt(2 * 9.81)
    tt = res.t[first] - t1
    assert np.max(np.abs(res["x_ball"][first] - (v1 * tt - 9.81 * tt**2 / 2))) < 1e-8
    assert len(res["x_ball"]) == 301
    other = Scene(m, ["x_p"], 1.5, events=[bounce], **start)
    assert "event ground(ball)" in other.plan.dropped and other.plan.parts[0].method == "exact"
    with pytest.raises(lg.ModelError, match="points="):
        Scene(m, ["x_ball"], 1.5, events=[bounce], t_eval=[0, 1], **start)


# -- the whole model's state and parameters given to a scene -------------------------------------------------


def pendulums_and_circuit(m1=0.3, l1=0.7, m2=1.2, l2=0.25, L=7e-3, C=0.1, R=0.5):
    """Two spherical pendulums (each with an ignorable azimuth) and an RLC circuit, in one model."""
    model = lg.Model("two pendulums and a circuit", dim=3)
    for i, (m, l) in enumerate(((m1, l1), (m2, l2)), 1):
        model.add("link", f"yoke{i}", f"yoke{i}")
        model.add("revolute", f"turn{i}", ("ground", f"yoke{i}"), axis=(0, 0, 1))
        model.add("link", f"arm{i}", f"arm{i}", points={"bob": (0, 0, -l)})
        model.add("revolute", f"tilt{i}", (f"yoke{i}", f"arm{i}"), axis=(1, 0, 0))
        model.add("mass", f"bob{i}", f"arm{i}.bob", m=m)
    model.add("gravity", "g", g=9.81)
    model.add("inductor", "L1", ("n1", "n2"), L=L)
    model.add("capacitor", "C1", ("n2", "0"), C=C)
    model.add("resistor", "R1", ("n1", "0"), R=R)
    return model


FULL = {"initial": {"theta_turn1": 0.4, "theta_tilt1": 0.9, "theta_turn2": -1.1, "theta_tilt2": 2.0, "q_L1": 3e-3},
        "velocity": {"theta_turn1": 1.7, "theta_tilt1": -0.3, "theta_turn2": 0.6, "theta_tilt2": 0.5, "q_L1": 0.02}}


@pytest.mark.slow
def test_the_whole_state_given_to_a_scene_that_eliminates_and_prunes():
    """Every coordinate's value and velocity given; each pendulum's azimuth eliminated (its momentum from its
    velocity in the given state), the circuit pruned.  Scene at rtol 1e-12 against the full model at 1e-13 over
    about two swings: 1e-10 on the angles, 1e-10 relative on the azimuth rate (evaluated from ∂R/∂C)."""
    model = pendulums_and_circuit()
    scene = Scene(model, ["theta_tilt1", "theta_tilt2", "theta_turn2'"], 3, tol=1e-12, reduce=True, **FULL)
    plan = scene.plan
    assert sorted(p.coordinates for p in plan.parts) == [["theta_turn1", "theta_tilt1"], ["theta_turn2", "theta_tilt2"]]
    assert [p.eliminated for p in plan.parts] == [["theta_turn1"], ["theta_turn2"]]
    assert plan.unused == {"theta_turn1": "eliminated through the Routhian, values not asked for",
                           "theta_turn2": "eliminated through the Routhian, values not asked for",
                           "q_L1": "coordinates the outputs do not depend on",
                           "q_L1'": "coordinates the outputs do not depend on"}
    assert "given, not needed: q_L1, q_L1' (coordinates the outputs do not depend on)" in scene.report()
    res = scene.run()
    ref = full_run(model, 3, FULL)
    for name in ("theta_tilt1", "theta_tilt2"):
        assert np.max(np.abs(res[name] - ref[name])) < 1e-10, name
    rate = ref.v["theta_turn2"]
    assert np.max(np.abs(res["theta_turn2'"] - rate)) < 1e-10 * np.max(np.abs(rate))


def test_the_whole_state_given_when_the_eliminated_part_is_pruned():
    """The circuit asked for, both pendulums (and their ignorable azimuths) pruned: their state is not needed."""
    model = pendulums_and_circuit()
    scene = Scene(model, ["q_L1", "[L1]'"], 0.5, **FULL)
    (part,) = scene.plan.parts
    assert part.coordinates == ["q_L1"] and part.method == "exact"
    assert set(scene.plan.unused) == {n for n in FULL["initial"] if n != "q_L1"} | {
        f"{n}'" for n in FULL["velocity"] if n != "q_L1"}
    res = scene.run()
    ref = full_run(model, 0.5, FULL)
    assert np.max(np.abs(res["q_L1"] - ref["q_L1"])) < 1e-10 * np.max(np.abs(ref["q_L1"]))
    assert np.max(np.abs(res["[L1]'"] - ref.v["q_L1"])) < 1e-10 * np.max(np.abs(ref.v["q_L1"]))


def test_symbolic_parameters_of_pruned_parts_may_be_given_or_left_out():
    m, l, L, C = sp.symbols("m l L C", positive=True)
    model = pendulums_and_circuit(m1=m, l1=l, L=L, C=C)
    values = {"m": 0.3, "l": 0.7, "L": 7e-3, "C": 0.1}
    ref = full_run(model, 3, FULL, params=values)
    by_hand = 0.5 * 0.3 * 0.7**2 * (ref.v["theta_tilt1"] ** 2 + np.sin(ref["theta_tilt1"]) ** 2 * ref.v["theta_turn1"] ** 2)
    for params in (values, {"m": 0.3, "l": 0.7}):  # L and C belong to the pruned circuit only
        scene = Scene(model, ["theta_tilt1", "T[bob1]"], 3, tol=1e-12, params=params, **FULL)
        assert {k for k, why in scene.plan.unused.items() if why == "parameters only of dropped components"} == set(params) - {"m", "l"}
        res = scene.run()
        assert np.max(np.abs(res["theta_tilt1"] - ref["theta_tilt1"])) < 1e-10
        assert np.max(np.abs(res["T[bob1]"] - by_hand)) < 1e-10 * np.max(by_hand)


def test_another_value_for_a_numeric_parameter_is_refused_where_kept_and_unused_where_pruned():
    model = pendulums_and_circuit()
    with pytest.raises(lg.ModelError, match="'m_bob1' .* given as a number .*sympy.Symbol"):
        Scene(model, ["theta_tilt1"], 1, params={"m_bob1": 0.5}, **FULL).plan
    scene = Scene(model, ["theta_tilt1"], 3, tol=1e-12, params={"L_L1": 2e-3}, **FULL)
    assert scene.plan.unused["L_L1"] == "parameters only of dropped components"
    ref = full_run(model, 3, FULL, params={"L_L1": 2e-3})
    assert np.max(np.abs(scene.run()["theta_tilt1"] - ref["theta_tilt1"])) < 1e-10


def test_names_the_model_does_not_have_are_refused_by_name():
    model = pendulums_and_circuit()
    with pytest.raises(lg.UnknownNameError, match=r"unknown coordinate 'theta_tilt3'.*theta_tilt1"):
        Scene(model, ["theta_tilt1"], 1, initial={**FULL["initial"], "theta_tilt3": 0.1})
    with pytest.raises(lg.UnknownNameError, match=r"unknown coordinate 'theta_trun1'.*theta_turn1"):
        Scene(model, ["theta_tilt1"], 1, velocity={**FULL["velocity"], "theta_trun1": 0.1})
    with pytest.raises(lg.UnknownNameError, match=r"unknown parameter 'm_bob3'.*m_bob1"):
        Scene(model, ["theta_tilt1"], 1, params={"m_bob3": 0.3}, **FULL)


def decades(lo, hi):
    """Floats drawn log-uniformly in [lo, hi] (most not exactly representable decimals)."""
    from hypothesis import strategies as st

    return st.floats(math.log10(lo), math.log10(hi)).map(lambda e: 10.0**e)


def _property_test():
    from hypothesis import given, settings
    from hypothesis import strategies as st

    unit = st.floats(-1.0, 1.0)
    spin = st.tuples(st.sampled_from((-1.0, 1.0)), st.floats(0.5, 2.0)).map(lambda s: s[0] * s[1])  # |φ̇| ≥ ω/2

    @settings(max_examples=10)
    @given(m1=decades(1e-2, 1e2), l1=decades(1e-2, 1e2), m2=decades(1e-2, 1e2), l2=decades(1e-2, 1e2),
           L=decades(1e-4, 1.0), R=decades(1e-2, 1e2), tilt=st.floats(0.3, 2.8), turn=st.floats(-math.pi, math.pi),
           spins=st.tuples(spin, spin), rates=st.tuples(unit, unit, unit), q=unit)
    @pytest.mark.slow
    def check(m1, l1, m2, l2, L, R, tilt, turn, spins, rates, q):
        """Scene at rtol 1e-11 against the full model at 1e-13 over 3/ω₀ (ω₀ = √(g/l₁), under half a swing):
        1e-8 on the angles, 1e-8 relative on the azimuth rate.  Each pendulum spins (its angular momentum
        keeps it off the vertical, where the azimuth of these angles is undetermined).  The reference runs the
        whole model with DOP853, which refuses a stiff circuit (R/L beyond some 1e5/s over the span): such draws
        are left out, the scene prunes the circuit either way."""
        from hypothesis import assume

        assume(R / L * 3 / math.sqrt(9.81 / l1) < 1e5)
        model = pendulums_and_circuit(m1, l1, m2, l2, L=L, C=0.1, R=R)
        w0, w2 = math.sqrt(9.81 / l1), math.sqrt(9.81 / l2)
        full = {"initial": {"theta_turn1": turn, "theta_tilt1": tilt, "theta_turn2": -turn, "theta_tilt2": 3.1 - tilt,
                            "q_L1": 1e-3 * q},
                "velocity": {"theta_turn1": w0 * spins[0], "theta_tilt1": w0 * rates[0],
                             "theta_turn2": w2 * spins[1], "theta_tilt2": w2 * rates[1], "q_L1": 1e-2 * rates[2]}}
        span = 3 / w0
        scene = Scene(model, ["theta_tilt1", "theta_turn1", "theta_turn1'"], span, tol=1e-11, points=101, offer=False,
                      reduce=True, **full)
        (part,) = scene.plan.parts
        assert part.eliminated == ["theta_turn1"]
        assert {"theta_tilt2", "q_L1", "theta_turn2'"} <= set(scene.plan.unused)
        res = scene.run()
        ref = model.simulate(span, t_eval=np.linspace(0, span, 101), **TIGHT, **full)
        assert np.max(np.abs(res["theta_tilt1"] - ref["theta_tilt1"])) < 1e-8
        assert np.max(np.abs(res["theta_turn1"] - ref["theta_turn1"])) < 1e-8
        rate = ref.v["theta_turn1"]
        assert np.max(np.abs(res["theta_turn1'"] - rate)) < 1e-8 * max(np.max(np.abs(rate)), w0)

    return check


test_scene_given_the_whole_state_agrees_with_the_full_model_on_random_values = _property_test()


def test_branch_outputs_say_what_they_are_and_spice_names_give_voltages(tmp_path, capsys):
    """An RC low-pass (4.7 kΩ, 100 nF) from 0.3 V: v(C1) = [C1]/C, i(C1) = [C1]', and each [X] is named."""
    from lagrangian.cli import main
    from lagrangian.netlist import read_netlist

    text = "rc\nR1 in out 4.7k\nC1 out 0 100n\nV1 in 0 DC 1\n.ic v(out)=0.3\n.tran 5u 1m\n.end\n"
    net = read_netlist(text)
    scene = Scene(net.model, ["[C1]", "v(C1)", "[C1]'", "i(C1)", "v(out)"], t_end=1e-3, initial=net.initial,
                  velocity=net.velocity)
    res = scene.run()
    assert np.allclose(res["v(C1)"], res["[C1]"] / 100e-9, rtol=1e-12)
    assert np.allclose(res["i(C1)"], res["[C1]'"], rtol=1e-12, atol=1e-15)
    assert np.allclose(res["v(out)"], res["v(C1)"], rtol=1e-12)
    tau = 4.7e3 * 100e-9
    assert np.allclose(res["v(C1)"], 1 - 0.7 * np.exp(-res.t / tau), atol=1e-7)
    assert res.meanings == {"[C1]": "charge through C1 [C] (its voltage: v(C1))", "[C1]'": "current through C1 [A]"}
    path = tmp_path / "rc.cir"
    path.write_text(text)
    assert main(["scene", str(path), "-o", "[C1]"]) == 0
    assert "[C1] — charge through C1 [C] (its voltage: v(C1)): at t = 0.001" in capsys.readouterr().out


def deck(masses, stiffnesses, damping=0.02):
    """Assemblies of two masses hanging from a deck shaken in the plane, each mass in its own assembly (the
    shaker scene of benchmarks/scenes.py, with values drawn by the caller), and gravity."""
    m = lg.Model("deck", dim=2)
    m.add("prescribed_motion", "table", "deck", position=sp.Matrix([sp.sin(4 * lg.t) / 20, 0]))
    for k, (pair, (k_hang, k_link)) in enumerate(zip(masses, stiffnesses)):
        m.add("mass", f"upper{k}", f"u{k}", m=pair[0])
        m.add("mass", f"lower{k}", f"w{k}", m=pair[1])
        m.add("spring", f"hang{k}", ("deck", f"u{k}"), k=k_hang, rest_length=0.5)
        m.add("spring", f"link{k}", (f"u{k}", f"w{k}"), k=k_link, rest_length=0.4)
        m.add("damper", f"drag{k}", ("deck", f"u{k}"), c=damping)
    m.add("gravity", "g", g=9.81)
    return m


@settings(max_examples=6, deadline=None)
@given(st.lists(st.tuples(st.floats(0.05, 5.0), st.floats(0.05, 5.0)), min_size=3, max_size=3),
       st.lists(st.tuples(st.floats(20.0, 2000.0), st.floats(20.0, 2000.0)), min_size=3, max_size=3),
       st.integers(0, 2))
def test_a_model_of_point_masses_is_pruned_by_its_graph_and_answers_as_the_whole_model(masses, stiffnesses, which):
    """The assemblies a scene's outputs cannot reach (through components; the shaken deck passes nothing on) are
    dropped before anything is derived, with the reason; the outputs equal the whole model's, simulated tightly;
    initial values of dropped coordinates and values of dropped parameters are accepted and reported unused."""
    model = deck(masses, stiffnesses)
    start = {"initial": {}, "velocity": {}}
    for k in range(3):
        start["initial"].update({f"x_u{k}": 0.1, f"y_u{k}": -0.5, f"x_w{k}": 0.15, f"y_w{k}": -0.9})
        start["velocity"].update({f"x_u{k}": 0.0, f"y_u{k}": 0.0, f"x_w{k}": 0.0, f"y_w{k}": 0.0})
    other = (which + 1) % 3
    scene = Scene(model, [f"x_w{which}", f"y_w{which}'"], 1.5, tol=1e-11, points=301,
                  params={f"k_hang{other}": 50.0}, **start)
    assert scene.pruned is not None and scene.full_model is model
    assert set(scene.model.components) == {f"{kind}{which}" for kind in ("upper", "lower", "hang", "link", "drag")} | {
        "table", "g"}
    plan = scene.plan
    assert "outputs' nodes do not reach" in plan.dropped[f"hang{other}"]
    assert plan.after["coordinates"] == 4
    assert plan.unused[f"x_u{other}"] == "coordinates the outputs do not depend on"
    assert plan.unused[f"k_hang{other}"] == "parameters only of dropped components"
    res = scene.run()
    ref = full_run(model, 1.5, {**start, "points": 301})
    assert np.max(np.abs(res[f"x_w{which}"] - ref[f"x_w{which}"])) < 1e-8
    assert np.max(np.abs(res[f"y_w{which}'"] - ref.v[f"y_w{which}"])) < 1e-7
    assert plan.before["coordinates"] == 12  # the whole model's, derived only when read


def test_graph_pruning_gives_way_where_the_graph_cannot_tell():
    """A load that reads another node's coordinate, an energy as output, or a name the model lacks: no pruning by
    the graph (the planner works from the equations), and an unknown coordinate is refused with the whole model's."""
    model = deck([(0.3, 0.2)] * 2, [(400.0, 300.0)] * 2)
    assert Scene(model, ["x_w0"], 1.0).pruned is not None
    assert Scene(model, ["x_w0", "E"], 1.0).pruned is None
    coupled = deck([(0.3, 0.2)] * 2, [(400.0, 300.0)] * 2)
    coupled.add("force", "pull", "w0", F=sp.Matrix([-2.0 * lg.coordinate("x_w1"), 0]))
    assert Scene(coupled, ["x_w0"], 1.0).pruned is None
    with pytest.raises(lg.UnknownNameError, match="x_w9.*x_u0"):
        Scene(model, ["x_w0"], 1.0, initial={"x_w9": 0.1})


def test_rotors_on_a_driven_shaft_are_pruned_by_the_graph_too():
    """A motor (a prescribed rotation) drives two rotors through shafts; asked about one, the scene drops the other
    branch before deriving anything, and answers as the whole model does."""
    m = lg.Model("drivetrain")
    m.add("prescribed_rotation", "motor", "m", angle=3.0 * lg.t + 0.2 * sp.sin(7 * lg.t))
    m.add("torsion_spring", "shaft1", ("m", "a"), k=47.0)
    m.add("inertia", "Ja", "a", J=7e-3)
    m.add("rotary_damper", "bearing", ("ground", "a"), c=2e-3)
    m.add("torsion_spring", "shaft2", ("m", "b"), k=120.0)
    m.add("inertia", "Jb", "b", J=0.03)
    m.add("torque", "load", "b", tau=-0.4)
    start = {"initial": {"theta_a": 0.0, "theta_b": 0.1}, "velocity": {"theta_a": 0.0, "theta_b": 0.0}}
    scene = Scene(m, ["theta_a'"], 2.0, tol=1e-11, points=201, **start)
    assert scene.pruned is not None and set(scene.model.components) == {"motor", "shaft1", "Ja", "bearing"}
    assert "outputs' nodes do not reach" in scene.plan.dropped["Jb"] and "theta_b" in scene.plan.unused
    assert "dropped 'shaft2', 'Jb', 'load': joins only nodes" in scene.report()  # one line for one reason
    ref = full_run(m, 2.0, {**start, "points": 201})
    assert np.max(np.abs(scene.run()["theta_a'"] - ref.v["theta_a"])) < 1e-8


def test_a_linear_part_solved_exactly_is_not_reduced_under_auto():
    """A transformer whose primary loop holds only inductors: that loop's charge is ignorable (coupled through the
    mutual inductance), and the part is linear time-invariant.  Solved exactly as it is, its reduction would save
    no integration, however long the span: "auto" declines and says why; both agree with the model's exact run."""
    m = lg.Model("transformer")
    m.add("inductor", "L1", ("a", "0"), L=7e-3)
    m.add("inductor", "L3", ("a", "0"), L=3e-3)
    m.add("inductor", "L2", ("b", "0"), L=2.2e-3)
    m.add("capacitor", "C2", ("b", "0"), C=1e-6)
    m.add("coupling", "K1", inductor1="L1", inductor2="L2", k=0.6)
    start = {"initial": {"q_L3": 0.0, "q_L2": 4.7e-7}, "velocity": {"q_L3": 1e-3, "q_L2": 0.0}}
    span = 30.0  # some 10⁵ periods of the tank: integrated, millions of evaluations
    scene = Scene(m, ["q_L2"], span, points=301, **start)
    (part,) = scene.plan.parts
    assert part.method == "exact" and part.eliminated == []
    assert "q_L3 ignorable, not eliminated: the part is linear time-invariant and solved exactly as it is" in scene.report()
    ref = m.simulate(span, method="exact", t_eval=scene.grid, **start)
    assert np.max(np.abs(scene.run()["q_L2"] - ref["q_L2"])) < 1e-9 * 4.7e-7
    forced = Scene(m, ["q_L2"], span, points=301, reduce=True, **start)
    assert forced.plan.parts[0].eliminated == ["q_L3"]
    assert np.max(np.abs(forced.run()["q_L2"] - ref["q_L2"])) < 1e-8 * 4.7e-7
