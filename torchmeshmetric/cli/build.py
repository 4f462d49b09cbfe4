"""The ``build`` command: compile the package's C++ extensions ahead of first use."""

from __future__ import annotations

import argparse
from typing import Any

from torchmeshmetric._console import say
from torchmeshmetric.cli.options import add_command

__all__ = ["add_build_command", "run"]


def run(args: argparse.Namespace) -> int:
    """Compile the C++ extensions now (once per machine), so no later command waits for them.

    Every extension is built into torch's extensions directory ($TORCH_EXTENSIONS_DIR, by default
    ~/.cache/torch_extensions) and imported once to check it; a build already there is only imported. Without a
    C++ compiler or ninja the command fails with the reason; the library then runs its pure formulations.
    """
    from torchmeshmetric import native
    from torchmeshmetric.cli._outputs import CLIError

    names = args.names or list(native.EXTENSIONS)
    unknown = [n for n in names if n not in native.EXTENSIONS]
    if unknown:
        raise CLIError(f"NAME: unknown extension(s) {unknown}; expected names from {list(native.EXTENSIONS)}")
    try:
        paths = native.build(names)
    except native.NativeBuildError as err:
        raise CLIError(str(err)) from err
    for name, path in paths.items():
        say(f"{name}: {path}")
    return 0


def add_build_command(sub: Any) -> None:
    """Add the ``build`` subcommand to the CLI's subparsers."""
    p = add_command(sub, "build", run)
    p.add_argument("names", nargs="*", metavar="NAME", help="extensions to build (default: all)")
