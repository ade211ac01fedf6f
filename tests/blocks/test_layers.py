"""``blocks/`` is the bottom layer (architecture: imports point downward only): its modules
import nothing of loopworks but ``loopworks.blocks`` and ``loopworks.errors``; the list of
kind modules lives above it, in ``loopworks.catalog`` (issue 13 point 1)."""

from __future__ import annotations

import ast
from pathlib import Path

BLOCKS = Path(__file__).resolve().parents[2] / "src" / "loopworks" / "blocks"
ALLOWED = ("loopworks.blocks", "loopworks.errors")


def _imports(path: Path) -> list[tuple[int, str]]:
    """(line, module) of every absolute loopworks import in ``path``, at any depth."""
    found = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            found += [(node.lineno, alias.name) for alias in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            found.append((node.lineno, node.module))
    return [(line, name) for line, name in found
            if name == "loopworks" or name.startswith("loopworks.")]


def test_blocks_import_nothing_above_them() -> None:
    files = sorted(BLOCKS.glob("*.py"))
    assert len(files) > 10
    above = [f"{path.name}:{line}: {name}" for path in files for line, name in _imports(path)
             if not any(name == a or name.startswith(a + ".") for a in ALLOWED)]
    assert above == []


def test_the_scan_sees_an_upward_import(tmp_path: Path) -> None:
    bad = tmp_path / "bad.py"
    bad.write_text("def f():\n    from loopworks.catalog import kinds\n    import loopworks.sim\n")
    assert _imports(bad) == [(2, "loopworks.catalog"), (3, "loopworks.sim")]
