"""Rich display in notebooks: the one place where text becomes HTML.

Models, results, reductions, steady motions, comparisons and scenes show
themselves in Jupyter through ``_repr_html_``, built from these pieces.
Every piece of text — names come from users and files — goes through
:func:`escape`; LaTeX is put between ``$$`` for the notebook's MathJax, its
``<``, ``>`` and ``&`` escaped as HTML too; charts are PNG images inlined as
base64.

>>> table(["name", "kind"], [["m1", "mass"], ["<b>", "spring"]])
'<table><thead><tr><th>name</th><th>kind</th></tr></thead><tbody><tr><td>m1</td><td>mass</td></tr><tr><td>&lt;b&gt;</td><td>spring</td></tr></tbody></table>'
>>> math(r"L = \\frac{1}{2} m \\dot{x}^{2}")
'<div>$$L = \\\\frac{1}{2} m \\\\dot{x}^{2}$$</div>'
"""

from __future__ import annotations

import base64
import html
import io
from collections.abc import Iterable, Sequence
from types import SimpleNamespace
from typing import Any

from . import charts

__all__ = ["escape", "table", "math", "figure", "png", "image", "block", "short"]


def escape(text: Any) -> str:
    """``text`` as HTML text: ``<``, ``>``, ``&`` and quotes escaped."""
    return html.escape(str(text), quote=True)


def table(header: Sequence[Any], rows: Iterable[Sequence[Any]]) -> str:
    """An HTML table; every cell escaped."""
    head = "".join(f"<th>{escape(h)}</th>" for h in header)
    body = "".join("<tr>" + "".join(f"<td>{escape(c)}</td>" for c in row) + "</tr>" for row in rows)
    return f"<table><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"


def math(latex: str) -> str:
    """Display LaTeX for MathJax (escaped as HTML text: MathJax reads the text, not the markup)."""
    return f"<div>$${escape(latex)}$$</div>"


def figure(**kwargs: Any):
    """A matplotlib ``Figure`` that no backend manages (``kwargs`` as ``Figure``'s), for charts written to files
    or inlined in HTML: the library never switches the user's backend (a notebook's inline charts stay inline),
    and these figures never pop up in a window or pile up in ``pyplot``'s list of open figures.

    >>> fig = figure(figsize=(3, 2))
    >>> _ = fig.subplots().plot([0, 1], [1, 0])
    >>> png(fig)[:8] == b"\\x89PNG\\r\\n\\x1a\\n"
    True
    """
    from matplotlib.figure import Figure

    return Figure(**kwargs)


def png(figure) -> bytes:
    """A matplotlib figure as PNG bytes; the figure is closed when ``pyplot`` holds it."""
    import matplotlib.pyplot as plt

    buffer = io.BytesIO()
    try:
        figure.savefig(buffer, format="png", dpi=90)
    finally:
        plt.close(figure)
    return buffer.getvalue()


def image(data: bytes, alt: str = "chart") -> str:
    """PNG bytes as an inline ``<img>``."""
    return f'<img alt="{escape(alt)}" src="data:image/png;base64,{base64.b64encode(data).decode()}"/>'


def block(title: str, *parts: str, note: str | None = None) -> str:
    """A titled block of HTML parts (already HTML), with an optional note in smaller type (text)."""
    foot = f"<p><small>{escape(note)}</small></p>" if note else ""
    return f"<div><p><b>{escape(title)}</b></p>{''.join(parts)}{foot}</div>"


def short(items: Sequence[Any], limit: int = 6) -> str:
    """A few items joined with commas, ``…`` and the count when there are more.

    >>> short(["a", "b", "c"], 2)
    'a, b, … (3)'
    """
    items = [str(i) for i in items]
    return ", ".join(items) if len(items) <= limit else ", ".join(items[:limit]) + f", … ({len(items)})"


#: Colours of the domains in drawings (others take the next colours of matplotlib's cycle).
DOMAIN_COLOURS = {"mechanical": "#1f77b4", "electrical": "#d62728", "rotational": "#2ca02c", "thermal": "#ff7f0e"}


@charts.plain
def draw_components(components: Sequence[Any], title: str, ax=None, ground: str = "ground"):
    """Draw a component graph: nodes as points (ground hatched), a two-terminal component as an edge, any other
    as a box joined to its terminals; everything labelled, coloured by domain.  Returns the Axes."""
    import matplotlib.pyplot as plt
    import networkx as nx

    graph = nx.MultiGraph()
    hubs, singles = {}, {}
    for comp in components:
        nodes = list(dict.fromkeys(comp.nodes))
        if len(nodes) == 2:
            graph.add_edge(nodes[0], nodes[1], key=comp.name, comp=comp)
        elif len(nodes) == 1:
            singles.setdefault(nodes[0], []).append(comp)
            graph.add_node(nodes[0])
        else:  # a box of its own, joined to each terminal (a transducer, a joint on three bodies, a global load)
            hub = ("component", comp.name)
            hubs[hub] = comp
            graph.add_node(hub)
            for node in nodes:
                graph.add_edge(hub, node, key=f"{comp.name}:{node}", comp=None)
    if ax is None:
        _, ax = plt.subplots(figsize=(8, 5.5), constrained_layout=True)
    if graph.number_of_nodes() == 0:
        ax.set_title(f"{title}: no components")
        ax.axis("off")
        return ax
    pos = nx.kamada_kawai_layout(nx.Graph(graph)) if graph.number_of_nodes() > 2 else nx.spring_layout(graph, seed=1)
    cycle = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    colours = dict(DOMAIN_COLOURS)

    def colour(domain):
        if domain not in colours:
            colours[domain] = cycle[len(colours) % len(cycle)]
        return colours[domain]

    seen: dict[tuple, int] = {}
    for u, v, key, data in graph.edges(keys=True, data=True):
        comp = data.get("comp")
        pair = tuple(sorted(map(str, (u, v))))
        k = seen[pair] = seen.get(pair, -1) + 1  # parallel components bend apart
        rad = 0.25 * ((k + 1) // 2) * (1 if k % 2 else -1)
        col = colour(comp.domain) if comp is not None else "0.6"
        ax.annotate("", xy=pos[v], xytext=pos[u], arrowprops=dict(arrowstyle="-", color=col, lw=2 if comp else 1,
                                                                   connectionstyle=f"arc3,rad={rad}"))
        if comp is not None:
            (x0, y0), (x1, y1) = pos[u], pos[v]
            mx, my = (x0 + x1) / 2 + rad * (y1 - y0) / 2, (y0 + y1) / 2 - rad * (x1 - x0) / 2  # the arc's middle
            ax.text(mx, my, f"{comp.name}\n{comp.kind}", fontsize=7, ha="center", va="center", color=col,
                    bbox=dict(boxstyle="round,pad=0.2", fc="white", ec=col, lw=0.8))
    for node, (x, y) in pos.items():
        if node in hubs:
            comp = hubs[node]
            ax.text(x, y, f"{comp.name}\n{comp.kind}", fontsize=7, ha="center", va="center", color="white",
                    bbox=dict(boxstyle="square,pad=0.3", fc=colour(comp.domain), ec="none"))
            continue
        is_ground = node in (ground, "0")
        ax.scatter([x], [y], s=90, c="white" if is_ground else "black", edgecolors="black", hatch="////" if is_ground else None,
                   zorder=3)
        label = str(node) + "".join(f"\n{c.name} ({c.kind})" for c in singles.get(node, []))
        ax.annotate(label, (x, y), xytext=(6, 6), textcoords="offset points", fontsize=8, zorder=4)
    for domain, col in colours.items():
        if any(getattr(c, "domain", None) == domain for c in components):
            ax.plot([], [], color=col, lw=2, label=domain)
    ax.legend(loc="lower right", fontsize=8, frameon=False)
    ax.set_title(title)
    ax.axis("off")
    ax.margins(0.15)
    return ax


def _schematic_parts(components: Sequence[Any]) -> tuple[list, list, list[str]]:
    """What a schematic draws: its two-terminal elements (a two-port's ports among them, each an element named
    ``<two-port>:1``, ``:2``, drawn as a box labelled with its number); the dashed lines tying elements together
    (a two-port's ports, labelled with its kind: a gyrator, a transducer's analogue; the elements a component
    without terminals names in its parameters of shape ``"name"``, labelled with its kind and numbers: coupled
    inductors, a transformer) as ``(name, elements, label)``; and the names of the components it cannot draw."""
    parts, ties, others = [], [], []
    drawn = {c.name for c in components if len(dict.fromkeys(c.nodes)) == 2}
    for c in components:
        if len(dict.fromkeys(c.nodes)) == 2:
            parts.append(c)
            continue
        try:
            branches = c.branches() if c.nodes else []
        except NotImplementedError:
            branches = []
        named = [c.params[p] for p, spec in c.parameters.items() if spec.shape == "name" and c.params.get(p) in drawn]
        one_domain = len(set(getattr(c, "terminal_domains", None) or ())) <= 1  # a transducer itself is no two-port
        if len(branches) >= 2 and one_domain and all(a != b for a, b in branches):
            ports = [SimpleNamespace(name=f"{c.name}:{i + 1}", nodes=branch, symbol=None, kind=c.kind, label=str(i + 1))
                     for i, branch in enumerate(branches)]
            parts += ports
            ties.append((c.name, [p.name for p in ports], f"{c.name} ({c.kind})"))
        elif not c.nodes and len(named) >= 2:
            numbers = [f"{p}={float(v):.3g}" for p, v in c.params.items()
                       if c.parameters[p].shape == "scalar" and getattr(v, "is_number", False)]
            ties.append((c.name, named, f"{c.name} ({c.kind}{', ' + ', '.join(numbers) if numbers else ''})"))
        else:
            others.append(c.name)
    return parts, ties, others


def schematic(components: Sequence[Any], title: str, ground: Sequence[str] = ("0", "ground")):
    """A schematic of two-terminal components with :mod:`schemdraw`: the nodes other than ground on one row, in
    the order of a walk from the first source, ground along the bottom; an element between neighbouring nodes
    sits on the row, one to ground hangs from its node, others (parallel, or between nodes further apart) are
    lifted onto rows above and joined by wires.  Each element is drawn with its ``symbol`` (a box with its kind
    when it has none) and labelled with its name.  Returns the ``schemdraw.Drawing``."""
    import networkx as nx
    import schemdraw
    import schemdraw.elements as elm

    parts, ties, others = _schematic_parts(components)
    if others:
        raise ValueError(f"only two-terminal elements, two-ports and couplings between named elements have "
                         f"schematic symbols; {short(others)} {'has' if len(others) == 1 else 'have'} other terminals: "
                         f"draw the model with draw()")
    graph = nx.MultiGraph()
    for c in parts:
        graph.add_edge(*c.nodes[:2], key=c.name)
    live = nx.Graph(graph.subgraph([n for n in graph if n not in ground]))
    start = next((n for c in parts if c.symbol and c.symbol.startswith("Source") for n in c.nodes if n not in ground),
                 next(iter(live), None))
    order: list[str] = []
    for component in ([start] if start is not None else []) + [n for n in live if n != start]:
        if component not in order:
            order += [n for n in nx.dfs_preorder_nodes(live, component) if n not in order]
    x = {n: 3.0 * i for i, n in enumerate(order)}
    top, low = 3.0, 0.0
    schemdraw.use("matplotlib")
    drawing = schemdraw.Drawing(show=False)
    drawing.config(fontsize=10, unit=2.5)
    used: dict[int, list[tuple[float, float]]] = {}  # row → the stretches its elements take
    hang: dict[str, int] = {}
    xs = list(x.values()) or [0.0]
    centres: dict[str, tuple[float, float]] = {}  # where each element is drawn

    def element(c, p, q):
        symbol = getattr(elm, c.symbol) if c.symbol and hasattr(elm, c.symbol) else None
        e = symbol() if symbol is not None else elm.RBox()
        if c.symbol == "SourceV":  # schemdraw marks its end +; a source's first node is its + terminal
            p, q = q, p
        text = getattr(c, "label", None) or (c.name if symbol is not None else f"{c.name}\n{c.kind}")
        drawing.add(e.endpoints(p, q).label(charts.literal(text), fontsize=9))
        centres[c.name] = ((p[0] + q[0]) / 2, (p[1] + q[1]) / 2)

    for c in parts:
        a, b = c.nodes[0], c.nodes[1]
        if a in ground and b in ground:
            continue
        if a in ground or b in ground:
            node = b if a in ground else a
            k = hang.get(node, 0)
            hang[node] = k + 1
            px = x[node] + 1.5 * k
            if k:
                drawing.add(elm.Line().endpoints((x[node] + 1.5 * (k - 1), top), (px, top)))
                drawing.add(elm.Line().endpoints((x[node] + 1.5 * (k - 1), low), (px, low)))
            p, q = ((px, top), (px, low)) if b in ground else ((px, low), (px, top))
            element(c, p, q)
            xs.append(px)
            continue
        lo, hi = sorted((x[a], x[b]))
        level = 0 if abs(order.index(a) - order.index(b)) == 1 else 1
        while any(lo < h and l < hi for l, h in used.get(level, [])):  # the lowest free stretch of a row
            level += 1
        used.setdefault(level, []).append((lo, hi))
        pair = (a, b)
        y = top + 2.0 * level
        if level:
            for n in pair:
                drawing.add(elm.Line().endpoints((x[n], top), (x[n], y)))
        p, q = (x[a], y), (x[b], y)
        element(c, p, q)
    if any(n in ground for c in parts for n in c.nodes):
        drawing.add(elm.Line().endpoints((min(xs), low), (max(xs), low)))
        drawing.add(elm.Ground().at((min(xs), low)))
    for name, joined, label in ties:  # a two-port's ports, or the elements a coupling names: a dashed line
        ends = [centres[n] for n in joined if n in centres]
        for (x0, y0), (x1, y1) in zip(ends, ends[1:]):
            length = max(((x1 - x0) ** 2 + (y1 - y0) ** 2) ** 0.5, 1e-9)
            cut = min(0.45, length / 4) / length  # from side to side of the two symbols, not through them
            start, end = (x0 + cut * (x1 - x0), y0 + cut * (y1 - y0)), (x1 - cut * (x1 - x0), y1 - cut * (y1 - y0))
            drawing.add(elm.Line(ls="--", color="gray").endpoints(start, end)
                        .label(charts.literal(label), loc="bottom", fontsize=8, color="gray"))
    for n in order:
        drawing.add(elm.Dot().at((x[n], top)).label(charts.literal(n), loc="top", fontsize=8, color="gray"))
    drawing.add(elm.Label().at(((min(xs) + max(xs)) / 2, top + 2.0 * max(used, default=0) + 2.0))
                .label(charts.literal(title), fontsize=11))
    return drawing
