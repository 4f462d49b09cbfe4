"""``torchmeshmetric ctc`` and ``torchmeshmetric bdrate``: outputs equal the library's, reports, typed errors."""

from __future__ import annotations

import argparse
import csv
import json
from pathlib import Path

import numpy as np
import pytest

from torchmeshmetric.cli import main
from torchmeshmetric.cli.ctc import frame_path
from torchmeshmetric.cli.options import ctc_options
from torchmeshmetric.mpeg.core.textured_mesh import load_textured_mesh
from torchmeshmetric.mpeg.ctc.bd_rate import bd_rate
from torchmeshmetric.mpeg.ctc.chain import ctc_sequence


def _sequence(tmp_path: Path, n: int = 2) -> list[str]:
    """Quantised icosphere frames (10 bits over [-1, 1]^3): source, and a decoded copy moved by up to 2 steps."""
    import trimesh

    s = trimesh.creation.icosphere(2)
    rng = np.random.default_rng(1)
    for k in range(n):
        q = np.round((s.vertices * (0.9 - 0.05 * k) + 1) * 511.5)
        d = np.clip(q + rng.integers(-2, 3, q.shape), 0, 1023)
        for name, v in (("src", q), ("dec", d)):
            lines = [f"v {int(a)} {int(b)} {int(c)}" for a, b, c in v] + [
                f"f {a + 1} {b + 1} {c + 1}" for a, b, c in s.faces
            ]
            (tmp_path / f"{name}_{k:03d}.obj").write_text("\n".join(lines) + "\n")
    return ["ctc", "--reference", str(tmp_path / "src_%03d.obj"), "--decoded", str(tmp_path / "dec_%03d.obj"),
            "--first-frame", "0", "--last-frame", str(n - 1), "--qp", "10", "--qt", "0", "--min-pos", "-1 -1 -1",
            "--max-pos", "1 1 1", "--resolution", "2", "--grid-size", "128", "--ibsm-resolution", "128",
            "--ibsm-cameras", "4"]  # fmt: skip


def test_ctc_json_equals_library(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """--json prints the frames and the means of ctc_sequence; progress lines go to stderr, one per frame."""
    args = _sequence(tmp_path)
    assert main([*args, "--json"]) == 0
    out = capsys.readouterr()
    d = json.loads(out.out)
    assert [r["frame"] for r in d["frames"]] == [0, 1]
    assert out.err.count("ctc: frame") == 2
    pairs = ((k, load_textured_mesh(tmp_path / f"src_{k:03d}.obj"), load_textured_mesh(tmp_path / f"dec_{k:03d}.obj"))
             for k in range(2))  # fmt: skip
    lib = ctc_sequence(pairs, qp=10, qt=0, min_pos=[-1] * 3, max_pos=[1] * 3, resolution=2.0, grid_size=128,
                       ibsm_resolution=128, ibsm_cameras=4).as_dict()  # fmt: skip
    assert d["mean"] == pytest.approx(lib["mean"], abs=0, rel=0)
    assert set(d["mean"]) == {"GridD1", "GridD2", "IbsmGeom", "IbsmLuma"}
    for a, b in zip(d["frames"], lib["frames"], strict=True):
        assert a == b


def test_ctc_out_writes_three_reports(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """--out REPORT: JSON, CSV in the spreadsheet's column order with a mean row, Markdown; refused when present."""
    args = _sequence(tmp_path)
    out = tmp_path / "rep"
    assert main([*args, "--no-ibsm", "--out", str(out)]) == 0
    capsys.readouterr()
    d = json.loads((tmp_path / "rep.json").read_text())
    assert "IbsmGeom" not in d["mean"] and d["settings"]["ibsm"] is None
    rows = list(csv.reader((tmp_path / "rep.csv").open()))
    assert rows[0] == ["frame", "GridD1", "GridD2"]
    assert [r[0] for r in rows[1:]] == ["0", "1", "mean"]
    assert float(rows[-1][1]) == d["mean"]["GridD1"]
    assert "| **mean** |" in (tmp_path / "rep.md").read_text()
    assert main([*args, "--no-ibsm", "--out", str(out)]) == 1
    assert "already exists (pass --overwrite" in capsys.readouterr().err


def test_ctc_checks_every_frame_first(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A missing frame, a bad pattern, a bad box: one error line naming the option, before any work."""
    args = _sequence(tmp_path)
    (tmp_path / "dec_001.obj").unlink()
    assert main(args) == 1
    err = capsys.readouterr().err
    assert "--decoded: frame 1: file" in err and "ctc: frame" not in err
    bad = [a if a != str(tmp_path / "src_%03d.obj") else str(tmp_path / "src.obj") for a in args]
    assert main(bad) == 1
    assert "--reference: expected one printf integer field" in capsys.readouterr().err
    (tmp_path / "dec_001.obj").write_text("v 0 0 0\nv 1 0 0\n")
    assert main(args) == 1
    err = capsys.readouterr().err.strip().splitlines()[-1]  # the frame said once, by the task's note (review X F10)
    assert "dec_001.obj' has no faces" in err and err.endswith("(while running frame 1)") and "frame 1: " not in err
    i = args.index("--max-pos")
    assert main([*args[: i + 1], "1 1", *args[i + 2 :]]) == 1
    assert "--max-pos: expected three finite numbers" in capsys.readouterr().err


def test_a_single_point_box_is_refused_with_the_options(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """--min-pos equal to --max-pos on every axis was refused only once frame 0 ran ("box: the box is a single point
    ... (while running frame 0)") (review B #10): it is now an option error, before any frame is read; a box flat on
    one axis stays accepted."""
    args = _sequence(tmp_path)
    i, j = args.index("--min-pos"), args.index("--max-pos")
    args[i + 1] = args[j + 1] = "1 1 1"
    assert main(args) == 1
    err = capsys.readouterr().err
    assert "--max-pos: [1.0, 1.0, 1.0] equals --min-pos [1.0, 1.0, 1.0] (the box is a single point)" in err
    assert "frame 0" not in err and "ctc: frame" not in err
    args[j + 1] = "1.00000001 1 1"  # one float32 corner (the sampler's): still a single point
    assert main(args) == 1
    assert "(the box is a single point)" in capsys.readouterr().err
    a = argparse.Namespace(qp=10, qt=12, decoded_qt=0, min_pos="0 0 0", max_pos="1 0 1")
    assert ctc_options(a, []) == ([0.0, 0.0, 0.0], [1.0, 0.0, 1.0])  # flat on one axis: a box


def test_a_line_box_is_refused_with_the_options(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A box flat on two axes (a line) was accepted, then frame 0 failed with "ref: expected at least one point, found
    an empty point cloud (while running frame 0)" (review S): mm dequantises every vertex onto the line and its grid
    sampling generates 0 points. It is now an option error naming both options and the flat axes."""
    args = _sequence(tmp_path)
    i, j = args.index("--min-pos"), args.index("--max-pos")
    args[i + 1], args[j + 1] = "-1 0 0", "1 0 0"
    assert main(args) == 1
    err = capsys.readouterr().err
    assert "--max-pos: [1.0, 0.0, 0.0] equals --min-pos [-1.0, 0.0, 0.0] on y and z (the box is a line" in err
    assert "frame 0" not in err


def test_frame_path() -> None:
    assert frame_path("a_%04d.obj", 12) == "a_0012.obj"
    assert frame_path("a_%d_100%%.obj", 3) == "a_3_100%.obj"
    with pytest.raises(ValueError, match="PATTERN"):
        frame_path("a_%d_%d.obj", 1)


def test_bdrate_command(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """bdrate A.csv B.csv --json: one BD-rate per metric column in both files, equal to bd_rate."""
    a: dict[str, list[float]] = {
        "rate": [1000, 2000, 4000, 8000],
        "GridD1": [60.1, 63.4, 66.2, 68.9],
        "IbsmGeom": [50, 53, 55, 57],
    }
    b: dict[str, list[float]] = {
        "rate": [900, 1900, 3900, 8100],
        "GridD1": [60.5, 63.9, 66.4, 69.3],
        "IbsmGeom": [50.5, 53.1, 55.9, 57.2],
    }
    for name, cols in (("a", a), ("b", b)):
        with (tmp_path / f"{name}.csv").open("w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(cols)
            w.writerows(zip(*cols.values(), strict=True))
    assert main(["bdrate", str(tmp_path / "a.csv"), str(tmp_path / "b.csv"), "--json"]) == 0
    d = json.loads(capsys.readouterr().out)["bd_rate"]
    assert set(d) == {"GridD1", "IbsmGeom"}
    assert d["GridD1"] == bd_rate(a["rate"], a["GridD1"], b["rate"], b["GridD1"])
    (tmp_path / "c.csv").write_text("rate,GridD1\n100,x\n")
    assert main(["bdrate", str(tmp_path / "a.csv"), str(tmp_path / "c.csv")]) == 1
    assert "c.csv:2: column 'GridD1': expected a number" in capsys.readouterr().err


def test_ctc_html_page_says_no_word_of_meshes_has_integer_frame_ticks_and_names_the_textures(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    # Review R #11: a page written by `ctc --out R --html` said "No meshes on this page: ... (the commands' `--html`
    # adds them)" (ctc never adds meshes), its per-frame plots had ticks 0.0, 0.2, ..., 1.0 for frames 0 and 1, and
    # its settings left the texture patterns out.
    from torchmeshmetric.viz import plots

    figures: list[object] = []
    real = plots.png_bytes

    def keep(fig: object) -> bytes:
        figures.append(fig)
        return real(fig)

    monkeypatch.setattr(plots, "png_bytes", keep)
    args = _sequence(tmp_path)
    assert main([*args, "--out", str(tmp_path / "rep"), "--html"]) == 0
    page = (tmp_path / "rep.html").read_text()
    assert "No meshes on this page" not in page and "reference_texture" in page and "decoded_texture" in page
    (fig,) = figures
    for ax in fig.axes:  # type: ignore[attr-defined]
        if ax.get_visible():
            lo, hi = ax.get_xlim()
            ticks = [t for t in ax.get_xticks() if lo <= t <= hi]
            assert ticks and all(float(t).is_integer() for t in ticks), ticks


def test_ctc_out_takes_the_json_name_as_evaluate_does(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Review X, F8: `--out r.json` wrote r.json.json, r.json.csv, r.json.md; `--out r.md` r.md.json and r.md.md."""
    args = _sequence(tmp_path)
    assert main([*args, "--no-ibsm", "--out", str(tmp_path / "r.json")]) == 0
    capsys.readouterr()
    assert sorted(p.name for p in tmp_path.glob("r.*")) == ["r.csv", "r.json", "r.md"]
    bad = str(tmp_path / "s.md")
    assert main([*args, "--no-ibsm", "--out", bad]) == 1
    err = capsys.readouterr().err
    assert f"--out {bad!r}: expected the outputs' stem or the .json file's name, found the suffix '.md'" in err, err
    assert not list(tmp_path.glob("s.*"))
