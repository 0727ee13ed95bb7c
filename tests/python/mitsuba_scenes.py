"""The scene both renderers draw in the Mitsuba plugin's tests and bench (tests/python and
bench/mitsuba_plugin.py): a sphere of a model material under a smooth environment map with a
blurred sun, in hybridbrdf's scene format and as a Mitsuba 3 dict built from the same numbers.

The two agree on every convention that matters, each checked by the render comparison:
- the environment: both map a direction d to (u, v) = (atan2(d.x, -d.z) / 2 pi, acos(d.y) / pi);
  hybridbrdf looks texels up nearest, Mitsuba bilinearly, so the map is smooth (the sun is a
  Gaussian of several texels);
- the sphere's shading frame: hybridbrdf's tangent is d p / d phi about -y, (-n.z, 0, n.x);
  Mitsuba's is d p / d u of its sphere, whose local z this rotation (+90 degrees about x) takes to -y;
- depth: hybridbrdf's max_depth counts surface interactions (1 = direct lighting), Mitsuba's
  counts path segments (2 = direct lighting);
- the camera: a pinhole, full field of view, square image (Mitsuba's fov axis does not matter),
  one-pixel box filter.
"""

import numpy as np

SUN_THETA_DEG, SUN_PHI_DEG, SUN_SIGMA_DEG = 50.0, 35.0, 6.0


def environment_map(width=512, height=256) -> np.ndarray:
    """(height, width, 3) float32 radiance: a blue-to-white sky gradient, a darker ground and a
    Gaussian sun at (SUN_THETA_DEG from +y, SUN_PHI_DEG from -z toward +x)."""
    v = (np.arange(height) + 0.5) / height
    u = (np.arange(width) + 0.5) / width
    theta, phi = np.meshgrid(v * np.pi, u * 2 * np.pi, indexing="ij")
    d = np.stack([np.sin(theta) * np.sin(phi), np.cos(theta), -np.sin(theta) * np.cos(phi)], axis=-1)
    st, sp = np.radians(SUN_THETA_DEG), np.radians(SUN_PHI_DEG)
    sun_dir = np.array([np.sin(st) * np.sin(sp), np.cos(st), -np.sin(st) * np.cos(sp)])
    angle = np.arccos(np.clip(d @ sun_dir, -1.0, 1.0))
    sun = 40.0 * np.exp(-0.5 * (angle / np.radians(SUN_SIGMA_DEG)) ** 2)
    up = np.clip(d[..., 1], 0.0, 1.0)[..., None]
    sky = (1 - up) * np.array([0.9, 0.9, 0.95]) + up * np.array([0.35, 0.5, 0.9])
    ground = np.array([0.25, 0.22, 0.2])
    env = np.where(d[..., 1:2] > 0, sky, ground) + sun[..., None] * np.array([1.0, 0.95, 0.85])
    return env.astype(np.float32)


CAMERA = dict(position=[0.0, 0.0, 3.2], look_at=[0.0, 0.0, 0.0], up=[0.0, 1.0, 0.0], fov_deg=40.0)


def hbrdf_scene(env_file: str, model_file: str, material: str, size: int, spp: int, seed: int,
                sampler: str = "mis") -> dict:
    return {"camera": dict(CAMERA, width=size, height=size),
            "environment": {"type": "file", "file": env_file},
            "materials": {"m": {"type": "model", "file": model_file, "material": material}},
            "objects": [{"type": "sphere", "center": [0, 0, 0], "radius": 1, "material": "m"}],
            "spp": spp, "max_depth": 1, "sampler": sampler, "nee": True, "seed": seed, "threads": 0}


def mitsuba_scene(mi, env_file: str, bsdf: dict, size: int, spp: int) -> dict:
    return {"type": "scene",
            "integrator": {"type": "path", "max_depth": 2},
            "sensor": {"type": "perspective", "fov": CAMERA["fov_deg"],
                       "to_world": mi.ScalarTransform4f().look_at(origin=CAMERA["position"], target=CAMERA["look_at"],
                                                                  up=CAMERA["up"]),
                       "film": {"type": "hdrfilm", "width": size, "height": size, "rfilter": {"type": "box"}},
                       "sampler": {"type": "independent", "sample_count": spp}},
            "env": {"type": "envmap", "filename": env_file},
            "sphere": {"type": "sphere", "to_world": mi.ScalarTransform4f().rotate([1, 0, 0], 90), "bsdf": bsdf}}


def block_stats(img: np.ndarray, mask: np.ndarray, block: int):
    """Per block x block tile with at least half its pixels in the mask: the mean RGB over the
    masked pixels and their count: ((tiles, 3), (tiles,))."""
    h, w, _ = img.shape
    means, counts = [], []
    for y in range(0, h - block + 1, block):
        for x in range(0, w - block + 1, block):
            m = mask[y:y + block, x:x + block]
            if m.mean() >= 0.5:
                means.append(img[y:y + block, x:x + block][m].mean(axis=0))
                counts.append(int(m.sum()))
    return np.array(means), np.array(counts)


def agreement(a1, a2, b1, b2, mask, block=8):
    """Tile-wise z scores of renderer A (two seeds) against renderer B (two seeds). Each pixel's
    noise variance is estimated from its two seeds, (x1 - x2)^2 / 2, so the variance of a tile's
    two-seed average is mean((x1 - x2)^2) / (4 n) over its n pixels (n - 1 >= 31 degrees of
    freedom per renderer: z is nearly normal). Returns (z (tiles, 3), A's tile means, B's)."""
    ma, n = block_stats((a1 + a2) / 2, mask, block)
    mb, _ = block_stats((b1 + b2) / 2, mask, block)
    va, _ = block_stats((a1 - a2) ** 2, mask, block)
    vb, _ = block_stats((b1 - b2) ** 2, mask, block)
    var = (va + vb) / (4.0 * n[:, None])
    return (ma - mb) / np.sqrt(np.maximum(var, 1e-30)), ma, mb
