"""The repository stands on its own: nothing points at files a user who clones it lacks.

The product (README, docs, code, --help, the report, examples, benchmarks,
tests) states its semantics in its own words (docs/semantics.md) and cites
the paper by what it is, never by a path outside the repository.
"""

from __future__ import annotations

import re
from pathlib import Path

import click
import pytest

ROOT = Path(__file__).resolve().parents[1]
FORBIDDEN = re.compile(r"shared/|SPEC\.md|SPEC §|SPEC's")
TREES = ("README.md", "CHANGELOG.md", "docs", "src", "examples", "benchmarks", "tests", ".ci",
         "firmware", "mkdocs.yml", "pyproject.toml")
SUFFIXES = {".md", ".py", ".toml", ".yml", ".c", ".h", ".cpp", ".ino", ".txt", ".html", ""}


def _files() -> list[Path]:
    out: list[Path] = []
    for name in TREES:
        path = ROOT / name
        if path.is_file():
            out.append(path)
        elif path.is_dir():
            out += [p for p in path.rglob("*") if p.is_file() and p.suffix in SUFFIXES
                    and "__pycache__" not in p.parts and p.name != Path(__file__).name
                    and not any(part.endswith(".egg-info") for part in p.parts)]
    return out


def test_no_file_points_outside_the_repository() -> None:
    hits = []
    for path in _files():
        try:
            text = path.read_text(encoding="utf-8")
        except UnicodeDecodeError:
            continue
        for no, line in enumerate(text.splitlines(), 1):
            if FORBIDDEN.search(line):
                hits.append(f"{path.relative_to(ROOT)}:{no}: {line.strip()}")
    assert hits == [], "\n".join(hits)


def test_help_texts_stand_alone() -> None:
    from esoarm.cli import cli

    root = click.Context(cli, info_name="esoarm")
    texts = [cli.get_help(root)]
    for name in cli.list_commands(root):
        cmd = cli.get_command(root, name)
        assert cmd is not None
        texts.append(cmd.get_help(click.Context(cmd, info_name=name, parent=root)))
    for text in texts:
        assert not FORBIDDEN.search(text), text
    assert "docs/semantics.md" in texts[0]


def test_semantics_page_has_the_sections_the_code_points_to() -> None:
    page = (ROOT / "docs" / "semantics.md").read_text(encoding="utf-8")
    for heading in ("## The paper", "## The sampled-data loop", "## Scenario format",
                    "## Output files and columns", "## Errors and exit codes"):
        assert f"\n{heading}\n" in page


@pytest.mark.parametrize("page", ["README.md", "docs/index.md"])
def test_the_paper_is_cited_by_what_it_is(page: str) -> None:
    text = (ROOT / page).read_text(encoding="utf-8")
    assert "extended state observer" in text.lower() and "lever-arm" in text
    assert "shared" not in text
