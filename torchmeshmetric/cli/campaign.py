"""The ``campaign`` command: several sequences, each with several methods, listed in a TOML manifest."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from torchmeshmetric._console import say
from torchmeshmetric.cli.options import add_cache_dir, add_command, add_html, add_temporal, common_options

__all__ = ["add_campaign_command", "run"]


def run(args: argparse.Namespace) -> int:
    """Evaluate a test campaign: several sequences, each with several methods (TOML manifest).

    Evaluate every method of every sequence listed in a TOML manifest (see examples/campaign.toml and
    docs/scaling.md); registrations of each sequence's original pairs are computed once and shared by its methods.
    Prints the combined tables (per sequence and overall: mean over sequences); with --out-dir writes
    campaign.json/.md/.csv and one report per sequence (<sequence>.json/.md/.csv). Under torchrun the work is shared
    by all processes.
    """
    from torchmeshmetric.cli._outputs import CLIError, check_writable, folder_inputs, make_folder, output_set
    from torchmeshmetric.cli._shared import (
        device_of,
        dtype_of,
        evaluate_across_ranks,
        fast_registration_options,
        load_frames,
        report_paths,
        temporal_methods,
        write_reports,
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
    from torchmeshmetric.evaluation.comparison import compare_methods
    from torchmeshmetric.evaluation.pipeline import check_methods
    from torchmeshmetric.evaluation.reports import write_json
    from torchmeshmetric.registration.cache import RegistrationCache

    if args.html and args.out_dir is None:
        raise CLIError("--html: the pages are written beside the reports, so it needs --out-dir")
    device = device_of(args)
    campaign = load_campaign(args.manifest)
    out = None if args.out_dir is None else Path(args.out_dir)
    stems = [COMBINED] + [report_name(s.name) for s in campaign.sequences]
    if out is not None:
        exts = ("json", "md", "csv", "html") if args.html else ("json", "md", "csv")
        targets = [out / f"{stem}.{ext}" for stem in stems for ext in exts]
        inputs: list[tuple[str, Any]] = [("MANIFEST", args.manifest)]
        for seq in campaign.sequences:
            inputs += folder_inputs(f"sequence {seq.name!r}: original", seq.original)
            for m, d in seq.methods.items():
                inputs += folder_inputs(f"sequence {seq.name!r}: method {m!r}", d)
        check_writable(targets if out.is_dir() else [out], args.overwrite, inputs=inputs, what="--out-dir")
    sequences = []
    for seq in campaign.sequences:
        original = load_frames(str(seq.original), f"sequence {seq.name!r}: original", dtype_of(args))
        methods = {
            m: load_frames(str(d), f"sequence {seq.name!r}: method {m!r}", dtype_of(args))
            for m, d in seq.methods.items()
        }
        check_methods(original, methods, sequence=seq.name)
        sequences.append((seq.name, original, methods))
    cache = RegistrationCache(args.cache_dir or campaign.cache_dir)
    evaluated = evaluate_across_ranks(
        sequences,
        cache,
        two_sided=campaign.two_sided,
        device=device,
        backend=args.backend,
        registration_options=fast_registration_options() if campaign.registration == "fast" else None,
    )
    if evaluated[0] is None:  # a torchrun rank other than 0: rank 0 reports
        return 0
    results = {seq.name: methods for seq, methods in zip(campaign.sequences, evaluated, strict=True)}
    print(campaign_tables(results))
    options = fast_registration_options() if campaign.registration == "fast" else None
    temporal = {  # --temporal: KG, KSO, STED per sequence and method, on the campaign's registrations (its cache)
        name: temporal_methods(original, methods, args, device, cache=cache, registration_options=options)[0]
        for name, original, methods in sequences
    }
    if out is None:
        return 0  # (--html without --out-dir was refused before any work)
    settings: dict[str, Any] = {
        "campaign": str(campaign.path),
        "two_sided": campaign.two_sided,
        "registration": campaign.registration,
        "dtype": args.dtype,
    }
    with output_set("the campaign's reports") as files:
        if not out.is_dir():
            make_folder(out, "--out-dir", files)
        for seq, stem in zip(campaign.sequences, stems[1:], strict=True):
            folders = {m: str(d) for m, d in seq.methods.items()}
            sequence_settings = {**settings, "sequence": seq.name, "original": str(seq.original), "methods": folders}
            paths = report_paths(str(out / f"{stem}.json"), html=args.html)
            # The same comparisons `compare` writes for these methods (default margin; none for a single method).
            comparisons = compare_methods(results[seq.name]) if len(results[seq.name]) >= 2 else None
            write_reports(
                paths,
                results[seq.name],
                sequence_settings,
                args.overwrite,
                comparisons=comparisons,
                temporal=temporal[seq.name],
            )
        combined = campaign_report_dict(results, settings=settings)
        write_json(out / f"{COMBINED}.json", combined, overwrite=args.overwrite)
        write_campaign_markdown(out / f"{COMBINED}.md", results, overwrite=args.overwrite)
        write_campaign_csv(out / f"{COMBINED}.csv", results, overwrite=args.overwrite)
        if args.html:
            from torchmeshmetric.evaluation.campaign import campaign_markdown
            from torchmeshmetric.viz.html_report import report_page, write_html

            page = report_page(
                combined, campaign_markdown(results), title=f"torchmeshmetric campaign: {campaign.path.name}"
            )
            write_html(out / f"{COMBINED}.html", page, overwrite=args.overwrite)
    say(f"wrote {out / COMBINED}.json/.md/.csv and one report per sequence")
    return 0


def add_campaign_command(sub: Any) -> None:
    """Add the ``campaign`` subcommand to the CLI's subparsers."""
    p = add_command(sub, "campaign", run, [common_options()])
    p.add_argument("manifest", metavar="MANIFEST", help="the campaign manifest (TOML); folders relative to it")
    p.add_argument(
        "--out-dir",
        default=None,
        metavar="DIR",
        help="write the combined report and the per-sequence reports there (created; its parent must exist)",
    )
    add_cache_dir(p, "registration cache folder (overrides the manifest's cache_dir); a rerun resumes from it")
    add_temporal(p)
    p.add_argument("--overwrite", action="store_true", help="replace existing reports in --out-dir")
    add_html(p, "also write every report as one offline page (.html): tables, curves (per sequence)")
