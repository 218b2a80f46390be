"""Loading scenarios: built-in names and TOML files, with overrides (the edge that validates)."""

from __future__ import annotations

import difflib
import tomllib
from importlib import resources
from pathlib import Path
from typing import Any

from esoarm import kinds as _kinds
from esoarm.scenario.errors import ScenarioError
from esoarm.scenario.schema import Scenario, _resolve_paths, build

__all__ = ["builtin_names", "load_scenario"]


def builtin_names(plant: str | None = None) -> list[str]:
    """Names of the scenarios shipped with the package (only those of plant kind ``plant``).

    Parameters
    ----------
    plant : str, optional
        A plant kind (``"lever-arm"``, ``"urdf"``, ...); None lists every built-in.

    Returns
    -------
    list of str
        Names, sorted, each loadable with :func:`load_scenario`.

    Examples
    --------
    >>> "test-1" in builtin_names() and "test-1" in builtin_names("lever-arm")
    True
    """
    root = resources.files("esoarm") / "scenarios"
    names = sorted(p.name[:-5] for p in root.iterdir() if p.name.endswith(".toml"))
    if plant is None:
        return names
    default = _kinds.PLANTS[0].KIND
    return [n for n in names
            if tomllib.loads(_builtin_text(n)).get("plant", {}).get("kind", default) == plant]


def _read_toml(text: str, source: str) -> dict[str, Any]:
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ScenarioError(f"{source}: TOML syntax error: {exc}") from None


def _builtin_text(name: str) -> str:
    return (resources.files("esoarm") / "scenarios" / f"{name}.toml").read_text(encoding="utf-8")


def load_scenario(
    scenario: str | Path | Scenario = "test-1",
    overrides: dict[str, Any] | list[str] | None = None,
) -> Scenario:
    """Load a scenario by built-in name or TOML path, with optional overrides.

    Parameters
    ----------
    scenario : str, Path or Scenario
        A built-in name (see :func:`builtin_names`), a path to a TOML file, or
        an existing :class:`Scenario`.
    overrides : dict or list of str, optional
        Dotted keys to change, e.g. ``{"observer.eps": 0.05}`` or
        ``["observer.eps=0.05", "observer.discretization=zoh"]``.

    Returns
    -------
    Scenario
        The validated, immutable scenario.

    Raises
    ------
    ScenarioError
        Unknown scenario, missing file, TOML syntax error, unknown key, wrong
        type, or a value out of range; the message names the key or file.

    Examples
    --------
    >>> scn = load_scenario("test-1", ["observer.eps=0.05", "controller.kind=pid"])
    >>> scn.observer.eps, scn.controller.kind, scn.n_samples
    (0.05, 'pid', 1000)
    >>> load_scenario("test-1", {"obs.eps": 0.05})
    Traceback (most recent call last):
    ...
    esoarm.scenario.ScenarioError: override: unknown key 'obs.eps'; did you mean 'observer.eps'?
    """
    if isinstance(scenario, Scenario):
        return scenario.with_overrides(overrides or {})
    text_name = str(scenario)
    path = Path(text_name)
    if text_name in builtin_names() and not path.suffix:
        source = f"built-in scenario '{text_name}'"
        data = _read_toml(_builtin_text(text_name), source)
        _resolve_paths(data, Path(str(resources.files("esoarm") / "scenarios")))
    elif path.suffix == ".toml" or path.exists() or "/" in text_name or "\\" in text_name:
        source = f"file '{text_name}'"
        if path.is_dir():
            raise ScenarioError(f"{source}: is a directory, expected a TOML file")
        if not path.is_file():
            raise ScenarioError(f"{source}: no such file")
        try:
            text = path.read_text(encoding="utf-8")
        except UnicodeDecodeError as exc:
            raise ScenarioError(f"{source}: not a text TOML file (byte 0x"
                                f"{exc.object[exc.start]:02x} at offset {exc.start} is not "
                                "UTF-8); a scenario is TOML text, see 'esoarm show test-1'"
                                ) from None
        except OSError as exc:
            raise ScenarioError(f"{source}: cannot read: {exc}") from None
        data = _read_toml(text, source)
        if not data:
            raise ScenarioError(f"{source}: sets no key (no table, no key=value line): a scenario "
                                "file holds at least the keys that differ from the defaults; start "
                                "from 'esoarm show test-1 > my-rig.toml'")
        data.setdefault("name", path.stem)
        _resolve_paths(data, path.resolve().parent)
    else:
        names = builtin_names()
        close = difflib.get_close_matches(text_name, names, n=1)
        hint = f"; did you mean '{close[0]}'?" if close else ""
        raise ScenarioError(
            f"unknown scenario '{text_name}': not a built-in ({', '.join(names)}) "
            f"nor a .toml file{hint}"
        )
    return build(data, overrides or {}, source=source)
