"""Run time: built fields -> one batched MJX environment with brax's State contract; the reward,
success and fall terms generated from the spec; variants of a field stepped in one batch.

Needs mujoco, mjx, jax and brax, never dm_control: a machine without it trains from build folders.
"""

import contextlib
import io

with contextlib.redirect_stdout(io.StringIO()):  # mjx (also via brax) prints about its optional warp backend
    import brax.envs.base  # noqa: F401
    from mujoco import mjx  # noqa: F401

from fieldgen.env.field import FieldEnv  # noqa: E402
from fieldgen.env.make import make  # noqa: E402

__all__ = ["FieldEnv", "make"]
