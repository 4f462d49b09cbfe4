"""The command line under ``torchrun``: a process group from the environment, threads and a GPU per process.

``torchrun --nproc-per-node N -m torchmeshmetric evaluate|compare|campaign ...`` starts ``N`` processes with
``RANK``, ``WORLD_SIZE``, ``LOCAL_RANK``, ``LOCAL_WORLD_SIZE``, ``MASTER_ADDR`` and ``MASTER_PORT`` set; the command
then joins one ``gloo`` process group (only Python objects are exchanged, so ``gloo`` also serves GPU runs), shares
the work (:mod:`torchmeshmetric.evaluation.distributed`) and rank 0 prints the tables and writes the reports.

Threads: ``--threads N`` wins; otherwise a user's ``OMP_NUM_THREADS`` wins, except torchrun's own default of 1 (it
sets ``OMP_NUM_THREADS=1`` when unset), which is replaced by the usable cores divided by the processes on this machine
(pass ``--threads 1`` to force one thread). GPU: with ``--device cuda`` each process uses ``cuda:LOCAL_RANK``.
"""

from __future__ import annotations

import datetime
import os
import signal
import sys
from collections.abc import Callable, Mapping
from types import FrameType
from typing import Any, NamedTuple

import torch
import torch.distributed as dist

from torchmeshmetric.evaluation.distributed import RankFailedError, in_flight

__all__ = ["COLLECTIVE_TIMEOUT", "SHARDED_COMMANDS", "Launch", "launch_from_environment", "run_command", "thread_count"]

#: The commands that share their work across the processes of a torchrun job.
SHARDED_COMMANDS = ("evaluate", "compare", "campaign", "ctc")

#: How long a rank waits in a collective for the others (their shares of the work may differ by hours).
COLLECTIVE_TIMEOUT = datetime.timedelta(days=1)


class Launch(NamedTuple):
    """Where this process sits in a ``torchrun`` job."""

    rank: int
    world_size: int
    local_rank: int
    local_world_size: int


def launch_from_environment(env: Mapping[str, str] | None = None) -> Launch | None:
    """The job described by torchrun's environment variables; ``None`` for a single process.

    Example:
        >>> launch_from_environment({"RANK": "1", "WORLD_SIZE": "2", "LOCAL_RANK": "1", "LOCAL_WORLD_SIZE": "2"})
        Launch(rank=1, world_size=2, local_rank=1, local_world_size=2)
        >>> launch_from_environment({}) is None
        True
    """
    env = os.environ if env is None else env
    world_size = int(env.get("WORLD_SIZE", "1"))
    if world_size <= 1:
        return None
    rank = int(env["RANK"])
    local_rank = int(env.get("LOCAL_RANK", rank))
    return Launch(rank, world_size, local_rank, int(env.get("LOCAL_WORLD_SIZE", world_size)))


def _usable_cores() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


def thread_count(
    explicit: int | None, launch: Launch | None, env: Mapping[str, str] | None = None, cores: int | None = None
) -> int | None:
    """The torch CPU threads for this process, or ``None`` to leave torch's own choice.

    Example:
        >>> job = Launch(0, 4, 0, 2)
        >>> thread_count(None, job, {"OMP_NUM_THREADS": "1"}, cores=16)  # torchrun's default: share the cores
        8
        >>> thread_count(None, job, {"OMP_NUM_THREADS": "3"}, cores=16), thread_count(2, job, {}, cores=16)
        (None, 2)
    """
    if explicit is not None:
        return explicit
    if launch is None:
        return None
    env = os.environ if env is None else env
    if env.get("OMP_NUM_THREADS", "1") != "1":
        return None
    return max(1, (_usable_cores() if cores is None else cores) // launch.local_world_size)


class Stopped(BaseException):
    """The launcher stopped this rank (SIGTERM: torchrun stops every rank when one of them fails)."""


def _stop(signum: int, frame: FrameType | None) -> None:
    raise Stopped


def _cuda_device(launch: Launch) -> str:
    if not torch.cuda.is_available():
        raise RuntimeError("--device cuda: no CUDA device is available (use --device cpu)")
    count = torch.cuda.device_count()
    if launch.local_rank >= count:
        raise RuntimeError(f"--device cuda: LOCAL_RANK {launch.local_rank} but only {count} CUDA devices here")
    torch.cuda.set_device(launch.local_rank)
    return f"cuda:{launch.local_rank}"


def _stopped_message(busy: list[tuple[int, str]]) -> str:
    """Why torchrun stopped this rank: another rank exited (died or failed outside the shared work)."""
    if len(busy) == 1:
        rank, task = busy[0]
        return f"rank {rank} failed on {task}: the process died (killed or crashed); torchrun stopped the others"
    if busy:
        names = "; ".join(f"rank {rank} on {task}" for rank, task in busy)
        return f"a rank died (killed or crashed); torchrun stopped the others; in flight: {names}"
    return "stopped by torchrun: another rank exited"


def run_command(command: Callable[[Any], int], args: Any) -> int:
    """Run a CLI command, inside a process group when torchrun started this process.

    Ranks other than 0 stay silent about failures of the shared work: rank 0 prints the one line that names the
    failing rank and frame pair, and every rank exits with code 1.
    """
    launch = launch_from_environment()
    threads = thread_count(getattr(args, "threads", None), launch)
    if threads is not None:
        torch.set_num_threads(threads)
    if launch is None:
        return command(args)
    if getattr(args, "command", None) not in SHARDED_COMMANDS:
        raise RuntimeError(
            f"{args.command} runs in one process; under torchrun use {', '.join(SHARDED_COMMANDS)} (WORLD_SIZE is "
            f"{launch.world_size})"
        )
    if getattr(args, "device", "cpu") == "cuda":
        args.device = _cuda_device(launch)
    previous = signal.signal(signal.SIGTERM, _stop)
    dist.init_process_group("gloo", timeout=COLLECTIVE_TIMEOUT)
    try:
        return command(args)
    except RankFailedError:
        if launch.rank != 0:
            return 1
        raise
    except Stopped:
        busy = in_flight()
        if launch.rank == min(set(range(launch.world_size)) - {r for r, _ in busy}):  # one line, from one survivor
            print(f"torchmeshmetric {args.command}: error: {_stopped_message(busy)}", file=sys.stderr)
        return 1
    finally:
        signal.signal(signal.SIGTERM, previous)
        dist.destroy_process_group()
