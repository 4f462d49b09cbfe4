"""The ``evaluate`` command: one simplified sequence against its original frames (the paper's Fig. 2)."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from torchmeshmetric.cli.options import add_command, common_options, evaluation_options, path_argument, report_options

__all__ = ["add_evaluate_command", "run"]


def run(args: argparse.Namespace) -> int:
    """Evaluate a simplified sequence against its original frames.

    For every simplified frame k >= 1: register original frame k-1 onto original frame k, measure the four distance
    sets from the simplified vertices (surface and nearest-vertex distance to frame k and to the registered frame
    k-1), print the paper's Tables I-IV and optionally write a report. Frames are paired by the frame numbers in
    their file names (the same numbers in both folders), or by natural sort order where a name has none; the counts
    must be equal.
    """
    from torchmeshmetric.cli._outputs import CLIError, check_writable, folder_inputs
    from torchmeshmetric.cli._shared import (
        determinacy_of,
        device_of,
        dtype_of,
        evaluate_methods,
        html_layers,
        kept_by,
        load_frames,
        mpeg_methods,
        report_paths,
        temporal_methods,
        write_reports,
    )
    from torchmeshmetric.evaluation.reports import paper_tables
    from torchmeshmetric.registration.cache import RegistrationCache

    device = device_of(args)
    folders = [("--original", args.original), ("--simplified", args.simplified)]
    paths = report_paths(args.out, args.mpeg, args.html, folders)
    inputs = folder_inputs("--original", args.original) + folder_inputs("--simplified", args.simplified)
    check_writable(list(paths.values()), args.overwrite, inputs=inputs, what="--out")
    original = load_frames(args.original, "--original", dtype_of(args))
    simplified = load_frames(args.simplified, "--simplified", dtype_of(args), (args.original, "--original"))
    if len(simplified) != len(original):  # named by the options: "method 'two'" named no option of this command
        raise CLIError(
            f"--simplified {args.simplified!r}: {len(simplified)} frames but --original {args.original!r} has "
            f"{len(original)} (must match)"
        )
    name = args.name or Path(args.simplified).resolve().name
    cache = RegistrationCache(args.cache_dir)  # kept: the --html page shows the best pair's registration
    results = evaluate_methods(original, {name: simplified}, args, device, cache=cache)
    determinacy, nudged = determinacy_of(original, {name: simplified}, results, args, device)
    if results is None:  # a torchrun rank other than 0: rank 0 reports
        return 0
    print(paper_tables(results, determinacy=determinacy, json_file=kept_by(args.out)))
    mpeg = mpeg_methods(original, {name: simplified}, args)
    temporal, determinacy = temporal_methods(
        original, {name: simplified}, args, device, cache=cache, determinacy=determinacy, nudged=nudged
    )
    settings = {
        "original": args.original,
        "methods": {name: args.simplified},
        "two_sided": not args.one_sided,
        "dtype": args.dtype,
        "determinacy": args.determinacy,
    }
    meshes = html_layers(results, original, {name: simplified}, cache, args) if paths else []
    write_reports(
        paths, results, settings, args.overwrite, mpeg, temporal=temporal, meshes=meshes, determinacy=determinacy
    )
    return 0


def add_evaluate_command(sub: Any) -> None:
    """Add the ``evaluate`` subcommand to the CLI's subparsers."""
    p = add_command(sub, "evaluate", run, [common_options(), evaluation_options(), report_options()])
    p.add_argument(
        "--original",
        type=path_argument,
        required=True,
        metavar="DIR",
        help="folder of the original frames (OBJ/PLY/OFF/STL/GLB)",
    )
    p.add_argument(
        "--simplified",
        type=path_argument,
        required=True,
        metavar="DIR",
        help="folder of the simplified frames, same count",
    )
    p.add_argument("--name", default=None, help="method name in the tables (default: the simplified folder's name)")
