"""What the commands share at run time: one-line errors, progress, device and precision, frames in, reports out.

Imported by a command's ``run`` only (it imports torch and the evaluation system), never to build the parser.
"""

from __future__ import annotations

import argparse
import os
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any, NamedTuple

import torch

from torchmeshmetric._atomic import atomic_write
from torchmeshmetric._console import say
from torchmeshmetric._format import json_safe
from torchmeshmetric.cli._outputs import CLIError, output_set
from torchmeshmetric.cli.options import NUDGED_CACHE
from torchmeshmetric.data.frames import frame_numbers, list_frames
from torchmeshmetric.data.sequence import load_sequence
from torchmeshmetric.evaluation.distributed import SequenceWork, evaluate_sequences
from torchmeshmetric.evaluation.pipeline import check_methods, evaluate_sequence
from torchmeshmetric.evaluation.reports import report_dict, write_csv, write_json, write_markdown
from torchmeshmetric.evaluation.results import SequenceEvaluation
from torchmeshmetric.kernels.index_cache import IndexCache
from torchmeshmetric.mpeg.comparison.sequence import mpeg_csv, mpeg_markdown, mpeg_sequence
from torchmeshmetric.registration.cache import RegistrationCache
from torchmeshmetric.registration.options import DEFAULT_SCHEDULE
from torchmeshmetric.tasks import is_distributed, rank_and_world_size
from torchmeshmetric.viz.plots import mpeg_figure, png_bytes

__all__ = [
    "NudgedRun",
    "determinacy_of",
    "nudged_cache",
    "nudged_run",
    "say_dtype_floor",
    "device_of",
    "dtype_of",
    "kept_by",
    "evaluate_across_ranks",
    "evaluate_method",
    "evaluate_methods",
    "fast_registration_options",
    "html_layers",
    "load_frames",
    "paired_files",
    "parse_methods",
    "progress",
    "report_paths",
    "simplify_frames",
    "temporal_methods",
    "write_reports",
]


def progress(label: str) -> Callable[[int, int], None]:
    """A progress callback printing a bar and the elapsed time on stderr after each frame pair."""
    start = time.perf_counter()

    def report(k: int, total: int) -> None:
        width = 20
        done = int(width * k / total)
        bar = "#" * done + "." * (width - done)
        say(f"{label} [{bar}] frame pair {k}/{total} ({time.perf_counter() - start:.1f} s)")

    return report


def device_of(args: argparse.Namespace) -> str:
    """The ``--device``, refused when it is ``cuda`` and no CUDA device is available."""
    if args.device == "cuda" and not torch.cuda.is_available():
        raise CLIError("--device cuda: no CUDA device is available (use --device cpu)")
    return str(args.device)


def report_paths(
    out: str | None, mpeg: bool = False, html: bool = False, folders: Sequence[tuple[str, str]] = ()
) -> dict[str, Path]:
    """The report files of ``--out REPORT.json``: ``.json``, ``.md``, ``.csv`` (and the ``--mpeg``, ``--html`` ones).

    ``--out`` must end in ``.json`` (the other files take its stem) and lie outside the input frame ``folders``
    (``(option, folder)``): a report named ``r.ply`` in a frame folder was read as a frame by every later run, and
    ``r.md`` was refused as "also --out" (found by review).
    """
    if out is None:
        if html:
            raise CLIError("--html: the page is written beside the report, so it needs --out REPORT.json")
        return {}
    json_path = Path(out)
    if json_path.suffix.lower() != ".json":
        found = f"the suffix {json_path.suffix!r}" if json_path.suffix else "no suffix"
        raise CLIError(
            f"--out {out!r}: expected a REPORT.json file name, found {found} (the .md and .csv reports are written "
            "beside it with its stem)"
        )
    for option, folder in folders:
        if Path(folder).is_dir() and json_path.parent.resolve() == Path(folder).resolve():
            raise CLIError(
                f"--out {out!r} lies in the input folder {option} {folder!r}: write the report outside the frame "
                "folders (a later run would read the folder's files as frames)"
            )
    paths = {"json": json_path, "md": json_path.with_suffix(".md"), "csv": json_path.with_suffix(".csv")}
    if html:
        paths["html"] = json_path.with_suffix(".html")
    if mpeg:
        paths.update(mpeg_csv=json_path.with_suffix(".mpeg.csv"), mpeg_png=json_path.with_suffix(".mpeg.png"))
    return paths


def kept_by(out: str | None) -> str:
    """What keeps the full values, for the note under printed tables: ``--out``'s file name, or the option."""
    return Path(out).name if out else "the JSON report (--out)"


def dtype_of(args: argparse.Namespace) -> Any:
    """The torch dtype of ``--dtype``."""
    return {"float32": torch.float32, "float64": torch.float64}[args.dtype]


def load_frames(directory: str, what: str, dtype: Any, paired_with: tuple[str, str] | None = None) -> list[Any]:
    """The frames of a folder (natural order), or a one-line error naming the option and the folder.

    ``paired_with``: ``(folder, option)`` of the original frames these are measured against; the frames are then
    paired with those by frame number (:func:`paired_files`), never by position alone when both folders number them.
    """
    if Path(directory).is_file():
        raise CLIError(f"{what} {directory!r} is a file; expected a folder of frames")
    if not Path(directory).is_dir():
        raise CLIError(f"{what} {directory!r}: no such directory")
    try:
        files = list_frames(directory)
        if paired_with is not None:
            files = paired_files(files, directory, what, *paired_with)
        frames = load_sequence(files, dtype=dtype)
    except CLIError:
        raise
    except Exception as exc:  # list_frames names its parameter ("paths: ..."): the option stands for it here
        raise CLIError(f"{what} {directory!r}: {str(exc).removeprefix('paths: ')}") from exc
    if len(frames) == 0:
        raise CLIError(f"{what} {directory!r}: no mesh files found")
    return list(frames)


def paired_files(
    files: list[Path],
    directory: str,
    what: str,
    original: str,
    original_what: str,
    original_files: Sequence[Path] | None = None,
) -> list[Path]:
    """``files`` (of ``directory``) in the order of the original frames of ``original``, paired by frame number.

    When every file name of both folders carries a frame number (:func:`~torchmeshmetric.data.frames.frame_numbers`:
    the first number in the names that differs from file to file), the two sets of numbers must be the same: a missing
    export or another numbering is refused, naming both folders, the first frame number in one folder only and the
    number each folder starts at (paired by position, original frame 1 would be measured against simplified frame 2
    in silence). Otherwise (a name without a number, no number that differs between all names, a single frame) the
    frames pair by natural order, as documented. Different counts of numbered frames are refused here, naming the
    first frame one folder lacks (the count check after it named only the counts: found by review O); unnumbered
    ones are left to the count check.

    ``original_files``: the original frames when ``original`` is not a folder (``temporal``'s printf patterns,
    resolved by the caller); default: the frames of the folder ``original``. ``directory`` and ``original`` are then
    only the names the messages quote.
    """
    originals = list_frames(original) if original_files is None else list(original_files)
    numbers, theirs = frame_numbers(originals), frame_numbers(files)
    if numbers is None or theirs is None:
        return files
    only = sorted(set(numbers) ^ set(theirs))  # the frame numbers in one folder only
    if not only:
        if len(files) != len(originals):  # the same numbers, repeated in one folder: the count check names the counts
            return files
        by_number = dict(zip(theirs, files, strict=True))
        return [by_number[n] for n in numbers]
    first = only[0]
    in_originals = first in numbers
    name = (originals[numbers.index(first)] if in_originals else files[theirs.index(first)]).name
    if len(files) != len(originals):
        which = (
            f"frame {first} of the original frames ({name!r}) is missing here"
            if in_originals
            else f"frame {first} ({name!r}) has no original frame"
        )
        more = f"; {len(only)} frame numbers are in one folder only" if len(only) > 1 else ""
        ranges = f"the original frames run from {min(numbers)} to {max(numbers)}, these from {min(theirs)} to "
        ranges += str(max(theirs))
        raise CLIError(
            f"{what} {directory!r}: {len(files)} frames but {original_what} {original!r} has {len(originals)} (must "
            f"match; {ranges}): {which}{more}"
        )
    ours, their = (original_what, original), (what, directory)
    has, lacks = (ours, their) if in_originals else (their, ours)
    start, their_start = min(numbers), min(theirs)
    shift = their_start - start
    if sorted(n + shift for n in numbers) == sorted(theirs):
        fix = (
            "the two number the same frames from different starts; rename the frames of "
            f"{what} to start at {start}, or those of {original_what} to start at {their_start}"
        )
    else:
        fix = f"rename (or re-export) the frames of {what} (or of {original_what}) to the same numbers"
    raise CLIError(
        f"{what} {directory!r} and {original_what} {original!r} number different frames: frame {first} "
        f"({name!r}) is in {has[0]} {has[1]!r} but not in {lacks[0]} {lacks[1]!r}; {original_what} starts at "
        f"frame {start} ({originals[numbers.index(start)].name!r}) and {what} at frame {their_start} "
        f"({files[theirs.index(their_start)].name!r}). Frames are paired by the frame number in their names (the "
        f"first number that differs from file to file), so {fix}"
    )


def write_reports(
    paths: dict[str, Path],
    methods: dict[str, Any],
    settings: dict[str, Any],
    overwrite: bool,
    mpeg: dict[str, Any] | None = None,
    comparisons: dict[str, Any] | None = None,
    temporal: dict[str, Any] | None = None,
    meshes: Sequence[Any] = (),
    determinacy: Any = None,
    say_written: bool = True,
) -> None:
    """Write the JSON, Markdown and CSV reports (and the --mpeg, --html ones) as one set; nothing when no --out.

    ``meshes``: the layers of the ``--html`` page's viewer (:func:`html_layers`); ``determinacy``: the
    ``--determinacy`` measurement (the tables' digits, and ``"determinacy"`` in the JSON); ``say_written``:
    ``False`` inside a caller's larger set (a campaign's), which says what it wrote once the whole set is.
    """
    if not paths:
        return
    report = report_dict(methods, settings=settings, comparisons=comparisons)
    if determinacy is not None:
        report["determinacy"] = json_safe(determinacy.as_dict())
    extra = ""
    if mpeg:
        report["mpeg"] = json_safe({name: seq.as_dict() for name, seq in mpeg.items()})
        extra = mpeg_markdown(mpeg)
    if temporal:  # the temporal figures: their own section, after the paper's tables (docs/temporal.md)
        from torchmeshmetric.temporal.report import temporal_markdown, temporal_report

        report["temporal"] = json_safe(temporal_report(temporal))
        section = temporal_markdown(temporal, determinacy=determinacy)
        extra = f"{extra}\n{section}" if extra else section
    written = [paths["json"], paths["md"], paths["csv"]]
    with output_set("the report"):
        write_json(paths["json"], report, overwrite=overwrite)
        write_markdown(
            paths["md"],
            methods,
            overwrite=overwrite,
            extra=extra,
            comparisons=comparisons,
            determinacy=determinacy,
            json_file=paths["json"].name,
        )
        write_csv(paths["csv"], methods, overwrite=overwrite)
        figures: list[tuple[str, bytes]] = []  # the --html page's PNGs besides its own
        if mpeg:
            written.append(atomic_write(paths["mpeg_csv"], mpeg_csv(mpeg), overwrite=overwrite))
            mpeg_png = png_bytes(mpeg_figure(mpeg))
            written.append(atomic_write(paths["mpeg_png"], mpeg_png, overwrite=overwrite))
            figures.append(("MPEG PSNR per frame", mpeg_png))
        if "html" in paths:
            written.append(
                _write_html_report(paths, report, methods, extra, comparisons, figures, meshes, overwrite, determinacy)
            )
    if say_written:
        say("wrote " + ", ".join(str(p) for p in written))


def _write_html_report(
    paths: dict[str, Path],
    report: dict[str, Any],
    methods: dict[str, Any],
    extra: str,
    comparisons: dict[str, Any] | None,
    figures: list[tuple[str, bytes]],
    meshes: Sequence[Any],
    overwrite: bool,
    determinacy: Any = None,
) -> Path:
    """The ``--html`` page of a report: its Markdown, curves, the best pair's histograms, ``figures``, the meshes."""
    from torchmeshmetric.evaluation.reports import markdown_report
    from torchmeshmetric.viz.html_report import report_page, write_html
    from torchmeshmetric.viz.plots import histogram_figure

    best = next(iter(methods.values())).best_pair_index()
    histograms = png_bytes(histogram_figure({n: r.pairs[best] for n, r in methods.items()}))
    figures = [("distance sets of the best pair", histograms), *figures]
    markdown = markdown_report(
        methods, extra=extra, comparisons=comparisons, determinacy=determinacy, json_file=paths["json"].name
    )
    page = report_page(
        report, markdown, title=f"torchmeshmetric report: {paths['json'].stem}", figures=figures, meshes=meshes
    )
    return write_html(paths["html"], page, overwrite=overwrite)


def html_layers(
    results: dict[str, Any], original: list[Any], methods: dict[str, list[Any]], cache: RegistrationCache, args: Any
) -> list[Any]:
    """The ``--html`` viewer's meshes of the best pair; its registration taken from ``cache`` (computed if absent)."""
    from torchmeshmetric.evaluation.pipeline import register_pairs
    from torchmeshmetric.viz.html_report import best_pair_layers

    if not getattr(args, "html", False) or not results:
        return []
    first = next(iter(results.values()))
    k = first.pairs[first.best_pair_index()].frame
    (registration,) = register_pairs(
        original[k - 1 : k + 1], registration_cache=cache, device=device_of(args), backend=args.backend
    )
    return best_pair_layers(results, original, methods, registration.registered_mesh(original[k - 1]))


def mpeg_methods(original: list[Any], methods: dict[str, list[Any]], args: argparse.Namespace) -> dict[str, Any]:
    """Per-frame MPEG figures of every method (``--mpeg``); printed as a Markdown table."""
    if not getattr(args, "mpeg", False):
        return {}

    out = {
        name: mpeg_sequence(
            original,
            frames,
            sampling=args.mpeg_sampling,
            grid_size=args.mpeg_grid_size,
            progress=progress(f"{name} mpeg"),
            names=("--original", f"method {name!r}"),
        )
        for name, frames in methods.items()
    }
    print(mpeg_markdown(out))
    return out


def temporal_methods(
    original: list[Any],
    methods: dict[str, list[Any]],
    args: argparse.Namespace,
    device: str,
    *,
    cache: RegistrationCache | None = None,
    registration_options: dict[str, Any] | None = None,
    determinacy: Any = None,
    nudged: NudgedRun | None = None,
    sequence: str | None = None,
) -> tuple[dict[str, Any], Any]:
    """KG, KSO and STED of every method (``--temporal``; docs/temporal.md), printed as a Markdown table.

    ``sequence``: a campaign's sequence, named in the printed section's title (a campaign prints one per sequence).

    With ``--determinacy`` (``determinacy`` and the ``nudged`` run of :func:`determinacy_of`), the figures are
    computed again on the nudged frames, on that run's registrations, and the returned determinacy holds their
    changes (its ``"temporal"`` table), so the section prints only the digits both runs share.

    Returns:
        ``(figures, determinacy)``: method name → :class:`~torchmeshmetric.temporal.TemporalFigures` (empty
        without ``--temporal``), and ``determinacy`` (with the temporal changes when measured).
    """
    if not getattr(args, "temporal", False):
        return {}, determinacy
    from torchmeshmetric.evaluation.determinacy import with_temporal_changes
    from torchmeshmetric.temporal.figures import FIGURE_NAMES, temporal_figures
    from torchmeshmetric.temporal.report import temporal_markdown

    def figures_of(first: list[Any], each: dict[str, list[Any]], registrations: RegistrationCache) -> dict[str, Any]:
        return {
            name: temporal_figures(
                first,
                frames,
                registration_cache=registrations,
                registration_options=registration_options,
                device=device,
                backend=args.backend,
            )
            for name, frames in each.items()
        }

    out = figures_of(original, methods, RegistrationCache(args.cache_dir) if cache is None else cache)
    if determinacy is not None and nudged is not None:
        again = figures_of(nudged.original, nudged.methods, nudged.cache)
        determinacy = with_temporal_changes(
            determinacy,
            {name: f.as_dict() for name, f in out.items()},
            {name: f.as_dict() for name, f in again.items()},
            FIGURE_NAMES,
        )
    print(temporal_markdown(out, determinacy=determinacy, sequence=sequence))
    return out, determinacy


def evaluate_method(
    name: str,
    original: list[Any],
    simplified: list[Any],
    args: argparse.Namespace,
    device: str,
    indexes: IndexCache,
    **options: Any,
) -> SequenceEvaluation:
    """One method's sequence evaluated with the command line's sides, device and backend, showing progress."""
    return evaluate_sequence(
        original,
        simplified,
        two_sided=not args.one_sided,
        device=device,
        progress=progress(name),
        backend=args.backend,
        indexes=indexes,
        **options,
    )


def evaluate_methods(
    original: list[Any],
    methods: dict[str, list[Any]],
    args: argparse.Namespace,
    device: str,
    *,
    registration_options: dict[str, Any] | None = None,
    cache: RegistrationCache | None = None,
) -> dict[str, Any] | None:
    """Every method evaluated against the original frames, sharing the registrations; ``None`` on torchrun ranks > 0.

    ``registration_options``: options of the default registration, the same on the local and the torchrun path.
    ``cache``: the registration cache (default: one on ``--cache-dir``), kept by a caller that reuses it.
    """
    cache = RegistrationCache(args.cache_dir) if cache is None else cache
    check_methods(original, methods)  # every method's count before any work
    if is_distributed():  # shared by the ranks of the torchrun job
        return evaluate_across_ranks(
            [("", original, methods)],
            cache,
            two_sided=not args.one_sided,
            device=device,
            backend=args.backend,
            registration_options=registration_options,
        )[0]
    indexes = IndexCache(max_entries=2 * len(original))  # each original frame's index built once for all methods
    return {
        name: evaluate_method(
            name,
            original,
            frames,
            args,
            device,
            indexes,
            registration_cache=cache,
            registration_options=registration_options,
        )
        for name, frames in methods.items()
    }


def nudged_cache(directory: str | os.PathLike[str] | None) -> RegistrationCache:
    """The registration cache of ``--determinacy``'s second run: ``directory/determinacy`` or, without, memory.

    The folder's name is :data:`~torchmeshmetric.cli.options.NUDGED_CACHE`.
    """
    return RegistrationCache(None if directory is None else Path(directory) / NUDGED_CACHE)


class NudgedRun(NamedTuple):
    """``--determinacy``'s second run: its frames, registrations (:func:`nudged_cache`) and evaluations."""

    original: list[Any]
    methods: dict[str, list[Any]]
    cache: RegistrationCache
    results: dict[str, Any] | None = None


def nudged_run(
    original: list[Any], methods: dict[str, list[Any]], rounding: str, cache: RegistrationCache
) -> NudgedRun:
    """``--determinacy``'s frames: the original and every method's moved by up to one unit of their storage.

    One seed for every frame: a coordinate moves by a function of its value, in the originals as in the simplified.
    Every frame is also stored in another order (:func:`~torchmeshmetric.evaluation.determinacy.relabel_frames`):
    the evaluation's registration draws independently of it (``sampling="canonical"``), and the change measured
    would include the one a re-export of the same surfaces makes if it did not. ``cache``: the second run's
    registrations (:func:`nudged_cache`: apart from the input's).
    """
    from torchmeshmetric.evaluation.determinacy import nudge_frames, relabel_frames

    say_dtype_floor(rounding, [original, *methods.values()])

    def moved(frames: list[Any]) -> list[Any]:
        return relabel_frames(nudge_frames(frames, rounding))

    return NudgedRun(moved(original), {name: moved(f) for name, f in methods.items()}, cache)


def say_dtype_floor(rounding: str, sequences: Sequence[Sequence[Any]]) -> None:
    """Say when ``--determinacy``'s unit is finer than the frames' dtype, which then sets the nudge (most places).

    A user who asks for 9 decimals of float32 frames in millimetres would otherwise read the dtype's digits as the
    file's (:func:`~torchmeshmetric.evaluation.determinacy.raised_fraction`).
    """
    from torchmeshmetric.evaluation.determinacy import raised_fraction

    frames = [f for frames in sequences for f in frames]
    share = raised_fraction(frames, rounding)
    if share > 0:
        dtype = str(frames[0].verts.dtype).removeprefix("torch.")
        say(
            f"--determinacy {rounding}: one unit is finer than the {dtype} frames hold at {share:.0%} of the "
            f"coordinates; those move by one {dtype} unit instead (--dtype float64 to measure the file's decimals)"
        )


def determinacy_of(
    original: list[Any],
    methods: dict[str, list[Any]],
    results: dict[str, Any] | None,
    args: argparse.Namespace,
    device: str,
) -> tuple[Any, NudgedRun | None]:
    """``--determinacy``: the same evaluation on nudged frames, compared with ``results``; ``(None, None)`` without.

    Every rank of a torchrun job runs it (the second evaluation is sharded like the first); rank 0 gets the
    :class:`~torchmeshmetric.evaluation.determinacy.Determinacy` and the :class:`NudgedRun` (for
    :func:`temporal_methods`). The nudged run's registrations go to :func:`nudged_cache` of ``--cache-dir``: a
    rerun resumes them, apart from the input's.
    """
    if getattr(args, "determinacy", None) is None:
        return None, None
    from torchmeshmetric.evaluation.determinacy import measure_determinacy

    say(f"--determinacy {args.determinacy}: evaluating again on nudged frames")
    nudged = nudged_run(original, methods, args.determinacy, nudged_cache(args.cache_dir))
    again = evaluate_methods(nudged.original, nudged.methods, args, device, cache=nudged.cache)
    if results is None or again is None:
        return None, None
    return measure_determinacy(results, again, args.determinacy), nudged._replace(results=again)


def evaluate_across_ranks(
    sequences: list[tuple[str, list[Any], dict[str, list[Any]]]],
    cache: RegistrationCache,
    *,
    two_sided: bool,
    device: str,
    backend: str,
    registration_options: dict[str, Any] | None,
) -> list[Any]:
    """Every method of every sequence, sharded over the ranks; results on rank 0, ``[None, ...]`` elsewhere."""
    _, world_size = rank_and_world_size()
    label = f"all methods on {world_size} processes" if world_size > 1 else "all methods"
    results = evaluate_sequences(
        [SequenceWork(*s) for s in sequences],
        registration_cache=cache,
        two_sided=two_sided,
        device=device,
        registration_options=registration_options,
        progress=progress(label),
        backend=backend,
    )
    return [None] * len(sequences) if results is None else list(results)


def parse_methods(specs: Sequence[str]) -> dict[str, str]:
    """The ``--method NAME=DIR`` arguments as ``{name: folder}``, in order; malformed or repeated names refused."""
    methods: dict[str, str] = {}
    for spec in specs:
        name, sep, directory = spec.partition("=")
        if not sep or not name.strip() or not directory:
            raise CLIError(f"--method {spec!r}: expected NAME=DIR")
        if name in methods:
            raise CLIError(f"--method {spec!r}: method name {name!r} given twice")
        alike = next((m for m in methods if m.strip() == name.strip()), None)
        if alike is not None:  # "A" and "A ": one name in every table (review X, F19)
            raise CLIError(f"--method {spec!r}: method name {name!r} differs from {alike!r} only by spaces around it, "
                           "and the tables would show both alike")  # fmt: skip
        methods[name] = directory
    return methods


def fast_registration_options() -> dict[str, Any]:
    """The demo's quick registration: 30 Adam steps in each stage but the last, and 1000 points per term.

    The last stage keeps its 80 annealed steps: cut to 30, it ends still changing its loss by 1.2-1.4e-3 of itself
    per window and is reported not converged (measured 2026-12-03 on the built-in sequence at resolutions 24 and 80;
    with 80 steps it converges at resolution 48 and above, ~0.1 s more per pair). At resolutions 16 and 24 (150-460
    vertices) it ends at 1.4-1.6e-4 (median; at most 2.5e-4) over generator seeds 0-7 since the criterion reads fixed
    correspondences and the graph follows the mesh's resolution (docs/registration.md, "Coarse meshes").

    Measured 2026-11-22 on the built-in sequence at resolution 80 (2-core x86-64 CPU sandbox): 3 frame pairs in
    6.1 s, mean residual to frame k 5.7-6.0e-4 (units of the ~1.9-unit-tall performer); the full registration at the
    paper's resolution 160 took 29 s for 5 pairs with residuals 1.9-2.2e-4.
    """
    return {
        "schedule": (*(stage._replace(max_steps=30) for stage in DEFAULT_SCHEDULE[:-1]), DEFAULT_SCHEDULE[-1]),
        "num_points": 1000,
        "num_target_samples": 1000,
    }


def simplify_frames(
    frames: list[Any],
    method: str,
    target: float | int,
    registrations: list[Any] | None,
    weight: float | None = None,
) -> list[Any]:
    """Every frame simplified with QEM, Registered QEM or tracking (Anchored QEM + slide), with the registrations."""
    # Imported here: fast-simplification is needed by simplify and demo only, not by the evaluation commands.
    from torchmeshmetric.simplification.registered_qem import DEFAULT_WEIGHT
    from torchmeshmetric.simplification.sequence import simplify_sequence

    if method == "qem":
        return simplify_sequence(frames, target)
    assert registrations is not None
    if method == "tracking":
        from torchmeshmetric.simplification.anchored_qem import DEFAULT_ANCHOR_WEIGHT
        from torchmeshmetric.simplification.temporal_slide import TemporalSlide
        from torchmeshmetric.simplification.tracking import simplify_tracking

        # Anchored QEM with the slide the training learned (docs/training.md): a gate of 1.000 on every held-out
        # vertex whatever its features, i.e. slide all the way along the surface; 1 - 1e-4 is that gate to its digits.
        slide = TemporalSlide(initial_gate=1.0 - 1e-4).to(frames[0].dtype)
        anchor = DEFAULT_ANCHOR_WEIGHT if weight is None else weight
        return simplify_tracking(frames, target, registrations, weight=anchor, slide=slide)
    return simplify_sequence(
        frames, target, registrations=registrations, weight=DEFAULT_WEIGHT if weight is None else weight
    )
