"""``hbrdf demo``'s sizes in plain Python: its parser states them in its help and imports no NumPy
(issue 57); :mod:`~hybridbrdf.demo.slices`, which runs the demo, does."""

#: Peak bytes per sample of one albedo estimate (directional_albedo: the repeated wo, u, the
#: sampler's float32 copies and outputs, the float64 weights; 88 measured), with a margin.
BYTES_PER_SAMPLE = 128
#: Samples per albedo estimate by default (hbrdf demo --samples).
SAMPLES = 200_000
