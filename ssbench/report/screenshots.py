"""Screenshots of a finished report, one PNG per section, taken by a headless Chromium (when one is installed):
what a person sees at a given window width, kept beside the report so a review can cite them.

Each section (at a glance, scenes, then every ``<span id="sec-…">`` block of ``index.html``) is cut into its own
copy of the page (same ``<head>``: styles, offline) and shot at ``width`` × a tall window; the empty bottom is
trimmed. Nothing leaves the machine (host names do not resolve)."""
from __future__ import annotations

import os
import re
import shutil
import subprocess
import tempfile
from typing import Optional

__all__ = ["find_chromium", "split_sections", "section_screenshots"]

#: names of a Chromium binary, first found on ``PATH`` wins
CHROMIUM_NAMES = ("chromium", "chromium-browser", "google-chrome")


def find_chromium() -> Optional[str]:
    """The first Chromium on ``PATH``, or None."""
    return next((shutil.which(n) for n in CHROMIUM_NAMES if shutil.which(n)), None)


def split_sections(page: str) -> dict[str, str]:
    """``{key: html}`` of the sections of a rendered ``index.html``: ``glance`` (the top, up to the scenes),
    ``scenes``, and one per ``<span id="sec-KEY">`` marker up to the next one (the last up to ``<footer``)."""
    body = page[page.index("<body>") + len("<body>"):]
    end = body.find("<footer")
    body = body if end < 0 else body[:end]
    marks = [(m.start(), m.group(1)) for m in re.finditer(r'<span id="sec-([A-Za-z0-9_]+)"></span>', body)]
    scenes = body.find('id="scenes"')
    scenes = body.rfind("<h2", 0, scenes) if scenes >= 0 else -1
    first = marks[0][0] if marks else len(body)
    out = {"glance": body[:scenes if 0 <= scenes < first else first]}
    if 0 <= scenes < first:
        out["scenes"] = body[scenes:first]
    for (a, key), (b, _) in zip(marks, marks[1:] + [(len(body), "")]):
        out[key] = body[a:b]
    return out


def _trim(png: str, background=(250, 251, 252)) -> tuple[int, int]:
    """Crop the rows at the bottom of ``png`` that are all ``background``; returns the new size."""
    import numpy as np
    from PIL import Image
    im = Image.open(png).convert("RGB")
    a = np.asarray(im)
    used = np.nonzero((np.abs(a.astype(int) - background).sum(2) > 6).any(1))[0]
    h = int(min(a.shape[0], used[-1] + 25)) if used.size else 1
    im.crop((0, 0, a.shape[1], h)).save(png)
    return a.shape[1], h


def section_screenshots(index_html: str, out_dir: Optional[str] = None, *, width: int = 1400, height: int = 16000,
                        chromium: Optional[str] = None, timeout: float = 180) -> dict[str, str]:
    """Screenshot every section of the report page ``index_html`` into ``out_dir`` (default: ``screenshots/``
    beside it) as ``<key>.png``, and every sweep explorer beside it (``explore_<effect>.html``) as
    ``explore_<effect>.png``; returns ``{key: path}``. A section taller than ``height`` pixels is cut there
    (the default report's tallest, the scenes, is ~7000 px at 1400 px). Raises ``RuntimeError`` when no Chromium
    is found."""
    chromium = chromium or find_chromium()
    if chromium is None:
        raise RuntimeError("screenshots: no Chromium on PATH (chromium, chromium-browser, google-chrome); "
                           "`make browser` installs one")
    page = open(index_html, encoding="utf-8").read()
    head, tail = page[:page.index("<body>") + len("<body>")], page[page.rindex("<script>"):] \
        if "<script>" in page else "</body></html>"
    out_dir = out_dir or os.path.join(os.path.dirname(os.path.abspath(index_html)), "screenshots")
    os.makedirs(out_dir, exist_ok=True)
    shots = {}
    here = os.path.dirname(os.path.abspath(index_html))
    with tempfile.TemporaryDirectory() as tmp:
        for key, html in split_sections(page).items():
            copy = os.path.join(here, f"_section_{key}.html")
            with open(copy, "w", encoding="utf-8") as f:
                f.write(head + html + tail)
            try:
                png = _shoot(chromium, copy, os.path.join(out_dir, f"{key}.png"), width, height, tmp, timeout)
            finally:
                os.remove(copy)
            if png:
                shots[key] = png
        for name in sorted(n for n in os.listdir(here) if re.fullmatch(r"explore_\w+\.html", n)):
            key = name[:-len(".html")]                  # the sweep explorers, as they open (first configuration)
            png = _shoot(chromium, os.path.join(here, name), os.path.join(out_dir, f"{key}.png"), width,
                         min(height, 2000), tmp, timeout)
            if png:
                shots[key] = png
    return shots


def _shoot(chromium: str, page: str, png: str, width: int, height: int, tmp: str, timeout: float) -> Optional[str]:
    """A ``width`` × ``height`` screenshot of ``page`` into ``png``, its empty bottom trimmed; ``None`` when
    Chromium wrote nothing."""
    subprocess.run([chromium, "--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars",
                    f"--user-data-dir={os.path.join(tmp, 'profile')}", "--host-resolver-rules=MAP * ~NOTFOUND",
                    "--virtual-time-budget=3000", f"--window-size={width},{height}",
                    f"--screenshot={png}", "file://" + os.path.abspath(page)],
                   capture_output=True, timeout=timeout, check=False)
    if not os.path.isfile(png):
        return None
    _trim(png)
    return png
