"""Hostile input, round two: special files and endless inputs.

Every file the Python side opens as input is checked before it is read (hybridbrdf.inputs): a
FIFO, a device (a symlink to /dev/zero or /dev/urandom), a folder, or a file larger than its
format can hold (a sparse file: no disk used) is refused in one line naming the file and what it
is, at once, without reading it. Before, a FIFO hung the reader, /dev/zero filled memory (5 GB
under `hbrdf eval`, then misreported as "lower --pairs") and deep JSON raised RecursionError.

A FIFO case must fail, not hang, when the check is missing: in-process cases arm an unblocker
that opens the FIFO's other end after a few seconds (the reader then sees an empty file and the
message check fails), and command-line cases run under a subprocess timeout.
"""

import contextlib
import json
import os
import resource
import subprocess
import sys
import time

import pytest

import hybridbrdf as hb
from hybridbrdf import inputs
from hybridbrdf.model.random import random_model
from hybridbrdf.sources.base import BRDFFormatError
from hybridbrdf.sources import open_source
from hybridbrdf.sources import merl, nbrdf, tensor_file, utia

# Each reader and the largest file it reads (a sparse file one byte beyond it must be refused).
READERS = {".binary": merl.FILE_BYTES, ".bsdf": tensor_file.MAX_FILE_BYTES, ".bin": utia.FILE_BYTES,
           ".h5": nbrdf.MAX_H5_BYTES}
KINDS = {"fifo": "is a FIFO, not a regular file", "zero": "is a character device, not a regular file",
         "urandom": "is a character device, not a regular file"}
CLI_TIMEOUT = 120  # seconds: a fresh interpreter importing torch on a loaded 2-core machine


def _unblock_later(path, after=4.0):
    """Open the FIFO ``path``'s other end after ``after`` seconds and close it: a reader blocked in
    open() then reads an empty file instead of hanging the test run. A separate process, as a
    blocked reader may hold the GIL (HDF5 opens files with it held)."""
    subprocess.Popen(["sh", "-c", 'sleep "$1"; exec 3<>"$2"', "unblock", str(after), os.fspath(path)],
                     stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)


def make_special(path, kind):
    """``path`` as a FIFO, or a symlink to /dev/zero or /dev/urandom."""
    if kind == "fifo":
        os.mkfifo(path)
        _unblock_later(path)
    else:
        os.symlink(f"/dev/{kind}", path)
    return path


def make_input(path, kind, what):
    """``path`` as a folder (``kind`` "folder") or a special file; the words its refusal must hold."""
    if kind == "folder":
        os.mkdir(path)
        return f"is a folder, not {what}"
    make_special(path, kind)
    return KINDS[kind]


#: Address space a command of these tests may use. Without the checks, reading /dev/zero takes
#: memory until the machine has none; under this cap it is a quick MemoryError, and the test fails.
CLI_MEMORY_CAP = 4 << 30


def _cap_memory():
    resource.setrlimit(resource.RLIMIT_AS, (CLI_MEMORY_CAP, resource.getrlimit(resource.RLIMIT_AS)[1]))


@contextlib.contextmanager
def memory_cap(extra=1 << 30):
    """This process may grow by at most ``extra`` bytes of address space in the block (the same
    guard as CLI_MEMORY_CAP, for in-process calls)."""
    with open("/proc/self/status") as fh:
        used = next(int(line.split()[1]) * 1024 for line in fh if line.startswith("VmSize:"))
    soft, hard = resource.getrlimit(resource.RLIMIT_AS)
    resource.setrlimit(resource.RLIMIT_AS, (used + extra if hard == resource.RLIM_INFINITY else min(used + extra, hard), hard))
    try:
        yield
    finally:
        resource.setrlimit(resource.RLIMIT_AS, (soft, hard))


def assert_refused_at_once(call, path, words, error=ValueError):
    """``call()`` raises ``error`` "<path>: <words>" (one line) within a second."""
    t0 = time.monotonic()
    with pytest.raises(error) as info, memory_cap():
        call()
    assert time.monotonic() - t0 < 1.0, "the file was read, or waited on, before being refused"
    text = str(info.value)
    assert "\n" not in text and text == f"{path}: {words}", text


def run(argv, **kw):
    return subprocess.run(argv, capture_output=True, text=True, timeout=CLI_TIMEOUT, preexec_fn=_cap_memory, **kw)


def assert_one_line_error(r, prog, path, words):
    assert r.returncode == 1, (r.returncode, r.stderr)
    assert "Traceback" not in r.stderr and r.stderr.count("\n") == 1, r.stderr
    assert r.stderr == f"{prog}: error: {path}: {words}\n", r.stderr


# ---- the readers ------------------------------------------------------------------------


@pytest.mark.parametrize("kind", sorted(KINDS))
@pytest.mark.parametrize("ext", sorted(READERS))
def test_readers_refuse_fifos_and_devices_before_opening(tmp_path, ext, kind):
    path = make_special(str(tmp_path / f"x{ext}"), kind)
    assert_refused_at_once(lambda: open_source(path), path, KINDS[kind], BRDFFormatError)


@pytest.mark.parametrize("ext", sorted(READERS))
def test_readers_refuse_files_larger_than_their_format_from_the_size(tmp_path, ext):
    path = tmp_path / f"x{ext}"
    with open(path, "wb") as fh:
        fh.truncate(READERS[ext] + 1)  # sparse: the size without the disk
    what = {".binary": "MERL file", ".bsdf": ".bsdf file", ".bin": "UTIA file", ".h5": "NBRDF .h5 file"}[ext]
    assert_refused_at_once(lambda: open_source(path), path,
                           f"{what} too long: {READERS[ext] + 1} bytes (a {what} is at most {READERS[ext]} bytes)",
                           BRDFFormatError)


def test_a_file_that_grows_while_read_is_cut_at_its_limit(tmp_path, monkeypatch):
    # The size check passes (the stat is made to lie, as a file growing between stat and read
    # would); the bounded read still takes no more than limit + 1 bytes.
    path = tmp_path / "g.bsdf"
    path.write_bytes(b"x" * 100)
    real_stat = os.stat

    class Small:
        def __init__(self, st):
            self.st_mode, self.st_size = st.st_mode, 10

    monkeypatch.setattr(inputs.os, "stat", lambda p, *a, **k: Small(real_stat(p, *a, **k)))
    assert_refused_at_once(lambda: inputs.read_input_bytes(path, ".bsdf file", 10, BRDFFormatError), str(path),
                           ".bsdf file too long: more than 10 bytes (it grew while being read)", BRDFFormatError)


@pytest.mark.parametrize("kind", ["fifo", "zero", "folder"])
def test_nbrdf_keras_config_is_checked_before_it_is_read(tmp_path, kind):
    h5 = tmp_path / "n.h5"
    h5.write_bytes(b"")  # a regular file: the config next to it is read first
    cfg = str(tmp_path / "n.json")
    words = make_input(cfg, kind, "a Keras config")
    assert_refused_at_once(lambda: open_source(h5), cfg, words, BRDFFormatError)


def test_nbrdf_keras_config_nested_5000_levels_is_one_line(tmp_path):
    (tmp_path / "n.h5").write_bytes(b"")
    cfg = tmp_path / "n.json"
    cfg.write_text("[" * 5000 + "]" * 5000)  # 10 KB; json.loads raised RecursionError
    assert_refused_at_once(lambda: open_source(tmp_path / "n.h5"), str(cfg),
                           "Keras config: JSON nested deeper than 64 levels", BRDFFormatError)


@pytest.mark.parametrize("field,value,words", [
    ("name", ["dense_1"], "Keras config layer 0: config.name is a list, not a string"),
    ("name", {"a": 1}, "Keras config layer 0: config.name is an object, not a string"),
    ("class_name", ["Dense"], "Keras config layer 0: class_name is a list, not a string"),
])
def test_nbrdf_keras_config_with_unhashable_names_is_one_line(tmp_path, field, value, words):
    (tmp_path / "n.h5").write_bytes(b"")
    layer = {"class_name": "Dense", "config": {"name": "dense_1", "units": 3}}
    if field == "name":
        layer["config"]["name"] = value
    else:
        layer[field] = value
    cfg = tmp_path / "n.json"
    cfg.write_text(json.dumps({"config": {"layers": [layer, {"class_name": "Lambda", "config": {}}]}}))
    assert_refused_at_once(lambda: open_source(tmp_path / "n.h5"), str(cfg), words, BRDFFormatError)


# ---- model files, scenes, checkpoints ----------------------------------------------------


@pytest.mark.parametrize("kind", sorted(KINDS))
def test_model_files_that_are_fifos_or_devices_are_refused(tmp_path, kind):
    path = make_special(str(tmp_path / "m.safetensors"), kind)
    assert_refused_at_once(lambda: hb.load_model(path), path, KINDS[kind], hb.ModelFileError)


@pytest.mark.parametrize("kind", sorted(KINDS))
def test_scene_files_that_are_fifos_or_devices_are_refused(tmp_path, kind):
    from hybridbrdf.render.tracer import load_scene_dict

    path = make_special(str(tmp_path / "s.json"), kind)
    assert_refused_at_once(lambda: load_scene_dict(path), path, KINDS[kind])


def test_scene_file_larger_than_the_bound_is_refused_from_its_size(tmp_path):
    from hybridbrdf.render.tracer import MAX_SCENE_BYTES, load_scene_dict

    path = tmp_path / "s.json"
    with open(path, "wb") as fh:
        fh.truncate(MAX_SCENE_BYTES + 1)
    assert_refused_at_once(lambda: load_scene_dict(path), str(path),
                           f"scene file too long: {MAX_SCENE_BYTES + 1} bytes (a scene file is at most "
                           f"{MAX_SCENE_BYTES} bytes)")


def test_checkpoint_that_is_a_device_is_refused(tmp_path):
    from hybridbrdf.fit import checkpoint

    path = make_special(str(tmp_path / "c.ckpt"), "zero")
    assert_refused_at_once(lambda: checkpoint.read(path), path, KINDS["zero"], checkpoint.CheckpointError)


# ---- the commands: one line, exit 1, nothing written, never a hang -------------------------


def test_eval_on_a_merl_file_linked_to_dev_zero_names_the_file_not_pairs(tmp_path):
    _, model = random_model("hybrid", latent=2, width=8, depth=1)
    model.save(tmp_path / "m.safetensors")
    src = make_special(str(tmp_path / "gold.binary"), "zero")
    r = run([sys.executable, "-m", "hybridbrdf.cli", "eval", str(tmp_path / "m.safetensors"), src, "--pairs", "1000"])
    assert "pairs" not in r.stderr
    assert_one_line_error(r, "hbrdf eval", src, KINDS["zero"])


def test_eval_on_a_fifo_does_not_hang(tmp_path):
    _, model = random_model("hybrid", latent=2, width=8, depth=1)
    model.save(tmp_path / "m.safetensors")
    src = str(tmp_path / "x.bsdf")
    os.mkfifo(src)  # no unblocker: the subprocess timeout is the guard
    r = run([sys.executable, "-m", "hybridbrdf.cli", "eval", str(tmp_path / "m.safetensors"), src])
    assert_one_line_error(r, "hbrdf eval", src, KINDS["fifo"])


@pytest.mark.parametrize("kind", ["zero", "urandom"])
def test_fit_on_an_endless_bsdf_is_one_line_and_writes_nothing(tmp_path, kind):
    src = make_special(str(tmp_path / "x.bsdf"), kind)
    out = tmp_path / "o.safetensors"
    out.write_bytes(b"previous model")
    r = run([sys.executable, "-m", "hybridbrdf.cli", "fit", src, "--out", str(out), "--steps", "1", "--no-preview"])
    assert_one_line_error(r, "hbrdf fit", src, KINDS[kind])
    assert out.read_bytes() == b"previous model"


def test_render_of_a_fifo_scene_does_not_hang(tmp_path):
    scene = str(tmp_path / "s.json")
    os.mkfifo(scene)
    out = tmp_path / "o.exr"
    out.write_bytes(b"previous image")
    r = run([sys.executable, "-m", "hybridbrdf.cli", "render", scene, "-o", str(out)])
    assert_one_line_error(r, "hbrdf render", scene, KINDS["fifo"])
    assert out.read_bytes() == b"previous image"


def test_codegen_of_a_fifo_model_does_not_hang(tmp_path):
    model = str(tmp_path / "m.safetensors")
    os.mkfifo(model)
    out = tmp_path / "o.glsl"
    out.write_text("previous code")
    r = run([sys.executable, "-m", "hybridbrdf.codegen.main", model, "--target", "glsl", "-o", str(out)])
    assert_one_line_error(r, "hbrdf-codegen", model, KINDS["fifo"])
    assert out.read_text() == "previous code"


# ---- the depth scan itself ---------------------------------------------------------------


@pytest.mark.parametrize("text,depth", [
    ("1", 0), ("{}", 1), ("[[1, [2]], {}]", 3),
    ('{"a": "[[[[{{{{"}', 1),                # brackets in strings do not count
    ('["a\\"[[[[", [1]]', 2),               # nor after an escaped quote
    ('["a\\\\", [[1]]]', 3),                # an escaped backslash ends before the quote
    ('["open [[[[', 1),                      # an unterminated string runs to the end (as in C++)
])
def test_json_depth(text, depth):
    assert inputs.json_depth(text) == depth
    if depth:
        try:
            assert _python_depth(json.loads(text)) == depth
        except ValueError:
            pass  # malformed: only the scan's value is stated


def _python_depth(value) -> int:
    if isinstance(value, list):
        return 1 + max((_python_depth(v) for v in value), default=0)
    if isinstance(value, dict):
        return 1 + max((_python_depth(v) for v in value.values()), default=0)
    return 0


@pytest.mark.parametrize("kind", ["fifo", "zero", "folder"])
def test_libhybridbrdf_refuses_special_model_files_in_the_same_words(tmp_path, kind):
    from hybridbrdf import _core

    path = str(tmp_path / "m.safetensors")
    words = make_input(path, kind, "a model file")
    assert_refused_at_once(lambda: hb.load_model(path), path, words, hb.ModelFileError)
    assert_refused_at_once(lambda: _core.Model(path), path, words, hb.ModelFileError)


def test_a_scene_naming_a_fifo_model_does_not_hang_the_render(tmp_path):
    from hybridbrdf.render import tracer as hr

    model = make_special(str(tmp_path / "m.safetensors"), "fifo")
    scene = {"camera": {"position": [0, 0, 4], "look_at": [0, 0, 0], "fov_deg": 40, "width": 4, "height": 4},
             "environment": {"type": "constant", "radiance": [1, 1, 1]},
             "materials": {"n": {"type": "model", "file": "m.safetensors", "material": "mat-0"}},
             "objects": [{"type": "sphere", "center": [0, 0, 0], "radius": 1, "material": "n"}], "spp": 1}
    (tmp_path / "s.json").write_text(json.dumps(scene))
    t0 = time.monotonic()
    with pytest.raises(ValueError) as info:
        hr.render(str(tmp_path / "s.json"))
    assert time.monotonic() - t0 < 1.0
    text = str(info.value)
    assert "\n" not in text and text.startswith(str(tmp_path / "s.json")) and text.endswith(
        f"{model}: is a FIFO, not a regular file"), text
