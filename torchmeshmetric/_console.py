"""A line on stderr in one write, so that the lines of processes sharing one stderr (torchrun's ranks) never merge."""

from __future__ import annotations

import sys

__all__ = ["say"]


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
