"""Rendering on a Dask cluster (a LocalCluster of worker processes) equals one process.

The oracle is the single-process render of the same volume, TF, camera and lattice:
``<= 1e-5`` per channel with early termination off, and with it on when pieces pass
their opacity on (``cross_termination=True``).
"""

from __future__ import annotations

import os
import pickle
import threading
import time

import numpy as np
import pytest

import sparsecast as sc
from sparsecast.distributed import ClusterVolume, connect

distributed = pytest.importorskip("distributed")

from synthetic import label_volume, sparse_volume  # noqa: E402

TOL = 1e-5


@pytest.fixture(scope="module")
def client():
    cluster = distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                       dashboard_address=None, silence_logs=40)
    c = distributed.Client(cluster)
    yield c
    c.close()
    cluster.close()


@pytest.fixture(scope="module")
def blobs():
    # x is the longest axis: the first cut is a plane x = 8k, which axis-parallel rays
    # with integer eyes and dt = 0.5 sample exactly
    return sparse_volume(np.random.default_rng(5), (20, 18, 40), 14, spacing=(1.0, 1.0, 1.0))


def _same(vol, tf, cam, client, w=40, h=32, **kw):
    ref = sc.render(vol, tf, cam, w, h, **{k: v for k, v in kw.items() if k not in ("pieces", "cross_termination")})
    img = sc.render(vol, tf, cam, w, h, client=client, **kw)
    diff = float(np.abs(img.rgba - ref.rgba).max())
    assert diff <= TOL, diff
    return ref, img


def test_every_piece_count_and_view_equals_one_process(client, blobs):
    tf = sc.TransferFunction.preset("viridis", blobs.value_range, threshold=0.1)
    lo, hi = (np.asarray(b) for b in blobs.bounds)
    c = (lo + hi) / 2
    cams = [sc.Camera.orbit(blobs, 30, 20), sc.Camera.orbit(blobs, -120, -35, projection="orthographic"),
            sc.Camera.look_at(lo + (hi - lo) * 0.3, c + (9.0, 2.0, 1.0), fov_y=90.0)]  # inside the volume
    for pieces in (2, 3, 4):
        for cam in cams:
            ref, img = _same(blobs, tf, cam, client, ert=1.0, pieces=pieces, index="kdtree-deep")
            assert img.stats["pieces"] >= 2 and img.stats["workers"] == 2
            # the lattice is shared: no sample taken twice, none missed (naive counts all)
    for cam in cams[:1]:
        ref, img = _same(blobs, tf, cam, client, ert=1.0, pieces=3, index="naive")
        assert img.stats["samples"] == ref.stats["samples"]


def test_samples_exactly_on_the_cut_faces_are_taken_once(client, blobs):
    tf = sc.TransferFunction.preset("viridis", blobs.value_range, threshold=0.05)
    cv = ClusterVolume(blobs, client, pieces=2)
    try:
        cuts = {int(b[0][0]) for b in cv.tree.boxes} - {0}
        assert cuts  # a cut plane x = 8 * brick, through the blobs
        cy, cz = 8.0, 9.0
        for eye_x, target_x in ((-10.0, 50.0), (50.0, -10.0)):  # both directions across the cut
            cam = sc.Camera.look_at((eye_x, cy, cz), (target_x, cy, cz), (0.0, 0.0, 1.0),
                                    projection="orthographic", ortho_height=16.0)
            ref = sc.render(blobs, tf, cam, 24, 24, ert=1.0, dt=0.5, index="naive")
            img = cv.render(tf, cam, 24, 24, ert=1.0, dt=0.5, index="naive")
            assert np.array_equal(img.samples, ref.samples)
            assert np.abs(img.rgba - ref.rgba).max() <= TOL
    finally:
        cv.close()


def test_shading_gradients_at_the_cuts_read_the_ghost_voxels(client, blobs):
    tf = sc.TransferFunction.preset("viridis", blobs.value_range, threshold=0.1)
    _same(blobs, tf, sc.Camera.orbit(blobs, 60, 10), client, ert=1.0, shading=True, pieces=4, index="grid-mm")


def test_cross_piece_termination_equals_one_process_with_termination(client, blobs):
    # nearly opaque wherever there is anything: rays terminate in the front pieces
    tf = sc.TransferFunction([(0.0, 0, 0, 0, 0), (0.05, 1, 0.5, 0, 1.0), (1.0, 1, 1, 1, 1.0)])
    cam = sc.Camera.orbit(blobs, 10, 5)
    ref, img = _same(blobs, tf, cam, client, ert=0.9, pieces=4, cross_termination=True, index="lbvh")
    assert img.stats["samples"] == ref.stats["samples"]
    # without it, pieces behind an opaque front keep marching: more samples, near the same image
    loose = sc.render(blobs, tf, cam, 40, 32, ert=0.9, pieces=4, client=client, index="lbvh")
    assert loose.stats["samples"] > ref.stats["samples"]
    assert np.abs(loose.rgba - ref.rgba).max() <= 1 - 0.9 + 1e-6


def test_a_tf_change_sends_the_tf_and_rebuilds_on_the_pieces(client, blobs):
    cam = sc.Camera.orbit(blobs, 200, 30)
    cv = ClusterVolume(blobs, client, pieces=2)
    try:
        futures = list(cv.futures)
        for threshold in (0.1, 0.5, 0.1):
            tf = sc.TransferFunction.preset("magma", blobs.value_range, threshold=threshold)
            ref = sc.render(blobs, tf, cam, 32, 32, ert=1.0)
            img = cv.render(tf, cam, 32, 32, ert=1.0)
            assert np.abs(img.rgba - ref.rgba).max() <= TOL
            again = cv.render(tf, cam, 32, 32, ert=1.0)  # same TF: indices kept
            assert again.stats["build_ms"] == 0.0
        assert cv.futures == futures  # the pieces were loaded once
        # the layers (20 bytes a pixel, at most the two pieces' and their composite) and
        # the frame's parameters (the TF) per piece: never voxels
        layers = 32 * 32 * 20
        assert layers <= img.stats["bytes_moved"] <= 3 * layers + 2 * len(pickle.dumps((tf, cam))) + 4096
    finally:
        cv.close()


def test_labels_clip_boxes_planes_rect_and_initial(client):
    rng = np.random.default_rng(11)
    vol = label_volume(rng, (24, 20, 36), 5, brick_aligned=True)
    tf = sc.TransferFunction.labels({1: (1, 0, 0, 0.6), 2: (0, 1, 0, 0.3), 4: (0, 0, 1, 0.8), 5: (1, 1, 0, 0.5)})
    cam = sc.Camera.orbit(vol, 40, 25)
    _same(vol, tf, cam, client, ert=1.0, pieces=3)
    _same(vol, tf, cam, client, ert=1.0, pieces=3, clip_box=((3.0, 2.5, 1.0), (16.0, 30.0, 20.0)),
          clip_open=((False, True, False), (True, False, False)))
    _same(vol, tf, cam, client, ert=1.0, pieces=3, clip_planes=[((18.0, 10.0, 12.0), (1.0, 0.3, -0.2))])
    init = np.zeros((10, 12, 4), np.float32)
    init[..., 2] = init[..., 3] = 0.25
    _same(vol, tf, cam, client, ert=1.0, pieces=3, rect=(20, 5, 12, 10), initial=init, background="white")
    _same(vol, tf, cam, client, ert=0.95, pieces=3, rect=(20, 5, 12, 10), initial=init, cross_termination=True)


def test_lazy_sources_are_read_by_the_workers_themselves(client, tmp_path, blobs):
    path = tmp_path / "blobs.npy"
    np.save(path, blobs.data)
    vol = sc.load_volume(path, lazy=True)
    assert vol.source_recipe is not None
    tf = sc.TransferFunction.preset("viridis", blobs.value_range, threshold=0.1)
    cv = ClusterVolume(vol, client, pieces=2)
    try:
        # no voxels in the graph: each worker opened the file and read its own bricks
        specs = client.gather([client.submit(lambda p: (p.spec.window is None, p.bytes_read), f) for f in cv.futures])
        assert all(no_window for no_window, _ in specs)
        assert sum(b for _, b in specs) < 1.5 * blobs.data.nbytes
        cam = sc.Camera.orbit(vol, 30, 20)
        ref = sc.render(blobs, tf, cam, 32, 32, ert=1.0)
        assert np.abs(cv.render(tf, cam, 32, 32, ert=1.0).rgba - ref.rgba).max() <= TOL
    finally:
        cv.close()


def test_a_worker_killed_mid_frame_and_the_frame_still_completes(client, blobs):
    tf = sc.TransferFunction.preset("viridis", blobs.value_range)
    cam = sc.Camera.orbit(blobs, 30, 20)
    cv = ClusterVolume(blobs, client, pieces=2)
    killed = []
    try:
        cv.render(tf, cam, 16, 16, ert=1.0, index="naive")  # pieces loaded, kernels warm
        before = set(client.nthreads())

        def kill_when_busy():
            deadline = time.time() + 60
            while time.time() < deadline:
                busy = [w for w, keys in client.processing().items() if any("render_piece" in str(k) for k in keys)]
                if busy:
                    try:
                        client.run(os._exit, 1, workers=busy[:1])
                    except Exception:  # the worker dies under the call
                        pass
                    killed.append(busy[0])
                    return
                time.sleep(0.002)

        t = threading.Thread(target=kill_when_busy)
        t.start()
        # a slow frame (every sample, many pixels) so the kill lands while pieces render
        img = cv.render(tf, cam, 320, 320, ert=1.0, index="naive", timeout=240)
        t.join()
        assert killed and killed[0] in before
        ref = sc.render(blobs, tf, cam, 320, 320, ert=1.0, index="naive")
        assert np.abs(img.rgba - ref.rgba).max() <= TOL
        client.wait_for_workers(2, timeout=60)
        nxt = cv.render(tf, cam, 32, 32, ert=1.0)  # and the client goes on
        assert np.abs(nxt.rgba - sc.render(blobs, tf, cam, 32, 32, ert=1.0).rgba).max() <= TOL
    finally:
        cv.close()


def test_a_frame_past_its_timeout_is_an_error_and_the_next_frame_works(client, blobs):
    tf = sc.TransferFunction.preset("viridis", blobs.value_range)
    cam = sc.Camera.orbit(blobs, 30, 20)
    cv = ClusterVolume(blobs, client, pieces=2)
    try:
        with pytest.raises(sc.DistributedError, match="timeout"):
            cv.render(tf, cam, 400, 400, ert=1.0, index="naive", timeout=0.001)
        ref = sc.render(blobs, tf, cam, 24, 24)
        assert np.abs(cv.render(tf, cam, 24, 24).rgba - ref.rgba).max() <= 1 - 0.99 + 1e-6
    finally:
        cv.close()


def test_an_unreachable_scheduler_is_one_clear_error():
    with pytest.raises(sc.DistributedError, match=r"cannot reach the Dask scheduler at 'tcp://127.0.0.1:9'"):
        connect("tcp://127.0.0.1:9", timeout=1.0)


def test_what_a_cluster_cannot_render_is_refused_before_any_work(client, blobs):
    tf = sc.TransferFunction.preset("viridis", blobs.value_range)
    cam = sc.Camera.orbit(blobs, 30, 20)
    with pytest.raises(sc.ParameterError, match="mode"):
        sc.render(blobs, tf, cam, 8, 8, client=client, mode="iso", iso=0.5)
    with pytest.raises(sc.ParameterError, match="clip_cap"):
        sc.render(blobs, tf, cam, 8, 8, client=client, clip_cap=True)
    with pytest.raises(sc.ParameterError, match="index name"):
        sc.render(blobs, tf, cam, 8, 8, client=client, index=sc.build_index(blobs, tf, "naive"))
    with pytest.raises(sc.ParameterError, match="client"):
        sc.render(blobs, tf, cam, 8, 8, client="tcp://somewhere:8786")
    with pytest.raises(sc.ParameterError, match="pieces: applies only with client"):
        sc.render(blobs, tf, cam, 8, 8, pieces=2)


def test_cli_render_on_a_scheduler_equals_the_local_render(client, tmp_path, monkeypatch, capsys):
    from cli_runner import run_cli

    path = tmp_path / "blobs.npy"
    vol = sparse_volume(np.random.default_rng(2), (16, 20, 24), 6)
    np.save(path, vol.data)
    args = ("render", str(path), "--size", "40x30", "--ert", "1", "--array")
    code, out, err = run_cli(monkeypatch, capsys, *args, str(tmp_path / "c.npy"), "-o", str(tmp_path / "c.png"),
                             "--scheduler", client.scheduler.address, "--pieces", "3")
    assert code == 0, err
    assert "on 3 pieces, 2 workers" in out
    code, out, err = run_cli(monkeypatch, capsys, *args, str(tmp_path / "l.npy"), "-o", str(tmp_path / "l.png"))
    assert code == 0, err
    assert np.abs(np.load(tmp_path / "c.npy") - np.load(tmp_path / "l.npy")).max() <= TOL


def test_cli_an_unreachable_scheduler_is_one_line_and_writes_nothing(tmp_path, monkeypatch, capsys):
    from cli_runner import run_cli

    code, out, err = run_cli(monkeypatch, capsys, "render", "-o", str(tmp_path / "x.png"),
                             "--scheduler", "tcp://127.0.0.1:9")
    assert code != 0
    assert "cannot reach the Dask scheduler at 'tcp://127.0.0.1:9'" in err
    assert "Traceback" not in err and not (tmp_path / "x.png").exists()
    code, _, err = run_cli(monkeypatch, capsys, "render", "-o", str(tmp_path / "x.png"), "--pieces", "2")
    assert code != 0 and "--pieces 2: applies only with --scheduler" in err


def test_the_viewer_session_renders_dvr_frames_on_the_cluster(client, blobs):
    from sparsecast.viewer.messages import RenderRequest
    from sparsecast.viewer.session import Session, ViewerData

    tf = sc.TransferFunction.preset("viridis", blobs.value_range, threshold=0.1)
    data = ViewerData.create(blobs, tf)
    local = Session(data)
    snap = local.update(RenderRequest(width=48, height=40))
    local.render_frame(snap)
    data.client, data.pieces = client, 2
    remote = Session(data)
    _, status = remote.render_frame(remote.update(RenderRequest(width=48, height=40)))
    assert status["pieces"] == 2
    # the viewer terminates rays at ert = 0.99 and its pieces run at once: each stops on
    # its own opacity, within 1 - ert of one process
    assert np.abs(remote.last_rgba - local.last_rgba).max() <= 1 - 0.99 + 1e-6


def test_pieces_kept_for_a_volume_go_when_the_volume_goes(client):
    import gc
    import weakref

    vol = sparse_volume(np.random.default_rng(8), (12, 12, 20), 3)
    tf = sc.TransferFunction.preset("viridis", vol.value_range)
    cam = sc.Camera.orbit(vol)
    first = sc.render(vol, tf, cam, 16, 16, client=client, pieces=2)
    again = sc.render(vol, tf, cam, 16, 16, client=client, pieces=2)  # the same pieces, indices kept
    assert again.stats["build_ms"] == 0.0 and first.stats["pieces"] == 2
    ref = weakref.ref(vol)
    del vol
    gc.collect()
    assert ref() is None


def test_a_bricked_volume_without_a_file_ships_its_windows_and_equals_one_process(client, blobs):
    vol = sc.BrickedVolume(blobs.data)  # eager: the pool holds everything, no source, no recipe
    tf = sc.TransferFunction.preset("viridis", blobs.value_range, threshold=0.1)
    cam = sc.Camera.orbit(vol, 120, -25)
    ref = sc.render(blobs, tf, cam, 32, 32, ert=1.0, shading=True)
    img = sc.render(vol, tf, cam, 32, 32, ert=1.0, shading=True, client=client, pieces=3)
    assert img.stats["pieces"] == 3 and np.abs(img.rgba - ref.rgba).max() <= TOL


@pytest.mark.parametrize("name", ["headsq_ct_64x64x93_uint16.nrrd", "tooth_103x94x161_uint8.nrrd"])
def test_real_ct_volumes_on_the_cluster_equal_one_process(client, shared_file, name):
    vol = sc.load_volume(shared_file(name))  # anisotropic spacing from the header
    lo, hi = vol.value_range
    tf = sc.TransferFunction.preset("bone", (lo, hi), threshold=0.25)
    for cam in (sc.Camera.orbit(vol, 35, 15), sc.Camera.orbit(vol, 0, 0, projection="orthographic")):
        _same(vol, tf, cam, client, w=48, h=40, ert=1.0, pieces=3, index="kdtree-deep", shading=True)
        _same(vol, tf, cam, client, w=48, h=40, ert=0.95, pieces=3, index="grid-pc", cross_termination=True)
