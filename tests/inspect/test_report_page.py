"""``report.html`` in headless Chromium (Debian's ``chromium`` and ``chromium-driver``,
driven through Selenium, no network): the tables render, a video plays, every link
and media source resolves inside the folder; a screenshot is taken."""

from __future__ import annotations

import os
import shutil
import tempfile
import time
from pathlib import Path
from urllib.parse import unquote, urlparse

import pytest
from selenium import webdriver
from selenium.webdriver.chrome.service import Service

from tests.inspect.conftest import evaluate_oracle
from tests.inspect.rrd import Recording

CHROMIUM = shutil.which("chromium")
DRIVER = shutil.which("chromedriver")
FLAGS = (
    "--headless=new",
    "--no-sandbox",
    "--disable-gpu",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--window-size=1400,1000",
)


@pytest.fixture
def browser():
    if CHROMIUM is None or DRIVER is None:
        if os.environ.get("CI"):
            pytest.fail("chromium and chromium-driver are missing (make system-deps installs them)")
        pytest.skip("needs Debian's chromium and chromium-driver (make system-deps)")
    options = webdriver.ChromeOptions()
    options.binary_location = CHROMIUM
    profile = tempfile.mkdtemp(prefix="bpns-chromium-")
    for flag in (*FLAGS, f"--user-data-dir={profile}"):
        options.add_argument(flag)
    driver = webdriver.Chrome(service=Service(DRIVER), options=options)
    try:
        yield driver
    finally:
        driver.quit()
        shutil.rmtree(profile, ignore_errors=True)


def _until(driver, script: str, attempts: int = 100):
    """Poll ``script`` until it returns something truthy (a video loading and playing)."""
    for _ in range(attempts):
        value = driver.execute_script(script)
        if value:
            return value
        time.sleep(0.1)
    return driver.execute_script(script)


def test_the_eval_report_opens_offline_plays_its_video_and_links_its_files(browser, tmp_path):
    out = tmp_path / "eval"
    recordings = tmp_path / "recordings"
    evaluate_oracle(
        "cover", out, failed=True, extra=("--report-videos", "failed", "--rerun", str(recordings))
    )
    page = out / "report.html"
    browser.get(page.as_uri())
    assert browser.title.startswith("bpns evaluation: cover, 1 eval tasks")
    assert browser.execute_script("return document.querySelectorAll('#results tr').length") == 2
    row = browser.execute_script(
        "return document.querySelector('tr.task').innerText.replace(/\\s+/g, ' ')"
    )
    assert "failed: refinement_failed" in row and "Pick(robot, block" in row

    # the failed task's video loads and plays
    assert browser.execute_script("return document.querySelectorAll('video').length") == 1
    browser.execute_script("document.querySelector('video').play()")
    played = _until(
        browser,
        "var v = document.querySelector('video');"
        "return v.readyState >= 2 && v.currentTime > 0 ? [v.readyState, v.currentTime] : null",
    )
    assert played, browser.execute_script("return document.querySelector('video').error")
    assert browser.execute_script("return document.querySelector('video').error") is None

    # every link and media source is a file in the folder (or a place on the page)
    targets = browser.execute_script(
        "return Array.from(document.querySelectorAll('a[href], video[src], video[poster]'))"
        ".map(e => e.getAttribute('href') || e.getAttribute('src') || e.getAttribute('poster'))"
    )
    ids = set(
        browser.execute_script(
            "return Array.from(document.querySelectorAll('[id]')).map(e => e.id)"
        )
    )
    for target in targets:
        if target.startswith("#"):
            assert target[1:] in ids, target
            continue
        assert not urlparse(target).scheme, f"{target}: the page must not reach out"
        assert (out / unquote(target)).resolve().is_file(), target
    recording = next(t for t in targets if t.endswith(".rrd"))
    assert Recording(out / unquote(recording)).children("atoms")

    # "show failed tasks only" hides nothing here; it hides solved rows elsewhere
    browser.execute_script("document.getElementById('only-failed').click()")
    visible = browser.execute_script(
        "return Array.from(document.querySelectorAll('tr.task')).filter("
        "r => r.style.display !== 'none').length"
    )
    assert visible == 1
    shot = tmp_path / "report.png"
    browser.save_screenshot(str(shot))
    assert shot.stat().st_size > 10_000
    keep = os.environ.get("BPNS_KEEP_SCREENSHOT")
    if keep:
        shutil.copy(shot, Path(keep))
