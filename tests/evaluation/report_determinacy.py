"""How many digits of each printed statistic the input determines: the measurement behind the report's digits.

A frame stored in float32 (or in an OBJ file with 6 decimals) is its float64 self rounded by ~1e-7 of the
coordinates; the simplifiers' discrete choices (which edge collapses next) and the registration turn that into a
change of every figure computed from the frame. A digit that such a rounding moves is not determined by the input,
and a report must not print it (issue 38). This script runs the pinned demo (tests/evaluation/test_report_pinned.py's
arguments) on

* ``demo``: the built-in frames in float64 (:func:`~torchmeshmetric.data.demo_sequence` with ``dtype=torch.float64``);
* ``captured``: the same frames made captured-like (:func:`~torchmeshmetric.data.add_capture_defects`: normalised,
  duplicate vertices, zero-area faces, unreferenced points, shuffled);

each as it is, rounded to float32 and rounded to 6 decimals, and prints, per statistic and set, the largest
relative change against the float64 run over the pairs and aggregates of both methods, and the digits that change
leaves (``-log10`` of it). Run::

    python -m tests.evaluation.report_determinacy
"""

from __future__ import annotations

import contextlib
import io
import json
import math
import sys
import tempfile
from collections import defaultdict
from collections.abc import Callable
from pathlib import Path
from typing import Any
from unittest import mock

import numpy as np
import torch

from tests.evaluation import test_report_pinned
from torchmeshmetric import Mesh
from torchmeshmetric.data import add_capture_defects
from torchmeshmetric.data import demo as demo_module

STATISTICS = ("ave", "var", "std", "mse", "rmse", "max", "min", "median", "p95", "psnr")
ROUNDINGS: dict[str, Callable[[np.ndarray], np.ndarray]] = {
    "float32": lambda v: v.astype(np.float32).astype(np.float64),
    "6 decimals": lambda v: np.round(v, 6),
}


def _report(captured: bool, rounding: Callable[[np.ndarray], np.ndarray] | None) -> dict[str, Any]:
    original = demo_module.demo_sequence

    def frames_as(*args: Any, **kwargs: Any) -> Any:
        seq = original(*args, **{**kwargs, "dtype": torch.float64})
        for i, frame in enumerate(seq.frames):
            mesh = add_capture_defects(frame, seed=i, normalize=False) if captured else frame
            v = mesh.verts.numpy()
            seq.frames[i] = Mesh(torch.from_numpy(v if rounding is None else rounding(v)), mesh.faces)
        return seq

    with (
        tempfile.TemporaryDirectory() as tmp,
        mock.patch.object(demo_module, "demo_sequence", frames_as),
        contextlib.redirect_stdout(io.StringIO()),
    ):
        return json.loads(test_report_pinned.run_demo(Path(tmp) / "demo")["report.json"])


def _summaries(block: dict[str, Any], prefix: str = "") -> dict[str, dict[str, Any]]:
    """Every summary (a dict with ``ave``) under ``block``, by its path: ``surface_k``, ``reverse.flicker``…"""
    out: dict[str, dict[str, Any]] = {}
    for name, value in block.items():
        if isinstance(value, dict):
            out.update({prefix + name: value} if "ave" in value else _summaries(value, f"{prefix}{name}."))
    return out


def _statistics(report: dict[str, Any]) -> dict[tuple[str, str, str], float]:
    """``(method: set, statistic, where) -> value`` for every summary of every method (pairs and aggregate).

    The registration's sets are the same for every method: they are reported once, as ``registration``.
    """
    out: dict[tuple[str, str, str], float] = {}
    for method, result in report["methods"].items():
        blocks = [(f"pair {i}", p) for i, p in enumerate(result["pairs"])]
        for where, block in [*blocks, ("aggregate", result["aggregate"])]:
            for name, stats in _summaries(block).items():
                owner = "registration" if name.startswith("registration.") else method
                for stat in STATISTICS:
                    if isinstance(stats.get(stat), float):
                        out[(f"{owner}: {name}", stat, where)] = stats[stat]
    return out


def main() -> None:
    """Print the measurement (``python -m tests.evaluation.report_determinacy [RESOLUTION]``, default the pinned 24)."""
    if len(sys.argv) > 1:
        i = test_report_pinned.ARGS.index("--resolution")
        test_report_pinned.ARGS[i + 1] = sys.argv[1]
    for fixture in ("demo", "captured"):
        base = _statistics(_report(fixture == "captured", None))
        for label, rounding in ROUNDINGS.items():
            got = _statistics(_report(fixture == "captured", rounding))
            worst: dict[str, float] = defaultdict(float)
            worst_set: dict[tuple[str, str], float] = defaultdict(float)
            for key, b in base.items():
                if not (math.isfinite(b) and math.isfinite(got[key])) or b == got[key]:
                    continue
                change = abs(got[key] - b) / max(abs(b), abs(got[key]))
                worst[key[1]] = max(worst[key[1]], change)
                worst_set[(key[0], key[1])] = max(worst_set[(key[0], key[1])], change)
            print(f"\n{fixture}, frames rounded to {label}: largest relative change (determined digits)")
            for stat in STATISTICS:
                w = worst[stat]
                digits = "all" if w == 0 else f"{-math.log10(w):.1f}"
                print(f"  {stat:7s} {w:9.2e}  ({digits})")
            print(f"  {'':40s} " + " ".join(f"{s:>8s}" for s in STATISTICS))
            for name in sorted({n for n, _ in worst_set}):
                print(f"  {name:40s} " + " ".join(f"{worst_set[(name, s)]:8.1e}" for s in STATISTICS))


if __name__ == "__main__":
    main()
