"""A Ray cluster as a pool: faults cost retries, never episodes; problems are one line."""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap

import pytest

from masspush.data.dataset import collect
from masspush.settings import get_setting

# Runs in its own process: a cluster of a head without CPUs and two one-CPU nodes, which
# `connect` refuses while the nodes are missing; then a collection whose tasks meet a
# killed worker process and a removed node.
FAULTS = textwrap.dedent(
    """
    import json, logging, os, sys, threading, time
    import ray
    from ray.cluster_utils import Cluster
    from masspush.cluster.errors import ClusterError
    from masspush.cluster.ray_pool import connect
    from masspush.data.dataset import collect
    from masspush.data.rollout import TRAIN, RandomPolicy, episode_seed
    from masspush.settings import get_setting

    out, marks = sys.argv[1], sys.argv[2]

    class Faulty(RandomPolicy):
        # Random pushes (the same name, so the same dataset). The first task with episode
        # 13 kills its worker process; the first with episode 27 stalls on its node, which
        # the driver then removes from the cluster.
        def reset(self, seeds):
            if episode_seed(TRAIN, 5, 13) in seeds and not os.path.exists(marks + "/killed"):
                open(marks + "/killed", "w").close()
                os._exit(1)
            if episode_seed(TRAIN, 5, 27) in seeds and not os.path.exists(marks + "/node"):
                with open(marks + "/node.tmp", "w") as f:
                    f.write(ray.get_runtime_context().get_node_id())
                os.replace(marks + "/node.tmp", marks + "/node")
                time.sleep(120)
            super().reset(seeds)

    cluster = Cluster(initialize_head=True, head_node_args={"num_cpus": 0})
    ray.init(address=cluster.address, logging_level=logging.ERROR)
    report = {}
    try:
        with connect("auto"):
            pass
    except ClusterError as err:
        report["no_cpus"] = str(err)
    nodes = [cluster.add_node(num_cpus=1) for _ in range(2)]
    cluster.wait_for_nodes()
    removed = []

    def remove_the_stalled_node():
        while not os.path.exists(marks + "/node"):
            time.sleep(0.05)
        stalled = open(marks + "/node").read()
        for node in nodes:
            if node.node_id == stalled:
                cluster.remove_node(node, allow_graceful=False)
                removed.append(stalled)

    threading.Thread(target=remove_the_stalled_node, daemon=True).start()
    with connect("auto") as pool:
        collect(get_setting("2link-1-10"), out, episodes=40, pusher="stiff", policy=Faulty(),
                base_seed=5, shard_size=10, workers=pool, progress=False)
    report["killed"] = os.path.exists(marks + "/killed")
    report["removed"] = len(removed)
    ray.shutdown()
    cluster.shutdown()
    print(json.dumps(report))
    """
)


@pytest.mark.slow
def test_a_lost_worker_or_node_costs_a_retry_never_an_episode(tmp_path):
    marks = tmp_path / "marks"
    marks.mkdir()
    proc = subprocess.run(
        [sys.executable, "-c", FAULTS, str(tmp_path / "ray"), str(marks)],
        capture_output=True, text=True, timeout=600,
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr[-3000:]
    report = json.loads(proc.stdout.strip().splitlines()[-1])
    assert report["killed"] and report["removed"] == 1
    assert "has 0 CPUs" in report["no_cpus"] and "\n" not in report["no_cpus"]
    collect(get_setting("2link-1-10"), tmp_path / "here", episodes=40, pusher="stiff",
            base_seed=5, shard_size=10, progress=False)  # fmt: skip
    for j in range(4):
        name = f"shard-{j:05d}.npz"
        assert (tmp_path / "ray" / name).read_bytes() == (tmp_path / "here" / name).read_bytes()


@pytest.mark.slow
def test_a_task_error_reaches_the_caller_as_itself(ray_cluster):
    from masspush.cluster.pool import open_pool

    def bad(shared, job):
        raise ValueError(f"job {job} is bad")

    with open_pool(ray_cluster) as pool, pytest.raises(ValueError, match=r"^job 1 is bad$"):
        list(pool.imap(bad, [1]))


def test_an_unreachable_cluster_is_one_line_before_any_work(tmp_path):
    pytest.importorskip("ray")
    proc = subprocess.run(
        [sys.executable, "-m", "masspush.cli", "collect", "--setting", "2link-1-10",
         "--episodes", "10", "--out", str(tmp_path / "d"), "--ray", "127.0.0.1:1"],
        capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert proc.returncode == 1
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and "cannot reach a Ray cluster at 127.0.0.1:1" in lines[0]
    assert not (tmp_path / "d" / "shard-00000.npz").exists()
