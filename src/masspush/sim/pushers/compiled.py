"""The arm's control loop compiled (osc_law.c), loaded with ctypes; the Python law in
`masspush.sim.pushers.arm` stays the reference and the fallback.

Where the library comes from: `make` builds it at install (`compiled.main()`) beside
this file; an installation without it builds it on
first use into the user's cache (~/.cache/masspush). Either way it is compiled against the
headers of the MuJoCo that runs it, and named for that version and the source's hash, so
an upgraded MuJoCo or an edited source gets a fresh build. Without a C compiler the arm
runs the Python law, 2.2x slower, and says so once. MASSPUSH_PURE_PYTHON=1 asks for the
Python law.
"""

from __future__ import annotations

import ctypes
import hashlib
import os
import shutil
import subprocess
import sys
import tempfile
import warnings
from collections.abc import Iterator
from contextlib import contextmanager
from functools import cache
from pathlib import Path
from typing import ClassVar

import mujoco
import numpy as np
from numpy.typing import ArrayLike

SOURCE = Path(__file__).with_name("osc_law.c")
MUJOCO_DIR = Path(mujoco.__file__).parent
# Named for the source and the MuJoCo it was built for: an edited osc_law.c or an upgraded
# MuJoCo gets a fresh build instead of a stale library.
LIBRARY = (
    f"osc_law-{hashlib.sha256(SOURCE.read_bytes()).hexdigest()[:12]}-mujoco{mujoco.__version__}.so"
)
PURE_PYTHON = "MASSPUSH_PURE_PYTHON"
"""Set (to anything but 0) to run the arms with the Python law."""
# -ffp-contract=off: no fused multiply-adds, whose single rounding would make the
# compiled law differ from NumPy's in the last bits.
CFLAGS = ["-O2", "-fPIC", "-shared", "-ffp-contract=off", "-std=c99"]


class Userdata:
    """Where the lockstep control callback (osc_law.c, `masspush_control`) keeps a
    simulation's push in `mjData.userdata`; the C file's U_ enum, checked at load."""

    PHASE, STEP, CONTACT, HOLD, DEADLINE, RETRACT, SPEED = range(7)
    X, R, V, AXIS, USE_AXIS = 7, 10, 19, 25, 28
    SIZE = 29
    # phases
    OFF, VELOCITY, RETRACTING, DONE, ARM_CONTACT, UNREACHABLE = range(6)
    FAILURES: ClassVar[dict[int, str | None]] = {
        DONE: None,
        ARM_CONTACT: "arm_contact",
        UNREACHABLE: "unreachable",
    }


class Arm(ctypes.Structure):
    _fields_ = [
        ("dof0", ctypes.c_int),
        ("act", ctypes.c_int * 6),
        ("site", ctypes.c_int),
        ("ee", ctypes.c_int),
        ("is_arm", ctypes.c_void_p),
        ("is_chain", ctypes.c_void_p),
        ("torque_limit", ctypes.c_double * 6),
        ("kp", ctypes.c_double),
        ("kd", ctypes.c_double),
        ("task_damping", ctypes.c_double),
        ("jac", ctypes.c_void_p),
        ("minv_jt", ctypes.c_void_p),
    ]


class Target(ctypes.Structure):
    _fields_ = [
        ("x_des", ctypes.c_double * 3),
        ("r_des", ctypes.c_double * 9),
        ("v_des", ctypes.c_double * 6),
        ("free_axis", ctypes.c_double * 3),
        ("use_free_axis", ctypes.c_int),
    ]


def _mujoco_library() -> Path:
    found = sorted(MUJOCO_DIR.glob("libmujoco.so*"))
    if not found:
        raise FileNotFoundError(f"no libmujoco.so in {MUJOCO_DIR}")
    return found[0]


def build(directory: str | os.PathLike) -> Path:
    """Compile osc_law.c against the running MuJoCo into `directory`; the library's path.
    Raises OSError (no compiler) or subprocess.CalledProcessError (a failed build)."""
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    compiler = os.environ.get("CC") or shutil.which("cc") or shutil.which("gcc")
    if compiler is None:
        raise FileNotFoundError("no C compiler (cc, gcc or $CC)")
    lib = _mujoco_library()
    out = directory / LIBRARY
    # Built under a temporary name and renamed: processes that build at once never load
    # a half-written library.
    with tempfile.NamedTemporaryFile(dir=directory, suffix=".so", delete=False) as tmp:
        partial = Path(tmp.name)
    try:
        subprocess.run(
            [compiler, *CFLAGS, "-I", str(MUJOCO_DIR / "include"), str(SOURCE), "-o",
             str(partial), str(lib), f"-Wl,-rpath,{lib.parent}", "-lm"],
            check=True, capture_output=True, text=True,
        )  # fmt: skip
        os.replace(partial, out)
    finally:
        partial.unlink(missing_ok=True)
    return out


BUILD_DIR = Path(__file__).parent / "_build"
"""Where `make` builds the library (an editable install's package directory)."""


def _candidates() -> list[Path]:
    cache_dir = Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache")) / "masspush"
    return [BUILD_DIR, cache_dir]


@cache
def library() -> ctypes.CDLL | None:
    """The compiled control loop, or None (the Python law then runs; said once)."""
    if os.environ.get(PURE_PYTHON, "0") not in ("", "0"):
        return None
    path = next((d / LIBRARY for d in _candidates() if (d / LIBRARY).exists()), None)
    reason = ""
    if path is None:
        for directory in _candidates():
            try:
                path = build(directory)
                break
            except (OSError, subprocess.CalledProcessError) as err:
                reason = getattr(err, "stderr", None) or str(err)
    if path is None:
        warnings.warn(
            f"the arms run their control law in Python (about 2x slower): the compiled law "
            f"could not be built ({reason.strip().splitlines()[-1] if reason else '?'})",
            RuntimeWarning,
            stacklevel=2,
        )
        return None
    lib = ctypes.CDLL(str(path))
    if lib.masspush_mujoco_version() != mujoco.mj_version():
        return None  # built for another MuJoCo: the Python law is always right
    pointer = ctypes.c_void_p
    for name in ("masspush_velocity_phase", "masspush_retract"):
        getattr(lib, name).restype = ctypes.c_int
    lib.masspush_velocity_phase.argtypes = [
        pointer, pointer, ctypes.POINTER(Arm), ctypes.POINTER(Target), ctypes.c_int,
        ctypes.c_int, pointer, ctypes.POINTER(ctypes.c_int), ctypes.POINTER(ctypes.c_int),
        ctypes.POINTER(ctypes.c_double),
    ]  # fmt: skip
    lib.masspush_retract.argtypes = [
        pointer, pointer, ctypes.POINTER(Arm), ctypes.POINTER(Target), ctypes.c_int,
        ctypes.POINTER(ctypes.c_double),
    ]  # fmt: skip
    lib.masspush_set_arm.argtypes = [ctypes.POINTER(Arm)]
    lib.masspush_set_arm.restype = None
    if lib.masspush_userdata_size() != Userdata.SIZE:
        return None  # a library out of step with this file: the Python law is always right
    return lib


@contextmanager
def lockstep_law(lib: ctypes.CDLL, arm: Arm) -> Iterator[None]:
    """While inside, `lib`'s control callback is MuJoCo's (`mjcb_control`, global to the
    process) for the arm `arm`; the callback that was there before comes back after, so
    that no other model stepped later in the process meets ours. Ours acts only on
    simulations whose userdata holds a push: every other scene steps as before."""
    lib.masspush_set_arm(ctypes.byref(arm))
    before = mujoco.get_mjcb_control()
    mujoco.set_mjcb_control(lib.masspush_control)
    try:
        yield
    finally:
        mujoco.set_mjcb_control(before)


def target(
    x_des: ArrayLike, r_des: ArrayLike, v_des: ArrayLike, free_axis: ArrayLike | None = None
) -> Target:
    t = Target()
    t.x_des[:] = np.asarray(x_des, float).tolist()
    t.r_des[:] = np.asarray(r_des, float).ravel().tolist()
    t.v_des[:] = np.asarray(v_des, float).tolist()
    if free_axis is not None:
        t.free_axis[:] = np.asarray(free_axis, float).tolist()
        t.use_free_axis = 1
    return t


def main() -> int:
    """`make`: build the library beside this file; say so where it cannot be built."""
    try:
        print(f"built {build(BUILD_DIR)}")
    except (OSError, subprocess.CalledProcessError) as err:
        print(f"the compiled arm law was not built, the arms will run the Python law: "
              f"{getattr(err, 'stderr', '') or err}", file=sys.stderr)  # fmt: skip
    return 0
