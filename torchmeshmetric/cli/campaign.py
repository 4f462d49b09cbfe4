"""The ``campaign`` command: several sequences, each with several methods, listed in a TOML manifest."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from torchmeshmetric._console import say
from torchmeshmetric.cli.options import (
    add_cache_dir,
    add_command,
    add_determinacy,
    add_html,
    add_temporal,
    common_options,
    path_argument,
)

__all__ = ["add_campaign_command", "run"]


def run(args: argparse.Namespace) -> int:
    """Evaluate a test campaign: several sequences, each with several methods (TOML manifest).

    Evaluate every method of every sequence listed in a TOML manifest (see examples/campaign.toml and
    docs/scaling.md); registrations of each sequence's original pairs are computed once and shared by its methods.
    Prints the combined tables (per sequence and overall: mean over sequences); with --out-dir writes
    campaign.json/.md/.csv and one report per sequence (<sequence>.json/.md/.csv). Under torchrun the work is shared
    by all processes. With --determinacy, every sequence is evaluated again on nudged frames, and every table (the
    combined ones and each sequence's) prints only the digits both runs share.
    """
    from torchmeshmetric.cli._outputs import (
        CLIError,
        check_folder,
        check_writable,
        folder_inputs,
        make_folder,
        output_set,
    )
    from torchmeshmetric.cli._shared import (
        NudgedRun,
        device_of,
        dtype_of,
        evaluate_across_ranks,
        fast_registration_options,
        load_frames,
        nudged_cache,
        nudged_run,
        report_paths,
        temporal_methods,
        write_reports,
    )
    from torchmeshmetric.evaluation.campaign import (
        COMBINED,
        campaign_report_dict,
        campaign_tables,
        load_campaign,
        measure_campaign_determinacy,
        report_name,
        write_campaign_csv,
        write_campaign_markdown,
    )
    from torchmeshmetric.evaluation.comparison import compare_methods, with_nudged_verdicts
    from torchmeshmetric.evaluation.determinacy import measure_determinacy
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
        check_folder(out, "--out-dir", may_create=True)  # a file there is refused now, not after the campaign ran
        check_writable(targets if out.is_dir() else [out], args.overwrite, inputs=inputs, what="--out-dir")
    sequences = []
    for seq in campaign.sequences:
        original = load_frames(str(seq.original), f"sequence {seq.name!r}: original", dtype_of(args))
        methods = {
            m: load_frames(
                str(d),
                f"sequence {seq.name!r}: method {m!r}",
                dtype_of(args),
                (str(seq.original), f"sequence {seq.name!r}: original"),
            )
            for m, d in seq.methods.items()
        }
        check_methods(original, methods, sequence=seq.name)
        sequences.append((seq.name, original, methods))
    cache = RegistrationCache(args.cache_dir or campaign.cache_dir)
    # --determinacy's own, made now: a file in the way of its folder is refused before the first run, not after
    second = None if args.determinacy is None else nudged_cache(args.cache_dir or campaign.cache_dir)
    options = fast_registration_options() if campaign.registration == "fast" else None

    def evaluate(each: list[tuple[str, list[Any], dict[str, list[Any]]]], registrations: RegistrationCache) -> Any:
        return evaluate_across_ranks(
            each,
            registrations,
            two_sided=campaign.two_sided,
            device=device,
            backend=args.backend,
            registration_options=options,
        )

    evaluated = evaluate(sequences, cache)
    nudged: list[NudgedRun] = []
    if second is not None:  # --determinacy, every rank: the second run is sharded like the first
        say(f"--determinacy {args.determinacy}: evaluating again on nudged frames")
        nudged = [nudged_run(original, methods, args.determinacy, second) for _, original, methods in sequences]
        work = [(name, run.original, run.methods) for (name, _, _), run in zip(sequences, nudged, strict=True)]
        again = evaluate(work, second)
        nudged = [n._replace(results=r) for n, r in zip(nudged, again, strict=True)]
    if evaluated[0] is None:  # a torchrun rank other than 0: rank 0 reports
        return 0
    results = {seq.name: methods for seq, methods in zip(campaign.sequences, evaluated, strict=True)}
    nudged_runs = dict(zip(results, nudged, strict=True)) if nudged else {}
    # rank 0 (the others returned above) holds every sequence's second run, as it holds the first
    again_results: dict[str, Any] = {name: run.results for name, run in nudged_runs.items()}
    determinacy = None  # of the combined tables; each sequence's own below
    determinacies: dict[str, Any] = dict.fromkeys(results)
    if again_results:
        determinacy = measure_campaign_determinacy(results, again_results, args.determinacy)
        for name in results:
            determinacies[name] = measure_determinacy(results[name], again_results[name], args.determinacy)
    kept = f"{COMBINED}.json" + ("" if out is not None else " (--out-dir)")
    print(campaign_tables(results, determinacy=determinacy, json_file=kept))
    temporal = {}  # --temporal: KG, KSO, STED per sequence and method, on the campaign's registrations (its cache)
    for name, original, methods in sequences:
        temporal[name], determinacies[name] = temporal_methods(
            original,
            methods,
            args,
            device,
            cache=cache,
            registration_options=options,
            determinacy=determinacies[name],
            nudged=nudged_runs.get(name),
            sequence=name,
        )
    if out is None:
        return 0  # (--html without --out-dir was refused before any work)
    settings: dict[str, Any] = {
        "campaign": str(campaign.path),
        "two_sided": campaign.two_sided,
        "registration": campaign.registration,
        "dtype": args.dtype,
        "determinacy": args.determinacy,
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
            if comparisons is not None and seq.name in again_results:  # --determinacy: is each verdict the input's?
                comparisons = with_nudged_verdicts(comparisons, compare_methods(again_results[seq.name]))
            write_reports(
                paths,
                results[seq.name],
                sequence_settings,
                args.overwrite,
                comparisons=comparisons,
                temporal=temporal[seq.name],
                determinacy=determinacies[seq.name],
                say_written=False,  # not yet: the campaign's set is written as a whole, or not at all
            )
        combined = campaign_report_dict(results, settings=settings, determinacy=determinacy)
        write_json(out / f"{COMBINED}.json", combined, overwrite=args.overwrite)
        write_campaign_markdown(out / f"{COMBINED}.md", results, overwrite=args.overwrite, determinacy=determinacy)
        write_campaign_csv(out / f"{COMBINED}.csv", results, overwrite=args.overwrite)
        if args.html:
            from torchmeshmetric.evaluation.campaign import campaign_markdown
            from torchmeshmetric.viz.html_report import report_page, write_html

            title = f"torchmeshmetric campaign: {campaign.path.name}"
            page = report_page(combined, campaign_markdown(results, determinacy=determinacy), title=title)
            write_html(out / f"{COMBINED}.html", page, overwrite=args.overwrite)
    say(f"wrote {out / COMBINED}.json/.md/.csv and one report per sequence")
    return 0


def add_campaign_command(sub: Any) -> None:
    """Add the ``campaign`` subcommand to the CLI's subparsers."""
    p = add_command(sub, "campaign", run, [common_options()])
    p.add_argument(
        "manifest", type=path_argument, metavar="MANIFEST", help="the campaign manifest (TOML); folders relative to it"
    )
    p.add_argument(
        "--out-dir",
        type=path_argument,
        default=None,
        metavar="DIR",
        help="write the combined report and the per-sequence reports there (created; its parent must exist)",
    )
    add_cache_dir(p, "registration cache folder (overrides the manifest's cache_dir); a rerun resumes from it")
    add_temporal(p)
    add_determinacy(p, "evaluate every sequence again", "docs/statistics.md")
    p.add_argument("--overwrite", action="store_true", help="replace existing reports in --out-dir")
    add_html(p, "also write every report as one offline page (.html): tables, curves (per sequence)")
