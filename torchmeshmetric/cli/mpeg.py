"""The ``torchmeshmetric mpeg REF DIS`` command: mmetric's figures for one mesh pair (table or JSON)."""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path
from typing import Any

from torchmeshmetric._format import format_number, json_safe
from torchmeshmetric.cli._scope import Scope, check_scope, fill_defaults
from torchmeshmetric.cli.options import as_option_error, corner, path_argument

__all__ = ["add_mpeg_command"]


def _fmt(x: Any) -> str:
    return format_number(x, ".9g")  # as mmetric prints its figures (9 significant digits)


def _table(d: dict[str, Any]) -> str:
    rows = [("", "symmetric", "ref->dis", "dis->ref")]
    from torchmeshmetric.mpeg.comparison.sequence import FRAME_KEYS

    keys = [k for k in (*FRAME_KEYS, "y_mse", "cb_mse", "cr_mse") if k in d]
    for k in keys:
        rows.append((k, _fmt(d[k]), _fmt(d["ref_to_dis"][k]), _fmt(d["dis_to_ref"][k])))
    w = [max(len(r[i]) for r in rows) for i in range(4)]
    lines = ["  ".join(c.ljust(w[i]) if i == 0 else c.rjust(w[i]) for i, c in enumerate(r)) for r in rows]
    lines.append(f"peak {_fmt(d['peak'])}  points ref {d['points_ref']}  dis {d['points_dis']}  ({d['sampling']})")
    return "\n".join(lines)


def float32(text: str) -> float:
    """An option's decimal text as mm reads it: the float32 nearest it (``strtof``), as a float holding that value.

    ``float`` then float32 rounds twice and picks the wrong neighbour for a decimal just past a float32 midpoint (mm
    prints ``Epsilon = 0.100000016`` for ``0.100000012665987014770507812501``, float64 first gave 0.100000009; review
    S). Beyond float32's range, the float itself (the comparison refuses it, quoting it).
    """
    import numpy as np

    from torchmeshmetric._float32_text import float32_from_text

    x = float32_from_text(text)
    return float(x) if np.isfinite(x) or not np.isfinite(float(text)) else float(text)


def _run_equality(args: argparse.Namespace) -> int:
    """``--mode equ``: mmetric's lines (texture maps, verdict, differences) or JSON; exit status 0 when equal."""
    from dataclasses import asdict

    from torchmeshmetric.cli.mpeg_outputs import load_pair, write_comparison_models
    from torchmeshmetric.mpeg.comparison.equality import load_equality_model, mesh_equality

    ref, dis = load_pair(args, lambda side, path, texture: load_equality_model(path, texture))
    try:
        result = mesh_equality(ref, dis, unoriented=args.unoriented, epsilon=args.epsilon)
    except ValueError as exc:
        raise as_option_error(exc, {"epsilon": "--epsilon"}) from exc
    # The files before the figures, in every mode: a closed stdout (`... | head -1`) ends the command at its print,
    # and the files asked for are written by then (mm, which prints first, dies of SIGPIPE without them).
    write_comparison_models(args, (ref, dis) if result.points else None)
    if args.json:
        print(json.dumps(asdict(result), indent=1))
    else:
        print(result.report(early_return=not args.all_differences))
    return 0 if result.equal else 1


_PCQM_OPTIONS = {
    "radius_curvature": "--radius-curvature",
    "knn": "--threshold-knn-search",
    "radius_factor": "--radius-factor",
}


def _run_pcqm(args: argparse.Namespace) -> int:
    """``--mode pcqm``: mm compare --mode pcqm's printed figures (or JSON)."""
    from torchmeshmetric.cli.mpeg_outputs import cloud_blocks, load_pair, write_models
    from torchmeshmetric.mpeg.comparison.csv_rows import mmetric_texture_url, pcqm_csv_row
    from torchmeshmetric.mpeg.comparison.pcqm import mpeg_pcqm
    from torchmeshmetric.mpeg.sampling.model_cloud import load_model_cloud

    ref, dis = load_pair(args, lambda side, path, texture: load_model_cloud(path, texture, name=f"{side} {path!r}"))
    try:
        result = mpeg_pcqm(
            ref,
            dis,
            radius_curvature=args.radius_curvature,
            knn=args.threshold_knn_search,
            radius_factor=args.radius_factor,
        )
    except ValueError as exc:
        raise as_option_error(exc, _PCQM_OPTIONS) from exc
    row = ""
    if args.output_csv is not None:
        row = pcqm_csv_row(
            result,
            model_a=args.ref,
            model_b=args.dis,
            map_a=mmetric_texture_url(args.ref, args.ref_texture),
            map_b=mmetric_texture_url(args.dis, args.dis_texture),
            radius_curvature=args.radius_curvature,
            knn=args.threshold_knn_search,
            radius_factor=args.radius_factor,
        )
    write_models(args, cloud_blocks(args, ref, dis), row)  # the files first: see _run_equality
    print(json.dumps(json_safe(result.to_dict()), indent=1) if args.json else result.report())
    return 0


def _run_topology(args: argparse.Namespace) -> int:
    """``--mode topo``: mmetric's topology verdict in its words (or JSON); exit status 0 when matching, 1 otherwise."""
    from dataclasses import asdict

    from torchmeshmetric.cli._outputs import CLIError
    from torchmeshmetric.cli.mpeg_outputs import load_pair, write_comparison_models
    from torchmeshmetric.mpeg.comparison.topology import topology_equivalence

    if args.face_map is None or args.vertex_map is None:
        raise CLIError(
            "--mode topo needs --face-map FILE and --vertex-map FILE (mmetric's --faceMapFile/--vertexMapFile)"
        )
    ref, dis = load_pair(args)
    result = topology_equivalence(ref, dis, args.face_map, args.vertex_map)
    write_comparison_models(args, None)  # the files first: see _run_equality
    print(json.dumps(asdict(result), indent=1) if args.json else result.report())
    return 0 if result.matching else 1


def _run_tfan(args: argparse.Namespace) -> int:
    """``--mode eqTFAN``: mmetric's lines (maps, connectivity, verdict, differences) or JSON; exit 0 when equal."""
    from dataclasses import asdict

    from torchmeshmetric.cli.mpeg_outputs import load_pair, write_comparison_models
    from torchmeshmetric.mpeg.comparison.equality import load_equality_model
    from torchmeshmetric.mpeg.comparison.tfan_comparison import tfan_equality

    ref, dis = load_pair(args, lambda side, path, texture: load_equality_model(path, texture))
    try:
        result = tfan_equality(ref, dis, early_return=not args.all_differences, epsilon=args.epsilon)
    except ValueError as exc:
        raise as_option_error(exc, {"epsilon": "--epsilon"}) from exc
    report = result.report()
    write_comparison_models(args, (ref, dis) if result.points else None)  # the files first: see _run_equality
    print(json.dumps({**asdict(result), "report": report}, indent=1) if args.json else report)
    return 0 if result.equal else 1


def _pcc_model(side: str, path: str, texture: str | None) -> Any:
    """A pcc model: a PLY without faces as the point cloud it is (mm compare --mode pcc takes it), else the mesh.

    A mesh PLY is read twice this way (the point reader stops at its declared faces, then the mesh reader); the
    comparison's sampling and searches dwarf that.
    """
    from torchmeshmetric.data.ply import read_ply_points
    from torchmeshmetric.mpeg.core.textured_mesh import load_textured_mesh
    from torchmeshmetric.mpeg.sampling.model_cloud import load_model_cloud

    if Path(path).suffix.lower() == ".ply" and read_ply_points(Path(path)) is not None:
        return load_model_cloud(path, texture, name=f"{side} {path!r}")
    return load_textured_mesh(path, texture)


_MAX_GRID_SIZE = 1 << 20  # ctc --grid-size's and the campaign manifest's bound
_PCC = frozenset({"pcc-grid", "pcc-mesh"})
_GRID = frozenset({"pcc-grid"})
_MESH = frozenset({"pcc-mesh"})
_EQU = frozenset({"equ", "eqTFAN"})
_PCQM = frozenset({"pcqm"})
_IBSM = frozenset({"ibsm"})
_GRID_TEXT = "--mode pcc --sampling grid"

# Where each of the mode-specific options acts (review X F3: elsewhere they were dropped without a word). A run's
# context is its mode, pcc split by its sampling; an option given in another context is refused before any work.
_SCOPES = {
    "sampling": Scope("--sampling", _PCC, "--mode pcc", default="grid"),
    "grid_size": Scope(
        "--grid-size", _GRID, _GRID_TEXT, "mesh mode samples by mm compare's subdivision, without a grid", 1024, _MESH
    ),
    "box": Scope(
        "--box",
        _GRID,
        _GRID_TEXT,
        "mesh mode's peak is the reference cloud's box diagonal: give --peak to fix the peak",
        instead_in=_MESH,
    ),
    "nearest": Scope(
        "--nearest", _GRID, _GRID_TEXT, "mesh mode filters textures as mm compare --mode pcc does", False, _MESH
    ),
    "peak": Scope("--peak", _PCC, "--mode pcc", "the other modes have no PSNR peak (mm compare --resolution)"),
    "face_map": Scope("--face-map", frozenset({"topo"}), "--mode topo"),
    "vertex_map": Scope("--vertex-map", frozenset({"topo"}), "--mode topo"),
    "radius_curvature": Scope("--radius-curvature", _PCQM, "--mode pcqm", default=0.001),
    "threshold_knn_search": Scope("--threshold-knn-search", _PCQM, "--mode pcqm", default=20),
    "radius_factor": Scope("--radius-factor", _PCQM, "--mode pcqm", default=2.0),
    "unoriented": Scope(
        "--unoriented",
        frozenset({"equ"}),
        "--mode equ",
        "eqTFAN compares oriented triangle fans (mm v1.1.7 ignores --eqTFAN_unoriented)",
        False,
        frozenset({"eqTFAN"}),
    ),
    "epsilon": Scope("--epsilon", _EQU, "--mode equ and eqTFAN", default=0.0),
    "all_differences": Scope("--all-differences", _EQU, "--mode equ and eqTFAN", default=False),
    "ibsm_resolution": Scope("--ibsm-resolution", _IBSM, "--mode ibsm", default=2048),
    "ibsm_cameras": Scope("--ibsm-cameras", _IBSM, "--mode ibsm", default=16),
    "output_csv": Scope(
        "--output-csv",
        _PCC | _PCQM | _IBSM,
        "--mode pcc, ibsm and pcqm",
        "mmetric v1.1.7 writes the text TODO where a verdict would be; the exit status and --json give it",
        instead_in=frozenset({"equ", "eqTFAN", "topo"}),
    ),
}


def finite_number(text: str) -> float:
    """An option's number, refused when parsed if it is not finite (``1e400`` was reported as ``found inf``)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, found {text!r}") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"expected a finite number, found {text!r}")
    return value


def _box_corner(text: str, option: str) -> list[float]:
    """A ``--box`` corner, within float32's range (mmetric reads the box as float32; -1e39 became -inf)."""
    import numpy as np

    from torchmeshmetric.cli._outputs import CLIError

    values = corner(text, option)
    if any(abs(v) > float(np.finfo(np.float32).max) for v in values):
        raise CLIError(f"{option}: {text!r} is beyond float32's range (mmetric reads the box as float32)")
    return values


def _check_options(args: argparse.Namespace) -> None:
    """Every option, before any file is read: each given in a mode it acts in, in its range; then the defaults."""
    from torchmeshmetric.cli._outputs import CLIError

    if args.mode == "pcc":
        sampling = args.sampling or "grid"
        context, text = f"pcc-{sampling}", f"--mode pcc --sampling {sampling}"
    else:
        context, text = args.mode, f"--mode {args.mode}"
    check_scope(args, _SCOPES, context, text)
    fill_defaults(args, _SCOPES)
    if args.mode == "pcc" and args.sampling == "grid" and not 2 <= args.grid_size <= _MAX_GRID_SIZE:
        # ctc's bound; a larger grid wrapped int64 ray counts (numpy's "invalid value encountered in cast")
        raise CLIError(f"--grid-size: expected an integer in 2..{_MAX_GRID_SIZE}, found {args.grid_size}")
    if args.box is not None:
        args.box = (_box_corner(args.box[0], "--box MIN"), _box_corner(args.box[1], "--box MAX"))


def _run(args: argparse.Namespace) -> int:
    from torchmeshmetric.cli.mpeg_outputs import check_outputs, load_pair, run_ibsm, write_pcc_outputs
    from torchmeshmetric.mpeg.comparison.mpeg_metrics import mpeg_point_clouds
    from torchmeshmetric.mpeg.comparison.pcc import mpeg_compare

    _check_options(args)
    check_outputs(args)
    if args.mode == "equ":
        return _run_equality(args)
    if args.mode == "topo":
        return _run_topology(args)
    if args.mode == "eqTFAN":
        return _run_tfan(args)
    if args.mode == "ibsm":
        return run_ibsm(args)
    if args.mode == "pcqm":
        return _run_pcqm(args)

    box = args.box  # parsed by _check_options
    ref, dis = load_pair(args, _pcc_model)
    try:
        clouds = mpeg_point_clouds(
            ref,
            dis,
            sampling=args.sampling,
            grid_size=args.grid_size,
            box=box,
            peak=args.peak,
            bilinear=not args.nearest,
            names=(f"REF {args.ref!r}", f"DIS {args.dis!r}"),
        )
    except ValueError as exc:
        raise as_option_error(exc, {"grid_size": "--grid-size", "peak": "--peak", "box": "--box"}) from exc
    result = mpeg_compare(clouds.ref, clouds.dis, peak=clouds.peak)
    write_pcc_outputs(args, clouds, result)
    d = result.to_dict()
    d["sampling"] = "grid" if args.sampling == "grid" else "mesh"
    if args.sampling == "grid":
        d["grid_size"] = args.grid_size
    if args.json:
        print(json.dumps(json_safe(d), indent=1))
    else:
        print(_table(d))
    return 0


def add_mpeg_command(sub: Any) -> None:
    """Add the ``mpeg`` subcommand to the CLI's subparsers."""
    p = sub.add_parser(
        "mpeg",
        help="MPEG D1/D2 (and colour) PSNR of one mesh pair, as mmetric computes them",
        description="MPEG's geometry (D1 point-to-point, D2 point-to-plane: MSE, PSNR, Hausdorff) and colour (Y, Cb, "
        "Cr PSNR) figures of DIS against REF, equal to mmetric v1.1.7's. --sampling grid (default) reproduces mm "
        "sample --mode grid --gridSize N --useNormal --bilinear --minPos/--maxPos BOX on both meshes, then mm compare "
        "--mode pcc --resolution PEAK; by default BOX = the reference's bounding box and PEAK = its diagonal (as "
        "mmetric's figures in docs/mpeg.md, 'Measured agreement with mmetric', were taken), no fixed-point "
        "rounding. That is not the V-DMC test model's recipe: "
        "its metric step dequantises both frames with --useFixedPoint, samples with --useFixedPoint over the "
        "*sequence's* box and passes the sequence box's longest side as --resolution -- use 'torchmeshmetric ctc' for "
        "it. --sampling mesh is mm compare --mode pcc on the meshes. Textures come from the OBJ's MTL (map_Kd) "
        "unless given. --mode equ is mm compare --mode equ instead: are the two meshes the same triangles in any order "
        "(corners compared by position, and UV, colour and normal where both have them); it prints mm's lines: the "
        "texture maps' comparison, the verdict and, with --all-differences, the position, UV, colour and normal "
        "differences (exit status 0 when equal, 1 otherwise); two models without faces (point clouds: OBJ 'v' "
        "lines, a PLY such as mm sample writes) are compared as mm compares them, their sorted points equal or within "
        "--epsilon. --mode eqTFAN is mm compare --mode eqTFAN: is DIS "
        "REF with its vertices and texture coordinates renamed (triangle fans); it prints mm's lines: the same "
        "texture maps' lines, the count lines, both connectivity passes, the verdict and the differences (exit status "
        "0 when equal, 1 otherwise; point clouds as in equ mode). --mode topo is mm compare --mode topo: is DIS the "
        "connectivity of REF under --face-map and --vertex-map (exit status 0 when matching, 1 otherwise).",
    )
    p.add_argument(
        "ref", type=path_argument, metavar="REF", help="reference mesh (OBJ/PLY; OBJ with MTL + texture for colour)"
    )
    p.add_argument("dis", type=path_argument, metavar="DIS", help="distorted mesh")
    p.add_argument(
        "--sampling", choices=("grid", "mesh"), default=None, help="grid (mm sample --mode grid, default) or mesh"
    )
    p.add_argument("--grid-size", type=int, default=None, metavar="N", help="grid steps (default 1024)")
    p.add_argument(
        "--box",
        nargs=2,
        metavar=("MIN", "MAX"),
        default=None,
        help='sampling box corners, e.g. --box "-1 -1 -1" "1 1 1" (default: the reference\'s bounding box); it must '
        "contain the reference",
    )
    p.add_argument(
        "--peak",
        type=finite_number,
        default=None,
        help="PSNR peak, mm compare --resolution (default: the box diagonal; the V-DMC test model passes the "
        "sequence box's longest side)",
    )
    p.add_argument(
        "--ref-texture", type=path_argument, default=None, metavar="IMG", help="texture of REF (overrides its MTL)"
    )
    p.add_argument(
        "--dis-texture", type=path_argument, default=None, metavar="IMG", help="texture of DIS (overrides its MTL)"
    )
    p.add_argument("--nearest", action="store_true", help="nearest texture filtering in grid mode (default bilinear)")
    p.add_argument("--json", action="store_true", help='print one JSON object (non-finite values as "inf")')
    p.add_argument(
        "--mode",
        choices=("pcc", "equ", "eqTFAN", "topo", "ibsm", "pcqm"),
        default="pcc",
        help="pcc: the D1/D2/colour figures (default); equ: mm compare --mode equ, the equality verdict; eqTFAN: mm "
        "compare --mode eqTFAN, the triangle-fan connectivity verdict; topo: mm "
        "compare --mode topo, the topology verdict; ibsm: mm compare --mode ibsm, the image-based figures; pcqm: mm "
        "compare --mode pcqm, the PCQM score and its PSNR (meshes sampled as mm compare does; point-cloud PLY files "
        "used as they are)",
    )
    p.add_argument(
        "--face-map",
        type=path_argument,
        default=None,
        metavar="FILE",
        help="topo mode: text file of 'b a' lines, face b of DIS is face a of REF (mm --faceMapFile)",
    )
    p.add_argument(
        "--vertex-map",
        type=path_argument,
        default=None,
        metavar="FILE",
        help="topo mode: text file of 'b a' lines, vertex b of DIS is vertex a of REF (mm --vertexMapFile)",
    )
    p.add_argument(
        "--radius-curvature",
        type=finite_number,
        default=None,
        metavar="R",
        help="pcqm mode: curvature neighbourhood radius relative to REF's box (mm --radiusCurvature, default 0.001)",
    )
    p.add_argument(
        "--threshold-knn-search",
        type=int,
        default=None,
        metavar="K",
        help="pcqm mode: neighbours of the projection quadric (mm --thresholdKnnSearch, default 20)",
    )
    p.add_argument(
        "--radius-factor",
        type=finite_number,
        default=None,
        metavar="F",
        help="pcqm mode: pooling radius over the curvature radius (mm --radiusFactor, default 2.0)",
    )
    p.add_argument(
        "--unoriented",
        action="store_true",
        help="equ mode: a triangle also equals its reversed copy (mm --unoriented; refused in eqTFAN mode, whose "
        "fans are oriented: mm v1.1.7 ignores --eqTFAN_unoriented)",
    )
    p.add_argument(
        "--epsilon",
        type=float32,
        default=None,
        metavar="E",
        help="equ / eqTFAN modes, models without faces (point clouds) only: sorted points at distance >= E differ, "
        "counted (mm --epsilon / --eqTFAN_epsilon; default 0: the sorted points must be equal); meshes ignore it, "
        "as mm does",
    )
    p.add_argument(
        "--all-differences",
        action="store_true",
        help="equ / eqTFAN modes: count every difference (mm --earlyReturn=false / --eqTFAN_earlyReturn=false) "
        "instead of stopping at the first, and print the position / UV / colour / normal lists' differences",
    )
    from torchmeshmetric.cli.mpeg_outputs import add_output_options

    add_output_options(p)
    p.set_defaults(func=_run)
