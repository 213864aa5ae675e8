"""LaTeX of models: the one place where names (of nodes and components, inside coordinate and symbol names) are
escaped for LaTeX, and the mechanics notation (``x`` for ``x(t)``, ``\\dot{x}`` for its rate) of notebook displays.
"""

from __future__ import annotations

import functools
import re

from .component import t

__all__ = ["to_latex"]

#: Characters that LaTeX reads as commands, in the names of coordinates and symbols (``_`` and ``^`` keep
#: SymPy's meaning: subscript and superscript).
_LATEX_SPECIAL = {"\\": r"\backslash{}", "{": r"\{", "}": r"\}", "$": r"\$", "&": r"\&", "#": r"\#", "%": r"\%",
                  "~": r"\sim{}"}
_LATEX_RE = re.compile("|".join(map(re.escape, _LATEX_SPECIAL)))


def _latex_escape(text: str) -> str:
    """``text`` with every LaTeX special character escaped (``%`` → ``\\%``)."""
    return _LATEX_RE.sub(lambda m: _LATEX_SPECIAL[m.group()], text)


@functools.cache
def _printers() -> tuple[type, type]:
    """The printers, made on first use (they are subclasses of SymPy's, which is imported then)."""
    from sympy.core.function import AppliedUndef
    from sympy.printing.latex import LatexPrinter, translate
    from sympy.printing.conventions import split_super_sub

    class _LatexPrinter(LatexPrinter):
        """SymPy's LaTeX printer, with the names of symbols and coordinate functions escaped for LaTeX: node and
        component names become part of those names, and may hold ``%``, ``{``, ``\\`` or ``#`` (the one place names
        are escaped for LaTeX).  Names without such characters print exactly as ``sympy.latex`` prints them."""

        def _split_super_sub(self, name: str) -> tuple[str, list[str], list[str]]:
            if name is None:
                return super()._split_super_sub(name)
            base, supers, subs = split_super_sub(name)
            return (translate(_latex_escape(base)), [translate(_latex_escape(x)) for x in supers],
                    [translate(_latex_escape(x)) for x in subs])

        def _print_Function(self, expr, exp=None) -> str:
            if not isinstance(expr, AppliedUndef):
                return super()._print_Function(expr, exp)
            # SymPy formats the name with % (name % args): built here by concatenation, so a % in a name is text
            name = self._hprint_Function(expr.func.__name__)
            if exp is not None:
                name = self.parenthesize_super(name) + "^{" + exp + "}"
            args = ",".join(str(self._print(a)) for a in expr.args)
            if self._settings["fold_func_brackets"] and len(expr.args) == 1 \
                    and not self._needs_function_brackets(expr.args[0]):
                return name + args
            return name + r"{\left(" + args + r" \right)}"


    class _DotPrinter(_LatexPrinter):
        """The mechanics notation: a coordinate ``x(t)`` prints as ``x``, its rates as ``\\dot{x}``, ``\\ddot{x}``."""

        def _print_Function(self, expr, exp=None) -> str:
            if isinstance(expr, AppliedUndef) and expr.args == (t,):
                name = self._hprint_Function(expr.func.__name__)
                return self.parenthesize_super(name) + "^{" + exp + "}" if exp is not None else name
            return super()._print_Function(expr, exp)

        def _print_Derivative(self, expr) -> str:
            f = expr.expr
            order = sum(n for v, n in expr.variable_count if v == t)
            if isinstance(f, AppliedUndef) and f.args == (t,) and len(expr.variable_count) == 1 and order <= 3:
                base, supers, subs = self._split_super_sub(f.func.__name__)
                text = "\\" + "d" * order + "ot{" + base + "}"
                return text + ("_{" + " ".join(subs) + "}" if subs else "") + ("^{" + " ".join(supers) + "}" if supers else "")
            return super()._print_Derivative(expr)

    return _LatexPrinter, _DotPrinter


def _latex(expr) -> str:
    return _printers()[0]().doprint(expr)


def to_latex(expr, dots: bool = True) -> str:
    """``expr`` as LaTeX with names escaped; ``dots``: in the mechanics notation (``x`` for ``x(t)``,
    ``\\dot{x}`` for its rate), else as ``sympy.latex`` writes it.

    >>> import sympy as sp
    >>> x = sp.Function("theta_j1")(t)
    >>> print(to_latex(x.diff(t) ** 2 / 2))
    \\frac{\\dot{\\theta}_{j1}^{2}}{2}
    """
    return _printers()[1 if dots else 0]().doprint(expr)
