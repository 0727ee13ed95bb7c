"""A capture rig (docs/ACQUISITION.md): pinhole cameras and point lights above a flat sample, and
the photographs taken as (camera, light) pairs.

The sample lies in the plane z = 0, centred at the origin, its normal +z, its tangent +x: the
sample's shading frame is the world frame (docs/CONVENTIONS.md). It covers ``sample_extent``
(width along x, height along y, in the rig's length unit); uv (0, 0) is its corner at (-w/2, +h/2):
u grows with x, v shrinks with y (glTF's v down, as a photograph from above shows it).

    {"format_version": 1, "image_size": [W, H], "sample_extent": [w, h],
     "cameras": [{"position": [x, y, z], "look_at": [x, y, z], "up": [x, y, z], "fov_deg": 40}],
     "lights":  [{"position": [x, y, z], "intensity": [r, g, b]}],
     "shots":   [{"camera": 0, "light": 0, "image": "photo_000.exr"}]}

A light's intensity is radiant intensity (power per steradian, per channel): a surface point at
distance d receives irradiance intensity * cos(theta_i) / d^2. Every key is checked on load and a
problem is one line naming the file and the key (``rig.json: lights[1].intensity: ...``).
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from typing import Any, Dict, List, Optional, Sequence

import numpy as np

from hybridbrdf.acquire.sizes import MAX_ITEMS, MAX_SIDE
from hybridbrdf.errors import InputFileError
from hybridbrdf.inputs import loads_json, read_input_text

FORMAT_VERSION = 1
#: Largest rig file read (a rig of thousands of shots is well under this).
MAX_RIG_BYTES = 16 << 20

TOP_KEYS = ("format_version", "image_size", "sample_extent", "cameras", "lights", "shots")
CAMERA_KEYS = ("position", "look_at", "up", "fov_deg")
LIGHT_KEYS = ("position", "intensity")
#: Photograph files a shot may name (hybridbrdf.acquire.photographs decodes them).
PHOTO_EXTENSIONS = (".exr", ".png", ".tif", ".tiff")
SHOT_KEYS = ("camera", "light", "image")


class RigError(InputFileError):
    """A rig description that cannot be used: ``"<file>: <key>: <problem>"``, one line."""


@dataclass
class Camera:
    """A pinhole camera at ``position`` looking at ``look_at``; ``up`` fixes the roll;
    ``fov_deg`` is the vertical field of view."""
    position: np.ndarray
    look_at: np.ndarray
    up: np.ndarray
    fov_deg: float

    def basis(self):
        """(right, up, forward) unit vectors of the image: x to the right, y up, looking forward."""
        forward = _unit(self.look_at - self.position)
        right = _unit(np.cross(forward, self.up))
        return right, np.cross(right, forward), forward


@dataclass
class Light:
    """An isotropic point light: ``intensity`` RGB radiant intensity at ``position``."""
    position: np.ndarray
    intensity: np.ndarray


@dataclass
class Shot:
    """One photograph: camera and light indices, and its image file (relative to the rig's folder)."""
    camera: int
    light: int
    image: str


@dataclass
class Rig:
    """Cameras, lights, shots, the photographs' size (W, H) and the sample's extent (w, h)."""
    image_size: tuple
    sample_extent: tuple
    cameras: List[Camera]
    lights: List[Light]
    shots: List[Shot] = field(default_factory=list)

    def to_dict(self) -> Dict[str, Any]:
        """The rig as the JSON document :func:`rig_from_dict` reads."""
        return {"format_version": FORMAT_VERSION, "image_size": [int(v) for v in self.image_size],
                "sample_extent": [float(v) for v in self.sample_extent],
                "cameras": [{"position": c.position.tolist(), "look_at": c.look_at.tolist(), "up": c.up.tolist(),
                             "fov_deg": float(c.fov_deg)} for c in self.cameras],
                "lights": [{"position": l.position.tolist(), "intensity": l.intensity.tolist()} for l in self.lights],
                "shots": [{"camera": s.camera, "light": s.light, "image": s.image} for s in self.shots]}


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v)


def photo_name(k: int) -> str:
    """The default file name of photograph ``k``."""
    return f"photo_{k:03d}.exr"


def _no_constant(name: str):
    raise ValueError(f"{name} is not a JSON number")


def load_rig(path) -> Rig:
    """Read and validate the rig file ``path`` (:class:`RigError` naming the file and key)."""
    path = os.fspath(path)
    text = read_input_text(path, "rig file", MAX_RIG_BYTES, RigError)
    data = loads_json(text, path, "rig file", RigError, parse_constant=_no_constant)
    return rig_from_dict(data, path)


class _RigReader:
    """The checks of one rig document, each failing with a :class:`RigError` that names the file
    (``path``) and the key."""

    def __init__(self, data: Any, path: str):
        self.data, self.path = data, path

    def fail(self, key: str, problem: str):
        raise RigError(self.path, f"{key}: {problem}")

    def keys(self, obj, where: str, allowed: Sequence[str], required: Sequence[str]):
        if not isinstance(obj, dict):
            self.fail(where or "the rig", "must be a JSON object")
        for k in obj:
            if k not in allowed:
                self.fail(f"{where}.{k}" if where else k, f"unknown key (known: {', '.join(allowed)})")
        for k in required:
            if k not in obj:
                self.fail(f"{where}.{k}" if where else k, "missing")

    def number(self, v, key: str, lo: float = -math.inf, hi: float = math.inf, open_lo: bool = False) -> float:
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            self.fail(key, f"must be a finite number, got {v!r}")
        if v < lo or v > hi or (open_lo and v == lo):
            self.fail(key, f"must lie in {'(' if open_lo else '['}{lo:g}, {hi:g}], got {v!r}")
        return float(v)

    def vector(self, v, key: str, n: int = 3, lo: float = -math.inf) -> np.ndarray:
        if not isinstance(v, list) or len(v) != n:
            self.fail(key, f"must be a list of {n} numbers, got {v!r}")
        return np.array([self.number(x, f"{key}[{i}]", lo) for i, x in enumerate(v)], dtype=np.float64)

    def index(self, v, key: str, count: int) -> int:
        if isinstance(v, bool) or not isinstance(v, int) or not 0 <= v < count:
            self.fail(key, f"must be an index 0 to {count - 1}, got {v!r}")
        return v

    def items(self, name: str, required: bool) -> list:
        v = self.data[name]
        if not isinstance(v, list):
            self.fail(name, "must be a list")
        if required and not v:
            self.fail(name, f"a rig needs at least one {name[:-1]}")
        if len(v) > MAX_ITEMS:
            self.fail(name, f"{len(v)} entries; at most {MAX_ITEMS}")
        return v

    def header(self):
        """(image_size, sample_extent) after the top-level keys and the format version."""
        data = self.data
        self.keys(data, "", TOP_KEYS, TOP_KEYS)
        if data["format_version"] != FORMAT_VERSION:
            self.fail("format_version", f"this library reads version {FORMAT_VERSION}, got {data['format_version']!r}")
        size = data["image_size"]
        if not isinstance(size, list) or len(size) != 2 or any(isinstance(s, bool) or not isinstance(s, int)
                                                               or not 1 <= s <= MAX_SIDE for s in size):
            self.fail("image_size", f"must be [width, height], whole numbers 1 to {MAX_SIDE}, got {size!r}")
        extent = self.vector(data["sample_extent"], "sample_extent", 2)
        if (extent <= 0).any():
            self.fail("sample_extent", f"must be positive, got {extent.tolist()}")
        return (size[0], size[1]), (float(extent[0]), float(extent[1]))

    def cameras(self) -> List[Camera]:
        cameras = []
        for i, c in enumerate(self.items("cameras", True)):
            where = f"cameras[{i}]"
            self.keys(c, where, CAMERA_KEYS, CAMERA_KEYS)
            cam = Camera(self.vector(c["position"], f"{where}.position"), self.vector(c["look_at"], f"{where}.look_at"),
                         self.vector(c["up"], f"{where}.up"),
                         self.number(c["fov_deg"], f"{where}.fov_deg", 0, 179, open_lo=True))
            if cam.position[2] <= 0:
                self.fail(f"{where}.position", f"must lie above the sample plane (z > 0), got {cam.position.tolist()}")
            forward = cam.look_at - cam.position
            if np.linalg.norm(forward) < 1e-9:
                self.fail(f"{where}.look_at", "equals the position")
            if np.linalg.norm(np.cross(_unit(forward), cam.up)) < 1e-6:
                self.fail(f"{where}.up", "is zero or parallel to the viewing direction")
            cameras.append(cam)
        return cameras

    def lights(self) -> List[Light]:
        lights = []
        for i, l in enumerate(self.items("lights", True)):
            where = f"lights[{i}]"
            self.keys(l, where, LIGHT_KEYS, LIGHT_KEYS)
            light = Light(self.vector(l["position"], f"{where}.position"),
                          self.vector(l["intensity"], f"{where}.intensity", lo=0))
            if light.position[2] <= 0:
                self.fail(f"{where}.position", f"must lie above the sample plane (z > 0), got {light.position.tolist()}")
            lights.append(light)
        return lights

    def shots(self, n_cameras: int, n_lights: int) -> List[Shot]:
        shots, names = [], set()
        for i, s in enumerate(self.items("shots", True)):
            where = f"shots[{i}]"
            self.keys(s, where, SHOT_KEYS, ("camera", "light"))
            image = s.get("image", photo_name(i))
            if not isinstance(image, str) or not image or os.path.basename(image) != image or image in (".", "..") \
                    or not image.lower().endswith(PHOTO_EXTENSIONS):
                self.fail(f"{where}.image", f"must be a plain {', '.join(PHOTO_EXTENSIONS)} file name inside the rig's "
                                            f"folder, got {image!r}")
            if image in names:
                self.fail(f"{where}.image", f"{image!r} names two shots")
            names.add(image)
            shots.append(Shot(self.index(s["camera"], f"{where}.camera", n_cameras),
                              self.index(s["light"], f"{where}.light", n_lights), image))
        return shots


def rig_from_dict(data: Any, path: str = "rig") -> Rig:
    """Validate a rig document (a dict as JSON gives it); ``path`` names it in errors."""
    reader = _RigReader(data, path)
    size, extent = reader.header()
    # In the document's order, so that the first bad key is the one reported.
    cameras = reader.cameras()
    lights = reader.lights()
    return Rig(size, extent, cameras, lights, reader.shots(len(cameras), len(lights)))


def check_rig(rig: Rig, path: str = "rig") -> Rig:
    """``rig`` validated as its JSON would be (a rig built in code meets the file's rules)."""
    return rig_from_dict(rig.to_dict(), path)


def shot_light_positions(rig: Rig, positions: Optional[np.ndarray] = None) -> np.ndarray:
    """(shots, 3) light position of each shot: the rig's, or the lights' ``positions`` (lights, 3)."""
    table = np.array([l.position for l in rig.lights]) if positions is None else np.asarray(positions)
    return table[[s.light for s in rig.shots]]
