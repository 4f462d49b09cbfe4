"""Command line interface of torchmeshmetric (also ``python -m torchmeshmetric``).

Commands:
  evaluate  evaluate one simplified sequence against its original frames (the paper's Fig. 2)
  compare   evaluate several simplification methods on one original sequence (Tables I-IV side by side)
  campaign  evaluate several sequences, each with several methods, listed in a TOML manifest
  report    an existing report as one offline HTML page (tables, curves, 3D viewer); --html on the commands above
  simplify  simplify every frame of a sequence with QEM, Registered QEM or tracking (Anchored QEM + slide)
  register  register one mesh (frame k-1) onto another (frame k), rigid then non-rigid
  demo      the main job: built-in sequence -> QEM and Registered QEM -> evaluation, tables, report and plots
  mpeg      MPEG D1/D2 (and colour) PSNR of one mesh pair, equal to mmetric's figures
  sample    a mesh to the point cloud mmetric's mm sample writes (face, sdiv, ediv, prnd, map)
  ctc       the V-DMC CTC metric step on a decoded sequence (grid D1/D2/colour and IBSM, mmetric's chain)
  ctc-campaign  a whole V-DMC CTC campaign: every sequence, rate and frame of a test codec and an anchor, the
            test model's CSV and the CTC sheet's summary (BD-rates, bpif, ratios), resumable
  ctc-face-errors  a decoded frame's CTC grid-sample errors per face (D1, D2, colour) as PLY/CSV
  bdrate    BD-rate of a test codec against an anchor, per metric (the CTC spreadsheet's bdRateExtend)
  validate  which distance sets respond to which controlled distortion (noise, offsets, flicker, registration)
  temporal  KG, KSO and STED of a distorted sequence (registered forms when the connectivity changes)
  build     compile the C++ extensions now (once per machine) instead of on first use

Errors (missing or corrupt files, frame-count mismatch, unwritable output) end with a one-line message on stderr
and exit code 1; reports are written atomically and never half-written. Set TORCHMESHMETRIC_DEBUG=1 for tracebacks.

evaluate, compare, campaign, ctc and ctc-campaign also run under torchrun (torchrun --nproc-per-node N -m
torchmeshmetric ...): the processes share the work and rank 0 prints and writes the same report as one process
(docs/scaling.md).
"""

# How the command line is built (docs/architecture.md): COMMANDS below is the one table of commands, as pip's
# commands_dict. `torchmeshmetric --help` is printed from the table alone; `torchmeshmetric COMMAND ...` imports
# only COMMAND's module (its parser: argparse and cli.options, no torch), and the command's `run` imports what it
# computes with. So --help and COMMAND --help never import torch, and a command pays only for its own imports.

from __future__ import annotations

import argparse
import contextlib
import importlib
import os
import sys
from collections.abc import Collection, Iterator, Sequence
from typing import NamedTuple

from torchmeshmetric._console import error_message, say, warnings_as_lines
from torchmeshmetric.cli import _interrupts

__all__ = ["COMMANDS", "CommandInfo", "build_parser", "main"]


class CommandInfo(NamedTuple):
    """One command of the table: where it is defined and the summary ``torchmeshmetric --help`` prints.

    Attributes:
        module_path: the module that defines the command, imported only when the command is run or its help asked.
        add_function: the function of that module that adds the command to the CLI's subparsers, ``add(sub)``: it
            calls ``sub.add_parser(name, help=summary, ...)``, declares the options and sets ``func`` (called with
            the parsed arguments, it runs the command and returns the exit code).
        summary: the command's one-line help (equal to the ``help`` its ``add_function`` gives, which a test checks).

    Example:
        >>> info = COMMANDS["bdrate"]
        >>> info.module_path, info.add_function
        ('torchmeshmetric.cli.bdrate', 'add_bdrate_command')
    """

    module_path: str
    add_function: str
    summary: str


#: The commands, in the order ``--help`` lists them.
COMMANDS: dict[str, CommandInfo] = {
    "evaluate": CommandInfo(
        "torchmeshmetric.cli.evaluate",
        "add_evaluate_command",
        "evaluate a simplified sequence against its original frames",
    ),
    "compare": CommandInfo(
        "torchmeshmetric.cli.compare",
        "add_compare_command",
        "compare several simplification methods (Tables I-IV side by side)",
    ),
    "campaign": CommandInfo(
        "torchmeshmetric.cli.campaign",
        "add_campaign_command",
        "evaluate a test campaign: several sequences, each with several methods (TOML manifest)",
    ),
    "report": CommandInfo(
        "torchmeshmetric.cli.report",
        "add_report_command",
        "an existing report (REPORT.json + REPORT.md) as one offline HTML page",
    ),
    "simplify": CommandInfo(
        "torchmeshmetric.cli.simplify",
        "add_simplify_command",
        "simplify every frame of a sequence with QEM, Registered QEM or tracking (Anchored QEM + slide)",
    ),
    "register": CommandInfo(
        "torchmeshmetric.cli.register",
        "add_register_command",
        "register one mesh onto another (rigid, then non-rigid)",
    ),
    "demo": CommandInfo(
        "torchmeshmetric.cli.demo",
        "add_demo_command",
        "the paper's experiment on the built-in sequence (QEM vs Registered QEM)",
    ),
    "mpeg": CommandInfo(
        "torchmeshmetric.cli.mpeg",
        "add_mpeg_command",
        "MPEG D1/D2 (and colour) PSNR of one mesh pair, as mmetric computes them",
    ),
    "sample": CommandInfo(
        "torchmeshmetric.cli.sample",
        "add_sample_command",
        "a mesh to the point cloud mmetric's mm sample writes (face, sdiv, ediv, prnd, map)",
    ),
    "ctc": CommandInfo(
        "torchmeshmetric.cli.ctc",
        "add_ctc_command",
        "the V-DMC CTC metric step on a decoded sequence (mmetric's sequence chain: grid D1/D2/colour, IBSM)",
    ),
    "ctc-campaign": CommandInfo(
        "torchmeshmetric.cli.ctc_campaign",
        "add_ctc_campaign_command",
        "a whole V-DMC CTC campaign (TOML manifest): every sequence, rate and frame, the CTC sheet's summary",
    ),
    "ctc-face-errors": CommandInfo(
        "torchmeshmetric.cli.ctc_face_errors",
        "add_ctc_face_errors_command",
        "a decoded frame's CTC errors per face (D1, D2, colour; mean and max) as PLY and CSV",
    ),
    "bdrate": CommandInfo(
        "torchmeshmetric.cli.bdrate",
        "add_bdrate_command",
        "BD-rate of a test codec against an anchor (the CTC spreadsheet's bdRateExtend), per metric",
    ),
    "validate": CommandInfo(
        "torchmeshmetric.cli.validate",
        "add_validate_command",
        "validation study: which distance sets respond to which controlled distortion",
    ),
    "temporal": CommandInfo(
        "torchmeshmetric.cli.temporal",
        "add_temporal_command",
        "KG, KSO and STED of a distorted sequence (registered forms when the connectivity changes)",
    ),
    "build": CommandInfo(
        "torchmeshmetric.cli.build",
        "add_build_command",
        "compile the C++ extensions now (once per machine) instead of on first use",
    ),
}


def _parser(full: Collection[str]) -> argparse.ArgumentParser:
    """The parser, with every option of the commands in ``full``; the others are listed by name and summary only."""
    parser = argparse.ArgumentParser(
        prog="torchmeshmetric", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    from torchmeshmetric._version import __version__

    parser.add_argument("--version", action="version", version=f"torchmeshmetric {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name, info in COMMANDS.items():
        if name in full:
            getattr(importlib.import_module(info.module_path), info.add_function)(sub)
        else:
            sub.add_parser(name, help=info.summary)  # never parsed: the command line names another command
    return parser


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of the command line, with every command's options (imports every command's module).

    Returns:
        The ``torchmeshmetric`` :class:`argparse.ArgumentParser`: one subcommand per entry of :data:`COMMANDS`;
        parsed arguments carry ``command`` and ``func`` (the command's runner).

    Example:
        >>> args = build_parser().parse_args(["bdrate", "anchor.csv", "test.csv"])
        >>> args.command, args.anchor, args.test, args.json
        ('bdrate', 'anchor.csv', 'test.csv', False)
    """
    return _parser(COMMANDS)


def _named_command(argv: Sequence[str]) -> list[str]:
    """The command the arguments name: the first one that is not an option (the top level takes no values)."""
    for arg in argv:
        if not arg.startswith("-"):
            return [arg] if arg in COMMANDS else []
    return []


COMPARISON_MODES = ("equ", "eqTFAN", "topo")
"""The ``mpeg`` modes whose exit status is a verdict, as ``diff``'s: 0 equal, 1 not equal, 2 trouble (an error)."""


def _error_code(args: argparse.Namespace) -> int:
    """The exit code of a command that failed: 1, or 2 for a comparison mode (1 is its "not equal"; review S).

    ``diff``'s convention: a script that tests ``mpeg --mode equ`` for 1 ("not equal") no longer takes a file that
    could not be read, or an option refused once the command ran, for a difference.
    """
    return 2 if args.command == "mpeg" and getattr(args, "mode", None) in COMPARISON_MODES else 1


def _error(command: str, exc: Exception, code: int = 1) -> int:
    """End a command that raised with one line on stderr and exit ``code`` (``TORCHMESHMETRIC_DEBUG=1``: re-raise)."""
    if os.environ.get("TORCHMESHMETRIC_DEBUG"):
        raise exc
    if "torchmeshmetric.launch" not in sys.modules:  # the command ran without torch: the same line, torch not loaded
        say(f"torchmeshmetric {command}: error: {error_message(exc)}")
        return code
    from torchmeshmetric.launch import error_line  # under torchrun: once, by rank 0 (or by the rank that failed)

    say(error_line(command, exc))
    return code


def _run(args: argparse.Namespace) -> int:
    """Run the parsed command (inside a process group under torchrun); an error, and each warning, becomes one line."""
    with warnings_as_lines(args.command):
        return _run_command(args)


def _run_command(args: argparse.Namespace) -> int:
    try:
        if getattr(args, "without_torch", False) and "WORLD_SIZE" not in os.environ:
            return int(args.func(args))  # a command that computes without torch (bdrate) starts without it
        from torchmeshmetric.launch import run_command  # torch: imported once a command is run, not for --help

        return int(run_command(args.func, args))
    except BrokenPipeError:
        # The reader of stdout went away (`torchmeshmetric mpeg A B | head -3`): nothing left to say to it, and
        # "error: [Errno 32] Broken pipe" was noise. Later writes (the interpreter's flush at exit) go nowhere, as
        # Python's documentation advises; a non-zero exit code (1; 2 for a comparison mode), as SIGPIPE's default
        # handling's non-zero end.
        with contextlib.suppress(OSError, ValueError):
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return _error_code(args)
    except Exception as exc:
        return _error(args.command, exc, _error_code(args))


@contextlib.contextmanager
def _silent_unless_rank_0() -> Iterator[None]:
    """Under torchrun, a rank other than 0 prints nothing while the command line is read.

    Every rank reads the same arguments, so a usage error (or ``--help``) is printed once for the job, by rank 0,
    and every rank exits with its code (2), as the errors of a running command (docs/scaling.md).
    """
    if os.environ.get("RANK", "0") == "0" or os.environ.get("WORLD_SIZE", "1") == "1":
        yield
        return
    with open(os.devnull, "w") as sink, contextlib.redirect_stdout(sink), contextlib.redirect_stderr(sink):
        yield


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the exit code.

    Exit codes: 0 ok, 1 error (one line on stderr), 2 usage error, 3 registration not converged, 130 interrupted
    (``mpeg --mode equ/eqTFAN/topo``: ``diff``'s, 0 equal, 1 not equal, 2 an error or a usage error)
    (Ctrl-C at any moment, start-up included: one line, ``torchmeshmetric: interrupted``; see
    ``torchmeshmetric.cli._interrupts``).

    Args:
        argv: the arguments; ``None``: ``sys.argv[1:]``, and this call is the whole program (the console script,
            ``python -m torchmeshmetric``), so a Ctrl-C during the interpreter's shutdown still ends with code 130.

    Returns:
        The exit code (above). A command's error is not raised: it is one line on stderr and the code
        (``TORCHMESHMETRIC_DEBUG=1`` re-raises it); a usage error exits through argparse's ``SystemExit(2)``.

    Example:
        >>> import os, tempfile
        >>> with tempfile.TemporaryDirectory() as folder:
        ...     for name, rates in (("anchor", [100, 200, 400, 800]), ("test", [90, 180, 360, 720])):
        ...         rows = ["rate,GridD1"] + [f"{r},{psnr}" for r, psnr in zip(rates, [30, 33, 36, 39])]
        ...         with open(os.path.join(folder, name + ".csv"), "w") as f:
        ...             _ = f.write(chr(10).join(rows))
        ...     main(["bdrate", os.path.join(folder, "anchor.csv"), os.path.join(folder, "test.csv")])  # 10 % less rate
        GridD1  -10.0000 %
        0
    """
    with _interrupts.handled(own_process=argv is None):
        try:
            arguments = sys.argv[1:] if argv is None else list(argv)
            parser = _parser(_named_command(arguments))
            with _silent_unless_rank_0():
                args = parser.parse_args(arguments)
            code = _run(args)
            # a Ctrl-C whose KeyboardInterrupt a finalizer dropped (Python printed "Exception ignored"): the command
            # went on, but it was interrupted all the same
            return _interrupts.interrupted() if _interrupts.pending() else code
        except KeyboardInterrupt:
            return _interrupts.interrupted()


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
