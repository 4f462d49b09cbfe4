"""OBJ vertex colours are checked by the one OBJ reader: a NaN or Inf colour is refused with file:line on every path
(issue 41, theme 7)."""

from __future__ import annotations

from pathlib import Path

import pytest

from torchmeshmetric.cli import main
from torchmeshmetric.data import load_mesh
from torchmeshmetric.data.mesh_file import MeshFileError
from torchmeshmetric.mpeg.core.textured_mesh import load_textured_mesh
from torchmeshmetric.mpeg.sampling.model_cloud import load_model_cloud

ROWS = ["v 0 0 0 1 0 0", "v 1 0 0 0 1 0", "v 1 1 0 0 0 1", "v 0 1 0 1 1 1", "f 1 2 3", "f 1 3 4"]


@pytest.mark.parametrize("bad", ["nan", "inf", "-inf"])
@pytest.mark.parametrize("slow", [False, True], ids=["fast-pass", "statement-pass"])
def test_a_non_finite_colour_is_refused_with_its_line(tmp_path: Path, capsys, bad, slow):
    rows = list(ROWS)
    rows[2] = f"v 1 1 0 0 {bad} 1"
    if slow:
        rows.insert(0, "# comment")
        rows[1] += "  # a comment after a statement: the statement-by-statement pass"
    p = tmp_path / "c.obj"
    p.write_text("\n".join(rows) + "\n")
    line = 4 if slow else 3
    pattern = rf"'{p}' vertex 2 \(line {line}\) has a non-finite colour"
    for read in (load_textured_mesh, load_model_cloud, load_mesh):
        with pytest.raises(MeshFileError, match=pattern):
            read(p)
    out = tmp_path / "o.ply"
    assert main(["sample", str(p), str(out)]) == 1
    err = capsys.readouterr().err.splitlines()[-1]
    assert f"'{p}' vertex 2 (line {line}) has a non-finite colour" in err and not out.exists()


def test_finite_colours_are_still_read(tmp_path: Path):
    p = tmp_path / "c.obj"
    p.write_text("\n".join(ROWS) + "\n")
    colors = load_textured_mesh(p).colors
    assert colors is not None and colors.tolist()[:2] == [[255.0, 0.0, 0.0], [0.0, 255.0, 0.0]]
