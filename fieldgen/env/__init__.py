"""Run time: built fields -> one batched MJX environment with brax's State contract; the reward,
success and fall terms generated from the spec; variants of a field stepped in one batch.

Needs mujoco, mjx, jax and brax, never dm_control: a machine without it trains from build folders.
Importing the package itself loads none of them but JAX: the trainers read the environment contract
(contract.py) without the physics; `FieldEnv`, and `make` when called, load it.
"""

from fieldgen.env.contract import Environment, State
from fieldgen.env.make import make

__all__ = ["Environment", "FieldEnv", "State", "make"]


def __getattr__(name):
    if name == "FieldEnv":
        from fieldgen.env.field import FieldEnv

        return FieldEnv
    raise AttributeError(f"module 'fieldgen.env' has no attribute {name!r}")
