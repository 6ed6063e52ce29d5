"""fieldgen's fields as MuJoCo Playground environments (`mujoco_playground.MjxEnv`), for Playground's
wrappers and training scripts: `pip install fieldgen[playground]`.

Playground's State names brax's `pipeline_state` `data`; otherwise a step is the field's own. Playground's
training wrappers (`wrapper.wrap_for_brax_training`) are brax's episode wrapper and an auto-reset of its own,
which swaps in the state it keeps in `info["AutoResetWrapper_first_data"]` and
`info["AutoResetWrapper_first_obs"]`: under brax's names a step goes through the field's adapter to brax's
wrappers (fieldgen.brax.BraxField), so that here too an episode lasts its full length and no start is replayed.
"""

from __future__ import annotations

from pathlib import Path

import fieldgen.env.quiet  # noqa: F401  (before MJX and brax)
from brax.envs.base import State as BraxState
from ml_collections import config_dict
from mujoco_playground import MjxEnv, State

from fieldgen.brax import BraxField, FieldAdapter
from fieldgen.env.field import FieldEnv
from fieldgen.env.make import make

# Playground's auto-reset keys -> brax's, which the adapter to brax's wrappers fills
_RESET_KEYS = {"AutoResetWrapper_first_data": "first_pipeline_state", "AutoResetWrapper_first_obs": "first_obs"}


class PlaygroundField(FieldAdapter, MjxEnv):
    """A field (a FieldEnv, or what fieldgen.make takes) behind Playground's MjxEnv interface; the field's own
    attributes (state_dim, goal_indices, observation_names, goal_reached...) read through."""

    def __init__(self, field: FieldEnv | str | Path, episode_length: int | None = None):
        if isinstance(field, FieldEnv) and episode_length not in (None, field.episode_length):
            raise ValueError(f"episode_length={episode_length!r} for an environment already made, whose episodes are "
                             f"{field.episode_length} steps: make it with fieldgen.make(..., episode_length=...), or "
                             "give PlaygroundField the field's name")
        self.field = field if isinstance(field, FieldEnv) else make(field, episode_length=episode_length)
        self._in_brax_wrappers = BraxField(self.field)
        spec = self.field.spec
        super().__init__(config_dict.create(ctrl_dt=spec.episode.control_dt, sim_dt=spec.episode.physics_dt,
                                            episode_length=self.field.episode_length))

    def reset(self, rng) -> State:
        return _playground(self.field.reset(rng))

    def step(self, state: State, action) -> State:
        info = {_RESET_KEYS.get(k, k): v for k, v in state.info.items()}
        brax = BraxState(state.data, state.obs, state.reward, state.done, state.metrics, info)
        return _playground(self._in_brax_wrappers.step(brax, action))

    @property
    def xml_path(self) -> str:
        raise NotImplementedError("a field's scene is compiled in memory: its MJCF is .field.artifact.xml, "
                                  "and `fieldgen build` writes it to scene.xml")

    @property
    def mj_model(self):
        return self.field.mj_model

    @property
    def mjx_model(self):
        return self.field.mjx_model

    def render(self, trajectory, height: int = 240, width: int = 320, camera: str | None = None, **_):
        """RGB frames through fieldgen's renderer (fieldgen.render.RenderError where no OpenGL is)."""
        states = [BraxState(s.data, s.obs, s.reward, s.done, s.metrics, s.info) for s in trajectory]
        return self.field.render(states, height, width, camera or "follow")


def _playground(state: BraxState) -> State:
    back = {brax: playground for playground, brax in _RESET_KEYS.items()}
    info = {back.get(k, k): v for k, v in state.info.items()}
    return State(state.pipeline_state, state.obs, state.reward, state.done, state.metrics, info)
