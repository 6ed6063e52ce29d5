"""A built field stepped by one of brax's physics pipelines (fieldgen.schema.backends.BRAX).

The soccer study trained on brax's positional pipeline and the CRL reference on its spring
pipeline; fieldgen runs the same scene.xml on them for like-for-like comparisons. Everything but
the physics is FieldEnv's own: observations, reward and success terms, fall rules, fresh draws on
every auto-reset, the divergence guard. brax's loader needs every body to carry a joint, so the
ant's jointless leg roots and the target marker are fused into their parents first; the joints,
and so q and qd, keep MuJoCo's order, and the marker's position rides beside the pipeline state.
"""

from __future__ import annotations

import importlib
import warnings
from typing import Any, Sequence

import fieldgen.env.quiet  # noqa: F401  (before MJX and brax)
import jax
import jax.numpy as jnp
import mujoco
from brax.io import mjcf
from flax import struct

from fieldgen.compile.artifact import Artifact
from fieldgen.env.field import FieldEnv
from fieldgen.schema.backends import BRAX, mjx_impl

PIPELINES = {name: importlib.import_module(f"brax.{name}.pipeline") for name in BRAX}


@struct.dataclass
class BraxData:
    """A pipeline's state and the target marker's position, read as FieldEnv and the video recorder
    read an mjx.Data: qpos, qvel and mocap_pos."""

    pipeline: Any
    mocap_pos: jax.Array

    @property
    def qpos(self) -> jax.Array:
        return self.pipeline.q

    @property
    def qvel(self) -> jax.Array:
        return self.pipeline.qd

    @property
    def xpos(self) -> jax.Array:
        """The bodies' world positions, as mjx.Data names them (the divergence guard reads them)."""
        return self.pipeline.x.pos


def load_system(xml: str, model: mujoco.MjModel):
    """brax's System of a scene, its jointless bodies fused into their parents."""
    fused = mujoco.MjModel.from_xml_string(mjcf.fuse_bodies(xml))
    names = [model.joint(i).name for i in range(model.njnt)]
    if [fused.joint(i).name for i in range(fused.njnt)] != names or fused.nq != model.nq:
        raise ValueError("fusing the scene's jointless bodies reordered its joints; brax's q would not be MuJoCo's qpos")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # brax's notice that its pipelines are unmaintained
        return mjcf.load_model(fused)


def check_batchable(artifacts: Sequence[Artifact]) -> None:
    """Variants batched in one simulation must run on MJX: brax's pipelines step one field."""
    on_brax = [a.spec for a in artifacts if mjx_impl(a.spec) is None]
    if len(artifacts) > 1 and on_brax:
        raise ValueError(f"variants train in one batch on MJX only; {on_brax[0].name} runs on brax's "
                         f"{on_brax[0].sim.backend} pipeline: train the stages in turn (without --mixed), "
                         "or give every stage sim.backend: mjx")


class BraxFieldEnv(FieldEnv):
    """FieldEnv on the pipeline its spec names (sim.backend); one field, no batched variants."""

    def __init__(self, artifacts: Artifact | Sequence[Artifact], episode_length: int | None = None,
                 auto_reset: bool = True):
        if not isinstance(artifacts, Artifact):
            check_batchable(artifacts)
            artifacts = artifacts[0]
        super().__init__(artifacts, episode_length, auto_reset)
        self.backend = self.spec.sim.backend
        self._pipeline = PIPELINES[self.backend]
        self.sys = load_system(self.artifact.xml, self.mj_model)

    def _fresh(self, variant: jax.Array, key: jax.Array, kickoff: jax.Array | None = None):
        data, goal = super()._fresh(variant, key, kickoff)
        return BraxData(self._pipeline.init(self.sys, data.qpos, data.qvel), data.mocap_pos), goal

    def _advance(self, sys, data: BraxData, action: jax.Array) -> tuple[BraxData, None]:
        state = jax.lax.fori_loop(0, self.n_substeps, lambda _, s: self._pipeline.step(sys, s, action), data.pipeline)
        return data.replace(pipeline=state), None

    def _restart(self, done: jax.Array, fresh: BraxData, data: BraxData) -> BraxData:
        return jax.tree.map(lambda f, d: jnp.where(done, f, d), fresh, data)
