"""``hbrdf view``'s default sizes in plain Python: the measured references' render size and samples
per pixel. The parser states them in its help and imports no NumPy (issue 57);
:mod:`~hybridbrdf.viewer.measured`, which renders the references, does."""

#: Default size (pixels, square) and samples per pixel of the measured render: 1.3-2.5 s per RGL
#: source on this project's 2-core machine (docs/VIEWER.md).
DEFAULT_SOURCE_SIZE = 192
DEFAULT_SOURCE_SPP = 64
