"""``torchmeshmetric mpeg REF DIS --mode equ``: mmetric's equality verdict, its exit status and JSON."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from torchmeshmetric.cli import main

QUAD = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n"


def _write(tmp_path: Path, name: str, faces: str) -> str:
    p = tmp_path / name
    p.write_text(QUAD + faces)
    return str(p)


def test_equal_and_reordered(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    a = _write(tmp_path, "a.obj", "f 1 2 3\nf 1 3 4\n")
    b = _write(tmp_path, "b.obj", "f 3 4 1\nf 2 3 1\n")  # same triangles, other order and first corner
    c = _write(tmp_path, "c.obj", "f 1 3 2\nf 1 3 4\n")  # the first triangle reversed
    assert main(["mpeg", a, b, "--mode", "equ"]) == 0
    assert capsys.readouterr().out == "meshes are equal\n"
    assert main(["mpeg", a, c, "--mode", "equ"]) == 1
    assert capsys.readouterr().out.splitlines() == [
        "meshes are not equal, early return.",
        "triangle number 0 from A has no equivalent in B",
    ]
    assert main(["mpeg", a, c, "--mode", "equ", "--unoriented"]) == 0
    assert capsys.readouterr().out == "meshes are equal\n"
    assert main(["mpeg", a, c, "--mode", "equ", "--all-differences", "--json"]) == 1
    d = json.loads(capsys.readouterr().out)
    assert (d["equal"], d["different_triangles"], d["first_unmatched"], d["textures"]) == (False, 1, 0, "skipped")


def test_different_counts(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    a = _write(tmp_path, "a.obj", "f 1 2 3\nf 1 3 4\n")
    b = _write(tmp_path, "b.obj", "f 1 2 3\n")
    assert main(["mpeg", a, b, "--mode", "equ"]) == 1
    assert capsys.readouterr().out == "meshes are not equal, number of triangles are different 2 vs 1\n"
