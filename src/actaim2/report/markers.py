"""Tables between marker comments in the repository's markdown, regenerated from records.

A generated table sits between two HTML comments (invisible when the markdown is rendered)::

    <!-- report:TABLE RECORD [RECORD ...] -->
    | ... the table, written by ``actaim2 report`` ... |
    <!-- /report:TABLE -->

TABLE is a name of ``tables.TABLES``; each RECORD a folder ``results/<RECORD>`` of the tree.
The files searched are README.md and every ``docs/**/*.md``.
"""
from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

from actaim2.report.records import Record, RecordError, load_record
from actaim2.report.tables import TABLES

BLOCK = re.compile(r"(?P<open><!-- report:(?P<table>[\w-]+)(?P<records>(?: +[\w.-]+)*) -->\n)"
                   r"(?P<body>.*?)"
                   r"(?P<close><!-- /report:(?P=table) -->)", re.S)


@dataclass(frozen=True)
class Block:
    path: Path
    table: str
    records: tuple[str, ...]
    body: str  # the text between the markers as it is
    expected: str  # the text the records give


def documents(root: Path) -> list[Path]:
    """README.md and the markdown under docs/, in a fixed order."""
    root = Path(root)
    return [p for p in [root / "README.md", *sorted((root / "docs").rglob("*.md"))] if p.is_file()]


def render(table: str, names: tuple[str, ...], root: Path, cache: dict[str, Record]) -> str:
    if table not in TABLES:
        raise RecordError(f"unknown report table {table!r} (known: {', '.join(TABLES)})")
    records = []
    for name in names:
        if name not in cache:
            cache[name] = load_record(root, name)
        records.append(cache[name])
    return "\n".join(TABLES[table](records)) + "\n"


def blocks(root: Path) -> list[Block]:
    """Every marked table of the documents, with what its records give; :class:`RecordError` names
    the file and marker of a missing record or unknown table."""
    cache: dict[str, Record] = {}
    found = []
    for path in documents(root):
        for m in BLOCK.finditer(path.read_text()):
            names = tuple(m["records"].split())
            try:
                expected = render(m["table"], names, root, cache)
            except RecordError as e:
                raise RecordError(f"{path.relative_to(root)}: report:{m['table']}: {e}") from None
            found.append(Block(path, m["table"], names, m["body"], expected))
    return found


def rewrite(root: Path) -> list[Path]:
    """Write every marked table from its records; returns the files that changed."""
    expected: dict[Path, list[str]] = {}
    for block in blocks(root):
        expected.setdefault(block.path, []).append(block.expected)
    changed = []
    for path, bodies in expected.items():
        text = path.read_text()
        queue = iter(bodies)
        new = BLOCK.sub(lambda m: m["open"] + next(queue) + m["close"], text)
        if new != text:
            path.write_text(new)
            changed.append(path)
    return changed
