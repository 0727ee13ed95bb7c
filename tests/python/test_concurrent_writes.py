"""Two processes writing the same output at once: the result is one of the two
complete files, never a mix, and no temporary is left behind. Model files and checkpoints go
through hybridbrdf.files.atomic_write_bytes (a temporary named by pid and 64 random bits, then a
rename); images through the tracer's StagedFile (a temporary named by pid, then a rename)."""

import json
import os
import subprocess
import sys

import numpy as np

from helpers import run_cli
from test_render import analytic_material, scene

WRITER = """
import sys
from hybridbrdf.files import atomic_write_bytes
path, byte, size, rounds = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), int(sys.argv[4])
payload = bytes([byte]) * size
for _ in range(rounds):
    atomic_write_bytes(path, payload)
"""


def test_two_writers_of_one_model_path_leave_one_complete_file(tmp_path):
    out = tmp_path / "m.safetensors"
    size = 4 << 20  # large enough that the two writes overlap
    procs = [subprocess.Popen([sys.executable, "-c", WRITER, str(out), str(b), str(size), "40"])
             for b in (0x41, 0x42)]
    assert [p.wait(timeout=300) for p in procs] == [0, 0]
    data = out.read_bytes()
    assert len(data) == size and data in (b"\x41" * size, b"\x42" * size)  # one writer's, whole
    assert os.listdir(tmp_path) == ["m.safetensors"]  # no temporaries left


def test_two_renders_to_one_image_leave_one_of_the_two(tmp_path):
    from hybridbrdf.render.tracer import read_image as read_exr

    path = tmp_path / "s.json"
    path.write_text(json.dumps(scene(analytic_material())))
    alone = {}
    for seed in (1, 2):
        target = tmp_path / f"alone{seed}.exr"
        r = run_cli("render", str(path), "-o", str(target), "--spp", "2", "--seed", str(seed), "--threads", "1",
                    "--quiet")
        assert r.returncode == 0, r.stderr
        alone[seed] = read_exr(str(target))
    assert not np.array_equal(alone[1], alone[2])  # the seeds tell the two writers apart
    out = tmp_path / "both.exr"
    procs = [subprocess.Popen([sys.executable, "-m", "hybridbrdf.cli", "render", str(path), "-o", str(out), "--spp",
                               "2", "--seed", str(seed), "--threads", "1", "--quiet"]) for seed in (1, 2)]
    assert [p.wait(timeout=300) for p in procs] == [0, 0]
    got = read_exr(str(out))
    assert any(np.array_equal(got, a) for a in alone.values())
    assert sorted(os.listdir(tmp_path)) == ["alone1.exr", "alone2.exr", "both.exr", "s.json"]
