"""Ctrl-C (SIGINT) at any moment of a command: one line, ``torchmeshmetric: interrupted``, and exit code 130.

Python turns SIGINT into ``KeyboardInterrupt`` at the next bytecode of the main thread, wherever that is. Inside an
import (torch's, numpy's or scipy's start-up; a lazily imported module later on) that is not safe to unwind: the
half-run import leaves broken modules behind, a library's ``except:`` around an optional import may swallow the
interrupt and fail later with another error (a scipy import interrupted this way ended in a ``RecursionError``),
and torch's C++ start-up code that called back into Python may abort the process (exit -6). So :func:`handled`
installs a handler that:

- inside an import (a frame of ``importlib._bootstrap`` on the stack), or at a second Ctrl-C, ends the process at
  once (:func:`exit_now`): the line, the files staged by the atomic writers removed, ``os._exit(130)``;
- elsewhere raises ``KeyboardInterrupt``, which unwinds through the atomic writers (nothing half-written, no
  temporary file left) to ``main``, which prints the line and returns 130.

An interrupt raised while a finalizer runs (``__del__``, a weakref callback: the garbage collector calls them between
any two bytecodes) is printed by Python as "Exception ignored in ..." and dropped, and the command went on to finish
with exit code 0 and its outputs written (seen once in 18 interrupted runs, 2026-12-07). So the interrupt stays
pending: the atomic writers raise it again before they put a file in place (:func:`raise_pending`, their
``before_commit`` hook), and ``main`` returns 130 for a command that ends with one pending.

The handler runs in the main thread between bytecodes, so a long C++ or OpenMP kernel finishes its call first (a
fraction of a second for the distance kernels) and is never interrupted in the middle of C++ code.
"""

from __future__ import annotations

import contextlib
import os
import signal
import sys
import threading
from collections.abc import Iterator
from types import FrameType
from typing import NoReturn

from torchmeshmetric import _atomic
from torchmeshmetric._console import say

__all__ = ["EXIT_CODE", "MESSAGE", "TERMINATING", "exit_now", "handled", "interrupted", "pending", "raise_pending"]

MESSAGE = "torchmeshmetric: interrupted"
EXIT_CODE = 130  # 128 + SIGINT, what shells report for a command ended by Ctrl-C
_SAID = threading.Event()  # the line is printed once, whichever of main and exit_now comes first
_PENDING = threading.Event()  # a Ctrl-C came (the handler raised); main has not reported it yet


def pending() -> bool:
    """Whether a Ctrl-C came that ``main`` has not reported yet (its ``KeyboardInterrupt`` may have been dropped)."""
    return _PENDING.is_set()


def raise_pending() -> None:
    """Raise ``KeyboardInterrupt`` again in the main thread if a Ctrl-C came, wherever its first raise went.

    The atomic writers call it before they put a file in place: an interrupt that a finalizer dropped still leaves
    no output behind. Other threads are left alone (the interrupt belongs to the main thread).
    """
    if _PENDING.is_set() and threading.current_thread() is threading.main_thread():
        raise KeyboardInterrupt


def interrupted(*, raw: bool = False) -> int:
    """Print the line on stderr (once per process) and return the exit code, 130.

    ``raw``: write to file descriptor 2 directly (on the way to ``os._exit``, which flushes no Python buffer).
    """
    if not _SAID.is_set():
        _SAID.set()
        if raw:
            with contextlib.suppress(OSError):
                os.write(2, (MESSAGE + "\n").encode())
        else:
            say(MESSAGE)
    return EXIT_CODE


def _in_import(frame: FrameType | None) -> bool:
    """Whether ``frame`` or one of its callers runs the import machinery (an import is in progress)."""
    while frame is not None:
        if frame.f_code.co_filename.startswith("<frozen importlib._bootstrap"):
            return True
        frame = frame.f_back
    return False


def exit_now() -> NoReturn:
    """End the process at once, without unwinding: the one line on stderr, exit code 130.

    The temporary files of the atomic writers (``torchmeshmetric._atomic``) are removed first, so an interrupted
    run leaves no file behind, neither complete nor partial; buffered standard output is dropped, not flushed.
    """
    atomic = sys.modules.get("torchmeshmetric._atomic")
    if atomic is not None:
        with contextlib.suppress(Exception):
            atomic.discard_pending()
    os._exit(interrupted(raw=True))


#: The signals that end a command as Ctrl-C does, but without unwinding (a ``timeout``, a scheduler, a closed
#: terminal): the staged files removed, one line, exit code 128 + the signal. They left the hidden
#: ``.NAME.RANDOM.tmp`` of the output being written behind (tens of MB; review X, F17).
TERMINATING = tuple(getattr(signal, name) for name in ("SIGTERM", "SIGHUP") if hasattr(signal, name))


def _terminated(signum: int, frame: FrameType | None) -> None:
    """SIGTERM / SIGHUP: the files staged by the atomic writers removed, one line, exit code 128 + ``signum``."""
    atomic = sys.modules.get("torchmeshmetric._atomic")
    if atomic is not None:
        with contextlib.suppress(Exception):
            atomic.discard_pending()
    with contextlib.suppress(OSError):
        os.write(2, f"torchmeshmetric: terminated ({signal.Signals(signum).name})\n".encode())
    os._exit(128 + signum)


class _Handler:
    """The SIGINT handler: raise ``KeyboardInterrupt`` where that unwinds safely, else :func:`exit_now`."""

    def __init__(self) -> None:
        self.interrupted = False

    def __call__(self, signum: int, frame: FrameType | None) -> None:
        if self.interrupted or _in_import(frame):
            exit_now()
        self.interrupted = True  # a second Ctrl-C while the first one unwinds ends the process at once
        _PENDING.set()  # in case a finalizer drops the raise below (see the module's docstring)
        raise KeyboardInterrupt


@contextlib.contextmanager
def handled(*, own_process: bool) -> Iterator[None]:
    """Install the SIGINT handler for the block (main thread only; a SIGINT that is ignored stays ignored).

    SIGTERM and SIGHUP at their default (which kills the process without a word) end it through
    :func:`_terminated` instead: the staged files removed, ``torchmeshmetric: terminated (SIGTERM)``, exit 143
    (SIGHUP: 129).

    Args:
        own_process: the block is the whole program (the console script, ``python -m torchmeshmetric``): when it
            ends, standard output is flushed and a later SIGINT (during the interpreter's shutdown) exits at once
            with the line and code 130 instead of a traceback. Otherwise the previous handler is restored.
    """
    if threading.current_thread() is not threading.main_thread() or signal.getsignal(signal.SIGINT) in (
        signal.SIG_IGN,
        None,  # a handler installed by C code, not ours to replace
    ):
        yield
        return
    _SAID.clear()
    _PENDING.clear()
    # not under torchrun: it stops the other ranks with SIGTERM when one fails, and launch.run_command keeps that
    # silent (one line for the job); a line from each stopped rank would be noise
    alone = os.environ.get("WORLD_SIZE", "1") == "1"
    ended = {sig: signal.getsignal(sig) for sig in TERMINATING} if alone else {}
    for sig, handler in ended.items():
        if handler is signal.SIG_DFL:  # one ignored (nohup) or set by the caller stays as it is
            signal.signal(sig, _terminated)
    previous = signal.signal(signal.SIGINT, _Handler())
    _atomic.before_commit = raise_pending
    try:
        yield
    finally:
        _atomic.before_commit = None
        _PENDING.clear()
        if own_process:
            with contextlib.suppress(Exception):
                sys.stdout.flush()
            signal.signal(signal.SIGINT, lambda signum, frame: exit_now())
        else:
            signal.signal(signal.SIGINT, previous)
            for sig, handler in ended.items():
                signal.signal(sig, handler)
