"""``python -m torchmeshmetric`` and the ``torchmeshmetric`` console script.

Ctrl-C is handled from the first line here, before the command line's modules are imported: the command line's
own handler (``torchmeshmetric.cli._interrupts``) is installed only once ``torchmeshmetric.cli`` (argparse, the
atomic writers, tempfile, random) is imported, and an interrupt in those first ~0.15 s printed a Python traceback
and exited 1 or -2 (review X, F18). Nothing has started then, so the early handler only says the line and exits 130.
The interpreter's own start-up (before this module runs: a few tens of milliseconds) keeps Python's handling.
"""

import os
import signal
import sys


def _interrupted_early(signum: int, frame: object) -> None:
    """SIGINT before the command line's handler: nothing started, nothing to clean up; the line and 130."""
    os.write(2, b"torchmeshmetric: interrupted\n")
    os._exit(130)


def run() -> int:
    """The program: the early SIGINT handler (unless SIGINT is ignored), then the command line; its exit code."""
    if signal.getsignal(signal.SIGINT) is signal.default_int_handler:
        signal.signal(signal.SIGINT, _interrupted_early)
    from torchmeshmetric.cli import main

    return main()


if __name__ == "__main__":
    sys.exit(run())
