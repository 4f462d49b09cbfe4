"""The NVIDIA Warp kernels of the benchmarks' Warp peers, built on first use.

No ``from __future__ import annotations`` in this module: Warp 1.2 (the version that travels to the GPU machine,
``gpu_check_wheels.sh``) reads a kernel's annotations as objects and fails on strings ("'str' object has no
attribute '__module__'"). Nothing is imported until :func:`kernels` is called (the suite imports every module for
its doctests, with or without Warp).
"""

from functools import cache
from types import SimpleNamespace


@cache
def kernels() -> SimpleNamespace:
    """``closest_face``, ``distance`` (the temporal step's peer) and ``query_distance`` (point->mesh)."""
    import warp as wp

    wp.config.quiet = True
    wp.init()

    @wp.kernel
    def closest_face(
        mesh: wp.uint64,
        points: wp.array(dtype=wp.vec3),
        face: wp.array(dtype=wp.int32),
        bu: wp.array(dtype=wp.float32),
        bv: wp.array(dtype=wp.float32),
    ):
        i = wp.tid()
        q = wp.mesh_query_point_no_sign(mesh, points[i], 1.0e6)
        face[i] = q.face
        bu[i] = q.u
        bv[i] = q.v

    @wp.kernel
    def distance(
        points: wp.array(dtype=wp.vec3),
        mesh_points: wp.array(dtype=wp.vec3),
        indices: wp.array(dtype=wp.int32),
        face: wp.array(dtype=wp.int32),
        bu: wp.array(dtype=wp.float32),
        bv: wp.array(dtype=wp.float32),
        out: wp.array(dtype=wp.float32),
    ):
        i = wp.tid()
        f = face[i]
        a = mesh_points[indices[3 * f]]
        b = mesh_points[indices[3 * f + 1]]
        c = mesh_points[indices[3 * f + 2]]
        closest = bu[i] * a + bv[i] * b + (1.0 - bu[i] - bv[i]) * c
        out[i] = wp.length(points[i] - closest)

    @wp.kernel
    def query_distance(mesh: wp.uint64, points: wp.array(dtype=wp.vec3), out: wp.array(dtype=wp.float32)):
        i = wp.tid()
        q = wp.mesh_query_point_no_sign(mesh, points[i], 1.0e6)
        out[i] = wp.length(points[i] - wp.mesh_eval_position(mesh, q.face, q.u, q.v))

    return SimpleNamespace(wp=wp, closest_face=closest_face, distance=distance, query_distance=query_distance)
