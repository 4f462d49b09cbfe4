"""The ``simplify`` command: every frame of a sequence simplified with QEM or Registered QEM."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from torchmeshmetric._console import say
from torchmeshmetric.cli.options import (
    add_cache_dir,
    add_command,
    add_target,
    add_weight,
    common_options,
    path_argument,
)

__all__ = ["add_simplify_command", "run"]


def run(args: argparse.Namespace) -> int:
    """Simplify every frame of a sequence with QEM or Registered QEM.

    Simplify each frame of --input into --output (same file names). 'rqem' (Registered QEM) also uses the previous
    original frame registered onto the current one; 'tracking' (Anchored QEM with the learned slide) makes each frame
    follow the previous simplified frame moved by that registration; frame 0 is simplified with QEM.
    """
    from torchmeshmetric._checks import EmptyInputError
    from torchmeshmetric.cli._outputs import (
        CLIError,
        check_folder,
        check_mesh_suffixes,
        check_writable,
        folder_inputs,
        make_folder,
        output_set,
    )
    from torchmeshmetric.cli._shared import (
        device_of,
        dtype_of,
        load_frames,
        simplify_frames,
    )
    from torchmeshmetric.data.frames import list_frames
    from torchmeshmetric.data.io import save_mesh
    from torchmeshmetric.evaluation.pipeline import register_pairs
    from torchmeshmetric.registration.cache import RegistrationCache

    if args.weight is not None and args.method == "qem":  # plain QEM has no weight: it was ignored in silence
        raise CLIError("--weight: applies to --method rqem and tracking, not qem")
    device = device_of(args)
    frames = load_frames(args.input, "--input", dtype_of(args))
    names = [Path(p).name for p in list_frames(args.input)]
    out_dir = Path(args.output)
    targets = [out_dir / n for n in names]
    check_mesh_suffixes(targets, "--output", names_from="--input")
    check_folder(out_dir, "--output", may_create=True)
    if out_dir.is_dir():
        check_writable(targets, args.overwrite, inputs=folder_inputs("--input", args.input), what="--output")
    from torchmeshmetric.simplification._target import resolve_target

    def target_error(name: str, exc: Exception) -> CLIError:
        """The library's ``target: ...`` retold about the option and the frame."""
        return CLIError(f"--target: frame {name!r}: {str(exc).removeprefix('target: ')}")

    for name, frame in zip(names, frames, strict=True):  # before the registrations, naming the option and the frame
        try:
            resolve_target(args.target, frame.num_faces)
        except (TypeError, ValueError) as exc:
            raise target_error(name, exc) from exc
    registrations = None
    if args.method in ("rqem", "tracking"):
        cache = RegistrationCache(args.cache_dir)
        registrations = register_pairs(frames, registration_cache=cache, device=device, backend=args.backend)
    # A target that collapses every face (a closed mesh asked for 1 or 2) is found by QEM while it simplifies, in a
    # message that named neither the option nor the frame (found by review). QEM simplifies each frame of qem on its
    # own, one at a time here to name it, and frame 0 of rqem and tracking (which go on from it).
    batches = [(n, [f]) for n, f in zip(names, frames, strict=True)] if args.method == "qem" else [(names[0], frames)]
    simplified: list[Any] = []
    for name, batch in batches:
        try:
            simplified += simplify_frames(batch, args.method, args.target, registrations, args.weight)
        except EmptyInputError as exc:
            if not str(exc).startswith("target: "):
                raise
            raise target_error(name, exc) from exc
    with output_set("the simplified frames") as files:
        make_folder(out_dir, "--output", files)
        for path, mesh in zip(targets, simplified, strict=True):
            save_mesh(mesh, path, overwrite=args.overwrite)
    for path, mesh, frame in zip(targets, simplified, frames, strict=True):
        count = resolve_target(args.target, frame.num_faces)
        # A frame left above its target was said only by a warning without the frame's name: methods compared at
        # different face counts (found by review). Each collapse removes two faces: count + 1 meets it.
        above = f" (above the target {count}: no collapse left; see the warning)" if mesh.num_faces > count + 1 else ""
        say(f"{path}: {frame.num_faces} -> {mesh.num_faces} faces{above}")
    return 0


def add_simplify_command(sub: Any) -> None:
    """Add the ``simplify`` subcommand to the CLI's subparsers."""
    p = add_command(sub, "simplify", run, [common_options()])
    p.add_argument("--input", type=path_argument, required=True, metavar="DIR", help="folder of the original frames")
    p.add_argument(
        "--output", type=path_argument, required=True, metavar="DIR", help="folder for the simplified frames (created)"
    )
    p.add_argument(
        "--method",
        choices=("qem", "rqem", "tracking"),
        default="qem",
        help="qem (default), rqem (Registered QEM) or tracking (Anchored QEM with the learned slide: each frame "
        "follows the previous one's tessellation, docs/training.md)",
    )
    add_target(p, 0.5, "faces to keep: a count (>= 1) or a ratio in (0, 1] of each frame's faces (default 0.5)")
    add_weight(
        p,
        "rqem: weight of the registered previous frame's quadrics (default: the library's DEFAULT_WEIGHT, "
        "chosen from the sweep in docs/simplification.md); tracking: the anchor weight (default DEFAULT_ANCHOR_WEIGHT)",
    )
    add_cache_dir(p, "registration cache folder (rqem and tracking)")
    p.add_argument("--overwrite", action="store_true", help="replace existing files in --output")
