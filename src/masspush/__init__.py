"""masspush: estimate how an articulated object's mass is distributed by pushing it.

Importing the package registers the Gymnasium environment "masspush/Chain-v0".
"""

from __future__ import annotations

import os

# MuJoCo picks its OpenGL backend when first imported; without a display, render headless
# through EGL (no extra packages needed) unless the user chose a backend.
if "MUJOCO_GL" not in os.environ and not os.environ.get("DISPLAY"):
    os.environ["MUJOCO_GL"] = "egl"

import gymnasium as gym

from masspush import _compat
from masspush.config import EnvConfig, PhysicsConfig
from masspush.env import ENV_ID, ChainEnv
from masspush.sim.batch import ChainBatch
from masspush.sim.chain import ChainParams, sample_chain
from masspush.sim.simulate import ChainSim, PushOutcome

__version__ = "0.1.0"

_compat.install()  # masspush.chain, masspush.robot, ... of 0.1 still import

if ENV_ID not in gym.registry:
    gym.register(id=ENV_ID, entry_point="masspush.env:ChainEnv")

__all__ = [
    "ENV_ID",
    "ChainBatch",
    "ChainEnv",
    "ChainParams",
    "ChainSim",
    "EnvConfig",
    "PhysicsConfig",
    "PushOutcome",
    "__version__",
    "sample_chain",
]
