"""Every error lagrangian promises: its class, and a message naming the culprit and the fix.

Each case is a small function that must raise.  One parametrized test checks
the class (always a subclass of :class:`lagrangian.LagrangianError`) and the
key words of the message with ``match=``; another checks that none of them is
a bare ``KeyError``/``ZeroDivisionError``/``SympifyError`` leaking out of the
library's internals.
"""

from __future__ import annotations

import math
import re
import types
import warnings

import pytest
import sympy as sp

import lagrangian as lg

# ---------------------------------------------------------------------------
# small builders


def oscillator(**options) -> lg.Model:
    """mass on a spring to ground: one coordinate, x_p."""
    m = lg.Model("osc", **options)
    m.add("mass", "M", "p", m=1)
    m.add("spring", "k", ("ground", "p"), k=1)
    return m


def quiet_simulate(model: lg.Model, *args, **kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", lg.InitialConditionWarning)
        return model.simulate(*args, **kwargs)


# --- building: kinds, parameters, values -----------------------------------


def unknown_kind():
    lg.Model().add("sprng", "k1", ("ground", "p"), k=1)


def unknown_kind_far_from_all():
    lg.Model().add("flux_capacitor", "fc", ("ground", "p"))


def missing_parameter():
    lg.Model().add("spring", "k1", ("ground", "p"))


def unknown_parameter():
    lg.Model().add("spring", "k1", ("ground", "p"), k=1, rest_lenght=0.5)


def negative_mass():
    lg.Model().add("mass", "m1", "p", m=-2)


def zero_capacitance():
    lg.Model().add("capacitor", "C1", ("n1", "ground"), C=0)


def negative_damping():
    lg.Model().add("damper", "c1", ("ground", "p"), c=-0.1)


def negative_rest_length():
    lg.Model().add("spring", "k1", ("ground", "p"), k=1, rest_length=-1)


def non_number_string():
    lg.Model().add("mass", "m1", "p", m="not a number")


def unparsable_string():
    lg.Model().add("resistor", "R1", ("n1", "ground"), R="2 +")


def bool_value():
    lg.Model().add("mass", "m1", "p", m=True)


def nan_value():
    lg.Model().add("spring", "k1", ("ground", "p"), k=float("nan"))


def inf_value():
    lg.Model().add("inductor", "L1", ("n1", "ground"), L=float("inf"))


def division_by_zero_string():
    lg.Model().add("capacitor", "C1", ("n1", "ground"), C="1/0")


def complex_value():
    lg.Model().add("mass", "m1", "p", m=1j)


def list_for_scalar():
    lg.Model().add("mass", "m1", "p", m=[1, 2])


def time_dependent_non_signal():
    lg.Model().add("spring", "k1", ("ground", "p"), k=1 + lg.t)


def symbol_declared_negative():
    lg.Model().add("mass", "m1", "p", m=sp.Symbol("m", negative=True))


def symbol_declared_zero_capacitance():
    lg.Model().add("capacitor", "C1", ("n1", "ground"), C=sp.Symbol("C", zero=True))


def string_vector():
    lg.Model(dim=2).add("gravity", "g", direction="down")


def symbolic_mass_negative_at_simulate():
    m = lg.Model("sym")
    m.add("mass", "m1", "p", m=sp.Symbol("m"))
    m.add("spring", "k1", ("ground", "p"), k=1)
    quiet_simulate(m, 1, params={"m": -1})


def symbolic_capacitance_zero_at_simulate():
    m = lg.Model("symc")
    m.add("capacitor", "C1", ("n1", "ground"), C="C")
    m.add("inductor", "L1", ("n1", "ground"), L=1)
    quiet_simulate(m, 1, params={"C": 0})


def symbolic_parameter_not_a_number_at_simulate():
    m = lg.Model("sym")
    m.add("mass", "m1", "p", m=sp.Symbol("m"))
    m.add("spring", "k1", ("ground", "p"), k=1)
    quiet_simulate(m, 1, params={"m": "heavy"})


def symbolic_parameter_nan_at_simulate():
    m = lg.Model("sym")
    m.add("mass", "m1", "p", m=sp.Symbol("m"))
    m.add("spring", "k1", ("ground", "p"), k=1)
    quiet_simulate(m, 1, params={"m": float("nan")})


def symbolic_parameters_without_values():
    m = lg.Model("needs-values")
    m.add("mass", "m1", "p", m=sp.Symbol("m"))
    m.add("spring", "k1", ("ground", "p"), k="k")
    quiet_simulate(m, 1)


def unknown_parameter_at_simulate():
    m = lg.Model("sym")
    m.add("mass", "m1", "p", m=sp.Symbol("mass"))
    m.add("spring", "k1", ("ground", "p"), k=1)
    quiet_simulate(m, 1, params={"mas": 1})


# --- nodes and names --------------------------------------------------------


def unknown_node():
    m = oscillator()
    m.check_node("pp")


def unknown_node_far():
    m = oscillator()
    m.check_node("x")


def invalid_node_name():
    lg.Model().add("mass", "m1", "", m=1)


def non_string_node_name():
    oscillator().check_node(None)


def unknown_component():
    oscillator().component("kk")


def dangling_node():
    m = oscillator()
    m.node("n9")
    m.lagrangian  # noqa: B018 - assembling is what raises


def duplicate_name():
    m = lg.Model()
    m.add("mass", "M", "p", m=1)
    m.add("spring", "M", ("ground", "p"), k=1)


def duplicate_name_across_domains():
    m = lg.Model()
    m.add("inductor", "X1", ("n1", "ground"), L=1)
    m.add("mass", "X1", "p", m=1)


def too_many_nodes():
    lg.Model().add("mass", "m1", ("a", "b"), m=1)


def too_few_nodes():
    lg.Model().add("spring", "k1", "a", k=1)


def nodes_for_global_component():
    lg.Model().add("gravity", "g", "a", g=9.81)


def empty_component_name():
    lg.Model().add("mass", "", "p", m=1)


def mixed_domains():
    m = lg.Model()
    m.add("mass", "M", "n1", m=1)
    m.add("inductor", "L1", ("n1", "ground"), L=1)
    m.coordinates  # noqa: B018


def empty_model():
    lg.Model("nothing").lagrangian  # noqa: B018


# --- topology ----------------------------------------------------------------


def floating_spring():
    m = oscillator()
    m.add("spring", "kf", ("a", "b"), k=1)
    m.coordinates  # noqa: B018


def floating_circuit_island():
    m = lg.Model()
    m.add("inductor", "L0", ("n1", "ground"), L=1)
    m.add("capacitor", "C0", ("n1", "ground"), C=1)
    m.add("inductor", "Lx", ("a", "b"), L=1)
    m.add("capacitor", "Cx", ("a", "b"), C=1)
    m.coordinates  # noqa: B018


def parallel_voltage_sources(formulation):
    m = lg.Model(formulation=formulation)
    m.add("voltage_source", "V1", ("n1", "ground"), E=1)
    m.add("voltage_source", "V2", ("n1", "ground"), E=2)
    m.add("resistor", "R1", ("n1", "ground"), R=1)
    m.coordinates  # noqa: B018


def triangle_of_voltage_sources(formulation):
    m = lg.Model(formulation=formulation)
    m.add("voltage_source", "Va", ("a", "b"), E=1)
    m.add("voltage_source", "Vb", ("b", "c"), E=1)
    m.add("voltage_source", "Vc", ("c", "a"), E=1)
    m.add("resistor", "R1", ("a", "ground"), R=1)
    m.add("inductor", "L1", ("b", "ground"), L=1)
    m.coordinates  # noqa: B018


def current_source_cut_set(formulation):
    m = lg.Model(formulation=formulation)
    m.add("current_source", "I1", ("ground", "n1"), I=1)
    m.add("capacitor", "C1", ("n1", "n2"), C=1)
    m.add("current_source", "I2", ("n2", "ground"), I=1)
    m.add("resistor", "R0", ("n3", "ground"), R=1)
    m.add("inductor", "L0", ("n3", "ground"), L=1)
    m.coordinates  # noqa: B018


def current_source_on_a_point_of_a_body(formulation):
    """A current source between ground and a body's point: in the whole graph the point hangs on the body, so no
    cut-set shows; in its own domain the source is alone."""
    m = lg.Model("cart", dim=2, formulation=formulation)
    m.add("body", "cart", "C", m=2.0, inertia=0.5)
    m.add("prismatic", "PX", ("ground", "C"))
    m.add("current_source", "Q", ("0", "C.origin"), I=sp.sin(lg.t))
    m.coordinates  # noqa: B018


def two_prescribed_motions_on_one_node():
    m = lg.Model()
    m.add("prescribed_motion", "P1", "s", position=lg.t)
    m.add("prescribed_motion", "P2", "s", position=2 * lg.t)
    m.add("spring", "k1", ("s", "p"), k=1)
    m.add("mass", "M", "p", m=1)
    m.coordinates  # noqa: B018


def callable_voltage_source_flux():
    m = lg.Model(formulation="flux")
    m.add("voltage_source", "Vs", ("n1", "ground"), E=lambda time: 1.0)
    m.add("resistor", "R1", ("n1", "n2"), R=1)
    m.add("capacitor", "C1", ("n2", "ground"), C=1)
    m.coordinates  # noqa: B018


def callable_current_source_charge():
    m = lg.Model(formulation="charge")
    m.add("current_source", "Is", ("ground", "n1"), I=lambda time: 1.0)
    m.add("resistor", "R1", ("n1", "ground"), R=1)
    m.add("inductor", "L1", ("n1", "ground"), L=1)
    m.coordinates  # noqa: B018


def callable_prescribed_motion():
    m = lg.Model()
    m.add("prescribed_motion", "P1", "s", position=lambda time: time)
    m.add("spring", "k1", ("s", "p"), k=1)
    m.add("mass", "M", "p", m=1)
    m.coordinates  # noqa: B018


# --- options, equations, initial conditions ---------------------------------


def unknown_option():
    lg.Model(dimm=2)


def invalid_option_value():
    lg.Model(formulation="charges")


def invalid_dim():
    lg.Model(dim=4)


def vector_of_wrong_length():
    m = oscillator(dim=2)
    m.add("gravity", "g", direction=(0, 0, -1))
    m.lagrangian  # noqa: B018


def scalar_force_in_2d():
    m = oscillator(dim=2)
    m.add("force", "F1", "p", F=1)
    m.lagrangian  # noqa: B018


def zero_gravity_direction():
    m = oscillator(dim=2)
    m.add("gravity", "g", direction=(0, 0))
    m.lagrangian  # noqa: B018


def node_without_inertia_or_damping():
    m = lg.Model("chain")
    m.add("spring", "k1", ("ground", "mid"), k=1)
    m.add("spring", "k2", ("mid", "end"), k=1)
    m.add("mass", "M", "end", m=1)
    m.equations  # noqa: B018


def capacitor_only_loop():
    m = lg.Model("caps")
    m.add("capacitor", "C1", ("n1", "ground"), C=1)
    m.add("capacitor", "C2", ("n1", "ground"), C=1)
    m.equations  # noqa: B018


def unknown_initial_coordinate():
    quiet_simulate(oscillator(), 1, initial={"x_pp": 1.0})


def unknown_initial_velocity():
    quiet_simulate(oscillator(), 1, velocity={"y_p": 1.0})


def first_order_velocity():
    m = lg.Model("creep")
    m.add("spring", "k1", ("ground", "p"), k=1)
    m.add("damper", "c1", ("ground", "p"), c=1)
    assert m.first_order == ["x_p"]
    quiet_simulate(m, 1, initial={"x_p": 1.0}, velocity={"x_p": 1.0})


def empty_time_span():
    quiet_simulate(oscillator(), 0)


def non_finite_initial():
    quiet_simulate(oscillator(), 1, initial={"x_p": float("inf")})


def unknown_coordinate_in_result():
    res = oscillator().simulate(0.1, initial={"x_p": 1.0}, velocity={"x_p": 0.0}, points=3)
    res["x_q"]


def unknown_plugin_kind_message():
    """A kind from a plugin that is not installed: the message points at ``lagrangian plugins``."""
    lg.Model().add("thermal_mass", "Th", "p")


def singular_mass_matrix_damper():
    """Two massless nodes joined only by a damper, each held by a spring.

    Both coordinates are first order, but the dissipation only fixes the
    *relative* velocity: the first-order block of the solve is c·[[1,-1],[-1,1]].
    """
    m = lg.Model("singular")
    m.add("spring", "k1", ("ground", "p"), k=1)
    m.add("spring", "k2", ("ground", "q"), k=2)
    m.add("damper", "c", ("p", "q"), c=1)
    assert m.first_order == ["x_p", "x_q"]
    m.simulate(1, initial={"x_p": 0.1, "x_q": 0.2})


# A tiny inerter (T = ½ b (v_b − v_a)²) registered at run time gives a
# singular mass matrix on the inertial side too.
class Inerter(lg.Component):
    """Ideal inerter: T = ½ b (v_b − v_a)²."""

    kind = "inerter"
    domain = "mechanical"
    parameters = {"b": lg.Parameter("inertance", unit="kg")}

    def contribute(self, ctx):
        dv = ctx.view.velocity(self.nodes[1]) - ctx.view.velocity(self.nodes[0])
        return lg.Contribution(T=self.b * lg.dot(dv, dv) / 2)

    @classmethod
    def example(cls):
        return lg.Example(("ground", "p"), {"b": 1}, context=[("spring", "k", ("ground", "p"), {"k": 1})])


@lg.hookimpl
def _register_inerter(register):
    register(Inerter)


def _inerter_plugin():
    plugin = types.ModuleType("inerter_plugin")
    plugin.register_component_types = _register_inerter
    return plugin


def singular_mass_matrix_inerter():
    reg = lg.Registry(plugins={"inerter_plugin": _inerter_plugin()})
    m = lg.Model("inerter", registry=reg)
    m.add("spring", "k1", ("ground", "p"), k=1)
    m.add("spring", "k2", ("ground", "q"), k=1)
    m.add("inerter", "B", ("p", "q"), b=1)
    assert m.first_order == []
    m.simulate(1, initial={"x_p": 0.1, "x_q": 0.0}, velocity={"x_p": 0.0, "x_q": 0.0})


# (id, function, exception class, regexes that must all occur in the message)
CASES = [
    ("unknown-kind", unknown_kind, lg.UnknownKindError,
     [r"'sprng'", r"Did you mean 'spring'\?", r"Known kinds: .*\bmass\b.*\bspring\b", r"cubic_spring"]),
    ("unknown-kind-no-suggestion", unknown_kind_far_from_all, lg.UnknownKindError,
     [r"'flux_capacitor'", r"Known kinds:", r"lagrangian plugins"]),
    ("unknown-kind-plugin-hint", unknown_plugin_kind_message, lg.UnknownKindError,
     [r"'thermal_mass'", r"plugin installed"]),
    ("missing-parameter", missing_parameter, lg.ParameterError,
     [r"component 'k1', parameter 'k'", r"required", r"stiffness"]),
    ("unknown-parameter", unknown_parameter, lg.ParameterError,
     [r"'rest_lenght'", r"no such parameter", r"Did you mean 'rest_length'\?", r"Its parameters: k, rest_length"]),
    ("negative-mass", negative_mass, lg.ParameterError,
     [r"component 'm1', parameter 'm'", r"must be positive", r"-2"]),
    ("zero-capacitance", zero_capacitance, lg.ParameterError,
     [r"component 'C1', parameter 'C'", r"must be positive", r"got 0"]),
    ("negative-damping", negative_damping, lg.ParameterError,
     [r"component 'c1', parameter 'c'", r"zero or positive", r"-0\.1"]),
    ("negative-rest-length", negative_rest_length, lg.ParameterError,
     [r"parameter 'rest_length'", r"zero or positive"]),
    ("non-number-string", non_number_string, lg.ParameterError,
     [r"component 'm1', parameter 'm'", r"expected a number or a SymPy expression", r"'not a number'"]),
    ("unparsable-string", unparsable_string, lg.ParameterError,
     [r"component 'R1', parameter 'R'", r"expected a number", r"'2 \+'"]),
    ("bool", bool_value, lg.ParameterError,
     [r"component 'm1', parameter 'm'", r"expected a number", r"True"]),
    ("nan", nan_value, lg.ParameterError,
     [r"component 'k1', parameter 'k'", r"finite real number", r"nan"]),
    ("inf", inf_value, lg.ParameterError,
     [r"component 'L1', parameter 'L'", r"finite real number", r"got 'inf'"]),
    ("one-over-zero", division_by_zero_string, lg.ParameterError,
     [r"component 'C1', parameter 'C'", r"finite real number", r"zoo"]),
    ("complex", complex_value, lg.ParameterError,
     [r"parameter 'm'", r"finite real number"]),
    ("list-for-scalar", list_for_scalar, lg.ParameterError,
     [r"parameter 'm'", r"expected"]),
    ("time-in-non-signal", time_dependent_non_signal, lg.ParameterError,
     [r"parameter 'k'", r"depends on time t", r"signal"]),
    ("symbol-declared-negative", symbol_declared_negative, lg.ParameterError,
     [r"component 'm1', parameter 'm'", r"must be positive", r"declared otherwise"]),
    ("symbol-declared-zero", symbol_declared_zero_capacitance, lg.ParameterError,
     [r"parameter 'C'", r"must be positive", r"declared otherwise"]),
    ("string-for-vector", string_vector, lg.ParameterError,
     [r"component 'g', parameter 'direction'", r"expected a vector", r"'down'"]),
    ("symbol-negative-at-simulate", symbolic_mass_negative_at_simulate, lg.ParameterError,
     [r"component 'm1', parameter 'm'", r"must be positive", r"-1"]),
    ("symbol-zero-at-simulate", symbolic_capacitance_zero_at_simulate, lg.ParameterError,
     [r"component 'C1', parameter 'C'", r"must be positive"]),
    ("symbol-string-at-simulate", symbolic_parameter_not_a_number_at_simulate, lg.ModelError,
     [r"parameter 'm'", r"must be a number", r"'heavy'"]),
    ("symbol-nan-at-simulate", symbolic_parameter_nan_at_simulate, lg.ParameterError,
     [r"parameter 'm'", r"finite real number"]),
    ("symbols-without-values", symbolic_parameters_without_values, lg.ModelError,
     [r"model 'needs-values'", r"symbolic parameters without values: k, m", r"params=\{'k': \.\.\., 'm': \.\.\.\}"]),
    ("unknown-parameter-at-simulate", unknown_parameter_at_simulate, lg.UnknownNameError,
     [r"unknown parameter 'mas'", r"Did you mean 'mass'\?", r"Known: k_k1, mass\."]),
    ("unknown-node", unknown_node, lg.UnknownNodeError,
     [r"unknown node 'pp'", r"Did you mean 'p'\?", r"Nodes of this model: ground, p"]),
    ("unknown-node-far", unknown_node_far, lg.UnknownNodeError,
     [r"unknown node 'x'", r"Nodes of this model: ground, p"]),
    ("invalid-node-name", invalid_node_name, lg.ModelError,
     [r"node names must be non-empty strings", r"''"]),
    ("node-name-none", non_string_node_name, lg.ModelError,
     [r"node names must be non-empty strings", r"None"]),
    ("unknown-component", unknown_component, lg.UnknownNameError,
     [r"unknown component 'kk'", r"Did you mean 'k'\?", r"Known: M, k"]),
    ("dangling-node", dangling_node, lg.DanglingNodeError,
     [r"node 'n9'", r"nothing attached", r"attach a component"]),
    ("duplicate-name", duplicate_name, lg.DuplicateNameError,
     [r"component name 'M'", r"already used by a mass at p", r"another name"]),
    ("duplicate-name-across-domains", duplicate_name_across_domains, lg.DuplicateNameError,
     [r"component name 'X1'", r"inductor"]),
    ("too-many-nodes", too_many_nodes, lg.ModelError,
     [r"mass 'm1' takes 1 node\(s\) \(node\), got 2", r"'a', 'b'"]),
    ("too-few-nodes", too_few_nodes, lg.ModelError,
     [r"spring 'k1' takes 2 node\(s\) \(a, b\), got 1"]),
    ("nodes-for-global", nodes_for_global_component, lg.ModelError,
     [r"gravity 'g' takes 0 node\(s\) \(no nodes\), got 1"]),
    ("empty-component-name", empty_component_name, lg.ModelError,
     [r"component names must be non-empty strings"]),
    ("mixed-domains", mixed_domains, lg.DomainError,
     [r"node 'n1'", r"inductor 'L1' \(electrical\)", r"'M' \(mechanical\)", r"transducer"]),
    ("empty-model", empty_model, lg.ModelError,
     [r"no components", r"Model\.add"]),
    ("floating-spring", floating_spring, lg.FloatingNetworkError,
     [r"nodes a, b", r"components kf", r"no path to the reference node 'ground'", r"connect one of them to ground"]),
    ("floating-circuit-island", floating_circuit_island, lg.FloatingNetworkError,
     [r"nodes a, b", r"components Cx, Lx", r"connect one of them to ground"]),
    ("parallel-voltage-sources-charge", lambda: parallel_voltage_sources("charge"), lg.TopologyError,
     [r"across-sources V1, V2 form a loop", r"Remove one"]),
    ("parallel-voltage-sources-flux", lambda: parallel_voltage_sources("flux"), lg.TopologyError,
     [r"across-sources V1, V2 form a loop", r"Remove one"]),
    ("voltage-source-triangle-charge", lambda: triangle_of_voltage_sources("charge"), lg.TopologyError,
     [r"across-sources Va, Vb, Vc form a loop", r"Remove one"]),
    ("voltage-source-triangle-flux", lambda: triangle_of_voltage_sources("flux"), lg.TopologyError,
     [r"across-sources Va, Vb, Vc form a loop", r"Remove one"]),
    ("current-source-cut-set-charge", lambda: current_source_cut_set("charge"), lg.TopologyError,
     [r"through-sources I1, I2 form a cut-set", r"isolating nodes n1, n2", r"Add a path"]),
    ("current-source-cut-set-flux", lambda: current_source_cut_set("flux"), lg.TopologyError,
     [r"through-sources I1, I2 form a cut-set", r"isolating nodes n1, n2", r"Add a path"]),
    ("current-source-on-a-body-point-charge", lambda: current_source_on_a_point_of_a_body("charge"), lg.TopologyError,
     [r"component 'Q' closes no loop", r"'ground' and 'C.origin'", r"not a point of a body"]),
    ("current-source-on-a-body-point-flux", lambda: current_source_on_a_point_of_a_body("flux"), lg.TopologyError,
     [r"nodes 'C.origin' reach ground in their domain only through 'Q'", r"not a point of a body"]),
    ("prescribed-motion-loop", two_prescribed_motions_on_one_node, lg.TopologyError,
     [r"across-sources P1, P2 form a loop"]),
    ("callable-voltage-source-flux", callable_voltage_source_flux, lg.ModelError,
     [r"voltage_source 'Vs'", r"integrated symbolically", r"SymPy expression of t", r"other formulation"]),
    ("callable-current-source-charge", callable_current_source_charge, lg.ModelError,
     [r"current_source 'Is'", r"integrated symbolically", r"other formulation"]),
    ("callable-prescribed-motion", callable_prescribed_motion, lg.ModelError,
     [r"prescribed_motion 'P1'", r"SymPy expression of t"]),
    ("unknown-option", unknown_option, lg.UnknownNameError,
     [r"unknown model option 'dimm'", r"Did you mean 'dim'\?", r"Known: dim, dynamics, formulation"]),
    ("invalid-option-value", invalid_option_value, lg.ModelError,
     [r"model option 'formulation'", r"must be one of 'charge', 'flux'", r"not 'charges'"]),
    ("invalid-dim", invalid_dim, lg.ModelError,
     [r"model option 'dim'", r"must be one of 1, 2, 3", r"not 4"]),
    ("vector-wrong-length", vector_of_wrong_length, lg.ModelError,
     [r"gravity 'g'", r"'direction' has 3 entries", r"dimension is 2"]),
    ("scalar-force-in-2d", scalar_force_in_2d, lg.ModelError,
     [r"force 'F1'", r"'F' must be a vector of 2 entries"]),
    ("zero-gravity-direction", zero_gravity_direction, lg.ModelError,
     [r"gravity 'g'", r"zero vector"]),
    ("node-without-inertia-or-damping", node_without_inertia_or_damping, lg.ModelError,
     [r"coordinate 'x_mid'", r"neither inertia nor dissipation", r"Add a mass or damper"]),
    ("capacitor-only-loop", capacitor_only_loop, lg.ModelError,
     [r"coordinate 'q_C2'", r"neither inertia nor dissipation", r"inductor or resistor"]),
    ("unknown-initial-coordinate", unknown_initial_coordinate, lg.UnknownNameError,
     [r"unknown coordinate 'x_pp'", r"Did you mean 'x_p'\?", r"Known: x_p"]),
    ("unknown-initial-velocity", unknown_initial_velocity, lg.UnknownNameError,
     [r"unknown coordinate 'y_p'", r"Known: x_p"]),
    ("velocity-of-first-order", first_order_velocity, lg.ModelError,
     [r"coordinate 'x_p' is first-order", r"cannot be given as an initial condition"]),
    ("empty-time-span", empty_time_span, lg.ModelError,
     [r"time span must end after it starts"]),
    ("non-finite-initial", non_finite_initial, lg.ModelError,
     [r"initial value of 'x_p' must be finite"]),
    ("unknown-coordinate-in-result", unknown_coordinate_in_result, lg.UnknownNameError,
     [r"unknown coordinate 'x_q'", r"Did you mean 'x_p'\?"]),
    ("singular-mass-matrix-damper", singular_mass_matrix_damper, lg.SingularMassMatrixError,
     [r"mass matrix is singular at t=0", r"x_p, x_q", r"not determined"]),
    ("singular-mass-matrix-inerter", singular_mass_matrix_inerter, lg.SingularMassMatrixError,
     [r"mass matrix is singular at t=0", r"x_p, x_q"]),
]


@pytest.mark.parametrize(("make", "exc", "patterns"), [c[1:] for c in CASES], ids=[c[0] for c in CASES])
def test_error_class_and_message(make, exc, patterns):
    assert issubclass(exc, lg.LagrangianError)
    with pytest.raises(exc, match=patterns[0]) as info:
        make()
    message = str(info.value)
    for pattern in patterns[1:]:
        assert re.search(pattern, message), f"{pattern!r} not in {message!r}"


@pytest.mark.parametrize("make", [c[1] for c in CASES], ids=[c[0] for c in CASES])
def test_errors_are_the_projects_not_leaked_internals(make):
    with pytest.raises(lg.LagrangianError) as info:
        make()
    err = info.value
    assert not isinstance(err, (KeyError, ZeroDivisionError, sp.SympifyError, TypeError, AttributeError))
    # a ModelError is also a ValueError, a NumericalError an ArithmeticError: callers can use either
    if isinstance(err, lg.ModelError):
        assert isinstance(err, ValueError)
    if isinstance(err, lg.NumericalError):
        assert isinstance(err, ArithmeticError)
    # the message is a sentence, not the repr of a key
    assert len(str(err)) > 20


# --- attributes the errors carry --------------------------------------------


def test_unknown_kind_carries_the_kind():
    with pytest.raises(lg.UnknownKindError) as info:
        unknown_kind()
    assert info.value.kind == "sprng"
    # the registry lookup alone raises the same, from None (no chained KeyError shown)
    with pytest.raises(lg.UnknownKindError) as info:
        lg.default_registry().component_type("capacitr")
    assert "Did you mean 'capacitor'?" in str(info.value)
    assert info.value.__suppress_context__


def test_parameter_error_carries_component_and_parameter():
    with pytest.raises(lg.ParameterError) as info:
        negative_damping()
    assert (info.value.component, info.value.parameter) == ("c1", "c")
    with pytest.raises(lg.ParameterError) as info:
        unknown_parameter()
    assert (info.value.component, info.value.parameter) == ("k1", "rest_lenght")


def test_unknown_node_and_name_carry_the_name():
    with pytest.raises(lg.UnknownNodeError) as info:
        unknown_node()
    assert info.value.node == "pp"
    with pytest.raises(lg.UnknownNameError) as info:
        unknown_initial_coordinate()
    assert info.value.name == "x_pp"


def test_floating_network_is_a_topology_error():
    assert issubclass(lg.FloatingNetworkError, lg.TopologyError)
    with pytest.raises(lg.TopologyError):
        floating_spring()


def test_hierarchy():
    for name in lg.errors.__all__:
        obj = getattr(lg, name)
        if isinstance(obj, type):
            assert issubclass(obj, lg.LagrangianError), name
            assert obj.__doc__, name
    assert issubclass(lg.SingularMassMatrixError, lg.NumericalError)
    assert issubclass(lg.IntegrationError, lg.NumericalError)
    assert issubclass(lg.PluginError, lg.LagrangianError)
    assert not issubclass(lg.PluginError, lg.ModelError)


# --- things that are *not* errors (so the cases above are meaningful) -------


def test_valid_neighbours_of_the_error_cases_pass():
    m = oscillator()
    assert m.check_node("p") == "p"
    assert m.check_node("GND") == "ground"
    assert m.check_node(0) == "ground"
    lg.Model().add("damper", "c0", ("ground", "p"), c=0)  # zero damping is allowed
    lg.Model().add("mass", "m1", "p", m=sp.Symbol("m", positive=True))
    lg.Model().add("mass", "m1", "p", m="m")  # a string is parsed into a symbol
    # one voltage source with a resistor in parallel is fine in both formulations
    for formulation in ("charge", "flux"):
        m = lg.Model(formulation=formulation)
        m.add("voltage_source", "V1", ("n1", "ground"), E=1)
        m.add("resistor", "R1", ("n1", "n2"), R=1)
        m.add("inductor", "L1", ("n2", "ground"), L=1)
        assert len(m.coordinates) == 1
    # the callable voltage source works in the charge formulation
    m = lg.Model(formulation="charge")
    m.add("voltage_source", "Vs", ("n1", "ground"), E=lambda time: 1.0)
    m.add("resistor", "R1", ("n1", "n2"), R=1)
    m.add("capacitor", "C1", ("n2", "ground"), C=1)
    res = m.simulate(1, initial={"q_R1": 0.0}, points=5)
    assert 0 < res["q_R1"][-1] < 1
    # a massless node with a damper is first-order, and simulates
    m = lg.Model("creep")
    m.add("spring", "k1", ("ground", "p"), k=1)
    m.add("damper", "c1", ("ground", "p"), c=1)
    res = m.simulate(1, initial={"x_p": 1.0}, points=3)
    assert res["x_p"][-1] == pytest.approx(math.exp(-1), rel=1e-6)


def test_symbolic_values_are_checked_at_simulate_not_before():
    m = lg.Model("sym")
    m.add("mass", "m1", "p", m=sp.Symbol("m"))
    m.add("spring", "k1", ("ground", "p"), k=1)
    assert [s.name for s in m.parameters] == ["m"]
    res = m.simulate(0.5, params={"m": 2}, initial={"x_p": 1.0}, velocity={"x_p": 0.0}, points=3)
    assert res["x_p"][0] == 1.0
    with pytest.raises(lg.ParameterError, match="'m1'"):
        m.simulate(0.5, params={"m": 0}, initial={"x_p": 1.0}, velocity={"x_p": 0.0})


def test_singular_mass_matrix_cannot_be_built_from_built_in_circuits():
    """The brief's candidate (two resistor chords sharing one tree inductor, charge
    formulation) is excluded by the normal tree: it is a minimum spanning tree by
    priority, so a resistor chord's loop holds only branches of priority <= resistor.
    Here the inductor ends up a chord with its own loop, and the solve is regular."""
    m = lg.Model("rr-l")
    m.add("inductor", "L1", ("n1", "ground"), L=1)
    m.add("resistor", "R1", ("n1", "ground"), R=1)
    m.add("resistor", "R2", ("n1", "ground"), R=2)
    assert sorted(m.coordinate_names) == ["q_L1", "q_R2"]  # R1 is the tree branch
    assert m.first_order == ["q_R2"]
    assert sp.Matrix(m.eq.A).det() != 0
    res = quiet_simulate(m, 0.5, points=3)
    assert all(abs(v[-1]) < 1e6 for v in res.q.values())


# --- input that once slipped past validation -


def test_float_dim_is_rejected_as_invalid_option():
    with pytest.raises(lg.ModelError, match="'dim'"):
        m = lg.Model(dim=2.0)
        m.add("mass", "M", "p", m=1)
        m.coordinates  # noqa: B018


def test_none_for_required_parameter_is_a_parameter_error():
    with pytest.raises(lg.ParameterError, match="parameter 'm'"):
        lg.Model().add("mass", "m1", "p", m=None)


def test_non_number_initial_condition_is_a_model_error():
    with pytest.raises(lg.ModelError, match="x_p"):
        oscillator().simulate(1, initial={"x_p": "abc"}, velocity={"x_p": 0.0})


@pytest.mark.filterwarnings("ignore::RuntimeWarning")
def test_integrator_failure_at_start_is_an_integration_error():
    # a 2-D damper between coincident nodes: D ~ (d·ḋ)²/|d|² is 0/0 at the default start
    m = lg.Model("coincident", dim=2)
    m.add("mass", "M", "p", m=1)
    m.add("spring", "k", ("ground", "p"), k=1)
    m.add("damper", "c", ("ground", "p"), c=1)
    with pytest.raises(lg.NumericalError):
        quiet_simulate(m, 1)


def test_warnings_name_the_users_line_and_methods_are_suggested_in_any_case():
    import inspect
    import warnings

    m = lg.Model("osc")
    m.add("mass", "m1", "p", m=0.3)
    m.add("spring", "k1", ("ground", "p"), k=40)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        line = inspect.currentframe().f_lineno + 1
        m.simulate(0.1)  # no initial conditions: they default to zero, with a warning
    assert [(w.filename, w.lineno) for w in caught if w.category is lg.InitialConditionWarning] == [(__file__, line)]
    with pytest.raises(lg.UnknownNameError, match="Did you mean 'RK45'"):
        m.simulate(0.1, method="rk45", initial={"x_p": 0.1}, velocity={"x_p": 0})


def test_a_lone_node_a_slip_away_from_another_gets_did_you_mean():
    import warnings

    m = lg.Model("cart")
    m.add("mass", "m", "crat", m=0.3)  # a slip: the spring and the damper hold "cart"
    m.add("spring", "k", ("ground", "cart"), k=4.0)
    m.add("damper", "c", ("ground", "cart"), c=0.1)
    with pytest.warns(lg.NodeNameWarning, match=r"node 'crat' is touched by one component only \('m'\).*Did you mean 'cart'"):
        m.coordinate_names
    family = lg.Model("balls", dim=2)  # numbered names are a family, not slips
    family.add("mass", "b1", "ball1", m=1.0)
    family.add("mass", "b2", "ball2", m=1.0)
    family.add("gravity", "g")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert family.coordinate_names == ["x_ball1", "y_ball1", "x_ball2", "y_ball2"]


@pytest.mark.parametrize("kind, param", [("voltage_source", "E"), ("current_source", "I")])
def test_a_source_given_a_sequence_is_refused_naming_it(kind, param):
    """A source drives one branch: a list (or array) is refused when the model is built, naming the component and the
    parameter, rather than taken as a 1-vector that a SPICE deck cannot hold."""
    import numpy as np

    for value in ([1550.0], (2.0, 3.0)):
        with pytest.raises(lg.ParameterError, match=rf"component 'S', parameter '{param}': is one signal .*not a sequence"):
            lg.Model("source").add(kind, "S", ("a", "0"), **{param: value})
    with pytest.raises(lg.ParameterError, match=rf"component 'S', parameter '{param}': expected a number"):
        lg.Model("source").add(kind, "S", ("a", "0"), **{param: np.array([2.0, 3.0])})
    plane = lg.Model("plane", dim=2)  # a force in the plane is still a vector
    plane.add("mass", "m", "p", m=0.3)
    plane.add("force", "F", "p", F=[1.0, 2.0])
    assert plane.coordinate_names == ["x_p", "y_p"]
