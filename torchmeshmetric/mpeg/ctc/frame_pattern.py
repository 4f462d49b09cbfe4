"""Frame file names from printf patterns such as ``dec_%04d.obj`` (mmetric's and the test model's convention).

Light on purpose (the standard library only): the ``ctc`` and ``ctc-campaign`` commands check their patterns with it
before torch is imported.
"""

from __future__ import annotations

import os
import re

__all__ = ["frame_path", "pattern_frames"]

_FIELD = re.compile(r"%[-+ #0]*\d*[diu]")
_FIELD_OR_PERCENT = re.compile(r"%%|%[-+ #0]*\d*[diu]")
_SEPARATORS = "".join(sorted({"/", os.sep, os.altsep or "/"}))


def frame_path(pattern: str, frame: int, option: str = "PATTERN") -> str:
    """One frame's file name from a printf frame pattern such as ``dec_%04d.obj`` (mmetric's convention).

    Raises:
        ValueError: the pattern has no integer field, or more than one conversion.

    Example:
        >>> frame_path("dec_%04d.obj", 7)
        'dec_0007.obj'
    """
    fields = _FIELD.findall(pattern.replace("%%", ""))
    if len(fields) != 1 or pattern.replace("%%", "").count("%") != 1:
        raise ValueError(f"{option}: expected one printf integer field such as dec_%04d.obj, found {pattern!r}")
    return pattern % frame


def pattern_frames(pattern: str, option: str = "PATTERN") -> list[int]:
    """The frame numbers whose files a printf frame pattern names and that exist, in increasing order.

    The folder that holds the pattern's integer field (``dec_%04d.obj``: the pattern's folder; ``f%03d/mesh.obj``:
    the folder of the ``f%03d`` folders) is listed once; a name counts as frame ``k`` only when the pattern writes
    frame ``k`` as exactly that name (``dec_%04d.obj`` names ``dec_0012.obj``, not ``dec_12.obj``), and the whole
    path is a file. Negative frames are not looked for. A folder that cannot be listed holds no frame.

    Raises:
        ValueError: the pattern has no integer field, or more than one conversion (as :func:`frame_path`).

    Example:
        >>> import tempfile, pathlib
        >>> d = pathlib.Path(tempfile.mkdtemp())
        >>> for name in ("dec_0000.obj", "dec_0001.obj", "dec_0003.obj", "dec_7.obj", "notes.txt"):
        ...     _ = (d / name).write_text("")
        >>> pattern_frames(str(d / "dec_%04d.obj"))
        [0, 1, 3]
    """
    frame_path(pattern, 0, option)  # the pattern's own check
    field = next(m for m in _FIELD_OR_PERCENT.finditer(pattern) if m.group() != "%%")
    start = max(pattern.rfind(sep, 0, field.start()) for sep in _SEPARATORS) + 1
    ends = [i for i in (pattern.find(sep, field.end()) for sep in _SEPARATORS) if i >= 0]
    end = min(ends, default=len(pattern))
    folder, component = pattern[:start].replace("%%", "%"), pattern[start:end]
    before, after = (
        part.replace("%%", "%") for part in (component[: field.start() - start], component[field.end() - start :])
    )
    # what the field writes: digits, with the padding or sign its flags add (%5d, %-5d: spaces; %+d: a plus)
    name = re.compile(re.escape(before) + r"([+ ]*\d+ *)" + re.escape(after))
    try:
        names = os.listdir(folder or ".")
    except OSError:
        return []
    frames = set()
    for entry in names:
        match = name.fullmatch(entry)
        if match is None:
            continue
        number = int(match.group(1).replace(" ", ""))
        if component % number == entry and os.path.isfile(frame_path(pattern, number, option)):
            frames.add(number)
    return sorted(frames)
