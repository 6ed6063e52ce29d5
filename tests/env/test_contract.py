"""The environment contract on every bundled field, on MJX and on brax's pipelines: reset and step pure under
jit+vmap, observations of the layout's size with the goal in place, finite numbers, every metric named; and the
contract as the trainers type it (fieldgen.env.contract) on every kind of environment: a field on MJX and on
each of brax's pipelines, several fields batched, the adapters to brax's and Playground's wrappers."""

from __future__ import annotations

import functools
import inspect
import subprocess
import sys
from types import SimpleNamespace

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from brax import envs
from typing_extensions import get_protocol_members

import fieldgen.brax
from fieldgen.brax import BraxField
from fieldgen.compile.variants import compile_variants
from fieldgen.env.brax_pipeline import BraxFieldEnv
from fieldgen.env.contract import Environment, State
from fieldgen.env.make import environment
from fieldgen.playground import PlaygroundField
from fieldgen.schema import FieldSpec, bundled_fields, load_spec


def distinct_scenes(names: list[str]) -> list[str]:
    """One field per distinct scene and episode rule: fields that differ only in their reward terms or
    in how far their targets are drawn step the same physics through the same code (the terms are
    checked against their formulas in test_task)."""
    seen, kept = set(), []
    for name in names:
        spec = load_spec(bundled_fields()[name])
        ignored = {"name": True, "description": True, "extends": True,
                   "task": {"reward": True, "target": {"radius": True}}}
        key = repr(spec.model_dump(exclude=ignored))
        if key not in seen:
            seen.add(key)
            kept.append(name)
    return kept


ANT_FIELDS = distinct_scenes(sorted(n for n in bundled_fields() if not n.startswith("point")
                                    and load_spec(bundled_fields()[n]).teams is None))  # matches: test_team.py


def rollout(env, n_envs=2, steps=3, seed=0):
    keys = jax.random.split(jax.random.PRNGKey(seed), n_envs)
    state = jax.jit(jax.vmap(env.reset))(keys)
    step = jax.jit(jax.vmap(env.step))
    actions = jax.random.uniform(jax.random.PRNGKey(seed + 1), (steps, n_envs, env.action_size), minval=-1, maxval=1)
    for a in actions:
        state = step(state, a)
    return state


def assert_contract(env, state, n_envs):
    assert state.obs.shape == (n_envs, env.observation_size)
    assert env.observation_size == env.state_dim + 2
    for x in (state.obs, state.reward, *state.metrics.values()):
        assert np.all(np.isfinite(np.asarray(x)))
    assert set(state.metrics) == set(env.metric_names) == {"success", *env.task.terms}
    goal_slice = slice(env.state_dim, env.state_dim + 2)
    np.testing.assert_array_equal(state.obs[:, goal_slice], state.info["goal"])


@pytest.mark.parametrize("name", ["point_nav", "point_soccer"])
def test_point_fields_step_under_jit_and_vmap(env_cache, name):
    env = env_cache(name)
    state = rollout(env, n_envs=4, steps=5)
    assert_contract(env, state, 4)
    assert int(state.info["episode_step"][0]) == 5


@pytest.mark.slow
@pytest.mark.parametrize("name", ANT_FIELDS)
def test_ant_fields_step_under_jit_and_vmap(env_cache, name):
    """The ant fields whose sim.backend names one of brax's pipelines are built and stepped here too."""
    env = env_cache(name)
    state = rollout(env, n_envs=2, steps=3)
    assert_contract(env, state, 2)
    assert env.action_size == 8


# -- the contract as trainers type it (fieldgen.env.contract), on every kind of environment -------------------

def on_backend(backend: str) -> tuple[str, dict]:
    """A bundled field on `backend`, or point_nav moved onto it where no bundled field runs there."""
    bundled = [n for n in sorted(bundled_fields()) if load_spec(bundled_fields()[n]).sim.backend == backend]
    return (bundled[0], {}) if bundled else ("point_nav", {"backend": backend})


@functools.cache
def batched_fields():
    """Two fields built to one structure and stepped in one batch; the environment is named after the last."""
    first = load_spec(bundled_fields()["point_nav"])
    last = first.model_dump()
    last["name"], last["task"]["success"]["radius"] = "point_nav_wide", 1.0
    return environment(compile_variants([first, FieldSpec.model_validate(last)]))


@functools.cache
def batched_with_kickoffs():
    """The batched fields with two kick-off points each: the agent a metre aside of its own start, and its own."""
    env = batched_fields()
    start = [*env.spec.agent.start]
    table = np.array([[[0, 0, 0, 0, start[0] + 1.0, start[1]], [0, 0, 0, 0, *start]]] * 2, np.float32)
    return environment([e for e in env.artifacts], kickoffs=table, kickoff_coordinates=[[0.5, 1.0]] * 2)


def brax_adapter(env_cache):
    """What brax's registry gives."""
    fieldgen.brax.register()
    env = envs.get_environment("point_nav")
    assert isinstance(env, BraxField)
    return env


KINDS = {
    "mjx": lambda cache: cache("point_nav"),
    **{backend: lambda cache, b=backend: cache(on_backend(b)[0], **on_backend(b)[1])
       for backend in ("spring", "positional", "generalized")},
    "batched": lambda cache: batched_fields(),
    "kickoffs": lambda cache: batched_with_kickoffs(),
    "playground": lambda cache: PlaygroundField(cache("point_nav")),
    "brax": brax_adapter,
}
CHEAP_TO_STEP = ("mjx", "generalized", "batched", "kickoffs", "playground", "brax")  # point agents; the ant
# fields step in test_ant_fields_step_under_jit_and_vmap


def check_members(env) -> None:
    """Every member of the contract, found without calling the instance's __getattr__ (as Python 3.12's
    isinstance looks them up), of the type and size it promises."""
    assert isinstance(env, Environment)
    for member in get_protocol_members(Environment):
        inspect.getattr_static(env, member)
    sizes = (env.observation_size, env.action_size, env.state_dim, env.episode_length)
    assert all(isinstance(n, int) and n > 0 for n in sizes)
    assert isinstance(env.name, str) and env.name
    assert isinstance(env.success_depends_on_goal, bool)
    assert isinstance(env.variant_count, int) and env.variant_count >= 1
    points = np.asarray(env.kickoff_coordinates)
    assert points.ndim == 2 and points.shape[0] == env.variant_count and np.all(np.isfinite(points[:, -1:]))
    goal, judged = np.asarray(env.goal_indices), np.asarray(env.success_goal_entries)
    assert goal.dtype.kind == judged.dtype.kind == "i" and goal.ndim == judged.ndim == 1 and len(judged) >= 2
    assert np.all((goal >= 0) & (goal < env.state_dim)) and np.all((judged >= 0) & (judged < len(goal)))
    assert env.observation_size == env.state_dim + len(goal)
    for names, size in ((env.observation_names, env.observation_size), (env.action_names, env.action_size)):
        assert len(names) == len(set(names)) == size and all(isinstance(n, str) for n in names)


def check_one_step(env) -> None:
    """reset and one step under jit: the state the contract describes, and a success that goal_reached agrees
    with; where the success depends on the goal, a state reaches the goal read from itself (hindsight's)."""
    state = jax.jit(env.reset)(jax.random.PRNGKey(0))
    state = jax.jit(env.step)(state, jnp.full(env.action_size, 0.5))
    assert isinstance(state, State) and float(state.done) == 0.0
    assert state.obs.shape == (env.observation_size,) and state.reward.shape == ()
    assert "success" in state.metrics
    assert {"goal", "rng", "truncation", "episode", "episode_step"} <= set(state.info)
    reached = env.goal_reached(state.obs[:env.state_dim], state.obs[env.state_dim:])
    assert reached.shape == () and float(reached) == float(state.metrics["success"])
    last = env.variant_count - 1
    first = jax.jit(env.reset_variant)(jax.random.PRNGKey(1), last)
    assert first.obs.shape == (env.observation_size,)
    # under jit, as a trainer resets its batch: run op by op, brax's generalized reset takes longer than its compile
    batch = jax.jit(jax.vmap(env.reset_variant, in_axes=(0, None)))(jax.random.split(jax.random.PRNGKey(2), 3), last)
    weights = jnp.full(env.variant_count, 1.0 / env.variant_count)
    assert jax.tree.structure(env.with_variant_weights(batch, weights)) == jax.tree.structure(batch)
    if np.asarray(env.kickoff_coordinates).shape[1]:
        levels = jnp.zeros(env.kickoff_coordinates.shape).at[:, 0].set(weights)
        assert jax.tree.structure(env.with_level_weights(batch, levels, jnp.ones_like(levels))) == \
            jax.tree.structure(batch)
        aside = jax.jit(env.reset_variant)(jax.random.PRNGKey(1), last, 0)
        moved = aside.obs[np.asarray(env.goal_indices)] - first.obs[np.asarray(env.goal_indices)]
        assert float(moved[0]) == pytest.approx(1.0, abs=0.2) and "level_counts" in aside.info
    if env.success_depends_on_goal:
        achieved = state.obs[np.asarray(env.goal_indices)]
        assert float(env.goal_reached(state.obs[:env.state_dim], achieved)) == 1.0
        assert float(env.goal_reached(state.obs[:env.state_dim], achieved + 100.0)) == 0.0


@pytest.mark.parametrize("kind", KINDS)
def test_every_kind_of_environment_keeps_the_contract(env_cache, kind):
    env = KINDS[kind](env_cache)
    check_members(env)
    if kind in CHEAP_TO_STEP:
        check_one_step(env)


@pytest.mark.slow
@pytest.mark.parametrize("kind", [k for k in KINDS if k not in CHEAP_TO_STEP])
def test_every_kind_of_environment_steps_as_the_contract_says(env_cache, kind):
    check_one_step(KINDS[kind](env_cache))


def test_each_brax_pipeline_kind_is_what_its_name_says(env_cache):
    for backend in ("spring", "positional", "generalized"):
        env = KINDS[backend](env_cache)
        assert isinstance(env, BraxFieldEnv) and env.backend == backend


def test_a_batch_of_fields_is_named_and_judged_after_its_last(env_cache):
    env = KINDS["batched"](env_cache)
    assert env.name == "point_nav_wide" and len(env.artifacts) == 2


def test_a_missing_member_fails_the_contract(env_cache):
    env = env_cache("point_nav")
    members = {m: getattr(env, m) for m in get_protocol_members(Environment)}
    assert isinstance(SimpleNamespace(**members), Environment)
    for member in members:
        assert not isinstance(SimpleNamespace(**{m: v for m, v in members.items() if m != member}), Environment)


def test_success_depends_on_goal_unless_it_is_the_goal_box(env_cache):
    assert env_cache("point_nav").success_depends_on_goal  # agent_near_target
    assert not env_cache("point_soccer").success_depends_on_goal  # ball_in_goal


def test_the_contract_and_the_trainers_load_neither_mujoco_nor_brax():
    check = ("import sys, fieldgen.env.contract, fieldgen.agents.registry; "
             "print(sorted({'mujoco', 'brax'} & set(sys.modules)))")
    done = subprocess.run([sys.executable, "-c", check], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "[]"
