"""The selection pass never materialises a points x faces matrix: peak memory follows max_memory."""

from __future__ import annotations

import subprocess
import sys
import textwrap


def test_peak_memory_stays_near_budget() -> None:
    # 3k points x 8k faces: a naive (P, F) pass with ~40 float32 temporaries per pair needs ~3.8 GB.
    code = textwrap.dedent(
        """
        import resource, torch, trimesh
        from torchmeshmetric import as_mesh, point_mesh_distance
        torch.set_num_threads(1)
        m = as_mesh(trimesh.creation.icosphere(subdivisions=5), dtype=torch.float32)
        m = type(m)(m.verts, m.faces[:8000])
        pts = torch.randn(3000, 3)
        before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
        r = point_mesh_distance(pts, m, max_memory=16 * 2**20)
        after = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
        print((after - before) / 1024)
        """
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    growth_mb = float(out.stdout.strip().splitlines()[-1])
    assert growth_mb < 200, f"peak RSS grew by {growth_mb:.0f} MB for a 16 MB budget"
