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


@pytest.mark.parametrize(
    ("header", "rows", "column", "where"),
    [
        ("rate,GridD1,GridD1", ("100,30,1", "200,33,2", "400,36,3"), "GridD1", "columns 2 and 3"),
        ("rate,GridD1,rate", ("100,30,1", "200,33,2", "400,36,3"), "rate", "columns 1 and 3"),
    ],
)
def test_a_column_named_twice_is_refused(tmp_path, capsys, header, rows, column, where):
    # Review X, F1: csv.DictReader kept the last of two equal names, so `rate,GridD1,GridD1` gave the third column's
    # BD-rate (+100 %) and a repeated `rate` +900 %, exit 0, without a word.
    good = tmp_path / "a.csv"
    good.write_text("rate,GridD1\n100,30\n200,33\n400,36\n")
    dup = tmp_path / "dup.csv"
    dup.write_text("\n".join((header, *rows)) + "\n")
    assert main(["bdrate", str(good), str(dup)]) == 1
    err = capsys.readouterr().err
    assert f"{dup}:1: column {column!r} appears twice in the header ({where}); which of the two is meant" in err, err


def test_a_csv_that_is_not_utf8_is_read_as_latin1_and_errors_name_file_and_line(tmp_path, capsys):
    # Review X, F2: "'utf-8' codec can't decode byte 0xff in position 12", naming neither file nor line. Now read
    # as the mesh readers read text (UTF-8, else Latin-1): a Latin-1 column name works, a bad cell names its line.
    good = tmp_path / "a.csv"
    good.write_text("rate,GridD1\n100,30\n200,33\n400,36\n")
    latin = tmp_path / "latin.csv"
    latin.write_bytes(b"rate,GridD1,Qualit\xe9\n100,30,1\n200,33,2\n400,36,3\n")
    assert main(["bdrate", str(good), str(latin)]) == 0
    assert capsys.readouterr().out.startswith("GridD1  +0.0000 %")
    latin.write_bytes(b"rate,GridD1\n\xff100,30\n200,33\n")
    assert main(["bdrate", str(good), str(latin)]) == 1
    err = capsys.readouterr().err
    assert f"{latin}:2: column 'rate': expected a number, found '\xff100'" in err, err
