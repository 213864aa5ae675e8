"""Domains: how part of the component graph becomes generalized coordinates.

A domain (registered by a plugin through ``register_domains``) receives the
sub-network of components that belong to it and returns a
:class:`DomainView`: the generalized coordinates it introduces, plus
whatever accessors its components read them through (node positions, branch
charges, branch flux linkages, ...).  Core code never looks inside a view.
"""

from __future__ import annotations

import unicodedata
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, ClassVar


from ..errors import ModelError
from .component import GROUND, Component, t
from . import deferred as _deferred

nx = _deferred.module("networkx", globals())
sp = _deferred.module("sympy", globals())

__all__ = ["Coordinate", "Option", "Network", "DomainView", "Shape", "Domain", "Context", "Incidence", "check_name", "coordinate",
           "rate"]


def check_name(name: str, what: str) -> None:
    r"""Refuse a name with a control character (NUL, ESC, DEL, a lone surrogate, ...): node and component names
    become the names of coordinates (SymPy functions, which cannot hold a NUL), C comments and SPICE decks, and
    no such character is text.  Tabs and line breaks are left to the writers, which keep them inert.

    >>> check_name("cart", "node name")
    >>> check_name("a\x00b", "node name")
    Traceback (most recent call last):
    ...
    lagrangian.errors.ModelError: node name 'a\x00b' contains the control character '\x00': names are printable text; remove it.
    """
    if name.isprintable():  # (no character of the classes Other or Separator but the space: none of these)
        return
    bad = [c for c in name if c not in "\t\n\r" and unicodedata.category(c) in ("Cc", "Cs")]
    if bad:
        raise ModelError(f"{what} {name!r} contains the control character {bad[0]!r}: names are printable text; "
                         f"remove it.")


@dataclass(frozen=True)
class Coordinate:
    """A generalized coordinate: a named function of time.

    >>> c = Coordinate.named("x_cart", "position of node 'cart'")
    >>> c.function
    x_cart(t)
    """

    name: str
    function: sp.Expr
    description: str = ""

    @classmethod
    def named(cls, name: str, description: str = "") -> "Coordinate":
        return cls(name, coordinate(name), description)


def coordinate(name: str) -> sp.Expr:
    """The coordinate called ``name`` as the function of time the equations hold, ``name(t)``: what a load that
    depends on the state is written in (``force``, ``torque``, ``body_torque``, ``generalized_force``), with
    :func:`rate` for its rate.  The model's coordinate names are ``Model.coordinate_names``; a name the model does
    not have is refused when the model is assembled, with the names it has.

    >>> import lagrangian as lg
    >>> th = lg.coordinate("theta_j1")
    >>> th, lg.rate("theta_j1")
    (theta_j1(t), Derivative(theta_j1(t), t))
    """
    if not isinstance(name, str) or not name:
        raise ModelError(f"a coordinate is named by a non-empty string, not {name!r}.")
    check_name(name, "coordinate name")  # a domain may build names from other text than Model.add checked
    return sp.Function(name, real=True)(t)


def rate(name: str) -> sp.Expr:
    """The rate ``d name/dt`` of the coordinate ``name`` (see :func:`coordinate`).

    >>> import lagrangian as lg
    >>> m = lg.Model("drag")
    >>> _ = m.add("mass", "m1", "p", m=0.3)
    >>> _ = m.add("force", "drag", "p", F=-0.2 * lg.rate("x_p") * abs(lg.rate("x_p")))
    >>> m.equations
    [Eq(0.3*Derivative(x_p(t), (t, 2)), -0.2*Abs(Derivative(x_p(t), t))*Derivative(x_p(t), t))]
    """
    return sp.Derivative(coordinate(name), t)


@dataclass(frozen=True)
class Option:
    """A model option a domain accepts, e.g. ``Option(1, "dimension", choices=(1, 2, 3))``."""

    default: Any
    doc: str
    choices: Sequence[Any] = ()


@dataclass
class Network:
    """The part of the component graph that belongs to one domain.

    ``graph`` is a networkx ``MultiGraph`` whose edges are keyed by component
    name and carry ``a``/``b`` (the branch orientation) and ``component``.
    It always contains the node ``ground``.
    """

    graph: nx.MultiGraph
    components: list[Component]
    ground: str = GROUND

    @property
    def nodes(self) -> list[str]:
        """Non-ground nodes, in insertion order."""
        return [n for n in self.graph.nodes if n != self.ground]


@dataclass
class Recursion:
    """The dynamics of a domain's coordinates computed step by step (:class:`RecursiveDynamics`): ``definitions``,
    ``(symbol, expression)`` pairs in order, each in the coordinates, their rates, the parameters and the symbols
    defined before it; in those, the ``accelerations`` (one per coordinate), the kinetic energy ``kinetic``, the
    momenta ``∂T/∂q̇`` (one per coordinate) and ``pivots``, positive numbers (one per coordinate) where the motion
    is determined (the articulated inertias about each joint's axis; zero where the mass matrix is singular).
    ``responses``: for each column ``c`` of generalized forces ``build`` was given, the accelerations ``M⁻¹ c`` it
    alone gives the mechanism at rest (one per coordinate)."""

    definitions: list[tuple[sp.Symbol, sp.Expr]]
    accelerations: list[sp.Expr]
    kinetic: sp.Expr
    momenta: list[sp.Expr]
    pivots: list[sp.Expr]
    responses: list[list[sp.Expr]] = field(default_factory=list)


@dataclass
class RecursiveDynamics:
    """A domain's offer to compute the accelerations of its coordinates by a recursion over its structure (a tree
    of rigid bodies: the articulated-body algorithm), in work linear in their number, rather than from closed-form
    equations of motion.

    ``covers`` names the components whose kinetic and potential energies the recursion accounts for (bodies, and
    uniform gravity on them); every other component of the model must then store no kinetic energy and add no
    couplings, frames or constraints: its potential, dissipation and loads enter as generalized forces.
    ``build(q, v, tau)`` gets the plain symbols of the coordinates and their rates (in the model's order, by name
    ``names``) and those generalized forces, and returns the :class:`Recursion`.  ``note`` says in words what the
    recursion is, for reports; ``forced``: the user asked for it (``Model(dynamics="recursive")``), so a model it
    cannot serve is refused by name rather than derived in closed form.  ``responds``: ``build(q, v, tau,
    columns)`` also takes columns of generalized forces and gives their :attr:`Recursion.responses`, so that
    constraints (closed loops, constraints on positions or velocities) keep the recursion: their forces ``Jᵀ λ``
    follow from a solve as small as their number (:mod:`lagrangian.derivation.recursion`).
    """

    covers: frozenset[str]
    names: tuple[str, ...]
    build: Callable[..., Recursion]
    note: str
    forced: bool = False
    responds: bool = False


@dataclass(frozen=True)
class Shape:
    """A part of a model's drawing in space, for :meth:`lagrangian.Result.animate`.

    ``points``: a ``dim × n`` SymPy matrix of world coordinates, expressions
    of the coordinates ``q(t)`` and ``t``.  ``kind``: ``"line"`` (a rigid
    part: the points joined in order), ``"link"`` (a spring or damper between
    two points: a thin line), ``"point"`` (a point mass), ``"joint"`` (a joint's
    location) or ``"ground"`` (the fixed frame's origin).  ``name``: the
    component (or node) drawn, the legend's label.
    """

    name: str
    kind: str
    points: Any


@dataclass
class DomainView:
    """What a domain exposes to components: at least its coordinates.

    ``branch_value(key)`` gives the integral quantity of a branch (edge key
    of the component graph) — a position difference, a charge, a flux
    linkage — in terms of the coordinates; analogies identify branches of
    two domains through it.  ``recursive``: the domain's offer of recursive
    dynamics (:class:`RecursiveDynamics`), or ``None``.
    """

    coordinates: list[Coordinate] = field(default_factory=list)
    #: holonomic constraints ``Φ(q, t) = 0`` among the coordinates (closed kinematic loops), kept with multipliers
    constraints: list[sp.Expr] = field(default_factory=list)
    recursive: RecursiveDynamics | None = None

    def branch_value(self, key: str) -> sp.Expr:
        raise NotImplementedError(f"{type(self).__name__} does not define branch quantities")

    def shapes(self) -> list["Shape"]:
        """What an animation of the model draws of this domain (:class:`Shape` s in world coordinates); none by
        default: a domain without positions in space (a circuit) draws nothing."""
        return []

    def branch_meaning(self, key: str, rate: bool = False) -> str:
        """What :meth:`branch_value` of ``key`` (or its rate) is, in words with its unit, for reports
        (``"charge through C1 [C]"``); domains with branch quantities override it."""
        return f"{'rate of the ' if rate else ''}branch quantity of {key}"


@dataclass
class Incidence:
    """A domain's coordinates and branch quantities in numbers, for the numeric assembly
    (:mod:`lagrangian.derivation.numeric`).

    ``coordinates``: their names, in the order of the view's.  ``branch``: by
    edge key, the branch quantity as ``{coordinate index: coefficient}``
    (a branch charge as the loop charges through it; a flux linkage as the
    difference of node fluxes).  ``prescribed``: keys of branches whose
    quantity a source fixes in part (a current source's loop in loop charges,
    a voltage source's path in node fluxes): not numbers alone.
    """

    coordinates: list[str]
    branch: dict[str, dict[int, float]]
    prescribed: set[str] = field(default_factory=set)

    @classmethod
    def of_nodes(cls, network: Network, prescribed: set[str], prefix: str) -> "Incidence":
        """One coordinate ``<prefix>_<node>`` per node of ``network`` not in ``prescribed`` (in the network's
        order), and each branch quantity the difference of its nodes' (``a`` minus ``b``; ground is 0): positions
        on one axis, angles about one axis.  Branches that touch a prescribed node are prescribed.

        >>> import networkx as nx
        >>> g = nx.MultiGraph()
        >>> _ = g.add_edge("p", "ground", key="m", a="p", b="ground")
        >>> _ = g.add_edge("ground", "p", key="k", a="ground", b="p")
        >>> inc = Incidence.of_nodes(Network(g, []), set(), "x")
        >>> inc.coordinates, inc.branch
        (['x_p'], {'m': {0: 1.0}, 'k': {0: -1.0}})
        """
        index: dict[str, int] = {}
        for node in network.nodes:
            if node not in prescribed:
                index[node] = len(index)
        branch: dict[str, dict[int, float]] = {}
        fixed: set[str] = set()
        for _, _, key, data in network.graph.edges(keys=True, data=True):
            a, b = data["a"], data["b"]
            if a in prescribed or b in prescribed:
                fixed.add(key)
                continue
            row: dict[int, float] = {}
            for node, sign in ((a, 1.0), (b, -1.0)):
                if node in index:
                    row[index[node]] = row.get(index[node], 0.0) + sign
            branch[key] = row
        return cls([f"{prefix}_{node}" for node in index], branch, fixed)


class Domain:
    """Base class of a physical domain.

    Subclasses set ``name`` and ``options`` and implement
    ``build(network, options) -> DomainView``, which must raise a
    :class:`lagrangian.errors.ModelError` subclass naming the culprit when the
    network cannot be given coordinates; optionally ``incidence(network,
    options)``, the same coordinates and branch quantities in numbers.
    """

    name: ClassVar[str]
    options: ClassVar[Mapping[str, Option]] = {}
    #: Whether :meth:`incidence` reads of ``network.graph`` only its ``nodes`` and ``edges(keys=, data=)`` (and the
    #: algorithms of :mod:`lagrangian.base.network`): then a model solved in numbers gives it a
    #: :class:`lagrangian.base.network.Multigraph`, and networkx is not imported.
    light_incidence: ClassVar[bool] = False

    def build(self, network: Network, options: Mapping[str, Any]) -> DomainView:  # pragma: no cover
        raise NotImplementedError

    def incidence(self, network: Network, options: Mapping[str, Any]) -> Incidence | None:
        """The coordinates and branch quantities of :meth:`build` as an :class:`Incidence`, or ``None`` (the
        default) for a domain whose branch quantities are not linear in its coordinates (a mechanism's)."""
        return None


@dataclass
class Context:
    """Passed to :meth:`Component.contribute`.

    ``view`` is the view of the component's own domain, ``views`` those of
    every domain in the model (for components that couple domains),
    ``options`` the model's options and ``components`` all components.

    Parameters given as numbers are symbols here (each component is its
    :meth:`~lagrangian.Component.symbolic_view`, and so is every entry of
    ``components``); ``values`` maps those symbols to their numbers, for a
    component that must decide something by value while it contributes
    (whether a coupling makes an inductance matrix singular):
    ``expr.xreplace(ctx.values)``.
    """

    view: DomainView
    views: Mapping[str, DomainView]
    options: Mapping[str, Any]
    components: Sequence[Component]
    t: sp.Symbol = t
    values: Mapping[sp.Symbol, Any] = field(default_factory=dict)
