"""mmetric's per-frame statistics file (``compare --outputCsv FILE``): its header, its rows, appended as it does.

mmetric opens the file in append mode, writes the header when the file is empty, then one row per compared pair:
the parameters, the frame number and the figures, separated by ``;``, floats with 9 significant digits
(``%.9g``: ``inf``, ``nan`` as C prints them), booleans as ``0`` / ``1``. Three modes have figures worth a row:
``pcc`` (D1/D2 PSNR and their Hausdorff PSNR, Y/Cb/Cr PSNR and the RGB Hausdorff PSNR; colour columns ``0`` without
colours), ``ibsm`` (geometry, RGB and YUV PSNR, then the processing time in seconds -- a clock reading, never
equal between runs) and ``pcqm`` (the score and its PSNR); equ, eqTFAN and topo rows hold the text ``TODO``
where their verdict would be (mmetric v1.1.7) and are not written. ``mm sample --outputCsv`` appends its own rows
(one header per sampling mode: the options, the search's outcome and the point count). The texture columns are
what mmetric names: the ``--inputMap`` given, or the first material's ``map_Kd`` of the OBJ's ``mtllib`` files as
``<OBJ folder>/<map_Kd>`` (``.`` for a bare file name), or empty.

:func:`append_csv_row` appends under an exclusive lock in one write, so concurrent runs appending to one file
interleave whole rows; it refuses a non-empty file whose first line is not this mode's header (mmetric would append
its row under another header).
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import BinaryIO

import numpy as np

from torchmeshmetric._checks import check_flag
from torchmeshmetric.mpeg.comparison.ibsm import IbsmResult
from torchmeshmetric.mpeg.comparison.pcc import MpegResult
from torchmeshmetric.mpeg.comparison.pcqm import PcqmResult

__all__ = [
    "IBSM_CSV_HEADER",
    "PCC_CSV_HEADER",
    "PCQM_CSV_HEADER",
    "SAMPLE_CSV_HEADERS",
    "CsvHeaderError",
    "append_csv_row",
    "check_csv_header",
    "ibsm_csv_row",
    "mmetric_texture_url",
    "pcc_csv_row",
    "pcqm_csv_row",
    "sample_csv_row",
]

PCC_CSV_HEADER = (
    "p_inputModelA;p_inputModelB;p_inputMapA;p_inputMapB;p_singlePass;p_hausdorff;p_color;p_resolution;"
    "p_neighborsProc;p_dropDuplicates;p_averageNormals;frame;resolution;c2c_psnr;haus_c2c_psnr;c2p_psnr;"
    "hausc2p_psnr;color_psnr[0];color_psnr[1];color_psnr[2];haus_rgb_psnr[0];haus_rgb_psnr[1];haus_rgb_psnr[2]"
)
IBSM_CSV_HEADER = (
    "p_inputModelA;p_inputModelB;p_inputMapA;p_inputMapB;p_ibsmRenderer;p_ibsmCameraCount;p_ibsmCameraRotation;"
    "p_ibsmResolution;p_ibsmDisableCulling;p_ibsmOutputPrefix;frame;geo_psnr;rgb_psnr;r_psnr;g_psnr;b_psnr;"
    "yuv_psnr;y_psnr;u_psnr;v_psnr;processingTime"
)
PCQM_CSV_HEADER = (
    "p_inputModelA;p_inputModelB;p_inputMapA;p_inputMapB;p_radiusCurvature;p_thresholdKnnSearch;p_radiusFactor;"
    "frame;pcqm;pcqm_psnr"
)

_SEARCH = "nbSamplesMin;nbSamplesMax;maxIterations"
SAMPLE_CSV_HEADERS = {
    "face": f"model;texture;frame;resolution;thickness;bilinear;{_SEARCH};computedResolution;nbSamples",
    "sdiv": f"model;texture;frame;mode;areaThreshold;bilinear;{_SEARCH};computedThreshold;nbSamples",
    "ediv": f"model;texture;frame;mode;resolution;lengthThreshold;bilinear;{_SEARCH};computedThreshold;nbSamples",
    "prnd": "model;texture;frame;mode;targetPointCount;bilinear;nbSamples",
    "map": "model;texture;frame;mode;nbSamples",
}
"""``mm sample --outputCsv``'s header for each mode the ``sample`` command has (mmetric's face header has no
``mode`` column, nor its rows)."""


class CsvHeaderError(ValueError):
    """The statistics file to append to starts with another header (another mode's, or not mmetric's)."""


def _g(x: float) -> str:
    """A C++ ``ostream`` value at precision 9: ``%.9g`` (``inf`` / ``nan`` as glibc prints them)."""
    return f"{float(x):.9g}"


def _f32(x: float) -> str:
    return _g(float(np.float32(x)))


def pcc_csv_row(
    result: MpegResult,
    *,
    model_a: str,
    model_b: str,
    map_a: str = "",
    map_b: str = "",
    resolution: float = 0.0,
    hausdorff: bool = True,
    frame: int = 0,
) -> str:
    """The row ``mm compare --mode pcc --outputCsv`` appends for one pair (default parameters otherwise).

    Args:
        result: the comparison (:func:`~torchmeshmetric.mpeg.comparison.pcc.mpeg_compare`, :func:`mpeg_metrics`).
        model_a: the ``--inputModelA`` name, as given.
        model_b: the ``--inputModelB`` name.
        map_a: the texture name mmetric reports for A (:func:`mmetric_texture_url`).
        map_b: the one of B.
        resolution: the ``--resolution`` given (0: the reference's diagonal, which ``result.peak`` holds).
        hausdorff: the ``--hausdorff`` flag (only its column: the Hausdorff figures are written either way).
        frame: the frame number.

    Returns:
        The row, without a newline.

    Example:
        >>> import torch
        >>> from torchmeshmetric.mpeg.comparison.pcc import mpeg_compare
        >>> from torchmeshmetric.mpeg.core.point_cloud import PointCloud
        >>> pc = PointCloud(torch.tensor([[0.0, 0, 0], [1, 0, 0]]), normals=torch.tensor([[0.0, 0, 1]] * 2))
        >>> pcc_csv_row(mpeg_compare(pc, pc), model_a="a.ply", model_b="b.ply")
        'a.ply;b.ply;;;0;1;0;0;1;2;1;0;1;inf;3081.29777;inf;3081.29777;0;0;0;0;0;0'
    """
    hausdorff = check_flag(hausdorff, "hausdorff")
    s = result.symmetric
    colour = s.color_psnr is not None and s.color_rgb_hausdorff_psnr is not None
    cols = [model_a, model_b, map_a, map_b, "0", str(int(hausdorff)), str(int(colour)), _f32(resolution)]
    cols += ["1", "2", "1", str(frame), _f32(result.peak)]
    cols += [_g(v) for v in (s.d1_psnr, s.d1_hausdorff_psnr, s.d2_psnr, s.d2_hausdorff_psnr)]
    if colour and s.color_psnr is not None and s.color_rgb_hausdorff_psnr is not None:
        cols += [_g(v) for v in (*s.color_psnr, *s.color_rgb_hausdorff_psnr)]
    else:
        cols += ["0"] * 6
    return ";".join(cols)


def ibsm_csv_row(
    result: IbsmResult,
    *,
    model_a: str,
    model_b: str,
    map_a: str = "",
    map_b: str = "",
    cameras: int = 16,
    resolution: int = 2048,
    disable_culling: bool = False,
    seconds: float = 0.0,
    frame: int = 0,
) -> str:
    """The row ``mm compare --mode ibsm --outputCsv`` appends (software renderer, no camera rotation, no prefix).

    Args:
        result: :func:`~torchmeshmetric.mpeg.comparison.ibsm.ibsm`'s figures.
        model_a: the ``--inputModelA`` name, as given.
        model_b: the ``--inputModelB`` name.
        map_a: the texture name mmetric reports for A (:func:`mmetric_texture_url`).
        map_b: the one of B.
        cameras: ``--ibsmCameraCount``.
        resolution: ``--ibsmResolution``.
        disable_culling: ``--ibsmDisableCulling``.
        seconds: the processing time to report (mmetric's ``processingTime`` column, a CPU clock reading).
        frame: the frame number.

    Returns:
        The row, without a newline.

    Example:
        >>> r = IbsmResult((0,) * 4, (0,) * 4, 0.0, (99.99,) * 4, (99.99,) * 4, 99.99, 0.0, 100.0, 10)
        >>> ibsm_csv_row(r, model_a="a.obj", model_b="b.obj", seconds=0.5)
        'a.obj;b.obj;;;sw_raster;16;0.0 0.0 0.0;2048;0;;0;99.99;99.99;99.99;99.99;99.99;99.99;99.99;99.99;99.99;0.5'
    """
    disable_culling = check_flag(disable_culling, "disable_culling")
    rgb, yuv = result.rgb_psnr, result.yuv_psnr
    cols = [model_a, model_b, map_a, map_b, "sw_raster", str(cameras), "0.0 0.0 0.0", str(resolution)]
    cols += [str(int(disable_culling)), "", str(frame), _g(result.geo_psnr)]
    cols += [_g(v) for v in (rgb[3], rgb[0], rgb[1], rgb[2], yuv[3], yuv[0], yuv[1], yuv[2])]
    cols.append(_f32(seconds))
    return ";".join(cols)


def pcqm_csv_row(
    result: PcqmResult,
    *,
    model_a: str,
    model_b: str,
    map_a: str = "",
    map_b: str = "",
    radius_curvature: float = 0.001,
    knn: int = 20,
    radius_factor: float = 2.0,
    frame: int = 0,
) -> str:
    """The row ``mm compare --mode pcqm --outputCsv`` appends: the options, then the score and its PSNR.

    Args:
        result: :func:`~torchmeshmetric.mpeg.comparison.pcqm.mpeg_pcqm`'s figures (the score as PCQM returns it
            to mmetric, rounded to float32: ``pcqm_float``).
        model_a: the ``--inputModelA`` name, as given.
        model_b: the ``--inputModelB`` name.
        map_a: the texture name mmetric reports for A (:func:`mmetric_texture_url`).
        map_b: the one of B.
        radius_curvature: ``--radiusCurvature`` (double).
        knn: ``--thresholdKnnSearch``.
        radius_factor: ``--radiusFactor`` (double).
        frame: the frame number.

    Returns:
        The row, without a newline.

    Example:
        >>> r = PcqmResult(0.0, 0.0, float("inf"), (0.0, 1.0, 1.0), 3, 3, 0.001)
        >>> pcqm_csv_row(r, model_a="a.obj", model_b="b.obj")
        'a.obj;b.obj;;;0.001;20;2;0;0;inf'
    """
    cols = [model_a, model_b, map_a, map_b, _g(radius_curvature), str(knn), _g(radius_factor), str(frame)]
    return ";".join([*cols, _g(result.pcqm_float), _g(result.psnr)])


def sample_csv_row(
    mode: str,
    *,
    model: str,
    texture: str,
    points: int,
    resolution: int = 1024,
    thickness: float = 0.0,
    area_threshold: float = 1.0,
    length_threshold: float = 0.0,
    num_samples: int = 2000000,
    bilinear: bool = False,
    num_samples_min: int = 0,
    num_samples_max: int = 0,
    max_iterations: int = 10,
    computed: float = 0.0,
    frame: int = 0,
) -> str:
    """The row ``mm sample --mode MODE --outputCsv`` appends (its header: :data:`SAMPLE_CSV_HEADERS`).

    Args:
        mode: ``face``, ``sdiv``, ``ediv``, ``prnd`` or ``map``.
        model: the ``-i`` name, as given.
        texture: the texture name mmetric reports (:func:`mmetric_texture_url`).
        points: the points sampled (the file's vertex count).
        resolution: ``--resolution`` (face, ediv), as given (not the searched one).
        thickness: ``--thickness`` (face; float32, as mmetric holds it).
        area_threshold: ``--areaThreshold`` (sdiv; float32), as given.
        length_threshold: ``--lengthThreshold`` (ediv; float32), as given.
        num_samples: ``--nbSamples`` (prnd's target count).
        bilinear: ``--bilinear``.
        num_samples_min: ``--nbSamplesMin`` (0: no search).
        num_samples_max: ``--nbSamplesMax``.
        max_iterations: ``--maxIterations``.
        computed: the search's resolution (face, an integer) or threshold (sdiv, ediv; float32); 0 without a search.
        frame: the frame number.

    Returns:
        The row, without a newline.

    Raises:
        ValueError: ``mode`` not one of the five.

    Example:
        >>> sample_csv_row("face", model="m.obj", texture="", points=10, thickness=0.3)
        'm.obj;;0;1024;0.300000012;0;0;0;10;0;10'
    """
    if mode not in SAMPLE_CSV_HEADERS:
        raise ValueError(f"mode: expected one of {sorted(SAMPLE_CSV_HEADERS)}, found {mode!r}")
    search = [str(num_samples_min), str(num_samples_max), str(max_iterations)]
    lead = [model, texture, str(frame)] + ([] if mode == "face" else [mode])
    cols = {
        "face": [str(resolution), _f32(thickness), str(int(bilinear)), *search, str(int(computed))],
        "sdiv": [_f32(area_threshold), str(int(bilinear)), *search, _f32(computed)],
        "ediv": [str(resolution), _f32(length_threshold), str(int(bilinear)), *search, _f32(computed)],
        "prnd": [str(num_samples), str(int(bilinear))],
        "map": [],
    }[mode]
    return ";".join([*lead, *cols, str(points)])


def _mtl_maps(folder: str, mtl: str) -> list[str]:
    """Each ``newmtl``'s texture as mmetric names it (``<OBJ folder>/<map_Kd>``, ``""`` without one)."""
    try:
        text = Path(folder + "/" + mtl).read_bytes().decode("utf-8", "replace")
    except OSError:
        return []  # mmetric prints "can't open file" and goes on without these materials
    maps: list[str] = []
    for line in text.split("\n"):
        if line.startswith("newmtl"):
            maps.append("")
        if line.startswith("map_Kd") and maps:
            maps[-1] = folder + "/" + line[line.find(" ") + 1 :]
    return maps


def mmetric_texture_url(model: str, texture: str | None = None) -> str:
    """The texture name mmetric reports for a model: ``--inputMap`` when given, else its first material's map.

    Args:
        model: the model file name, as given to mmetric.
        texture: the ``--inputMap`` given, or ``None``.

    Returns:
        The name (``""`` when the model names no texture).

    Example:
        >>> mmetric_texture_url("frame.ply"), mmetric_texture_url("a.obj", "t.png")
        ('', 't.png')
    """
    if texture is not None:
        return texture
    if not model.lower().endswith(".obj"):
        return ""
    from torchmeshmetric.mpeg.core.model_files import obj_header

    folder = os.path.dirname(model) or "."
    maps: list[str] = []
    for line in obj_header(model).split("\n") if obj_header(model) else []:
        maps += _mtl_maps(folder, line[len("mtllib ") :])
    return maps[0] if maps else ""


def _check_first_line(p: Path, first: bytes, header: str) -> None:
    found = first.rstrip(b"\r\n").decode("utf-8", "replace")
    if found != header:
        raise CsvHeaderError(
            f"output CSV '{p}': its first line is {found[:120]!r}, not this mode's header {header[:60]!r}...; "
            "rows of another kind would be appended under it: use another file"
        )


def check_csv_header(path: str | os.PathLike, header: str) -> None:
    r"""Refuse, before any work, a statistics file :func:`append_csv_row` would refuse (another first line).

    Args:
        path: the CSV file (missing or empty: accepted).
        header: :data:`PCC_CSV_HEADER`, :data:`IBSM_CSV_HEADER` or one of :data:`SAMPLE_CSV_HEADERS`.

    Raises:
        CsvHeaderError: the file is not empty and its first line is not ``header``.
        OSError: the file exists and cannot be opened for appending (``PermissionError`` for a read-only file).

    Example:
        >>> import tempfile, pathlib
        >>> p = pathlib.Path(tempfile.mkdtemp()) / "stats.csv"
        >>> check_csv_header(p, "a;b")  # missing: accepted
        >>> _ = p.write_text("x;y\n")
        >>> try:
        ...     check_csv_header(p, "a;b")
        ... except CsvHeaderError:
        ...     print("refused")
        refused
    """
    p = Path(path)
    if p.is_file():
        # opened for appending (nothing written, the file unchanged): a read-only file was found only after the
        # comparison (review X F15); a missing file is not created here
        with open(p, "ab"):
            pass
    if p.is_file() and p.stat().st_size:
        with open(p, "rb") as fh:
            _check_first_line(p, fh.readline(), header)


@contextlib.contextmanager
def _locked(path: Path) -> Iterator[BinaryIO]:
    with open(path, "a+b") as fh:
        try:
            import fcntl
        except ImportError:  # pragma: no cover (not POSIX: no advisory lock)
            yield fh
            return
        fcntl.flock(fh.fileno(), fcntl.LOCK_EX)
        try:
            yield fh
        finally:
            fcntl.flock(fh.fileno(), fcntl.LOCK_UN)


def append_csv_row(path: str | os.PathLike, header: str, rows: Sequence[str]) -> Path:
    r"""Append rows to a statistics file as mmetric does: the header first when the file is empty or new.

    The rows are appended in one write under an exclusive lock; nothing already in the file is changed (a missing
    final newline is added before the rows).

    Args:
        path: the CSV file (created when missing).
        header: :data:`PCC_CSV_HEADER`, :data:`IBSM_CSV_HEADER` or one of :data:`SAMPLE_CSV_HEADERS`.
        rows: the rows to append (:func:`pcc_csv_row`, :func:`ibsm_csv_row`).

    Returns:
        The path.

    Raises:
        CsvHeaderError: the file is not empty and its first line is not ``header``.
        ValueError: a row holds a lone surrogate that no file name gave (nothing written, no file created).

    Example:
        >>> import tempfile, pathlib
        >>> p = pathlib.Path(tempfile.mkdtemp()) / "stats.csv"
        >>> _ = append_csv_row(p, "a;b", ["1;2"]), append_csv_row(p, "a;b", ["3;4"])
        >>> p.read_text()
        'a;b\n1;2\n3;4\n'
    """
    p = Path(path)
    # Encoded before the file is opened (which creates it): a failure leaves no empty file behind (review X F16). A
    # file name's bytes that are not UTF-8 reach Python as surrogate escapes (os.fsdecode) and are written back as the
    # bytes they were, as mmetric writes the name it was given.
    text = "".join(r + "\n" for r in rows)
    try:
        data, head = text.encode("utf-8", "surrogateescape"), (header + "\n").encode("utf-8", "surrogateescape")
    except UnicodeEncodeError as exc:
        raise ValueError(f"rows: {text[exc.start : exc.end]!r} cannot be written to {str(p)!r} ({exc.reason})") from exc
    with _locked(p) as fh:
        fh.seek(0)
        first = fh.readline()
        fh.seek(0, os.SEEK_END)
        size = fh.tell()
        out = b""
        if size == 0:
            out = head
        else:
            _check_first_line(p, first, header)
            fh.seek(size - 1)
            if fh.read(1) != b"\n":
                out = b"\n"
        fh.seek(0, os.SEEK_END)
        fh.write(out + data)
        fh.flush()
        os.fsync(fh.fileno())
    return p
