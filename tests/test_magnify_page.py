"""``repro.magnify --html``: one self-contained page, checked as a person sees it in headless Chromium.

The page is written by the CLI into ``tmp_path`` and opened by Chromium (as in
``tests/test_report_browser.py``) with a small script that waits for the page to load, records every
``<img>`` that did not load, moves each before/after slider and ticks the map checkbox, and reports what
the browser then shows (the after image's clip, the overlay's display). Without ``chromium`` the browser
tests are skipped with that reason.
"""

from __future__ import annotations

import json
import re
import subprocess

import numpy as np
import pytest

from repro.magnify import PROG, main
from repro.photo_io import write_photo
from tests.photo_cli import cli_runner, textured_photo
from tests.test_report_browser import CHROMIUM

run, assert_one_line_error = cli_runner(main, PROG)

needs_chromium = pytest.mark.skipif(
    CHROMIUM is None, reason="chromium is not installed: `make system-deps` installs it as root (else: apt-get "
                             "install chromium)")

#: Injected before </body> of a copy of the page: acts as a person would and reports what the browser shows.
_CHECK_SCRIPT = """
<script>
window.addEventListener('load', function () {
  var imgs = Array.from(document.images);
  var boxes = Array.from(document.querySelectorAll('.compare'));
  var before = boxes.map(function (b) { return getComputedStyle(b.querySelector('img.after')).clipPath; });
  boxes.forEach(function (b) { var r = b.querySelector('input[type=range]'); r.value = 20;
                               r.dispatchEvent(new Event('input')); });
  var moved = boxes.map(function (b) { return getComputedStyle(b.querySelector('img.after')).clipPath; });
  var map0 = boxes.map(function (b) { return getComputedStyle(b.querySelector('img.map')).display; });
  var box = document.getElementById('show-map'); box.checked = true; box.dispatchEvent(new Event('change'));
  var map1 = boxes.map(function (b) { return getComputedStyle(b.querySelector('img.map')).display; });
  var out = document.createElement('pre'); out.id = 'browser-check';
  out.textContent = JSON.stringify({
    images: imgs.length, broken: imgs.filter(function (i) { return !(i.complete && i.naturalWidth > 0); })
                                      .map(function (i) { return i.alt; }),
    external: imgs.filter(function (i) { return i.getAttribute('src').indexOf('data:') !== 0; }).length,
    ids: boxes.map(function (b) { return b.parentElement.id; }),
    clip_before: before, clip_moved: moved, map_hidden: map0, map_shown: map1,
    widths: boxes.map(function (b) { return b.getBoundingClientRect().width; })});
  document.body.appendChild(out);
});
</script>
"""


@pytest.fixture(autouse=True)
def cache_dir(tmp_path, monkeypatch):
    monkeypatch.setenv("DEFOCUS_CACHE_DIR", str(tmp_path / "cache"))


def _browser_check(page, tmp_path) -> dict:
    probe = page.with_name("_check.html")
    probe.write_text(page.read_text(encoding="utf-8").replace("</body>", _CHECK_SCRIPT + "</body>"), encoding="utf-8")
    proc = subprocess.run([CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
                           f"--user-data-dir={tmp_path / 'profile'}", "--virtual-time-budget=10000", "--dump-dom",
                           probe.as_uri()], capture_output=True, text=True, timeout=120)
    m = re.search(r'<pre id="browser-check">(.*?)</pre>', proc.stdout, re.S)
    assert m, f"chromium printed no check result (rc {proc.returncode}): {proc.stderr[-2000:]}"
    return json.loads(m.group(1).replace("&quot;", '"').replace("&amp;", "&"))


@pytest.fixture
def page(tmp_path, capsys):
    photo = write_photo(tmp_path / "photo.png", textured_photo(96, 128))
    sigma = np.zeros((96, 128))
    sigma[:, 64:] = 3.0
    np.save(tmp_path / "map.npy", sigma)
    status, out, err = run([photo, "--map", tmp_path / "map.npy", "-o", tmp_path / "out.jpg",
                            "--html", tmp_path / "page.html"], capsys)
    assert status == 0, err
    assert out.split() == [str(tmp_path / "out.jpg"), str(tmp_path / "page.html")]
    return tmp_path / "page.html"


def test_page_is_self_contained(page):
    text = page.read_text(encoding="utf-8")
    srcs = re.findall(r'src="([^"]*)"', text)
    assert len(srcs) == 10  # 3 views × (before, after, map) + the colour scale
    assert all(s.startswith(("data:image/png;base64,", "data:image/jpeg;base64,")) for s in srcs)
    assert not re.search(r"(href|src)=\"(https?:|//|file:)", text) and "<link" not in text
    assert 'id="zoom-subject"' in text and 'id="zoom-background"' in text


@needs_chromium
def test_page_in_chromium_sliders_and_map_overlay_work(page, tmp_path):
    result = _browser_check(page, tmp_path)
    assert result["images"] == 10 and result["broken"] == [] and result["external"] == 0
    assert result["ids"] == ["whole", "zoom-subject", "zoom-background"]
    assert result["clip_before"] == ["inset(0px 0px 0px 50%)"] * 3
    assert result["clip_moved"] == ["inset(0px 0px 0px 20%)"] * 3       # the slider moves the before/after split
    assert result["map_hidden"] == ["none"] * 3 and result["map_shown"] == ["block"] * 3
    assert result["widths"][0] > 4 * 128                                 # a small photo is shown enlarged


@needs_chromium
def test_browser_check_sees_a_broken_image(page, tmp_path):
    """The check can fail: an image whose data is corrupt is reported as broken."""
    text = page.read_text(encoding="utf-8")
    page.write_text(re.sub(r'(alt="subject: after" src="data:image/png;base64,)[^"]*', r"\1AAAA", text),
                    encoding="utf-8")
    assert _browser_check(page, tmp_path)["broken"] == ["subject: after"]


def test_zoom_centres_follow_the_subject_and_the_background():
    from repro._magnify_page import zoom_centres

    sigma = np.full((300, 400), 2.0)
    sigma[100:200, 50:150] = 0.1   # the sharp subject
    sigma[:, 330:] = 6.0           # the blurriest background
    subject, background = zoom_centres(sigma, side=60)
    assert 100 <= subject[0] < 200 and 50 <= subject[1] < 150
    assert background[1] >= 330
    assert zoom_centres(sigma, focus_point=(10, 20), side=60)[0] == (20, 10)   # (x, y) → (row, column)
    mask = np.zeros((300, 400))
    mask[250:270, 300:320] = 1.0
    assert zoom_centres(sigma, keep_sharp=mask, side=60)[0] == (259, 309)


def test_html_written_only_with_the_photo(tmp_path, capsys):
    """A failure after the page is built leaves no page (the page is written with the other outputs)."""
    photo = write_photo(tmp_path / "photo.png", textured_photo(48, 64))
    status, _, err = run([photo, "--factor", "1e9", "-o", tmp_path / "out.png", "--html", tmp_path / "page.html"],
                         capsys)
    assert status == 2 and err[-1].startswith(f"{PROG}: error: --factor 1e+09 is too large"), err
    assert not (tmp_path / "page.html").exists() and not (tmp_path / "out.png").exists()
