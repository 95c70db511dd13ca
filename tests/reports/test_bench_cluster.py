"""`masspush bench ray`: the same collection here and on Ray, checked to be identical."""

from __future__ import annotations

import pytest

from masspush.reports.bench_cluster import ClusterBench, bench_cluster


@pytest.mark.slow
def test_the_bench_compares_a_ray_collection_with_the_local_one(ray_cluster):
    result = bench_cluster(
        ClusterBench(setting="2link-1-10", pusher="stiff", episodes=12, shard_size=4,
                     cpus=(2,), overhead_tasks=5)
    )  # fmt: skip
    ray = result["ray_2"]
    assert ray["identical"] is True
    assert ray["episodes_per_s"] > 0 and ray["overhead_per_task_ms"] > 0
    assert ray["ratio_to_local"] == pytest.approx(result["local"]["seconds"] / ray["seconds"])


def test_bad_bench_sizes_are_refused():
    with pytest.raises(ValueError, match="cpus"):
        ClusterBench(cpus=())
    with pytest.raises(ValueError, match="episodes"):
        ClusterBench(episodes=0)
