"""Command line interface: ``torchmeshmetric <command>`` (also ``python -m torchmeshmetric``)."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

__all__ = ["main"]


def _cmd_demo(args: argparse.Namespace) -> int:
    import torch
    import trimesh

    from torchmeshmetric import as_mesh, nearest_vertex_distance, point_mesh_distance, vertex_set

    reference = as_mesh(trimesh.creation.icosphere(subdivisions=args.subdivisions))
    coarse = as_mesh(trimesh.creation.icosphere(subdivisions=max(0, args.subdivisions - 2)))
    points = vertex_set(coarse)
    sets = {
        "surface": point_mesh_distance(points, reference).dists,
        "vertex": nearest_vertex_distance(points, vertex_set(reference)).dists,
    }
    print(f"simplified: {coarse.num_verts} vertices; reference: {reference.num_faces} faces (unit icosphere)")
    print(f"{'distance':<10}{'Ave':>12}{'Var':>12}{'STD':>12}{'MSE':>12}{'RMSE':>12}")
    for name, d in sets.items():
        d = d.double()
        mse = (d * d).mean()
        row = [d.mean(), d.var(unbiased=False), d.std(unbiased=False), mse, mse.sqrt()]
        print(f"{name:<10}" + "".join(f"{float(x):>12.4e}" for x in row))
    del torch
    return 0


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of the command line."""
    parser = argparse.ArgumentParser(prog="torchmeshmetric", description=__doc__)
    sub = parser.add_subparsers(dest="command", required=True)
    demo = sub.add_parser("demo", help="distance statistics between two built-in meshes")
    demo.add_argument("--subdivisions", type=int, default=4, help="subdivisions of the reference icosphere (default 4)")
    demo.set_defaults(func=_cmd_demo)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the exit code."""
    args = build_parser().parse_args(argv)
    return int(args.func(args))


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
