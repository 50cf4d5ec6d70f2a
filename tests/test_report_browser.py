"""``report/index.html`` as a person sees it: rendered by headless Chromium (Debian's ``chromium``).

The report is generated into ``tmp_path`` by ``python -m repro.report`` from the committed figures
(``report/figures``: PNGs and metrics, present in every clone), then opened in Chromium with a small
script that waits for the page to load and records every ``<img>`` that did not load
(``naturalWidth == 0``), whether the claims table is there (rows and columns), and the size of the
inline SVG verdict marks. On failure a screenshot of the page is written to
``tests/_failures/report_browser.png``.

``make system-deps`` (run by ``make test`` and ``.ci/run``) installs ``chromium`` with apt-get when it
runs as root; without it these tests are skipped with that reason.
"""

from __future__ import annotations

import json
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from experiments.claims import CLAIMS

ROOT = Path(__file__).resolve().parents[1]
FAILURES = ROOT / "tests" / "_failures"
CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser") or shutil.which("google-chrome")

pytestmark = pytest.mark.skipif(
    CHROMIUM is None,
    reason="chromium is not installed and could not be: `make system-deps` installs it only as root with "
           "apt-get (else: apt-get install chromium)")

#: Injected before </body> of a copy of the page: reports what the browser actually rendered.
_CHECK_SCRIPT = """
<script>
window.addEventListener('load', function () {
  var imgs = Array.from(document.images);
  var broken = imgs.filter(function (i) { return !(i.complete && i.naturalWidth > 0); })
                   .map(function (i) { return i.getAttribute('src'); });
  var table = document.getElementById('claims');
  var marks = Array.from(document.querySelectorAll('svg.mark')).map(function (s) {
    var r = s.getBoundingClientRect(); return [r.width, r.height]; });
  var out = document.createElement('pre'); out.id = 'browser-check';
  out.textContent = JSON.stringify({
    images: imgs.length, broken: broken, loaded_widths: imgs.map(function (i) { return i.naturalWidth; }),
    claims_table: !!table,
    claims_rows: table ? table.querySelectorAll('tr').length - 1 : 0,
    claims_columns: table ? table.querySelectorAll('tr')[0].children.length : 0,
    marks: marks.length, marks_drawn: marks.filter(function (m) { return m[0] > 0 && m[1] > 0; }).length});
  document.body.appendChild(out);
});
</script>
"""

_EMOJI = re.compile("[\U0001F000-\U0001FAFF\u2600-\u27BF\u2B50\u2B55\u26AA\u26AB\uFE0F]")


def _chromium(*args, timeout=120) -> subprocess.CompletedProcess:
    return subprocess.run([CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
                           "--hide-scrollbars", *args], capture_output=True, text=True, timeout=timeout)


def browser_check(page: Path, profile: Path) -> dict:
    """Open a copy of ``page`` (same folder, so relative image paths resolve) with the check script."""
    text = page.read_text(encoding="utf-8")
    assert "</body>" in text
    probe = page.with_name("_browser_check.html")
    probe.write_text(text.replace("</body>", _CHECK_SCRIPT + "</body>"), encoding="utf-8")
    proc = _chromium(f"--user-data-dir={profile}", "--virtual-time-budget=15000", "--dump-dom", probe.as_uri())
    m = re.search(r'<pre id="browser-check">(.*?)</pre>', proc.stdout, re.S)
    assert m, f"chromium printed no check result (rc {proc.returncode}): {proc.stderr[-2000:]}"
    return json.loads(m.group(1).replace("&quot;", '"').replace("&amp;", "&"))


def screenshot(page: Path, out: Path, profile: Path) -> None:
    out.parent.mkdir(parents=True, exist_ok=True)
    _chromium(f"--user-data-dir={profile}", "--window-size=1280,4000", "--virtual-time-budget=15000",
              f"--screenshot={out}", page.as_uri())


def _make_report(figures_src: Path, out: Path) -> Path:
    figs = out / "figures"
    figs.mkdir(parents=True)
    for f in figures_src.iterdir():
        if f.suffix in (".png", ".json", ".csv", ".parquet"):
            shutil.copy2(f, figs / f.name)
    proc = subprocess.run([sys.executable, "-m", "repro.report", "--figures", str(figs), "--out", str(out)],
                          cwd=ROOT, capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    return out / "index.html"


@pytest.fixture(scope="module")
def committed_report(tmp_path_factory) -> Path:
    """index.html generated from the committed report/figures into a temporary folder."""
    src = ROOT / "report" / "figures"
    assert any(src.glob("*.metrics.json")), "the committed report/figures has no metrics"
    return _make_report(src, tmp_path_factory.mktemp("committed") / "report")


def test_report_opens_in_chromium_with_every_image_and_the_claims_table(committed_report, tmp_path):
    src = ROOT / "report" / "figures"
    page = committed_report
    result = browser_check(page, tmp_path / "profile")
    try:
        assert result["images"] >= len(list(src.glob("*.metrics.json")))
        assert result["broken"] == [], f"images that did not load: {result['broken']}"
        assert all(w > 0 for w in result["loaded_widths"])
        assert result["claims_table"] and result["claims_rows"] == len(CLAIMS)
        assert result["claims_columns"] >= 3  # claim, where, one column per (preset, scene set)
        assert result["marks"] >= len(CLAIMS) and result["marks_drawn"] == result["marks"]
    except AssertionError:
        screenshot(page, FAILURES / "report_browser.png", tmp_path / "profile")
        raise


def test_browser_check_sees_a_missing_image(tmp_path):
    """The check can fail: a figure whose PNG is missing is reported as a broken image."""
    from experiments.results_table import write_results
    from tests.claims_tables import fig10

    figs = tmp_path / "src"
    figs.mkdir()
    write_results(figs, fig10(0.001), {})
    (figs / "fig10.metrics.json").write_text(json.dumps({"title": "CoC vs distance", "mode": "quick"}))
    page = _make_report(figs, tmp_path / "report")
    result = browser_check(page, tmp_path / "profile")
    assert result["broken"] == ["figures/fig10.png"]
    assert result["claims_table"] and result["claims_rows"] == len(CLAIMS)


def test_verdict_marks_are_text_or_svg_never_emoji(committed_report):
    page = committed_report
    for path in (page, page.with_name("README.md")):
        found = _EMOJI.findall(path.read_text(encoding="utf-8"))
        assert not found, f"{path.name} has emoji {sorted(set(found))}"
    from experiments.claims import claim_matrix
    from repro.report import claims_block, load_figures

    _, table = load_figures(ROOT / "report" / "figures")
    block = claims_block(claim_matrix(table), report_link="report/README.md")
    assert not _EMOJI.findall(block) and "`+` reproduced" in block
    assert "<svg class='mark'" in page.read_text(encoding="utf-8")
