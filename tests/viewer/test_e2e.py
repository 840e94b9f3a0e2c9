"""End to end: the real server on a free port, the page in headless Chromium (Selenium).

Skips cleanly when Selenium, Chromium or its driver is missing (``.ci/run`` tries to
install Debian's ``chromium`` and ``chromium-driver``).
"""

from __future__ import annotations

import os
import shutil
import time

import pytest

pytest.importorskip("starlette", reason="viewer extras not installed (pip install -e '.[view]')")
pytest.importorskip("uvicorn", reason="viewer extras not installed (pip install -e '.[view]')")
webdriver = pytest.importorskip("selenium.webdriver", reason="selenium not installed (pip install -e '.[test]')")

import sparsecast as sc  # noqa: E402
from sparsecast.viewer.server import ViewerServer  # noqa: E402
from sparsecast.viewer.session import ViewerData  # noqa: E402

BROWSERS = ("chromium", "chromium-browser", "google-chrome", "chrome")
DRIVERS = ("chromedriver",)


def _find(names):
    for n in names:
        p = shutil.which(n)
        if p:
            return p
    return None


@pytest.fixture(scope="module")
def driver():
    browser = os.environ.get("SPARSECAST_CHROME") or _find(BROWSERS)
    drv = os.environ.get("SPARSECAST_CHROMEDRIVER") or _find(DRIVERS)
    if not browser or not drv:
        pytest.skip("no headless browser: install chromium and chromium-driver (apt-get install chromium chromium-driver)")
    from selenium.webdriver.chrome.service import Service

    opts = webdriver.ChromeOptions()
    opts.binary_location = browser
    for arg in ("--headless=new", "--no-sandbox", "--disable-dev-shm-usage", "--disable-gpu",
                "--window-size=1100,800", "--no-first-run", "--disable-extensions"):
        opts.add_argument(arg)
    opts.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    try:
        d = webdriver.Chrome(service=Service(executable_path=drv), options=opts)
    except Exception as exc:  # driver/browser mismatch, no display libraries, ...
        pytest.skip(f"could not start headless Chromium: {str(exc).splitlines()[0][:200]}")
    d.set_script_timeout(30)
    yield d
    d.quit()


@pytest.fixture(scope="module")
def server():
    vol = sc.datasets.nbody_blobs(48, n_clusters=3, blobs_per_cluster=20, seed=5)
    srv = ViewerServer(ViewerData.create(vol, "viridis", index="grid-pc"), "127.0.0.1", 0).start()
    yield srv
    srv.stop()


def wait_for(d, script, timeout=60.0, what="condition"):
    t0 = time.monotonic()
    while time.monotonic() - t0 < timeout:
        v = d.execute_script(script)
        if v:
            return v
        time.sleep(0.05)
    raise AssertionError(f"timed out waiting for {what}: {script}")


# Frames shown so far once the latest request's full frame is on screen, else 0.
IDLE = ("((s) => (s && s.lastStatus && !s.lastStatus.preview && s.lastStatus.seq === s.seq && !s.dirty)"
        " ? s.frames : 0)(window.sparsecastViewer)")
CANVAS = "return document.getElementById('view').toDataURL('image/png');"


def test_page_renders_and_tf_drag_changes_frame(driver, server, tmp_path):
    from selenium.webdriver.common.action_chains import ActionChains
    from selenium.webdriver.common.by import By

    driver.get(server.url)
    wait_for(driver, f"return {IDLE};", 90, "the first full frame")
    hello = driver.execute_script("return window.sparsecastViewer.hello;")
    assert hello["indices"] == ["auto", *sc.available_indices()]
    options = [o.get_attribute("value") for o in driver.find_elements(By.CSS_SELECTOR, "#index option")]
    assert options == hello["indices"]
    status = driver.find_element(By.ID, "status").text
    assert "frame" in status and "rebuild" in status and "samples" in status
    before = driver.execute_script(CANVAS)
    frames0 = driver.execute_script("return window.sparsecastViewer.frames;")

    # Drag the top opacity point (x = 1) down: a new TF, a new index, a new frame.
    tf_canvas = driver.find_element(By.ID, "tf")
    n = driver.execute_script("return window.sparsecastViewer.tf.points.length;")
    a0 = driver.execute_script(f"return window.sparsecastViewer.tf.points[{n - 1}][4];")
    px, py = driver.execute_script(f"return window.sparsecastViewer.pointPixel({n - 1});")
    w, h = tf_canvas.size["width"], tf_canvas.size["height"]
    (ActionChains(driver)
     .move_to_element_with_offset(tf_canvas, int(px - w / 2) - 1, int(py - h / 2))
     .click_and_hold().move_by_offset(0, 30).move_by_offset(0, 40).release().perform())
    a1 = driver.execute_script(f"return window.sparsecastViewer.tf.points[{n - 1}][4];")
    assert a1 < a0 - 0.2, (a0, a1)
    wait_for(driver, f"const f = {IDLE}; return f > {frames0} ? f : 0;", 30, "a full frame after the TF drag")
    after = driver.execute_script(CANVAS)
    assert after != before
    last = driver.execute_script("return window.sparsecastViewer.lastStatus;")
    assert last["index"] == "grid-pc"  # (the index was rebuilt by a preview frame during the drag)

    # Orbit: dragging the image gives preview frames, then a full frame.
    view = driver.find_element(By.ID, "view")
    frames1 = driver.execute_script("return window.sparsecastViewer.frames;")
    ActionChains(driver).move_to_element(view).click_and_hold().move_by_offset(40, 0).move_by_offset(40, 10).release().perform()
    wait_for(driver, f"const f = {IDLE}; return f > {frames1} ? f : 0;", 30, "a full frame after orbiting")
    assert driver.execute_script("return window.sparsecastViewer.previewFrames;") >= 1
    assert driver.execute_script(CANVAS) != after

    shot = tmp_path / "viewer.png"
    driver.save_screenshot(str(shot))
    assert shot.stat().st_size > 1000
    print(f"screenshot: {shot}")
    errors = [e for e in driver.get_log("browser") if e.get("level") == "SEVERE"]
    assert not errors, errors
