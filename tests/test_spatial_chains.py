"""Spatial chains of rigid bodies against sympy.physics.mechanics' KanesMethod.

Our bodies write their kinetic energy in their own axes (angular velocity and
centre-of-mass velocity carried joint by joint) and declare the frame, so the
derivation writes the terms from the frame's turning in closed form.  Each
check here compares the mass matrix and forcing with KanesMethod's, built
independently from the same geometry, at random states (and times, for a
driven joint), with masses and inertias drawn over decades.
"""

from __future__ import annotations

import functools

import numpy as np
import pytest
import sympy as sp
import sympy.physics.mechanics as me
from hypothesis import given, settings
from hypothesis import strategies as st

import lagrangian as lg
from lagrangian.tape import size

G = 9.81
AXIS = (0.6, 0.0, 0.8)  # the tilted revolute axis, in the first body's frame
PIVOT, COM0, HINGE, COM1, TIP = (0.05, -0.02, 0.0), (0.03, 0.01, -0.21), (0.0, 0.04, -0.43), (0.12, 0.0, 0.0), (0.0, 0.0, -0.31)


def chain(m0, I0, m1, I1, m2=None, I2=None, driven=None) -> lg.Model:
    """Body 0 on a spherical joint ("zxz") off its centre, body 1 on a revolute joint about a tilted axis (driven
    when ``driven`` is an expression of t), body 2 (unless ``m2`` is None) on a spherical joint ("xyz") at body
    1's tip."""
    m = lg.Model("spatial chain", dim=3)
    m.add("body", "b0", "b0", m=m0, inertia=I0, com=COM0, points={"hinge": HINGE})
    m.add("body", "b1", "b1", m=m1, inertia=I1, com=COM1, points={"tip": TIP})
    if m2 is not None:
        m.add("body", "b2", "b2", m=m2, inertia=I2, com=(0.0, 0.0, -0.17))
    m.add("spherical", "s0", ("ground", "b0"), parent_point=PIVOT, sequence="zxz")
    m.add("revolute", "r1", ("b0", "b1"), parent_point=HINGE, axis=AXIS, **({"angle": driven} if driven is not None else {}))
    if m2 is not None:
        m.add("spherical", "s2", ("b1", "b2"), parent_point=TIP)
    m.add("gravity", "g", g=G)
    return m


def vec(frame, xyz):
    return xyz[0] * frame.x + xyz[1] * frame.y + xyz[2] * frame.z


@functools.lru_cache(maxsize=None)
def kane(driven: bool):
    """KanesMethod for :func:`chain` with symbolic masses and inertias (derived once), as NumPy functions of
    (parameters, q, u, t); ``driven``: bodies 0 and 1 only, body 1 turned by 0.7 sin(1.3 t)."""
    T = me.dynamicsymbols._t
    m = sp.symbols("m0:3", positive=True)
    I = [sp.symbols(f"I{k}_0:{6 if k == 0 else 3}") for k in range(3)]  # xx, yy, zz (, xy, yz, zx: body 0)
    q = list(me.dynamicsymbols("q0:3")) + ([] if driven else list(me.dynamicsymbols("q3:7")))
    u = [me.dynamicsymbols(f"u{k}") for k in range(len(q))]
    angle1 = 0.7 * sp.sin(1.3 * T) if driven else q[3]
    N = me.ReferenceFrame("N")
    O = me.Point("O")
    O.set_vel(N, 0)
    A0 = N.orientnew("A0", "Body", q[0:3], "zxz")
    A1 = A0.orientnew("A1", "Axis", [angle1, vec(A0, AXIS)])
    A2 = A1.orientnew("A2", "Body", q[4:7] if not driven else [0, 0, 0], "xyz")
    P0 = O.locatenew("P0", vec(N, PIVOT))
    G0 = P0.locatenew("G0", vec(A0, COM0))
    H = P0.locatenew("H", vec(A0, HINGE))
    G1 = H.locatenew("G1", vec(A1, COM1))
    Tp = H.locatenew("T", vec(A1, TIP))
    G2 = Tp.locatenew("G2", vec(A2, (0.0, 0.0, -0.17)))
    for point in (G0, H, G1, Tp, G2):
        point.set_vel(N, point.pos_from(O).dt(N))
    placed = ((G0, A0), (G1, A1)) + (() if driven else ((G2, A2),))
    bodies = [me.RigidBody(f"b{k}", Gk, Ak, m[k], (me.inertia(Ak, *I[k]), Gk)) for k, (Gk, Ak) in enumerate(placed)]
    loads = [(Gk, -m[k] * G * N.z) for k, (Gk, _) in enumerate(placed)]
    km = me.KanesMethod(N, q, u, kd_eqs=[qi.diff(T) - ui for qi, ui in zip(q, u)])
    km.kanes_equations(bodies, loads)
    Q, U, t = sp.symbols(f"Q0:{len(q)}"), sp.symbols(f"U0:{len(q)}"), sp.Symbol("t")
    subs = {**dict(zip(u, U)), **{qi.diff(T): ui for qi, ui in zip(q, U)}}
    params = [*m[:len(placed)], *[x for row in I[:len(placed)] for x in row]]
    args = (params, Q, U, t)
    M = sp.lambdify(args, km.mass_matrix.xreplace({**subs, **dict(zip(q, Q)), T: t}), "numpy", cse=True)
    f = sp.lambdify(args, km.forcing.xreplace({**subs, **dict(zip(q, Q)), T: t}), "numpy", cse=True)
    return M, f


def inertia(draw_scale, ratios, off):
    """A positive-definite inertia tensor with principal-like diagonal ``draw_scale · ratios`` and small products."""
    a, b, c = (draw_scale * r for r in ratios)
    return [[a, off * a, 0.0], [off * a, b, -off * b], [0.0, -off * b, c]]


def flat(I, products=False):
    return [I[0][0], I[1][1], I[2][2], *([I[0][1], I[1][2], I[2][0]] if products else [])]


def worst_difference(model, params, driven: bool, rng) -> float:
    """Largest relative difference of the accelerations q̈ (ours: the compiled right-hand side) and of the mass
    matrix from KanesMethod's, at random states and times."""
    M_ref, f_ref = kane(driven)
    numeric = model.numeric()
    numeric.use_compiled("tape")
    n = len(model.coordinate_names)
    worst = 0.0
    for _ in range(6):
        q = rng.uniform(-1.2, 1.2, n)
        q[1] = rng.uniform(0.3, 2.8)  # zxz: away from its gimbal lock at 0 and π
        v = rng.uniform(-2.0, 2.0, n)
        time = rng.uniform(0.0, 3.0)
        ours = numeric.rhs(time, np.concatenate([q, v]))[n:]
        theirs = np.linalg.solve(np.asarray(M_ref(params, q, v, time), float),
                                 np.asarray(f_ref(params, q, v, time), float).ravel())
        worst = max(worst, float(np.max(np.abs(ours - theirs)) / np.max(np.abs(theirs))))
    return worst


masses = st.floats(1e-2, 1e2)
scales = st.floats(1e-4, 1e0)
ratios = st.tuples(st.floats(0.6, 1.0), st.floats(0.6, 1.0), st.floats(0.6, 1.0))
offs = st.floats(-0.2, 0.2)


@settings(max_examples=4, deadline=None)
@given(masses, scales, ratios, offs, masses, scales, ratios, masses, scales, ratios, st.integers(0, 2**32 - 1))
def test_spatial_chain_matches_kane_over_decades(m0, s0, r0, o0, m1, s1, r1, m2, s2, r2, seed):
    I0, I1, I2 = inertia(s0, r0, o0), inertia(s1, r1, 0.0), inertia(s2, r2, 0.0)
    model = chain(m0, I0, m1, I1, m2, I2)
    params = [m0, m1, m2, *flat(I0, True), *flat(I1), *flat(I2)]
    assert worst_difference(model, params, False, np.random.default_rng(seed)) < 1e-9


def test_driven_joint_in_a_spatial_chain_matches_kane():
    """A rheonomic frame: body 1 turned by a prescribed angle 0.7 sin(1.3 t) (ordinary values, no symbols)."""
    I0, I1 = inertia(0.021, (1.0, 0.8, 0.7), 0.1), inertia(0.0034, (1.0, 0.9, 0.6), 0.0)
    model = chain(0.3, I0, 0.047, I1, driven=0.7 * sp.sin(1.3 * lg.t))
    params = [0.3, 0.047, *flat(I0, True), *flat(I1)]
    assert worst_difference(model, params, True, np.random.default_rng(5)) < 1e-9


def compiled(model):
    numeric = model.numeric()
    numeric.use_compiled("tape")
    return numeric


def test_declared_frames_give_the_same_equations_smaller(monkeypatch):
    """The closed-form frame terms against the general formula (every coefficient differentiated): the same
    mass matrix and forcing at random states, in fewer operations.  (Against KanesMethod: benchmarks/spatial.py.)"""
    def build():
        return chain(0.3, inertia(0.02, (1, 0.9, 0.8), 0.1), 0.2, inertia(0.01, (1, 1, 0.7), 0), 0.1,
                     inertia(0.004, (0.8, 1, 0.9), 0))

    declared = build()
    declared.eq  # noqa: B018 - derived before the declarations are switched off
    monkeypatch.setattr(lg.derive.Derivation, "frames", lambda self, frames: None)
    general = build()
    assert size(list(declared.eq.M) + list(declared.eq.f)) < 0.9 * size(list(general.eq.M) + list(general.eq.f))
    rng = np.random.default_rng(11)
    for _ in range(5):
        q, v = rng.uniform(-1.2, 1.2, 7), rng.uniform(-2, 2, 7)
        q[1] = rng.uniform(0.3, 2.8)
        y = np.concatenate([q, v])
        a1, a2 = (compiled(m).rhs(0.0, y) for m in (declared, general))
        assert np.allclose(a1, a2, rtol=1e-11, atol=1e-12 * np.abs(a2).max())


class _BadFrame(lg.Component):
    """A component declaring a moving frame that is not a 3-vector."""

    kind = "bad_frame"
    domain = "mechanical"
    terminals = ("p",)

    def contribute(self, ctx):
        v = ctx.view.velocity(self.nodes[0])
        return lg.Contribution(T=v[0] ** 2 / 2, frames=[self.frame(v)])

    @staticmethod
    def frame(v):
        return lg.MovingFrame(sp.Matrix([v[0], v[1]]))

    @classmethod
    def example(cls):
        return lg.Example("p", {})


def test_a_moving_frame_that_is_not_a_3_vector_is_refused_naming_the_component(registry_with, monkeypatch):
    m = lg.Model("bad", dim=3, registry=registry_with(_BadFrame))
    m.add("mass", "p", "p", m=1)
    m.add("bad_frame", "b", "p")
    with pytest.raises(lg.ModelError, match=r"bad_frame 'b': frames\[0\]\.omega must be a 3 × 1"):
        m.mass_matrix  # noqa: B018
    monkeypatch.setattr(_BadFrame, "frame", staticmethod(lambda v: lg.MovingFrame(v, v)))  # velocities: one vector
    other = lg.Model("bad", dim=3, registry=registry_with(_BadFrame))
    other.add("mass", "p", "p", m=1)
    other.add("bad_frame", "b", "p")
    with pytest.raises(lg.ModelError, match=r"bad_frame 'b': frames\[0\]\.velocities must be a tuple of 3 × 1"):
        other.mass_matrix  # noqa: B018


def test_free_body_carrying_a_slider_matches_kane():
    """Translations in the joints (a free joint's x, y, z; a prismatic joint along a tilted axis of a turning body)
    enter the body-frame velocities as rates of the joint offset: checked against KanesMethod."""
    axis, at, com_a, com_b = (0.0, 0.6, -0.8), (0.11, -0.05, 0.02), (0.02, -0.01, 0.04), (0.0, 0.03, -0.02)
    Ia, Ib = inertia(0.013, (1.0, 0.85, 0.7), 0.15), inertia(0.0021, (0.9, 1.0, 0.75), 0.0)
    m = lg.Model("free body with a slider", dim=3)
    m.add("body", "a", "a", m=0.83, inertia=Ia, com=com_a)
    m.add("body", "b", "b", m=0.057, inertia=Ib, com=com_b)
    m.add("free", "fly", ("ground", "a"), sequence="zyx")
    m.add("prismatic", "slide", ("a", "b"), parent_point=at, axis=axis)
    m.add("spring", "k", ("a.origin", "b.origin"), k=37.0, rest_length=0.1)
    m.add("gravity", "g", g=G)

    T = me.dynamicsymbols._t
    q = me.dynamicsymbols("q0:7")
    u = me.dynamicsymbols("u0:7")
    N = me.ReferenceFrame("N")
    O = me.Point("O")
    O.set_vel(N, 0)
    A = N.orientnew("A", "Body", q[3:6], "zyx")
    Oa = O.locatenew("Oa", q[0] * N.x + q[1] * N.y + q[2] * N.z)
    Ga = Oa.locatenew("Ga", vec(A, com_a))
    Ob = Oa.locatenew("Ob", vec(A, at) + q[6] * vec(A, axis))
    Gb = Ob.locatenew("Gb", vec(A, com_b))
    for point in (Oa, Ga, Ob, Gb):
        point.set_vel(N, point.pos_from(O).dt(N))
    stretch = Ob.pos_from(Oa).magnitude()
    force = 37.0 * (stretch - 0.1) * Ob.pos_from(Oa).normalize()
    bodies = [me.RigidBody("A", Ga, A, 0.83, (me.inertia(A, *flat(Ia, True)), Ga)),
              me.RigidBody("B", Gb, A, 0.057, (me.inertia(A, *flat(Ib)), Gb))]
    loads = [(Ga, -0.83 * G * N.z), (Gb, -0.057 * G * N.z), (Ob, -force), (Oa, force)]
    km = me.KanesMethod(N, q, u, kd_eqs=[qi.diff(T) - ui for qi, ui in zip(q, u)])
    km.kanes_equations(bodies, loads)
    Q, U = sp.symbols("Q0:7"), sp.symbols("U0:7")
    subs = {**dict(zip(u, U)), **{qi.diff(T): ui for qi, ui in zip(q, U)}}
    M_ref = sp.lambdify((Q, U), km.mass_matrix.xreplace({**subs, **dict(zip(q, Q))}), "numpy", cse=True)
    f_ref = sp.lambdify((Q, U), km.forcing.xreplace({**subs, **dict(zip(q, Q))}), "numpy", cse=True)
    assert m.coordinate_names == ["x_fly", "y_fly", "z_fly", "gamma_fly", "beta_fly", "alpha_fly", "s_slide"]  # z, y, x
    numeric = compiled(m)
    rng = np.random.default_rng(3)
    for _ in range(6):
        qs = rng.uniform(-1.0, 1.0, 7)
        qs[6] = rng.uniform(0.05, 0.4)
        us = rng.uniform(-2.0, 2.0, 7)
        ours = numeric.rhs(0.0, np.concatenate([qs, us]))[7:]
        theirs = np.linalg.solve(np.asarray(M_ref(qs, us), float), np.asarray(f_ref(qs, us), float).ravel())
        assert np.max(np.abs(ours - theirs)) < 1e-9 * np.max(np.abs(theirs))
