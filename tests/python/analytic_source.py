"""A BRDFSource with exactly known values for fitting tests: f_a of the
project's own analytic model (float64 PyTorch), optionally plus a
retro-reflective bump that no single GGX lobe can express."""

import numpy as np
import torch

from hybridbrdf.sources.base import BRDFSource
from hybridbrdf.torch_brdf import eval_analytic


class AnalyticTestSource(BRDFSource):
    def __init__(self, name, params, retro=0.0):
        self.name, self.params, self.retro = name, params, retro
        self.isotropic = params.isotropic
        self.origin = "test: analytic" + (" + retro bump" if retro else "")

    def _eval(self, wi, wo):
        p = self.params
        f = eval_analytic(torch.tensor(wi), torch.tensor(wo), torch.tensor(p.kd), torch.tensor(p.eta),
                          torch.tensor(p.alpha)).numpy()
        return f + self.retro * np.exp(-20.0 * (1.0 - (wi * wo).sum(1)))[:, None]
