"""Plain PyTorch training loop: optimise the vertex offsets of a coarse mesh toward a reference with the loss.

Run: PYTHONPATH=. python examples/train_with_loss.py   (a few seconds on a CPU)
"""

import torch
import trimesh

from torchmeshmetric import Mesh
from torchmeshmetric.metrics import MeshSurfaceDistance, MeshSurfaceDistanceLoss


def main() -> None:
    torch.manual_seed(0)
    reference = trimesh.creation.capsule(height=1.0, radius=0.5, count=[10, 10])  # the "original" frame
    coarse = trimesh.creation.icosphere(subdivisions=1, radius=0.8)  # a poor "simplified" mesh
    verts = torch.tensor(coarse.vertices, dtype=torch.float32)
    faces = torch.tensor(coarse.faces)
    offsets = torch.zeros_like(verts, requires_grad=True)
    # Squared, two-sided: pulls vertices onto the surface (MSE) and the surface over the reference's vertices.
    loss_fn = MeshSurfaceDistanceLoss(power=2, two_sided=True)
    opt = torch.optim.Adam([offsets], lr=0.03)
    for step in range(61):
        opt.zero_grad()
        loss = loss_fn(Mesh(verts + offsets, faces), reference)
        loss.backward()
        opt.step()
        if step % 10 == 0:
            print(f"step {step:3d}  loss {loss.item():.6f}")
    metric = MeshSurfaceDistance(two_sided=True)
    metric.update(Mesh((verts + offsets).detach(), faces), reference)
    out = metric.compute()
    print({k: round(out[k].item(), 5) for k in ("ave", "rmse", "max", "reverse_max", "hausdorff")})


if __name__ == "__main__":
    main()
