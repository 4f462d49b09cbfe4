"""pcqm's point-cloud PLY path goes through the one checked PLY reader (issue 41, theme 3)."""

from __future__ import annotations

import os
import struct
from pathlib import Path

import numpy as np
import pytest

from torchmeshmetric.cli import main
from torchmeshmetric.data.mesh_file import MeshFileError
from torchmeshmetric.mpeg.sampling.model_cloud import load_model_cloud

HEAD = "ply\nformat {fmt} 1.0\nelement vertex {n}\nproperty float x\nproperty float y\nproperty float z\n"
COLOUR = "property uchar red\nproperty uchar green\nproperty uchar blue\n"


def _ascii(path: Path, rows: list[str], n: int | None = None, extra: str = "", colour: bool = False) -> Path:
    head = HEAD.format(fmt="ascii", n=len(rows) if n is None else n) + (COLOUR if colour else "") + extra
    path.write_text(head + "end_header\n" + "".join(r + "\n" for r in rows))
    return path


def test_a_point_cloud_is_read_with_its_colours(tmp_path):
    p = _ascii(tmp_path / "c.ply", ["0 0 0 10 20 30", "1 2 3 255 0 7"], colour=True)
    cloud = load_model_cloud(p)
    assert cloud.points.tolist() == [[0, 0, 0], [1, 2, 3]]
    assert cloud.colors is not None and cloud.colors.tolist() == [[10, 20, 30], [255, 0, 7]]
    b = tmp_path / "b.ply"
    body = struct.pack("<3f3B", 0, 0, 0, 10, 20, 30) + struct.pack("<3f3B", 1, 2, 3, 255, 0, 7)
    b.write_bytes((HEAD.format(fmt="binary_little_endian", n=2) + COLOUR + "end_header\n").encode() + body)
    again = load_model_cloud(b)
    assert again.points.tolist() == cloud.points.tolist() and again.colors.tolist() == cloud.colors.tolist()


@pytest.mark.parametrize(
    ("write", "pattern"),
    [
        (lambda p: p.write_bytes(b""), r"'{p}' is empty \(0 bytes\)"),
        (lambda p: p.write_bytes(np.random.default_rng(0).bytes(300)), r"'{p}' is not a mesh file \(a PLY file starts"),
        (lambda p: _ascii(p, ["0 0 0"], extra="element face x\n"), r"'{p}' line 7: 'element face x' is not"),
        (lambda p: _ascii(p, ["0 0 0", "nan 1 2"]), r"'{p}' vertex 1 \(line 9\) has non-finite coordinates"),
        (lambda p: _ascii(p, ["0 0 0", "1 1 1"], n=4), r"'{p}' declares 4 vertex elements of 3 values but holds 6"),
        (lambda p: _ascii(p, ["0 0 zero"]), r"'{p}' line 8: vertex 0 holds 'zero', which is not a number"),
        (
            lambda p: p.write_bytes(
                (HEAD.format(fmt="binary_little_endian", n=4) + "end_header\n").encode() + struct.pack("<6f", *range(6))
            ),
            r"'{p}' declares 4 vertex elements of 12 bytes \(48 bytes\) but holds 24 bytes",
        ),
    ],
    ids=["empty", "random", "face-count", "nan", "truncated-ascii", "not-a-number", "truncated-binary"],
)
def test_bad_point_cloud_files_are_refused_naming_the_file(tmp_path, capsys, write, pattern):
    p = tmp_path / "cloud.ply"
    write(p)
    expected = pattern.format(p=str(p).replace(".", r"\."))
    with pytest.raises(MeshFileError, match=expected):
        load_model_cloud(p)
    good = _ascii(tmp_path / "good.ply", ["0 0 0", "1 0 0", "0 1 0"])
    assert main(["mpeg", str(good), str(p), "--mode", "pcqm"]) == 1
    line = capsys.readouterr().err.splitlines()[-1]
    assert line.startswith("torchmeshmetric mpeg: error:") and str(p) in line, line
    assert os.path.getsize(good) > 0


@pytest.mark.parametrize(
    ("rows", "n", "pattern"),
    [
        # found by review: colours were cast to uchar unchecked, "300 -5 2.7" became [44, 251, 2]
        (["0 0 0 300 -5 2.7"], None, r"line 11: vertex 0 property 'red' is 300, .* uchar cannot hold \(outside"),
        (["0 0 0 30 -5 2.7"], None, r"line 11: vertex 0 property 'green' is -5, .* uchar cannot hold \(outside"),
        (["0 0 0 30 5 2.7"], None, r"line 11: vertex 0 property 'blue' is 2.7, .* uchar cannot hold \(not an integer"),
        # found by review: only the total count of values was checked, so a long line made up for a short one
        (["0 0 0 1 2 3 4", "1 1 1 1 2"], None, r"line 11: vertex 0 has 7 value\(s\); its header declares 6"),
        (["0 0 0 1 2 3 1 1 1 1 2 3"], 2, r"line 11: vertex 0 has 12 value\(s\); its header declares 6"),
        # Python's float (the old parser here) read "1_0" as 10
        (["0 0 0 1 2 3", "1_0 1 1 1 2 3"], None, r"line 12: vertex 1 holds '1_0', which is not a number"),
    ],
)
def test_point_cloud_values_fit_their_lines_and_types(tmp_path, rows, n, pattern):
    p = _ascii(tmp_path / "c.ply", rows, n=n, colour=True)
    with pytest.raises(MeshFileError, match=pattern) as info:
        load_model_cloud(p)
    assert str(p) in str(info.value)
