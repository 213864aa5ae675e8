"""The documentation as a reader meets it: README blocks run as written, gallery outputs free of machine paths,
animations drawn where the kinematics put the bodies (in a real browser), notebook charts shown once.

- ``readme_blocks_standalone``: every Python block of the README, run on its own in a fresh interpreter from a
  directory holding the repository's ``examples`` (as from a clone's root): passed/total.
- ``gallery_path_leaks``: outputs of the built gallery (``make docs`` first; ``--build`` builds it) that print a
  path of the machine that built them (a temporary directory, the checkout, a home, ``site-packages``).
- ``animation_pixel_error_px``: a bob 0.4 m below its pivot, animated (``Result.animate``) and written as a page;
  headless Chromium shows the page at 1280×800 at two times (the player set to two frames) and takes a screenshot
  of each; the largest distance, in pixels, between the centre of the bob's disc of colour in the screenshot and
  the pixel its closed-form position ``(0.4 sin θ, −0.4 cos θ)`` maps to.  ``null`` where Chromium is not
  installed (``apt-get install chromium``).
- ``duplicate_figures``: cells of the notebook (``examples/notes.ipynb``, executed by nbclient with matplotlib's
  inline backend, as in Jupyter) that show one chart twice.

Run: ``.venv/bin/python benchmarks/docs_check.py [--build] [--jobs 2]``.  Prints a table and, as its last line, a
JSON object.
"""

from __future__ import annotations

import argparse
import concurrent.futures
import hashlib
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
PYTHON = sys.executable
#: What a machine's own path looks like in an output.
MACHINE_PATH = re.compile(r"(/tmp/|/var/folders/|/private/var/|/home/\w|/root/|/Users/\w|site-packages|"
                          + re.escape(str(ROOT)) + r")")


def readme_blocks(jobs: int) -> tuple[int, int, list[str]]:
    """(passed, total, the first lines of those that failed)."""
    readme = (ROOT / "README.md").read_text()
    blocks = re.findall(r"```python\n(.*?)```", readme, re.S)
    plugin = next(b for b in blocks if "register_component_types" in b)

    def run(block: str) -> bool:
        with tempfile.TemporaryDirectory() as work:
            (Path(work) / "examples").symlink_to(ROOT / "examples")
            (Path(work) / "my_plugin.py").write_text(plugin)
            env = {**os.environ, "MPLBACKEND": "Agg", "PYTHONPATH": work}
            done = subprocess.run([PYTHON, "-c", block], cwd=work, env=env, capture_output=True, text=True,
                                  timeout=600)
            return done.returncode == 0

    with concurrent.futures.ThreadPoolExecutor(jobs) as pool:
        ok = list(pool.map(run, blocks))
    return sum(ok), len(blocks), [b.strip().splitlines()[0] for b, good in zip(blocks, ok) if not good]


def gallery_leaks(build: bool) -> tuple[int | None, list[str]]:
    """(outputs of the gallery that print a machine path, where), or ``None`` where no gallery is built."""
    html = ROOT / "docs" / "_build" / "html"
    if build:
        subprocess.run(["make", "-C", str(ROOT), "docs"], check=True)
    pages = sorted((html / "gallery").glob("*.html")) if (html / "gallery").is_dir() else []
    if not pages:
        return None, []
    leaks = []
    for page in pages:
        text = page.read_text(encoding="utf-8")
        for out in re.findall(r'<div class="sphx-glr-script-out[^"]*".*?</pre>', text, re.S):
            hit = MACHINE_PATH.search(out)
            if hit:
                leaks.append(f"{page.name}: …{out[max(0, hit.start() - 40):hit.end() + 40]!r}…")
    return len(leaks), leaks


def _browser() -> str | None:
    return next((shutil.which(n) for n in ("chromium", "chromium-browser", "google-chrome") if shutil.which(n)), None)


def bob():
    """A bob 0.4 m below its pivot, released at 1.1 rad: its run (1.2 s) and the animation of 7 frames of it."""
    import lagrangian as lg

    m = lg.Model("bob", dim=2)
    m.add("body", "bob", "bob", m=0.3, inertia=2e-3)
    m.add("revolute", "j", ("ground", "bob"), child_point=(0, 0.4))
    m.add("gravity", "g")
    res = m.simulate(1.2, initial={"theta_j": 1.1}, velocity={"theta_j": 0.0}, points=121)
    return res, res.animate(frames=7)


def animation_pixels() -> tuple[float | None, list[str]]:
    """The largest pixel error of the bob in two screenshots, and what was measured."""
    browser = _browser()
    if browser is None:
        return None, ["Chromium not installed: apt-get install chromium"]
    res, anim = bob()
    page = anim.to_html()
    player = re.search(r"\b(anim[0-9a-f]+) = new Animation", page).group(1)
    fig = anim.figure(0)
    height = fig.get_size_inches()[1] * fig.dpi
    box = fig.axes[0].get_legend().get_window_extent()
    colour = np.array([int(anim.colour("bob.com")[i:i + 2], 16) for i in (1, 3, 5)])
    errors, notes = [], []
    with tempfile.TemporaryDirectory() as work:
        for frame in (1, 5):
            # the page as written, its body's margin set to zero (the player's image at the top left) and the
            # player moved to ``frame`` once it is made
            shown = page.replace("<body>", "<body style=\"margin:0\">", 1).replace(
                "</body>", f"<script>window.addEventListener('load', () => setTimeout(() => "
                           f"{player}.set_frame({frame}), 200));</script>\n</body>", 1)
            path = Path(work) / f"frame{frame}.html"
            path.write_text(shown, encoding="utf-8")
            shot = Path(work) / f"frame{frame}.png"
            subprocess.run([browser, "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                            "--disable-background-networking", "--disable-component-update", "--disable-sync",
                            f"--user-data-dir={work}/profile", "--hide-scrollbars", "--window-size=1280,800",
                            "--virtual-time-budget=3000", f"--screenshot={shot}", path.as_uri()],
                           capture_output=True, timeout=120, check=True)
            from PIL import Image

            image = np.asarray(Image.open(shot).convert("RGB")).astype(int)
            rows, cols = np.nonzero(np.all(np.abs(image - colour) <= 40, axis=-1))
            inside = (cols < fig.get_size_inches()[0] * fig.dpi) & (rows < height)
            legend = (cols >= box.x0 - 2) & (cols <= box.x1 + 2) & (rows >= height - box.y1 - 2) & \
                     (rows <= height - box.y0 + 2)
            keep = inside & ~legend
            k = int(np.argmin(np.abs(res.t - anim.times[frame])))
            theta = res["theta_j"][k]
            expected = anim.figure(frame).axes[0].transData.transform([[0.4 * np.sin(theta), -0.4 * np.cos(theta)]])[0]
            expected[1] = height - expected[1]
            seen = np.array([cols[keep].mean(), rows[keep].mean()]) if keep.sum() > 20 else np.array([np.inf] * 2)
            errors.append(float(np.hypot(*(seen - expected))))
            notes.append(f"frame {frame} (t = {anim.times[frame]:.2f} s): bob at ({seen[0]:.1f}, {seen[1]:.1f}) px, "
                         f"predicted ({expected[0]:.1f}, {expected[1]:.1f})")
    return max(errors), notes


def duplicate_figures() -> tuple[int, int]:
    """(cells showing one image twice, cells with an image) of the notebook, executed as Jupyter does: images as
    outputs of their own (PNG, SVG) and inside objects' HTML (a run's summary, a comparison's table and chart)."""
    import nbclient
    import nbformat

    nb = nbformat.read(ROOT / "examples" / "notes.ipynb", as_version=4)
    with tempfile.TemporaryDirectory() as work:
        (Path(work) / "examples").symlink_to(ROOT / "examples")
        nbclient.NotebookClient(nb, timeout=600, kernel_name="python3", resources={"metadata": {"path": work}}).execute()
    twice = pictured = 0
    for cell in nb.cells:
        data = [o.get("data", {}) for o in cell.get("outputs", [])]
        images = [d[kind] for d in data for kind in ("image/png", "image/svg+xml") if kind in d]
        images += [src for d in data for src in re.findall(r'src="data:image/[^"]+"', d.get("text/html", ""))]
        images = [hashlib.sha256(str(i).encode()).hexdigest() for i in images]
        pictured += bool(images)
        twice += len(images) != len(set(images))
    return twice, pictured


def main() -> None:
    parser = argparse.ArgumentParser(description=(__doc__ or "").partition("\n")[0])
    parser.add_argument("--build", action="store_true", help="build the documentation first (make docs)")
    parser.add_argument("--jobs", type=int, default=2, help="README blocks run at once")
    args = parser.parse_args()
    passed, total, failed = readme_blocks(args.jobs)
    leaks, where = gallery_leaks(args.build)
    pixel, measured = animation_pixels()
    twice, pictured = duplicate_figures()
    print(f"{'README Python blocks that run on their own':48s} {passed}/{total}" + "".join(f"\n    failed: {f}" for f in failed))
    print(f"{'gallery outputs printing a machine path':48s} {'not built (make docs)' if leaks is None else leaks}"
          + "".join(f"\n    {w}" for w in where[:10]))
    print(f"{'animation: largest pixel error in Chromium':48s} {'n/a' if pixel is None else f'{pixel:.2f} px'}"
          + "".join(f"\n    {n}" for n in measured))
    print(f"{'notebook cells showing a chart twice':48s} {twice} (of {pictured} with charts)")
    print(json.dumps({"readme_blocks_standalone": f"{passed}/{total}", "gallery_path_leaks": leaks,
                      "animation_pixel_error_px": None if pixel is None else round(pixel, 2),
                      "duplicate_figures": twice}))


if __name__ == "__main__":
    main()
