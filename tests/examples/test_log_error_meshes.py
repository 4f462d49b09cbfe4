"""examples/log_error_meshes.py runs: one error mesh an epoch in TensorBoard and as GLB, the error going down."""

import importlib.util
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("lightning")
pytest.importorskip("tensorboard")

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "log_error_meshes.py"


def test_example_logs_one_mesh_an_epoch(tmp_path):
    from tests.viz.test_mesh_logging import _tb_events

    spec = importlib.util.spec_from_file_location("log_error_meshes", EXAMPLE)
    assert spec is not None and spec.loader is not None
    example = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(example)
    folder = example.main(str(tmp_path), epochs=2)
    events = _tb_events(folder)
    colours = [events[(tag, step)][0][0] for tag, step in sorted(events) if tag == "val/error_mesh_COLOR"]
    assert len(colours) == 2 and {s for t, s in events if t == "val/error_mesh_COLOR"} == {10, 20}
    assert all(config["torchmeshmetric"]["vmax"] == 0.08 for _, config in events.values())
    # training moves the sphere onto the reference: darker colours (green grows with the error on this scale)
    green = [float(np.mean(c[:, 1])) for c in colours]
    assert green[1] < green[0]
    # the tag with its hash, one file per tag and step ("val/error_mesh" was "val_error_mesh": review A, 5)
    assert sorted(p.name for p in tmp_path.rglob("*.glb")) == [
        "val_error_mesh-830a3d9e_step000010.glb",
        "val_error_mesh-830a3d9e_step000020.glb",
    ]
