"""The pool protocol, the address check and the chunking: no cluster needed."""

from __future__ import annotations

import numpy as np
import pytest

from masspush.cluster.pool import check_address, gather, is_pool, open_pool, split


@pytest.mark.parametrize("address", ["auto", "local", "ray://10.0.0.5:10001", "head:6379",
                                     "192.168.1.2:6379"])  # fmt: skip
def test_addresses_a_cluster_can_have_pass(address, monkeypatch):
    monkeypatch.setattr("importlib.util.find_spec", lambda name: object())
    check_address(address)


@pytest.mark.parametrize("address", ["", "remote", "ray://host", "http://h:1", "h:port", 3])
def test_other_addresses_fail_in_one_line_naming_the_option(address):
    with pytest.raises(ValueError, match=r"^ray must be auto, local, ray://HOST:PORT"):
        check_address(address)


def test_without_ray_installed_the_message_says_how_to_get_it(monkeypatch):
    monkeypatch.setattr("importlib.util.find_spec", lambda name: None)
    with pytest.raises(ValueError, match=r"pip install 'masspush\[ray\]'"):
        check_address("local")


def test_no_address_leaves_the_workers_as_they_are():
    with open_pool(None, 3) as workers:
        assert workers == 3 and not is_pool(workers)


def test_split_covers_every_index_once_in_order(serial_pool):
    indices = np.arange(5, 105)
    chunks = split(indices, serial_pool(size=3))
    assert np.array_equal(np.concatenate(chunks), indices)
    assert len(chunks) == 12  # about four per worker
    assert [len(c) for c in split(indices, serial_pool(), per_task=40)] == [40, 40, 20]


def test_gather_restores_the_order_of_the_jobs(serial_pool):
    pool = serial_pool()
    assert is_pool(pool)
    assert gather(pool.imap(lambda s, j: s * j, [1, 2, 3], shared=10), 3) == [10, 20, 30]
