"""The ``demo`` command, the main job: built-in sequence -> QEM and Registered QEM -> evaluation, report, plots."""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

from torchmeshmetric._console import say
from torchmeshmetric.cli.options import (
    add_command,
    add_html,
    add_seed,
    add_target,
    add_weight,
    as_option_error,
    common_options,
    evaluation_options,
    int_in_range,
    parse_weights,
    path_argument,
)

if TYPE_CHECKING:
    from torchmeshmetric.evaluation.results import SequenceEvaluation

__all__ = ["add_demo_command", "run"]


_DEMO_MARKER = ".torchmeshmetric-demo"
# Defaults sized so that `demo` runs in under 2 minutes on 2 CPU cores; the paper's sizes: --resolution 160
# --registration full (and any --frames), which takes minutes per frame pair on such a machine.
DEMO_FRAMES = 6
DEMO_RESOLUTION = 160
DEMO_TARGET = 0.97
DEMO_WEIGHTS = (0.0, 0.5, 1.0, 2.0, 4.0, 8.0)
DEMO_OUT_DIR = "torchmeshmetric-demo"


def run(args: argparse.Namespace) -> int:
    """The paper's experiment on the built-in sequence (QEM vs Registered QEM).

    Generate the built-in volumetric-video-like sequence, register each original frame k-1 onto frame k, simplify
    every frame with QEM and with Registered QEM (which uses the registered previous frame), evaluate both, print
    the paper's four tables and write report.json/.md/.csv, plots and coloured PLYs. The defaults are the paper's
    sizes (6 frames of ~20k vertices / 40k faces, keep 97% of the faces, full registration): about 30 s on 2 CPU
    cores (more on a busy machine); the first run on a machine first builds the C++ extension once, with a progress
    line (minutes on 2 cores; `torchmeshmetric build` does it ahead). --frames 4 --resolution 80 --registration fast
    is a ~20 s preview.
    """
    from torchmeshmetric.cli._outputs import CLIError
    from torchmeshmetric.cli._shared import (
        device_of,
        dtype_of,
        evaluate_method,
        fast_registration_options,
        simplify_frames,
    )
    from torchmeshmetric.data.demo import demo_sequence
    from torchmeshmetric.evaluation.pipeline import register_pairs
    from torchmeshmetric.evaluation.reports import paper_tables
    from torchmeshmetric.kernels.index_cache import IndexCache
    from torchmeshmetric.registration.cache import RegistrationCache
    from torchmeshmetric.simplification._target import resolve_target

    device = device_of(args)
    out_dir = _demo_out_dir(args)
    t0 = time.perf_counter()
    # --frames (>= 2: one frame pair) and --resolution (>= 16, demo_sequence's least) were refused when parsed
    # (exit 2); demo_sequence refuses sizes beyond this machine's memory before it makes a frame, naming its argument
    try:
        seq = demo_sequence(args.frames, resolution=args.resolution, seed=args.seed)
    except ValueError as exc:
        raise as_option_error(exc, {"num_frames": "--frames", "resolution": "--resolution"}) from None
    frames = [f.to(dtype=dtype_of(args)) for f in seq.frames]
    for f in frames:  # a face count above a frame's faces: refused before the registration, not after it
        try:
            resolve_target(args.target, f.num_faces, "--target")
        except ValueError as exc:
            raise CLIError(str(exc)) from exc
    sizes = ", ".join(f"{f.num_verts}v/{f.num_faces}f" for f in frames)
    say(f"demo sequence: {len(frames)} frames ({sizes}) in {time.perf_counter() - t0:.1f} s")

    t0 = time.perf_counter()
    registrations = register_pairs(
        frames,
        registration_options=fast_registration_options() if args.registration == "fast" else {},
        registration_cache=RegistrationCache(args.cache_dir),
        device=device,
        backend=args.backend,
    )
    residual = ", ".join(f"{float(r.residual.mean()):.2e}" for r in registrations)
    say(
        f"registered {len(registrations)} original frame pairs ({args.registration}) in "
        f"{time.perf_counter() - t0:.1f} s; mean residual to frame k: {residual}"
    )

    t0 = time.perf_counter()
    try:
        simplified = {
            "Orig QEM": simplify_frames(frames, "qem", args.target, None),
            "Reg QEM": simplify_frames(frames, "rqem", args.target, registrations, args.weight),
        }
    except ValueError as exc:  # a target that leaves no face (--target 1)
        raise as_option_error(exc, {"target": "--target"}) from None
    say(f"simplified with QEM and Registered QEM in {time.perf_counter() - t0:.1f} s")

    indexes = IndexCache(max_entries=2 * len(frames))  # each original frame's index built once for both methods
    results = {
        # ground_truth: the built-in sequence's true motion, so the registration's error is reported
        name: evaluate_method(
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
    say(f"wrote to {out_dir}: {', '.join(written)}")
    return 0


def _demo_out_dir(args: argparse.Namespace) -> Path:
    """The demo's output folder, checked (created with the outputs; another tool's non-empty one: --overwrite)."""
    import os

    from torchmeshmetric.cli._outputs import CLIError, check_creatable, check_folder

    out_dir = Path(args.out_dir)
    check_folder(out_dir, "--out-dir", may_create=True)
    check_creatable(out_dir, "--out-dir")  # before the sequence is made and simplified, not after
    if out_dir.exists() and not (out_dir / _DEMO_MARKER).exists() and any(out_dir.iterdir()) and not args.overwrite:
        raise CLIError(f"--out-dir {str(out_dir)!r} exists and was not written by the demo (pass --overwrite)")
    if out_dir.is_dir() and not os.access(out_dir, os.W_OK):
        raise CLIError(f"--out-dir {str(out_dir)!r} is not writable")
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
    from torchmeshmetric._atomic import atomic_write
    from torchmeshmetric.cli._outputs import make_folder, output_set
    from torchmeshmetric.data.io import save_mesh
    from torchmeshmetric.evaluation.reports import report_dict, write_csv, write_json, write_markdown

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
    with output_set("the demo's outputs") as files:
        # The folder and its marker are part of the set: a run that fails (or a bad option) leaves neither
        make_folder(out_dir, "--out-dir", files)
        atomic_write(out_dir / _DEMO_MARKER, "", overwrite=True)
        report = report_dict(results, settings=settings)
        write_json(out_dir / "report.json", report, overwrite=True)
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
        figures: list[tuple[str, bytes]] = []
        if not args.no_plots:
            written += _demo_plots(out_dir, results, simplified, figures)
        if args.html:
            written.append(_demo_html(out_dir, frames, results, simplified, registrations, report, figures))
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
    from torchmeshmetric._atomic import atomic_write
    from torchmeshmetric.evaluation.sweep import registered_qem_sweep
    from torchmeshmetric.viz.sweep import plot_weight_sweep

    t0 = time.perf_counter()
    sweep = registered_qem_sweep(
        frames, registrations, args.target, args.weights, device=device, ground_truth=ground_truth
    )
    say(f"weight sweep ({len(args.weights)} weights + QEM) in {time.perf_counter() - t0:.1f} s")
    table = sweep.markdown()
    print("### Registered QEM weight sweep (mean over pairs of the per-pair Ave)\n\n" + table)
    atomic_write(out_dir / "weight_sweep.md", "# Registered QEM weight sweep\n\n" + table, overwrite=True)
    atomic_write(out_dir / "weight_sweep.json", json.dumps(sweep.as_dict(), indent=2) + "\n", overwrite=True)
    written = ["weight_sweep.md", "weight_sweep.json"]
    if plots:
        plot_weight_sweep(sweep, out_dir / "weight_sweep.png", overwrite=True)
        written.append("weight_sweep.png")
    return written


def _demo_html(
    out_dir: Path,
    frames: list[Any],
    results: dict[str, Any],
    simplified: dict[str, list[Any]],
    registrations: list[Any],
    report: dict[str, Any],
    figures: list[tuple[str, bytes]],
) -> str:
    """``report.html``: the report's page with the PNGs of --plots (or, with --no-plots, drawn for the page)."""
    from torchmeshmetric.evaluation.reports import markdown_report
    from torchmeshmetric.viz.html_report import best_pair_layers, report_page, write_html
    from torchmeshmetric.viz.plots import histogram_figure, png_bytes

    best = next(iter(results.values())).best_pair_index()
    draw_curves = not figures  # with plots, `figures` holds the PNGs just written (curves, histograms): not redrawn
    if not figures:
        pairs = {n: r.pairs[best] for n, r in results.items()}
        figures = [("distance sets of the best pair", png_bytes(histogram_figure(pairs)))]
    k = next(iter(results.values())).pairs[best].frame
    registered = registrations[k - 1].registered_mesh(frames[k - 1])
    # the built-in performer is ~1.9 units tall (data.demo): its distances are in those units
    meshes = best_pair_layers(results, frames, simplified, registered, unit="units (performer ~1.9 tall)")
    page = report_page(
        report,
        markdown_report(results),
        title="torchmeshmetric demo: QEM vs Registered QEM",
        figures=figures,
        meshes=meshes,
        curves=draw_curves,
    )
    return write_html(out_dir / "report.html", page, overwrite=True).name


def _demo_plots(
    out_dir: Path, results: dict[str, Any], simplified: dict[str, list[Any]], figures: list[tuple[str, bytes]]
) -> list[str]:
    """Histograms and curves (PNG), and each method's best frame coloured by its error (PLY, one colour scale).

    The colour is the distance of each simplified vertex to the registered frame k-1 (temporal consistency). The
    PNGs are appended to ``figures`` (for the --html page, which shows them as they are).
    """
    from torchmeshmetric._atomic import atomic_write
    from torchmeshmetric.viz.colors import write_error_ply
    from torchmeshmetric.viz.html_report import CURVES_CAPTION
    from torchmeshmetric.viz.plots import frame_curves_figure, histogram_figure, png_bytes

    best = next(iter(results.values())).best_pair_index()
    curves = png_bytes(frame_curves_figure({n: [p.as_dict() for p in r.pairs] for n, r in results.items()}))
    histograms = png_bytes(histogram_figure({n: r.pairs[best] for n, r in results.items()}))
    atomic_write(out_dir / "frame_curves.png", curves, overwrite=True)
    atomic_write(out_dir / "histograms.png", histograms, overwrite=True)
    figures += [(CURVES_CAPTION, curves), ("distance sets of the best pair", histograms)]
    written = ["histograms.png", "frame_curves.png"]
    # one scale for all methods (none when every distance is 0: write_error_ply then takes its default)
    vmax = max(float(r.pairs[best].distances["surface_k_minus_1"].max()) for r in results.values()) or None
    for name, result in results.items():
        pair = result.pairs[best]
        path = out_dir / f"error_{name.lower().replace(' ', '_')}_frame{pair.frame:03d}.ply"
        write_error_ply(
            path, simplified[name][pair.frame], pair.distances["surface_k_minus_1"], vmax=vmax, overwrite=True
        )
        written.append(path.name)
    return written


def add_demo_command(sub: Any) -> None:
    """Add the ``demo`` subcommand to the CLI's subparsers."""
    p = add_command(sub, "demo", run, [common_options(), evaluation_options()])
    p.add_argument(
        "--frames",
        type=int_in_range(2),
        default=DEMO_FRAMES,
        help=f"frames of the built-in sequence (default {DEMO_FRAMES})",
    )
    p.add_argument(
        "--resolution",
        type=int_in_range(16),  # demo_sequence's least resolution, refused when parsed (exit 2) as docs/cli.md says
        default=DEMO_RESOLUTION,
        help=f"mesh resolution of the built-in sequence (default {DEMO_RESOLUTION}: the paper's ~20k vertices / "
        "40k faces per frame; 80 gives about 5k vertices / 10k faces)",
    )
    add_seed(p, "seed of the built-in sequence (default 0; 0 to 2**63-1)")
    add_target(
        p,
        DEMO_TARGET,
        f"faces to keep per frame: a count or a ratio in (0, 1] (default {DEMO_TARGET}: the paper removes 3%% "
        "of the triangles)",
    )
    p.add_argument(
        "--registration",
        choices=("fast", "full"),
        default="full",
        help="full (default): the library's default registration (about 6 s per 20k-vertex frame pair on 2 cores); "
        "fast: 30 optimisation steps in the first three stages (the last keeps 80) and 1000 points per term, "
        "quicker with a ~1.4x larger residual",
    )
    add_weight(p, "Registered QEM's weight of the registered previous frame (default: the library's DEFAULT_WEIGHT)")
    p.add_argument(
        "--weights",
        type=parse_weights,
        default=DEMO_WEIGHTS,
        metavar="W1,W2,...",
        help="also run Registered QEM at each of these weights beside plain QEM and write weight_sweep.md/.json "
        f"and the Pareto plot weight_sweep.png (default {','.join(f'{w:g}' for w in DEMO_WEIGHTS)}; 'none' skips)",
    )
    p.add_argument(
        "--out-dir",
        type=path_argument,
        default=DEMO_OUT_DIR,
        metavar="DIR",
        help=f"output folder (default {DEMO_OUT_DIR}, in the current folder)",
    )
    p.add_argument("--overwrite", action="store_true", help="write into --out-dir even if another tool made it")
    p.add_argument("--no-plots", action="store_true", help="skip PNG plots and coloured PLY files")
    p.add_argument("--save-meshes", action="store_true", help="also save the simplified frames as PLY")
    add_html(p, "also write report.html: the report as one offline page (tables, curves, 3D error viewer)")
