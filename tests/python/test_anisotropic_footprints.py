"""Anisotropic texture footprints in the tracer (docs/RENDERING.md, "Anisotropic footprints"): the
camera ray's pixel footprint on the surface in uv (ray differentials) read by probes along its
major axis at the minor axis' level of detail, centred on the pixel.

The reference is independent of the tracer's lookup: the box filter of the level-0 texture over
each pixel's preimage, supersampled in float64 NumPy (rays through a grid of points of the pixel,
their hits on the plane, the bilinear texture there written out here), not a mip chain.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import hybridbrdf as hb
from hybridbrdf.svbrdf import SVBRDF

from helpers import saved_random_model

FOV, WIDTH, HEIGHT = 40.0, 48, 36
SIZE, SQUARE = 256, 8
LOW, HIGH = 0.1, 0.8  # the checkerboard's albedos


@pytest.fixture(scope="module")
def model(tmp_path_factory):
    _, m = saved_random_model(tmp_path_factory.mktemp("aniso"), "hybrid")
    return m


def _checker_kd():
    ys, xs = np.mgrid[0:SIZE, 0:SIZE]
    odd = ((xs // SQUARE + ys // SQUARE) % 2).astype(np.float64)
    return LOW + (HIGH - LOW) * odd


@pytest.fixture(scope="module")
def checker(model, tmp_path_factory):
    """One layer, Fresnel off (an eta map of 1: f_a = kd / pi), its kd a checkerboard of 8-texel
    squares, with its mip chain: under a white sky by cosine sampling a sample returns its kd."""
    folder = tmp_path_factory.mktemp("checker") / "checker"
    kd = np.repeat(_checker_kd()[..., None], 3, axis=2).astype(np.float32)
    maps = [{"kd": kd, "eta": np.ones((SIZE, SIZE, 3), np.float32)}]
    SVBRDF(model, ["mat-0"], (SIZE, SIZE), maps=maps).with_mips().save(folder, format="exr")
    return folder


def _camera(position, look_at):
    return {"position": list(position), "look_at": list(look_at), "up": [0, 1, 0], "fov_deg": FOV,
            "width": WIDTH, "height": HEIGHT}


def _scene(folder, camera, plane_size, **settings):
    base = {"camera": camera, "environment": {"type": "constant", "radiance": [1, 1, 1]},
            "materials": {"tex": {"type": "textured", "svbrdf": str(folder), "evaluate": "analytic"}},
            "objects": [{"type": "plane", "center": [0, 0, 0], "normal": [0, 1, 0], "tangent": [1, 0, 0],
                         "size": plane_size, "material": "tex"}],
            "spp": 1, "max_depth": 1, "nee": False, "sampler": "cosine", "seed": 3, "threads": 1}
    base.update(settings)
    return base


def _bilinear(tex, u, v):
    """The level-0 map at (u, v), repeat addressing: texel (i, j) centred at ((i + 0.5) / W, (j + 0.5) / H)."""
    h, w = tex.shape
    x, y = u * w - 0.5, v * h - 0.5
    x0, y0 = np.floor(x), np.floor(y)
    fx, fy = x - x0, y - y0
    i0, j0 = x0.astype(int) % w, y0.astype(int) % h
    i1, j1 = (i0 + 1) % w, (j0 + 1) % h
    return ((1 - fx) * (1 - fy) * tex[j0, i0] + fx * (1 - fy) * tex[j0, i1] + (1 - fx) * fy * tex[j1, i0]
            + fx * fy * tex[j1, i1])


def _box_reference(camera, plane_size, tex, sub=24):
    """Per pixel, the mean of the bilinear texture over its preimage on the plane y = 0 (uv =
    0.5 + x / size, 0.5 + z / size: make_plane with tangent +x, bitangent n x t = -z), from a sub x sub
    grid of rays; NaN where a ray misses the plane."""
    pos, look = np.asarray(camera["position"], float), np.asarray(camera["look_at"], float)
    fwd = (look - pos) / np.linalg.norm(look - pos)
    right = np.cross(fwd, [0.0, 1.0, 0.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, fwd)
    tan_half = math.tan(math.radians(FOV) / 2)
    o = (np.arange(sub) + 0.5) / sub
    ys, xs = np.mgrid[0:HEIGHT, 0:WIDTH]
    px = (xs[..., None, None] + o[None, None, None, :]).repeat(sub, axis=2)
    py = (ys[..., None, None] + o[None, None, :, None]).repeat(sub, axis=3)
    sx = (2 * px / WIDTH - 1) * tan_half * WIDTH / HEIGHT
    sy = (1 - 2 * py / HEIGHT) * tan_half
    d = fwd + right * sx[..., None] + up * sy[..., None]
    with np.errstate(divide="ignore", invalid="ignore"):
        t = -pos[1] / d[..., 1]
    hit = pos + t[..., None] * d
    u, v = 0.5 + hit[..., 0] / plane_size, 0.5 + hit[..., 2] / plane_size
    inside = (t > 0) & (np.abs(u - 0.5) < 0.5) & (np.abs(v - 0.5) < 0.5)
    value = _bilinear(tex, np.where(inside, u, 0.5), np.where(inside, v, 0.5))
    return np.where(inside.all(axis=(2, 3)), value.mean(axis=(2, 3)), np.nan)


def _relative_errors(image, reference):
    on = ~np.isnan(reference)
    d = np.abs(image[..., 0][on] - reference[on])
    return float(d.mean() / reference[on].mean()), float(np.percentile(d, 95) / reference[on].mean())


def test_anisotropic_lookup_is_the_box_filter_of_the_pixels_preimage(checker):
    """A plane seen at a grazing angle (footprints up to 50 texels long and a few wide): at 1 spp the
    anisotropic lookup (16 probes) is within 0.045 (relative MAE) and 0.16 (p95) of the texture
    averaged over each pixel's preimage; the isotropic ray cone greys the squares out across the
    view (0.22 / 0.61 measured) and fails that bound, as does no mip chain (aliasing). Seen failing
    (0.19 MAE) with the probes spread over the minor axis instead of the major one."""
    camera, plane = _camera((0, 0.6, 6), (0, 0, -4)), 16.0
    reference = _box_reference(camera, plane, _checker_kd())
    assert (~np.isnan(reference)).sum() > 0.4 * WIDTH * HEIGHT
    errors = {}
    for name, settings in {"anisotropic": {"anisotropic": 16}, "isotropic": {"anisotropic": 1},
                           "no mips": {"mip_lod": False}}.items():
        image, _ = hb.render.tracer.render(_scene(checker, camera, plane, **settings), quiet=True)
        errors[name] = _relative_errors(image, reference)
    print({k: tuple(round(x, 4) for x in v) for k, v in errors.items()})
    mae, p95 = errors["anisotropic"]
    assert mae < 0.045 and p95 < 0.16
    assert errors["isotropic"][0] > 0.045 and errors["no mips"][0] > 0.045


def test_a_constant_texture_renders_the_same_with_anisotropic_footprints(model, tmp_path):
    """No bias where the texture is constant: two layers mixed 0.3, layer 1 with constant kd and alpha
    maps and a chain; the full hybrid mixture under a sky, NEE and MIS, three bounces: anisotropic
    footprints (probes averaged by weight, alpha through sqrt) against level 0 agree to float
    rounding. Seen failing (0.23 of the brightest pixel) with the probes' weights summed, not
    averaged."""
    size = 64
    weights = np.zeros((size, size, 3), np.float32)
    weights[..., 0] = 0.3
    maps = [{}, {"kd": np.full((size, size, 3), [0.6, 0.3, 0.1], np.float32),
                 "alpha": np.full((size, size, 2), 0.2, np.float32)}]
    SVBRDF(model, ["mat-0", "mat-2"], (size, size), weights=weights, maps=maps).with_mips().save(
        tmp_path / "const", format="exr")
    scene = _scene(tmp_path / "const", _camera((0, 0.6, 6), (0, 0, -4)), 16.0,
                   environment={"type": "sky", "resolution": [64, 32]}, max_depth=3, nee=True, sampler="mis", spp=4)
    scene["materials"]["tex"]["evaluate"] = "full"
    anisotropic, _ = hb.render.tracer.render(scene, anisotropic=16, quiet=True)
    without, _ = hb.render.tracer.render(scene, mip_lod=False, quiet=True)
    assert np.abs(anisotropic - without).max() <= 1e-5 * max(1.0, float(np.abs(without).max()))


def test_magnified_texels_are_unchanged(checker):
    """Where the footprint is below a texel on both axes (one probe at lod <= 0: level 0), the
    anisotropic lookup reads level 0 at the footprint's centre: through pixel centres the render is
    the render without mips bit for bit, and at 1 spp with jitter it is that same image to 1e-3 (the
    lookup centred on the pixel: the jitter no longer reaches the texture; without mips the edges of
    the squares alias, up to 0.35 off). Seen failing with the centre offset's sign flipped."""
    camera, plane = _camera((0, 1.5, 0.3), (0, 0, 0)), 16.0  # about half a texel per pixel: magnified
    centres, _ = hb.render.tracer.render(_scene(checker, camera, plane, pixel_jitter=False, mip_lod=False), quiet=True)
    aniso_centres, _ = hb.render.tracer.render(_scene(checker, camera, plane, pixel_jitter=False), quiet=True)
    assert np.array_equal(aniso_centres, centres)
    jittered, _ = hb.render.tracer.render(_scene(checker, camera, plane), quiet=True)
    plain, _ = hb.render.tracer.render(_scene(checker, camera, plane, mip_lod=False), quiet=True)
    print(f"jittered anisotropic vs centres {np.abs(jittered - centres).max():.2e}, "
          f"without mips {np.abs(plain - centres).max():.3f}")
    assert np.abs(jittered - centres).max() < 1e-3
    assert np.abs(plain - centres).max() > 0.05
    assert np.ptp(centres) > 0.5  # the checkerboard shows
