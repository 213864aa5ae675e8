"""Routhian reduction: :class:`ReducedModel`, a model with its ignorable coordinates eliminated, and :func:`reduce`.

The momentum equations ``p_i = C_i`` are solved for the ignorable velocities
and the Routhian ``R = Σ C_i q̇_i − L`` formed on the generic equations (once
per structure); the reduced model is a :class:`~lagrangian.Model` over the
remaining coordinates with ``−R`` as its Lagrangian, which simulates (the
ignorable coordinates reconstructed by quadrature on request), integrates the
ignorable coordinates symbolically and finds its steady motions.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

from ...base.budget import DEFAULT_SECONDS, BudgetExceeded, within
from ...base.component import t
from ...base.identity import equal, is_zero
from ...base.text import as_expr
from ...derivation.equations import Equations
from ...errors import ReductionError, UnknownNameError
from ...base import display
from ...base.latex import to_latex
from ...model import Model
from ...numerics.simulation import Result
from ..derived import DerivedModel
from .cache import _by_structure, _put
from .cyclic import _coupling, _named, ignorability
from .steady import SteadyMotion, _numeric_roots, _solve
from .tidy import _drop, _factors_vanishing, _terms, _tidy
from ...base import deferred as _deferred

sp = _deferred.module("sympy", globals())


class ReducedModel(DerivedModel):
    """A model with its ignorable coordinates eliminated through the Routhian (make one with :func:`reduce`).

    It is a :class:`~lagrangian.Model`: ``lagrangian`` (``= −R``),
    ``equations``, ``mass_matrix``, ``forcing``, ``parameters`` and
    ``simulate`` work as for the full model, over the remaining coordinates.
    The momenta ``C_<name>`` are parameters: give them with ``momenta=``,
    or give the ignorable coordinates' velocities in ``velocity=`` and they
    are computed from the full model's momenta.  ``simulate(...,
    reconstruct=True)`` integrates the ignorable coordinates by quadrature
    along the reduced motion (their initial values from ``initial=``).

    Attributes (in terms of ``q(t)`` and ``q̇(t)``): ``routhian`` ``R``,
    ``momenta`` ``{coordinate: C}``, ``rates`` ``{coordinate: ∂R/∂C}`` (the
    ignorable velocities), ``effective_potential`` (``None`` when ``−R`` is
    not quadratic in the velocities), ``gyroscopic`` (velocity-linear part
    of ``−R``), ``singularities`` (expressions whose zeros make the
    momentum equations singular: coordinate singularities of the
    reduction).

    Constraints on velocities (nonholonomic) that hold neither the
    ignorable coordinates nor their rates carry over unchanged, with their
    owners (``eq.velocity_constraints``, ``eq.velocity_owners``): they enter
    the reduced equations with multipliers (Lagrange–d'Alembert) as in the
    full model, in ``simulate`` (initial rates checked against them) and in
    impulses; the analyses that need a system without them (steady motions,
    their stability, linearization) refuse such a reduced model by name.
    """

    def __init__(self, full: Model, ignorable: Sequence[str], momenta: Mapping[str, Any] | None = None,
                 _quadrature: Sequence[str] = (), _parent: "ReducedModel | None" = None):
        super().__init__(full, f"{full.name} (reduced)", self._build_equations)
        self.full = full
        self.ignored = list(ignorable)
        self._quadrature = tuple(_quadrature)
        if _parent is not None:
            self.__dict__.update({k: v for k, v in _parent.__dict__.items() if k.startswith("_r_")})
        else:
            self._reduce(momenta or {})
        self._siblings: dict[tuple[str, ...], ReducedModel] = {}

    # -- the reduction -------------------------------------------------------
    def _reduce(self, momenta: Mapping[str, Any]) -> None:
        """Reduce the generic equations (parameters given as numbers still symbols), then put the values in:
        a model given numbers and its twin given symbols take the same decisions on the same expressions."""
        full = self.full
        eq = full.eq
        generic = eq.generic()
        values = eq.values
        names = eq.names
        I = [names.index(n) for n in self.ignored]
        K = [i for i in range(len(names)) if i not in I]
        q, v = eq.sym.q, eq.sym.v
        C = []
        for n in self.ignored:
            given = momenta.get(n)
            C.append(sp.Symbol(f"C_{n}", real=True) if given is None else as_expr(given, f"momenta[{n!r}]"))
        unknown = [k for k in momenta if k not in self.ignored]
        if unknown:
            raise UnknownNameError("ignorable coordinate (for momenta=)", unknown[0], self.ignored)
        # One reduction per structure: the same components with other numbers reuse it (the symbols standing
        # for the numbers are renamed to canonical ones in the key, and back in the parts).
        key = ("reduce", tuple(names), tuple(self.ignored), tuple(C),
               *(sp.sympify(generic[k]) for k in ("L", "D")),
               *(sp.ImmutableMatrix(generic[k]) for k in ("M", "Q", "constraints", "velocity_constraints")))
        parts = _by_structure(key, values, lambda: self._reduce_generic(generic, names, I, K, q, v, C))
        self._r_generic = parts
        self._r_values = dict(values)
        self._r_parts = {k: _put(part, values) for k, part in parts.items()}

    def _reduce_generic(self, generic, names, I, K, q, v, C) -> dict:
        full = self.full
        qI, vI = [q[i] for i in I], [v[i] for i in I]
        p = [_drop(generic["p"][i], qI) for i in I]
        MII = sp.Matrix([[_drop(generic["M"][i, j], qI) for j in I] for i in I])
        rest = [e.xreplace(dict.fromkeys(vI, sp.Integer(0))) for e in p]
        # p = rest + M·v̇ term by term (never their difference: SymPy would merge round-off into a "term")
        affine = all(equal(p[a], rest[a] + sum(MII[a, b] * vI[b] for b in range(len(I)))) for a in range(len(I)))
        # each entry tidied on its own (small, cheap): sin² + cos² gone before the solve spreads it everywhere
        MII = MII.applyfunc(_tidy)
        rest = [_tidy(e) for e in rest]
        det = _tidy(MII.det(method="berkowitz"))
        if is_zero(det) or not affine:
            null = MII.nullspace()
            combo = ""
            if null:
                vec = null[0]
                combo = " the momenta " + " and ".join(f"p_{n}" for n, c in zip(self.ignored, vec) if c != 0) + \
                    " are not independent (∂²L/∂q̇² is singular on these coordinates)."
            raise ReductionError(
                f"the momentum equations p = C of model {full.name!r} cannot be solved for the velocities of "
                f"{', '.join(self.ignored)}:{combo or ' they are not linear in those velocities.'} Reduce fewer "
                f"coordinates (ignorable=[...]), or give every combination of them inertia."
            )
        if not K:
            raise ReductionError(
                f"every coordinate of model {full.name!r} is ignorable ({', '.join(self.ignored)}): the motion is "
                f"uniform and nothing is left to reduce to; simulate the full model (or keep one coordinate)."
            )
        # p_I = rest + M_II v_I (checked above) makes L = L|v_I=0 + restᵀ v_I + ½ v_Iᵀ M_II v_I exactly, so with
        # w = C − rest:  v_I = M_II⁻¹ w  and  R = C·v_I − L = ½ wᵀ M_II⁻¹ w − L|v_I=0  (no substitution into L)
        w = sp.Matrix(len(C), 1, [c - r for c, r in zip(C, rest)])  # a column even when nothing is ignored
        adjugate = MII.adjugate().applyfunc(_tidy)
        rates = [_tidy(e / det) for e in adjugate * w]
        at = dict(zip(vI, rates))
        L = _drop(generic["L"], qI)
        R = _tidy((w.T * adjugate * w)[0, 0] / (2 * det) - L.xreplace(dict.fromkeys(vI, sp.Integer(0))))
        vK = [v[k] for k in K]
        lam = sp.Dummy("lambda")
        Lr = -R
        scaled = Lr.xreplace({s: lam * s for s in vK})
        parts = [scaled.xreplace({lam: 0}), sp.diff(scaled, lam).xreplace({lam: 0}),
                 sp.diff(scaled, lam, 2).xreplace({lam: 0}) / 2]
        quadratic = equal(Lr, parts[0] + parts[1] + parts[2])
        R = _terms(R)
        if quadratic:
            T, G, V = _terms(parts[2]), _terms(parts[1]), _terms(-parts[0])
        else:  # not quadratic in the velocities: no effective potential
            T, G, V = Lr - parts[0], sp.Integer(0), -parts[0]
        D = _drop(generic["D"], qI)
        Q = [_tidy(_drop(generic["Q"][k], qI).xreplace(at)) for k in K]
        constraints = [_drop(c, qI) for c in generic["constraints"]]
        # constraints on velocities hold neither q_I nor q̇_I (else q_I would not be ignorable): they carry over
        velocity = [_drop(c, [*qI, *vI]) for c in generic["velocity_constraints"]]
        return {
            "K": K, "I": I, "C": C, "rates": rates, "R": R, "T": T, "G": G, "V": V, "D": D, "Q": Q,
            "constraints": constraints, "velocity": velocity, "quadratic": quadratic,
            "singular": _factors_vanishing(det), "det": det,
        }

    def _build_equations(self) -> Equations:
        parts = self._r_generic
        full_eq = self.full.eq
        keep = [i for i in range(len(full_eq.names))
                if i in parts["K"] or full_eq.names[i] in self._quadrature]
        coords = [full_eq.coordinates[i] for i in keep]
        Q = [sp.Integer(0)] * len(keep)
        quad = {}
        for row, i in enumerate(keep):
            if i in parts["K"]:
                Q[row] = parts["Q"][parts["K"].index(i)]
            else:
                quad[row] = parts["rates"][parts["I"].index(i)]
        # constraints on velocities (Lagrange–d'Alembert) enter the reduced equations as the full model's do
        velocity = list(parts.get("velocity") or [])
        owners = getattr(full_eq, "constraint_owners", None) if velocity else None
        return Equations.from_energies(coords, parts["T"], parts["V"], parts["G"], parts["D"], Q,
                                       parts["constraints"], full_eq.constraint_rate, quad, values=self._r_values,
                                       constraint_owners=owners, velocity_constraints=velocity,
                                       velocity_owners=full_eq.velocity_owners if velocity else ())

    # -- what the reduction found --------------------------------------------------
    def _show(self, expr):
        return self.full.eq.display(expr)

    def __repr__(self) -> str:
        return (f"<ReducedModel {self.name!r}: {display.short(self.ignored)} eliminated, "
                f"coordinates {display.short(self.coordinate_names)}>")

    def _repr_html_(self) -> str:
        """The Routhian, the effective potential, the conserved momenta and the reduced equations (Jupyter)."""
        latex = to_latex
        parts = [display.math(rf"R = {latex(self.routhian)}")]
        if self.effective_potential is not None:
            parts.append(display.math(rf"V_{{\mathrm{{eff}}}} = {latex(self.effective_potential)}"))
        parts.append(display.table(["eliminated", "conserved momentum"],
                                   [[n, str(m)] for n, m in self.momenta.items()]))
        parts += [display.math(rf"{latex(e.lhs)} = {latex(e.rhs)}") for e in self.equations]
        return display.block(f"reduced model {self.name}", *parts,
                             note=f"singular where {display.short(self.singularities)} = 0" if self.singularities else None)

    @property
    def routhian(self) -> sp.Expr:
        """``R = Σ C_i q̇_i − L`` with the ignorable velocities eliminated."""
        return self._show(self._r_parts["R"])

    @property
    def momenta(self) -> dict[str, sp.Expr]:
        """``{ignorable coordinate: C}``: the conserved momenta (symbols ``C_<name>`` unless given)."""
        return dict(zip(self.ignored, self._r_parts["C"]))

    @property
    def rates(self) -> dict[str, sp.Expr]:
        """``{ignorable coordinate: q̇_i = ∂R/∂C_i}`` in the remaining coordinates and the momenta."""
        return {n: self._show(r) for n, r in zip(self.ignored, self._r_parts["rates"])}

    @property
    def effective_potential(self) -> sp.Expr | None:
        """``V_eff``: ``R`` at zero remaining velocities (``None`` if ``−R`` is not quadratic in them)."""
        return self._show(self._r_parts["V"]) if self._r_parts["quadratic"] else None

    @property
    def gyroscopic(self) -> sp.Expr:
        """The part of ``−R`` linear in the remaining velocities (zero when the ignorable motion does not couple)."""
        return self._show(self._r_parts["G"])

    @property
    def singularities(self) -> list[sp.Expr]:
        """Expressions (in the remaining coordinates) whose zeros make ``∂²L/∂q̇_i²`` singular."""
        return [self._show(s) for s in self._r_parts["singular"]]

    def momenta_from(self, initial: Mapping[str, float] | None = None, velocity: Mapping[str, float] | None = None,
                     params: Mapping[str, float] | None = None) -> dict[str, float]:
        """The momenta ``p_i = ∂L/∂q̇_i`` of a full-model state (coordinates and velocities by name)."""
        eq = self.full.eq
        initial, velocity = dict(initial or {}), dict(velocity or {})
        for given in (initial, velocity):
            for name in given:
                if name not in eq.names:
                    raise UnknownNameError("coordinate", name, eq.names)
        values = {s: v for s, v in self.full._values(self._full_params(params), overrides=True).items()}
        point = {**{q: float(initial.get(n, 0.0)) for q, n in zip(eq.sym.q, eq.names)},
                 **{v: float(velocity.get(n, 0.0)) for v, n in zip(eq.sym.v, eq.names)}, t: 0.0}
        out = {}
        for n, i in zip(self.ignored, self._r_parts["I"]):
            out[n] = float(eq.generic()["p"][i].xreplace(values).xreplace(point))
        return out

    def _full_params(self, params: Mapping[str, float] | None) -> dict[str, float]:
        full_names = {s.name for s in self.full.parameters} | set(self.full.parameter_values)
        return {k: v for k, v in (params or {}).items() if k in full_names}

    # -- simulation --------------------------------------------------------------------
    def reconstructing(self, names: Sequence[str] | bool = True) -> "ReducedModel":
        """The same reduced model, also integrating the ignorable coordinates ``names`` by quadrature."""
        names = tuple(self.ignored if names is True else ([] if names is False else names))
        for n in names:
            if n not in self.ignored:
                raise UnknownNameError("ignorable coordinate (for reconstruct=)", n, self.ignored)
        names = tuple(n for n in self.ignored if n in names)
        if names == self._quadrature:
            return self
        if names not in self._siblings:
            self._siblings[names] = ReducedModel(self.full, self.ignored, _quadrature=names, _parent=self)
        return self._siblings[names]

    def simulate(self, t_end=10.0, *, initial=None, velocity=None, params=None, momenta=None,
                 reconstruct: bool | Sequence[str] | None = None, **kwargs) -> Result:
        """Integrate the reduced equations (see :meth:`lagrangian.Model.simulate` for the options).

        ``momenta`` gives ``C`` by ignorable coordinate; otherwise the
        ignorable coordinates' velocities in ``velocity`` (a full-model
        state) give them.  ``reconstruct=True`` (or a list of names) also
        integrates the ignorable coordinates by quadrature, starting from
        their values in ``initial``; ``False`` integrates none; by default,
        those of :meth:`reconstructing` (none for :func:`reduce`'s model).  A start on a singular set of the
        reduction (``singularities``) with a nonzero momentum is refused.
        """
        initial, velocity = dict(initial or {}), dict(velocity or {})
        params = dict(params or {})
        momenta = dict(momenta or {})
        for n in momenta:
            if n not in self.ignored:
                raise UnknownNameError("ignorable coordinate (for momenta=)", n, self.ignored)
        from_state = [n for n in self.ignored if n in velocity]
        if from_state:
            clash = [n for n in from_state if n in momenta]
            if clash:
                raise ReductionError(
                    f"both a velocity and a momentum were given for {', '.join(clash)}: give one or the other."
                )
            momenta.update({n: value for n, value in self.momenta_from(initial, velocity, params).items() if n in from_state})
        for n, C in zip(self.ignored, self._r_parts["C"]):
            if isinstance(C, sp.Symbol) and C.name.startswith("C_"):
                if n in momenta:
                    params[C.name] = momenta[n]
                elif C.name not in params:
                    raise ReductionError(
                        f"the momentum of ignorable coordinate {n!r} has no value: give momenta={{{n!r}: ...}}, "
                        f"params={{{C.name!r}: ...}}, or its velocity in velocity= (a full-model state)."
                    )
        target = self if reconstruct is None else self.reconstructing(reconstruct)
        keep = set(target.coordinate_names)
        start = {k: val for k, val in initial.items() if k in keep}
        speed = {k: val for k, val in velocity.items() if k in keep and k not in self.ignored}
        dropped = [k for k in list(initial) + list(velocity) if k not in keep and k not in self.ignored
                   and k not in self.full.eq.names]
        if dropped:
            raise UnknownNameError("coordinate", dropped[0], self.full.eq.names)
        target._check_singular(start, params)
        known = {s.name for s in target.parameters} | set(target.parameter_values)
        unknown = [k for k in params if k not in known and k not in {s.name for s in self.full.parameters}]
        if unknown:
            raise UnknownNameError("parameter", unknown[0], known)
        params = {k: v for k, v in params.items() if k in known}
        return Model.simulate(target, t_end, initial=start, velocity=speed, params=params, **kwargs)

    def _check_singular(self, initial: Mapping[str, float], params: Mapping[str, float]) -> None:
        parts = self._r_parts
        if not parts["singular"]:
            return
        eq = self.full.eq
        values = {s: sp.Float(params[s.name]) for s in self.parameters if s.name in params}
        point = {eq.sym.q[k]: sp.Float(initial.get(eq.names[k], 0.0)) for k in parts["K"]}
        for s in parts["singular"]:
            value = s.xreplace(values).xreplace(point)
            if value.is_number and abs(float(value)) < 1e-12:
                moving = [n for n, C in zip(self.ignored, parts["C"]) if sp.sympify(C).xreplace(values) != 0]
                if moving:
                    raise ReductionError(
                        f"the initial state of {self.name!r} lies where {self._show(s)} = 0, a singularity of the "
                        f"reduction: with a nonzero momentum of {', '.join(moving)} the effective potential is "
                        f"infinite there (the motion cannot reach it). Start off that set, or with zero momentum."
                    )

    def quadrature(self, motion: "Mapping[str, Any] | SteadyMotion", initial: Mapping[str, Any] | None = None,
                   t0: Any = 0) -> dict[str, sp.Expr]:
        """The ignorable coordinates by symbolic quadrature, ``q_i(t) = q_i(t₀) + ∫ ∂R/∂C_i dt``.

        ``motion`` gives the remaining coordinates as SymPy expressions of
        ``t`` (or is a :class:`SteadyMotion`); ``initial`` the ignorable
        coordinates' values at ``t0`` (default symbols ``<name>_0``).  Where
        SymPy cannot integrate, the result holds an unevaluated ``Integral``.
        """
        eq = self.reconstructing(False).eq
        if isinstance(motion, SteadyMotion):
            motion = motion.coordinates
        motion = dict(motion)
        for n in motion:
            if n not in eq.names:
                raise UnknownNameError("remaining coordinate", n, eq.names)
        missing = [n for n in eq.names if n not in motion]
        if missing:
            raise ReductionError(f"quadrature needs the motion of every remaining coordinate; missing: {', '.join(missing)}.")
        tau = sp.Symbol("tau", real=True)
        path = {}
        for i, n in enumerate(eq.names):
            expr = as_expr(motion[n], f"the motion of {n!r}")
            path[eq.sym.q[i]] = expr.subs(t, tau)
            path[eq.sym.v[i]] = sp.diff(expr, t).subs(t, tau)
        out = {}
        initial = dict(initial or {})
        for n, rate in zip(self.ignored, self._r_parts["rates"]):
            start = as_expr(initial.get(n, sp.Symbol(f"{n}_0", real=True)), f"initial[{n!r}]")
            integrand = _tidy(rate.xreplace(path).subs(t, tau))
            out[n] = start + sp.integrate(integrand, (tau, t0, t))
        return out

    # -- steady motion -------------------------------------------------------------------
    def steady_conditions(self) -> list[sp.Eq]:
        """The conditions for steady motion: the reduced equations at zero remaining velocities (``∂R/∂q_k = 0``)."""
        return [sp.Eq(self._show(e), 0) for e in self._steady_exprs()]

    def _constraint_forces(self) -> list[sp.Symbol]:
        """The multipliers of the constraints on velocities at a steady motion: the forces that hold it (one per
        constraint, unknowns of the steady-motion conditions)."""
        if getattr(self, "_mu", None) is None:
            owners = self.reconstructing(False).eq.velocity_owners
            self._mu = [sp.Dummy(f"mu_{owner}", real=True) for owner in owners]
        return self._mu

    def _steady_exprs(self) -> list[sp.Expr]:
        eq = self.reconstructing(False).eq
        if len(eq.constraints):
            raise ReductionError(f"steady motions of {self.name!r}: models with loop constraints are not supported.")
        rest = dict.fromkeys(eq.sym.v, sp.Integer(0))
        f = sp.ImmutableMatrix(eq.generic()["f"])
        parts = _by_structure(("steady", f), eq.values, lambda: {"exprs": [_tidy(e.xreplace(rest)) for e in f]})
        out = _put(parts["exprs"], eq.values)
        c = sp.Matrix(eq.generic()["velocity_constraints"])
        if len(c):  # at rest the constraints on velocities push with A(q)ᵀ μ, and need b(q) = 0
            A, b = _put(list(c.jacobian(eq.sym.v)), eq.values), _put(list(c.xreplace(rest)), eq.values)
            n, mu = len(out), self._constraint_forces()
            out = [e + sum(m * A[k * n + i] for k, m in enumerate(mu)) for i, e in enumerate(out)]
            out += [e for e in b if not is_zero(e)]
        if any(e.has(t) for e in out):
            raise ReductionError(
                f"the reduced equations of {self.name!r} depend explicitly on time: there is no steady motion."
            )
        return out

    def steady_motions(self, solve_for: Sequence[str] | None = None, *, params: Mapping[str, float] | None = None,
                       momenta: Mapping[str, float] | None = None,
                       search: Mapping[str, tuple[float, float]] | None = None,
                       budget: float | None = DEFAULT_SECONDS) -> list["SteadyMotion"]:
        """Every steady motion (all branches): the remaining coordinates constant, the ignorable ones uniform.

        Symbolically, ``solve_for`` names the unknowns — remaining
        coordinates (default), momenta ``C_<name>`` or parameters — and the
        other quantities stay symbols (a coordinate not solved for becomes a
        symbol ``<name>_0``).  With ``params`` and ``momenta`` giving every
        value, the coordinates are found numerically when SymPy cannot
        solve: all roots of the conditions in ``search`` ranges (default
        ``(−π, π]`` for joint angles), by bracketing in one coordinate and
        by Newton from a grid of starts in several.

        A reduced model that keeps constraints on velocities (a sled's knife
        edge) rests where its forces are held by the constraints' forces
        ``A(q)ᵀ μ`` too (with ``b(q) = 0``): its rests come in families, and a
        coordinate the conditions leave free stays a symbol ``<name>_0`` (a
        sled pulled across its edge by a spring rests anywhere along the
        spring's line).  They are solved symbolically only.

        The symbolic solve runs under a budget of ``budget`` seconds (``None``:
        none); past it a :class:`~lagrangian.ReductionError` says what to
        give instead (numeric values, a search range, fewer unknowns).
        """
        eq = self.reconstructing(False).eq
        names = eq.names
        q = eq.sym.q
        exprs = self._steady_exprs()
        values = self._values_for(params, momenta)
        exprs = [e.xreplace(values) for e in exprs]
        forces = self._constraint_forces() if len(eq.velocity_constraints) else []
        unknowns_names = list(solve_for) if solve_for is not None else list(names)
        lookup = {n: q[i] for i, n in enumerate(names)}
        lookup.update({C.name: C for C in self._r_parts["C"] if isinstance(C, sp.Symbol)})
        lookup.update({s.name: s for s in self.parameters})
        unknowns = []
        for n in unknowns_names:
            if n not in lookup:
                raise UnknownNameError("unknown to solve for", n, lookup)
            unknowns.append(lookup[n])
        rest = {q[i]: sp.Symbol(f"{n}_0", real=True) for i, n in enumerate(names) if q[i] not in unknowns}
        exprs = [e.xreplace(rest) for e in exprs]
        unknowns += forces  # the constraint forces that hold a steady motion: solved for, never shown
        free = set().union(*(e.free_symbols for e in exprs)) - set(unknowns)
        numeric = solve_for is None and not free
        unfolded = [e.replace(sp.Abs, lambda x: x).replace(sp.sign, lambda x: sp.Integer(1)) for e in exprs]
        rational = all(e.is_rational_function(*unknowns) for e in unfolded)
        branches = None
        if rational or not numeric or forces:
            try:
                branches = within(_solve, exprs, unknowns, seconds=budget)
            except BudgetExceeded:
                if not numeric:
                    raise ReductionError(
                        f"SymPy did not solve the steady-motion conditions of {self.name!r} for "
                        f"{', '.join(unknowns_names)} within the budget of {budget:g} s: give numeric params= and "
                        f"momenta= so the coordinates are found numerically (in search= ranges), solve for fewer "
                        f"unknowns, or raise budget=."
                    ) from None
                # every value is known: the coordinates are found numerically instead
        if branches is None and forces:
            raise ReductionError(
                f"SymPy did not solve the steady-motion conditions of {self.name!r}, whose constraints on velocities "
                f"({', '.join(map(repr, sorted(set(eq.velocity_owners))))}) hold it at rest along whole families of "
                f"positions, so there is no numeric search for isolated roots: solve for fewer coordinates "
                f"(solve_for=[...]; the others stay symbols <name>_0), or raise budget=.")
        if branches is None:
            if not numeric:
                raise ReductionError(
                    f"SymPy cannot solve the steady-motion conditions of {self.name!r} for "
                    f"{', '.join(unknowns_names)}; give numeric params= and momenta= to solve them numerically."
                )
            branches = _numeric_roots(self.name, self.eq.coordinates, exprs, names, q, search or {})
        for n, (lo, hi) in (search or {}).items():  # solved symbolically too: only what lies in the ranges asked
            if n not in lookup or lookup[n] not in q:
                raise UnknownNameError("remaining coordinate (for search=)", n, names)
            qi = lookup[n]
            branches = [sol for sol in branches if qi not in sol or not sol[qi].is_number
                        or float(lo) <= float(sol[qi]) <= float(hi)]
        out = []
        for sol in branches:
            coords = {}
            # a coordinate the solve leaves free (a family of rests held by constraints on velocities) is a symbol
            family = {q[i]: sp.Symbol(f"{n}_0", real=True) for i, n in enumerate(names) if q[i] in unknowns
                      and q[i] not in sol}
            sol = {k: sp.sympify(v).xreplace(family) for k, v in sol.items()}
            for i, n in enumerate(names):
                coords[n] = sol.get(q[i], rest.get(q[i], family.get(q[i])))
            fixed = {q[i]: coords[n] for i, n in enumerate(names)}
            others = {s: val for s, val in sol.items() if s not in q}
            C_values = {n: sp.sympify(C).xreplace(values).xreplace(others) for n, C in zip(self.ignored, self._r_parts["C"])}
            rates = {n: _tidy(r.xreplace(values).xreplace(others).xreplace(fixed).xreplace(dict.fromkeys(eq.sym.v, 0)))
                     for n, r in zip(self.ignored, self._r_parts["rates"])}
            out.append(SteadyMotion(self, coords, C_values, rates, dict(values) | others))
        return out

    def _values_for(self, params, momenta) -> dict[sp.Symbol, sp.Expr]:
        params, momenta = dict(params or {}), dict(momenta or {})
        out: dict[sp.Symbol, sp.Expr] = {}
        known = {s.name: s for s in self.parameters}
        for n, val in momenta.items():
            if n not in self.ignored:
                raise UnknownNameError("ignorable coordinate (for momenta=)", n, self.ignored)
            C = self._r_parts["C"][self.ignored.index(n)]
            if isinstance(C, sp.Symbol):
                out[C] = sp.nsimplify(val) if val == 0 else sp.Float(val)
        for k, val in params.items():
            if k not in known:
                raise UnknownNameError("parameter", k, known)
            out[known[k]] = sp.Float(val)
        return out


def reduce(model: Model, ignorable: Sequence[str] | None = None, momenta: Mapping[str, Any] | None = None) -> ReducedModel:
    """Eliminate ignorable coordinates of ``model`` through the Routhian; return the :class:`ReducedModel`.

    ``ignorable`` names the coordinates to eliminate (default: every
    ignorable one, see :func:`ignorability`); ``momenta`` gives values or
    expressions for their momenta (default: symbols ``C_<name>``).  A
    coordinate that is not ignorable, or momentum equations that cannot be
    solved for the ignorable velocities (a singular ``∂²L/∂q̇²``), raise
    :class:`~lagrangian.ReductionError` saying why.

    Constraints on velocities (nonholonomic) stay in the reduced model,
    with their multipliers: a coordinate they couple (it or its rate
    appears in one, so the constraint's force acts along it and its
    momentum is not conserved) is not ignorable, and asking to reduce it is
    refused naming the component.  A sled on a knife edge at its centre of
    mass carrying a flywheel: the flywheel's angle is eliminated, the edge
    stays, and the sled turns at a constant rate (on a circle):

    >>> import lagrangian as lg
    >>> m = lg.Model("sled with flywheel", dim=2)
    >>> _ = m.add("body", "b", "b", m=2, inertia=0.1)
    >>> _ = m.add("free", "j", ("ground", "b"))
    >>> _ = m.add("knife_edge", "edge", "b")
    >>> _ = m.add("body", "w", "w", m=0.5, inertia=0.02)
    >>> _ = m.add("revolute", "r", ("b", "w"))
    >>> red = reduce(m)
    >>> red.ignored, red.coordinate_names, red.eq.velocity_owners
    (['theta_r'], ['x_j', 'y_j', 'theta_j'], ['edge'])
    >>> res = red.simulate(2, initial={"x_j": 0, "y_j": 0, "theta_j": 0, "theta_r": 0},
    ...                    velocity={"x_j": 1, "y_j": 0, "theta_j": 0.5, "theta_r": 3}, reconstruct=True, points=3)
    >>> [round(float(x), 9) for x in res["theta_j"]], [round(float(x), 9) for x in res["theta_r"]]
    ([0.0, 0.5, 1.0], [0.0, 3.0, 6.0])
    >>> reduce(m, ["x_j"])
    Traceback (most recent call last):
    ...
    lagrangian.errors.ReductionError: coordinate 'x_j' of model 'sled with flywheel' cannot be reduced: the constraint on velocities (nonholonomic) of 'edge' couples it, ...
    """
    report = ignorability(model)
    coupled = _coupling(model)
    if ignorable is None:
        ignorable = [n for n, r in report.items() if r.ignorable]
        if not ignorable:
            why = "; ".join(f"{r.coordinate}: {r.reason}" for r in report.values())
            owners = sorted({o for names in coupled.values() for o in names})
            lead = (f" (the constraints on velocities of {_named(owners)} couple "
                    f"{'every coordinate' if len(coupled) == len(report) else ', '.join(coupled)}: nonholonomic)"
                    if owners else "")
            raise ReductionError(f"model {model.name!r} has no ignorable coordinate{lead}: {why}.")
    else:
        ignorable = [ignorable] if isinstance(ignorable, str) else list(ignorable)
        for n in ignorable:
            if n not in report:
                raise UnknownNameError("coordinate", n, report)
            if n in coupled:
                raise ReductionError(
                    f"coordinate {n!r} of model {model.name!r} cannot be reduced: the constraint on velocities "
                    f"(nonholonomic) of {_named(coupled[n])} couples it, so the constraint's force acts along it and "
                    f"its momentum is not conserved. "
                    + (f"The model's ignorable coordinates, which no such constraint holds: "
                       f"{', '.join(x for x, r in report.items() if r.ignorable)}." if any(
                           r.ignorable for r in report.values()) else "The model has no ignorable coordinate to reduce."))
            if not report[n].ignorable:
                raise ReductionError(f"coordinate {n!r} of model {model.name!r} is not ignorable: {report[n].reason}.")
    return ReducedModel(model, ignorable, momenta)
