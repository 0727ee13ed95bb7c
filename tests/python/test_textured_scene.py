"""scenes/textured.json, the textured example scene (issue 57): the two commands its description
prints run as printed (from a copy of the repository's layout: results/ and scenes/), and the
picture shows both layers: the disc's pixels are yellower than the paper's."""

import contextlib
import io
import json
import os
import pathlib
import shlex
import shutil

import numpy as np

from hybridbrdf.cli import main as hbrdf
from hybridbrdf.render.tracer import read_exr

ROOT = pathlib.Path(__file__).resolve().parents[2]


def test_the_scene_renders_by_the_commands_it_prints(tmp_path, monkeypatch):
    scene = json.loads((ROOT / "scenes" / "textured.json").read_text())
    commands = [part.strip() for part in scene["description"].split("root: ", 1)[1].split("; then ")]
    assert len(commands) == 2 and all(c.startswith("hbrdf ") for c in commands), commands
    os.symlink(ROOT / "results", tmp_path / "results")
    shutil.copytree(ROOT / "scenes", tmp_path / "scenes")
    monkeypatch.chdir(tmp_path)
    for command in commands:
        with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()) as err:
            status = hbrdf(shlex.split(command)[1:])
        assert status in (0, None), (command, err.getvalue())
    image = read_exr(tmp_path / "out" / "textured.exr")
    assert image.shape == (100, 160, 3) and np.isfinite(image).all() and (image >= 0).all()
    # The tile faces the camera: its centre is in the golden disc, its corners on the white paper.
    yellowness = image[..., 0] / np.maximum(image[..., 2], 1e-6)
    w = image.shape[1]
    tile = yellowness[:, int(0.65 * w):]
    lit = image[:, int(0.65 * w):].sum(-1) > 0.05
    assert np.percentile(tile[lit], 95) > 1.5 * np.percentile(tile[lit], 5)
