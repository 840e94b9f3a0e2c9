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


OVERLAY_ALPHA = ("return ((x, y) => { const c = document.getElementById('clip-overlay');"
                 " const r = c.getBoundingClientRect();"
                 " return c.getContext('2d').getImageData(Math.round(x * c.width / r.width),"
                 " Math.round(y * c.height / r.height), 1, 1).data[3]; })(arguments[0], arguments[1]);")


def test_dragging_a_clip_box_handle_moves_that_face(driver, server):
    """The clip box is drawn over the frame with a handle per face; dragging the x-hi
    handle towards the x-lo one moves that face (sliders follow, preview frames, no index
    rebuild) and does not orbit; with the overlay hidden the same drag orbits."""
    from selenium.webdriver.common.action_chains import ActionChains
    from selenium.webdriver.common.by import By

    driver.get(server.url)
    wait_for(driver, f"return {IDLE};", 90, "the first full frame")
    st = driver.execute_script("return window.sparsecastViewer;")
    assert st["frameCamera"] is not None and driver.find_element(By.ID, "clip-show").is_selected()
    p0, p1 = (driver.execute_script(f"return window.sparsecastViewer.handlePixel({i});") for i in (0, 1))
    assert p0 and p1
    assert driver.execute_script(OVERLAY_ALPHA, *p1) > 0  # the handle is drawn where it is picked
    view = driver.find_element(By.ID, "view")
    w, h = view.size["width"], view.size["height"]
    az0, previews0 = st["camera"]["azimuth"], st["previewFrames"]
    dx, dy = 0.4 * (p0[0] - p1[0]), 0.4 * (p0[1] - p1[1])

    def drag_x_hi():
        (ActionChains(driver).move_to_element_with_offset(view, round(p1[0] - w / 2), round(p1[1] - h / 2))
         .click_and_hold().move_by_offset(round(dx / 2), round(dy / 2)).move_by_offset(round(dx / 2), round(dy / 2))
         .release().perform())

    st = _changed_after(driver, "dragging the x-hi handle", drag_x_hi)
    box = st["clip"]["box"]
    assert 0.45 < box[1][0] < 0.75 and box[0] == [0, 0, 0] and box[1][1:] == [1, 1], box
    assert st["camera"]["azimuth"] == az0  # no orbit
    assert st["previewFrames"] > previews0 and not st["lastStatus"]["rebuilt"]
    assert driver.find_element(By.ID, "clip-x-hi").get_attribute("value") == str(round(box[1][0] * 1000))
    p1b = driver.execute_script("return window.sparsecastViewer.handlePixel(1);")
    # the handle came along (to the rounding of the pointer offsets, and the motion across the axis dropped)
    assert abs(p1b[0] - (p1[0] + dx)) < 2.5 and abs(p1b[1] - (p1[1] + dy)) < 2.5

    driver.find_element(By.ID, "clip-show").click()
    assert driver.execute_script("return window.sparsecastViewer.handlePixel(1);") is None
    assert driver.execute_script(OVERLAY_ALPHA, *p1b) == 0
    st = _changed_after(driver, "a drag with the overlay hidden", lambda: (
        ActionChains(driver).move_to_element_with_offset(view, round(p1b[0] - w / 2), round(p1b[1] - h / 2))
        .click_and_hold().move_by_offset(30, 0).release().perform()))
    assert st["camera"]["azimuth"] != az0 and st["clip"]["box"] == box
    errors = [e for e in driver.get_log("browser") if e.get("level") == "SEVERE"]
    assert not errors, errors


def test_clip_plane_rows_and_handles(driver, server):
    """Add plane: a row and a cut in the picture (no index rebuild); its centre handle drags
    the plane along its normal (the offset follows, the handle stays under the pointer), its
    tip handle tilts the normal; flip, the checkbox and remove change the frame; the add
    button stops at 6 planes, and "whole volume" removes them all."""
    from selenium.webdriver.common.action_chains import ActionChains
    from selenium.webdriver.common.by import By

    driver.get(server.url)
    wait_for(driver, f"return {IDLE};", 90, "the first full frame")
    full = driver.execute_script(CANVAS)
    add = driver.find_element(By.ID, "plane-add")
    st = _changed_after(driver, "adding a plane", add.click)
    assert len(st["planes"]) == 1 and st["planes"][0]["enabled"] and not st["lastStatus"]["rebuilt"]
    plane0 = st["planes"][0]["plane"]
    assert plane0[:3] == [0.5, 0.5, 0.5] and sorted(abs(v) for v in plane0[3:]) == [0, 0, 1]
    rows = driver.find_elements(By.CSS_SELECTOR, "#plane-list .plane-row")
    assert len(rows) == 1
    offset = rows[0].find_element(By.CSS_SELECTOR, ".plane-offset-value")
    assert float(offset.get_attribute("value")) == pytest.approx(0, abs=1e-6)

    view = driver.find_element(By.ID, "view")
    w, h = view.size["width"], view.size["height"]
    ic = driver.execute_script("return window.sparsecastViewer.planeHandleIndex(0, 'centre');")
    it = driver.execute_script("return window.sparsecastViewer.planeHandleIndex(0, 'tip');")
    pc, pt = (driver.execute_script(f"return window.sparsecastViewer.handlePixel({i});") for i in (ic, it))
    assert pc and pt and driver.execute_script(OVERLAY_ALPHA, *pc) > 0
    # Drag the centre a third of the way to the tip: along the normal's image direction.
    dx, dy = (pt[0] - pc[0]) / 3, (pt[1] - pc[1]) / 3

    def drag(p, dx, dy):
        (ActionChains(driver).move_to_element_with_offset(view, round(p[0] - w / 2), round(p[1] - h / 2))
         .click_and_hold().move_by_offset(round(dx / 2), round(dy / 2)).move_by_offset(round(dx / 2), round(dy / 2))
         .release().perform())

    az0 = st["camera"]["azimuth"]
    st = _changed_after(driver, "dragging the plane's centre", lambda: drag(pc, dx, dy))
    plane1 = st["planes"][0]["plane"]
    assert plane1[3:] == plane0[3:] and plane1[:3] != plane0[:3] and st["camera"]["azimuth"] == az0
    assert float(offset.get_attribute("value")) > 0  # moved the way the normal points
    pc1 = driver.execute_script(f"return window.sparsecastViewer.handlePixel({ic});")
    assert abs(pc1[0] - (pc[0] + dx)) < 2.5 and abs(pc1[1] - (pc[1] + dy)) < 2.5

    pt1 = driver.execute_script(f"return window.sparsecastViewer.handlePixel({it});")
    st = _changed_after(driver, "tilting the plane", lambda: drag(pt1, -(pt1[1] - pc1[1]) / 4, (pt1[0] - pc1[0]) / 4))
    n = st["planes"][0]["plane"][3:]
    assert n != plane0[3:] and sum(v * v for v in n) == pytest.approx(1)
    st = _changed_after(driver, "flipping the plane", rows[0].find_element(By.CSS_SELECTOR, ".plane-flip").click)
    assert st["planes"][0]["plane"][3:] == pytest.approx([-v for v in n])
    st = _changed_after(driver, "disabling the plane", rows[0].find_element(By.CSS_SELECTOR, ".plane-on").click)
    assert driver.execute_script(CANVAS) == full and not st["planes"][0]["enabled"]
    assert driver.execute_script(f"return window.sparsecastViewer.planeHandleIndex(0, 'centre');") == -1
    rows[0].find_element(By.CSS_SELECTOR, ".plane-on").click()
    wait_for(driver, f"return {IDLE};", 30, "a frame with the plane back")

    for _ in range(5):
        add.click()
    assert len(driver.find_elements(By.CSS_SELECTOR, "#plane-list .plane-row")) == 6 and not add.is_enabled()
    driver.find_elements(By.CSS_SELECTOR, "#plane-list .plane-remove")[-1].click()
    assert len(driver.find_elements(By.CSS_SELECTOR, "#plane-list .plane-row")) == 5 and add.is_enabled()
    wait_for(driver, f"return {IDLE};", 30, "a frame with five planes")
    st = _changed_after(driver, "whole volume", driver.find_element(By.ID, "clip-reset").click)
    assert st["planes"] == [] and not driver.find_elements(By.CSS_SELECTOR, "#plane-list .plane-row")
    assert driver.execute_script(CANVAS) == full
    errors = [e for e in driver.get_log("browser") if e.get("level") == "SEVERE"]
    assert not errors, errors


def test_keys_orbit_zoom_and_move_the_current_plane(driver, server):
    """Over the page, arrows orbit and + zooms; [ / ] move the plane last added along its
    normal and f flips it; typed into a field, the same keys do nothing to the view."""
    from selenium.webdriver.common.action_chains import ActionChains
    from selenium.webdriver.common.by import By
    from selenium.webdriver.common.keys import Keys

    driver.get(server.url)
    wait_for(driver, f"return {IDLE};", 90, "the first full frame")
    body = driver.find_element(By.TAG_NAME, "body")
    cam0 = driver.execute_script("return window.sparsecastViewer.camera;")
    press = lambda key: lambda: ActionChains(driver).move_to_element(body).send_keys(key).perform()
    st = _changed_after(driver, "the right arrow", press(Keys.ARROW_RIGHT))
    step = driver.execute_script("return window.sparsecastInteraction.KEY_ORBIT_DEG;")
    assert st["camera"]["azimuth"] == pytest.approx((cam0["azimuth"] + step) % 360)
    assert st["camera"]["elevation"] == pytest.approx(cam0["elevation"])
    st = _changed_after(driver, "the + key", press("+"))
    assert st["camera"]["zoom"] > cam0["zoom"]

    st = _changed_after(driver, "adding a plane", driver.find_element(By.ID, "plane-add").click)
    plane0 = st["planes"][0]["plane"]
    offset = driver.find_element(By.CSS_SELECTOR, "#plane-list .plane-offset-value")
    s0 = float(offset.get_attribute("value"))
    # four steps move the cut a tenth of the box: through some of the blobs
    st = _changed_after(driver, "the ] key", press("]]]]"))
    assert st["planes"][0]["plane"][3:] == plane0[3:] and float(offset.get_attribute("value")) > s0
    st = _changed_after(driver, "the f key", press("f"))
    assert st["planes"][0]["plane"][3:] == pytest.approx([-v for v in plane0[3:]])
    # keys typed into the plane's normal field stay there
    cam1 = st["camera"]
    normal = driver.find_element(By.CSS_SELECTOR, "#plane-list .plane-normal")
    normal.send_keys(Keys.ARROW_LEFT, "]")
    assert driver.execute_script("return window.sparsecastViewer.camera;") == cam1
    errors = [e for e in driver.get_log("browser") if e.get("level") == "SEVERE"]
    assert not errors, errors


def _series_volume():
    """Four steps of a blob field, each step's blobs shifted: every step looks different."""
    import numpy as np

    base = sc.datasets.nbody_blobs(40, n_clusters=3, blobs_per_cluster=12, seed=5).data
    return sc.VolumeSeries.from_array(np.stack([np.roll(base, 6 * t, axis=2) for t in range(4)]), name="rolling")


@pytest.fixture(scope="module")
def series_server():
    srv = ViewerServer(ViewerData.create(_series_volume(), "viridis", index="grid-pc"), "127.0.0.1", 0).start()
    yield srv
    srv.stop()


@pytest.fixture(scope="module")
def label_server():
    import numpy as np

    seg = np.zeros((32, 32, 32), np.uint8)
    seg[4:14, 4:14, 4:14], seg[12:26, 14:28, 10:24], seg[20:30, 2:12, 18:30] = 1, 2, 3
    srv = ViewerServer(ViewerData.create(sc.Volume(seg), sc.TransferFunction.labels([1, 2, 3]), index="kdtree-deep"),
                       "127.0.0.1", 0).start()
    yield srv
    srv.stop()


def _click_slider(driver, el_id, fraction):
    """Click a range input at ``fraction`` of its width: the value jumps there ('input' and 'change' fire)."""
    from selenium.webdriver.common.action_chains import ActionChains
    from selenium.webdriver.common.by import By

    el = driver.find_element(By.ID, el_id)
    w = el.size["width"]
    ActionChains(driver).move_to_element_with_offset(el, int((fraction - 0.5) * (w - 16)), 0).click().perform()
    return el


def _changed_after(driver, what, act):
    """Run ``act``; wait for a full frame of the new state; assert the picture changed."""
    before = driver.execute_script(CANVAS)
    frames = driver.execute_script(f"return {IDLE};")
    act()
    wait_for(driver, f"const f = {IDLE}; return f > {frames} ? f : 0;", 60, f"a full frame after {what}")
    after = driver.execute_script(CANVAS)
    assert after != before, f"{what} did not change the picture"
    return driver.execute_script("return window.sparsecastViewer;")


def test_isovalue_clip_and_time_sliders_change_the_frame(driver, series_server):
    from selenium.webdriver.common.by import By
    from selenium.webdriver.support.ui import Select

    driver.get(series_server.url)
    wait_for(driver, f"return {IDLE};", 90, "the first full frame")
    assert not driver.find_element(By.ID, "time-box").get_attribute("hidden")
    assert driver.find_element(By.ID, "labels-box").get_attribute("hidden")  # not a label volume

    st = _changed_after(driver, "moving the time slider", lambda: _click_slider(driver, "time", 1.0))
    assert st["time"] == 3 and st["lastStatus"]["time"] == 3

    st = _changed_after(driver, "moving a clip slider", lambda: _click_slider(driver, "clip-x-hi", 0.5))
    assert 0.3 < st["clip"]["box"][1][0] < 0.7 and st["lastStatus"]["samples"] > 0

    st = _changed_after(driver, "switching to iso", lambda: Select(driver.find_element(By.ID, "mode")).select_by_value("iso"))
    assert st["lastStatus"]["mode"] == "iso"
    assert driver.find_element(By.ID, "iso").is_displayed()
    iso0 = st["iso"][0]
    st = _changed_after(driver, "moving the isovalue slider", lambda: _click_slider(driver, "iso", 0.15))
    assert st["iso"][0] < iso0 and st["lastStatus"]["mode"] == "iso"
    errors = [e for e in driver.get_log("browser") if e.get("level") == "SEVERE"]
    assert not errors, errors


def test_label_table_toggles_a_label(driver, label_server):
    from selenium.webdriver.common.by import By

    driver.get(label_server.url)
    wait_for(driver, f"return {IDLE};", 90, "the first full frame")
    assert driver.find_element(By.ID, "tf-box").get_attribute("hidden")  # no TF editor for labels
    rows = driver.find_elements(By.CSS_SELECTOR, "#label-table tbody tr")
    assert [r.find_elements(By.TAG_NAME, "td")[1].text for r in rows] == ["0", "1", "2", "3"]
    assert rows[0].find_elements(By.TAG_NAME, "td")[3].text.replace(",", "").isdigit()
    box2 = driver.find_element(By.CSS_SELECTOR, "#label-table input[data-id='2']")
    assert box2.is_selected()
    samples0 = driver.execute_script("return window.sparsecastViewer.lastStatus.samples;")
    st = _changed_after(driver, "hiding label 2", box2.click)
    assert st["lastStatus"]["samples"] < samples0  # its bricks are skipped now
    st = _changed_after(driver, "hiding all labels", driver.find_element(By.ID, "labels-none").click)
    assert st["lastStatus"]["samples"] == 0
    errors = [e for e in driver.get_log("browser") if e.get("level") == "SEVERE"]
    assert not errors, errors
