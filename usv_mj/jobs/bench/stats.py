"""The benchmark's statistics beyond a mean and its interval (docs/metrics.md, "Statistics"): time to an
event with censoring, paired tests per cell, and Holm's correction over a comparison's tests.

- **Time to an event** (settling, reaching the goal): an episode whose event did not happen by its
  end is *censored* at its duration T, not a number to average. Every episode of a cell runs the
  same T, so the censoring is at one common time after every observed event; the Kaplan-Meier
  estimate then equals the empirical distribution with the censored episodes placed after all the
  events (at "> T"). :func:`censored_median` gives the fraction reached, the median and the
  distribution-free 95 % interval of the median from the order statistics (the binomial ranks of
  :func:`median_ranks`): a median or an end of its interval that lands on a censored episode reads
  "> T" (not reached within the episode).
- **Paired tests** over the episodes two controllers share (same task, condition, vessel and episode
  index: the same start pose and sea): the Wilcoxon signed-rank test for a continuous metric
  (:func:`wilcoxon_p`), the exact sign test for a time to an event (:func:`censored_pairs`: a pair's
  order is known unless both were censored, which is a tie; Gehan's scoring for paired data with a
  common censoring time), McNemar's exact test for a 0/1 outcome (the sign test on the discordant
  pairs). All two-sided.
- **Multiple comparisons**: Holm's step-down correction (:func:`holm`) over every test of one
  comparison (every cell and metric): it holds the family-wise error rate at alpha for any
  dependence between the tests, and rejects whatever Bonferroni rejects.
"""

from __future__ import annotations

import math

import numpy as np


def binom_cdf(k: int, n: int, p: float = 0.5) -> float:
    """P(B <= k) for B ~ Binomial(n, p) (exact, by the sum)."""
    if k < 0:
        return 0.0
    if k >= n:
        return 1.0
    return float(sum(math.comb(n, i) * p**i * (1 - p) ** (n - i) for i in range(k + 1)))


def sign_test_p(a: int, b: int) -> float:
    """Two-sided exact sign test of ``a`` against ``b`` successes (ties left out): 2 P(B <= min(a, b)),
    B ~ Binomial(a + b, 1/2), at most 1; 1 when there is no untied pair."""
    n = a + b
    if n == 0:
        return 1.0
    return min(1.0, 2.0 * binom_cdf(min(a, b), n))


def wilcoxon_p(x, y) -> float:
    """Two-sided Wilcoxon signed-rank p of the pairs (x_i, y_i) (``scipy.stats.wilcoxon``, zero
    differences dropped, the exact distribution for small samples without ties); 1 when every
    difference is 0."""
    d = np.asarray(x, float) - np.asarray(y, float)
    if not np.any(d != 0):
        return 1.0
    from scipy.stats import wilcoxon

    return float(wilcoxon(x, y, zero_method="wilcox", alternative="two-sided").pvalue)


def censored_pairs(ta, ra, tb, rb) -> tuple[int, int, int]:
    """(a first, b first, ties) over pairs of times to an event with a common censoring time:
    ``ta``, ``tb`` the times [s] (any value where not reached), ``ra``, ``rb`` whether the event
    happened. A reached event comes before a censored one; two reached ones compare their times;
    two censored ones (or equal times) are a tie."""
    a_first = b_first = ties = 0
    for x, rx, y, ry in zip(ta, ra, tb, rb):
        if rx and ry:
            if x < y:
                a_first += 1
            elif y < x:
                b_first += 1
            else:
                ties += 1
        elif rx:
            a_first += 1
        elif ry:
            b_first += 1
        else:
            ties += 1
    return a_first, b_first, ties


def holm(pvalues) -> list[float]:
    """Holm-Bonferroni adjusted p-values, in the order given: with the m p-values sorted
    p_(1) <= ... <= p_(m), adjusted p_(i) = max over j <= i of min(1, (m - j + 1) p_(j)). A test is
    rejected at family-wise level alpha when its adjusted p < alpha."""
    p = [float(v) for v in pvalues]
    m = len(p)
    order = sorted(range(m), key=lambda i: p[i])
    out = [0.0] * m
    running = 0.0
    for rank, i in enumerate(order):
        running = max(running, min(1.0, (m - rank) * p[i]))
        out[i] = running
    return out


def median_ranks(n: int, level: float = 0.95) -> tuple[int, int]:
    """1-based ranks (j, k) of the order statistics that bound the median with confidence >= level,
    distribution-free: the largest j with P(B <= j - 1) <= (1 - level)/2, B ~ Binomial(n, 1/2), and
    k = n + 1 - j; j = 0 when no such j exists (n < 6 at 95 %: the interval is unbounded)."""
    alpha = (1.0 - level) / 2.0
    j = 0
    while j + 1 <= n and binom_cdf(j, n) <= alpha:
        j += 1
    return j, n + 1 - j


def censored_median(times, reached, level: float = 0.95) -> dict:
    """Fraction reached, median and its interval of times to an event censored at one common time
    after every event (module docstring). ``times`` [s] of the reached episodes are used; the
    others count as later than all of them. Returns ``{"n", "reached", "median", "lo", "hi"}``, with
    ``math.inf`` where the value lands on a censored episode (not reached within the episode) and
    ``lo`` = 0 when the interval has no lower order statistic."""
    times, reached = list(times), [bool(r) for r in reached]
    t = [float(x) for x, r in zip(times, reached) if r]
    n, k = len(reached), len(t)
    if n == 0:
        return {"n": 0, "reached": 0, "median": math.nan, "lo": math.nan, "hi": math.nan}
    x = sorted(t) + [math.inf] * (n - k)

    def at(rank):   # 1-based order statistic
        return x[rank - 1]

    if n % 2:
        median = at((n + 1) // 2)
    else:
        a, b = at(n // 2), at(n // 2 + 1)
        median = math.inf if math.isinf(b) else 0.5 * (a + b)
    j, kk = median_ranks(n, level)
    lo = at(j) if j >= 1 else 0.0
    hi = at(kk) if 1 <= kk <= n and j >= 1 else math.inf
    return {"n": n, "reached": k, "median": median, "lo": lo, "hi": hi}


__all__ = ["binom_cdf", "sign_test_p", "wilcoxon_p", "censored_pairs", "holm", "median_ranks", "censored_median"]
