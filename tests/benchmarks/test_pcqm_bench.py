"""PCQM (ours) vs ``mm compare --mode pcqm`` on a demo frame pair of ~50k sampled points each.

Run: ``python -m pytest tests/benchmarks/test_pcqm_bench.py --benchmark-only -s``. Both sides do the same work: read
the two OBJ files (per-vertex colours), sample them as mm compare does, compute PCQM with the default parameters.
"""

from __future__ import annotations

import subprocess
from pathlib import Path

import numpy as np
import pytest

from tests.mpeg.conftest import MM
from torchmeshmetric.data import demo_sequence
from torchmeshmetric.mpeg import load_model_cloud, mpeg_pcqm


def _coloured_obj(mesh: object, path: Path) -> Path:
    v = mesh.verts.numpy().astype(np.float64)  # type: ignore[attr-defined]
    t = (v - v.min(0)) / (v.max(0) - v.min(0))
    c = np.stack([t[:, 0], 0.5 + 0.5 * np.sin(7 * t[:, 1]), t[:, 2] ** 2], axis=1)
    rows = [f"v {x:.9g} {y:.9g} {z:.9g} {r:.6f} {g:.6f} {b:.6f}" for (x, y, z), (r, g, b) in zip(v, c, strict=True)]
    rows += [f"f {i + 1} {j + 1} {k + 1}" for i, j, k in mesh.faces.numpy()]  # type: ignore[attr-defined]
    path.write_text("\n".join(rows) + "\n")
    return path


@pytest.fixture(scope="module")
def pair(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    seq = demo_sequence(2, resolution=104)  # ~8.4k vertices per frame: ~50k points as mm compare samples them
    d = tmp_path_factory.mktemp("pcqm")
    return _coloured_obj(seq.frames[0], d / "f0.obj"), _coloured_obj(seq.frames[1], d / "f1.obj")


def _ours(ref: Path, dis: Path) -> float:
    return mpeg_pcqm(load_model_cloud(ref), load_model_cloud(dis)).pcqm


def _mm(ref: Path, dis: Path) -> None:
    args = [str(MM), "compare", "--mode", "pcqm", "--inputModelA", str(ref), "--inputModelB", str(dis)]
    subprocess.run(args, check=True, capture_output=True, cwd=ref.parent)  # PCQM writes a CSV into its cwd


@pytest.mark.parametrize("contender", ["ours", "mmetric"])
def test_pcqm_pair(benchmark, record, pair, contender: str) -> None:  # type: ignore[no-untyped-def]
    ref, dis = pair
    benchmark.group = "pcqm-50k-points"
    if contender == "mmetric":
        if not MM.is_file():
            pytest.skip("mmetric's mm binary absent")
        benchmark.pedantic(_mm, args=(ref, dis), rounds=3, iterations=1)
        record(benchmark.group, "mmetric (compare --mode pcqm)", min(benchmark.stats.stats.data))
        return
    score = benchmark.pedantic(_ours, args=(ref, dis), rounds=3, iterations=1)
    record(benchmark.group, "ours", min(benchmark.stats.stats.data))
    assert 0.0 < score < 1.0
