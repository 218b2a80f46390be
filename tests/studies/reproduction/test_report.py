"""report.html: content taken from the runs, self-contained, and rendered in headless Chromium.

The browser test loads a copy of the report with a small checker script
injected at the top of <head> (the shipped report has no scripts).  The
checker records console errors, uncaught errors and resource load failures,
and after the load event writes, into the DOM, every image's ``complete`` and
``naturalWidth``; Chromium's ``--dump-dom`` returns that DOM.  Any console
message in Chromium's log (``--enable-logging=stderr``) also fails the test.
A screenshot of the whole page is kept under pytest's tmp path and copied to
``test-artifacts/report.png`` (git-ignored); the path is printed.
"""

from __future__ import annotations

import base64
import json
import os
import re
import shutil
import subprocess
from html.parser import HTMLParser
from pathlib import Path

import pytest

from esoarm import __version__
from esoarm.studies.reproduction.report import ASSUMPTIONS, assumption_rows
from esoarm.studies.reproduction.run import EPS_SET, PAPER_TABLES, run_reproduction, write_outputs

pytestmark = pytest.mark.slow  # end to end (the fast tier is -m 'not slow')

ROOT = Path(__file__).resolve().parents[3]
ARTIFACTS = ROOT / "test-artifacts"
CHROMIUM_FLAGS = (
    "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
    "--disable-background-networking", "--disable-component-update", "--disable-sync",
    "--hide-scrollbars", "--enable-logging=stderr", "--v=0",
)

CHECKER = """<script id="esoarm-checker">
(function () {
  var errors = [];
  var note = function (kind, text) { errors.push(kind + ": " + String(text)); };
  ["error", "warn"].forEach(function (level) {
    var orig = console[level];
    console[level] = function () {
      note("console." + level, Array.prototype.join.call(arguments, " "));
      return orig.apply(console, arguments);
    };
  });
  window.addEventListener("error", function (ev) {
    var t = ev.target;
    if (t && t !== window && (t.src || t.href)) { note("load failed", t.src || t.href); }
    else { note("uncaught", ev.message); }
  }, true);
  window.addEventListener("load", function () {
    var imgs = Array.prototype.map.call(document.images, function (img) {
      return {alt: img.alt, complete: img.complete, w: img.naturalWidth, h: img.naturalHeight};
    });
    var out = document.createElement("pre");
    out.id = "esoarm-check";
    out.textContent = JSON.stringify({errors: errors, images: imgs,
      height: document.documentElement.scrollHeight});
    document.body.appendChild(out);
  });
})();
</script>"""


def find_chromium() -> str | None:
    """Path of Debian's chromium (or another Chromium/Chrome on PATH)."""
    for name in ("/usr/bin/chromium", "chromium", "chromium-browser", "google-chrome"):
        path = shutil.which(name)
        if path:
            return path
    return None


def run_chromium(browser: str, profile: Path, *args: str) -> subprocess.CompletedProcess:
    env = {**os.environ, "HOME": str(profile)}  # keep the browser's files in the tmp dir
    return subprocess.run(
        [browser, *CHROMIUM_FLAGS, f"--user-data-dir={profile}", *args],
        capture_output=True, text=True, timeout=90, env=env, check=False)


def console_lines(stderr: str) -> list[str]:
    """Chromium log lines carrying page console output (``:CONSOLE``)."""
    return [line for line in stderr.splitlines() if ":CONSOLE" in line]


@pytest.fixture(scope="module")
def outputs(tmp_path_factory: pytest.TempPathFactory) -> tuple[object, Path]:
    rep = run_reproduction()
    out = tmp_path_factory.mktemp("reproduce")
    write_outputs(rep, out)
    return rep, out


@pytest.fixture(scope="module")
def html_text(outputs: tuple[object, Path]) -> str:
    return (outputs[1] / "report.html").read_text(encoding="utf-8")


class _Collect(HTMLParser):
    def __init__(self) -> None:
        super().__init__()
        self.tags: list[tuple[str, dict[str, str | None]]] = []
        self.text: list[str] = []

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        self.tags.append((tag, dict(attrs)))

    def handle_data(self, data: str) -> None:
        self.text.append(data)


def _parse(text: str) -> _Collect:
    parser = _Collect()
    parser.feed(text)
    return parser


def test_report_is_self_contained(html_text: str) -> None:
    page = _parse(html_text)
    tags = [t for t, _ in page.tags]
    assert "script" not in tags and "iframe" not in tags and "link" not in tags
    for tag, attrs in page.tags:
        for name in ("src", "href"):
            value = attrs.get(name)
            if value is None:
                continue
            # only embedded data and in-page anchors: nothing to fetch
            assert value.startswith(("data:", "#")), (tag, name, value[:80])
    imgs = [attrs for tag, attrs in page.tags if tag == "img"]
    assert len(imgs) == 7  # Fig. 4-7, Theorem 2, discretizations, frequency domain
    for attrs in imgs:
        src = attrs["src"] or ""
        assert src.startswith("data:image/png;base64,")
        assert base64.b64decode(src.split(",", 1)[1])[:8] == b"\x89PNG\r\n\x1a\n"
        assert attrs.get("alt")


def test_report_numbers_come_from_the_runs(outputs: tuple[object, Path], html_text: str) -> None:
    rep = outputs[0]
    text = " ".join(_parse(html_text).text)
    for test, table in PAPER_TABLES.items():
        for eps in EPS_SET:
            assert f"{table[eps][0]:.4f}" in text  # the paper's value, quoted
            assert f"{rep.metric(test, eps, 'rms_error'):.4f}" in text  # the twin's, computed
            assert f"{rep.metric(test, eps, 'rms_u'):.4f}" in text
    for claim in rep.claims:
        assert claim.evidence in text
    n_ok = sum(c.reproduced for c in rep.claims)
    assert f"{n_ok} of {len(rep.claims)} claims reproduced" in text
    assert f"esoarm {__version__}" in text
    for key, scn in rep.scenarios.items():
        assert key in text
        assert f'name = "{scn.name}"' in text  # the resolved TOML is embedded
    for check in rep.bound_checks:
        assert f"{check.driver:.4g}" in text


def test_assumption_values_are_read_from_the_scenarios(outputs: tuple[object, Path]) -> None:
    rep = outputs[0]
    changed = {k: s.with_overrides({"controller.k2": 16.0, "rig.coulomb_friction": 0.07})
               for k, s in rep.scenarios.items()}
    rows = {key: value for key, value, _unit, _why in assumption_rows(changed)}
    assert rows["controller.k2"] == "16.0"
    assert rows["rig.coulomb_friction"] == "0.07"
    rows = {key: (value, unit) for key, value, unit, _ in assumption_rows(rep.scenarios)}
    assert rows["controller.k1"] == ("10.0", "1/s")
    refs = [k for k in rows if k.startswith("reference")]
    assert len(refs) == 2 and any("multisine" in rows[k][0] for k in refs)  # test-1 ≠ test-2
    assert {k.split(" ")[0] for k in rows} == {k for k, _ in ASSUMPTIONS}


def test_report_renders_in_headless_chromium(outputs: tuple[object, Path], html_text: str,
                                             tmp_path: Path) -> None:
    browser = find_chromium()
    if browser is None:
        pytest.skip("no Chromium on this machine: install it with "
                    "`apt-get install -y chromium` (.ci/run does) to render report.html")
    page = tmp_path / "report-checked.html"
    page.write_text(html_text.replace("<head>", "<head>" + CHECKER, 1), encoding="utf-8")
    profile = tmp_path / "chromium-profile"
    dom = run_chromium(browser, profile, "--virtual-time-budget=10000",
                       "--window-size=1280,900", "--dump-dom", page.as_uri())
    assert dom.returncode == 0, dom.stderr[-2000:]
    match = re.search(r'<pre id="esoarm-check">(.*?)</pre>', dom.stdout, re.S)
    assert match, "the checker did not run (no load event?):\n" + dom.stderr[-2000:]
    check = json.loads(match.group(1).replace("&quot;", '"').replace("&amp;", "&")
                       .replace("&lt;", "<").replace("&gt;", ">"))
    assert check["errors"] == []
    assert console_lines(dom.stderr) == []
    assert len(check["images"]) == 7  # Fig. 4-7, Theorem 2, discretizations, frequency domain
    assert 'id="frequency"' in html_text
    for img in check["images"]:
        assert img["complete"] and img["w"] > 300 and img["h"] > 200, img
    # Screenshot of the whole page (height measured above), kept with the test output.
    height = min(int(check["height"]) + 40, 16000)
    shot = tmp_path / "report.png"
    res = run_chromium(browser, profile, f"--window-size=1280,{height}",
                       f"--screenshot={shot}", (outputs[1] / "report.html").as_uri())
    assert res.returncode == 0 and shot.is_file() and shot.stat().st_size > 10_000, res.stderr
    assert console_lines(res.stderr) == []
    ARTIFACTS.mkdir(exist_ok=True)
    (ARTIFACTS / ".gitignore").write_text("# written by the tests; not tracked\n*\n")
    kept = ARTIFACTS / "report.png"
    shutil.copyfile(shot, kept)
    shutil.copyfile(outputs[1] / "report.html", ARTIFACTS / "report.html")
    print(f"\nreport screenshot: {shot}\n           copy: {kept}")


def test_checker_catches_a_broken_image(tmp_path: Path) -> None:
    """The browser check can fail: a missing image and a console error are caught."""
    browser = find_chromium()
    if browser is None:
        pytest.skip("no Chromium on this machine: install it with `apt-get install -y chromium`")
    page = tmp_path / "broken.html"
    page.write_text("<!DOCTYPE html><html><head></head><body>"
                    '<img alt="x" src="data:image/png;base64,AAAA">'
                    '<img alt="y" src="missing.png"><p>text</p></body></html>', encoding="utf-8")
    text = page.read_text().replace("<head>", "<head>" + CHECKER, 1)
    text = text.replace("<p>text</p>", "<p>text</p><script>console.error('boom')</script>")
    page.write_text(text, encoding="utf-8")
    dom = run_chromium(browser, tmp_path / "profile", "--virtual-time-budget=5000",
                       "--dump-dom", page.as_uri())
    match = re.search(r'<pre id="esoarm-check">(.*?)</pre>', dom.stdout, re.S)
    assert match
    check = json.loads(match.group(1).replace("&quot;", '"').replace("&amp;", "&"))
    assert [img["w"] for img in check["images"]] == [0, 0]
    assert any("boom" in e for e in check["errors"])
    assert any("missing.png" in e for e in check["errors"])
    assert console_lines(dom.stderr)


def test_summary_is_computed_from_the_runs(outputs):
    from esoarm.studies.reproduction.report import summary_text
    from esoarm.studies.reproduction.run import TABLE_NAMES

    rep = outputs[0]
    text = summary_text(rep)
    for test in TABLE_NAMES:
        best = min(EPS_SET, key=lambda e, t=test: rep.metric(t, e, "rms_error"))
        assert f"ε = {best:g} s in {test}" in text
    for claim in rep.claims:
        part = text.split("Not reproduced:")[1 if not claim.reproduced else 0]
        assert claim.statement in part


def test_report_depends_only_on_the_reproduction_data() -> None:
    """No import cycle: the report reads a Reproduction, it never imports the runner."""
    import subprocess
    import sys

    code = ("import sys, esoarm.studies.reproduction.report as r; "
            "import esoarm.studies.reproduction.data; "
            "import inspect; inspect.getsource(r); "
            "print(sorted(m for m in sys.modules if m.startswith('esoarm.studies.')))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout
    assert "esoarm.studies.reproduction.run'" not in out and "reproduce_outputs" not in out
    import ast

    tree = ast.parse((ROOT / "src/esoarm/studies/reproduction/report.py").read_text())
    imported = {node.module for node in ast.walk(tree)
                if isinstance(node, ast.ImportFrom) and node.module}
    assert {m for m in imported if m.startswith("esoarm.studies")} == {
        "esoarm.studies.reproduction.data"}
