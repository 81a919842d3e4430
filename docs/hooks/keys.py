"""MkDocs hook: the key reference page (keys.md), generated at every docs
build from the core's tables (``softspine._core.keys()``, ``src/keys.rs``),
which the tests check against the keys the readers accept."""

from __future__ import annotations

from mkdocs.structure.files import File


def _table(rows: list[dict[str, str]]) -> list[str]:
    out = ["| key | unit | default | meaning |", "|---|---|---|---|"]
    for row in rows:
        cells = [f"`{row['name']}`", row["unit"], row["default"], row["meaning"]]
        out.append("| " + " | ".join(c.replace("|", "\\|") for c in cells) + " |")
    return out


def on_files(files, config):
    from softspine._core import keys

    tables = keys()
    lines = [
        "# Keys of a scene and a robot",
        "",
        "Every key the core reads, with its unit (SI), its default and its meaning;",
        "generated from the core (`src/keys.rs`), which the tests hold to the keys",
        "the readers accept. A key that is not here is refused by name. A scene is",
        "`softspine.Scene(d)` or `softspine.solve(d)`; a robot `softspine.Robot(d)`;",
        "both read the same keys from a `.json` or `.toml` file.",
        "",
        "## Scene",
        "",
        *_table(tables["scene"]),
        "",
        "## Robot",
        "",
        "A robot has one drive: the muscles' keys, the tendons' or the magnets'.",
        "",
        *_table(tables["robot"]),
        "",
    ]
    files.append(File.generated(config, "keys.md", content="\n".join(lines)))
    return files
