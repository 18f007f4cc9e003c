"""The evaluation report opens in a real browser (headless Chromium): every
image and chart of the manifest appears, the page loads without errors and
needs no network, and a screenshot is saved for a person to look at
(`target/report-screenshot.png`).

Chromium comes from Debian's `chromium` package; this test installs it
when it is missing (apt-get, as CI runs as root), and fails if it cannot:
it never passes silently without a browser."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest

import uwhl_rs
from systools import installed
from uwhl_rs import synth

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def _chromium() -> str:
    return installed("chromium", "chromium", "chromium-browser")


def _run(browser: str, *args: str, timeout: int = 120) -> subprocess.CompletedProcess:
    # no network: a page that tried to fetch anything would show it as an error
    base = [browser, "--headless", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
            "--no-first-run", "--proxy-server=127.0.0.1:9", "--proxy-bypass-list=<-loopback>",
            "--enable-logging=stderr", "--v=0", "--virtual-time-budget=5000"]
    return subprocess.run(base + list(args), capture_output=True, text=True, timeout=timeout)


def test_the_report_renders_in_chromium(tmp_path):
    browser = _chromium()
    entries = []
    for k, wt in enumerate(["3C", "II"]):
        img, truth = synth.demo_input(120, 160, water_type=wt, seed=k + 3)
        name = f"scene_{wt}.png"
        uwhl_rs.images.write_image(tmp_path / name, img, bits=8, encoding="linear")
        d = np.where(np.isfinite(truth["distance"]), truth["distance"], 0)
        np.save(tmp_path / f"{name}.npy", d)
        entries.append({"path": name, "distance": f"{name}.npy", "water_type": wt,
                        "charts": [{"name": f"chart {wt}", "gray_patches": [[20, 90, 30, 100], [40, 90, 50, 100]],
                                    "region": [[15, 85, 55, 105]]}]})
    (tmp_path / "m.json").write_text(json.dumps({"images": entries}))
    out = tmp_path / "out"
    r = subprocess.run([sys.executable, "-m", "uwhl_rs", "evaluate", str(tmp_path / "m.json"), "-o", str(out),
                        "--water-type", "II,3C,7C", "-q"], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    url = (out / "report.html").resolve().as_uri()
    dom = _run(browser, "--dump-dom", url)
    assert dom.returncode == 0, dom.stderr[-2000:]
    page = dom.stdout
    assert 'id="summary"' in page
    for e in entries:
        assert e["path"] in page and e["charts"][0]["name"] in page, e["path"]
    # every image is inline and decodes: the browser keeps data: URIs, no file or network fetch
    assert page.count("data:image/png;base64,") >= 2 * 4
    # both profiles side by side, and each image's contact sheet of the three types with the choice framed
    assert "Water type (revised)" in page and "Water type (paper)" in page
    assert page.count('<figure class="type') == 2 * 3 and page.count('class="type chosen"') == 2
    errors = [line for line in dom.stderr.splitlines()
              if "Uncaught" in line or "ERR_" in line or "Failed to load resource" in line]
    assert not errors, errors
    shot = os.path.join(ROOT, "target", "report-screenshot.png")
    os.makedirs(os.path.dirname(shot), exist_ok=True)
    s = _run(browser, f"--screenshot={shot}", "--window-size=1400,1800", url)
    assert s.returncode == 0 and os.path.getsize(shot) > 10_000, s.stderr[-2000:]
    from PIL import Image

    with Image.open(shot) as im:
        a = np.asarray(im.convert("RGB"))
    # not a blank page: the inline images put many colours on it
    assert len(np.unique(a.reshape(-1, 3)[::37], axis=0)) > 200
