from __future__ import annotations

import json

from tests.cli.cli_helpers import Counting, write_frames
from torchmeshmetric.cli import main
from torchmeshmetric.data.sequence import load_sequence
from torchmeshmetric.temporal import temporal_figures
from torchmeshmetric.temporal.report import FIGURE_DIGITS_NOTE


def test_evaluate_and_compare_report_the_temporal_figures(capsys, tmp_path, sequence, known_registration):
    orig, simp = sequence
    out = tmp_path / "report.json"
    assert main(["evaluate", "--original", str(orig), "--simplified", str(simp), "--out", str(out), "--temporal"]) == 0
    printed = capsys.readouterr().out
    assert known_registration.calls == 2  # the 2 original pairs, registered once for the tables and the figures
    want = temporal_figures(load_sequence(str(orig)), load_sequence(str(simp)), registration_fn=Counting())
    got = json.loads(out.read_text())["temporal"]["simp"]
    assert got == want.as_dict() and got["registered"] is True
    markdown = (tmp_path / "report.md").read_text()
    for text in (printed, markdown):
        # The registered form's digits (FIGURE_FORMATS: 3 significant for KG, KSO and STED_t, 2 for STED_s and STED:
        # what float32 rounding leaves; the registrations draw independently of the storage order), and why.
        digits = (("kg", 3), ("kso", 3), ("sted_s", 2), ("sted_t", 3), ("sted", 2))
        row = "| simp | " + " | ".join(format(getattr(want, k), f"#.{n}g") for k, n in digits) + " |"
        assert "## Temporal metrics (KG, KSO, STED" in text and row in text and FIGURE_DIGITS_NOTE in text
    other = write_frames(tmp_path / "other", 0)
    out2 = tmp_path / "compare.json"
    argv = ["compare", "--original", str(orig), "--method", f"A={simp}", "--method", f"B={other}", "--out", str(out2)]
    assert main([*argv, "--temporal"]) == 0
    assert sorted(json.loads(out2.read_text())["temporal"]) == ["A", "B"]
    assert main([*argv[:-2], "--out", str(tmp_path / "plain.json")]) == 0  # without --temporal: no section
    assert "temporal" not in json.loads((tmp_path / "plain.json").read_text())
