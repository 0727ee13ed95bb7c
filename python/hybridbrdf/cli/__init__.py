"""The ``hbrdf`` command line: ``fit``, ``add``, ``edit``, ``mix``, ``eval``, ``view``, ``info``, ``demo``, ``render``,
``raster``, ``paint``, ``bound``, ``acquire``.

``hbrdf <command> --help`` documents every flag. The fit flags, their help and defaults are
generated from :class:`hybridbrdf.fit.settings.FitSettings` (:func:`add_fit_flags`), and so is the
README's synopsis of ``hbrdf fit`` (:func:`fit_synopsis`; a test keeps the README current).

One module per command (``hybridbrdf.cli.<command>``), each with ``add_parser(sub)`` and ``run(args)``.
Building the parser imports no PyTorch: ``hbrdf --help`` and a mistyped flag answer at once, and
each command imports what it runs (the fit, the tracer, the viewer) only in ``run``.

A SOURCE is a file (.binary MERL, .bsdf RGL, .bin UTIA, .h5 NBRDF), a folder, a
glob, or synthetic:NAME (synthetic:all for every built-in material).
Errors are printed as one line on stderr with a non-zero exit status.
"""

from __future__ import annotations

import argparse
import dataclasses
import importlib
import json
import math
import sys

from hybridbrdf import spec
from hybridbrdf.errors import one_line_text
from hybridbrdf.fit.settings import ADD_LOSS_EPS, ADD_STEPS, FitSettings, Number, parse_mlp
from hybridbrdf.version import __version__

#: The commands in the order ``hbrdf --help`` lists them, each with its line there (its module's
#: ``add_parser`` uses the same). A command line builds only its own command's parser: the others'
#: names and lines are all ``--help`` and argparse's choice of command need (:func:`build_parser`).
COMMANDS = {
    "fit": "fit one shared network + per-material parameters to BRDF sources",
    "add": "add BRDF sources to the shipped prior (fine-tuned) or to a model (network kept)",
    "eval": "per-material SMAPE/cMAE of a model against BRDF sources",
    "edit": "add an edited copy of a material (new analytic parameters, same latent code)",
    "mix": "add a blend of two materials (analytic parameters and latent codes)",
    "bound": "fit energy-bound tables so that no material reflects more light than it receives",
    "paint": "paint a textured material: layers of materials under grey masks (docs/SVBRDF.md)",
    "export": "write a glTF 2.0 asset: a fitted metallic-roughness fallback and the hybrid material itself (docs/GLTF.md)",
    "convert": "rewrite a textured material's maps: PNG, EXR or KTX2 block formats, with or without mip chain",
    "view": "write one self-contained HTML page that shows the materials live (WebGPU or WebGL2)",
    "info": "describe a model file",
    "demo": "plot BRDF slices of built-in analytic materials and print their albedo",
    "render": "render a scene with the Embree path tracer",
    "raster": "draw a scene with a Vulkan raster pipeline and the generated GLSL (docs/RASTER.md)",
    "acquire": "SVBRDF acquisition from photographs: simulated captures (docs/ACQUISITION.md)",
}

EPILOG = ("SOURCE: a file (.binary MERL, .bsdf RGL, .bin UTIA, .h5 NBRDF network), a folder, a glob, "
          "or synthetic:NAME (synthetic:all = every built-in material).")

#: A number flag of the command line: finite (nan and inf say nothing about a scene or a blend);
#: the library checks each value's own range.
FINITE = Number(float, -math.inf, math.inf)

#: A loop that can run for minutes shows a progress bar on stderr: on a terminal from the start,
#: elsewhere (a log) once it has run this many seconds, and then a line every PROGRESS_LOG_S.
PROGRESS_DELAY_S = 3.0
PROGRESS_LOG_S = 10.0


def progress_bar(iterable, total: int, desc: str, unit: str, quiet: bool = False):
    """``iterable`` with a progress bar on stderr (tqdm) unless ``quiet``: drawn at once when stderr
    is a terminal, else only after :data:`PROGRESS_DELAY_S` seconds, so quick runs and pipes
    stay clean. Print lines meanwhile with :func:`print_beside`, which does not tear it."""
    from tqdm import tqdm

    tty = sys.stderr.isatty()
    return tqdm(iterable, total=total, desc=desc, unit=unit, file=sys.stderr, disable=quiet, leave=False,
                delay=0.0 if tty else PROGRESS_DELAY_S, mininterval=0.1 if tty else PROGRESS_LOG_S)


def print_beside(bar, line: str) -> None:
    """``line`` on stdout while ``bar`` runs: through ``bar.write`` (which clears and redraws it)
    when both go to one terminal, else a plain print (a redraw would write the bar into a log)."""
    if sys.stdout.isatty() and sys.stderr.isatty():
        bar.write(line, file=sys.stdout)
    else:
        print(line, flush=True)


def _open_all(specs):
    from hybridbrdf.sources import expand_sources, open_source  # NumPy: not for --help

    return [open_source(s) for s in expand_sources(specs)]


def log_function(quiet: bool):
    """Where a command's log messages go: stderr, or nowhere with --quiet."""
    return (lambda msg: None) if quiet else (lambda msg: print(msg, file=sys.stderr))


# ---- the fit flags, generated from FitSettings ------------------------------------------------

def _fit_fields():
    return [f for f in dataclasses.fields(FitSettings) if f.metadata.get("flag")]


def add_fit_flags(parser: argparse.ArgumentParser, sections=None, skip=()) -> None:
    """``hbrdf fit``'s setting flags, one per FitSettings field that has one (only those of
    ``sections`` when given, and none of the fields named in ``skip``)."""
    for f in _fit_fields():
        m = f.metadata
        if (sections is not None and m["section"] not in sections) or f.name in skip:
            continue
        kwargs = dict(m["cli"])
        if kwargs.get("action") not in ("store_true", "store_false"):
            kwargs["default"] = None  # unset: FitSettings' default (shown in the help text)
        parser.add_argument(m["flag"], dest=f.name, help=m["help"].replace("%(default)s", str(f.default)), **kwargs)


def settings_from_args(args: argparse.Namespace, sparse: bool = False):
    """FitSettings from parsed flags: a flag left unset keeps its value in the recipe
    (``--recipe``, default hybridbrdf: the fields' defaults). ``sparse``: the settings of a
    sparse fit (``hbrdf add``), whose steps default to :data:`~hybridbrdf.fit.settings.ADD_STEPS` and
    (without --recipe) its loss epsilon to :data:`~hybridbrdf.fit.settings.ADD_LOSS_EPS`."""
    from hybridbrdf.fit.joint import default_device  # PyTorch: asks it for a GPU

    values = {}
    for f in _fit_fields():
        v = getattr(args, f.name, None)  # a command may offer a subset of the flags (hbrdf add)
        if v is not None:
            values[f.name] = v
    if "width" in values:  # --mlp WIDTHxDEPTH sets two fields
        values["width"], values["depth"] = parse_mlp(values["width"])
    if "latent" not in values and spec.ARCHS.get(values.get("arch"), {}).get("analytic") is False:
        values["latent"] = 12  # no analytic part: the hybrid's l = 4 plus its 8 analytic parameters
    if sparse:
        values.setdefault("steps", ADD_STEPS)
        if "recipe" not in values:  # hbrdf add's own loss epsilon, unless a recipe sets one
            values.setdefault("loss_eps", ADD_LOSS_EPS)
    values.setdefault("device", default_device())
    return FitSettings.from_recipe(values.pop("recipe", "hybridbrdf"), sources=list(args.sources), **values)


def fit_synopsis() -> str:
    """The README's synopsis of the fit flags, generated from FitSettings."""
    parts = []
    for f in _fit_fields():
        m = f.metadata
        action = m["cli"].get("action")
        if action in ("store_true", "store_false"):
            parts.append(f"[{m['flag']}]")
            continue
        if "choices" in m["cli"]:
            value = "|".join(m["cli"]["choices"])
        elif f.name == "width":
            value = f"{f.default}x3"
        else:
            value = m["cli"].get("metavar") or (str(f.default) if f.default is not None else "X")
        parts.append(f"[{m['flag']} {value}]")
    lines, line = [], "hbrdf fit SOURCE... --out MODEL"
    for part in parts:
        if len(line) + 1 + len(part) > 96:
            lines.append(line)
            line = "         " + part
        else:
            line += " " + part
    lines.append(line)
    return "\n".join(lines)


def add_quiet_flag(parser: argparse.ArgumentParser, shown_while: str) -> None:
    """The ``--quiet`` flag of a command whose progress bar appears only once a loop runs long
    (:func:`progress_bar`); ``shown_while`` says which loop ("the tables are fitted")."""
    parser.add_argument("--quiet", action="store_true",
                        help=f"no progress bar (shown on stderr while {shown_while}: at once on a terminal, "
                             "elsewhere after a few seconds)")


def layer_masks(values, what: str) -> list:
    """``--layer`` values ``WHAT=MASK`` as (what, mask) pairs (the last '=' splits: a source may hold
    one); ``what`` names the left side in the error (hbrdf paint, hbrdf acquire simulate)."""
    layers = []
    for v in values or []:
        name, sep, mask = v.rpartition("=")
        if not sep or not name or not mask:
            raise ValueError(f"--layer takes {what}=MASK, got {v!r}")
        layers.append((name, mask))
    return layers


def _shown(value) -> str:
    """A value from a model file's free-form records (training, metrics, origin) as ``hbrdf
    info`` prints it: floats with 6 significant digits, anything else as one printable line.
    Those records are informative, not part of the contract, so no value of them may stop info."""
    if isinstance(value, (bool, int)):
        return str(value)
    if isinstance(value, float):
        text = f"{value:.6g}"
        return text if any(c in text for c in ".enia") else text + ".0"  # a float still reads as one
    return one_line_text(value if isinstance(value, str) else json.dumps(value, default=str)[:200])


def _settings_line(title: str, recorded: dict, sections, extra=()) -> str:
    """``title: key value, ...`` for the FitSettings fields of ``sections`` a model file records."""
    keys = [f.name for f in dataclasses.fields(FitSettings) if f.metadata["section"] in sections
            and f.name != "sources"] + list(extra)
    return f"{title}: " + ", ".join(f"{k} {_shown(recorded[k])}" for k in keys if recorded.get(k) is not None)


# ---- the parser and the entry point -----------------------------------------------------------

def build_parser(only: str = None) -> argparse.ArgumentParser:
    """The ``hbrdf`` parser: one subcommand per command module's ``add_parser`` (:data:`COMMANDS`).
    With ``only`` (a command's name, or ``""`` for none), every other command is a placeholder of
    its name and line, and its module is not imported: what :func:`main` builds, so that ``hbrdf
    --help`` and an argument error import no command's dependencies (NumPy among them)."""
    parser = argparse.ArgumentParser(prog="hbrdf", description="Hybrid neural-microfacet BRDFs.", epilog=EPILOG)
    parser.add_argument("--version", action="version", version=f"hybridbrdf {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)
    for name, line in COMMANDS.items():
        if only is None or name == only:
            # Here rather than at the top: each command module imports this package's helpers above.
            importlib.import_module(f"{__name__}.{name}").add_parser(sub)
        else:
            sub.add_parser(name, help=line, add_help=False)
    return parser


def _command_of(argv) -> str:
    """The command an ``hbrdf`` command line names ("" when none: ``--help``, ``--version``, a
    typo); ``hbrdf`` itself has no option that takes a value, so it is the first word that is no option."""
    for word in argv:
        if word in ("-h", "--help", "--version"):
            return ""
        if not word.startswith("-"):
            return word if word in COMMANDS else ""
    return ""


def _reported_errors() -> tuple:
    """The exceptions main() prints as one line. A lost rank of a data-parallel fit is one; its
    class is PyTorch's side of the package, loaded only by a fit that could raise it."""
    errors = (ValueError, KeyError, OSError, FloatingPointError)
    distributed = sys.modules.get("hybridbrdf.fit.distributed")
    return errors + ((distributed.RankLostError,) if distributed is not None else ())


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    args = build_parser(only=_command_of(argv)).parse_args(argv)
    try:
        return args.func(args)
    except KeyboardInterrupt as exc:
        # A fit stopped between steps says how far it got and where its checkpoint is.
        print(f"hbrdf {args.command}: {exc if str(exc) else 'interrupted'}", file=sys.stderr)
        return 130
    except Exception as exc:
        if not isinstance(exc, _reported_errors()):
            raise
        msg = exc.args[0] if isinstance(exc, KeyError) and exc.args else str(exc)
        print(f"hbrdf {args.command}: error: {one_line_text(str(msg))}", file=sys.stderr)  # one line, always
        return 1
