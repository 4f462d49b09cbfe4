"""The ``torchmeshmetric ctc`` command: the V-DMC CTC metric step over a decoded sequence.

Only the standard library is imported here: ``--help`` stays fast; torch and the metrics load inside the run
function. Every option and every frame file is checked, and the outputs' folder, before any frame is computed; the
next frame pair is read while the current one is computed.
"""

from __future__ import annotations

import argparse
import csv
import io
import json
import math
import time
from pathlib import Path
from typing import Any

from torchmeshmetric._console import say
from torchmeshmetric._format import format_number, json_safe
from torchmeshmetric.cli.options import ctc_options, output_stem, path_argument
from torchmeshmetric.mpeg.ctc.box import _FLOAT32_MAX, _float32
from torchmeshmetric.mpeg.ctc.frame_pattern import frame_path

__all__ = ["add_ctc_command", "frame_path"]


def _fmt(x: Any) -> str:
    return format_number(x, ".4f")


def _csv(d: dict[str, Any], columns: list[str]) -> str:
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["frame", *columns])
    for row in d["frames"]:
        w.writerow([row["frame"], *(repr(float(row[c])) if c in row else "" for c in columns)])
    w.writerow(["mean", *(repr(float(d["mean"][c])) if c in d["mean"] else "" for c in columns)])
    return buf.getvalue()


def _markdown(d: dict[str, Any], columns: list[str], settings: dict[str, Any]) -> str:
    lines = ["# V-DMC CTC metrics", ""]
    lines += [f"- {k}: `{v}`" for k, v in settings.items()]
    lines += ["", "| frame | " + " | ".join(columns) + " |", "|---|" + "---:|" * len(columns)]
    for row in d["frames"]:
        lines.append(f"| {row['frame']} | " + " | ".join(_fmt(row.get(c, "")) for c in columns) + " |")
    lines.append("| **mean** | " + " | ".join(f"**{_fmt(d['mean'].get(c, ''))}**" for c in columns) + " |")
    lines += ["", "Mean: mmetric's statistic, the mean over frames of the per-frame PSNR clipped at 99.99 dB.", ""]
    return "\n".join(lines)


_STAGES = ("read", "dequantize", "grid", "pcc", "ibsm")


def _check_options(args: argparse.Namespace) -> tuple[list[float], list[float]]:
    """Every numeric option, by its name, before any file is read."""
    if args.last_frame < args.first_frame:
        raise ValueError(f"--last-frame: {args.last_frame} is before --first-frame {args.first_frame}")
    if not math.isfinite(args.resolution) or args.resolution <= 0:
        raise ValueError(f"--resolution: expected a positive number (the box's longest side), found {args.resolution}")
    peak = _float32(args.resolution)
    if not 0 < peak <= _FLOAT32_MAX:  # found per frame, as the library's "peak: ... (while running frame 0)"
        raise ValueError(
            f"--resolution: expected a positive number within float32's range (mmetric rounds the peak to float32), "
            f"found {args.resolution!r}, which rounds to {peak if peak <= _FLOAT32_MAX else math.inf}"
        )
    return ctc_options(args, (("--grid-size", args.grid_size, 1, 1 << 20),
                              ("--ibsm-resolution", args.ibsm_resolution, 1, 1 << 15),
                              ("--ibsm-cameras", args.ibsm_cameras, 2, 4096)))  # fmt: skip


def _frame_files(args: argparse.Namespace) -> list[tuple[int, Path, Path, Path | None, Path | None]]:
    """Every frame's files, each checked to be a non-empty file."""
    files = []
    for k in range(args.first_frame, args.last_frame + 1):
        paths = [
            (Path(frame_path(getattr(args, attr), k, opt)) if getattr(args, attr) is not None else None, opt)
            for attr, opt in (("reference", "--reference"), ("decoded", "--decoded"),
                              ("reference_texture", "--reference-texture"), ("decoded_texture", "--decoded-texture"))
        ]  # fmt: skip
        for p, opt in paths:
            if p is None:
                continue
            if p.is_dir():
                raise ValueError(f"{opt}: frame {k}: {str(p)!r} is a directory, expected a file")
            if not p.is_file():
                raise ValueError(f"{opt}: frame {k}: file {str(p)!r} not found")
            if p.stat().st_size == 0:
                raise ValueError(f"{opt}: frame {k}: file {str(p)!r} is empty")
        (ref, _), (dis, _), (rt, _), (dt, _) = paths
        assert ref is not None and dis is not None
        files.append((k, ref, dis, rt, dt))
    return files


def _check_colour(args: argparse.Namespace, k: int, ref: Any, dis: Any, first: dict[str, bool]) -> None:
    """A texture given for UV-less frames, or colour present in some frames only, would change the colour means."""
    for name, mesh, option in (("reference", ref, "--reference-texture"), ("decoded", dis, "--decoded-texture")):
        if getattr(args, option[2:].replace("-", "_")) is not None and mesh.uvs is None:
            raise ValueError(f"{option}: frame {k}: the {name} OBJ has no texture coordinates (vt), so its texture "
                             "cannot be sampled")  # fmt: skip
        has = bool(mesh.has_color)
        if first.setdefault(name, has) != has:
            now, before = ("has", "have none") if has else ("has no", "have")
            raise ValueError(f"--{name}: frame {k}: the {name} frame {now} colour (texture or vertex colours) while "
                             f"the earlier frames {before}; the colour means need every frame")  # fmt: skip


def load_ctc_mesh(path: str | Path, texture: str | Path | None, option: str) -> Any:
    """A frame's textured mesh, a reader's error retold about the option that gave the file.

    The library names its arguments (``texture: cannot read texture ...``): which of the two textures was not said
    (review X F10). Now ``--decoded-texture: cannot read texture ...`` (or ``--decoded's texture``, from its MTL).

    Args:
        path: the mesh file.
        texture: the texture given on the command line, or ``None`` (the MTL's).
        option: the mesh's option, ``--reference`` or ``--decoded``.
    """
    from torchmeshmetric.cli.options import as_option_error
    from torchmeshmetric.mpeg.core.textured_mesh import load_textured_mesh

    names = {"path": option, "mesh": option, "texture": f"{option}-texture" if texture else f"{option}'s texture"}
    try:
        return load_textured_mesh(path, texture)
    except ValueError as exc:
        raise as_option_error(exc, names) from exc


def _run_ctc(args: argparse.Namespace) -> int:
    lo, hi = _check_options(args)
    files = _frame_files(args)
    if args.html and args.out is None:
        raise ValueError("--html: the page is written beside the report, so it needs --out REPORT")
    exts = ("json", "csv", "md", "html") if args.html else ("json", "csv", "md")
    if args.out is not None:  # REPORT or REPORT.json (as evaluate --out): never REPORT.json.json
        args.out = output_stem(args.out, "--out", (".json", ".csv", ".md", ".html"))
    outputs = [] if args.out is None else [Path(f"{args.out}.{ext}") for ext in exts]
    from torchmeshmetric.cli._outputs import check_writable

    inputs = [
        (option, p)
        for frame in files
        for option, p in zip(
            ("--reference", "--decoded", "--reference-texture", "--decoded-texture"), frame[1:], strict=True
        )
    ]
    check_writable(outputs, args.overwrite, inputs=inputs, what="--out")  # never an input, distinct, writable
    from torchmeshmetric.mpeg.ctc.chain import CTC_COLUMNS, CtcSequence

    done = _compute(args, files, lo, hi)
    if done is None:
        return 0
    seq = CtcSequence(done, tuple(c for c in CTC_COLUMNS if any(c in f.figures for f in done)))
    _report(args, seq, lo, hi, outputs)
    return 0


def _compute(args: argparse.Namespace, files: list[Any], lo: list[float], hi: list[float]) -> list[Any] | None:
    """Every frame's figures (on rank 0 under torchrun, ``None`` on the others); frames read one pair ahead."""
    from torchmeshmetric.data.sequence import Prefetcher
    from torchmeshmetric.mpeg.ctc.chain import CTC_COLUMNS, CtcFrame, ctc_frame
    from torchmeshmetric.mpeg.ctc.settings import CtcSettings
    from torchmeshmetric.tasks import rank_and_world_size, run_tasks, shard

    start = time.perf_counter()
    rank, world = rank_and_world_size()

    def load(task: tuple[int, Path, Path, Path | None, Path | None]) -> tuple[Any, Any, float]:
        _, ref, dis, rt, dt = task
        t0 = time.perf_counter()
        # the reader refuses a file without faces too (both the grid sampling and IBSM need a surface); the frame
        # is the task's note ("while running frame k"), said once
        r = load_ctc_mesh(ref, rt, "--reference")
        return r, load_ctc_mesh(dis, dt, "--decoded"), time.perf_counter() - t0

    settings = CtcSettings(qp=args.qp, qt=args.qt, min_pos=lo, max_pos=hi, resolution=args.resolution,
                           decoded_qt=args.decoded_qt, grid_size=args.grid_size,
                           ibsm_resolution=None if args.no_ibsm else args.ibsm_resolution,
                           ibsm_cameras=args.ibsm_cameras)  # fmt: skip
    ahead = Prefetcher([files[i] for i in shard(len(files), rank, world)], load=load, ahead=1)
    totals = dict.fromkeys(_STAGES, 0.0)
    colour: dict[str, bool] = {}

    def one_frame(task: tuple[int, Path, Path, Path | None, Path | None]) -> CtcFrame:
        k = task[0]
        r, d, read_s = next(ahead)  # run_tasks takes this rank's tasks in the prefetcher's order
        _check_colour(args, k, r, d, colour)
        f = ctc_frame(r, d, settings, frame=k)
        seconds = {"read": read_s, **f.seconds}
        figs = "  ".join(f"{c} {_fmt(f.figures[c])}" for c in CTC_COLUMNS if c in f.figures)
        line = f"ctc: frame {k}: {figs}  [{time.perf_counter() - start:.1f} s]"
        if args.verbose:
            for s in _STAGES:
                totals[s] += seconds.get(s, 0.0)
            line += "  " + " ".join(f"{s} {seconds.get(s, 0.0):.2f}" for s in _STAGES)
        say(line)
        return f

    with ahead:
        # under torchrun the frames are shared round robin by the ranks and gathered on rank 0, which reports
        done = run_tasks(one_frame, files, describe=lambda t: f"frame {t[0]}", to=0)
    if args.verbose:
        wall = time.perf_counter() - start
        parts = " ".join(f"{s} {totals[s]:.2f}" for s in _STAGES)
        say(f"ctc: {len(files)} frames in {wall:.2f} s (reading overlapped); stage seconds: {parts}")
    if done is None or rank != 0:
        return None
    return done


def _report(args: argparse.Namespace, seq: Any, lo: list[float], hi: list[float], outputs: list[Path]) -> None:
    from torchmeshmetric._atomic import atomic_file_set, atomic_write

    d = seq.as_dict()
    columns = list(seq.columns)
    settings = {
        "reference": args.reference,
        "reference_texture": args.reference_texture,  # the page's settings left the textures out (review R #11)
        "decoded": args.decoded,
        "decoded_texture": args.decoded_texture,
        "frames": f"{args.first_frame}..{args.last_frame}",
        "qp": args.qp,
        "qt": args.qt,
        "decoded_qt": args.decoded_qt,
        "min_pos": lo,
        "max_pos": hi,
        "resolution": args.resolution,
        "grid_size": args.grid_size,
        "ibsm": None if args.no_ibsm else {"resolution": args.ibsm_resolution, "cameras": args.ibsm_cameras},
    }
    if outputs:
        with atomic_file_set():
            atomic_write(outputs[0], json.dumps(json_safe({**d, "settings": settings}), indent=1) + "\n",
                         overwrite=args.overwrite)  # fmt: skip
            atomic_write(outputs[1], _csv(d, columns), overwrite=args.overwrite)
            atomic_write(outputs[2], _markdown(d, columns, settings), overwrite=args.overwrite)
            if args.html:
                from torchmeshmetric.viz.html_report import report_page, write_html

                page = report_page(json_safe({**d, "settings": settings}), _markdown(d, columns, settings),
                                   title=f"V-DMC CTC metrics: {Path(args.out).name}")  # fmt: skip
                write_html(outputs[3], page, overwrite=args.overwrite)
    if args.json:
        print(json.dumps(json_safe(d), indent=1))
    else:
        width = max(len(c) for c in columns)
        for c in columns:
            print(f"{c.ljust(width)}  {_fmt(d['mean'][c])}")
        if outputs:
            print("wrote " + ", ".join(str(p) for p in outputs))


def add_ctc_command(sub: Any) -> None:
    """Add the ``ctc`` subcommand to the CLI's subparsers."""
    p = sub.add_parser(
        "ctc",
        help="the V-DMC CTC metric step on a decoded sequence (mmetric's sequence chain: grid D1/D2/colour, IBSM)",
        description="The metric step of the MPEG V-DMC common test conditions, as the test model's scripts/run.sh runs "
        "mmetric v1.1.7 (mm sequence), frame by frame: dequantize --useFixedPoint both meshes over the sequence box "
        "(source with --qp/--qt, decoded with --qp/--decoded-qt, UV box 0..1); reindex --sort oriented; sample --mode "
        "grid --useNormal --useFixedPoint --bilinear --gridSize N over the sequence box (--min-pos/--max-pos); compare "
        "--mode pcc --resolution R (R: the test model passes the longest side of the sequence's bounding box); compare "
        "--mode ibsm (2048 x 2048, 16 cameras, software renderer, culling and reordering on) on the dequantised "
        "meshes. Prints the CTC spreadsheet's columns GridD1, GridD2, GridLuma, GridChromaCb, GridChromaCr, IbsmGeom "
        "(IBSM GEO PSNR), IbsmLuma (IBSM Y PSNR), each the mean over frames of the per-frame PSNR clipped at 99.99 "
        "(mmetric's statistics). Frames are read one pair at a time; progress per frame goes to stderr.",
    )
    p.add_argument(
        "--reference",
        type=path_argument,
        required=True,
        metavar="PATTERN",
        help="quantised source frames, e.g. src_%%04d.obj",
    )
    p.add_argument(
        "--decoded", type=path_argument, required=True, metavar="PATTERN", help="decoded frames, e.g. dec_%%04d.obj"
    )
    p.add_argument("--first-frame", type=int, required=True, metavar="F", help="first frame number (included)")
    p.add_argument("--last-frame", type=int, required=True, metavar="L", help="last frame number (included)")
    p.add_argument("--qp", type=int, required=True, help="geometry bit depth (mm dequantize --qp)")
    p.add_argument("--qt", type=int, required=True, help="UV bit depth of the source (mm dequantize --qt)")
    p.add_argument("--decoded-qt", type=int, default=0, help="UV bit depth of the decoded frames (test model: 0)")
    p.add_argument("--min-pos", required=True, metavar='"X Y Z"', help="the sequence box's min corner (--minPos)")
    p.add_argument("--max-pos", required=True, metavar='"X Y Z"', help="the sequence box's max corner (--maxPos)")
    p.add_argument("--resolution", type=float, required=True, metavar="R",
                   help="PSNR peak of the grid figures (compare --resolution; CTC: the box's longest side)",
                   )  # fmt: skip
    p.add_argument(
        "--reference-texture",
        type=path_argument,
        default=None,
        metavar="PATTERN",
        help="source textures (default: MTL)",
    )
    p.add_argument(
        "--decoded-texture", type=path_argument, default=None, metavar="PATTERN", help="decoded textures (default: MTL)"
    )
    p.add_argument("--grid-size", type=int, default=1024, metavar="N", help="sample --gridSize (default 1024)")
    p.add_argument("--ibsm-resolution", type=int, default=2048, metavar="N", help="--ibsmResolution (2048)")
    p.add_argument("--ibsm-cameras", type=int, default=16, metavar="N", help="--ibsmCameraCount (16)")
    p.add_argument("--no-ibsm", action="store_true", help="leave IBSM (IbsmGeom, IbsmLuma) out")
    p.add_argument("--json", action="store_true", help='print {"frames": [...], "mean": {...}} (non-finite: "inf")')
    p.add_argument(
        "--out",
        type=path_argument,
        default=None,
        metavar="REPORT",
        help="write REPORT.json, REPORT.csv, REPORT.md (REPORT or REPORT.json)",
    )
    p.add_argument("--overwrite", action="store_true", help="replace existing --out files")
    p.add_argument("--html", action="store_true", help="also write REPORT.html: the report as one offline page")
    p.add_argument(
        "--verbose", action="store_true", help="seconds per stage (read, dequantize, grid, pcc, ibsm) on stderr"
    )
    p.set_defaults(func=_run_ctc)
