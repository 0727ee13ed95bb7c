"""Plain-Python defaults of the raster frame, for ``hbrdf raster``'s parser (no NumPy)."""

#: Mesa's CPU Vulkan driver, which ``lavapipe=True`` (``--lavapipe``) pins.
LAVAPIPE_ICD = "/usr/share/vulkan/icd.d/lvp_icd.x86_64.json"
#: Sphere tessellation by default: phi segments (theta gets half); the flat triangles then reach
#: 3.8e-5 of the radius inside the sphere (the tool's ``sphere_gap``).
SPHERE_SEGMENTS = 512
