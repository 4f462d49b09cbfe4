"""The command line's shared option groups and argument types (imported by every command's parser; no torch).

Each command module declares its own options and takes the groups it needs from here: :func:`common_options`
(device, precision, kernel backend, threads: every command that computes), :func:`evaluation_options` (the
commands that evaluate sequences) and :func:`report_options` (the commands that write one report).
"""

from __future__ import annotations

import argparse
import math
import re
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

__all__ = [
    "add_cache_dir",
    "NUDGED_CACHE",
    "as_option_error",
    "cache_folder",
    "corner",
    "add_command",
    "add_determinacy",
    "add_seed",
    "add_target",
    "add_weight",
    "common_options",
    "evaluation_options",
    "input_file_error",
    "output_stem",
    "parse_target",
    "path_argument",
    "parse_weight",
    "parse_weights",
    "positive_int",
    "report_options",
    "seed_int",
    "thread_count",
]


def path_argument(text: str) -> str:
    """An argument that names a file, folder or file pattern: not empty (``Path("")`` is the current folder).

    An empty value (an unset shell variable, ``--cache-dir ""``) would otherwise read the meshes of the current
    folder or write there.
    """
    if not text.strip():
        raise argparse.ArgumentTypeError(f"expected a path, found {text!r}")
    return text


def int_in_range(low: int, high: int | None = None) -> Callable[[str], int]:
    """An argparse type: an integer in ``[low, high]`` (``high=None``: no upper bound), refused when parsed (exit 2).

    Example:
        >>> int_in_range(3, 24)("5")
        5
    """
    if high is not None:
        span = f"an integer from {low} to {high}"
    else:
        span = "a positive integer" if low == 1 else f"an integer >= {low}"

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected {span}, found {text!r}") from None
        if value < low or (high is not None and value > high):
            raise argparse.ArgumentTypeError(f"expected {span}, found {text!r}")
        return value

    return parse


positive_int = int_in_range(1)
"""An argument that is an integer >= 1."""


def max_threads() -> int:
    """The most ``--threads`` this machine takes: 4 per CPU core, at least 64.

    More threads than cores never speeds torch's CPU work up (5000 threads on 2 cores ran 4.7x slower), and far more
    cannot be started: ``--threads 100000`` failed with "can't start new thread", blamed on an input option, and then
    segfaulted (exit 139); ``--threads 99999999999999999999`` said "Overflow when unpacking long long" (review X, F6).
    The floor keeps a script that asks for a few dozen threads working on a small machine.
    """
    import os

    return max(64, 4 * (os.cpu_count() or 1))


def thread_count(text: str) -> int:
    """A ``--threads``: an integer from 1 to :func:`max_threads`, refused when parsed (exit 2) with the reason."""
    high = max_threads()
    try:
        value = int(text)
    except ValueError:
        value = 0
    if not 1 <= value <= high:
        raise argparse.ArgumentTypeError(
            f"expected an integer from 1 to {high} (4 per CPU core of this machine, at least 64: more threads than "
            f"cores only slow torch down), found {text!r}"
        )
    return value


SEED_MAX = 2**63 - 1
"""The largest ``--seed``: numpy's generators take any integer >= 0, torch's ``manual_seed`` a signed 64-bit one."""

seed_int = int_in_range(0, SEED_MAX)
"""A ``--seed`` (every command that takes one): ``-1`` gave numpy's "expected non-negative integer" without the
option, and 2**64 ran in ``demo`` but failed in ``validate`` with "Overflow when unpacking long long" (review X, F12).
"""


def add_seed(p: argparse.ArgumentParser, help_text: str) -> None:
    """Add ``--seed`` (default 0; an integer from 0 to :data:`SEED_MAX`, checked when parsed) with its help."""
    p.add_argument("--seed", type=seed_int, default=0, help=help_text)


def parse_ratio(text: str) -> float:
    """A ratio in (0, 1] (``validate --keep``), refused when parsed (exit 2)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a ratio in (0, 1], found {text!r}") from None
    if not 0 < value <= 1:  # NaN too
        raise argparse.ArgumentTypeError(f"expected a ratio in (0, 1], found {text!r}")
    return value


def parse_target(text: str) -> float | int:
    """A ``--target``, read as the library reads ``target``: a face count, or a ratio of faces to keep.

    An integer is a face count (>= 1); a number with a point or an exponent is a ratio of each frame's faces to keep,
    in (0, 1] (``1.0`` keeps every face; it was read as a count of 1 face).

    Example:
        >>> parse_target("500"), parse_target("0.25"), parse_target("1.0")
        (500, 0.25, 1.0)
    """
    try:
        value = int(text)
    except ValueError:
        pass
    else:
        if value < 1:
            raise argparse.ArgumentTypeError(f"expected a face count (>= 1) or a ratio in (0, 1], found {text!r}")
        return value
    try:
        ratio = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a face count or a ratio in (0, 1], found {text!r}") from None
    if not 0 < ratio <= 1:  # NaN too
        raise argparse.ArgumentTypeError(f"expected a face count (>= 1) or a ratio in (0, 1], found {text!r}")
    return ratio


def _finite_non_negative(text: str, noun: str) -> float:
    """A number finite and >= 0, the message naming what it is (``weight``, ``fraction``)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a {noun} >= 0, found {text!r}") from None
    if not (value >= 0 and value != float("inf")):
        raise argparse.ArgumentTypeError(f"expected a finite {noun} >= 0, found {text!r}")
    return value


def parse_weight(text: str) -> float:
    """A Registered QEM weight: finite and >= 0."""
    return _finite_non_negative(text, "weight")


def parse_fraction(text: str) -> float:
    """A fraction >= 0 (``--relative-margin``): checked when parsed, not after the evaluation it qualifies."""
    return _finite_non_negative(text, "fraction")


def parse_weights(text: str) -> tuple[float, ...]:
    """A comma-separated list of weights, or ``none`` (no weight: an empty tuple)."""
    if text.strip().lower() == "none":
        return ()
    weights = tuple(parse_weight(w) for w in text.split(",") if w.strip())
    if not weights:
        raise argparse.ArgumentTypeError(f"expected a comma-separated list of weights or 'none', found {text!r}")
    return weights


MPEG_GRID_SIZE_MAX = 1 << 20
"""The largest ``--mpeg-grid-size`` (``ctc --grid-size``'s bound): the grid's steps per side of the box."""


def common_options(dtype_help: str | None = None) -> argparse.ArgumentParser:
    """Options of every command that computes: device, precision, kernel backend, threads.

    Args:
        dtype_help: ``--dtype``'s help where the command uses the precision otherwise than the default text says.
    """
    common = argparse.ArgumentParser(add_help=False)
    common.add_argument(
        "--device", choices=("cpu", "cuda"), default="cpu", help="where distances and registration run (default cpu)"
    )
    common.add_argument(
        "--dtype",
        choices=("float32", "float64"),
        default="float32",
        help=dtype_help
        or "precision of the frames and of every distance (default float32: statistics within ~3e-5 relative of "
        "float64 on a 40k-face pair, see the docs' command-line page; float64 to compare tiny differences); the "
        "registration of the original frames computes in float64 either way (the same figures on every CPU)",
    )
    common.add_argument(
        "--backend",
        choices=("auto", "bvh", "triton", "pruned", "bruteforce"),
        default="auto",
        help="exact distance kernel (default auto: the C++ BVH on the CPU, Triton on CUDA); all give the same values",
    )
    common.add_argument(
        "--threads",
        type=thread_count,
        default=None,
        metavar="N",
        help="torch CPU threads of this process (default: torch's choice; under torchrun: the cores divided by the "
        "processes on this machine unless OMP_NUM_THREADS is set to more than 1)",
    )
    return common


def evaluation_options() -> argparse.ArgumentParser:
    """Options of the commands that evaluate sequences: sides, registration cache, MPEG figures."""
    evaluation = argparse.ArgumentParser(add_help=False)
    evaluation.add_argument(
        "--one-sided",
        action="store_true",
        help="only the paper's simplified -> reference sets; by default the reverse (reference -> simplified) "
        "sets are reported too, so a simplification that drops part of the surface cannot score well",
    )
    add_cache_dir(
        evaluation,
        "keep registrations of original frame pairs in DIR (keyed by mesh content and settings) and reuse "
        "them in later runs (default: in memory for this run only)",
    )
    evaluation.add_argument(
        "--mpeg",
        action="store_true",
        help="also report MPEG's per-frame D1/D2 PSNR and Hausdorff (mmetric's figures, frame k vs original frame "
        "k) in the tables and reports (REPORT.mpeg.csv, REPORT.mpeg.png); averaged as the CTC: mean of per-frame PSNR",
    )
    evaluation.add_argument(
        "--mpeg-sampling", choices=("grid", "mesh"), default="grid", help="MPEG sampling (default grid, the CTC's)"
    )
    evaluation.add_argument(
        "--mpeg-grid-size",
        # checked when parsed: the library's check (grid_size >= 2) came after the whole evaluation, naming
        # "grid_size" (review X, F7); the upper bound is ctc --grid-size's
        type=int_in_range(2, MPEG_GRID_SIZE_MAX),
        default=1024,
        metavar="N",
        help=f"MPEG grid size, 2 to {MPEG_GRID_SIZE_MAX} (default 1024)",
    )
    add_temporal(evaluation)
    return evaluation


def add_temporal(p: argparse.ArgumentParser) -> None:
    """Add ``--temporal`` (KG, KSO and STED of every method in the tables and reports)."""
    p.add_argument(
        "--temporal",
        action="store_true",
        help="also report KG, KSO, STED_s, STED_t and STED of every method (registered forms when the connectivity "
        "changes, docs/temporal.md; on the evaluation's registrations)",
    )


def report_options() -> argparse.ArgumentParser:
    """Options of the commands that write one report (evaluate, compare)."""
    output = argparse.ArgumentParser(add_help=False)
    output.add_argument(
        "--out",
        type=path_argument,
        default=None,
        metavar="REPORT.json",
        help="write the JSON report there, and the paper's tables beside it as REPORT.md and REPORT.csv "
        "(a name ending in .json, outside the input frame folders; default: print the tables only)",
    )
    output.add_argument("--overwrite", action="store_true", help="replace existing output files")
    add_html(output, "also write REPORT.html: the report as one offline page (tables, curves, 3D error viewer)")
    add_determinacy(output, "evaluate again", "docs/statistics.md")
    return output


def add_determinacy(p: argparse.ArgumentParser, again: str, docs: str) -> None:
    """Add ``--determinacy ROUNDING``; ``again``: what the command repeats on the nudged frames; ``docs``: its page."""
    p.add_argument(
        "--determinacy",
        default=None,
        metavar="ROUNDING",
        type=parse_rounding,
        help=f"measure which digits this run's input determines: {again} with every coordinate moved by up to one "
        "unit of the frames' storage ('float32', or N for a text file's N decimals) and print only the digits both "
        f"runs share (twice the time; {docs})",
    )


def parse_rounding(text: str) -> str:
    """``--determinacy``'s value, checked and canonical: ``"float32"`` or a number of decimals 0..15 (``"015"``: 15).

    The canonical text is what the messages and the report's settings say.
    """
    from torchmeshmetric.evaluation.determinacy import storage_unit

    try:
        storage_unit(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(f"expected 'float32' or a number of decimals 0..15, found {text!r}") from exc
    return text if text == "float32" else str(int(text))


def add_html(p: argparse.ArgumentParser, help_text: str) -> None:
    """Add ``--html`` (also write the report as one self-contained page) with the command's own help."""
    p.add_argument("--html", action="store_true", help=help_text)


#: The folder under ``--cache-dir`` (or a campaign's cache folder) where ``--determinacy`` keeps the registrations
#: of the nudged frames: a rerun resumes the second run as it resumes the first, and the folder's own entries stay
#: those of the input (the nudged frames are not the input; content keys keep the two apart anyway).
NUDGED_CACHE = "determinacy"


def cache_folder(text: str) -> str:
    """A ``--cache-dir``: a path (:func:`path_argument`) that is not an existing file, nor its :data:`NUDGED_CACHE`.

    Checked when the command line is read: the cache stores an entry only after its registration ran. A folder on
    the way that cannot be searched is refused too: ``Path.is_file`` raised ``PermissionError`` from inside argparse,
    which printed a Python traceback (review X, F13).
    """
    from pathlib import Path

    for folder in (Path(path_argument(text)), Path(text) / NUDGED_CACHE):
        try:
            is_file = folder.is_file()
        except OSError as exc:
            raise argparse.ArgumentTypeError(
                f"cannot look into {str(_unsearchable(folder))!r} to find {text!r} ({exc.strerror or exc})"
            ) from None
        if is_file:
            raise argparse.ArgumentTypeError(f"expected a folder (created when needed), found the file {str(folder)!r}")
    return text


def _unsearchable(path: Any) -> Any:
    """The first folder above ``path`` (a ``Path``) that cannot be searched, else ``path``'s parent."""
    import os

    for folder in reversed(path.parents):
        if str(folder) not in ("", ".") and folder.is_dir() and not os.access(folder, os.X_OK):
            return folder
    return path.parent


def add_cache_dir(p: argparse.ArgumentParser, help_text: str) -> None:
    """Add ``--cache-dir DIR`` (a registration cache folder) with the command's own help."""
    p.add_argument("--cache-dir", type=cache_folder, default=None, metavar="DIR", help=help_text)


def add_target(p: argparse.ArgumentParser, default: float | int, help_text: str) -> None:
    """Add ``--target`` (faces to keep) with the command's default and help."""
    p.add_argument("--target", type=parse_target, default=default, help=help_text)


def add_weight(p: argparse.ArgumentParser, help_text: str) -> None:
    """Add ``--weight`` (Registered QEM's weight; default ``None``: the library's) with the command's help."""
    p.add_argument("--weight", type=parse_weight, default=None, help=help_text)


def add_command(
    sub: Any,
    name: str,
    run: Callable[[argparse.Namespace], int],
    parents: Sequence[argparse.ArgumentParser] = (),
) -> argparse.ArgumentParser:
    """A subcommand that runs ``run``; its help is the command table's summary, its description ``run``'s docstring.

    The description is the docstring without its first paragraph (the summary line).
    """
    from torchmeshmetric.cli import COMMANDS

    _, _, description = (run.__doc__ or "").partition("\n\n")
    p: argparse.ArgumentParser = sub.add_parser(
        name,
        parents=list(parents),
        help=COMMANDS[name].summary,
        # as is: argparse %-formats a description only when it holds "%(prog)" (none does), so "%%" showed doubled
        # ("97%%", found by review O); help= strings are %-formatted, and write "%%" (docstrings: gone under -OO)
        description=" ".join(description.split()),
    )
    p.set_defaults(func=run)
    return p


def corner(text: str, option: str) -> list[float]:
    """A box corner given as three finite numbers (``"-1 -1 -1"`` or ``"-1,-1,-1"``).

    Args:
        text: the option's value.
        option: the option's name in the error (``"--min-pos"``).

    Raises:
        ValueError: not three finite numbers.

    Example:
        >>> corner("-1, 0 2.5", "--min-pos")
        [-1.0, 0.0, 2.5]
    """
    parts = [p for p in re.split(r"[,\s]+", text.strip()) if p]
    try:
        values = [float(p) for p in parts]
    except ValueError:
        values = []
    if len(values) != 3 or not all(math.isfinite(v) for v in values):
        raise ValueError(f'{option}: expected three finite numbers such as "-1 -1 -1", found {text!r}')
    return values


def ctc_options(
    args: argparse.Namespace, ranges: Sequence[tuple[str, int, int, int]]
) -> tuple[list[float], list[float]]:
    """The CTC commands' chain options, checked by name before any file is read; the sequence box.

    Checks ``--qp`` (7..31), ``--qt`` and ``--decoded-qt`` (0..31), then each ``(option, value, low, high)`` of
    ``ranges``, then the box ``--min-pos`` / ``--max-pos``.

    Args:
        args: the parsed options (``qp``, ``qt``, ``decoded_qt``, ``min_pos``, ``max_pos``).
        ranges: the command's other integer options and their inclusive bounds.

    Returns:
        ``(min_pos, max_pos)``, three floats each.

    Raises:
        ValueError: an option out of its range, a corner that is not three finite numbers, ``--max-pos`` below
            ``--min-pos`` on an axis or equal to it on every axis (a box that is a single point); each names the
            option.

    Example:
        >>> a = argparse.Namespace(qp=10, qt=12, decoded_qt=0, min_pos="0 0 0", max_pos="1 1 1")
        >>> ctc_options(a, [("--grid-size", 1024, 2, 1 << 20)])
        ([0.0, 0.0, 0.0], [1.0, 1.0, 1.0])
    """
    common = (("--qp", args.qp, 7, 31), ("--qt", args.qt, 0, 31), ("--decoded-qt", args.decoded_qt, 0, 31))
    for option, value, low, high in (*common, *ranges):
        if not low <= value <= high:
            raise ValueError(f"{option}: expected an integer in {low}..{high}, found {value}")
    from torchmeshmetric.mpeg.ctc.box import check_box

    lo, hi = corner(args.min_pos, "--min-pos"), corner(args.max_pos, "--max-pos")
    check_box(lo, hi, ("--min-pos", "--max-pos"))  # the manifest's and CtcSettings' check too
    return lo, hi


def as_option_error(exc: ValueError, options: dict[str, str]) -> Exception:
    """A library error about an argument (``knn: ...``) retold about the option that set it (``--knn-...: ...``).

    Args:
        exc: the library's error, whose message starts with the argument's name and a colon.
        options: argument name -> command-line option.

    Returns:
        A ``CLIError`` naming the option (chained to ``exc``), or ``exc`` itself when it names no listed argument.
    """
    from torchmeshmetric.cli._outputs import CLIError

    head, sep, rest = str(exc).partition(": ")
    names = [n.strip() for n in head.split(",")]
    if not sep or not all(n in options for n in names):
        return exc
    err = CLIError(f"{', '.join(options[n] for n in names)}: {rest}")
    err.__cause__ = exc
    return err


def input_file_error(option: str, path: object, exc: Exception) -> Exception:
    """A reader's error about the file an option gave, retold naming the option and the file once.

    The readers name their own parameter (``path: could not read mesh file 'x.ply' ...``): the CLI said
    ``--target 'x.ply': path: could not read mesh file 'x.ply' ...`` (review X, F10). The parameter is dropped, and
    the file is named only where the message does not name it already; an ``OSError`` says what the system said
    (``permission denied``), not ``[Errno 13] Permission denied: 'x'``.

    Returns:
        A ``CLIError`` (chained to ``exc``).

    Example:
        >>> str(input_file_error("--mesh", "x.ply", ValueError("path: mesh file 'x.ply' does not exist")))
        "--mesh: mesh file 'x.ply' does not exist"
        >>> str(input_file_error("--mesh", "x.ply", ValueError("expected one colour per vertex")))
        "--mesh 'x.ply': expected one colour per vertex"
        >>> str(input_file_error("--mesh", "x.ply", PermissionError(13, "Permission denied", "x.ply")))
        "--mesh 'x.ply': cannot read it (permission denied)"
    """
    from torchmeshmetric.cli._outputs import CLIError

    if isinstance(exc, OSError) and exc.strerror:
        text = f"cannot read it ({exc.strerror.lower()})"
    else:
        text = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        head, sep, rest = text.partition(": ")
        if sep and head == "path":
            text = rest
    named = str(path) in text
    err = CLIError(f"{option}: {text}" if named else f"{option} {str(path)!r}: {text}")
    err.__cause__ = exc
    return err


def output_stem(out: str, option: str, suffixes: Sequence[str]) -> str:
    """The stem of a command's output files (``OUT`` of ``OUT.json``, ``OUT.csv``, ...), given as the stem or a name.

    ``--out`` of ``ctc`` and ``ctc-face-errors`` is a stem, while ``evaluate --out`` is the JSON's name:
    ``ctc --out r.json`` wrote ``r.json.json``, ``r.json.csv``, ``r.json.md`` (review X, F8). A name ending in the
    first of ``suffixes`` (the main output's, ``.json``; ``ctc-face-errors``: ``.ply``) stands for its stem, as
    ``evaluate --out r.json`` does; one ending in another output's suffix is refused (which file was meant is not
    clear); any other text is the stem as before (``seq.r1`` writes ``seq.r1.json``).

    Raises:
        ValueError: a name ending in another output's suffix, naming the option.

    Example:
        >>> output_stem("r.json", "--out", (".json", ".csv", ".md")), output_stem("seq.r1", "--out", (".json",))
        ('r', 'seq.r1')
    """
    suffix = Path(out).suffix.lower()
    if suffix == suffixes[0]:
        return out[: -len(suffix)]
    if suffix in suffixes[1:]:
        raise ValueError(
            f"{option} {out!r}: expected the outputs' stem or the {suffixes[0]} file's name, found the suffix "
            f"{Path(out).suffix!r} (the {', '.join(suffixes)} files are written with one stem)"
        )
    return out
