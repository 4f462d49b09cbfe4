import pytest
import trimesh

from torchmeshmetric.cli import main


@pytest.mark.slow  # ~70 s on the shared 2-core sandbox with the brute-force kernels (issue 5 speeds this up)
def test_register_writes_source_topology_on_target_shape(capsys, tmp_path):
    source = trimesh.creation.icosphere(subdivisions=1)
    target = trimesh.creation.icosphere(subdivisions=2)
    target.vertices[:, 0] *= 1.1  # a non-rigid change (stretch) plus a shift
    target.apply_translation([0.05, 0, 0])
    source.export(tmp_path / "a.ply")
    target.export(tmp_path / "b.ply")
    out = tmp_path / "r.ply"
    code = main(
        ["register", "--source", str(tmp_path / "a.ply"), "--target", str(tmp_path / "b.ply"), "--out", str(out)]
    )
    stdout, stderr = capsys.readouterr()
    assert code == 0, stdout + stderr
    registered = trimesh.load(out, process=False)
    assert registered.faces.tolist() == source.faces.tolist()
    # registered vertices lie on the target surface (residual well below the 10 % stretch)
    _, dist, _ = trimesh.proximity.closest_point(target, registered.vertices)
    assert dist.max() < 0.02 * target.scale
    assert "converged: True" in stdout
    # The residual's figures with the digits of the report tables' registration rows: those of every row (2
    # significant, 3 for Max), since the registration draws independently of how the frames are stored (review L #1).
    figures = stdout.split("residual to target surface: ")[1].split("; wrote")[0].split(", ")
    texts = {f.split()[0]: f.split()[1] for f in figures}
    digits = {k: len(t.lstrip("~").split("e")[0].replace(".", "").lstrip("0")) for k, t in texts.items()}
    assert digits == {"ave": 2, "rmse": 2, "max": 3}
    assert not any(t.startswith("~") for t in texts.values())
    # never overwrite unasked
    assert (
        main(["register", "--source", str(tmp_path / "a.ply"), "--target", str(tmp_path / "b.ply"), "--out", str(out)])
        == 1
    )


def test_register_source_folder_is_named_as_a_folder(capsys, tmp_path):
    # `register --source DIR` said "--source 'DIR': no such file" (found by review E)
    frames = tmp_path / "frames"
    frames.mkdir()
    target = tmp_path / "t.ply"
    trimesh.creation.icosphere(subdivisions=1).export(target)
    assert main(["register", "--source", str(frames), "--target", str(target), "--out", str(tmp_path / "o.ply")]) == 1
    err = capsys.readouterr().err
    assert f"--source {str(frames)!r} is a folder; expected a mesh file" in err, err
