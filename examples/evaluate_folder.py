"""Evaluate a folder of simplified frames against a folder of original frames, without the CLI.

    PYTHONPATH=. python examples/evaluate_folder.py ORIGINAL_DIR SIMPLIFIED_DIR [--out report.json [--overwrite]]

Frames are matched in natural order of their file names (the ``evaluate`` command also pairs them by frame
number). Registrations of the original frames are cached in
ORIGINAL_DIR/../.registrations so evaluating another method on the same originals does not repeat them.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from torchmeshmetric.evaluation import evaluate_sequence, paper_tables, report_dict, write_json
from torchmeshmetric.evaluation.reports import statistic_cell


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("original")
    parser.add_argument("simplified")
    parser.add_argument("--out", default=None, help="write the JSON report there")
    parser.add_argument("--overwrite", action="store_true", help="replace an existing --out")
    args = parser.parse_args()
    if args.out and Path(args.out).exists() and not args.overwrite:  # checked now, not after the whole evaluation
        parser.error(f"--out {args.out!r} already exists (pass --overwrite to replace it)")
    from torchmeshmetric.data import load_sequence  # frames in natural file-name order

    original = load_sequence(args.original)
    simplified = load_sequence(args.simplified)
    cache_dir = Path(args.original).resolve().parent / ".registrations"
    result = evaluate_sequence(
        original,
        simplified,
        registration_cache_dir=str(cache_dir),
        progress=lambda k, n: print(f"pair {k}/{n}", file=sys.stderr),
    )
    name = Path(args.simplified).name
    kept_by = Path(args.out).name if args.out else "the JSON report (--out)"  # the note names what keeps every digit
    print(paper_tables({name: result}, json_file=kept_by))
    for pair in result.pairs:  # per-frame temporal consistency and the registration's own quality
        # The tables' digits (statistic_cell: those the input determines, the same in every row).
        k_minus_1 = statistic_cell(float(pair.statistics["surface_k_minus_1"].rmse), "rmse")
        residual = statistic_cell(float(pair.registration_statistics.rmse), "rmse")
        print(f"frame {pair.frame}: surface_k_minus_1 rmse {k_minus_1}, registration residual rmse {residual}")
    if args.out:
        write_json(args.out, report_dict({name: result}), overwrite=args.overwrite)
    return 0


if __name__ == "__main__":
    sys.exit(main())
