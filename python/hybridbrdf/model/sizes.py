"""The sizes of a model's estimates in plain Python: their direction grids, default sample counts
and peak bytes per sample (docs/CONVENTIONS.md, "Counts and memory").

The estimates themselves (:func:`~hybridbrdf.model.editing.albedo_profile`,
:func:`~hybridbrdf.model.energy.tables`) run in NumPy; ``hbrdf info`` and ``hbrdf bound`` state
these sizes in their help, and a command line's parser imports no NumPy (issue 57: an argument
error answers in Python's start-up time). This module imports nothing but the generated contract.
"""

from __future__ import annotations

from hybridbrdf import spec

#: Peak bytes per direction pair of a model's eval through libhybridbrdf
#: (:attr:`HybridModel.LIBRARY_BYTES_PER_PAIR <hybridbrdf.model.file.HybridModel>`): float32 copies of
#: the directions, the float32 output and its float64 copy (62 measured from float64 views), with a margin.
LIBRARY_BYTES_PER_PAIR = 96


def torch_bytes_per_pair(width: int, depth: int, itemsize: int = 4) -> int:
    """Peak bytes per direction pair of a model's eval through PyTorch (HybridModel.bytes_per_pair
    with a dtype; a fit step's activations, three times this, fit/joint.py): the inputs and f_a's
    terms (64 values), two activations per hidden unit and layer, and one layer more, because
    which freed buffer the allocator hands back depends on thread timing: 16x2 in float32 peaked
    at 539-559 bytes alone and 670 beside other jobs (2026-11-30, test_hostile_api), where two
    per layer gave 640."""
    return itemsize * (64 + 2 * width * (depth + 2))


# ---- the albedo profile (editing.albedo_profile, model.albedo, hbrdf info --albedo-samples) ----

#: Outgoing elevations (degrees) of the albedo grid: every 10 degrees to 80, then toward grazing,
#: where Fresnel and masking change fastest.
ALBEDO_THETA_DEG = (0.0, 10.0, 20.0, 30.0, 40.0, 50.0, 60.0, 70.0, 80.0, 85.0, 88.0)
#: Outgoing azimuths (degrees): the network sees wi and wo in the local frame, so even an
#: isotropic material's albedo can depend on phi; anisotropic ones do by design.
ALBEDO_PHI_DEG = (0.0, 45.0, 90.0, 135.0)
#: Peak bytes per incident sample and outgoing direction of an albedo estimate, besides the
#: model's own evaluation (model.bytes_per_pair): the repeated directions, u, the sampler's
#: outputs, the contributions (119 bytes measured in all through libhybridbrdf).
ALBEDO_BYTES_PER_SAMPLE = 96


def albedo_bytes_per_sample(pair_bytes: int) -> int:
    """Peak memory of :func:`~hybridbrdf.model.editing.albedo_profile` per incident sample (all
    outgoing directions of the grid) for a model whose evaluation takes ``pair_bytes`` a pair
    (model.bytes_per_pair()): what ``samples`` is bounded by (hybridbrdf.limits)."""
    return len(ALBEDO_THETA_DEG) * len(ALBEDO_PHI_DEG) * (ALBEDO_BYTES_PER_SAMPLE + pair_bytes)


# ---- the energy bound's estimate (energy.tables, hbrdf bound --samples) -----------------------

#: Elevations per node interval of the table (spec.ENERGY_NODES nodes) at which the albedo is
#: estimated (its ends and between).
ELEVATIONS_PER_INTERVAL = 4
#: Elevations closer to the horizon (cos theta; 89.97 to 89.89 degrees), where a network's
#: correction can still rise (measured: 1.03 at 89.9 degrees for one prior material with a table
#: fitted without them); they bind the first interval's nodes.
HORIZON_COS = (0.0005, 0.001, 0.002)
#: Azimuths (degrees) of every elevation: the network sees wi and wo in the local frame, so even an
#: isotropic material's albedo can depend on phi, and not with period 180 degrees. 22.5 degrees
#: apart: with 45 a kd = 1, eta = 10 edit peaked between two of them 1.5% above the target.
AZIMUTHS = tuple(22.5 * i for i in range(16))
#: Samples per direction (stratified, MIS of the material's f_a).
SAMPLES = 4096
#: Peak bytes per sample and fixed direction of a material's estimate (the repeated directions,
#: u, the sampler's outputs, both sides' values and contributions: 228 measured, with a margin).
BYTES_PER_DIRECTION_SAMPLE = 256


def energy_directions() -> int:
    """How many fixed directions the energy bound's estimate has: the horizon's elevations, those of
    every node interval and cos theta = 1, each at every azimuth (energy._directions builds them)."""
    return (len(HORIZON_COS) + (spec.ENERGY_NODES - 1) * ELEVATIONS_PER_INTERVAL + 1) * len(AZIMUTHS)


def energy_bytes_per_sample() -> int:
    """Peak memory of one material's energy-bound estimate per sample (every fixed direction):
    what ``samples`` of :func:`~hybridbrdf.model.energy.tables` is bounded by (hybridbrdf.limits)."""
    return energy_directions() * BYTES_PER_DIRECTION_SAMPLE
