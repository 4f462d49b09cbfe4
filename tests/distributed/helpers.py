"""Shared helpers of the distributed tests: the test registration, torchrun command lines, report comparison.

The registration lives here, not in known_cli.py, so that its cache key (its module and name) is the same in a
test process and in a ``python -m tests.distributed.known_cli`` process.
"""

import json
import os
import signal
import socket
import subprocess
import sys
import time
import uuid
from pathlib import Path

import torch

from tests.cli.cli_helpers import STEP
from torchmeshmetric.registration import CachedRegistration

ROOT = Path(__file__).resolve().parents[2]


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def torchrun(module: str, *argv: str, nproc: int = 2, env=None, **kwargs) -> subprocess.Popen:
    """Start ``torchrun --standalone --nproc-per-node N -m MODULE ARGV`` from the repository root."""
    full = {**os.environ, "PYTHONPATH": str(ROOT), **(env or {})}
    cmd = [sys.executable, "-m", "torch.distributed.run", "--standalone", f"--nproc-per-node={nproc}"]
    return subprocess.Popen(
        [*cmd, "-m", module, *argv],
        cwd=ROOT,
        env=full,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        **kwargs,
    )


def finish(proc: subprocess.Popen, timeout: float = 300) -> tuple[int, str, str]:
    out, err = proc.communicate(timeout=timeout)
    return proc.returncode, out, err


def without_timings(value):
    """A report without the wall-clock ``timings`` (they differ between any two runs)."""
    if isinstance(value, dict):
        return {k: without_timings(v) for k, v in value.items() if k != "timings"}
    if isinstance(value, list):
        return [without_timings(v) for v in value]
    return value


def same_report_set(a: Path, b: Path) -> None:
    """JSON equal but for timings (exact floats, not approximately), CSV and Markdown byte-identical."""
    assert without_timings(json.loads(a.read_text())) == without_timings(json.loads(b.read_text()))
    for ext in (".csv", ".md"):
        assert a.with_suffix(ext).read_bytes() == b.with_suffix(ext).read_bytes(), ext


def _frame_of_target(source) -> int:
    """Frame k of the pair: the test frames are icospheres translated by STEP * k along x."""
    return round(float(source.verts[:, 0].mean()) / STEP) + 1


def register(source, target, *, device=None, **options):
    k = _frame_of_target(source)
    fault = os.environ.get("TMM_TEST_FAULT", "")
    if fault == f"kill@{k}":
        os.kill(os.getpid(), signal.SIGKILL)
    if fault == f"raise@{k}":
        raise ValueError(f"registration diverged (injected at frame {k})")
    time.sleep(float(os.environ.get("TMM_TEST_SLOW", "0")))
    calls = os.environ.get("TMM_TEST_CALLS")
    if calls:
        open(os.path.join(calls, f"{k}-{uuid.uuid4().hex}"), "w").close()
    verts = source.verts + torch.tensor([STEP, 0, 0], dtype=source.verts.dtype)
    return CachedRegistration(verts, torch.zeros(source.num_verts, dtype=verts.dtype), True, 0.0)
