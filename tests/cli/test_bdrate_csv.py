"""bdrate given a CSV that is no rate curve: the error shows the header found (review O, finding F-bdrate-tm-csv)."""

from __future__ import annotations

from pathlib import Path

import pytest

from torchmeshmetric.cli import main
from torchmeshmetric.mpeg.ctc.sheet import RatePoint, format_test_model_csv


def _test_model_csv(path: Path, shift: float) -> str:
    # what ctc-campaign writes as anchor.csv / test.csv (cli/ctc_campaign.py: format_test_model_csv of its rows)
    points = [
        RatePoint(1, 3, r, 1000.0 * 2**r, {"GridD1": 60.0 + r + shift, "GridD2": 64.0 + r + shift}, 500)
        for r in (1, 2, 3)
    ]
    path.write_text(format_test_model_csv(points))
    return str(path)


def test_the_campaigns_own_csvs_are_refused_saying_where_their_bd_rates_are(tmp_path, capsys):
    # A codec engineer's first try: `bdrate anchor.csv test.csv` on ctc-campaign's outputs. It said "expected a
    # header with a 'rate' column", naming neither the header found nor what to pass.
    anchor, test = _test_model_csv(tmp_path / "anchor.csv", 0.0), _test_model_csv(tmp_path / "test.csv", 0.5)
    assert main(["bdrate", anchor, test]) == 1
    err = capsys.readouterr().err
    header = Path(anchor).read_text().splitlines()[0]
    assert header.startswith("SeqId,CondId,RateId,NbOutputFaces,TotalBitstreamBits,GridD1")
    assert f"torchmeshmetric bdrate: error: {anchor}:1: expected a header with a 'rate' column" in err, err
    assert f"found the test model's CSV header {header!r}" in err and "ctc-campaign's summary.csv" in err, err


@pytest.mark.parametrize(
    ("text", "found"),
    [
        ("bitrate,GridD1\n100,30\n200,33\n", "found the header 'bitrate,GridD1'"),
        ("Rate;GridD1\n100;30\n200;33\n", "found the header 'Rate;GridD1'"),  # another separator: one column
        ("", "found an empty file"),
    ],
)
def test_a_csv_without_a_rate_column_shows_its_header(tmp_path, capsys, text, found):
    good = tmp_path / "a.csv"
    good.write_text("rate,GridD1\n100,30\n200,33\n400,36\n")
    bad = tmp_path / "b.csv"
    bad.write_text(text)
    assert main(["bdrate", str(good), str(bad)]) == 1
    err = capsys.readouterr().err
    expected = "expected a header with a 'rate' column and one column per metric (one row per rate point)"
    assert f"{bad}:1: {expected}, {found}" in err, err
