"""Animations of mechanisms: the parts a model draws (:class:`~lagrangian.base.domain.Shape`), evaluated along a run,
played in a notebook or written to a page or a movie.

An :class:`Animation` holds, for every shape, its points in world coordinates at each frame's time (what
:meth:`lagrangian.Result.animate` evaluates from the model's kinematics), and draws them with matplotlib: in the
plane for a model in one or two dimensions, in perspective for three.  In a notebook it shows as a player (a time
slider, play and pause: matplotlib's ``to_jshtml``, its frames embedded as images, so it needs no network and no
JavaScript library from outside); ``save("m.html")`` writes the same player as a page of its own,
``save("m.gif")`` a movie (Pillow) and ``save("m.mp4")`` one with ffmpeg.

Importing this module imports no matplotlib.
"""

from __future__ import annotations

import html
import re
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import ModelError
from . import charts
from .limits import refuse

__all__ = ["Animation"]
#: Colours of the shapes, in turn (matplotlib's tab10).
PALETTE = ("#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f", "#bcbd22",
           "#17becf")
_STYLE = {  # matplotlib keywords by shape kind
    "line": dict(lw=4, solid_capstyle="round", zorder=2),
    "link": dict(lw=1.2, ls="--", zorder=1),
    "point": dict(ls="none", marker="o", ms=11, zorder=3),
    "joint": dict(ls="none", marker="o", ms=6, mfc="white", mew=1.5, zorder=4),
    "ground": dict(ls="none", marker="^", ms=12, color="0.35", zorder=0),
}


#: The player's buttons, as text in glyphs common fonts hold (matplotlib's player draws them with a web font from
#: a CDN): first frame, previous, play backwards, pause, play, next, last; slower, faster.
_ICONS = {"fa-fast-backward": "|&#x25C0;", "fa-step-backward": "&#x2039;", "fa-play-reverse": "&#x25C0;",
          "fa-pause": "&#x2016;", "fa-play": "&#x25B6;", "fa-step-forward": "&#x203A;", "fa-fast-forward": "&#x25B6;|",
          "fa-minus": "&minus;", "fa-plus": "+"}


class Animation:
    """A mechanism's motion: ``shapes`` (``(name, kind, points)`` with ``points`` of shape ``frames × n × 3``, world
    coordinates; a planar model's third coordinate is zero) at ``times``.  Drawn in the plane (``dim`` 1 or 2) or
    in space (3).

    >>> import numpy as np
    >>> angle = np.linspace(0, np.pi, 5)
    >>> tip = np.stack([np.cos(angle), np.sin(angle), 0 * angle], axis=-1)[:, None, :]
    >>> a = Animation("swing", angle, [("tip", "point", tip)], dim=2)
    >>> len(a), a.position("tip", 4).round(12).tolist()
    (5, [[-1.0, 0.0, 0.0]])
    """

    def __init__(self, title: str, times: np.ndarray, shapes: Sequence[tuple[str, str, np.ndarray]], dim: int,
                 fps: float = 20, size: tuple[float, float] = (6.4, 4.8), dpi: int = 100):
        self.title, self.times, self.dim = title, np.asarray(times, dtype=float), dim
        self.shapes = [(name, kind, np.asarray(points, dtype=float)) for name, kind, points in shapes]
        refuse("an animation", self.times.size, "frames")
        for name, kind, points in self.shapes:
            if kind not in _STYLE:
                raise ModelError(f"shape {name!r}: unknown kind {kind!r}; one of {', '.join(_STYLE)}.")
            if points.ndim != 3 or points.shape[0] != self.times.size or points.shape[2] != 3:
                raise ModelError(f"shape {name!r}: points of shape {points.shape}, expected "
                                 f"({self.times.size}, n, 3): frames, points, coordinates.")
            if not np.all(np.isfinite(points)):
                frame = int(np.argwhere(~np.isfinite(points))[0][0])
                raise ModelError(f"shape {name!r} has no finite position at t = {self.times[frame]:.6g}: the run "
                                 f"left the mechanism's geometry (a singular configuration?).")
        self.fps, self.size, self.dpi = float(fps), size, int(dpi)
        self._drawn: tuple | None = None
        self._player: str | None = None

    def __len__(self) -> int:
        return self.times.size

    def position(self, name: str, frame: int) -> np.ndarray:
        """The points of shape ``name`` at frame ``frame`` (``n × 3``, world coordinates)."""
        for shape, _, points in self.shapes:
            if shape == name:
                return points[frame]
        raise ModelError(f"the animation draws no shape {name!r}; it draws {', '.join(s[0] for s in self.shapes)}.")

    # -- drawing ---------------------------------------------------------------------------------------------

    def _limits(self) -> list[tuple[float, float]]:
        """Axis ranges that hold every shape at every frame, with a margin, equal in scale."""
        every = np.concatenate([p.reshape(-1, 3) for _, _, p in self.shapes]) if self.shapes else np.zeros((1, 3))
        lo, hi = every.min(axis=0), every.max(axis=0)
        axes = 3 if self.dim == 3 else 2
        centre = (lo + hi)[:axes] / 2
        half = max(float(np.max(hi[:axes] - lo[:axes])) / 2, 1e-9) * 1.15
        return [(c - half, c + half) for c in centre]

    @charts.plain
    def _draw(self):
        """The figure, its axes, one artist per shape and the time label (made once)."""
        if self._drawn is None:
            from matplotlib.figure import Figure

            fig = Figure(figsize=self.size, dpi=self.dpi)
            ax = fig.add_subplot(projection="3d") if self.dim == 3 else fig.add_subplot()
            limits = self._limits()
            ax.set_xlim(*limits[0])
            ax.set_ylim(*limits[1])
            if self.dim == 3:
                ax.set_zlim(*limits[2])
                ax.set_box_aspect((1, 1, 1))
                ax.set_zlabel("z (m)")
            else:
                ax.set_aspect("equal")
                if self.dim == 1:
                    ax.set_yticks([])
            ax.set_xlabel("x (m)")
            ax.set_ylabel("y (m)" if self.dim > 1 else "")
            artists = []
            colours = iter(PALETTE * (1 + len(self.shapes) // len(PALETTE)))
            for name, kind, points in self.shapes:
                style = dict(_STYLE[kind])
                if "color" not in style:
                    style["color"] = next(colours)
                    if kind == "joint":
                        style["mec"] = style["color"]
                data = points[0]
                if self.dim == 3:
                    (artist,) = ax.plot(data[:, 0], data[:, 1], data[:, 2], label=name, **style)
                else:
                    (artist,) = ax.plot(data[:, 0], data[:, 1], label=name, **style)
                artists.append(artist)
            label = ax.set_title(f"{self.title}    t = {self.times[0]:.3f} s")  # (room for it, in the layout)
            if len(self.shapes) <= 12:
                ax.legend(loc="upper right", fontsize=7, frameon=False)
            fig.tight_layout()
            self._drawn = (fig, ax, artists, label)
        return self._drawn

    def figure(self, frame: int = 0):
        """The matplotlib ``Figure`` showing frame ``frame`` (drawn, so its pixels are there to read)."""
        fig = self._draw()[0]
        self._show(frame)
        fig.canvas.draw()
        return fig

    def _show(self, frame: int) -> list:
        fig, ax, artists, label = self._draw()
        for artist, (_, _, points) in zip(artists, self.shapes):
            data = points[frame]
            if self.dim == 3:
                artist.set_data_3d(data[:, 0], data[:, 1], data[:, 2])
            else:
                artist.set_data(data[:, 0], data[:, 1])
        label.set_text(f"{self.title}    t = {self.times[frame]:.3f} s")
        return [*artists, label]

    def pixels(self, name: str, frame: int) -> np.ndarray:
        """Where shape ``name``'s points are drawn at ``frame``: ``n × 2`` pixel coordinates (column, row from the
        top left) of the frame's image, at the animation's ``dpi``."""
        fig = self.figure(frame)
        ax = fig.axes[0]
        points = self.position(name, frame)
        if self.dim == 3:
            from mpl_toolkits.mplot3d import proj3d

            x, y, _ = proj3d.proj_transform(points[:, 0], points[:, 1], points[:, 2], ax.get_proj())
            xy = np.column_stack([x, y])
        else:
            xy = points[:, :2]
        display = ax.transData.transform(xy)
        height = fig.get_size_inches()[1] * fig.dpi
        return np.column_stack([display[:, 0], height - display[:, 1]])

    def colour(self, name: str) -> str:
        """The colour shape ``name`` is drawn in, as ``#rrggbb``."""
        from matplotlib.colors import to_hex

        _, _, artists, _ = self._draw()
        for artist, (shape, _, _) in zip(artists, self.shapes):
            if shape == name:
                return to_hex(artist.get_color())
        raise ModelError(f"the animation draws no shape {name!r}; it draws {', '.join(s[0] for s in self.shapes)}.")

    def _animation(self):
        from matplotlib.animation import FuncAnimation

        fig, _, _, _ = self._draw()
        return FuncAnimation(fig, self._show, frames=len(self), interval=1000 / self.fps, blit=False)

    # -- outputs ---------------------------------------------------------------------------------------------

    def to_jshtml(self) -> str:
        """The player (frames as embedded images, a time slider, play and pause) as an HTML fragment that needs
        no network: matplotlib's player, its buttons' icons (a web font it links from a CDN) written as text.  Made
        once (about 60 ms a frame at the default size): showing it again, or saving it as a page, reuses it."""
        if self._player is None:
            self._player = self._make_player()
        return self._player

    def _make_player(self) -> str:
        import matplotlib as mpl

        size = len(self) * self.size[0] * self.size[1] * self.dpi**2 * 0.2 / 2**20  # a PNG frame's MB, generously
        with mpl.rc_context({"animation.embed_limit": max(20.0, 2 * size)}):
            player = self._animation().to_jshtml(fps=self.fps, default_mode="loop")
        player = re.sub(r'<link rel="stylesheet"\s+href="https?://[^"]*font-awesome[^"]*">', "", player)
        return re.sub(r'<i class="fa (fa-[a-z-]+)( fa-flip-horizontal)?"></i>',
                      lambda m: _ICONS["fa-play-reverse" if m.group(2) else m.group(1)], player)

    def _repr_html_(self) -> str:
        return self.to_jshtml()

    def to_html(self) -> str:
        """A page of its own holding the player: it needs no network and no file beside it."""
        title = html.escape(self.title)
        return (f"<!DOCTYPE html>\n<html lang=\"en\">\n<head><meta charset=\"utf-8\"><title>{title}</title></head>\n"
                f"<body>\n{self.to_jshtml()}\n</body>\n</html>\n")

    def save(self, path: Any) -> Path:
        """Write the animation: ``.html`` (the player, a page of its own), ``.gif`` (Pillow) or ``.mp4`` (ffmpeg,
        which must be on ``PATH``).  Returns the path."""
        path = Path(path)
        suffix = path.suffix.lower()
        if suffix in (".html", ".htm"):
            path.write_text(self.to_html(), encoding="utf-8")
            return path
        if suffix == ".gif":
            from matplotlib.animation import PillowWriter

            self._animation().save(str(path), writer=PillowWriter(fps=self.fps), dpi=self.dpi)
            return path
        if suffix == ".mp4":
            from matplotlib.animation import FFMpegWriter, writers

            if not writers.is_available("ffmpeg"):
                raise ModelError(f"{path}: writing an .mp4 needs ffmpeg on PATH (apt-get install ffmpeg); "
                                 f"or write a .gif or an .html page.")
            self._animation().save(str(path), writer=FFMpegWriter(fps=self.fps), dpi=self.dpi)
            return path
        raise ModelError(f"{path}: an animation is written as .html, .gif or .mp4, not {suffix or 'a file without a suffix'}.")
