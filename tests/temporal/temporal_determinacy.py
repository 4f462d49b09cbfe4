"""How many digits of KG, KSO, STED_s, STED_t and STED the input determines: the measurement behind their digits.

The companion of tests/evaluation/report_determinacy.py for the temporal section of the reports and the
``temporal`` command. The built-in sequence in float64 is the original; each distortion gives a distorted sequence;
both are then rounded to float32 (how frames are stored) and to 6 decimals (an OBJ file's usual precision), and
the figures are computed again. Printed: per distortion and rounding, each figure and its relative change against
the float64 run, and the digits that change leaves (``-log10`` of it). The exact forms are continuous functions of
the vertices; the registered forms go through the original's registrations and the tracking, whose discrete
choices can amplify the rounding (as the paper's statistics do). Run::

    python -m tests.temporal.temporal_determinacy [RESOLUTION] [FRAMES]

(default 160 and 4: the paper's size, three pairs; a few minutes on 2 cores).
"""

from __future__ import annotations

import math
import sys
import time
from collections.abc import Callable

import torch

from torchmeshmetric.data import demo_sequence
from torchmeshmetric.simplification import simplify_qem
from torchmeshmetric.structures import Mesh
from torchmeshmetric.temporal.figures import FIGURE_NAMES, temporal_figures

ROUNDINGS: dict[str, Callable[[torch.Tensor], torch.Tensor]] = {
    "float32": lambda v: v.to(torch.float32).to(torch.float64),
    "6 decimals": lambda v: torch.round(v, decimals=6),
}


def _quantised(bits: int) -> Callable[[list[Mesh]], list[Mesh]]:
    def distort(frames: list[Mesh]) -> list[Mesh]:
        out = []
        for m in frames:
            lo, hi = m.verts.amin(0), m.verts.amax(0)
            step = (hi - lo).max() / (2**bits - 1)
            out.append(Mesh(torch.round((m.verts - lo) / step) * step + lo, m.faces))
        return out

    return distort


def _normal_noise(size: float) -> Callable[[list[Mesh]], list[Mesh]]:
    def distort(frames: list[Mesh]) -> list[Mesh]:
        gen = torch.Generator().manual_seed(0)
        out = []
        for m in frames:
            diag = float((m.verts.amax(0) - m.verts.amin(0)).norm())
            amount = torch.randn(m.num_verts, 1, generator=gen, dtype=torch.float64) * size * diag
            out.append(Mesh(m.verts + amount * m.vertex_normals(), m.faces))
        return out

    return distort


def _simplified(keep: float) -> Callable[[list[Mesh]], list[Mesh]]:
    return lambda frames: [simplify_qem(m, keep) for m in frames]


#: name -> (original: "fixed" connectivity or the demo's "own" per frame, distortion, registered forms?)
DISTORTIONS: dict[str, tuple[str, Callable[[list[Mesh]], list[Mesh]], bool]] = {
    "fixed connectivity, quantised 10 bits (exact)": ("fixed", _quantised(10), False),
    "fixed connectivity, normal noise 1e-3 (exact)": ("fixed", _normal_noise(1e-3), False),
    "fixed connectivity, normal noise 1e-3 (registered)": ("fixed", _normal_noise(1e-3), True),
    "own connectivity, quantised 10 bits (registered)": ("own", _quantised(10), True),
    "own connectivity, QEM 50 % (registered)": ("own", _simplified(0.5), True),
}


def _figures(original: list[Mesh], distorted: list[Mesh], registered: bool) -> dict[str, float]:
    f = temporal_figures(original, distorted, registered=registered).as_dict()
    return {name: float(f[name]) for name in FIGURE_NAMES}


def main() -> None:
    """Print the measurement (``python -m tests.temporal.temporal_determinacy [RESOLUTION] [FRAMES]``)."""
    resolution = int(sys.argv[1]) if len(sys.argv) > 1 else 160
    num_frames = int(sys.argv[2]) if len(sys.argv) > 2 else 4
    demo = demo_sequence(num_frames, resolution=resolution, dtype=torch.float64)
    first = demo.frames[0]
    originals = {
        "own": list(demo.frames),
        # Frame 0 carried by the demo's own motion: one connectivity, so the exact forms apply.
        "fixed": [Mesh(demo.transfer(first.verts, 0, k), first.faces) for k in range(num_frames)],
    }
    print(f"demo, resolution {resolution}, {num_frames} frames, {first.num_verts} vertices in frame 0")
    for name, (which, distort, registered) in DISTORTIONS.items():
        original = originals[which]
        distorted = distort(original)
        t0 = time.perf_counter()
        base = _figures(original, distorted, registered)
        print(f"\n{name} ({time.perf_counter() - t0:.1f} s): " + ", ".join(f"{k} {v:.9g}" for k, v in base.items()))
        for label, rounding in ROUNDINGS.items():
            rounded = [[Mesh(rounding(m.verts), m.faces) for m in seq] for seq in (original, distorted)]
            got = _figures(rounded[0], rounded[1], registered)
            cells = []
            for k in FIGURE_NAMES:
                a, b = base[k], got[k]
                change = 0.0 if a == b else abs(a - b) / max(abs(a), abs(b))
                digits = "all" if change == 0 else f"{-math.log10(change):.1f}"
                cells.append(f"{k} {change:.1e} ({digits})")
            print(f"  rounded to {label:10s}: " + ", ".join(cells))


if __name__ == "__main__":
    main()
