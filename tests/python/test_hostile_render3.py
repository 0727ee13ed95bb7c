"""Hostile input for the renderer, round three (issue 45: defects 3, 6, 7, 8 and 9; docs/RENDERING.md,
"Limits and validation", "Input and output files" and "Environments"):

- a full disk while writing the EXR or PNG output is a one-line error naming the file, exit 1, no
  temporary and no truncated file left (a small tmpfs where root may mount one; everywhere, the same
  failure through RLIMIT_FSIZE, which makes write() fail as a full disk does);
- a replaced output keeps its permissions, a new one gets the umask's;
- an environment map with a texel that is not finite or is negative is refused, naming the file, the
  texel and its value (it rendered without its sun, or black, with exit 0), in the tracer and in
  ``hbrdf view --env``;
- geometry beyond what float32 can place at the camera's scale is refused naming the object (a plane
  of 3e10 rendered black, a plane of 1e20, a mesh at 1e20..3e38 and a sphere of radius 1e20 vanished);
  geometry inside the limits renders as exactly as a small scene;
- a scene dict nested 10,000 deep is the files' one-line depth error, not a RecursionError.
"""

import contextlib
import json
import os
import re
import resource
import signal
import subprocess

import numpy as np
import pytest

from hybridbrdf import _core
from hybridbrdf.errors import InputFileError
from hybridbrdf.render import tracer as hr
from hybridbrdf.viewer.lighting import environment_spec, page_environment

from helpers import run_cli

pytestmark = pytest.mark.skipif(not getattr(_core, "HAVE_RENDERER", False), reason="built without the renderer")

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
MODEL = os.path.join(REPO, "results", "rgl54_hybrid_32x2.safetensors")
KD, L = 0.8, 0.5  # the plane's Lambert albedo, the constant environment's radiance


def plane_scene(size=8.0, scale=1.0, width=32, height=24):
    """A Lambert plane (kd 0.8) 1 below a camera at distance ~4.2 from the origin, under a constant
    environment of radiance 0.5; every length times ``scale``. With cosine sampling, no NEE and one
    bounce every sample of a plane pixel is exactly kd L = 0.4 and every sky pixel 0.5, whatever the
    plane's size: an exact reference that does not come from the tracer."""
    return {"camera": {"position": [0, 0.6 * scale, 4.2 * scale], "look_at": [0, 0, 0], "width": width, "height": height},
            "environment": {"type": "constant", "radiance": [L, L, L]},
            "materials": {"m": {"type": "analytic", "kd": KD, "eta": 1.0}},  # eta 1: no specular lobe
            "objects": [{"type": "plane", "center": [0, -scale, 0], "normal": [0, 1, 0], "size": size * scale, "material": "m"}],
            "spp": 4, "max_depth": 1, "sampler": "cosine", "nee": False, "threads": 2}


def write_scene(tmp_path, s, name="s.json"):
    path = tmp_path / name
    path.write_text(json.dumps(s))
    return path


def one_line_error(r, pattern):
    assert r.returncode == 1, (r.returncode, r.stdout[-500:], r.stderr[-2000:])
    assert r.stderr.count("\n") == 1 and "Traceback" not in r.stderr, r.stderr[-2000:]
    assert re.search(pattern, r.stderr), r.stderr


# ---- defect 3: a full disk ----------------------------------------------------------------------


def noise_image(h=48, w=64, seed=0):
    """Incompressible pixels, so the encoded files span several 4 KiB pages."""
    return np.random.default_rng(seed).random((h, w, 3), dtype=np.float32)


def encoded_size(tmp_path, kind):
    path = tmp_path / f"probe.{kind}"
    (hr.write_exr if kind == "exr" else hr.write_png)(noise_image(), str(path))
    size = path.stat().st_size
    path.unlink()
    return size


@contextlib.contextmanager
def small_tmpfs(tmp_path):
    """A 1 MiB tmpfs at tmp_path/full (root only; a skip with the reason elsewhere)."""
    mnt = tmp_path / "full"
    mnt.mkdir()
    r = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=1m", "tmpfs", str(mnt)], capture_output=True, text=True)
    if r.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here (root only): {r.stderr.strip()}")
    try:
        yield mnt
    finally:
        subprocess.run(["umount", "-l", str(mnt)], check=False)


def fill_leaving_pages(mnt, pages):
    """Fill the file system at mnt until exactly `pages` free 4 KiB pages remain."""
    st = os.statvfs(mnt)
    assert st.f_frsize == 4096
    with open(mnt / "filler", "wb") as f:
        f.write(b"\0" * ((st.f_bavail - pages) * 4096))
    assert os.statvfs(mnt).f_bavail == pages


@pytest.mark.parametrize("kind", ["exr", "png"])
def test_a_full_tmpfs_is_an_error_naming_the_file_and_leaves_nothing(tmp_path, kind):
    """One page short of the file: stdio wrote the whole pages straight through and kept the tail in its
    buffer, whose failure only fclose() reported, unchecked: exit 0 and a truncated file."""
    size = encoded_size(tmp_path, kind)
    assert size % 4096 != 0 and size > 4096, size
    with small_tmpfs(tmp_path) as mnt:
        fill_leaving_pages(mnt, size // 4096)
        target = mnt / f"r.{kind}"
        with pytest.raises(ValueError) as err:
            (hr.write_exr if kind == "exr" else hr.write_png)(noise_image(), str(target))
        assert str(err.value) == f"{target}: cannot write the file: No space left on device", str(err.value)
        assert sorted(p.name for p in mnt.iterdir()) == ["filler"]
        # The CLI, both outputs, one page short of the two: the one that fails is named, exit 1,
        # neither file written. A noisy render (sky, NEE, 1 spp), so that both files span pages.
        s = plane_scene(width=64, height=48)
        s.update(spp=1, nee=True, sampler="mis", environment={"type": "sky", "resolution": [64, 32]})
        path = write_scene(tmp_path, s)
        hr.render(str(path), out=str(tmp_path / "r.exr"), png=str(tmp_path / "r.png"))
        pages = sum(-(-(tmp_path / n).stat().st_size // 4096) for n in ("r.exr", "r.png"))
        assert pages >= 3, pages
        (mnt / "filler").unlink()
        fill_leaving_pages(mnt, pages - 1)
        r = run_cli("render", str(path), "-o", str(mnt / "r.exr"), "--png", str(mnt / "r.png"), "--quiet")
        one_line_error(r, "^hbrdf render: error: " + re.escape(f"{mnt}/r.") + r"(exr|png): cannot (write|flush \(fsync\)) "
                       r"the file: No space left on device$")
        assert sorted(p.name for p in mnt.iterdir()) == ["filler"]


def write_limited(kind, target, limit):
    """Write noise_image() to `target` in a forked child whose files may not grow past `limit` bytes
    (RLIMIT_FSIZE; SIGXFSZ ignored, so write() fails with EFBIG as on a full disk): "wrote", or the
    writer's error message."""
    read, write = os.pipe()
    pid = os.fork()
    if pid == 0:  # the child: no pytest teardown, whatever happens
        try:
            signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
            resource.setrlimit(resource.RLIMIT_FSIZE, (limit, resource.getrlimit(resource.RLIMIT_FSIZE)[1]))
            try:
                (hr.write_exr if kind == "exr" else hr.write_png)(noise_image(), str(target))
                message = "wrote"
            except ValueError as exc:
                message = str(exc)
            os.write(write, message.encode())
        finally:
            os._exit(0)
    os.close(write)
    os.waitpid(pid, 0)
    with os.fdopen(read, "rb") as f:
        return f.read().decode()


@pytest.mark.parametrize("kind", ["exr", "png"])
@pytest.mark.parametrize("short_by", [1, 2000])
def test_a_write_that_fails_part_way_is_an_error_on_any_file_system(tmp_path, kind, short_by):
    """RLIMIT_FSIZE makes write() fail past a size, as a full disk does: portable, no root needed.
    One byte short, the failure came only at fclose(), and the old writers renamed a file one byte
    short into place and said "wrote" (tinyexr's SaveEXR and stb's stbi_write_png both report success
    there: checked through ctypes on Debian's libtinyexr and libstb)."""
    size = encoded_size(tmp_path, kind)
    target = tmp_path / f"r.{kind}"
    assert write_limited(kind, target, size - short_by) == f"{target}: cannot write the file: File too large"
    assert sorted(p.name for p in tmp_path.iterdir()) == [], "a partial or temporary file was left"
    assert write_limited(kind, target, size) == "wrote" and target.stat().st_size == size


# ---- defect 6: permissions -------------------------------------------------------------------------


def test_a_replaced_output_keeps_its_mode_and_a_new_one_gets_the_umask(tmp_path):
    path = write_scene(tmp_path, plane_scene(width=8, height=6))
    exr, png = tmp_path / "r.exr", tmp_path / "r.png"
    for f in (exr, png):
        f.write_bytes(b"old")
        os.chmod(f, 0o640)
    r = run_cli("render", str(path), "-o", str(exr), "--png", str(png), "--quiet")
    assert r.returncode == 0, r.stderr
    assert exr.read_bytes() != b"old" and png.read_bytes() != b"old"
    assert [oct(f.stat().st_mode & 0o7777) for f in (exr, png)] == ["0o640", "0o640"]
    os.chmod(exr, 0o604)  # the API's writers too
    hr.write_exr(noise_image(4, 4), str(exr))
    assert oct(exr.stat().st_mode & 0o7777) == "0o604"
    # New files: 0666 minus the umask, as before.
    new = tmp_path / "new"
    old_umask = os.umask(0o027)
    try:
        hr.render(str(path), out=str(new / "n.exr"), png=str(new / "n.png"))
    finally:
        os.umask(old_umask)
    assert [oct((new / n).stat().st_mode & 0o7777) for n in ("n.exr", "n.png")] == ["0o640", "0o640"]


# ---- defect 7: environment maps --------------------------------------------------------------------


def env_map(fill=1.0, texels=()):
    """An 8 x 4 map of ``fill`` with ``texels`` {(x, y): rgb} set."""
    img = np.full((4, 8, 3), fill, dtype=np.float32)
    for (x, y), rgb in dict(texels).items():
        img[y, x] = rgb
    return img


BAD_MAPS = [
    # A clipped sun: one +Inf texel. It rendered without its sun, exit 0.
    ("one +Inf texel", env_map(texels={(5, 2): [1.0, np.inf, 1.0]}), "texel (5, 2) G = inf is not finite"),
    ("all NaN", env_map(np.nan), "texel (0, 0) R = nan is not finite"),
    ("all negative", env_map(-1.0), "texel (0, 0) R = -1 is negative"),
    ("one negative texel", env_map(texels={(7, 3): [0.5, 0.5, -0.25]}), "texel (7, 3) B = -0.25 is negative"),
    ("one -Inf texel", env_map(texels={(0, 1): [-np.inf, 0, 0]}), "texel (0, 1) R = -inf is not finite"),
]


@pytest.mark.parametrize("label, image, problem", BAD_MAPS, ids=[m[0] for m in BAD_MAPS])
def test_a_map_with_a_non_finite_or_negative_texel_is_refused_naming_file_texel_and_value(tmp_path, label, image, problem):
    env = tmp_path / "e.exr"
    hr.write_exr(image, str(env))
    assert np.array_equal(hr.read_image(str(env)), image, equal_nan=True)  # the file holds what the test says
    s = plane_scene(width=8, height=6)
    s["environment"] = {"type": "file", "file": "e.exr"}
    path = write_scene(tmp_path, s)
    with pytest.raises(ValueError, match="^" + re.escape(f"{path}: environment: {env}: {problem}; an environment "
                                                         "map's texels must be finite radiances >= 0")):
        hr.render(str(path), out=str(tmp_path / "r.exr"))
    assert not (tmp_path / "r.exr").exists()
    if label == "one +Inf texel":  # the CLI: one line, exit 1
        r = run_cli("render", str(path), "-o", str(tmp_path / "r.exr"), "--quiet")
        one_line_error(r, "^hbrdf render: error: " + re.escape(f"{path}: environment: {env}: {problem};"))
    # hbrdf view --env reads the map through the same loader.
    with pytest.raises(ValueError, match="^" + re.escape(f"--env: environment: {env}: {problem};")):
        page_environment(environment_spec(str(env)))


def test_hbrdf_view_refuses_a_map_with_an_infinite_sun(tmp_path):
    if not os.path.exists(MODEL):
        pytest.skip(f"{MODEL} is not in this checkout")
    env = tmp_path / "sun.exr"
    hr.write_exr(env_map(texels={(2, 1): [np.inf] * 3}), str(env))
    out = tmp_path / "p.html"
    r = run_cli("view", MODEL, "--env", str(env), "--out", str(out))
    assert r.returncode != 0 and not out.exists()
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and f"{env}: texel (2, 1) R = inf is not finite" in lines[0], r.stderr


def test_a_valid_map_with_zeros_still_lights_as_before(tmp_path):
    """The rule refuses what is not a radiance; black texels are radiances (0) and stay."""
    env = tmp_path / "e.exr"
    image = env_map(L, texels={(1, 1): [0, 0, 0]})
    hr.write_exr(image, str(env))
    got = np.asarray(_core.render_environment(json.dumps({"type": "file", "file": str(env)}), str(tmp_path), "t"))
    assert np.array_equal(got, image)


# ---- defect 8: geometry float32 cannot place ------------------------------------------------------


def obj_file(path, points):
    path.write_text("".join(f"v {x!r} {y!r} {z!r}\n" for x, y, z in points) + "f 1 2 3\n")
    return path


HUGE = [
    ("plane 3e10", {"type": "plane", "center": [0, -1, 0], "normal": [0, 1, 0], "size": 3e10}, "vertex 0 (-1.5e+10, -1, 1.5e+10) "
     "has a coordinate of magnitude 1.5e+10, above the limit 212132 = 50000 x the camera's distance to its look_at point (4.24264)"),
    ("plane 1e20", {"type": "plane", "center": [0, -1, 0], "normal": [0, 1, 0], "size": 1e20},
     "has a coordinate of magnitude 5e+19, above the limit 1e+12 for any coordinate"),
    ("sphere 1e20", {"type": "sphere", "center": [0, -1e20, 0], "radius": 1e20},
     "the sphere (center (0, -1e+20, 0), radius 1e+20) has a coordinate of magnitude 2e+20, above the limit 1e+12 for any "
     "coordinate"),
    ("mesh 1e20..3e38", {"type": "mesh", "file": "huge.obj"},
     "vertex 0 (1e+20, 0, 0) has a coordinate of magnitude 1e+20, above the limit 1e+12 for any coordinate"),
]


@pytest.mark.parametrize("label, obj, problem", HUGE, ids=[h[0] for h in HUGE])
def test_geometry_float32_cannot_place_is_refused_naming_the_object(tmp_path, label, obj, problem):
    obj_file(tmp_path / "huge.obj", [(1e20, 0, 0), (3e38, 0, 0), (0, 3e38, 1e20)])
    s = plane_scene(width=8, height=6)
    s["objects"].append(dict(obj, material="m"))
    path = write_scene(tmp_path, s)
    expected = (re.escape(f"{path}: objects[1]: ") + ".*" + re.escape(problem) +
                re.escape('; float32 places points that far out too coarsely (docs/RENDERING.md, "Limits")') + "$")
    with pytest.raises(ValueError, match="^" + expected):
        hr.render(str(path), out=str(tmp_path / "r.exr"))
    assert not (tmp_path / "r.exr").exists()
    if label == "plane 3e10":  # the CLI: one line, exit 1
        one_line_error(run_cli("render", str(path), "-o", str(tmp_path / "r.exr"), "--quiet"),
                       "^hbrdf render: error: " + expected)


@pytest.mark.parametrize("camera, problem", [
    ({"position": [0, 0, 2e12], "look_at": [0, 0, 0]}, "camera: position has a coordinate of magnitude 2e+12, above the limit 1e+12"),
    ({"position": [0, 0, 1e4], "look_at": [0, 0, 1e4 - 4]},
     "camera: position has a coordinate of magnitude 10000, above the limit 2000 = 500 x its distance to look_at (4)"),
])
def test_a_camera_float32_cannot_place_is_refused(tmp_path, camera, problem):
    s = plane_scene(width=8, height=6)
    s["camera"].update(camera)
    with pytest.raises(ValueError, match="^<scene dict>: " + re.escape(problem)):
        hr.render(s)


@pytest.mark.parametrize("size, scale", [(8.0, 1.0), (1e5, 1.0), (2e4, 1e6)])
def test_planes_inside_the_limits_render_exactly(size, scale):
    """kd L under every plane pixel, L above: exact with cosine sampling and one bounce. The last case is
    a plane of 2e10 seen from 4.2e6 (inside the limits at that scale): its edges' cross product overflowed
    float, the normal became 0 and the plane rendered black with exit 0."""
    img, _ = hr.render(plane_scene(size, scale))
    lower, upper = img[img.shape[0] - 4:], img[:3]
    assert np.allclose(lower, KD * L, rtol=1e-6, atol=0) and np.allclose(upper, L, rtol=1e-6, atol=0), (
        float(lower.min()), float(lower.max()), float(upper.min()))


# ---- defect 9: deep scene dicts ----------------------------------------------------------------------


def nested(depth, leaf=0):
    value = leaf
    for i in range(depth):
        value = [value] if i % 2 else {"k": value}
    return value


@pytest.mark.parametrize("where", ["description", "objects"])
def test_a_scene_dict_nested_10000_deep_is_the_files_one_line_error(where):
    s = plane_scene(width=8, height=6)
    s[where] = nested(10_000)
    with pytest.raises(InputFileError) as err:
        hr.render(s)
    assert str(err.value) == "<scene dict>: scene dict: nested deeper than 64 levels"


def test_a_scene_dict_that_contains_itself_is_refused_not_looped():
    s = plane_scene(width=8, height=6)
    s["description"] = s
    with pytest.raises(InputFileError, match="nested deeper than 64 levels"):
        hr.render(s)


def test_the_dict_bound_is_the_files_bound(tmp_path):
    """The same document: 64 levels pass the depth check as dict and as file, 65 fail both."""
    for depth, ok in ((64, True), (65, False)):
        s = plane_scene(width=8, height=6)
        s["description"] = nested(depth - 1)  # the scene itself is level 1
        path = write_scene(tmp_path, s, f"d{depth}.json")
        for scene in (s, str(path)):
            try:
                hr.load_scene_dict(scene)
                passed = True
            except InputFileError as exc:
                assert "nested deeper than 64 levels" in str(exc)
                passed = False
            assert passed == ok, (depth, type(scene))
