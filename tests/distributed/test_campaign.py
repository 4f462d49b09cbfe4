"""``torchmeshmetric campaign MANIFEST`` in one process: combined and per-sequence reports, manifest errors."""

import json
import math
import re

import pytest

import tests.distributed.helpers as known
from tests.cli.cli_helpers import write_frames
from tests.distributed.helpers import without_timings
from torchmeshmetric.cli import main
from torchmeshmetric.cli._shared import fast_registration_options
from torchmeshmetric.evaluation.campaign import ManifestError, load_campaign
from torchmeshmetric.evaluation.determinacy import shared_cell, value_change
from torchmeshmetric.evaluation.reports import COLUMN_FORMATS

MANIFEST = """
[options]
two_sided = true

[[sequences]]
name = "walk"
original = "walk/orig"
methods = {{ fine = "walk/fine", coarse = "walk/coarse" }}

[[sequences]]
name = "run fast"
original = "run/orig"
methods = {{ fine = "run/fine" }}
{extra}
"""


@pytest.fixture(autouse=True)
def exact_registration(monkeypatch):
    monkeypatch.delenv("TMM_TEST_CALLS", raising=False)
    monkeypatch.setattr("torchmeshmetric.evaluation.pipeline.default_register", known.register)


@pytest.fixture
def campaign(tmp_path):
    for seq, n in (("walk", 4), ("run", 3)):
        (tmp_path / seq).mkdir()
        write_frames(tmp_path / seq / "orig", 2, n=n)
        write_frames(tmp_path / seq / "fine", 1, n=n)
        if seq == "walk":
            write_frames(tmp_path / seq / "coarse", 0, n=n)
    path = tmp_path / "campaign.toml"
    path.write_text(MANIFEST.format(extra=""))
    return path


def test_campaign_writes_combined_and_per_sequence_reports_equal_to_compare(tmp_path, campaign, capsys):
    out = tmp_path / "report"
    assert main(["campaign", str(campaign), "--out-dir", str(out)]) == 0
    stdout, _ = capsys.readouterr()
    assert "| overall | coarse | k-th |" in stdout and "| run fast | fine | (k-1)-th |" in stdout
    names = sorted(p.name for p in out.iterdir())
    assert names == sorted(f"{s}.{e}" for s in ("campaign", "walk", "run_fast") for e in ("json", "md", "csv"))
    # each sequence's report is the compare command's report for it (of the same name: the note names its JSON), with
    # the manifest's default registration = "full", the one compare runs ("fast": the next test)
    walk = tmp_path / "walk"
    (tmp_path / "compare").mkdir()
    assert main(["compare", "--original", str(walk / "orig"), "--method", f"fine={walk / 'fine'}", "--method",
                 f"coarse={walk / 'coarse'}", "--out", str(tmp_path / "compare" / "walk.json")]) == 0  # fmt: skip
    got, want = (json.loads(p.read_text()) for p in (out / "walk.json", tmp_path / "compare" / "walk.json"))
    assert without_timings(got["methods"]) == without_timings(want["methods"])
    for ext in ("md", "csv"):
        assert (out / f"walk.{ext}").read_text() == (tmp_path / "compare" / f"walk.{ext}").read_text()
    # overall: per method, the mean over the sequences it ran on of each sequence's average
    combined = json.loads((out / "campaign.json").read_text())
    seq = {
        name: json.loads((out / f"{stem}.json").read_text())
        for name, stem in (("walk", "walk"), ("run fast", "run_fast"))
    }
    assert combined["overall"]["coarse"]["sequences"] == ["walk"]
    assert combined["overall"]["fine"]["sequences"] == ["walk", "run fast"]
    for field in ("ave", "rmse", "max", "p95"):
        parts = [seq[s]["methods"]["fine"]["aggregate"]["surface_k_minus_1"][field] for s in ("walk", "run fast")]
        assert combined["overall"]["fine"]["surface_k_minus_1"][field] == math.fsum(parts) / 2
        assert combined["sequences"]["run fast"]["methods"]["fine"]["aggregate"]["surface_k_minus_1"][field] == parts[1]
    rows = (out / "campaign.csv").read_text().splitlines()
    assert rows[0] == "table,sequence,algorithm,set,ave,var,std,mse,rmse,max,p95,psnr"
    overall_rows = [r for r in rows if r.startswith("III,overall,fine,surface_k_minus_1,")]
    assert len(overall_rows) == 1
    ave = combined["overall"]["fine"]["surface_k_minus_1"]["ave"]
    assert float(overall_rows[0].split(",")[4]) == ave
    # a second run without --overwrite refuses before computing; with it, replaces
    capsys.readouterr()
    assert main(["campaign", str(campaign), "--out-dir", str(out)]) == 1
    assert "already exists" in capsys.readouterr().err
    assert main(["campaign", str(campaign), "--out-dir", str(out), "--overwrite"]) == 0


def test_fast_registration_reports_differ_from_compare_in_the_registered_rows(tmp_path, campaign, monkeypatch):
    # docs/scaling.md (review O, F-campaign-vs-compare): the per-sequence report is compare's with registration =
    # "full" (above); compare has no --registration, so under "fast" every registered row differs, the k-th rows not
    def register(source, target, *, device=None, **options):
        done = known.register(source, target, device=device)
        fast = options.get("num_points") == fast_registration_options()["num_points"]
        return done._replace(verts=done.verts + 0.01) if fast else done  # "fast" lands elsewhere

    monkeypatch.setattr("torchmeshmetric.evaluation.pipeline.default_register", register)
    fast = MANIFEST.format(extra="").replace("two_sided = true", 'two_sided = true\nregistration = "fast"')
    campaign.write_text(fast)
    assert main(["campaign", str(campaign), "--out-dir", str(tmp_path / "report")]) == 0
    walk = tmp_path / "walk"
    (tmp_path / "compare").mkdir()
    assert main(["compare", "--original", str(walk / "orig"), "--method", f"fine={walk / 'fine'}", "--method",
                 f"coarse={walk / 'coarse'}", "--out", str(tmp_path / "compare" / "walk.json")]) == 0  # fmt: skip
    got, want = ((tmp_path / d / "walk.md").read_text().splitlines() for d in ("report", "compare"))
    assert len(got) == len(want)
    rows = [g for g, w in zip(got, want, strict=True) if g.startswith("| ") and g != w]  # tables and comparisons
    assert rows and all(any(s in g for s in ("(k-1)-th", "flicker", "Registration", "k_minus_1")) for g in rows), rows
    for mesh in ("| k-th |", "| (k-1)-th |", "| flicker |"):
        mine = [g for g in got if mesh in g]
        assert mine and (mine == [w for w in want if mesh in w]) == (mesh == "| k-th |"), mesh


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        ("[options.more]\nx = 1", "unknown option 'more'"),
        ('[[sequences]]\nname = "walk"\noriginal = "x"\nmethods = { a = "y" }', "same report file name 'walk'"),
        ('[[sequences]]\nname = "campaign"\noriginal = "x"\nmethods = { a = "y" }', "reserved"),
        # found by review E: "overall" labelled both a sequence's rows and the rows over all sequences
        ('[[sequences]]\nname = "overall"\noriginal = "x"\nmethods = { a = "y" }', "sequence 'overall': the name"),
        ('[[sequences]]\nname = " Overall"\noriginal = "x"\nmethods = { a = "y" }', "rows over all sequences"),
        # found by review E: an empty method name made rows "| s |  | k-th |" and a verdict titled "  vs B"
        (
            '[[sequences]]\nname = "z"\noriginal = "x"\nmethods = { "" = "y" }',
            "sequence 'z': 'methods' has an empty method name ''",
        ),
        ('[[sequences]]\nname = "z"\noriginal = "x"\nmethods = { " " = "y" }', "empty method name ' '"),
        (
            '[[sequences]]\nname = " "\noriginal = "x"\nmethods = { a = "y" }',
            "'name' must be a non-empty string, found ' '",
        ),
        ('[[sequences]]\nname = "z"\noriginal = "x"\nmethods = {}', "'methods' must be a table"),
        ('[[sequences]]\nname = "z"\noriginal = "x"\nmethods = { a = 3 }', "method 'a' must be a folder"),
        ("[[sequences]]\noriginal = 'x'", "'name' must be a non-empty string"),
        ("colour = 'red'", "unknown key 'colour'"),
        ("x = = 1", "(at line 16"),
    ],
)
def test_manifest_errors_name_the_file_and_the_key(tmp_path, campaign, extra, message):
    campaign.write_text(MANIFEST.format(extra="") + "\n" + extra + "\n")
    with pytest.raises(ManifestError, match="campaign manifest") as info:
        load_campaign(campaign)
    assert message in str(info.value)


def test_campaign_errors_are_one_line_before_any_work(tmp_path, campaign, capsys):
    (tmp_path / "run" / "fine" / "frame_02.ply").unlink()
    assert main(["campaign", str(campaign), "--out-dir", str(tmp_path / "out")]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    fine, orig = str(tmp_path / "run" / "fine"), str(tmp_path / "run" / "orig")
    assert err == [f"torchmeshmetric campaign: error: sequence 'run fast': method 'fine' {fine!r}: 2 frames but "
                   f"sequence 'run fast': original {orig!r} has 3 (must match; the original frames run from 0 to 2, "
                   "these from 0 to 1): frame 2 of the original frames ('frame_02.ply') is missing here"]  # fmt: skip
    assert not (tmp_path / "out").exists()
    assert main(["campaign", str(tmp_path / "nope.toml")]) == 1
    assert "no such file" in capsys.readouterr().err
    campaign.write_text(MANIFEST.format(extra="").replace('"run/orig"', '"run/missing"'))
    assert main(["campaign", str(campaign)]) == 1
    assert "sequence 'run fast': original" in capsys.readouterr().err


def _cells(markdown: str, title: str, first: str) -> dict[tuple[str, str], list[str]]:
    """The rows of the table titled ``title`` whose first cell is ``first``: (algorithm, mesh) -> statistic cells."""
    section = markdown.split(f"### {title}\n\n")[1].split("\n\n")[0]
    rows = [[c.strip() for c in line.strip("|").split("|")] for line in section.splitlines()[2:]]
    return {(r[1], r[2]): r[3:] for r in rows if r[0] == first}


def test_determinacy_digits_are_each_sequence_reports_digits(tmp_path, campaign, capsys):
    out = tmp_path / "report"
    assert main(["campaign", str(campaign), "--out-dir", str(out), "--determinacy", "1", "--temporal"]) == 0
    stdout, err = capsys.readouterr()
    assert "--determinacy 1: evaluating again on nudged frames" in err
    # one temporal section per sequence, each named; one line for the files, once the whole set is written
    assert "## Temporal metrics of sequence 'walk'" in stdout and "## Temporal metrics of sequence 'run fast'" in stdout
    assert [line for line in err.splitlines() if line.startswith("wrote")] == [
        f"wrote {out / 'campaign'}.json/.md/.csv and one report per sequence"
    ]
    combined = json.loads((out / "campaign.json").read_text())
    assert combined["settings"]["determinacy"] == "1"
    changes = combined["determinacy"]["changes"]
    assert combined["determinacy"]["rounding"] == "1 decimal"
    # rows: per sequence (walk: 2 methods, run fast: 1) and overall (2 methods), each (k-1)-th and k-th
    assert {t: len(rows) for t, rows in changes.items()} == {"III": 10, "IV": 10, "III-reverse": 10, "IV-reverse": 10}
    # A nudge of up to 0.1 on unit spheres moves the reverse surface distances by tens of percent (measured on the
    # compare command's spheres, tests/cli/test_determinacy_cli.py): some first digits move, and are marked.
    assert max(row["ave"] for row in changes["III-reverse"]) > 0.1
    md = (out / "campaign.md").read_text()
    assert stdout.split("## Temporal")[0].count("| ~") == md.count("| ~") > 0
    assert "this run's input determines" in md and "campaign.json keeps the full values" in md
    # each sequence's report is compare --determinacy's for it, and its Table III cells are the combined ones
    walk = tmp_path / "walk"
    (tmp_path / "compare").mkdir()
    argv = ["compare", "--original", str(walk / "orig"), "--method", f"fine={walk / 'fine'}", "--method",
            f"coarse={walk / 'coarse'}", "--out", str(tmp_path / "compare" / "walk.json"), "--determinacy", "1",
            "--temporal"]  # fmt: skip
    assert main(argv) == 0
    got, want = (json.loads(p.read_text()) for p in (out / "walk.json", tmp_path / "compare" / "walk.json"))
    assert got["determinacy"] == want["determinacy"] and len(got["determinacy"]["changes"]["temporal"]) == 2
    assert (out / "walk.md").read_text() == (tmp_path / "compare" / "walk.md").read_text()
    sequence_md = (out / "walk.md").read_text()
    table_iii = "Table III: average over pairs, mesh surface distance"
    walk_rows = _cells(md, "Average over pairs, mesh surface distance (Table III)", "walk")
    assert list(walk_rows) == [("fine", "(k-1)-th"), ("fine", "k-th"), ("coarse", "(k-1)-th"), ("coarse", "k-th")]
    for (method, mesh), cells in walk_rows.items():
        line = next(r for r in sequence_md.split(table_iii)[1].splitlines() if r.startswith(f"| {method} | {mesh} |"))
        assert cells == [c.strip() for c in line.strip("|").split("|")][2:]
    # the overall rows: their own change, not their sequences'
    reverse = "Two-sided check: average over pairs, reference -> simplified, mesh surface distance"
    overall = _cells(md, reverse, "overall")
    assert list(overall) == list(walk_rows)
    for i, ((method, mesh), cells) in enumerate(overall.items(), start=6):
        value = combined["overall"][method]["reverse"]["surface_k" if mesh == "k-th" else "surface_k_minus_1"]["ave"]
        again = combined["determinacy"]["nudged"]["III-reverse"][i]["ave"]
        assert changes["III-reverse"][i]["ave"] == value_change(value, again)
        # what both runs print, to the digits of every row (COLUMN_FORMATS)
        assert cells[0] == shared_cell(value, again, COLUMN_FORMATS["ave"]), (cells[0], value, again)
    capsys.readouterr()
    assert main(["campaign", str(campaign)]) == 0
    plain = capsys.readouterr().out
    assert "campaign.json (--out-dir) keeps the full values" in plain and "this run's input determines" not in plain


def test_determinacy_rerun_resumes_the_nudged_registrations_from_the_cache(tmp_path, campaign, capsys, monkeypatch):
    calls = tmp_path / "calls"
    calls.mkdir()
    monkeypatch.setenv("TMM_TEST_CALLS", str(calls))  # one file per registration run
    cache = tmp_path / "cache"
    argv = ["campaign", str(campaign), "--cache-dir", str(cache), "--determinacy", "1"]
    assert main([*argv, "--out-dir", str(tmp_path / "first")]) == 0
    # walk: 3 original pairs, run: 2, the same frames as walk's first 2 (one cache: 3 registrations); each registered
    # on the input's frames and on the nudged ones, which go to their own folder: the cache's entries stay the input's.
    assert len(list(calls.iterdir())) == 6
    assert len(list(cache.glob("*.pt"))) == 3 and len(list((cache / "determinacy").glob("*.pt"))) == 3
    assert main([*argv, "--out-dir", str(tmp_path / "again")]) == 0
    assert len(list(calls.iterdir())) == 6  # a rerun resumes both runs: nothing registered again
    for name in ("campaign", "walk", "run_fast"):
        first, again = ((tmp_path / d / f"{name}.json").read_text() for d in ("first", "again"))
        # the same report but for the cache's word: the rerun's registrations were all found there
        assert '"cached": false' not in again
        first, again = (json.loads(re.sub('"cached": (true|false)', '"cached": null', t)) for t in (first, again))
        assert without_timings(first) == without_timings(again), name
        assert (tmp_path / "first" / f"{name}.md").read_text() == (tmp_path / "again" / f"{name}.md").read_text()


def test_an_out_dir_that_is_a_file_is_refused_before_any_evaluation(tmp_path, campaign, capsys, monkeypatch):
    calls = tmp_path / "calls"
    calls.mkdir()
    monkeypatch.setenv("TMM_TEST_CALLS", str(calls))
    notes = tmp_path / "notes.txt"
    notes.write_text("mine")
    for extra in ([], ["--overwrite"]):  # --overwrite replaces reports in the folder, never a file in its place
        assert main(["campaign", str(campaign), "--out-dir", str(notes), "--determinacy", "float32", *extra]) == 1
        err = capsys.readouterr().err
        assert f"--out-dir {str(notes)!r}: {str(notes)!r} is a file, not a folder" in err, err
    assert notes.read_text() == "mine" and not any(calls.iterdir())


def test_a_cache_folder_that_is_a_file_is_refused_before_any_evaluation(tmp_path, campaign, capsys, monkeypatch):
    calls = tmp_path / "calls"
    calls.mkdir()
    monkeypatch.setenv("TMM_TEST_CALLS", str(calls))
    (tmp_path / "regs").write_text("mine")
    text = campaign.read_text().replace("two_sided = true", 'two_sided = true\ncache_dir = "regs"')
    campaign.write_text(text)
    with pytest.raises(ManifestError, match=r"option 'cache_dir' must be a folder, found the file '.*regs'"):
        load_campaign(campaign)
    # --determinacy's folder in a cache given on the command line, or in the manifest's cache folder
    campaign.write_text(text.replace('"regs"', '"cache"'))
    (tmp_path / "cache").mkdir()
    (tmp_path / "cache" / "determinacy").write_text("mine")
    argv = ["campaign", str(campaign), "--determinacy", "float32"]
    assert main(argv) == 1
    assert "found the file" in capsys.readouterr().err and not any(calls.iterdir())
    (tmp_path / "other").mkdir()
    (tmp_path / "other" / "determinacy").write_text("mine")
    with pytest.raises(SystemExit):
        main([*argv, "--cache-dir", str(tmp_path / "other")])
    err = capsys.readouterr().err
    blocker = str(tmp_path / "other" / "determinacy")
    assert f"argument --cache-dir: expected a folder (created when needed), found the file {blocker!r}" in err
    assert not any(calls.iterdir())


def test_overall_psnr_leaves_a_lossless_sequence_out():
    # A sequence whose mean PSNR is inf (every pair lossless) made the overall PSNR inf (found by review E): the
    # library's rule (mean_psnr) is the mean over the finite ones; every other statistic stays the plain mean.
    from torchmeshmetric.evaluation.campaign import _mean

    out = _mean([{"surface_k": {"psnr": math.inf, "mse": 0.0}}, {"surface_k": {"psnr": 40.0, "mse": 1e-4}}])
    assert out == {"surface_k": {"psnr": 40.0, "mse": 5e-5}}
