"""``python -m tests.distributed.known_cli ARGS``: the CLI with the exact registration of the test sequences.

Run by torchrun in the distributed tests (a monkeypatch cannot reach other processes). Environment:

* ``TMM_TEST_CALLS``: a folder that receives one file per registration computed (counts work across processes);
* ``TMM_TEST_FAULT``: ``kill@K`` or ``raise@K``: the process registering frame pair ``K-1 -> K`` kills itself
  (SIGKILL, as the kernel's OOM killer would) or raises;
* ``TMM_TEST_SLOW``: seconds each registration takes (to make concurrent runs overlap);
* ``TMM_TEST_RANK_ERROR``: a rank number: that rank alone fails its argument checks (before any work).
"""

import os
import sys

import torchmeshmetric.cli
import torchmeshmetric.cli._shared
import torchmeshmetric.evaluation
import torchmeshmetric.evaluation.pipeline
from tests.distributed.helpers import register
from torchmeshmetric.cli import main

if __name__ == "__main__":  # only then: pytest imports this module too (doctests) and must not be patched
    torchmeshmetric.evaluation.pipeline.default_register = register
    torchmeshmetric.evaluation.default_register = register
    bad_rank = os.environ.get("TMM_TEST_RANK_ERROR")
    if bad_rank is not None and os.environ.get("RANK") == bad_rank:

        def refuse(*args: object, **kwargs: object) -> None:
            raise ValueError(f"injected on rank {bad_rank} only")

        torchmeshmetric.cli._shared.check_methods = refuse  # type: ignore[assignment]
    sys.exit(main(sys.argv[1:]))
