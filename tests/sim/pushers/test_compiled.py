"""The compiled control loop (osc_law.c) against the Python law, the reference: the same
rest poses, failures and traces on a fixed set of pushes, failures included (issue 27)."""

from __future__ import annotations

import shutil
from dataclasses import replace

import numpy as np
import pytest

from masspush.config import PhysicsConfig
from masspush.sim.actions import PushGeometry
from masspush.sim.chain import sample_chain
from masspush.sim.pushers import compiled, make_pusher
from masspush.sim.simulate import ChainSim

# Where a C compiler is, the library must load: `make` builds it, or the first use does.
pytestmark = pytest.mark.skipif(
    shutil.which("cc") is None and shutil.which("gcc") is None, reason="no C compiler here"
)


def test_the_compiled_law_is_there_where_a_compiler_is():
    assert compiled.library() is not None


def _pushers(arm: str):
    ours, reference = make_pusher(arm), make_pusher(arm)
    reference.use_compiled = False
    return ours, reference


def _same_push(physics, chain, action, ours, reference) -> str | None:
    results = []
    for pusher in (ours, reference):
        sim = ChainSim(chain, physics, pusher)
        outcome = sim.push(np.asarray(action, float))
        results.append((sim.config(), outcome.failure, outcome.steps, pusher.trace))
    (q, failure, steps, trace), (q_ref, failure_ref, steps_ref, trace_ref) = results
    assert failure == failure_ref and steps == steps_ref
    np.testing.assert_allclose(q, q_ref, rtol=0, atol=1e-9)
    assert trace.contact_step == trace_ref.contact_step
    np.testing.assert_allclose(trace.tip_speed, trace_ref.tip_speed, rtol=0, atol=1e-9)
    assert trace.max_torque_ratio == pytest.approx(trace_ref.max_torque_ratio, abs=1e-9)
    return failure


@pytest.mark.slow
@pytest.mark.parametrize("arm", ["kuka", "ur10"])
@pytest.mark.parametrize("n_links", [2, 3])
def test_compiled_law_gives_the_reference_rest_poses(arm, n_links):
    physics = replace(PhysicsConfig(), n_links=n_links)
    ours, reference = _pushers(arm)
    rng = np.random.default_rng(n_links)
    for i in range(6):
        chain = sample_chain(physics, np.random.default_rng(100 + i))
        _same_push(physics, chain, rng.uniform(-1, 1, 2), ours, reference)


@pytest.mark.slow
def test_compiled_law_fails_as_the_reference_does():
    # Links 8 cm tall: the KUKA's wrist meets them in some pushes ("arm_contact").
    physics = replace(PhysicsConfig(), link_height=0.08)
    ours, reference = _pushers("kuka")
    failures = []
    for i, action in enumerate([(0.31, -0.64), (0.84, 0.36), (-0.87, 0.58), (0.54, -0.33)]):
        chain = sample_chain(physics, np.random.default_rng(1000 + 7 + i))
        failures.append(_same_push(physics, chain, action, ours, reference))
    assert "arm_contact" in failures, failures


@pytest.mark.slow
@pytest.mark.parametrize("arm", ["kuka", "ur10"])
def test_a_push_at_nothing_times_out_alike(arm):
    """A contact point with no chain there: the tip never touches, 'unreachable' at the
    velocity phase's deadline, in both laws."""
    physics = PhysicsConfig()
    chain = sample_chain(physics, np.random.default_rng(0))
    push = PushGeometry(np.array([0.4, 0.4]), np.array([1.0, 0.0]), 2.0)
    traces = []
    for pusher in _pushers(arm):
        sim = ChainSim(chain, physics, pusher)
        failure = pusher.deliver(sim.model, sim.data, push, physics)
        assert failure == "unreachable" and pusher.trace.contact_step is None
        traces.append(pusher.trace.tip_speed)
    np.testing.assert_allclose(traces[0], traces[1], rtol=0, atol=1e-9)


def test_the_python_law_is_there_when_asked_for_or_no_compiler(monkeypatch, tmp_path):
    compiled.library.cache_clear()
    monkeypatch.setenv(compiled.PURE_PYTHON, "1")
    assert compiled.library() is None
    compiled.library.cache_clear()
    monkeypatch.delenv(compiled.PURE_PYTHON)
    monkeypatch.setattr(compiled, "_candidates", lambda: [tmp_path / "a", tmp_path / "b"])
    monkeypatch.setenv("CC", str(tmp_path / "no-such-compiler"))
    with pytest.warns(RuntimeWarning, match="run their control law in Python"):
        assert compiled.library() is None
    compiled.library.cache_clear()


def test_a_build_makes_a_library_of_the_running_mujoco(tmp_path):
    import ctypes

    import mujoco

    path = compiled.build(tmp_path)
    assert path.name == compiled.LIBRARY and path.name.endswith(f"-mujoco{mujoco.__version__}.so")
    assert ctypes.CDLL(str(path)).masspush_mujoco_version() == mujoco.mj_version()
    assert [p.name for p in tmp_path.iterdir()] == [path.name]  # no partial file left
