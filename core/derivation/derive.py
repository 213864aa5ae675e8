"""Fast, structure-keeping differentiation for deriving equations of motion.

SymPy's ``diff`` is general but slow: every call goes through ``Derivative``
with its checks and assumption queries, and derivatives of the same
sub-expression are recomputed each time they occur.  The equations of a
mechanism differentiate the same few sub-expressions (``l_k sin q_k``) again
and again, so this module differentiates with memoized rules for sums,
products, powers, ``sin`` and ``cos`` (anything else falls back to SymPy),
prunes by which symbols each sub-expression depends on, and never expands.

:class:`Derivation` computes ``M`` and ``f`` of ``M q̈ = f`` from ``T``, ``V``,
``G``, ``D`` and ``Q`` (see :mod:`lagrangian.equations`).  The kinetic energy
is first split into terms ``c(q, t) · w_a · w_b`` with ``w = J(q, t) q̇ + b(q, t)``
affine in the velocities — a point mass gives ``½ m (ẋ² + ẏ²)``, a body
``½ I ω²``, an inductor ``½ L q̇²`` — whose contributions are written down
directly::

    M_ij += c (J_ai J_bj + J_aj J_bi)
    f_i  -= c (J_ai h_b + J_bi h_a) + ċ (J_ai w_b + J_bi w_a) − ∂c/∂q_i w_a w_b
            + c (g_ai w_b + g_bi w_a)

with ``h = J̇ q̇ + ḃ`` (the rate of ``w`` at ``q̈ = 0``, in one pass over ``w``) and
``g_i = Σ_j (∂J_i/∂q_j − ∂J_j/∂q_i) q̇_j + ∂J_i/∂t − ∂b/∂q_i`` (zero for ``w`` the time derivative of a
position; in closed form for the components of a declared moving frame's vectors, :meth:`Derivation.frames`).
Entries that share the same Jacobian column are collected before they are
built, so that ``M_ij`` of an ``n``-link chain is one product of columns times
one sum of masses instead of ``n`` products.  Whatever is not of that form (and ``V``, ``G``, ``D``) goes
through the general formulas ``p = ∂L/∂q̇``, ``M = ∂p/∂q̇``,
``f = ∂L/∂q − (∂p/∂q) q̇ − ∂p/∂t − ∂D/∂q̇ + Q``.  Both give the same equations.

The memoized derivatives, time derivatives and substitution are in
:mod:`.calculus`, the quick numeric probe :func:`float_value` in :mod:`.probe`;
their public names are importable from here too.
"""

from __future__ import annotations

from collections.abc import Sequence

from .calculus import Calculus, Rewriter, from_entries, cross, time_derivative, time_integral, trig
from .probe import float_value
from ..base import deferred as _deferred

sp = _deferred.module("sympy", globals())

__all__ = ["Calculus", "Derivation", "Rewriter", "cross", "float_value", "general", "time_derivative", "time_integral",
           "trig"]


# -- the derivation -------------------------------------------------------------------------------


class _Affine:
    """``w = Σ_j J[j] q̇_j + b`` (``J``: index → expression, nonzero entries only)."""

    __slots__ = ("w", "J", "b", "h", "curl")

    def __init__(self, w, J: dict, b):
        self.w, self.J, self.b = w, J, b
        self.h = None  # terms of J̇ q̇ + ḃ
        self.curl = None  # i → g_i


class Derivation:
    """``M`` and ``f`` (and, on request, ``p``) from the energy terms on plain symbols ``q``, ``v``, ``t``."""

    def __init__(self, q: Sequence[sp.Symbol], v: Sequence[sp.Symbol], t: sp.Symbol):
        self.q, self.v, self.t = list(q), list(v), t
        self.n = len(self.q)
        self.qidx = {s: i for i, s in enumerate(self.q)}
        self.vidx = {s: i for i, s in enumerate(self.v)}
        self.vset = frozenset(self.v)
        self.calc = Calculus([*self.q, *self.v, t])
        self._term_memo: dict = {}
        self._affine_memo: dict = {}
        self._canon_memo: dict = {}
        self._rate_memo: dict = {}
        self._frame_curls: dict = {}  # w → {i: g_i}, components of moving frames' vectors (:meth:`frames`)

    # ---- splitting T --------------------------------------------------------------------------
    def _vdep(self, e) -> bool:
        return not self.vset.isdisjoint(self.calc.deps(e))

    def split(self, T) -> tuple[list, list]:
        """``T`` as ``Σ c · w_a · w_b`` (``(c, a, b)`` with affine ``a``, ``b``) plus the terms of other forms."""
        products: list = []
        rest: list = []
        stack = [(T, ())]
        while stack:
            expr, factors = stack.pop()
            if expr == 0:
                continue
            if not self._vdep(expr):
                rest.append((factors, expr))
                continue
            if expr.is_Add:
                stack.extend((a, factors) for a in expr.args)
                continue
            args = expr.args if expr.is_Mul else (expr,)
            free, lin = [], []
            for a in args:
                if not self._vdep(a):
                    free.append(a)
                elif a.is_Pow and a.args[1] == 2:
                    lin += [a.args[0], a.args[0]]
                else:
                    lin.append(a)
            if len(lin) == 1 and lin[0].is_Add:
                stack.extend((a, factors + tuple(free)) for a in lin[0].args)
                continue
            if len(lin) == 2 and lin[0] == lin[1]:
                # (x q̇)² arrives expanded as x² q̇²: put x back into w, as in the other addends' w
                roots = [a.args[0] for a in free if a.is_Pow and a.args[1] == 2 and not a.args[0].is_number]
                if roots:
                    free = [a for a in free if not (a.is_Pow and a.args[1] == 2 and not a.args[0].is_number)]
                    w = sp.Mul(*roots, lin[0])
                    lin = [w, w]
            if len(lin) == 2:
                wa, wb = self.affine(lin[0]), self.affine(lin[1])
                if wa is not None and wb is not None:
                    products.append((sp.Mul(*factors, *free), wa, wb))
                    continue
            rest.append((factors, expr))
        return products, [sp.Mul(*f, e) for f, e in rest]

    def _terms(self, term) -> list | None:
        """``term`` (one addend) as ``[(j or None, coefficient)]``: ``Σ coefficient · q̇_j`` (+ the ``None`` part)."""
        out = self._term_memo.get(term, False)
        if out is not False:
            return out
        if not self._vdep(term):
            out = [(None, term)]
        elif term in self.vidx:
            out = [(self.vidx[term], sp.S.One)]
        elif term.is_Mul:
            dep = [k for k, a in enumerate(term.args) if self._vdep(a)]
            out = None
            if len(dep) == 1:
                k = dep[0]
                a = term.args[k]
                others = term.args[:k] + term.args[k + 1 :]
                if a in self.vidx:
                    out = [(self.vidx[a], sp.Mul(*others))]
                elif a.is_Add:
                    inner = self.affine(a)
                    if inner is not None:
                        out = [(j, sp.Mul(*others, c)) for j, c in inner.J.items()]
                        if inner.b != 0:
                            out.append((None, sp.Mul(*others, inner.b)))
        else:
            out = None
        self._term_memo[term] = out
        return out

    def affine(self, w) -> _Affine | None:
        """``w`` as an affine form in the velocities with velocity-free coefficients, or None."""
        out = self._affine_memo.get(w, False)
        if out is not False:
            return out
        coefs: dict = {}
        rest = []
        out = None
        for term in w.args if w.is_Add else (w,):
            parts = self._terms(term)
            if parts is None:
                break
            for j, c in parts:
                if j is None:
                    rest.append(c)
                else:
                    coefs.setdefault(j, []).append(c)
        else:
            J = {j: (cs[0] if len(cs) == 1 else sp.Add(*cs)) for j, cs in coefs.items()}
            out = _Affine(w, {j: c for j, c in J.items() if c != 0}, sp.Add(*rest))
        self._affine_memo[w] = out
        return out

    # ---- pieces of f ----------------------------------------------------------------------------
    def _canon(self, x) -> tuple[bool, sp.Expr]:
        """``(negated, y)`` with ``x = ±y`` and ``y`` of SymPy's canonical sign, so that ``x`` and ``-x`` share a key."""
        out = self._canon_memo.get(x)
        if out is None:
            out = (True, -x) if x.could_extract_minus_sign() else (False, x)
            self._canon_memo[x] = out
        return out

    def _h(self, A: _Affine) -> list:
        """``J̇ q̇ + ḃ`` as a list of ``(negated, term)``: the rate of ``w`` at ``q̈ = 0`` (:meth:`rate`)."""
        if A.h is None:
            h = self.rate(A.w)
            A.h = [self._canon(term) for term in (h.args if h.is_Add else (h,) if h != 0 else ())]
        return A.h

    def rate(self, e):
        """``Σ_k ∂e/∂q_k q̇_k + ∂e/∂t`` (``d e/dt`` at ``q̈ = 0``) in one memoized pass over ``e``'s tree.

        One pass, not a partial derivative per coordinate: the velocity of a body deep in a spatial chain is nested
        through every joint above it, and each shared sub-expression is differentiated once."""
        memo = self._rate_memo
        out = memo.get(e)
        if out is not None:
            return out
        deps = self.calc.deps(e)
        if not deps or deps <= self.vset:
            out = sp.S.Zero
        elif e in self.qidx:
            out = self.v[self.qidx[e]]
        elif e == self.t:
            out = sp.S.One
        elif e.is_Add:
            out = sp.Add(*[self.rate(a) for a in e.args])
        elif e.is_Mul:
            args = e.args
            terms = []
            for k, a in enumerate(args):
                da = self.rate(a)
                if da != 0:
                    terms.append(sp.Mul(*args[:k], da, *args[k + 1 :]))
            out = sp.Add(*terms)
        elif e.is_Pow and not self.calc.deps(e.args[1]):
            base, exp = e.args
            db = self.rate(base)
            out = sp.S.Zero if db == 0 else (sp.Mul(sp.S(2), base, db) if exp == 2 else sp.Mul(exp, sp.Pow(base, exp - 1), db))
        elif isinstance(e, sp.sin):
            out = sp.Mul(trig(sp.cos, e.args[0]), self.rate(e.args[0]))
        elif isinstance(e, sp.cos):
            out = sp.Mul(-sp.S.One, trig(sp.sin, e.args[0]), self.rate(e.args[0]))
        else:
            calc = self.calc
            out = sp.Add(*[sp.Mul(calc.diff(e, s), self.v[self.qidx[s]]) for s in deps if s in self.qidx],
                         calc.diff(e, self.t))
        memo[e] = out
        return out

    def _curl(self, A: _Affine) -> dict:
        """``g_i = Σ_j (∂J_i/∂q_j − ∂J_j/∂q_i) q̇_j + ∂J_i/∂t − ∂b/∂q_i`` for every ``i`` where it is not zero."""
        if A.curl is not None:
            return A.curl
        known = self._frame_curls.get(A.w)
        if known is None and self._frame_curls:
            known = self._frame_curls.get(-A.w)
            if known is not None:
                known = {i: -g for i, g in known.items()}
        if known is not None:
            A.curl = known
            return known
        calc, q, v, t = self.calc, self.q, self.v, self.t
        qdeps = {j: [self.qidx[s] for s in calc.deps(c) if s in self.qidx] for j, c in A.J.items()}
        rows = set(A.J)
        for j, ks in qdeps.items():
            rows.update(ks)
        bdeps = [self.qidx[s] for s in calc.deps(A.b) if s in self.qidx]
        rows.update(bdeps)
        curl = {}
        for i in sorted(rows):
            terms = []
            Ji = A.J.get(i)
            seen = set()
            if Ji is not None:
                for j in qdeps[i]:
                    seen.add(j)
                    d1 = calc.diff(Ji, q[j])
                    d2 = calc.diff(A.J[j], q[i]) if j in A.J else sp.S.Zero
                    if d1 is d2 or d1 == d2:
                        continue
                    terms.append(sp.Mul(sp.Add(d1, -d2), v[j]))
                if t in calc.deps(Ji):
                    terms.append(calc.diff(Ji, t))
            for j, ks in qdeps.items():
                if j not in seen and i in ks:
                    d2 = calc.diff(A.J[j], q[i])
                    if d2 != 0:
                        terms.append(sp.Mul(-sp.S.One, d2, v[j]))
            if i in bdeps:
                terms.append(-calc.diff(A.b, q[i]))
            g = sp.Add(*terms)
            if g != 0:
                curl[i] = g
        A.curl = curl
        return curl

    # ---- assembling M and f ---------------------------------------------------------------------
    def frames(self, frames: Sequence) -> None:
        """Register moving frames: ``(ω, [v, ...])``, 3-vectors in the frame's axes (:class:`~lagrangian.MovingFrame`).

        The curl terms ``g_i`` of their components are then written in closed form.  With ``R`` the frame's
        rotation, ``ω`` its angular velocity ``Rᵀ Ṙ`` and ``Ω_i = ∂ω/∂q̇_i``, the structure equation
        ``∂Ω_i/∂q_j − ∂Ω_j/∂q_i = Ω_i × Ω_j`` gives ``g_i = Ω_i × ω``; for a velocity ``v = Rᵀ ṗ`` with
        ``V_i = ∂v/∂q̇_i``, ``g_i = V_i × ω + Ω_i × v`` (``t`` counted as a coordinate of rate 1, so rheonomic
        frames are covered).  A vector whose components are not affine in the velocities is left to the general
        formula."""
        for omega, velocities in frames:
            Om = [self.affine(e) for e in omega]
            if any(a is None for a in Om):
                continue
            self._frame_curl_add(omega, Om, omega, Om, None)
            for vel in velocities:
                Vs = [self.affine(e) for e in vel]
                if all(a is not None for a in Vs):
                    self._frame_curl_add(vel, Vs, omega, Om, True)

    def _frame_curl_add(self, vec, A3, omega, Om, velocity) -> None:
        cols = sorted(set().union(*(a.J for a in A3), *(a.J for a in Om)))

        def col(As, i):
            return [a.J.get(i, sp.S.Zero) for a in As]

        curls: list[dict] = [dict(), dict(), dict()]
        for i in cols:
            Vi, Oi = col(A3, i), col(Om, i)
            g = cross(Oi, omega) if velocity is None else [sp.Add(a, b) for a, b in zip(cross(Vi, omega), cross(Oi, vec))]
            for k in range(3):
                if g[k] != 0:
                    curls[k][i] = g[k]
        for k in range(3):
            w = vec[k]
            if w != 0 and w not in self._frame_curls:
                self._frame_curls[w] = curls[k]

    def equations(self, T, V, G, D, Q: Sequence, frames: Sequence = ()) -> tuple[list[list], list]:
        """``(M, f)``: the mass matrix (a SymPy matrix, built from its nonzero entries: a chain of 10⁴ masses has 10⁴ of
        them, not 10⁸) and the forcing as a list; ``frames``: see :meth:`frames`."""
        n, calc, q, v, t = self.n, self.calc, self.q, self.v, self.t
        self.frames(frames)
        products, rest = self.split(T)
        self.products, self.rest = products, rest
        Mbuckets: dict[tuple[int, int], dict] = {}  # (i, j), i <= j: (J_i, J_j) → [coef]
        fbuckets: list[dict] = [dict() for _ in range(n)]  # i: J_i → {term: [coef]}
        fextra: list[list] = [[] for _ in range(n)]

        canon = self._canon

        def add_M(i, j, x, y, c):
            if i > j:
                i, j, x, y = j, i, y, x
            (nx, x), (ny, y) = canon(x), canon(y)
            Mbuckets.setdefault((i, j), {}).setdefault((x, y), []).append(-c if nx != ny else c)

        def add_f(i, x, terms, c):
            nx, x = canon(x)
            bucket = fbuckets[i].setdefault(x, {})
            minus_c = None
            for neg, term in terms:
                if neg != nx:
                    if minus_c is None:
                        minus_c = -c
                    bucket.setdefault(term, []).append(minus_c)
                else:
                    bucket.setdefault(term, []).append(c)

        for c, A, B in products:
            square = A is B
            cM = sp.Mul(sp.S(2), c) if square else c
            if square:
                items = list(A.J.items())
                for k, (i, x) in enumerate(items):
                    for j, y in items[k:]:
                        add_M(i, j, x, y, cM)
                hA = self._h(A)
                for i, x in items:
                    add_f(i, x, hA, cM)
            else:
                c2 = sp.Mul(sp.S(2), c)
                for i, x in A.J.items():
                    for j, y in B.J.items():
                        add_M(i, j, x, y, c2 if i == j else c)  # M_ij = c (J_ai J_bj + J_aj J_bi)
                hA, hB = self._h(A), self._h(B)
                for i, x in A.J.items():
                    add_f(i, x, hB, c)
                for i, y in B.J.items():
                    add_f(i, y, hA, c)
            # a coefficient that depends on q or t, and the curl terms
            cdeps = calc.deps(c)
            if cdeps:
                cdot = sp.Add(*[sp.Mul(calc.diff(c, s), v[self.qidx[s]]) for s in cdeps if s in self.qidx],
                              calc.diff(c, t))
                if cdot != 0:
                    for i, x in A.J.items():
                        fextra[i].append(sp.Mul(-sp.S.One, cdot, x, B.w))
                    for i, y in B.J.items():
                        fextra[i].append(sp.Mul(-sp.S.One, cdot, y, A.w))
                for s in cdeps:
                    if s in self.qidx:
                        fextra[self.qidx[s]].append(sp.Mul(calc.diff(c, s), A.w, B.w))
            for i, g in self._curl(A).items():
                fextra[i].append(sp.Mul(-sp.S.One, c, g, B.w))
            for i, g in self._curl(B).items():
                fextra[i].append(sp.Mul(-sp.S.One, c, g, A.w))
        M: dict[tuple[int, int], sp.Expr] = {}
        for (i, j), bucket in sorted(Mbuckets.items()):
            M[i, j] = M[j, i] = _collect([(sp.Mul(x, y), cs) for (x, y), cs in bucket.items()], pythagoras=i == j)
        f = [sp.S.Zero] * n
        for i in range(n):
            parts = []
            for x, terms in fbuckets[i].items():
                inner = _collect(list(terms.items()))
                if inner != 0:
                    parts.append(sp.Mul(-sp.S.One, x, inner))
            f[i] = parts + fextra[i]
        # the general formulas for everything else
        Lrest_T = sp.Add(*rest, G)
        pr = {}
        for s in calc.deps(Lrest_T):
            if s in self.vidx:
                pr[self.vidx[s]] = calc.diff(Lrest_T, s)
        for i, p in pr.items():
            for s in calc.deps(p):
                if s in self.vidx:
                    j = self.vidx[s]
                    d = calc.diff(p, s)
                    if d != 0:
                        M[i, j] = sp.Add(M.get((i, j), sp.S.Zero), d)
        for i, part in self.gradient(V).items():
            f[i].append(sp.Mul(-sp.S.One, part))
        for s in calc.deps(Lrest_T):
            if s in self.qidx:
                f[self.qidx[s]].append(calc.diff(Lrest_T, s))
        for i, p in pr.items():
            for s in calc.deps(p):
                if s in self.qidx:
                    f[i].append(sp.Mul(-sp.S.One, calc.diff(p, s), v[self.qidx[s]]))
                elif s == t:
                    f[i].append(-calc.diff(p, t))
        for s in calc.deps(D):
            if s in self.vidx:
                f[self.vidx[s]].append(-calc.diff(D, s))
        for i in range(n):
            if Q[i] != 0:
                f[i].append(Q[i])
        self._rest_momenta = pr
        return from_entries(n, n, {k: e for k, e in M.items() if e != 0}), [sp.Add(*terms) for terms in f]

    def gradient(self, E) -> dict:
        """``{i: ∂E/∂q_i}`` for a velocity-free ``E``, with ``E`` first distributed over its sums into
        ``Σ_τ τ · (Σ coefficients)`` (``τ``: the parts that depend on ``q`` and ``t``), so that a term shared by
        many addends (``l_k sin q_k`` in the height of every mass beyond link ``k``) is differentiated once."""
        calc = self.calc
        terms: dict = {}
        stack = [(E, ())]
        while stack:
            e, factors = stack.pop()
            if not calc.deps(e):
                continue
            if e.is_Add:
                stack.extend((a, factors) for a in e.args)
                continue
            if e.is_Mul:
                free = [a for a in e.args if not calc.deps(a)]
                dep = [a for a in e.args if calc.deps(a)]
                if len(dep) == 1 and dep[0].is_Add:
                    stack.extend((a, factors + tuple(free)) for a in dep[0].args)
                    continue
                if free:
                    e, factors = sp.Mul(*dep), factors + tuple(free)
            terms.setdefault(e, []).append(factors)
        grad: list[dict] = [dict() for _ in range(self.n)]
        for term, coefs in terms.items():
            total = None
            for s in calc.deps(term):
                i = self.qidx.get(s)
                if i is None:
                    continue
                d = calc.diff(term, s)
                if d != 0:
                    if total is None:
                        total = _coef_sum(coefs)
                    grad[i].setdefault(total, []).append(d)
        return {i: _collect_sums(g) for i, g in enumerate(grad) if g}

    def momenta(self) -> list:
        """``p = ∂L/∂q̇`` (after :meth:`equations`)."""
        n = self.n
        p = [[] for _ in range(n)]
        for c, A, B in self.products:
            for i, x in A.J.items():
                p[i].append(sp.Mul(c, x, B.w))
            for i, y in B.J.items():
                p[i].append(sp.Mul(c, y, A.w))
        for i, pi in self._rest_momenta.items():
            p[i].append(pi)
        return [sp.Add(*terms) for terms in p]


def _coef_sum(coefs: list) -> sp.Expr:
    """``Σ_k Π coefs[k]`` (each a tuple of factors), with the factors common to every addend taken out."""
    split = []
    for c in coefs:
        num, sym = sp.S.One, []
        for x in c:
            if x.is_Number:
                num *= x
            else:
                sym.append(x)
        split.append((num, sym))
    if len(split) == 1:
        return sp.Mul(split[0][0], *split[0][1])
    common = set(split[0][1])
    for _, sym in split[1:]:
        common.intersection_update(sym)
        if not common:
            break
    nums = {num for num, _ in split}
    cnum = nums.pop() if len(nums) == 1 else sp.S.One
    rest = []
    for num, sym in split:
        for x in common:
            sym.remove(x)
        rest.append(sp.Mul(num / cnum, *sym))
    return sp.Mul(cnum, *common, sp.Add(*rest))


def _collect_sums(by_sum: dict) -> sp.Expr:
    """``Σ_S S · Σ terms`` from ``{S: [terms]}``, with ``S`` and ``−S`` merged and written ``S · (...)`` or ``−S · (...)``."""
    groups: dict = {}
    for s, terms in by_sum.items():
        if s == 0:
            continue
        if s.could_extract_minus_sign():
            groups.setdefault(-s, ([], []))[1].extend(terms)
        else:
            groups.setdefault(s, ([], []))[0].extend(terms)
    out = []
    for s, (pos, neg) in groups.items():
        if not neg:
            out.append(sp.Mul(s, pos[0] if len(pos) == 1 else sp.Add(*pos)))
        elif not pos:
            out.append(sp.Mul(-sp.S.One, s, neg[0] if len(neg) == 1 else sp.Add(*neg)))
        else:
            out.append(sp.Mul(s, sp.Add(*pos, *[-t for t in neg])))
    return sp.Add(*out)


def _collect(items: list, pythagoras: bool = False) -> sp.Expr:
    """``Σ term · Σ coefs`` with the terms of equal coefficient sums gathered: ``Σ_S S · Σ terms`` (and, with
    ``pythagoras``, ``r sin²u + r cos²u`` replaced by ``r`` in each ``Σ terms``)."""
    by_sum: dict = {}
    for term, coefs in items:
        s = coefs[0] if len(coefs) == 1 else sp.Add(*coefs)
        if s != 0:
            by_sum.setdefault(s, []).append(term)
    if pythagoras:
        by_sum = {s: _pythagoras(terms) for s, terms in by_sum.items()}
    return _collect_sums(by_sum)


def _pythagoras(terms: list) -> list:
    """``terms`` with each pair ``r·sin(u)²``, ``r·cos(u)²`` replaced by ``r``."""
    found: dict = {}
    for k, term in enumerate(terms):
        args = term.args if term.is_Mul else (term,)
        for a in args:
            if a.is_Pow and a.args[1] == 2 and isinstance(a.args[0], (sp.sin, sp.cos)):
                rest = tuple(x for x in args if x is not a)
                found.setdefault((a.args[0].args[0], rest), {})[a.args[0].func] = k
                break
    merged, drop = [], set()
    for (u, rest), where in found.items():
        if len(where) == 2:
            drop.update(where.values())
            merged.append(sp.Mul(*rest))
    if not merged:
        return terms
    return [term for k, term in enumerate(terms) if k not in drop] + merged


def general(T, V, G, D, Q: Sequence, q: Sequence, v: Sequence, t: sp.Symbol) -> tuple[sp.Matrix, sp.Matrix]:
    """``(M, f)`` by the textbook formulas with SymPy's ``diff`` on the whole Lagrangian and no structure: the
    reference :class:`Derivation` is checked against (slow for large models)."""
    L = T - V + G
    n = len(q)
    p = [sp.diff(L, vi) for vi in v]
    M = sp.Matrix(n, n, lambda i, j: sp.diff(p[i], v[j]))
    f = sp.Matrix([
        sp.diff(L, q[i]) - sum((sp.diff(p[i], q[j]) * v[j] for j in range(n)), sp.Integer(0))
        - sp.diff(p[i], t) - sp.diff(D, v[i]) + Q[i]
        for i in range(n)
    ])
    return M, f
