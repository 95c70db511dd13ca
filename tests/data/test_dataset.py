import json
import subprocess
import sys
import time

import numpy as np
import pytest

from masspush.data.dataset import DatasetError, collect, load_dataset, read_manifest, shard_path
from masspush.settings import get_setting

SETTING = get_setting("2link-0.1-1")


def small(path, episodes=30, **kw):
    return collect(
        SETTING, path, episodes=episodes, pusher="stiff", shard_size=10, progress=False, **kw
    )


def test_collect_and_load(tmp_path):
    manifest = small(tmp_path / "d")
    loaded_manifest, eps = load_dataset(tmp_path / "d")
    assert loaded_manifest == manifest and manifest.shards == 3
    assert manifest.setting["name"] == "2link-0.1-1" and manifest.pusher == "stiff"
    assert manifest.schema_version == 1 and manifest.code_version
    np.testing.assert_array_equal(eps.index, np.arange(30))
    assert eps.observations.shape == (30, 3, 4) and eps.actions.shape == (30, 2, 2)
    assert load_dataset(tmp_path / "d", limit=12)[1].index.tolist() == list(range(12))


@pytest.mark.slow
def test_a_killed_collection_resumes_without_losing_or_duplicating(tmp_path):
    reference = tmp_path / "ref"
    small(reference, episodes=60)
    _, expected = load_dataset(reference)
    target = tmp_path / "killed"
    cmd = [
        sys.executable,
        "-m",
        "masspush.cli",
        "collect",
        "--setting",
        "2link-0.1-1",
        "--pusher",
        "stiff",
        "--episodes",
        "60",
        "--shard-size",
        "10",
        "--out",
        str(target),
    ]
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.time() + 120
    while not shard_path(target, 1).exists() and time.time() < deadline:
        time.sleep(0.05)
    proc.kill()
    proc.wait()
    done_before = len(list(target.glob("shard-*.npz")))
    assert 1 <= done_before < 6, "the kill came too late to test resuming"
    small(target, episodes=60)
    _, resumed = load_dataset(target)
    np.testing.assert_array_equal(resumed.index, np.arange(60))  # none lost, none twice
    for name in ("observations", "actions", "masses"):
        np.testing.assert_array_equal(getattr(resumed, name), getattr(expected, name))
    assert not list(target.glob("*.tmp"))


def test_corrupt_truncated_and_foreign_datasets_are_refused(tmp_path):
    root = tmp_path / "d"
    small(root)
    shard = shard_path(root, 1)
    shard.write_bytes(shard.read_bytes()[:100])
    with pytest.raises(DatasetError, match="truncated or corrupt"):
        load_dataset(root)
    shard.unlink()
    with pytest.raises(DatasetError, match="incomplete"):
        load_dataset(root)
    small(root)  # resuming repairs it
    load_dataset(root)
    manifest = json.loads((root / "manifest.json").read_text())
    manifest["schema_version"] = 99
    (root / "manifest.json").write_text(json.dumps(manifest))
    with pytest.raises(DatasetError, match="schema version 99"):
        load_dataset(root)
    with pytest.raises(DatasetError, match="not a masspush dataset"):
        load_dataset(tmp_path)


def test_a_manifest_says_where_its_episodes_were_pushed(tmp_path):
    root = tmp_path / "d"
    small(root)
    assert read_manifest(root).worlds == "setting"
    manifest = json.loads((root / "manifest.json").read_text())
    del manifest["worlds"]  # as written before the field existed
    (root / "manifest.json").write_text(json.dumps(manifest))
    assert read_manifest(root).worlds == "setting"
    (root / "manifest.json").write_text(json.dumps({**manifest, "worlds": "mars"}))
    with pytest.raises(DatasetError, match="worlds must be one of"):
        read_manifest(root)


def test_resuming_with_other_parameters_is_refused(tmp_path):
    small(tmp_path / "d")
    with pytest.raises(DatasetError, match="different collection"):
        small(tmp_path / "d", base_seed=3)


def _same(a, b) -> None:
    for name in ("index", "observations", "actions", "masses"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))


def test_a_finished_dataset_is_left_as_it_is(tmp_path, monkeypatch):
    small(tmp_path / "d", episodes=20)
    import masspush.data.dataset as dataset

    def read_only(*_):
        raise PermissionError(13, "Read-only file system", str(tmp_path / "d"))

    # On read-only storage any write fails: a rerun of a finished collection writes nothing.
    monkeypatch.setattr(dataset, "_write_json", read_only)
    monkeypatch.setattr(dataset, "write_shard", read_only)
    assert small(tmp_path / "d", episodes=20).episodes == 20
    assert small(tmp_path / "d", episodes=10).episodes == 20  # complete and larger: kept


def test_a_dataset_is_resized_only_when_asked(tmp_path):
    whole = load_dataset(small(tmp_path / "ref", episodes=25) and tmp_path / "ref")[1]
    small(tmp_path / "d", episodes=25)
    (tmp_path / "d" / "shard-00001.npz").unlink()  # incomplete
    with pytest.raises(DatasetError, match="--episodes 25 to resume it, or add --resize"):
        small(tmp_path / "d", episodes=15)
    assert small(tmp_path / "d", episodes=15, resize=True).episodes == 15
    manifest, cut = load_dataset(tmp_path / "d")
    assert manifest.episodes == 15 and not shard_path(tmp_path / "d", 2).exists()
    _same(cut, whole.select(whole.index < 15))
    small(tmp_path / "d", episodes=25)  # grown back: the same episodes
    _same(load_dataset(tmp_path / "d")[1], whole)


def test_a_full_disk_leaves_whole_shards_and_resumes(tmp_path, monkeypatch):
    import errno

    import masspush.data.dataset as dataset

    whole = load_dataset(small(tmp_path / "ref") and tmp_path / "ref")[1]
    real = np.savez_compressed
    calls = []

    def disk_fills(f, **arrays):
        calls.append(1)
        if len(calls) == 2:
            f.write(b"partial")
            raise OSError(errno.ENOSPC, "No space left on device")
        real(f, **arrays)

    monkeypatch.setattr(dataset.np, "savez_compressed", disk_fills)
    with pytest.raises(OSError, match="the 10 episodes written are safe") as err:
        small(tmp_path / "d")
    assert err.value.filename.endswith("shard-00001.npz")
    assert not list((tmp_path / "d").glob("*.tmp"))
    small(tmp_path / "d")
    _same(load_dataset(tmp_path / "d")[1], whole)


def test_a_collection_larger_than_the_disk_is_refused_before_work(tmp_path, monkeypatch):
    import shutil

    import masspush.data.dataset as dataset

    monkeypatch.setattr(dataset.shutil, "disk_usage", lambda _: shutil._ntuple_diskusage(1, 1, 1))
    monkeypatch.setattr(dataset, "run_episodes", lambda *_: pytest.fail("started work"))
    with pytest.raises(OSError, match=r"need about .* GB .* are free"):
        small(tmp_path / "d")


def shard_bytes(root) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(root.glob("shard-*.npz"))}


@pytest.mark.parametrize("episodes", [30, 7])  # three shards; fewer shards than workers
def test_a_collection_on_a_pool_writes_the_same_shards_byte_for_byte(
    tmp_path, serial_pool, episodes
):
    small(tmp_path / "here", episodes=episodes)
    pool = serial_pool(size=2)
    small(tmp_path / "pool", episodes=episodes, workers=pool)
    assert shard_bytes(tmp_path / "pool") == shard_bytes(tmp_path / "here")
    # Few shards are split into chunks of episodes, so every worker has work.
    assert pool.tasks > -(-episodes // 10)


def test_a_collection_on_a_pool_stopped_midway_resumes_to_the_same_shards(tmp_path, serial_pool):
    small(tmp_path / "here", episodes=40)
    with pytest.raises(KeyboardInterrupt):
        small(tmp_path / "pool", episodes=40, workers=serial_pool(stop_after=5))
    written = len(shard_bytes(tmp_path / "pool"))
    assert 1 <= written < 4
    small(tmp_path / "pool", episodes=40, workers=serial_pool())
    assert shard_bytes(tmp_path / "pool") == shard_bytes(tmp_path / "here")


@pytest.mark.slow
def test_a_collection_on_a_ray_cluster_is_byte_identical(tmp_path, ray_cluster):
    from masspush.cluster.pool import open_pool

    small(tmp_path / "here", episodes=30)
    with open_pool(ray_cluster) as pool:
        small(tmp_path / "ray", episodes=30, workers=pool)
    assert shard_bytes(tmp_path / "ray") == shard_bytes(tmp_path / "here")
