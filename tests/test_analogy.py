"""Analogies between mechanisms and circuits, both directions, checked symbolically.

The expected equations are the mechanism's own (derived independently of the
analogue); the analogue's equations, rewritten through the coordinate map,
must equal them term by term.
"""

import networkx as nx
import pytest
import sympy as sp
from hypothesis import given, settings
from hypothesis import strategies as st

import lagrangian as lg
from lagrangian.analogy import AnalogyError, map_model

m_, k_, c_, F0, w = sp.symbols("m k c F0 omega", positive=True)
ANALOGIES = ["force-voltage", "force-current"]


def equations_in_source_terms(mapped):
    """The analogue's residuals M q̈ − f, rewritten in the source model's coordinates."""
    target = mapped.model
    funcs = [c.function for c in target.coordinates]
    acc = sp.Matrix([f.diff(lg.t, 2) for f in funcs])
    return [mapped.to_source(r) for r in target.mass_matrix * acc - target.forcing]


def residuals(model):
    funcs = [c.function for c in model.coordinates]
    acc = sp.Matrix([f.diff(lg.t, 2) for f in funcs])
    return list(model.mass_matrix * acc - model.forcing)


def same_equations(a, b):
    """Two residual lists describe the same equations: each of a is ± one of b (order may differ)."""
    remaining = [sp.expand(r) for r in b]
    for r in a:
        r = sp.expand(r)
        match = next((i for i, s in enumerate(remaining) if sp.simplify(r - s) == 0 or sp.simplify(r + s) == 0), None)
        if match is None:
            return False
        remaining.pop(match)
    return not remaining


def driven_msd():
    m = lg.Model("msd")
    m.add("mass", "m", "p", m=m_)
    m.add("spring", "k", ("ground", "p"), k=k_)
    m.add("damper", "c", ("ground", "p"), c=c_)
    m.add("force", "F", "p", F=F0 * sp.sin(w * lg.t))
    return m


def chain():
    m = lg.Model("chain")
    m.add("mass", "m1", "a", m=1)
    m.add("mass", "m2", "b", m=2)
    m.add("spring", "k1", ("ground", "a"), k=4)
    m.add("spring", "k2", ("a", "b"), k=3)
    m.add("damper", "c2", ("a", "b"), c=sp.Rational(3, 10))
    m.add("force", "F", "b", F=sp.cos(lg.t))
    m.add("gravity", "g", g=sp.Symbol("g", positive=True))
    return m


def shaken():
    """A mass on a spring and damper whose far end is driven along X(t) = 0.1 sin t."""
    m = lg.Model("shaken")
    m.add("mass", "m", "p", m=1)
    m.add("spring", "k", ("s", "p"), k=9)
    m.add("damper", "c", ("s", "p"), c=sp.Rational(1, 2))
    m.add("prescribed_motion", "X", "s", position=sp.Rational(1, 10) * sp.sin(lg.t))
    return m


@pytest.mark.parametrize("analogy", ANALOGIES)
@pytest.mark.parametrize("build", [driven_msd, chain, shaken], ids=["msd", "chain", "shaken"])
def test_analogue_equations_equal_the_mechanism(build, analogy):
    mech = build()
    mapped = map_model(mech, analogy)
    assert mapped.direction == "forward"
    assert {c.domains for c in mapped.model.components.values()} == {("electrical",)}
    assert mapped.model.options["formulation"] == ("charge" if analogy == "force-voltage" else "flux")
    assert same_equations(equations_in_source_terms(mapped), residuals(mech))


@pytest.mark.parametrize("analogy", ANALOGIES)
def test_element_table_and_values(analogy):
    mapped = map_model(driven_msd(), analogy)
    kinds = {name: c.kind for name, c in mapped.model.components.items()}
    if analogy == "force-voltage":
        assert kinds == {"L_m": "inductor", "C_k": "capacitor", "R_c": "resistor", "V_F": "voltage_source"}
        comps = mapped.model.components
        assert (comps["L_m"].L, comps["C_k"].C, comps["R_c"].R) == (m_, 1 / k_, c_)
    else:
        assert kinds == {"C_m": "capacitor", "L_k": "inductor", "R_c": "resistor", "I_F": "current_source"}
        comps = mapped.model.components
        assert (comps["C_m"].C, comps["L_k"].L, comps["R_c"].R) == (m_, 1 / k_, 1 / c_)
    assert mapped.origin == {name: name.split("_", 1)[1] for name in kinds}


def test_force_current_keeps_the_topology_and_force_voltage_takes_the_dual():
    mech = chain()
    fc = map_model(mech, "force-current").model
    # same nodes: every mechanical node is a circuit node, masses become capacitors to ground
    assert set(fc.nodes) == set(mech.nodes)
    # force-voltage: elements in parallel between a and b (k2, c2) end up in series, sharing one mesh current
    fv = map_model(mech, "force-voltage").model
    g = fv.graph()
    series_node = set(g.edges(keys=True))
    (u1, v1, _), (u2, v2, _) = [(u, v, k) for u, v, k in series_node if k in ("C_k2", "R_c2")]
    shared = {u1, v1} & {u2, v2}
    assert len(shared) == 1 and g.degree(shared.pop()) == 2


@pytest.mark.parametrize("analogy", ANALOGIES)
def test_round_trip_gives_the_same_mechanism(analogy):
    mech = chain()
    there = map_model(mech, analogy)
    back = map_model(there.model, analogy)
    assert back.direction == "inverse"
    kinds = sorted(c.kind for c in back.model.components.values())
    assert kinds.count("mass") == 2 and kinds.count("spring") == 2 and kinds.count("damper") == 1
    # compose the coordinate maps: back-model coordinates -> circuit -> original
    composed = {f: there.to_source(expr) for f, expr in back.coordinates.items()}
    funcs = [c.function for c in back.model.coordinates]
    acc = sp.Matrix([f.diff(lg.t, 2) for f in funcs])
    res = [sp.sympify(r).subs(composed).doit() for r in back.model.mass_matrix * acc - back.model.forcing]
    assert same_equations(res, residuals(mech))


def test_circuit_to_mechanism_series_rlc_is_a_driven_oscillator():
    L, C, R, E = sp.symbols("L C R E", positive=True)
    rlc = lg.Model("rlc")
    rlc.add("voltage_source", "V1", ("n1", "0"), E=E * sp.cos(lg.t))
    rlc.add("resistor", "R1", ("n1", "n2"), R=R)
    rlc.add("inductor", "L1", ("n2", "n3"), L=L)
    rlc.add("capacitor", "C1", ("n3", "0"), C=C)
    mech = map_model(rlc, "force-voltage").model
    (x,) = [c.function for c in mech.coordinates]
    # L x'' + R x' + x/C = ±E cos t (the sign depends only on the orientation the dual picks)
    (r,) = residuals(mech)
    expected = L * x.diff(lg.t, 2) + R * x.diff(lg.t) + x / C
    assert sp.simplify(r - expected - E * sp.cos(lg.t)) == 0 or sp.simplify(r - expected + E * sp.cos(lg.t)) == 0


def test_circuit_to_mechanism_parallel_rlc_force_current():
    rlc = lg.Model("parallel", formulation="flux")
    rlc.add("current_source", "I1", ("0", "n1"), I=sp.sin(2 * lg.t))
    rlc.add("resistor", "R1", ("n1", "0"), R=2)
    rlc.add("inductor", "L1", ("n1", "0"), L=sp.Rational(1, 4))
    rlc.add("capacitor", "C1", ("n1", "0"), C=3)
    mapped = map_model(rlc, "force-current")
    kinds = sorted(c.kind for c in mapped.model.components.values())
    assert kinds == ["damper", "force", "mass", "spring"]
    comps = {c.kind: c for c in mapped.model.components.values()}
    assert (comps["mass"].m, comps["spring"].k, comps["damper"].c, comps["force"].F) == (3, 4, sp.Rational(1, 2), sp.sin(2 * lg.t))
    assert same_equations(equations_in_source_terms(mapped), residuals(rlc))


def test_third_party_kind_takes_part():
    """The example plugin declares force-voltage analogues for its cubic spring (and a cubic capacitor)."""
    m = lg.Model("duffing")
    m.add("mass", "m", "p", m=1)
    m.add("cubic_spring", "s", ("ground", "p"), k=2, k3=sp.Rational(1, 2))
    mapped = map_model(m, "force-voltage")
    assert {c.kind for c in mapped.model.components.values()} == {"inductor", "cubic_capacitor"}
    assert sp.simplify(mapped.to_source(mapped.model.lagrangian) - m.lagrangian) == 0
    with pytest.raises(AnalogyError, match="cubic_spring.*register_analogues"):
        map_model(m, "force-current")


def test_non_planar_network_suggests_force_current():
    m = lg.Model("k33")
    left, right = ["a", "b", "c"], ["d", "e", "ground"]
    for i, u in enumerate(left + right[:2]):
        m.add("mass", f"m{i}", u, m=1)
    for u in left:
        for v in right:
            m.add("spring", f"k_{u}{v}", (u, v), k=1)
    assert not nx.check_planarity(nx.Graph(m.graph()))[0]
    with pytest.raises(AnalogyError, match="not planar.*force–current"):
        map_model(m, "force-voltage")
    mapped = map_model(m, "force-current")  # keeps the topology: fine
    assert same_equations(equations_in_source_terms(mapped), residuals(m))


@pytest.mark.parametrize(
    "make, analogy, pattern",
    [
        (lambda m: m.add("capacitor", "C9", ("n1", "n2"), C=1), "force-current", "C9.*two moving points.*other analogy"),
        (lambda m: m.add("voltage_source", "V9", ("n1", "n2"), E=1), "force-current", "V9.*two moving points"),
    ],
)
def test_circuit_elements_without_mechanical_analogue(make, analogy, pattern):
    m = lg.Model("floating", formulation="flux")
    m.add("capacitor", "C1", ("n1", "0"), C=1)
    m.add("inductor", "L1", ("n2", "0"), L=1)
    m.add("capacitor", "C2", ("n2", "0"), C=1)
    make(m)
    with pytest.raises(AnalogyError, match=pattern):
        map_model(m, analogy)


def test_mechanical_rest_length_and_unknown_analogy_are_clear_errors():
    m = lg.Model("rest")
    m.add("mass", "m", "p", m=1)
    m.add("spring", "k", ("ground", "p"), k=1, rest_length=0.5)
    with pytest.raises(AnalogyError, match="'k' has a rest length"):
        map_model(m, "force-current")
    with pytest.raises(lg.UnknownNameError, match="force-voltage"):
        map_model(m, "force-volt")


def test_initial_state_maps_through_the_coordinates():
    mapped = map_model(chain(), "force-voltage")
    q0, v0 = mapped.initial({"x_a": 0.1, "x_b": -0.2}, {"x_a": 0.3}, params={"g": 9.81})
    by_source = {str(expr): name for name, expr in zip((c.name for c in mapped.model.coordinates), mapped.coordinates.values())}
    assert q0[by_source["x_a(t)"]] == pytest.approx(0.1) and q0[by_source["x_b(t)"]] == pytest.approx(-0.2)
    assert v0[by_source["x_a(t)"]] == pytest.approx(0.3) and v0[by_source["x_b(t)"]] == 0


def test_coupled_model_maps_its_mechanical_part_and_the_coil_to_a_gyrator():
    Bl, Le, Re, mc, ks, cs = sp.symbols("Bl L_e R_e m_c k_s c_s", positive=True)
    m = lg.Model("speaker")
    m.add("voltage_source", "V", ("n1", "0"), E=sp.sin(lg.t))
    m.add("resistor", "Re", ("n1", "n2"), R=Re)
    m.add("inductor", "Le", ("n2", "n3"), L=Le)
    m.add("moving_coil", "coil", ("n3", "0", "cone"), Bl=Bl)
    m.add("mass", "mc", "cone", m=mc)
    m.add("spring", "ks", ("ground", "cone"), k=ks)
    m.add("damper", "cs", ("ground", "cone"), c=cs)
    mapped = map_model(m, "force-voltage")
    kinds = {name: c.kind for name, c in mapped.model.components.items()}
    assert kinds["G_coil"] == "gyrator" and kinds["Le"] == "inductor" and kinds["L_mc"] == "inductor"
    assert mapped.origin["Le"] == "Le" and mapped.origin["G_coil"] == "coil"
    assert same_equations(equations_in_source_terms(mapped), residuals(m))
    with pytest.raises(AnalogyError, match="formulation='flux'"):
        map_model(m, "force-current")  # the coil needs the charge formulation the flux analogue cannot keep


@pytest.mark.parametrize("analogy", ["torque-voltage", "torque-current"])
def test_rotational_analogues_equal_the_shaft_equations(analogy):
    J, k, c, tau = sp.symbols("J k c tau", positive=True)
    m = lg.Model("shaft")
    m.add("inertia", "J1", "a", J=J)
    m.add("inertia", "J2", "b", J=2 * J)
    m.add("torsion_spring", "k1", ("ground", "a"), k=k)
    m.add("torsion_spring", "k2", ("a", "b"), k=k)
    m.add("rotary_damper", "c2", ("a", "b"), c=c)
    m.add("torque", "T", "b", tau=tau * sp.cos(lg.t))
    mapped = map_model(m, analogy)
    assert same_equations(equations_in_source_terms(mapped), residuals(m))


def _divergence(signed: dict, ends) -> dict:
    """Net signed count of edges at each node: zero everywhere for a cycle (a sum of closed loops)."""
    out: dict = {}
    for key, sign in signed.items():
        a, b = ends(key)
        out[a] = out.get(a, 0) + sign
        out[b] = out.get(b, 0) - sign
    return {n: v for n, v in out.items() if v}


@settings(max_examples=60, deadline=None)
@given(st.data())
def test_the_dual_of_a_planar_multigraph_swaps_its_cycles_and_its_cuts(data):
    """Random planar networks (a fan: nodes on a path, each joined to the path's neighbours or to ground, or to
    both), each branch repeated up to three times, either way round: the dual has E − V + 2 nodes, the branches at
    each node of the network form a loop of the dual, and the branches round each mesh form a loop of the network,
    which is what makes a dual."""
    from lagrangian.circuits.analogy import dual_branches

    nodes = [f"p{i}" for i in range(data.draw(st.integers(1, 5)))]
    pairs = [("ground", nodes[0])]
    for prev, node in zip(nodes, nodes[1:]):  # connected: by the path, by ground, or both
        both = [(prev, node), ("ground", node)]
        pairs += [p for p in both if data.draw(st.booleans())] or [both[data.draw(st.integers(0, 1))]]
    g = nx.MultiGraph()
    for j, (u, v) in enumerate(pairs):
        for r in range(data.draw(st.integers(1, 3))):
            a, b = (u, v) if data.draw(st.booleans()) else (v, u)
            g.add_edge(a, b, key=f"e{j}_{r}", a=a, b=b)
    dual = dual_branches(g)
    edges = {k: (d["a"], d["b"]) for _, _, k, d in g.edges(keys=True, data=True)}
    meshes = {f for pair in dual.values() for f in pair}
    assert "ground" in meshes
    assert len(meshes) == len(edges) - g.number_of_nodes() + 2
    for node in g.nodes:  # a node's star: a loop of the dual
        star = {k: (1 if a == node else -1) for k, (a, b) in edges.items() if node in (a, b) and a != b}
        assert not _divergence(star, dual.__getitem__)
    for mesh in meshes:  # a mesh's boundary: a loop of the network
        boundary = {k: (1 if r == mesh else -1) for k, (r, l) in dual.items() if mesh in (r, l) and r != l}
        assert not _divergence(boundary, edges.__getitem__)
