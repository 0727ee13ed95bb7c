"""Models with random weights, for the work whose outcome does not depend on fitted
values: file round trips, code generation and conformance tests (the same inputs
through two implementations), and throughput benchmarks."""

from __future__ import annotations

from typing import Optional, Sequence, Tuple

import numpy as np
import torch

from hybridbrdf import spec
from hybridbrdf.model import energy
from hybridbrdf.model.file import HybridModel
from hybridbrdf.model.networks import build_model


def random_model(arch: str = "hybrid", n: int = 3, latent: int = 4, width: int = 16, depth: int = 2,
                 isotropic: Optional[Sequence[bool]] = None,
                 output_layer: str = "shared", energy_bound: bool = False) -> Tuple[torch.nn.Module, HybridModel]:
    """A model of ``arch`` for ``n`` materials named ``mat-0`` .. ``mat-<n-1>`` (hardgelu
    activation), as the training module and as a :class:`HybridModel`; ``output_layer``
    "material" gives each material its own output layer (different per material: the noise);
    ``energy_bound`` gives each material a random energy-bound table (nodes in [0.2, 1], one node
    at 1 and one at 0.5 exactly: what the code paths do, not a fitted bound).

    The weights are the fresh initialisation plus N(0, 0.3^2) noise. The torch global
    seed is set to 0 first, so that every call with the same arguments returns the same
    model (a failing test or a timed run can be repeated exactly)."""
    torch.manual_seed(0)
    mod = build_model(arch, n, width, depth, latent, "hardgelu", isotropic, output_layer=output_layer)
    with torch.no_grad():
        for p in mod.parameters():
            p.add_(torch.randn_like(p) * 0.3)
    names = [f"mat-{i}" for i in range(n)]
    model = HybridModel.from_module(mod, names, ["test"] * n, {"steps": 0})
    if energy_bound:
        table = (0.2 + 0.8 * torch.rand(n, spec.ENERGY_NODES)).numpy().astype(np.float32)
        table[:, -1], table[:, 3] = 1.0, 0.5
        model = energy.attach(model, table)
    return mod, model
