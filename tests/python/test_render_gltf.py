"""The tracer's glTF objects fed by a second writer (trimesh), through hybridbrdf.render.render
(docs/RENDERING.md, "glTF objects"): an unbound glTF material renders as the f_a of the stated
mapping, computed here in float64 from the material's factors, per pixel against the scene
format's own plane; in the direct-light comparison mode the image does not depend on the seed."""

import json

import numpy as np
import pytest

from hybridbrdf.render import render

trimesh = pytest.importorskip("trimesh")

BASE, METALLIC, ROUGHNESS = (0.8, 0.4, 0.2), 0.25, 0.6


def mapping(base, metallic, roughness, ior=1.5, specular=1.0, specular_color=(1.0, 1.0, 1.0)):
    """docs/RENDERING.md's glTF -> f_a mapping, float64."""
    base = np.asarray(base, np.float64)
    f0_ior = ((ior - 1.0) / (ior + 1.0)) ** 2
    dielectric = np.minimum(f0_ior * np.asarray(specular_color), 1.0) * specular
    f0 = np.clip(dielectric * (1.0 - metallic) + base * metallic, 0.0, 1.0)
    eta = np.clip((1.0 + np.sqrt(f0)) / (1.0 - np.sqrt(f0)), 1.0, 10.0)
    alpha = max(roughness * roughness, 1e-4)
    return {"kd": (base * (1.0 - metallic)).tolist(), "eta": eta.tolist(), "alpha": [alpha, alpha]}


def scene(obj, tmp_path, seed=0):
    return {"camera": {"position": [0.4, 3.0, 2.5], "look_at": [0, 0, 0], "fov_deg": 50, "width": 24, "height": 18},
            "environment": {"type": "constant", "radiance": 0},
            "lights": [{"type": "point", "position": [0.3, 1.5, -0.2], "intensity": [2, 3, 4]},
                       {"type": "directional", "direction": [1, 2, -0.5], "irradiance": [1.5, 0.5, 2]}],
            "objects": [obj], "max_depth": 1, "spp": 1, "pixel_jitter": False, "shadows": False,
            "seed": seed, "threads": 1}


@pytest.fixture(scope="module")
def plane_glb(tmp_path_factory):
    """The scene format's plane of size 4 facing +y (make_plane's corners, triangles and uvs),
    written by trimesh with a metallic-roughness material."""
    path = tmp_path_factory.mktemp("gltf") / "plane.glb"
    mesh = trimesh.Trimesh(vertices=[[-2, 0, 2], [2, 0, 2], [2, 0, -2], [-2, 0, -2]], faces=[[0, 1, 2], [0, 2, 3]],
                           vertex_normals=np.tile([0.0, 1.0, 0.0], (4, 1)), process=False)
    material = trimesh.visual.material.PBRMaterial(name="Paint", baseColorFactor=[int(255 * c) for c in BASE] + [255],
                                                   metallicFactor=METALLIC, roughnessFactor=ROUGHNESS)
    mesh.visual = trimesh.visual.TextureVisuals(uv=[[0, 1], [1, 1], [1, 0], [0, 0]], material=material)
    mesh.export(path)
    return path


def test_unbound_material_renders_as_the_mapping(plane_glb, tmp_path):
    img, _ = render(scene({"type": "gltf", "file": str(plane_glb)}, tmp_path))
    base = [round(255 * c) / 255 for c in BASE]  # the factors as trimesh stored them
    reference, _ = render(scene({"type": "plane", "center": [0, 0, 0], "normal": [0, 1, 0], "tangent": [1, 0, 0],
                                 "size": 4, "material": {"type": "analytic", **mapping(base, METALLIC, ROUGHNESS)}},
                                tmp_path))
    lit = reference > 0
    assert lit.mean() > 0.5
    np.testing.assert_allclose(img, reference, rtol=1e-5, atol=1e-7)
    # The mapping is not the identity: a plain dielectric of that base colour renders otherwise.
    other, _ = render(scene({"type": "plane", "center": [0, 0, 0], "normal": [0, 1, 0], "tangent": [1, 0, 0], "size": 4,
                             "material": {"type": "analytic", **mapping(base, 0.0, ROUGHNESS)}}, tmp_path))
    assert np.abs(other - reference).max() > 1e-2


def test_direct_light_mode_is_deterministic(plane_glb, tmp_path):
    a, _ = render(scene({"type": "gltf", "file": str(plane_glb)}, tmp_path, seed=1))
    b, _ = render(scene({"type": "gltf", "file": str(plane_glb)}, tmp_path, seed=99))
    assert np.array_equal(a, b)
    c, _ = render(scene({"type": "gltf", "file": str(plane_glb)}, tmp_path, seed=99), pixel_jitter=True)
    assert not np.array_equal(a, c)


def test_bad_bind_is_one_line(plane_glb, tmp_path):
    s = scene({"type": "gltf", "file": str(plane_glb), "bind": {"Nope": "x"}}, tmp_path)
    path = tmp_path / "s.json"
    path.write_text(json.dumps(s))
    with pytest.raises(Exception) as info:
        render(str(path))
    assert str(info.value) == f"{path}: objects[0].bind.Nope: the asset has no material named 'Nope' (it has 'Paint')"
