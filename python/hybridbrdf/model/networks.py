"""The hybrid model of the paper (Eq. 1), its ablation variants and the fully
neural baseline, in PyTorch.

    f_t(wi, wo) = f_c + f_g * f_a,    (f_c, f_g) = psi(wi, wo, z)       (paper Eq. 1)

A model holds one shared network and, per material, the analytic parameters
p = (kd, eta, alpha) and a latent code z. Parameters are stored
reparameterised so that every optimiser step keeps them in range:

    kd    = KD_MIN + (KD_MAX - KD_MIN) sigmoid(kd_raw)      in (0, 1)
    eta   = ETA_MIN + (ETA_MAX - ETA_MIN) sigmoid(eta_raw)  in (1, 10)
    alpha = exp(log(ALPHA_MIN) (1 - sigmoid(a_raw)))  in (ALPHA_MIN, 1), log-uniform in the raw value

Isotropic materials use alpha_y = alpha_x (one raw value is ignored).

Architectures (``arch``):

The architectures, their input layout and combine rules are declared once in the model
contract, ``spec/model.json`` (generated into :mod:`hybridbrdf.spec` and the C++ library):

- ``hybrid``: network input (wi, wo, z) in that order; 6 outputs, f_c = exp(o[0:3]),
  f_g = sigmoid(o[3:6]); the pre-exp value is clamped to ``pre_exp_max`` (default
  :data:`PRE_EXP_MAX`; a model file records its own).
- ``additive`` (ablation): 3 outputs o, f_t = max(f_a + o, 0). The paper adds o
  unclamped; the clamp keeps the loss's log(1 + cos f) defined.
- ``logmul`` (ablation): 3 outputs o, f_t = exp(log f_a + o) = f_a exp(o).
- ``analytic-input`` (ablation): as ``hybrid``, with log(1 + f_a) (3 values) appended to the input.
- ``neural``: the fully neural baseline, the paper's adaptation of Zeltner et al. 2024 (see
  :class:`NeuralBRDF`): no analytic part, a latent of ``latent`` dims per material.
"""

from __future__ import annotations

import math
from typing import Dict, List, Optional, Sequence

import torch
from torch import nn

from hybridbrdf import spec
from hybridbrdf.brdf.torch_brdf import _normalize, eval_analytic, half_angle_cosines, reciprocal_inputs

ARCHS = tuple(spec.ARCHS)
ACTIVATIONS = tuple(spec.ACTIVATIONS)
_FLT_MAX = float(torch.finfo(torch.float32).max)

#: Default bound on every value passed to exp() (spec.PRE_EXP_MAX: exp(16) = 8.9e6 is far above
#: any measured BRDF value and keeps float32 and float16 products from overflowing).
PRE_EXP_MAX = spec.PRE_EXP_MAX
ALPHA_MIN = spec.ALPHA_MIN
_LOG_ALPHA_MIN = math.log(ALPHA_MIN)
# The ranges of the reparameterisation are the contract's (spec/model.json); alpha's log-uniform
# map exp(log(ALPHA_MIN) (1 - s)) ends at 1, so it holds only while the contract's ALPHA_MAX is 1.
assert spec.ALPHA_MAX == 1.0, "alpha's reparameterisation assumes ALPHA_MAX = 1"
_KD_SPAN = spec.KD_MAX - spec.KD_MIN
_ETA_SPAN = spec.ETA_MAX - spec.ETA_MIN


def hardgelu(x: torch.Tensor) -> torch.Tensor:
    """The paper authors' "hardGeLU": 0 for x < -1.5, x for x > 1.5, x (x + 1.5) / 3 between.

    Written as x * clamp((x + knee) / (2 knee), 0, 1) with knee = spec.HARDGELU_KNEE = 1.5
    (x times a hard sigmoid), the same function in three branch-free operations, for
    shaders as for PyTorch."""
    knee = spec.HARDGELU_KNEE
    return x * torch.clamp((x + knee) * (1.0 / (2.0 * knee)), 0.0, 1.0)


def activation_fn(name: str):
    if name == "relu":
        return torch.relu
    if name == "hardgelu":
        return hardgelu
    raise ValueError(f"unknown activation {name!r}; expected one of {', '.join(ACTIVATIONS)}")


def combine(rule: str, o: torch.Tensor, f_a: Optional[torch.Tensor], pre_exp_max: float) -> torch.Tensor:
    """f_t from the network output ``o`` (..., n_out) and ``f_a`` (..., 3) by combine ``rule``
    (spec.COMBINES; every reader implements the same table, spec/activation_combine.json):
    gated f_c + f_g f_a with f_c = exp(min(o[0:3], pre_exp_max)), f_g = sigmoid(o[3:6]) (paper
    Eq. 1); additive max(f_a + o, 0); logmul f_a exp(min(o, pre_exp_max)) held at FLT_MAX (f_a
    reaches 3.2e15 and exp(80) 5.5e34, so the product can pass it); exp exp(min(o, pre_exp_max))
    (no analytic part; ``f_a`` unused)."""
    if rule == "gated":
        return torch.exp(o[..., 0:3].clamp(max=pre_exp_max)) + torch.sigmoid(o[..., 3:6]) * f_a
    if rule == "additive":
        return torch.clamp(f_a + o, min=0.0)
    if rule == "logmul":
        return (f_a * torch.exp(o.clamp(max=pre_exp_max))).clamp(max=_FLT_MAX)
    if rule == "exp":
        return torch.exp(o.clamp(max=pre_exp_max))
    raise ValueError(f"unknown combine rule {rule!r}; expected one of {', '.join(spec.COMBINES)}")


def energy_bound_scale(table: torch.Tensor, cos_theta: torch.Tensor) -> torch.Tensor:
    """k(cos_theta) of energy-bound tables (spec/model.json, energy_bounds): ``table`` (..., K) and
    ``cos_theta`` broadcast against its leading dimensions; sum_j k_j max(0, 1 - |x (K - 1) - j|),
    linear between the nodes x_j = j / (K - 1), summed node by node as libhybridbrdf and the
    generated shaders do."""
    t = cos_theta * float(table.shape[-1] - 1)
    k = torch.zeros_like(t)
    for j in range(table.shape[-1]):
        k = k + table[..., j] * torch.clamp(1.0 - torch.abs(t - float(j)), min=0.0)
    return k


class MLP(nn.Module):
    """``depth`` hidden layers of ``width`` units with the chosen activation, then a linear output."""

    def __init__(self, n_in: int, width: int, depth: int, n_out: int, activation: str):
        super().__init__()
        if depth < 1 or width < 1:
            raise ValueError(f"MLP needs depth >= 1 and width >= 1, got {width}x{depth}")
        sizes = [n_in] + [width] * depth
        self.hidden = nn.ModuleList(nn.Linear(a, b) for a, b in zip(sizes[:-1], sizes[1:]))
        self.out = nn.Linear(width, n_out)
        self.activation_name = activation
        self._act = activation_fn(activation)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.forward_from(self.hidden[0](x))

    def forward_from(self, pre: torch.Tensor) -> torch.Tensor:
        """The network from the first hidden layer's pre-activation ``pre`` on (a caller that
        computes the first layer by parts: HybridBRDF._first_layer)."""
        return self.out(self.features_from(pre))

    def features_from(self, pre: torch.Tensor) -> torch.Tensor:
        """The last hidden layer's activations, from the first one's pre-activation ``pre``: what
        an output layer (shared, or a material's own) reads."""
        x = self._act(pre)
        for layer in self.hidden[1:]:
            x = self._act(layer(x))
        return x

    def layers(self) -> List[nn.Linear]:
        return list(self.hidden) + [self.out]


def _unit_pair(wi: torch.Tensor, wo: torch.Tensor):
    """Unit wi, wo (invalid ones replaced by +z) and the mask of pairs where both are
    valid and above the horizon."""
    wi_n, ok_i = _normalize(wi)
    wo_n, ok_o = _normalize(wo)
    return wi_n, wo_n, ok_i & ok_o & (wi_n[..., 2] > 0) & (wo_n[..., 2] > 0)


def _inverse_sigmoid(p: torch.Tensor) -> torch.Tensor:
    p = p.clamp(1e-6, 1 - 1e-6)
    return torch.log(p) - torch.log1p(-p)


# The hybrid's reparameterisation (the per-texel fits of hybridbrdf.acquire use it too): kd and eta
# sigmoids into the contract's ranges, alpha log-uniform in [ALPHA_MIN, 1].
def kd_from_raw(raw: torch.Tensor) -> torch.Tensor:
    return spec.KD_MIN + _KD_SPAN * torch.sigmoid(raw)


def eta_from_raw(raw: torch.Tensor) -> torch.Tensor:
    return spec.ETA_MIN + _ETA_SPAN * torch.sigmoid(raw)


def alpha_from_raw(raw: torch.Tensor) -> torch.Tensor:
    # The clamp only absorbs exp()'s last-bit rounding below ALPHA_MIN.
    return torch.exp(_LOG_ALPHA_MIN * (1.0 - torch.sigmoid(raw))).clamp(ALPHA_MIN, spec.ALPHA_MAX)


def raw_from_analytic(kd: torch.Tensor, eta: torch.Tensor, alpha: torch.Tensor):
    """The inverse of :func:`kd_from_raw`, :func:`eta_from_raw` and :func:`alpha_from_raw`: (kd_raw, eta_raw, alpha_raw) of parameter values."""
    return (_inverse_sigmoid((kd - spec.KD_MIN) / _KD_SPAN), _inverse_sigmoid((eta - spec.ETA_MIN) / _ETA_SPAN),
            _inverse_sigmoid(1.0 - torch.log(alpha.clamp(ALPHA_MIN, 1.0)) / _LOG_ALPHA_MIN))


class HybridBRDF(nn.Module):
    """Shared network + per-material (p, z) for the hybrid architecture and its ablations.

    ``isotropic``: one flag per material. ``forward(wi, wo)`` with wi, wo of shape
    (B, 3) evaluates every material on the same directions and returns
    ``(f_t, f_a)`` of shape (M, B, 3); ``material`` restricts to a subset (LongTensor).
    """

    def __init__(
        self,
        n_materials: int,
        arch: str = "hybrid",
        width: int = 32,
        depth: int = 3,
        latent: int = 4,
        activation: str = "hardgelu",
        isotropic: Optional[Sequence[bool]] = None,
        pre_exp_max: float = PRE_EXP_MAX,
        output_layer: str = "shared",
    ):
        super().__init__()
        if output_layer not in spec.OUTPUT_LAYERS:
            raise ValueError(f"unknown output layer {output_layer!r}; expected one of {', '.join(spec.OUTPUT_LAYERS)}")
        if arch not in ARCHS or not spec.ARCHS[arch]["analytic"]:
            raise ValueError(f"HybridBRDF arch must be one of {', '.join(a for a in ARCHS if spec.ARCHS[a]['analytic'])}; got {arch!r}")
        if latent < 0:
            raise ValueError(f"latent dimension must be >= 0, got {latent}")
        self.arch = arch
        self.width, self.depth, self.latent_dim, self.activation = width, depth, latent, activation
        self.pre_exp_max = float(pre_exp_max)
        a = spec.ARCHS[arch]
        self.combine_rule = a["combine"]
        n_out = a["n_out"]
        n_in = a["direction_count"] + latent + a["extra_count"]
        self.mlp = MLP(n_in, width, depth, n_out, activation)
        iso = torch.ones(n_materials, dtype=torch.bool) if isotropic is None else torch.as_tensor(list(isotropic))
        if iso.shape != (n_materials,):
            raise ValueError(f"isotropic needs {n_materials} flags, got {tuple(iso.shape)}")
        self.register_buffer("isotropic", iso)
        # Start every material as a grey (kd 0.5), fairly rough (alpha 0.3) dielectric
        # (eta 1.5): a broad lobe receives gradient from everywhere, a sharp one does not.
        self.kd_raw = nn.Parameter(torch.zeros(n_materials, 3))
        self.eta_raw = nn.Parameter(torch.full((n_materials, 3), float(_inverse_sigmoid(torch.tensor((1.5 - spec.ETA_MIN) / _ETA_SPAN)))))
        alpha0 = float(_inverse_sigmoid(torch.tensor(1.0 - math.log(0.3) / _LOG_ALPHA_MIN)))
        self.alpha_raw = nn.Parameter(torch.full((n_materials, 2), alpha0))
        self.z = nn.Parameter(torch.randn(n_materials, latent) * 0.01)
        with torch.no_grad():
            if n_out == 6:
                # Start with a small correction and an open gate (spec FC_INIT, FG_INIT):
                # the analytic part carries the fit at first.
                self.mlp.out.bias[0:3] = spec.FC_INIT
                self.mlp.out.bias[3:6] = spec.FG_INIT
            else:
                self.mlp.out.bias.zero_()
        self.output_layer = output_layer
        if output_layer == "material":
            # Each material's own output layer (spec/model.json, output_layers), started as copies of
            # the shared one; the shared one is then gone (the file holds the heads only).
            self.head_weight = nn.Parameter(self.mlp.out.weight.detach().clone().expand(n_materials, -1, -1).contiguous())
            self.head_bias = nn.Parameter(self.mlp.out.bias.detach().clone().expand(n_materials, -1).contiguous())
            self.mlp.out = None

    @property
    def n_materials(self) -> int:
        return self.kd_raw.shape[0]

    @property
    def n_out(self) -> int:
        return self.head_bias.shape[1] if self.output_layer == "material" else self.mlp.out.out_features

    def set_output_bias(self, channels: slice, value: float) -> None:
        """Sets the output bias of ``channels`` (the shared layer's, or every material's head) to
        ``value``: how a fit starts f_c (FitSettings.fc_init)."""
        with torch.no_grad():
            if self.output_layer == "material":
                self.head_bias[:, channels] = value
            else:
                self.mlp.out.bias[channels] = value

    def heads(self, idx: torch.Tensor):
        """(weight (M, n_out, width), bias (M, n_out)) of materials ``idx``, or None (shared layer)."""
        return (self.head_weight[idx], self.head_bias[idx]) if self.output_layer == "material" else None

    # ---- analytic parameters -------------------------------------------------
    def kd(self) -> torch.Tensor:
        return kd_from_raw(self.kd_raw)

    def eta(self) -> torch.Tensor:
        return eta_from_raw(self.eta_raw)

    def alpha(self) -> torch.Tensor:
        a = alpha_from_raw(self.alpha_raw)
        return torch.where(self.isotropic[:, None], a[:, :1].expand_as(a), a)

    def set_analytic(self, index: int, kd, eta, alpha) -> None:
        """Initialise material ``index`` from parameter values (inverse of the reparameterisation)."""
        with torch.no_grad():
            raw = raw_from_analytic(*(torch.as_tensor(v, dtype=torch.float32) for v in (kd, eta, alpha)))
            self.kd_raw[index], self.eta_raw[index], self.alpha_raw[index] = raw

    # ---- evaluation ------------------------------------------------------------
    def forward(self, wi: torch.Tensor, wo: torch.Tensor, material: Optional[torch.Tensor] = None):
        idx = torch.arange(self.n_materials, device=wi.device) if material is None else material
        return self.evaluate(wi, wo, self.kd()[idx], self.eta()[idx], self.alpha()[idx], self.z[idx], self.heads(idx))

    def evaluate(self, wi, wo, kd, eta, alpha, z, head=None):
        """(f_t, f_a), each (M, B, 3), for explicit per-material values kd, eta (M,3),
        alpha (M,2), z (M,l) on shared directions wi, wo (B,3), and with material output
        layers, ``head`` = (weight (M, n_out, width), bias (M, n_out)).

        The network sees unit directions; f_t is 0 where either direction is below
        the horizon or invalid (as f_a is), so f_c cannot leak light there."""
        wi_n, wo_n, valid = _unit_pair(wi, wo)
        f_a = eval_analytic(wi_n[None], wo_n[None], kd[:, None], eta[:, None], alpha[:, None])  # (M, B, 3)
        extra = torch.log1p(f_a) if spec.ARCHS[self.arch]["extra"] == "log1p_fa" else None
        kind = spec.ARCHS[self.arch]["directions"]
        directions = [reciprocal_inputs(wi_n, wo_n)] if kind == "reciprocal" else [wi_n, wo_n]
        if kind == "local_half":
            directions.append(half_angle_cosines(wi_n, wo_n))
        pre = self._first_layer(torch.cat(directions, dim=-1), z, extra)
        if self.output_layer == "material":
            if head is None:
                raise ValueError("a model with material output layers needs each material's head")
            # o[m, b] = W_m x[m, b] + b_m: one batched matrix product over the materials.
            o = torch.baddbmm(head[1][:, None, :], self.mlp.features_from(pre), head[0].transpose(1, 2))
        else:
            o = self.mlp.forward_from(pre)
        f_t = self.combine(o, f_a)
        return torch.where(valid[None, :, None], f_t, torch.zeros_like(f_t)), f_a

    def evaluate_pairs(self, wi, wo, kd, eta, alpha, z, head=None):
        """(f_t, f_a), each (N, 3), where pair i has its own values: kd, eta (N, 3), alpha (N, 2),
        z (N, l) on directions wi, wo (N, 3), and with material output layers one ``head`` =
        (weight (n_out, width), bias (n_out)) for every pair: the texels of one layer of a
        textured material (docs/SVBRDF.md). Same function as :meth:`evaluate`, rounded alike
        up to the order of the first layer's sums."""
        wi_n, wo_n, valid = _unit_pair(wi, wo)
        f_a = eval_analytic(wi_n, wo_n, kd, eta, alpha)  # (N, 3)
        kind = spec.ARCHS[self.arch]["directions"]
        directions = [reciprocal_inputs(wi_n, wo_n)] if kind == "reciprocal" else [wi_n, wo_n]
        if kind == "local_half":
            directions.append(half_angle_cosines(wi_n, wo_n))
        d = torch.cat(directions, dim=-1)
        first = self.mlp.hidden[0]
        n_dir, l = d.shape[-1], self.latent_dim
        pre = d @ first.weight[:, :n_dir].t() + (z @ first.weight[:, n_dir:n_dir + l].t() + first.bias)
        if spec.ARCHS[self.arch]["extra"] == "log1p_fa":
            pre = pre + torch.log1p(f_a) @ first.weight[:, n_dir + l:].t()
        if self.output_layer == "material":
            if head is None:
                raise ValueError("a model with material output layers needs the layer's head")
            o = self.mlp.features_from(pre) @ head[0].t() + head[1]
        else:
            o = self.mlp.forward_from(pre)
        f_t = self.combine(o, f_a)
        return torch.where(valid[:, None], f_t, torch.zeros_like(f_t)), f_a

    def _first_layer(self, directions: torch.Tensor, z: torch.Tensor, extra: Optional[torch.Tensor]) -> torch.Tensor:
        """The first hidden layer's pre-activation (M, B, width) for the input layout of
        spec/model.json (direction inputs, latent code, extra inputs), computed by parts.

        The direction inputs (B, 6) are shared by every material and the latent code (M, l) by
        every pair, so W [d; z; e] + b = (W_d d) + (W_z z + b) [+ W_e e]: a (B x 6) and an
        (M x l) product broadcast-added instead of one (M B x (6 + l)) product of a concatenated
        input. Same function, rounded differently; it spares a joint fit the (M, B, 6 + l) input
        tensor and, in the backward pass, that tensor's gradient (docs/LOSS.md, "Fitting in 30 minutes")."""
        first = self.mlp.hidden[0]
        n_dir, l = directions.shape[-1], self.latent_dim
        w_dir, w_z, w_extra = first.weight[:, :n_dir], first.weight[:, n_dir:n_dir + l], first.weight[:, n_dir + l:]
        pre = (directions @ w_dir.t())[None] + (z @ w_z.t() + first.bias)[:, None]
        if extra is not None:
            pre = pre + extra @ w_extra.t()
        return pre

    def combine(self, o: torch.Tensor, f_a: torch.Tensor) -> torch.Tensor:
        """The network output o and f_a -> f_t, by the architecture's combine rule (spec.COMBINES)."""
        return combine(self.combine_rule, o, f_a, self.pre_exp_max)

    def material_tensors(self) -> Dict[str, torch.Tensor]:
        """Evaluation-ready per-material values: kd, eta, alpha, z (float32, detached)."""
        out = {
            "kd": self.kd().detach().float(),
            "eta": self.eta().detach().float(),
            "alpha": self.alpha().detach().float(),
            "z": self.z.detach().float(),
        }
        if self.output_layer == "material":
            out["head_weight"] = self.head_weight.detach().float()
            out["head_bias"] = self.head_bias.detach().float()
        return out


class NeuralBRDF(nn.Module):
    """The fully neural baseline: the paper's adaptation (Sec. 4.1) of Zeltner et al. 2024,
    "Real-Time Neural Appearance Models".

    Our reading, documented because the paper gives it in one sentence: the encoder is
    replaced by a trainable latent code of ``latent`` dims per material (12 or 16 = the
    hybrid's l + analytic parameter count). A frame-transform module, one linear layer
    from the latent code, predicts 3 shading frames (a normal and a tangent each,
    Gram-Schmidt orthonormalised; initialised to the geometric frame). wi and wo are
    expressed in each frame (18 numbers) and, with the latent code, feed a shallow MLP
    whose 3 outputs give f = exp(o) (o clamped to ``pre_exp_max``).
    """

    N_FRAMES = spec.NEURAL_FRAMES

    def __init__(self, n_materials: int, width: int = 32, depth: int = 3, latent: int = 12,
                 activation: str = "hardgelu", isotropic: Optional[Sequence[bool]] = None,
                 pre_exp_max: float = PRE_EXP_MAX):
        super().__init__()
        self.arch = "neural"
        self.output_layer = "shared"  # material output layers are for the analytic architectures
        self.width, self.depth, self.latent_dim, self.activation = width, depth, latent, activation
        self.pre_exp_max = float(pre_exp_max)
        self.frames = nn.Linear(latent, self.N_FRAMES * 6)
        with torch.no_grad():
            self.frames.weight.mul_(0.1)
            self.frames.bias.copy_(torch.tensor([0.0, 0, 1, 1, 0, 0] * self.N_FRAMES))
        self.mlp = MLP(self.N_FRAMES * 6 + latent, width, depth, 3, activation)
        iso = torch.ones(n_materials, dtype=torch.bool) if isotropic is None else torch.as_tensor(list(isotropic))
        self.register_buffer("isotropic", iso)
        self.z = nn.Parameter(torch.randn(n_materials, latent) * 0.01)

    @property
    def n_materials(self) -> int:
        return self.z.shape[0]

    @property
    def n_out(self) -> int:
        return self.mlp.out.out_features

    def shading_frames(self, z: torch.Tensor):
        """(M, 3 frames, 3 axes t, b, n, 3) orthonormal frames from latent codes (M, L)."""
        raw = self.frames(z).view(-1, self.N_FRAMES, 2, 3)
        n = torch.nn.functional.normalize(raw[:, :, 0], dim=-1, eps=1e-8)
        t = raw[:, :, 1] - (raw[:, :, 1] * n).sum(-1, keepdim=True) * n
        t = torch.nn.functional.normalize(t, dim=-1, eps=1e-8)
        b = torch.cross(n, t, dim=-1)
        return torch.stack([t, b, n], dim=2)

    def forward(self, wi: torch.Tensor, wo: torch.Tensor, material: Optional[torch.Tensor] = None):
        idx = torch.arange(self.n_materials, device=wi.device) if material is None else material
        return self.evaluate(wi, wo, self.z[idx])

    def evaluate(self, wi, wo, z):
        """(f, None): f (M, B, 3) for latent codes z (M, L) on shared directions (B, 3)."""
        frames = self.shading_frames(z)  # (M, F, 3, 3)
        m, b = z.shape[0], wi.shape[0]
        wi_n, wo_n, valid = _unit_pair(wi, wo)
        wi_f = torch.einsum("mfac,bc->mbfa", frames, wi_n).reshape(m, b, -1)
        wo_f = torch.einsum("mfac,bc->mbfa", frames, wo_n).reshape(m, b, -1)
        o = self.mlp(torch.cat([wi_f, wo_f, z[:, None].expand(m, b, self.latent_dim)], dim=-1))
        f = combine("exp", o, None, self.pre_exp_max)
        return torch.where(valid[None, :, None], f, torch.zeros_like(f)), None

    def evaluate_pairs(self, wi, wo, z):
        """f (N, 3) where pair i has its own latent code z (N, L) on directions wi, wo (N, 3): the
        per-texel codes of hybridbrdf.acquire's neural-only fit. Same function as :meth:`evaluate`."""
        frames = self.shading_frames(z)  # (N, F, 3, 3)
        wi_n, wo_n, valid = _unit_pair(wi, wo)
        wi_f = torch.einsum("nfac,nc->nfa", frames, wi_n).reshape(len(z), -1)
        wo_f = torch.einsum("nfac,nc->nfa", frames, wo_n).reshape(len(z), -1)
        f = combine("exp", self.mlp(torch.cat([wi_f, wo_f, z], dim=-1)), None, self.pre_exp_max)
        return torch.where(valid[:, None], f, torch.zeros_like(f))

    def material_tensors(self) -> Dict[str, torch.Tensor]:
        return {"z": self.z.detach().float()}


def build_model(arch: str, n_materials: int, width: int, depth: int, latent: int, activation: str,
                isotropic: Optional[Sequence[bool]] = None, pre_exp_max: float = PRE_EXP_MAX,
                output_layer: str = "shared") -> nn.Module:
    """A fresh model of architecture ``arch`` for ``n_materials`` materials; ``output_layer``
    "material" gives each material its own output layer (architectures with an analytic part)."""
    if arch not in ARCHS:
        raise ValueError(f"unknown architecture {arch!r}; expected one of {', '.join(ARCHS)}")
    if spec.ARCHS[arch]["directions"] == "frames":
        if output_layer != "shared":
            raise ValueError("material output layers are for architectures with an analytic part, not neural")
        return NeuralBRDF(n_materials, width, depth, latent, activation, isotropic, pre_exp_max)
    return HybridBRDF(n_materials, arch, width, depth, latent, activation, isotropic, pre_exp_max, output_layer)
