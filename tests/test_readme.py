"""The README's set-up commands and generated tables stay true."""

from __future__ import annotations

import re
from pathlib import Path

from esoarm.scenario.keys_doc import scenario_keys_markdown

ROOT = Path(__file__).resolve().parents[1]
README = (ROOT / "README.md").read_text(encoding="utf-8")


def test_scenario_key_table_matches_schema() -> None:
    block = re.search(r"<!-- scenario-keys:start -->\n(.*?)<!-- scenario-keys:end -->", README,
                      re.S)
    assert block is not None, "README lost its scenario-keys markers"
    assert block.group(1) == scenario_keys_markdown(), (
        "README scenario table drifted from the schema: regenerate with "
        "`python -m esoarm.scenario.keys_doc`"
    )


def test_readme_opens_with_the_two_setup_commands() -> None:
    first_block = re.search(r"```bash\n(.*?)```", README, re.S)
    assert first_block is not None
    lines = first_block.group(1).strip().splitlines()
    assert lines[0].endswith("esoarm reproduce")
    assert "pytest" in lines[1]


def test_ci_runs_the_readme_test_command() -> None:
    first_block = re.search(r"```bash\n(.*?)```", README, re.S)
    assert first_block is not None
    test_command = first_block.group(1).strip().splitlines()[1]
    assert test_command in (ROOT / ".ci" / "run").read_text(encoding="utf-8")


def test_every_cli_command_is_in_the_readme() -> None:
    from esoarm.cli import COMMANDS

    for name in COMMANDS:
        assert f"`esoarm {name}" in README, f"README's CLI table misses `esoarm {name}`"
