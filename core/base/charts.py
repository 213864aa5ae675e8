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

from typing import Any

__all__ = ["Chart", "subplots"]


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
