"""``hbrdf export``: a model's materials or a textured material as a glTF 2.0 asset (docs/GLTF.md)."""

from __future__ import annotations

import argparse

from hybridbrdf.cli import COMMANDS


def add_parser(sub) -> None:
    p = sub.add_parser("export", help=COMMANDS["export"],
                       description="Write a GLB that any glTF 2.0 viewer opens: one mesh per material, each with a "
                                   "metallic-roughness material (KHR_materials_ior, _specular, _anisotropy) fitted to "
                                   "the material's analytic part f_a, and the HBRDF_hybrid_material extension carrying "
                                   "the hybrid material itself (the model file, or the textured material's folder), "
                                   "which hybridbrdf.gltf.read_hybrid reads back bit for bit. Prints each fallback's "
                                   "SMAPE/cMAE against f_a and against the hybrid (docs/GLTF.md). A fit takes a few "
                                   "seconds of CPU per material.")
    p.add_argument("source", metavar="MODEL_OR_SVBRDF",
                   help="a model file (.safetensors) or a textured material's folder (holding svbrdf.json)")
    p.add_argument("--gltf", required=True, metavar="OUT.glb", help="the GLB to write (replaced once complete)")
    p.add_argument("--mesh", default="sphere", metavar="sphere|plane|FILE.obj",
                   help="the geometry each material is shown on: a UV sphere, a plane, or a Wavefront OBJ "
                        "(default: %(default)s)")
    p.add_argument("--material", nargs="+", metavar="NAME",
                   help="the model's materials to export (default: all of them; not for a textured material)")
    p.add_argument("--quiet", action="store_true", help="print nothing but errors")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    import os

    from hybridbrdf.gltf import export_gltf

    if args.material and os.path.isdir(args.source):
        raise ValueError("--material names materials of a model file; a textured material is exported whole")

    def progress(name, report):
        if args.quiet:
            return
        line = f"{name}: kept {report.kept}"
        for (which, against), (s, c) in sorted(report.metrics.items()):
            line += f"; {which} vs {against} SMAPE {s:.4f} cMAE {c:.5f}"
        print(line, flush=True)

    reports = export_gltf(args.source, args.gltf, mesh=args.mesh, materials=args.material, progress=progress)
    if not args.quiet:
        print(f"wrote {args.gltf}: {len(reports)} material(s) on {os.path.basename(args.mesh)}")
    return 0
