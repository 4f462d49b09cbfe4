"""The ``torchmeshmetric sample MESH OUT.ply`` command: a mesh to the point cloud (PLY or OBJ) ``mm sample`` writes."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any, Literal

from torchmeshmetric.cli.options import path_argument

__all__ = ["add_sample_command"]


_OPTIONS = {
    "resolution": "--resolution",
    "thickness": "--thickness",
    "num_samples": "--num-samples",
    "length_threshold": "--length-threshold",
    "area_threshold": "--area-threshold",
    "max_depth": "--max-depth",
    "num_samples_min": "--num-samples-min",
    "num_samples_max": "--num-samples-max",
    "max_iterations": "--max-iterations",
}


def _run(args: argparse.Namespace) -> int:
    from torchmeshmetric.cli._outputs import CLIError, check_appended_csv, check_writable
    from torchmeshmetric.cli.options import as_option_error
    from torchmeshmetric.mpeg.core.textured_mesh import load_textured_mesh
    from torchmeshmetric.mpeg.sampling.edge_sampling import edge_sample
    from torchmeshmetric.mpeg.sampling.face_sampling import face_sample
    from torchmeshmetric.mpeg.sampling.map_sampling import map_sample
    from torchmeshmetric.mpeg.sampling.prnd_sampling import prnd_sample
    from torchmeshmetric.mpeg.sampling.subdivision_sampling import subdivision_sample

    out = Path(args.output)
    if out.suffix.lower() not in (".ply", ".obj"):  # mm sample writes by the name's suffix, these two only
        raise CLIError(f"OUT: {str(out)!r} must end with .ply or .obj")
    from torchmeshmetric.mpeg.comparison.csv_rows import mmetric_texture_url

    try:
        texture = mmetric_texture_url(args.mesh, args.texture) or None
    except (OSError, ValueError):  # an unreadable mesh is reported by its reader
        texture = None
    inputs = [("MESH", args.mesh), ("--texture" if args.texture else "MESH's texture", texture)]
    csv = [] if args.output_csv is None else [("--output-csv", Path(args.output_csv))]
    check_writable([out], args.overwrite, inputs=inputs, what="OUT", appended=csv)
    if csv:
        from torchmeshmetric.mpeg.comparison.csv_rows import SAMPLE_CSV_HEADERS

        check_appended_csv(csv[0][1], SAMPLE_CSV_HEADERS[args.mode])
    # the library's errors name its arguments (mesh, texture, num_samples_min...): retold with the command's names
    options = {**_OPTIONS, "path": "MESH", "mesh": f"MESH {args.mesh!r}"}
    options["texture"] = "--texture" if args.texture else "MESH's texture"
    try:
        mesh = load_textured_mesh(args.mesh, args.texture)
    except ValueError as exc:
        raise as_option_error(exc, options) from exc

    def sample(value: float | None = None) -> Any:
        """The mode's sampling; ``value`` replaces the resolution (face) or threshold (sdiv, ediv) when searched."""
        if args.mode == "face":
            res = args.resolution if value is None else int(value)
            return face_sample(mesh, resolution=res, thickness=args.thickness, bilinear=args.bilinear)
        if args.mode == "map":
            return map_sample(mesh)
        if args.mode == "prnd":
            return prnd_sample(mesh, num_samples=args.num_samples, bilinear=args.bilinear)
        if args.mode == "ediv":
            length = args.length_threshold if value is None else value
            return edge_sample(mesh, length_threshold=length, resolution=args.resolution, bilinear=args.bilinear)
        depth, area = (args.max_depth, args.area_threshold) if value is None else (10000, value)  # mm's search depth
        mapped = args.map_threshold and value is None  # mmetric's search runs without it
        return subdivision_sample(
            mesh, max_depth=depth, area_threshold=area, bilinear=args.bilinear, map_threshold=mapped
        )

    if args.num_samples_min:
        if args.mode not in ("face", "sdiv", "ediv"):
            raise CLIError(f"--num-samples-min: a search of face, sdiv and ediv modes, not of {args.mode} mode")
        from torchmeshmetric.mpeg.sampling.sample_count_search import search_sample_count

        kind: Literal["resolution", "threshold"] = "resolution" if args.mode == "face" else "threshold"
        try:
            found = search_sample_count(sample, kind, args.num_samples_min, args.num_samples_max, args.max_iterations)
        except ValueError as exc:
            raise as_option_error(exc, options) from exc
        pc, computed = found.cloud, found.value
        if found.earlier_points and pc.colors is not None:
            # mmetric's Model::reset keeps the earlier samplings' colours: its file then has none (see CountSearch)
            pc = type(pc)(pc.points, pc.normals, None, pc.uvs)
        print(f"Computed {kind} {found.value:.9g} after {found.iterations} iterations")
    else:
        computed = 0.0
        try:
            pc = sample()
        except ValueError as exc:
            raise as_option_error(exc, options) from exc
        except MemoryError as exc:  # beyond the free memory, below the physical memory the checks refuse at
            option = {"prnd": "--num-samples", "sdiv": "--area-threshold", "map": "MESH's texture"}.get(
                args.mode, "--length-threshold" if args.mode == "ediv" and args.length_threshold else "--resolution"
            )
            raise CLIError(f"{option}: the {args.mode} sampling needs more memory than is free here ({exc})") from exc
    _write(args, out, texture or "", pc, computed)
    print(f"Generated {pc.num_points} points -> {out}")
    return 0


def _write(args: argparse.Namespace, out: Path, texture: str, pc: Any, computed: float) -> None:
    """OUT and the ``--output-csv`` row as one set: OUT appears only once the row is appended."""
    from torchmeshmetric._atomic import atomic_write_with
    from torchmeshmetric.cli._outputs import output_set
    from torchmeshmetric.mpeg.comparison.csv_rows import SAMPLE_CSV_HEADERS, append_csv_row, sample_csv_row
    from torchmeshmetric.mpeg.core.model_files import point_cloud_blocks

    with output_set("OUT and the CSV row"):
        # mm sample keeps no header of the input: an OBJ starts with an empty line, never the mesh's mtllib; the
        # text is formatted block by block as it is written (a cloud of millions of points is never one string)
        blocks = point_cloud_blocks(pc, out.suffix)
        atomic_write_with(out, lambda fh: fh.writelines(blocks), overwrite=args.overwrite)
        if args.output_csv is not None:
            row = sample_csv_row(
                args.mode,
                model=args.mesh,
                texture=texture,
                points=pc.num_points,
                resolution=args.resolution,
                thickness=args.thickness,
                area_threshold=args.area_threshold,
                length_threshold=args.length_threshold,
                num_samples=args.num_samples,
                bilinear=args.bilinear,
                num_samples_min=args.num_samples_min,
                num_samples_max=args.num_samples_max,
                max_iterations=args.max_iterations,
                computed=computed,
            )
            append_csv_row(args.output_csv, SAMPLE_CSV_HEADERS[args.mode], [row])  # last: a failure keeps no OUT


def add_sample_command(sub: Any) -> None:
    """Add the ``sample`` subcommand to the CLI's subparsers."""
    p = sub.add_parser(
        "sample",
        help="a mesh to the point cloud mmetric's mm sample writes (face, sdiv, ediv, prnd, map)",
        description="Sample MESH as 'mm sample --mode face' (or sdiv, ediv, prnd, map) does and writes its PLY or "
        "OBJ (byte for byte as mm writes it, except ediv, whose points come in another order); --output-csv appends "
        "the row of mm sample --outputCsv. The grid sampling of the CTC is inside the 'mpeg' and 'ctc' commands.",
    )
    p.add_argument(
        "mesh", type=path_argument, metavar="MESH", help="mesh to sample (OBJ/PLY; OBJ with MTL + texture for colour)"
    )
    p.add_argument(
        "output",
        type=path_argument,
        metavar="OUT",
        help="PLY or OBJ file to write, as mm sample -o writes it (never overwritten unless --overwrite)",
    )
    p.add_argument(
        "--mode",
        choices=("face", "sdiv", "ediv", "prnd", "map"),
        default="face",
        help="mm sample --mode: face (default), sdiv, ediv, prnd or map (one point per texel; needs a texture)",
    )
    p.add_argument("--resolution", type=int, default=1024, help="steps along the bounding box's largest side (1024)")
    p.add_argument("--thickness", type=float, default=0.0, help="distance sampled either side of each face (0)")
    p.add_argument("--max-depth", type=int, default=100, help="sdiv: mm --maxDepth, 1 keeps the corners (100)")
    p.add_argument("--area-threshold", type=float, default=1.0, help="sdiv: faces at least this large are split (1.0)")
    p.add_argument(
        "--length-threshold",
        type=float,
        default=0.0,
        help="ediv: mm --lengthThreshold, edges split while half as long; 0 = box side / --resolution (0)",
    )
    p.add_argument("--num-samples", type=int, default=2000000, help="prnd: mm --nbSamples, the target count (2e6)")
    p.add_argument(
        "--map-threshold",
        action="store_true",
        help="sdiv: also split faces while their corners' texels are more than one apart (mm --mapThreshold)",
    )
    p.add_argument(
        "--num-samples-min",
        type=int,
        default=0,
        metavar="N",
        help="face/sdiv/ediv: resample, searching the resolution or threshold, until the count is in [N, MAX] (mm "
        "--nbSamplesMin; 0 = no search)",
    )
    p.add_argument("--num-samples-max", type=int, default=0, metavar="MAX", help="mm --nbSamplesMax (> N)")
    p.add_argument("--max-iterations", type=int, default=10, help="mm --maxIterations of the search (10)")
    p.add_argument("--bilinear", action="store_true", help="bilinear texture filtering (default nearest, as mm)")
    p.add_argument(
        "--texture", type=path_argument, default=None, metavar="IMG", help="texture of MESH (overrides its MTL)"
    )
    p.add_argument(
        "--output-csv",
        type=path_argument,
        default=None,
        metavar="FILE",
        help="append mm sample --outputCsv's row (options, searched value, point count; the mode's header first in a "
        "new or empty file)",
    )
    p.add_argument("--overwrite", action="store_true", help="replace OUT if it exists (never MESH nor its texture)")
    p.set_defaults(func=_run)
