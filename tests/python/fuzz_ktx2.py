"""The fuzz suite's KTX2 surface (docs/TEXTURES.md; issue 58): damaged and forged KTX2 files
through both readers, hybridbrdf.svbrdf.ktx2.read_ktx2 and libhybridbrdf's render::read_ktx2.

Invariant: both refuse with the same one-line error naming the file, or both read the same
levels (bit for bit); within fuzz_surfaces' time and address-space bounds (a forged size must be
refused, not allocated); the file is never changed. Inputs: :func:`mutate_ktx2`, structure-aware
damage of a valid file (a header, index, level-index, descriptor or key/value field set to an
extreme or a neighbouring value, levels swapped or cut) or fuzz_surfaces' byte damage.
tests/python/test_fuzz.py drives it with Hypothesis; bench/fuzz_scale.py at scale.
"""

from __future__ import annotations

import pathlib
import struct
import tempfile

import numpy as np

import fuzz_surfaces as fs
from hybridbrdf import _core
from hybridbrdf.svbrdf import ktx2

SEED_FORMATS = ("BC7_SRGB_BLOCK", "BC1_RGB_UNORM_BLOCK", "BC4_UNORM_BLOCK", "BC5_UNORM_BLOCK",
                "R8G8B8A8_SRGB", "R16G16B16A16_SFLOAT")
EXTREMES = [0, 1, 2, 3, 4, 15, 16, 63, 64, 255, 2**16, 2**31 - 1, 2**31, 2**32 - 1]
EXTREMES64 = EXTREMES + [2**32, 2**62, 2**63, 2**64 - 1]


def seed_files() -> dict:
    """Valid small files (17 x 9, a full chain) by format name."""
    rng = np.random.default_rng(0)
    out = {}
    with tempfile.TemporaryDirectory() as d:
        for name in SEED_FORMATS:
            fmt = ktx2.FORMATS[ktx2.vk_format(name)]
            levels = []
            for w, h in ktx2.level_sizes(17, 9, ktx2.max_levels(17, 9)):
                level = rng.integers(0, 256, (h, w, min(fmt.channels, 3)), np.uint8)
                levels.append(level.astype(np.float32) / 255 if fmt.kind.startswith("float") else level)
            path = pathlib.Path(d) / "s.ktx2"
            ktx2.write_ktx2(path, levels, name)
            out[name] = path.read_bytes()
    return out


def _fields(data: bytes) -> list:
    """(offset, struct format) of every structural field of a valid file's layout."""
    fields = [(o, "<I") for o in range(12, 64, 4)] + [(64, "<Q"), (72, "<Q")]
    count = max(1, struct.unpack_from("<I", data, 40)[0])
    fields += [(80 + 24 * p + 8 * k, "<Q") for p in range(count) for k in range(3)]
    dfd = struct.unpack_from("<I", data, 48)[0]
    fields += [(dfd + 4 * k, "<I") for k in range((struct.unpack_from("<I", data, 52)[0]) // 4)]
    fields += [(dfd + k, "<B") for k in range(4, 24)]  # the descriptor's byte-wide fields
    kvd = struct.unpack_from("<I", data, 56)[0]
    fields += [(kvd, "<I")]
    return fields


def mutate_ktx2(seed: bytes, rng: np.random.Generator) -> bytes:
    """One structure-aware damage of ``seed`` (a valid file), or a byte-level one."""
    kind = int(rng.integers(0, 5))
    b = bytearray(seed)
    if kind <= 2:  # a structural field: an extreme, a neighbour, or random bits
        offset, fmt = _fields(seed)[int(rng.integers(0, len(_fields(seed))))]
        old = struct.unpack_from(fmt, b, offset)[0]
        top = {"<B": 255, "<I": 2**32 - 1, "<Q": 2**64 - 1}[fmt]
        choices = [v for v in (EXTREMES64 if fmt == "<Q" else EXTREMES) if v <= top]
        value = [choices[int(rng.integers(0, len(choices)))], (old + int(rng.integers(-16, 17))) % (top + 1),
                 int(rng.integers(0, 256)) if fmt == "<B" else int(rng.integers(0, 2**31))][kind]
        struct.pack_into(fmt, b, offset, value)
    elif kind == 3:  # levels swapped in the index, or one level's entry copied over another's
        count = max(1, struct.unpack_from("<I", b, 40)[0])
        p, q = (int(rng.integers(0, count)) for _ in range(2))
        ep, eq = bytes(b[80 + 24 * p:104 + 24 * p]), bytes(b[80 + 24 * q:104 + 24 * q])
        b[80 + 24 * p:104 + 24 * p] = eq
        if rng.random() < 0.5:
            b[80 + 24 * q:104 + 24 * q] = ep
    else:
        return fs.mutate_bytes(seed, rng)
    return bytes(b)


def check_ktx2(data: bytes, path: pathlib.Path) -> str:
    """Both readers on ``data`` written at ``path``: the same levels, or the same one-line error."""
    path.write_bytes(data)
    results = []
    for read in (lambda: ktx2.read_ktx2(path), lambda: _core.render_read_ktx2(str(path))):
        try:
            with fs._memory_bound():
                results.append(read())
        except Exception as exc:  # noqa: BLE001
            fs.expect_clean_error("KTX2 file", exc, str(path))
            results.append(str(exc))
    if path.read_bytes() != data:
        raise fs.Violation("KTX2 file: the file was changed by reading it")
    py, cpp = results
    if isinstance(py, str) or isinstance(cpp, str):
        if not (isinstance(py, str) and isinstance(cpp, str) and py == cpp):
            raise fs.Violation(f"KTX2 file: the readers disagree: Python {str(py)[:300]!r}, C++ {str(cpp)[:300]!r}")
        return fs.REJECTED
    if py.vk_format != cpp["vk_format"] or len(py.levels) != len(cpp["levels"]) or not all(
            np.array_equal(a, b, equal_nan=a.dtype.kind == "f") for a, b in zip(py.levels, cpp["levels"])):
        raise fs.Violation("KTX2 file: both readers accepted it but read different levels")
    return fs.VALID
