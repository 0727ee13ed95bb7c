"""The fuzz suite's normal-map and KTX2-normal-map cases (issue 58, "Bad input"): each hostile
normal map refused in one line naming its file, nothing written; a KTX2 normal map in a format
the quantity cannot hold (sRGB, one channel) refused alike by both loaders."""

from __future__ import annotations

import numpy as np
import pytest

import hybridbrdf as hb
from hybridbrdf.svbrdf.asset import SVBRDF, load_svbrdf
from hybridbrdf.svbrdf.ktx2 import read_ktx2, write_ktx2

from helpers import run_cli_here, saved_random_model


@pytest.fixture(scope="module")
def model(tmp_path_factory):
    return saved_random_model(tmp_path_factory.mktemp("m"), "hybrid")


def _write_png(path, array, mode):
    from PIL import Image

    Image.fromarray(array, mode).save(path)


HOSTILE_PNGS = [
    ("another size", lambda p: _write_png(p, np.full((2, 8, 3), 128, np.uint8), "RGB"), "normal map is 8x2"),
    ("not a PNG", lambda p: p.write_bytes(b"\x89PNG\r\n\x1a\n" + b"\0" * 20), "normal.png"),
    ("empty", lambda p: p.write_bytes(b""), "normal.png"),
]


@pytest.mark.parametrize("name,make,words", HOSTILE_PNGS, ids=[h[0] for h in HOSTILE_PNGS])
def test_hostile_normal_maps_through_paint(model, tmp_path, name, make, words):
    path, m = model
    make(tmp_path / "normal.png")
    r = run_cli_here("paint", str(path), "--base", m.materials[0], "--size", "8x4", "--normal", str(tmp_path / "normal.png"),
                     "--format", "ktx2", "--out", str(tmp_path / "sv"))
    assert r.returncode != 0 and words in r.stderr, r.stderr
    assert len(r.stderr.strip().splitlines()) == 1 and "normal.png" in r.stderr and not (tmp_path / "sv").exists()


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_non_finite_normal_arrays_are_refused(model, bad):
    _, m = model
    normal = np.zeros((4, 8, 2), np.float32)
    normal[1, 2, 0] = bad
    with pytest.raises(ValueError) as err:
        SVBRDF(m, [m.materials[0]], (8, 4), normal=normal)
    assert "normal" in str(err.value) and len(str(err.value).splitlines()) == 1


@pytest.mark.parametrize("vk,words", [
    ("BC7_SRGB_BLOCK", "is sRGB-encoded (a sampler decodes it), so its transfer must be srgb, not linear"),
    ("BC4_UNORM_BLOCK", "BC4_UNORM_BLOCK holds 1 channel(s); this normal map needs 2"),
])
def test_ktx2_normal_map_in_a_format_it_cannot_hold(model, tmp_path, vk, words):
    """A normal map rewritten as an sRGB or one-channel KTX2: refused by Python's and libhybridbrdf's
    loaders with the same line (the folder otherwise valid)."""
    _, m = model
    xy = np.stack(np.meshgrid(np.linspace(-0.3, 0.3, 8), np.linspace(-0.2, 0.2, 4)), axis=2).astype(np.float32)
    SVBRDF(m, [m.materials[0]], (8, 4), normal=xy).save(tmp_path / "sv", format="ktx2")
    tex = read_ktx2(tmp_path / "sv" / "normal.ktx2")
    assert tex.name == "BC5_UNORM_BLOCK"
    levels = [np.pad(lv, ((0, 0), (0, 0), (0, 1))) if vk.startswith("BC7") else lv[..., :1] for lv in tex.levels]
    write_ktx2(tmp_path / "sv" / "normal.ktx2", levels, vk)
    with pytest.raises(Exception) as py_err:
        load_svbrdf(tmp_path / "sv")
    with pytest.raises(Exception) as cpp_err:
        hb._core.Svbrdf(str(tmp_path / "sv"))
    assert words in str(py_err.value) and str(py_err.value) == str(cpp_err.value)
    assert len(str(py_err.value).splitlines()) == 1
