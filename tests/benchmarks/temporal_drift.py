"""The tracking's share of the registered forms' gap: the same distorted frames measured with the true correspondence
(no drift) and with the library's registration, under the exact remesh of ``temporal_validation``.

Run (once; a few minutes): ``python -m tests.benchmarks.temporal_drift MODEL_DIR`` (a folder of OBJ frames with one
connectivity, e.g. ``models/horse-gallop`` of CraGL/Hyperspectral-Inverse-Skinning, never committed). Prints
registered / exact for STED_t, STED_s and KG per case and correspondence; docs/temporal.md holds the figures.
"""

from __future__ import annotations

import sys

import numpy as np
import torch

from tests.benchmarks.temporal_validation import distort, remesh_exact
from tests.temporal.test_exact_remesh import _true_registrations
from torchmeshmetric.data.sequence import load_sequence
from torchmeshmetric.evaluation.pipeline import register_pairs
from torchmeshmetric.temporal import kg_error, registered_pair, sted

CASES = [("bump", 0.004), ("bump", 0.016), ("flicker", 0.002), ("flicker", 0.008), ("noise", 0.002)]


def main() -> None:
    frames = load_sequence(sys.argv[1], dtype=torch.float64)[:8]
    faces = frames[0].faces
    a = torch.stack([m.verts for m in frames])
    diag = float(frames[0].bbox_diagonal())
    rng = np.random.default_rng(0)
    orig = [remesh_exact(v, faces, rng) for v in a]
    true = _true_registrations(a, faces, orig)
    real = register_pairs(orig)
    for i, (kind, level) in enumerate(CASES):
        b = distort(kind, level, a, faces, diag, 100 + i)
        dis = [remesh_exact(v, faces, rng) for v in b]
        exact = sted(a, b, faces)
        for name, regs in (("true", true), ("registered", real)):
            p = registered_pair(orig, dis, registrations=regs)
            r = sted(p.original, p.distorted, p.faces)
            t = r.temporal.item() / exact.temporal.item()
            s = r.spatial.item() / exact.spatial.item()
            kg = kg_error(p.original, p.distorted).item() / kg_error(a, b).item()
            print(f"{kind} {level} {name} t {t:.3f} s {s:.3f} kg {kg:.3f}", flush=True)


if __name__ == "__main__":
    main()
