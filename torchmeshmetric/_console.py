"""A line on stderr in one write, so that the lines of processes sharing one stderr (torchrun's ranks) never merge."""

from __future__ import annotations

import contextlib
import sys
import warnings
from collections.abc import Iterator

__all__ = ["error_message", "say", "warnings_as_lines"]


def say(line: str) -> None:
    """Write ``line`` and its newline to ``sys.stderr`` in a single write, then flush.

    ``print(line, file=sys.stderr)`` hands the text and the newline to the stream separately; with Python's streams
    unbuffered (``PYTHONUNBUFFERED=1`` or ``-u``, common in containers and CI) they are two system calls, and two
    ranks writing at once interleave as ``A... B...`` on one line and an empty line after (measured: two processes
    printing 3000 lines each into one pipe, 367 lines merged with ``print``, none with this). A single write of less
    than ``PIPE_BUF`` (4096 bytes on Linux) to a pipe is atomic.

    Args:
        line: the text, without its newline.

    Example:
        >>> say("ctc-campaign: 16 frames")  # doctest: +SKIP
    """
    stream = sys.stderr
    if stream is None:  # pythonw, or a daemon that closed it: nothing to say to
        return
    stream.write(line + "\n")
    stream.flush()


@contextlib.contextmanager
def warnings_as_lines(command: str) -> Iterator[None]:
    r"""While a command runs, print each warning as one line, ``torchmeshmetric <command>: warning: <message>``.

    Python's format adds the warning's source file and line and the source line itself (``records.write(key,
    record)``), which tell the command's user nothing (review R #11). Only the text is changed: filters (``-W
    error``) and recorders (``pytest.warns``, ``catch_warnings(record=True)``) see the warning as before; a category
    other than ``UserWarning`` is named (``RegistrationWarning: ...``). Written in one call, as :func:`say`.

    Args:
        command: the command's name.

    Example:
        >>> with warnings_as_lines("ctc"):
        ...     warnings.formatwarning("frame 2 is empty", UserWarning, "x.py", 1)
        'torchmeshmetric ctc: warning: frame 2 is empty\n'
    """
    previous = warnings.formatwarning

    def one_line(
        message: Warning | str, category: type[Warning], filename: str, lineno: int, line: str | None = None
    ) -> str:
        kind = "warning" if category is UserWarning else category.__name__
        return f"torchmeshmetric {command}: {kind}: {message}\n"

    warnings.formatwarning = one_line
    try:
        yield
    finally:
        warnings.formatwarning = previous


def error_message(exc: BaseException) -> str:
    r"""The first line of an error as the command line prints it (``torchmeshmetric CMD: error: <this>``).

    An ``OSError`` that no check caught names its file and says what the system said in words:
    ``'x.obj': permission denied`` rather than ``[Errno 13] Permission denied: 'x.obj'`` (review X, F14).

    Example:
        >>> error_message(PermissionError(13, "Permission denied", "x.obj"))
        "'x.obj': permission denied"
        >>> error_message(ValueError("bad\nmore"))
        'bad'
    """
    if isinstance(exc, OSError) and exc.strerror and exc.filename is not None:
        return f"{str(exc.filename)!r}: {exc.strerror.lower()}"
    text = str(exc).strip()
    return text.splitlines()[0] if text else type(exc).__name__
