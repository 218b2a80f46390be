"""MkDocs hooks: generate the reference pages from the code at build time.

Placeholders in the Markdown sources are replaced while the site is built,
so the published reference cannot drift from the code:

``<!-- esoarm:scenario-keys -->``
    the scenario key table, :func:`esoarm.scenario.keys_doc.scenario_keys_markdown`;
``<!-- esoarm:cli-reference -->``
    ``--help`` of ``esoarm`` and of every subcommand, walked from
    :data:`esoarm.cli.cli` (:func:`cli_reference_markdown`);
``<!-- esoarm:example NAME -->``
    the source of ``examples/NAME``;
``<!-- esoarm:paper-tables -->`` (also ``claims``, ``summary``, ``theorem2``, ``findings``,
``assumptions``, ``pole-table``)
    results of a reproduction run once per build (:func:`reproduction`), and
    its figures as generated files ``generated/<stem>.png``.

Every ``esoarm.<module>.<name>`` written in backticks in any page is
imported; a name that does not exist fails the build (so the theory page's
equation-to-function map stays true).  Pages of other engineers listed in the
navigation (hardware guide, protocol, benchmarks) are dropped from the
navigation while their file does not exist; pages not listed are added
(``benchmarks*.md`` to the Benchmarks section, others under "More").

Run ``mkdocs build --strict`` (CI does); ``python docs/hooks.py cli`` prints
the generated CLI reference.
"""

from __future__ import annotations

import importlib
import math
import re
import sys
from pathlib import Path

DOCS = Path(__file__).resolve().parent
ROOT = DOCS.parent
OPTIONAL_PAGES = ("hardware.md", "protocol.md", "benchmarks.md")

_REF = re.compile(r"`(esoarm(?:\.[A-Za-z_][A-Za-z0-9_]*)+)(?:\(\))?`")
_EXAMPLE = re.compile(r"<!-- esoarm:example ([A-Za-z0-9_.-]+) -->")


class DocsError(Exception):
    """A generated part of the docs cannot be built (fails ``mkdocs build``)."""


def cli_reference_markdown() -> str:
    """``--help`` of the ``esoarm`` group and of every subcommand, as Markdown.

    Groups are descended: ``esoarm log`` is followed by ``esoarm log import`` and every
    other command of the group, at any depth, each under its own heading.
    """
    import click

    from esoarm.cli import cli

    root = click.Context(cli, info_name="esoarm", terminal_width=100, max_content_width=100)
    parts = ["## `esoarm`\n", "```text\n" + cli.get_help(root) + "\n```\n"]

    def descend(group: click.Group, parent: click.Context, path: str) -> None:
        for name in group.list_commands(parent):
            cmd = group.get_command(parent, name)
            if cmd is None:
                raise DocsError(f"esoarm CLI: command '{path} {name}' is registered but "
                                "cannot be loaded")
            ctx = click.Context(cmd, info_name=name, parent=parent, terminal_width=100,
                                max_content_width=100)
            full = f"{path} {name}"
            parts.append(f"## `{full}`\n")
            parts.append("```text\n" + cmd.get_help(ctx) + "\n```\n")
            if isinstance(cmd, click.Group):
                descend(cmd, ctx, full)

    descend(cli, root, "esoarm")
    return "\n".join(parts)


def check_reference(dotted: str) -> None:
    """Import ``esoarm.a.b.c``: the longest importable module, then attributes."""
    parts = dotted.split(".")
    for cut in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:cut]))
        except ModuleNotFoundError:
            continue
        for attr in parts[cut:]:
            if not hasattr(obj, attr):
                raise DocsError(f"docs name `{dotted}`, but '{attr}' does not exist")
            obj = getattr(obj, attr)
        return
    raise DocsError(f"docs name `{dotted}`, which cannot be imported")


_REPRODUCTION: list = []


def reproduction():  # type: ignore[no-untyped-def]
    """One reproduction per build (cached): the numbers and figures of the results pages."""
    if not _REPRODUCTION:
        from esoarm.studies.reproduction.run import run_reproduction

        _REPRODUCTION.append(run_reproduction())
    return _REPRODUCTION[0]


def _md_table(head: list[str], rows: list[list[str]]) -> str:
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    lines += ["| " + " | ".join(c.replace("|", "\\|") for c in row) + " |" for row in rows]
    return "\n".join(lines) + "\n"


def _results_markdown(name: str) -> str:
    """Markdown for one results placeholder (see the module docstring)."""
    from esoarm.studies.reproduction.run import EPS_SET, PAPER_TABLES, TABLE_NAMES

    if name == "pole-table":
        ts = 0.02
        return "\n".join(f"| {e:g} | {ts / e:.3g} | {1 - ts / e:.4f} | {math.exp(-ts / e):.4f} |"
                         for e in (0.01, 0.015, 0.02, 0.03, 0.05, 0.09, 0.2)) + "\n"
    if name == "assumptions":
        from esoarm.studies.reproduction.report import assumption_rows
        from esoarm.studies.reproduction.run import experiment_set

        return _md_table(["key", "value", "unit", "why it is an assumption"],
                         [[f"`{k}`", f"`{v}`", u, w]
                          for k, v, u, w in assumption_rows(experiment_set())])
    rep = reproduction()
    if name == "paper-tables":
        out = []
        for test, table in TABLE_NAMES.items():
            rows = [[f"{e:g}", f"{PAPER_TABLES[test][e][0]:.4f}",
                     f"{rep.metric(test, e, 'rms_error'):.4f}", f"{PAPER_TABLES[test][e][1]:.4f}",
                     f"{rep.metric(test, e, 'rms_u'):.4f}"] for e in EPS_SET]
            out.append(f"**{table} — {test}** (RMS over the run; paper: hardware, twin: "
                       "digital twin)\n\n" + _md_table(
                           ["ε [s]", "error, paper [rad]", "error, twin [rad]",
                            "control, paper [N·m]", "control, twin [N·m]"], rows))
        return "\n".join(out)
    if name == "claims":
        rows = [["**reproduced**" if c.reproduced else "**not reproduced**", c.source,
                 c.statement, c.evidence] for c in rep.claims]
        n_ok = sum(c.reproduced for c in rep.claims)
        return (f"{n_ok} of {len(rep.claims)} claims reproduced.\n\n"
                + _md_table(["on the twin", "paper", "claim", "numbers behind it"], rows))
    if name == "theorem2":
        rows = [[c.theorem, f"`{c.run}`", " / ".join(f"{m:.3g}" for m in c.measured),
                 " / ".join(f"{b:.3g}" for b in c.bound), "holds" if c.holds else "**violated**"]
                for c in rep.bound_checks]
        return ("Measured over t ≥ 2 s. Theorem 1: max |θ − z1| [rad] / |θ̇ − z2| [rad/s] / "
                "|f − z3| [rad/s²]; Theorem 2: max |e| [rad] against μ/k2.\n\n"
                + _md_table(["theorem", "run", "measured", "bound", "verdict"], rows))
    if name == "summary":
        from esoarm.studies.reproduction.report import summary_text

        return summary_text(rep) + "\n"
    if name == "twins":
        from esoarm.studies.reproduction.twins import compared_twins, twins_markdown

        return twins_markdown(compared_twins({"nominal": rep}))
    if name == "findings":
        from esoarm.studies.reproduction.run import discretization_findings

        return "\n".join(f"- {s}" for s in discretization_findings(rep)) + "\n"
    raise DocsError(f"unknown placeholder esoarm:{name}")


_RESULTS = re.compile(
    r"<!-- esoarm:(paper-tables|claims|summary|theorem2|findings|assumptions|pole-table|twins)"
    r" -->")


def generated_figures() -> dict[str, bytes]:
    """PNG bytes of the reproduction's figures, by stem (fig4 … fig7, theorem2, ...)."""
    from esoarm.plotting.run import figure_bytes
    from esoarm.studies.reproduction.run import figure_specs

    return {stem: figure_bytes(draw(), "png", dpi=100)
            for stem, _caption, draw in figure_specs(reproduction())}


def render_placeholders(markdown: str, page: str) -> str:
    """Replace the placeholders of one page and check its ``esoarm.*`` names."""
    markdown = _RESULTS.sub(lambda m: _results_markdown(m.group(1)), markdown)
    if "<!-- esoarm:scenario-keys -->" in markdown:
        from esoarm.scenario.keys_doc import scenario_keys_markdown

        markdown = markdown.replace("<!-- esoarm:scenario-keys -->", scenario_keys_markdown())
    if "<!-- esoarm:cli-reference -->" in markdown:
        markdown = markdown.replace("<!-- esoarm:cli-reference -->", cli_reference_markdown())

    def example(match: re.Match[str]) -> str:
        path = ROOT / "examples" / match.group(1)
        if not path.is_file():
            raise DocsError(f"{page}: example '{match.group(1)}' not found in examples/")
        return f"```python\n{path.read_text(encoding='utf-8').rstrip()}\n```"

    markdown = _EXAMPLE.sub(example, markdown)
    for dotted in sorted(set(_REF.findall(markdown))):
        try:
            check_reference(dotted)
        except DocsError as exc:
            raise DocsError(f"{page}: {exc}") from None
    return markdown


def _filter_nav(nav: list, docs_dir: Path) -> list:
    out = []
    for item in nav:
        if isinstance(item, dict):
            (title, target), = item.items()
            if isinstance(target, list):
                target = _filter_nav(target, docs_dir)
                if target:
                    out.append({title: target})
            elif target not in OPTIONAL_PAGES or (docs_dir / target).is_file():
                out.append(item)
        elif item not in OPTIONAL_PAGES or (docs_dir / item).is_file():
            out.append(item)
    return out


# -- MkDocs hook entry points -----------------------------------------------------

def on_config(config, **kwargs):  # type: ignore[no-untyped-def]
    """Complete the nav from the files that exist.

    Optional pages that do not exist yet are dropped; ``benchmarks*.md`` files
    not listed are added to the Benchmarks section, and any other page not
    listed goes under "More" (titled by its first heading), so that a page
    added by someone else is never orphaned (orphans fail ``--strict``).
    """
    docs_dir = Path(config["docs_dir"])
    nav = config.get("nav")
    if nav:
        listed = set(_nav_files(nav))
        unlisted = [p.relative_to(docs_dir).as_posix() for p in sorted(docs_dir.rglob("*.md"))
                    if p.relative_to(docs_dir).as_posix() not in listed]
        nav = _filter_nav(nav, docs_dir)
        for name in unlisted:
            if Path(name).name.startswith("benchmarks"):
                section_name = "Benchmarks"
                rest = Path(name).stem.replace("benchmarks", "").strip("-_ ").replace("-", " ")
                title = f"Benchmarks: {rest}" if rest else "Benchmarks"
            else:
                section_name = "More"
                title = _first_heading(docs_dir / name)
            _section(nav, section_name).append({title: name})
        config["nav"] = nav
    return config


def _first_heading(path: Path) -> str:
    for line in path.read_text(encoding="utf-8").splitlines():
        if line.startswith("# "):
            return line[2:].strip()
    return path.stem.replace("-", " ").replace("_", " ").capitalize()


def _section(nav: list, name: str) -> list:
    for item in nav:
        if isinstance(item, dict) and isinstance(item.get(name), list):
            return item[name]
    section: list = []
    nav.append({name: section})
    return section


def _nav_files(nav: list) -> list[str]:
    out: list[str] = []
    for item in nav:
        target = next(iter(item.values())) if isinstance(item, dict) else item
        if isinstance(target, list):
            out += _nav_files(target)
        else:
            out.append(str(target))
    return out


def on_files(files, config, **kwargs):  # type: ignore[no-untyped-def]
    """Add the reproduction's figures as generated files ``generated/<stem>.png``.

    Only when a page refers to ``generated/`` (the reproduction takes seconds).
    """
    from mkdocs.structure.files import File

    docs_dir = Path(config["docs_dir"])
    if not any("generated/" in p.read_text(encoding="utf-8") for p in docs_dir.rglob("*.md")):
        return files

    for stem, png in generated_figures().items():
        files.append(File.generated(config, f"generated/{stem}.png", content=png))
    return files


def on_page_markdown(markdown, page, config, files, **kwargs):  # type: ignore[no-untyped-def]
    """Fill the generated parts of a page."""
    from mkdocs.exceptions import PluginError

    try:
        return render_placeholders(markdown, page.file.src_path)
    except DocsError as exc:
        raise PluginError(str(exc)) from None


if __name__ == "__main__":  # pragma: no cover
    if sys.argv[1:] == ["cli"]:
        print(cli_reference_markdown())
    else:
        print("usage: python docs/hooks.py cli", file=sys.stderr)
        sys.exit(2)
