"""The network as the code template writes it: the layers of a model (hidden layers, then the
shared output layer, a material's own output layer as literals, or none where the output layer
is read from the material), the latent code folded into the first bias for one material, and
the statements of the unrolled form (weights as literals, one statement per neuron)."""

from __future__ import annotations

from typing import Any, Callable, Dict, List, Optional, Sequence, Tuple

import numpy as np

from hybridbrdf import spec
from hybridbrdf.codegen.literals import float_literal, half_pairs
from hybridbrdf.model.file import HybridModel


def _c_declaration(text: str) -> str:
    return text


def unrolled_layer(layer: Dict[str, object], index: int, last: bool, fp16: bool = False,
                   let: Callable[[str], str] = _c_declaration) -> List[str]:
    """Statements of one fully connected layer with its weights as literals:
    ``float h<index>_<j> = hbrdf_activation(b + w * x + ...);`` (``o[j] = ...`` for the
    output layer); ``let`` is the dialect's declaration of "float NAME" (WGSL: ``let NAME: f32``). Inputs are ``x[k]`` for the first layer and the previous layer's
    ``h`` otherwise; exactly-zero weights are left out (the inputs are finite).
    ``fp16`` rounds the weights (not the bias) to binary16 first."""
    n_in, n_out = layer["n_in"], layer["n_out"]
    w = np.asarray(layer["weight"], dtype=np.float32).reshape(n_out, n_in)
    if fp16:
        w = w.astype(np.float16).astype(np.float32)
    b = np.asarray(layer["bias"], dtype=np.float32)
    inputs = [f"x[{k}]" for k in range(n_in)] if index == 0 else [f"h{index - 1}_{k}" for k in range(n_in)]
    lines = []
    for j in range(n_out):
        terms = [float_literal(b[j])]
        for k in range(n_in):
            if w[j, k] != 0.0:
                terms.append(f"{'-' if w[j, k] < 0 else '+'} {float_literal(abs(w[j, k]))} * {inputs[k]}")
        expr = " ".join(terms)
        lines.append(f"o[{j}] = {expr};" if last else f"{let(f'float h{index}_{j}')} = hbrdf_activation({expr});")
    return lines


def split_first_layer(layer: Dict[str, object], pixel_inputs: Dict[int, str], fp16: bool = False,
                      let: Callable[[str], str] = _c_declaration) -> Tuple[List[str], List[str]]:
    """The first layer split at a raster frame's light loop (the per-pixel form, ``hbrdf_pixel``):
    ``(pixel, light)`` statements. ``pixel_inputs`` maps the input index of each value that is the
    same for every light of a pixel (the latent code, wo) to its expression, in the order they are
    summed (latent first: with a constant material every partial sum is a constant the compiler
    folds); ``pixel`` sets ``px.pre0[j]`` to the bias plus those terms, ``light`` declares
    ``h0_<j> = hbrdf_activation(px.pre0[j] + ...)`` with the other inputs ``x[k]``. The same terms as
    :func:`unrolled_layer`'s; only the order of the sum differs (float rounding)."""
    n_in, n_out = layer["n_in"], layer["n_out"]
    w = np.asarray(layer["weight"], dtype=np.float32).reshape(n_out, n_in)
    if fp16:
        w = w.astype(np.float16).astype(np.float32)
    b = np.asarray(layer["bias"], dtype=np.float32)
    light_inputs = {k: f"x[{k}]" for k in range(n_in) if k not in pixel_inputs}
    pixel, light = [], []
    for j in range(n_out):
        pixel.append(f"px.pre0[{j}] = {_weighted_sum(float_literal(b[j]), w[j], pixel_inputs)};")
        light.append(f"{let(f'float h0_{j}')} = hbrdf_activation({_weighted_sum(f'px.pre0[{j}]', w[j], light_inputs)});")
    return pixel, light


def _weighted_sum(first: str, row, inputs: Dict[int, str]) -> str:
    """``first + w_k * input_k ...`` over ``inputs`` (index -> expression) in their order, exactly-zero
    weights left out (the inputs are finite)."""
    terms = [first] + [f"{'-' if row[k] < 0 else '+'} {float_literal(abs(row[k]))} * {expr}"
                       for k, expr in inputs.items() if row[k] != 0.0]
    return " ".join(terms)


def unrolled_head(width: int, n_out: int, depth: int) -> List[str]:
    """The output layer of a model with material output layers, read from the material:
    ``o[j] = m.head_b[j] + m.head_w[j * width + k] * h<depth-1>_k + ...`` with constant indices
    (shader compilers then address the material's constants directly, no dynamic indexing)."""
    lines = []
    for j in range(n_out):
        terms = [f"m.head_b[{j}]"] + [f"+ m.head_w[{j * width + k}] * h{depth - 1}_{k}" for k in range(width)]
        lines.append(f"o[{j}] = {' '.join(terms)};")
    return lines


def unrolled_frames(tensors) -> List[str]:
    """``raw_frames[j] = b + W z`` for the neural baseline's 18 frame outputs, weights as literals."""
    w = np.asarray(tensors["frames.weight"], dtype=np.float32)
    b = np.asarray(tensors["frames.bias"], dtype=np.float32)
    lines = []
    for j in range(w.shape[0]):
        terms = [float_literal(b[j])] + [f"{'-' if w[j, k] < 0 else '+'} {float_literal(abs(w[j, k]))} * m.z[{k}]"
                                         for k in range(w.shape[1]) if w[j, k] != 0.0]
        lines.append(f"raw_frames[{j}] = {' '.join(terms)};")
    return lines


_HALF_MAX = 65504.0  # largest finite IEEE binary16 value


def check_half_range(layers) -> None:
    """--precision fp16 rounds layer weights to binary16: one beyond +-65504 would become Inf and
    every output NaN, so it is an error, not a silent overflow."""
    for i, layer in enumerate(layers):
        top = float(np.abs(layer["weight"]).max(initial=0.0))
        if top > _HALF_MAX:
            raise ValueError(f"--precision fp16: layer {i} has a weight of magnitude {top:.6g}, beyond the "
                             f"half-precision range (65504); use --precision fp32")


def _layer(weight, bias) -> Dict[str, Any]:
    return {"n_in": weight.shape[1], "n_out": weight.shape[0], "weight": weight.ravel(), "bias": bias}


def network_layers(model: HybridModel, names: Sequence[str], *, fold_latent: bool, analytic_only: bool,
                   literal_head: Optional[str], precision: str, unrolled: bool,
                   let: Callable[[str], str] = _c_declaration) -> Tuple[List[Dict[str, Any]], bool, int, int]:
    """The layers the template writes for ``model``'s materials ``names``: ``(layers,
    head_in_material, n_in, latent_in)``, each layer ``{"n_in", "n_out", "weight", "bias",
    "weight_half_pairs", "unrolled"}``. ``head_in_material``: the output layer is each material's
    own, read from HbrdfMaterial (then not among ``layers``); ``n_in``/``latent_in``: the first
    layer's inputs and the latent ones among them (0 with ``fold_latent``, where the one
    material's latent inputs are constants and W0[:, z] z joins the first bias). ``let``: the
    dialect's declaration of the unrolled form's "float NAME" (literals.DIALECTS)."""
    a, t = model.arch, model.tensors
    latent = a["latent"]
    layers = [_layer(t[f"mlp.hidden.{i}.weight"], t[f"mlp.hidden.{i}.bias"]) for i in range(a["depth"])]
    # The output layer: the shared one; with material output layers (spec/model.json) each
    # material's own, held in HbrdfMaterial as engines hold per-material constants, or as
    # literals where one material is emitted for a scene (or literal_head names it).
    head_in_material = False
    if model.output_layer != "material":
        layers.append(_layer(t["mlp.out.weight"], t["mlp.out.bias"]))
    elif literal_head is not None or (fold_latent and not analytic_only):
        i = model.index(literal_head if literal_head is not None else names[0])
        layers.append(_layer(t["materials.head_weight"][i], t["materials.head_bias"][i]))
    elif not analytic_only:
        head_in_material = True
    n_in, latent_in = a["n_in"], latent
    if fold_latent and latent:
        # One material: its latent inputs are constants, so W0[:, z] z joins the first bias.
        z_start = spec.ARCHS[model.kind]["direction_count"]
        w0 = t["mlp.hidden.0.weight"].astype(np.float64)
        z = t["materials.z"][model.index(names[0])].astype(np.float64)
        bias = (t["mlp.hidden.0.bias"].astype(np.float64) + w0[:, z_start:z_start + latent] @ z).astype(np.float32)
        w0 = np.delete(w0, np.s_[z_start:z_start + latent], axis=1).astype(np.float32)
        layers[0] = _layer(w0, bias)
        n_in, latent_in = n_in - latent, 0
    if precision == "fp16":
        check_half_range(layers)
    for i, layer in enumerate(layers):
        layer["weight_half_pairs"] = half_pairs(layer["weight"])
        layer["unrolled"] = (unrolled_layer(layer, i, i == len(layers) - 1 and not head_in_material,
                                            precision == "fp16", let) if unrolled else [])
    return layers, head_in_material, n_in, latent_in
