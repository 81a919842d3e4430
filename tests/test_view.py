"""``softspine.view`` (issue 29, item 10): a self-contained interactive page
whose parts stand where the answer says (the tube around the backbone, a
disk at each section end, each tendon at its offset, the tip frame, the
obstacles and the contact forces), rendered by headless Chromium (kaleido's)
to a picture that shows them."""

from __future__ import annotations

import json
import re
import subprocess
import sys

import numpy as np
import pytest

import softspine

go = pytest.importorskip("plotly.graph_objects")

TENDONS = "examples/robots/tendon_robot.toml"


@pytest.fixture(scope="module")
def tendon_robot():
    robot = softspine.Robot.from_file(TENDONS)
    return robot, robot.forward(tensions=[8, 0, 0, 0, 6, 0, 0, 0, 5], load=0.02)


def traces(fig, name):
    return [t for t in fig.data if t.name == name]


def test_the_page_is_self_contained_and_holds_the_figure(tmp_path, tendon_robot):
    robot, sol = tendon_robot
    path = tmp_path / "robot.html"
    fig = softspine.view(sol, path, robot=robot, title="tendon robot")
    page = path.read_text(encoding="utf-8")
    # plotly.js inside, nothing fetched: it opens offline.
    assert not re.search(r"<script[^>]+src=", page)
    assert "Plotly.newPlot" in page and len(page) > 1_000_000
    # The figure in the page is the one returned.
    shown = json.loads(re.search(r"Plotly\.newPlot\(\s*\"[^\"]+\",\s*(\[.*?\]),\s*\{",
                                 page, flags=re.S).group(1))
    assert len(shown) == len(fig.data)


def test_the_parts_stand_where_the_answer_says(tendon_robot):
    robot, sol = tendon_robot
    fig = softspine.view(sol, robot=robot, radius=0.002)
    # The tube: every vertex at the radius from its node, across the tangent.
    (tube,) = traces(fig, "backbone")
    vertices = np.stack([tube.x, tube.y, tube.z], axis=-1).reshape(len(sol.positions), -1, 3)
    off = vertices - np.asarray(sol.positions)[:, None, :]
    np.testing.assert_allclose(np.linalg.norm(off, axis=-1), 0.002, rtol=1e-12)
    tangents = np.asarray(sol.rotation_matrices)[:, :, 2]
    assert np.abs(np.einsum("kai,ki->ka", off, tangents)).max() < 1e-15
    # A disk at each section end, centred on the backbone.
    disks = traces(fig, "disks")
    assert len(disks) == robot.sections
    ends = np.asarray(sol.positions_at(robot.length * np.arange(1, 4) / 3))
    np.testing.assert_allclose([[d.x[0], d.y[0], d.z[0]] for d in disks], ends, atol=1e-12)
    # Each tendon from its offset at the base to its section's end.
    tendons = traces(fig, "tendons")
    fields = robot.to_dict()["tendons"]
    assert len(tendons) == len(fields) == 9
    base = np.asarray(sol.rotation_matrices)[0]
    for line, tendon in zip(tendons, fields, strict=True):
        start = np.array([line.x[0], line.y[0], line.z[0]])
        offset = np.r_[np.asarray(tendon["offset"]).reshape(-1, 2)[0], 0.0]
        np.testing.assert_allclose(start, sol.positions[0] + base @ offset, atol=1e-12)
        end_s = robot.length * tendon["section"] / 3
        end = np.array([line.x[-1], line.y[-1], line.z[-1]])
        reach = np.linalg.norm(np.asarray(tendon["offset"]).reshape(-1, 2)[-1])
        assert np.linalg.norm(end - sol.positions_at(end_s)) == pytest.approx(reach, rel=1e-12)
    # The tip frame along the tip's material axes.
    tip = np.asarray(sol.rotation_matrices)[-1]
    for axis in range(3):
        (arrow,) = [t for t in fig.data if t.name == f"tip d{axis + 1}"]
        direction = np.array([arrow.x[1] - arrow.x[0], arrow.y[1] - arrow.y[0],
                              arrow.z[1] - arrow.z[0]])
        np.testing.assert_allclose(direction, 0.1 * robot.length * tip[:, axis], atol=1e-15)


def test_obstacles_and_contact_forces_are_drawn():
    ball = {"shape": "sphere", "centre": [0.5, 0.5, -0.3], "radius": 0.1}
    floor = {"shape": "half_space", "point": [0.0, 0.0, -0.95], "normal": [0.0, 0.0, 1.0]}
    robot = softspine.Robot({"sections": 3, "obstacles": [ball, floor]})
    pressed = robot.forward([[0.5, 0.0]] * 3, load=0.03)
    assert len(pressed.contacts["force"]) > 0
    fig = softspine.view([pressed, robot.forward([[0.0, 0.0]] * 3)], robot=robot)
    assert len(traces(fig, "backbone 1")) == len(traces(fig, "backbone 2")) == 1
    (sphere,) = traces(fig, "obstacle 0")
    surface = np.stack([sphere.x, sphere.y, sphere.z], axis=-1)
    np.testing.assert_allclose(np.linalg.norm(surface - ball["centre"], axis=-1), 0.1)
    (forces,) = traces(fig, "contact forces")
    assert len(forces.x) == 3 * len(pressed.contacts["force"])
    assert len(traces(fig, "muscles")) == 2 * 3  # three muscles on each backbone


def test_a_contact_force_is_drawn_whole_with_its_friction():
    # The robot bent into a frictional wall slides down it: its arrow is the
    # wall's whole force on the rod, the friction beside the normal force.
    wall = {"shape": "half_space", "point": [0.15, 0, 0], "normal": [-1, 0, 0], "friction": 0.5}
    robot = softspine.Robot({"obstacles": [wall]})
    sol = robot.forward(np.tile([0.0, 0.6], (10, 1)), load=0.03)
    c = sol.contacts
    assert len(c["force"]) == 1 and np.linalg.norm(c["friction"][0]) > 0.1 * c["force"][0]
    (forces,) = traces(softspine.view(sol, robot=robot), "contact forces")
    arrow = np.array([forces.x[1] - forces.x[0], forces.y[1] - forces.y[0],
                      forces.z[1] - forces.z[0]])
    whole = c["force"][0] * c["normal"][0] + c["friction"][0]
    np.testing.assert_allclose(arrow, 0.1 * robot.length * whole / np.linalg.norm(whole),
                               atol=1e-12)


def test_headless_chromium_draws_the_robot(tmp_path, tendon_robot):
    # kaleido renders the figure in its own headless Chromium: the picture
    # shows the blue tube, the orange tendons and the grey disks.
    pytest.importorskip("kaleido")
    image = pytest.importorskip("matplotlib.image")
    robot, sol = tendon_robot
    path = tmp_path / "robot.png"
    softspine.view(sol, robot=robot).write_image(path, width=500, height=500)
    rgb = image.imread(path)[..., :3]
    def count(colour, tol=0.12):
        return int((np.abs(rgb - np.asarray(colour) / 255).max(axis=-1) < tol).sum())
    assert count((70, 130, 180), tol=0.2) > 500      # steelblue, shaded
    assert count((255, 140, 0)) > 100                # darkorange
    assert count((128, 128, 128), tol=0.2) > 100     # grey disks


def test_bad_results_are_refused_by_name():
    with pytest.raises(ValueError, match="result: nothing to draw"):
        softspine.view([])
    with pytest.raises(TypeError, match="result\\[0\\]: expected a Solution or an IkResult"):
        softspine.view(42)  # type: ignore[arg-type]


def test_without_plotly_the_error_names_the_extra():
    code = ("import sys; sys.modules['plotly'] = None; sys.modules['plotly.graph_objects'] = None;"
            "import softspine; softspine.view(softspine.solve({'length': 1.0, "
            "'stiffness': {'kx': 1, 'ky': 1, 'kz': 1}}))")
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=120)
    assert run.returncode == 1
    assert "softspine.view needs plotly: pip install 'softspine[view]'" in run.stderr
