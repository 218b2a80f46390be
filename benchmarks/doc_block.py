"""The block of a docs page between ``<!-- TAG -->`` and ``<!-- /TAG -->``, read and
rewritten by the benchmarks that write their tables into the docs."""

from __future__ import annotations

import re
from pathlib import Path


def _pattern(tag: str) -> re.Pattern[str]:
    return re.compile(rf"(<!-- {re.escape(tag)} -->\n)(.*?)(\n?<!-- /{re.escape(tag)} -->)", re.S)


def read_block(path: Path, tag: str) -> str:
    """The text between ``tag``'s markers in ``path`` (exit with a line naming the file and
    the tag where the markers are missing)."""
    m = _pattern(tag).search(Path(path).read_text(encoding="utf-8"))
    if m is None:
        raise SystemExit(f"{path}: no <!-- {tag} --> markers")
    return m.group(2)


def write_block(path: Path, tag: str, text: str) -> None:
    """Replace the text between ``tag``'s markers in ``path`` by ``text`` (one newline after
    it before the closing marker)."""
    path = Path(path)
    doc = path.read_text(encoding="utf-8")
    if _pattern(tag).search(doc) is None:
        raise SystemExit(f"{path}: no <!-- {tag} --> markers")
    body = text.rstrip("\n")
    path.write_text(_pattern(tag).sub(lambda m: m.group(1) + body + "\n" + m.group(3).lstrip("\n"),
                                      doc, count=1), encoding="utf-8")
