"""fieldgen: robot-soccer fields from YAML specs, compiled to batched MJX environments.

`fieldgen.make(...)` is imported lazily so that `fieldgen validate` and friends
start without loading JAX.
"""

import ctypes.util
import os


def headless_gl(find_library=ctypes.util.find_library) -> str:
    """mujoco's offscreen back end for a machine without a display: EGL, else OSMesa, else none.

    Naming a back end whose library is missing breaks `import mujoco` itself (PyOpenGL raises
    AttributeError, which mujoco does not catch), so a training machine without EGL could not
    even simulate; with none, only drawing fails, and fieldgen says so where it draws."""
    for backend, library in (("egl", "EGL"), ("osmesa", "OSMesa")):
        if find_library(library):
            return backend
    return "disable"


if "MUJOCO_GL" not in os.environ:
    os.environ["MUJOCO_GL"] = headless_gl()

from fieldgen.version import VERSION as __version__  # noqa: E402


def __getattr__(name):
    if name in ("make", "FieldEnv"):
        from fieldgen import env

        return getattr(env, name)
    if name == "load_policy":
        from fieldgen.policy_folder import load_policy

        return load_policy
    raise AttributeError(f"module 'fieldgen' has no attribute {name!r}")
