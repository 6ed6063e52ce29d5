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


GL_LIBRARIES = {"egl": ("EGL", "libegl1"), "osmesa": ("OSMesa", "libosmesa6")}  # back end: library, Debian package
# what mujoco takes for MUJOCO_GL on Linux (mujoco/rendering/classic/gl_context.py); the first five draw nothing
GL_VALUES = ("disable", "disabled", "off", "false", "0", "enable", "enabled", "on", "true", "1", "glfw", "glx", "egl",
             "osmesa", "")


def gl_problem(environ=os.environ, find_library=ctypes.util.find_library, system: str | None = None) -> str | None:
    """Why the MUJOCO_GL a user set would break `import mujoco` itself (a value mujoco refuses, or a back end
    whose library is missing: a traceback from PyOpenGL in every command), in a sentence; None where it would not."""
    import platform

    value = environ.get("MUJOCO_GL")
    if value is None or (system or platform.system()) != "Linux":
        return None
    backend = value.lower().strip()
    pick = "or unset MUJOCO_GL for fieldgen to pick one (EGL, else OSMesa, else none, where nothing is drawn)"
    if backend not in GL_VALUES:
        return (f"MUJOCO_GL={value} is no back end mujoco knows: set it to egl, osmesa, glfw, glx or disable, {pick}")
    if backend in GL_LIBRARIES and not find_library(GL_LIBRARIES[backend][0]):
        library, package = GL_LIBRARIES[backend]
        found = [b for b, (lib, _) in GL_LIBRARIES.items() if find_library(lib)]
        other = f"set MUJOCO_GL={found[0]} (installed here), " if found else ""
        return (f"MUJOCO_GL={value} names {library}, whose library is not installed here, and mujoco cannot load "
                f"without it: install it (Debian and Ubuntu: apt install {package}), {other}{pick}")
    return None


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
