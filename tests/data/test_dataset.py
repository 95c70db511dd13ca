import json
import subprocess
import sys
import time

import numpy as np
import pytest

from masspush.data.dataset import DatasetError, collect, load_dataset, shard_path
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


def test_resuming_with_other_parameters_is_refused(tmp_path):
    small(tmp_path / "d")
    with pytest.raises(DatasetError, match="different collection"):
        small(tmp_path / "d", base_seed=3)
