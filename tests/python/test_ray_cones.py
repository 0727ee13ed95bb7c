"""Texture footprints in the tracer (docs/RENDERING.md, "Texture footprints"): camera rays carry
ray cones, and textured materials read their mip chains at the cone's level of detail.

The references are written out here from the scene's numbers, not taken from the tracer: the
camera's rays, their hits on the plane and the ray-cone level of detail
lod = 0.5 log2(W H uv_area / world_area) + log2(w / |n.d|), w = 2 tan(fov/2) / height x t x
max(1/8, 1/sqrt(spp)), computed in float64 NumPy.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import hybridbrdf as hb
from hybridbrdf.svbrdf import SVBRDF
from hybridbrdf.svbrdf.mips import chain_length, level_size

from helpers import saved_random_model

FOV, WIDTH, HEIGHT, SPP = 40.0, 48, 36, 16


@pytest.fixture(scope="module")
def model(tmp_path_factory):
    _, m = saved_random_model(tmp_path_factory.mktemp("cones"), "hybrid")
    return m


def _camera(position, look_at):
    return {"position": list(position), "look_at": list(look_at), "up": [0, 1, 0], "fov_deg": FOV,
            "width": WIDTH, "height": HEIGHT}


def _scene(folder, camera, plane_size, plane_center=(0, 0, 0), evaluate="full", **settings):
    """A textured plane y = 0 (normal +y) under a constant white environment, direct light by
    cosine BSDF sampling alone: a Lambert texel of albedo kd returns kd exactly, per sample. The
    ray cone's isotropic lookup ("anisotropic": 1; the anisotropic footprints' tests are
    test_anisotropic_footprints.py)."""
    base = {"camera": camera, "environment": {"type": "constant", "radiance": [1, 1, 1]},
            "materials": {"tex": {"type": "textured", "svbrdf": str(folder), "evaluate": evaluate}},
            "objects": [{"type": "plane", "center": list(plane_center), "normal": [0, 1, 0], "tangent": [1, 0, 0],
                         "size": plane_size, "material": "tex"}],
            "spp": SPP, "max_depth": 1, "nee": False, "sampler": "cosine", "seed": 7, "threads": 1, "anisotropic": 1}
    base.update(settings)
    return base


def _plane_lod(camera, plane_size, plane_center, texels, px, py, spp=SPP):
    """Ray-cone lod at image points (px, py) of rays hitting the plane y = 0, by hand; NaN off the plane."""
    pos, look = np.asarray(camera["position"], float), np.asarray(camera["look_at"], float)
    fwd = (look - pos) / np.linalg.norm(look - pos)
    right = np.cross(fwd, [0.0, 1.0, 0.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, fwd)
    tan_half = math.tan(math.radians(FOV) / 2)
    sx = (2 * px / WIDTH - 1) * tan_half * WIDTH / HEIGHT
    sy = (1 - 2 * py / HEIGHT) * tan_half
    d = fwd + right * sx[..., None] + up * sy[..., None]
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = -pos[1] / d[..., 1]                              # the plane y = 0
    hit = pos + t[..., None] * d
    half = plane_size / 2
    inside = (t > 0) & (np.abs(hit[..., 0] - plane_center[0]) < half) & (np.abs(hit[..., 2] - plane_center[2]) < half)
    width = 2 * tan_half / HEIGHT * t * max(0.125, 1 / math.sqrt(spp))   # the cone's width at the hit
    cos_nd = np.abs(d[..., 1])
    uv_per_world = 1.0 / plane_size                           # the plane's uv spans [0, 1] over its size
    with np.errstate(divide="ignore", invalid="ignore"):
        lod = 0.5 * math.log2(texels[0] * texels[1]) + np.log2(uv_per_world * width / cos_nd)
    return np.where(inside, lod, np.nan)


def _pixel_lods(camera, plane_size, plane_center, texels, sub=8):
    """(HEIGHT, WIDTH, sub*sub) lods at a sub x sub grid inside every pixel (the box the tracer jitters over)."""
    o = (np.arange(sub) + 0.5) / sub
    ys, xs = np.mgrid[0:HEIGHT, 0:WIDTH]
    px = xs[..., None, None] + o[None, None, None, :]
    py = ys[..., None, None] + o[None, None, :, None]
    px, py = np.broadcast_arrays(px, py)
    return _plane_lod(camera, plane_size, plane_center, texels, px.reshape(HEIGHT, WIDTH, -1), py.reshape(HEIGHT, WIDTH, -1))


def _lambert_ramp(model, folder, size):
    """One layer, Fresnel off (an eta map of 1: f_a = kd / pi) and a kd map constant on every level,
    level L's kd = 0.05 + 0.08 L: trilinear lookup makes kd = 0.05 + 0.08 clamp(lod, 0, last) exactly."""
    levels = chain_length((size, size))

    def maps(level):
        w, h = level_size((size, size), level)
        return [{"kd": np.full((h, w, 3), 0.05 + 0.08 * level, np.float32), "eta": np.ones((h, w, 3), np.float32)}]

    sv = SVBRDF(model, ["mat-0"], (size, size), maps=maps(0), mips=[(None, maps(L)) for L in range(1, levels)])
    sv.save(folder, format="exr")
    return levels


def test_camera_ray_lod_on_a_slanted_plane_is_the_ray_cone_value(model, tmp_path):
    """Every pixel of a plane receding from the camera reads the chain at the ray-cone lod computed
    by hand (pixel mean over the jitter box). Seen to fail without the slant term 1/|n.d| (lod off by
    0.88 on average, 3.7 at most)."""
    size, plane, center = 256, 16.0, (0.0, 0.0, -6.0)
    levels = _lambert_ramp(model, tmp_path / "ramp", size)
    camera = _camera((0, 1, 2), (0, 0, -6))
    image, _ = hb.render.tracer.render(_scene(tmp_path / "ramp", camera, plane, center, evaluate="analytic"))
    lods = _pixel_lods(camera, plane, center, (size, size))
    on_plane = ~np.isnan(lods).any(axis=2)
    expected = np.clip(lods[on_plane], 0, levels - 1).mean(axis=1)  # kd is linear in the clamped lod
    measured = (image[on_plane].mean(axis=1) - 0.05) / 0.08
    assert on_plane.sum() > 0.5 * WIDTH * HEIGHT
    assert expected.min() < 0.5 and expected.max() > 4  # magnified near the camera, minified far away
    # The tracer's 16 jittered samples against the grid's mean: a pixel whose lod spans r has a
    # standard error of r / sqrt(12 x 16); allow 4.2 of them, plus float32 rounding.
    spread = np.ptp(np.clip(lods[on_plane], 0, levels - 1), axis=1)
    error = np.abs(measured - expected)
    print(f"lod error: mean {error.mean():.4f}, max {error.max():.4f}; worst over 1.2 r / 4: {(error / (0.01 + 0.3 * spread)).max():.2f}")
    assert np.all(error < 0.01 + 1.2 * spread / math.sqrt(SPP))
    assert error.mean() < 0.02


def test_mip_lod_off_reads_level_0(model, tmp_path):
    """"mip_lod": false renders the level-0 albedo everywhere (the flag reaches the tracer)."""
    _lambert_ramp(model, tmp_path / "ramp", 64)
    camera = _camera((0, 1, 2), (0, 0, -6))
    image, _ = hb.render.tracer.render(_scene(tmp_path / "ramp", camera, 16.0, (0, 0, -6), evaluate="analytic"),
                                       mip_lod=False)
    lods = _pixel_lods(camera, 16.0, (0, 0, -6), (64, 64), sub=2)
    on_plane = ~np.isnan(lods).any(axis=2)
    assert np.abs(image[on_plane] - 0.05).max() < 1e-6


def _constant_chain(model, folder, size=64):
    """Two layers mixed 0.3 everywhere, layer 1 with constant kd and alpha maps, with its mip chain:
    every level holds the same values."""
    weights = np.zeros((size, size, 3), np.float32)
    weights[..., 0] = 0.3
    maps = [{}, {"kd": np.full((size, size, 3), [0.6, 0.3, 0.1], np.float32),
                 "alpha": np.full((size, size, 2), 0.2, np.float32)}]
    SVBRDF(model, ["mat-0", "mat-2"], (size, size), weights=weights, maps=maps).with_mips().save(folder, format="exr")


def test_a_constant_texture_renders_the_same_with_and_without_lod(model, tmp_path):
    """No bias where the texture is constant: the full hybrid mixture under a sky, NEE and MIS, three
    bounces, with footprints and without, agree to float rounding (the trilinear mix of equal
    values). Seen to fail (2.4, 64% of the brightest pixel) with the trilinear lookup's two level
    weights summing to 1.5 instead of 1."""
    _constant_chain(model, tmp_path / "const")
    scene = _scene(tmp_path / "const", _camera((0, 1, 2), (0, 0, -6)), 16.0, (0, 0, -6),
                   environment={"type": "sky", "resolution": [64, 32]}, max_depth=3, nee=True, sampler="mis", spp=4)
    with_lod, _ = hb.render.tracer.render(scene)
    without, _ = hb.render.tracer.render(scene, mip_lod=False)
    assert np.abs(with_lod - without).max() <= 1e-5 * max(1.0, float(np.abs(without).max()))


def test_a_magnified_texture_renders_as_without_mips(model, tmp_path):
    """Where the footprint is below a texel (lod <= 0 at every sample, checked by hand here) the render
    with mips is the render without, bit for bit, on a checkerboard of two materials. The plane's
    largest lod is -0.38: seen to fail with the cone twice as wide (+1)."""
    size = 128
    weights = np.zeros((size, size, 3), np.float32)
    ys, xs = np.mgrid[0:size, 0:size]
    weights[..., 0] = ((xs // 8 + ys // 8) % 2).astype(np.float32)
    SVBRDF(model, ["mat-0", "mat-2"], (size, size), weights=weights).with_mips().save(tmp_path / "check", format="png")
    camera, plane = _camera((0, 3, 0.5), (0, 0, 0)), 4.0
    lods = _pixel_lods(camera, plane, (0, 0, 0), (size, size), sub=4)
    assert -1.0 < np.nanmax(lods) < -0.3 and np.isnan(lods).sum() == 0  # the plane fills the image, magnified
    scene = _scene(tmp_path / "check", camera, plane, environment={"type": "sky", "resolution": [64, 32]},
                   max_depth=2, nee=True, sampler="mis", spp=SPP)
    with_lod, _ = hb.render.tracer.render(scene)
    without, _ = hb.render.tracer.render(scene, mip_lod=False)
    assert np.array_equal(with_lod, without)
    assert np.ptp(without) > 0.05  # the checkerboard shows
