"""The ``report`` command: an existing report (REPORT.json and its REPORT.md) as one self-contained HTML page."""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

from torchmeshmetric._console import say
from torchmeshmetric.cli.options import add_command, input_file_error, path_argument

__all__ = ["add_report_command", "run"]


def run(args: argparse.Namespace) -> int:
    """Write an existing report as one offline HTML page.

    Reads REPORT.json and the Markdown written beside it (REPORT.md: the tables), and writes REPORT.html (or --out):
    the tables (sortable), the per-frame curves drawn from the JSON, and, with --mesh, an interactive 3D viewer of
    error-coloured PLY files (e.g. the demo's error_*.ply) in their own colours. Works for the reports of evaluate,
    compare, demo, campaign (and its sequences) and ctc. The histograms and the error scale need the per-vertex
    distances, which a report does not keep: the commands' own --html writes them.
    """
    from torchmeshmetric.cli._outputs import CLIError, check_writable

    source = Path(args.report)
    markdown_path = source.with_suffix(".md")
    out = Path(args.out) if args.out else source.with_suffix(".html")
    if args.out and out.suffix.lower() != ".html":
        # as every writer checks its suffix: with --overwrite, `--out orig/frame_000.ply` replaced a frame of the
        # evaluated sequence with the page (review X, F9); an .html name is never a frame nor a report
        found = f"the suffix {out.suffix!r}" if out.suffix else "no suffix"
        raise CLIError(f"--out {args.out!r}: expected a PAGE.html file name, found {found}")
    if not source.is_file():
        raise CLIError(f"REPORT {str(source)!r}: no such file")
    # REPORT itself first: a JSON that is no report was said to lack "its Markdown" (found by review)
    try:
        report = json.loads(source.read_text(encoding="utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise CLIError(f"REPORT {str(source)!r}: not a JSON report ({exc})") from exc
    if not isinstance(report, dict):
        raise CLIError(f"REPORT {str(source)!r}: expected a JSON object, found {type(report).__name__}")
    from torchmeshmetric.viz.html_report import check_report, file_layer, report_page, write_html

    try:
        check_report(report)
    except ValueError as exc:
        raise CLIError(f"REPORT {str(source)!r}: not a report this command reads: {exc}") from exc
    if not markdown_path.is_file():
        raise CLIError(f"its Markdown (the tables) {str(markdown_path)!r}: no such file")
    meshes = [Path(m) for m in args.mesh]
    for m in meshes:
        if not m.is_file():
            raise CLIError(f"--mesh {str(m)!r}: no such file")
    inputs = [("REPORT", source), ("its Markdown", markdown_path), *(("--mesh", m) for m in meshes)]
    # without --out the page is REPORT.html: named so, not as an --out the user never gave (found by review O)
    check_writable([out], args.overwrite, inputs=inputs, what="--out" if args.out else "the page")
    layers: list[Any] = []
    for m in meshes:
        try:
            layers.append(file_layer(m))
        except (ValueError, OSError) as exc:  # the reader names its own argument ("path: ..."): name the option
            raise input_file_error("--mesh", m, exc) from None
    page = report_page(
        report, markdown_path.read_text(encoding="utf-8"), title=f"torchmeshmetric report: {source.stem}", meshes=layers
    )
    write_html(out, page, overwrite=args.overwrite)
    say(f"wrote {out}")
    return 0


def add_report_command(sub: Any) -> None:
    """Add the ``report`` subcommand to the CLI's subparsers."""
    p = add_command(sub, "report", run)
    p.add_argument(
        "report",
        type=path_argument,
        metavar="REPORT.json",
        help="a report written by evaluate, compare, demo, campaign or ctc",
    )
    p.add_argument(
        "--out",
        type=path_argument,
        default=None,
        metavar="PAGE.html",
        help="the page, a name ending in .html (default: REPORT.html beside REPORT)",
    )
    p.add_argument(
        "--mesh",
        type=path_argument,
        action="append",
        default=[],
        metavar="FILE.ply",
        help="an error-coloured mesh for the 3D viewer (e.g. the demo's error_*.ply), in its own colours; repeat",
    )
    p.add_argument("--overwrite", action="store_true", help="replace an existing page")
