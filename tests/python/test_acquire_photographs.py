"""Photographs from a camera (docs/ACQUISITION.md, issue 61 part 4): 8- and 16-bit PNG and TIFF
decoded through the capture index's encoding, saturated pixels masked like pixels that are not
finite, and one-line refusals of the files a fit cannot use.

The references are independent of the library's reader: PNG files are written here byte by byte
(zlib and the PNG chunk layout), sRGB is encoded here by IEC 61966-2-1's piecewise formula, and
every decoded value is checked against the interval its integer code stands for."""

import json
import os
import struct
import zlib

import numpy as np
import pytest

from hybridbrdf.acquire import simulate
from hybridbrdf.acquire.capture import CaptureError, load_capture, write_capture
from hybridbrdf.acquire.exposure import usable_pixels
from hybridbrdf.acquire.mixture import Mixture
from hybridbrdf.acquire.observations import texel_observations
from hybridbrdf.acquire.rigs import flash_rig
from hybridbrdf.sources import open_source


def srgb_encode(x):
    """IEC 61966-2-1: linear [0, 1] -> encoded [0, 1]."""
    x = np.asarray(x, np.float64)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(np.maximum(x, 0.0031308), 1 / 2.4) - 0.055)


def srgb_decode(v):
    v = np.asarray(v, np.float64)
    return np.where(v <= 0.04045, v / 12.92, ((v + 0.055) / 1.055) ** 2.4)


def _chunk(kind: bytes, data: bytes) -> bytes:
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)


def write_png(path, codes, bits, colour_type=2, palette=None):
    """A PNG written by hand: IHDR, (PLTE), one IDAT of filter-0 rows, IEND."""
    h, w = codes.shape[:2]
    dtype = ">u2" if bits == 16 else "u1"
    rows = codes.astype(dtype).reshape(h, -1)
    raw = b"".join(b"\x00" + r.tobytes() for r in rows)
    out = b"\x89PNG\r\n\x1a\n" + _chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, bits, colour_type, 0, 0, 0))
    if palette is not None:
        out += _chunk(b"PLTE", bytes(palette))
    out += _chunk(b"IDAT", zlib.compress(raw)) + _chunk(b"IEND", b"")
    with open(path, "wb") as f:
        f.write(out)


@pytest.fixture(scope="module")
def exr_capture(tmp_path_factory):
    """A 6-photograph flash capture of gold and plastic halves, no noise, as float EXR."""
    weights = np.zeros((2, 4, 2))
    weights[:, :2, 0], weights[:, 2:, 1] = 1, 1
    rig = flash_rig(6, size=(24, 20))
    cap = simulate(rig, Mixture([open_source("synthetic:gold"), open_source("synthetic:plastic")], weights))
    folder = tmp_path_factory.mktemp("exr") / "capture"
    write_capture(cap, folder)
    return str(folder), rig, cap.photos


def recode(src, dst, encode, ext, photographs):
    """A copy of the capture ``src`` whose photographs are ``encode(photo) -> image`` files ``ext``
    and whose index states ``photographs``."""
    os.makedirs(dst)
    rig = json.load(open(os.path.join(src, "rig.json")))
    index = json.load(open(os.path.join(src, "capture.json")))
    _, photos, _ = load_capture(src)
    for k, shot in enumerate(rig["shots"]):
        shot["image"] = f"photo_{k:03d}{ext}"
        encode(photos[k], os.path.join(dst, shot["image"]))
    index["photographs"] = photographs
    json.dump(rig, open(os.path.join(dst, "rig.json"), "w"))
    json.dump(index, open(os.path.join(dst, "capture.json"), "w"))
    return dst


def test_16_bit_linear_and_8_bit_srgb_read_back_within_their_quantisation_step(exr_capture, tmp_path):
    import tifffile

    src, rig, photos = exr_capture
    scale = 1.05 * max(float(p.max()) for p in photos)  # no pixel saturates
    lin16 = lambda p, path: write_png(path, np.round(np.clip(p / scale, 0, 1) * 65535), 16)
    srgb8 = lambda p, path: write_png(path, np.round(srgb_encode(np.clip(p / scale, 0, 1)) * 255), 8)
    tif16 = lambda p, path: tifffile.imwrite(path, np.round(np.clip(p / scale, 0, 1) * 65535).astype(np.uint16),
                                             photometric="rgb")
    for name, encode, ext, enc, top in (("lin16", lin16, ".png", "linear", 65535), ("srgb8", srgb8, ".png", "srgb", 255),
                                        ("tif16", tif16, ".tif", "linear", 65535)):
        folder = recode(src, str(tmp_path / name), encode, ext, {"encoding": enc, "scale": scale})
        _, read, _ = load_capture(folder)
        for truth, got in zip(photos, read):
            x = np.clip(truth / scale, 0, 1).astype(np.float64)
            # The code c stands for every linear value whose encoding rounds to it: the decoded
            # value and the truth both lie in [dec((c - 1/2) / top), dec((c + 1/2) / top)].
            code = np.round((srgb_encode(x) if enc == "srgb" else x) * top)
            dec = srgb_decode if enc == "srgb" else (lambda v: v)
            lo, hi = dec(np.clip((code - 0.5) / top, 0, 1)), dec(np.clip((code + 0.5) / top, 0, 1))
            assert (x >= lo - 1e-12).all() and (x <= hi + 1e-12).all()  # the reference is self-consistent
            step = scale * (hi - lo)
            err = np.abs(got.astype(np.float64) - truth)
            assert (err <= step + 2e-7 * scale).all(), f"{name}: {float((err - step).max())} beyond the step"
        assert float(step.max()) < (0.02 if enc == "srgb" else 2e-5) * scale


def test_saturated_pixels_are_masked_counted_and_kept_out_of_the_observations(exr_capture, tmp_path):
    src, rig, photos = exr_capture
    scale = 0.6 * max(float(p.max()) for p in photos)  # the brightest pixels clip
    clip16 = lambda p, path: write_png(path, np.round(np.clip(p / scale, 0, 1) * 65535), 16)
    folder = recode(src, str(tmp_path / "clipped"), clip16, ".png", {"encoding": "linear", "scale": scale})
    with pytest.raises(CaptureError, match=r"photo_00\d.png: \d+ pixels saturated \(first at column \d+, row \d+\)"):
        load_capture(folder)
    rig, read, index, saturated = load_capture(folder, finite=False, saturation=True)
    expected = [(np.round(np.clip(p / scale, 0, 1) * 65535) == 65535).any(axis=2) for p in photos]
    assert sum(int(e.sum()) for e in expected) > 20
    for e, s in zip(expected, saturated):
        np.testing.assert_array_equal(s, e)
    masks, report = usable_pixels(rig, read, saturated=saturated)
    assert report["saturated"] == sum(int(e.sum()) for e in expected) and report["not finite"] == 0
    assert all(not (m & e).any() for m, e in zip(masks, expected))
    # The observations hold exactly the unclipped pixels' rows: each clipped pixel's row is gone and
    # every other row is the EXR capture's within 16-bit quantisation.
    exact = texel_observations(rig, photos, (2, 2), usable=[~e for e in expected])
    obs = texel_observations(rig, read, (2, 2), usable=masks)
    assert obs.dropped["masked"] == exact.dropped["masked"] > 0
    np.testing.assert_array_equal(obs.offsets, exact.offsets)
    np.testing.assert_allclose(obs.value, exact.value, rtol=2e-4, atol=1e-4)
    everything = texel_observations(rig, photos, (2, 2))
    assert len(everything.value) > len(obs.value)


def _folder_with(tmp_path, exr_capture, name, write, photographs=None):
    src, _, _ = exr_capture
    folder = str(tmp_path / name)

    def encode(p, path):
        if path.endswith("photo_001.png"):
            write(p, path)
        else:
            write_png(path, np.round(np.clip(p, 0, 1) * 65535), 16)
    return recode(src, folder, encode, ".png", photographs or {"encoding": "linear"})


def test_bad_photographs_and_encodings_are_refused_in_one_line_naming_the_file(exr_capture, tmp_path):
    import tifffile

    src, _, _ = exr_capture
    cases = {
        "truncated": (lambda p, path: (write_png(path, np.zeros((20, 24, 3)), 16),
                                       open(path, "r+b").truncate(60)), r"photo_001.png: cannot read the PNG"),
        "size": (lambda p, path: write_png(path, np.zeros((21, 24, 3)), 16),
                 r"photo_001.png: photograph is 24x21; the rig says 24x20"),
        "palette": (lambda p, path: write_png(path, np.zeros((20, 24)), 8, colour_type=3, palette=[0, 0, 0, 255, 255, 255]),
                    r"photo_001.png: a palette \(indexed\) PNG"),
        "grey": (lambda p, path: write_png(path, np.zeros((20, 24)), 16, colour_type=0),
                 r"photo_001.png: a PNG of 1 channel\(s\) \(grey\); a photograph needs RGB"),
    }
    for name, (write, words) in cases.items():
        folder = _folder_with(tmp_path, exr_capture, name, write)
        with pytest.raises(CaptureError) as err:
            load_capture(folder, finite=False)
        assert "\n" not in str(err.value)
        assert __import__("re").search(words, str(err.value)), (name, str(err.value))
        assert str(err.value).startswith(os.path.join(folder, "photo_001.png")), str(err.value)
    bad_index = {"unknown encoding": ({"encoding": "gamma22"}, "photographs: encoding: unknown encoding 'gamma22'"),
                 "scale": ({"scale": 0}, "photographs: scale: expected a number > 0"),
                 "key": ({"gamma": 2.2}, "photographs: unknown key 'gamma'")}
    for name, (entry, words) in bad_index.items():
        folder = _folder_with(tmp_path, exr_capture, name.replace(" ", "_"), lambda p, path: write_png(path, p * 0, 16),
                              entry)
        with pytest.raises(CaptureError) as err:
            load_capture(folder)
        assert str(err.value) == f"{os.path.join(folder, 'capture.json')}: {words}" or words in str(err.value), str(err.value)
        assert "\n" not in str(err.value) and str(err.value).startswith(os.path.join(folder, "capture.json"))
    # TIFFs: 32-bit integers refused; an sRGB statement on float photographs refused.
    tiff32 = recode(src, str(tmp_path / "int32"), lambda p, path: tifffile.imwrite(path, (p * 1000).astype(np.uint32), photometric="rgb"),
                    ".tif", {"encoding": "linear"})
    with pytest.raises(CaptureError, match=r"photo_000.tif: a TIFF of uint32 samples; photographs are 8- or 16-bit"):
        load_capture(tiff32)
    float_srgb = recode(src, str(tmp_path / "fsrgb"), lambda p, path: tifffile.imwrite(path, p.astype(np.float32), photometric="rgb"),
                        ".tif", {"encoding": "srgb"})
    with pytest.raises(CaptureError, match=r"photo_000.tif: a float photograph is linear"):
        load_capture(float_srgb)
    float_linear = recode(src, str(tmp_path / "flin"), lambda p, path: tifffile.imwrite(path, p.astype(np.float32), photometric="rgb"),
                          ".tif", {"encoding": "linear"})
    _, read, _ = load_capture(float_linear)
    np.testing.assert_array_equal(read[0], load_capture(src)[1][0])
