"""The ``validate`` command: which distance sets respond to which controlled distortion."""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path
from typing import Any

from torchmeshmetric._console import say
from torchmeshmetric.cli.options import add_command, add_seed, as_option_error, int_in_range, parse_ratio, path_argument
from torchmeshmetric.evaluation._validation_names import DISTORTIONS

__all__ = ["add_validate_command", "distortion_names", "run"]


def distortion_names(text: str) -> list[str]:
    """``--distortions``: comma-separated names of the study's distortions, refused when parsed (exit 2).

    ``","`` and ``""`` name none: the first ran nothing and died on its empty tables, the second ran every
    distortion as if the option were not given (found by review).

    Example:
        >>> distortion_names("noise, sliding")
        ['noise', 'sliding']
    """
    names = [n.strip() for n in text.split(",") if n.strip()]
    expected = f"comma-separated names from {', '.join(DISTORTIONS)}"
    if not names:
        raise argparse.ArgumentTypeError(f"expected {expected}, found {text!r} (no name)")
    unknown = [n for n in names if n not in DISTORTIONS]
    if unknown:
        raise argparse.ArgumentTypeError(f"expected {expected}, found {', '.join(map(repr, unknown))}")
    return names


def run(args: argparse.Namespace) -> int:
    """Validation study: which distance sets respond to which controlled distortion.

    On the built-in sequence (true motion known): a tracked simplification, evaluated with the true registration,
    distorted at 6 strengths by frame-k noise, simplification level, constant and alternating normal offsets,
    sliding along the surface, per-frame re-simplification and registration error. Prints and writes the Spearman
    rank correlation between strength and each set's statistics and the relative change (validation.md/.json,
    validation.png). The default (reduced) size takes well under 2 minutes on 2 CPU cores; --full is the paper's
    frame size (docs/validation.md).
    """
    from torchmeshmetric._atomic import atomic_write
    from torchmeshmetric._checks import SizeLimitError
    from torchmeshmetric._format import json_safe
    from torchmeshmetric.cli._outputs import check_creatable, check_folder, check_writable, make_folder, output_set
    from torchmeshmetric.evaluation.validation import (
        FULL,
        REDUCED,
        STRENGTHS,
        check_validation_arguments,
        run_validation,
    )
    from torchmeshmetric.viz.validation import plot_validation

    preset = dict(FULL if args.full else REDUCED)
    for key in ("frames", "resolution", "keep"):
        if getattr(args, key) is not None:
            preset[key] = getattr(args, key)
    # --frames, --resolution, --keep and --distortions were refused when parsed (exit 2, with the library's bounds:
    # tests/cli/test_demo.py), so this check, which names the library's arguments, only gives the distortions' names
    names = check_validation_arguments(
        frames=preset["frames"], resolution=preset["resolution"], keep=preset["keep"], distortions=args.distortions
    )
    out_dir = Path(args.out_dir)
    paths = [out_dir / "validation.json", out_dir / "validation.md"] + (
        [] if args.no_plots else [out_dir / "validation.png"]
    )
    check_folder(out_dir, "--out-dir", may_create=True)  # created with the files, so a failed run leaves none
    check_creatable(out_dir, "--out-dir")
    if out_dir.is_dir():
        check_writable(paths, args.overwrite, inputs=[], what="--out-dir")
    # The time is linear in both: say what was asked for before minutes of work
    say(
        f"validate: {len(names)} distortions x {STRENGTHS} strengths, each an evaluation of {preset['frames'] - 1} "
        f"frame pairs at resolution {preset['resolution']}"
    )
    start = time.perf_counter()
    try:
        result = run_validation(
            seed=args.seed,
            distortions=names,
            progress=lambda n: say(f"validate: {n} done ({time.perf_counter() - start:.1f} s)"),
            **preset,
        )
    except SizeLimitError as exc:  # the built-in sequence's size check (before any frame is made)
        raise as_option_error(exc, {"num_frames": "--frames", "resolution": "--resolution"}) from None
    settings = result.settings
    title = (
        f"# torchmeshmetric validation study\n\nBuilt-in sequence, {settings['frames']} frames at resolution "
        f"{settings['resolution']} (~{settings['faces_per_frame']} faces), tracked QEM simplification keeping "
        f"{settings['keep']:g} of the faces, true registration (residual Ave {result.registration['ave']:.3g}); "
        f"{'two-sided' if settings['two_sided'] else 'one-sided'}; {result.seconds:.1f} s.\n\n"
    )
    text = result.markdown()
    print(title + text)
    with output_set("the validation study") as files:  # all three files or none
        make_folder(out_dir, "--out-dir", files)
        report = json.dumps(json_safe(result.as_dict()), indent=2, allow_nan=False) + "\n"
        atomic_write(paths[0], report, overwrite=args.overwrite)
        atomic_write(paths[1], title + text, overwrite=args.overwrite)
        if not args.no_plots:
            plot_validation(result, paths[2], overwrite=args.overwrite)
    say(f"wrote {', '.join(str(p) for p in paths)}")
    return 0


def add_validate_command(sub: Any) -> None:
    """Add the ``validate`` subcommand to the CLI's subparsers."""
    p = add_command(sub, "validate", run)
    p.add_argument("--full", action="store_true", help="6 frames at resolution 160 (~40k faces), two-sided")
    p.add_argument(
        "--frames",
        type=int_in_range(3, 24),  # validation.MAX_FRAMES; refused when parsed (exit 2), as docs/cli.md says
        default=None,
        help="frames of the built-in sequence, 3 to 24 (reduced default 4)",
    )
    p.add_argument(
        "--resolution", type=int_in_range(16), default=None, help="mesh resolution, >= 16 (reduced default 48)"
    )
    p.add_argument(
        "--keep",
        type=parse_ratio,
        default=None,
        help="fraction of faces the tracked simplification keeps, in (0, 1] (default 0.5)",
    )
    add_seed(p, "seed of the sequence and the distortions (default 0; 0 to 2**63-1)")
    p.add_argument(
        "--distortions",
        type=distortion_names,
        default=None,
        metavar="A,B,...",
        help=f"only these distortions, comma-separated: {', '.join(DISTORTIONS)} (default all)",
    )
    p.add_argument(
        "--out-dir",
        type=path_argument,
        default="torchmeshmetric-validation",
        metavar="DIR",
        help="output folder (default torchmeshmetric-validation, in the current folder)",
    )
    p.add_argument("--overwrite", action="store_true", help="replace existing output files")
    p.add_argument("--no-plots", action="store_true", help="skip validation.png")
