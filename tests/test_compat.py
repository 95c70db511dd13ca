import importlib
import pickle

import masspush
from masspush._compat import OLD_PATHS


def test_every_module_path_of_the_flat_layout_still_imports():
    for old, new in OLD_PATHS.items():
        assert importlib.import_module(f"masspush.{old}") is importlib.import_module(new)


def test_public_names_users_import_keep_working():
    from masspush.chain import sample_chain
    from masspush.robot import PushReport, RestPose, Robot, SimRobot  # noqa: F401

    from masspush.bayes import ParticleFilter  # noqa: F401

    assert sample_chain is masspush.sample_chain
    assert masspush.ChainBatch.__module__ == "masspush.sim.batch"


def test_a_pickle_that_names_an_old_module_loads():
    from masspush.sim.chain import ChainParams

    # Protocol 0 names the module as text: what a file saved before the move holds.
    old = pickle.dumps(ChainParams, protocol=0).replace(b"masspush.sim.chain", b"masspush.chain")
    assert b"masspush.chain\n" in old
    assert pickle.loads(old) is ChainParams
