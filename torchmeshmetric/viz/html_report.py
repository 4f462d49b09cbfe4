"""A report as one self-contained HTML page: its tables (sortable), its figures and a 3D viewer of error meshes.

The page is another writer of a report the commands already write: its tables are the report's Markdown
(``report.md``, rendered here, so every table of it is on the page and no table is computed twice), its per-frame
curves are drawn from the JSON report (:func:`~torchmeshmetric.viz.plots.frame_curves_figure`, the figure of
``frame_curves.png``), its histograms are :func:`~torchmeshmetric.viz.plots.histogram_figure`, and its meshes carry
the colours of :func:`~torchmeshmetric.viz.colors.error_colors` (those of the error-coloured PLY files).

Everything is inside the file: figures as PNG ``data:`` URLs, meshes as base64 binary arrays (float32 positions,
uint16/uint32 faces, uint8 RGB colours) and a small hand-written WebGL viewer (``report_page.js`` beside this
module; why not three.js or model-viewer: docs/report.md). It opens from ``file://`` with no server and
loads nothing from the network. Meshes above ``max_faces`` faces are decimated for display (QEM), each kept vertex
taking the error of its nearest original vertex, so the colours stay the measured ones.
"""

from __future__ import annotations

import base64
import html
import json
import os
import re
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import torch

from torchmeshmetric._atomic import atomic_write
from torchmeshmetric._checks import check_flag
from torchmeshmetric._format import plain_label
from torchmeshmetric.structures import MeshLike
from torchmeshmetric.viz.colors import ERROR_COLOR_ANCHORS
from torchmeshmetric.viz.error_mesh import DISPLAY_FACES, ErrorMesh, error_mesh

__all__ = [
    "CURVES_CAPTION",
    "html_page",
    "markdown_html",
    "best_pair_layers",
    "file_layer",
    "report_figures",
    "write_html",
]


#: Caption of the per-frame curves (:func:`~torchmeshmetric.viz.plots.frame_curves_figure`) on a page.
CURVES_CAPTION = "RMSE per frame pair"


def file_layer(path: str | os.PathLike[str], *, max_faces: int = DISPLAY_FACES) -> ErrorMesh:
    """A mesh file with vertex colours (e.g. an ``error_*.ply`` of the demo) as a layer in its own colours.

    The file holds colours, not distances, so the layer has no scale (``vmax`` is NaN). A mesh above ``max_faces``
    is decimated, each kept vertex taking the colour of its nearest original vertex.

    Raises:
        ValueError: the file cannot be read, or has no vertex colours.
    """
    from torchmeshmetric.mpeg.core.textured_mesh import load_textured_mesh

    p = Path(path)
    loaded = load_textured_mesh(p)  # the package's reader of meshes with colour
    if loaded.colors is None:
        raise ValueError(f"{p}: expected a mesh with one colour per vertex (an error-coloured PLY), found none")
    mesh, rgb = loaded.mesh, loaded.colors.round().to(torch.int64)
    layer = error_mesh(p.name, mesh, None, what=f"colours of {p.name}", max_faces=max_faces)
    if layer.decimated_from is not None:
        from torchmeshmetric.kernels.nearest import nearest_vertex_distance

        rgb = rgb[nearest_vertex_distance(torch.from_numpy(layer.verts).double(), mesh.verts.double()).idx]
    return layer._replace(colors=rgb.numpy().astype(np.uint8), vmax=float("nan"))


def best_pair_layers(
    results: Mapping[str, Any],
    original: Sequence[MeshLike],
    simplified: Mapping[str, Sequence[MeshLike]],
    registered: MeshLike | None = None,
    *,
    unit: str = "mesh units",
    max_faces: int = DISPLAY_FACES,
) -> list[ErrorMesh]:
    """The viewer's layers of the report's best pair (frames ``k-1 -> k``, the pair of Tables I/II).

    Original frame ``k`` (the reference, grey); the registered frame ``k-1`` coloured by its registration residual
    (distance to the surface of frame ``k``: the noise floor of the ``k-1`` sets); every method's simplified
    frame ``k`` coloured by its distance to the registered frame ``k-1`` (the colours of the demo's
    ``error_*.ply``, one scale for all methods); with a two-sided evaluation, original frame ``k`` coloured by
    each method's reverse distance (frame ``k``'s vertices to the simplified surface: parts a method dropped).

    Args:
        results: method name → its :class:`~torchmeshmetric.evaluation.SequenceEvaluation`.
        original: the original frames.
        simplified: method name → its simplified frames.
        registered: original frame ``k-1`` registered onto frame ``k`` (its layer is left out when ``None``).
        unit: the unit of the distances.
        max_faces: see :func:`~torchmeshmetric.viz.error_mesh.error_mesh`.
    """
    first = next(iter(results.values()))
    best = first.best_pair_index()
    k = first.pairs[best].frame
    pairs = {name: r.pairs[best] for name, r in results.items()}
    layers = [error_mesh(f"original frame {k}", original[k], None, what="", unit=unit, max_faces=max_faces)]
    if registered is not None:
        layers.append(
            error_mesh(
                f"original frame {k - 1} registered onto {k}",
                registered,
                first.pairs[best].registration_residual,
                what=f"registration residual: distance to the surface of frame {k}",
                unit=unit,
                max_faces=max_faces,
            )
        )
    # one scale for all methods (no scale to share when every distance is 0: each layer then takes its default)
    vmax = max(float(p.distances["surface_k_minus_1"].max()) for p in pairs.values()) or None
    for name, pair in pairs.items():
        layers.append(
            error_mesh(
                f"{name}: simplified frame {k}",
                simplified[name][k],
                pair.distances["surface_k_minus_1"],
                what=f"surface distance to the registered frame {k - 1}",
                vmax=vmax,
                unit=unit,
                max_faces=max_faces,
            )
        )
    if all("surface_k" in p.reverse_distances for p in pairs.values()):
        rmax = max(float(p.reverse_distances["surface_k"].max()) for p in pairs.values()) or None
        for name, pair in pairs.items():
            layers.append(
                error_mesh(
                    f"original frame {k} against {name}",
                    original[k],
                    pair.reverse_distances["surface_k"],
                    what=f"reverse: distance of frame {k}'s vertices to {name}'s simplified surface",
                    vmax=rmax,
                    unit=unit,
                    max_faces=max_faces,
                )
            )
    return layers


def report_page(
    report: Mapping[str, Any],
    markdown: str,
    *,
    title: str,
    figures: Sequence[tuple[str, bytes]] = (),
    meshes: Sequence[ErrorMesh] = (),
    curves: bool = True,
) -> str:
    """The page of a written report: :func:`report_figures` of its JSON, ``figures``, ``meshes`` and its Markdown.

    Args:
        report: the JSON report.
        markdown: the report's Markdown (its tables).
        title: the page's title.
        figures: further ``(caption, PNG bytes)`` (e.g. the histograms of the best pair).
        meshes: the viewer's layers.
        curves: draw :func:`report_figures` (``False``: ``figures`` already hold them, e.g. the demo's
            ``frame_curves.png``).
    """
    curves = check_flag(curves, "curves")
    notes = [f"{report.get('tool', 'torchmeshmetric')} {report.get('version', '')}".strip()]
    if not meshes and not isinstance(report.get("frames"), list):  # a CTC report has no meshes to add (review R #11)
        notes.append("No meshes on this page: the report was written without them (the commands' `--html` adds them).")
    drawn = report_figures(report) if curves else []
    return html_page(title, markdown, figures=[*drawn, *figures], meshes=meshes, notes=notes)


#: The top-level keys by which a JSON report is recognised: a sequence report's ``"methods"``, a campaign's
#: ``"sequences"``, a CTC report's ``"frames"``.
REPORT_KEYS = ("methods", "sequences", "frames")
_NON_FINITE = ("nan", "inf", "-inf")  # how a report writes non-finite numbers (json_safe)


def _number(value: object, where: str) -> None:
    """A report's number: a JSON number, or a non-finite one as the report writes it."""
    if isinstance(value, bool) or not (isinstance(value, (int, float)) or value in _NON_FINITE):
        raise ValueError(f"{where}: expected a number (or 'nan', 'inf'), found {value!r}")


def _frame(row: object, where: str, what: str) -> None:
    """A pair's or a row's ``"frame"``: an integer (the curves' x axis)."""
    frame = row.get("frame") if isinstance(row, Mapping) else None
    if isinstance(frame, bool) or not isinstance(frame, int):
        raise ValueError(f"{where}: expected an object with an integer 'frame'{what}, found {row!r:.80}")


def _statistics(value: object, where: str) -> None:
    """A set's statistics as a report holds them: an object whose ``"rmse"`` is a number (the curves' values)."""
    if not isinstance(value, Mapping):
        raise ValueError(f"{where}: expected an object of statistics (with 'rmse'), found {value!r:.80}")
    _number(value.get("rmse"), f"{where} -> rmse")


def check_report(report: Mapping[str, Any]) -> None:
    """Check that a JSON report has the shape :func:`report_figures` and :func:`report_page` read.

    A sequence report: ``"methods"``, each with its ``"pairs"`` (the same frames in every method, each pair a
    ``"frame"`` and its sets' ``"rmse"``; with ``"flicker"`` the registration's residual too); a campaign's
    combined report: ``"sequences"``; a CTC report: ``"frames"``, each a ``"frame"`` and its figures.

    Raises:
        ValueError: naming the first key (as a path such as ``methods -> 'A' -> pairs[2] -> frame``) whose value
            does not fit, or the report's keys when it is none of these.
    """
    from torchmeshmetric.evaluation.results import FLICKER, SET_NAMES

    if not any(key in report for key in REPORT_KEYS):
        raise ValueError(
            f"expected a report with one of the keys {list(REPORT_KEYS)}, found the keys {list(report)[:8]}"
        )
    methods = report.get("methods")
    if methods is not None:
        if not isinstance(methods, Mapping) or not methods:
            raise ValueError(f"methods: expected a non-empty object of methods, found {methods!r:.80}")
        frames: list[object] | None = None
        for name, method in methods.items():
            at = f"methods -> {name!r}"
            if not isinstance(method, Mapping):
                raise ValueError(f"{at}: expected an object, found {method!r:.80}")
            pairs = method.get("pairs")
            if pairs is None:
                continue
            if not isinstance(pairs, list) or not pairs:
                raise ValueError(f"{at} -> pairs: expected a non-empty list, found {pairs!r:.80}")
            for i, pair in enumerate(pairs):
                _frame(pair, f"{at} -> pairs[{i}]", "")
                sets = [s for s in (*SET_NAMES, FLICKER) if s in pair]
                if not sets:
                    raise ValueError(f"{at} -> pairs[{i}]: no distance set (expected some of {list(SET_NAMES)})")
                for s in sets:
                    _statistics(pair[s], f"{at} -> pairs[{i}] -> {s}")  # a bare number crashed the curves
                if FLICKER in pair:
                    registration = pair.get("registration")
                    if not isinstance(registration, Mapping):
                        raise ValueError(
                            f"{at} -> pairs[{i}] -> registration: expected an object with the 'residual' of a "
                            f"measured flicker, found {registration!r:.80}"
                        )
                    _statistics(registration.get("residual"), f"{at} -> pairs[{i}] -> registration -> residual")
            these = [p["frame"] for p in pairs]
            if frames is not None and these != frames:
                raise ValueError(f"{at} -> pairs: frames {these}, the first method's {frames} (must match)")
            frames = these
    rows = report.get("frames")
    if rows is not None:
        if not isinstance(rows, list) or not rows:
            raise ValueError(f"frames: expected a non-empty list, found {rows!r:.80}")
        for i, row in enumerate(rows):
            _frame(row, f"frames[{i}]", " and its figures")  # a row without one crashed the page with 'frame'
            if len(row) < 2:
                raise ValueError(f"frames[{i}]: expected an object with a 'frame' and its figures, found {row!r:.80}")
            for key, value in row.items():
                _number(value, f"frames[{i}] -> {key}")


def report_figures(report: Mapping[str, Any]) -> list[tuple[str, bytes]]:
    """The figures a JSON report's data give, as ``(caption, PNG bytes)``.

    A sequence report (``evaluate``, ``compare``, ``demo``: ``"methods"`` with ``"pairs"``) gives the per-frame
    curves of every set's RMSE (``frame_curves.png``); a CTC report (``ctc``: ``"frames"``) the curve of every
    column over the frames; a campaign's combined report holds averages only (its sequences' reports have the curves).

    Args:
        report: the JSON report (as written, non-finite numbers as strings).

    Raises:
        ValueError: a report of another shape (:func:`check_report`).
    """
    from torchmeshmetric.viz.plots import _figure, frame_curves_figure, png_bytes

    check_report(report)
    figures = []
    methods = report.get("methods")
    if isinstance(methods, Mapping) and all(isinstance(m, Mapping) and "pairs" in m for m in methods.values()):
        pairs = {name: m["pairs"] for name, m in methods.items()}
        figures.append((CURVES_CAPTION, png_bytes(frame_curves_figure(pairs))))
    frames = report.get("frames")
    if isinstance(frames, list) and frames:
        from matplotlib.ticker import MaxNLocator  # matplotlib on use only (see _figure)

        columns = [c for c in frames[0] if c != "frame"]
        fig = _figure()(figsize=(5 * min(len(columns), 3), 3.6 * ((len(columns) + 2) // 3)), layout="constrained")
        axes = fig.subplots((len(columns) + 2) // 3, min(len(columns), 3), squeeze=False).ravel()
        for ax, column in zip(axes, columns, strict=False):
            ax.plot([f["frame"] for f in frames], [float(f.get(column, "nan")) for f in frames], marker="o")
            ax.set_title(plain_label(column), fontsize=10)
            ax.set_xlabel("frame")
            ax.xaxis.set_major_locator(MaxNLocator(integer=True))  # frames are integers (it drew 0.2, 0.4, ...)
            ax.set_ylabel("dB" if "psnr" in column.lower() or column.startswith(("Grid", "Ibsm")) else "")
        for ax in axes[len(columns) :]:
            ax.set_visible(False)
        fig.suptitle("per frame")
        figures.append(("per frame", png_bytes(fig)))
    return figures


_INLINE = (
    (re.compile(r"`([^`]+)`"), r"<code>\1</code>"),
    (re.compile(r"\*\*([^*]+)\*\*"), r"<strong>\1</strong>"),
)


#: A Markdown backslash escape (CommonMark: a backslash before ASCII punctuation stands for that character):
#: ``\*`` of a footnote mark, and every markup character of a name (:func:`~torchmeshmetric._format.markdown_cell`).
_ESCAPE = re.compile(r"\\([!-/:-@\[-`{-~])")
_HELD = re.compile("\ue000(\\d+)\ue001")  # a held escaped character (private-use marks around its index)


def _inline(text: str) -> str:
    r"""A line of Markdown as HTML: ``code``, **strong** and backslash escapes (``\*`` is a literal ``*``)."""
    held: list[str] = []

    def hold(match: re.Match[str]) -> str:
        held.append(match.group(1))
        return f"\ue000{len(held) - 1}\ue001"

    out = html.escape(_ESCAPE.sub(hold, text), quote=False)  # an escaped character starts no markup
    for pattern, repl in _INLINE:
        out = pattern.sub(repl, out)
    return _HELD.sub(lambda m: html.escape(held[int(m.group(1))], quote=False), out)


def _cells(line: str) -> list[str]:
    r"""A table row's cells: split at each ``|`` that is not escaped (``\|`` in a name, :func:`markdown_cell`)."""
    cells = re.split(r"(?<!\\)\|", line.strip().removeprefix("|").removesuffix("|"))
    return [c.strip().replace("\\|", "|") for c in cells]  # its other escapes are read by _inline


def markdown_html(text: str) -> str:
    r"""The Markdown the report writers produce (headings, pipe tables, lists, paragraphs) as HTML.

    Tables become ``<table class="sortable">`` (the page sorts them by a click on a header); a cell's text is
    kept as written (the report's printed digits).

    Example:
        >>> print(markdown_html("## T\n\n| a | b |\n|---|---|\n| 1 | **2** |\n"))
        <h2 id="t">T</h2>
        <table class="sortable"><thead><tr><th>a</th><th>b</th></tr></thead>
        <tbody><tr><td>1</td><td><strong>2</strong></td></tr></tbody></table>
    """
    lines = text.splitlines()
    out: list[str] = []
    paragraph: list[str] = []
    items: list[str] = []

    def flush() -> None:
        if paragraph:
            out.append("<p>" + _inline(" ".join(paragraph)) + "</p>")
            paragraph.clear()
        if items:
            out.append("<ul>" + "".join(f"<li>{_inline(i)}</li>" for i in items) + "</ul>")
            items.clear()

    i = 0
    while i < len(lines):
        line = lines[i]
        heading = re.match(r"^(#{1,6})\s+(.*)$", line)
        if heading:
            flush()
            level, title = len(heading.group(1)), heading.group(2).strip()
            slug = re.sub(r"[^a-z0-9]+", "-", title.lower()).strip("-")
            out.append(f'<h{level} id="{slug}">{_inline(title)}</h{level}>')
        elif line.startswith("|") and i + 1 < len(lines) and re.match(r"^\|[\s:|-]+\|?\s*$", lines[i + 1]):
            flush()
            head = "".join(f"<th>{_inline(c)}</th>" for c in _cells(line))
            rows = []
            i += 2
            while i < len(lines) and lines[i].startswith("|"):
                rows.append("<tr>" + "".join(f"<td>{_inline(c)}</td>" for c in _cells(lines[i])) + "</tr>")
                i += 1
            out.append(
                f'<table class="sortable"><thead><tr>{head}</tr></thead>\n<tbody>{"".join(rows)}</tbody></table>'
            )
            continue
        elif re.match(r"^\s*[-*]\s+", line):
            if paragraph:
                flush()
            items.append(re.sub(r"^\s*[-*]\s+", "", line))
        elif not line.strip():
            flush()
        else:
            if items:
                flush()
            paragraph.append(line.strip())
        i += 1
    flush()
    return "\n".join(out)


def _b64(array: np.ndarray) -> str:
    return base64.b64encode(np.ascontiguousarray(array).tobytes()).decode("ascii")


def _layer_json(layer: ErrorMesh) -> dict[str, Any]:
    wide = layer.verts.shape[0] > 65535
    return {
        "name": layer.name,
        "verts": _b64(layer.verts.astype("<f4")),
        "faces": _b64(layer.faces.astype("<u4" if wide else "<u2")),
        "index32": wide,
        "colors": _b64(layer.colors),
    }


def _gradient() -> str:
    stops = ", ".join(f"rgb({r:.0f},{g:.0f},{b:.0f})" for r, g, b in ERROR_COLOR_ANCHORS)
    return f"linear-gradient(to right, {stops})"


def _layer_item(i: int, layer: ErrorMesh) -> str:
    note = f" (shown decimated from {layer.decimated_from} faces)" if layer.decimated_from else ""
    if not layer.what:
        scale = '<span class="bar" style="background:rgb(190,190,190)"></span> reference'
    elif layer.vmax != layer.vmax:  # NaN: colours read from a file, whose scale the file does not hold
        scale = f'<span class="bar" style="background:{_gradient()}"></span> the scale of the run that wrote it'
    else:
        scale = (
            f'<span class="bar" style="background:{_gradient()}"></span> 0 … {layer.vmax:.3g} {html.escape(layer.unit)}'
        )

    return (
        f'<li><label><input type="checkbox" data-layer="{i}" checked> <b>{html.escape(layer.name)}</b></label>'
        f"<br><small>{html.escape(layer.what)}{html.escape(note)}</small><br><small>{scale}</small></li>"
    )


def html_page(
    title: str,
    markdown: str = "",
    *,
    figures: Sequence[tuple[str, bytes]] = (),
    meshes: Sequence[ErrorMesh] = (),
    notes: Sequence[str] = (),
) -> str:
    """The self-contained page: viewer (when ``meshes``), figures, then the report's Markdown with sortable tables.

    Args:
        title: the page's title.
        markdown: the report's Markdown (its tables become sortable HTML tables).
        figures: ``(caption, PNG bytes)`` shown as images.
        meshes: the viewer's layers (none: no viewer).
        notes: lines shown under the title (e.g. what is not on the page and why).

    Returns:
        The HTML text (UTF-8, no external resource).

    Example:
        >>> table = chr(10).join(["| a | b |", "|---|---|", "| 1 | 2 |"])
        >>> page = html_page("Demo <1>", table, notes=["no meshes: none given"])
        >>> "<h1>Demo &lt;1&gt;</h1>" in page, 'id="viewer"' in page, page.count("<table")
        (True, False, 1)
    """
    parts = [f"<h1>{html.escape(title)}</h1>"]
    parts += [f'<p class="note">{_inline(n)}</p>' for n in notes]
    if meshes:
        items = "".join(_layer_item(i, layer) for i, layer in enumerate(meshes))
        # No "<" in the block: "</script" would end it, and "<!--" then "<script" would make the parser run past
        # its end (HTML's double-escaped script state), swallowing the page. JSON reads \u003c as "<".
        data = json.dumps([_layer_json(layer) for layer in meshes]).replace("<", "\\u003c")
        parts.append(
            '<section id="viewer"><h2>Error-coloured meshes</h2><div class="viewer">'
            '<canvas id="tmm-canvas" width="960" height="560"></canvas>'
            f'<ul class="layers">{items}</ul></div>'
            "<p><small>Drag to turn, wheel to zoom, double-click to reset; tick a mesh to show it. Shown meshes "
            "stand side by side, in the order of the list.</small></p>"
            f'<script type="application/json" id="tmm-meshes">{data}</script></section>'
        )
    if figures:
        parts.append('<section id="figures"><h2>Figures</h2>')
        for caption, png in figures:
            src = "data:image/png;base64," + base64.b64encode(png).decode("ascii")
            parts.append(f'<figure><img alt="{html.escape(caption)}" src="{src}"><figcaption>{html.escape(caption)}'
                         "</figcaption></figure>")  # fmt: skip
        parts.append("</section>")
    if markdown:
        parts.append(f'<section id="report">{markdown_html(markdown)}</section>')
    body = "\n".join(parts)
    here = Path(__file__).parent
    script = (here / "report_page.js").read_text(encoding="utf-8")
    style = (here / "report_page.css").read_text(encoding="utf-8")
    return (
        '<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8">'
        '<link rel="icon" href="data:,">'  # no favicon request, even from file://
        f"<title>{html.escape(title)}</title><style>{style}</style></head>\n<body>\n{body}\n"
        f"<script>{script}</script>\n</body></html>\n"
    )


def write_html(path: str | os.PathLike[str], page: str, *, overwrite: bool = False) -> Path:
    """Write an :func:`html_page` atomically.

    Args:
        path: destination ``.html`` file.
        page: the page's text (:func:`html_page`), written as UTF-8.
        overwrite: replace an existing file.

    Returns:
        The path written.

    Raises:
        FileExistsError: ``path`` exists and ``overwrite`` is ``False``.
        TypeError: ``overwrite`` is not a bool.

    Example:
        >>> import os, tempfile
        >>> with tempfile.TemporaryDirectory() as folder:
        ...     text = write_html(os.path.join(folder, "report.html"), html_page("Demo", "## Tables")).read_text()
        >>> text.startswith("<!DOCTYPE html>"), "<h1>Demo</h1>" in text
        (True, True)
    """
    overwrite = check_flag(overwrite, "overwrite")
    return atomic_write(path, page, overwrite=overwrite)
