"""The viewer session's render features: clip, isosurfaces, label tables, time steps.

Every frame must equal ``sc.render`` with the same parameters (the session only maps
the client's fractions and ids onto them), and the index cache must rebuild only
when emptiness changes.
"""

from __future__ import annotations

import numpy as np
import pytest

import sparsecast as sc
from sparsecast.viewer.messages import CameraSpec, ClipSpec, IndexSpec, LabelSpec, RenderRequest
from sparsecast.viewer.session import Session, ViewerData, tf_from_spec

ATOL = 1e-5
W, H = 48, 40


@pytest.fixture(scope="module")
def blobs():
    return sc.datasets.nbody_blobs(40, n_clusters=3, blobs_per_cluster=12, seed=3)


@pytest.fixture(scope="module")
def segmentation():
    """Ids 0 (background), 1, 2, 5 in three boxes."""
    seg = np.zeros((24, 28, 32), np.uint8)
    seg[4:12, 4:14, 4:16] = 1
    seg[10:20, 12:24, 10:22] = 2
    seg[14:22, 2:10, 20:30] = 5
    return sc.Volume(seg, spacing=(1.0, 1.2, 0.8), name="seg")


def camera(vol, s: Session) -> sc.Camera:
    c = s.camera
    return sc.Camera.orbit(vol, c.azimuth, c.elevation, zoom=c.zoom, pan=c.pan)


def frame(s: Session, **kw):
    _, st = s.render_frame(s.update(RenderRequest(width=W, height=H, **kw)))
    return st, s.last_rgba


def test_clip_box_and_planes_equal_render_and_never_rebuild(blobs):
    data = ViewerData.create(blobs, "viridis", index="grid-pc")
    s = Session(data)
    st0, full = frame(s)
    clip = ClipSpec(((0.1, 0.0, 0.25), (0.8, 0.6, 1.0)), ((0.5, 0.5, 0.5, 1.0, 1.0, 0.0),))
    st, img = frame(s, clip=clip)
    assert st0["rebuilt"] and not st["rebuilt"]
    lo, hi = blobs.bounds
    ext = hi - lo
    box = (lo + np.array(clip.box[0]) * ext, lo + np.array(clip.box[1]) * ext)
    ref = sc.render(blobs, tf_from_spec(data.tf), camera(blobs, s), W, H, background="black",
                    clip_box=box, clip_planes=[(lo + 0.5 * ext, (1.0, 1.0, 0.0))])
    np.testing.assert_allclose(img, ref.rgba, atol=ATOL)
    assert np.abs(img - full).max() > 0.05 and st["samples"] < st0["samples"]
    # Back to the whole box: the first frame again, still no rebuild.
    st, img = frame(s, clip=ClipSpec())
    assert not st["rebuilt"]
    np.testing.assert_allclose(img, full, atol=ATOL)


@pytest.mark.parametrize("index", ["grid-pc", "kdtree-deep"])
def test_clip_planes_in_the_pages_message_equal_render(blobs, index):
    """A render message as the page sends it (clip planes as [px, py, pz, nx, ny, nz] rows:
    points in box fractions, normals in world axes of any length) gives the frame
    ``sc.render`` draws with those planes in world units; kdtree-deep also drops the tiles'
    leaves behind the planes, which must not change the picture."""
    import json

    from sparsecast.transfer import PRESETS
    from sparsecast.viewer.messages import parse_message
    from sparsecast.viewer.session import viewer_indices

    planes = [[0.5, 0.4, 0.6, 0.3, -1.0, 0.2], [0.6, 0.5, 0.5, -2.0, 0.6, 0.0]]
    msg = {"type": "render", "seq": 3, "width": W, "height": H, "index": {"name": index, "cell": None},
           "camera": {"azimuth": 40.0, "elevation": 25.0, "zoom": 1.1},
           "clip": {"box": [[0.05, 0.0, 0.1], [1.0, 0.9, 1.0]], "planes": planes, "cap": False}}
    req = parse_message(json.dumps(msg), indices=viewer_indices(), presets=PRESETS)
    data = ViewerData.create(blobs, "viridis", index=index)
    s = Session(data)
    _, st = s.render_frame(s.update(req))
    lo, hi = blobs.bounds
    ext = hi - lo
    box = (lo + np.array(msg["clip"]["box"][0]) * ext, lo + np.array(msg["clip"]["box"][1]) * ext)
    world = [(lo + np.array(p[:3]) * ext, tuple(p[3:])) for p in planes]
    ref = sc.render(blobs, tf_from_spec(data.tf), camera(blobs, s), W, H, background="black", index=index,
                    clip_box=box, clip_planes=world)
    np.testing.assert_allclose(s.last_rgba, ref.rgba, atol=ATOL)
    unclipped = sc.render(blobs, tf_from_spec(data.tf), camera(blobs, s), W, H, background="black", index=index,
                          clip_box=box)
    assert np.abs(ref.rgba - unclipped.rgba).max() > 0.05  # the planes cut something visible
    # Each plane on its own cuts differently: neither is a no-op in the pair.
    for p in world:
        one = sc.render(blobs, tf_from_spec(data.tf), camera(blobs, s), W, H, background="black", index=index,
                        clip_box=box, clip_planes=[p])
        assert np.abs(one.rgba - ref.rgba).max() > 0.05


@pytest.mark.parametrize("mode", ["iso", "iso+dvr"])
def test_isosurfaces_equal_render_and_rebuild_only_for_a_new_isovalue(blobs, mode):
    data = ViewerData.create(blobs, "viridis", index="grid-pc")
    s = Session(data)
    lo, hi = data.histogram_range
    v = lo + 0.3 * (hi - lo)
    st, img = frame(s, mode=mode, iso=(v,))
    ref = sc.render(blobs, tf_from_spec(data.tf), camera(blobs, s), W, H, background="black", mode=mode, iso=v)
    np.testing.assert_allclose(img, ref.rgba, atol=ATOL)
    assert st["mode"] == mode and img[..., 3].max() > 0.5
    st, _ = frame(s, camera=type(s.camera)(80.0, 10.0, 1.2))
    assert not st["rebuilt"]  # camera moves reuse the iso index
    recoloured = type(data.tf)(data.tf.points, "magma", data.tf.value_range)
    st, img2 = frame(s, tf=recoloured)
    # iso: colours come from the TF, emptiness from the isovalue alone; iso+dvr: the TF's opacity counts.
    assert st["rebuilt"] == (mode == "iso+dvr")
    ref = sc.render(blobs, tf_from_spec(recoloured), camera(blobs, s), W, H, background="black", mode=mode, iso=v)
    np.testing.assert_allclose(img2, ref.rgba, atol=ATOL)
    st, _ = frame(s, iso=(lo + 0.6 * (hi - lo),))
    assert st["rebuilt"]
    st, img3 = frame(s, iso=(v,))
    assert not st["rebuilt"]  # the first isovalue's index is still cached
    np.testing.assert_allclose(img3, img2, atol=ATOL)


def test_label_volume_hello_lists_ids_colours_and_counts(segmentation):
    tf = sc.TransferFunction.labels({1: (1, 0, 0, 1), 2: (0, 1, 0, 0.5)})
    data = ViewerData.create(segmentation, tf)
    h = data.hello()
    ids, counts = np.unique(segmentation.data, return_counts=True)
    assert h["labels"]["ids"] == ids.tolist() and h["labels"]["counts"] == counts.tolist()
    assert h["labels"]["visible"] == [1, 2]
    colours = dict(zip(h["labels"]["ids"], h["labels"]["colors"]))
    assert colours[1] == [1.0, 0.0, 0.0, 1.0] and colours[2] == [0.0, 1.0, 0.0, 0.5]
    assert all(len(colours[i]) == 4 and colours[i][3] > 0 for i in (0, 5))  # ready to show when ticked
    assert h["modes"] == ["dvr"] and h["state"]["tf"] is None
    # Generated colours: an id the TF leaves out is told apart from the ones it shows.
    gen = ViewerData.create(segmentation, sc.TransferFunction.labels([1, 2, 5])).labels
    assert gen.colors[0] not in [gen.colors[i] for i in (1, 2, 5)] and gen.visible == (1, 2, 5)
    assert ViewerData.create(sc.Volume(segmentation.data.astype(np.float32)), "viridis").hello()["labels"] is None


def test_hiding_and_recolouring_labels_equal_render(segmentation):
    tf = sc.TransferFunction.labels([1, 2, 5])
    data = ViewerData.create(segmentation, tf, index="kdtree-deep")
    s = Session(data)
    st0, shown = frame(s)
    ref = sc.render(segmentation, tf, camera(segmentation, s), W, H, background="black")
    np.testing.assert_allclose(shown, ref.rgba, atol=ATOL)
    st, img = frame(s, labels=LabelSpec(visible=(1, 5)))
    assert st["rebuilt"]  # a visibility change is a TF change
    ref = sc.render(segmentation, tf.hidden([2]), camera(segmentation, s), W, H, background="black")
    np.testing.assert_allclose(img, ref.rgba, atol=ATOL)
    # The image changed, and the rebuilt index skips: fewer samples than naive takes
    # for the new TF (hiding an occluder may let rays go deeper, so not fewer than before).
    naive = sc.render(segmentation, tf.hidden([2]), camera(segmentation, s), W, H, index="naive")
    assert np.abs(img - shown).max() > 0.05 and st["samples"] < naive.stats["samples"]
    st, img = frame(s, labels=LabelSpec(visible=(0, 1, 5), colors=((5, 0.2, 0.3, 1.0, 0.7),)))
    ref = sc.render(segmentation, tf.hidden([2]).with_labels({5: (0.2, 0.3, 1.0, 0.7), 0: data.labels.colors[0]}),
                    camera(segmentation, s), W, H, background="black")
    np.testing.assert_allclose(img, ref.rgba, atol=ATOL)
    st, img = frame(s, labels=LabelSpec(visible=()))
    assert img[..., :3].max() == 0.0 and st["samples"] == 0  # black background, every brick skipped


def test_label_tf_on_a_non_label_volume_is_one_clear_error(blobs):
    from sparsecast.errors import ParameterError

    with pytest.raises(ParameterError, match="label volume"):
        ViewerData.create(blobs, sc.TransferFunction.labels([1]))


def test_time_steps_equal_render_over_the_series_range():
    rng = np.random.default_rng(0)
    steps = np.zeros((4, 20, 24, 28), np.float32)
    for t in range(4):  # a blob moving along x, brighter each step
        z, y, x = np.mgrid[:20, :24, :28]
        steps[t] = (1 + t) * np.exp(-((x - 6 - 5 * t) ** 2 + (y - 12) ** 2 + (z - 10) ** 2) / 18.0)
    steps += rng.random(steps.shape, np.float32) * 0.01
    series = sc.VolumeSeries.from_array(steps, name="moving")
    data = ViewerData.create(series, "viridis", time=1)
    assert data.tf.value_range == series.value_range and data.histogram_range == series.value_range
    h = data.hello()
    assert h["series"] == {"steps": 4, "names": list(series.names)} and h["state"]["time"] == 1
    s = Session(data)
    tf = tf_from_spec(data.tf)
    st, img1 = frame(s)
    assert st["time"] == 1
    np.testing.assert_allclose(img1, sc.render(series[1], tf, camera(series[1], s), W, H,
                                               background="black").rgba, atol=ATOL)
    st, img3 = frame(s, time=3, index=IndexSpec("grid-pc"))
    assert st["rebuilt"] and st["time"] == 3
    np.testing.assert_allclose(img3, sc.render(series[3], tf, camera(series[3], s), W, H,
                                               background="black").rgba, atol=ATOL)
    assert np.abs(img3 - img1).max() > 0.05
    st, _ = frame(s, time=1)
    st, _ = frame(s, time=3)
    assert not st["rebuilt"]  # each step's index stays cached


def test_naive_probe_renders_the_same_scene(blobs):
    data = ViewerData.create(blobs, "viridis", index="grid-pc")
    s = Session(data)
    snap = s.update(RenderRequest(width=W, height=H, mode="iso", iso=(0.5,),
                                  clip=ClipSpec(((0, 0, 0), (0.5, 1, 1)))))
    s.render_frame(snap)
    assert s.needs_probe(snap)
    assert s.probe_naive(snap, 1.0)["naive_ms"] > 0
    assert not s.needs_probe(snap)
    assert s.needs_probe(s.update(RenderRequest(width=W, height=H, clip=ClipSpec())))  # another view


def test_the_viewer_opens_a_lazy_volume(blobs, tmp_path):
    """A volume read lazily from a Zarr store under a memory budget: the session's
    histogram and frames come without a dense array, and equal the dense volume's."""
    store = sc.io.convert_volume(blobs, tmp_path / "blobs.zarr", chunks=16).path
    lazy = sc.load_volume(store, lazy=True, memory_limit="4MB")
    assert isinstance(lazy, sc.BrickedVolume)
    dense_s = Session(ViewerData.create(blobs, "viridis", index="kdtree-deep"))
    lazy_s = Session(ViewerData.create(lazy, "viridis", index="kdtree-deep"))
    assert lazy_s.data.histogram.sum() == blobs.data.size
    for kw in ({}, {"clip": ClipSpec(((0.2, 0.0, 0.0), (0.7, 1.0, 1.0)), ())}):
        _, want = frame(dense_s, **kw)
        _, got = frame(lazy_s, **kw)
        np.testing.assert_allclose(got, want, atol=ATOL)
    assert 0 < lazy.resident_bricks <= lazy.stored_bricks  # the frames paged bricks in


def test_cap_the_cut_equals_render_with_clip_cap_and_only_with_a_cut(blobs):
    data = ViewerData.create(blobs, "viridis", index="kdtree-deep")
    s = Session(data)
    # cut through the brightest voxel, so that the cut face shows something to cap
    k, j, i = np.unravel_index(np.argmax(blobs.data), blobs.shape)
    clip = ClipSpec(((i / (blobs.shape[2] - 1), 0.0, 0.0), (1.0, 1.0, 1.0)))
    _, plain = frame(s, clip=clip)
    st, capped = frame(s, clip=ClipSpec(clip.box, (), cap=True))
    assert not st["rebuilt"]  # capping changes no emptiness
    lo, hi = blobs.bounds
    box = (lo + np.array(clip.box[0]) * (hi - lo), hi)
    ref = sc.render(blobs, tf_from_spec(data.tf), camera(blobs, s), W, H, background="black", clip_box=box,
                    clip_cap=True)
    np.testing.assert_allclose(capped, ref.rgba, atol=ATOL)
    assert np.abs(capped - plain).max() > 0.01
    # cap on, nothing cut: the unclipped frame
    _, whole = frame(s, clip=ClipSpec(cap=True))
    np.testing.assert_allclose(whole, sc.render(blobs, tf_from_spec(data.tf), camera(blobs, s), W, H,
                                                background="black").rgba, atol=ATOL)


def test_smooth_label_boundaries_toggle_equals_render_of_the_smoothed_tf(segmentation):
    tf = sc.TransferFunction.labels([1, 2, 5])
    data = ViewerData.create(segmentation, tf, index="kdtree-deep")
    assert data.hello()["labels"]["smooth"] is False
    s = Session(data)
    _, nearest = frame(s)
    _, smooth = frame(s, labels=LabelSpec(smooth=True))
    ref = sc.render(segmentation, tf.smoothed(), camera(segmentation, s), W, H, background="black")
    np.testing.assert_allclose(smooth, ref.rgba, atol=ATOL)
    assert np.abs(smooth - nearest).max() > 0.01
    _, again = frame(s, labels=LabelSpec(visible=(1, 2, 5)))  # other label edits keep it smooth
    np.testing.assert_allclose(again, smooth, atol=ATOL)
    _, back = frame(s, labels=LabelSpec(smooth=False))
    np.testing.assert_allclose(back, nearest, atol=ATOL)


def test_hello_sends_the_world_box_and_frames_the_camera_they_were_rendered_with(segmentation):
    """The page's clip-box overlay needs the box the clip fractions refer to and the exact
    camera of each frame (full and preview sizes differ, and with them the aspect)."""
    data = ViewerData.create(segmentation, sc.TransferFunction.labels([1, 2]))
    h = data.hello()
    lo, hi = segmentation.bounds
    assert h["volume"]["bounds"] == [lo.tolist(), hi.tolist()]
    s = Session(data)
    cam = CameraSpec(70.0, -25.0, 1.4, (0.2, 0.1))
    for preview, w, hh in ((False, 96, 40), (True, 1024, 600)):
        snap = s.update(RenderRequest(width=w, height=hh, preview=preview, camera=cam))
        _, st = s.render_frame(snap)
        p = camera(segmentation, s).ray_params(st["width"], st["height"])
        fc = st["camera"]
        assert fc["perspective"] is True and (st["width"], st["height"]) == (snap.width, snap.height)
        np.testing.assert_allclose([*fc["eye"], *fc["forward"], *fc["right"], *fc["up"]], p[:12], rtol=1e-12)
        # right / up are the half extents of the image plane: their ratio is the frame's aspect
        assert np.linalg.norm(fc["right"]) / np.linalg.norm(fc["up"]) == pytest.approx(st["width"] / st["height"])
