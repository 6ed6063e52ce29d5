"""fieldgen: robot-soccer fields from YAML specs, compiled to batched MJX environments.

`fieldgen.make(...)` is imported lazily so that `fieldgen validate` and friends
start without loading JAX.
"""

import os

os.environ.setdefault("MUJOCO_GL", "egl")  # headless rendering; no display on training machines

__version__ = "0.1.0"


def __getattr__(name):
    if name in ("make", "FieldEnv"):
        from fieldgen import env

        return getattr(env, name)
    raise AttributeError(f"module 'fieldgen' has no attribute {name!r}")
