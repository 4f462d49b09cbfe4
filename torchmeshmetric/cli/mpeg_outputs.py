"""The files ``torchmeshmetric mpeg`` writes beside its figures, as mmetric's ``compare`` writes them.

``--output-model-ref/--output-model-dis`` (mmetric's ``--outputModelA/B``), as PLY or OBJ: in pcc mode the two
point clouds compared (the grid samples, or the mesh-mode subdivision of the reordered mesh); in ibsm mode the two
meshes after mmetric's oriented reordering; in equ and eqTFAN modes the sorted positions of two point clouds, and
in these modes and topo mode for meshes the empty models mmetric writes there. ``--output-csv`` (``--outputCsv``):
one row appended per run, the header first in a new or empty file. The files are checked before any computation
(never an input, distinct, a CSV with this mode's header) and written as one set: the models appear once the CSV
row is appended (never over an existing file without ``--overwrite``); the CSV is only ever appended to.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import time
from collections.abc import Callable, Iterable
from functools import partial
from pathlib import Path
from typing import Any, BinaryIO

from torchmeshmetric._atomic import atomic_write_with
from torchmeshmetric.cli.options import path_argument

__all__ = [
    "add_output_options",
    "check_outputs",
    "cloud_blocks",
    "csv_header",
    "load_pair",
    "run_ibsm",
    "write_comparison_models",
    "write_models",
    "write_pcc_outputs",
]


def add_output_options(p: Any) -> None:
    """The ``mpeg`` command's output-file options."""
    p.add_argument(
        "--output-csv",
        type=path_argument,
        default=None,
        metavar="FILE",
        help="pcc/ibsm/pcqm modes: append mmetric's --outputCsv row (header first in a new or empty file)",
    )
    p.add_argument(
        "--output-model-ref",
        type=path_argument,
        default=None,
        metavar="FILE",
        help="REF's model as mm --outputModelA writes it (.ply/.obj): pcc mode its sampled cloud; ibsm mode REF "
        "reordered; equ/eqTFAN modes a point cloud's sorted points (meshes, and topo mode: mm's empty model)",
    )
    p.add_argument(
        "--output-model-dis", type=path_argument, default=None, metavar="FILE", help="the same for DIS (--outputModelB)"
    )
    p.add_argument("--overwrite", action="store_true", help="replace existing --output-model-* files")
    p.add_argument(
        "--ibsm-resolution", type=int, default=None, metavar="N", help="ibsm mode: buffer side, 1..32768 (2048)"
    )
    p.add_argument("--ibsm-cameras", type=int, default=None, metavar="N", help="ibsm mode: camera count (16)")


def _inputs(args: argparse.Namespace) -> list[tuple[str, Any]]:
    """Every file the ``mpeg`` command reads: the meshes, their textures (given or from the MTL) and the maps."""
    from torchmeshmetric.mpeg.comparison.csv_rows import mmetric_texture_url

    files: list[tuple[str, Any]] = [("REF", args.ref), ("DIS", args.dis)]
    for name, mesh, texture in (("REF", args.ref, args.ref_texture), ("DIS", args.dis, args.dis_texture)):
        option = f"--{name.lower()}-texture" if texture else f"{name}'s texture"
        with contextlib.suppress(OSError, ValueError):  # an unreadable mesh is reported by its reader
            files.append((option, mmetric_texture_url(mesh, texture) or None))
    return [*files, ("--face-map", args.face_map), ("--vertex-map", args.vertex_map)]


def check_outputs(args: argparse.Namespace) -> None:
    """Refuse, before any computation, output files that cannot be written (mode checks: cli/mpeg.py, _SCOPES).

    The models and the CSV are the output set of :func:`torchmeshmetric.cli._outputs.check_writable` (never an input,
    distinct, writable), and a CSV that starts with another header is refused here, before the comparison.
    """
    from torchmeshmetric.cli._outputs import CLIError, check_appended_csv, check_writable

    named = [(o, Path(m)) for o, m in (("--output-model-ref", args.output_model_ref),
                                         ("--output-model-dis", args.output_model_dis)) if m is not None]  # fmt: skip
    # an --output-csv of a mode that writes none is refused with the other options of another mode (cli/mpeg.py)
    for option, m in named:
        if m.suffix.lower() not in (".ply", ".obj"):  # mmetric writes by the name's last three letters, no other
            raise CLIError(f"{option}: {str(m)!r} must end with .ply or .obj")
    csv = [] if args.output_csv is None else [("--output-csv", Path(args.output_csv))]
    if not named and not csv:
        return
    check_writable(
        [m for _, m in named], args.overwrite, inputs=_inputs(args), what=[o for o, _ in named], appended=csv
    )
    if csv:
        check_appended_csv(csv[0][1], csv_header(args.mode))


def csv_header(mode: str) -> str:
    """The ``--output-csv`` header of a mode that writes one (pcc, ibsm, pcqm)."""
    from torchmeshmetric.mpeg.comparison import csv_rows

    return {"pcc": csv_rows.PCC_CSV_HEADER, "ibsm": csv_rows.IBSM_CSV_HEADER, "pcqm": csv_rows.PCQM_CSV_HEADER}[mode]


Blocks = Iterable[bytes]
"""A file's UTF-8 text in blocks (``model_files``' ``*_blocks``), formatted as the file is written."""


def _put(blocks: Blocks, fh: BinaryIO) -> None:
    fh.writelines(blocks)


def _write(args: argparse.Namespace, files: tuple[Blocks, Blocks], header: str, row: str) -> None:
    """The models and the CSV row as one set: the models appear only once the row is appended."""
    from torchmeshmetric.cli._outputs import output_set
    from torchmeshmetric.mpeg.comparison.csv_rows import append_csv_row

    with output_set("the output models and CSV row"):
        for path, blocks in zip((args.output_model_ref, args.output_model_dis), files, strict=True):
            if path is not None:  # block by block: a model of millions of points never sits in memory as one text
                atomic_write_with(path, partial(_put, blocks), overwrite=args.overwrite)
        if args.output_csv is not None:
            append_csv_row(args.output_csv, header, [row])  # last: a failure before it keeps no model


def write_comparison_models(args: argparse.Namespace, models: tuple[Any, Any] | None) -> None:
    """The equ / eqTFAN / topo modes' output models, as mmetric writes them.

    Args:
        args: the command's arguments.
        models: the two :class:`~torchmeshmetric.mpeg.comparison.equality.EqualityModel` when mmetric's point-cloud
            branch ran (neither has a triangle): their positions, sorted in mmetric's order, are the files; ``None``
            otherwise (meshes, topo mode), where mmetric writes the models it left empty.
    """
    import numpy as np
    import torch

    from torchmeshmetric.mpeg.comparison.point_order import mmetric_point_order
    from torchmeshmetric.mpeg.core.model_files import empty_model_text, obj_header, point_cloud_blocks
    from torchmeshmetric.mpeg.core.point_cloud import PointCloud

    files: list[Blocks] = []
    for k, (path, name) in enumerate(((args.output_model_ref, args.ref), (args.output_model_dis, args.dis))):
        if path is None:
            files.append(())
        elif models is None:
            files.append([empty_model_text(Path(path).suffix, obj_header(name)).encode("utf-8")])
        else:  # the positions only, in mmetric's sorted order
            positions = models[k].positions
            cloud = PointCloud(torch.from_numpy(np.ascontiguousarray(positions[mmetric_point_order(positions)])))
            files.append(point_cloud_blocks(cloud, Path(path).suffix, obj_header(name)))
    write_models(args, (files[0], files[1]))


def write_models(args: argparse.Namespace, files: tuple[Blocks, Blocks], row: str = "") -> None:
    """The two model files (empty: a file not asked for) and the mode's ``--output-csv`` row, as one set."""
    _write(args, files, csv_header(args.mode) if args.output_csv is not None else "", row)


def cloud_blocks(args: argparse.Namespace, ref: Any, dis: Any) -> tuple[Blocks, Blocks]:
    """The two clouds compared, as the files ``--output-model-ref/dis`` name (PLY or OBJ), in blocks.

    The OBJ starts with the input's ``mtllib`` lines, as ``mm compare`` keeps them, except in grid mode, whose
    clouds are ``mm sample``'s files: it keeps no header (an empty first line). Empty for a file not asked for.
    """
    from torchmeshmetric.mpeg.core.model_files import obj_header, point_cloud_blocks

    grid = args.mode == "pcc" and args.sampling == "grid"
    files: list[Blocks] = []
    for path, cloud, name in ((args.output_model_ref, ref, args.ref), (args.output_model_dis, dis, args.dis)):
        header = "" if grid or path is None else obj_header(name)
        files.append(() if path is None else point_cloud_blocks(cloud, Path(path).suffix, header))
    return files[0], files[1]


def write_pcc_outputs(args: argparse.Namespace, clouds: Any, result: Any) -> None:
    """The pcc mode's output models and CSV row."""
    from torchmeshmetric.mpeg.comparison.csv_rows import PCC_CSV_HEADER, mmetric_texture_url, pcc_csv_row

    ref, dis = cloud_blocks(args, clouds.ref, clouds.dis)
    row = ""
    if args.output_csv is not None:
        given = args.peak if args.sampling == "mesh" else result.peak  # the grid chain passes the peak to mm
        row = pcc_csv_row(
            result,
            model_a=args.ref,
            model_b=args.dis,
            map_a=mmetric_texture_url(args.ref, args.ref_texture),
            map_b=mmetric_texture_url(args.dis, args.dis_texture),
            resolution=0.0 if given is None else given,
        )
    _write(args, (ref, dis), PCC_CSV_HEADER, row)


def _ibsm_lines(r: Any) -> str:
    """The figures as mmetric prints them (``R   PSNR = ...``)."""
    names = ("R  ", "G  ", "B  ", "RGB", "Y  ", "U  ", "V  ", "YUV")
    values = (*r.rgb_psnr, *r.yuv_psnr)
    lines = [f"{n} PSNR = {v:.9g}" for n, v in zip(names, values, strict=True)]
    return "\n".join([*lines, f"GEO PSNR = {r.geo_psnr:.9g}"])


def load_pair(args: argparse.Namespace, load: Callable[[str, str, str | None], Any] | None = None) -> tuple[Any, Any]:
    """REF and DIS, a library error retold about the argument that gave the file (``REF``, ``--dis-texture``).

    Args:
        args: the command's arguments (``ref``, ``dis``, ``ref_texture``, ``dis_texture``).
        load: ``(side, path, texture) -> mesh`` (default: the textured mesh, ``load_textured_mesh``).
    """
    from torchmeshmetric.cli.options import as_option_error
    from torchmeshmetric.mpeg.core.textured_mesh import load_textured_mesh

    meshes = []
    for side, path, texture in (("REF", args.ref, args.ref_texture), ("DIS", args.dis, args.dis_texture)):
        options = {"path": side, "mesh": f"{side} {path!r}"}
        options["texture"] = f"--{side.lower()}-texture" if texture else f"{side}'s texture"
        try:
            meshes.append(load_textured_mesh(path, texture) if load is None else load(side, path, texture))
        except ValueError as exc:
            raise as_option_error(exc, options) from exc
    return meshes[0], meshes[1]


def run_ibsm(args: argparse.Namespace) -> int:
    """``--mode ibsm``: mmetric's IBSM figures of DIS against REF, and its output files."""
    from dataclasses import asdict

    from torchmeshmetric._format import json_safe
    from torchmeshmetric.cli.options import as_option_error
    from torchmeshmetric.mpeg.comparison.csv_rows import IBSM_CSV_HEADER, ibsm_csv_row, mmetric_texture_url
    from torchmeshmetric.mpeg.comparison.ibsm import ibsm
    from torchmeshmetric.mpeg.core.model_files import obj_header, textured_mesh_blocks
    from torchmeshmetric.mpeg.core.reindex import oriented_reindex

    check_outputs(args)
    ref, dis = load_pair(args)
    start = time.process_time()
    try:
        result = ibsm(ref, dis, resolution=args.ibsm_resolution, cameras=args.ibsm_cameras)
    except ValueError as exc:
        raise as_option_error(exc, {"resolution": "--ibsm-resolution", "cameras": "--ibsm-cameras"}) from exc
    seconds = time.process_time() - start
    files: list[Blocks] = []
    for path, mesh, name in ((args.output_model_ref, ref, args.ref), (args.output_model_dis, dis, args.dis)):
        header = "" if path is None else obj_header(name)
        files.append(() if path is None else textured_mesh_blocks(oriented_reindex(mesh), Path(path).suffix, header))
    row = ""
    if args.output_csv is not None:
        row = ibsm_csv_row(
            result,
            model_a=args.ref,
            model_b=args.dis,
            map_a=mmetric_texture_url(args.ref, args.ref_texture),
            map_b=mmetric_texture_url(args.dis, args.dis_texture),
            cameras=args.ibsm_cameras,
            resolution=args.ibsm_resolution,
            seconds=seconds,
        )
    _write(args, (files[0], files[1]), IBSM_CSV_HEADER, row)  # the files first, as every mode: see _run_equality
    print(json.dumps(json_safe(asdict(result)), indent=1) if args.json else _ibsm_lines(result))
    return 0
