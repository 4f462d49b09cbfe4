"""The rows of mmetric's model files as text (``mpeg.core._text_rows``): C's ``%.9g`` for every float32, both ways.

The C++ formatter (``native/model_text.cpp``, ``std::to_chars``) and the Python one must print glibc's ``%.9g`` of
each float32 promoted to double, byte for byte: checked against Python's ``format(v, ".9g")`` (an exact,
correctly rounded formatter like glibc's) on millions of random bit patterns and on every boundary case below, and
against glibc's own ``snprintf`` (through ctypes) where the two could differ: the sign of a NaN, which glibc prints
(``-nan``) and Python does not.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import io
import math
import sys
import tracemalloc

import numpy as np
import pytest
import torch

from torchmeshmetric import native
from torchmeshmetric.mpeg.core import _text_rows
from torchmeshmetric.mpeg.core._text_rows import BLOCK_ROWS, text_rows
from torchmeshmetric.mpeg.core.model_files import mmetric_obj_text, mmetric_ply_text, point_cloud_blocks
from torchmeshmetric.mpeg.core.point_cloud import PointCloud

FORMULATIONS = ["native", "python"]


@pytest.fixture(params=FORMULATIONS)
def formulation(request: pytest.FixtureRequest, monkeypatch: pytest.MonkeyPatch) -> str:
    """Each test runs with the C++ formatter and with the Python one (the extension made unavailable)."""
    if request.param == "native":
        if native.try_load("pcc") is None:
            pytest.skip("the C++ extension 'pcc' cannot be built here")
    else:
        monkeypatch.setattr(_text_rows.native, "try_load", lambda name: None)
    return str(request.param)


def _format(values: np.ndarray) -> list[str]:
    """Each float32 value's text, one row of one column each."""
    text = b"".join(text_rows(values.reshape(-1, 1), None, prefix="", seps=["\n"])).decode()
    return text.split("\n")[:-1]


def _python_g9(values: np.ndarray) -> list[str]:
    """Python's ``.9g`` of each value as a double, with glibc's ``-nan`` for a NaN whose sign bit is set."""
    signed_nan = (np.isnan(values) & np.signbit(values)).tolist()
    with np.errstate(invalid="ignore"):  # signalling NaNs
        doubles = values.astype(np.float64).tolist()
    return ["-nan" if s else format(v, ".9g") for v, s in zip(doubles, signed_nan, strict=True)]


def _from_bits(bits: np.ndarray) -> np.ndarray:
    return np.asarray(bits, np.uint32).view(np.float32)


def _boundary_floats() -> np.ndarray:
    """The float32 values where ``%.9g`` is easiest to get wrong.

    Signed zeros, infinities, NaNs of both signs (quiet and signalling payloads), the smallest and largest
    subnormals and normals, 64 floats either side of every power of ten in float32's range and of the points where
    nine digits round up to the next power (``9.999999995e(k-1)``: the exponent and the fixed/exponent switch of
    ``%g`` change there, at 1e-5 and 1e9 included), and 65,536 consecutive floats from 2^20, whose ulp is 1/8:
    a quarter of them (``.125``, ``.375``, ...) are ties at the tenth digit, rounded half to even.
    """
    special = [0x00000000, 0x80000000, 0x7F800000, 0xFF800000, 0x7FC00000, 0xFFC00000, 0x7F800001, 0xFF800001]
    special += [0x7FBFFFFF, 0xFFFFFFFF, 0x00000001, 0x80000001, 0x007FFFFF, 0x807FFFFF, 0x00800000, 0x80800000]
    special += [0x7F7FFFFF, 0xFF7FFFFF, 0x3F800000, 0xBF800000]
    out = [_from_bits(np.array(special))]
    steps = np.arange(-64, 65, dtype=np.int64)
    for k in range(-46, 40):
        for centre in (10.0**k, 9.999999995 * 10.0 ** (k - 1)):
            with np.errstate(over="ignore"):
                c = np.float32(centre)
            if not np.isfinite(c) or c == 0:
                continue
            bits = np.int64(np.array([c]).view(np.uint32)[0]) + steps
            bits = bits[(bits > 0) & (bits < 0x7F800000)]
            out += [_from_bits(bits), -_from_bits(bits)]
    ties = np.array([np.float32(2**20)]).view(np.uint32)[0] + np.arange(65536, dtype=np.uint32)
    out += [_from_bits(ties), -_from_bits(ties)]
    return np.concatenate(out)


def test_random_bit_patterns_as_python(formulation: str) -> None:
    """2,000,000 random float32 bit patterns (every exponent alike, NaNs and subnormals among them) print as C's."""
    rng = np.random.default_rng(20261207)
    values = _from_bits(rng.integers(0, 2**32, 2_000_000, dtype=np.uint64).astype(np.uint32))
    if formulation == "python":
        values = values[:200_000]  # the Python formatter is the slow fallback: a tenth of them
    assert _format(values) == _python_g9(values)


def test_random_coordinates_as_python(formulation: str) -> None:
    """1,000,000 coordinate-like values (normal, scaled 1e-8..1e8), as models hold them, print as C's."""
    rng = np.random.default_rng(7)
    n = 1_000_000 if formulation == "native" else 100_000
    values = (rng.normal(size=n) * 10.0 ** rng.integers(-8, 9, n)).astype(np.float32)
    assert _format(values) == _python_g9(values)


def test_boundary_cases_as_python(formulation: str) -> None:
    values = _boundary_floats()
    assert _format(values) == _python_g9(values)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glibc's snprintf is the oracle (mmetric's libc)")
def test_boundary_and_random_cases_as_glibc(formulation: str) -> None:
    """glibc's ``snprintf("%.9g")`` itself, the oracle, on the boundary cases and 100,000 random bit patterns."""
    libc = ctypes.CDLL(ctypes.util.find_library("c"))
    buf = ctypes.create_string_buffer(64)

    def glibc(v: float) -> str:
        libc.snprintf(buf, ctypes.c_size_t(64), b"%.9g", ctypes.c_double(v))
        return buf.value.decode()

    rng = np.random.default_rng(11)
    values = np.concatenate(
        [_boundary_floats(), _from_bits(rng.integers(0, 2**32, 100_000, dtype=np.uint64).astype(np.uint32))]
    )
    with np.errstate(invalid="ignore"):
        doubles = values.astype(np.float64).tolist()
    assert _format(values) == [glibc(v) for v in doubles]


def test_signed_nan_as_glibc(formulation: str) -> None:
    """A NaN with its sign bit set prints ``-nan`` as mmetric's ostream (glibc) prints it; Python alone wrote ``nan``.

    A PLY row of such a normal was ``nan`` before this formatter (Python's ``format`` drops a NaN's sign).
    """
    nan, neg = np.float32("nan"), -np.float32("nan")
    text = mmetric_ply_text(np.zeros((1, 3), np.float32), np.array([[nan, neg, 1]], np.float32))
    assert text.splitlines()[-1] == "0 0 0 nan -nan 1 "


def test_integers_separators_and_prefix(formulation: str) -> None:
    """Integers of every size in decimal, each value followed by its separator; ``%`` in a text is plain text."""
    ints = np.array([[0, -1, np.iinfo(np.int64).max], [np.iinfo(np.int64).min, 10**9, 1234567890123]], np.int64)
    floats = np.array([[1.5], [-0.0]], np.float32)
    text = b"".join(text_rows(floats, ints, prefix="%d ", seps=["|", "/", "%s", "\n"])).decode()
    assert text == "%d 1.5|0/-1%s9223372036854775807\n%d -0|-9223372036854775808/1000000000%s1234567890123\n"


def test_blocks_across_the_block_size(formulation: str) -> None:
    """Rows past :data:`BLOCK_ROWS` come in further blocks, which join to the rows in order."""
    n = BLOCK_ROWS + 3
    points = np.arange(3 * n, dtype=np.float32).reshape(n, 3) / np.float32(7)
    blocks = list(text_rows(points, np.arange(n)[:, None], prefix="v ", seps=[" ", " ", " ", "\n"]))
    assert len(blocks) == 2
    rows = b"".join(blocks).decode().splitlines()
    assert rows[0] == "v 0 0.142857149 0.285714298 0"
    assert rows[-1] == f"v {' '.join(format(float(x), '.9g') for x in points[-1])} {n - 1}"
    assert len(rows) == n


def test_no_rows(formulation: str) -> None:
    assert list(text_rows(np.zeros((0, 3), np.float32), None, prefix="v ", seps=[" ", " ", "\n"])) == []


def test_bad_tables_named() -> None:
    with pytest.raises(ValueError, match="both None"):
        list(text_rows(None, None, prefix="", seps=[]))
    with pytest.raises(ValueError, match=r"floats has 2 rows and ints 3"):
        list(text_rows(np.zeros((2, 1)), np.zeros((3, 1)), prefix="", seps=["", ""]))
    with pytest.raises(ValueError, match=r"seps has 1 texts, expected one per column \(2\)"):
        list(text_rows(np.zeros((2, 1)), np.zeros((2, 1)), prefix="", seps=[""]))
    with pytest.raises(ValueError, match="2-D tables"):
        list(text_rows(np.zeros(2), None, prefix="", seps=[""]))


def test_files_equal_in_both_formulations(monkeypatch: pytest.MonkeyPatch) -> None:
    """A PLY with normals, colours and faces and an OBJ with colours, UVs and normals: the same bytes either way."""
    if native.try_load("pcc") is None:
        pytest.skip("the C++ extension 'pcc' cannot be built here")
    rng = np.random.default_rng(3)
    n = 5000
    p, nr = rng.normal(size=(n, 3)).astype(np.float32), rng.normal(size=(n, 3)).astype(np.float32)
    col = (rng.random((n, 3)) * 255).astype(np.float32)
    uv, f = rng.random((n, 2)).astype(np.float32), rng.integers(0, n, (n, 3))
    texts = []
    for fallback in (False, True):
        if fallback:
            monkeypatch.setattr(_text_rows.native, "try_load", lambda name: None)
        texts.append(
            (
                mmetric_ply_text(p, nr, col, f),
                mmetric_obj_text(p, f, uvs=uv, colors=col, header="mtllib m.mtl"),
                mmetric_obj_text(p, np.zeros((0, 3), np.int64), normals=nr),
            )
        )
    assert texts[0] == texts[1]
    ply, obj, cloud = texts[0]
    lines = ply.splitlines()
    rgb = " ".join(str(math.floor(c + 0.5)) for c in col[0].tolist())  # roundf of colours in [0, 255)
    assert lines[lines.index("end_header") + 1].endswith(rgb)
    assert obj.splitlines()[2 * n + 1] == "usemtl material0000"  # the header, n v rows, n vt rows
    assert cloud.splitlines()[n + 1].startswith("vn ")


def test_blocks_keep_the_memory_bounded(tmp_path) -> None:  # type: ignore[no-untyped-def]
    """Writing a 400,000-point cloud holds a block of its text at a time, not the whole text (12.7 MB here).

    Measured: the Python objects allocated while writing peak at ~2 MB (a block and its table), where the whole
    text, as the writers built it before, peaked above 100 MB (a string per row, then the joined text).
    """
    rng = np.random.default_rng(5)
    cloud = PointCloud(torch.from_numpy(rng.normal(size=(400_000, 3)).astype(np.float32)))

    class _Sink(io.RawIOBase):  # counts the bytes: a BytesIO would hold the whole text itself
        size = 0

        def write(self, b) -> int:  # type: ignore[no-untyped-def,override]
            self.size += len(b)
            return len(b)

    sink = _Sink()
    tracemalloc.start()
    try:
        sink.writelines(point_cloud_blocks(cloud, ".ply"))
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert sink.size > 12_000_000
    assert peak < sink.size / 3, f"peak {peak} bytes while writing {sink.size}"
