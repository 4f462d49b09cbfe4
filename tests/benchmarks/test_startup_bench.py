"""Start-up cost in fresh processes: ``import torch`` (the peer) vs ``import torchmeshmetric`` and ``--help``.

Run on a quiet machine: ``python -m pytest tests/benchmarks/test_startup_bench.py --benchmark-only -s``. Goals
(issue 22): ``import torchmeshmetric`` <= ``import torch`` + 0.35 s, ``torchmeshmetric --help`` and
``torchmeshmetric evaluate --help`` <= 0.5 s; min of ``TMM_BENCH_ROUNDS`` (default 5) fresh processes each, the
contenders interleaved round by round so that a busy machine slows them alike. Also timed: ``python -c pass`` (the
interpreter alone), the first use of a torch-based name and of a torchmetrics-based class, and what ``evaluate``
imports before it computes. The table printed gives each contender's best time, its difference to
``import torch`` and whether its goal is met.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
ROUNDS = int(os.environ.get("TMM_BENCH_ROUNDS", "5"))
SCRIPT = shutil.which("torchmeshmetric", path=str(Path(sys.executable).parent))
HELP = [SCRIPT] if SCRIPT else [sys.executable, "-m", "torchmeshmetric"]

PEER = "import torch"
#: What `torchmeshmetric evaluate ...` imports before it computes: its module, the run-time helpers, the launcher.
EVALUATE_IMPORTS = "import torchmeshmetric.cli.evaluate, torchmeshmetric.cli._shared, torchmeshmetric.launch"
#: contender -> (command, goal: the most seconds it may take, or None; relative to the peer when the flag is set)
CONTENDERS: dict[str, tuple[list[str], float | None, bool]] = {
    "python -c pass": ([sys.executable, "-c", "pass"], None, False),
    PEER: ([sys.executable, "-c", "import torch"], None, False),
    "import torchmeshmetric": ([sys.executable, "-c", "import torchmeshmetric"], 0.35, True),
    "torchmeshmetric --help": ([*HELP, "--help"], 0.5, False),
    "torchmeshmetric evaluate --help": ([*HELP, "evaluate", "--help"], 0.5, False),
    "torchmeshmetric.Mesh": ([sys.executable, "-c", "import torchmeshmetric; torchmeshmetric.Mesh"], 0.35, True),
    "evaluate's imports (before computing)": (
        [sys.executable, "-c", EVALUATE_IMPORTS],
        None,
        False,
    ),
    "torchmeshmetric.MeshSurfaceDistance": (
        [sys.executable, "-c", "import torchmeshmetric; torchmeshmetric.MeshSurfaceDistance"],
        None,
        False,
    ),
}

#: The ratio tables (tests/benchmarks/conftest.py): group -> our contender; PEERS: the peers timed beside it.
GROUPS = {
    "start-up: import": "import torchmeshmetric",
    "start-up: first name used": "torchmeshmetric.Mesh",
    "start-up: --help": "torchmeshmetric --help",
}
PEERS = {
    "start-up: import": ("python -c pass", PEER),
    "start-up: first name used": (PEER,),
    "start-up: --help": ("python -c pass", PEER),
}


def _seconds(command: list[str]) -> float:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [str(REPO), os.environ.get("PYTHONPATH")]))}
    t0 = time.perf_counter()
    subprocess.run(command, check=True, stdout=subprocess.DEVNULL, env=env, cwd=REPO)
    return time.perf_counter() - t0


def test_start_up(benchmark, record):
    best = dict.fromkeys(CONTENDERS, float("inf"))

    def rounds() -> None:
        for _ in range(ROUNDS):
            for name, (command, _, _) in CONTENDERS.items():
                best[name] = min(best[name], _seconds(command))

    benchmark.pedantic(rounds, rounds=1, iterations=1)
    benchmark.group = "start-up (fresh processes)"
    print(f"\nstart-up, best of {ROUNDS} fresh processes each (interleaved):")
    for name, seconds in best.items():
        _, goal, relative = CONTENDERS[name]
        limit = None if goal is None else goal + (best[PEER] if relative else 0.0)
        verdict = "" if limit is None else f"   goal <= {limit:.2f} s: {'met' if seconds <= limit else 'NOT met'}"
        print(f"  {name:<38s} {seconds:6.3f} s   {seconds - best[PEER]:+6.3f} s vs {PEER}{verdict}")
        for group, ours in GROUPS.items():
            if name == ours or name in PEERS[group]:
                record(group, "ours" if name == ours else name, seconds)
