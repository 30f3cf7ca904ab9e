"""Open an HTML page in a real headless Chromium and report what a reader would get.

The reports promise a page that a browser opens from disk, without a server or network: it
loads, every embedded figure decodes to an image of non-zero size, and every link of the
navigation bar lands on an element of the page. Python's HTML parser cannot check the first
two; a browser can. ``inspect_page`` copies the page, adds a small script that collects these
facts once the page has loaded (the report itself holds no script), and reads them back from
``chromium --dump-dom``. No Python dependency: Chromium comes from the distribution's packages
(``apt-get install chromium``; ``.ci/run`` installs it).

Without Chromium the tests skip, except under ``CI=true``, where they fail: CI must run them.
"""

from __future__ import annotations

import html
import json
import os
import re
import shutil
import subprocess
from pathlib import Path

import pytest

__all__ = ["FLAGS", "chromium", "inspect_page"]

# flags that work on a closed network, as root, without a display or a GPU
FLAGS = ("--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
         "--disable-background-networking", "--disable-component-update", "--disable-sync")

_PROBE = """<script>
window.addEventListener("load", () => {
  // after "load" every image has loaded; drawing it on a canvas decodes it in full
  const imgs = [...document.images].map((img) => {
    let decoded = false, inked = 0;
    try {
      const c = document.createElement("canvas");
      c.width = img.naturalWidth; c.height = img.naturalHeight;
      const ctx = c.getContext("2d");
      ctx.drawImage(img, 0, 0);
      const px = ctx.getImageData(0, 0, c.width, c.height).data;
      for (let i = 0; i < px.length; i += 4) {
        if (px[i + 3] > 0 && (px[i] < 250 || px[i + 1] < 250 || px[i + 2] < 250)) inked++;
      }
      decoded = img.complete && c.width > 0 && c.height > 0;
    } catch (e) { decoded = false; }
    const box = img.getBoundingClientRect();
    return {alt: img.alt, src: img.getAttribute("src").slice(0, 30), decoded: decoded,
            width: img.naturalWidth, height: img.naturalHeight, inked_pixels: inked,
            shown_width: box.width, shown_height: box.height};
  });
  const links = [...document.querySelectorAll("a[href]")].map((a) => {
    const href = a.getAttribute("href");
    const target = href.startsWith("#") ? document.getElementById(href.slice(1)) : null;
    return {href: href, resolves: target !== null,
            shown: target !== null && target.getClientRects().length > 0};
  });
  const out = document.createElement("pre");
  out.id = "__browser_probe__";
  out.textContent = JSON.stringify({ready: document.readyState, title: document.title,
                                    images: imgs, links: links,
                                    text_length: document.body.innerText.length});
  document.body.appendChild(out);
});
</script>"""


def chromium() -> str:
    """Path of the Chromium executable; skip the test if there is none, fail under CI=true."""
    for name in ("chromium", "chromium-browser", "google-chrome"):
        path = shutil.which(name)
        if path:
            return path
    if os.environ.get("CI", "").lower() == "true":
        pytest.fail("CI=true but no Chromium on PATH: the browser tests must run in CI "
                    "(.ci/run installs it with apt-get install -y chromium)")
    pytest.skip("needs Chromium on PATH (apt-get install chromium)")


def inspect_page(page: Path, workdir: Path) -> dict:
    """Load ``page`` in headless Chromium and return what the probe saw.

    Parameters
    ----------
    page : Path
        A self-contained HTML file (it is copied into ``workdir`` with the probe added).
    workdir : Path
        Scratch directory (the copy and Chromium's fresh profile).

    Returns
    -------
    dict
        ``ready`` (document.readyState), ``title``, ``images`` (per image: ``decoded``,
        natural ``width``/``height`` [px], ``inked_pixels`` (pixels that are neither white nor
        transparent), ``shown_width``/``shown_height`` [CSS px]),
        ``links`` (per link: ``href``, ``resolves`` to an element id, ``shown``) and
        ``text_length`` (characters of rendered text).
    """
    text = page.read_text(encoding="utf-8")
    assert text.count("</body>") == 1, "the page must have one </body>"
    probe = workdir / f"probe-{page.name}"
    probe.write_text(text.replace("</body>", _PROBE + "</body>"), encoding="utf-8")
    cmd = [chromium(), *FLAGS, f"--user-data-dir={workdir / 'chromium-profile'}",
           "--virtual-time-budget=10000", "--window-size=1200,900", "--dump-dom",
           probe.resolve().as_uri()]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=180, check=False)
    shutil.rmtree(workdir / "chromium-profile", ignore_errors=True)
    m = re.search(r'<pre id="__browser_probe__">(.*?)</pre>', proc.stdout, flags=re.S)
    assert m, ("the page did not finish loading in Chromium (exit status "
               f"{proc.returncode}): {proc.stderr[-2000:]}")
    return json.loads(html.unescape(m.group(1)))
