"""Screenshot of a synthetic recording in the Rerun web viewer (headless chromium)."""

from __future__ import annotations

import os
import shutil
import subprocess
import zlib
from pathlib import Path

import numpy as np
import pytest

from gcs_monitor.tools.screenshot import CHROMIUM, screenshot_rrd
from tests.helpers.synthetic_rrd import write_synthetic_rrd

DOCS_IMG = Path(__file__).resolve().parents[2] / "docs" / "img" / "dashboard.png"
# GCS_UPDATE_SCREENSHOT=1 copies the screenshot over the README's; by default the test leaves the
# source tree alone.
UPDATE_DOCS_IMG = os.environ.get("GCS_UPDATE_SCREENSHOT") == "1"


def _png_gray(path: Path) -> np.ndarray:
    """Decode an 8-bit RGB/RGBA non-interlaced PNG (what chromium writes) to gray, no PIL needed."""
    data = path.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    pos, idat, w = 8, b"", 0
    h = ch = 0
    while pos < len(data):
        n = int.from_bytes(data[pos : pos + 4], "big")
        kind, body = data[pos + 4 : pos + 8], data[pos + 8 : pos + 8 + n]
        if kind == b"IHDR":
            w, h = int.from_bytes(body[:4], "big"), int.from_bytes(body[4:8], "big")
            assert body[8] == 8 and body[12] == 0
            ch = {2: 3, 6: 4}[body[9]]
        elif kind == b"IDAT":
            idat += body
        pos += 12 + n
    raw = np.frombuffer(zlib.decompress(idat), dtype=np.uint8).reshape(h, 1 + w * ch)
    img = np.zeros((h, w * ch), dtype=np.int32)
    prev = np.zeros(w * ch, dtype=np.int32)
    for y in range(h):  # PNG row filters (RFC 2083 sec. 6)
        f, line = raw[y, 0], raw[y, 1:].astype(np.int32)
        cur = np.zeros_like(line)
        if f == 0:
            cur = line
        elif f == 2:
            cur = (line + prev) & 0xFF
        else:
            for x in range(w * ch):
                a = cur[x - ch] if x >= ch else 0
                b, c = prev[x], prev[x - ch] if x >= ch else 0
                if f == 1:
                    pred = a
                elif f == 3:
                    pred = (a + b) // 2
                else:
                    p = a + b - c
                    pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                    pred = a if pa <= pb and pa <= pc else (b if pb <= pc else c)
                cur[x] = (line[x] + pred) & 0xFF
        img[y], prev = cur, cur
    return img.reshape(h, w, ch)[:, :, :3].mean(axis=2)


@pytest.mark.slow
@pytest.mark.browser
def test_dashboard_screenshot(tmp_path: Path) -> None:
    if not Path(CHROMIUM).exists():
        if shutil.which("apt-get") is None:
            pytest.skip("chromium missing and no apt-get")
        subprocess.run(["apt-get", "install", "-y", "chromium"], check=True)
    rrd = tmp_path / "demo.rrd"
    stats = write_synthetic_rrd(rrd, duration_s=30.0)
    assert stats["events"] == 2
    png = screenshot_rrd(rrd, tmp_path / "dashboard.png", wait_s=40.0)
    gray = _png_gray(png)
    assert gray.shape == (1000, 1600)
    # Not blank / not the grey "Loading..." page: a rendered dashboard has plot lines, legends
    # and the 3-D view, i.e. many distinct gray levels and real contrast in each half.
    assert gray.std() > 20.0
    assert len(np.unique(gray.astype(np.uint8))) > 64
    left, right = gray[:, :900], gray[:, 1000:]
    assert left.std() > 10.0 and right.std() > 10.0
    if UPDATE_DOCS_IMG:
        DOCS_IMG.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(png, DOCS_IMG)
