"""The ``compare`` command: several simplification methods on one original sequence (Tables I-IV side by side)."""

from __future__ import annotations

import argparse
from typing import Any

from torchmeshmetric.cli.options import (
    add_command,
    common_options,
    evaluation_options,
    parse_fraction,
    path_argument,
    report_options,
)

__all__ = ["add_compare_command", "run"]


def run(args: argparse.Namespace) -> int:
    """Compare several simplification methods (Tables I-IV side by side).

    Evaluate several simplified versions of one original sequence; registrations of the original frames are computed
    once and shared by all methods. With two or more methods, every pair of methods is compared set by set: the mean
    difference over frame pairs, its 95% paired t interval and a verdict ('<A> better', '<B> better' or
    'inconclusive': the interval contains 0, or the difference is below the registration's noise floor (k-1 and
    flicker sets) or the relative margin), in the report's 'comparisons' and as verdict tables.
    """
    from torchmeshmetric.cli._outputs import check_writable, folder_inputs
    from torchmeshmetric.cli._shared import (
        determinacy_of,
        device_of,
        dtype_of,
        evaluate_methods,
        html_layers,
        kept_by,
        load_frames,
        mpeg_methods,
        parse_methods,
        report_paths,
        temporal_methods,
        write_reports,
    )
    from torchmeshmetric.evaluation.comparison import compare_methods, comparison_markdown, with_nudged_verdicts
    from torchmeshmetric.evaluation.reports import paper_tables
    from torchmeshmetric.registration.cache import RegistrationCache

    device = device_of(args)
    specs = parse_methods(args.method)
    folders = [("--original", args.original)] + [(f"--method {n}", d) for n, d in specs.items()]
    paths = report_paths(args.out, args.mpeg, args.html, folders)
    inputs = folder_inputs("--original", args.original)
    for name, folder in specs.items():
        inputs += folder_inputs(f"--method {name}", folder)
    check_writable(list(paths.values()), args.overwrite, inputs=inputs, what="--out")
    original = load_frames(args.original, "--original", dtype_of(args))
    frames = {
        name: load_frames(d, f"--method {name}", dtype_of(args), (args.original, "--original"))
        for name, d in specs.items()
    }
    cache = RegistrationCache(args.cache_dir)  # kept: the --html page shows the best pair's registration
    results = evaluate_methods(original, frames, args, device, cache=cache)
    determinacy, nudged = determinacy_of(original, frames, results, args, device)
    if results is None:  # a torchrun rank other than 0: rank 0 reports
        return 0
    print(paper_tables(results, determinacy=determinacy, json_file=kept_by(args.out)))
    mpeg = mpeg_methods(original, frames, args)
    temporal, determinacy = temporal_methods(
        original, frames, args, device, cache=cache, determinacy=determinacy, nudged=nudged
    )
    comparisons = None
    if len(results) >= 2:
        comparisons = compare_methods(results, relative_margin=args.relative_margin)
        if nudged is not None and nudged.results is not None:  # --determinacy: is each verdict the input's?
            again = compare_methods(nudged.results, relative_margin=args.relative_margin)
            comparisons = with_nudged_verdicts(comparisons, again)
        print("## Comparisons with confidence\n\n" + comparison_markdown(comparisons))
    settings = {
        "original": args.original,
        "methods": specs,
        "two_sided": not args.one_sided,
        "relative_margin": args.relative_margin,
        "dtype": args.dtype,
        "determinacy": args.determinacy,
    }
    meshes = html_layers(results, original, frames, cache, args) if paths else []
    write_reports(
        paths, results, settings, args.overwrite, mpeg, comparisons, temporal, meshes=meshes, determinacy=determinacy
    )
    return 0


def add_compare_command(sub: Any) -> None:
    """Add the ``compare`` subcommand to the CLI's subparsers."""
    p = add_command(sub, "compare", run, [common_options(), evaluation_options(), report_options()])
    p.add_argument("--original", type=path_argument, required=True, metavar="DIR", help="folder of the original frames")
    p.add_argument(
        "--method",
        required=True,
        action="append",
        metavar="NAME=DIR",
        help="a method's name and the folder of its simplified frames; repeat for every method",
    )
    p.add_argument(
        "--relative-margin",
        type=parse_fraction,  # -1 or nan was refused after the whole registration and evaluation (found by review)
        default=0.02,
        metavar="FRACTION",
        help="differences below this fraction of the better method's value are 'inconclusive' (default 0.02; "
        "0 relies on the interval and the registration's noise floor alone)",
    )
