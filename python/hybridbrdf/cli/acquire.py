"""``hbrdf acquire``: the acquisition commands (docs/ACQUISITION.md). ``hbrdf acquire simulate``
photographs a flat sample, an exact mixture of measured BRDFs under masks, with a rig (a rig file, a
phone's flash at N positions or a K x V light stage) and writes the capture folder; ``hbrdf acquire
fit`` fits per-texel maps on a frozen prior to a capture's photographs and writes a textured material.

Each run imports the acquisition code it drives (PyTorch, the fit) when it runs: building the
parser imports none of it."""

from __future__ import annotations

import argparse
import math
import os
import sys

from hybridbrdf.acquire.sizes import FINETUNE_MIN_SHOTS, FINETUNE_STEPS, MAX_ITEMS, MAX_SIDE, STEPS
from hybridbrdf.cli import COMMANDS, layer_masks
from hybridbrdf.errors import InputFileError


def _number(lo: float, hi: float = math.inf, open_lo: bool = False):
    """An argparse type: a finite float in [lo, hi] ((lo, hi] with ``open_lo``)."""
    def parse(text: str) -> float:
        try:
            v = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
        if not math.isfinite(v) or v < lo or v > hi or (open_lo and v == lo):
            raise argparse.ArgumentTypeError(f"expected a number in {'(' if open_lo else '['}{lo:g}, {hi:g}], got {text!r}")
        return v
    return parse


def _count(lo: int, hi: int):
    """An argparse type: a whole number in [lo, hi]."""
    def parse(text: str) -> int:
        if not text.strip().isdigit() or not lo <= int(text) <= hi:
            raise argparse.ArgumentTypeError(f"expected a whole number {lo} to {hi}, got {text!r}")
        return int(text)
    return parse


def _pair(kind, lo, hi, what: str):
    """An argparse type: AxB, two values of ``kind`` in [lo, hi] (``what`` names them)."""
    def parse(text: str):
        a, sep, b = text.lower().partition("x")
        try:
            if not sep:
                raise ValueError
            out = (kind(a), kind(b))
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected {what}, got {text!r}") from None
        if not all(math.isfinite(v) and lo <= v <= hi and v > 0 for v in out):
            raise argparse.ArgumentTypeError(f"expected {what}, each in (0, {hi:g}], got {text!r}")
        return out
    return parse


def _inside(path: str, folder: str) -> bool:
    path, folder = os.path.realpath(path), os.path.realpath(folder)
    return path == folder or path.startswith(folder.rstrip(os.sep) + os.sep)


def run_simulate(args: argparse.Namespace) -> int:
    """``hbrdf acquire simulate``: everything checked (rig, masks, sources, the output folder) before
    the first photograph; the folder written once complete."""
    from tqdm import tqdm

    from hybridbrdf.acquire import simulate
    from hybridbrdf.acquire.capture import check_output_folder, write_capture
    from hybridbrdf.acquire.mixture import Mixture
    from hybridbrdf.acquire.noise import NoiseModel
    from hybridbrdf.acquire.rig import load_rig
    from hybridbrdf.acquire.rigs import flash_rig, light_stage_rig
    from hybridbrdf.fit.painting import read_grey
    from hybridbrdf.sources import open_source

    layers = layer_masks(args.layer, "SOURCE")
    if args.read_noise and not args.photons:
        raise ValueError("--read-noise needs --photons (the noise model's scale)")
    if len(layers) > 3:
        raise ValueError(f"at most 3 --layer over the base, got {len(layers)}")
    inputs = [p for p in [args.rig, args.base] + [x for pair in layers for x in pair] if p and os.path.exists(p)]
    for p in inputs:
        if _inside(p, args.out):
            raise InputFileError(args.out, f"--out holds the input {p}; writing it would destroy that input")
    check_output_folder(os.path.abspath(args.out))
    if args.rig:
        rig = load_rig(args.rig)
    elif args.flash:
        rig = flash_rig(args.flash, distance=args.distance or 0.3, extent=args.extent, size=args.size)
    else:
        rig = light_stage_rig(args.stage[0], args.stage[1], light_distance=args.distance or 1.0,
                              camera_distance=args.distance or 1.0, extent=args.extent, size=args.size)
    masks = [read_grey(mask, "mask") for _, mask in layers]
    for (_, path), m in zip(layers, masks):
        if m.shape != masks[0].shape:
            raise InputFileError(path, f"mask is {m.shape[1]}x{m.shape[0]}; the first mask is "
                                       f"{masks[0].shape[1]}x{masks[0].shape[0]}")
    mixture = Mixture.painted(open_source(args.base), [open_source(name) for name, _ in layers], masks)
    noise = NoiseModel(args.photons, args.read_noise)
    with tqdm(total=len(rig.shots), desc="photographs", unit="photo", disable=args.quiet) as bar:
        capture = simulate(rig, mixture, noise, args.light_jitter, args.seed, on_photo=lambda k: bar.update(1))
    folder = write_capture(capture, args.out)
    w, h = rig.image_size
    noise_words = (f"Poisson-Gaussian noise, {args.photons:g} photons at radiance 1, read noise {args.read_noise:g} e-"
                   if args.photons else "no noise")
    print(f"wrote {folder}: {len(rig.shots)} photographs {w}x{h} ({len(rig.cameras)} camera(s), "
          f"{len(rig.lights)} light(s)), {len(mixture.sources)} layer(s) "
          f"({', '.join(s.name for s in mixture.sources)}), {noise_words}, light jitter {args.light_jitter:g}")
    return 0


def run_fit(args: argparse.Namespace) -> int:
    """``hbrdf acquire fit``: one progress bar per stage (analytic, clusters, merge, final clusters,
    network, texels, energy tables), a line per cluster and a message before writing; warnings on stderr."""
    import torch
    from tqdm import tqdm

    from hybridbrdf.acquire.acquisition import REPORT_FILE, acquire

    bars = {}

    def progress(stage: str, done: int, total: int) -> None:
        if stage not in bars:
            for bar in bars.values():
                bar.close()
            bars[stage] = tqdm(total=total, desc=stage, unit="step", disable=args.quiet)
        bar = bars[stage]
        bar.total = total
        bar.update(done - bar.n)

    say = (lambda msg: None) if args.quiet else (lambda msg: tqdm.write(msg))
    torch.set_num_threads(args.threads)
    try:
        maps = acquire(args.capture, args.out, prior=args.prior, size=args.size, steps=args.steps, seed=args.seed,
                       resume=args.resume, force=args.force, progress=progress, log=say,
                       warn=lambda msg: tqdm.write(msg, file=sys.stderr), refit_heads=args.refit_heads,
                       finetune_network=args.finetune_network, select=args.select, isotropic=not args.anisotropic)
    finally:
        for bar in bars.values():
            bar.close()
    h, w = maps.layer.shape
    tuned = maps.report["finetune_network"]  # the default depends on the capture's photographs
    print(f"wrote {os.path.abspath(args.out)}: a {w}x{h} textured material, {len(maps.layers)} layer(s) "
          f"({', '.join(maps.layers)}), fitted on {args.prior or 'the shipped prior'}"
          f"{', each cluster with its head refitted' if args.refit_heads else ''}"
          f"{f', the network fine-tuned {tuned} steps' if tuned else ''}"
          f"{', each cluster its material chosen on held-out photographs' if args.select else ''}"
          f"{', the azimuths as photographed' if args.anisotropic else ''}; the clusters and "
          f"their materials in {REPORT_FILE}")
    return 0


def add_parser(sub) -> None:
    """``hbrdf acquire`` and its subcommands (``simulate``, ``fit``)."""
    p = sub.add_parser("acquire", help=COMMANDS["acquire"],
                       description="SVBRDF acquisition from photographs (docs/ACQUISITION.md).")
    commands = p.add_subparsers(dest="acquire_command", required=True, metavar="{simulate,fit}")
    _add_simulate_parser(commands)
    _add_fit_parser(commands)


def _add_simulate_parser(commands) -> None:
    """``hbrdf acquire simulate``."""
    s = commands.add_parser(
        "simulate", help="photograph a flat sample, an exact mixture of measured BRDFs under masks",
        description="Photograph a flat sample whose SVBRDF is an exact mixture of measured BRDFs under grey masks "
                    "(composited as hbrdf paint does: the last --layer on top) with a rig, and write the capture "
                    "folder: one linear HDR OpenEXR per shot, rig.json, capture.json (the truth: noise, seed, the "
                    "lights' true positions, the layers) and weights.exr. Per pixel (one ray through its centre): "
                    "radiance = g(uv, wi, wo) cos(theta_i) I / d^2; pixels off the sample read 0 before noise. "
                    "OUT is replaced only when it is a capture folder (or empty), once complete.")
    rig = s.add_mutually_exclusive_group(required=True)
    rig.add_argument("--rig", metavar="RIG.json", help="a rig file (docs/ACQUISITION.md, the rig format)")
    rig.add_argument("--flash", type=_count(1, MAX_ITEMS), metavar="N",
                     help="a phone-style capture: N photographs, each lit by a flash 1 cm beside the lens, over a "
                          "50-degree cap at --distance (default 0.3)")
    rig.add_argument("--stage", type=_pair(int, 1, MAX_ITEMS, "KxV, K lights and V cameras"), metavar="KxV",
                     help="a light stage: K lights (a 75-degree cap) and V cameras (a 60-degree cap) at --distance "
                          "(default 1.0), every camera under every light: K*V photographs")
    s.add_argument("--size", type=_pair(int, 1, MAX_SIDE, "WxH pixels"), default=(256, 256), metavar="WxH",
                   help="photographs' size for --flash and --stage (default 256x256)")
    s.add_argument("--extent", type=_pair(float, 0, 1e6, "WxH, the sample's size"), default=(0.1, 0.1), metavar="WxH",
                   help="the sample's width and height in the rig's length unit, for --flash and --stage "
                        "(default 0.1x0.1)")
    s.add_argument("--distance", type=_number(0, 1e6, open_lo=True), metavar="D",
                   help="distance of the cameras and lights from the sample's centre, for --flash (default 0.3) "
                        "and --stage (default 1.0)")
    s.add_argument("--base", required=True, metavar="SOURCE",
                   help="layer 0: a measured file (.binary, .bsdf, .bin, .h5) or synthetic:NAME")
    s.add_argument("--layer", action="append", metavar="SOURCE=MASK",
                   help="a layer over the others (repeatable, at most 3): a measured file or synthetic:NAME and its "
                        "grey mask (PNG or EXR, the first channel; every mask the same size, the weights map's)")
    s.add_argument("--photons", type=_number(0, 1e12, open_lo=True), metavar="P",
                   help="Poisson-Gaussian noise: photoelectrons per channel at radiance 1 (a white Lambertian lit "
                        "head-on by a generated rig's light reads 1); default: no noise")
    s.add_argument("--read-noise", type=_number(0, 1e9), default=0.0, metavar="E",
                   help="the sensor's Gaussian read noise in electrons, with --photons (default 0)")
    s.add_argument("--light-jitter", type=_number(0, 1e6), default=0.0, metavar="S",
                   help="calibration error: each light rendered at its stated position plus a Gaussian offset of "
                        "standard deviation S per axis (rig units); rig.json keeps the stated positions (default 0)")
    s.add_argument("--seed", type=_count(0, 2 ** 63 - 1), default=0, help="seed of the noise and the jitter (default 0)")
    s.add_argument("--out", required=True, metavar="DIR", help="the capture folder to write")
    s.add_argument("--quiet", action="store_true", help="no progress bar")
    s.set_defaults(func=run_simulate)


def _add_fit_parser(commands) -> None:
    """``hbrdf acquire fit``."""
    f = commands.add_parser(
        "fit", help="fit per-texel maps on a frozen prior to a capture's photographs; write a textured material",
        description="Fit per-texel maps (analytic parameters p and latent code z per texel) on a hybrid prior "
                    "to the photographs of a capture (a capture folder, or a rig file beside its photographs) and "
                    "write a textured-material folder as hbrdf paint does (docs/SVBRDF.md): texels are clustered "
                    "(at most 4: the layers), each cluster starts at the prior's material that explains it best, "
                    "the prior's network is fine-tuned on the capture when it has 32 photographs or more, and "
                    "each texel is refined from its cluster's values, then shrunk toward them as far as the "
                    "texels' differences are noise. Prints a line per cluster (its texels, the "
                    "material chosen and the runner-up with their loss and relative error) and warns on stderr "
                    "when a cluster's best material leaves an error well above the noise; OUT/acquisition.json "
                    "records them. Photographs: float EXR/TIFF, or 8/16-bit PNG/TIFF decoded by capture.json's "
                    "\"photographs\" encoding (linear or srgb, scale, black_level); saturated pixels (a channel at "
                    "the largest code) and pixels that are not finite are left out (counted); photographs whose sample pixels mostly read below 3x the noise floor are left out "
                    "(counted); a capture with nothing usable is refused. A checkpoint beside OUT "
                    "(.OUT.acquire-checkpoint) lets --resume continue an interrupted run; OUT is written once "
                    "complete and replaced only when it is a textured material's folder (or empty).")
    f.add_argument("capture", metavar="CAPTURE", help="a capture folder (capture.json, rig.json, photographs) or a "
                                                     "rig file whose folder holds the photographs")
    f.add_argument("--out", required=True, metavar="DIR", help="the textured-material folder to write")
    f.add_argument("--prior", metavar="MODEL", help="a hybrid model file whose frozen network and materials the fit "
                                                    "uses (default: the shipped prior)")
    f.add_argument("--size", type=_pair(int, 1, MAX_SIDE, "WxH texels"), default=(128, 128), metavar="WxH",
                   help="the texel map's size (default 128x128)")
    f.add_argument("--steps", type=_count(1, 1000000), default=STEPS, metavar="N",
                   help=f"per-texel steps, each reading 8 rows of every texel (default {STEPS}; the analytic stage "
                        "runs N/2)")
    f.add_argument("--seed", type=_count(0, 2 ** 63 - 1), default=0, help="seed of the row draws and clusters (default 0)")
    f.add_argument("--threads", type=_count(1, 1024), default=1, metavar="N",
                   help="torch threads (default 1: on a busy 2-core machine two threads made a step 15-35x slower, "
                        "docs/ACQUISITION.md)")
    f.add_argument("--refit-heads", action="store_true",
                   help="refit each cluster's output layer (its material's head) to the cluster's photographs: each "
                        "cluster becomes a layer <material>.acq<k> of its own; an option, not a clear win "
                        "(docs/ACQUISITION_GAP.md); recorded in OUT/acquisition.json")
    f.add_argument("--finetune-network", type=_count(0, 1000000), default=None, metavar="N",
                   help="after the clusters, fine-tune the prior's network, each cluster's head and values on the "
                        "clusters' pure texels for N steps, the prior's materials replayed against its own output; "
                        "each cluster anchored where no photograph looked (it may not brighten there); the texels "
                        "are then fitted on the tuned network, which OUT's model carries; each cluster a layer "
                        f"<material>.acq<k> (default: {FINETUNE_STEPS} when the capture has at least "
                        f"{FINETUNE_MIN_SHOTS} photographs, else 0, docs/ACQUISITION_GAP.md; 0: off); the "
                        "replay's drift recorded in OUT/acquisition.json")
    f.add_argument("--select", action="store_true",
                   help="choose each cluster's prior material on held-out photographs: about a fifth of the shots "
                        "held out, the training shots' best 3 materials each fitted to the cluster's purest texels "
                        "on the rest, the lowest loss on the held-out shots kept and refitted on all; every "
                        "candidate's held-out loss printed and recorded in OUT/acquisition.json "
                        "(docs/ACQUISITION_GAP.md)")
    f.add_argument("--anisotropic", action="store_true",
                   help="fit the observations with the azimuths as photographed; by default each is turned about "
                        "the normal by its own azimuth (exact for an isotropic material, and it keeps the fit from "
                        "learning the rig's few azimuths: docs/ACQUISITION_GAP.md); recorded in OUT/acquisition.json")
    f.add_argument("--resume", action="store_true", help="continue the interrupted run's checkpoint (same settings)")
    f.add_argument("--force", action="store_true", help="start afresh over an existing checkpoint")
    f.add_argument("--quiet", action="store_true", help="no progress bars or messages (warnings still go to stderr)")
    f.set_defaults(func=run_fit)
