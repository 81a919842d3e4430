"""The speed-against-error report regenerates its table, plot and README block."""

from __future__ import annotations

import pytest

import report


@pytest.mark.slow
def test_report_runs_and_writes_table_plot_and_readme(tmp_path):
    readme = tmp_path / "README.md"
    readme.write_text(f"intro\n{report.START}\nold\n{report.END}\nend\n")
    rows = report.run(tmp_path, quick=True)
    assert (tmp_path / "report.png").stat().st_size > 10_000
    table = (tmp_path / "report.md").read_text()
    assert table.count("\n") == len(rows) + 2
    assert report.update_readme(readme, table)
    text = readme.read_text()
    assert "old" not in text and "| newton fd2 |" in text and text.endswith("end\n")
    # Every scene, every method; Newton's error falls with n on every scene.
    for scene in report.suite():
        for method in ("newton fd2", "newton fe4", "shooting"):
            own = [r for r in rows if r["scene"] == scene and r["method"] == method]
            for key in ("error", "shape"):
                errors = [r[key] for r in own if r["converged"]]
                assert len(errors) >= 4 and errors[-1] < errors[0] / 100, (method, key)
        assert {r["method"] for r in rows if r["scene"] == scene} >= {
            "newton fd2", "newton fe4", "shooting", "lm", "reference"}
