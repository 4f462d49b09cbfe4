"""The ``torchmeshmetric sample MESH OUT.ply`` command: a mesh to the point cloud mmetric's ``mm sample`` writes."""

from __future__ import annotations

import argparse
from typing import Any

__all__ = ["add_sample_command"]


def _run(args: argparse.Namespace) -> int:
    from pathlib import Path

    from torchmeshmetric._atomic import atomic_write
    from torchmeshmetric.cli._shared import check_writable
    from torchmeshmetric.mpeg.edge_sampling import edge_sample
    from torchmeshmetric.mpeg.face_sampling import face_sample
    from torchmeshmetric.mpeg.map_sampling import map_sample
    from torchmeshmetric.mpeg.model_files import point_cloud_ply_text
    from torchmeshmetric.mpeg.prnd_sampling import prnd_sample
    from torchmeshmetric.mpeg.subdivision_sampling import subdivision_sample
    from torchmeshmetric.mpeg.textured_mesh import load_textured_mesh

    out = Path(args.output)
    check_writable([out], args.overwrite)
    mesh = load_textured_mesh(args.mesh, args.texture)
    if args.mode == "face":
        pc = face_sample(mesh, resolution=args.resolution, thickness=args.thickness, bilinear=args.bilinear)
    elif args.mode == "map":
        pc = map_sample(mesh)
    elif args.mode == "prnd":
        pc = prnd_sample(mesh, num_samples=args.num_samples, bilinear=args.bilinear)
    elif args.mode == "ediv":
        pc = edge_sample(
            mesh, length_threshold=args.length_threshold, resolution=args.resolution, bilinear=args.bilinear
        )
    else:
        pc = subdivision_sample(
            mesh, max_depth=args.max_depth, area_threshold=args.area_threshold, bilinear=args.bilinear
        )
    atomic_write(out, point_cloud_ply_text(pc), overwrite=args.overwrite)
    print(f"Generated {pc.num_points} points -> {out}")
    return 0


def add_sample_command(sub: Any) -> None:
    """Add the ``sample`` subcommand to the CLI's subparsers."""
    p = sub.add_parser(
        "sample",
        help="a mesh to the point cloud mmetric's mm sample writes (face, sdiv, ediv, prnd, map)",
        description="Sample MESH as 'mm sample --mode face' (or sdiv, ediv, prnd, map) does and writes its PLY "
        "(byte for byte as mm writes it, except ediv, whose points come in another order). The grid "
        "sampling of the CTC is inside the 'mpeg' and 'ctc' commands.",
    )
    p.add_argument("mesh", metavar="MESH", help="mesh to sample (OBJ/PLY; OBJ with MTL + texture for colour)")
    p.add_argument("output", metavar="OUT", help="PLY file to write (never overwritten unless --overwrite)")
    p.add_argument(
        "--mode",
        choices=("face", "sdiv", "ediv", "prnd", "map"),
        default="face",
        help="mm sample --mode: face (default), sdiv, ediv, prnd or map (one point per texel; needs a texture)",
    )
    p.add_argument("--resolution", type=int, default=1024, help="steps along the bounding box's largest side (1024)")
    p.add_argument("--thickness", type=float, default=0.0, help="distance sampled either side of each face (0)")
    p.add_argument("--max-depth", type=int, default=100, help="sdiv: mm --maxDepth, 1 keeps the corners (100)")
    p.add_argument("--area-threshold", type=float, default=1.0, help="sdiv: faces at least this large are split (1.0)")
    p.add_argument(
        "--length-threshold",
        type=float,
        default=0.0,
        help="ediv: mm --lengthThreshold, edges split while half as long; 0 = box side / --resolution (0)",
    )
    p.add_argument("--num-samples", type=int, default=2000000, help="prnd: mm --nbSamples, the target count (2e6)")
    p.add_argument("--bilinear", action="store_true", help="bilinear texture filtering (default nearest, as mm)")
    p.add_argument("--texture", default=None, metavar="IMG", help="texture of MESH (overrides its MTL)")
    p.add_argument("--overwrite", action="store_true", help="replace OUT if it exists")
    p.set_defaults(func=_run)
