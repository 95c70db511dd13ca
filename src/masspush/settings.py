"""The paper's named experimental settings: number of links and link mass range."""

from __future__ import annotations

from dataclasses import dataclass, replace

from masspush.config import PhysicsConfig


PAPER_PUSHER = "kuka"
"""The pusher for reproducing the paper's experiments: its simulated arm, the KUKA KR 5.
With the stiff pusher the [0.1, 1] and [1, 10] kg settings are the same problem up to a
mass scale it cannot see (docs/simulation.md); with the arm they differ, as in the paper.
The stiff pusher stays available everywhere as the fast option (~3x faster per push on one
core, and it alone runs on the multi-threaded batch path)."""


@dataclass(frozen=True)
class Setting:
    """A named experimental setting (everything else as in `PhysicsConfig`'s defaults)."""

    name: str
    n_links: int
    mass_range: tuple[float, float]
    """Each link's mass ~ U(mass_range), kg."""

    def physics(self, base: PhysicsConfig | None = None) -> PhysicsConfig:
        return replace(base or PhysicsConfig(), n_links=self.n_links, mass_range=self.mass_range)


# The six settings of the paper's Table 1, in its order.
SETTINGS: dict[str, Setting] = {
    s.name: s
    for s in (
        Setting("2link-0.1-1", 2, (0.1, 1.0)),
        Setting("2link-1-10", 2, (1.0, 10.0)),
        Setting("2link-0.1-10", 2, (0.1, 10.0)),
        Setting("3link-0.1-1", 3, (0.1, 1.0)),
        Setting("3link-1-10", 3, (1.0, 10.0)),
        Setting("3link-0.1-10", 3, (0.1, 10.0)),
    )
}


def get_setting(name: str) -> Setting:
    """The named setting, or a ValueError listing the known names."""
    try:
        return SETTINGS[name]
    except KeyError:
        raise ValueError(f"unknown setting {name!r}; known settings: {list(SETTINGS)}") from None
