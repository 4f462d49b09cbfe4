"""The HTML report: one offline page per report (--html on every report-writing command, and ``report``).

Every page is opened in headless Chromium where it is installed (Debian's ``chromium``; skipped elsewhere): no
console error, the viewer's canvas drawn (pixels of the error colours in a screenshot), every table of the report's
Markdown present and sortable.
"""

from __future__ import annotations

import base64
import importlib.util
import json
import re
import shutil
from pathlib import Path

import numpy as np
import pytest
import torch
import trimesh

from tests.cli.cli_helpers import write_frames
from tests.viz.browser import CHROMIUM, drawn_pixels, open_page
from torchmeshmetric.cli import main
from torchmeshmetric.viz.colors import error_colors
from torchmeshmetric.viz.error_mesh import error_mesh
from torchmeshmetric.viz.html_report import file_layer, markdown_html

needs_chromium = pytest.mark.skipif(
    CHROMIUM is None, reason="headless Chromium not installed (apt-get install chromium)"
)
SMALL = ["--frames", "3", "--resolution", "24", "--target", "0.5", "--weights", "none"]


def _md_tables(markdown: str) -> list[list[list[str]]]:
    """The pipe tables of a Markdown text: rows of cells (header included, rule left out)."""
    tables, rows = [], []
    for line in [*markdown.splitlines(), ""]:
        if line.startswith("|"):
            if not re.match(r"^\|[\s:|-]+\|?\s*$", line):
                rows.append([c.strip().replace("**", "") for c in line.strip().strip("|").split("|")])
        elif rows:
            tables.append(rows)
            rows = []
    return tables


def _html_tables(page: str) -> list[list[list[str]]]:
    out = []
    for table in re.findall(r"<table.*?</table>", page, flags=re.S):
        rows = re.findall(r"<tr>(.*?)</tr>", table, flags=re.S)
        out.append([[re.sub(r"<[^>]+>", "", c).strip() for c in re.findall(r"<t[hd]>(.*?)</t[hd]>", r)] for r in rows])
    return out


def _assert_self_contained(page: str) -> None:
    """Nothing loaded from anywhere: every src/href is a data: URL or an anchor; no fetch of a file or the net."""
    links = re.findall(r'(?:src|href)\s*=\s*"([^"]*)"', page)
    assert links and all(link.startswith(("data:", "#")) for link in links), links[:5]
    assert not re.search(r"<script[^>]+src=|<link[^>]+stylesheet|@import|fetch\(|XMLHttpRequest|https?://", page)


def _check_in_browser(page: Path, tmp_path: Path, *, meshes: bool) -> None:
    if CHROMIUM is None:
        return
    markdown = page.with_suffix(".md").read_text()
    opened = open_page(page, tmp_path)
    assert opened.errors == [] and opened.console == []
    assert len(_html_tables(opened.dom)) == len(_md_tables(markdown))  # every table of the report is on the page
    assert opened.sorted_column is not None
    # read as the page's sortKey reads a cell: after a "~" (a digit the storage order or --determinacy moved)
    numbers = [float(c.lstrip("~")) for c in opened.sorted_column if re.match(r"^~?-?[\d.]+(e[-+]?\d+)?$", c)]
    assert numbers == sorted(numbers) and len(numbers) >= 2
    if meshes:
        drawn = drawn_pixels(opened)
        _, _, width, height = opened.canvas  # type: ignore[misc]
        assert len(drawn) > 0.03 * width * height  # the meshes cover a good part of the canvas
        # the darkest colour of the error scale (no error), lit: blue well above red and green
        purple = (drawn[:, 2].astype(int) > drawn[:, 1].astype(int) + 20) & (drawn[:, 0] < 120)
        assert purple.sum() > 100
    else:
        assert opened.canvas is None


def test_markdown_tables_are_the_reports_cells():
    markdown = (
        "# Title\n\n### Table I: x\n\n| Algorithm | Mesh | Ave |\n|---|---|---|\n| A | k-th | **1.5e-05** |\n"
        "| B | k-th | 2 |\n\n- a `note`\n- b\n\nText\nmore <text>.\n"
    )
    page = markdown_html(markdown)
    assert _html_tables(page) == _md_tables(markdown)
    assert '<h3 id="table-i-x">Table I: x</h3>' in page
    assert "<ul><li>a <code>note</code></li><li>b</li></ul>" in page
    assert "<p>Text more &lt;text&gt;.</p>" in page


def test_error_mesh_decimated_for_display_keeps_the_errors():
    sphere = trimesh.creation.icosphere(subdivisions=4)  # 5120 faces
    d = torch.from_numpy(np.abs(sphere.vertices[:, 2]))
    whole = error_mesh("s", sphere, d, what="z", vmax=1.0)
    small = error_mesh("s", sphere, d, what="z", vmax=1.0, max_faces=1000)
    assert whole.decimated_from is None and small.decimated_from == 5120
    assert len(small.faces) <= 1000
    # each kept vertex has the colour of the error of its nearest original vertex (of one of them, where the float32
    # positions shown cannot tell two apart)
    dist = np.sqrt(((small.verts[:, None, :].astype(np.float64) - sphere.vertices[None]) ** 2).sum(-1))
    colours = error_colors(d, 1.0).numpy()[:, :3]
    for i, row in enumerate(dist):
        nearest = np.flatnonzero(row <= row.min() + 1e-6)
        assert any(np.array_equal(small.colors[i], colours[j]) for j in nearest), i


def test_demo_html_page(capsys, tmp_path, known_registration):
    out = tmp_path / "demo"
    assert main(["demo", *SMALL, "--out-dir", str(out), "--html"]) == 0
    capsys.readouterr()
    page_path = out / "report.html"
    page = page_path.read_text()
    _assert_self_contained(page)
    assert page_path.stat().st_size < 10 * 2**20
    assert _html_tables(page) == _md_tables((out / "report.md").read_text())
    layers = json.loads(re.search(r'id="tmm-meshes">(.*?)</script>', page, flags=re.S).group(1))
    names = [layer["name"] for layer in layers]
    k = json.loads((out / "report.json").read_text())["methods"]["Reg QEM"]["best_pair"]["frame"]
    assert names == [
        f"original frame {k}",
        f"original frame {k - 1} registered onto {k}",
        f"Orig QEM: simplified frame {k}",
        f"Reg QEM: simplified frame {k}",
        f"original frame {k} against Orig QEM",  # the reverse sets (two-sided by default)
        f"original frame {k} against Reg QEM",
    ]
    assert page.count("<img alt=") == 2  # RMSE per frame pair (frame_curves.png), histograms of the best pair
    _check_in_browser(page_path, tmp_path, meshes=True)
    # the same report as a page again, from its files, with the demo's error PLYs in their own colours
    plys = sorted(out.glob("error_*.ply"))
    assert (
        main(["report", str(out / "report.json"), "--out", str(tmp_path / "again.html"), "--mesh", str(plys[0])]) == 0
    )
    again = (tmp_path / "again.html").read_text()
    assert _html_tables(again) == _html_tables(page)
    layer = file_layer(plys[0])
    read = trimesh.load(plys[0], process=False)
    assert np.array_equal(layer.colors, read.visual.vertex_colors[:, :3])
    (tmp_path / "again.md").write_text((out / "report.md").read_text())
    _check_in_browser(tmp_path / "again.html", tmp_path, meshes=True)


def test_evaluate_and_compare_pages(capsys, tmp_path, known_registration):
    orig, simp = write_frames(tmp_path / "orig", 2), write_frames(tmp_path / "simp", 1)
    rep = tmp_path / "eval.json"
    args = ["evaluate", "--original", str(orig), "--simplified", str(simp), "--out", str(rep), "--html"]
    assert main([*args, "--mpeg", "--mpeg-sampling", "mesh"]) == 0
    assert known_registration.calls == 2  # the page's registered frame came from the evaluation's cache
    page = rep.with_suffix(".html").read_text()
    _assert_self_contained(page)
    assert _html_tables(page) == _md_tables(rep.with_suffix(".md").read_text())
    assert page.count("simplified frame") >= 1 and "registered onto" in page
    # curves, histograms, and the --mpeg plot: the bytes of REPORT.mpeg.png, drawn once
    assert page.count("<img alt=") == 3
    assert base64.b64encode(rep.with_suffix(".mpeg.png").read_bytes()).decode() in page
    _check_in_browser(rep.with_suffix(".html"), tmp_path, meshes=True)
    cmp = tmp_path / "cmp.json"
    args = ["compare", "--original", str(orig), "--method", f"a={simp}", "--method", f"b={orig}", "--out", str(cmp)]
    assert main([*args, "--html"]) == 0
    page = cmp.with_suffix(".html").read_text()
    assert _html_tables(page) == _md_tables(cmp.with_suffix(".md").read_text())
    assert "Comparisons with confidence" in page
    _check_in_browser(cmp.with_suffix(".html"), tmp_path, meshes=True)
    capsys.readouterr()
    assert main(["evaluate", "--original", str(orig), "--simplified", str(simp), "--html"]) == 1
    assert "--html: the page is written beside the report, so it needs --out" in capsys.readouterr().err


def test_report_command_refuses_what_it_cannot_read(capsys, tmp_path):
    # review G, finding 10: REPORT is read before its Markdown is looked for; a JSON that is no report was said to
    # lack "its Markdown", which hid the real problem
    report = str(tmp_path / "r.json")
    (tmp_path / "r.json").write_text("[1, 2]")
    assert main(["report", report]) == 1
    assert f"error: REPORT {report!r}: expected a JSON object, found list" in capsys.readouterr().err
    (tmp_path / "r.json").write_text("{}")
    assert main(["report", report]) == 1
    assert f"error: REPORT {report!r}: not a report this command reads: expected a report" in capsys.readouterr().err
    (tmp_path / "r.json").write_text("{")
    assert main(["report", report]) == 1
    assert "not a JSON report" in capsys.readouterr().err
    (tmp_path / "r.json").write_text(json.dumps({"methods": {"A": {"pairs": [_pair(1), _pair(2)]}}}))
    assert main(["report", report]) == 1  # a report without the Markdown of its tables
    markdown = str(tmp_path / "r.md")
    assert f"error: its Markdown (the tables) {markdown!r}: no such file" in capsys.readouterr().err
    (tmp_path / "r.md").write_text("# r\n")
    assert main(["report", report]) == 0 and (tmp_path / "r.html").is_file()


def _pair(frame: int, rmse: object = 0.5) -> dict:
    return {
        "frame": frame,
        **{s: {"rmse": rmse} for s in ("surface_k", "surface_k_minus_1", "vertex_k", "vertex_k_minus_1")},
    }


@pytest.mark.parametrize(
    ("report", "message"),
    [
        ({"name": "pkg", "version": "1"}, "expected a report with one of the keys ['methods', 'sequences', 'frames']"),
        ({"methods": {}}, "methods: expected a non-empty object of methods"),
        ({"methods": {"A": {"pairs": [_pair(1), _pair(2)]}, "B": {"pairs": [_pair(1)]}}},
         "methods -> 'B' -> pairs: frames [1], the first method's [1, 2] (must match)"),
        ({"methods": {"A": {"pairs": [{"surface_k": {"rmse": 1}}]}}},
         "methods -> 'A' -> pairs[0]: expected an object with an integer 'frame'"),
        ({"methods": {"A": {"pairs": [_pair(1, "banana")]}}},
         "methods -> 'A' -> pairs[0] -> surface_k_minus_1 -> rmse: expected a number (or 'nan', 'inf'), found "
         "'banana'"),
        ({"methods": {"A": {"pairs": [{"frame": 1}]}}}, "methods -> 'A' -> pairs[0]: no distance set"),
        ({"frames": [{"frame": 0}]}, "frames[0]: expected an object with a 'frame' and its figures"),
        ({"frames": "abc"}, "frames: expected a non-empty list"),
        # review A, finding 4: these passed the check, then crashed the page with a bare Python message
        ({"methods": {"A": {"pairs": [{**_pair(1), "surface_k": 0.5}]}}},
         "methods -> 'A' -> pairs[0] -> surface_k: expected an object of statistics (with 'rmse'), found 0.5"),
        ({"methods": {"A": {"pairs": [{**_pair(1), "flicker": {"rmse": 0.1}, "registration": 0.2}]}}},
         "methods -> 'A' -> pairs[0] -> registration: expected an object with the 'residual'"),
        ({"methods": {"A": {"pairs": [{**_pair(1), "flicker": {"rmse": 0.1}, "registration": {"residual": 0.2}}]}}},
         "methods -> 'A' -> pairs[0] -> registration -> residual: expected an object of statistics"),
        ({"frames": [{"x": 1, "a": 1}]}, "frames[0]: expected an object with an integer 'frame' and its figures"),
        ({"frames": [{"frame": "nan", "a": 1}]}, "frames[0]: expected an object with an integer 'frame'"),
    ],
)  # fmt: skip
def test_report_command_names_what_does_not_fit(capsys, tmp_path, report, message):
    # Each of these stopped deep inside the plotting with a message naming neither the file nor the key (review).
    (tmp_path / "r.json").write_text(json.dumps(report))
    (tmp_path / "r.md").write_text("# r\n")
    assert main(["report", str(tmp_path / "r.json")]) == 1
    err = capsys.readouterr().err.strip()
    assert err.startswith(f"torchmeshmetric report: error: REPORT {str(tmp_path / 'r.json')!r}: not a report this")
    assert message in err and len(err.splitlines()) == 1, err
    assert not (tmp_path / "r.html").exists()
    (tmp_path / "r.json").write_text(json.dumps({"methods": {"A": {"pairs": [_pair(1), _pair(2, "inf")]}}}))
    assert main(["report", str(tmp_path / "r.json")]) == 0  # the shape it reads, non-finite figures as written


def test_campaign_pages(capsys, tmp_path, known_registration):
    a, b = write_frames(tmp_path / "a", 2), write_frames(tmp_path / "b", 1)
    manifest = tmp_path / "c.toml"
    manifest.write_text(f'[[sequences]]\nname = "one"\noriginal = "{a}"\nmethods = {{ m = "{b}", n = "{a}" }}\n')
    out = tmp_path / "out"
    assert main(["campaign", str(manifest), "--out-dir", str(out), "--html"]) == 0
    for stem in ("campaign", "one"):
        page = (out / f"{stem}.html").read_text()
        _assert_self_contained(page)
        assert _html_tables(page) == _md_tables((out / f"{stem}.md").read_text())
    _check_in_browser(out / "campaign.html", tmp_path, meshes=False)
    capsys.readouterr()
    assert main(["campaign", str(manifest), "--html"]) == 1
    assert "needs --out-dir" in capsys.readouterr().err


@pytest.mark.skipif(importlib.util.find_spec("torchmeshmetric.mpeg") is None, reason="needs the mpeg package")
def test_ctc_page(capsys, tmp_path):
    from tests.mpeg.test_cli_ctc import _sequence

    args = _sequence(tmp_path)
    assert main([*args, "--out", str(tmp_path / "rep"), "--html"]) == 0
    page = (tmp_path / "rep.html").read_text()
    _assert_self_contained(page)
    assert _html_tables(page) == _md_tables((tmp_path / "rep.md").read_text())
    assert page.count('<img alt="per frame"') == 1
    _check_in_browser(tmp_path / "rep.html", tmp_path, meshes=False)


def test_layer_names_cannot_break_the_pages_script_block(tmp_path):
    # "<!--" then "<script" inside a script block put HTML's parser in its double-escaped state, where "</script>"
    # no longer ends the block: the tables and the page's own script became its text (found by review).
    from torchmeshmetric.viz.html_report import html_page

    sphere = trimesh.creation.icosphere(subdivisions=1)
    errors = torch.from_numpy(np.abs(sphere.vertices[:, 2]))
    names = ["x<!--", "<script> y", "</script><b>z"]
    layers = [error_mesh(name, sphere, errors, what="z", vmax=1.0) for name in names]
    markdown = "### Table\n\n| a | b | c | d |\n|---|---|---|---|\n| 1 | 2 | 3 | 2.5 |\n| 4 | 5 | 6 | 1.5 |\n"
    page = html_page("names", markdown, meshes=layers)
    block = re.search(r'id="tmm-meshes">(.*?)</script>', page, flags=re.S).group(1)
    assert "<" not in block and [layer["name"] for layer in json.loads(block)] == names
    assert page.count("<table") == 1 and "&lt;!--" in page  # the names shown escaped in the layer list
    path = tmp_path / "names.html"
    path.write_text(page, encoding="utf-8")
    if CHROMIUM is not None:
        opened = open_page(path, tmp_path)
        assert opened.errors == [] and opened.console == []
        # the table is live (sorted by a click on its header: the page's script ran) and the viewer drew; before
        # the fix the click sorted nothing, the serialized DOM still showing the swallowed table as text
        assert opened.sorted_column == ["1.5", "2.5"] and len(drawn_pixels(opened)) > 0


def test_a_pipe_in_a_name_keeps_its_row():
    # "QEM | 50 %" split its row into one cell more than the header had, in the .md and on the page (review).
    from torchmeshmetric.evaluation import evaluate_sequence
    from torchmeshmetric.evaluation.reports import paper_tables
    from torchmeshmetric.temporal import TemporalFigures
    from torchmeshmetric.temporal.report import temporal_markdown
    from torchmeshmetric.viz.html_report import _cells

    frames = [trimesh.creation.icosphere(subdivisions=2) for _ in range(2)]
    coarse = [trimesh.creation.icosphere(subdivisions=1) for _ in range(2)]
    name = "QEM | 50 %"
    result = evaluate_sequence(frames, coarse, registration_fn=lambda src, dst: src)
    figures = TemporalFigures(1.0, 2.0, 0.1, 0.2, 0.1, True, 3, 100)
    for markdown in (paper_tables({name: result}), temporal_markdown({name: figures})):
        rows = [line for line in markdown.splitlines() if line.startswith("|") and not line.startswith("|---")]
        header = _cells(rows[0])
        assert all(len(_cells(r)) == len(header) for r in rows[1:]) and _cells(rows[1])[0] == name
        assert _html_tables(markdown_html(markdown))[0][1][0] == name  # the page shows the name itself


def test_a_mesh_the_viewer_cannot_show_is_named_by_its_option(capsys, tmp_path):
    (tmp_path / "r.json").write_text(json.dumps({"frames": [{"frame": 0, "GridD1": 60.0}]}))
    (tmp_path / "r.md").write_text("# r\n")
    plain = tmp_path / "plain.ply"
    trimesh.creation.icosphere(subdivisions=1).export(plain)  # no vertex colours
    # review X, F10: the reader's parameter leaked (`--mesh 'x': path: ... 'x' ...`, the file named twice); the file
    # is named once, by the reader's message where it names it
    md = tmp_path / "r.md"
    for mesh, start, message in (
        (md, f"--mesh: '{md}' has unsupported suffix '.md'", ""),
        (plain, f"--mesh: {plain}: ", "one colour per vertex"),
    ):
        assert main(["report", str(tmp_path / "r.json"), "--mesh", str(mesh)]) == 1
        err = capsys.readouterr().err
        assert err.startswith(f"torchmeshmetric report: error: {start}") and message in err, err
        assert "path:" not in err and err.count(str(mesh)) == 1, err


def test_markdown_backslash_escapes_are_shown_as_the_character():
    # The note under the verdict tables ("\* noise floor ...") showed its backslash on the page (review A, 8); a
    # name's backslash (escaped by markdown_cell) shows as itself, and escapes no "*" of the name.
    from torchmeshmetric._format import markdown_cell

    name = "C:\\*b*|c\\"
    page = markdown_html(f"\\* noise floor: x\n\n| name |\n|---|\n| {markdown_cell(name)} |\n")
    assert "<p>* noise floor: x</p>" in page
    assert _html_tables(page) == [[["name"], [name]]]  # the name itself


def test_viewer_layers_of_a_method_without_error_are_drawn():
    # vmax 0 is refused now (it coloured every vertex "no error"): a method equal to the original, whose distances
    # are all 0, takes the default scale instead of a shared scale of 0
    from torchmeshmetric.evaluation import evaluate_sequence
    from torchmeshmetric.viz.html_report import best_pair_layers

    frames = [trimesh.creation.icosphere(subdivisions=1) for _ in range(2)]
    result = evaluate_sequence(frames, frames, registration_fn=lambda src, dst: src)
    layers = best_pair_layers({"same": result}, frames, {"same": frames})
    assert len(layers) > 1 and [layer.vmax for layer in layers[1:]] == [1.0] * (len(layers) - 1)
    assert layers[1].colors.tolist() == [[68, 1, 84]] * len(frames[1].vertices)  # every vertex: no error


_SORT_HARNESS = """
var document = {querySelectorAll: function () { return []; }, getElementById: function () { return null; }};
eval(require("fs").readFileSync(process.argv[1], "utf8"));
var keyed = JSON.parse(process.argv[2]).map(function (c) { return [sortKey(c), c]; });
keyed.sort(function (a, b) { return compareKeys(a[0], b[0]); });
console.log(JSON.stringify(keyed.map(function (p) { return p[1]; })));
"""


@pytest.mark.skipif(shutil.which("node") is None, reason="needs node to run the page's script")
@pytest.mark.parametrize(
    ("cells", "expected"),
    [
        # "~0.10" (a --determinacy mark) was text: sorted before every number (review A, finding 10)
        (["0.030", "~0.012", "0.0050", "~0.10", "0.020"], ["0.0050", "~0.012", "0.020", "0.030", "~0.10"]),
        # a verdict cell sorts by its difference, whatever the winner's name (":" in it too); text after numbers
        (["≈: -0.000303 ± 0.000863", "a|b x: -0.00115 ± 0.0008", "~B: 0.5 ± 1", "n: a: 2 ± 1", "nan", "inf", "-inf"],
         ["-inf", "a|b x: -0.00115 ± 0.0008", "≈: -0.000303 ± 0.000863", "~B: 0.5 ± 1", "n: a: 2 ± 1", "inf", "nan"]),
    ],
)  # fmt: skip
def test_the_pages_sort_reads_the_number_after_the_reports_marks(cells, expected):
    import subprocess

    script = Path(__file__).resolve().parents[2] / "torchmeshmetric" / "viz" / "report_page.js"
    out = subprocess.run(
        ["node", "-e", _SORT_HARNESS, str(script), json.dumps(cells)], capture_output=True, text=True, check=True
    )
    assert json.loads(out.stdout) == expected


def test_the_docs_state_the_viewer_scripts_size():
    # html_report.py said "~170 lines", docs/report.md "about 130 lines", the file had 134 (review A, finding 12):
    # the docs now give its size in one place, checked here
    root = Path(__file__).resolve().parents[2]
    claimed = re.search(r"\| ours \(`report_page.js`\) \| about (\d+) KB \|", (root / "docs" / "report.md").read_text())
    size = (root / "torchmeshmetric" / "viz" / "report_page.js").stat().st_size
    assert claimed is not None and abs(size / 1000 - int(claimed.group(1))) < 1, size
    assert "lines" not in re.search(
        r"WebGL viewer \(``report_page.js``[^)]*\)", (root / "torchmeshmetric" / "viz" / "html_report.py").read_text()
    ).group(0)


def test_report_names_out_when_its_folder_is_missing(capsys, tmp_path):
    # "error: output folder 'nodir' does not exist" named no option; the other report errors name --out/--mesh
    (tmp_path / "r.json").write_text(json.dumps({"frames": [{"frame": 0, "GridD1": 60.0}]}))
    (tmp_path / "r.md").write_text("# r\n")
    out = tmp_path / "nodir" / "x.html"
    assert main(["report", str(tmp_path / "r.json"), "--out", str(out)]) == 1
    err = capsys.readouterr().err.strip()
    assert err == (
        f"torchmeshmetric report: error: --out {str(out)!r}: output folder {str(out.parent)!r} does not exist"
    )


def test_report_rerun_names_the_default_page_not_out(capsys, tmp_path):
    # Found by review O: `report r.json` twice said "--out 'r.html' already exists", an option never given
    (tmp_path / "r.json").write_text(json.dumps({"frames": [{"frame": 0, "GridD1": 60.0}]}))
    (tmp_path / "r.md").write_text("# r\n")
    page = tmp_path / "r.html"
    page.write_text("keep me")
    assert main(["report", str(tmp_path / "r.json")]) == 1
    err = capsys.readouterr().err.strip()
    assert err == (
        f"torchmeshmetric report: error: the page {str(page)!r} already exists (pass --overwrite to replace it)"
    )
    assert page.read_text() == "keep me"
    assert main(["report", str(tmp_path / "r.json"), "--overwrite"]) == 0
    assert page.read_text() != "keep me"


@pytest.mark.parametrize("name", ["frame_000.ply", "x.txt", "page", "r.htm"])
def test_report_out_must_be_an_html_page(capsys, tmp_path, name):
    # Review X, F9: `report r.json --out orig/frame_000.ply --overwrite` replaced a frame of the evaluated sequence
    # with the page (any suffix was taken); every other writer checks its suffix before any work
    (tmp_path / "r.json").write_text(json.dumps({"frames": [{"frame": 0, "GridD1": 60.0}]}))
    (tmp_path / "r.md").write_text("# r\n")
    out = tmp_path / name
    out.write_text("a frame")
    assert main(["report", str(tmp_path / "r.json"), "--out", str(out), "--overwrite"]) == 1
    found = f"the suffix {out.suffix!r}" if out.suffix else "no suffix"
    err = capsys.readouterr().err.strip()
    assert err == f"torchmeshmetric report: error: --out {str(out)!r}: expected a PAGE.html file name, found {found}"
    assert out.read_text() == "a frame"
    assert main(["report", str(tmp_path / "r.json"), "--out", str(tmp_path / "P.HTML")]) == 0
