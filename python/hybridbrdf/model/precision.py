"""Half-precision weights as a model: what ``hbrdf-codegen --precision fp16`` stores, in a form
the library and PyTorch evaluate, so that the cost of fp16 can be measured (bench/fp16_cost.py)
and the generated fp16 code checked against it (the tests)."""

from __future__ import annotations

import copy

import numpy as np

from hybridbrdf.model.file import HybridModel


def half_rounded(model: HybridModel) -> HybridModel:
    """A copy of ``model`` whose network layer weights (``mlp.*.weight``; not the biases, which
    the generated code keeps in float32) are rounded to IEEE binary16 and back to float32."""
    rounded = copy.deepcopy(model)
    for k, v in rounded.tensors.items():
        if k.startswith("mlp.") and k.endswith(".weight"):
            rounded.tensors[k] = v.astype(np.float16).astype(np.float32)
    return rounded
