"""``python -m tests.distributed.known_cli ARGS``: the CLI with the exact registration of the test sequences.

Run by torchrun in the distributed tests (a monkeypatch cannot reach other processes). Environment:

* ``TMM_TEST_CALLS``: a folder that receives one file per registration computed (counts work across processes);
* ``TMM_TEST_FAULT``: ``kill@K`` or ``raise@K``: the process registering frame pair ``K-1 -> K`` kills itself
  (SIGKILL, as the kernel's OOM killer would) or raises.
"""

import os
import signal
import sys
import uuid

import torch

import torchmeshmetric.evaluation
import torchmeshmetric.evaluation.pipeline
from tests.cli.cli_helpers import STEP
from torchmeshmetric.cli import main
from torchmeshmetric.evaluation import CachedRegistration


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
    calls = os.environ.get("TMM_TEST_CALLS")
    if calls:
        open(os.path.join(calls, f"{k}-{uuid.uuid4().hex}"), "w").close()
    verts = source.verts + torch.tensor([STEP, 0, 0], dtype=source.verts.dtype)
    return CachedRegistration(verts, torch.zeros(source.num_verts, dtype=verts.dtype), True, 0.0)


torchmeshmetric.evaluation.pipeline.default_register = register
torchmeshmetric.evaluation.default_register = register

if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
