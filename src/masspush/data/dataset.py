"""Rollout datasets on disk: a manifest and NPZ shards of episodes.

Format (schema 1), a directory:
- `manifest.json`: schema version, setting (name, links, mass range), pusher, policy,
  noise, base seed, episodes, shard size, masspush version and git commit, created.
- `shard-00000.npz`, ...: shard j holds episodes j*S .. min((j+1)*S, N) - 1, the arrays of
  `masspush.data.rollout.Episodes` under the same names (docs/datasets.md lists them).

Why NPZ shards: episode i is fully determined by (base seed, i), so a shard can be
recomputed from its number alone; each shard is written to a temporary file and renamed
into place, so a killed collection leaves only whole shards behind and resumes by
computing the missing ones, never losing or duplicating an episode. NPZ is NumPy's own
format (no extra dependency, readable from any language with a zip and .npy reader),
compressed, and one shard is a few hundred kB. HDF5 or Zarr would add a dependency and
partial-write states to handle for no gain at this size.
"""

from __future__ import annotations

import errno
import json
import os
import shutil
import subprocess
import time
import zipfile
from collections import Counter
from collections.abc import Iterator
from dataclasses import asdict, dataclass, fields, replace
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
from tqdm import tqdm

from masspush.cluster.pool import TaskPool, Workers, check_address, is_pool, open_pool
from masspush.config import EnvConfig, check_choice, check_int
from masspush.data.rollout import (
    POLICIES,
    TRAIN,
    Episodes,
    Policy,
    empty_episodes,
    run_chunk,
    run_episodes,
)
from masspush.settings import Setting, get_setting
from masspush.sim.pushers import pusher_field, pusher_kind

SCHEMA_VERSION = 1
MANIFEST = "manifest.json"
WORLDS = ("setting", "randomised", "target")
"""Where a dataset's episodes were pushed (`Manifest.worlds`)."""


class DatasetError(ValueError):
    """A dataset that cannot be used: missing, truncated, corrupt or of another schema."""


def code_version() -> str:
    """masspush's version, and the git commit when run from a checkout, marked ".dirty"
    when the package's source differs from that commit (a result then cannot be traced to
    a commit alone; shipped model files do not count)."""
    from masspush import __version__

    here = Path(__file__).parents[1]  # the package root

    def git(*args: str) -> subprocess.CompletedProcess:
        return subprocess.run(["git", *args], capture_output=True, text=True, timeout=5, cwd=here)

    try:
        commit = git("rev-parse", "--short", "HEAD").stdout.strip()
        changed = git("status", "--porcelain", "--untracked-files=no", "--", "*.py", "*.xml")
        if commit and changed.stdout.strip():
            commit += ".dirty"
    except (OSError, subprocess.SubprocessError):
        commit = ""
    return f"{__version__}+{commit}" if commit else __version__


@dataclass(frozen=True)
class Manifest:
    schema_version: int
    setting: dict[str, Any]
    pusher: str
    policy: str
    obs_noise: float
    action_noise: float
    pushes: int
    base_seed: int
    purpose: int
    episodes: int
    shard_size: int
    code_version: str
    created: str
    worlds: str = "setting"
    """Where the episodes were pushed: "setting", the setting's own simulated world
    (`masspush collect`); "randomised", a world drawn per episode from
    `masspush.real.WorldRanges`, or "target", the sim-to-real target world, each as that
    world's robot observed it (`masspush randomise`; the noise fields are then the
    setting's, what the robot's software assumes). Manifests written before this field
    existed are the setting's."""

    @property
    def shards(self) -> int:
        return -(-self.episodes // self.shard_size)

    def identity(self) -> dict[str, Any]:
        """What must match for a resumed collection to continue this one."""
        d = asdict(self)
        for key in ("episodes", "code_version", "created"):
            d.pop(key)
        return d


def new_manifest(
    setting: Setting, env_config: EnvConfig, pusher: str, policy: str, base_seed: int,
    episodes: int, shard_size: int, worlds: str = "setting",
) -> Manifest:  # fmt: skip
    """The manifest of training episodes collected now with this code: of `setting` under
    `env_config`'s noise and pushes, pushed by `pusher` and the policy named `policy`."""
    return Manifest(
        schema_version=SCHEMA_VERSION,
        setting=setting.as_dict(),
        pusher=pusher,
        policy=policy,
        obs_noise=env_config.obs_noise,
        action_noise=env_config.action_noise,
        pushes=env_config.pushes,
        base_seed=base_seed,
        purpose=TRAIN,
        episodes=episodes,
        shard_size=shard_size,
        code_version=code_version(),
        created=time.strftime("%Y-%m-%dT%H:%M:%S%z"),
        worlds=worlds,
    )


def write_manifest(root: str | os.PathLike, manifest: Manifest) -> None:
    """Write `manifest` as `root`'s (atomically, as the shards)."""
    _write_json(Path(root) / MANIFEST, asdict(manifest))


def shard_path(root: Path, j: int) -> Path:
    return root / f"shard-{j:05d}.npz"


def read_manifest(root: str | os.PathLike) -> Manifest:
    path = Path(root) / MANIFEST
    if not path.exists():
        raise DatasetError(f"{root} is not a masspush dataset: {MANIFEST} is missing")
    try:
        data = json.loads(path.read_text())
    except (OSError, json.JSONDecodeError) as err:
        raise DatasetError(f"{path} is unreadable or corrupt: {err}") from None
    version = data.get("schema_version")
    if version != SCHEMA_VERSION:
        raise DatasetError(
            f"{path} has schema version {version!r}; this masspush reads version "
            f"{SCHEMA_VERSION}: recollect the data, or use the masspush that wrote it"
        )
    try:
        manifest = Manifest(**data)
    except TypeError as err:
        raise DatasetError(
            f"{path} does not have the schema-{SCHEMA_VERSION} fields: {err}"
        ) from None
    if manifest.worlds not in WORLDS:
        raise DatasetError(f"{path}: worlds must be one of {list(WORLDS)}, got {manifest.worlds!r}")
    return manifest


@dataclass(frozen=True)
class CollectConfig:
    """`masspush collect`: rollout episodes into a dataset directory (resumable)."""

    setting: str
    """Named setting, e.g. 2link-0.1-1."""
    out: str
    """Dataset directory (a rerun resumes what is there)."""
    episodes: int
    """Episodes the dataset is to hold."""
    policy: str = "random"
    """The pushing policy (registered names: `masspush.data.rollout.POLICIES`)."""
    pusher: str | None = pusher_field()
    """The pusher (default: the setting's)."""
    seed: int = 0
    """Base seed of the episodes."""
    shard_size: int = 1000
    """Episodes per shard file."""
    workers: int | None = None
    """Processes for an arm (default: one per core); with --ray local, the CPUs of the
    cluster started for the run."""
    ray: str | None = None
    """Run on a Ray cluster, one task per shard: auto (this machine's cluster), local (one
    started for the run), ray://HOST:PORT or HOST:PORT (pip install 'masspush[ray]')."""
    settings_file: str | None = None
    """TOML file with custom settings."""
    resize: bool = False
    """Make an existing dataset hold exactly --episodes (cutting it down deletes episodes)."""

    MAX_EPISODES: ClassVar[int] = 100_000_000
    """More is a typo, not a dataset: 10^8 two-link episodes already take ~60 GB."""

    def __post_init__(self) -> None:
        check_int("episodes", self.episodes)
        if self.episodes > self.MAX_EPISODES:
            raise ValueError(
                f"episodes must be at most {self.MAX_EPISODES:,}, got {self.episodes:,}"
            )
        check_int("shard_size", self.shard_size)
        check_int("seed", self.seed, 0)
        check_int("workers", self.workers, optional=True)
        check_choice("policy", self.policy, tuple(POLICIES))
        if self.pusher is not None:
            pusher_kind(self.pusher)
        check_address(self.ray)


def collect_dataset(config: CollectConfig, progress: bool = True) -> Manifest:
    """`collect` as `config` says."""
    setting = get_setting(config.setting, config.settings_file)
    with open_pool(config.ray, config.workers) as workers:
        return collect(
            setting, config.out, episodes=config.episodes,
            pusher=config.pusher or setting.pusher, policy=config.policy, base_seed=config.seed,
            shard_size=config.shard_size, workers=workers, progress=progress,
            resize=config.resize,
        )  # fmt: skip


def collect(
    setting: Setting,
    out: str | os.PathLike,
    episodes: int,
    pusher: str,
    policy: str | Policy = "random",
    base_seed: int = 0,
    shard_size: int = 1000,
    env_config: EnvConfig | None = None,
    workers: Workers = None,
    progress: bool = True,
    resize: bool = False,
) -> Manifest:
    """Collect `episodes` episodes into `out`, resuming whatever is already there.

    `policy`: a registered policy's name, or a `Policy` object (a trained one). A larger
    `episodes` than the directory's grows it; a smaller one is refused while the dataset is
    incomplete, unless `resize` makes it hold exactly `episodes` (shards beyond are deleted).
    A request that would not fit on the disk is refused before any work; a disk that fills
    up during the collection leaves only whole shards, and the same command resumes.
    `workers` may be a `TaskPool` (a Ray cluster): one task per shard, written here."""
    if episodes < 1 or shard_size < 1:
        raise ValueError(f"episodes and shard_size must be >= 1, got {episodes}, {shard_size}")
    if isinstance(policy, str):
        if policy not in POLICIES:
            raise ValueError(f"unknown policy {policy!r}; known: {sorted(POLICIES)}")
        policy = POLICIES[policy]()
    root = Path(out)
    root.mkdir(parents=True, exist_ok=True)
    env_config = env_config or setting.env_config(pusher)
    manifest = new_manifest(setting, env_config, pusher, policy.name, base_seed, episodes,
                            shard_size)  # fmt: skip
    old = read_manifest(root) if (root / MANIFEST).exists() else None
    if old is not None:
        if old.identity() != manifest.identity():
            raise DatasetError(
                f"{root} holds a different collection ({old.identity()}); "
                "collect into another directory"
            )
        manifest = _resized(root, old, episodes, resize)
    if old is None or old.episodes != manifest.episodes:
        write_manifest(root, manifest)  # unchanged: read-only storage is fine
    todo = [j for j in range(manifest.shards) if not _complete(root, manifest, j)]
    missing = sum(_shard_len(manifest, j) for j in todo)
    _check_disk(root, env_config, missing)
    done = manifest.episodes - missing
    # initial: a resumed collection's rate and time left count only the episodes run now.
    with tqdm(
        total=manifest.episodes,
        initial=done,
        desc=f"collecting {setting.name} ({pusher})",
        unit="ep",
        disable=not progress,
    ) as bar:
        if is_pool(workers):
            shards = _shards_on_pool(
                workers, manifest, todo, (env_config, policy, TRAIN, base_seed)
            )
        else:
            shards = (
                (j, run_episodes(env_config, policy, _shard_indices(manifest, j), TRAIN,
                                 base_seed, workers))
                for j in todo
            )  # fmt: skip
        for j, eps in shards:
            try:
                write_shard(shard_path(root, j), eps)
            except OSError as err:
                raise OSError(err.errno, (
                    f"{err.strerror}; the {done} episodes written are safe: "
                    "free space and rerun the same command to resume"),
                    str(shard_path(root, j))) from err  # fmt: skip
            bar.update(len(eps))
            done += len(eps)
    return manifest


def _shard_indices(manifest: Manifest, j: int) -> np.ndarray:
    lo = j * manifest.shard_size
    return np.arange(lo, lo + _shard_len(manifest, j))


def _shards_on_pool(
    pool: TaskPool, manifest: Manifest, todo: list[int], shared: tuple
) -> Iterator[tuple[int, Episodes]]:
    """The shards `todo` computed on `pool`, as each completes: a task per shard, or, with
    fewer shards than about four per worker, a shard split into chunks of consecutive
    episodes (put back together in order, so the shard is the same)."""
    parts = max(1, -(-4 * pool.size // len(todo))) if todo else 1
    tasks = []
    for j in todo:
        tasks += [(j, chunk) for chunk in np.array_split(_shard_indices(manifest, j), parts)
                  if len(chunk)]  # fmt: skip
    waiting = Counter(j for j, _ in tasks)
    done: dict[int, dict[int, Episodes]] = {j: {} for j in todo}
    for t, eps in pool.imap(run_chunk, [chunk for _, chunk in tasks], shared):
        j = tasks[t][0]
        done[j][t] = eps
        if len(done[j]) == waiting[j]:
            chunks = done.pop(j)
            yield j, Episodes.concatenate([chunks[t] for t in sorted(chunks)])


def _resized(root: Path, old: Manifest, episodes: int, resize: bool) -> Manifest:
    """The manifest after a request for `episodes`: grown, kept, or (`resize`) cut down."""
    if episodes >= old.episodes:
        # Growing a dataset keeps its shards: episode i is the same whatever N is.
        return replace(old, episodes=episodes)
    if not resize:
        if all(_complete(root, old, j) for j in range(old.shards)):
            return old  # complete and larger than asked: nothing to do
        raise DatasetError(
            f"{root} is a collection of {old.episodes:,} episodes, not yet complete; rerun "
            f"with --episodes {old.episodes} to resume it, or add --resize to make it hold "
            f"{episodes:,}"
        )
    new = replace(old, episodes=episodes)
    for j in range(new.shards, old.shards):
        shard_path(root, j).unlink(missing_ok=True)
    last = new.shards - 1
    if _complete(root, old, last) and _shard_len(new, last) < _shard_len(old, last):
        part = read_shard(shard_path(root, last))
        keep = np.arange(len(part)) < _shard_len(new, last)
        write_shard(shard_path(root, last), part.select(keep))
    return new


def _check_disk(root: Path, env_config: EnvConfig, episodes: int) -> None:
    """Refuse, before any work, a collection that would not fit on the disk."""
    n = env_config.physics.n_links
    one = empty_episodes(1, env_config.pushes, n)
    need = episodes * sum(getattr(one, f.name).nbytes for f in fields(Episodes))
    free = shutil.disk_usage(root).free
    if need > free:
        raise OSError(errno.ENOSPC, (
            f"the {episodes:,} episodes to collect need about {need / 1e9:.2f} GB "
            f"(uncompressed), {free / 1e9:.2f} GB are free"), str(root))  # fmt: skip


def _shard_len(manifest: Manifest, j: int) -> int:
    return min(manifest.shard_size, manifest.episodes - j * manifest.shard_size)


def _complete(root: Path, manifest: Manifest, j: int) -> bool:
    return shard_complete(shard_path(root, j), _shard_len(manifest, j))


def shard_complete(path: Path, episodes: int) -> bool:
    """Whether the shard at `path` is there, readable and holds `episodes` episodes."""
    if not path.exists():
        return False
    try:
        return len(read_shard(path)) == episodes
    except DatasetError:
        return False  # a damaged shard is recomputed


def _write_json(path: Path, data: dict) -> None:
    tmp = path.with_suffix(".tmp")
    tmp.write_text(json.dumps(data, indent=2))
    os.replace(tmp, path)


def write_shard(path: Path, eps: Episodes) -> None:
    tmp = path.with_name(path.name + ".tmp")
    try:
        with open(tmp, "wb") as f:
            np.savez_compressed(f, **{fl.name: getattr(eps, fl.name) for fl in fields(Episodes)})
        os.replace(tmp, path)  # atomic: a shard is either whole or absent
    except BaseException:
        tmp.unlink(missing_ok=True)  # a full disk or a kill leaves no partial file behind
        raise


def read_shard(path: Path) -> Episodes:
    try:
        with np.load(path, allow_pickle=False) as z:
            arrays = {fl.name: z[fl.name] for fl in fields(Episodes)}
    except (zipfile.BadZipFile, EOFError, OSError, ValueError) as err:
        raise DatasetError(
            f"{path} is truncated or corrupt ({err}); delete it and resume"
        ) from None
    except KeyError as err:
        raise DatasetError(
            f"{path} lacks the array {err}; not a schema-{SCHEMA_VERSION} shard"
        ) from None
    e = len(arrays["index"])
    if any(len(a) != e for a in arrays.values()):
        raise DatasetError(f"{path} has arrays of different lengths; it is corrupt")
    return Episodes(**arrays)


def load_dataset(root: str | os.PathLike, limit: int | None = None) -> tuple[Manifest, Episodes]:
    """The manifest and (the first `limit`) episodes of a complete dataset."""
    root = Path(root)
    manifest = read_manifest(root)
    wanted = manifest.episodes if limit is None else min(limit, manifest.episodes)
    parts, have = [], 0
    for j in range(manifest.shards):
        if have >= wanted:
            break
        path = shard_path(root, j)
        if not path.exists():
            raise DatasetError(
                f"{root} is incomplete: {path.name} is missing; resume the collection "
                f"({'masspush randomise' if manifest.worlds != 'setting' else 'masspush collect'}"
                f" ... --out {root})"
            )
        part = read_shard(path)
        if len(part) != _shard_len(manifest, j):
            raise DatasetError(
                f"{path} holds {len(part)} episodes, expected {_shard_len(manifest, j)}"
            )
        parts.append(part)
        have += len(part)
    episodes = Episodes.concatenate(parts)
    if limit is not None:
        episodes = episodes.select(np.arange(len(episodes)) < wanted)
    if not np.array_equal(episodes.index, np.arange(len(episodes))):
        raise DatasetError(f"{root}: episode indices are not 0..{len(episodes) - 1}; corrupt")
    return manifest, episodes
