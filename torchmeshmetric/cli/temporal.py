"""The ``temporal`` command: KG, KSO, STED_s, STED_t and STED of a distorted sequence against its original."""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

from torchmeshmetric.cli.options import add_cache_dir, add_command, add_determinacy, common_options, path_argument

__all__ = ["add_temporal_command", "frame_files", "run"]


def frame_files(spec: str, what: str, first_frame: int | None, last_frame: int | None) -> list[Path] | str:
    """The frames a command-line argument names: a folder (returned as is), or a printf pattern's files.

    A pattern such as ``dec_%04d.obj`` runs from ``first_frame`` (default: 0, or 1 when frame 0 does not exist) to
    ``last_frame`` (default: the highest frame number whose file exists), and every frame of that range must exist,
    as ``mm``'s ``--firstFrame``/``--lastFrame`` and the V-DMC scripts' frame ranges read every frame of theirs: a
    missing frame is refused, naming it and its file (the scan stopped at the first gap and the count check then
    named no frame: found by review O). An existing folder is a folder, a ``%`` in its name too (``runs/100%_q``).

    Raises:
        CLIError: the pattern is malformed or names no file, a frame of the range is missing, a frame range given
            for a folder (its frames have no numbers to select by), or ``last_frame`` before ``first_frame`` (or
            before the default first frame).
    """
    from torchmeshmetric.cli._outputs import CLIError
    from torchmeshmetric.cli.ctc import frame_path
    from torchmeshmetric.mpeg.ctc.frame_pattern import pattern_frames

    if "%" not in spec or Path(spec).is_dir():
        if (first_frame is not None or last_frame is not None) and Path(spec).is_dir():
            raise CLIError(
                f"--first-frame/--last-frame: they select a printf pattern's frames; {what} {spec!r} is a folder "
                "(every frame of it is read)"
            )
        return spec
    if first_frame is not None and last_frame is not None and last_frame < first_frame:
        # The loop never ran and the count check called frame first_frame missing (found by review).
        raise CLIError(f"--last-frame {last_frame} is before --first-frame {first_frame}: no frame to read")
    try:
        existing = pattern_frames(spec, what)
        start = first_frame
        if start is None:
            start = 0 if Path(frame_path(spec, 0, what)).is_file() else 1
        if last_frame is not None and last_frame < start:
            raise CLIError(
                f"--last-frame {last_frame} is before {what} {spec!r}'s first frame, {start} (the default "
                "--first-frame: 0, or 1 when frame 0 does not exist)"
            )
        last = last_frame if last_frame is not None else max(existing, default=start - 1)
        if last < start:  # no file from the first frame on
            found = f" (its files run from frame {existing[0]} to {existing[-1]})" if existing else ""
            raise CLIError(f"{what} {spec!r}: no frame file from frame {start}{found}")
        files = [Path(frame_path(spec, k, what)) for k in range(start, last + 1)]
    except ValueError as exc:
        raise CLIError(str(exc)) from exc
    for k, path in enumerate(files, start):
        if path.is_file():
            continue
        until = "--last-frame" if last_frame is not None else "its last file, the default --last-frame"
        hint = ""
        if k == start and first_frame is None and existing:  # numbered from elsewhere (V-DMC's 1051, ...)
            hint = f"; its first file is frame {existing[0]}: pass --first-frame {existing[0]}"
        raise CLIError(
            f"{what} {spec!r}: frame {k} is missing ({path}): every frame from {start} to {last} ({until}) "
            f"is read{hint}"
        )
    return files


def run(args: argparse.Namespace) -> int:
    """KG, KSO, STED_s, STED_t and STED of a distorted sequence against its original.

    ORIGINAL and DISTORTED are folders (frames in natural order) or printf patterns such as dec_%04d.obj, their
    frames paired by the frame number in their names as evaluate pairs them (different numbers are refused, naming
    both inputs; names without a number that tells the frames apart pair by position). When every frame of both has
    the original's vertex count and triangles, the figures are the exact same-connectivity ones; otherwise (or with
    --registered) the registered forms: frame 0 of the original followed through the frames by the registration of
    each original frame onto the next, the distorted frames carried onto it along its normals (docs/temporal.md).
    """
    from torchmeshmetric._format import json_safe
    from torchmeshmetric.cli._outputs import CLIError
    from torchmeshmetric.cli._shared import device_of, dtype_of, paired_files
    from torchmeshmetric.data.frames import list_frames
    from torchmeshmetric.data.sequence import load_sequence
    from torchmeshmetric.evaluation.determinacy import storage_unit
    from torchmeshmetric.registration.cache import RegistrationCache
    from torchmeshmetric.temporal.figures import FIGURE_NAMES, temporal_figures
    from torchmeshmetric.temporal.report import (
        FIGURE_DIGITS_NOTE,
        FIGURE_FORMATS,
        FIGURE_LABELS,
        format_figure,
        temporal_determinacy_note,
        unconverged_tracking_note,
    )

    device = device_of(args)
    inputs = (("ORIGINAL", args.original), ("DISTORTED", args.distorted))
    files: list[list[Path]] = []
    for what, spec in inputs:
        paths = frame_files(spec, what, args.first_frame, args.last_frame)
        if isinstance(paths, str) and Path(paths).is_file():
            raise CLIError(
                f"{what} {spec!r} is a file; expected a folder of frames or a printf pattern such as dec_%04d.obj"
            )
        if isinstance(paths, str) and not Path(paths).is_dir():
            raise CLIError(f"{what} {spec!r}: no such directory (or a printf pattern such as dec_%04d.obj)")
        try:
            files.append(list_frames(paths) if isinstance(paths, str) else paths)
        except Exception as exc:  # list_frames names its parameter ("paths: ..."): the argument stands for it here
            raise CLIError(f"{what} {spec!r}: {str(exc).removeprefix('paths: ')}") from exc
    # Paired by frame number as evaluate pairs them (found by review G): by position, a folder or pattern numbered
    # from 1 was measured against one numbered from 0 in silence, and each pattern picks its own default first frame.
    files[1] = paired_files(files[1], args.distorted, "DISTORTED", args.original, "ORIGINAL", original_files=files[0])
    sequences = []
    for (what, spec), paths in zip(inputs, files, strict=True):
        try:
            sequences.append(load_sequence(paths, dtype=dtype_of(args)))
        except Exception as exc:
            raise CLIError(f"{what} {spec!r}: {exc}") from exc
    original, distorted = sequences
    if len(original) != len(distorted):  # unnumbered frames (numbered ones: paired_files names the frame one lacks)
        raise CLIError(f"DISTORTED: {len(distorted)} frames, ORIGINAL: {len(original)}; the counts must be equal")
    if len(original) < 2:
        raise CLIError(f"ORIGINAL: {len(original)} frame; the temporal metrics need at least 2")

    def figures_of(first: list[Any], second: list[Any], cache: RegistrationCache) -> Any:
        return temporal_figures(
            first,
            second,
            registered=True if args.registered else None,
            registration_cache=cache,
            device=device,
            backend=args.backend,
        )

    cache = RegistrationCache(args.cache_dir) if args.cache_dir else RegistrationCache()
    figures = figures_of(original, distorted, cache)
    values: dict[str, Any] = figures.as_dict()
    determinacy = None
    if args.determinacy is not None:
        from torchmeshmetric._console import say
        from torchmeshmetric.cli._shared import nudged_cache, say_dtype_floor
        from torchmeshmetric.evaluation.determinacy import (
            Determinacy,
            nudge_frames,
            relabel_frames,
            with_temporal_changes,
        )

        say(f"--determinacy {args.determinacy}: computing the figures again on nudged frames")
        say_dtype_floor(args.determinacy, [original, distorted])
        again = figures_of(
            relabel_frames(nudge_frames(original, args.determinacy)),  # another storage order too, as evaluate's
            relabel_frames(nudge_frames(distorted, args.determinacy)),
            nudged_cache(args.cache_dir),  # apart from the input's registrations; a rerun resumes them
        ).as_dict()
        determinacy = with_temporal_changes(
            Determinacy(storage_unit(args.determinacy), 0, {}), {"": values}, {"": again}, FIGURE_NAMES
        )
        values["determinacy"] = determinacy.as_dict()
    if args.json:
        print(json.dumps(json_safe(values), indent=2))
        return 0
    form = "registered (connectivity differs)" if figures.registered else "exact (same connectivity)"
    if figures.registered and args.registered:
        form = "registered (--registered)"
    print(f"{figures.num_frames} frames, {figures.num_verts} vertices followed; {form}")
    specs = FIGURE_FORMATS[bool(figures.registered)]
    for name in FIGURE_NAMES:
        if determinacy is None:
            text = format_figure(name, values[name], registered=figures.registered)
        else:
            text = determinacy.cell("temporal", 0, name, values[name], specs[name])
        print(f"{FIGURE_LABELS[name]:<12} {text}")
    note = FIGURE_DIGITS_NOTE if determinacy is None else temporal_determinacy_note(determinacy)
    print(note.replace("The JSON keeps", "--json keeps").replace("the JSON keeps", "--json keeps"))
    if figures.unconverged:
        print(unconverged_tracking_note(figures.unconverged))
    return 0


def add_temporal_command(sub: Any) -> None:
    """Add the ``temporal`` subcommand to the CLI's subparsers."""
    dtype_help = (
        "precision the frames are loaded in (default float32); the registered forms' registrations, KG, KSO and "
        "STED themselves are computed in float64 either way (float64: the files' every digit)"
    )
    p = add_command(sub, "temporal", run, [common_options(dtype_help)])
    p.add_argument(
        "original",
        type=path_argument,
        metavar="ORIGINAL",
        help="original frames: a folder or a pattern such as src_%%04d.obj",
    )
    p.add_argument(
        "distorted", type=path_argument, metavar="DISTORTED", help="distorted frames: a folder or a pattern, same count"
    )
    p.add_argument("--json", action="store_true", help="print the figures as JSON")
    p.add_argument(
        "--registered",
        action="store_true",
        help="use the registered forms even when the connectivity allows the exact ones",
    )
    p.add_argument(
        "--first-frame",
        type=int,
        default=None,
        metavar="F",
        help="patterns: first frame number (default 0, or 1 when frame 0 does not exist)",
    )
    p.add_argument(
        "--last-frame",
        type=int,
        default=None,
        metavar="L",
        help="patterns: last frame number, included (default: the highest whose file exists); every frame from the "
        "first to the last must exist",
    )
    add_cache_dir(p, "registration cache folder (registered forms)")
    add_determinacy(p, "compute the figures again", "docs/temporal.md")
