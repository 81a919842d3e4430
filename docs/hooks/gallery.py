"""MkDocs hook: the examples gallery, one page per script of ``examples/``
(its docstring as the text, its figure, ``docs/<script>.png``, where it draws
one, and its source as the code), built at every docs build so that it cannot
drift from the scripts the tests run."""

from __future__ import annotations

import ast
from pathlib import Path

from mkdocs.structure.files import File

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"
DOCS = EXAMPLES.parent / "docs"


def figure(script: Path) -> Path:
    """Where the gallery takes the figure a script draws."""
    return DOCS / f"{script.stem}.png"


def _page(script: Path) -> str:
    source = script.read_text(encoding="utf-8")
    doc = ast.get_docstring(ast.parse(source)) or ""
    title, _, body = doc.partition("\n")
    shown = f"\n![{script.name}](../{script.stem}.png)\n" if figure(script).exists() else ""
    return f"# {script.name}\n\n{title}\n{body}\n{shown}\n```python\n{source}```\n"


def on_files(files, config):
    scripts = sorted(EXAMPLES.glob("*.py"))
    index = ["# Examples", "", "Runnable scripts from the repository's `examples/`; "
             "the test suite runs every one.", ""]
    for script in scripts:
        uri = f"examples/{script.stem}.md"
        files.append(File.generated(config, uri, content=_page(script)))
        summary = (ast.get_docstring(ast.parse(script.read_text())) or "").split("\n")[0]
        index.append(f"* [{script.name}]({script.stem}.md): {summary}")
    files.append(File.generated(config, "examples/index.md", content="\n".join(index) + "\n"))
    return files
