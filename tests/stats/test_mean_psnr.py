"""mean_psnr: the one rule for a PSNR in a mean; +inf is left out and counted, NaN and -inf are refused."""

import math
from collections import namedtuple

import pytest

from torchmeshmetric.evaluation.results import mean_statistics
from torchmeshmetric.stats.statistics import mean_psnr


def test_infinite_psnrs_are_left_out_and_counted():
    assert mean_psnr([40.0, 50.0, math.inf]) == (45.0, 1)
    assert mean_psnr([math.inf, math.inf]) == (math.inf, 2)
    assert mean_psnr([30.0, 40.0]) == (35.0, 0)


@pytest.mark.parametrize(
    ("values", "position", "why"),
    [
        ([40.0, math.nan], 1, "a NaN PSNR is a bug upstream"),
        ([-math.inf, 40.0], 0, "a PSNR of -inf is impossible for a finite peak"),
        ([math.inf, math.nan], 1, "a NaN PSNR is a bug upstream"),
    ],
)
def test_nan_and_minus_inf_are_refused_naming_the_source(values, position, why):
    # review F, finding 7: mean_psnr([40, nan]) gave (40.0, 0) and mean_psnr([-inf, 40]) gave (40.0, 0): dropped,
    # neither counted nor propagated, in Tables III/IV's mean PSNR and a campaign's overall.
    with pytest.raises(ValueError, match=f"the frames' d1_psnr: PSNR .* at position {position} of 2 .*{why}"):
        mean_psnr(values, "the frames' d1_psnr")


def test_tables_mean_psnr_refuses_a_nan_pair_naming_the_pairs():
    stats = namedtuple("S", "ave psnr")
    assert mean_statistics([stats(1.0, 40.0), stats(3.0, math.inf)]) == {"ave": 2.0, "psnr": 40.0}
    with pytest.raises(ValueError, match="stats: the pairs' psnr: PSNR nan at position 1 of 2"):
        mean_statistics([stats(1.0, 40.0), stats(3.0, math.nan)])
