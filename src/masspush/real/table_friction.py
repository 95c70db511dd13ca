"""The lab table's friction as a tuned push density reads it from a recording's pushes, and
the check that it has not drifted from the calibration's.

A tuned density (`masspush.real.density_tuning`) takes the table's friction as an input and
its sorting marginalises over a grid of them; the same likelihoods, pooled over a
recording's episodes (each episode's classes marginalised, equal priors, so no label is
needed), peak at the friction the lab's table shows on that recording's day. It is the
density's reading, not a measured coefficient: a lab whose table the density reads at 0.54
may measure 0.6. Read on the calibration recording and again on a later day's, the ratio
tracks the table's drift: lab 9's days read -9, -11, -20 and +9 % where its friction had
moved -7, -12, -22 and +14 % (docs/notebook/2026-12-07-wider-friction.md). A calibration held
within 15 % in that lab; beyond it the reading warns (`FrictionDriftWarning`) and the lab
recalibrates.
"""

from __future__ import annotations

import warnings
from typing import Any, NamedTuple

import numpy as np

from masspush.data.recording import Recording
from masspush.learn.push_density import PushDensity
from masspush.real.density_tuning import SortingEvidence, sorting_evidence

DRIFT_LIMIT = 0.15
"""Relative change of the table friction's reading from the calibration's beyond which a
sorting warns: lab 9's calibration held at -12 and +14 % (sorted 94.0 and 93.3 % of the same
chains, 91.3 and 96.0 % on the calibration day) and not at -22 % with the density's own
friction range (85.3 %) (docs/notebook/2026-12-07-another-day.md) [ours, measured]."""

BOOTSTRAP = 1000
"""Resamples of the episodes behind the reading's interval."""


class FrictionDriftWarning(UserWarning):
    """The table reads further from the calibration's friction than `DRIFT_LIMIT`."""


class FrictionReading(NamedTuple):
    """The table's friction as a tuned density reads it from some episodes' pushes."""

    value: float
    low: float
    """5th percentile over episodes resampled with replacement (`BOOTSTRAP`)."""
    high: float
    """95th percentile, likewise."""
    episodes: int
    """Episodes with at least one push."""
    edge: str | None
    """'low' or 'high' where the reading is at that end of the grid read over: the table
    may lie beyond it."""

    def as_dict(self) -> dict[str, Any]:
        return self._asdict()

    def change(self, reference: FrictionReading | dict[str, Any]) -> float:
        """The relative change from `reference` (this / reference - 1)."""
        ref = reference["value"] if isinstance(reference, dict) else reference.value
        return self.value / ref - 1


def peak(profile: np.ndarray, grid: np.ndarray) -> float:
    """The maximiser of a log-likelihood `profile` over an evenly spaced `grid`, refined by
    the parabola through the best point and its neighbours."""
    k = int(np.argmax(profile))
    if k == 0 or k == len(grid) - 1:
        return float(grid[k])
    left, mid, right = profile[k - 1 : k + 2]
    curvature = left - 2 * mid + right
    shift = 0.0 if curvature >= 0 else 0.5 * (left - right) / curvature
    return float(grid[k] + shift * (grid[1] - grid[0]))


def friction_profiles(evidence: SortingEvidence) -> np.ndarray:
    """(E, F) each episode's log-likelihood at each friction of the evidence's grid, its
    class unknown (the classes marginalised, equal priors); episodes without a push left
    out."""
    return np.logaddexp.reduce(evidence.joint[evidence.pushed], axis=1)


def pool_reading(
    profiles: np.ndarray, grid: np.ndarray, where: str, seed: int = 0
) -> FrictionReading:
    """The friction at which episodes' `profiles` (E, F) over `grid`, added up, peak, with an
    interval from the episodes resampled; a one-line ValueError where there is none."""
    if len(profiles) == 0:
        raise ValueError(f"{where}: no episode with a push to read the table's friction from")
    value = peak(profiles.sum(0), grid)
    draws = np.random.default_rng(seed).integers(0, len(profiles), (BOOTSTRAP, len(profiles)))
    low, high = np.percentile([peak(profiles[rows].sum(0), grid) for rows in draws], [5, 95])
    edge = "low" if value <= grid[0] else "high" if value >= grid[-1] else None
    return FrictionReading(value, float(low), float(high), len(profiles), edge)


def read_friction(
    density: PushDensity, recording: Recording, where: str, pushes: int | None = None
) -> FrictionReading:
    """The table friction that the tuned `density` reads from a recording's episodes (their
    first `pushes` pushes; all by default)."""
    evidence = sorting_evidence(density, recording, where, pushes)
    return pool_reading(friction_profiles(evidence), evidence.grid, where)


def calibration_friction(density: PushDensity) -> dict[str, Any] | None:
    """The reading `masspush tune-density` kept of its calibration episodes (None for
    densities tuned before it kept one)."""
    return (density.meta.get("tuned") or {}).get("table_friction")


def friction_lines(reading: FrictionReading, calibration: dict[str, Any] | None) -> list[str]:
    """The reading in words, with its change from the calibration's."""
    line = (f"table friction as the tuned density reads it: {reading.value:.3f} (90 % interval "
            f"{reading.low:.3f}-{reading.high:.3f}, {reading.episodes} episodes)")  # fmt: skip
    if reading.edge:
        line += f", at the {reading.edge} end of the frictions it reads over"
    lines = [line]
    if calibration is not None:
        change = reading.change(calibration)
        verdict = "beyond" if abs(change) > DRIFT_LIMIT else "within"
        lines.append(
            f"calibration's: {calibration['value']:.3f}; change {100 * change:+.0f} %, {verdict} "
            f"the {100 * DRIFT_LIMIT:.0f} % a calibration was measured to hold"
        )
    return lines


def check_drift(reading: FrictionReading, density: PushDensity, where: str) -> None:
    """Warn (`FrictionDriftWarning`) where the reading is at an end of the grid read over, or
    further from the calibration's than `DRIFT_LIMIT` (densities tuned before the
    calibration's reading was kept are not compared)."""
    calibration = calibration_friction(density)
    change = None if calibration is None else reading.change(calibration)
    if reading.edge:
        what = f"at the {reading.edge} end of the frictions it reads over ({reading.value:.3f})"
    elif change is not None and abs(change) > DRIFT_LIMIT:
        what = (f"{100 * change:+.0f} % from the calibration's friction ({reading.value:.3f} "
                f"against {calibration['value']:.3f})")  # fmt: skip
    else:
        return
    warnings.warn(
        f"{where}: the table reads {what}: repeat the governor fit and the calibration run "
        "(docs/real-robot.md, 'Another day in the lab')",
        FrictionDriftWarning,
        stacklevel=2,
    )
