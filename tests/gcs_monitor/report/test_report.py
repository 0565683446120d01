"""The post-flight report: one self-contained page, and its look in headless Chromium."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import pytest

from gcs_monitor.cli import main
from tests.helpers.dataflash import plane_log

DATA = Path(__file__).resolve().parents[2] / "data" / "real"
DOCS_IMG = Path(__file__).resolve().parents[3] / "docs" / "img"


def test_report_page_is_self_contained(tmp_path: Path) -> None:
    log = plane_log(tmp_path / "plane.bin", seconds=8.0)
    rc = main(["report", str(log), str(DATA / "px4_sitl_current_topics.ulg"),
               "--out", str(tmp_path / "out")])
    assert rc == 0
    for name in ("plane.html", "px4_sitl_current_topics.html"):
        page = (tmp_path / "out" / name).read_text()
        for section in ("Flight overview", "Coverage per family", "Alarm timeline",
                        "Health counters"):
            assert section in page
        assert "http://" not in page and "https://" not in page  # nothing fetched
    assert "HIGHRES_IMU" in (tmp_path / "out" / "plane.html").read_text()


def test_report_goes_on_past_a_bad_file(tmp_path: Path, capsys) -> None:
    bad = tmp_path / "empty.ulg"
    bad.write_bytes(b"")
    rc = main(["report", str(bad), str(DATA / "px4_sitl_current_topics.ulg"),
               "--out", str(tmp_path / "out")])
    assert rc == 2 and "1 of 2 files could not be used" in capsys.readouterr().err
    assert (tmp_path / "out" / "px4_sitl_current_topics.html").exists()


@pytest.mark.browser
@pytest.mark.parametrize("log, png", [
    ("ardupilot_bin/erle_copter_16.BIN", "report_ardupilot.png"),
    ("px4_ulog/pyulog_sample_logging_tagged_and_default_params.ulg", "report_px4.png")])
def test_report_screenshot(log: str, png: str, real_data_file, tmp_path: Path) -> None:
    """The page renders in headless Chromium (a non-trivial PNG); GCS_UPDATE_SCREENSHOT=1
    writes docs/img/report_*.png."""
    if shutil.which("chromium") is None:
        pytest.skip("needs Debian chromium (make test-browser installs it)")
    from gcs_monitor.report import write_report
    from gcs_monitor.tools.screenshot import screenshot_page

    page = write_report(real_data_file(log), tmp_path)
    out = screenshot_page(page, tmp_path / png, height_px=2400)
    assert out.stat().st_size > 50_000
    if os.environ.get("GCS_UPDATE_SCREENSHOT"):
        DOCS_IMG.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(out, DOCS_IMG / png)
