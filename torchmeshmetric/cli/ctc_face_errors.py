"""The ``torchmeshmetric ctc-face-errors`` command: one decoded frame's CTC errors per face, as PLY and CSV.

Only the standard library is imported here (``--help`` stays fast); the metrics load when the command runs.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from torchmeshmetric._console import say
from torchmeshmetric.cli.options import add_command, ctc_options, output_stem, path_argument

__all__ = ["add_ctc_face_errors_command", "run"]

_COLOR_BY = ("d1_mean", "d1_max", "d2_mean", "d2_max", "y_mean", "y_max", "cb_mean", "cb_max", "cr_mean", "cr_max")


def run(args: argparse.Namespace) -> int:
    """A decoded frame's CTC grid-sample errors per face (D1, D2, colour; mean and max), as PLY and CSV.

    Runs the ctc command's chain on one frame pair (dequantize --useFixedPoint over the sequence box, reindex --sort
    oriented, grid sampling, duplicate merging) and gives every face of the decoded mesh (--side decoded; --side
    source: of the source) the mean and the largest error of the samples it produced: squared point-to-point (D1)
    and point-to-plane (D2) errors against the other frame's samples, squared Y, Cb, Cr differences when both have
    colour. Writes OUT.ply (the dequantised, reindexed mesh with every error as a face property and a face colour
    from --color-by) and OUT.csv (one row per face, the PLY's face order), what mmetric's per-point output shows,
    gathered on the faces a viewer draws.
    """
    from torchmeshmetric.cli._outputs import CLIError, check_writable

    lo, hi = ctc_options(args, [("--grid-size", args.grid_size, 2, 1 << 20)])
    if args.color_by not in _COLOR_BY:
        raise CLIError(f"--color-by: expected one of {', '.join(_COLOR_BY)}, found {args.color_by!r}")
    args.out = output_stem(args.out, "--out", (".ply", ".csv"))  # OUT or OUT.ply: never OUT.ply.ply
    outputs = [Path(f"{args.out}.ply"), Path(f"{args.out}.csv")]
    inputs = [
        ("--reference", args.reference),
        ("--reference-texture", args.reference_texture),
        ("--decoded", args.decoded),
        ("--decoded-texture", args.decoded_texture),
    ]
    check_writable(outputs, args.overwrite, inputs=inputs, what="--out")
    from torchmeshmetric.cli._outputs import output_set
    from torchmeshmetric.cli.ctc import load_ctc_mesh
    from torchmeshmetric.mpeg.ctc.face_errors import ctc_face_errors, write_face_errors_csv, write_face_errors_ply
    from torchmeshmetric.mpeg.ctc.settings import CtcSettings

    ref = load_ctc_mesh(args.reference, args.reference_texture, "--reference")
    dis = load_ctc_mesh(args.decoded, args.decoded_texture, "--decoded")
    settings = CtcSettings(qp=args.qp, qt=args.qt, min_pos=lo, max_pos=hi, decoded_qt=args.decoded_qt,
                           grid_size=args.grid_size)  # fmt: skip
    errors = ctc_face_errors(ref, dis, settings, side=args.side)
    if args.color_by[:2] in ("y_", "cb", "cr") and errors.color_mean is None:
        raise ValueError(f"--color-by {args.color_by}: the frames have no colour (texture or vertex colours)")
    with output_set("the per-face errors"):
        write_face_errors_ply(outputs[0], errors, color_by=args.color_by, overwrite=args.overwrite)
        write_face_errors_csv(outputs[1], errors, overwrite=args.overwrite)
    sampled = int((errors.samples > 0).sum())
    say(
        f"{errors.samples.shape[0]} faces ({sampled} with samples, {int(errors.samples.sum())} samples); "
        f"wrote {outputs[0]}, {outputs[1]}"
    )
    return 0


def add_ctc_face_errors_command(sub: Any) -> None:
    """Add the ``ctc-face-errors`` subcommand to the CLI's subparsers."""
    p = add_command(sub, "ctc-face-errors", run)
    p.add_argument("--reference", type=path_argument, required=True, metavar="OBJ", help="the quantised source frame")
    p.add_argument("--decoded", type=path_argument, required=True, metavar="OBJ", help="the decoded frame")
    p.add_argument("--qp", type=int, required=True, help="geometry bit depth (mm dequantize --qp)")
    p.add_argument("--qt", type=int, required=True, help="UV bit depth of the source (mm dequantize --qt)")
    p.add_argument("--decoded-qt", type=int, default=0, help="UV bit depth of the decoded frame (test model: 0)")
    p.add_argument("--min-pos", required=True, metavar='"X Y Z"', help="the sequence box's min corner (--minPos)")
    p.add_argument("--max-pos", required=True, metavar='"X Y Z"', help="the sequence box's max corner (--maxPos)")
    p.add_argument(
        "--reference-texture", type=path_argument, default=None, metavar="PNG", help="source texture (default: MTL)"
    )
    p.add_argument(
        "--decoded-texture", type=path_argument, default=None, metavar="PNG", help="decoded texture (default: MTL)"
    )
    p.add_argument("--grid-size", type=int, default=1024, metavar="N", help="sample --gridSize (default 1024)")
    p.add_argument(
        "--side",
        choices=("decoded", "source"),
        default="decoded",
        help="whose faces: the decoded frame's (its samples against the source's) or the source's",
    )
    p.add_argument(
        "--color-by",
        default="d1_mean",
        metavar="ERROR",
        help=f"the PLY's face colour: one of {', '.join(_COLOR_BY)} (default d1_mean)",
    )
    p.add_argument(
        "--out", type=path_argument, required=True, metavar="OUT", help="write OUT.ply and OUT.csv (OUT or OUT.ply)"
    )
    p.add_argument("--overwrite", action="store_true", help="replace existing OUT.ply / OUT.csv")
