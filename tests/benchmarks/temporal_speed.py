"""Speed of one registered STED against its registrations: a 20-frame, ~20k-vertex sequence (the demo performer).

Run once: ``python -m tests.benchmarks.temporal_speed [--frames 20] [--resolution 160]``. The original is
``demo_sequence`` (each frame meshed on its own); the distorted sequence is every frame simplified by QEM to half
its faces. Times, in the same process: the ``F - 1`` registrations (``register_pairs``), then the registered form
given them (tracking, carrying, KG/KSO/STED). Goal (issue 44): the whole registered STED (registrations included)
within 2x the registrations, i.e. the rest within 1x.
"""

from __future__ import annotations

import argparse
import time

import torch

from torchmeshmetric.data.demo import demo_sequence
from torchmeshmetric.evaluation.pipeline import register_pairs
from torchmeshmetric.simplification.qem import simplify_qem
from torchmeshmetric.temporal import kg_error, kso_error, registered_pair, sted


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=20)
    parser.add_argument("--resolution", type=int, default=160)
    args = parser.parse_args()
    seq = demo_sequence(args.frames, resolution=args.resolution)
    original = seq.frames
    distorted = [simplify_qem(m, 0.5) for m in original]
    verts = sum(m.num_verts for m in original) / len(original)
    threads = torch.get_num_threads()
    print(f"{len(original)} frames, {verts:.0f} vertices on average; torch threads {threads}", flush=True)
    t0 = time.perf_counter()
    registrations = register_pairs(original)
    t_reg = time.perf_counter() - t0
    print(f"registrations: {t_reg:.1f} s", flush=True)
    t0 = time.perf_counter()
    pair = registered_pair(original, distorted, registrations=registrations)
    t_pair = time.perf_counter() - t0
    t0 = time.perf_counter()
    s = sted(pair.original, pair.distorted, pair.faces)
    kg, kso = kg_error(pair.original, pair.distorted), kso_error(pair.original, pair.distorted)
    t_metrics = time.perf_counter() - t0
    rest = t_pair + t_metrics
    print(
        f"tracking + carrying {t_pair:.1f} s, metrics {t_metrics:.2f} s (KG {kg.item():.4g}, KSO {kso.item():.4g}, "
        f"STED_s {s.spatial.item():.4g}, STED_t {s.temporal.item():.4g}); registered STED / registrations = "
        f"{(t_reg + rest) / t_reg:.3f} (rest / registrations = {rest / t_reg:.3f})",
        flush=True,
    )


if __name__ == "__main__":
    main()
