"""TemporalConsistency in a training/validation loop (plain PyTorch, no Lightning needed).

A toy "learned simplifier": per-vertex offsets applied to a coarse template of each frame, trained so that the
simplified frame k lies on original frame k; every epoch the validation loop measures temporal consistency against
frames k and k-1 with the metric. Registrations of the original pairs are computed in the first validation epoch and
reused from the metric's in-memory cache afterwards.

    PYTHONPATH=. python examples/validation_temporal_consistency.py
"""

from __future__ import annotations

import torch
import trimesh

from torchmeshmetric import Mesh, point_mesh_distance
from torchmeshmetric.evaluation import TemporalConsistency, flatten_statistics


def frame(k: int, subdivisions: int) -> Mesh:
    m = trimesh.creation.icosphere(subdivisions=subdivisions)
    m.apply_translation([0.05 * k, 0, 0])
    return Mesh(torch.tensor(m.vertices, dtype=torch.float32), torch.tensor(m.faces))


def shift_register(source: Mesh, target: Mesh) -> Mesh:
    """The exact registration of this toy sequence (a translation); drop `registration_fn=` to use the library's."""
    return Mesh(source.verts + torch.tensor([0.05, 0.0, 0.0]), source.faces)


def main() -> None:
    originals = [frame(k, 3) for k in range(4)]
    templates = [frame(k, 1) for k in range(4)]
    offsets = torch.nn.Parameter(torch.zeros(len(templates), templates[0].num_verts, 3))
    optimizer = torch.optim.Adam([offsets], lr=1e-2)
    metric = TemporalConsistency(registration_fn=shift_register)

    for epoch in range(3):
        for k, (template, original) in enumerate(zip(templates, originals, strict=True)):  # training
            verts = template.verts * 1.2 + offsets[k]  # start off the surface on purpose
            loss = point_mesh_distance(verts, original).dists.square().mean()
            optimizer.zero_grad()
            loss.backward()
            optimizer.step()
        metric.reset()
        with torch.no_grad():  # validation
            for k in range(1, len(originals)):
                simplified = Mesh(templates[k].verts * 1.2 + offsets[k], templates[k].faces)
                metric.update(simplified, originals[k], originals[k - 1])
        logs = flatten_statistics(metric.compute())
        print(
            f"epoch {epoch}: surface_k_minus_1/rmse {float(logs['surface_k_minus_1/rmse']):.4f}  "
            f"reverse/surface_k/max {float(logs['reverse/surface_k/max']):.4f}"
        )


if __name__ == "__main__":
    main()
