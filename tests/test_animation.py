"""Animations of mechanisms (``Result.animate``): the drawn positions against the bodies' kinematics written out
here in closed form, the pixels of the player's frames against where those positions fall, and the outputs
(a page of its own, a GIF) read back by their own readers."""

from __future__ import annotations

import base64
import importlib.util
import io
import pickle
import re
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st
from PIL import Image

import lagrangian as lg
from lagrangian.errors import ModelError

L1, L2 = 0.45, 0.3


def double_pendulum() -> lg.Model:
    m = lg.Model("double pendulum", dim=2)
    m.add("rod", "r1", "r1", m=0.3, length=L1)
    m.add("rod", "r2", "r2", m=0.2, length=L2)
    m.add("revolute", "j1", ("ground", "r1"))
    m.add("revolute", "j2", ("r1", "r2"), parent_point=(L1, 0))
    m.add("gravity", "g")
    return m


@pytest.fixture(scope="module")
def swing():
    m = double_pendulum()
    res = m.simulate(1.5, initial={"theta_j1": -0.7, "theta_j2": 0.9}, velocity={"theta_j1": 0.0, "theta_j2": 0.0},
                     points=301)
    return m, res, res.animate(frames=12)


def test_rods_are_drawn_where_their_kinematics_put_them(swing):
    """Each rod from its joint to its end: (L1 cos θ1, L1 sin θ1), then L2 along θ1 + θ2 (relative angles)."""
    _, res, anim = swing
    assert len(anim) == 12
    picked = [int(np.argmin(np.abs(res.t - t))) for t in anim.times]
    assert np.array_equal(res.t[picked], anim.times)  # frames are output times: nothing interpolated
    for frame, i in enumerate(picked):
        a, b = res["theta_j1"][i], res["theta_j2"][i]
        elbow = np.array([L1 * np.cos(a), L1 * np.sin(a), 0.0])
        tip = elbow + [L2 * np.cos(a + b), L2 * np.sin(a + b), 0.0]
        np.testing.assert_allclose(anim.position("r1", frame), [[0, 0, 0], elbow], rtol=0, atol=1e-12)
        np.testing.assert_allclose(anim.position("r2", frame), [elbow, tip], rtol=0, atol=1e-12)
        np.testing.assert_allclose(anim.position("j2", frame), [elbow], rtol=0, atol=1e-12)


def test_a_ball_in_space_is_drawn_where_its_kinematics_put_it():
    """A ball L below a spherical joint (body-fixed x, y, z angles): its centre at −R(α, β, γ)·(0, 0, L)."""
    L = 0.8
    m = lg.Model("ball", dim=3)
    m.add("body", "ball", "ball", m=0.3, inertia=(2e-3, 2e-3, 2e-3))
    m.add("spherical", "pivot", ("ground", "ball"), child_point=(0, 0, L))
    m.add("gravity", "g")
    names = m.coordinate_names
    res = m.simulate(0.8, initial=dict(zip(names, (0.4, -0.3, 0.2))), velocity=dict(zip(names, (0.5, 0.1, 0.0))),
                     points=81)
    anim = res.animate(frames=9)
    assert anim.dim == 3

    def rot(axis, angle):  # the right-handed turn by ``angle`` about axis 0 (x), 1 (y) or 2 (z)
        c, s = np.cos(angle), np.sin(angle)
        i, j = (axis + 1) % 3, (axis + 2) % 3
        R = np.eye(3)
        R[i, i], R[i, j], R[j, i], R[j, j] = c, -s, s, c
        return R

    for frame, time in enumerate(anim.times):
        k = int(np.argmin(np.abs(res.t - time)))
        R = rot(0, res[names[0]][k]) @ rot(1, res[names[1]][k]) @ rot(2, res[names[2]][k])
        np.testing.assert_allclose(anim.position("ball.com", frame)[0], -R @ [0, 0, L], rtol=0, atol=1e-12)


def _docs_check():
    """``benchmarks/docs_check.py``, which measures the same in a browser: its bob and its measurement."""
    spec = importlib.util.spec_from_file_location("docs_check", Path(__file__).resolve().parents[1] / "benchmarks" /
                                                  "docs_check.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _frames(page: str) -> list[np.ndarray]:
    """The player's frames, decoded from the page (RGB arrays)."""
    data = re.findall(r'data:image/png;base64,([A-Za-z0-9+/=\\\n]+)"', page)  # lines end in a backslash
    return [np.asarray(Image.open(io.BytesIO(base64.b64decode(re.sub(r"[\\\n]", "", d)))).convert("RGB"))
            for d in data]


def _centroid(image: np.ndarray, colour: str, outside) -> np.ndarray:
    """Mean (column, row) of the pixels of ``colour`` (within 40 per channel) outside the box ``outside``."""
    rgb = np.array([int(colour[i:i + 2], 16) for i in (1, 3, 5)])
    rows, cols = np.nonzero(np.all(np.abs(image.astype(int) - rgb) <= 40, axis=-1))
    (x0, y0), (x1, y1) = outside
    keep = ~((cols >= x0) & (cols <= x1) & (rows >= y0) & (rows <= y1))
    assert keep.sum() > 20, "the body's colour is not in the frame"
    return np.array([cols[keep].mean(), rows[keep].mean()])


def test_the_players_frames_show_the_body_where_its_position_falls():
    """A bob 0.4 m below its pivot: in two frames of the page, its disc of colour is centred on the pixel its
    closed-form position (0.4 sin θ, −0.4 cos θ) maps to through the frame's axes."""
    res, anim = _docs_check().bob()
    frames = _frames(anim.to_html())
    assert len(frames) == 7
    fig = anim.figure(0)
    height = fig.get_size_inches()[1] * fig.dpi
    box = fig.axes[0].get_legend().get_window_extent()
    legend = ((box.x0 - 2, height - box.y1 - 2), (box.x1 + 2, height - box.y0 + 2))
    for frame in (1, 5):
        k = int(np.argmin(np.abs(res.t - anim.times[frame])))
        theta = res["theta_j"][k]
        expected = anim.figure(frame).axes[0].transData.transform([[0.4 * np.sin(theta), -0.4 * np.cos(theta)]])[0]
        expected[1] = height - expected[1]
        seen = _centroid(frames[frame], anim.colour("bob.com"), legend)
        assert np.max(np.abs(seen - expected)) <= 2.0, (frame, seen, expected)


def test_a_page_of_its_own_and_a_gif(tmp_path, swing):
    _, res, anim = swing
    page = anim.save(tmp_path / "swing.html").read_text()
    assert page.startswith("<!DOCTYPE html>") and 'type="range"' in page  # the time slider
    assert "fa fa-" not in page  # the buttons are text, not a web font
    assert not re.search(r'<script[^>]+src=|<link[^>]+href=|src="https?:', page)  # nothing from outside
    assert len(_frames(page)) == 12
    gif = Image.open(res.animate(tmp_path / "swing.gif", frames=5).save(tmp_path / "swing.gif"))
    assert gif.n_frames == 5 and gif.size == (640, 480)


def test_a_pickled_result_is_animated_with_its_model(swing):
    m, res, _ = swing
    back = pickle.loads(pickle.dumps(res))
    with pytest.raises(ModelError, match=r"res.animate\(model=m\)"):
        back.animate(frames=2)
    np.testing.assert_array_equal(back.animate(model=m, frames=3).position("r1", 2),
                                  res.animate(frames=3).position("r1", 2))


def test_what_cannot_be_animated_is_refused_by_name(swing, tmp_path):
    _, res, anim = swing
    c = lg.Model("rc")
    c.add("voltage_source", "V1", ("in", "0"), E=1.0)
    c.add("resistor", "R1", ("in", "out"), R=1e3)
    c.add("capacitor", "C1", ("out", "0"), C=2.2e-6)
    with pytest.raises(ModelError, match="nothing in space to draw"):
        c.simulate(1e-3, initial={"q_R1": 0.0}, points=11).animate()
    for frames in (0, -3, 2.5, True):
        with pytest.raises(ModelError, match="frames must be a positive whole number"):
            res.animate(frames=frames)
    with pytest.raises(ModelError, match="lagrangian.limits.frames"):
        res.animate(frames=10**6)
    with pytest.raises(ModelError, match=r"\.html, \.gif or \.mp4"):
        anim.save(tmp_path / "swing.avi")
    with pytest.raises(ModelError, match="no shape 'r3'"):
        anim.position("r3", 0)


@settings(max_examples=15, deadline=None)
@given(k=st.floats(5.0, 5e3), m1=st.floats(0.05, 5.0), x0=st.floats(-0.5, 0.5).filter(lambda x: abs(x) > 1e-3))
def test_masses_on_a_line_are_drawn_at_their_coordinates(k, m1, x0):
    """A mass on a spring over decades of values: the mass at (x, 0), the spring from the ground to it."""
    m = lg.Model("osc")
    m.add("mass", "m1", "p", m=m1)
    m.add("spring", "k1", ("ground", "p"), k=k)
    res = m.simulate(1.0, initial={"x_p": x0}, velocity={"x_p": 0.0}, points=41)
    anim = res.animate(frames=5)
    for frame, time in enumerate(anim.times):
        x = res["x_p"][int(np.argmin(np.abs(res.t - time)))]
        assert abs(x - x0 * np.cos(np.sqrt(k / m1) * time)) <= 1e-7 * abs(x0)  # the run, against the closed form
        np.testing.assert_allclose(anim.position("p", frame), [[x, 0, 0]], rtol=0, atol=1e-14 * abs(x0))
        np.testing.assert_allclose(anim.position("k1", frame), [[0, 0, 0], [x, 0, 0]], rtol=0, atol=1e-14 * abs(x0))


def test_a_run_with_other_values_is_drawn_with_them():
    """``simulate(params=...)`` gives the rods other lengths for that run: the drawing takes the run's lengths."""
    m = double_pendulum()
    res = m.simulate(0.5, initial={"theta_j1": -0.7, "theta_j2": 0.9}, velocity={"theta_j1": 0.0, "theta_j2": 0.0},
                     points=51, params={"length_r1": 0.8, "parent_point_j2_0": 0.8, "length_r2": 0.25})
    anim = res.animate(frames=3)
    a, b = res["theta_j1"][-1], res["theta_j2"][-1]
    elbow = np.array([0.8 * np.cos(a), 0.8 * np.sin(a), 0.0])
    np.testing.assert_allclose(anim.position("r2", 2), [elbow, elbow + [0.25 * np.cos(a + b), 0.25 * np.sin(a + b), 0]],
                               rtol=0, atol=1e-12)


@pytest.mark.slow
def test_in_headless_chromium_the_body_is_where_its_kinematics_put_it():
    """The page as a browser shows it: headless Chromium at 1280×800, the player set to two frames, the bob's disc
    within 2 px of where its closed-form position falls (``benchmarks/docs_check.py`` prints the figure)."""
    docs_check = _docs_check()
    if docs_check._browser() is None:
        pytest.skip("Chromium is not installed (apt-get install chromium)")
    error, measured = docs_check.animation_pixels()
    assert error <= 2.0, measured
