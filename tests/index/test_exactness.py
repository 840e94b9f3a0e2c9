"""The main oracle: every exact empty-space-skipping index renders the naive image.

Parametrised over :func:`sparsecast.available_indices`, so an index registered by a
later issue is checked here without new test code (``bbox_index.py`` registers a
trivial one to prove it); per-index build options to exercise are listed in
``INDEX_OPTIONS``.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import sparsecast as sc
from sparsecast.index.auto import EDITING_INDEX, SPARSE_INDEX
from synthetic import label_volume, sparse_volume
from sparsecast.index.registry import _INDICES

import bbox_index  # noqa: F401  (registers "test-bbox": a new index gets every test below)

#: build options each index is tested with (default: its defaults only)
INDEX_OPTIONS: dict[str, list[dict]] = {
    "grid-mm": [{"cell": 4}, {"cell": 8}, {"cell": 16}],
    "grid-pc": [{"cell": 4}, {"cell": 8}, {"cell": 32}],
    # issue 4 (k-d trees, hybrid grids): edit only these lines
    "kdtree-shallow": [{}],
    "kdtree-deep": [{}],
    "hybrid-pc": [{}],
    "hybrid-mm": [{}],
    # issue 5 (LBVH): edit only this line
    "lbvh": [{}, {"prune": None}, {"prune": 0.3}, {"brick": 4, "voting": "voxels"}, {"prune": 1.0, "brick": 16}],
    # issue 6 (BIH; only mode="ess" is exact): edit only this line
    "bih": [{}, {"mode": "ess", "brick": 4, "variant": "basic"}, {"layout": "chunks", "chunk_depth": 3}],
}

EXACT = [n for n in sc.available_indices() if n != "naive" and _INDICES[n].exact]
CASES = [(n, opt) for n in EXACT for opt in INDEX_OPTIONS.get(n, [{}])]
CASE_IDS = [f"{n}-{'-'.join(f'{k}{v}' for k, v in o.items()) or 'default'}" for n, o in CASES]
ATOL = 1e-5


def assert_same_as_naive(vol, tf, cam, w, h, name, opts, **kw):
    ref = sc.render(vol, tf, cam, w, h, index="naive", **kw)
    img = sc.render(vol, tf, cam, w, h, index=name, **opts, **kw)
    diff = np.abs(img.rgba - ref.rgba).max()
    assert diff <= ATOL, f"{name} {opts}: max abs diff {diff:.3g} vs naive"
    # Skipping never adds samples, and never loses one of non-zero opacity
    # (with early termination off, the non-empty count must match exactly).
    assert img.stats["samples"] <= ref.stats["samples"]
    if kw.get("ert", 0.99) >= 1.0:
        assert img.stats["samples_nonempty"] == ref.stats["samples_nonempty"]
    return img, ref


def _cameras(vol):
    c = vol.center
    L = vol.diagonal
    lo, hi = vol.bounds
    inside = lo + (hi - lo) * np.array([0.45, 0.5, 0.55])
    cams = {
        "orbit-persp": sc.Camera.orbit(vol, 30, 20),
        "orbit-ortho": sc.Camera.orbit(vol, -125, -35, projection="orthographic"),
        "axis+x-ortho": sc.Camera.look_at(c - [L, 0, 0], c, projection="orthographic", ortho_height=L),
        "axis-z-persp": sc.Camera.look_at(c + [0, 0, L], c, up=(0, 1, 0), fov_y=45),
        "axis+y-ortho": sc.Camera.look_at(c - [0, L, 0], c, projection="orthographic", ortho_height=L),
        "grazing": sc.Camera.look_at(c + [L, 0.0, 0.5 * (hi[2] - lo[2]) - 1e-9], c + [0, 0, 0.5 * (hi[2] - lo[2]) - 1e-9],
                                     projection="orthographic", ortho_height=L),
        "inside": sc.Camera.look_at(inside, inside + [0.3, 1.0, -0.2], fov_y=100),
    }
    return cams


@pytest.fixture(scope="module")
def scene():
    rng = np.random.default_rng(11)
    vol = sparse_volume(rng, (37, 29, 45), 9, spacing=(1.0, 0.8, 1.3), origin=(2.0, -1.0, 0.5))
    return vol


pytestmark = pytest.mark.skipif(not EXACT, reason="no exact ESS index registered yet")


@pytest.mark.parametrize("name, opts", CASES, ids=CASE_IDS)
@pytest.mark.parametrize("camera", ["orbit-persp", "orbit-ortho", "axis+x-ortho", "axis-z-persp",
                                    "axis+y-ortho", "grazing", "inside"])
def test_fixed_scenes_equal_naive(scene, name, opts, camera):
    vol = scene
    tf = sc.TransferFunction.preset("viridis", (0.0, 1.0), threshold=0.15)
    cam = _cameras(vol)[camera]
    assert_same_as_naive(vol, tf, cam, 40, 32, name, opts, dt=0.45, ert=1.0)
    assert_same_as_naive(vol, tf, cam, 24, 24, name, opts, dt=0.7, shading=True)


@pytest.mark.parametrize("name, opts", CASES, ids=CASE_IDS)
def test_uint8_and_tf_edits(name, opts):
    """A TF edit means a new index; each must agree with naive (uint8 volume)."""
    rng = np.random.default_rng(5)
    vol = sparse_volume(rng, (20, 33, 27), 6, dtype="uint8")
    cam = sc.Camera.orbit(vol, 60, 10)
    for threshold in (0.0, 0.05, 0.3, 0.8):
        tf = sc.TransferFunction.preset("magma", (0, 255), threshold=threshold)
        idx = sc.build_index(vol, tf, name, **opts)
        ref = sc.render(vol, tf, cam, 20, 20)
        img = sc.render(vol, tf, cam, 20, 20, index=idx)
        assert np.abs(img.rgba - ref.rgba).max() <= ATOL


@pytest.mark.parametrize("name, opts", CASES, ids=CASE_IDS)
def test_tf_without_empty_space(name, opts, scene):
    """Every value visible: nothing to skip, same image, same sample count as naive."""
    tf = sc.TransferFunction([(0, 0.2, 0.4, 0.9, 0.05), (1, 1, 1, 1, 0.3)])
    cam = sc.Camera.orbit(scene, 15, 40)
    img, ref = assert_same_as_naive(scene, tf, cam, 24, 24, name, opts, ert=1.0)
    assert img.stats["samples"] == ref.stats["samples"]


@pytest.mark.parametrize("name, opts", CASES, ids=CASE_IDS)
def test_skips_on_a_sparse_scene(name, opts):
    """Every exact index takes strictly fewer samples than naive where there is
    empty space to skip: an index that yields the whole box fails here."""
    rng = np.random.default_rng(21)
    vol = sparse_volume(rng, (48, 40, 56), 3)
    tf = sc.TransferFunction.preset("viridis", (0.0, 1.0), threshold=0.3)
    cam = sc.Camera.orbit(vol, 35, 25)
    img, ref = assert_same_as_naive(vol, tf, cam, 32, 32, name, opts, ert=1.0)
    assert img.stats["samples"] < ref.stats["samples"], f"{name} {opts} skipped nothing"


@pytest.mark.parametrize("name, opts", CASES, ids=CASE_IDS)
def test_all_empty_takes_no_samples(name, opts, scene):
    tf = sc.TransferFunction([(0, 1, 1, 1, 0), (1, 1, 1, 1, 0)])
    img = sc.render(scene, tf, sc.Camera.orbit(scene), 16, 16, index=name, background="white", **opts)
    assert img.stats["samples"] == 0
    assert np.array_equal(img.rgba, np.ones_like(img.rgba))


@st.composite
def random_scenes(draw):
    # at least 2 voxels per axis: render() refuses thinner volumes (issue 14, item 12)
    shape = tuple(draw(st.integers(2, 40)) for _ in range(3))
    seed = draw(st.integers(0, 2**32 - 1))
    rng = np.random.default_rng(seed)
    vol = sparse_volume(rng, shape, draw(st.integers(0, 6)),
                        spacing=tuple(draw(st.sampled_from([0.6, 1.0, 1.7])) for _ in range(3)),
                        origin=tuple(draw(st.sampled_from([0.0, -3.5, 7.25])) for _ in range(3)))
    n = draw(st.integers(2, 5))
    # Positions on a 0.01 grid: spans like 1e-307 between points are not a TF anyone
    # draws, and TransferFunction rejects them.
    xs = sorted(draw(st.lists(st.integers(-10, 110).map(lambda i: i / 100), min_size=n, max_size=n)))
    if xs[-1] == xs[0]:
        xs[-1] += 0.01
    pts = [(x, draw(st.floats(0, 1)), draw(st.floats(0, 1)), draw(st.floats(0, 1)),
            draw(st.sampled_from([0.0, 0.0, 0.2, 0.9, 1.0]))) for x in xs]
    tf = sc.TransferFunction(pts, table_size=draw(st.sampled_from([256, 1024])))
    proj = draw(st.sampled_from(["orthographic", "perspective"]))
    if draw(st.booleans()):
        az = draw(st.sampled_from([0.0, 90.0, 180.0, 270.0, 33.0, -71.0]))
        el = draw(st.sampled_from([0.0, 90.0, -90.0, 12.0, -47.0]))
        cam = sc.Camera.orbit(vol, az, el, projection=proj, zoom=draw(st.sampled_from([0.8, 1.0, 2.5])))
    else:  # axis-parallel look-at, possibly from inside the volume
        lo, hi = vol.bounds
        eye = lo + (hi - lo) * np.array([draw(st.floats(-0.5, 1.5)) for _ in range(3)])
        axis = draw(st.integers(0, 2))
        d = np.zeros(3)
        d[axis] = draw(st.sampled_from([-1.0, 1.0]))
        up = (0.0, 0.0, 1.0) if axis != 2 else (0.0, 1.0, 0.0)
        cam = sc.Camera.look_at(eye, eye + d, up, projection=proj, fov_y=80.0,
                                ortho_height=max(vol.diagonal, 1.0))
    kw = dict(dt=draw(st.sampled_from([0.3, 0.5, 1.0, 0.77])), ert=draw(st.sampled_from([1.0, 0.99, 0.6])))
    return vol, tf, cam, kw


@pytest.mark.parametrize("name, opts", CASES, ids=CASE_IDS)
@settings(max_examples=20, deadline=None)
@given(data=random_scenes())
def test_property_equal_naive(name, opts, data):
    vol, tf, cam, kw = data
    assert_same_as_naive(vol, tf, cam, 12, 10, name, opts, **kw)


@pytest.mark.parametrize("name, opts", CASES, ids=CASE_IDS)
@pytest.mark.parametrize("view", [(30, 20), (0, 0)])
def test_real_data_equal_naive(shared_file, name, opts, view):
    path = shared_file("mni152_t1_197x233x189_uint8.nrrd")
    vol = _load_cached(path)
    tf = sc.TransferFunction.preset("bone", vol.value_range)
    cam = sc.Camera.orbit(vol, *view, projection="orthographic")
    img, ref = assert_same_as_naive(vol, tf, cam, 64, 64, name, opts, dt=1.0)
    assert img.stats["samples"] < ref.stats["samples"]  # the brain has empty space around it


# The indices index="auto" picks, on the 12-bit CT stored in uint16 (anisotropic
# spacing) and on the same CT in Hounsfield units as int16 (air at -1024): brick ranges,
# classification and skipping of integer data other than uint8, and of negative values.
# (Every index on every dtype would compile each index's driver per dtype; the traversal
# is dtype-free and tested on float32 and uint8 above.)
@pytest.mark.parametrize("name", [SPARSE_INDEX, EDITING_INDEX])
@pytest.mark.parametrize("dtype", ["uint16", "int16"])
def test_real_ct_in_uint16_and_int16_equal_naive(shared_file, name, dtype):
    vol = _load_cached(shared_file("headsq_ct_64x64x93_uint16.nrrd"))
    assert vol.dtype == np.uint16
    if dtype == "int16":
        vol = sc.Volume((vol.data.astype(np.int32) - 1024).astype(np.int16), spacing=vol.spacing, origin=vol.origin)
        assert vol.value_range[0] < 0
    lo, hi = vol.value_range
    tf = sc.TransferFunction.preset("bone", (lo, hi), threshold=0.3)
    for view in [(30, 20), (0, 0)]:
        cam = sc.Camera.orbit(vol, *view, projection="perspective")
        img, ref = assert_same_as_naive(vol, tf, cam, 48, 48, name, {}, dt=0.8, ert=1.0)
        assert img.stats["samples"] < ref.stats["samples"]  # air skipped (the grid's 8^3 cells less finely)
        assert ref.rgba[..., 3].max() > 0.5


@pytest.mark.parametrize("name, opts", CASES, ids=CASE_IDS)
def test_real_data_clipped_equal_naive(shared_file, name, opts):
    """A clip box and a clip plane through real data (faces between voxels, an oblique
    plane): what the deep k-d tree culls from its tile lists, and every other index's
    clipped intervals, still take naive's samples."""
    path = shared_file("mni152_t1_197x233x189_uint8.nrrd")
    vol = _load_cached(path)
    tf = sc.TransferFunction.preset("bone", vol.value_range)
    lo, hi = vol.bounds
    ext = hi - lo
    box = (tuple(lo + ext * [0.13, 0.2, 0.07]), tuple(lo + ext * [0.503, 0.91, 0.77]))
    plane = (tuple(lo + ext * 0.41), (0.3, -1.0, 0.45))
    for view in ((30, 20), (-140, -10)):
        cam = sc.Camera.orbit(vol, *view, projection="orthographic")
        img, ref = assert_same_as_naive(vol, tf, cam, 64, 64, name, opts, dt=1.0, clip_box=box, clip_planes=[plane])
        assert ref.stats["samples_nonempty"] > 0  # the clip leaves brain in view


_CACHE: dict = {}


def _load_cached(path):
    if path not in _CACHE:
        _CACHE[path] = sc.load_volume(path)
    return _CACHE[path]


# -- issue 15, item 1: zero opacity exactly on data values ---------------------------
_LEVELS = [0.0, 0.125, 0.25, 0.5, 1.0]


@st.composite
def constant_brick_scenes(draw):
    """Boxes of constant value (most of the volume exactly 0) and a TF whose control
    points, zero-opacity ones among them, sit exactly on those values."""
    shape = tuple(draw(st.integers(2, 30)) for _ in range(3))
    data = np.zeros(shape, np.float32)
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    for _ in range(draw(st.integers(0, 4))):
        lo = [int(rng.integers(0, n)) for n in shape]
        hi = [a + int(rng.integers(1, 12)) for a in lo]
        data[lo[0]:hi[0], lo[1]:hi[1], lo[2]:hi[2]] = draw(st.sampled_from(_LEVELS))
    vol = sc.Volume(data, spacing=(1.0, 0.9, 1.2))
    xs = sorted(draw(st.lists(st.sampled_from(_LEVELS), min_size=2, max_size=4)))
    pts = [(x, 0.9, 0.6, 0.3, draw(st.sampled_from([0.0, 0.0, 0.4, 1.0]))) for x in xs]
    pts.insert(0, (0.0, 0.9, 0.6, 0.3, 0.0))  # zero at the data minimum, like the viewer's editor
    tf = sc.TransferFunction(pts, (0.0, draw(st.sampled_from([1.0, 2.0]))),
                             table_size=draw(st.sampled_from([256, 1024])))
    cam = sc.Camera.orbit(vol, draw(st.sampled_from([0.0, 30.0, 145.0])), draw(st.sampled_from([0.0, 25.0, -60.0])),
                          projection=draw(st.sampled_from(["orthographic", "perspective"])))
    return vol, tf, cam


@pytest.mark.parametrize("name, opts", CASES, ids=CASE_IDS)
@settings(max_examples=10, deadline=None)
@given(data=constant_brick_scenes())
def test_property_constant_bricks_equal_naive(name, opts, data):
    vol, tf, cam = data
    assert_same_as_naive(vol, tf, cam, 12, 10, name, opts, dt=0.5, ert=1.0)


@pytest.mark.parametrize("name, opts", CASES, ids=CASE_IDS)
def test_ramp_from_zero_skips_the_zero_background(name, opts):
    """A TF that is 0 at the data minimum and ramps up from there: the all-zero
    background is empty space (it was classified non-empty, one entry too wide)."""
    rng = np.random.default_rng(21)
    vol = sparse_volume(rng, (48, 40, 56), 3)
    tf = sc.TransferFunction([(0.0, 1, 1, 1, 0.0), (1.0, 1, 0.5, 0.2, 0.8)], (0.0, 1.0))
    cam = sc.Camera.orbit(vol, 35, 25)
    img, ref = assert_same_as_naive(vol, tf, cam, 32, 32, name, opts, ert=1.0)
    assert img.stats["samples"] < ref.stats["samples"], f"{name} {opts} skipped nothing"


# -- issue 19, item 1: label volumes, nearest sampling ----------------------------------
@st.composite
def label_scenes(draw):
    """Label boxes with faces on or beside brick faces; a random subset of ids shown."""
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    shape = tuple(draw(st.integers(2, 34)) for _ in range(3))
    n = draw(st.integers(1, 7))
    vol = label_volume(rng, shape, n, "uint8",  # (one dtype: each compiles every index's nearest driver)
                       brick_aligned=draw(st.booleans()), spacing=(1.0, 0.8, 1.25))
    shown = draw(st.lists(st.integers(1, n), min_size=1, max_size=n, unique=True))
    tf = sc.TransferFunction.labels({i: (0.2 + 0.1 * i % 0.8, 0.5, 1.0 - 0.1 * i, draw(st.sampled_from([0.3, 1.0])))
                                     for i in shown}, smooth=draw(st.booleans()))  # nearest or smooth boundaries
    cams = _cameras(vol)
    cam = cams[draw(st.sampled_from(sorted(cams)))]
    return vol, tf, cam, draw(st.booleans())


@pytest.mark.parametrize("name, opts", CASES, ids=CASE_IDS)
@settings(max_examples=12, deadline=None)
@given(data=label_scenes())
def test_property_labels_equal_naive(name, opts, data):
    vol, tf, cam, shade = data
    assert_same_as_naive(vol, tf, cam, 12, 10, name, opts, dt=0.5, ert=1.0, shading=shade)


#: indices that classify by value range during traversal (min-max) or not at all:
#: hidden labels skip there only where the range of a cell excludes every visible id
RANGE_ONLY = {"grid-mm", "hybrid-mm", "test-bbox"}


@pytest.mark.parametrize("name, opts", CASES, ids=CASE_IDS)
@pytest.mark.parametrize("smooth", [False, True])
def test_hidden_labels_skip(name, opts, smooth):
    """Hiding the label that fills most bricks skips its bricks (and stays exact): the
    per-brick label sets see that a brick of {0, 5} has nothing visible once 5 is hidden,
    although its range [0, 5] spans the visible id 2."""
    data = np.zeros((64, 64, 64), np.uint8)
    data[4:60, 4:60, 4:30] = 5   # a big slab, hidden in the second image
    data[50:54, 50:54, 50:54] = 2  # a small visible box
    vol = sc.Volume(data)
    cam = sc.Camera.orbit(vol, 30, 20)
    shown = sc.TransferFunction.labels({2: (1, 0, 0, 1), 5: (0, 0, 1, 0.4)}, smooth=smooth)
    img_all, _ = assert_same_as_naive(vol, shown, cam, 24, 24, name, opts, ert=1.0)
    img_hidden, _ = assert_same_as_naive(vol, shown.hidden([5]), cam, 24, 24, name, opts, ert=1.0)
    if name in RANGE_ONLY:
        assert img_hidden.stats["samples"] <= img_all.stats["samples"]
    else:
        assert img_hidden.stats["samples"] < 0.5 * img_all.stats["samples"], f"{name} {opts}"


# -- issue 19, item 3: isosurfaces (and iso + DVR) --------------------------------------
@st.composite
def iso_scenes(draw):
    """Sparse blobs, 1-3 isovalues (some exactly on voxel values), any camera of _cameras."""
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    shape = tuple(draw(st.integers(2, 34)) for _ in range(3))
    vol = sparse_volume(rng, shape, draw(st.integers(0, 5)), spacing=(1.0, 0.8, 1.25))
    vox = np.unique(vol.data)
    values = [float(draw(st.sampled_from(list(vox)))) if draw(st.booleans()) else draw(st.floats(0.02, 0.98))
              for _ in range(draw(st.integers(1, 3)))]
    colors = [(0.9, 0.5, 0.2, draw(st.sampled_from([1.0, 0.4]))) for _ in values]
    tf = sc.TransferFunction.preset("viridis", (0.0, 1.0), threshold=0.5)
    cams = _cameras(vol)
    return vol, tf, cams[draw(st.sampled_from(sorted(cams)))], values, colors


@pytest.mark.parametrize("name, opts", CASES, ids=CASE_IDS)
@settings(max_examples=10, deadline=None)
@given(data=iso_scenes(), mode=st.sampled_from(["iso", "iso+dvr"]))
def test_property_iso_equal_naive(name, opts, data, mode):
    vol, tf, cam, values, colors = data
    # render(mode=...) is the iso mode here; the BIH's build mode "ess" is its default.
    opts = {k: v for k, v in opts.items() if not (k == "mode" and v == "ess")}
    ref = sc.render(vol, tf, cam, 12, 10, index="naive", mode=mode, iso=values, iso_colors=colors, dt=0.5)
    img = sc.render(vol, tf, cam, 12, 10, index=name, mode=mode, iso=values, iso_colors=colors, dt=0.5, **opts)
    diff = np.abs(img.rgba - ref.rgba).max()
    assert diff <= ATOL, f"{name} {opts} {mode}: max abs diff {diff:.3g} vs naive"


@pytest.mark.parametrize("mode", ["iso", "iso+dvr"])
def test_real_data_iso_equal_naive(shared_file, mode):
    """The shared tooth CT (anisotropic spacing) at the bench's isovalue, shaded: every
    exact index, and the bricked layout, give naive's image (the refine on each cell's
    cubic reads the same corners from either layout)."""
    vol = _load_cached(shared_file("tooth_103x94x161_uint8.nrrd"))
    lo, hi = vol.value_range
    iso = lo + 0.35 * (hi - lo)
    tf = sc.TransferFunction.preset("bone", vol.value_range, threshold=0.5)
    cam = sc.Camera.orbit(vol, 30, 20)
    kw = dict(mode=mode, iso=[iso, lo + 0.6 * (hi - lo)], iso_colors=[(0.9, 0.8, 0.7, 0.6), (1, 1, 1, 1)], dt=0.5)
    ref = sc.render(vol, tf, cam, 48, 40, index="naive", **kw)
    assert ref.stats["samples_nonempty"] > 0  # surfaces in view
    for name, opts in CASES:
        opts = {k: v for k, v in opts.items() if not (k == "mode" and v == "ess")}
        img = sc.render(vol, tf, cam, 48, 40, index=name, **opts, **kw)
        diff = np.abs(img.rgba - ref.rgba).max()
        assert diff <= ATOL, f"{name} {opts} {mode}: max abs diff {diff:.3g} vs naive"
    bricked = sc.BrickedVolume(vol.data, spacing=vol.spacing, origin=vol.origin)
    img = sc.render(bricked, tf, cam, 48, 40, index="kdtree-deep", **kw)
    assert np.abs(img.rgba - ref.rgba).max() <= ATOL, "bricked differs from dense"
