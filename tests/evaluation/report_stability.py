"""How far the pinned demo report's floats move when the demo's frames move by one ulp or 1e-9 (relative).

The measurement behind :data:`tests.evaluation.test_report_pinned.RTOL`: another machine computes the frames (torch's
vectorised ``sin``/``exp`` per instruction set), the simplifications and the registration with other last bits, so
the report may differ from the golden by what such perturbations of the input move it. Run::

    python -m tests.evaluation.report_stability
"""

from __future__ import annotations

import json
import math
import tempfile
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any
from unittest import mock

import numpy as np
import torch

from tests.evaluation.test_report_pinned import run_demo
from torchmeshmetric import Mesh
from torchmeshmetric.data import demo as demo_module


def _floats(data: Any, path: str = "") -> Iterator[tuple[str, float]]:
    if isinstance(data, dict):
        for k, v in data.items():
            yield from _floats(v, f"{path}.{k}")
    elif isinstance(data, list):
        for i, v in enumerate(data):
            yield from _floats(v, f"{path}[{i}]")
    elif isinstance(data, float):
        yield path, data


def _report(perturb: Callable[[np.ndarray], np.ndarray] | None) -> dict[str, float]:
    original = demo_module.demo_sequence

    def perturbed(*args: Any, **kwargs: Any) -> Any:
        seq = original(*args, **kwargs)
        # The demo's frames are float32 and the pinned run computes in float64: perturb their float64 values.
        for i, frame in enumerate(seq.frames):
            v = frame.verts.detach().double().numpy()
            seq.frames[i] = Mesh(torch.from_numpy(v if perturb is None else perturb(v)), frame.faces)
        return seq

    with tempfile.TemporaryDirectory() as tmp, mock.patch.object(demo_module, "demo_sequence", perturbed):
        texts = run_demo(Path(tmp) / "demo")
    return dict(_floats(json.loads(texts["report.json"])))


def main() -> None:
    base = _report(None)
    for name, fn in {
        "ulp+": lambda v: np.nextafter(v, np.inf),
        "ulp-": lambda v: np.nextafter(v, -np.inf),
        "rel1e-9": lambda v: v * (1 + 1e-9),
    }.items():
        got = _report(fn)
        worst = max(
            ((abs(got[k] - b) / abs(b) if b else abs(got[k]), k) for k, b in base.items() if math.isfinite(b)),
        )
        print(f"{name:8s} largest relative change {worst[0]:.1e} at {worst[1]}")


if __name__ == "__main__":
    main()
