"""The report in a real browser: headless Chromium loads ``index.html`` offline from ``file://`` and finds no
missing image and no console error, and drives the first A/B compare box (wipe both ways, swap, 2× zoom) the way
a user would; a screenshot is saved (to ``$SSBENCH_SCREENSHOT_DIR`` too, when set).

How: a copy of the page gets a small checker script as the first thing in ``<head>`` (the report itself has no
script). It records uncaught errors, failed resource loads and ``console.error`` calls, and on ``load`` writes
``{images, broken, errors}`` as JSON into the DOM, which ``chromium --dump-dom`` prints. Chromium's own console
lines on stderr (``--enable-logging=stderr``) that name an error are added to ``errors``. Network names do not
resolve (``--host-resolver-rules``), so the page must work offline. Skipped only when no Chromium binary
(``chromium``, ``chromium-browser``, ``google-chrome``) is on ``PATH``: ``make browser`` installs Debian's.
"""
import html
import json
import os
import re
import shutil
import struct
import subprocess
from pathlib import Path

import pytest

CHROMIUM = next((shutil.which(n) for n in ("chromium", "chromium-browser", "google-chrome") if shutil.which(n)), None)
needs_chromium = pytest.mark.skipif(CHROMIUM is None, reason="no Chromium binary (chromium, chromium-browser, "
                                    "google-chrome) on PATH; `make browser` or `apt-get install -y chromium`")

CHECKER = """<script>/* ssbench browser check: test copy only */
(function () {
  var errors = [];
  window.addEventListener("error", function (e) {
    var t = e.target;
    errors.push(t && t !== window && (t.src || t.href) ? "failed to load " + (t.src || t.href)
                                                        : "uncaught: " + e.message);
  }, true);
  window.addEventListener("unhandledrejection", function (e) { errors.push("unhandled rejection: " + e.reason); });
  var err = console.error;
  console.error = function () { errors.push("console.error: " + Array.prototype.join.call(arguments, " "));
                                 return err.apply(console, arguments); };
  window.addEventListener("load", function () {
    var imgs = Array.prototype.slice.call(document.images);
    var broken = imgs.filter(function (i) { return !i.complete || i.naturalWidth === 0; })
                     .map(function (i) { return i.getAttribute("src"); });
    var result = {images: imgs.length, broken: broken, errors: errors};
    var vw = document.documentElement.clientWidth, name = function (el) {
      return el.tagName.toLowerCase() + (el.id ? "#" + el.id : "") + (el.className ? "." + el.className : "");
    };
    if (document.querySelector("table")) {      /* layout: nothing wider than the window, no cell over a cell */
      var wide = [];
      Array.prototype.forEach.call(document.querySelectorAll("body *"), function (el) {
        var r = el.getBoundingClientRect(), clip = false;   /* inside a box that scrolls or clips: fine */
        for (var a = el.parentElement; a && a !== document.body && !clip; a = a.parentElement)
          clip = getComputedStyle(a).overflowX !== "visible";
        if (r.width > 0 && r.right > vw + 1 && !clip && wide.length < 5) wide.push(name(el) + " " + Math.round(r.right));
      });
      var over = [];
      Array.prototype.forEach.call(document.querySelectorAll("tr"), function (tr) {
        var cells = Array.prototype.slice.call(tr.children);
        for (var i = 1; i < cells.length; i++) {
          var a = cells[i - 1].getBoundingClientRect(), b = cells[i].getBoundingClientRect();
          if (a.width && b.width && a.right > b.left + 0.5 && over.length < 5) over.push(tr.textContent.slice(0, 60));
        }
      });
      Array.prototype.forEach.call(document.querySelectorAll(".tables"), function (box) {
        var ts = Array.prototype.slice.call(box.querySelectorAll(":scope > *"));
        for (var i = 0; i < ts.length; i++) for (var j = i + 1; j < ts.length; j++) {
          var a = ts[i].getBoundingClientRect(), b = ts[j].getBoundingClientRect();
          if (a.left < b.right && b.left < a.right && a.top < b.bottom && b.top < a.bottom) over.push(name(ts[i]));
        }
      });
      result.layout = {viewport: vw, page: document.documentElement.scrollWidth, wide: wide, overlaps: over};
    }
    var box = document.querySelector(".compare");
    if (box) {                     /* drive the first A/B compare like a user: wipe both ways, swap, zoom */
      var det = box.closest("details");
      if (det) det.open = true;
      box.scrollIntoView();
      var wipe = box.querySelector("input.wipe"), stage = box.querySelector(".stage");
      var shown = function () {
        var r = stage.getBoundingClientRect(), el = document.elementFromPoint(r.left + 0.25 * r.width,
                                                                             r.top + 0.5 * r.height);
        return el ? el.className : null;
      };
      var set = function (v) { wipe.value = v; wipe.dispatchEvent(new Event("input")); return shown(); };
      var c = {count: document.querySelectorAll(".compare").length, at0: set(0), at100: set(100)};
      box.querySelector("button.swap").click();
      c.after_swap = wipe.value;
      var zoom = box.querySelector("select.zoom");
      zoom.value = "2"; zoom.dispatchEvent(new Event("change"));
      c.zoom2 = stage.getBoundingClientRect().width / box.querySelector("img.b").naturalWidth;
      result.compare = c;
    }
    var ex = document.querySelector(".explorer");
    if (ex) {                      /* drive the sweep explorer: move its first slider to the other end */
      var state = function () {
        var sel = ex.querySelector("#sel");
        return {point: ex.getAttribute("data-point"), image: ex.querySelector("#image").getAttribute("src"),
                error: ex.querySelector("#error").getAttribute("src"),
                ring: sel ? sel.getAttribute("cx") + "," + sel.getAttribute("cy") : null,
                rows: ex.querySelectorAll("#numbers tr").length};
      };
      var x = {sliders: ex.querySelectorAll("#knobs input").length, methods: ex.querySelector("#method").options.length,
               points: ex.querySelectorAll("#plot circle[data-id]").length, before: state()};
      var s = ex.querySelector("#knobs input");
      if (s) {
        s.value = Number(s.value) === Number(s.max) ? s.min : s.max;
        s.dispatchEvent(new Event("input"));
        x.after = state();
      }
      result.explorer = x;
    }
    var pre = document.createElement("pre");
    pre.id = "ssbench-check";
    pre.textContent = JSON.stringify(result);
    document.body.appendChild(pre);
  });
})();
</script>"""
#: Chromium stderr console lines that report an error (its console messages are all logged at INFO level)
CONSOLE_ERROR = re.compile(r"CONSOLE.*(Uncaught|Failed to load|net::ERR_|Refused to|Not allowed to load)")


def _chromium(tmp: Path, *args: str) -> subprocess.CompletedProcess:
    cmd = [CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--no-first-run", "--no-default-browser-check",
           "--disable-extensions", f"--user-data-dir={tmp / 'chromium-profile'}", "--enable-logging=stderr", "--v=0",
           "--host-resolver-rules=MAP * ~NOTFOUND", "--virtual-time-budget=5000", *args]
    try:
        return subprocess.run(cmd, capture_output=True, text=True, timeout=180, check=False)
    except subprocess.TimeoutExpired as e:
        pytest.fail(f"chromium did not finish within 180 s: {' '.join(cmd)}\n{e.stderr}")


def check_page(page: Path, tmp: Path) -> dict:
    """Load ``page`` (a copy with :data:`CHECKER` injected, beside it) in headless Chromium; the checker's result."""
    text = page.read_text(encoding="utf-8")
    assert "<head>" in text, f"{page}: no <head> to inject the checker into"
    copy = page.with_name("_browser_check.html")
    copy.write_text(text.replace("<head>", "<head>\n" + CHECKER, 1), encoding="utf-8")
    r = _chromium(tmp, "--dump-dom", "--window-size=1400,1000", copy.as_uri())
    m = re.search(r'<pre id="ssbench-check">(.*?)</pre>', r.stdout, re.S)
    assert m, f"the checker wrote no result (chromium exit {r.returncode}):\n{r.stderr[-3000:]}"
    out = json.loads(html.unescape(m.group(1)))
    out["errors"] += [line for line in r.stderr.splitlines() if CONSOLE_ERROR.search(line)]
    return out


def screenshot(page: Path, png: Path, tmp: Path, size=(1280, 2000)) -> tuple[int, int]:
    """A ``size`` screenshot of ``page`` to ``png``; returns its pixel size (read from the PNG header)."""
    r = _chromium(tmp, f"--screenshot={png}", f"--window-size={size[0]},{size[1]}", "--hide-scrollbars",
                  page.as_uri())
    assert png.is_file(), f"no screenshot written (chromium exit {r.returncode}):\n{r.stderr[-3000:]}"
    head = png.read_bytes()[:24]
    assert head[:8] == b"\x89PNG\r\n\x1a\n", f"{png} is not a PNG"
    return struct.unpack(">II", head[16:24])


def external_urls(text: str) -> list[str]:
    """``src``/``href``/``url(...)`` values that leave the machine (the page must work offline)."""
    refs = re.findall(r"""(?:src|href)\s*=\s*["']([^"']*)["']""", text) + re.findall(r"url\(([^)]*)\)", text)
    return [u for u in refs if re.match(r"\s*['\"]?\s*(https?:)?//", u)]


@needs_chromium
def test_the_checker_sees_broken_images_and_errors(tmp_path):
    """The negative control: without it the report test below could pass on a checker that sees nothing."""
    import matplotlib.image as mimage
    import numpy as np
    mimage.imsave(tmp_path / "ok.png", np.zeros((4, 6, 3), np.uint8))
    page = tmp_path / "page.html"
    page.write_text('<!DOCTYPE html><html><head><meta charset="utf-8"></head><body><img src="ok.png">'
                    '<img src="missing.png"><script>console.error("boom"); undefinedFunction();</script>'
                    "</body></html>")
    out = check_page(page, tmp_path)
    assert out["images"] == 2 and out["broken"] == ["missing.png"]
    assert any("console.error: boom" in e for e in out["errors"])
    assert any("undefinedFunction" in e for e in out["errors"])
    assert any("missing.png" in e for e in out["errors"])
    clean = tmp_path / "clean.html"
    clean.write_text('<!DOCTYPE html><html><head></head><body><img src="ok.png"></body></html>')
    assert check_page(clean, tmp_path) == {"images": 1, "broken": [], "errors": []}
    bad = tmp_path / "layout.html"                     # a table past the window and a cell drawn over its neighbour
    bad.write_text('<!DOCTYPE html><html><head></head><body><table><tr><td style="min-width:3000px">wide</td></tr>'
                   '<tr><td style="position:relative;left:40px">over</td><td>next</td></tr></table></body></html>')
    layout = check_page(bad, tmp_path)["layout"]
    assert any(w.startswith("td") for w in layout["wide"]) and layout["overlaps"], layout


def test_external_urls_are_found():
    page = ('<a href="#ao">x</a><img src="img/a.png"><link href="https://cdn.example/x.css">'
            '<script src="//cdn.example/x.js"></script><style>b { background: url("http://x/y.png") }</style>')
    assert external_urls(page) == ["https://cdn.example/x.css", "//cdn.example/x.js", '"http://x/y.png"']


@pytest.mark.slow
@pytest.mark.mitsuba
@needs_chromium
def test_report_in_headless_chromium(tmp_path, monkeypatch):
    from ssbench.report.build import build_report
    monkeypatch.setenv("SSBENCH_CACHE_DIR", str(tmp_path / "cache"))
    index = Path(build_report(str(tmp_path / "reports"), scenes=["sphere_on_plane"], width=32, height=24, spp=4,
                              progress=False, ao=True, ao_rays=2, ssr=False, implicit=False, speed=False,
                              tuning=False))
    page = tmp_path / "reports" / "latest" / "index.html"
    text = page.read_text(encoding="utf-8")
    assert external_urls(text) == [], "the report must work offline"
    srcs = re.findall(r'<img[^>]*\ssrc="([^"]+)"', text)
    assert any(s.startswith("img/ao/") for s in srcs), "no AO section images: the check would test too little"
    out = check_page(page, tmp_path)
    compare, layout = out.pop("compare", None), out.pop("layout", None)
    # the layout holds at 1400 px: no element past the window's right edge (wide tables scroll in their own box),
    # no table cell over its neighbour, no table of a .tables box over another
    assert layout is not None and layout["wide"] == [] and layout["overlaps"] == [], layout
    assert layout["page"] <= layout["viewport"], layout
    assert out["images"] == len(srcs) and out["broken"] == [] and out["errors"] == [], out
    # the A/B wipe really changes which image is shown, swap flips it, zoom is nearest-neighbour 2x
    assert compare is not None and compare["count"] >= 4, compare           # one per AO method
    assert compare["at0"] == "b" and compare["at100"] == "a" and compare["after_swap"] == "0", compare
    assert abs(compare["zoom2"] - 2.0) < 0.05, compare
    png = tmp_path / "report.png"
    assert screenshot(page, png, tmp_path) == (1280, 2000)
    from ssbench.report.screenshots import section_screenshots            # what `ssbench report --screenshots` does
    shots = section_screenshots(str(page), chromium=CHROMIUM)
    assert list(shots) == ["glance", "scenes", "ao", "ssr", "implicit", "glossy", "time", "speed", "tuning",
                          "calibration"], shots
    import numpy as np
    from PIL import Image
    ao_shot = np.asarray(Image.open(shots["ao"]).convert("RGB"))
    assert ao_shot.shape[1] == 1400 and ao_shot.shape[0] > 300, ao_shot.shape    # trimmed, not empty
    assert (np.abs(ao_shot.astype(int) - (250, 251, 252)).sum(2) > 6).mean() > 0.05     # there is something on it
    assert not list((page.parent).glob("_section_*.html"))                 # the temporary copies are gone
    keep = os.environ.get("SSBENCH_SCREENSHOT_DIR")
    if keep:
        os.makedirs(keep, exist_ok=True)
        shutil.copyfile(png, os.path.join(keep, f"report-{index.parent.name}.png"))


def test_section_split_covers_the_page_in_order():
    from ssbench.report.screenshots import split_sections
    page = ('<html><head></head><body><h1>t</h1><h2 id="glance">At a glance</h2><table></table>'
            '<h2 style="x" id="scenes">Scenes</h2><p>s</p><span id="sec-ao"></span><h2 id="ao">AO</h2>'
            '<span id="sec-ssr"></span><h2 id="ssr">SSR</h2><footer>f</footer></body></html>')
    parts = split_sections(page)
    assert list(parts) == ["glance", "scenes", "ao", "ssr"]
    assert 'id="glance"' in parts["glance"] and "Scenes" not in parts["glance"]
    assert parts["scenes"].startswith('<h2 style="x" id="scenes">') and parts["ao"].endswith("<h2 id=\"ao\">AO</h2>")
    assert "footer" not in parts["ssr"]
