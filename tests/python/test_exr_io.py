"""read_exr beside write_exr (issue 57): what one writes the other reads back float for float, and
a file that is not an EXR, or a truncated one, is refused in one line naming it."""

import numpy as np
import pytest

from hybridbrdf.errors import InputFileError
from hybridbrdf.render.tracer import EXR_MAGIC, read_exr, write_exr


def test_write_then_read_gives_back_the_same_floats(tmp_path):
    rng = np.random.default_rng(4)
    image = np.concatenate([rng.random((5, 7, 3)) * 10.0 ** rng.integers(-6, 6, (5, 7, 3)),
                            np.array([[[0.0, -0.0, 65504.0]] * 7])], axis=0).astype(np.float32)
    path = tmp_path / "round.exr"
    write_exr(image, path)
    assert path.read_bytes()[:4] == EXR_MAGIC == bytes([0x76, 0x2F, 0x31, 0x01])  # the OpenEXR magic, 20000630
    back = read_exr(path)
    assert back.dtype == np.float32 and back.shape == image.shape
    np.testing.assert_array_equal(back, image)


def test_not_an_exr_or_truncated_is_one_line_naming_the_file(tmp_path):
    png = tmp_path / "picture.exr"  # the name says EXR; the bytes do not
    png.write_bytes(b"\x89PNG\r\n\x1a\n" + bytes(64))
    with pytest.raises(InputFileError, match="is not an OpenEXR file") as err:
        read_exr(png)
    assert str(png) in str(err.value) and "\n" not in str(err.value)
    good = tmp_path / "good.exr"
    write_exr(np.ones((8, 8, 3), np.float32), good)
    cut = tmp_path / "cut.exr"
    cut.write_bytes(good.read_bytes()[:60])
    with pytest.raises(Exception) as err:
        read_exr(cut)
    assert str(cut) in str(err.value) and "\n" not in str(err.value).strip()
    with pytest.raises(InputFileError, match="No such file"):
        read_exr(tmp_path / "missing.exr")
