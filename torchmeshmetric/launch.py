"""The command line under ``torchrun``: a process group from the environment, threads and a GPU per process.

``torchrun --nproc-per-node N -m torchmeshmetric evaluate|compare|campaign ...`` starts ``N`` processes with
``RANK``, ``WORLD_SIZE``, ``LOCAL_RANK``, ``LOCAL_WORLD_SIZE``, ``MASTER_ADDR`` and ``MASTER_PORT`` set; the command
then joins one ``gloo`` process group (only Python objects are exchanged, so ``gloo`` also serves GPU runs), shares
the work (:mod:`torchmeshmetric.tasks`) and rank 0 prints the tables and writes the reports.

Threads: ``--threads N`` wins; otherwise a user's ``OMP_NUM_THREADS`` wins, except torchrun's own default of 1 (it
sets ``OMP_NUM_THREADS=1`` when unset), which is replaced by the usable cores divided by the processes on this machine
(pass ``--threads 1`` to force one thread). GPU: with ``--device cuda`` each process uses ``cuda:LOCAL_RANK``.
"""

from __future__ import annotations

import contextlib
import datetime
import os
import signal
import time
from collections.abc import Callable, Mapping
from types import FrameType
from typing import Any, NamedTuple

import torch
import torch.distributed as dist

from torchmeshmetric._console import error_message, say
from torchmeshmetric.tasks import RankFailedError, default_store, in_flight

__all__ = [
    "COLLECTIVE_TIMEOUT",
    "ERROR_WAIT",
    "SHARDED_COMMANDS",
    "Launch",
    "error_line",
    "launch_from_environment",
    "report_error",
    "run_command",
    "thread_count",
]

#: The commands that share their work across the processes of a torchrun job.
SHARDED_COMMANDS = ("evaluate", "compare", "campaign", "ctc", "ctc-campaign")

#: How long a rank waits in a collective for the others (their shares of the work may differ by hours).
COLLECTIVE_TIMEOUT = datetime.timedelta(days=1)


#: How long a rank other than 0 that failed waits for rank 0's error line (to stay silent when it is the same).
ERROR_WAIT = datetime.timedelta(seconds=5)

_ERROR_KEY = "torchmeshmetric/error/0"  # rank 0's error line, in the process group's key-value store
_SAID_KEY = "torchmeshmetric/error/said"  # set once some rank printed an error line for the job


def error_line(command: str, exc: BaseException, rank: int | None = None) -> str:
    """The one line the command line prints for an error: ``torchmeshmetric <command>: error: <first line>``.

    ``rank``: the torchrun rank that alone saw it (its number then prefixes the message).

    Example:
        >>> error_line("compare", ValueError("method 'b': 2 simplified frames but 3 original frames"))
        "torchmeshmetric compare: error: method 'b': 2 simplified frames but 3 original frames"
        >>> error_line("compare", ValueError("bad"), rank=1)
        'torchmeshmetric compare: error: rank 1: bad'
        >>> err = ValueError("bad")
        >>> err.__notes__ = ["while running frame pair 1 -> 2"]
        >>> error_line("compare", err)
        'torchmeshmetric compare: error: bad (while running frame pair 1 -> 2)'
    """
    message = error_message(exc)
    notes = [n for n in getattr(exc, "__notes__", ()) if isinstance(n, str)]  # e.g. the task (tasks.name_task)
    if notes:
        message += f" ({'; '.join(notes)})"
    where = "" if rank is None else f"rank {rank}: "
    return f"torchmeshmetric {command}: error: {where}{message}"


def _rank_0_line(store: Any, wait: datetime.timedelta) -> str | None:
    """Rank 0's error line once it is posted (waiting up to ``wait``); ``None`` when it is not (in time)."""
    if store is None:
        return None
    try:
        if wait.total_seconds() > 0:
            store.wait([_ERROR_KEY], wait)
        elif not store.check([_ERROR_KEY]):
            return None
        return bytes(store.get(_ERROR_KEY)).decode()
    except Exception:  # not posted in time, or the store is gone with rank 0
        return None


def _said(store: Any) -> bool:
    """Whether some rank already printed the job's error line."""
    try:
        return store is not None and bool(store.check([_SAID_KEY]))
    except Exception:
        return False


def report_error(launch: Launch, command: str, exc: BaseException) -> int:
    """Print a rank's error once for the whole job; the exit code (1).

    Every rank usually fails alike (a bad argument or file is bad for all): rank 0 prints the line and posts it in
    the store, the others wait for it (up to :data:`ERROR_WAIT`) and stay silent when it is theirs. A rank whose error
    rank 0 did not report (it failed alone: a file unreadable on its node, its own device) prints its line with its
    rank, so that no error is lost.
    """
    line = error_line(command, exc)
    store = default_store()
    if launch.rank == 0:
        _post(store, _ERROR_KEY, line)
    elif _rank_0_line(store, ERROR_WAIT) == line:
        return 1
    else:
        line = error_line(command, exc, rank=launch.rank)
    _post(store, _SAID_KEY, line)  # the ranks torchrun then stops stay silent: the job's error is said
    say(line)
    return 1


def _post(store: Any, key: str, value: str) -> None:
    if store is not None:
        with contextlib.suppress(Exception):  # the store is best effort: the line is printed anyway
            store.set(key, value)


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


def _join(launch: Launch) -> None:
    """Join the job's process group; a rank that cannot waits for torchrun to stop it before it says so.

    A rank that is slow to start (a loaded machine) can still be connecting its peers when the others have already
    failed alike (a missing folder), said so once and exited: its connection then breaks ("Gloo connectFullMesh
    failed ... Connection closed by peer"), a second line for one error, about the wrong cause (seen 2026-12-06 in
    CI, 3 ranks on 2 cores). Such a failure comes just before torchrun's SIGTERM (1.3 s there): waiting for it
    (:class:`Stopped`, silent) up to :data:`ERROR_WAIT` leaves the job one line; a failure that
    no SIGTERM follows (a rank alone that cannot reach the others) is raised, and printed with the rank.

    Raises:
        Stopped: torchrun stopped this rank while it was joining, or right after it failed to.
        RuntimeError: the group could not be joined and no other rank ended the job.
    """
    try:
        dist.init_process_group("gloo", timeout=COLLECTIVE_TIMEOUT)
    except Exception as exc:
        time.sleep(ERROR_WAIT.total_seconds())  # SIGTERM raises Stopped in here
        raise RuntimeError(f"rank {launch.rank}: could not join the job's process group: {exc}") from exc


def run_command(command: Callable[[Any], int], args: Any) -> int:
    """Run a CLI command, inside a process group when torchrun started this process.

    Ranks other than 0 stay silent about failures of the shared work: rank 0 prints the one line that names the
    failing rank and frame pair, and every rank exits with code 1. Any other error is printed once for the job
    (:func:`report_error`): by rank 0, or by the rank that alone saw it, with its rank.
    """
    launch = launch_from_environment()
    threads = thread_count(getattr(args, "threads", None), launch)
    if threads is not None:
        torch.set_num_threads(threads)
    if launch is None:
        return command(args)
    if getattr(args, "command", None) not in SHARDED_COMMANDS:
        if launch.rank != 0:
            return 1  # the same refusal on every rank (it depends on the arguments alone): rank 0 says it
        raise RuntimeError(
            f"{args.command} runs in one process; under torchrun use {', '.join(SHARDED_COMMANDS)} (WORLD_SIZE is "
            f"{launch.world_size})"
        )
    previous = signal.signal(signal.SIGTERM, _stop)
    try:
        _join(launch)
    except BaseException as exc:  # no group to leave: only the handler to restore
        signal.signal(signal.SIGTERM, previous)
        if isinstance(exc, Stopped):
            return 1  # another rank exited while this one was joining: it (or rank 0) said why
        raise
    try:
        if getattr(args, "device", "cpu") == "cuda":  # in the group: a device missing on some ranks is said once
            args.device = _cuda_device(launch)
        return command(args)
    except RankFailedError:
        if launch.rank != 0 or _said(default_store()):
            return 1  # rank 0 names the failing rank, unless that rank already said why itself
        raise
    except Exception as exc:
        if os.environ.get("TORCHMESHMETRIC_DEBUG"):
            raise
        return report_error(launch, args.command, exc)
    except Stopped:
        busy = in_flight()
        if _said(default_store()):
            return 1  # a rank failed and said why; torchrun stopped the others
        if launch.rank == min(set(range(launch.world_size)) - {r for r, _ in busy}):  # one line, from one survivor
            say(f"torchmeshmetric {args.command}: error: {_stopped_message(busy)}")
        return 1
    finally:
        signal.signal(signal.SIGTERM, previous)
        dist.destroy_process_group()
