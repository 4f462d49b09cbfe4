"""The ``torchmeshmetric ctc`` and ``torchmeshmetric bdrate`` commands (the V-DMC CTC metric step and its BD-rates).

Only the standard library is imported here: ``--help`` stays fast; torch and the metrics load inside the run
functions.
"""

from __future__ import annotations

import argparse
import csv
import io
import json
import math
import re
import sys
import time
from pathlib import Path
from typing import Any

__all__ = ["add_bdrate_command", "add_ctc_command", "frame_path"]

_COLUMNS = ("GridD1", "GridD2", "GridLuma", "GridChromaCb", "GridChromaCr", "IbsmGeom", "IbsmLuma")
_FIELD = re.compile(r"%[-+ #0]*\d*[diu]")


def frame_path(pattern: str, frame: int, option: str = "PATTERN") -> str:
    """One frame's file name from a printf frame pattern such as ``dec_%04d.obj`` (mmetric's convention).

    Raises:
        ValueError: the pattern has no integer field, or more than one conversion.

    Example:
        >>> frame_path("dec_%04d.obj", 7)
        'dec_0007.obj'
    """
    fields = _FIELD.findall(pattern.replace("%%", ""))
    if len(fields) != 1 or pattern.replace("%%", "").count("%") != 1:
        raise ValueError(f"{option}: expected one printf integer field such as dec_%04d.obj, found {pattern!r}")
    return pattern % frame


def _corner(text: str, option: str) -> list[float]:
    parts = [p for p in re.split(r"[,\s]+", text.strip()) if p]
    try:
        values = [float(p) for p in parts]
    except ValueError:
        values = []
    if len(values) != 3 or not all(math.isfinite(v) for v in values):
        raise ValueError(f'{option}: expected three finite numbers such as "-1 -1 -1", found {text!r}')
    return values


def _fmt(x: Any) -> str:
    if isinstance(x, float):
        return "inf" if math.isinf(x) else ("nan" if math.isnan(x) else f"{x:.4f}")
    return str(x)


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


def _run_ctc(args: argparse.Namespace) -> int:
    from torchmeshmetric._atomic import atomic_file_set, atomic_write
    from torchmeshmetric.mpeg.command import json_safe

    if args.last_frame < args.first_frame:
        raise ValueError(f"--last-frame: {args.last_frame} is before --first-frame {args.first_frame}")
    if not math.isfinite(args.resolution) or args.resolution <= 0:
        raise ValueError(f"--resolution: expected a positive number (the box's longest side), found {args.resolution}")
    lo, hi = _corner(args.min_pos, "--min-pos"), _corner(args.max_pos, "--max-pos")
    if any(h < lo_ for lo_, h in zip(lo, hi, strict=True)):
        raise ValueError(f"--max-pos: {hi} is below --min-pos {lo}")
    frames = list(range(args.first_frame, args.last_frame + 1))
    # every file is checked before any work starts
    files = []
    for k in frames:
        ref = Path(frame_path(args.reference, k, "--reference"))
        dis = Path(frame_path(args.decoded, k, "--decoded"))
        rt = (
            None
            if args.reference_texture is None
            else Path(frame_path(args.reference_texture, k, "--reference-texture"))
        )
        dt = None if args.decoded_texture is None else Path(frame_path(args.decoded_texture, k, "--decoded-texture"))
        for p, opt in ((ref, "--reference"), (dis, "--decoded"), (rt, "--reference-texture"),
                       (dt, "--decoded-texture")):  # fmt: skip
            if p is not None and not p.is_file():
                raise ValueError(f"{opt}: frame {k}: file {str(p)!r} not found")
        files.append((k, ref, dis, rt, dt))
    outputs = []
    if args.out is not None:
        outputs = [Path(f"{args.out}.{ext}") for ext in ("json", "csv", "md")]
        for p in outputs:
            if p.exists() and not args.overwrite:
                raise ValueError(f"--out: {str(p)!r} already exists (pass --overwrite to replace it)")

    from torchmeshmetric.mpeg.ctc import CtcFrame, CtcSequence, ctc_frame
    from torchmeshmetric.mpeg.textured_mesh import load_textured_mesh
    from torchmeshmetric.tasks import rank_and_world_size, run_tasks

    start = time.perf_counter()

    def one_frame(task: tuple[int, Path, Path, Path | None, Path | None]) -> CtcFrame:
        k, ref, dis, rt, dt = task
        try:  # the reader refuses a file without faces too (both the grid sampling and IBSM need a surface)
            r, d = load_textured_mesh(ref, rt), load_textured_mesh(dis, dt)
        except ValueError as exc:
            raise ValueError(f"frame {k}: {exc}") from exc
        f = ctc_frame(
            r,
            d,
            qp=args.qp,
            qt=args.qt,
            min_pos=lo,
            max_pos=hi,
            resolution=args.resolution,
            decoded_qt=args.decoded_qt,
            grid_size=args.grid_size,
            ibsm_resolution=None if args.no_ibsm else args.ibsm_resolution,
            ibsm_cameras=args.ibsm_cameras,
            frame=k,
        )
        figs = "  ".join(f"{c} {_fmt(f.figures[c])}" for c in _COLUMNS if c in f.figures)
        elapsed = time.perf_counter() - start
        print(f"ctc: frame {k}: {figs}  [{elapsed:.1f} s]", file=sys.stderr, flush=True)
        return f

    # under torchrun the frames are shared round robin by the ranks and gathered on rank 0, which reports
    done = run_tasks(one_frame, files, describe=lambda t: f"frame {t[0]}", to=0)
    if done is None or rank_and_world_size()[0] != 0:
        return 0
    seq = CtcSequence(done, tuple(c for c in _COLUMNS if any(c in f.figures for f in done)))
    d = seq.as_dict()
    columns = list(seq.columns)
    settings = {
        "reference": args.reference,
        "decoded": args.decoded,
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
    if args.json:
        print(json.dumps(json_safe(d), indent=1))
    else:
        width = max(len(c) for c in columns)
        for c in columns:
            print(f"{c.ljust(width)}  {_fmt(d['mean'][c])}")
        if outputs:
            print("wrote " + ", ".join(str(p) for p in outputs))
    return 0


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
    p.add_argument("--reference", required=True, metavar="PATTERN", help="quantised source frames, e.g. src_%%04d.obj")
    p.add_argument("--decoded", required=True, metavar="PATTERN", help="decoded frames, e.g. dec_%%04d.obj")
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
    p.add_argument("--reference-texture", default=None, metavar="PATTERN", help="source textures (default: MTL)")
    p.add_argument("--decoded-texture", default=None, metavar="PATTERN", help="decoded textures (default: MTL)")
    p.add_argument("--grid-size", type=int, default=1024, metavar="N", help="sample --gridSize (default 1024)")
    p.add_argument("--ibsm-resolution", type=int, default=2048, metavar="N", help="--ibsmResolution (2048)")
    p.add_argument("--ibsm-cameras", type=int, default=16, metavar="N", help="--ibsmCameraCount (16)")
    p.add_argument("--no-ibsm", action="store_true", help="leave IBSM (IbsmGeom, IbsmLuma) out")
    p.add_argument("--json", action="store_true", help='print {"frames": [...], "mean": {...}} (non-finite: "inf")')
    p.add_argument("--out", default=None, metavar="REPORT", help="write REPORT.json, REPORT.csv, REPORT.md")
    p.add_argument("--overwrite", action="store_true", help="replace existing --out files")
    p.set_defaults(func=_run_ctc)


def _read_curve(path: str) -> dict[str, list[float]]:
    p = Path(path)
    if not p.is_file():
        raise ValueError(f"{path}: file not found")
    with open(p, newline="", encoding="utf-8") as fh:
        reader = csv.DictReader(fh)
        if reader.fieldnames is None or "rate" not in reader.fieldnames:
            raise ValueError(f"{path}:1: expected a header with a 'rate' column and one column per metric")
        cols: dict[str, list[float]] = {k: [] for k in reader.fieldnames if k}
        for lineno, row in enumerate(reader, 2):
            for k in cols:
                try:
                    cols[k].append(float(row[k]))
                except (TypeError, ValueError):
                    raise ValueError(f"{path}:{lineno}: column {k!r}: expected a number, found {row[k]!r}") from None
    return cols


def _run_bdrate(args: argparse.Namespace) -> int:
    from torchmeshmetric.mpeg.bd_rate import bd_rate

    a, b = _read_curve(args.anchor), _read_curve(args.test)
    metrics = [k for k in a if k != "rate" and k in b]
    if not metrics:
        raise ValueError(f"{args.test}: no metric column in common with {args.anchor}")
    out = {m: bd_rate(a["rate"], a[m], b["rate"], b[m]) for m in metrics}
    if args.json:
        from torchmeshmetric.mpeg.command import json_safe

        print(json.dumps(json_safe({"bd_rate": out}), indent=1))
    else:
        width = max(len(m) for m in metrics)
        for m in metrics:
            print(f"{m.ljust(width)}  {out[m]:+.4f} %")
    return 0


def add_bdrate_command(sub: Any) -> None:
    """Add the ``bdrate`` subcommand to the CLI's subparsers."""
    p = sub.add_parser(
        "bdrate",
        help="BD-rate of a test codec against an anchor (the CTC spreadsheet's bdRateExtend), per metric",
        description="Bjontegaard delta rate in percent of TEST against ANCHOR, per metric column present in both "
        "CSVs (a 'rate' column and one PSNR column per metric, one row per rate point): log10(rate) as a piecewise "
        "cubic Hermite function of PSNR (the CTC spreadsheet's bdRateExtend: its slopes, no monotonicity clamp), "
        "integrated exactly over the overlapping PSNR range; +-100 when the curves do not overlap. Negative = TEST "
        "needs less rate for the same quality.",
    )
    p.add_argument("anchor", metavar="ANCHOR.csv", help="the anchor's rate points")
    p.add_argument("test", metavar="TEST.csv", help="the tested codec's rate points")
    p.add_argument("--json", action="store_true", help='print {"bd_rate": {"GridD1": percent, ...}}')
    p.set_defaults(func=_run_bdrate)
