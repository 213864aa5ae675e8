"""python-control systems of transfer functions and frequency responses.

python-control (``import control``) is the optional extra
``pip install 'lagrangian[control]'``: imported when a conversion is asked
for, never by importing lagrangian.

- :func:`transfer_function`: a :class:`~lagrangian.frequency.TransferFunction`
  as a ``control.TransferFunction``, its numerator and denominator the
  coefficients of its rational expression in ``s``
  (:attr:`~lagrangian.frequency.TransferFunction.expr`);
- :func:`frequency_response_data`: a
  :class:`~lagrangian.frequency.FrequencyResponse` as a
  ``control.FrequencyResponseData`` (``ω = 2π f``).

A linearization's state space is :meth:`lagrangian.frequency.LinearModel.to_control`.  The objects are taken as
they are (their attributes read, nothing of theirs imported); input and output names are our labels.

>>> import lagrangian as lg
>>> from lagrangian.frequency import transfer_function
>>> m = lg.Model("rc")
>>> _ = m.add("voltage_source", "V1", ("in", "0"), E=0)
>>> _ = m.add("resistor", "R1", ("in", "out"), R=1e3)
>>> _ = m.add("capacitor", "C1", ("out", "0"), C=2.2e-6)
>>> sys = transfer_function(m, "V1", "v(C1)").to_control()     # 1 / (R C s + 1)
>>> sys.input_labels, sys.output_labels, round(float(sys.dcgain()), 12)
(['V1'], ['v(C1)'], 1.0)
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..errors import ModelError
from ..base import deferred as _deferred

sp = _deferred.module("sympy", globals())

__all__ = ["frequency_response_data", "state_space_system", "transfer_function"]

#: The Laplace variable, as :data:`lagrangian.frequency.s` spells it (SymPy symbols of one name are one symbol).
_s = _deferred.symbol("s")


def _python_control(what: str) -> Any:
    """The ``control`` module (python-control), or a :class:`~lagrangian.errors.ModelError` saying how to install it
    when it is missing; ``what`` names the conversion that needs it."""
    try:
        import control
    except ImportError:
        raise ModelError(f"{what} needs python-control, which is not installed: pip install 'lagrangian[control]' "
                         f"(or pip install control).") from None
    return control


def _symbols(linear: Any) -> list[str]:
    """The names of the symbols without values in a symbolic linearization's matrices, sorted."""
    names = {p.name for p in getattr(linear, "parameters", [])}
    for attr in ("M", "C", "K", "Phi", "B", "Bi", "Cq", "D", "Di", "Phi_v"):
        value = getattr(linear, attr, None)
        for X in value if isinstance(value, list) else [value]:
            if isinstance(X, sp.MatrixBase):
                names |= {x.name for x in X.free_symbols}
    return sorted(names)


def _refuse_symbolic(linear: Any, what: str) -> None:
    """A :class:`~lagrangian.errors.ModelError` when ``linear`` (a linearization) is symbolic: python-control takes
    numbers."""
    if linear.symbolic:
        names = _symbols(linear)
        missing = f" ({', '.join(names)} without values)" if names else ""
        raise ModelError(f"model {linear.model!r} is linearized symbolically{missing}, and python-control takes "
                         f"numbers: {what} needs a numeric linearization; give the parameters values "
                         f"(linearize(..., params={{...}}) or the components' own values).")


def state_space_system(lin: Any) -> Any:
    """``lin`` (a :class:`~lagrangian.analysis.linearize.LinearModel`) as a ``control.StateSpace``: its
    :meth:`state_space` (loop constraints in independent coordinates, constraints on velocities in independent
    coordinates and speeds), inputs, outputs and states named by our labels, the system by the model."""
    _refuse_symbolic(lin, "LinearModel.to_control()")
    control = _python_control("LinearModel.to_control()")
    try:
        A, B, C, D, states = lin.state_space()
    except ModelError as exc:
        pair = f"{lin.inputs[0]!r}, {lin.outputs[0]!r}" if lin.inputs and lin.outputs else "input, output"
        raise ModelError(f"{exc} A control.StateSpace cannot hold it: transfer_function(lin, {pair})"
                         f".to_control() gives a control.TransferFunction, exact in s.") from None
    return control.ss(A, B, C, D, inputs=list(lin.inputs), outputs=list(lin.outputs), states=states, name=lin.model)


def transfer_function(tf: Any) -> Any:
    """``tf`` (a :class:`~lagrangian.frequency.TransferFunction`) as a ``control.TransferFunction``: the coefficients
    of its expression's numerator and denominator in ``s`` (highest power first), its input and output named by our
    labels (swapped for an inverse one, an impedance ``E / i``: the current in, the voltage out), the system by the
    model.

    Refused (:class:`~lagrangian.errors.ModelError`) for a symbolic transfer
    function, naming its symbols, and without python-control.

    >>> import lagrangian as lg
    >>> from lagrangian.frequency import transfer_function
    >>> m = lg.Model("msd")
    >>> _ = m.add("mass", "m", "p", m=0.3)
    >>> _ = m.add("spring", "k", ("ground", "p"), k=40.0)
    >>> _ = m.add("damper", "c", ("ground", "p"), c=0.5)
    >>> _ = m.add("force", "F", "p", F=0)
    >>> sys = transfer_function(m, "F", "x_p").to_control()   # 1 / (m s² + c s + k), monic
    >>> [c.round(6).tolist() for c in (sys.num[0][0], sys.den[0][0])]
    [[3.333333], [1.0, 1.666667, 133.333333]]
    """
    _refuse_symbolic(tf.linear, f"the transfer function {tf.output} / {tf.input}")
    control = _python_control("TransferFunction.to_control()")
    num, den = sp.fraction(sp.together(tf.expr))
    coefficients = [_coefficients(p, tf) for p in (num, den)]
    inputs, outputs = ([tf.output], [tf.input]) if tf.inverse else ([tf.input], [tf.output])
    return control.tf(*coefficients, inputs=inputs, outputs=outputs, name=tf.linear.model)


def _coefficients(poly: sp.Expr, tf: Any) -> np.ndarray:
    """The coefficients of ``poly`` in ``s``, highest power first, as floats.

    A large model's expression is formed from its poles and zeros
    (:meth:`~lagrangian.frequency.TransferFunction.expr`), where conjugate
    pairs leave imaginary parts of the size of a rounding: dropped when each
    is below ``1e-8`` of the bound on that coefficient, the polynomial of
    the roots' magnitudes (``|a_n| Π (s + |r_i|)``); larger ones are refused.
    """
    try:
        values = np.array([complex(c) for c in sp.Poly(sp.expand(poly), _s).all_coeffs()])
    except (TypeError, sp.PolynomialError):
        raise ModelError(f"the transfer function {tf.output} / {tf.input} of model {tf.linear.model!r} is not a "
                         f"rational function of s with number coefficients ({poly}); python-control cannot take "
                         f"it.") from None
    if not np.any(values.imag):
        return values.real
    bound = abs(values[0]) * np.abs(np.poly(-np.abs(np.roots(values)))) if len(values) > 1 else np.abs(values)
    if np.all(np.abs(values.imag) <= 1e-8 * bound):
        return values.real
    raise ModelError(f"the transfer function {tf.output} / {tf.input} of model {tf.linear.model!r} has complex "
                     f"coefficients ({poly}); python-control's TransferFunction takes real ones.")


def frequency_response_data(response: Any) -> Any:
    """``response`` (a :class:`~lagrangian.frequency.FrequencyResponse`) as a ``control.FrequencyResponseData``: the
    same complex values at ``ω = 2π f`` (rad/s), every output by every input, named by our labels.

    >>> import lagrangian as lg
    >>> from lagrangian.frequency import frequency_response
    >>> m = lg.Model("rc")
    >>> _ = m.add("voltage_source", "V1", ("in", "0"), E=0)
    >>> _ = m.add("resistor", "R1", ("in", "out"), R=1e3)
    >>> _ = m.add("capacitor", "C1", ("out", "0"), C=2.2e-6)
    >>> data = frequency_response(m, [10.0, 100.0], outputs=["v(C1)"]).to_control()
    >>> data.output_labels, data.omega.round(3).tolist()
    (['v(C1)'], [62.832, 628.319])
    """
    control = _python_control("FrequencyResponse.to_control()")
    return control.frd(np.asarray(response.H, dtype=complex), 2 * np.pi * np.asarray(response.frequencies, float),
                       inputs=list(response.inputs), outputs=[str(o) for o in response.outputs], name=response.model)
