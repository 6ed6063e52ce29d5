"""MJX's implementations of a field's physics (fieldgen.schema.backends: mjx steps JAX's, warp MuJoCo Warp's),
and what Warp needs that JAX does not.

Warp fixes its capacities when its data is made, and its contact buffer is shared by every environment of a
batch: each environment gets the contacts and constraint rows JAX's implementation allocates for the model (all
it can ever hold), times the environments reserved for the batch (`worlds`). Warp leaves out what does not fit
and only flags it, so a field records the flags (`OVERFLOW`) and whoever steps it stops on them (`check`).
"""

from __future__ import annotations

import functools
import math
import os
import sys
import tempfile
from typing import Callable

import jax
import numpy as np

from fieldgen.env import warp_start
# OVERFLOW: Warp's flags since reset, kept over auto-resets
from fieldgen.env.contract import OVERFLOW, merged_overflow  # noqa: F401
from fieldgen.schema.errors import Problem, SpecError

# Warp's flags (mujoco_warp's OverflowType) that are not a capacity outgrown: iteration limits reached
NOT_CAPACITY = ("ITERATIONS", "LS_ITERATIONS")


class PhysicsOverflow(RuntimeError):
    """An environment outgrew one of Warp's capacities: its physics left contacts or constraints out."""


class WarpMissing(SpecError):
    """A field on sim.backend warp where warp-lang is not installed: a spec problem (every command that makes an
    environment refuses it in one paragraph), though the remedy is an install, not an edit."""

    def __init__(self, field: str):
        self.field = field
        super().__init__([Problem(None, None, None, "sim.backend",
                                  "warp (MuJoCo Warp's kernels) needs warp-lang, which is not installed here: "
                                  "pip install -c requirements.lock -e '.[warp]' in fieldgen's checkout (or pip "
                                  "install 'fieldgen[warp]'); sim.backend: mjx steps the same field on MJX's JAX "
                                  "implementation without it")])

    def __str__(self) -> str:
        return f"{self.field}: sim.backend: {self.problems[0].message}"


def capacities(mj_model) -> tuple[int, int]:
    """(contacts, constraint rows) JAX's implementation allocates for one environment of the model."""
    from mujoco import mjx  # here: the trainers read this module's names without loading the physics

    data = mjx.make_data(mj_model, impl="jax")
    return int(data._impl.contact.dist.shape[0]), int(data._impl.efc_J.shape[0])


def put_model(mj_model, impl: str, device=None, field: str = "the field", **options):
    """The field's mjx.Model of implementation `impl` (options: mjx.put_model's, e.g. Warp's graph_mode); Warp's
    reports overflows in its data alone. WarpMissing where `field` needs Warp and warp-lang is not installed."""
    from mujoco import mjx

    if impl == "warp":
        require_warp(field)
        start_warp()

    model = mjx.put_model(mj_model, device=device, impl=impl, **options)
    if impl == "warp":  # the flags are read (`overflow_bits`); a warning printed per world and step would flood
        model = model.tree_replace({"opt._impl.warn_overflow": 0})
    return model


def require_warp(field: str) -> None:
    """Refuse (WarpMissing) a field on Warp's physics where warp-lang cannot be imported."""
    try:
        import warp  # noqa: F401
    except ImportError:
        raise WarpMissing(field) from None


# Warp's native library says so on stderr at its start on a machine without NVIDIA's driver, where its CPU kernels
# step the field as asked: a line that reads like a failure to a user on a laptop
NO_CUDA_DRIVER = "Warp CUDA warning: Could not find or load the NVIDIA CUDA driver."


def without_native_line(call, line_start: str):
    """Call `call()` with what native code writes to stderr (file descriptor 2, below Python's sys.stderr) held
    back, then pass on every line of it but those starting with `line_start`."""
    sys.stderr.flush()
    saved = os.dup(2)
    with tempfile.TemporaryFile(mode="w+b") as held:
        os.dup2(held.fileno(), 2)
        try:
            return call()
        finally:
            sys.stderr.flush()
            os.dup2(saved, 2)
            os.close(saved)
            held.seek(0)
            kept = [line for line in held.read().decode(errors="replace").splitlines(keepends=True)
                    if not line.startswith(line_start)]
            if kept:
                sys.stderr.write("".join(kept))
                sys.stderr.flush()


@functools.cache
def start_warp() -> None:
    """Start Warp once per process, quietly (no line per module of kernels loaded, nor the note of a missing
    NVIDIA driver: NO_CUDA_DRIVER), its solve starting where MuJoCo's does (warp_start)."""
    import warp

    warp.config.log_level = max(warp.config.log_level, warp.LOG_WARNING)
    without_native_line(warp.init, NO_CUDA_DRIVER)
    warp_start.install()


def make_data(mj_model, impl: str, device, worlds: int = 1, field: str = "the field"):
    """Fresh data of one environment; Warp's sized for a batch of `worlds` environments (WarpMissing as
    put_model)."""
    from mujoco import mjx

    if impl != "warp":
        return mjx.make_data(mj_model, device=device, impl=impl)
    require_warp(field)
    start_warp()
    contacts, rows = capacities(mj_model)
    return mjx.make_data(mj_model, device=device, impl="warp", naconmax=contacts * worlds, njmax=rows)


def home_data(mj_model, impl: str, device, worlds: int = 1, field: str = "the field"):
    """make_data's data at the model's `home` keyframe, where every episode starts from."""
    return make_data(mj_model, impl, device, worlds, field).replace(qpos=jax.numpy.asarray(mj_model.key("home").qpos))


class UnreservedBatch(ValueError):
    """A program steps more environments of a Warp field at once than its physics was sized for: Warp would leave
    contacts out of every step and only flag it."""


def batch_guard(field: str, reserved: Callable[[], int]) -> Callable:
    """An identity on a step's control that refuses, as a program is traced, a batch of more environments than
    `reserved()` (SizedForBatch.reserve_worlds): Warp's contact buffer is shared by the batch, and vmap hides its size
    from the step. Under nested vmaps (seeds x environments) the outermost sees the product."""
    from jax.custom_batching import custom_vmap

    @custom_vmap
    def guard(ctrl):
        return ctrl

    @guard.def_vmap
    def _batched(axis_size, in_batched, ctrl):
        if not in_batched[0]:
            ctrl = jax.numpy.broadcast_to(ctrl, (axis_size, *ctrl.shape))
        worlds = math.prod(ctrl.shape[:-1])  # a control is a vector: every axis before it is a batch's
        if worlds > reserved():
            raise UnreservedBatch(
                f"{field} runs on sim.backend warp, whose contact buffer is shared by every environment stepped at "
                f"once, and this program steps {worlds} at once where {reserved()} were reserved: Warp would leave "
                f"contacts out of their steps. Call env.reserve_worlds({worlds}) before the program is traced "
                f"(fieldgen's trainers and commands do), or use sim.backend: mjx")
        return guard(ctrl), True

    return guard


class SizedForBatch:
    """A field stepped on MJX whose physics is sized for the batch that steps it: `reserve_worlds` before a
    program is traced, `_guard` (batch_guard) in each step's control to refuse a batch beyond it as the program is
    traced, and `check_physics` on the flags after. The field has `name`, `impl` and `mj_model`, and makes its data
    anew for a batch in `_size_for` (Warp's alone: JAX's needs nothing)."""

    worlds = 1  # environments one batch may step: Warp's data is sized for them

    def _size_for(self, worlds: int) -> None:
        raise NotImplementedError

    @functools.cached_property
    def _guard(self) -> Callable:
        return batch_guard(self.name, lambda: self.worlds)

    def reserve_worlds(self, worlds: int) -> None:
        """Size the physics for batches of up to `worlds` environments (all a program steps: seeds x envs), before
        the programs that step them are traced: Warp's contact buffer is shared by a batch; JAX's needs nothing."""
        if self.impl == "warp" and worlds > self.worlds:
            self.worlds = worlds
            self._size_for(worlds)

    def check_physics(self, overflow) -> None:
        """Raise PhysicsOverflow where `overflow` (info[OVERFLOW] of any number of environments, or merged_overflow
        of it) says one outgrew Warp's capacities."""
        check(self.name, int(np.bitwise_or.reduce(np.asarray(overflow).ravel())), self.mj_model, self.worlds)


def overflow_bits(data) -> jax.Array:
    """Warp's overflow flags this environment's last physics step raised, as int32 bits."""
    return merged_overflow(data._impl.overflow)


def overflow_names(bits: int) -> list[str]:
    """The names of Warp's overflow flags set in `bits` (mujoco_warp's OverflowType)."""
    from mujoco.mjx.third_party.mujoco_warp._src.types import OverflowType

    return [flag.name for flag in OverflowType if flag.value and bits & flag.value]


def check(field: str, bits: int, mj_model, worlds: int) -> None:
    """Raise PhysicsOverflow where `bits` (overflow flags of any environment) hold an outgrown capacity."""
    names = [name for name in overflow_names(bits) if name not in NOT_CAPACITY]
    if not names:
        return
    contacts, rows = capacities(mj_model)
    raise PhysicsOverflow(
        f"{field}: an environment outgrew MuJoCo Warp's capacity ({', '.join(names)}; {contacts} contacts per "
        f"environment x {worlds} environments reserved, {rows} constraint rows per environment), so its physics "
        f"left contacts or constraints out; step it in batches of at most {worlds} environments "
        f"(env.reserve_worlds reserves more), or use sim.backend: mjx")
