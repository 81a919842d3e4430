"""The demo command solves the demo scene and writes a PNG."""

from __future__ import annotations

from softspine.cli import main


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
