"""NIfTI volumes (``.nii``, ``.nii.gz``), through nibabel."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ..axes import axcodes, space_directions
from ..errors import FileFormatError
from ..volume import Volume
from .budget import check_declared
from .files import file_size, require_regular_file
from .reading import Read, read_guard

__all__ = ["read_nifti", "write_nifti"]


def nifti_steps(path: Path) -> int | None:
    """Time steps of a 4-D NIfTI image ``(x, y, z, t)`` from its header, None for 3-D."""
    import nibabel as nib

    require_regular_file(path, "NIfTI file")
    img = read_guard(path, "NIfTI", nib.load, str(path))
    shape = tuple(int(n) for n in img.header.get_data_shape())
    while len(shape) > 3 and shape[-1] == 1:
        shape = shape[:-1]
    return shape[3] if len(shape) == 4 else None


def read_nifti(path: Path, step: int | None = None) -> Read:
    """A 3-D scalar NIfTI-1/2 image (trailing singleton axes dropped).

    The on-disk dtype is kept unless ``scl_slope``/``scl_inter`` are set and
    non-trivial (then the scaled values, at least float32); spacing from the zooms,
    origin from the affine's translation; the orientation (axis codes) from the affine
    (``aff2axcodes``) when the sform or qform code says it maps to a patient frame (a
    file with both codes 0 is ANALYZE-style: orientation unknown). ``step``: volume
    ``t`` of a 4-D ``(x, y, z, t)`` image, read alone through nibabel's array proxy.
    """
    import nibabel as nib

    require_regular_file(path, "NIfTI file")
    img = read_guard(path, "NIfTI", nib.load, str(path), mmap=False)
    _check_size(path, img)

    def _read():
        dataobj = img.dataobj
        if nib.is_proxy(dataobj):
            # nibabel moves scl_slope/scl_inter from the header into the proxy on load
            # (the image's header then reads NaN), so take them from the proxy.
            slope = getattr(dataobj, "slope", None)
            inter = getattr(dataobj, "inter", None)
            if step is not None:
                # One volume: the proxy reads only its bytes (a .gz decompresses up to them)
                # and scales them; bring the dtype to what the 3-D path gives.
                index = (slice(None),) * 3 + (step,) + (0,) * (len(dataobj.shape) - 4)
                raw = np.asarray(dataobj[index])
                if raw.dtype.kind == "f" and img.get_data_dtype().kind != "f":
                    raw = raw.astype(np.result_type(img.get_data_dtype(), np.float32))
                slope = inter = None
            else:
                raw = np.asarray(dataobj.get_unscaled())
        else:
            raw = np.asanyarray(dataobj)
            slope, inter = img.header.get_slope_inter()
        zooms = img.header.get_zooms()
        return np.array(raw), slope, inter, zooms

    raw, slope, inter, zooms = read_guard(path, "NIfTI", _read)
    # Drop trailing singleton axes (x, y, z, 1) which are common in the wild.
    while raw.ndim > 3 and raw.shape[-1] == 1:
        raw = raw[..., 0]
    if raw.ndim != 3:
        raise FileFormatError(
            f"{str(path)!r}: {raw.ndim}-D NIfTI image of shape {raw.shape}; expected a 3-D scalar volume"
        )
    slope = None if slope is None or not np.isfinite(float(slope)) else float(slope)
    inter = None if inter is None or not np.isfinite(float(inter)) else float(inter)
    if (slope not in (None, 0.0, 1.0)) or (inter not in (None, 0.0)):
        out_dtype = np.result_type(raw.dtype, np.float32)
        s = 1.0 if slope in (None, 0.0) else slope
        i = 0.0 if inter is None else inter
        raw = raw.astype(out_dtype) * out_dtype.type(s) + out_dtype.type(i)
    data = np.ascontiguousarray(raw.transpose(2, 1, 0))  # (x, y, z) -> (z, y, x)
    spacing = np.asarray(zooms[:3], dtype=np.float64)
    if spacing.shape != (3,) or not np.all(np.isfinite(spacing)) or np.any(spacing <= 0):
        spacing = None
    affine = np.asarray(img.affine, dtype=np.float64)
    origin = affine[:3, 3]
    if not np.all(np.isfinite(origin)):
        origin = None
    coded = int(img.header["sform_code"]) > 0 or int(img.header["qform_code"]) > 0
    return Read(data, spacing, origin, axcodes(affine[:3, :3]) if coded else None)


def _check_size(path: Path, img) -> None:
    """The header's shape and dtype against the file (uncompressed) and the memory limit,
    before nibabel allocates what the header claims."""
    shape = tuple(int(n) for n in img.header.get_data_shape())
    dtype = img.header.get_data_dtype()
    declared = math.prod(shape) * dtype.itemsize
    what = f"NIfTI header (shape {shape}, {dtype.name})"
    size = file_size(path)
    if path.name.lower().endswith(".gz"):
        check_declared(path, declared, what, compressed_bytes=size)
    else:
        offset = int(getattr(img.dataobj, "offset", 0) or 0)
        check_declared(path, declared, what, available=size - offset)


def write_nifti(volume: Volume, tmp: Path, compress: bool) -> None:
    """Affine = diag(spacing) + origin, its columns' signs and order from the orientation
    (a NIfTI world is RAS+, so a volume without orientation reads back as RAS); ``.nii.gz``
    is compressed by its name (``compress`` is ignored)."""
    import nibabel as nib

    affine = np.eye(4)
    affine[:3, :3] = space_directions(volume.orientation or ("R", "A", "S")) * volume.spacing
    affine[:3, 3] = volume.origin
    img = nib.Nifti1Image(np.asarray(volume.data).transpose(2, 1, 0), affine)  # (z,y,x) -> (x,y,z)
    img.header.set_data_dtype(volume.data.dtype)
    img.header.set_xyzt_units("mm")
    nib.save(img, str(tmp))
