"""Command line interface of torchmeshmetric (also ``python -m torchmeshmetric``).

Commands:
  evaluate  evaluate one simplified sequence against its original frames (the paper's Fig. 2)
  compare   evaluate several simplification methods on one original sequence (Tables I-IV side by side)
  campaign  evaluate several sequences, each with several methods, listed in a TOML manifest
  simplify  simplify every frame of a sequence with QEM or Registered QEM
  register  register one mesh (frame k-1) onto another (frame k), rigid then non-rigid
  demo      the main job: built-in sequence -> QEM and Registered QEM -> evaluation, tables, report and plots
  mpeg      MPEG D1/D2 (and colour) PSNR of one mesh pair, equal to mmetric's figures
  validate  which distance sets respond to which controlled distortion (noise, offsets, flicker, registration)

Errors (missing or corrupt files, frame-count mismatch, unwritable output) end with a one-line message on stderr
and exit code 1; reports are written atomically and never half-written. Set TORCHMESHMETRIC_DEBUG=1 for tracebacks.

evaluate, compare and campaign also run under torchrun (torchrun --nproc-per-node N -m torchmeshmetric ...): the
processes share the work and rank 0 prints and writes the same report as one process (docs/scaling.md).
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import sys
import time
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import Any

import torch

from torchmeshmetric._atomic import atomic_file_set, atomic_write, blocking_file
from torchmeshmetric.data import demo_sequence, list_frames, load_mesh, load_sequence, save_mesh
from torchmeshmetric.evaluation import (
    RegistrationCache,
    compare_methods,
    comparison_markdown,
    evaluate_sequence,
    paper_tables,
    register_pairs,
    registered_qem_sweep,
    report_dict,
    write_csv,
    write_json,
    write_markdown,
)
from torchmeshmetric.evaluation.campaign import (
    COMBINED,
    campaign_report_dict,
    campaign_tables,
    load_campaign,
    report_name,
    write_campaign_csv,
    write_campaign_markdown,
)
from torchmeshmetric.evaluation.distributed import (
    SequenceWork,
    evaluate_sequences,
    is_distributed,
    rank_and_world_size,
)
from torchmeshmetric.evaluation.reports import _clean
from torchmeshmetric.evaluation.results import SequenceEvaluation
from torchmeshmetric.evaluation.validation import DISTORTIONS, FULL, REDUCED, run_validation
from torchmeshmetric.kernels import IndexCache
from torchmeshmetric.launch import run_command
from torchmeshmetric.mpeg.command import add_mpeg_command, json_safe
from torchmeshmetric.mpeg.sequence import mpeg_csv, mpeg_markdown, mpeg_sequence
from torchmeshmetric.registration import DEFAULT_SCHEDULE
from torchmeshmetric.simplification import DEFAULT_WEIGHT, simplify_sequence
from torchmeshmetric.stats import distance_statistics
from torchmeshmetric.viz import (
    plot_frame_curves,
    plot_histograms,
    plot_mpeg_curves,
    plot_validation,
    plot_weight_sweep,
    write_error_ply,
)

__all__ = ["build_parser", "main"]


class CLIError(Exception):
    """An error reported to the user as one line (exit code 1)."""


# --------------------------------------------------------------------------------------------- helpers
def _progress(label: str) -> Callable[[int, int], None]:
    start = time.perf_counter()

    def report(k: int, total: int) -> None:
        width = 20
        done = int(width * k / total)
        bar = "#" * done + "." * (width - done)
        print(f"{label} [{bar}] frame pair {k}/{total} ({time.perf_counter() - start:.1f} s)", file=sys.stderr)

    return report


def _device(args: argparse.Namespace) -> str:
    if args.device == "cuda" and not torch.cuda.is_available():
        raise CLIError("--device cuda: no CUDA device is available (use --device cpu)")
    return str(args.device)


def _report_paths(out: str | None, mpeg: bool = False) -> dict[str, Path]:
    if out is None:
        return {}
    json_path = Path(out)
    paths = {"json": json_path, "md": json_path.with_suffix(".md"), "csv": json_path.with_suffix(".csv")}
    if mpeg:
        paths.update(mpeg_csv=json_path.with_suffix(".mpeg.csv"), mpeg_png=json_path.with_suffix(".mpeg.png"))
    return paths


def _dtype(args: argparse.Namespace) -> Any:
    return {"float32": torch.float32, "float64": torch.float64}[args.dtype]


def _check_folder(folder: Path, what: str, *, may_create: bool = False) -> None:
    """An output folder: existing (or, with ``may_create``, missing), never a file nor below a file."""
    if not folder.is_dir():
        blocker = blocking_file(folder)
        if blocker is not None:
            raise CLIError(f"{what} {str(folder)!r}: {str(blocker)!r} is a file, not a folder")
        if not may_create:
            raise CLIError(f"{what} {str(folder)!r} does not exist")


def _make_folder(folder: Path, what: str, files: Any) -> None:
    """Create an output folder inside a file set (removed again when the run fails), naming a file in the way."""
    try:
        files.mkdir(folder)
    except (FileExistsError, NotADirectoryError) as exc:  # a file appeared in the way since the check
        _check_folder(folder, what)
        raise CLIError(f"{what} {str(folder)!r}: cannot create it ({exc.strerror})") from exc
    except OSError as exc:
        raise CLIError(f"{what} {str(folder)!r}: cannot create it ({exc.strerror})") from exc


@contextlib.contextmanager
def _output_set(what: str) -> Iterator[Any]:
    """Write this run's outputs as one set (all or none); a write error becomes one line saying nothing was kept."""
    try:
        with atomic_file_set() as files:
            yield files
    except OSError as exc:
        reason = exc.strerror or str(exc)
        where = f" ({exc.filename})" if exc.filename else ""
        raise CLIError(f"could not write {what}: {reason}{where}; none of its files was written") from exc


def _check_writable(paths: Sequence[Path], overwrite: bool) -> None:
    """Fail before any computation when an output cannot be written."""
    for path in paths:
        folder = path.parent if str(path.parent) else Path(".")
        _check_folder(folder, "output folder")
        if not os.access(folder, os.W_OK):
            raise CLIError(f"output folder {str(folder)!r} is not writable")
        if path.is_dir():
            raise CLIError(f"output {str(path)!r} is a directory, expected a file")
        if path.exists() and not overwrite:
            raise CLIError(f"output {str(path)!r} already exists (pass --overwrite to replace it)")


def _load_frames(directory: str, what: str, dtype: Any) -> list[Any]:
    if not Path(directory).is_dir():
        raise CLIError(f"{what} {directory!r}: no such directory")
    try:
        frames = load_sequence(directory, dtype=dtype)
    except Exception as exc:
        raise CLIError(f"{what} {directory!r}: {exc}") from exc
    if len(frames) == 0:
        raise CLIError(f"{what} {directory!r}: no mesh files found")
    return list(frames)


def _write_reports(
    paths: dict[str, Path],
    methods: dict[str, Any],
    settings: dict[str, Any],
    overwrite: bool,
    mpeg: dict[str, Any] | None = None,
    comparisons: dict[str, Any] | None = None,
) -> None:

    if not paths:
        return
    report = report_dict(methods, settings=settings, comparisons=comparisons)
    extra = ""
    if mpeg:
        report["mpeg"] = json_safe({name: seq.as_dict() for name, seq in mpeg.items()})
        extra = mpeg_markdown(mpeg)
    written = [paths["json"], paths["md"], paths["csv"]]
    with _output_set("the report"):
        write_json(paths["json"], report, overwrite=overwrite)
        write_markdown(paths["md"], methods, overwrite=overwrite, extra=extra, comparisons=comparisons)
        write_csv(paths["csv"], methods, overwrite=overwrite)
        if mpeg:
            written.append(atomic_write(paths["mpeg_csv"], mpeg_csv(mpeg), overwrite=overwrite))
            written.append(plot_mpeg_curves(mpeg, paths["mpeg_png"], overwrite=overwrite))
    print("wrote " + ", ".join(str(p) for p in written), file=sys.stderr)


def _mpeg_methods(original: list[Any], methods: dict[str, list[Any]], args: argparse.Namespace) -> dict[str, Any]:
    """Per-frame MPEG figures of every method (``--mpeg``); printed as a Markdown table."""
    if not getattr(args, "mpeg", False):
        return {}

    out = {
        name: mpeg_sequence(
            original,
            frames,
            sampling=args.mpeg_sampling,
            grid_size=args.mpeg_grid_size,
            progress=_progress(f"{name} mpeg"),
        )
        for name, frames in methods.items()
    }
    print(mpeg_markdown(out))
    return out


def _evaluate_method(
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
        progress=_progress(name),
        backend=args.backend,
        indexes=indexes,
        **options,
    )


def _evaluate_methods(
    original: list[Any], methods: dict[str, list[Any]], args: argparse.Namespace, device: str
) -> dict[str, Any] | None:

    cache = RegistrationCache(args.cache_dir)
    indexes = IndexCache(max_entries=2 * len(original))  # each original frame's index built once for all methods
    results = {}
    for name, frames in methods.items():
        if len(frames) != len(original):
            raise CLIError(
                f"method {name!r}: {len(frames)} simplified frames but {len(original)} original frames (must match)"
            )
        if len(original) < 2:
            raise CLIError(f"the sequence has {len(original)} frame; at least 2 are needed (pairs k-1, k)")
        if is_distributed():
            continue  # evaluated below, shared by the ranks of the torchrun job
        results[name] = _evaluate_method(name, original, frames, args, device, indexes, registration_cache=cache)
    if is_distributed():
        return _evaluate_across_ranks([("", original, methods)], cache, args, device)[0]
    return results


def _evaluate_across_ranks(
    sequences: list[tuple[str, list[Any], dict[str, list[Any]]]], cache: Any, args: argparse.Namespace, device: str
) -> list[Any]:
    """Every method of every sequence, sharded over the ranks; results on rank 0, ``[None, ...]`` elsewhere."""
    _, world_size = rank_and_world_size()
    label = f"all methods on {world_size} processes" if world_size > 1 else "all methods"
    results = evaluate_sequences(
        [SequenceWork(*s) for s in sequences],
        registration_cache=cache,
        two_sided=not args.one_sided,
        device=device,
        registration_options=getattr(args, "register_options", None),
        progress=_progress(label),
        backend=args.backend,
    )
    return [None] * len(sequences) if results is None else list(results)


# --------------------------------------------------------------------------------------------- commands
def _cmd_evaluate(args: argparse.Namespace) -> int:
    """Evaluate a simplified sequence against its original frames.

    For every simplified frame k >= 1: register original frame k-1 onto original frame k, measure the four distance
    sets from the simplified vertices (surface and nearest-vertex distance to frame k and to the registered frame
    k-1), print the paper's Tables I-IV and optionally write a report. Frames are matched by natural sort order of
    the file names in each folder; the counts must be equal.
    """
    device = _device(args)
    paths = _report_paths(args.out, args.mpeg)
    _check_writable(list(paths.values()), args.overwrite)
    original = _load_frames(args.original, "--original", _dtype(args))
    simplified = _load_frames(args.simplified, "--simplified", _dtype(args))
    name = args.name or Path(args.simplified).resolve().name
    results = _evaluate_methods(original, {name: simplified}, args, device)
    if results is None:  # a torchrun rank other than 0: rank 0 reports
        return 0
    print(paper_tables(results))
    mpeg = _mpeg_methods(original, {name: simplified}, args)
    settings = {
        "original": args.original,
        "methods": {name: args.simplified},
        "two_sided": not args.one_sided,
        "dtype": args.dtype,
    }
    _write_reports(paths, results, settings, args.overwrite, mpeg)
    return 0


def _positive_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a positive integer, found {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected a positive integer, found {text!r}")
    return value


def _parse_methods(specs: Sequence[str]) -> dict[str, str]:
    methods: dict[str, str] = {}
    for spec in specs:
        name, sep, directory = spec.partition("=")
        if not sep or not name or not directory:
            raise CLIError(f"--method {spec!r}: expected NAME=DIR")
        if name in methods:
            raise CLIError(f"--method {spec!r}: method name {name!r} given twice")
        methods[name] = directory
    return methods


def _cmd_compare(args: argparse.Namespace) -> int:
    """Compare several simplification methods (Tables I-IV side by side).

    Evaluate several simplified versions of one original sequence; registrations of the original frames are computed
    once and shared by all methods. With two or more methods, every pair of methods is compared set by set: the mean
    difference over frame pairs, its 95% paired t interval and a verdict ('<A> better', '<B> better' or
    'inconclusive': the interval contains 0, or the difference is below the registration's noise floor (k-1 and
    flicker sets) or the relative margin), in the report's 'comparisons' and as verdict tables.
    """
    device = _device(args)
    specs = _parse_methods(args.method)
    paths = _report_paths(args.out, args.mpeg)
    _check_writable(list(paths.values()), args.overwrite)
    original = _load_frames(args.original, "--original", _dtype(args))
    frames = {name: _load_frames(d, f"--method {name}", _dtype(args)) for name, d in specs.items()}
    results = _evaluate_methods(original, frames, args, device)
    if results is None:  # a torchrun rank other than 0: rank 0 reports
        return 0
    print(paper_tables(results))
    mpeg = _mpeg_methods(original, frames, args)
    comparisons = None
    if len(results) >= 2:
        comparisons = compare_methods(results, relative_margin=args.relative_margin)
        print("## Comparisons with confidence\n\n" + comparison_markdown(comparisons))
    settings = {
        "original": args.original,
        "methods": specs,
        "two_sided": not args.one_sided,
        "relative_margin": args.relative_margin,
        "dtype": args.dtype,
    }
    _write_reports(paths, results, settings, args.overwrite, mpeg, comparisons)
    return 0


def _cmd_campaign(args: argparse.Namespace) -> int:
    """Evaluate a test campaign: several sequences, each with several methods (TOML manifest).

    Evaluate every method of every sequence listed in a TOML manifest (see examples/campaign.toml and
    docs/scaling.md); registrations of each sequence's original pairs are computed once and shared by its methods.
    Prints the combined tables (per sequence and overall: mean over sequences); with --out-dir writes
    campaign.json/.md/.csv and one report per sequence (<sequence>.json/.md/.csv). Under torchrun the work is shared
    by all processes.
    """
    device = _device(args)
    campaign = load_campaign(args.manifest)
    out = None if args.out_dir is None else Path(args.out_dir)
    stems = [COMBINED] + [report_name(s.name) for s in campaign.sequences]
    if out is not None:
        targets = [out / f"{stem}.{ext}" for stem in stems for ext in ("json", "md", "csv")]
        _check_writable(targets if out.is_dir() else [out], args.overwrite)
    sequences = []
    for seq in campaign.sequences:
        original = _load_frames(str(seq.original), f"sequence {seq.name!r}: original", _dtype(args))
        methods = {
            m: _load_frames(str(d), f"sequence {seq.name!r}: method {m!r}", _dtype(args))
            for m, d in seq.methods.items()
        }
        for method, frames in methods.items():
            if len(frames) != len(original):
                raise CLIError(
                    f"sequence {seq.name!r}: method {method!r}: {len(frames)} simplified frames but {len(original)} "
                    "original frames (must match)"
                )
        if len(original) < 2:
            raise CLIError(f"sequence {seq.name!r}: {len(original)} frame; at least 2 are needed (pairs k-1, k)")
        sequences.append((seq.name, original, methods))
    args.one_sided = not campaign.two_sided
    args.register_options = _fast_registration_options() if campaign.registration == "fast" else None
    cache = RegistrationCache(args.cache_dir or campaign.cache_dir)
    evaluated = _evaluate_across_ranks(sequences, cache, args, device)
    if evaluated[0] is None:  # a torchrun rank other than 0: rank 0 reports
        return 0
    results = {seq.name: methods for seq, methods in zip(campaign.sequences, evaluated, strict=True)}
    print(campaign_tables(results))
    if out is None:
        return 0
    settings: dict[str, Any] = {
        "campaign": str(campaign.path),
        "two_sided": campaign.two_sided,
        "registration": campaign.registration,
        "dtype": args.dtype,
    }
    with _output_set("the campaign's reports") as files:
        if not out.is_dir():
            _make_folder(out, "--out-dir", files)
        for seq, stem in zip(campaign.sequences, stems[1:], strict=True):
            folders = {m: str(d) for m, d in seq.methods.items()}
            sequence_settings = {**settings, "sequence": seq.name, "original": str(seq.original), "methods": folders}
            paths = _report_paths(str(out / f"{stem}.json"))
            # The same comparisons `compare` writes for these methods (default margin; none for a single method).
            comparisons = compare_methods(results[seq.name]) if len(results[seq.name]) >= 2 else None
            _write_reports(paths, results[seq.name], sequence_settings, args.overwrite, comparisons=comparisons)
        combined = campaign_report_dict(results, settings=settings)
        write_json(out / f"{COMBINED}.json", combined, overwrite=args.overwrite)
        write_campaign_markdown(out / f"{COMBINED}.md", results, overwrite=args.overwrite)
        write_campaign_csv(out / f"{COMBINED}.csv", results, overwrite=args.overwrite)
    print(f"wrote {out / COMBINED}.json/.md/.csv and one report per sequence", file=sys.stderr)
    return 0


def _parse_target(text: str) -> float | int:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a face count or a ratio in (0, 1), found {text!r}") from None
    if value >= 1 and value.is_integer():
        return int(value)
    if 0 < value < 1:
        return value
    raise argparse.ArgumentTypeError(f"expected a face count (>= 1) or a ratio in (0, 1), found {text!r}")


def _parse_weight(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a weight >= 0, found {text!r}") from None
    if not (value >= 0 and value != float("inf")):
        raise argparse.ArgumentTypeError(f"expected a finite weight >= 0, found {text!r}")
    return value


def _parse_weights(text: str) -> tuple[float, ...]:
    if text.strip().lower() == "none":
        return ()
    weights = tuple(_parse_weight(w) for w in text.split(",") if w.strip())
    if not weights:
        raise argparse.ArgumentTypeError(f"expected a comma-separated list of weights or 'none', found {text!r}")
    return weights


def _fast_registration_options() -> dict[str, Any]:
    """The demo's quick registration: 30 Adam steps per stage (instead of up to 120) and 1000 points per term.

    Measured 2026-11-22 on the built-in sequence at resolution 80 (2-core x86-64 CPU sandbox): 3 frame pairs in
    6.1 s, mean residual to frame k 5.7-6.0e-4 (units of the ~1.9-unit-tall performer); the full registration at the
    paper's resolution 160 took 29 s for 5 pairs with residuals 1.9-2.2e-4.
    """
    return {
        "schedule": tuple(stage._replace(max_steps=30) for stage in DEFAULT_SCHEDULE),
        "num_points": 1000,
        "num_target_samples": 1000,
    }


def _simplify_frames(
    frames: list[Any],
    method: str,
    target: float | int,
    registrations: list[Any] | None,
    weight: float | None = None,
) -> list[Any]:

    if method == "qem":
        return simplify_sequence(frames, target)
    assert registrations is not None
    return simplify_sequence(
        frames, target, registrations=registrations, weight=DEFAULT_WEIGHT if weight is None else weight
    )


def _cmd_simplify(args: argparse.Namespace) -> int:
    """Simplify every frame of a sequence with QEM or Registered QEM.

    Simplify each frame of --input into --output (same file names). 'rqem' (Registered QEM) also uses the previous
    original frame registered onto the current one; frame 0 is simplified with QEM.
    """
    device = _device(args)
    frames = _load_frames(args.input, "--input", _dtype(args))
    names = [Path(p).name for p in list_frames(args.input)]
    out_dir = Path(args.output)
    targets = [out_dir / n for n in names]
    _check_folder(out_dir, "--output", may_create=True)
    if out_dir.is_dir():
        _check_writable(targets, args.overwrite)
    registrations = None
    if args.method == "rqem":
        cache = RegistrationCache(args.cache_dir)
        registrations = register_pairs(frames, registration_cache=cache, device=device, backend=args.backend)
    simplified = _simplify_frames(frames, args.method, args.target, registrations, args.weight)
    with _output_set("the simplified frames") as files:
        _make_folder(out_dir, "--output", files)
        for path, mesh in zip(targets, simplified, strict=True):
            save_mesh(mesh, path, overwrite=args.overwrite)
    for path, mesh, frame in zip(targets, simplified, frames, strict=True):
        print(f"{path}: {frame.num_faces} -> {mesh.num_faces} faces", file=sys.stderr)
    return 0


def _cmd_register(args: argparse.Namespace) -> int:
    """Register one mesh onto another (rigid, then non-rigid).

    Align --source (frame k-1) onto --target (frame k), keeping the source's vertices and topology, and write the
    registered mesh. Exit code 3 when the registration did not converge.
    """
    device = _device(args)
    _check_writable([Path(args.out)], args.overwrite)
    dtype = _dtype(args)
    meshes = []
    for flag, path in (("--source", args.source), ("--target", args.target)):
        if not Path(path).is_file():
            raise CLIError(f"{flag} {path!r}: no such file")
        try:
            meshes.append(load_mesh(path, dtype=dtype))
        except Exception as exc:
            raise CLIError(f"{flag} {path!r}: {exc}") from exc
    source, target = meshes
    (reg,) = register_pairs([source, target], device=device, backend=args.backend)
    save_mesh(reg.registered_mesh(source), args.out, overwrite=args.overwrite)
    stats = distance_statistics(reg.residual, peak=float(target.bbox_diagonal()))
    print(
        f"registered {args.source} onto {args.target} in {reg.seconds:.2f} s (converged: {reg.converged}); "
        f"residual to target surface: ave {stats.ave:.4g}, rmse {stats.rmse:.4g}, max {stats.max:.4g}; wrote {args.out}"
    )
    return 0 if reg.converged else 3


_DEMO_MARKER = ".torchmeshmetric-demo"
# Defaults sized so that `demo` runs in under 2 minutes on 2 CPU cores; the paper's sizes: --resolution 160
# --registration full (and any --frames), which takes minutes per frame pair on such a machine.
DEMO_FRAMES = 6
DEMO_RESOLUTION = 160
DEMO_TARGET = 0.97
DEMO_WEIGHTS = (0.0, 0.5, 1.0, 2.0, 4.0, 8.0)


def _cmd_demo(args: argparse.Namespace) -> int:
    """The paper's experiment on the built-in sequence (QEM vs Registered QEM).

    Generate the built-in volumetric-video-like sequence, register each original frame k-1 onto frame k, simplify
    every frame with QEM and with Registered QEM (which uses the registered previous frame), evaluate both, print
    the paper's four tables and write report.json/.md/.csv, plots and coloured PLYs. The defaults are the paper's
    sizes (6 frames of ~20k vertices / 40k faces, keep 97% of the faces, full registration): about 40 s on 2 CPU
    cores; the first run on a machine also compiles the C++ distance extension once (~30 s). --resolution 80
    --registration fast is a ~15 s preview.
    """
    device = _device(args)
    out_dir = _demo_out_dir(args)
    t0 = time.perf_counter()
    kwargs: dict[str, Any] = {"seed": args.seed}
    if args.resolution is not None:
        kwargs["resolution"] = args.resolution
    seq = demo_sequence(args.frames, **kwargs)
    frames = [f.to(dtype=_dtype(args)) for f in seq.frames]
    sizes = ", ".join(f"{f.num_verts}v/{f.num_faces}f" for f in frames)
    print(f"demo sequence: {len(frames)} frames ({sizes}) in {time.perf_counter() - t0:.1f} s", file=sys.stderr)

    t0 = time.perf_counter()
    registrations = register_pairs(
        frames,
        registration_options=_fast_registration_options() if args.registration == "fast" else {},
        registration_cache=RegistrationCache(args.cache_dir),
        device=device,
        backend=args.backend,
    )
    residual = ", ".join(f"{float(r.residual.mean()):.2e}" for r in registrations)
    print(
        f"registered {len(registrations)} original frame pairs ({args.registration}) in "
        f"{time.perf_counter() - t0:.1f} s; mean residual to frame k: {residual}",
        file=sys.stderr,
    )

    t0 = time.perf_counter()
    simplified = {
        "Orig QEM": _simplify_frames(frames, "qem", args.target, None),
        "Reg QEM": _simplify_frames(frames, "rqem", args.target, registrations, args.weight),
    }
    print(f"simplified with QEM and Registered QEM in {time.perf_counter() - t0:.1f} s", file=sys.stderr)

    indexes = IndexCache(max_entries=2 * len(frames))  # each original frame's index built once for both methods
    results = {
        # ground_truth: the built-in sequence's true motion, so the registration's error is reported
        name: _evaluate_method(
            name,
            frames,
            simp,
            args,
            device,
            indexes,
            precomputed_registrations=registrations,
            ground_truth=seq.transfer,
        )
        for name, simp in simplified.items()
    }
    print(paper_tables(results))
    written = _write_demo(out_dir, frames, results, simplified, registrations, args, device, seq.transfer)
    print(f"wrote to {out_dir}: {', '.join(written)}", file=sys.stderr)
    return 0


def _demo_out_dir(args: argparse.Namespace) -> Path:
    """The demo's output folder, created and marked as the demo's (another tool's non-empty one: --overwrite)."""
    out_dir = Path(args.out_dir)
    _check_folder(out_dir, "--out-dir", may_create=True)
    if out_dir.exists() and not (out_dir / _DEMO_MARKER).exists() and any(out_dir.iterdir()) and not args.overwrite:
        raise CLIError(f"--out-dir {str(out_dir)!r} exists and was not written by the demo (pass --overwrite)")
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
        (out_dir / _DEMO_MARKER).touch()
    except OSError as exc:
        raise CLIError(f"--out-dir {str(out_dir)!r}: cannot write ({exc.strerror})") from exc
    return out_dir


def _write_demo(
    out_dir: Path,
    frames: list[Any],
    results: dict[str, SequenceEvaluation],
    simplified: dict[str, list[Any]],
    registrations: list[Any],
    args: argparse.Namespace,
    device: str,
    ground_truth: Any,
) -> list[str]:
    """The demo's report, meshes, plots and weight sweep, written as one set; the names written."""
    settings = {
        "demo": {
            "frames": args.frames,
            "resolution": args.resolution,
            "seed": args.seed,
            "target": args.target,
            "registration": args.registration,
            "weight": args.weight,
            "weights": list(args.weights),
        },
        "two_sided": not args.one_sided,
        "dtype": args.dtype,
    }
    with _output_set("the demo's outputs") as files:
        write_json(out_dir / "report.json", report_dict(results, settings=settings), overwrite=True)
        write_markdown(out_dir / "report.md", results, overwrite=True)
        write_csv(out_dir / "report.csv", results, overwrite=True)
        written = ["report.json", "report.md", "report.csv"]
        if args.save_meshes:
            for name, simp in simplified.items():
                slug = name.lower().replace(" ", "_")
                files.mkdir(out_dir / slug)
                for k, mesh in enumerate(simp):
                    save_mesh(mesh, out_dir / slug / f"frame_{k:03d}.ply", overwrite=True)
            written.append("<method>/frame_*.ply")
        if not args.no_plots:
            written += _demo_plots(out_dir, results, simplified)
        if args.weights:
            written += _demo_sweep(out_dir, frames, registrations, args, device, ground_truth, not args.no_plots)
    return written


def _demo_sweep(
    out_dir: Path,
    frames: list[Any],
    registrations: list[Any],
    args: argparse.Namespace,
    device: str,
    ground_truth: Any,
    plots: bool,
) -> list[str]:
    """Registered QEM at every weight of --weights beside plain QEM: table, JSON and Pareto plot."""
    t0 = time.perf_counter()
    sweep = registered_qem_sweep(
        frames, registrations, args.target, args.weights, device=device, ground_truth=ground_truth
    )
    print(f"weight sweep ({len(args.weights)} weights + QEM) in {time.perf_counter() - t0:.1f} s", file=sys.stderr)
    table = sweep.markdown()
    print("### Registered QEM weight sweep (mean over pairs of the per-pair Ave)\n\n" + table)
    atomic_write(out_dir / "weight_sweep.md", "# Registered QEM weight sweep\n\n" + table, overwrite=True)
    atomic_write(out_dir / "weight_sweep.json", json.dumps(sweep.as_dict(), indent=2) + "\n", overwrite=True)
    written = ["weight_sweep.md", "weight_sweep.json"]
    if plots:
        plot_weight_sweep(sweep, out_dir / "weight_sweep.png", overwrite=True)
        written.append("weight_sweep.png")
    return written


def _demo_plots(out_dir: Path, results: dict[str, Any], simplified: dict[str, list[Any]]) -> list[str]:
    """Histograms and curves (PNG), and each method's best frame coloured by its error (PLY, one colour scale).

    The colour is the distance of each simplified vertex to the registered frame k-1 (temporal consistency).
    """
    best = next(iter(results.values())).best_pair_index()
    plot_histograms({n: r.pairs[best] for n, r in results.items()}, out_dir / "histograms.png", overwrite=True)
    plot_frame_curves(results, out_dir / "frame_curves.png", overwrite=True)
    written = ["histograms.png", "frame_curves.png"]
    vmax = max(float(r.pairs[best].distances["surface_k_minus_1"].max()) for r in results.values())
    for name, result in results.items():
        pair = result.pairs[best]
        path = out_dir / f"error_{name.lower().replace(' ', '_')}_frame{pair.frame:03d}.ply"
        write_error_ply(
            path, simplified[name][pair.frame], pair.distances["surface_k_minus_1"], vmax=vmax, overwrite=True
        )
        written.append(path.name)
    return written


def _cmd_validate(args: argparse.Namespace) -> int:
    """Validation study: which distance sets respond to which controlled distortion.

    On the built-in sequence (true motion known): a tracked simplification, evaluated with the true registration,
    distorted at 6 strengths by frame-k noise, simplification level, constant and alternating normal offsets,
    sliding along the surface, per-frame re-simplification and registration error. Prints and writes the Spearman
    rank correlation between strength and each set's statistics and the relative change (validation.md/.json,
    validation.png). The default (reduced) size takes well under 2 minutes on 2 CPU cores; --full is the paper's
    frame size (docs/validation.md).
    """
    preset = dict(FULL if args.full else REDUCED)
    for key in ("frames", "resolution", "keep"):
        if getattr(args, key) is not None:
            preset[key] = getattr(args, key)
    names = None
    if args.distortions:
        names = [n.strip() for n in args.distortions.split(",") if n.strip()]
        unknown = [n for n in names if n not in DISTORTIONS]
        if unknown:
            raise CLIError(f"--distortions: unknown {unknown}; expected names from {list(DISTORTIONS)}")
    out_dir = Path(args.out_dir)
    paths = [out_dir / "validation.json", out_dir / "validation.md"] + (
        [] if args.no_plots else [out_dir / "validation.png"]
    )
    if not out_dir.is_dir():
        try:
            out_dir.mkdir(parents=True)
        except OSError as exc:
            raise CLIError(f"--out-dir {str(out_dir)!r}: cannot create ({exc.strerror})") from exc
    _check_writable(paths, args.overwrite)
    start = time.perf_counter()
    result = run_validation(
        seed=args.seed,
        distortions=names,
        progress=lambda n: print(f"validate: {n} done ({time.perf_counter() - start:.1f} s)", file=sys.stderr),
        **preset,
    )
    settings = result.settings
    title = (
        f"# torchmeshmetric validation study\n\nBuilt-in sequence, {settings['frames']} frames at resolution "
        f"{settings['resolution']} (~{settings['faces_per_frame']} faces), tracked QEM simplification keeping "
        f"{settings['keep']:g} of the faces, true registration (residual Ave {result.registration['ave']:.3g}); "
        f"{'two-sided' if settings['two_sided'] else 'one-sided'}; {result.seconds:.1f} s.\n\n"
    )
    text = result.markdown()
    print(title + text)
    atomic_write(
        paths[0], json.dumps(_clean(result.as_dict()), indent=2, allow_nan=False) + "\n", overwrite=args.overwrite
    )
    atomic_write(paths[1], title + text, overwrite=args.overwrite)
    if not args.no_plots:
        plot_validation(result, paths[2], overwrite=args.overwrite)
    print(f"wrote {', '.join(str(p) for p in paths)}", file=sys.stderr)
    return 0


# --------------------------------------------------------------------------------------------- parser
def _common_options() -> argparse.ArgumentParser:
    """Options of every command that computes: device, precision, kernel backend, threads."""
    common = argparse.ArgumentParser(add_help=False)
    common.add_argument(
        "--device", choices=("cpu", "cuda"), default="cpu", help="where distances and registration run (default cpu)"
    )
    common.add_argument(
        "--dtype",
        choices=("float32", "float64"),
        default="float32",
        help="precision of the frames and of every computation (default float32: statistics within ~3e-5 "
        "relative of float64 on a 40k-face pair, see the docs' command-line page; float64 to compare tiny differences)",
    )
    common.add_argument(
        "--backend",
        choices=("auto", "bvh", "triton", "pruned", "bruteforce"),
        default="auto",
        help="exact distance kernel (default auto: the C++ BVH on the CPU, Triton on CUDA); all give the same values",
    )
    common.add_argument(
        "--threads",
        type=_positive_int,
        default=None,
        metavar="N",
        help="torch CPU threads of this process (default: torch's choice; under torchrun: the cores divided by the "
        "processes on this machine unless OMP_NUM_THREADS is set to more than 1)",
    )
    return common


def _evaluation_options() -> argparse.ArgumentParser:
    """Options of the commands that evaluate sequences: sides, registration cache, MPEG figures."""
    evaluation = argparse.ArgumentParser(add_help=False)
    evaluation.add_argument(
        "--one-sided",
        action="store_true",
        help="only the paper's simplified -> reference sets; by default the reverse (reference -> simplified) "
        "sets are reported too, so a simplification that drops part of the surface cannot score well",
    )
    _add_cache_dir(
        evaluation,
        "keep registrations of original frame pairs in DIR (keyed by mesh content and settings) and reuse "
        "them in later runs (default: in memory for this run only)",
    )
    evaluation.add_argument(
        "--mpeg",
        action="store_true",
        help="also report MPEG's per-frame D1/D2 PSNR and Hausdorff (mmetric's figures, frame k vs original frame "
        "k) in the tables and reports (REPORT.mpeg.csv, REPORT.mpeg.png); averaged as the CTC: mean of per-frame PSNR",
    )
    evaluation.add_argument(
        "--mpeg-sampling", choices=("grid", "mesh"), default="grid", help="MPEG sampling (default grid, the CTC's)"
    )
    evaluation.add_argument("--mpeg-grid-size", type=int, default=1024, metavar="N", help="MPEG grid size (1024)")
    return evaluation


def _report_options() -> argparse.ArgumentParser:
    """Options of the commands that write one report (evaluate, compare)."""
    output = argparse.ArgumentParser(add_help=False)
    output.add_argument(
        "--out",
        default=None,
        metavar="REPORT.json",
        help="write the JSON report there, and the paper's tables beside it as REPORT.md and REPORT.csv "
        "(default: print the tables only)",
    )
    output.add_argument("--overwrite", action="store_true", help="replace existing output files")
    return output


def _add_cache_dir(p: argparse.ArgumentParser, help_text: str) -> None:
    p.add_argument("--cache-dir", default=None, metavar="DIR", help=help_text)


def _add_target(p: argparse.ArgumentParser, default: float | int, help_text: str) -> None:
    p.add_argument("--target", type=_parse_target, default=default, help=help_text)


def _add_weight(p: argparse.ArgumentParser, help_text: str) -> None:
    p.add_argument("--weight", type=_parse_weight, default=None, help=help_text)


def _command(
    sub: Any, name: str, func: Callable[[argparse.Namespace], int], parents: Sequence[argparse.ArgumentParser]
) -> argparse.ArgumentParser:
    """A subcommand that runs ``func``; its help is the first line of ``func``'s docstring, its description the rest."""
    summary, _, description = (func.__doc__ or "").partition("\n\n")
    p: argparse.ArgumentParser = sub.add_parser(
        name,
        parents=list(parents),
        help=summary[:1].lower() + summary[1:].rstrip("."),  # docstrings are gone under python -OO
        description=" ".join(description.split()).replace("%", "%%"),
    )
    p.set_defaults(func=func)
    return p


def _add_evaluate(sub: Any, parents: Sequence[argparse.ArgumentParser]) -> None:
    p = _command(sub, "evaluate", _cmd_evaluate, parents)
    p.add_argument(
        "--original", required=True, metavar="DIR", help="folder of the original frames (OBJ/PLY/OFF/STL/GLB)"
    )
    p.add_argument("--simplified", required=True, metavar="DIR", help="folder of the simplified frames, same count")
    p.add_argument("--name", default=None, help="method name in the tables (default: the simplified folder's name)")


def _add_compare(sub: Any, parents: Sequence[argparse.ArgumentParser]) -> None:
    p = _command(sub, "compare", _cmd_compare, parents)
    p.add_argument("--original", required=True, metavar="DIR", help="folder of the original frames")
    p.add_argument(
        "--method",
        required=True,
        action="append",
        metavar="NAME=DIR",
        help="a method's name and the folder of its simplified frames; repeat for every method",
    )
    p.add_argument(
        "--relative-margin",
        type=float,
        default=0.02,
        metavar="FRACTION",
        help="differences below this fraction of the better method's value are 'inconclusive' (default 0.02; "
        "0 relies on the interval and the registration's noise floor alone)",
    )


def _add_campaign(sub: Any, parents: Sequence[argparse.ArgumentParser]) -> None:
    p = _command(sub, "campaign", _cmd_campaign, parents)
    p.add_argument("manifest", metavar="MANIFEST", help="the campaign manifest (TOML); folders relative to it")
    p.add_argument(
        "--out-dir",
        default=None,
        metavar="DIR",
        help="write the combined report and the per-sequence reports there (created; its parent must exist)",
    )
    _add_cache_dir(p, "registration cache folder (overrides the manifest's cache_dir); a rerun resumes from it")
    p.add_argument("--overwrite", action="store_true", help="replace existing reports in --out-dir")


def _add_simplify(sub: Any, parents: Sequence[argparse.ArgumentParser]) -> None:
    p = _command(sub, "simplify", _cmd_simplify, parents)
    p.add_argument("--input", required=True, metavar="DIR", help="folder of the original frames")
    p.add_argument("--output", required=True, metavar="DIR", help="folder for the simplified frames (created)")
    p.add_argument("--method", choices=("qem", "rqem"), default="qem", help="qem (default) or rqem (Registered QEM)")
    _add_target(p, 0.5, "faces to keep: a count (>= 1) or a ratio in (0, 1) of each frame's faces (default 0.5)")
    _add_weight(
        p,
        "rqem: weight of the registered previous frame's quadrics (default: the library's DEFAULT_WEIGHT, "
        "chosen from the sweep in docs/simplification.md)",
    )
    _add_cache_dir(p, "registration cache folder (rqem only)")
    p.add_argument("--overwrite", action="store_true", help="replace existing files in --output")


def _add_register(sub: Any, parents: Sequence[argparse.ArgumentParser]) -> None:
    p = _command(sub, "register", _cmd_register, parents)
    p.add_argument("--source", required=True, metavar="FILE", help="mesh to move (frame k-1)")
    p.add_argument("--target", required=True, metavar="FILE", help="mesh to align to (frame k)")
    p.add_argument("--out", required=True, metavar="FILE", help="registered mesh (e.g. registered.ply)")
    p.add_argument("--overwrite", action="store_true", help="replace --out if it exists")


def _add_demo(sub: Any, parents: Sequence[argparse.ArgumentParser]) -> None:
    p = _command(sub, "demo", _cmd_demo, parents)
    p.add_argument(
        "--frames", type=int, default=DEMO_FRAMES, help=f"frames of the built-in sequence (default {DEMO_FRAMES})"
    )
    p.add_argument(
        "--resolution",
        type=int,
        default=DEMO_RESOLUTION,
        help=f"mesh resolution of the built-in sequence (default {DEMO_RESOLUTION}: the paper's ~20k vertices / "
        "40k faces per frame; 80 gives about 5k vertices / 10k faces)",
    )
    p.add_argument("--seed", type=int, default=0, help="seed of the built-in sequence (default 0)")
    _add_target(
        p,
        DEMO_TARGET,
        f"faces to keep per frame: a count or a ratio in (0, 1) (default {DEMO_TARGET}: the paper removes 3%% "
        "of the triangles)",
    )
    p.add_argument(
        "--registration",
        choices=("fast", "full"),
        default="full",
        help="full (default): the library's default registration (about 6 s per 20k-vertex frame pair on 2 cores); "
        "fast: 30 optimisation steps per stage and 1000 points per term, quicker with a ~1.4x larger residual",
    )
    _add_weight(p, "Registered QEM's weight of the registered previous frame (default: the library's DEFAULT_WEIGHT)")
    p.add_argument(
        "--weights",
        type=_parse_weights,
        default=DEMO_WEIGHTS,
        metavar="W1,W2,...",
        help="also run Registered QEM at each of these weights beside plain QEM and write weight_sweep.md/.json "
        f"and the Pareto plot weight_sweep.png (default {','.join(f'{w:g}' for w in DEMO_WEIGHTS)}; 'none' skips)",
    )
    p.add_argument("--out-dir", default="torchmeshmetric-demo", metavar="DIR", help="output folder")
    p.add_argument("--overwrite", action="store_true", help="write into --out-dir even if another tool made it")
    p.add_argument("--no-plots", action="store_true", help="skip PNG plots and coloured PLY files")
    p.add_argument("--save-meshes", action="store_true", help="also save the simplified frames as PLY")


def _add_validate(sub: Any) -> None:
    p = _command(sub, "validate", _cmd_validate, ())
    p.add_argument("--full", action="store_true", help="6 frames at resolution 160 (~40k faces), two-sided")
    p.add_argument("--frames", type=int, default=None, help="frames of the built-in sequence (reduced default 4)")
    p.add_argument("--resolution", type=int, default=None, help="mesh resolution (reduced default 48)")
    p.add_argument(
        "--keep", type=float, default=None, help="fraction of faces the tracked simplification keeps (default 0.5)"
    )
    p.add_argument("--seed", type=int, default=0, help="seed of the sequence and the distortions (default 0)")
    p.add_argument("--distortions", default=None, metavar="A,B,...", help="only these distortions (default all)")
    p.add_argument("--out-dir", default="torchmeshmetric-validation", metavar="DIR", help="output folder")
    p.add_argument("--overwrite", action="store_true", help="replace existing output files")
    p.add_argument("--no-plots", action="store_true", help="skip validation.png")


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of the command line."""
    common, evaluation, report = _common_options(), _evaluation_options(), _report_options()
    parser = argparse.ArgumentParser(
        prog="torchmeshmetric", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    _add_evaluate(sub, [common, evaluation, report])
    _add_compare(sub, [common, evaluation, report])
    _add_campaign(sub, [common])
    _add_simplify(sub, [common])
    _add_register(sub, [common])
    _add_demo(sub, [common, evaluation])
    add_mpeg_command(sub)
    from torchmeshmetric.mpeg.ctc_command import add_bdrate_command, add_ctc_command

    add_ctc_command(sub)
    add_bdrate_command(sub)
    _add_validate(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the exit code (0 ok, 1 error, 2 usage error, 3 registration not converged)."""
    args = build_parser().parse_args(argv)
    try:
        return int(run_command(args.func, args))
    except KeyboardInterrupt:
        print("torchmeshmetric: interrupted", file=sys.stderr)
        return 130
    except Exception as exc:
        if os.environ.get("TORCHMESHMETRIC_DEBUG"):
            raise
        message = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        print(f"torchmeshmetric {args.command}: error: {message}", file=sys.stderr)
        return 1


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
