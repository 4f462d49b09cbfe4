"""``torchmeshmetric ctc-campaign``: every figure equal to ``mm sequence``'s, resumable, checks first, typed errors.

The campaign is examples/ctc_campaign.toml on the data examples/make_ctc_campaign_data.py makes (2 textured sequences
x 2 rates x 5 frames, a test codec and an anchor; grid 128, IBSM 128 x 4). The oracle is the test model's chain in
``mm sequence`` (tests/mpeg/test_ctc.py's ``_mm_chain``, run on each point's frames through links named as it
expects), tolerance one unit of the 9th digit mmetric prints (1e-6 dB, tests/mpeg/test_ctc.py).
"""

from __future__ import annotations

import csv
import json
import math
import re
import shutil
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from tests.mpeg.test_ctc import MM_BIN, TOL_DB, _mm_chain, _parse
from torchmeshmetric._checksum import content_sha256
from torchmeshmetric.cli import main
from torchmeshmetric.mpeg.ctc import campaign as ctc_campaign
from torchmeshmetric.mpeg.ctc.campaign import FrameTask
from torchmeshmetric.mpeg.ctc.manifest import CtcManifestError, load_ctc_campaign

REPO = Path(__file__).resolve().parents[2]
FRAMES, RATES, CODECS = 5, (1, 2), ("anchor", "test")
SEQUENCES = ("sphere", "ellipsoid")


def _make(root: Path) -> Path:
    """The example's manifest and data in ``root``; returns the manifest."""
    sys.path.insert(0, str(REPO / "examples"))
    try:
        import make_ctc_campaign_data
    finally:
        sys.path.pop(0)
    make_ctc_campaign_data.make(root / "ctc-campaign-data")
    manifest = root / "ctc_campaign.toml"
    shutil.copy(REPO / "examples" / "ctc_campaign.toml", manifest)
    return manifest


@pytest.fixture(scope="module")
def campaign(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """(manifest, output folder of one complete run with a fresh cache)."""
    root = tmp_path_factory.mktemp("ctc_campaign")
    manifest = _make(root)
    assert main(["ctc-campaign", str(manifest), "--out-dir", str(root / "out")]) == 0
    return manifest, root / "out"


def _frames(out: Path) -> dict[tuple[str, str, int, int], dict[str, str]]:
    with (out / "frames.csv").open() as fh:
        return {(r["codec"], r["sequence"], int(r["rate"]), int(r["frame"])): r for r in csv.DictReader(fh)}


@pytest.mark.skipif(not MM_BIN.is_file(), reason="mmetric's mm binary absent (../shared/tools/mmetric/mm)")
def test_every_figure_equals_mm_sequence(campaign: tuple[Path, Path], tmp_path: Path) -> None:
    """Per frame and per point (the test model's CSV), every figure of both codecs equals mm sequence's."""
    manifest, out = campaign
    data = manifest.parent / "ctc-campaign-data"
    frames = _frames(out)
    for codec in CODECS:
        with (out / f"{codec}.csv").open() as fh:
            rows = {(int(r["SeqId"]), int(r["RateId"])): r for r in csv.DictReader(fh)}
        for seq_id, seq in enumerate(SEQUENCES, start=1):
            for rate in RATES:
                d = tmp_path / f"{codec}_{seq}_{rate}"
                d.mkdir()
                for k in range(FRAMES):  # the names _mm_chain runs mm on
                    for ext in ("obj", "png"):
                        (d / f"src_{k:04d}.{ext}").symlink_to(data / seq / "src" / f"src_{k:04d}.{ext}")
                        (d / f"dec_{k:04d}.{ext}").symlink_to(data / seq / codec / f"r{rate}" / f"dec_{k:04d}.{ext}")
                box = (np.array([-1, -1, -1], np.float32), np.array([1, 1, 1], np.float32))
                log = _mm_chain(d, FRAMES, 10, 8, box, 2.0, 128, textured=True, ibsm=(128, 4))
                mm_frames, mm_means = _parse(log)
                assert len(mm_frames) == FRAMES
                for k, f_mm in enumerate(mm_frames):
                    ours = frames[codec, seq, rate, k]
                    assert set(f_mm) == {c for c in f_mm if ours[c] != ""} and len(f_mm) == 7
                    for c, v in f_mm.items():
                        assert abs(float(ours[c]) - v) <= TOL_DB, (codec, seq, rate, k, c, ours[c], v)
                row = rows[seq_id, rate]
                for c, v in mm_means.items():
                    assert abs(float(row[c]) - v) <= TOL_DB, (codec, seq, rate, c, row[c], v)
                    assert row[c] == format(v, ".9g")  # the CSV holds what the test model's collection holds


def test_outputs_and_summary(campaign: tuple[Path, Path]) -> None:
    """The test model's CSVs (bits, faces, times from the anchor's CSV and the test's points), summary, plots."""
    _, out = campaign
    with (out / "anchor.csv").open() as fh:
        anchor = list(csv.DictReader(fh))
    assert [(r["SeqId"], r["CondId"], r["RateId"]) for r in anchor] == [
        ("1", "1", "1"),
        ("1", "1", "2"),
        ("2", "1", "1"),
        ("2", "1", "2"),
    ]
    assert anchor[0]["TotalBitstreamBits"] == "41000" and anchor[0]["UserEncoderRuntime"] == "12"
    with (out / "test.csv").open() as fh:
        test = list(csv.DictReader(fh))
    assert test[1]["TotalBitstreamBits"] == "81900" and test[1]["NbOutputFaces"] == str(5 * 320)  # counted
    report = json.loads((out / "summary.json").read_text())
    cond = report["conditions"][0]
    assert [s["name"] for s in cond["sequences"]] == list(SEQUENCES)
    assert [c["class"] for c in cond["classes"]] == ["cat1-A", "cat1-B"]
    assert all(v < 0 for v in cond["overall"]["bd_rate"].values())  # the test codec is the cleaner one
    assert cond["overall"]["component_ratios"]["mesh_inter"] == 0.0  # IF(B = 0, 0, ...)
    assert cond["sequences"][0]["bpif"]["anchor"] == pytest.approx((41000 / 1600 + 91000 / 1600) / 2, rel=1e-15)
    for seq in SEQUENCES:
        assert (out / f"rd_c1_{seq}.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_resume_computes_only_missing_frames(
    campaign: tuple[Path, Path], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Interrupted after 7 frames, a rerun computes the 33 others and writes the uninterrupted run's files."""
    manifest, reference = campaign
    calls: list[str] = []
    real = ctc_campaign._compute

    def counting(campaign, task, key, *rest):  # type: ignore[no-untyped-def]
        record = real(campaign, task, key, *rest)
        calls.append(key)
        if len(calls) == 7 and stop:
            raise KeyboardInterrupt
        return record

    monkeypatch.setattr(ctc_campaign, "_compute", counting)
    args = ["ctc-campaign", str(manifest), "--out-dir", str(tmp_path / "out"), "--cache-dir", str(tmp_path / "c")]
    stop = True
    assert main(args) == 130
    assert not (tmp_path / "out").exists()
    first = list(calls)
    stop, calls[:] = False, []
    assert main([*args, "--no-plots"]) == 0
    assert len(calls) == 2 * 2 * 2 * FRAMES - 7 and not set(calls) & set(first)
    for name in ("anchor.csv", "test.csv", "frames.csv", "summary.csv", "summary.md"):
        assert (tmp_path / "out" / name).read_bytes() == (reference / name).read_bytes(), name
    calls[:] = []
    assert main([*args, "--no-plots", "--overwrite"]) == 0
    assert calls == []  # everything from the cache


@pytest.mark.parametrize("damage", [math.nan, "nan", "abc", None])
def test_a_damaged_cache_record_is_computed_again(
    campaign: tuple[Path, Path], tmp_path: Path, monkeypatch: pytest.MonkeyPatch, damage: object
) -> None:
    """A record of the shared cache holding NaN (JSON's NaN or "nan") reached anchor.csv and the summary, and "abc"
    failed with a bare "could not convert string to float" (review B #4): the record is not used, a warning names
    its file, the frame is computed again (its record replaced), and the outputs equal the intact run's."""
    manifest, reference = campaign
    cache = tmp_path / "c"
    shutil.copytree(load_ctc_campaign(manifest).cache_dir, cache)  # type: ignore[arg-type]
    record_file = _campaign_records(cache)[0]
    record = json.loads(record_file.read_text())
    record.pop("sha256")
    record["figures"]["GridD1"] = damage
    record_file.write_text(json.dumps({**record, "sha256": content_sha256(record)}))  # damaged by its writer
    calls: list[str] = []
    real = ctc_campaign._compute

    def counting(campaign, task, key, *rest):  # type: ignore[no-untyped-def]
        calls.append(key)
        return real(campaign, task, key, *rest)

    monkeypatch.setattr(ctc_campaign, "_compute", counting)
    args = ["ctc-campaign", str(manifest), "--out-dir", str(tmp_path / "out"), "--cache-dir", str(cache), "--no-plots"]
    with pytest.warns(UserWarning, match=rf"{record_file.name}: damaged cache record \(GridD1={damage!r}"):
        assert main(args) == 0
    assert calls == [record["key"]]
    for name in ("anchor.csv", "test.csv", "frames.csv", "summary.csv", "summary.md"):
        assert (tmp_path / "out" / name).read_bytes() == (reference / name).read_bytes(), name
    assert json.loads(record_file.read_text())["figures"]["GridD1"] == pytest.approx(
        ctc_campaign._read_cached(cache, record["key"], ibsm=True)["figures"]["GridD1"]  # type: ignore[index]
    )
    assert math.isfinite(json.loads(record_file.read_text())["figures"]["GridD1"])


def test_an_overwrite_rerun_removes_the_earlier_runs_plots_it_does_not_draw(
    campaign: tuple[Path, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """An --overwrite rerun that draws no plots left the earlier run's RD plots (with its BD figures in their titles)
    beside the new summary (review B #7): the plots the earlier summary.json lists and this run does not draw are
    removed; a PNG of the user's in the folder is kept."""
    manifest, reference = campaign
    out = tmp_path / "out"
    shutil.copytree(reference, out)
    plots = sorted(p.name for p in out.glob("rd_*.png"))
    assert plots == ["rd_c1_ellipsoid.png", "rd_c1_sphere.png"]
    assert json.loads((out / "summary.json").read_text())["plots"] == ["rd_c1_sphere.png", "rd_c1_ellipsoid.png"]
    (out / "rd_c1_mine.png").write_bytes(b"the user's")
    assert main(["ctc-campaign", str(manifest), "--out-dir", str(out), "--overwrite"]) == 0  # the same plots drawn
    assert sorted(p.name for p in out.glob("rd_*.png")) == ["rd_c1_ellipsoid.png", "rd_c1_mine.png", "rd_c1_sphere.png"]
    capsys.readouterr()
    assert main(["ctc-campaign", str(manifest), "--out-dir", str(out), "--overwrite", "--no-plots"]) == 0
    assert sorted(p.name for p in out.glob("rd_*.png")) == ["rd_c1_mine.png"]
    assert (out / "rd_c1_mine.png").read_bytes() == b"the user's"
    assert json.loads((out / "summary.json").read_text())["plots"] == []
    err = capsys.readouterr().err
    assert f"ctc-campaign: removed rd_c1_sphere.png, an RD plot of the earlier run in {out}/" in err


def test_reports_another_run_wrote_meanwhile_are_named(
    campaign: tuple[Path, Path], tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """Two independent runs into one --out-dir: the one finishing second failed with atomic_write's API message
    ("pass overwrite=True / --overwrite") (review B #8); it now names the situation and the option, and writes none
    of its files."""
    manifest, _ = campaign
    out = tmp_path / "out"
    out.mkdir()
    real = ctc_campaign._compute

    def other_run_writes(campaign, task, key, *rest):  # type: ignore[no-untyped-def]
        (out / "anchor.csv").write_text("the other run's\n")
        return real(campaign, task, key, *rest)

    monkeypatch.setattr(ctc_campaign, "_compute", other_run_writes)
    args = ["ctc-campaign", str(manifest), "--out-dir", str(out), "--cache-dir", str(tmp_path / "c"), "--no-plots"]
    assert main(args) == 1
    err = capsys.readouterr().err
    assert (
        f"--out-dir {str(out)!r}: anchor.csv was written while this campaign ran (another run of the campaign into "
        "the same folder?); the frames are in the cache folder: rerun with --overwrite to replace that run's files, "
        "or give another --out-dir; none of this run's files was written"
    ) in err
    assert "overwrite=True" not in err
    assert sorted(p.name for p in out.iterdir()) == ["anchor.csv"] and (out / "anchor.csv").read_text() == (
        "the other run's\n"
    )


def test_checks_before_any_frame(campaign: tuple[Path, Path], tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    """A missing decoded frame, or a point without bits: one error line, naming the point, before any frame."""
    manifest, _ = campaign
    data = manifest.parent / "ctc-campaign-data"
    text = manifest.read_text().replace("ctc-campaign-data/", str(data) + "/")
    bad = tmp_path / "m.toml"
    bad.write_text(text.replace("test/r{rate_id}/dec_%04d.obj", "test/r{rate_id}/missing_%04d.obj"))
    out = ["--out-dir", str(tmp_path / "out"), "--cache-dir", str(tmp_path / "c")]
    assert main(["ctc-campaign", str(bad), *out]) == 1
    err = capsys.readouterr().err
    assert "test sequence 'sphere' condition 1 rate 1 frame 0: file" in err and "missing_0000.obj' not found" in err
    bad.write_text(text.replace("total_bits = 36900\n", ""))
    assert main(["ctc-campaign", str(bad), *out]) == 1
    err = capsys.readouterr().err
    assert "test: sequence 'sphere' condition 1 rate 1: no bitstream size" in err
    assert "ctc-campaign: anchor" not in err and not (tmp_path / "c").exists()


def test_an_out_dir_that_is_a_file_is_refused_before_any_frame(
    campaign: tuple[Path, Path], tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    # With --overwrite too: that option replaces reports in the folder, never a file standing for the folder.
    manifest, _ = campaign
    notes = tmp_path / "notes.txt"
    notes.write_text("mine")
    for extra in ([], ["--overwrite"]):
        argv = ["ctc-campaign", str(manifest), "--out-dir", str(notes), "--cache-dir", str(tmp_path / "c"), *extra]
        assert main(argv) == 1
        err = capsys.readouterr().err
        assert f"--out-dir {str(notes)!r}: {str(notes)!r} is a file, not a folder" in err, err
        assert "ctc-campaign: anchor" not in err and not (tmp_path / "c").exists()
    assert notes.read_text() == "mine"


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (("qp = 10", "qp = 3"), r"sequence 'sphere': 'qp' must be an integer in 7\.\.31, found 3"),
        (("qp = 10", 'qp = "ten"'), r"sequence 'sphere': 'qp' must be an integer, found 'ten'"),
        (("qp = 10", "qp = true"), r"sequence 'sphere': 'qp' must be an integer, found True"),
        (("rates = [1, 2]", "rates = [1, 1]"), r"condition 1: 'rates' repeats a RateId"),
        (("frame_count = 5", "frame_count = 5\ncolour = 1"), r"sequences\[0\]: unknown key 'colour'"),
        (("src_%04d.obj", "src.obj"), r"sequence 'sphere': source: expected one printf integer field"),
        (("r{rate_id}/dec", "r{rate}/dec"), r"'decoded': unknown field 'rate'"),
        (('sequence = "sphere"', 'sequence = "cube"'), r"\[anchor\]\.points\[0\]: 'sequence' 'cube' is not"),
        (("max_pos = [1, 1, 1]", "max_pos = [1, 1, -2]"), r"'max_pos': \[1\.0, 1\.0, -2\.0\] is below 'min_pos'"),
        (("max_pos = [1, 1, 1]", "max_pos = [-1, -1, -1]"), r"'max_pos': \[-1\.0, -1\.0, -1\.0\] equals 'min_pos'"),
        # 0 bits made the point's BD-rates vanish from the summary without a word (found by review)
        (("total_bits = 36900", "total_bits = 0"), r"points\[0\]: 'total_bits' must be > 0"),
        # a test codec named as the anchor gave a summary and RD legends whose two codecs read the same
        (('name = "test"', 'name = "anchor"'), r"\[test\] name 'anchor' is the anchor's name too"),
    ],
)
def test_manifest_errors_name_the_key(tmp_path: Path, edit: tuple[str, str], message: str) -> None:
    text = (REPO / "examples" / "ctc_campaign.toml").read_text()
    assert edit[0] in text
    p = tmp_path / "m.toml"
    p.write_text(text.replace(edit[0], edit[1], 1))
    with pytest.raises(CtcManifestError, match=message):
        load_ctc_campaign(p)


def test_example_manifest_reads() -> None:
    c = load_ctc_campaign(REPO / "examples" / "ctc_campaign.toml")
    assert [s.name for s in c.sequences] == list(SEQUENCES) and c.conditions[0].rates == RATES
    assert c.anchor.csv is not None and c.test.points[1, 1, 2]["total_bits"] == 81900
    assert c.sequences[0].resolution == 2.0 and not math.isnan(c.sequences[1].fps)


def test_point_means_and_the_lossless_rule() -> None:
    """A point's row: mmetric's clipped means at 9 digits; lossless and identical grid samples: inf everywhere."""
    same = {"figures": {"GridD1": math.inf, "GridD2": math.inf, "IbsmGeom": 99.99}, "faces_dis": 10}
    off = {"figures": {"GridD1": 70.123456789, "GridD2": math.inf, "IbsmGeom": 60.0}, "faces_dis": 12}
    p = ctc_campaign._point([same, same], {"total_bits": 8.0}, (1, 0, 0), True, "x")
    assert p.figures == {"GridD1": math.inf, "GridD2": math.inf, "IbsmGeom": math.inf} and p.output_faces == 20
    p = ctc_campaign._point([same, off], {"total_bits": 8.0, "output_faces": 5}, (1, 0, 0), True, "x")
    assert p.figures == {"GridD1": 85.0567284, "GridD2": 99.99, "IbsmGeom": 79.995} and p.output_faces == 5
    with pytest.raises(ValueError, match=r"x: GridLuma is computed on 1 of 2 frames"):
        ctc_campaign._point(
            [same, {"figures": {**off["figures"], "GridLuma": 30.0}}], {"total_bits": 8.0}, (1, 1, 1), False, "x"
        )


def test_a_second_codec_reuses_the_anchors_frames(
    campaign: tuple[Path, Path], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Another test codec against the same anchor (same cache): only its frames whose files differ are computed."""
    manifest, reference = campaign
    data = manifest.parent / "ctc-campaign-data"
    for seq in SEQUENCES:  # a copy of the test codec's files in another folder, one frame changed
        shutil.copytree(data / seq / "test", data / seq / "test2", dirs_exist_ok=True)
    changed = data / "sphere" / "test2" / "r1" / "dec_0003.obj"
    lines = changed.read_text().splitlines()
    lines[0] = "v " + " ".join(str(int(x) + 1) for x in lines[0].split()[1:])
    changed.write_text("\n".join(lines) + "\n")
    second = manifest.parent / "second.toml"
    second.write_text(manifest.read_text().replace("/test/r{rate_id}", "/test2/r{rate_id}"))
    calls: list[FrameTask] = []
    real = ctc_campaign._compute

    def counting(campaign, task, *rest):  # type: ignore[no-untyped-def]
        calls.append(task)
        return real(campaign, task, *rest)

    monkeypatch.setattr(ctc_campaign, "_compute", counting)
    assert main(["ctc-campaign", str(second), "--out-dir", str(tmp_path / "out"), "--no-plots"]) == 0
    assert [(t.codec, t.seq.name, t.rate_id, t.frame) for t in calls] == [("test", "sphere", 1, 3)]
    assert (tmp_path / "out" / "anchor.csv").read_bytes() == (reference / "anchor.csv").read_bytes()
    assert (tmp_path / "out" / "test.csv").read_bytes() != (reference / "test.csv").read_bytes()


def test_bits_runtimes_and_memory_from_the_codecs_files(tmp_path: Path) -> None:
    """As collect_results.sh: bits = bitstream size * 8, the logs' 4th fields (memory / 1024); manifest points win."""
    from torchmeshmetric.mpeg.ctc.manifest import CtcCampaignSequence, CtcCodec

    seq = CtcCampaignSequence("ball", 3, "cat1-B", "s_%04d.obj", None, 0, 2, 30.0, 10, 8, (0, 0, 0), (1, 1, 1), 1.0)
    folder = tmp_path / "s3c1r2_ball"
    folder.mkdir()
    (folder / "out.vmesh").write_bytes(b"\0" * 1234)
    (folder / "encoder.log").write_text(
        "Sequence face count 6400\nSequence processing time 12.5 s\nSequence peak memory 20480 KB\n"
    )
    (folder / "decoder.log").write_text("Sequence processing time 1.25 s\nSequence peak memory 10240 KB\n")
    t = str(tmp_path / "s{seq_id}c{cond_id}r{rate_id}_{sequence}")
    codec = CtcCodec(
        "test",
        "d_%04d.obj",
        bitstream=t + "/out.vmesh",
        encoder_log=t + "/encoder.log",
        decoder_log=t + "/decoder.log",
        points={(3, 1, 2): {"decoder_seconds": 2.0}},
    )
    v = ctc_campaign._codec_values(codec, seq, 1, 2, {})
    assert v == {
        "total_bits": 1234 * 8,
        "output_faces": 6400.0,
        "encoder_seconds": 12.5,
        "encoder_memory": 20.0,
        "decoder_seconds": 2.0,
        "decoder_memory": 10.0,
    }
    (folder / "decoder.log").write_text("Sequence processing time n/a\n")
    with pytest.raises(ValueError, match=r"decoder.log:1: expected a number as the 4th field"):
        ctc_campaign._codec_values(codec, seq, 1, 2, {})
    with pytest.raises(ValueError, match=r"test: sequence 'ball' condition 1 rate 1: bitstream .* not found"):
        ctc_campaign._codec_values(codec, seq, 1, 1, {})
    (folder / "out.vmesh").write_bytes(b"")  # a failed encode: no point at 0 bits (its BD figures would vanish)
    with pytest.raises(ValueError, match=r"test: sequence 'ball' condition 1 rate 2: bitstream .* is empty"):
        ctc_campaign._codec_values(codec, seq, 1, 2, {})


@pytest.mark.parametrize("statement", ["map_Kd my tex.png", "map_Kd -s 1 1 1 my tex.png", "map_Kd my_tex.png"])
def test_a_frames_key_holds_its_texture_whatever_its_name(tmp_path: Path, statement: str) -> None:
    # The key read the map_Kd line's last word: "my tex.png" was no file, the texture was left out of the key, and
    # a changed texture reused the cached figures (found by review: GridLuma 31.14 from the cache, 8.97 computed).
    frame = tmp_path / "f.obj"
    frame.write_text("mtllib m.mtl\nusemtl a\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nf 1/1 2/2 3/3\n")
    (tmp_path / "m.mtl").write_text(f"newmtl a\n{statement}\n")
    texture = tmp_path / statement.split(" 1 1 1 ")[-1].removeprefix("map_Kd ")
    texture.write_bytes(b"first texture")
    first, alone = ctc_campaign._digest((str(frame), True)), ctc_campaign._digest((str(frame), False))
    texture.write_bytes(b"another texture")
    assert ctc_campaign._digest((str(frame), True)) != first
    assert ctc_campaign._digest((str(frame), False)) == alone  # a texture given apart is keyed by its own file


def test_sequences_whose_plots_share_a_file_name_are_refused(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    # "sphere a" and "sphere_a" both drew rd_c1_sphere_a.png: one plot written over the other (found by review).
    manifest = _make(tmp_path)
    data = tmp_path / "ctc-campaign-data"
    (data / "sphere_a").symlink_to(data / "sphere", target_is_directory=True)
    (data / "sphere a").symlink_to(data / "ellipsoid", target_is_directory=True)
    text = manifest.read_text().replace('"sphere"', '"sphere_a"').replace('"ellipsoid"', '"sphere a"')
    manifest.write_text(text)
    out = tmp_path / "out"
    assert main(["ctc-campaign", str(manifest), "--out-dir", str(out), "--cache-dir", str(tmp_path / "c")]) == 1
    err = capsys.readouterr().err
    assert "sequences 'sphere_a' and 'sphere a' would write the same RD plots (rd_c<condition>_sphere_a.png)" in err
    assert not out.exists() and not (tmp_path / "c").exists()  # refused before any frame


def test_a_frames_key_holds_the_results_version_not_the_package_version(
    campaign: tuple[Path, Path], monkeypatch: pytest.MonkeyPatch
) -> None:
    # Review I #5: the key held the package's version, 0.1.0 through every change that moved a figure, so a fix never
    # invalidated a record. CTC_RESULTS_VERSION is raised with such a change: the earlier records then miss, cleanly.
    import warnings

    manifest, _ = campaign
    parsed = load_ctc_campaign(manifest)
    task = ctc_campaign.plan_frames(parsed)[0]
    files = [(task.ref, task.ref_texture is None), (task.dis, task.dis_texture is None)]
    files += [(t, False) for t in (task.ref_texture, task.dis_texture) if t is not None]
    digests = {f: ctc_campaign._digest(f) for f in files}
    key = ctc_campaign._key(parsed, task, digests)
    assert parsed.cache_dir is not None
    record = ctc_campaign._read_cached(parsed.cache_dir, key, ibsm=True)  # the complete run's record of this frame
    assert isinstance(record, dict) and record["settings"]["results_version"] == ctc_campaign.CTC_RESULTS_VERSION == 1
    monkeypatch.setattr("torchmeshmetric._version.__version__", "9.9.9")
    assert ctc_campaign._key(parsed, task, digests) == key
    monkeypatch.setattr(ctc_campaign, "CTC_RESULTS_VERSION", 2)
    bumped = ctc_campaign._key(parsed, task, digests)
    assert bumped != key
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a miss, not a damaged record
        assert ctc_campaign._read_cached(parsed.cache_dir, bumped, ibsm=True) is None


def test_a_read_only_cache_folder_warns_once_and_the_campaign_writes_its_files(
    campaign: tuple[Path, Path], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # Review I #6: with the cache folder on a read-only mount, ctc-campaign died at its first frame ("error: [Errno
    # 30] Read-only file system: '.../12'"). Now the campaign goes on without storing, after one warning naming it.
    import errno

    manifest, reference = campaign
    calls: list[Path] = []

    def read_only(path: Path, *args: object, **kwargs: object) -> None:
        calls.append(path)
        raise OSError(errno.EROFS, "Read-only file system", str(path.parent))

    monkeypatch.setattr(ctc_campaign, "atomic_write", read_only)
    out = tmp_path / "out"
    args = ["ctc-campaign", str(manifest), "--out-dir", str(out), "--cache-dir", str(tmp_path / "ro"), "--no-plots"]
    with pytest.warns(UserWarning) as record:
        assert main(args) == 0
    messages = [str(w.message) for w in record if "cache folder" in str(w.message)]
    assert len(messages) == 1 and messages[0].startswith(
        f"cannot store frame records in the cache folder {tmp_path / 'ro'} (Read-only file system: "
    )
    assert "the campaign goes on and stores the records it can" in messages[0]
    assert len(calls) == 2 * 2 * 2 * FRAMES  # every record tried (review R #8), one warning per cause
    for name in ("frames.csv", "anchor.csv", "test.csv", "summary.csv"):
        assert (out / name).read_text() == (reference / name).read_text(), name


_TRIANGLE = "usemtl a\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nf 1/1 2/2 3/3\n"


@pytest.mark.parametrize(
    ("obj", "mtl_name", "mtl"),
    [
        ("mtllib m.mtl # exported by the encoder\n" + _TRIANGLE, "m.mtl", "newmtl a\nmap_Kd tex.png\n"),
        ("mtllib m.mtl#note\n" + _TRIANGLE, "m.mtl", "newmtl a\nmap_Kd tex.png\n"),
        ("mtllib\tm.mtl\t\n" + _TRIANGLE, "m.mtl", "newmtl a\nmap_Kd\ttex.png\n"),
        ("  mtllib m.mtl\n" + _TRIANGLE, "m.mtl", "newmtl a\nmap_Kd tex.png\n"),
        ("\ufeffmtllib m.mtl\n" + _TRIANGLE, "m.mtl", "newmtl a\nmap_Kd tex.png\n"),
        (("mtllib m.mtl\n" + _TRIANGLE).replace("\n", "\r\n"), "m.mtl", "newmtl a\r\nmap_Kd tex.png\r\n"),
        (("mtllib m.mtl\n" + _TRIANGLE).replace("\n", "\r"), "m.mtl", "newmtl a\rmap_Kd tex.png\r"),
        ("mtllib \\\n  m.mtl\n" + _TRIANGLE, "m.mtl", "newmtl a\nmap_Kd tex.png\n"),
        ("mtllib my m.mtl\n" + _TRIANGLE, "my m.mtl", "newmtl a\nmap_Kd tex.png\n"),
        ("mtllib m.mtl\n" + _TRIANGLE, "m.mtl", "newmtl a # skin\nmap_Kd -s 1 1 1 -o 0 0 tex.png # the atlas\n"),
    ],
    ids=["comment", "comment-no-space", "tabs", "indented", "bom", "crlf", "cr", "continuation", "spaces", "mtl"],
)
def test_a_frames_key_holds_the_mtl_and_texture_the_reader_uses(
    tmp_path: Path, obj: str, mtl_name: str, mtl: str
) -> None:
    # Review R #1: the key read "mtllib dec.mtl # exported by encoder" as the file "dec.mtl # exported by encoder",
    # which does not exist, and left the MTL and its texture out; the reader strips the comment and uses them, so a
    # changed texture reused stale figures (GridLuma 32.60 from the cache, 40.35 computed). Every form the reader
    # accepts must bring its MTL and texture into the key.
    from PIL import Image

    from torchmeshmetric.data.obj import obj_mtllibs, parse_obj
    from torchmeshmetric.mpeg.core.textured_mesh import load_textured_mesh

    frame = tmp_path / "f.obj"
    frame.write_bytes(obj.encode())
    (tmp_path / mtl_name).write_bytes(mtl.encode())
    texture = tmp_path / "tex.png"
    Image.new("RGB", (4, 4), (200, 10, 10)).save(texture)
    assert obj_mtllibs(frame.read_bytes()) == [n for n, _ in parse_obj(frame, frame.read_bytes()).mtllibs]
    assert load_textured_mesh(frame).texture is not None  # the reader does use the MTL's texture
    first = ctc_campaign._digest((str(frame), True))
    Image.new("RGB", (4, 4), (10, 200, 10)).save(texture)
    assert ctc_campaign._digest((str(frame), True)) != first
    changed = ctc_campaign._digest((str(frame), True))
    (tmp_path / mtl_name).write_bytes(mtl.replace("tex.png", "tex.png ").encode())  # the MTL's bytes are keyed too
    assert ctc_campaign._digest((str(frame), True)) != changed


def _campaign_records(cache: Path) -> list[Path]:
    """The records of the example campaign in a copy of the fixture's cache (another test adds a second codec's)."""
    return [p for p in sorted(cache.rglob("*.json")) if p.is_file() and "/test2/" not in p.read_text()]


def _counting_compute(monkeypatch: pytest.MonkeyPatch) -> list[str]:
    calls: list[str] = []
    real = ctc_campaign._compute

    def counting(campaign, task, key, *rest):  # type: ignore[no-untyped-def]
        calls.append(key)
        return real(campaign, task, key, *rest)

    monkeypatch.setattr(ctc_campaign, "_compute", counting)
    return calls


def _resign(path: Path, edit: Any) -> None:
    """Edit a record and give it the checksum of its new content (a record damaged by its writer)."""
    record = json.loads(path.read_text())
    record.pop("sha256")
    edit(record)
    path.write_text(json.dumps({**record, "sha256": content_sha256(record)}))


_UNMATCHED = r"its content does not match its checksum"


@pytest.mark.parametrize(
    ("damage", "why"),
    [
        # review R #6: GridD1 edited to 70.0 reached frames.csv and the CSVs silently
        (lambda p: p.write_text(p.read_text().replace('"GridD1": ', '"GridD1": 1')), _UNMATCHED),
        # review R #2: a record without one figure: a misleading error about textures, or a blank column
        (lambda p: p.write_text(p.read_text().replace('"IbsmLuma"', '"IbsmLumaX"')), _UNMATCHED),
        (lambda p: _resign(p, lambda r: r["figures"].pop("IbsmLuma")), r"no IbsmLuma: the campaign's settings"),
        (lambda p: _resign(p, lambda r: r["figures"].pop("GridChromaCb")), r"no GridChromaCb: the campaign's"),
        (lambda p: _resign(p, lambda r: r["figures"].pop("GridD2")), r"no GridD2: the campaign's settings"),
        (lambda p: _resign(p, lambda r: r.update(key="0" * 64)), r"it holds the record of the key '0000"),
        # review R #7: a truncated or empty record was computed again without the warning the docs promise
        (lambda p: p.write_bytes(p.read_bytes()[:200]), r"not JSON \(Unterminated string|not JSON \(Expecting"),
        (lambda p: p.write_bytes(b""), r"not JSON \(an empty file\)"),
        (lambda p: p.write_bytes(b"\xff\xfe" * 10), r"not JSON \("),
    ],
    ids=[
        "edited",
        "renamed-figure",
        "no-ibsm-luma",
        "one-colour-figure",
        "no-grid-d2",
        "other-key",
        "truncated",
        "empty",
        "binary",
    ],
)
def test_a_record_failing_its_checks_is_named_and_computed_again(
    campaign: tuple[Path, Path], tmp_path: Path, monkeypatch: pytest.MonkeyPatch, damage: Any, why: str
) -> None:
    manifest, reference = campaign
    cache = tmp_path / "c"
    shutil.copytree(load_ctc_campaign(manifest).cache_dir, cache)  # type: ignore[arg-type]
    record_file = _campaign_records(cache)[3]
    key = record_file.stem
    damage(record_file)
    calls = _counting_compute(monkeypatch)
    args = ["ctc-campaign", str(manifest), "--out-dir", str(tmp_path / "out"), "--cache-dir", str(cache), "--no-plots"]
    with pytest.warns(UserWarning, match=rf"{record_file.name}: damaged cache record \(({why})"):
        assert main(args) == 0
    assert calls == [key]
    for name in ("anchor.csv", "test.csv", "frames.csv", "summary.csv", "summary.md"):
        assert (tmp_path / "out" / name).read_bytes() == (reference / name).read_bytes(), name
    assert isinstance(ctc_campaign._read_cached(cache, key, ibsm=True), dict)  # replaced by a sound record


def test_records_without_a_checksum_are_computed_again_after_one_warning(
    campaign: tuple[Path, Path], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Records written before they held a checksum: not trusted (one warning for all of them), computed again."""
    manifest, reference = campaign
    cache = tmp_path / "c"
    shutil.copytree(load_ctc_campaign(manifest).cache_dir, cache)  # type: ignore[arg-type]
    old = _campaign_records(cache)[:3]
    for path in old:
        record = json.loads(path.read_text())
        del record["sha256"]
        path.write_text(json.dumps(record))
    calls = _counting_compute(monkeypatch)
    args = ["ctc-campaign", str(manifest), "--out-dir", str(tmp_path / "out"), "--cache-dir", str(cache), "--no-plots"]
    with pytest.warns(UserWarning) as caught:
        assert main(args) == 0
    messages = [str(w.message) for w in caught if "cache record" in str(w.message)]
    assert len(messages) == 1 and messages[0].startswith(f"3 cache records in {cache} hold no checksum (sha256;")
    assert sorted(calls) == sorted(p.stem for p in old)
    assert (tmp_path / "out" / "frames.csv").read_bytes() == (reference / "frames.csv").read_bytes()
    assert all("sha256" in json.loads(p.read_text()) for p in old)


def test_one_unwritable_record_path_does_not_stop_storing_the_others(
    campaign: tuple[Path, Path], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # Review R #8: a folder standing at one record's path turned storing off for the rest of the run, so every
    # rerun computed all the later frames again. Now that record alone is not stored, after one warning.
    manifest, _ = campaign
    cache = tmp_path / "c"
    shutil.copytree(load_ctc_campaign(manifest).cache_dir, cache)  # type: ignore[arg-type]
    records = _campaign_records(cache)
    blocked = records[0]
    for path in records:
        path.unlink()
    blocked.mkdir()
    (blocked / "x").write_text("")  # not removable by the writer either
    calls = _counting_compute(monkeypatch)
    args = ["ctc-campaign", str(manifest), "--out-dir", str(tmp_path / "out"), "--cache-dir", str(cache), "--no-plots"]
    with pytest.warns(UserWarning) as caught:
        assert main(args) == 0
    assert len(calls) == 2 * 2 * 2 * FRAMES
    stored = [str(w.message) for w in caught if "cannot store" in str(w.message)]
    assert len(stored) == 1 and str(blocked) in stored[0], stored
    assert _campaign_records(cache) == records[1:]
    calls[:] = []
    with pytest.warns(UserWarning) as caught:  # the folder is still there: read as damaged, and again not stored
        assert main([*args, "--overwrite"]) == 0
    assert calls == [blocked.stem]
    messages = [str(w.message) for w in caught]
    assert any(re.search(r"damaged cache record \(cannot be read \(Is a directory\)\)", m) for m in messages), messages
    stored = [m for m in messages if "cannot store" in m]
    assert len(stored) == 1 and str(blocked) in stored[0], stored


def test_a_manifest_without_cache_dir_resumes_from_ctc_cache_beside_it(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # Review R #3: the docs give cache_dir = "ctc-cache" as the default and say a rerun resumes from it; without the
    # key no cache was used, and every rerun computed every frame again. The default is now that folder, relative
    # to the manifest as its other paths (whatever the working folder); cache_dir = "" keeps no cache.
    manifest = _make(tmp_path)
    text = manifest.read_text()
    assert 'cache_dir = "ctc-campaign-data/cache"' in text
    manifest.write_text(
        text.replace('cache_dir = "ctc-campaign-data/cache"', "").replace("frame_count = 5", "frame_count = 1")
    )
    assert load_ctc_campaign(manifest).cache_dir == tmp_path / "ctc-cache"
    monkeypatch.chdir(tmp_path / "ctc-campaign-data")  # another working folder
    calls = _counting_compute(monkeypatch)
    args = ["ctc-campaign", str(manifest), "--out-dir", str(tmp_path / "out"), "--no-plots", "--overwrite"]
    assert main(args) == 0
    assert len(calls) == 2 * 2 * 2 and len(list((tmp_path / "ctc-cache").rglob("*.json"))) == len(calls)
    calls[:] = []
    assert main(args) == 0
    assert calls == []  # resumed: every frame from the cache
    manifest.write_text(manifest.read_text().replace("[options]", '[options]\ncache_dir = ""'))
    assert load_ctc_campaign(manifest).cache_dir is None


@pytest.mark.parametrize("folder", ["pct 50%", "brace{x}", "both %d {sequence}", "%%"])
def test_a_manifest_in_a_folder_named_with_percent_or_braces_runs(
    tmp_path: Path, folder: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    # Review R #4: the manifest's folder was joined to each relative path before the printf and {field} checks, so
    # "pct 50%/c2.toml" was refused ("source: expected one printf integer field ..., found 'pct 50%/src/...'") and
    # "brace{x}/c2.toml" too ("'source': unknown field 'x'"); the user could not escape the folder's name.
    root = tmp_path / folder
    root.mkdir()
    manifest = _make(root)
    manifest.write_text(manifest.read_text().replace("frame_count = 5", "frame_count = 1"))
    campaign = load_ctc_campaign(manifest)
    tasks = ctc_campaign.plan_frames(campaign)
    assert tasks[0].ref == str(root / "ctc-campaign-data" / "sphere" / "src" / "src_0000.obj")
    assert tasks[-1].dis_texture == str(root / "ctc-campaign-data" / "ellipsoid" / "test" / "r2" / "dec_0000.png")
    assert all(Path(p).is_file() for _, p in campaign.input_files() if p is not None)
    monkeypatch.chdir(tmp_path)
    out = Path(folder) / "out"
    assert main(["ctc-campaign", str(Path(folder) / manifest.name), "--out-dir", str(out), "--no-plots"]) == 0
    assert (tmp_path / out / "frames.csv").is_file()


def test_a_frame_count_typo_stops_at_the_first_missing_file_at_once(
    campaign: tuple[Path, Path], tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture
) -> None:
    # Review R #5: frame_count = 300000 (for 300) listed and resolved every input path of the campaign (1.8 M) for
    # the output check before the frames were planned: 38 s and 1.1 GB before "file ... not found" (130 s and 3.6 GB
    # here). The frames are now planned first, each file checked in order: 1.25 s and 228 MB, as a correct count.
    from torchmeshmetric.mpeg.ctc.manifest import CtcCampaign

    manifest, _ = campaign
    big = manifest.parent / "big.toml"
    big.write_text(manifest.read_text().replace("frame_count = 5", "frame_count = 300000"))

    def listed(self: CtcCampaign) -> list[tuple[str, str | Path | None]]:
        raise AssertionError("every input path listed before the frames were planned")

    monkeypatch.setattr(CtcCampaign, "input_files", listed)
    out = ["--out-dir", str(tmp_path / "out"), "--cache-dir", str(tmp_path / "c")]
    assert main(["ctc-campaign", str(big), *out]) == 1
    err = capsys.readouterr().err
    assert "anchor sequence 'sphere' condition 1 rate 1 frame 5: file" in err and "src_0005.obj' not found" in err


def test_a_box_flat_on_one_axis_is_accepted_by_the_manifest_as_by_ctc(tmp_path: Path) -> None:
    # Review R #9: ctc accepts a box flat on one axis (docs/ctc.md), ctc-campaign refused the same box ("'max_pos'
    # [1.0, 1.0, 0.0] must be above 'min_pos' [-1.0, -1.0, 0.0] on every axis"). One check now serves both.
    import argparse

    from torchmeshmetric.cli.options import ctc_options
    from torchmeshmetric.mpeg.ctc.settings import CtcSettings

    text = (REPO / "examples" / "ctc_campaign.toml").read_text()
    p = tmp_path / "m.toml"
    p.write_text(
        text.replace("min_pos = [-1, -1, -1]\nmax_pos = [1, 1, 1]", "min_pos = [-1, -1, 0]\nmax_pos = [1, 1, 0]", 1)
    )
    seq = load_ctc_campaign(p).sequences[0]
    assert (seq.min_pos, seq.max_pos, seq.resolution) == ((-1.0, -1.0, 0.0), (1.0, 1.0, 0.0), 2.0)
    args = argparse.Namespace(qp=10, qt=8, decoded_qt=0, min_pos="-1 -1 0", max_pos="1 1 0")
    assert ctc_options(args, []) == ([-1.0, -1.0, 0.0], [1.0, 1.0, 0.0])
    CtcSettings(qp=10, qt=8, min_pos=seq.min_pos, max_pos=seq.max_pos)
    with pytest.raises(ValueError, match=r"the box is a single point"):
        CtcSettings(qp=10, qt=8, min_pos=[1, 1, 1], max_pos=[1, 1, 1])
    with pytest.raises(ValueError, match=r"on x and z \(the box is a line"):  # review S: mm samples no point
        CtcSettings(qp=10, qt=8, min_pos=[1, -1, 1], max_pos=[1, 1, 1])
    p.write_text(
        text.replace("min_pos = [-1, -1, -1]\nmax_pos = [1, 1, 1]", "min_pos = [0, 0, -1]\nmax_pos = [0, 0, 1]", 1)
    )
    with pytest.raises(ValueError, match=r"'max_pos': \[0.0, 0.0, 1.0\] equals 'min_pos' .* on x and y"):
        load_ctc_campaign(p)


def test_clear_errors_of_the_campaign(
    campaign: tuple[Path, Path], tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture
) -> None:
    """Review R #10: each error names what the user wrote (the folder, the manifest and its key), once."""
    manifest, _ = campaign
    data = manifest.parent / "ctc-campaign-data"
    cache = ["--cache-dir", str(tmp_path / "c"), "--no-plots"]
    # --out-dir beside the input anchor.csv: it said "--out-dir 'anchor.csv' is the input anchor csv ..."
    assert main(["ctc-campaign", str(manifest), "--out-dir", str(data), "--overwrite", *cache]) == 1
    err = capsys.readouterr().err
    assert f"--out-dir {str(data)!r}: its {str(data / 'anchor.csv')!r} is the input [anchor] csv" in err, err
    # a missing codec CSV: "nope.csv: file not found", naming neither the manifest nor the key
    bad = manifest.parent / "nope.toml"
    bad.write_text(manifest.read_text().replace('csv = "ctc-campaign-data/anchor.csv"', 'csv = "nope.csv"'))
    assert main(["ctc-campaign", str(bad), "--out-dir", str(tmp_path / "o1"), *cache]) == 1
    err = capsys.readouterr().err
    assert f"CTC campaign manifest {str(bad)!r}: [anchor] 'csv': {str(manifest.parent / 'nope.csv')!r} not found" in err
    # a grid too fine for the memory: it named --grid-size, an option ctc-campaign does not have
    from torchmeshmetric.mpeg.sampling import grid_sampling

    monkeypatch.setattr(grid_sampling, "_available_memory", lambda: 1000)
    assert main(["ctc-campaign", str(manifest), "--out-dir", str(tmp_path / "o2"), *cache]) == 1
    err = capsys.readouterr().err
    assert f"CTC campaign manifest {str(manifest)!r}: [options] grid_size 128: the grid sampling would give" in err
    assert "--grid-size" not in err
    monkeypatch.undo()
    # a malformed decoded frame: the task was said twice, with a stray "path:"
    broken = manifest.parent / "broken"
    shutil.copytree(data / "sphere" / "test" / "r2", broken)
    with (broken / "dec_0001.obj").open("a") as fh:
        fh.write("f 1 2 99999\n")
    b2 = manifest.parent / "broken.toml"
    b2.write_text(
        manifest.read_text().replace(
            'decoded = "ctc-campaign-data/{sequence}/test/r{rate_id}/dec_%04d.obj"', 'decoded = "broken/dec_%04d.obj"'
        )
    )
    assert main(["ctc-campaign", str(b2), "--out-dir", str(tmp_path / "o3"), *cache]) == 1
    line = next(x for x in capsys.readouterr().err.splitlines() if "error:" in x)
    assert line.count("frame 1") == 1 and "path:" not in line and "vertex index 99999" in line, line


def test_frames_with_the_same_inputs_are_not_counted_from_the_cache(
    tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    # Review R #11: with the anchor's and test's decoded files the same and an empty cache, it said "2 frames, 1
    # computed, 1 from the cache": the frame computed once for both was counted as read from the cache.
    manifest = _make(tmp_path)
    text = (
        manifest.read_text()
        .replace("frame_count = 5", "frame_count = 1")
        .replace("/test/r{rate_id}", "/anchor/r{rate_id}")
    )
    manifest.write_text(text)
    args = ["ctc-campaign", str(manifest), "--out-dir", str(tmp_path / "out"), "--no-plots"]
    assert main(args) == 0
    assert "ctc-campaign: 8 frames, 4 computed (" in (err := capsys.readouterr().err)
    assert "s of chains), 0 from the cache, 4 the same as another frame of the campaign; " in err
    assert main([*args, "--overwrite"]) == 0
    assert "s of chains), 4 from the cache, 4 the same as another frame of the campaign; " in capsys.readouterr().err
