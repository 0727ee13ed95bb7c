"""The ``hbrdf`` command line: ``fit``, ``add``, ``edit``, ``mix``, ``eval``, ``view``, ``info``, ``demo``, ``render``,
``paint``, ``bound``, ``acquire``.

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
import json
import math
import sys

from hybridbrdf import spec
from hybridbrdf.errors import one_line_text
from hybridbrdf.fit.settings import ADD_LOSS_EPS, ADD_STEPS, FitSettings, Number, parse_mlp
from hybridbrdf.sources import expand_sources, open_source
from hybridbrdf.version import __version__

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

def build_parser() -> argparse.ArgumentParser:
    """The ``hbrdf`` parser: one subcommand per command module's ``add_parser``."""
    # Here rather than at the top: each command module imports this package's helpers above.
    from hybridbrdf.cli import (acquire, add, bound, demo, edit, eval as eval_, fit, info, mix, paint, render,
                                view)

    parser = argparse.ArgumentParser(prog="hbrdf", description="Hybrid neural-microfacet BRDFs.", epilog=EPILOG)
    parser.add_argument("--version", action="version", version=f"hybridbrdf {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)
    for command in (fit, add, eval_, edit, mix, bound, paint, view, info, demo, render, acquire):
        command.add_parser(sub)
    return parser


def _reported_errors() -> tuple:
    """The exceptions main() prints as one line. A lost rank of a data-parallel fit is one; its
    class is PyTorch's side of the package, loaded only by a fit that could raise it."""
    errors = (ValueError, KeyError, OSError, FloatingPointError)
    distributed = sys.modules.get("hybridbrdf.fit.distributed")
    return errors + ((distributed.RankLostError,) if distributed is not None else ())


def main(argv=None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
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
