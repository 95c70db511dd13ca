"""Episodes as data: running them (`rollout`), datasets of them on disk (`dataset`), and
recordings of a robot's sessions (`recording`).

The names below are its public API (what experiments/ may import)."""

from masspush._exports import lazy, names

EXPORTS = {
    "rollout": ("EVAL", "TRAIN", "POLICIES", "Episodes", "Policy", "RandomPolicy",
                "episode_seed", "run_batch", "run_episodes"),
    "dataset": ("CollectConfig", "collect", "collect_dataset", "load_dataset", "read_shard",
                "write_shard"),
    "recording": ("Recording", "check_recording", "read_recording", "write_recording"),
}  # fmt: skip
__getattr__ = lazy(__name__, EXPORTS)
__all__ = names(EXPORTS)
