"""The viewer's pointer mappings (static/interaction.js), run under node.

Skips when node is not installed: the page itself needs only a browser.
"""

from __future__ import annotations

import json
import shutil
import subprocess
from importlib import resources

import pytest

NODE = shutil.which("node")
pytestmark = pytest.mark.skipif(NODE is None, reason="node not installed (needed to run the viewer's JS)")
SCRIPT = resources.files("sparsecast.viewer") / "static" / "interaction.js"


def js(expr: str):
    """Value of ``expr`` (JSON-serialisable) with interaction.js loaded as ``ui``."""
    prog = f"const ui = require({json.dumps(str(SCRIPT))}); console.log(JSON.stringify({expr}));"
    out = subprocess.run([NODE, "-e", prog], capture_output=True, text=True, timeout=30, check=True)
    return json.loads(out.stdout)


def test_opacity_snaps_to_zero_near_the_floor():
    h, pad = 120, 6
    floor = h - pad
    assert js(f"[{floor}, {floor - 1}, {floor - 4}, {h}].map((y) => ui.opacityAt(y, {h}, {pad}))") == [0, 0, 0, 0]
    a = js(f"ui.opacityAt({floor - 5}, {h}, {pad})")
    assert 0 < a < 0.1
    assert js(f"ui.opacityAt({h // 2}, {h}, {pad})") == pytest.approx(0.5)
    assert js(f"[ui.opacityAt({pad}, {h}, {pad}), ui.opacityAt(0, {h}, {pad})]") == [1, 1]


def _front_point_on_screen(az: float, el: float) -> tuple[float, float]:
    """Screen position (right, up) of the surface point that faces the camera at (0, 0)."""
    import numpy as np

    import sparsecast as sc

    vol = sc.Volume(np.zeros((9, 9, 9), np.float32))
    front = vol.center + (sc.Camera.orbit(vol, 0, 0).eye - vol.center) * 0.1
    cam = sc.Camera.orbit(vol, az, el)
    forward, right, up = cam.basis()
    d = front - cam.eye
    return float(d @ right / (d @ forward)), float(d @ up / (d @ forward))


@pytest.mark.parametrize("dx, dy", [(10, 0), (-10, 0), (0, 10), (0, -10), (7, -5)])
def test_orbit_drag_moves_the_surface_with_the_mouse(dx, dy):
    """Dragging right moves the surface under the cursor right; dragging down (client y
    grows) moves it down, i.e. against the camera's up vector."""
    ang = js(f"ui.orbitDrag(0, 0, {dx}, {dy})")
    x0, y0 = _front_point_on_screen(0.0, 0.0)
    x1, y1 = _front_point_on_screen(ang["azimuth"], ang["elevation"])
    assert (x1 - x0) * dx >= 0 and (dx == 0 or abs(x1 - x0) > 1e-3)
    assert (y1 - y0) * -dy >= 0 and (dy == 0 or abs(y1 - y0) > 1e-3)
    assert 0 <= ang["azimuth"] < 360 and -90 < ang["elevation"] < 90


def test_sliders_map_onto_the_range_and_back():
    n = js("ui.SLIDER_STEPS")
    assert js(f"[0, {n // 2}, {n}, -5, {n + 9}].map((p) => ui.sliderValue(p, -2, 6))") == [-2, 2, 6, -2, 6]
    assert js(f"[-2, 2, 6, -100, 100].map((v) => ui.sliderPos(v, -2, 6))") == [0, n // 2, n, 0, n]
    assert js("ui.sliderPos(3, 1, 1)") == 0  # a constant volume: no range to slide over
    v = js(f"ui.sliderValue(ui.sliderPos(0.3141, 0, 1), 0, 1)")
    assert abs(v - 0.3141) <= 0.5 / n


def test_clip_sliders_keep_lo_below_hi():
    assert js("ui.clipPair(0.2, 0.7, 'lo')") == [0.2, 0.7]
    assert js("ui.clipPair(0.8, 0.7, 'lo')") == [0.8, 0.8]  # lo pushed hi up
    assert js("ui.clipPair(0.3, 0.1, 'hi')") == [0.1, 0.1]  # hi pushed lo down


# --- the clip-box overlay: projection with the frame's camera, face drags ------------------

def _cameras():
    """Viewer-like cameras: perspective orbits (one panned and zoomed, one mirrored by a
    left-handed orientation) and orthographic ones, framing an anisotropic box."""
    import numpy as np

    import sparsecast as sc

    vol = sc.Volume(np.zeros((20, 14, 9), np.float32), spacing=(1.0, 1.5, 0.7), origin=(-3.0, 2.0, 5.0))
    vol_las = sc.Volume(np.zeros((20, 14, 9), np.float32), orientation="LAS")
    return {
        "perspective": (vol, sc.Camera.orbit(vol, 30.0, 20.0)),
        "perspective-panned": (vol, sc.Camera.orbit(vol, 200.0, -35.0, zoom=1.7, pan=(0.3, -0.2), fov_y=50.0)),
        "perspective-mirrored": (vol_las, sc.Camera.orbit(vol_las, 15.0, 10.0, view="anterior")),
        "orthographic": (vol, sc.Camera.orbit(vol, 120.0, 60.0, projection="orthographic", zoom=1.3)),
        "orthographic-look-at": (vol, sc.Camera.look_at((40.0, -30.0, 20.0), vol.center, projection="orthographic",
                                                         ortho_height=25.0)),
    }


def _frame_camera(cam, w, h):
    from sparsecast.viewer.session import frame_camera

    return frame_camera(cam, w, h)


def _python_pixel(cam, p, w, h):
    """Image position (x right, y down, pixels) of world point ``p``, derived from the
    camera's basis and field of view (not from ray_params)."""
    import numpy as np

    forward, right, up = cam.basis()
    d = np.asarray(p, float) - cam.eye
    if cam.projection == "perspective":
        half = np.tan(np.radians(cam.fov_y) / 2)
        x, y = d @ right / (d @ forward), d @ up / (d @ forward)
    else:
        half = cam.ortho_height / 2
        x, y = d @ right, d @ up
    return (x / (half * w / h) + 1) / 2 * w, (1 - y / half) / 2 * h


@pytest.mark.parametrize("name", list(_cameras()))
def test_projection_inverts_the_renderers_primary_rays(name):
    """A point anywhere on the ray the renderer casts through pixel (col, row) projects
    to that pixel's centre, and any world point lands where the camera's own geometry
    puts it: the overlay is drawn with the camera the server renders with."""
    import numpy as np

    from sparsecast.kernels.camera import primary_ray

    vol, cam = _cameras()[name]
    w, h = 72, 48
    params = cam.ray_params(w, h)
    pixels = [(0, 0), (w - 1, 0), (0, h - 1), (w - 1, h - 1), (36, 24), (11, 37), (60, 5)]
    pts, want = [], []
    for col, row in pixels:
        ray = np.array(primary_ray(params, col, row, w, h))
        for t in (0.5 * vol.diagonal, vol.diagonal, 2.0 * vol.diagonal):
            pts.append((ray[:3] + t * ray[3:]).tolist())
            want.append((col + 0.5, row + 0.5))
    fc = json.dumps(_frame_camera(cam, w, h))
    got = js(f"{json.dumps(pts)}.map((p) => ui.projectPoint({fc}, p, {w}, {h}))")
    np.testing.assert_allclose(got, want, atol=1e-6)
    # Arbitrary points (the volume's corners and beyond) against the basis-and-fov derivation.
    lo, hi = vol.bounds
    rng = np.random.default_rng(1)
    world = (lo + rng.uniform(-0.3, 1.3, (20, 3)) * (hi - lo)).tolist()
    got = js(f"{json.dumps(world)}.map((p) => ui.projectPoint({fc}, p, {w}, {h}))")
    np.testing.assert_allclose(got, [_python_pixel(cam, p, w, h) for p in world], atol=1e-6)


@pytest.mark.parametrize("name", ["perspective-panned", "orthographic"])
def test_pixel_ray_is_the_renderers_ray(name):
    import numpy as np

    from sparsecast.kernels.camera import primary_ray

    _, cam = _cameras()[name]
    w, h = 40, 30
    fc = json.dumps(_frame_camera(cam, w, h))
    for col, row in ((0, 0), (39, 29), (17, 8)):
        o, d = js(f"ui.pixelRay({fc}, {col + 0.5}, {row + 0.5}, {w}, {h})")
        ref = np.array(primary_ray(cam.ray_params(w, h), col, row, w, h))
        np.testing.assert_allclose(np.array(d) / np.linalg.norm(d), ref[3:], atol=1e-12)
        # same line: the renderer's origin lies on it
        diff = ref[:3] - np.array(o)
        np.testing.assert_allclose(diff - (diff @ ref[3:]) * ref[3:], 0, atol=1e-9)


def test_projection_refuses_points_behind_a_perspective_eye_and_clips_edges():
    vol, cam = _cameras()["perspective"]
    fc = json.dumps(_frame_camera(cam, 64, 64))
    behind = (cam.eye - (cam.target - cam.eye)).tolist()
    front = cam.target.tolist()
    assert js(f"ui.projectPoint({fc}, {behind}, 64, 64)") is None
    seg = js(f"ui.clipSegment({fc}, {behind}, {front}, 0.5)")
    assert js(f"ui.depth({fc}, {json.dumps(seg[0])})") == pytest.approx(0.5)
    assert seg[1] == pytest.approx(front)
    assert js(f"ui.clipSegment({fc}, {behind}, {behind}, 0.5)") is None


def test_box_edges_and_face_handles():
    import numpy as np

    lo, hi = [0, -1, 2], [4, 3, 3]
    edges = np.array(js(f"ui.boxEdges({lo}, {hi})"))
    assert edges.shape == (12, 2, 3)
    # Every edge joins two corners and runs along exactly one axis; 4 edges per axis.
    axes = [int(np.flatnonzero(a != b)[0]) for a, b in edges if np.count_nonzero(a != b) == 1]
    assert sorted(axes) == [0] * 4 + [1] * 4 + [2] * 4
    assert {tuple(c) for c in edges.reshape(-1, 3)} == {(x, y, z) for x in (0, 4) for y in (-1, 3) for z in (2, 3)}
    handles = js(f"ui.faceHandles({lo}, {hi})")
    assert [(f["axis"], f["side"]) for f in handles] == [(j, s) for j in range(3) for s in ("lo", "hi")]
    assert handles[1]["point"] == [4, 1, 2.5] and handles[4]["point"] == [2, 1, 2]
    box = js("ui.clipBoxWorld([[-2, 0, 10], [2, 8, 20]], [[0, 0.25, 0.5], [1, 0.75, 0.6]])")
    np.testing.assert_allclose(box, [[-2, 2, 15], [2, 6, 16]])
    assert js("ui.pickHandle([[10, 10], null, [14, 10]], 13, 10, 6)") == 2
    assert js("ui.pickHandle([[10, 10], [50, 50]], 30, 30, 6)") == -1


def _drag(fc, bounds, box, axis, side, dx, dy, w=96, h=96):
    return js(f"ui.faceDrag({fc}, {json.dumps(bounds)}, {json.dumps(box)}, {axis}, '{side}', {dx}, {dy}, {w}, {h})")


@pytest.mark.parametrize("name", ["perspective", "perspective-panned", "orthographic"])
@pytest.mark.parametrize("axis, side", [(0, "hi"), (1, "lo"), (2, "hi")])
def test_dragging_a_face_handle_moves_the_face_under_the_pointer(name, axis, side):
    """Drag a face's handle along the image direction of its axis: the face follows the
    pointer (its centre ends under it, perspective included, where equal image steps are
    not equal steps along the axis); drag across that direction: the face stays."""
    import numpy as np

    vol, cam = _cameras()[name]
    w = h = 96
    lo, hi = vol.bounds
    bounds = [lo.tolist(), hi.tolist()]
    box = [[0.2, 0.35, 0.3], [0.7, 0.8, 0.75]]

    def centre_px(b):
        c = 0.5 * (np.array(b[0]) + np.array(b[1]))
        c[axis] = b[0 if side == "lo" else 1][axis]
        return np.array(_python_pixel(cam, lo + c * (hi - lo), w, h))

    # The face's direction on screen, from the Python camera: where the centre goes when
    # the face moves by 0.1 of the box.
    moved = [r[:] for r in box]
    moved[0 if side == "lo" else 1][axis] += -0.1 if side == "lo" else 0.1
    step = centre_px(moved) - centre_px(box)
    assert np.linalg.norm(step) > 2  # (these views see every axis from the side)
    fc = json.dumps(_frame_camera(cam, w, h))
    for k in (0.5, 1.0, 2.0, -0.8):
        d = k * step
        new = _drag(fc, bounds, box, axis, side, *d.tolist())
        b2 = [r[:] for r in box]
        b2[0][axis], b2[1][axis] = new
        f = new[0 if side == "lo" else 1]
        f0 = box[0 if side == "lo" else 1][axis]
        assert np.sign(f - f0) == np.sign(k) * (-1 if side == "lo" else 1)
        assert np.linalg.norm(centre_px(b2) - (centre_px(box) + d)) < 1e-6
        # Any motion across the axis's image adds nothing.
        across = d + 0.7 * np.array([-step[1], step[0]])
        assert _drag(fc, bounds, box, axis, side, *across.tolist()) == pytest.approx(new, abs=1e-9)
    perp = np.array([-step[1], step[0]])
    assert _drag(fc, bounds, box, axis, side, *perp.tolist()) == pytest.approx([box[0][axis], box[1][axis]], abs=1e-9)


def test_face_drags_stop_at_the_opposite_face_and_the_volume_box():
    import numpy as np

    vol, cam = _cameras()["perspective"]
    lo, hi = vol.bounds
    bounds = [lo.tolist(), hi.tolist()]
    box = [[0.2, 0.1, 0.3], [0.7, 0.8, 0.75]]
    fc = json.dumps(_frame_camera(cam, 96, 96))
    s = np.array(js(f"ui.faceAxisPx({fc}, {json.dumps(bounds)}, {json.dumps(box)}, 0, 'hi', 96, 96)"))
    far = (s * 5).tolist()  # five boxes along +x
    assert _drag(fc, bounds, box, 0, "hi", *far) == [0.2, 1.0]
    assert _drag(fc, bounds, box, 0, "lo", *far) == [0.7, 0.7]  # lo stops at hi
    back = (-s * 5).tolist()
    assert _drag(fc, bounds, box, 0, "hi", *back) == [0.2, 0.2]  # hi stops at lo
    assert _drag(fc, bounds, box, 0, "lo", *back) == [0.0, 0.7]


def test_a_face_seen_head_on_does_not_move():
    """Looking straight down z, the z faces' normals have no extent on screen: a drag
    there would be a division by ~0, so it does nothing."""
    import sparsecast as sc

    vol, _ = _cameras()["perspective"]
    cam = sc.Camera.look_at(vol.center + [0, 0, 100.0], vol.center, up=(0, 1, 0))
    lo, hi = vol.bounds
    bounds = [lo.tolist(), hi.tolist()]
    box = [[0.2, 0.1, 0.3], [0.7, 0.8, 0.75]]
    fc = json.dumps(_frame_camera(cam, 96, 96))
    n = js(f"Math.hypot(...ui.faceAxisPx({fc}, {json.dumps(bounds)}, {json.dumps(box)}, 2, 'hi', 96, 96))")
    assert n < js("ui.MIN_AXIS_PX")
    assert _drag(fc, bounds, box, 2, "hi", 30, -40) == [0.3, 0.75]
    assert _drag(fc, bounds, box, 0, "hi", 30, 0) != [0.2, 0.7]  # x still moves


def test_the_overlay_outlines_the_clip_box_the_session_renders():
    """End to end without a browser: render a clip box of an opaque volume in a viewer
    session, project the box with the hello's world box and the frame's camera as the
    page does: the projected corners bound the rendered footprint to a pixel."""
    import numpy as np

    import sparsecast as sc
    from sparsecast.viewer.messages import CameraSpec, ClipSpec, RenderRequest, TFSpec
    from sparsecast.viewer.session import Session, ViewerData

    vol = sc.Volume(np.ones((24, 20, 16), np.float32), spacing=(1.0, 1.3, 0.9), origin=(5.0, -2.0, 1.0))
    opaque = TFSpec(((0.0, 1.0, 1.0, 1.0, 1.0), (1.0, 1.0, 1.0, 1.0, 1.0)), None, (0.0, 2.0))
    data = ViewerData.create(vol, "viridis", index="naive")
    box = ((0.15, 0.3, 0.2), (0.8, 0.9, 0.6))
    s = Session(data)
    w, h = 88, 64
    for cam in (CameraSpec(35.0, 25.0, 1.0), CameraSpec(250.0, -40.0, 1.6, (0.1, -0.2))):
        _, st = s.render_frame(s.update(RenderRequest(width=w, height=h, tf=opaque, camera=cam,
                                                      clip=ClipSpec(box))))
        # white on the black background: the colour is the opacity
        rows, cols = np.nonzero(s.last_rgba[..., :3].max(axis=-1) > 0.05)
        assert len(rows) > 100
        fc, bounds = json.dumps(st["camera"]), json.dumps(data.hello()["volume"]["bounds"])
        pts = np.array(js(f"(() => {{ const [lo, hi] = ui.clipBoxWorld({bounds}, {json.dumps(box)});"
                          f"return ui.boxEdges(lo, hi).flat().map((p) => ui.projectPoint({fc}, p, {w}, {h})); }})()"))
        # pixel (col, row) covers [col, col + 1): the footprint's extent in image coordinates
        got = [cols.min(), cols.max() + 1, rows.min(), rows.max() + 1]
        want = [pts[:, 0].min(), pts[:, 0].max(), pts[:, 1].min(), pts[:, 1].max()]
        np.testing.assert_allclose(got, want, atol=1.0)


# --- clip planes: their cut of the box, offsets, handles, drags and tilts ------------------

def _plane_world(bounds, plane):
    """(point, unit normal) in world units of a message plane [px, py, pz, nx, ny, nz]."""
    import numpy as np

    lo, hi = (np.asarray(b, float) for b in bounds)
    n = np.asarray(plane[3:], float)
    return lo + np.asarray(plane[:3], float) * (hi - lo), n / np.linalg.norm(n)


BOUNDS = [[-3.0, 2.0, 5.0], [17.0, 23.0, 11.3]]  # the anisotropic box of _cameras' volume


def _random_planes(n, seed):
    import numpy as np

    rng = np.random.default_rng(seed)
    out = [[0.5, 0.5, 0.5, 1, 0, 0], [0.2, 0.9, 0.4, 0, -1, 0], [0.5, 0.5, 0.5, 1, 1, 1]]
    for _ in range(n):
        out.append([*rng.uniform(0, 1, 3).tolist(), *rng.normal(size=3).tolist()])
    return out


def test_plane_box_polygon_is_the_planes_convex_cut_of_the_box():
    """Vertices on the plane and on the box's surface, convex and counter-clockwise seen
    from the normal's side, and the polygon's area equals the area of the plane's points
    that lie in the box (counted on a grid in the plane with numpy)."""
    import numpy as np

    lo, hi = (np.array(b) for b in BOUNDS)
    tol = 1e-9 * np.linalg.norm(hi - lo)
    planes = _random_planes(9, 4)
    polys = js(f"{json.dumps(planes)}.map((p) => ui.planeBoxPolygon({BOUNDS[0]}, {BOUNDS[1]},"
               f" ui.fracToWorld({json.dumps(BOUNDS)}, p.slice(0, 3)), p.slice(3)))")
    for plane, poly in zip(planes, polys):
        p, n = _plane_world(BOUNDS, plane)
        q = np.array(poly)
        assert 3 <= len(q) <= 6, (plane, poly)
        np.testing.assert_allclose((q - p) @ n, 0, atol=tol)
        assert np.all(q >= lo - tol) and np.all(q <= hi + tol)
        assert np.all(np.min(np.minimum(np.abs(q - lo), np.abs(q - hi)), axis=1) < tol)  # on a face
        e = np.roll(q, -1, axis=0) - q
        turns = np.cross(e, np.roll(e, -1, axis=0)) @ n
        assert np.all(turns > 0), turns  # convex, counter-clockwise about +n
        area = 0.5 * np.sum(np.cross(q - q[0], np.roll(q, -1, axis=0) - q[0]) @ n)
        # Grid over the plane, centred at the plane point nearest the box centre.
        u = np.cross(n, [1.0, 0, 0] if abs(n[0]) < 0.9 else [0, 1.0, 0])
        u /= np.linalg.norm(u)
        v = np.cross(n, u)
        c = (lo + hi) / 2
        c = c - ((c - p) @ n) * n
        r, m = 0.5 * np.linalg.norm(hi - lo), 500
        g = (np.arange(m) + 0.5) / m * 2 * r - r
        pts = c + g[:, None, None] * u + g[None, :, None] * v
        inside = np.all((pts >= lo) & (pts <= hi), axis=-1).sum()
        assert area == pytest.approx(inside * (2 * r / m) ** 2, rel=0.02)
    # A plane through a face gives that face whichever way its normal points; one beside the box, nothing.
    for sign in (1, -1):
        face = js(f"ui.planeBoxPolygon({BOUNDS[0]}, {BOUNDS[1]}, {BOUNDS[1]}, [{sign}, 0, 0])")
        assert sorted(map(tuple, face)) == sorted((17.0, y, z) for y in (2.0, 23.0) for z in (5.0, 11.3))
    assert js(f"ui.planeBoxPolygon({BOUNDS[0]}, {BOUNDS[1]}, [18, 2, 5], [1, 0, 0.1])") == []


def test_plane_offsets_sweep_the_box_and_keep_the_point_inside():
    import numpy as np

    lo, hi = (np.array(b) for b in BOUNDS)
    corners = np.array([[(lo, hi)[k >> j & 1][j] for j in range(3)] for k in range(8)])
    for plane in _random_planes(6, 7):
        p, n = _plane_world(BOUNDS, plane)
        h = js(f"ui.planeHalfRange({json.dumps(BOUNDS)}, {plane[3:]})")
        assert h == pytest.approx(np.max((corners - (lo + hi) / 2) @ n))
        s0 = js(f"ui.planeOffset({json.dumps(BOUNDS)}, {plane})")
        assert s0 == pytest.approx((p - (lo + hi) / 2) @ n)
        for s in (-1.5 * h, -h, -0.6 * h, 0.0, 0.3 * h, 0.99 * h, h, 2 * h):
            got = js(f"ui.planeAtOffset({json.dumps(BOUNDS)}, {plane}, {s})")
            q, m = _plane_world(BOUNDS, got)
            np.testing.assert_allclose(m, n, atol=1e-12)  # same unit normal
            assert all(0 <= f <= 1 for f in got[:3]), got
            assert (q - (lo + hi) / 2) @ n == pytest.approx(np.clip(s, -h, h), abs=1e-9)
            # The point slides along the normal while that stays in the box.
            slid = p + (np.clip(s, -h, h) - s0) * n
            if np.all((slid - lo) / (hi - lo) >= 0) and np.all((slid - lo) / (hi - lo) <= 1):
                np.testing.assert_allclose(q, slid, atol=1e-9)
    # Full offset: the corner farthest along the normal; an axis normal keeps the point on the axis.
    got = js(f"ui.planeAtOffset({json.dumps(BOUNDS)}, [0.5, 0.5, 0.5, 1, -2, 0.5], 1e9)")
    assert got[:3] == [1, 0, 1]
    assert js(f"ui.planeAtOffset({json.dumps(BOUNDS)}, [0.9, 0.2, 0.5, 0, 0, -1], 2.0)")[:3] == \
        pytest.approx([0.9, 0.2, 0.5 - 2.0 / 6.3])


def test_new_plane_faces_away_from_the_camera_along_the_nearest_axis():
    import numpy as np

    box = [[0.2, 0.0, 0.4], [0.6, 1.0, 0.8]]
    for name, (vol, cam) in _cameras().items():
        lo, hi = vol.bounds
        fc = json.dumps(_frame_camera(cam, 64, 64))
        bounds = json.dumps([lo.tolist(), hi.tolist()])
        got = js(f"ui.newPlane({fc}, {bounds}, {json.dumps(box)})")
        assert got[:3] == pytest.approx([0.4, 0.5, 0.6])
        c = lo + np.array(got[:3]) * (hi - lo)
        view = c - cam.eye if cam.projection == "perspective" else cam.basis()[0]
        j = int(np.argmax(np.abs(view)))
        want = np.zeros(3)
        want[j] = np.sign(view[j])
        assert got[3:] == want.tolist(), name
    assert js("ui.newPlane(null, [[0, 0, 0], [1, 1, 1]], [[0, 0, 0], [1, 1, 1]])") == [0.5, 0.5, 0.5, 1, 0, 0]


def test_clip_message_sends_the_enabled_planes():
    rows = [{"plane": [0.5, 0.5, 0.5, 1, 0, 0], "enabled": True}, {"plane": [0.1, 0.2, 0.3, 0, 1, 0], "enabled": False},
            {"plane": [0.4, 0.5, 0.6, 0, 0, -1], "enabled": True}]
    msg = js(f"ui.clipMessage([[0, 0, 0], [1, 0.5, 1]], {json.dumps(rows)}, 1, 6)")
    assert msg == {"box": [[0, 0, 0], [1, 0.5, 1]], "planes": [rows[0]["plane"], rows[2]["plane"]], "cap": True}
    assert js(f"ui.clipMessage([[0, 0, 0], [1, 1, 1]], {json.dumps(rows)}, false, 1)")["planes"] == [rows[0]["plane"]]


def _handle_px(cam, bounds, plane, w, h, which="centre"):
    import numpy as np

    p, n = _plane_world(bounds, plane)
    if which == "tip":
        p = p + js("ui.PLANE_TIP_FRACTION") * np.linalg.norm(np.subtract(bounds[1], bounds[0])) * n
    return np.array(_python_pixel(cam, p, w, h))


@pytest.mark.parametrize("name", ["perspective", "perspective-panned", "orthographic"])
def test_dragging_a_planes_centre_moves_it_along_its_normal_under_the_pointer(name):
    """As for box faces: along the normal's image direction the plane follows the pointer
    (the re-projected centre lands under it); across it nothing moves; the normal stays."""
    import numpy as np

    vol, cam = _cameras()[name]
    w = h = 96
    lo, hi = vol.bounds
    bounds = [lo.tolist(), hi.tolist()]
    plane = [0.45, 0.5, 0.55, 0.6, -0.5, 0.62]
    p, n = _plane_world(bounds, plane)
    sweep = 2 * js(f"ui.planeHalfRange({json.dumps(bounds)}, {plane[3:]})")
    moved = plane[:3] + 0.05 * sweep * n / (hi - lo)
    step = _handle_px(cam, bounds, [*moved, *plane[3:]], w, h) - _handle_px(cam, bounds, plane, w, h)
    assert np.linalg.norm(step) > 2
    fc = json.dumps(_frame_camera(cam, w, h))
    s0 = js(f"ui.planeOffset({json.dumps(bounds)}, {plane})")
    for k in (0.5, 1.0, 2.0, -1.5):
        d = k * step
        new = js(f"ui.planeDrag({fc}, {json.dumps(bounds)}, {plane}, {d[0]}, {d[1]}, {w}, {h})")
        assert new[3:] == plane[3:]
        s1 = js(f"ui.planeOffset({json.dumps(bounds)}, {new})")
        assert np.sign(s1 - s0) == np.sign(k)
        np.testing.assert_allclose(_handle_px(cam, bounds, new, w, h), _handle_px(cam, bounds, plane, w, h) + d,
                                   atol=1e-6)
        across = d + 0.6 * np.array([-step[1], step[0]])
        again = js(f"ui.planeDrag({fc}, {json.dumps(bounds)}, {plane}, {across[0]}, {across[1]}, {w}, {h})")
        assert again == pytest.approx(new, abs=1e-9)


def test_plane_drags_stop_at_the_volume_box_and_recentre():
    import numpy as np

    vol, cam = _cameras()["perspective"]
    lo, hi = vol.bounds
    bounds = [lo.tolist(), hi.tolist()]
    fc = json.dumps(_frame_camera(cam, 96, 96))
    plane = [0.5, 0.4, 0.5, 1.0, 0.8, -0.3]
    s = np.array(js(f"ui.planeAxisPx({fc}, {json.dumps(bounds)}, {plane}, 96, 96)"))
    for k in (4.0, -4.0):  # four whole sweeps either way
        new = js(f"ui.planeDrag({fc}, {json.dumps(bounds)}, {plane}, {k * s[0]}, {k * s[1]}, 96, 96)")
        f = np.array(new[:3])
        assert np.all(f >= 0) and np.all(f <= 1) and np.any((f < 1e-9) | (f > 1 - 1e-9)), f
        # on the normal's line through the start point
        p, n = _plane_world(bounds, plane)
        q, _ = _plane_world(bounds, new)
        np.testing.assert_allclose(np.cross(q - p, n), 0, atol=1e-9)
        # Recentred on release: the same plane, its point back inside the box.
        r = js(f"ui.planeRecentre({json.dumps(bounds)}, {new})")
        q2, _ = _plane_world(bounds, r)
        assert (q2 - q) @ n == pytest.approx(0, abs=1e-9) and r[3:] == new[3:]
        assert all(0 < t < 1 for t in r[:3]), r
    inside = [0.3, 0.6, 0.5, 1, 0, 0]
    assert js(f"ui.planeRecentre({json.dumps(bounds)}, {inside})") == inside


def test_a_plane_seen_head_on_does_not_move():
    import numpy as np

    import sparsecast as sc

    vol, _ = _cameras()["perspective"]
    lo, hi = vol.bounds
    bounds = [lo.tolist(), hi.tolist()]
    n = np.array([0.3, -0.4, 0.866])
    cam = sc.Camera.look_at(vol.center + 80 * n, vol.center, up=(0, 1, 0))
    fc = json.dumps(_frame_camera(cam, 96, 96))
    plane = [0.5, 0.5, 0.5, *n.tolist()]
    px = js(f"ui.planeAxisPx({fc}, {json.dumps(bounds)}, {plane}, 96, 96)")
    assert np.hypot(*px) < js("ui.MIN_AXIS_PX")
    assert js(f"ui.planeDrag({fc}, {json.dumps(bounds)}, {plane}, 30, -40, 96, 96)") == plane
    side = [0.5, 0.5, 0.5, 1, 0, 0]  # seen from the side: it moves
    assert js(f"ui.planeDrag({fc}, {json.dumps(bounds)}, {side}, 30, 0, 96, 96)") != side


def _pointer_ray(fc, x, y, w, h):
    """Origin and unit direction of the ray through image position (x, y), from the frame
    camera's definition (session.frame_camera)."""
    import numpy as np

    u, v = x / w * 2 - 1, 1 - y / h * 2
    eye, fwd, right, up = (np.array(fc[k]) for k in ("eye", "forward", "right", "up"))
    if fc["perspective"]:
        d = fwd + u * right + v * up
        return eye, d / np.linalg.norm(d)
    return eye + u * right + v * up, fwd


@pytest.mark.parametrize("name", ["perspective", "perspective-panned", "orthographic", "orthographic-look-at"])
def test_tilting_a_plane_puts_its_tip_under_the_pointer(name):
    """The tip handle follows the pointer on the sphere about the centre: unit normal, the
    point unchanged; where the pointer's ray meets the sphere the tip re-projects under the
    pointer, on the half of the sphere it started on; where it misses, the normal is
    perpendicular to that ray (the tip on the sphere's outline) and points the way the
    pointer went on screen."""
    import numpy as np

    vol, cam = _cameras()[name]
    w = h = 96
    lo, hi = vol.bounds
    bounds = [lo.tolist(), hi.tolist()]
    frame = _frame_camera(cam, w, h)
    fc = json.dumps(frame)
    length = js("ui.PLANE_TIP_FRACTION") * np.linalg.norm(hi - lo)
    forward = cam.basis()[0]
    hits = misses = 0
    for n0 in ([0.2, 0.9, -0.3], [-0.7, 0.1, 0.5], (-forward + 0.3 * cam.basis()[1]).tolist(),
               (forward + 0.2 * cam.basis()[2]).tolist()):
        plane = [0.4, 0.55, 0.5, *n0]
        c, m0 = _plane_world(bounds, plane)
        tip0 = _handle_px(cam, bounds, plane, w, h, "tip")
        centre = _handle_px(cam, bounds, plane, w, h)
        near0 = m0 @ _pointer_ray(frame, *tip0, w, h)[1] < 0
        out = tip0 - centre
        out = out / np.linalg.norm(out) if np.linalg.norm(out) > 1e-9 else np.array([1.0, 0.0])
        for d in (np.array([6.0, 0.0]), np.array([0.0, -9.0]), np.array([-5.0, 4.0]), 40 * out, 200 * out):
            new = js(f"ui.planeTilt({fc}, {json.dumps(bounds)}, {plane}, {d[0]}, {d[1]}, {w}, {h})")
            assert new[:3] == plane[:3] and np.linalg.norm(new[3:]) == pytest.approx(1)
            _, m = _plane_world(bounds, new)
            o, ray = _pointer_ray(frame, *(tip0 + d), w, h)
            if np.linalg.norm(np.cross(c - o, ray)) < length:  # the ray meets the sphere
                hits += 1
                np.testing.assert_allclose(_handle_px(cam, bounds, new, w, h, "tip"), tip0 + d, atol=1e-6)
                assert (m @ ray < 0) == near0
            else:
                misses += 1
                assert m @ ray == pytest.approx(0, abs=1e-9)
                moved = _handle_px(cam, bounds, new, w, h, "tip") - centre
                assert moved @ (tip0 + d - centre) > 0.9 * np.linalg.norm(moved) * np.linalg.norm(tip0 + d - centre)
    assert hits >= 10 and misses >= 2


def test_the_pages_planes_render_as_render_does_and_the_overlay_outlines_the_cut():
    """End to end without a browser: planes made with the page's functions (add plane,
    an offset, a tilt, a flip, one row disabled) go through clipMessage into a render
    message the server parses; the session's frame equals ``sc.render`` with those planes
    in world units; and for an opaque box cut by one plane, the kept corners and the
    projected cut polygon bound the rendered footprint to a pixel."""
    import numpy as np

    import sparsecast as sc
    from sparsecast.transfer import PRESETS
    from sparsecast.viewer.messages import parse_message
    from sparsecast.viewer.session import Session, ViewerData, tf_from_spec, viewer_indices

    # Fine voxels: near the polygon's corners the kept part is a thin wedge that a ray
    # crosses in a short chord, which a coarse sample spacing may step over.
    vol = sc.Volume(np.ones((72, 60, 48), np.float32), spacing=(1 / 3, 1.3 / 3, 0.3), origin=(5.0, -2.0, 1.0))
    data = ViewerData.create(vol, "viridis", index="kdtree-deep")
    s = Session(data)
    w, h = 64, 56
    opaque = {"points": [[0, 1, 1, 1, 1], [1, 1, 1, 1, 1]], "colormap": None, "value_range": [0, 2]}
    base = {"type": "render", "width": w, "height": h, "tf": opaque,
            "camera": {"azimuth": 35.0, "elevation": 25.0, "zoom": 1.0}}
    _, st = s.render_frame(s.update(parse_message(json.dumps({**base, "seq": 1}), indices=viewer_indices(),
                                                  presets=PRESETS)))
    fc, bounds = json.dumps(st["camera"]), json.dumps(data.hello()["volume"]["bounds"])
    box = [[0.0, 0.1, 0.0], [1.0, 1.0, 0.9]]
    rows = js(f"""(() => {{
        const b = {bounds}, cam = {fc};
        let a = ui.newPlane(cam, b, {box});
        a = ui.planeAtOffset(b, a, 0.15 * ui.planeHalfRange(b, a.slice(3)));
        a = ui.planeTilt(cam, b, a, 7, -4, {w}, {h});
        let c = ui.planeAtOffset(b, [0.5, 0.5, 0.5, 0, 1, 0], 3.0);
        c = [...c.slice(0, 3), ...c.slice(3).map((v) => -v)];  // flip
        return [{{plane: a, enabled: true}}, {{plane: [0.5, 0.5, 0.5, 1, 0, 0], enabled: false}},
                {{plane: c, enabled: true}}];
    }})()""")
    clip = js(f"ui.clipMessage({box}, {json.dumps(rows)}, false, 6)")
    assert len(clip["planes"]) == 2
    _, st = s.render_frame(s.update(parse_message(json.dumps({**base, "seq": 2, "clip": clip}),
                                                  indices=viewer_indices(), presets=PRESETS)))
    lo, hi = vol.bounds
    cam = sc.Camera.orbit(vol, 35.0, 25.0)
    world = [_plane_world([lo, hi], p) for p in clip["planes"]]
    ref = sc.render(vol, tf_from_spec(s.tf), cam, w, h, background="black",
                    clip_box=(lo + np.array(box[0]) * (hi - lo), lo + np.array(box[1]) * (hi - lo)),
                    clip_planes=[(p, tuple(n)) for p, n in world])
    np.testing.assert_allclose(s.last_rgba, ref.rgba, atol=1e-5)

    # One plane over the whole box: the footprint is the projection of the kept part.
    plane = clip["planes"][0]
    _, st = s.render_frame(s.update(parse_message(json.dumps({**base, "seq": 3, "clip": {"planes": [plane]}}),
                                                  indices=viewer_indices(), presets=PRESETS)))
    rows_, cols = np.nonzero(s.last_rgba[..., :3].max(axis=-1) > 1e-3)
    assert len(rows_) > 100
    p, n = _plane_world([lo, hi], plane)
    corners = np.array([[(lo, hi)[k >> j & 1][j] for j in range(3)] for k in range(8)])
    kept = corners[(corners - p) @ n > 0].tolist()
    pts = np.array(js(f"(() => {{ const b = {bounds}, pl = {plane};"
                      f"const poly = ui.planeBoxPolygon(b[0], b[1], ui.fracToWorld(b, pl.slice(0, 3)), pl.slice(3));"
                      f"return poly.concat({json.dumps(kept)}).map((q) => ui.projectPoint({fc}, q, {w}, {h})); }})()"))
    got = [cols.min(), cols.max() + 1, rows_.min(), rows_.max() + 1]
    want = [pts[:, 0].min(), pts[:, 0].max(), pts[:, 1].min(), pts[:, 1].max()]
    np.testing.assert_allclose(got, want, atol=1.0)
    full = [_python_pixel(cam, q, w, h) for q in corners]
    assert min(q[0] for q in full) < want[0] - 2 or max(q[0] for q in full) > want[1] + 2 or \
        min(q[1] for q in full) < want[2] - 2 or max(q[1] for q in full) > want[3] + 2  # the plane cut the outline


# --- keyboard ------------------------------------------------------------------------------

@pytest.mark.parametrize("key, dx, dy", [("ArrowRight", 1, 0), ("ArrowLeft", -1, 0), ("ArrowDown", 0, 1),
                                         ("ArrowUp", 0, -1)])
def test_arrow_keys_orbit_like_a_drag_of_their_direction(key, dx, dy):
    cam = {"azimuth": 30.0, "elevation": 10.0, "zoom": 1.5}
    got = js(f"[ui.keyAction({json.dumps(key)}, false, {json.dumps(cam)}), "
             f"ui.keyAction({json.dumps(key)}, true, {json.dumps(cam)}), ui.KEY_ORBIT_DEG]")
    coarse, fine, deg = got[0]["camera"], got[1]["camera"], got[2]
    for step, moved in ((deg, coarse), (1.0, fine)):  # shift: one degree
        assert moved["azimuth"] == pytest.approx(30.0 + dx * step)
        assert moved["elevation"] == pytest.approx(10.0 + dy * step)
        assert moved["zoom"] == 1.5
    # the same sense as dragging the pointer that way (which moves the surface with it)
    drag = js(f"ui.orbitDrag(30, 10, {dx * 10}, {dy * 10})")
    assert (drag["azimuth"] - 30.0) * dx >= 0 and (drag["elevation"] - 10.0) * dy >= 0
    # elevation stops short of the poles, azimuth wraps
    top = js('ui.keyAction("ArrowDown", false, {"azimuth": 358, "elevation": 88, "zoom": 1})')["camera"]
    assert top["elevation"] < 90
    assert js('ui.keyAction("ArrowRight", false, {"azimuth": 358, "elevation": 0, "zoom": 1})')["camera"][
        "azimuth"] == pytest.approx((358 + js("ui.KEY_ORBIT_DEG")) % 360)


def test_zoom_plane_and_other_keys():
    cam = {"azimuth": 0, "elevation": 0, "zoom": 2.0}
    f = js("ui.KEY_ZOOM")
    zin, zout, eq = (js(f"ui.keyAction({json.dumps(k)}, false, {json.dumps(cam)})")["camera"]["zoom"]
                     for k in ("+", "-", "="))
    assert zin == pytest.approx(2.0 * f) and zout == pytest.approx(2.0 / f) and eq == zin
    assert js('ui.keyAction("+", false, {"azimuth": 0, "elevation": 0, "zoom": 49})')["camera"]["zoom"] == 50
    assert js(f'ui.keyAction("]", false, {json.dumps(cam)})') == {"plane": 1}
    assert js(f'ui.keyAction("[", true, {json.dumps(cam)})') == {"plane": -0.25}
    assert js(f'ui.keyAction("f", false, {json.dumps(cam)})') == {"flip": True}
    for key in ("a", "Enter", " ", "Escape"):
        assert js(f"ui.keyAction({json.dumps(key)}, false, {json.dumps(cam)})") is None


def test_plane_keys_move_it_along_its_normal_within_the_box():
    import numpy as np

    lo, hi = (np.array(b) for b in BOUNDS)
    frac = js("ui.KEY_PLANE_FRACTION")
    for plane in _random_planes(4, 11):
        h = js(f"ui.planeHalfRange({json.dumps(BOUNDS)}, {plane[3:]})")
        s0 = js(f"ui.planeOffset({json.dumps(BOUNDS)}, {plane})")
        for steps in (1, -1, 3, -0.25):
            got = js(f"ui.planeNudge({json.dumps(BOUNDS)}, {plane}, {steps})")
            s1 = js(f"ui.planeOffset({json.dumps(BOUNDS)}, {json.dumps(got)})")
            assert s1 == pytest.approx(np.clip(s0 + steps * frac * h, -h, h), abs=1e-9)
            np.testing.assert_allclose(got[3:], np.asarray(plane[3:]) / np.linalg.norm(plane[3:]), atol=1e-12)
            assert all(0 <= c <= 1 for c in got[:3])
        # held down, it stops at the far corner of the box
        far = js(f"ui.planeNudge({json.dumps(BOUNDS)}, {plane}, 1e6)")
        assert js(f"ui.planeOffset({json.dumps(BOUNDS)}, {json.dumps(far)})") == pytest.approx(h)
