"""Error metrics for mass-distribution estimates; arrays are (episodes, links)."""

from __future__ import annotations

import numpy as np

PAPER_EPS = 1e-4
"""The authors' guard against division by zero in their percentage error [code]."""


def mae(pred: np.ndarray, true: np.ndarray) -> float:
    """Mean absolute error over all episodes and links."""
    return float(np.mean(np.abs(np.asarray(pred) - np.asarray(true))))


def percentage_error(pred: np.ndarray, true: np.ndarray) -> float:
    """The paper's "percentage error" exactly as its authors coded it (x100).

    The batch's MAE (one scalar) divided by (1e-4 + m_ij) for every link j of every episode
    i, averaged: mean_ij MAE / (1e-4 + m_ij). Not the mean of per-link relative errors:
    large errors on light links are not weighted up (shared/notes/paper-details.md).
    """
    true = np.asarray(true, dtype=float)
    return float(np.mean(mae(pred, true) / (PAPER_EPS + true)) * 100.0)


def relative_error(pred: np.ndarray, true: np.ndarray) -> float:
    """Mean per-link relative error x100: mean_ij |m_hat_ij - m_ij| / m_ij."""
    true = np.asarray(true, dtype=float)
    return float(np.mean(np.abs(np.asarray(pred) - true) / true) * 100.0)


def constant_prediction(true: np.ndarray) -> np.ndarray:
    """The uniform distribution 1/n for every episode: the mean distribution, since links'
    masses are drawn i.i.d. (what an estimator that learnt nothing would say)."""
    true = np.asarray(true)
    return np.full_like(true, 1.0 / true.shape[1], dtype=float)


def all_metrics(pred: np.ndarray, true: np.ndarray) -> dict[str, float]:
    """Every metric, and the same for the constant prediction (the floor to beat)."""
    const = constant_prediction(true)
    return {
        "percentage_error": percentage_error(pred, true),
        "relative_error": relative_error(pred, true),
        "mae": mae(pred, true),
        "constant_floor": percentage_error(const, true),
        "constant_floor_relative_error": relative_error(const, true),
        "constant_floor_mae": mae(const, true),
    }


def paired_rows(a: dict, b: dict) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(estimates of a, estimates of b, truths) on the episodes both records scored."""
    common = sorted(set(a["index"]) & set(b["index"]))
    if not common:
        raise ValueError("the two records share no episode")

    def rows(record: dict, key: str) -> np.ndarray:
        where = {i: k for k, i in enumerate(record["index"])}
        return np.array([record[key][where[i]] for i in common], dtype=float)

    truth = rows(a, "truth")
    if not np.allclose(truth, rows(b, "truth"), atol=1e-5):
        raise ValueError("the records disagree on the truth: not the same episodes")
    return rows(a, "estimate"), rows(b, "estimate"), truth


def paired_percentage_errors(a: dict, b: dict) -> tuple[float, float, int]:
    """The paper's metric for two models on the episodes both scored, from their
    per-episode records (index, estimate, truth): its scale, the mean of 1 / true share,
    depends on which episodes are in the batch, so models that left out different failed
    episodes are compared only on the common ones. Returns (error of a, error of b, n)."""
    est_a, est_b, truth = paired_rows(a, b)
    return percentage_error(est_a, truth), percentage_error(est_b, truth), len(truth)


def paired_difference_interval(
    a: dict, b: dict, level: float = 0.95, resamples: int = 4000, seed: int = 0
) -> tuple[float, float]:
    """Bootstrap interval of (error of a) - (error of b) in the paper's metric, on the
    episodes both scored: the episodes are resampled with replacement, both models scored
    on each resample. An interval holding 0 says that these episodes do not tell the two
    apart."""
    if not 0 < level < 1:
        raise ValueError(f"level must be in (0, 1), got {level}")
    est_a, est_b, truth = paired_rows(a, b)
    rng = np.random.default_rng(seed)
    diffs = np.empty(resamples)
    for r in range(resamples):
        k = rng.integers(0, len(truth), len(truth))
        diffs[r] = percentage_error(est_a[k], truth[k]) - percentage_error(est_b[k], truth[k])
    tail = (1 - level) / 2
    low, high = np.quantile(diffs, [tail, 1 - tail])
    return float(low), float(high)
