r"""Comparisons of simplification methods with confidence: paired differences over frame pairs.

For two methods ``A`` and ``B`` evaluated on the same original sequence, every set and every statistic gives one
number per frame pair ``k`` for each method. The **experimental unit is the frame pair**: the per-vertex distances
inside a pair are not independent samples of the sequence (neighbouring vertices share the same simplification
decisions and the same registration error), so a test over vertices would call a difference of a few parts per
million "significant" on any mesh of 20k vertices. We therefore work with the paired differences

.. math::

    d_k = s_A(k) - s_B(k), \qquad k = 1, \dots, n,

(``s`` a per-pair statistic such as ``ave``), report their mean :math:`\bar d` (which equals the difference of the
methods' aggregates, the means over pairs of Tables III/IV) and the paired Student *t* interval

.. math::

    \bar d \pm t_{0.975,\, n-1}\, \frac{s_d}{\sqrt n},

with :math:`s_d` the sample standard deviation of the :math:`d_k`. Why *t* and not a bootstrap or a sign-flip test:
sequences are often short (the paper and our demo have 5 pairs); with 5 units a percentile bootstrap has only 126
distinct resamples and its intervals are too narrow, and an exact sign-flip test cannot reach a two-sided
``p < 0.05`` at all (its smallest ``p`` is 2/32). The *t* interval is exact when the differences are normal and
independent, and robust to moderate non-normality; its limits are in ``docs/statistics.md``.

**A PSNR of inf** (a pair measured without error). A pair that both methods measure without error has no
difference in dB: it is left out of the PSNR's differences and counted (``"both_inf_pairs"``), as
:func:`~torchmeshmetric.stats.statistics.mean_psnr` leaves it out of each method's mean PSNR, so that :math:`\bar d`
is still the difference of the two means. A pair only one method measures without error is a difference of
``±inf``: one sign on every pair is a verdict, a sign that changes leaves the difference undefined.

**Verdict.** ``"<A> better"`` or ``"<B> better"`` only when the interval excludes 0 *and* the difference is above
the set's **noise floor**; otherwise ``"inconclusive"``. Lower is better for distances, higher for PSNR (any
statistic whose name contains ``psnr``). Noise floors:

* the sets measured against the registered frame ``k-1`` (``surface_k_minus_1``, ``vertex_k_minus_1``,
  ``flicker`` and their reverse sets) carry the registration's error: the floor of a distance statistic is the
  same statistic of the registration's residual (mean over pairs), or of its error to the true motion when that is
  known and larger; for a PSNR it is the PSNR change that moving the RMSE by the floor's RMSE would cause,
  :math:`20 \log_{10}((r + f) / r)` dB with ``r`` the smaller of the two methods' RMSE;
* every set also has a **relative margin** (``relative_margin``, default 2 %): differences smaller than that
  fraction of the better method's value are not called (the evaluation's own resolution: two simplifications that
  differ only by the sign of a constant normal offset of a fraction of the triangle size measure a few parts per
  thousand apart on a tessellated reference, consistently enough for a *t* interval to exclude 0; see
  ``docs/statistics.md``).

The comparison reads per-pair statistics from :meth:`SequenceEvaluation.as_dict` (or a report's JSON), so it is
generic over whatever sets and statistics a pair carries, including statistics other modules add (e.g. MPEG
PSNRs): every set-like entry (a mapping of statistic names to numbers) is compared.
"""

from __future__ import annotations

import functools
import itertools
import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from torchmeshmetric._checks import check_real
from torchmeshmetric._format import format_number, markdown_cell
from torchmeshmetric.evaluation.determinacy import shared_cell
from torchmeshmetric.evaluation.results import FLOOR_SET_NAMES, SequenceEvaluation
from torchmeshmetric.stats.statistics import mean_psnr

__all__ = [
    "DEFAULT_COMPARISON_STATISTICS",
    "comparison_markdown",
    "compare_methods",
    "with_nudged_verdicts",
    "paired_t_interval",
    "t_quantile",
]

#: Why a PSNR entry has no difference (``"difference": null``): one method measured a pair without error.
UNDEFINED_PSNR = (
    "a PSNR is inf (a pair measured without error) on some frame pairs and the difference changes sign: "
    "no mean difference in dB exists; compare the rmse"
)

#: Statistics compared by default (plus every statistic whose name contains ``psnr``).
DEFAULT_COMPARISON_STATISTICS: tuple[str, ...] = ("ave", "rmse", "max", "p95")

_NOT_SETS = ("frame", "registration", "timings", "peak")
_REVERSE = "reverse"


@functools.cache  # a pure function of (p, df): compare_methods asks for the same few quantiles hundreds of times
def t_quantile(p: float, df: int) -> float:
    """Quantile ``p`` in ``(0.5, 1)`` of Student's *t* distribution with ``df >= 1`` degrees of freedom.

    The density, written in ``theta = atan(x / sqrt(df))`` (a bounded, smooth integrand ``cos(theta)^(df-1)``), is
    integrated with 128-point Gauss-Legendre quadrature and the CDF inverted by bisection (relative error below
    1e-10 against ``scipy.stats.t.ppf`` for ``df`` 1 to 1000 and ``p`` up to 0.999, tested).

    Example:
        >>> round(t_quantile(0.975, 4), 4), round(t_quantile(0.975, 1), 3)
        (2.7764, 12.706)
    """
    if not 0.5 < p < 1.0:
        raise ValueError(f"p: expected a probability in (0.5, 1), found {p!r}")
    if df < 1:
        raise ValueError(f"df: expected at least 1 degree of freedom, found {df!r}")
    nodes, weights = np.polynomial.legendre.leggauss(128)
    u, w = 0.5 * (nodes + 1.0), 0.5 * weights
    log_c = math.lgamma((df + 1) / 2) - math.lgamma(df / 2) - 0.5 * math.log(df * math.pi)

    def mass(t: float) -> float:  # P(0 <= T <= t), with x = sqrt(df) tan(theta): a bounded, smooth integrand
        top = math.atan(t / math.sqrt(df))
        theta = top * u
        return float(top * math.sqrt(df) * np.sum(w * np.exp(log_c + (df - 1) * np.log(np.cos(theta)))))

    lo, hi = 0.0, 1.0
    while mass(hi) < p - 0.5:
        hi *= 2.0
    for _ in range(100):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if mass(mid) < p - 0.5 else (lo, mid)
    return 0.5 * (lo + hi)


def paired_t_interval(differences: Sequence[float], confidence: float = 0.95) -> tuple[float, float, float]:
    """Mean of paired differences and its two-sided Student *t* confidence interval.

    Args:
        differences: one difference per experimental unit (frame pair).
        confidence: coverage of the interval.

    Returns:
        ``(mean, low, high)``; with fewer than 2 differences the interval is ``(-inf, inf)``.

    Raises:
        ValueError: no difference, a NaN or infinite one (the interval was ``(nan, nan, nan)``), or ``confidence``
            outside ``(0, 1)``.

    Example:
        >>> mean, lo, hi = paired_t_interval([1.0, 2.0, 3.0])
        >>> mean, round(lo, 4), round(hi, 4)
        (2.0, -0.4841, 4.4841)
    """
    level = check_real(confidence, "confidence")
    if not 0.0 < level < 1.0:  # NaN too; it was reported as t_quantile's "p: ... found 0.5"
        raise ValueError(f"confidence: expected a coverage in (0, 1), found {confidence!r}")
    d = np.asarray(differences, dtype=np.float64)
    if d.size == 0:
        raise ValueError("differences: expected at least one difference, found none")
    if not np.isfinite(d).all():
        raise ValueError(f"differences: expected finite differences, found {int((~np.isfinite(d)).sum())} NaN/Inf")
    mean = float(d.mean())
    if d.size < 2:
        return mean, -math.inf, math.inf
    half = t_quantile(0.5 + level / 2, d.size - 1) * float(d.std(ddof=1)) / math.sqrt(d.size)
    return mean, mean - half, mean + half


def _pair_sets(pair: Mapping[str, Any], prefix: str = "") -> dict[str, dict[str, float]]:
    """Every set-like entry of a pair's dict: ``{set name: {statistic: value}}`` (reverse sets as ``reverse:...``)."""
    out: dict[str, dict[str, float]] = {}
    for key, value in pair.items():
        if (not prefix and key in _NOT_SETS) or not isinstance(value, Mapping) or not value:
            continue
        name = f"{prefix}{key}"
        if all(isinstance(v, Mapping) for v in value.values()):
            out.update(_pair_sets(value, f"{name}:"))
        else:
            out[name] = {k: _number(v) for k, v in value.items() if _number(v) is not None}  # type: ignore[misc]
    return out


def _number(value: Any) -> float | None:
    """A statistic's value as a float (JSON writes non-finite values as strings); ``None`` if not a number."""
    if isinstance(value, bool):
        return None
    if isinstance(value, (int, float)):
        return float(value)
    if isinstance(value, str) and value in ("inf", "-inf", "nan"):
        return float(value)
    return None


def _pairs(method: SequenceEvaluation | Mapping[str, Any]) -> list[Mapping[str, Any]]:
    if isinstance(method, SequenceEvaluation):
        return [p.as_dict() for p in method.pairs]
    return list(method["pairs"])


def _higher_is_better(statistic: str) -> bool:
    return "psnr" in statistic


def _is_floor_set(name: str) -> bool:
    base = name.split(":", 1)[1] if name.startswith(f"{_REVERSE}:") else name
    return base in FLOOR_SET_NAMES


def _registration_floor(pairs_a: list[Mapping[str, Any]], pairs_b: list[Mapping[str, Any]]) -> dict[str, float]:
    """Per statistic: mean over pairs of the larger of the registration's residual and its error (both methods)."""
    floors: dict[str, list[float]] = {}
    for pa, pb in zip(pairs_a, pairs_b, strict=True):
        per_pair: dict[str, float] = {}
        for pair in (pa, pb):
            registration = pair.get("registration", {})
            for what in ("residual", "error"):
                for stat, value in registration.get(what, {}).items():
                    v = _number(value)
                    if v is not None and math.isfinite(v):
                        per_pair[stat] = max(per_pair.get(stat, 0.0), v)
        for stat, v in per_pair.items():
            floors.setdefault(stat, []).append(v)
    return {stat: float(np.mean(v)) for stat, v in floors.items() if len(v) == len(pairs_a)}


def _compare_values(
    a: list[float],
    b: list[float],
    statistic: str,
    floor: float,
    relative_margin: float,
    confidence: float,
    names: tuple[str, str],
) -> dict[str, Any]:
    # A pair both methods measure without error (PSNR inf for both) has no difference in dB: the one rule (mean_psnr)
    # leaves it out and counts it ("both_inf_pairs"). It entered the interval as a difference of 0, which pulled the
    # mean difference towards 0 and narrowed the interval with a pair that tells the methods nothing apart.
    pairs = list(zip(a, b, strict=True))
    if _higher_is_better(statistic):
        pairs = [(x, y) for x, y in pairs if not x == y == math.inf]
    entry = _paired_entry(
        [x for x, _ in pairs], [y for _, y in pairs], statistic, floor, relative_margin, confidence, names
    )
    if len(pairs) < len(a):
        entry["both_inf_pairs"] = len(a) - len(pairs)
    return entry


def _paired_entry(
    a: list[float],
    b: list[float],
    statistic: str,
    floor: float,
    relative_margin: float,
    confidence: float,
    names: tuple[str, str],
) -> dict[str, Any]:
    """One entry of :func:`compare_methods` from the pairs' values (none left out here); see its docs."""
    if all(x == y for x, y in zip(a, b, strict=True)):  # identical (no pair left included): no difference at all
        return {"difference": 0.0, "ci95": [0.0, 0.0], "verdict": "inconclusive"}
    diffs = [0.0 if x == y else x - y for x, y in zip(a, b, strict=True)]  # equal infinities of a distance: none
    if not all(math.isfinite(d) for d in diffs):
        # A PSNR of inf (a pair measured without error) leaves no mean nor interval: it gave "nan ± inf" and
        # "inconclusive" where one method won on every pair (found by review). One sign on every pair is a verdict.
        higher = _higher_is_better(statistic)
        if not any(math.isnan(d) for d in diffs) and (all(d >= 0 for d in diffs) or all(d <= 0 for d in diffs)):
            a_wins = (max(diffs) > 0) == higher
            mean = math.inf if max(diffs) > 0 else -math.inf
            return {
                "difference": mean,
                "ci95": [min(diffs), max(diffs)],
                "verdict": f"{names[0 if a_wins else 1]} better",
            }
        # Lossless (inf) on some pairs and the sign changing: no difference in dB is defined. It gave "nan ± inf"
        # (JSON "nan"; found by review E): say so in words; the same sets' rmse/ave are compared as usual.
        return {"difference": None, "ci95": None, "verdict": "inconclusive", "undefined": UNDEFINED_PSNR}
    mean, lo, hi = paired_t_interval(diffs, confidence)
    if "psnr" in statistic:  # the one rule (mean_psnr): a pair both measure without error (inf) is left out
        mean_a, mean_b = (mean_psnr(v, f"{name}'s {statistic}")[0] for v, name in zip((a, b), names, strict=True))
    else:
        mean_a, mean_b = float(np.mean(a)), float(np.mean(b))
    higher = _higher_is_better(statistic)
    better = max(mean_a, mean_b) if higher else min(mean_a, mean_b)
    threshold = max(floor, relative_margin * abs(better))
    verdict = "inconclusive"
    if (lo > 0 or hi < 0) and abs(mean) > threshold:
        a_wins = (mean > 0) == higher
        verdict = f"{names[0] if a_wins else names[1]} better"
    return {"difference": mean, "ci95": [lo, hi], "verdict": verdict}


def compare_methods(
    methods: Mapping[str, SequenceEvaluation | Mapping[str, Any]],
    *,
    statistics: Sequence[str] = DEFAULT_COMPARISON_STATISTICS,
    confidence: float = 0.95,
    relative_margin: float = 0.02,
) -> dict[str, dict[str, dict[str, dict[str, Any]]]]:
    """Every pair of methods, every set, the main statistics: difference, confidence interval and verdict.

    See the module docstring for the method (paired *t* interval over frame pairs) and the verdict's noise floors.

    Args:
        methods: method name → its :class:`SequenceEvaluation`, or its part of a JSON report (``{"pairs": [...]}``);
            all on the same original sequence (same frame pairs).
        statistics: statistics to compare when a set has them; every statistic whose name contains ``psnr`` is
            compared too.
        confidence: coverage of the interval (the JSON key stays ``ci95``; default 0.95).
        relative_margin: differences below this fraction of the better method's value are ``"inconclusive"``
            (``0`` to rely on the interval and the registration floor alone).

    Returns:
        ``{"<A> vs <B>": {set: {statistic: {"difference": A - B, "ci95": [lo, hi], "verdict": ...}}}}``; entries
        of the sets measured against the registered frame ``k-1`` (and ``flicker``) also hold ``"noise_floor"``.
        A PSNR entry also holds ``"both_inf_pairs"`` when both methods measure some frame pairs without error
        (PSNR inf for both): those pairs have no difference in dB and are left out of the difference and its
        interval, as :func:`~torchmeshmetric.stats.statistics.mean_psnr` leaves an inf out of a mean (with every
        pair so, the methods are identical: difference 0). A PSNR inf for one method only is a difference of
        ``±inf``: one sign on every pair is a verdict, the sign changing leaves the difference undefined
        (:data:`UNDEFINED_PSNR`).

    Raises:
        ValueError: fewer than two methods, or methods evaluated on different frame pairs.

    Example:
        >>> import trimesh
        >>> from torchmeshmetric.evaluation import evaluate_sequence
        >>> frames = [trimesh.creation.icosphere(subdivisions=2) for _ in range(3)]
        >>> coarse = [trimesh.creation.icosphere(subdivisions=1) for _ in range(3)]
        >>> same = lambda src, dst: src
        >>> out = compare_methods({
        ...     "A": evaluate_sequence(frames, coarse, registration_fn=same),
        ...     "B": evaluate_sequence(frames, coarse, registration_fn=same),
        ... })
        >>> a_vs_b = out["A vs B"]
        >>> surface_k = a_vs_b["surface_k"]
        >>> entry = surface_k["ave"]
        >>> entry["difference"], entry["verdict"]
        (0.0, 'inconclusive')
    """
    if len(methods) < 2:
        raise ValueError(f"methods: expected at least two methods to compare, found {len(methods)}")
    if not 0.0 < confidence < 1.0:
        raise ValueError(f"confidence: expected a probability in (0, 1), found {confidence!r}")
    if not (math.isfinite(relative_margin) and relative_margin >= 0):
        raise ValueError(f"relative_margin: expected a fraction >= 0, found {relative_margin!r}")
    pairs = {name: _pairs(m) for name, m in methods.items()}
    frames = {name: [p.get("frame") for p in ps] for name, ps in pairs.items()}
    first = next(iter(frames))
    for name, f in frames.items():
        if f != frames[first] or not f:
            raise ValueError(
                f"methods: {name!r} was evaluated on frame pairs {f}, {first!r} on {frames[first]} (must match)"
            )
    sets = {name: [_pair_sets(p) for p in ps] for name, ps in pairs.items()}
    out: dict[str, dict[str, dict[str, dict[str, Any]]]] = {}
    for name_a, name_b in itertools.combinations(methods, 2):
        floors = _registration_floor(pairs[name_a], pairs[name_b])
        result: dict[str, dict[str, dict[str, Any]]] = {}
        common = [s for s in sets[name_a][0] if all(s in p for p in sets[name_a] + sets[name_b])]
        for set_name in common:
            floor_set = _is_floor_set(set_name)
            stats = [
                st
                for st in sets[name_a][0][set_name]
                if (st in statistics or "psnr" in st) and all(st in p[set_name] for p in sets[name_a] + sets[name_b])
            ]
            entries = {}
            for stat in stats:
                a = [p[set_name][stat] for p in sets[name_a]]
                b = [p[set_name][stat] for p in sets[name_b]]
                floor = _floor(stat, set_name, floors, a, b, sets[name_a], sets[name_b]) if floor_set else 0.0
                entry = _compare_values(a, b, stat, floor, relative_margin, confidence, (name_a, name_b))
                if floor_set:
                    entry["noise_floor"] = floor
                entries[stat] = entry
            if entries:
                result[set_name] = entries
        out[f"{name_a} vs {name_b}"] = result
    return out


def _floor(
    stat: str,
    set_name: str,
    floors: Mapping[str, float],
    a: list[float],
    b: list[float],
    sets_a: list[dict[str, dict[str, float]]],
    sets_b: list[dict[str, dict[str, float]]],
) -> float:
    """The registration floor of one statistic of a ``k-1``/flicker set (see the module docstring)."""
    if not _higher_is_better(stat):
        return floors.get(stat, floors.get("rmse", 0.0))
    f = floors.get("rmse", 0.0)
    rmse = [p[set_name].get("rmse", math.nan) for p in sets_a + sets_b]
    r = min(float(np.mean(rmse[: len(sets_a)])), float(np.mean(rmse[len(sets_a) :])))
    if not (math.isfinite(r) and r > 0):
        return math.inf if f > 0 else 0.0
    return 20.0 * math.log10((r + f) / r)


def with_nudged_verdicts(
    comparisons: Mapping[str, Mapping[str, Mapping[str, Mapping[str, Any]]]],
    nudged: Mapping[str, Mapping[str, Mapping[str, Mapping[str, Any]]]],
) -> dict[str, dict[str, dict[str, dict[str, Any]]]]:
    """``comparisons`` with each entry's verdict, difference and interval on the frames ``--determinacy`` nudged.

    A verdict is a property of the methods only if the input's storage cannot change it: the same comparison on
    frames moved by up to one unit of their storage (:func:`~torchmeshmetric.evaluation.determinacy.nudge_frames`)
    must reach it too. :func:`comparison_markdown` marks a cell whose two verdicts differ with ``~`` before the
    winner, and prints the difference, the interval's half-width and the noise floor with only the digits both runs
    share.

    Args:
        comparisons: :func:`compare_methods` of the run.
        nudged: :func:`compare_methods` of the same methods evaluated on the nudged frames.

    Returns:
        A copy of ``comparisons`` whose entries hold ``"nudged_verdict"``, ``"nudged_difference"`` and
        ``"nudged_ci95"`` (and ``"nudged_noise_floor"`` where the entry has a noise floor); an entry missing from
        ``nudged`` gets none of them.

    Example:
        >>> run = {"A vs B": {"surface_k": {"ave": {"difference": 0.2, "ci95": [0.1, 0.3], "verdict": "A better"}}}}
        >>> ave = {"difference": 0.1, "ci95": [-0.1, 0.3], "verdict": "inconclusive"}
        >>> again = {"A vs B": {"surface_k": {"ave": ave}}}
        >>> marked = with_nudged_verdicts(run, again)
        >>> entry = marked["A vs B"].get("surface_k").get("ave")
        >>> entry["nudged_verdict"], entry["nudged_difference"], entry["nudged_ci95"]
        ('inconclusive', 0.1, [-0.1, 0.3])
    """
    out: dict[str, dict[str, dict[str, dict[str, Any]]]] = {}
    for title, sets in comparisons.items():
        out[title] = {}
        for set_name, entries in sets.items():
            out[title][set_name] = {}
            for stat, entry in entries.items():
                other = nudged.get(title, {}).get(set_name, {}).get(stat)
                keys = ("verdict", "difference", "ci95", "noise_floor")
                extra = {} if other is None else {f"nudged_{k}": other[k] for k in keys if k in other}
                out[title][set_name][stat] = {**entry, **extra}
    return out


def _undefined(entry: Mapping[str, Any]) -> str | None:
    """Which run's difference is undefined (a PSNR inf on some pairs, the sign changing): the cell's words, or None.

    The run's own (``"difference": null``) or, with ``--determinacy``, the nudged run's (``"nudged_difference":
    null``): either way no digit of a difference is shared, so the cell says so and the note under the tables
    explains it (:data:`UNDEFINED_PSNR`).
    """
    if entry["difference"] is None:
        return "undefined (PSNR inf on a pair)"
    if "nudged_difference" in entry and entry["nudged_difference"] is None:
        return "undefined on the nudged frames (PSNR inf on a pair)"
    return None


def _undetermined(entry: Mapping[str, Any]) -> bool:
    """Whether the nudged frames reached another verdict (:func:`with_nudged_verdicts`)."""
    return entry.get("nudged_verdict", entry["verdict"]) != entry["verdict"]


def _cell(x: float) -> str:
    return format_number(x, ".3g")  # 3 significant digits: a verdict cell holds two numbers


def _half_width(ci95: Sequence[float]) -> float:
    lo, hi = ci95
    return (hi - lo) / 2 if math.isfinite(hi - lo) else math.inf


def _numbers(entry: Mapping[str, Any], statistic: str) -> tuple[str, str]:
    """The difference and the half-width of a verdict cell; with the nudged run's, only the digits both print alike.

    A PSNR difference is in dB, as the tables' PSNR: its digits are decimals (at most one, the tables' rule); every
    other number keeps significant digits (:func:`~torchmeshmetric.evaluation.determinacy.shared_cell`).
    """
    difference, half = entry["difference"], _half_width(entry["ci95"])
    if "nudged_difference" not in entry:
        return _cell(difference), _cell(half)
    spec = ".1f" if _higher_is_better(statistic) else "#.3g"
    text = shared_cell(difference, entry["nudged_difference"], spec)
    return text, shared_cell(half, _half_width(entry["nudged_ci95"]), "#.3g")


def _floor_cell(entry: Mapping[str, Any]) -> str:
    """The noise floor of a verdict cell; with the nudged run's, only the digits both print alike.

    A floor is a registration residual (for PSNR, the dB it is worth): the registrations on the nudged frames are
    other fits, so its digits are measured like the difference's. It is a threshold, not a level, so every floor
    keeps significant digits (a PSNR floor of a few thousandths of a dB keeps them too).
    """
    floor = entry["noise_floor"]
    if "nudged_noise_floor" not in entry:
        return _cell(floor)
    return shared_cell(floor, entry["nudged_noise_floor"], "#.3g")


def comparison_markdown(comparisons: Mapping[str, Mapping[str, Mapping[str, Mapping[str, Any]]]]) -> str:
    """Compact verdict tables (one per pair of methods) as Markdown.

    Rows are sets, columns statistics; a cell reads ``<winner>: difference ± half-width`` or
    ``≈ difference ± half-width`` when inconclusive (the difference is ``A - B``). Sets with a registration noise
    floor are marked ``*`` and their floor is listed under the table, as are the frame pairs a PSNR's difference
    leaves out (both methods measure them without error). With the verdicts on nudged frames
    (:func:`with_nudged_verdicts`), a cell whose verdict they change starts with ``~``, the note under the tables
    counts them, and each number (the noise floors too) keeps only the digits both runs share (``~`` before a number
    none of whose digits held).

    Args:
        comparisons: the verdicts of :func:`compare_methods` (``{"<A> vs <B>": {set: {statistic: entry}}}``, each
            entry with ``"difference"``, ``"ci95"``, ``"verdict"`` and optionally ``"noise_floor"``,
            ``"both_inf_pairs"`` and the ``"nudged_*"`` keys of :func:`with_nudged_verdicts`).

    Returns:
        The Markdown text: per pair of methods a ``###`` title and a table, the notes under it, then the legend.

    Raises:
        KeyError: an entry without ``"difference"``, ``"ci95"`` or ``"verdict"``.

    Example:
        >>> ave = {"difference": 0.2, "ci95": [0.1, 0.3], "verdict": "A better"}
        >>> rmse = {"difference": -0.01, "ci95": [-0.03, 0.01], "verdict": "inconclusive"}
        >>> lines = comparison_markdown({"A vs B": {"surface_k": {"ave": ave, "rmse": rmse}}}).splitlines()
        >>> print(lines[2]); print(lines[4])
        | set | ave | rmse |
        | surface_k | A: 0.2 ± 0.1 | ≈: -0.01 ± 0.02 |
    """
    out = []
    for title, sets in comparisons.items():
        stats: list[str] = []
        for entries in sets.values():
            stats += [s for s in entries if s not in stats]
        # a method's name is the user's: one line, its "|" escaped (else a row gets a cell more than its header)
        out += [f"### {markdown_cell(title)} (difference A - B, 95 % interval over frame pairs)", ""]
        out += ["| set | " + " | ".join(stats) + " |", "|---|" + "---|" * len(stats)]
        floors = []
        for set_name, entries in sets.items():
            cells = []
            for stat in stats:
                e = entries.get(stat)
                if e is None:
                    cells.append("")
                    continue
                winner = e["verdict"].removesuffix(" better") if e["verdict"] != "inconclusive" else "≈"
                mark = "~" if _undetermined(e) else ""
                undefined = _undefined(e)
                if undefined is not None:  # a PSNR inf on some pairs, the sign changing (UNDEFINED_PSNR)
                    cells.append(f"{mark}{markdown_cell(winner)}: {undefined}")
                    continue
                difference, half = _numbers(e, stat)
                cells.append(f"{mark}{markdown_cell(winner)}: {difference} ± {half}")
            marked = f"{set_name} *" if any("noise_floor" in e for e in entries.values()) else set_name
            out.append(f"| {marked} | " + " | ".join(cells) + " |")
            if any("noise_floor" in e for e in entries.values()):
                floors.append(f"{set_name}: " + ", ".join(f"{s} {_floor_cell(e)}" for s, e in entries.items()))
        out.append("")
        if floors:
            out += ["\\* noise floor (registration residual, or its error when known): " + "; ".join(floors), ""]
        # the pairs a PSNR's difference leaves out, as mean_psnr leaves an inf out (compare_methods' both_inf_pairs)
        both_inf = [
            f"{n} {st} {e['both_inf_pairs']}" for n, es in sets.items() for st, e in es.items() if "both_inf_pairs" in e
        ]
        if both_inf:
            out += [
                "Frame pairs both methods measure without error (PSNR inf for both), left out of that PSNR's "
                "difference and interval: " + "; ".join(both_inf),
                "",
            ]
    out.append(
        "≈: inconclusive (the interval contains 0, or the difference is below the noise floor or the relative "
        "margin). Units: frame pairs; see docs/statistics.md. The sets marked * go through the registration, "
        "which draws its samples independently of how the original frames are stored (face order, corners, vertex "
        "numbering: 3 other orders of frames of about 20k vertices moved those sets' figures by at most 7e-5 "
        "relative, docs/statistics.md); --determinacy includes another order."
    )
    nudged = [e for sets in comparisons.values() for entries in sets.values() for e in entries.values()]
    if any(_undefined(e) is not None for e in nudged):
        out[-1] += (
            " undefined: a PSNR is inf (a pair measured without error) on some pairs and the difference changes "
            "sign (in the run, or on the frames nudged by --determinacy), so no mean difference in dB exists; "
            "compare the rmse."
        )
    if any("nudged_verdict" in e for e in nudged):
        changed = sum(_undetermined(e) for e in nudged)
        out[-1] += (
            f" Verdicts on the frames nudged by --determinacy: {len(nudged) - changed} of {len(nudged)} the same"
            + (
                "; ~ marks a verdict the nudge changed (the JSON's 'nudged_verdict'): the input's storage decides "
                "it, not the methods."
                if changed
                else "."
            )
            + " Differences, half-widths and noise floors keep the digits both runs share ('~' before a number: none "
            "of its digits held; a PSNR difference: it moved by 1 dB or more)."
        )
    return "\n".join(out) + "\n"
