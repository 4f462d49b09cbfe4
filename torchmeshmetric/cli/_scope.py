"""Options that act in some modes only: one table per command, checked before any work (review X F3).

``mpeg --sampling mesh --box ...`` computed with the reference's box (peak 3.46 where the same box in grid mode gives
6.93) and exited 0; ``--grid-size 0``, ``--nearest``, an inverted ``--box``, a missing ``--face-map``, the pcqm and
ibsm options were likewise dropped without a word outside their modes, while ``--output-csv`` in equ mode was
refused. The policy is now one: an option given where it has no effect is refused, naming the option, the mode it
was given in and what acts instead. mmetric accepts some of these silently; a user who sets ``--box`` to fix the
peak across frames expects the box to act, and gets another figure.

The options are told given from absent by their parsed value: ``None`` (their parser default; the real default is
filled in by :func:`fill_defaults` once the check passed) or ``True`` for a flag.
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass
from typing import Any

__all__ = ["Scope", "check_scope", "fill_defaults"]


@dataclass(frozen=True)
class Scope:
    """Where one option acts.

    Attributes:
        flag: the option as typed (``--box``).
        contexts: the contexts (a command's own names, e.g. ``pcc-grid``, ``equ``) where it acts.
        where: those contexts in the user's words (``--mode pcc --sampling grid``).
        instead: what acts in the other contexts, or what to use instead (``""``: nothing to add).
        default: the value it takes where it is not given.
        instead_in: the contexts whose message ``instead`` fits (``None``: every one).
    """

    flag: str
    contexts: frozenset[str]
    where: str
    instead: str = ""
    default: Any = None
    instead_in: frozenset[str] | None = None


def check_scope(args: argparse.Namespace, scopes: dict[str, Scope], context: str, context_text: str) -> None:
    """Refuse the first option of ``scopes`` given in ``args`` that does not act in ``context``.

    Args:
        args: the parsed arguments; an option absent is ``None`` or ``False``.
        scopes: destination -> :class:`Scope`.
        context: the context of this run (one of the scopes' ``contexts`` names).
        context_text: the same in the user's words (``--mode equ``).

    Raises:
        CLIError: ``--box: used in --mode pcc --sampling grid only, not in --sampling mesh; ...``.

    Example:
        >>> scopes = {"box": Scope("--box", frozenset({"grid"}), "--sampling grid")}
        >>> check_scope(argparse.Namespace(box=None), scopes, "mesh", "--sampling mesh")  # not given: fine
        >>> check_scope(argparse.Namespace(box=("0 0 0", "1 1 1")), scopes, "mesh", "--sampling mesh")
        Traceback (most recent call last):
            ...
        torchmeshmetric.cli._outputs.CLIError: --box: used in --sampling grid only, not in --sampling mesh
    """
    from torchmeshmetric.cli._outputs import CLIError

    for dest, scope in scopes.items():
        value = getattr(args, dest)
        if value is None or value is False or context in scope.contexts:
            continue
        fits = scope.instead and (scope.instead_in is None or context in scope.instead_in)
        instead = f"; {scope.instead}" if fits else ""
        raise CLIError(f"{scope.flag}: used in {scope.where} only, not in {context_text}{instead}")


def fill_defaults(args: argparse.Namespace, scopes: dict[str, Scope]) -> None:
    """Give every option of ``scopes`` left absent its default (once :func:`check_scope` passed).

    Example:
        >>> a = argparse.Namespace(grid_size=None)
        >>> fill_defaults(a, {"grid_size": Scope("--grid-size", frozenset({"grid"}), "grid", default=1024)})
        >>> a.grid_size
        1024
    """
    for dest, scope in scopes.items():
        if getattr(args, dest) is None:
            setattr(args, dest, scope.default)
