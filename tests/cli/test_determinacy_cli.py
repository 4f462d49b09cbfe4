"""``--determinacy`` on evaluate and compare: a second run on nudged frames decides the tables' digits."""

from __future__ import annotations

import json

import pytest
import torch

from tests.cli.cli_helpers import Counting, write_frames
from torchmeshmetric.cli import main
from torchmeshmetric.data.sequence import load_sequence


def _row(markdown: str, table: str, mesh: str) -> list[str]:
    """The cells of one row (``mesh``: ``(k-1)-th``, ``k-th``, ``flicker``) of the table titled ``table``."""
    section = markdown.split(f"{table}\n")[1].split("\n\n")[0]
    line = next(line for line in section.splitlines() if line.startswith(f"| simp | {mesh} |"))
    return line.strip("| ").split(" | ")[2:]


REVERSE_SURFACE = "reference -> simplified, mesh surface distance"
REVERSE_VERTEX = "reference -> simplified, nearest vertex distance"


def test_evaluate_determinacy_float32(capsys, tmp_path, sequence, known_registration):
    orig, simp = sequence
    plain, nudged = tmp_path / "plain.json", tmp_path / "nudged.json"
    assert main(["evaluate", "--original", str(orig), "--simplified", str(simp), "--out", str(plain)]) == 0
    calls = known_registration.calls
    argv = ["evaluate", "--original", str(orig), "--simplified", str(simp), "--out", str(nudged)]
    assert main([*argv, "--determinacy", "float32"]) == 0
    err = capsys.readouterr().err
    assert "--determinacy float32: evaluating again on nudged frames" in err
    assert known_registration.calls == 3 * calls  # the run, then the run and its nudged twin
    report = json.loads(nudged.read_text())
    assert report["settings"]["determinacy"] == "float32"
    determinacy = report["determinacy"]
    assert determinacy["rounding"] == "float32" and determinacy["seed"] == 0
    changes = determinacy["changes"]
    assert [len(changes[t]) for t in ("I", "II", "III", "IV", "III-reverse", "IV-reverse")] == [4, 3, 4, 3, 4, 3]
    # The spheres' reverse distances (~0.03) move by 5.5e-7 (relative) under a float32 nudge (measured,
    # 2026-12-05): every digit holds, the row is the plain run's.
    assert 0 < changes["III-reverse"][1]["ave"] < 1e-5
    md, plain_md = nudged.with_suffix(".md").read_text(), plain.with_suffix(".md").read_text()
    assert _row(md, REVERSE_SURFACE, "k-th") == _row(plain_md, REVERSE_SURFACE, "k-th")
    assert not any(cell.startswith("~") for cell in _row(md, REVERSE_SURFACE, "k-th"))
    # The simplified vertices are vertices of frame k: the storage keeps them there, and so does the nudge (a
    # function of the stored value), so their distances stay exactly 0 and every digit holds.
    table_iii = "Table III: average over pairs, mesh surface distance"
    assert changes["III"][1]["ave"] == 0.0 and _row(md, table_iii, "k-th") == _row(plain_md, table_iii, "k-th")
    # The (k-1)-th distances are the registered translation's rounding, ~1e-8: the nudge moves them by half (0.52,
    # measured), so not even their first digit is the input's.
    assert changes["III"][0]["ave"] > 0.1
    assert all(cell.startswith("~") for cell in _row(md, table_iii, "(k-1)-th"))
    assert "this run's input determines" in md and "this run's input determines" not in plain_md


def test_coarse_rounding_leaves_fewer_digits(capsys, tmp_path, sequence, known_registration):
    orig, simp = sequence
    out = tmp_path / "r.json"
    argv = ["evaluate", "--original", str(orig), "--simplified", str(simp), "--out", str(out), "--determinacy", "1"]
    assert main(argv) == 0
    changes = json.loads(out.read_text())["determinacy"]["changes"]
    md = out.with_suffix(".md").read_text()
    # A nudge of up to 0.1 on spheres of radius 1 (measured, 2026-12-05): the reverse surface distances' average
    # moves by 0.32 (no digit holds), the reverse nearest-vertex one of the (k-1)-th mesh by 0.070 (one digit).
    assert 0.1 < changes["III-reverse"][1]["ave"] < 1
    assert _row(md, REVERSE_SURFACE, "k-th")[0].startswith("~")
    assert 0.01 < changes["IV-reverse"][0]["ave"] < 0.1
    ave = _row(md, REVERSE_VERTEX, "(k-1)-th")[0]
    assert not ave.startswith("~") and len(ave.replace("0.", "").lstrip("0")) == 1


def test_compare_determinacy(capsys, tmp_path, sequence, known_registration):
    orig, simp = sequence
    argv = ["compare", "--original", str(orig), "--method", f"A={simp}", "--method", f"B={simp}"]
    assert main([*argv, "--determinacy", "6"]) == 0
    out = capsys.readouterr().out
    assert known_registration.calls == 4 and "this run's input determines" in out
    # Identical methods: every verdict "inconclusive", on the nudged frames too.
    note = out.split("Verdicts on the frames nudged by --determinacy: ")[1].split("\n")[0]
    total = int(note.split(" of ")[1].split()[0])
    assert (
        note.startswith(f"{total} of {total} the same. Differences, half-widths and noise floors keep") and total > 10
    )


def test_compare_marks_verdicts_the_nudge_changes(capsys, tmp_path, known_registration):
    orig = write_frames(tmp_path / "orig", 3)
    a, b = write_frames(tmp_path / "a", 1), write_frames(tmp_path / "b", 2)
    out = tmp_path / "c.json"
    argv = ["compare", "--original", str(orig), "--method", f"A={a}", "--method", f"B={b}", "--out", str(out)]
    assert main([*argv, "--determinacy", "1"]) == 0
    entries = json.loads(out.read_text())["comparisons"]["A vs B"]
    verdicts = {(s, st): (e["verdict"], e["nudged_verdict"]) for s, es in entries.items() for st, e in es.items()}
    changed = {key for key, (run, nudged) in verdicts.items() if run != nudged}
    # A nudge of up to 0.1 on unit spheres moves the reverse distances by tens of percent (measured, 2026-12-06:
    # 11 of 50 verdicts change, among them every called reverse surface_k one).
    assert changed and len(changed) < len(verdicts)
    md = out.with_suffix(".md").read_text()
    table = md.split("### A vs B")[1].split("\n\n")[1].splitlines()
    header = [c.strip() for c in table[0].strip("|").split("|")][1:]
    marked = set()
    for line in table[2:]:
        cells = [c.strip() for c in line.strip("|").split("|")]
        marked |= {(cells[0].removesuffix(" *"), st) for st, c in zip(header, cells[1:], strict=True) if c[:1] == "~"}
    assert marked == changed
    assert f"Verdicts on the frames nudged by --determinacy: {len(verdicts) - len(changed)} of {len(verdicts)}" in md
    # The noise floors (registration residuals: other fits on the nudged frames) are kept from both runs, and the
    # list under the table prints each with the digits the two share.
    from torchmeshmetric.evaluation.determinacy import shared_cell

    floored = {s: es for s, es in entries.items() if any("noise_floor" in e for e in es.values())}
    assert floored and all("nudged_noise_floor" in e for es in floored.values() for e in es.values())
    floors = md.split("\\* noise floor (registration residual, or its error when known): ")[1].split("\n")[0]
    for set_name, es in floored.items():
        cells = ", ".join(
            f"{st} {shared_cell(e['noise_floor'], e['nudged_noise_floor'], '#.3g')}" for st, e in es.items()
        )
        assert f"{set_name}: {cells}" in floors


@pytest.mark.parametrize("bad", ["float16", "-2", "16", "x", "\u0663", "\u00b2"])  # Arabic-Indic 3, superscript 2
def test_bad_rounding_is_an_argument_error(capsys, sequence, bad):
    orig, simp = sequence
    with pytest.raises(SystemExit) as exit_info:
        main(["evaluate", "--original", str(orig), "--simplified", str(simp), f"--determinacy={bad}"])
    assert exit_info.value.code == 2
    err = capsys.readouterr().err
    assert "--determinacy: expected 'float32' or a number of decimals 0..15" in err and repr(bad) in err


def test_temporal_section_keeps_the_digits_both_runs_share(capsys, tmp_path, sequence, known_registration):
    from torchmeshmetric.evaluation.determinacy import Determinacy, nudge_frames, relabel_frames
    from torchmeshmetric.temporal.figures import FIGURE_NAMES, temporal_figures
    from torchmeshmetric.temporal.report import FIGURE_DIGITS_NOTE, FIGURE_FORMATS, format_figure

    orig, simp = sequence
    out = tmp_path / "r.json"
    argv = ["evaluate", "--original", str(orig), "--simplified", str(simp), "--out", str(out), "--temporal"]
    assert main([*argv, "--determinacy", "float32"]) == 0
    printed = capsys.readouterr().out
    # The temporal figures of both runs reuse their runs' registrations: 2 pairs, twice.
    assert known_registration.calls == 4
    report = json.loads(out.read_text())
    figures, (changes,) = report["temporal"]["simp"], report["determinacy"]["changes"]["temporal"]
    load = [load_sequence(str(d), dtype=torch.float32) for d in (orig, simp)]
    # the second run's frames: nudged, and stored in another order (review L: the registrations follow it)
    moved = [relabel_frames(nudge_frames(frames, "float32")) for frames in load]
    again = temporal_figures(*moved, registration_fn=Counting())
    for name in FIGURE_NAMES:
        a, b = figures[name], getattr(again, name)
        assert changes[name] == abs(a - b) / max(abs(a), abs(b))  # the same frames and registrations: the same bits
    assert report["determinacy"]["nudged"]["temporal"] == [{k: getattr(again, k) for k in FIGURE_NAMES}]
    determinacy = Determinacy(
        "float32", 0, {"temporal": [changes]}, {"temporal": [{k: getattr(again, k) for k in FIGURE_NAMES}]}
    )
    want = [determinacy.cell("temporal", 0, k, figures[k], FIGURE_FORMATS[True][k]) for k in FIGURE_NAMES]
    for text in (printed, out.with_suffix(".md").read_text()):
        line = next(line for line in text.split("## Temporal metrics")[1].splitlines() if line.startswith("| simp |"))
        assert line.strip("| ").split(" | ")[1:-1] == want
        assert "this run's input determines: the figures were computed again" in text and FIGURE_DIGITS_NOTE not in text
    # KG of the translated spheres moves by ~2.5e-7 (measured, 2026-12-06): its 3 registered digits hold; STED_t is
    # the exact translation's rounding (~8e-8) and moves by 0.55: not one of its digits is the input's.
    assert changes["kg"] < 1e-5 and want[0] == format_figure("kg", figures["kg"], registered=True)
    assert changes["sted_t"] > 0.1 and want[FIGURE_NAMES.index("sted_t")].startswith("~")


def test_a_rerun_resumes_the_nudged_registrations_apart_from_the_inputs(capsys, tmp_path, sequence, known_registration):
    orig, simp = sequence
    cache = tmp_path / "cache"
    argv = ["evaluate", "--original", str(orig), "--simplified", str(simp), "--cache-dir", str(cache)]
    (tmp_path / "a").mkdir(), (tmp_path / "b").mkdir()
    assert main([*argv, "--determinacy", "float32", "--out", str(tmp_path / "a" / "r.json")]) == 0
    # 2 original pairs, registered on the input's frames and on the nudged ones (cache/determinacy)
    assert known_registration.calls == 4
    assert len(list(cache.glob("*.pt"))) == 2 and len(list((cache / "determinacy").glob("*.pt"))) == 2
    assert main([*argv, "--determinacy", "float32", "--out", str(tmp_path / "b" / "r.json")]) == 0
    assert known_registration.calls == 4  # both runs resumed from the cache
    assert (tmp_path / "a" / "r.md").read_text() == (tmp_path / "b" / "r.md").read_text()
    assert main(argv) == 0 and known_registration.calls == 4  # without --determinacy: the input's entries alone


def test_a_unit_finer_than_the_frames_dtype_is_said(capsys, sequence, known_registration):
    orig, simp = sequence
    argv = ["evaluate", "--original", str(orig), "--simplified", str(simp)]
    # unit spheres in float32: spacing 6e-8 to 1.2e-7, finer than 9 decimals but for the exact zeros
    assert main([*argv, "--determinacy", "9"]) == 0
    err = capsys.readouterr().err
    assert "--determinacy 9: one unit is finer than the float32 frames hold at " in err
    assert "those move by one float32 unit instead (--dtype float64 to measure the file's decimals)" in err
    for quiet in (["--determinacy", "float32"], ["--determinacy", "9", "--dtype", "float64"]):
        assert main([*argv, *quiet]) == 0
        assert "is finer than" not in capsys.readouterr().err


def test_the_note_names_the_json_that_keeps_the_full_values(capsys, tmp_path, sequence, known_registration):
    orig, simp = sequence
    argv = ["evaluate", "--original", str(orig), "--simplified", str(simp)]
    assert main(argv) == 0  # printed, no JSON written: the note says which option writes it
    assert "Compare methods to those digits; the JSON report (--out) keeps the full values." in capsys.readouterr().out
    assert main([*argv, "--out", str(tmp_path / "walk.json"), "--determinacy", "float32"]) == 0
    printed, md = capsys.readouterr().out, (tmp_path / "walk.md").read_text()
    for text in (printed, md):
        assert "walk.json keeps the full values and, under 'determinacy'" in text and "report.json" not in text


def test_the_rounding_is_recorded_canonically(tmp_path, sequence, known_registration):
    orig, simp = sequence
    out = tmp_path / "r.json"
    argv = ["evaluate", "--original", str(orig), "--simplified", str(simp), "--out", str(out), "--determinacy", "015"]
    assert main(argv) == 0
    report = json.loads(out.read_text())
    assert report["settings"]["determinacy"] == "15" and report["determinacy"]["rounding"] == "15 decimals"
