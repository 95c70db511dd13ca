"""The real-robot path: the robot interface and its backends, recorded sessions, the
classifier fine-tuned on real episodes, the sim-to-real test world and domain randomisation.

The names of the 0.1 module `masspush.robot` are importable from here (`masspush.robot`
itself still imports, as this package)."""

from masspush.real.backends import (
    BACKENDS,
    RecordedPolicy,
    ReplayMismatchError,
    ReplayRobot,
    SimRobot,
    make_robot,
)
from masspush.real.robot import (
    EstimationEpisode,
    PushReport,
    RestPose,
    Robot,
    fmt,
    print_push,
    run_estimation,
    run_segments,
)

__all__ = [
    "BACKENDS",
    "EstimationEpisode",
    "PushReport",
    "RecordedPolicy",
    "ReplayMismatchError",
    "ReplayRobot",
    "RestPose",
    "Robot",
    "SimRobot",
    "fmt",
    "make_robot",
    "print_push",
    "run_estimation",
    "run_segments",
]
