"""Open a page in headless Chromium (Debian's ``chromium`` package): its errors, its DOM and a screenshot.

No driver or protocol library: two runs of the browser's own command line. The first opens a copy of the page with
a first script that records ``console.error`` calls and uncaught errors (and the viewer canvas' position) into
attributes of ``<html>``, read back from ``--dump-dom``; the second takes a screenshot of the page as written, and
every console line Chromium logs for it is kept (the page itself logs nothing, so any line but WebGL's
"GPU stall due to ReadPixels" note, which the screenshot's read-back causes, is a finding).
"""

from __future__ import annotations

import json
import re
import shutil
import subprocess
from html import unescape
from pathlib import Path
from typing import NamedTuple

import numpy as np

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
WINDOW = (1400, 1000)
_FLAGS = [
    "--headless",
    "--no-sandbox",  # tests run as root in CI containers
    "--disable-gpu",
    "--use-angle=swiftshader",  # WebGL on the CPU
    "--enable-unsafe-swiftshader",
    "--no-first-run",
    "--disable-extensions",
    f"--window-size={WINDOW[0]},{WINDOW[1]}",
]
_RECORDER = """<script>
(function () {
  var errors = [], root = document.documentElement, error = console.error;
  console.error = function () {
    errors.push(Array.prototype.join.call(arguments, " "));
    error.apply(console, arguments);
  };
  window.addEventListener("error", function (e) { errors.push("uncaught: " + e.message); });
  window.addEventListener("load", function () {
    setTimeout(function () {
      var c = document.getElementById("tmm-canvas"), r = c && c.getBoundingClientRect();
      root.setAttribute("data-errors", JSON.stringify(errors));
      root.setAttribute("data-canvas", JSON.stringify(r ? [r.left, r.top, r.width, r.height] : null));
      var th = document.querySelector("table.sortable th:nth-child(4)");  // a column of numbers, sorted by a click
      if (th) {
        th.click();
        var cells = Array.prototype.map.call(th.closest("table").tBodies[0].rows, function (row) {
          return row.cells[3].textContent; });
        root.setAttribute("data-sorted", JSON.stringify(cells));
      }
    }, 0);
  });
})();
</script>"""


class Opened(NamedTuple):
    """What the browser saw of a page."""

    errors: list[str]  # console.error calls and uncaught errors
    console: list[str]  # console lines Chromium logged (WebGL's read-back note left out)
    dom: str  # the DOM after the page's scripts ran
    canvas: tuple[int, int, int, int] | None  # the viewer canvas' box in the screenshot (left, top, width, height)
    sorted_column: list[str] | None  # the 4th column of the first table after a click on its header
    screenshot: np.ndarray  # (H, W, 3) uint8


def _run(args: list[str]) -> subprocess.CompletedProcess[str]:
    assert CHROMIUM is not None
    return subprocess.run([CHROMIUM, *_FLAGS, *args], capture_output=True, text=True, timeout=180, check=False)


def open_page(page: Path, work: Path) -> Opened:
    """Open ``page`` (a file) in headless Chromium from ``file://``; ``work`` is a scratch folder."""
    from PIL import Image

    text = page.read_text(encoding="utf-8")
    checked = work / f"checked-{page.name}"
    checked.write_text(text.replace("<head>", "<head>" + _RECORDER, 1), encoding="utf-8")
    dumped = _run(["--dump-dom", "--virtual-time-budget=10000", checked.resolve().as_uri()])
    dom = dumped.stdout
    found = re.search(r'<html[^>]*data-errors="([^"]*)"', dom)
    assert found, f"the page did not finish loading in the browser:\n{dumped.stderr[-2000:]}"
    errors = json.loads(unescape(found.group(1)))
    box = json.loads(unescape(re.search(r'data-canvas="([^"]*)"', dom).group(1)))  # type: ignore[union-attr]
    shot = work / f"{page.stem}.png"
    taken = _run([f"--screenshot={shot}", "--virtual-time-budget=10000", page.resolve().as_uri()])
    console = [
        line for line in taken.stderr.splitlines() if ":CONSOLE" in line and "GPU stall due to ReadPixels" not in line
    ]
    image = np.asarray(Image.open(shot).convert("RGB"))
    canvas = None if box is None else tuple(round(v) for v in box)
    column = re.search(r'data-sorted="([^"]*)"', dom)
    sorted_column = None if column is None else json.loads(unescape(column.group(1)))
    return Opened(errors, console, dom, canvas, sorted_column, image)  # type: ignore[arg-type]


def drawn_pixels(opened: Opened) -> np.ndarray:
    """The canvas' pixels that differ from its clear colour (0.98 grey: 250, 250, 250), as ``(N, 3)``."""
    assert opened.canvas is not None, "the page has no viewer canvas"
    left, top, width, height = opened.canvas
    inside = opened.screenshot[top + 2 : top + height - 2, left + 2 : left + width - 2].reshape(-1, 3)
    return inside[np.abs(inside.astype(int) - 250).max(axis=1) > 3]
