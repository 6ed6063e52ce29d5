"""fieldgen's fields as MuJoCo Playground environments (`mujoco_playground.MjxEnv`), for Playground's
wrappers and training scripts: `pip install fieldgen[playground]`.

Playground's State names brax's `pipeline_state` `data`; otherwise a step is the field's own. Under
Playground's auto-reset wrapper (`wrapper.wrap_for_brax_training`), which swaps in the state it keeps in
`info["AutoResetWrapper_first_data"]` and `info["AutoResetWrapper_first_obs"]`, the field leaves a fresh
episode there at every step, as it does for brax's (fieldgen.env.field), so no start is replayed.
"""

from __future__ import annotations

from pathlib import Path

from brax.envs.base import State as BraxState
from ml_collections import config_dict
from mujoco_playground import MjxEnv, State

from fieldgen.env.field import FieldEnv
from fieldgen.env.make import make

# Playground's auto-reset keys -> brax's, which the field fills
_RESET_KEYS = {"AutoResetWrapper_first_data": "first_pipeline_state", "AutoResetWrapper_first_obs": "first_obs"}


class PlaygroundField(MjxEnv):
    """A field (a FieldEnv, or what fieldgen.make takes) behind Playground's MjxEnv interface; the field's own
    attributes (state_dim, goal_indices, observation_names, goal_reached...) read through."""

    def __init__(self, field: FieldEnv | str | Path, episode_length: int | None = None):
        self.field = field if isinstance(field, FieldEnv) else make(field, episode_length=episode_length)
        spec = self.field.spec
        super().__init__(config_dict.create(ctrl_dt=spec.episode.control_dt, sim_dt=spec.episode.physics_dt,
                                            episode_length=self.field.episode_length))

    def __getattr__(self, name):
        if name.startswith("_") or name == "field":
            raise AttributeError(name)
        return getattr(self.field, name)

    def reset(self, rng) -> State:
        return _playground(self.field.reset(rng))

    def step(self, state: State, action) -> State:
        info = {_RESET_KEYS.get(k, k): v for k, v in state.info.items()}
        brax = BraxState(state.data, state.obs, state.reward, state.done, state.metrics, info)
        return _playground(self.field.step(brax, action))

    @property
    def xml_path(self) -> str:
        raise NotImplementedError("a field's scene is compiled in memory: its MJCF is .field.artifact.xml, "
                                  "and `fieldgen build` writes it to scene.xml")

    @property
    def action_size(self) -> int:
        return self.field.action_size

    @property
    def observation_size(self) -> int:
        return self.field.observation_size

    @property
    def mj_model(self):
        return self.field.mj_model

    @property
    def mjx_model(self):
        return self.field.mjx_model

    def render(self, trajectory, height: int = 240, width: int = 320, camera: str | None = None, **_):
        """RGB frames through fieldgen's renderer (fieldgen.render.RenderError where no OpenGL is)."""
        states = [BraxState(s.data, s.obs, s.reward, s.done, s.metrics, s.info) for s in trajectory]
        return self.field.render(states, camera or "follow", height, width)


def _playground(state: BraxState) -> State:
    back = {brax: playground for playground, brax in _RESET_KEYS.items()}
    info = {back.get(k, k): v for k, v in state.info.items()}
    return State(state.pipeline_state, state.obs, state.reward, state.done, state.metrics, info)
