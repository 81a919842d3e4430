"""The command line: demo and track print, plot and save their results; help
shows every default; errors are one line."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

import softspine
from softspine.cli import main
from softspine.scenes import demo_robot_scene


def test_demo_writes_a_plot(tmp_path, capsys):
    out = tmp_path / "demo.png"
    assert main(["demo", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "converged" in printed and "tip position" in printed
    assert out.stat().st_size > 10_000
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_bad_scene_file_is_an_error_not_a_traceback(tmp_path, capsys):
    bad = tmp_path / "bad.json"
    bad.write_text('{"length": -1, "stiffness": {"kx": 1, "ky": 1, "kz": 1}}')
    assert main(["demo", "--scene", str(bad), "--out", str(tmp_path / "x.png")]) == 2
    assert "length: must be positive" in capsys.readouterr().err


def test_track_prints_a_summary_and_writes_a_plot(tmp_path, capsys):
    out = tmp_path / "track.png"
    assert main(["track", "--trajectory", "spiral", "--load", "0.06", "--points", "12",
                 "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "reached 12/12" in printed and "time per point" in printed
    assert "geometric" in printed
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_version_and_help_show_the_defaults(capsys):
    with pytest.raises(SystemExit) as done:
        main(["--version"])
    assert done.value.code == 0
    assert capsys.readouterr().out.strip() == f"softspine {softspine.__version__}"
    for command in ("demo", "track", "track-table"):
        with pytest.raises(SystemExit):
            main([command, "--help"])
        text = " ".join(capsys.readouterr().out.split())
        assert "(default:" in text, command
    with pytest.raises(SystemExit):
        main(["track", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert "tip mass, kg (default: 0.03)" in text and "--robot FILE" in text


def test_demo_saves_the_solution_as_npz_and_csv(tmp_path):
    assert main(["demo", "--no-plot", "--save", str(tmp_path / "sol.npz")]) == 0
    assert main(["demo", "--no-plot", "--save", str(tmp_path / "sol.csv")]) == 0
    sol = softspine.solve(demo_robot_scene())
    saved = np.load(tmp_path / "sol.npz")
    assert np.array_equal(saved["positions"], sol.positions)
    assert str(saved["status"]) == "converged"
    table = np.loadtxt(tmp_path / "sol.csv", delimiter=",", skiprows=1)
    assert table.shape == (sol.n_elements + 1, 14)
    assert np.array_equal(table[:, 1:4], sol.positions)
    assert np.array_equal(table[:, 11:14], sol.moments)
    # What np.load gives back (0-d arrays for the scalars, the None fields
    # left out) is a solution again: it failed with "solution.n_elements:
    # expected an integer, got ndarray", then "tip_reaction_force: missing".
    again = softspine.Solution.from_dict(dict(np.load(tmp_path / "sol.npz")))
    assert again.n_elements == sol.n_elements and again.status == "converged"
    assert again.tip_reaction_force is None and again.stable == sol.stable
    np.testing.assert_array_equal(again.positions, sol.positions)
    np.testing.assert_array_equal(again.quaternions, sol.quaternions)


def test_track_reads_a_robot_and_a_trajectory_file_and_saves_csv(tmp_path, capsys):
    robot = {"sections": 3, "length": 0.6}
    (tmp_path / "robot.json").write_text(json.dumps(robot))
    targets = np.array([[0.1, 0.0, -0.55], [0.12, 0.02, -0.54], [0.1, 0.05, -0.55]])
    (tmp_path / "path.csv").write_text(
        "x,y,z\n" + "\n".join(",".join(map(str, p)) for p in targets) + "\n")
    out = tmp_path / "track.csv"
    assert main(["track", "--robot", str(tmp_path / "robot.json"), "--trajectory",
                 str(tmp_path / "path.csv"), "--load", "0", "--no-plot", "--save",
                 str(out)]) == 0
    assert "reached 3/3" in capsys.readouterr().out
    lines = out.read_text().splitlines()
    assert lines[0].startswith("target_x,target_y,target_z,tip_x") and len(lines) == 4
    assert lines[0].endswith("kappa2_x,kappa2_y")
    first = lines[1].split(",")
    expected = softspine.Robot(robot).inverse(targets[0])
    assert np.allclose([float(x) for x in first[3:6]], expected.tip_position, atol=1e-8)
    assert first[7] == "True" and first[8] == "reached"


def test_cli_errors_are_one_line(tmp_path, capsys):
    bad = tmp_path / "bad.csv"
    bad.write_text("1,2\n")
    for argv, message in [
        (["track", "--trajectory", str(bad), "--no-plot"], "line 1: expected three numbers"),
        (["demo", "--no-plot", "--save", "x.txt"], "--save: expected a .csv or .npz file"),
        (["track", "--robot", str(tmp_path / "none.toml"), "--no-plot"], "none.toml"),
    ]:
        assert main(argv) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith("softspine: error: "), err
        assert message in err[0], err


@pytest.mark.parametrize("command", ["demo", "track"])
def test_without_matplotlib_the_error_says_no_plot(command):
    # Issue 29, item 8: the demo on a machine without the plot extra names
    # the extra and the way around it, in one line, before any work.
    hide = ("import sys; sys.modules['matplotlib'] = None; "
            "from softspine.cli import main; sys.exit(main(sys.argv[1:]))")
    run = subprocess.run([sys.executable, "-c", hide, command], capture_output=True,
                         text=True, timeout=120)
    assert run.returncode == 2, run.stderr
    assert run.stderr.count("\n") == 1, run.stderr
    assert run.stderr.strip() == ("softspine: error: softspine's plots need matplotlib: "
                                  "pip install 'softspine[plot]'; or run with --no-plot")
    assert "scene:" not in run.stdout  # before any work
    ok = subprocess.run([sys.executable, "-c", hide, command, "--no-plot"],
                        capture_output=True, text=True, timeout=300)
    assert ok.returncode == 0, ok.stderr
