"""The ``torchmeshmetric ctc-campaign MANIFEST`` command: a whole V-DMC CTC campaign and the CTC sheet's summary.

Only the standard library is imported here (``--help`` stays fast); the campaign loads the metrics when it runs.
"""

from __future__ import annotations

import argparse
import json
import re
import time
from pathlib import Path
from typing import Any

from torchmeshmetric._console import say
from torchmeshmetric.cli.options import add_command, cache_folder, path_argument

__all__ = ["add_ctc_campaign_command", "run"]

#: The files written in --out-dir besides the RD plots.
_TABLES = ("anchor.csv", "test.csv", "frames.csv", "summary.csv", "summary.md", "summary.json")


def _slug(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9._-]+", "_", text).strip("_") or "x"


def _plot_name(cond_id: int, sequence: str) -> str:
    return f"rd_c{cond_id}_{_slug(sequence)}.png"


_PLOT_NAME = re.compile(r"rd_c\d+_[A-Za-z0-9._-]+\.png")


def _earlier_plots(out: Path) -> list[str]:
    """The RD plots an earlier run of this command wrote in ``out``: those its ``summary.json`` lists."""
    try:
        report = json.loads((out / "summary.json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return []
    if not isinstance(report, dict) or report.get("tool") != "torchmeshmetric" or "conditions" not in report:
        return []
    plots = report.get("plots")
    return [p for p in plots if isinstance(p, str) and _PLOT_NAME.fullmatch(p)] if isinstance(plots, list) else []


def run(args: argparse.Namespace) -> int:
    """Run a V-DMC CTC campaign: every sequence, condition, rate and frame of a test codec and an anchor.

    Reads a TOML manifest (examples/ctc_campaign.toml, docs/ctc.md): sequences (quantised source frames, box, bit
    depths, frame rate, class), conditions and rates, and for the anchor and the test codec their decoded frames and
    bitstream figures (the test model's CSV, bitstream files, encoder and decoder logs, or values in the manifest).
    Runs mmetric's CTC chain (the ctc command's) on every frame not in the cache folder yet (a rerun resumes; a
    second codec reuses the anchor's frames), then writes in --out-dir: anchor.csv and test.csv (the test model's
    CSV, as collect_results.sh collects it from mmetric), frames.csv (every frame's figures), summary.csv/.md/.json
    (the CTC spreadsheet's summary: BD-rate per metric, BD-TotGeoRate, BD-AttrRate, bpif, component ratios, time
    and memory ratios; class and overall averages) and one RD-curve PNG per sequence and lossy condition. Under
    torchrun the frames are shared by all processes and rank 0 writes the same files.
    """
    from torchmeshmetric.cli._outputs import CLIError, check_folder, check_writable, make_folder, output_set
    from torchmeshmetric.mpeg.ctc.manifest import load_ctc_campaign

    start = time.perf_counter()
    campaign = load_ctc_campaign(args.manifest)
    out = Path(args.out_dir)
    names = list(_TABLES)
    if not args.no_plots:
        slugs: dict[str, str] = {}
        for s in campaign.sequences:  # "sphere a" and "sphere_a": one plot file, the second written over the first
            if (other := slugs.setdefault(_slug(s.name), s.name)) != s.name:
                raise CLIError(
                    f"sequences {other!r} and {s.name!r} would write the same RD plots (rd_c<condition>_"
                    f"{_slug(s.name)}.png): rename one, or pass --no-plots"
                )
        names += [
            _plot_name(c.cond_id, s.name)
            for c in campaign.conditions
            if not c.lossless and len(c.rates) > 1
            for s in campaign.sequences
        ]
    check_folder(out, "--out-dir", may_create=True)  # a file there is refused now, not after the campaign ran
    from torchmeshmetric.mpeg.ctc.campaign import plan_frames, run_ctc_campaign

    # the frames first, each file checked in order: a frame_count typo (300000 for 300) stops at its first missing
    # file at once, where listing and resolving every input path of the campaign took minutes and GBs (review R #5)
    tasks = plan_frames(campaign)
    targets = [out / n for n in names] if out.is_dir() else [out]
    check_writable(
        targets,
        args.overwrite,
        inputs=campaign.input_files(),
        # a report in the folder is named as the folder's: "--out-dir '.': its 'anchor.csv' is the input [anchor]
        # csv" (it read "--out-dir 'anchor.csv' is the input ...", naming a file as the option's value; review R #10)
        what=[f"--out-dir {str(out)!r}: its" if t != out else "--out-dir" for t in targets],
    )
    cache = Path(args.cache_dir) if args.cache_dir else None
    if cache is not None or campaign.cache_dir is not None:
        check_folder(cache or campaign.cache_dir, "cache folder", may_create=True)  # type: ignore[arg-type]

    def progress(task: Any, record: dict[str, Any]) -> None:
        figs = "  ".join(f"{c} {v:.4f}" for c, v in record["figures"].items())
        say(f"ctc-campaign: {task.describe()}: {figs}  [{record['seconds']:.2f} s]")

    result = run_ctc_campaign(campaign, cache_dir=cache, progress=progress, tasks=tasks)
    if result is None:  # a torchrun rank other than 0: rank 0 reports
        return 0
    from torchmeshmetric._atomic import atomic_write
    from torchmeshmetric._format import json_safe
    from torchmeshmetric._version import __version__
    from torchmeshmetric.mpeg.ctc.campaign import frame_rows_csv
    from torchmeshmetric.mpeg.ctc.sheet import ctc_summary, format_test_model_csv, summary_csv, summary_markdown

    summary = ctc_summary(
        result.sequences, result.conditions, result.points["anchor"], result.points["test"], names=result.names
    )
    settings = {
        "manifest": str(campaign.path),
        "grid_size": campaign.grid_size,
        "ibsm": None
        if campaign.ibsm_resolution is None
        else {"resolution": campaign.ibsm_resolution, "cameras": campaign.ibsm_cameras},
    }
    plots = (
        []
        if args.no_plots
        else [
            (cond, seq, _plot_name(cond["id"], seq["name"]))
            for cond in summary["conditions"]
            if not cond["lossless"]
            for seq in cond["sequences"]
            if len(seq["rates"]) > 1
        ]
    )
    report = {
        "tool": "torchmeshmetric",
        "version": __version__,
        "settings": settings,
        "plots": [name for *_, name in plots],
        **summary,
    }
    # an --overwrite rerun: the plots the earlier run wrote (its summary.json lists them) that this run does not draw
    # would sit beside the new summary with the earlier BD figures in their titles
    inputs = {Path(p).resolve() for _, p in campaign.input_files() if p is not None}
    earlier = _earlier_plots(out) if args.overwrite else []
    stale = [out / n for n in earlier if n not in report["plots"] and (out / n).resolve() not in inputs]
    if not args.overwrite:  # they were absent when the campaign started: another run wrote them meanwhile
        appeared = [n for n in [*_TABLES, *report["plots"]] if (out / n).exists() or (out / n).is_symlink()]
        if appeared:
            kept = "the frames are in the cache folder: " if cache is not None or campaign.cache_dir else ""
            raise CLIError(
                f"--out-dir {str(out)!r}: {appeared[0]} was written while this campaign ran (another run of the "
                f"campaign into the same folder?); {kept}rerun with --overwrite to replace that run's files, or "
                "give another --out-dir; none of this run's files was written"
            )
    with output_set("the campaign's reports") as files:
        if not out.is_dir():
            make_folder(out, "--out-dir", files)
        for codec in ("anchor", "test"):
            rows = [result.points[codec][k] for k in sorted(result.points[codec])]
            atomic_write(out / f"{codec}.csv", format_test_model_csv(rows), overwrite=args.overwrite)
        atomic_write(out / "frames.csv", frame_rows_csv(result.frames), overwrite=args.overwrite)
        atomic_write(out / "summary.csv", summary_csv(summary), overwrite=args.overwrite)
        atomic_write(out / "summary.md", summary_markdown(summary), overwrite=args.overwrite)
        atomic_write(out / "summary.json", json.dumps(json_safe(report), indent=1) + "\n", overwrite=args.overwrite)
        if plots:
            from torchmeshmetric.viz.rd_curves import plot_rd_curves

            for cond, seq, name in plots:
                plot_rd_curves(
                    seq,
                    out / name,
                    names=result.names,
                    title=f"{seq['name']} - {cond['name']}",
                    overwrite=args.overwrite,
                )
    for path in stale:
        if path.is_file() and not path.is_symlink():
            path.unlink()
            say(
                f"ctc-campaign: removed {path.name}, an RD plot of the earlier run in {out}/ that this run does "
                "not draw"
            )
    print(summary_markdown(summary))
    wall = time.perf_counter() - start
    chains = result.chain_seconds
    same = len(result.frames) - result.computed - result.from_cache  # counted "from the cache" (review R #11)
    line = (
        f"ctc-campaign: {len(result.frames)} frames, {result.computed} computed ({chains:.2f} s of chains), "
        f"{result.from_cache} from the cache"
        + (f", {same} the same as another frame of the campaign" if same else "")
        + f"; {wall:.2f} s in all"
    )
    if chains > 0:
        line += f" (campaign overhead {100 * (wall - chains) / chains:+.1f} % of the chains)"
    say(line + f"; wrote {out}/")
    return 0


def add_ctc_campaign_command(sub: Any) -> None:
    """Add the ``ctc-campaign`` subcommand to the CLI's subparsers."""
    p = add_command(sub, "ctc-campaign", run)
    p.add_argument(
        "manifest", type=path_argument, metavar="MANIFEST", help="the campaign manifest (TOML); paths relative to it"
    )
    p.add_argument(
        "--out-dir",
        type=path_argument,
        required=True,
        metavar="DIR",
        help="write the CSVs, the summary and the RD plots there (created; its parent must exist)",
    )
    p.add_argument(
        "--cache-dir",
        type=cache_folder,
        default=None,
        metavar="DIR",
        help="per-frame cache folder (overrides the manifest's cache_dir, default ctc-cache beside the manifest); a "
        "rerun resumes from it",
    )
    p.add_argument("--no-plots", action="store_true", help="write no RD-curve PNGs")
    p.add_argument("--overwrite", action="store_true", help="replace existing files in --out-dir")
