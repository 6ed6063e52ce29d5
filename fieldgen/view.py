"""A field, or a policy playing on it, live in MuJoCo's interactive viewer (`fieldgen view`).

The viewer only shows: one environment of the field is stepped by the environment's own `reset` and `step`
on JAX's CPU backend, the functions the trainers batch, so the observation, reward, success and episode ends
are theirs; each control step its joint positions and target are copied into the viewer's MjData, at the
environment's control rate in real time. The viewer's own keys and mouse work as usual beside PAUSE_KEY and
NEW_EPISODE_KEY.
"""

from __future__ import annotations

import os
import sys
import time
import warnings
from typing import Callable

import jax
import jax.numpy as jnp
import mujoco
import numpy as np

from fieldgen.cameras import FOLLOW, FREE, TOP
from fieldgen.render import _mark, _scene_option, _view_height

PAUSE_KEY, NEW_EPISODE_KEY = 32, 259  # GLFW's codes of Space and Backspace
FREE_DISTANCE = 1.1  # the free camera's first distance from the field's centre, in lengths the top view frames
KEYS = "Space pauses and resumes; Backspace starts a new episode"


class NoDisplay(RuntimeError):
    """No window can open here: no display, or the viewer failed to open one."""


def no_display_reason(environ=None, platform: str | None = None) -> str | None:
    """Why no window can open on this machine, without trying (a Linux machine with neither an X nor a Wayland
    display); None where one may."""
    environ = os.environ if environ is None else environ
    displayed = environ.get("DISPLAY") or environ.get("WAYLAND_DISPLAY")
    if (platform or sys.platform).startswith("linux") and not displayed:
        return "DISPLAY and WAYLAND_DISPLAY are unset"
    return None


class Player:
    """One environment of a field played in real time: a new episode as the environment's reset draws it, then
    control steps of the environment's own step, a policy choosing each action (zero actions without one).
    Keys reach it from the viewer's thread (`on_key`) and take effect at the next `tick`."""

    def __init__(self, env, act: Callable | None = None, seed: int = 0):
        """`act`: observation -> action in [-1, 1] (fieldgen.load_policy's, or a run's exported policy)."""
        self.cpu = jax.devices("cpu")[0]
        # a policy's weights (fieldgen.load_policy's pytree) brought to the CPU, where the environment steps
        on_cpu = lambda x: jax.device_put(x, self.cpu) if isinstance(x, jax.Array) else x  # noqa: E731
        self.env, self.act = env, jax.tree.map(on_cpu, act)
        with jax.default_device(self.cpu):
            self.key = jax.random.PRNGKey(seed)
            self._reset, self._step = jax.jit(env.reset), jax.jit(env.step)
            self._policy = jax.jit(self.act if act is not None else lambda obs: jnp.zeros(env.action_size))
        self.paused, self.new_episode_asked = False, False
        self.state = None
        self.new_episode()

    def new_episode(self) -> None:
        """A fresh episode: goal, ball and kick-off drawn as the environment's reset draws them."""
        with jax.default_device(self.cpu):
            self.key, key = jax.random.split(self.key)
            self.state = self._reset(key)
        self.new_episode_asked = False

    def on_key(self, keycode: int) -> None:
        """The viewer's key callback (its own keys work as well)."""
        if keycode == PAUSE_KEY:
            self.paused = not self.paused
        elif keycode == NEW_EPISODE_KEY:
            self.new_episode_asked = True

    def tick(self) -> None:
        """One control step, or the new episode asked for; nothing while paused."""
        if self.new_episode_asked:
            self.new_episode()
        elif not self.paused:
            with jax.default_device(self.cpu):
                self.state = self._step(self.state, self._policy(self.state.obs))

    def show(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        """The state's joints and targets (mocap bodies) in `data`, its positions computed."""
        physics = self.state.pipeline_state
        data.qpos[:], data.qvel[:] = np.asarray(physics.qpos), np.asarray(physics.qvel)
        data.mocap_pos[:] = np.asarray(physics.mocap_pos)
        mujoco.mj_forward(model, data)

    def status(self) -> tuple[str, str]:
        """Labels and values of the episode so far, for the viewer's corner."""
        acting = "zero actions" if self.act is None else "its policy"
        step = f"{int(self.state.info['episode_step'])} of {self.env.episode_length}" + " (paused)" * self.paused
        reward, success = np.asarray(self.state.reward), np.asarray(self.state.metrics["success"])
        if reward.ndim:  # a match: each side's own (home, away), the policy playing every agent of both
            episode = (f"{step}, reward home {reward[0]:.3f} away {reward[1]:.3f}, goal home {success[0]:.0f} "
                       f"away {success[1]:.0f}")
            acting = "zero actions" if self.act is None else "its policy on both sides"
        else:
            episode = f"{step}, reward {float(reward):.3f}, success {float(success):.0f}"
        return "field\nstep\nkeys", "\n".join((f"{self.env.spec.name}, {acting}", episode, KEYS))


def open_viewer(player: Player, camera: str = FREE, panels: bool = True):
    """MuJoCo's passive viewer on the player's field, its keys sent to the player, looking through `camera`
    (FREE, or one of the scene's: fieldgen.cameras), the floor markings and the target shown as fieldgen.render
    draws them. NoDisplay where no window opens."""
    import mujoco.viewer

    reason = no_display_reason()
    if reason is None:
        reason = _window_system_problem()
    if reason is not None:
        raise NoDisplay(reason)
    model = player.env.mj_model
    data = mujoco.MjData(model)
    player.show(model, data)
    try:
        handle = mujoco.viewer.launch_passive(model, data, key_callback=player.on_key, show_left_ui=panels,
                                              show_right_ui=panels)
    except Exception as exc:  # noqa: BLE001 - a window system fails in its own way (macOS: run under mjpython)
        raise NoDisplay(str(exc)) from None
    with handle.lock():
        handle.opt.geomgroup[:] = _scene_option(model, FOLLOW if camera == FREE else camera).geomgroup
        if camera != FREE:
            handle.cam.type = mujoco.mjtCamera.mjCAMERA_FIXED
            handle.cam.fixedcamid = model.cam(camera).id
        else:  # from behind the start, looking along the field towards the goal, the whole field in view
            handle.cam.lookat[:] = (*model.cam_pos[model.cam(TOP).id][:2], 0.0)
            handle.cam.distance = FREE_DISTANCE * _view_height(model, TOP)
            handle.cam.azimuth, handle.cam.elevation = 90.0, -50.0
    return handle


def play(handle, player: Player, camera: str = FREE, seconds: float | None = None) -> None:
    """Step and show the player at its environment's control rate until the window closes (or `seconds` pass),
    never faster than the wall clock; a step that falls behind is not caught up on."""
    model, data = player.env.mj_model, handle.d
    end = None if seconds is None else time.monotonic() + seconds
    due = time.monotonic()
    while handle.is_running() and (end is None or time.monotonic() < end):
        player.tick()
        with handle.lock():
            player.show(model, data)
            if camera == TOP:  # the discs render.py puts under the agent and the ball in the top view
                handle.user_scn.ngeom = 0
                _mark(model, data, handle.user_scn, camera)
        if hasattr(handle, "set_texts"):  # outside the lock, which it takes itself
            labels, values = player.status()
            handle.set_texts((mujoco.mjtFontScale.mjFONTSCALE_150, mujoco.mjtGridPos.mjGRID_BOTTOMLEFT, labels, values))
        handle.sync()
        due = max(due + player.env.dt, time.monotonic())
        time.sleep(max(0.0, due - time.monotonic()))


def _window_system_problem() -> str | None:
    """Why GLFW cannot start here (a display named but unreachable), found before the viewer's own thread would
    wait for a window that never comes; None where it starts."""
    try:
        import glfw

        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            if glfw.init():
                return None
            description = glfw.get_error()[1] if hasattr(glfw, "get_error") else None
    except Exception as exc:  # noqa: BLE001 - a missing library, an unreachable display
        description = str(exc)
    if isinstance(description, bytes):
        description = description.decode(errors="replace")
    return f"GLFW cannot open a window ({description or 'no reason given'})"
