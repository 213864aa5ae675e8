"""Linearization of a model about an operating point, in second-order (Laplace) form.

About a state where the model is at rest (``q = q₀``, ``q̇ = 0``, the inputs
at their operating values, ``t = t₀``), small motions ``δq`` obey

    M δq̈ + C δq̇ + K δq − Φ_qᵀ δλ = (Σ_k B_k s^k + Bi/s) u,      Φ_q δq = 0

with ``M`` the mass matrix at the point, ``C = −∂f/∂q̇``,
``K = −∂f/∂q − ∂(Φ_qᵀ λ₀)/∂q`` (``f`` the forcing of ``M q̈ = f``, ``λ₀`` the
loop-closure multipliers holding the point), ``B_k`` the coefficients
of the inputs' ``k``-th time derivatives (a prescribed motion drives a
damper through its velocity: ``B = c s + k``) and ``Bi`` that of their
integral (a voltage source fixes a node's flux linkage to ``∫E dt``).  An
input is a source or load component: its signal parameter becomes its
value plus ``u = ẇ`` (:meth:`lagrangian.Component.with_input`), so ``u``
enters exactly where the parameter does.  Outputs are coordinates (``"x_p"``, a rate
``"x_p'"``, an acceleration ``"x_p''"``), quantities components name
(``"v(C1)"``, ``"i(L1)"``) or SymPy expressions of the coordinates; each is
a row ``y = Σ_k (Cq_k δq + D_k u) s^k``.

The Laplace form keeps loop constraints exact (the multipliers are
unknowns, not stabilized) and first-order coordinates (a zero row of ``M``)
as they are; :meth:`LinearModel.state_space` gives ``ẋ = A x + B u``,
``y = C x + D u`` where one exists.  A model whose parameters are symbols
without values is linearized symbolically (SymPy matrices), the same
structure as with numbers.

>>> import lagrangian as lg
>>> from lagrangian.frequency import linearize
>>> m = lg.Model("msd")
>>> _ = m.add("mass", "m", "p", m=0.3)
>>> _ = m.add("spring", "k", ("ground", "p"), k=40.0)
>>> _ = m.add("damper", "c", ("ground", "p"), c=0.5)
>>> _ = m.add("force", "F", "p", F=0)
>>> lin = linearize(m, inputs=["F"], outputs=["x_p"])
>>> lin.M, lin.C, lin.K, lin.B[0]
(array([[0.3]]), array([[0.5]]), array([[40.]]), array([[1.]]))
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..base.component import check_value, t
from ..base.identity import is_zero
from ..errors import ModelError, UnknownNameError
from ..model import Model
from ..derivation.calculus import Calculus, Rewriter, symbols_of
from ..derivation.recursion import tangents
from .lti import _number, numeric, stamped
from .control import state_space_system
from .equilibrium import check_closure, check_rest, check_rolling, multipliers, settle
from .motion import kane_state_space, null_space, number, rates, steady_check
from .channels import _INPUT, _atoms, _channel, _input_unit, _label, _outputs, _signal_of, _unit, _with_inputs
from ..base import deferred as _deferred

sp = _deferred.module("sympy", globals())

__all__ = ["LinearModel", "linearize", "s"]


def __getattr__(name: str):
    if name == "s":  # the Laplace variable of transfer functions, SymPy's symbol (imported when first asked for)
        return sp.Symbol("s")
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


@dataclass
class LinearModel:
    """The linearization ``M δq̈ + C δq̇ + K δq − Φ_qᵀ δλ = (Σ_k B_k s^k + Bi/s) u``, ``Φ_q δq = 0``, outputs
    ``y = Σ_k (Cq_k δq + D_k u) s^k + Di u/s``.

    Matrices are NumPy arrays, or SymPy matrices when ``symbolic``.  ``B``,
    ``Cq`` and ``D`` are lists indexed by the power of ``s``; ``Bi`` is the
    coefficient of ``u/s``, nonzero for a source whose integral fixes a
    coordinate (a voltage source in node fluxes), and ``Di`` the same in the
    outputs (an inductor's current there).  ``at`` is the
    operating point (coordinate values: floats where the model was
    linearized in numbers), ``y0`` the outputs there, ``u0`` each input's
    signal as its component holds it (a number, a netlist's waveform of
    :mod:`lagrangian.base.waveforms`, an expression of ``t``), ``time`` the
    instant ``t₀``.
    """

    model: str
    coordinates: list[str]
    inputs: list[str]
    outputs: list[str]
    M: Any
    C: Any
    K: Any
    Phi: Any
    B: list
    Bi: Any
    Cq: list
    D: list
    Di: Any
    symbolic: bool
    at: dict[str, Any] = field(default_factory=dict)
    u0: dict[str, Any] = field(default_factory=dict)
    y0: dict[str, Any] = field(default_factory=dict)
    time: float = 0.0
    first_order: list[str] = field(default_factory=list)
    parameters: list[sp.Symbol] = field(default_factory=list)
    #: units of the inputs and outputs by label (``""`` where unknown), for charts
    units: dict[str, str] = field(default_factory=dict)
    #: the rates ``q̇₀`` of a steady motion linearized about (:func:`linearize`'s ``velocity=``), by coordinate
    velocity: dict[str, Any] = field(default_factory=dict)
    #: constraints on velocities ``A(q) q̇ + b(q, t) = 0`` (nonholonomic): ``A`` at the point, one row each.  They are
    #: the last rows of the constraints, whose rows in ``Phi`` are then ``∂(A q̇ + b)/∂q``: the row reads
    #: ``(Phi + Phi_v s) δq = 0``, and the multiplier acts along ``Phi_v`` (Lagrange–d'Alembert).  ``None``: none.
    Phi_v: Any = None

    def __repr__(self) -> str:
        kind = "symbolic" if self.symbolic else "numeric"
        on_rates = f" ({self.velocity_rows} on velocities)" if self.velocity_rows else ""
        return (f"<LinearModel of {self.model!r}: {len(self.coordinates)} coordinates, {self.Phi.shape[0]} constraints"
                f"{on_rates}, inputs {self.inputs}, outputs {self.outputs}, {kind}>")

    @property
    def velocity_rows(self) -> int:
        """How many of the constraints are on velocities (nonholonomic): the last rows of ``Phi``."""
        return 0 if self.Phi_v is None else self.Phi_v.shape[0]

    def rate_rows(self) -> Any:
        """The coefficient of ``s`` in the constraint rows (constraints × coordinates): ``Phi_v`` in the rows of the
        constraints on velocities, zero in the others."""
        m, n, k = self.Phi.shape[0], len(self.coordinates), self.velocity_rows
        if self.symbolic:
            return sp.zeros(m - k, n).col_join(sp.Matrix(self.Phi_v)) if k else sp.zeros(m, n)
        return np.vstack([np.zeros((m - k, n)), self.Phi_v]) if k else np.zeros((m, n))

    def force_rows(self) -> Any:
        """The directions the constraints' multipliers act along (constraints × coordinates): ``Φ_q`` for a
        constraint on positions, ``A`` for one on velocities."""
        k = self.velocity_rows
        if not k:
            return self.Phi
        h = self.Phi.shape[0] - k
        if self.symbolic:
            return sp.Matrix(self.Phi)[:h, :].col_join(sp.Matrix(self.Phi_v))
        return np.vstack([self.Phi[:h], self.Phi_v])

    @property
    def size(self) -> int:
        """Unknowns of the Laplace-domain solve: coordinates plus multipliers."""
        return len(self.coordinates) + self.Phi.shape[0]

    def pencil(self, s_value) -> tuple[Any, Any]:
        """The system matrix ``[[M s² + C s + K, −Φ_qᵀ], [Φ_q, 0]]`` and right-hand side ``[Σ B_k s^k; 0]`` at
        ``s_value`` (a number, or :data:`s` for the symbolic form)."""
        P = self.M * s_value**2 + self.C * s_value + self.K
        rhs = sum((b * s_value**k for k, b in enumerate(self.B)), self.B[0] * 0)
        if not _zero_matrix(self.Bi):
            rhs = rhs + self.Bi / s_value
        m = self.Phi.shape[0]
        if not m:
            return P, rhs
        rows = self.Phi + self.rate_rows() * s_value if self.velocity_rows else self.Phi
        if self.symbolic or isinstance(s_value, sp.Basic):
            rows, force = sp.Matrix(rows), sp.Matrix(self.force_rows())
            top = sp.Matrix(P).row_join(-force.T)
            return top.col_join(rows.row_join(sp.zeros(m, m))), sp.Matrix(rhs).col_join(sp.zeros(m, len(self.inputs)))
        top = np.hstack([P, -self.force_rows().T])
        bottom = np.hstack([rows, np.zeros((m, m))])
        return np.vstack([top, bottom]), np.vstack([rhs, np.zeros((m, len(self.inputs)))])

    def output_rows(self, s_value) -> tuple[Any, Any]:
        """``Σ_k Cq_k s^k`` (outputs × coordinates) and ``Σ_k D_k s^k`` (outputs × inputs) at ``s_value``."""
        Cq = sum((c * s_value**k for k, c in enumerate(self.Cq)), self.Cq[0] * 0)
        D = sum((d * s_value**k for k, d in enumerate(self.D)), self.D[0] * 0)
        if not _zero_matrix(self.Di):
            D = D + self.Di / s_value
        return Cq, D

    def independent(self) -> "LinearModel":
        """The same linearization in independent coordinates: the loop constraints ``Φ_q δq = 0`` solved for as
        many coordinates as they fix (those whose columns of ``Φ_q`` are best conditioned, by QR with column
        pivoting), the others kept; ``M``, ``C``, ``K`` projected as ``Nᵀ M N`` with ``δq = N δq_independent``,
        outputs as ``Cq N``.  Numeric linearizations only; with constraints on velocities there is no such
        second-order form (fewer speeds than coordinates): :meth:`state_space` takes independent speeds."""
        if self.velocity_rows:
            raise ModelError(f"model {self.model!r} has constraints on velocities: its independent speeds are fewer "
                             f"than its coordinates, so it has no second-order form in independent coordinates; use "
                             f"state_space() (independent coordinates and speeds) or the Laplace form.")
        return _independent(self) if self.Phi.shape[0] else self

    def state_space(self) -> tuple[Any, Any, Any, Any, list[str]]:
        """``(A, B, C, D, states)`` of ``ẋ = A x + B u``, ``y = C x + D u`` with ``x = (δq, δq̇ of the inertial
        coordinates)``.

        With loop constraints the state is that of independent coordinates
        (:meth:`independent`).  With constraints on velocities (nonholonomic)
        it is Kane's: independent coordinates ``δq_i`` and independent speeds
        ``δu`` (the rates of the coordinates whose columns of the constraints'
        Jacobian are the worst conditioned; the others, dependent, follow from
        them), named ``"x_p"`` and ``"x_p'"`` (:func:`~lagrangian.analysis.
        motion.kane_state_space`).  Raises :class:`~lagrangian.errors.ModelError`
        when the model has no such form here: inputs that enter through
        their derivatives (a prescribed motion: use the transfer function,
        which takes ``s`` exactly), or outputs that need the acceleration of
        a first-order coordinate.
        """
        if self.velocity_rows:
            return kane_state_space(self)
        if self.Phi.shape[0]:
            return self.independent().state_space()
        if not (_zero_matrix(self.Bi) and _zero_matrix(self.Di)):
            raise ModelError(f"model {self.model!r}: inputs {', '.join(self.inputs)} fix a coordinate through their "
                             f"integral (a voltage source in node fluxes), so ẋ = A x + B u has no B; use the transfer "
                             f"function, or the other formulation.")
        if any(not _zero_matrix(b) for b in self.B[1:]):
            raise ModelError(f"model {self.model!r}: inputs {', '.join(self.inputs)} enter through their time "
                             f"derivatives (a prescribed motion driving a damper or a mass), so ẋ = A x + B u has no "
                             f"B; use its transfer function, in which s u is exact.")
        lib = sp if self.symbolic else None
        n = len(self.coordinates)
        first = [self.coordinates.index(c) for c in self.first_order]
        inertial = [i for i in range(n) if i not in first]
        # the unknowns (q̈ of the inertial coordinates, q̇ of the first-order ones): W w = B u − K q − C_I v
        W = _cols(self.M, inertial, lib).row_join(_cols(self.C, first, lib)) if lib else np.hstack(
            [self.M[:, inertial], self.C[:, first]])
        rhs_x = (-self.K).row_join(-_cols(self.C, inertial, lib)) if lib else np.hstack([-self.K, -self.C[:, inertial]])
        if lib:
            sol = W.LUsolve(rhs_x.row_join(self.B[0]))
        else:
            _check_regular(W, self.model)
            sol = np.linalg.solve(W, np.hstack([rhs_x, self.B[0]]))
        nx = n + len(inertial)
        Wx, Wu = sol[:, :nx], sol[:, nx:]
        A = sp.zeros(nx, nx) if lib else np.zeros((nx, nx))
        B = sp.zeros(nx, len(self.inputs)) if lib else np.zeros((nx, len(self.inputs)))
        for p, i in enumerate(inertial):
            A[i, n + p] = 1
            A[n + p, :] = Wx[p, :]
            B[n + p, :] = Wu[p, :]
        for r, i in enumerate(first):
            A[i, :] = Wx[len(inertial) + r, :]
            B[i, :] = Wu[len(inertial) + r, :]
        # outputs: q, q̇ = A[:n] x + B[:n] u, q̈ of inertial ones = A[n:] x + B[n:] u
        Cq = list(self.Cq) + [self.Cq[0] * 0] * (3 - len(self.Cq))
        D = list(self.D) + [self.D[0] * 0] * (3 - len(self.D))
        if len(self.D) > 1 and any(not _zero_matrix(d) for d in self.D[1:]):
            raise ModelError(f"model {self.model!r}: outputs {', '.join(self.outputs)} depend on the inputs' "
                             f"derivatives; use the transfer function.")
        for j in first:
            if not _zero_matrix(Cq[2][:, j]):
                raise ModelError(f"model {self.model!r}: an output needs the acceleration of first-order coordinate "
                                 f"{self.coordinates[j]!r}, which the state does not carry; use the transfer function.")
        sel = (lambda M, cols: _cols(M, cols, lib)) if lib else (lambda M, cols: M[:, cols])
        acc = A[n:, :] if lib else A[n:]
        C_out = Cq[0].row_join(sp.zeros(Cq[0].rows, len(inertial))) if lib else np.hstack(
            [Cq[0], np.zeros((Cq[0].shape[0], len(inertial)))])
        C_out = C_out + Cq[1] * A[:n, :] + sel(Cq[2], inertial) * acc if lib else (
            C_out + Cq[1] @ A[:n] + sel(Cq[2], inertial) @ acc)
        D_out = D[0] + Cq[1] * B[:n, :] + sel(Cq[2], inertial) * B[n:, :] if lib else (
            D[0] + Cq[1] @ B[:n] + sel(Cq[2], inertial) @ B[n:])
        states = list(self.coordinates) + [f"{self.coordinates[i]}'" for i in inertial]
        return A, B, C_out, D_out, states

    def to_control(self) -> Any:
        """The linearization as a python-control state space (``pip install 'lagrangian[control]'``).

        Returns
        -------
        control.StateSpace
            :meth:`state_space`'s ``A, B, C, D`` (with loop constraints in independent coordinates, with constraints
            on velocities in independent coordinates and speeds), inputs, outputs and states named by our labels.

        Raises
        ------
        ModelError
            For a symbolic linearization (naming its symbols without values); for one with no state-space form
            (inputs through their derivatives or integral: ``transfer_function(lin, input, output).to_control()``
            gives each entry exactly in ``s``); without python-control.

        Examples
        --------
        >>> import lagrangian as lg
        >>> from lagrangian.frequency import linearize
        >>> m = lg.Model("msd")
        >>> _ = m.add("mass", "m", "p", m=0.3)
        >>> _ = m.add("spring", "k", ("ground", "p"), k=40.0)
        >>> _ = m.add("damper", "c", ("ground", "p"), c=0.5)
        >>> _ = m.add("force", "F", "p", F=0)
        >>> sys = linearize(m, inputs=["F"], outputs=["x_p"]).to_control()
        >>> sys.state_labels, round(float(sys.dcgain()), 12)      # 1 / k
        (['x_p', "x_p'"], 0.025)
        """
        return state_space_system(self)


def _independent(lin: LinearModel) -> LinearModel:
    """:meth:`LinearModel.independent`."""
    if lin.symbolic:
        raise ModelError(f"model {lin.model!r}: independent coordinates of a symbolic linearization are not formed; "
                         f"give the parameters values (params=).")
    if lin.first_order:
        raise ModelError(f"model {lin.model!r}: first-order coordinates ({', '.join(lin.first_order)}) inside closed "
                         f"loops have no independent-coordinate form here; use the transfer function.")
    _, free, N = null_space(lin.Phi, len(lin.coordinates))  # Φ_d δq_d + Φ_i δq_i = 0: δq = N δq_i
    project = (lambda X: N.T @ X @ N)
    return LinearModel(**{**lin.__dict__, "coordinates": [lin.coordinates[i] for i in free], "M": project(lin.M),
                          "C": project(lin.C), "K": project(lin.K), "Phi": np.zeros((0, len(free))),
                          "B": [N.T @ b for b in lin.B], "Bi": N.T @ lin.Bi, "Cq": [c @ N for c in lin.Cq],
                          "at": {lin.coordinates[i]: lin.at[lin.coordinates[i]] for i in free}})


def _cols(M: sp.Matrix, cols: list[int], lib) -> sp.Matrix:
    return M.extract(list(range(M.rows)), cols)


def _zero_matrix(M) -> bool:
    if isinstance(M, sp.MatrixBase):
        return all(is_zero(e) for e in M)
    return not np.any(M)


def _check_regular(W: np.ndarray, model: str) -> None:
    if W.size and np.linalg.cond(W) > 1e14:
        raise ModelError(f"model {model!r}: the matrix of accelerations and first-order rates is singular at this "
                         f"point, so the linearization has no state-space form here.")


# ---------------------------------------------------------------------------
# Building the linearization
# ---------------------------------------------------------------------------


def linearize(model: Model, at: Mapping[str, Any] | None = None, *, velocity: Mapping[str, Any] | None = None,
              inputs: Sequence[str] | None = None, outputs: Sequence[Any] | None = None,
              params: Mapping[str, Any] | None = None, time: float = 0.0, symbolic: bool | None = None,
              tol: float = 1e-8) -> LinearModel:
    """Linearize ``model`` about the operating point ``at`` (coordinate values; zeros by default), at rest.

    ``inputs``: names of components with a signal parameter (sources,
    forces, torques, prescribed motions), or ``"name.param"``; every such
    component by default.  ``outputs``: coordinate names (``"x_p"``,
    ``"x_p'"``, ``"x_p''"``), component quantities (``"v(C1)"``,
    ``"i(V1)"``) or SymPy expressions of the coordinates; every coordinate
    by default.  A coordinate a constraint eliminated (``eliminate=``) is an
    output too (its solution in the remaining coordinates and ``t``), but
    not a key of ``at``: the point is given by the coordinates it follows from.  ``params``: values of symbolic parameters.  ``symbolic``:
    keep parameters without values as symbols (the default when there are
    such); otherwise every parameter must have a value.  ``time``: the
    instant ``t₀`` of a model whose equations depend on time.

    ``velocity``: the rates of a steady motion to linearize about instead
    of rest (coordinate names to rates; zeros by default): every rate stays
    constant there, and a coordinate that moves must be ignorable (absent
    from the equations: a position, a heading, a wheel's angle) —
    :mod:`lagrangian.analysis.motion`.  A model with constraints on
    velocities (rolling without slipping, knife edges) is linearized on
    them, Lagrange–d'Alembert's way: ``LinearModel.Phi_v`` holds them, the
    Laplace form, :func:`~lagrangian.frequency.modes` and transfer functions
    take them, and :meth:`LinearModel.state_space` gives Kane's independent
    coordinates and speeds.

    The point must be an equilibrium (a steady motion, given rates): a :class:`~lagrangian.errors.ModelError`
    names the coordinates that would accelerate there (beyond ``tol`` of the
    forces' scale) and by how much.  With no ``at``, the point is where
    Newton's method from the origin comes to rest, as SPICE finds its
    operating point (``LinearModel.at`` says where).  A linear model (no
    coefficient depends on the state) has the same linearization about every
    point, so it need not rest there (a DC bias, a DC current through an
    inductor).

    >>> import lagrangian as lg
    >>> m = lg.Model("rack")
    >>> _ = m.add("mass", "rack", "p", m=0.5), m.add("spring", "k", ("ground", "p"), k=20.0)
    >>> _ = m.add("force", "F", "p", F=0.0), m.add("inertia", "J", "s", J=1e-3)
    >>> _ = m.add("rack_and_pinion", "mesh", rack="x_p", pinion="theta_s", radius=0.02, eliminate="theta_s")
    >>> lin = linearize(m, inputs=["F"], outputs=["theta_s"])
    >>> lin.coordinates, float(lin.Cq[0][0, 0])   # θ = x / r
    (['x_p'], 50.0)
    """
    if not isinstance(model, Model):
        raise ModelError(f"linearize takes a lagrangian.Model, got {type(model).__name__}.")
    params = dict(params or {})
    if not np.isfinite(float(time)):
        raise ModelError(f"time must be a finite number, got {time!r}.")
    time = float(time)
    if at is None and velocity is None and not params and symbolic is not True:
        fast = numeric(model, inputs, outputs, time)
        if fast is not None:  # linear time-invariant, said in numbers: nothing symbolic is built
            Jq = np.zeros((0, len(fast["names"])))
            return _linear_model(model, None, fast["channels"], None, outputs, fast["names"], fast["first_order"],
                                 fast["point"], time, False, (fast["M"], fast["C"], fast["K"], Jq, fast["Bw"]),
                                 fast["rows"])
    twin, channels = _with_inputs(model, inputs)  # the same components, inputs driven: its checks are the model's
    twin._no_state_callables("linearization")
    values = _parameter_values(twin, params, symbolic)
    is_symbolic = any(not isinstance(x, (int, float)) for x in values.values()) or bool(_unvalued(twin, values))
    if symbolic is False and is_symbolic:
        missing = sorted(p.name for p in _unvalued(twin, values))
        raise ModelError(f"model {model.name!r} has symbolic parameters without values: {', '.join(missing)}. "
                         f"Give them in params=, or linearize symbolically (symbolic=True).")
    point = _operating_point(twin, twin.coordinate_names, at, is_symbolic)
    moving = rates(twin, twin.coordinate_names, velocity)
    fast = None if (is_symbolic or moving) else stamped(twin, channels, values, None if at is None else point, time,
                                                        outputs)
    if fast is not None:  # linear time-invariant: read off the stamps, nothing derived
        Jq = np.zeros((0, len(fast["names"])))
        return _linear_model(model, twin, channels, values, outputs, fast["names"], fast["first_order"],
                             fast["point"], time, False, (fast["M"], fast["C"], fast["K"], Jq, fast["Bw"]),
                             fast["rows"])
    eq = twin.eq
    if eq.recursion is not None and not (is_symbolic or moving or eq.multipliers):
        by_recursion = _by_recursion(model, twin, eq, channels, values, outputs, point, time, tol, settle=at is None)
        if by_recursion is not None:
            return by_recursion
    names = eq.names
    q, v = list(eq.sym.q), list(eq.sym.v)
    n = len(q)
    g = eq._generic
    M_g, f_g, Phi_g, c_g = g["M"], g["f"], g["constraints"], g["velocity_constraints"]
    # inputs: u(t) and its derivatives as plain symbols
    u_syms: dict[Any, tuple[int, int]] = {}  # the symbol standing for the k-th derivative of input col → (col, k)
    symbol_of: dict[tuple[int, int], sp.Symbol] = {}

    def usym(col: int, k: int) -> sp.Symbol:
        if (col, k) not in symbol_of:
            symbol_of[col, k] = sym = sp.Dummy(f"u{col}_{k}", real=True)
            u_syms[sym] = (col, k)
        return symbol_of[col, k]

    replace: dict[Any, Any] = {}
    order = 0
    for expr in _atoms(list(f_g) + list(M_g) + list(g["constraints"]) + list(c_g), channels):
        if isinstance(expr, sp.core.function.AppliedUndef) and expr.args != (t,):
            replace[expr] = sp.Integer(0)  # w(0), from integrating a source over [0, t]: w is 0 at the point
            continue
        k, col = _channel(expr, channels)
        replace[expr] = usym(col, k)
        order = max(order, k)
    calc = eq._derivation.calc
    f_u = f_g.xreplace(replace) if replace else f_g
    M_u = M_g.xreplace(replace) if replace else M_g
    subs = {**{qs: point[nm] for qs, nm in zip(q, names)}, **{vs: moving.get(nm, sp.Integer(0)) for vs, nm in zip(v, names)},
            **{us: sp.Integer(0) for us in u_syms}, t: sp.Float(time) if time else sp.Integer(0)}
    subs.update({sym: (sp.Float(val) if isinstance(val, float) else val) for sym, val in values.items()})

    rewrite = [Rewriter(subs), dict(subs), {}]  # memoized values and slopes at the point; renewed when subs moves

    def fresh():
        if rewrite[1] != subs:
            rewrite[:] = [Rewriter(subs), dict(subs), {}]
        return rewrite

    def at_point(expr):
        out = fresh()[0](sp.sympify(expr, strict=True))
        return out if is_symbolic else _number(out, model.name)

    def slope(expr, x, by=calc):
        """``∂expr/∂x`` at the point, in forward mode (:meth:`Calculus.at`): never built as an expression."""
        value, _, memo = fresh()
        out = by.at(sp.sympify(expr, strict=True), x, value, memo)
        return out if is_symbolic else _number(out, model.name)

    def matrix(rows, cols, entries):
        """A matrix from ``{(i, j): value}`` (the entries that may be nonzero): NumPy, or SymPy when symbolic."""
        if is_symbolic:
            out = sp.zeros(rows, cols)
            for (i, j), value in entries.items():
                out[i, j] = value
            return out
        out = np.zeros((rows, cols))
        for (i, j), value in entries.items():
            out[i, j] = value
        return out

    unsupported = [str(a.func) for a in _atoms(list(f_u) + list(M_u), ()) if isinstance(a, sp.core.function.AppliedUndef)]
    if unsupported:
        raise ModelError(f"model {model.name!r}: signals given as Python callables ({', '.join(sorted(set(unsupported)))}) "
                         f"have no operating value to linearize about; give them as numbers or SymPy expressions of t.")
    free = [symbols_of([e]) for e in f_u]
    index_v, index_q = {x: j for j, x in enumerate(v)}, {x: j for j, x in enumerate(q)}
    by_v = [(i, index_v[x], x) for i in range(n) for x in free[i] if x in index_v]
    by_q = [(i, index_q[x], x) for i in range(n) for x in free[i] if x in index_q]
    mv = len(c_g)
    c_u = c_g.xreplace(replace) if (mv and replace) else c_g
    at_rest_inputs = {us: sp.Integer(0) for us in u_syms}  # the inputs at their operating values
    steady_check(model.name, names, q, moving,
                 [e.xreplace(at_rest_inputs) for e in [*M_u.todok().values(), *f_u, *Phi_g, *c_u]],
                 {k: x for k, x in values.items() if isinstance(x, (int, float))}, calc.diff)
    if at is None and not is_symbolic and not len(Phi_g) and not mv and not moving:
        # a nonlinear model's rest point nearest the origin
        settle(f_u, lambda: {(i, j): slope(f_u[i], x) for i, j, x in by_q}, q, names, point, subs, at_point, n)
    f0 = sp.Matrix([at_point(e) for e in f_u])
    M0 = matrix(n, n, {ij: at_point(e) for ij, e in M_u.todok().items()})
    C0 = matrix(n, n, {(i, j): -slope(f_u[i], x) for i, j, x in by_v})
    K0 = matrix(n, n, {(i, j): -slope(f_u[i], x) for i, j, x in by_q})
    # linear (no coefficient depends on the state): the same linearization about every point, rest or not (a DC
    # current through a loop without a capacitor): nothing to check
    state = set(q) | set(v)
    linear = not symbols_of(list(M_u.todok().values())) & state and Calculus(state).affine(f_u)
    # the k-th derivative of w is s^(k−1) u: B_(k−1), or Bi (u/s) for w itself
    n_in = len(channels)
    channels_by_col = {c[1]: c[0] for c in channels.values()}
    Bw = [sp.zeros(n, n_in) for _ in range(max(order, 1) + 1)]
    by_u = Calculus(u_syms)
    for us, (col, k) in u_syms.items():
        for i in range(n):
            if us in free[i]:
                Bw[k][i, col] += slope(f_u[i], us, by_u)
    m = len(Phi_g)
    Phi_u = Phi_g.xreplace(replace) if (m and replace) else Phi_g
    driven = sorted({channels_by_col[u_syms[x][0]] for c in Phi_u for x in sp.sympify(c, strict=True).free_symbols if x in u_syms})
    if driven:
        raise ModelError(f"model {model.name!r}: inputs {', '.join(driven)} move a closed kinematic loop (they enter its "
                         f"closure constraints); linearizing about them is not supported. Drive the loop with a force "
                         f"or torque instead.")
    driven = sorted({channels_by_col[u_syms[x][0]] for c in c_u for x in sp.sympify(c, strict=True).free_symbols if x in u_syms})
    if driven and inputs is None:  # a rolling contact's turntable: no input unless asked for
        return linearize(model, at, velocity=velocity, inputs=[c[0] for c in channels.values() if c[0] not in driven],
                         outputs=outputs, params=params, time=time, symbolic=symbolic, tol=tol)
    if driven:
        raise ModelError(f"model {model.name!r}: inputs {', '.join(driven)} enter its constraints on velocities; "
                         f"linearizing about them is not supported. Drive the model with a force or torque instead.")
    Jq = matrix(m, n, {(k, j): slope(Phi_u[k], q[j]) for k in range(m) for j in range(n)})
    # constraints on velocities c = A(q, t) q̇ + b: rows (∂c/∂q + A s) δq = 0, multipliers along A
    Gq = matrix(mv, n, {(k, j): slope(c_u[k], q[j]) for k in range(mv) for j in range(n)})
    Av = matrix(mv, n, {(k, j): slope(c_u[k], v[j]) for k in range(mv) for j in range(n)})
    W = Jq.col_join(Av) if is_symbolic else np.vstack([Jq, Av])
    if m + mv:
        check_closure(model.name, [at_point(c) for c in Phi_u], is_symbolic, tol)
        if mv:
            check_rolling(model.name, [at_point(c) for c in c_u], eq.velocity_owners, Av, moving, is_symbolic, tol)
        lam0 = multipliers(model.name, f0, W, is_symbolic, names, tol, K0, point, check=not linear, moving=moving)
        for k in range(m + mv):
            if is_zero(lam0[k]) if is_symbolic else lam0[k] == 0:
                continue
            row, by = (Phi_u[k], q) if k < m else (c_u[k - m], v)
            for i in range(n):
                first = calc.diff(row, by[i])
                for j in range(n):
                    K0[i, j] -= lam0[k] * slope(first, q[j])
    elif not linear:
        check_rest(model.name, f0, names, is_symbolic, tol, K0, M0, point, moving=moving)
    Phi = Jq.col_join(Gq) if is_symbolic else np.vstack([Jq, Gq])
    Cq, Dw, y0 = _outputs(twin, eq, outputs, usym, channels, at_point)
    lin = _linear_model(model, twin, channels, values, outputs, names, [names[i] for i in eq.first_order], point,
                        time, is_symbolic, (M0, C0, K0, Phi, Bw), (Cq, Dw, y0))
    lin.velocity = dict(moving)
    lin.Phi_v = (sp.Matrix(Av) if is_symbolic else np.array(Av, dtype=float)) if mv else None
    return lin


def _by_recursion(model: Model, twin: Model, eq, channels, values, outputs, point, time, tol, settle: bool):
    """The linearization of a model its recursion serves (numbers, at rest, no constraints), from forward
    derivatives through the recursion's steps (:func:`lagrangian.derivation.recursion.tangents`): ``M = ∂p/∂q̇``,
    ``K = −∂(M q̈)/∂q``, ``C = −M ∂q̈/∂q̇`` and, for each input's signal and derivative, ``B = M ∂q̈/∂u``; never
    the closed form (which a 10-body spatial chain did not finish in 300 s).  ``settle``: Newton's method on
    ``q̈(q) = 0`` first, as :func:`~lagrangian.analysis.equilibrium.settle` does on ``f``.  None where the steps
    hold what the forward rules do not know (the closed form then decides)."""
    names, q, v, n = eq.names, list(eq.sym.q), list(eq.sym.v), len(eq.names)
    rec = eq.recursion.recursion
    found = sorted(_atoms([e for _, e in rec.definitions] + list(rec.accelerations), channels), key=sp.default_sort_key)
    env = {**{s: float(x) for s, x in values.items() if isinstance(x, (int, float))}, t: float(time)}
    env.update({s: 0.0 for s in v})
    env.update({a: 0.0 for a in found if isinstance(a, sp.core.function.AppliedUndef) and a.args != (t,)})  # (w(0): 0 at the point)
    inputs = [a for a in found if not (isinstance(a, sp.core.function.AppliedUndef) and a.args != (t,))]
    slots = [_channel(a, channels) for a in inputs]  # (derivative order k, input column)
    x = np.array([float(point[nm]) for nm in names])

    def at(x):
        env.update(zip(q, x.tolist()))
        return tangents(rec, env, q, v, inputs)

    out = at(x)
    for _ in range(50 if settle and out is not None else 0):
        qdd, J, _ = out
        step, *_ = np.linalg.lstsq(J[:, :n], qdd, rcond=None)
        if not np.all(np.isfinite(step)):
            break
        x, out = x - step, at(x - step)
        if out is None or np.abs(step).max(initial=0.0) <= 1e-14 * max(1.0, np.abs(x).max(initial=0.0)):
            break
    if out is None:
        return None
    if settle:
        point.update({nm: sp.Float(float(value)) for nm, value in zip(names, x)})
    qdd, J, P = out
    M0 = P[:, n:2 * n]
    env.update(zip(v, qdd.tolist()))  # (∂p/∂q at q̇ = q̈ is (∂M/∂q) q̈: f = M q̈ off an exact rest point too)
    moved = tangents(rec, env, q, v, inputs)
    if moved is None or not all(np.all(np.isfinite(a)) for a in (*out, *moved)):
        return None  # (a pivot of the recursion is zero there, a gimbal lock: the closed form says what it can)
    C0, K0 = -M0 @ J[:, n:2 * n], -(M0 @ J[:, :n] + moved[2][:, :n])
    check_rest(model.name, M0 @ qdd, names, False, tol, K0, M0, point)
    Bw = [np.zeros((n, len(channels))) for _ in range(max([k for k, _ in slots] + [1]) + 1)]
    for j, (k, col) in enumerate(slots):  # the k-th derivative of w is s^(k−1) u: B_(k−1), or Bi (u/s) for w itself
        Bw[k][:, col] += M0 @ J[:, 2 * n + j]
    subs = {**{s: sp.Float(float(point[nm])) for s, nm in zip(q, names)}, **{s: sp.Integer(0) for s in v},
            t: sp.Float(time) if time else sp.Integer(0),
            **{s: sp.Float(x) if isinstance(x, float) else x for s, x in values.items()}}
    symbol_of: dict = {}

    def usym(col: int, k: int) -> sp.Symbol:
        if (col, k) not in symbol_of:  # (an output's dependence on an input: at its operating value, 0)
            symbol_of[col, k] = sym = sp.Dummy(f"u{col}_{k}", real=True)
            subs[sym] = sp.Integer(0)
        return symbol_of[col, k]

    rows = _outputs(twin, eq, outputs, usym, channels,
                    lambda e: _number(Rewriter(subs)(sp.sympify(e, strict=True)), model.name))
    return _linear_model(model, twin, channels, values, outputs, names, [], point, time, False,
                         (M0, C0, K0, np.zeros((0, n)), Bw), rows)


def _linear_model(model: Model, twin: Model, channels, values, outputs, names, first, point, time, is_symbolic,
                  matrices, rows) -> LinearModel:
    """The :class:`LinearModel` of the pieces: ``matrices`` ``(M, C, K, Φ_q, Bw)``, output ``rows`` ``(Cq, Dw, y0)``."""
    (M0, C0, K0, Jq, Bw), (Cq, Dw, y0) = matrices, rows
    units = {_label(o): _unit(_label(o)) for o in (outputs if outputs is not None else names)}
    for label, _, _ in channels.values():
        comp = model.component(_INPUT.match(label).group(1))
        units[label] = _input_unit(comp, _INPUT.match(label).group(2) or _signal_of(comp))
    if is_symbolic:
        conv = (lambda x: sp.Matrix(x))
    else:
        def conv(x):
            return np.array(x, dtype=float) if isinstance(x, np.ndarray) else np.array(x.tolist(), dtype=float).reshape(x.shape)
    return LinearModel(
        model=model.name, coordinates=list(names), inputs=[c[0] for c in channels.values()],
        outputs=[_label(o) for o in (outputs if outputs is not None else names)],
        M=conv(M0), C=conv(C0), K=conv(K0), Phi=conv(Jq), B=[conv(b) for b in Bw[1:]], Bi=conv(Bw[0]),
        Cq=[conv(c) for c in Cq], D=[conv(d) for d in Dw[1:]], Di=conv(Dw[0]), symbolic=is_symbolic, at=dict(point), time=time,
        u0={c[0]: c[2] for c in channels.values()}, y0=y0, first_order=first, units=units,
        parameters=[] if twin is None else sorted(_unvalued(twin, values), key=lambda p: p.name),
    )


def _parameter_values(model: Model, params: Mapping[str, Any], symbolic: bool | None) -> dict[sp.Symbol, Any]:
    """The parameters' values: those given as numbers, and ``params`` by name."""
    by_name: dict[str, list[sp.Symbol]] = {}
    for sym in list(model.parameters) + list(model.assembly.values):
        by_name.setdefault(sym.name, []).append(sym)
    values: dict[sp.Symbol, Any] = {sym: float(val) for sym, val in model.assembly.values.items()}
    for key, val in params.items():
        if key not in by_name:
            raise UnknownNameError("parameter", key, by_name)
        if isinstance(val, sp.Basic) and not val.is_number:
            entry = val
        else:
            try:
                entry = float(val)
            except (TypeError, ValueError):
                raise ModelError(f"parameter {key!r} must be a number, got {val!r:.80}.") from None
            if not np.isfinite(entry):
                raise ModelError(f"parameter {key!r} must be finite, got {val!r:.80}.")
        for sym in by_name[key]:
            values[sym] = entry
    _check_rules(model, values, {s for k in params for s in by_name[k] if s in model.assembly.values})
    return values


def _check_rules(model: Model, values: Mapping[sp.Symbol, Any], overridden: set) -> None:
    """Numbers given in ``params=`` obey their parameters' rules (a spring's stiffness positive, ...), as
    ``simulate`` requires: :class:`~lagrangian.ParameterError` naming the component otherwise."""
    numbers = {s: sp.Float(v) for s, v in values.items() if not isinstance(v, sp.Basic)}
    for comp in model.components.values():
        for pname, spec in comp.parameters.items():
            value = comp.params.get(pname)
            if isinstance(value, sp.Expr) and value.free_symbols - {t}:
                entry = value.xreplace(numbers)
                if entry.is_number:
                    check_value(entry, spec.check, comp.name, pname)
    model._check_overrides({s: float(numbers[s]) for s in overridden if s in numbers})


def _unvalued(model: Model, values: Mapping[sp.Symbol, Any]) -> set:
    return {p for p in model.parameters if p not in values}


def _operating_point(model: Model, names: list[str], at: Mapping[str, Any] | None, symbolic: bool) -> dict:
    point = {nm: sp.Integer(0) for nm in names}
    if at is None:
        return point
    if not isinstance(at, Mapping):
        raise ModelError(f"at= is a mapping of coordinate names to values, got {type(at).__name__}.")
    eliminated = model.assembly.eliminated
    for key, val in at.items():
        if key in eliminated:
            raise eliminated[key].refusal("at", f"the point of {key} follows")
        if key not in point:
            raise UnknownNameError("coordinate", key, names)
        point[key] = number("at", key, val)
    return point
