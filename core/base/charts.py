"""Charts that user-facing ``plot()`` methods return: a matplotlib ``Figure`` shown once in a notebook.

With a notebook's inline backend, ``pyplot`` draws every figure still open at the end of a cell, and IPython draws
the cell's value too: a ``plot()`` that returns its ``Figure`` as the cell's last expression was shown twice.  A
``Chart`` shown as a cell's value (``_ipython_display_``) draws itself and leaves ``pyplot``'s list, so the end of
the cell does not draw it again; ``resp.plot();`` and ``fig = resp.plot()`` are drawn once by ``pyplot``, and a
script's ``plt.show()`` shows it as any figure.

Importing this module imports no matplotlib: ``Chart`` is made on first use (and found by this module's name,
so a chart pickles as any figure).
"""

from __future__ import annotations

import functools
from typing import Any

__all__ = ["Chart", "subplots", "plain", "literal"]


def _ipython_display_(self) -> None:
    import matplotlib.pyplot as plt
    from IPython.core.pylabtools import print_figure
    from IPython.display import Image, display

    plt.close(self)  # the end of the cell draws the figures pyplot holds: not this one again
    display(Image(data=print_figure(self, "png", bbox_inches="tight"), format="png"))


def _chart() -> type:
    made = globals().get("_made")
    if made is None:
        from matplotlib.figure import Figure

        made = type("Chart", (Figure,), {"__module__": __name__, "__doc__": "A ``Figure`` that, shown as a notebook "
                                         "cell's value, is drawn once.", "_ipython_display_": _ipython_display_})
        globals()["_made"] = made
    return made


def __getattr__(name: str) -> Any:
    if name == "Chart":
        return _chart()
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def subplots(*args: Any, **kwargs: Any):
    """``pyplot.subplots`` making a ``Chart``.

    >>> fig, ax = subplots(figsize=(3, 2))
    >>> type(fig).__name__, hasattr(fig, "_ipython_display_")
    ('Chart', True)
    >>> import matplotlib.pyplot as plt; plt.close(fig)
    """
    import matplotlib.pyplot as plt

    return plt.subplots(*args, FigureClass=_chart(), **kwargs)


def plain(func):
    r"""``func`` drawing its charts with matplotlib's mathematics off: the names it writes in them (components,
    nodes, outputs, models: text users give) are shown as written, where ``$…$`` in a name would be read as
    mathematics, and ``$\nosuch{$`` fail the drawing.  None of this package's own labels use it.

    >>> import matplotlib.pyplot as plt
    >>> @plain
    ... def chart(name):
    ...     fig, ax = plt.subplots()
    ...     ax.set_title(name)
    ...     return fig
    >>> fig = chart(r"k$\nosuch{$"); fig.canvas.draw(); print(fig.axes[0].get_title())
    k$\nosuch{$
    >>> plt.close(fig)
    """
    @functools.wraps(func)
    def drawn(*args: Any, **kwargs: Any):
        import matplotlib as mpl

        # that one setting only: ``rc_context`` would restore every setting on the way out, the inline backend's
        # ``interactive`` among them when pyplot was first imported inside, and a notebook would not draw the chart
        before = mpl.rcParams["text.parse_math"]
        mpl.rcParams["text.parse_math"] = False
        try:
            return func(*args, **kwargs)
        finally:
            mpl.rcParams["text.parse_math"] = before

    return drawn


def literal(text: Any) -> str:
    r"""``text`` escaped for a label drawn later, outside :func:`plain` (schemdraw draws when shown): ``$`` as
    ``\$``.

    >>> print(literal("R$1"))
    R\$1
    """
    return str(text).replace("$", "\\$")
