"""Does ``--determinacy``'s nudge see what the storage rounding of the input does to an evaluation?

Frames whose unrounded positions are known (``demo_sequence`` in float64, optionally captured-like) are simplified
once (QEM, 50 %) and evaluated three times, in float64 arithmetic: as they are (A), rounded to the storage (B), and B
nudged by :func:`~torchmeshmetric.evaluation.determinacy.nudge_frames` (C). The change A -> B is what the storage
did; B -> C is what ``--determinacy`` measures on the stored frames. Prints the largest change per statistic of
both and how many table cells print the same digits (docs/statistics.md, "Per run: --determinacy")::

    python -m tests.evaluation.nudge_check [RESOLUTION] [FRAMES] [demo|captured] [float32|DECIMALS]
"""

from __future__ import annotations

import sys
import time

import torch

from torchmeshmetric import Mesh
from torchmeshmetric.cli._shared import simplify_frames
from torchmeshmetric.data import add_capture_defects
from torchmeshmetric.data.demo import demo_sequence
from torchmeshmetric.evaluation.determinacy import Determinacy, determined_digits, measure_determinacy, nudge_frames
from torchmeshmetric.evaluation.pipeline import evaluate_sequence
from torchmeshmetric.evaluation.reports import COLUMN_FORMATS


def _store(verts: torch.Tensor, rounding: str) -> torch.Tensor:
    """``verts`` as a float32 file or a file with ``rounding`` decimals holds them (back in float64)."""
    return verts.float().double() if rounding == "float32" else torch.round(verts, decimals=int(rounding))


def main(argv: list[str]) -> None:
    resolution = int(argv[0]) if argv else 160
    num_frames = int(argv[1]) if len(argv) > 1 else 3
    captured = len(argv) > 2 and argv[2] == "captured"
    rounding = argv[3] if len(argv) > 3 else "float32"
    seq = demo_sequence(num_frames, resolution=resolution, dtype=torch.float64)
    frames = [add_capture_defects(f, seed=i, normalize=False) if captured else f for i, f in enumerate(seq.frames)]
    frames = [Mesh(f.verts, f.faces, validate=False) for f in frames]
    simplified = [Mesh(m.verts.double(), m.faces, validate=False) for m in simplify_frames(frames, "qem", 0.5, None)]

    def stored(fr: list[Mesh]) -> list[Mesh]:
        return [Mesh(_store(f.verts, rounding), f.faces, validate=False) for f in fr]

    t0 = time.perf_counter()
    exact = {"qem": evaluate_sequence(frames, simplified)}
    kept = {"qem": evaluate_sequence(stored(frames), stored(simplified))}
    nudged_frames = nudge_frames(stored(frames), rounding), nudge_frames(stored(simplified), rounding)
    nudged = {"qem": evaluate_sequence(*nudged_frames)}
    print(f"3 evaluations in {time.perf_counter() - t0:.1f} s, {frames[0].num_verts} vertices", file=sys.stderr)
    truth: Determinacy = measure_determinacy(exact, kept, rounding)
    seen: Determinacy = measure_determinacy(kept, nudged, rounding)
    alike = total = too_many = 0
    largest: dict[str, list[float]] = {}
    for table, rows in truth.changes.items():
        for row_truth, row_seen in zip(rows, seen.changes[table], strict=True):
            for key, change in row_truth.items():
                want, got = (
                    determined_digits(change, COLUMN_FORMATS[key]),
                    determined_digits(row_seen[key], COLUMN_FORMATS[key]),
                )
                total, alike, too_many = total + 1, alike + (want == got), too_many + (got > want)
                pair = largest.setdefault(key, [0.0, 0.0])
                pair[0], pair[1] = max(pair[0], change), max(pair[1], row_seen[key])
    kind = "captured-like" if captured else "demo"
    print(f"{kind}, resolution {resolution}, {rounding}: cells printed alike {alike} of {total}, "
          f"with a digit too many {too_many}")  # fmt: skip
    for key, (t, s) in largest.items():
        print(f"  {key:5s} largest change: rounding {t:.2g}, nudge {s:.2g}")


if __name__ == "__main__":
    main(sys.argv[1:])
