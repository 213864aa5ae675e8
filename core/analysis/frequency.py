"""The frequency domain: transfer functions, impedances, frequency response and normal modes.

Everything here works on the linearization of a model about an operating
point (:func:`linearize`, in :mod:`lagrangian.analysis.linearize`), in
Laplace form: ``H(s) = (Σ Cq_k s^k) X(s) + Σ D_k s^k`` with ``X`` solving
``[[M s² + C s + K, −Φ_qᵀ], [Φ_q, 0]] X = [Σ B_k s^k; 0]``.  Loop
constraints stay exact, inputs may enter through their derivatives (a
prescribed motion through a damper), and nothing is inverted that need not
be.

- :func:`transfer_function`: ``H(s)`` between one input and one output, as a
  SymPy rational function (exact in the parameters' symbols for a symbolic
  model), with its poles, zeros and DC gain;
- :func:`impedance`: the driving-point impedance seen by a source;
- :func:`frequency_response`: ``H(j 2π f)`` for every input and output on a
  frequency grid (:func:`decades` makes SPICE's ``.ac dec`` grid), with Bode
  and Nyquist charts;
- :func:`modes`: natural frequencies, damping ratios and mode shapes;
- :func:`speed_sweep`: the eigenvalues of a steady motion against its speed,
  and the speeds where a mode changes stability.

A series RLC driven by a voltage source: its current over the source
voltage is ``s C / (L C s² + R C s + 1)``.

>>> import sympy as sp
>>> import lagrangian as lg
>>> from lagrangian.frequency import transfer_function, modes
>>> m = lg.Model("rlc")
>>> _ = m.add("voltage_source", "V1", ("in", "0"), E=0)
>>> _ = m.add("resistor", "R1", ("in", "a"), R=sp.Symbol("R", positive=True))
>>> _ = m.add("inductor", "L1", ("a", "b"), L=sp.Symbol("L", positive=True))
>>> _ = m.add("capacitor", "C1", ("b", "0"), C=sp.Symbol("C", positive=True))
>>> H = transfer_function(m, "V1", "i(L1)")
>>> H.expr
C*s/(C*L*s**2 + C*R*s + 1)
>>> m2 = lg.Model("lc")
>>> _ = m2.add("inductor", "L1", ("a", "0"), L=7e-3)
>>> _ = m2.add("capacitor", "C1", ("a", "0"), C=2.2e-6)
>>> round(float(modes(m2).frequencies[0]), 3)     # 1 / (2π √(LC)) Hz
1282.507
"""

from __future__ import annotations

import decimal
import math
import numbers
from collections.abc import Iterator, Mapping, Sequence, Set
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..base import charts
from ..base.latex import _latex_escape, to_latex
from ..base.limits import refuse
from ..errors import ModelError, UnknownNameError
from ..model import Model
from . import control as _control
from .linearize import LinearModel, linearize
from .closed_form import cancel_pairs, closed_roots, inverse_laplace, polynomial_roots, sorted_roots
from .interactive import interact
from .laplace import FLOOR, _respond, _solve
from .locus import RootLocus, pole_zero_map, root_locus
from .modes import Modes, _descriptor, _eigenvalues, _linear, _numeric, _scale, modes
from .parametric import ParametricResponse
from .speeds import SpeedSweep, speed_sweep
from ..base import deferred as _deferred

sp = _deferred.module("sympy", globals())
_s = _deferred.symbol("s")  # the Laplace variable (lagrangian.linearize.s)

__all__ = ["FrequencyResponse", "Modes", "RootLocus", "SpeedSweep", "TransferFunction", "decades",
           "frequency_response", "impedance", "interact", "linearize", "modes", "pole_zero_map", "root_locus", "s",
           "speed_sweep", "sweep", "transfer_function"]

#: Largest number of unknowns for which a transfer function is solved in exact arithmetic with SymPy.
SYMBOLIC_MAX = 8

#: A response's note says where values have fewer than six certain digits: an error bound above this share of them.
DIGITS = 1e-6


def decades(start: float, stop: float, points: int = 20) -> np.ndarray:
    """Frequencies from ``start`` to ``stop`` (Hz), ``points`` per decade, as ngspice's ``.ac dec`` makes them
    (:func:`sweep`).

    >>> decades(1, 100, 2).round(3).tolist()
    [1.0, 3.162, 10.0, 31.623, 100.0]
    """
    return sweep("dec", points, start, stop)


def sweep(kind: str, points: int, start: float, stop: float) -> np.ndarray:
    """The frequencies of ngspice's ``.ac kind points start stop`` (its ``acan.c``): for ``"dec"``,
    ``floor(points × decades)`` equal ratios from ``start`` to ``stop``, both included; for ``"oct"``, the ratio
    ``2^(1/points)`` from ``start`` while not past ``stop``; for ``"lin"``, ``points`` equally spaced.

    A grid of more than :data:`lagrangian.limits.grid_points <lagrangian.limits>` frequencies is refused before it
    is made (:func:`sweep_size`).

    >>> sweep("dec", 7, 3, 20e3)[:3].round(4).tolist()    # 26 steps of (20000/3)^(1/26)
    [3.0, 4.2092, 5.9057]
    >>> sweep("lin", 3, 10, 30).tolist()
    [10.0, 20.0, 30.0]
    """
    size = sweep_size(kind, points, start, stop)
    whole, start, stop = _count(points, f"a {kind} sweep"), float(start), float(stop)
    if kind == "lin":
        return np.linspace(start, stop, size)
    if kind == "oct":  # a ratio of 2^(1/points) from start, up to stop
        return start * 2.0 ** (np.arange(size) / whole)
    if size == 1:
        return np.array([start])
    return start * np.exp(math.log(stop / start) * np.arange(size) / (size - 1))


def sweep_size(kind: str, points: Any, start: Any, stop: Any, what: str | None = None) -> int:
    """How many frequencies :func:`sweep` gives for these arguments, which are checked as it checks them; a grid of
    more than :data:`lagrangian.limits.grid_points <lagrangian.limits>` is refused (``what`` names the request in
    the message; by default the sweep).

    >>> sweep_size("dec", 10, 1, 1e6), sweep_size("oct", 2, 1, 8), sweep_size("lin", 5, 1, 2)
    (61, 7, 5)
    """
    if kind not in ("dec", "oct", "lin"):
        raise ModelError(f"a sweep is 'dec', 'oct' or 'lin', not {kind!r}.")
    per = {"dec": " per decade", "oct": " per octave", "lin": ""}[kind]
    what = what or f"a {kind} sweep of {points!r:.30} points{per} from {start!r:.30} to {stop!r:.30} Hz"
    whole = _count(points, what)
    ends = []
    for end in (start, stop):
        if isinstance(end, (bool, np.bool_, str, bytes)) or not isinstance(end, numbers.Real):
            raise ModelError(f"{what}: the start and stop frequencies are numbers of Hz, got {end!r:.40} of type "
                             f"{type(end).__name__}.")
        try:
            ends.append(float(end))
        except OverflowError:  # an int beyond a float
            ends.append(math.inf)
    start, stop = ends
    if not (0 < start <= stop < math.inf) or (kind != "lin" and start == stop):
        raise ModelError(f"{what}: a {kind} sweep needs 0 < start {'≤' if kind == 'lin' else '<'} stop, both finite, "
                         f"got start={start!r}, stop={stop!r}.")
    if kind == "lin":
        refuse(what, whole, "grid_points")
        return whole
    steps = whole * math.log(stop / start) / math.log(10.0 if kind == "dec" else 2.0) + 1e-9  # inf for 10**400
    refuse(what, math.floor(steps) + 1 if math.isfinite(steps) else steps, "grid_points")
    return max(int(math.floor(steps)), 0) + 1


def _count(points: Any, what: str) -> int:
    """``points`` as a whole number ≥ 1 (an int, or a float with a whole value: ``1e3``); bools, text, fractions,
    nan and infinities are refused, naming ``what``."""
    whole = None
    if isinstance(points, numbers.Integral) and not isinstance(points, (bool, np.bool_)):
        whole = int(points)
    elif isinstance(points, numbers.Real) and not isinstance(points, (bool, np.bool_)):
        value = float(points)
        whole = int(value) if math.isfinite(value) and value == int(value) else None
    if whole is None or whole < 1:
        raise ModelError(f"{what}: the number of points must be a whole number ≥ 1, got {points!r:.40} of type "
                         f"{type(points).__name__} (e.g. 20).")
    return whole


# ---------------------------------------------------------------------------
# Transfer functions
# ---------------------------------------------------------------------------


@dataclass
class TransferFunction:
    """``H(s)`` from one input to one output of a linearized model (``inverse``: ``1/H``, for impedances).

    Call it with ``s`` values (complex) for numbers; :attr:`expr` is the
    rational function, :meth:`poles`, :meth:`zeros` and :attr:`dc_gain`
    describe it.
    """

    linear: LinearModel
    input: str
    output: str
    inverse: bool = False
    _expr: Any = field(default=None, repr=False)

    def __repr__(self) -> str:
        what = f"1 / ({self.output} / {self.input})" if self.inverse else f"{self.output} / {self.input}"
        return f"<TransferFunction {what} of {self.linear.model!r}>"

    def _repr_latex_(self) -> str:
        """``H(s)`` as the notebook shows it: its output over its input, then its rational function (names escaped
        for LaTeX).

        >>> import lagrangian as lg
        >>> m = lg.Model("rc")
        >>> _ = m.add("voltage_source", "V1", ("in", "0"), E=0)
        >>> _ = m.add("resistor", "R1", ("in", "a"), R=2)
        >>> _ = m.add("capacitor", "C1", ("a", "0"), C=0.5)
        >>> print(transfer_function(m, "V1", "v(C1)")._repr_latex_())
        $$\\frac{\\text{v(C1)}}{\\text{V1}}(s) = \\frac{1.0}{1.0 s + 1.0}$$
        """
        def text(label: str) -> str:
            return r"\text{" + _latex_escape(str(label)).replace("_", r"\_") + "}"

        num, den = (text(self.input), text(self.output)) if self.inverse else (text(self.output), text(self.input))
        return f"$$\\frac{{{num}}}{{{den}}}(s) = {to_latex(self.expr, dots=False)}$$"

    def _pick(self) -> LinearModel:
        lin = self.linear
        i, o = lin.inputs.index(self.input), lin.outputs.index(self.output)
        return LinearModel(**{**lin.__dict__, "inputs": [self.input], "outputs": [self.output],
                              "B": [b[:, i:i + 1] for b in lin.B], "Bi": lin.Bi[:, i:i + 1], "Di": lin.Di[o:o + 1, i:i + 1],
                              "Cq": [c[o:o + 1, :] for c in lin.Cq],
                              "D": [d[o:o + 1, i:i + 1] for d in lin.D]})

    def __call__(self, svals) -> np.ndarray | complex:
        scalar = np.ndim(svals) == 0
        sv = np.atleast_1d(np.asarray(svals, dtype=complex))
        H = _solve(self._pick(), sv)[:, 0, 0]
        if self.inverse:
            with np.errstate(divide="ignore", invalid="ignore"):
                H = 1 / H
        return complex(H[0]) if scalar else H

    @property
    def expr(self) -> sp.Expr:
        """``H(s)`` as a SymPy rational function of :data:`s`, in lowest terms.

        Solved in exact arithmetic (the parameters' symbols, or the binary
        values of their floating-point numbers as rationals, so factors that
        cancel cancel exactly) for at most :data:`SYMBOLIC_MAX` unknowns;
        with numbers its coefficients are then floats, the denominator
        monic.  A larger numeric model's comes from its poles, zeros and
        gain, with coinciding pole–zero pairs cancelled."""
        if self._expr is None:
            if self.linear.size <= SYMBOLIC_MAX or self.linear.symbolic:
                self._expr = self._exact()
            else:
                self._expr = self._from_roots()
        return self._expr

    def _exact(self) -> sp.Expr:
        lin = self._pick()
        if lin.size > SYMBOLIC_MAX:
            raise ModelError(f"model {lin.model!r}: a symbolic transfer function of {lin.size} unknowns is beyond "
                             f"{SYMBOLIC_MAX}; give the parameters values (params=) for a numeric one.")
        if not lin.symbolic:  # the floats' exact binary values: what cancels, cancels exactly
            lin = _rational(lin)
        P, rhs = lin.pencil(_s)
        X = sp.Matrix(P).LUsolve(sp.Matrix(rhs))
        Cq, D = lin.output_rows(_s)
        n = len(lin.coordinates)
        H = sp.cancel(sp.together((sp.Matrix(Cq) * X[:n, :] + sp.Matrix(D))[0, 0]))
        if self.inverse:
            H = sp.cancel(1 / H)
        if self.linear.symbolic:
            return sp.factor(H)
        num, den = sp.fraction(H)
        num, den = sp.Poly(num, _s), sp.Poly(den, _s)
        lead = den.LC()
        return (sp.Poly([sp.Float(c / lead) for c in num.all_coeffs()], _s).as_expr()
                / sp.Poly([sp.Float(c / lead) for c in den.all_coeffs()], _s).as_expr())

    def _from_roots(self) -> sp.Expr:
        z, p = self._roots()
        w0 = _scale(self.linear)
        probe = complex(0.173 * w0, 0.911 * w0)
        value = complex(self(probe))
        gain = value * np.prod([probe - x for x in p]) / np.prod([probe - x for x in z])
        if abs(gain.imag) <= 1e-8 * abs(gain):
            gain = gain.real
        num = np.real_if_close(np.poly(z) * gain, tol=1e6) if len(z) else np.array([gain])
        den = np.real_if_close(np.poly(p), tol=1e6) if len(p) else np.array([1.0])
        poly = (lambda c: sum(sp.Float(x) * _s ** (len(c) - 1 - i) if np.isreal(x) else sp.sympify(complex(x)) * _s ** (len(c) - 1 - i)
                              for i, x in enumerate(c)))
        return poly(np.atleast_1d(num)) / poly(np.atleast_1d(den))

    @property
    def gain(self) -> sp.Expr | float:
        """The gain ``k`` of ``H = k Π(s − zᵢ) / Π(s − pⱼ)``: the ratio of the leading coefficients of the numerator
        and the denominator (an expression of the parameters for a symbolic model).  Up to :data:`SYMBOLIC_MAX`
        unknowns, where :attr:`expr` is solved."""
        if self.linear.size > SYMBOLIC_MAX:
            raise ModelError(f"the gain of {self!r} is read off its rational function, solved up to {SYMBOLIC_MAX} "
                             f"unknowns (this model has {self.linear.size}): use dc_gain, or poles() and zeros().")
        num, den = sp.fraction(self.expr)
        k = sp.cancel(sp.Poly(num, _s).LC() / sp.Poly(den, _s).LC())
        return k if self.linear.symbolic else float(k) if k.is_real else complex(k)

    def poles(self) -> np.ndarray | list:
        """The finite poles of ``H`` (rad/s, complex), sorted by magnitude; for a model with symbolic parameters,
        their closed forms (a list of SymPy expressions, each repeated by its multiplicity), up to the quartic, and
        refused by name beyond (no formula in radicals in general).

        A mode that the input does not reach or the output does not see
        cancels against a zero and is not a pole of ``H`` (the drift of a
        loop charge, seen only through its rate).  Up to
        :data:`SYMBOLIC_MAX` unknowns they are the roots of the exact
        rational function's denominator; beyond, the generalized eigenvalues
        of the linearization's pencil, less those matched by an invariant
        zero.
        """
        return self._roots()[1]

    def zeros(self) -> np.ndarray | list:
        """The finite zeros of ``H`` (rad/s, complex), sorted by magnitude, as :meth:`poles`: the roots of the
        numerator, or the invariant zeros (where ``[[A − sE, B], [C, D]]`` loses rank) less those matched by a
        pole; closed forms for a symbolic model, as :meth:`poles`."""
        return self._roots()[0]

    def _roots(self) -> tuple[np.ndarray, np.ndarray] | tuple[list, list]:
        lin = self._pick()
        if lin.symbolic:  # closed forms, as a list of SymPy expressions (a root repeated by its multiplicity)
            num, den = sp.fraction(self.expr)
            return closed_roots(num, f"the zeros of {self!r}"), closed_roots(den, f"the poles of {self!r}")
        _numeric(lin, "poles and zeros")
        if lin.size <= SYMBOLIC_MAX:
            num, den = sp.fraction(self.expr)
            return sorted_roots(polynomial_roots(num)), sorted_roots(polynomial_roots(den))
        w0 = _scale(lin)
        z = _eigenvalues(_descriptor(lin, with_io=True), w0)
        p = _eigenvalues(_descriptor(lin, with_io=False), w0)
        z, p = cancel_pairs(z, p, w0)
        return (p, z) if self.inverse else (z, p)

    def step_response(self) -> sp.Expr:
        """The response to a unit step at ``t = 0`` from rest, in closed form: a SymPy expression of
        :data:`lagrangian.t` (the inverse Laplace transform of ``H(s)/s`` by partial fractions over the poles,
        :func:`lagrangian.analysis.closed_form.inverse_laplace`; symbols where the model has them).  Up to
        :data:`SYMBOLIC_MAX` unknowns, where :attr:`expr` is solved.

        >>> import lagrangian as lg
        >>> m = lg.Model("rc")
        >>> _ = m.add("voltage_source", "V1", ("in", "0"), E=0)
        >>> _ = m.add("resistor", "R1", ("in", "a"), R=2)
        >>> _ = m.add("capacitor", "C1", ("a", "0"), C=0.5)
        >>> transfer_function(m, "V1", "v(C1)").step_response()
        1.0 - 1.0*exp(-1.0*t)
        """
        return inverse_laplace(self._rational_expr("step_response") / _s, f"the step response of {self!r}")

    def impulse_response(self) -> sp.Expr:
        """The response to a unit impulse at ``t = 0`` from rest, in closed form (as :meth:`step_response`, of
        ``H(s)``; a ``DiracDelta`` where ``H`` does not vanish at high frequency)."""
        return inverse_laplace(self._rational_expr("impulse_response"), f"the impulse response of {self!r}")

    def _rational_expr(self, what: str) -> sp.Expr:
        if self.linear.size > SYMBOLIC_MAX:
            raise ModelError(f"{what} of {self!r} is read off its rational function, solved up to {SYMBOLIC_MAX} "
                             f"unknowns (this model has {self.linear.size}): simulate the model instead "
                             f"(method='exact' solves it exactly).")
        return self.expr

    @property
    def dc_gain(self) -> float | complex:
        """``H(0)``; ``inf`` where a pole sits at ``s = 0`` (a free mass, a capacitor with no path to ground)."""
        if self.linear.symbolic:
            return sp.limit(self.expr, _s, 0)
        if self.linear.size <= SYMBOLIC_MAX:
            num, den = sp.fraction(self.expr)
            n0, d0 = complex(num.subs(_s, 0)), complex(den.subs(_s, 0))
            if d0 == 0:  # an exact zero of the denominator (the coefficients are exact up to this point)
                return math.inf if n0 != 0 else float(sp.limit(self.expr, _s, 0))
            value = n0 / d0
            return value.real if abs(value.imag) <= 1e-12 * abs(value) else value
        with np.errstate(all="ignore"):
            if not (np.any(self._pick().Bi) or np.any(self._pick().Di)):
                value = complex(self(0.0))
            else:  # u/s terms: the limit s → 0, extrapolated from three points along the real axis
                eps = 1e-4 * _scale(self.linear)
                h1, h2, h4 = (complex(self(eps / k)) for k in (1, 2, 4))
                growing = abs(h4) > 3 * abs(h2) > 9 * abs(h1)  # like 1/s: a pole at s = 0
                value = complex("inf") if growing else (8 * h4 - 6 * h2 + h1) / 3
        if not np.isfinite(value):
            return math.inf
        return value.real if abs(value.imag) <= 1e-12 * abs(value) else value

    def to_control(self) -> Any:
        """``H(s)`` as a python-control transfer function (``pip install 'lagrangian[control]'``).

        Returns
        -------
        control.TransferFunction
            Numerator and denominator from :attr:`expr`, named by our input and output labels.  Beyond
            :data:`SYMBOLIC_MAX` unknowns those come from the poles and zeros, and a ratio of polynomials of high
            degree holds the response to fewer digits (about 1e-7 for a 20-section ladder, degree 40): the
            linearization's :meth:`~lagrangian.frequency.LinearModel.to_control` keeps it to 1e-12.

        Raises
        ------
        ModelError
            For a symbolic transfer function (naming its symbols), or without python-control.

        Examples
        --------
        >>> import lagrangian as lg
        >>> m = lg.Model("rl")
        >>> _ = m.add("voltage_source", "V1", ("in", "0"), E=0)
        >>> _ = m.add("resistor", "R1", ("in", "a"), R=10.0)
        >>> _ = m.add("inductor", "L1", ("a", "0"), L=7e-3)
        >>> sys = transfer_function(m, "V1", "i(L1)").to_control()    # 1 / (L s + R)
        >>> sys.poles().real.round(6).tolist(), round(float(sys.dcgain()), 12)
        ([-1428.571429], 0.1)
        """
        return _control.transfer_function(self)


def transfer_function(system: Model | LinearModel, input: str, output: Any, **kwargs: Any) -> TransferFunction:
    """``H(s)`` from ``input`` (a source or load component) to ``output`` (a coordinate, ``"v(C1)"``, ...).

    ``kwargs`` go to :func:`linearize` (``at``, ``params``, ``time``, ``symbolic``).
    """
    lin = _linear(system, [input], [output], kwargs)
    return TransferFunction(lin, lin.inputs[0] if isinstance(system, Model) else input,
                            lin.outputs[0] if isinstance(system, Model) else str(output))


def impedance(system: Model, source: str, **kwargs: Any) -> TransferFunction:
    """The driving-point impedance ``Z(s)`` the circuit presents to ``source``.

    For a voltage source it is ``E / i`` with ``i`` the current the source
    delivers (out of its ``a`` terminal into the circuit); for a current
    source, the voltage across the circuit between the nodes it drives
    over its current.  Mechanical impedance is the same with a force as
    the source and the driven point's velocity as the output.
    """
    comp = system.component(source)
    if comp.kind == "voltage_source":
        lin = linearize(system, inputs=[source], outputs=[f"i({source})"], **kwargs)
        lin = _negated(lin)
        return TransferFunction(lin, lin.inputs[0], lin.outputs[0], inverse=True)
    if comp.kind == "current_source":
        lin = _negated(linearize(system, inputs=[source], outputs=[f"v({source})"], **kwargs))
        return TransferFunction(lin, lin.inputs[0], lin.outputs[0])
    if comp.kind == "force":
        node = comp.nodes[0]
        velocity = [nm for nm in system.coordinate_names if nm == f"x_{node}"]
        if not velocity:
            raise ModelError(f"force {source!r}: its node {node!r} has no coordinate of its own; give the output "
                             f"with transfer_function(model, {source!r}, <velocity>).")
        lin = linearize(system, inputs=[source], outputs=[f"x_{node}'"], **kwargs)
        return TransferFunction(lin, lin.inputs[0], lin.outputs[0], inverse=True)
    raise ModelError(f"impedance takes a voltage source, a current source or a force; {source!r} is a {comp.kind}.")


def _rational(lin: LinearModel) -> LinearModel:
    """``lin`` with every matrix in exact rationals (each float's own binary value)."""
    def exact(a):
        return sp.Matrix(a.shape[0], a.shape[1], [sp.Rational(float(x)) for x in np.ravel(a)])

    return LinearModel(**{**lin.__dict__, "symbolic": True, "M": exact(lin.M), "C": exact(lin.C), "K": exact(lin.K),
                          "Phi": exact(lin.Phi), "Phi_v": None if lin.Phi_v is None else exact(lin.Phi_v), "B": [exact(b) for b in lin.B], "Bi": exact(lin.Bi),
                          "Cq": [exact(c) for c in lin.Cq], "D": [exact(d) for d in lin.D], "Di": exact(lin.Di)})


def _negated(lin: LinearModel) -> LinearModel:
    return LinearModel(**{**lin.__dict__, "Cq": [-c for c in lin.Cq], "D": [-d for d in lin.D], "Di": -lin.Di})


# ---------------------------------------------------------------------------
# Frequency response
# ---------------------------------------------------------------------------


@dataclass
class FrequencyResponse:
    """``H(j 2π f)`` of every output to every input (``H[output, input]`` over :attr:`frequencies`, Hz)."""

    model: str
    frequencies: np.ndarray
    inputs: list[str]
    outputs: list[str]
    H: np.ndarray  # outputs × inputs × frequencies
    notes: list[str] = field(default_factory=list)
    #: units of the inputs and outputs by label (``""`` where unknown)
    units: dict[str, str] = field(default_factory=dict)
    #: ``∂H/∂p`` by parameter name (outputs × inputs × frequencies), when asked for (``sensitivities=``)
    sensitivities: dict[str, np.ndarray] = field(default_factory=dict)
    #: the first-order bound of each value's rounding error (outputs × inputs × frequencies): what rounding the
    #: entries of ``M``, ``C``, ``K`` and the solve can do (:func:`lagrangian.analysis.laplace._respond`).  A value
    #: whose bound is at least its size is refused (``nan``, and a note says so); ``None`` where not computed
    error: np.ndarray | None = None

    def sensitivity(self, wrt: str, output: Any = None, input: str | None = None) -> np.ndarray:
        """``∂H[output, input]/∂wrt`` over the frequencies (the only output and input when not named)."""
        if wrt not in self.sensitivities:
            raise UnknownNameError("sensitivity", wrt, self.sensitivities)
        o = self._index(self.outputs, self.outputs[0] if output is None and len(self.outputs) == 1 else output, "output")
        i = self._index(self.inputs, self.inputs[0] if input is None and len(self.inputs) == 1 else input, "input")
        return self.sensitivities[wrt][o, i]

    def unit(self, output: Any, input: str) -> str:
        """The unit of ``H[output, input]`` (``"V/A"``, ``"m/N"``, ``"V/V"``), or ``""`` when either is unknown."""
        top, bottom = self.units.get(str(output), ""), self.units.get(input, "")
        if not top or not bottom:
            return ""
        num, _, den = top.partition("/")
        den = " ".join(x for x in (den, bottom) if x)
        return f"{num}/{den}" if " " not in den else f"{num}/({den})"

    def __repr__(self) -> str:
        return (f"<FrequencyResponse of {self.model!r}: {len(self.outputs)} output(s) × {len(self.inputs)} input(s), "
                f"{len(self.frequencies)} frequencies {self.frequencies[0]:g}–{self.frequencies[-1]:g} Hz>")

    def to_xarray(self):
        """The response as an :class:`xarray.Dataset`: ``H`` (complex) over ``output``, ``input`` and ``frequency``
        (Hz), with each ratio's unit (``unit``, over output and input), the error bounds (``error``) and the
        sensitivities (``dH/d<name>``) where the response has them, the model and notes as attributes.

        >>> import lagrangian as lg
        >>> m = lg.Model("rc")
        >>> _ = m.add("voltage_source", "V1", ("in", "0"), E=0)
        >>> _ = m.add("resistor", "R1", ("in", "a"), R=1e3)
        >>> _ = m.add("capacitor", "C1", ("a", "0"), C=2.2e-6)
        >>> ds = frequency_response(m, [10.0, 100.0], inputs=["V1"], outputs=["v(C1)", "i(R1)"]).to_xarray()
        >>> ds.H.dims, ds.unit.sel(output="i(R1)", input="V1").item(), ds.frequency.attrs["units"]
        (('output', 'input', 'frequency'), 'A/V', 'Hz')
        """
        import xarray as xr

        dims = ("output", "input", "frequency")
        data = {"H": xr.Variable(dims, self.H)}
        if self.error is not None:
            data["error"] = xr.Variable(dims, self.error, {"description": "bound of each value's rounding error"})
        for name, dH in self.sensitivities.items():
            data[f"dH/d{name}"] = xr.Variable(dims, dH)
        units = np.array([[self.unit(o, i) for i in self.inputs] for o in self.outputs], dtype=object)
        coords = {"output": list(self.outputs), "input": list(self.inputs),
                  "frequency": xr.Variable(("frequency",), self.frequencies, {"units": "Hz"}),
                  "unit": (("output", "input"), units)}
        return xr.Dataset(data, coords=coords, attrs={"model": self.model, "notes": "\n".join(self.notes)})

    def to_pandas(self):
        """The response as a :class:`pandas.DataFrame` of complex values indexed by ``frequency`` (Hz): a column per
        output (one input), or per ``(output, input)`` (several).

        >>> import lagrangian as lg
        >>> m = lg.Model("rc")
        >>> _ = m.add("voltage_source", "V1", ("in", "0"), E=0)
        >>> _ = m.add("resistor", "R1", ("in", "a"), R=1e3)
        >>> _ = m.add("capacitor", "C1", ("a", "0"), C=2.2e-6)
        >>> df = frequency_response(m, [10.0, 100.0], inputs=["V1"], outputs=["v(C1)"]).to_pandas()
        >>> list(df.columns), df.index.name, df.shape
        (['v(C1)'], 'frequency', (2, 1))
        """
        import pandas as pd

        index = pd.Index(self.frequencies, name="frequency")
        if len(self.inputs) == 1:
            return pd.DataFrame({o: self.H[k, 0] for k, o in enumerate(self.outputs)}, index=index)
        columns = pd.MultiIndex.from_tuples([(o, i) for o in self.outputs for i in self.inputs], names=["output", "input"])
        return pd.DataFrame(self.H.reshape(-1, len(self.frequencies)).T, index=index, columns=columns)

    def __getitem__(self, key) -> np.ndarray:
        """``resp["v(C1)"]`` (the only input) or ``resp["v(C1)", "V1"]``: the complex response."""
        out, inp = key if isinstance(key, tuple) else (key, None)
        o = self._index(self.outputs, out, "output")
        if inp is None:
            if len(self.inputs) != 1:
                raise ModelError(f"this response has inputs {self.inputs}: name one, as resp[{out!r}, {self.inputs[0]!r}].")
            i = 0
        else:
            i = self._index(self.inputs, inp, "input")
        return self.H[o, i]

    @staticmethod
    def _index(names: list[str], name: Any, what: str) -> int:
        key = str(name)
        if key not in names:
            raise UnknownNameError(what, key, names)
        return names.index(key)

    def to_control(self) -> Any:
        """The response as python-control frequency-response data (``pip install 'lagrangian[control]'``).

        Returns
        -------
        control.FrequencyResponseData
            ``H`` at ``ω = 2π f`` (rad/s), outputs and inputs named by our labels.

        Examples
        --------
        >>> import lagrangian as lg
        >>> m = lg.Model("rl")
        >>> _ = m.add("voltage_source", "V1", ("in", "0"), E=0)
        >>> _ = m.add("resistor", "R1", ("in", "a"), R=10.0)
        >>> _ = m.add("inductor", "L1", ("a", "0"), L=7e-3)
        >>> data = frequency_response(m, [1e3], outputs=["i(L1)"]).to_control()
        >>> data.input_labels, data.output_labels, data.omega.round(3).tolist()
        (['V1'], ['i(L1)'], [6283.185])
        """
        return _control.frequency_response_data(self)

    def magnitude_db(self, output: Any, input: str | None = None) -> np.ndarray:
        """``20 log10 |H|``."""
        with np.errstate(divide="ignore"):
            return 20 * np.log10(np.abs(self[output, input] if input else self[output]))

    def phase_deg(self, output: Any, input: str | None = None) -> np.ndarray:
        """The phase of ``H`` in degrees, unwrapped along the frequency grid."""
        return np.degrees(np.unwrap(np.angle(self[output, input] if input else self[output])))

    def _legend(self, output: str, input: str) -> str:
        unit = self.unit(output, input)
        return f"{output} / {input}" + (f" ({unit})" if unit else "")

    @charts.plain
    def plot(self, kind: str = "bode", *, outputs: Sequence[Any] | None = None, input: str | None = None,
             path: str | None = None):
        """A Bode chart (magnitude in dB and phase against log frequency) or a Nyquist chart; returns the matplotlib
        Figure and writes it to ``path`` (PNG) when given."""
        if kind not in ("bode", "nyquist"):
            raise ModelError(f"kind is 'bode' or 'nyquist', not {kind!r}.")
        chosen = [str(o) for o in (outputs or self.outputs)]
        inp = input or self.inputs[0]
        if kind == "bode":
            fig, (ax_m, ax_p) = charts.subplots(2, 1, sharex=True, figsize=(7, 6))
            for o in chosen:
                ax_m.semilogx(self.frequencies, self.magnitude_db(o, inp), label=self._legend(o, inp))
                ax_p.semilogx(self.frequencies, self.phase_deg(o, inp), label=self._legend(o, inp))
            ax_m.set_ylabel("|H| (dB re 1 unit of each ratio)" if any(self.unit(o, inp) for o in chosen)
                            else "|H| (dB)")
            ax_p.set_ylabel("phase (°)")
            ax_p.set_xlabel("frequency (Hz)")
            ax_m.legend(fontsize=8)
            for ax in (ax_m, ax_p):
                ax.grid(True, which="both", alpha=0.3)
        else:
            fig, ax = charts.subplots(figsize=(6, 6))
            for o in chosen:
                H = self[o, inp]
                ax.plot(H.real, H.imag, label=self._legend(o, inp))
                ax.plot(H.real, -H.imag, "--", alpha=0.4)
            # the critical point −1 marked where the curve's own scale shows it, without scaling the axes to it (a
            # response of 1e-3 was squashed to a dot beside it)
            ax.annotate("+", xy=(-1, 0), ha="center", va="center", color="r", annotation_clip=True)
            units = {self.unit(o, inp) for o in chosen}
            suffix = f" ({units.pop()})" if len(units) == 1 and "" not in units else ""
            ax.set_xlabel(f"Re H{suffix}")
            ax.set_ylabel(f"Im H{suffix}")
            ax.axis("equal")
            ax.legend(fontsize=8)
            ax.grid(True, alpha=0.3)
        fig.suptitle(f"{self.model}: frequency response")
        fig.tight_layout()
        if path is not None:
            fig.savefig(path, dpi=110)
        return fig


def frequency_response(system: Model | LinearModel, frequencies: Any, *, inputs: Sequence[str] | None = None,
                       outputs: Sequence[Any] | None = None, sensitivities: Sequence[str] | None = None,
                       **kwargs: Any) -> FrequencyResponse:
    """``H(j 2π f)`` at ``frequencies`` (Hz) for every input and output (see :func:`linearize` for both and for
    ``kwargs``).  ``sensitivities``: parameter names (as in ``parameter_values``) whose exact derivatives
    ``∂H/∂p`` the response carries too (:meth:`FrequencyResponse.sensitivity`; a model about rest with its own
    values: :class:`~lagrangian.analysis.parametric.ParametricResponse`).

    Each value carries the bound of its rounding error (:attr:`FrequencyResponse.error`).  A value without a certain
    digit is given as ``nan``, and the notes say where: 1 mH across 10 nF in loop charges, at a millihertz, loses
    ``L s²`` (4e-8) beside ``1/C`` (1e8); in node fluxes it does not.

    >>> import lagrangian as lg
    >>> def tank(formulation):
    ...     m = lg.Model("tank", formulation=formulation)
    ...     _ = m.add("voltage_source", "V1", ("in", "0"), E=0)
    ...     _ = m.add("resistor", "R1", ("in", "a"), R=10.0)
    ...     _ = m.add("capacitor", "C1", ("a", "0"), C=1e-8)
    ...     _ = m.add("inductor", "L1", ("a", "0"), L=1e-3)
    ...     return frequency_response(m, [1e-3, 1.0], inputs=["V1"], outputs=["v(C1)"])
    >>> def exact(f):                           # Z / (R + Z), Z = s L ∥ 1/(s C)
    ...     s = 2j * np.pi * f
    ...     Z = s * 1e-3 / (1 + s**2 * 1e-3 * 1e-8)
    ...     return Z / (10.0 + Z)
    >>> loops = tank("charge")
    >>> loops.H[0, 0, 0], loops.notes[0][:42]
    (np.complex128(nan+0j), 'no certain digit at 1 frequencies (first a')
    >>> bool(abs(loops.H[0, 0, 1] - exact(1.0)) <= loops.error[0, 0, 1] < 1e-4 * abs(exact(1.0))), loops.notes[1][:40]
    (True, 'fewer than six certain digits at 1 frequ')
    >>> nodes = tank("flux")
    >>> bool(np.all(np.abs(nodes.H[0, 0] - exact(nodes.frequencies)) < 1e-12 * np.abs(exact(nodes.frequencies))))
    True
    >>> nodes.notes, bool(np.all(nodes.error < 1e-13 * np.abs(nodes.H)))
    ([], True)
    """
    f = _frequencies(frequencies)
    if sensitivities:
        if not isinstance(system, Model) or kwargs:
            raise ModelError("sensitivities= takes a Model (not a linearization) at rest with its own parameter "
                             "values: give other values to the model itself.")
        unknown = [n for n in sensitivities if n not in system.parameter_values]
        if unknown:
            raise UnknownNameError("parameter", unknown[0], system.parameter_values)
        if np.any(f <= 0):
            raise ModelError("sensitivities= needs positive frequencies (a response's derivative at 0 Hz may hold 1/s).")
        names = list(dict.fromkeys(sensitivities))
        parametric = ParametricResponse(system, inputs, outputs, names)
        _, dH = parametric.evaluate([system.parameter_values[n] for n in names], f)
        out = frequency_response(system, f, inputs=inputs, outputs=outputs)
        out.sensitivities = {n: dH[j] for j, n in enumerate(names)}
        return out
    lin = _linear(system, inputs, outputs, kwargs)
    H, bound, uncertain = _respond(lin, 2j * np.pi * f)
    notes = []
    pole = ~np.all(np.isfinite(H) | uncertain, axis=(1, 2))
    if np.any(pole):
        notes.append(f"not finite at {np.count_nonzero(pole)} frequencies (a pole on the grid, first at "
                     f"{f[pole][0]:g} Hz)")
    if np.any(uncertain):
        where = f[np.any(uncertain, axis=(1, 2))]
        notes.append(f"no certain digit at {len(where)} frequencies (first at {where[0]:g} Hz), given as nan: "
                     "M s² + C s + K is singular, or nearly, in double precision there, its terms being decades "
                     "apart (a circuit is better conditioned at low frequencies in node fluxes, formulation='flux', "
                     "at high ones in loop charges)")
    with np.errstate(invalid="ignore"):
        loose = np.isfinite(H) & (bound > DIGITS * np.abs(H)) & (bound > FLOOR * np.nanmax(np.abs(H), axis=0, initial=0))
    if np.any(loose):
        where = f[np.any(loose, axis=(1, 2))]
        notes.append(f"fewer than six certain digits at {len(where)} frequencies (first at {where[0]:g} Hz): .error "
                     "bounds each value's error")
    return FrequencyResponse(lin.model, f, list(lin.inputs), list(lin.outputs), np.moveaxis(H, 0, -1), notes,
                             dict(lin.units), error=np.moveaxis(bound, 0, -1))


def _frequencies(frequencies: Any) -> np.ndarray:
    """``frequencies`` (Hz) as a 1-D float array: one number or a sequence (a list, a tuple, an array) of real,
    finite numbers ≥ 0 (0 Hz is DC).  Anything else is a :class:`~lagrangian.ModelError` saying what is wrong with
    it: text, a mapping or a set (no order), an iterator (give a list), bools, complex numbers (frequencies are real:
    ``H`` is evaluated at ``s = j 2π f``)."""
    shown = f"{frequencies!r:.80}"
    fix = "give a list or array of real numbers ≥ 0 (Hz), such as decades(1, 1e6, 20) or [0, 50, 1e3]"
    if frequencies is None or isinstance(frequencies, (str, bytes, bytearray, Mapping, Set)):
        what = "nothing" if frequencies is None else f"a {type(frequencies).__name__}"
        raise ModelError(f"frequencies must be numbers of Hz, got {what} ({shown}): {fix}.")
    if isinstance(frequencies, Iterator):  # read once, perhaps without end: never drawn from here
        raise ModelError(f"frequencies must be a sequence, got an iterator ({shown}): give list(...) of it, or {fix}.")
    try:
        given = np.asarray(frequencies)
    except (TypeError, ValueError, OverflowError) as exc:  # ragged lists, objects NumPy cannot hold
        raise ModelError(f"frequencies must be a 1-D sequence of numbers of Hz, got {shown} ({type(exc).__name__}): "
                         f"{fix}.") from None
    if given.ndim > 1:
        raise ModelError(f"frequencies must be a 1-D sequence of numbers of Hz, got an array of shape {given.shape}: "
                         f"{fix}.")
    kind = given.dtype.kind
    if kind == "O":  # Python objects: each must be a real number (a Fraction, a SymPy number, a Decimal)
        items = given.ravel().tolist()
        bad = next((x for x in items if isinstance(x, (bool, np.bool_))
                    or not isinstance(x, (numbers.Real, decimal.Decimal))), None)
        if bad is not None or not items:
            kind = "c" if isinstance(bad, numbers.Complex) and not isinstance(bad, (bool, np.bool_)) else "?"
        else:
            try:
                given = np.array([float(x) for x in items], dtype=float)
            except (TypeError, ValueError, OverflowError):  # a SymPy symbol, an int beyond a float
                kind = "?"
            else:
                kind = "f"
    if kind == "c":
        raise ModelError(f"frequencies must be real numbers of Hz, got complex values ({shown}): the response is "
                         f"evaluated at s = j·2π·f, so give f (real, ≥ 0), not s.")
    if kind == "b":
        raise ModelError(f"frequencies must be numbers of Hz, got bools ({shown}): {fix}.")
    if kind not in "iuf":
        raise ModelError(f"frequencies must be real numbers of Hz, got {shown}: {fix}.")
    f = np.atleast_1d(given.astype(float))
    if not f.size:
        raise ModelError(f"frequencies must hold at least one frequency, got {shown}: {fix}.")
    if not np.all(np.isfinite(f)) or np.any(f < 0):
        bad = f[~(np.isfinite(f) & (f >= 0))][0]
        raise ModelError(f"frequencies must be finite and ≥ 0 Hz, got {bad!r} in {shown}: {fix}.")
    return f


def __getattr__(name: str):
    if name == "s":  # the Laplace variable, SymPy's symbol (imported when first asked for)
        return sp.Symbol("s")
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
