"""A capture's folder (docs/ACQUISITION.md): the photographs as float32 OpenEXR, the rig that took
them, and (for a simulated capture) the truth behind them.

    rig.json          the rig (hybridbrdf.acquire.rig): cameras, lights as stated, shots and their images
    photo_000.exr ... one linear HDR photograph per shot, the rig's image size (a real capture's
                      may be 8/16-bit PNG or TIFF, decoded by the index's "photographs" encoding:
                      hybridbrdf.acquire.photographs)
    capture.json      {"format_version": 1, "rig": "rig.json", "simulated": {...}}: the noise model,
                      seed, light jitter, the lights' true positions, the mixture's layers (their
                      source paths or synthetic names) and its weights map
    weights.exr       the mixture's w_1, w_2, w_3 in R, G, B (w_0 = 1 - their sum), when it has layers

A folder is written whole into a temporary folder beside it, then renamed into place; an existing
folder is replaced only when it is a capture (holds capture.json) or is empty.
"""

from __future__ import annotations

import json
import os
import shutil
from typing import List, Tuple

import numpy as np

from hybridbrdf.acquire.photographs import PhotoEncoding, decode_photo, encoding_of_index
from hybridbrdf.acquire.rig import Rig, load_rig
from hybridbrdf.acquire.simulation import Capture
from hybridbrdf.errors import InputFileError
from hybridbrdf.inputs import check_input_file, loads_json, read_input_text
from hybridbrdf.render.tracer import write_exr
from hybridbrdf.sources import SYNTHETIC_PREFIX
from hybridbrdf.files import atomic_write_bytes, make_parent_folder

FORMAT_VERSION = 1
INDEX_FILE = "capture.json"
RIG_FILE = "rig.json"
WEIGHTS_FILE = "weights.exr"
#: Largest photograph file read: 8192 x 8192 RGB float32 and a file format's headers.
MAX_PHOTO_BYTES = 8192 * 8192 * 12 + (1 << 20)


class CaptureError(InputFileError):
    """A capture folder that cannot be used: one line naming the file and the problem."""


def _json_bytes(data) -> bytes:
    return (json.dumps(data, indent=1, allow_nan=False) + "\n").encode()


def source_spec(source) -> str:
    """What reopens ``source`` with ``hybridbrdf.open_source``: its file, or synthetic:NAME."""
    return os.path.abspath(source.path) if source.path else SYNTHETIC_PREFIX + source.name


def check_output_folder(folder: str) -> None:
    """Refuse (one line) a ``folder`` that exists and is not a capture, so nothing is replaced by
    mistake, and create the folders on the way to it (docs/CONVENTIONS.md, "Writing files"): a
    file in the way is refused here, before the photographs are rendered."""
    if os.path.lexists(folder):
        if not os.path.isdir(folder):
            raise InputFileError(folder, "exists and is not a folder")
        if os.listdir(folder) and not os.path.isfile(os.path.join(folder, INDEX_FILE)):
            raise InputFileError(folder, f"is a folder without {INDEX_FILE} (not a capture); refusing to replace it")
    make_parent_folder(folder)


def write_capture(capture: Capture, folder) -> str:
    """Write ``capture`` as the folder ``folder`` (atomically: a temporary folder beside it, then a
    rename; an existing capture is replaced, any other non-empty folder refused). Returns the path."""
    folder = os.path.abspath(os.fspath(folder))
    check_output_folder(folder)
    mixture = capture.mixture
    if len(mixture.sources) > 4:
        raise ValueError(f"a capture's weights map holds at most 4 layers, the mixture has {len(mixture.sources)}")
    w, h = capture.rig.image_size
    for k, photo in enumerate(capture.photos):
        if photo.shape != (h, w, 3) or not np.isfinite(photo).all():
            raise ValueError(f"photo {k} must be finite with shape {(h, w, 3)}, got {photo.shape}")
    if len(capture.photos) != len(capture.rig.shots):
        raise ValueError(f"{len(capture.photos)} photos for {len(capture.rig.shots)} shots")
    parent = os.path.dirname(folder)
    os.makedirs(parent, exist_ok=True)
    tmp, old = f"{folder}.tmp{os.getpid()}", f"{folder}.old{os.getpid()}"
    shutil.rmtree(tmp, ignore_errors=True)
    try:
        os.makedirs(tmp)
        for shot, photo in zip(capture.rig.shots, capture.photos):
            write_exr(photo, os.path.join(tmp, shot.image))
        weights = None
        if len(mixture.sources) > 1:
            rest = mixture.weights[..., 1:]
            rest = np.concatenate([rest, np.zeros(rest.shape[:2] + (3 - rest.shape[2],))], axis=2)
            write_exr(rest.astype(np.float32), os.path.join(tmp, WEIGHTS_FILE))
            weights = WEIGHTS_FILE
        atomic_write_bytes(os.path.join(tmp, RIG_FILE), _json_bytes(capture.rig.to_dict()))
        index = {"format_version": FORMAT_VERSION, "rig": RIG_FILE,
                 "simulated": {"noise": capture.noise.to_dict(), "seed": capture.seed,
                               "light_jitter": capture.light_jitter,
                               "true_light_positions": np.asarray(capture.true_light_positions).tolist(),
                               "layers": [{"name": s.name, "origin": s.origin, "source": source_spec(s)}
                                          for s in mixture.sources],
                               "weights": weights}}
        atomic_write_bytes(os.path.join(tmp, INDEX_FILE), _json_bytes(index))
        if os.path.lexists(folder):
            os.rename(folder, old)
        os.rename(tmp, folder)
        fd = os.open(parent, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
        shutil.rmtree(old, ignore_errors=True)
    return folder


def read_photo(path: str, size: Tuple[int, int], finite: bool = True,
               encoding: PhotoEncoding = PhotoEncoding()) -> Tuple[np.ndarray, np.ndarray]:
    """(photograph (H, W, 3) float32 radiance, saturated (H, W) bool), checked: a regular file of
    the rig's ``size`` (W, H), float EXR/TIFF or 8/16-bit PNG/TIFF decoded by ``encoding``
    (:mod:`~hybridbrdf.acquire.photographs`), whose pixels are finite and unsaturated
    (:class:`CaptureError` naming the file otherwise); ``finite`` False lets both through (a fit
    masks them)."""
    check_input_file(path, "photograph", MAX_PHOTO_BYTES, CaptureError)
    image, saturated = decode_photo(path, size, encoding, CaptureError)
    bad = ~np.isfinite(image)
    if finite and bad.any():
        r, c, _ = (int(v[0]) for v in np.nonzero(bad))
        raise CaptureError(path, f"{int(bad.sum())} values are not finite (first at column {c}, row {r})")
    if finite and saturated.any():
        r, c = (int(v[0]) for v in np.nonzero(saturated))
        raise CaptureError(path, f"{int(saturated.sum())} pixels saturated (first at column {c}, row {r})")
    return image, saturated


def load_capture(folder, finite: bool = True, saturation: bool = False):
    """(rig, photos, index) of a capture folder (or of a rig file, whose folder holds its images):
    every photograph present, of the rig's size, finite and unsaturated (unless ``finite`` is
    False), decoded by the index's ``photographs`` encoding. ``saturation`` adds a fourth item,
    per photograph its (H, W) mask of saturated pixels."""
    folder = os.fspath(folder)
    if os.path.isdir(folder):
        index_path = os.path.join(folder, INDEX_FILE)
        index = loads_json(read_input_text(index_path, "capture index", 1 << 24, CaptureError), index_path,
                           "capture index", CaptureError)
        if not isinstance(index, dict) or index.get("format_version") != FORMAT_VERSION:
            raise CaptureError(index_path, f"not a capture index of format_version {FORMAT_VERSION}")
        rig_name = index.get("rig")
        if not isinstance(rig_name, str) or os.path.basename(rig_name) != rig_name:
            raise CaptureError(index_path, f"rig: must be a plain file name inside the folder, got {rig_name!r}")
        rig_path = os.path.join(folder, rig_name)
        encoding = encoding_of_index(index, index_path, CaptureError)
    else:
        rig_path, index, encoding = folder, {}, PhotoEncoding()
    rig = load_rig(rig_path)
    base = os.path.dirname(rig_path)
    read = [read_photo(os.path.join(base, s.image), rig.image_size, finite, encoding) for s in rig.shots]
    photos = [image for image, _ in read]
    return (rig, photos, index, [mask for _, mask in read]) if saturation else (rig, photos, index)
