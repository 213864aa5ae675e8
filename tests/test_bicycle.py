"""The Whipple bicycle (``lagrangian.models.whipple_bicycle``) with the benchmark parameters of Meijaard,
Papadopoulos, Ruina and Schwab (2007): its accelerations against a model built apart in sympy.physics.mechanics'
KanesMethod (in the benchmark's own axes, z down, pitch zero upright, the rear wheel's rolling built into its
kinematics), with numbers and with symbols; the loop's closure upright; its linearization about straight running
against the benchmark's published matrices, eigenvalues, weave and capsize speeds, and a small lean followed along
the published linear equations; energy and constraints kept along a run."""

import functools
import math

import numpy as np
import pytest
import sympy as sp
import sympy.physics.mechanics as me
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.linalg import expm
from scipy.optimize import brentq

from lagrangian import models
from lagrangian.frequency import linearize, speed_sweep
from lagrangian.plugins.multibody import consistent_initial, constraint_residual

#: The benchmark's Table 1, in its axes: x forward, y to the right, z down, origin at the rear contact.
BENCH = dict(w=1.02, c=0.08, lam=math.pi / 10, g=9.81, rR=0.3, mR=2.0, IRxx=0.0603, IRyy=0.12,
             xB=0.3, zB=-0.9, mB=85.0, IB=((9.2, 0, 2.4), (0, 11.0, 0), (2.4, 0, 2.8)),
             xH=0.9, zH=-0.7, mH=4.0, IH=((0.05892, 0, -0.00756), (0, 0.06, 0), (-0.00756, 0, 0.00708)),
             rF=0.35, mF=3.0, IFxx=0.1405, IFyy=0.28)

pytestmark = pytest.mark.slow  # each test derives the bicycle's equations (about 3 s)

NAMES = ["x_frame", "y_frame", "z_frame", "theta_yaw", "theta_roll", "theta_pitch", "theta_rear", "theta_steer",
         "theta_front"]


@functools.lru_cache(maxsize=1)
def bicycle():
    return models.whipple_bicycle()


def upright(v, p=BENCH):
    """The benchmark bicycle running straight and upright at speed ``v``: ``(initial, velocity)`` in our
    coordinates (the rear axle over the origin, the steer axes pitched back by λ, the wheels rolling forwards)."""
    initial = {**dict.fromkeys(NAMES, 0.0), "z_frame": p["rR"], "theta_pitch": -p["lam"]}
    velocity = {**dict.fromkeys(NAMES, 0.0), "x_frame": v, "theta_rear": v / p["rR"], "theta_front": v / p["rF"]}
    return initial, velocity


@functools.lru_cache(maxsize=1)
def kane_bicycle():
    """Numeric functions of :func:`kane_method`'s bicycle.

    Returns ``(pitch, dependent, accelerations, axle)``: the pitch closing the loop at (roll, steer); the dependent
    speeds at (yaw, roll, pitch, steer, u_roll, u_rear, u_steer); the rates' derivatives (u_roll, u_rear, u_steer,
    u_yaw, u_pitch, u_front) at the whole state; the rear axle's position and velocity from the rear contact."""
    km, q, u, height, slip, (P, Do, N) = kane_method()
    yaw, roll, pitch, steer = q
    # the dependent speeds, solved numerically from the constraints (linear in the speeds)
    slip = sp.Matrix(slip)
    dep = sp.lambdify((*q, *u[:3]), [slip.jacobian(u[3:]), slip.jacobian(u[:3])], "numpy", cse=True)

    def dependent(*values):
        A_dep, A_ind = (np.asarray(a, float) for a in dep(*values))
        return np.linalg.solve(A_dep, -A_ind @ np.asarray(values[4:], float))

    h = sp.lambdify((roll, steer, pitch), height, "numpy")

    def closing_pitch(r, s):
        return brentq(lambda x: h(r, s, x), -0.5, 0.5, xtol=1e-15, rtol=4 * np.finfo(float).eps)

    full = sp.lambdify((*km.q, *km.u), [km.mass_matrix_full, km.forcing_full], "numpy", cse=True)
    order = [list(km.q).index(x) for x in q] + [4 + list(km.u).index(x) for x in u]

    def accelerations(*values):
        state = np.empty(10)
        state[order] = values
        M, f = full(*state)
        rates = np.linalg.solve(np.asarray(M, float), np.asarray(f, float).ravel())[4:]
        return rates[[list(km.u).index(x) for x in u]]

    axle = sp.lambdify((*q, *u), [list(Do.pos_from(P).to_matrix(N)), list(Do.vel(N).to_matrix(N))], "numpy",
                       cse=True)
    return closing_pitch, dependent, accelerations, axle


def kane_method():
    """The Whipple bicycle in sympy.physics.mechanics, built apart from ours, in the benchmark's axes (N: x forward,
    y right, z down).  The rear frame C turns from N by yaw (about z), roll (about x) and pitch (about y), C = N
    upright; the fork E turns by steer about the steer axis (pointing down, tilted λ forward), the wheels about C.y
    and E.y.  The rear contact is at rest (the rear wheel's rolling is in its kinematics, as in Moore's
    formulation); the front contact's velocity is zero (three constraints: not sliding, and staying on the ground),
    and its height the holonomic constraint.  Speeds: roll, rear wheel and steer rates independent; yaw, pitch and
    front wheel rates dependent.

    Returns ``(km, q, u, height, slip, (P, Do, N))``: the ``KanesMethod`` with its equations formed, the
    coordinates (yaw, roll, pitch, steer), the speeds (roll, rear wheel and steer rates, then yaw, pitch and front
    wheel rates), the front contact's height and slip velocity, the rear contact, the rear axle and the ground's
    frame."""
    p = BENCH
    yaw, roll, pitch, steer = q = me.dynamicsymbols("yaw roll pitch steer")
    u_roll, u_rear, u_steer, u_yaw, u_pitch, u_front = u = me.dynamicsymbols("u_roll u_rear u_steer u_yaw u_pitch u_front")
    lam, rR, rF, w, c = p["lam"], p["rR"], p["rF"], p["w"], p["c"]
    N = me.ReferenceFrame("N")
    A = N.orientnew("A", "Axis", (yaw, N.z))
    B = A.orientnew("B", "Axis", (roll, A.x))
    C = B.orientnew("C", "Axis", (pitch, B.y))
    axis = math.sin(lam) * C.x + math.cos(lam) * C.z
    E = C.orientnew("E", "Axis", (steer, axis))
    D, F = me.ReferenceFrame("D"), me.ReferenceFrame("F")  # the wheels (their turns are ignorable)
    A.set_ang_vel(N, u_yaw * N.z)
    B.set_ang_vel(A, u_roll * A.x)
    C.set_ang_vel(B, u_pitch * B.y)
    E.set_ang_vel(C, u_steer * axis)
    D.set_ang_vel(C, u_rear * C.y)
    F.set_ang_vel(E, u_front * E.y)
    P = me.Point("P")  # the rear contact
    P.set_vel(N, 0)
    Do = P.locatenew("Do", -rR * B.z)  # the rear axle: B.z is the wheel plane's downward direction
    Do.v2pt_theory(P, N, D)
    Bo = Do.locatenew("Bo", p["xB"] * C.x + (p["zB"] + rR) * C.z)
    S = Do.locatenew("S", (w + c) * C.x + rR * C.z)  # where the steer axis meets the ground upright
    Ho = S.locatenew("Ho", (p["xH"] - w - c) * E.x + p["zH"] * E.z)
    Fo = S.locatenew("Fo", -c * E.x - rF * E.z)
    for point in (Bo, S):
        point.v2pt_theory(Do, N, C)
    for point in (Ho, Fo):
        point.v2pt_theory(S, N, E)
    down = N.z - N.z.dot(E.y) * E.y
    Q = Fo.locatenew("Q", rF * down.normalize())  # the front contact
    Q.v2pt_theory(Fo, N, F)
    height = Q.pos_from(P).dot(N.z)
    slip = [Q.vel(N).dot(A.x), Q.vel(N).dot(A.y), Q.vel(N).dot(A.z)]
    IB, IH = p["IB"], p["IH"]
    bodies = [
        me.RigidBody("frame", Bo, C, p["mB"], (me.inertia(C, IB[0][0], IB[1][1], IB[2][2], IB[0][1], IB[1][2], IB[2][0]), Bo)),
        me.RigidBody("fork", Ho, E, p["mH"], (me.inertia(E, IH[0][0], IH[1][1], IH[2][2], IH[0][1], IH[1][2], IH[2][0]), Ho)),
        me.RigidBody("rear", Do, D, p["mR"], (me.inertia(C, p["IRxx"], p["IRyy"], p["IRxx"]), Do)),
        me.RigidBody("front", Fo, F, p["mF"], (me.inertia(E, p["IFxx"], p["IFyy"], p["IFxx"]), Fo)),
    ]
    loads = [(body.masscenter, body.mass * p["g"] * N.z) for body in bodies]
    kd = [yaw.diff() - u_yaw, roll.diff() - u_roll, pitch.diff() - u_pitch, steer.diff() - u_steer]
    km = me.KanesMethod(N, q_ind=[yaw, roll, steer], q_dependent=[pitch], configuration_constraints=[height],
                        u_ind=u[:3], u_dependent=u[3:], velocity_constraints=slip, kd_eqs=kd,
                        constraint_solver="CRAMER")
    km.kanes_equations(bodies, loads)
    return km, q, u, height, slip, (P, Do, N)


def kane_state(yaw, roll, steer, u_roll, u_rear, u_steer):
    """A consistent state of the KanesMethod bicycle, rear contact at the origin, and the same state in ours."""
    closing_pitch, dependent, accelerations, axle = kane_bicycle()
    pitch = closing_pitch(roll, steer)
    u_yaw, u_pitch, u_front = dependent(yaw, roll, pitch, steer, u_roll, u_rear, u_steer)
    q = (yaw, roll, pitch, steer)
    u = (u_roll, u_rear, u_steer, u_yaw, u_pitch, u_front)
    (X, Y, Z), (VX, VY, VZ) = axle(*q, *u)
    lam = BENCH["lam"]
    # the benchmark's axes to ours (y and z reversed): angles about y and z change sign, and our steer axes are
    # the rear frame pitched back by λ; the wheels' turns are ignorable (any values)
    ours_q = [X, -Y, -Z, -yaw, roll, -pitch - lam, 0.3, -steer, -1.1]
    ours_v = [VX, -VY, -VZ, -u_yaw, u_roll, -u_pitch, -u_rear, -u_steer, -u_front]
    return (q, u), np.array(ours_q + ours_v, dtype=float)


@settings(max_examples=6, deadline=None)
@given(st.floats(-math.pi, math.pi), st.floats(-0.4, 0.4), st.floats(-0.6, 0.6),
       st.tuples(st.floats(-1.5, 1.5), st.floats(-40.0, 40.0), st.floats(-3.0, 3.0)))
def test_accelerations_match_kane_near_upright(yaw, roll, steer, rates):
    """At consistent states near upright (any heading, leaning and steering, rolling either way), the rates' derivatives
    — lean, rear wheel and steer, and those of the dependent yaw, pitch and front wheel — agree with KanesMethod's."""
    (q, u), y = kane_state(yaw, roll, steer, *rates)
    ours = bicycle().numeric().rhs(0.0, y)[9:]  # x, y, z, yaw, roll, pitch, rear, steer, front
    ours = np.array([ours[4], -ours[6], -ours[7], -ours[3], -ours[5], -ours[8]])  # as u_roll, u_rear, u_steer, ...
    theirs = np.asarray(kane_bicycle()[2](*q, *u), dtype=float)
    scale = BENCH["g"] / BENCH["rR"] + sum(x * x for x in u)
    assert np.max(np.abs(ours - theirs)) <= 1e-10 * scale


def test_upright_closes_the_loop_at_the_benchmarks_pitch():
    """Upright and steered straight, both wheels touch the ground with the steer axis tilted back by λ: the loop's
    closure, solved from a pitch of 0, is pitch = −λ with the rear axle at rR, and the rolling constraints make the
    frame run at v = ω rR and the front wheel turn at v / rF."""
    initial, velocity = upright(5.0)
    start = consistent_initial(bicycle(), {**initial, "theta_pitch": 0.0, "z_frame": 0.0},
                               {"theta_rear": velocity["theta_rear"]},
                               independent=["x_frame", "y_frame", "theta_yaw", "theta_roll", "theta_rear", "theta_steer",
                                            "theta_front"])
    assert start.initial["theta_pitch"] == pytest.approx(-BENCH["lam"], abs=1e-12)
    assert start.initial["z_frame"] == pytest.approx(BENCH["rR"], abs=1e-12)
    assert [start.velocity[n] for n in NAMES] == pytest.approx([velocity[n] for n in NAMES], abs=1e-12)


#: The benchmark's linearized equations of straight running, M q̈ + v C1 q̇ + (g K0 + v² K2) q = 0 in q = (lean φ,
#: steer δ) (Meijaard et al. 2007, section A and Table 2, which they reproduce to 14 digits with two programs), its
#: eigenvalues at 5 m/s and its weave and capsize speeds.
PUBLISHED_M = np.array([[80.81722, 2.31941332208709], [2.31941332208709, 0.29784188199686]])
PUBLISHED_C1 = np.array([[0.0, 33.86641391492494], [-0.85035641456978, 1.68540397397560]])
PUBLISHED_K0 = np.array([[-80.95, -2.59951685249872], [-2.59951685249872, -0.80329488458618]])
PUBLISHED_K2 = np.array([[0.0, 76.59734589573222], [0.0, 2.65431523794604]])
PUBLISHED_EIGENVALUES_AT_5 = [-14.07838969279822, -0.77534188219585 - 4.46486771378823j,
                              -0.77534188219585 + 4.46486771378823j, -0.32286642900409]
WEAVE_SPEED, CAPSIZE_SPEED = 4.29238253634111, 6.02426201538837


LATERAL = ["theta_roll", "theta_steer", "theta_roll'", "theta_steer'"]
#: the benchmark's lean φ is ours, its steer δ (to the right) our steer's opposite
FLIP = np.diag([1.0, -1.0, 1.0, -1.0])


def unit_speed(p=BENCH):
    """The rates of straight running at 1 m/s: the rear axle forward, both wheels turning forward."""
    return {"x_frame": 1.0, "theta_rear": 1 / p["rR"], "theta_front": 1 / p["rF"]}


def kane_matrix(v):
    """Our state matrix about straight running at ``v``: lagrangian.frequency.linearize about the steady motion, in
    Kane's independent coordinates and speeds (``LinearModel.state_space``)."""
    initial, _ = upright(v)
    lin = linearize(bicycle(), at={"z_frame": initial["z_frame"], "theta_pitch": initial["theta_pitch"]},
                    velocity={k: v * x for k, x in unit_speed().items()} if v else None, inputs=[])
    A, _, _, _, states = lin.state_space()
    return A, states


def linearized(v):
    """The block of lean and steer, (φ, δ, φ̇, δ̇) in the benchmark's signs, of our linearization at ``v``; the
    other states (the position, heading and wheel angles, the rear wheel's speed) must not feed it, as the
    benchmark's lateral equations say."""
    A, states = kane_matrix(v)
    assert states == ["x_frame", "y_frame", "theta_yaw", "theta_roll", "theta_rear", "theta_steer", "theta_front",
                      "theta_roll'", "theta_rear'", "theta_steer'"]  # pitch follows from the front wheel's contact
    lateral = [states.index(n) for n in LATERAL]
    others = [i for i in range(len(states)) if i not in lateral]
    assert np.max(np.abs(A[np.ix_(lateral, others)])) <= 1e-12 * np.max(np.abs(A))
    return FLIP @ A[np.ix_(lateral, lateral)] @ FLIP


def published(v, g=9.81):
    return np.block([[np.zeros((2, 2)), np.eye(2)],
                     [-np.linalg.solve(PUBLISHED_M, g * PUBLISHED_K0 + v * v * PUBLISHED_K2),
                      -np.linalg.solve(PUBLISHED_M, v * PUBLISHED_C1)]])


@pytest.mark.parametrize("v", [0.0, 2.0, 5.0, 8.0])
def test_straight_running_linearizes_to_the_benchmarks_equations(v):
    A = linearized(v)
    want = published(v)
    assert np.max(np.abs(A - want)) < 1e-12 * np.max(np.abs(want))


def test_the_speed_sweep_finds_the_weave_and_capsize_speeds_to_the_digits_published():
    """Eigenvalues against speed from 0 to 10 m/s (three linearizations, the state matrix quadratic in the speed):
    at every speed the published equations' eigenvalues, and the weave and capsize speeds the benchmark gives to 15
    digits."""
    sweep = speed_sweep(bicycle(), np.linspace(0.0, 10.0, 41), at={"z_frame": BENCH["rR"], "theta_pitch": -BENCH["lam"]},
                        velocity=unit_speed())
    assert sweep.exact and sweep.states[3] == "theta_roll"
    for v, lam in zip(sweep.speeds, sweep.eigenvalues):
        want = np.linalg.eigvals(published(v))
        ours = lam[np.argsort(np.abs(lam))][-4:]  # the other six are zero: position, heading, wheels, speed
        for z in want:
            assert np.min(np.abs(ours - z)) <= 1e-9 * max(abs(z), 1.0)
    weave, capsize = sweep.crossings()
    assert (weave.kind, weave.becomes, capsize.kind, capsize.becomes) == ("oscillatory", "stable", "real", "unstable")
    assert weave.speed == pytest.approx(WEAVE_SPEED, abs=2e-13)
    assert capsize.speed == pytest.approx(CAPSIZE_SPEED, abs=2e-13)


def test_the_benchmarks_eigenvalues_weave_and_capsize_speeds():
    """At 5 m/s the eigenvalues of the benchmark's Table 2; at the weave speed the weave's pair crosses the imaginary
    axis, at the capsize speed the capsize's root passes through zero: between them it is self-stable."""
    eig = np.sort_complex(np.linalg.eigvals(linearized(5.0)))
    assert eig == pytest.approx(np.sort_complex(PUBLISHED_EIGENVALUES_AT_5), abs=1e-12)
    weave = np.linalg.eigvals(linearized(WEAVE_SPEED))
    oscillating = weave[np.abs(weave.imag) > 1]
    assert len(oscillating) == 2 and np.max(np.abs(oscillating.real)) < 1e-12
    capsize = np.linalg.eigvals(linearized(CAPSIZE_SPEED))
    assert np.min(np.abs(capsize)) < 1e-12 and np.max(capsize.real) < 1e-12


def start_leaning(v, lean_rate):
    """Upright and straight at ``v``, the lean starting to turn at ``lean_rate``: the other rates from the constraints
    (the rear wheel's kept at v / rR, the steer's at 0)."""
    initial, velocity = upright(v)
    return consistent_initial(bicycle(), initial, {"theta_roll": lean_rate, "theta_rear": velocity["theta_rear"]},
                              independent=["x_frame", "y_frame", "theta_yaw", "theta_roll", "theta_rear", "theta_steer",
                                           "theta_front"])


def test_a_perturbed_bicycle_at_5_m_s_keeps_its_energy_and_rolls_on_its_wheels():
    """Upright at 5 m/s and given a lean rate of 0.2 rad/s, it leans and swings back; the rolling constraints do no
    work, so its energy stays, and both wheels stay on the ground, rolling without slipping."""
    model = bicycle()
    start = start_leaning(5.0, 0.2)
    res = model.simulate(1.0, initial=start.initial, velocity=start.velocity, points=201, rtol=1e-11, atol=1e-12)
    E = res.E
    assert np.max(np.abs(E - E[0])) < 1e-9 * abs(E[0])
    assert constraint_residual(model, res) < 1e-9
    assert res["z_frame"] == pytest.approx(BENCH["rR"] * np.cos(res["theta_roll"]), abs=1e-9)  # the rear wheel's height
    lean = res["theta_roll"]
    assert 0.02 < np.max(lean) < 0.05 and abs(lean[-1]) < 0.5 * np.max(lean)


def test_a_small_lean_at_5_m_s_follows_the_benchmarks_linear_equations_and_dies_away():
    """Given a lean rate of 1 mrad/s at 5 m/s, lean and steer follow the benchmark's linearized equations (the
    published matrices' exp(A t) from (0, 0, 0.001, 0)) to their second-order error, and die away: at 5 m/s the
    benchmark is self-stable."""
    start = start_leaning(5.0, 1e-3)
    res = bicycle().simulate(5.0, initial=start.initial, velocity=start.velocity, points=101, rtol=1e-11, atol=1e-14)
    A = published(5.0)
    linear = np.array([expm(A * t) @ np.array([0.0, 0.0, 1e-3, 0.0]) for t in res.t])
    lean, steer = res["theta_roll"], -res["theta_steer"]  # the benchmark steers to the right
    assert np.max(np.abs(lean - linear[:, 0])) < 2e-6 * np.max(np.abs(linear[:, 0]))
    assert np.max(np.abs(steer - linear[:, 1])) < 2e-6 * np.max(np.abs(linear[:, 1]))
    assert np.max(np.abs(lean[-20:])) < 0.15 * np.max(np.abs(lean))


def test_parameters_given_as_symbols_take_their_values_at_run_time():
    """Tilt, wheelbase and the frame's mass as symbols: the equations keep them, and given the benchmark's values
    at run time the accelerations are KanesMethod's."""
    lam, w, mB = sp.symbols("lam w m_B", positive=True)
    model = models.whipple_bicycle(lam=lam, w=w, mB=mB)
    assert {"lam", "w", "m_B"} <= {str(s) for s in model.eq.mass_matrix.free_symbols}
    (q, u), y = kane_state(0.3, 0.1, 0.2, 0.5, -12.0, -1.0)
    a = model.numeric(params={"lam": BENCH["lam"], "w": BENCH["w"], "m_B": BENCH["mB"]}).rhs(0.0, y)[9:]
    ours = np.array([a[4], -a[6], -a[7], -a[3], -a[5], -a[8]])
    theirs = np.asarray(kane_bicycle()[2](*q, *u), dtype=float)
    assert np.max(np.abs(ours - theirs)) <= 1e-10 * (BENCH["g"] / BENCH["rR"] + sum(x * x for x in u))


def test_text_given_for_a_parameter_is_read_as_data_never_run(tmp_path):
    """Text for a dimension is read by lagrangian.text (``"1.02"``, ``"pi/10"``), and code in it is refused."""
    import lagrangian as lg

    assert models.whipple_bicycle(w="1.02", lam="pi/10").coordinate_names == NAMES
    marker = tmp_path / "ran"
    with pytest.raises(lg.ExpressionError, match=r"whipple_bicycle\(w=\)"):
        models.whipple_bicycle(w=f"__import__('os').system('touch {marker}')")
    assert not marker.exists()
