"""Scaling out: 2 processes x 1 thread (torchrun) vs 1 process x 2 threads, on the same work, in the same run.

Run: ``python -m pytest tests/benchmarks/test_distributed_bench.py --benchmark-only -s``.

The work: ``compare`` on a 6-frame built-in sequence at the paper's size (``resolution=160``: ~20k vertices / ~40k
faces per frame, 5 frame pairs) with 2 methods (QEM keeping 97 % and 50 % of the faces), the library's full
registration, a fresh registration cache each time. Both contenders are the command line started as a new process
(``python -m torchmeshmetric`` vs ``torchrun --nproc-per-node 2 -m torchmeshmetric``), so both pay process start-up;
the sequence and its simplifications are written once beforehand and not timed. ``TMM_BENCH_FRAMES`` and
``TMM_BENCH_RESOLUTION`` change the size. The terminal summary prints both wall times and their ratio; each case also
prints the CPU time of all its processes (a check on overheads that contention from other jobs does not inflate much).
"""

from __future__ import annotations

import os
import resource
import subprocess
import sys
import time
from pathlib import Path

import pytest

from torchmeshmetric.data import demo_sequence, save_mesh
from torchmeshmetric.simplification import simplify_qem

ROOT = Path(__file__).resolve().parents[2]
FRAMES = int(os.environ.get("TMM_BENCH_FRAMES", "6"))
RESOLUTION = int(os.environ.get("TMM_BENCH_RESOLUTION", "160"))
CPU_SECONDS: dict[str, float] = {}
GROUP = f"compare: {FRAMES} frames at resolution {RESOLUTION}, 2 methods, full registration"


@pytest.fixture(scope="module")
def sequence(tmp_path_factory):
    root = tmp_path_factory.mktemp("scaling")
    frames = demo_sequence(FRAMES, resolution=RESOLUTION).frames
    for name, target in (("original", None), ("qem97", 0.97), ("qem50", 0.5)):
        (root / name).mkdir()
        for k, frame in enumerate(frames):
            save_mesh(frame if target is None else simplify_qem(frame, target), root / name / f"frame_{k:03d}.ply")
    print(f"\n{GROUP}: {frames[0].num_verts} vertices / {frames[0].num_faces} faces in frame 0")
    return root


def _cpu() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def _run(command: list[str], out: Path) -> float:
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    env.pop("OMP_NUM_THREADS", None)
    start, cpu = time.perf_counter(), _cpu()
    subprocess.run(command, cwd=ROOT, env=env, check=True, capture_output=True)
    seconds = time.perf_counter() - start
    CPU_SECONDS[command[2]] = _cpu() - cpu  # "torchmeshmetric" or "torch.distributed.run"
    assert out.is_file()
    return seconds


@pytest.mark.parametrize("contender", ["1 process x 2 threads", "2 processes x 1 thread"])
def test_scaling_out_with_torchrun(benchmark, record, sequence, tmp_path, contender):
    out = tmp_path / "report.json"
    args = ["compare", "--original", str(sequence / "original"), "--method", f"QEM 97%={sequence / 'qem97'}"]
    args += ["--method", f"QEM 50%={sequence / 'qem50'}", "--out", str(out), "--overwrite"]
    args += ["--cache-dir", str(tmp_path / "cache")]  # fresh per round: every registration is computed
    if contender.startswith("1 process"):
        command = [sys.executable, "-m", "torchmeshmetric", *args, "--threads", "2"]
    else:
        launcher = [sys.executable, "-m", "torch.distributed.run", "--standalone", "--nproc-per-node", "2"]
        command = [*launcher, "-m", "torchmeshmetric", *args, "--threads", "1"]

    def once() -> float:
        for entry in (tmp_path / "cache").glob("*"):
            entry.unlink()
        return _run(command, out)

    seconds = benchmark.pedantic(once, rounds=1, iterations=1)
    record(GROUP, "ours" if contender.startswith("2 processes") else contender, seconds)
    cpu = CPU_SECONDS[command[2]]
    print(f"{contender}: {seconds:.1f} s wall, {cpu:.1f} s CPU (all its processes, user + system)")
