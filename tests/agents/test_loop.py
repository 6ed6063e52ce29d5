"""Several seeds under vmap, the pure train(key), and one run sharded over two (CPU) devices."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from fieldgen.agents import crl, loop, ppo
from fieldgen.env.contract import TORSO_QUATERNION, torso_entries


@pytest.fixture(scope="module")
def seed_one(env_cache, tiny_crl):
    """A tiny CRL run of seed 1 on one device, shared by the comparisons below."""
    return loop.run(crl.make_train(tiny_crl(), env_cache("point_nav")), [1], 2)


@pytest.mark.slow
def test_vmapped_seeds_match_seeds_run_alone(env_cache, seed_one, tiny_crl):
    both, rows = loop.run(crl.make_train(tiny_crl(), env_cache("point_nav")), [0, 1], 2)
    alone, alone_rows = seed_one
    for a, b in zip(jax.tree.leaves(loop.seed_slice(both.nets, 1)), jax.tree.leaves(loop.seed_slice(alone.nets, 0))):
        np.testing.assert_allclose(np.asarray(a), np.asarray(b), rtol=1e-4, atol=1e-5)
    assert {r["seed"] for r in rows} == {0, 1} and len(rows) == 6
    assert [r["diverged_episodes"] for r in rows if r["eval"]] == [0.0] * 4  # a sound field blows up nowhere
    ours = [r for r in rows if r["seed"] == 1]
    for a, b in zip(ours, alone_rows):
        assert a["critic_loss" if a["eval"] else "success_any"] == pytest.approx(
            b["critic_loss" if b["eval"] else "success_any"], rel=1e-4)


def test_each_seeds_blown_up_episodes_are_summed_over_its_environments():
    counted = np.asarray([[0, 2, 1], [0, 0, 0]], np.int32)  # [seeds, envs], as State.info holds them
    assert loop.diverged_episodes(counted, 2)["diverged_episodes"].tolist() == [3, 0]
    assert loop.diverged_episodes(None, 2) == {}  # an environment that does not count them


@pytest.mark.slow
def test_pure_train_is_the_stepwise_run(env_cache):
    config = ppo.PPOConfig(total_steps=2 * 8 * 20, num_envs=8, unroll_length=20, num_minibatches=4, update_epochs=2,
                           hidden=(32, 32), num_evals=2, eval_envs=8)
    algo = ppo.make_train(config, env_cache("point_nav"))
    state, metrics = jax.jit(jax.vmap(loop.pure_train(algo, 2)))(jax.random.PRNGKey(3)[None])
    _, rows = loop.run(algo, [3], 2)
    # the surrogate is a mean of advantage-normalised terms that can cancel to near 0: float32 rounding
    # of the vmapped run is then an absolute, not a relative, difference
    np.testing.assert_allclose(np.asarray(metrics["policy_loss"][0]), [r["policy_loss"] for r in rows[1:]],
                               rtol=1e-4, atol=1e-6)
    np.testing.assert_allclose(np.asarray(metrics["time_at_goal"][0]), [r["time_at_goal"] for r in rows[1:]])


TWO_DEVICES = """
import json
import sys
import jax
import fieldgen
from fieldgen.agents import crl, loop
assert len(jax.local_devices()) == 2
algo = crl.make_train(crl.CRLConfig.layered(**json.loads(sys.argv[1])), fieldgen.make("point_nav"))
out = {}
for seeds in ([1], [0, 1]):  # one seed: its environments split; two: a seed per device
    state, rows = loop.run(algo, seeds, 2)
    columns = state.buffer.data["state"]
    out[len(seeds)] = {"rows": [r for r in rows if r["seed"] == 1], "devices": len(columns.sharding.device_set),
                       "split_axis": [i for i, n in enumerate(columns.sharding.spec) if n][0]}
print(json.dumps(out))
"""


@pytest.mark.slow
def test_two_devices_match_one(seed_one, tiny_crl):
    """The same CRL run on this process's one device and on two host devices. One seed: its environments
    and buffer are split across the two, and the metrics agree within float32 reduction-order tolerance.
    Two seeds: each device trains one (the buffer is split along the seed axis), nothing crosses between
    them, and seed 1 matches its run alone as closely as vmapped seeds do."""
    _, one = seed_one
    flags = f"{os.environ.get('XLA_FLAGS', '')} --xla_force_host_platform_device_count=2"
    env = {**os.environ, "XLA_FLAGS": flags, "JAX_PLATFORMS": "cpu"}
    proc = subprocess.run([sys.executable, "-c", TWO_DEVICES, json.dumps(tiny_crl().model_dump())], env=env,
                          capture_output=True, text=True, cwd=Path(__file__).parents[2], timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]
    runs = json.loads(proc.stdout.strip().splitlines()[-1])
    for seeds, split_axis, rel in (("1", 2, 2e-3), ("2", 0, 1e-4)):  # buffer columns: [seeds, rows, envs, ...]
        two = runs[seeds]
        assert two["devices"] == 2 and two["split_axis"] == split_axis
        assert len(two["rows"]) == len(one) == 3
        for a, b in zip(one, two["rows"]):
            for name in ("success_any", "time_at_goal", "critic_loss", "actor_loss"):
                if name in a:
                    assert b[name] == pytest.approx(a[name], rel=rel, abs=rel / 2), (seeds, name)


@pytest.mark.slow
def test_evaluation_reports_each_reward_terms_mean(write_spec):
    """point_nav never terminates early, so return = time at goal + 0.1 x 100 steps x mean agent_progress."""
    import fieldgen

    spec = write_spec("extends: point_nav\nname: point_nav_dense\ntask:\n  reward:\n    - {term: success}\n"
                      "    - {term: agent_progress, weight: 0.1}\n")
    env = fieldgen.make(spec)
    policy, key = (lambda obs: obs[:, -2:] - obs[:, :2]), jax.random.PRNGKey(0)
    metrics, nothing = jax.device_get(loop.evaluate_policy(env, policy, key, 8))
    assert set(metrics) == {"success_any", "time_at_goal", "closest_distance", "farthest_from_start",
                            "episode_length", "episode_return", "term_agent_progress"}
    assert metrics["term_agent_progress"] > 0  # the policy heads for the target
    assert metrics["episode_length"] == env.episode_length
    expected = metrics["time_at_goal"] + 0.1 * env.episode_length * metrics["term_agent_progress"]
    assert metrics["episode_return"] == pytest.approx(expected, rel=1e-4)
    assert nothing is None

    filmed, (qpos, done) = jax.device_get(loop.evaluate_policy(env, policy, key, 8, lambda s: s.pipeline_state.qpos))
    floats = lambda m: {k: float(v) for k, v in m.items()}  # noqa: E731
    assert floats(filmed) == pytest.approx(floats(metrics))  # filming changes nothing measured
    assert qpos.shape == (env.episode_length, env.mj_model.nq) and done.shape == (env.episode_length,)
    first = env.reset(jax.random.split(key, 8)[0])  # the first episode is the one filmed
    np.testing.assert_allclose(qpos[0], first.pipeline_state.qpos)
    assert np.linalg.norm(qpos[-1, :2] - first.info["goal"]) < np.linalg.norm(qpos[0, :2] - first.info["goal"])


@pytest.mark.slow
def test_sampled_actions_take_a_fresh_key_at_every_step_and_the_mean_ones_none(write_spec):
    """With sampled, evaluate_policy hands the policy a key per step (the same steps of two episodes get
    different ones, two steps of one episode too); without, the policy is called on observations alone."""
    import fieldgen

    env = fieldgen.make(write_spec("extends: point_nav\nname: point_nav_keys\n"))
    keys_seen = []

    def policy(obs, key=None):
        if key is None:
            return jnp.zeros((obs.shape[0], env.action_size))
        keys_seen.append(key)  # traced once, inside the scan
        return jax.random.uniform(key, (obs.shape[0], env.action_size), minval=-1.0, maxval=1.0)

    key = jax.random.PRNGKey(3)
    still, _ = jax.device_get(loop.evaluate_policy(env, policy, key, 4))
    assert not keys_seen
    moving, (qpos, _) = jax.device_get(loop.evaluate_policy(env, policy, key, 4, lambda s: s.pipeline_state.qpos,
                                                            sampled=True))
    assert len(keys_seen) == 1
    assert float(moving["closest_distance"]) != pytest.approx(float(still["closest_distance"]))
    steps = np.diff(qpos[:, :2], axis=0)
    assert len({tuple(np.round(d, 6)) for d in steps[:10]}) == 10  # each step drew its own action
    again, _ = jax.device_get(loop.evaluate_policy(env, policy, key, 4, sampled=True))
    other, _ = jax.device_get(loop.evaluate_policy(env, policy, jax.random.PRNGKey(4), 4, sampled=True))
    assert float(again["closest_distance"]) == float(moving["closest_distance"])  # the evaluation key decides
    assert float(other["closest_distance"]) != float(moving["closest_distance"])


def test_a_trainers_start_is_traced_once_for_its_shapes_checkpoints_and_program():
    """The shapes a run's checkpoint and learner are read through and its programs placed by come from one
    trace of its start per seed count, which the start program's compile reuses; the environment is sized for
    every environment of every seed before it (Warp's data is shaped by it), whoever asks for the shapes first."""
    from types import SimpleNamespace

    from fieldgen.agents import programs

    traced = []

    class Reserving:
        worlds = 1

        def reserve_worlds(self, worlds):
            self.worlds = max(self.worlds, worlds)

    class Starting:
        compiled: dict = {}
        env = Reserving()
        config = SimpleNamespace(num_envs=4, eval_envs=8)

        def start(self, key):
            traced.append((key.shape, self.env.worlds))
            return {"x": jnp.zeros(3) + key[0]}

    trainer, keys = Starting(), jnp.zeros((2, 2), jnp.uint32)
    start, shapes = programs.started(trainer, keys)
    assert programs.started(trainer, keys)[1] is shapes and shapes["x"].shape == (2, 3)
    assert traced == [((2,), 2 * 8)]  # two seeds of the larger of training's and evaluation's batches
    jax.jit(start)(keys)
    assert len(traced) == 1
    programs.started(trainer, jnp.zeros((3, 2), jnp.uint32))  # another seed count: its own trace
    assert traced[1] == ((2,), 3 * 8)


@pytest.mark.slow
def test_an_evaluation_is_handed_on_while_the_next_chunk_holds_its_call_and_dated_when_it_ended(env_cache, tiny_crl,
                                                                                                monkeypatch):
    """A chunk's call that holds its thread until the chunk ends (as on a GPU) leaves the loop free to hand the
    last evaluation on meanwhile; each row's wall_seconds dates its own evaluation. Here every chunk's call
    holds until an evaluation has been handed on, and the loop's clock moves only inside chunks, 100 s each."""
    import threading
    from concurrent.futures import Future
    from types import SimpleNamespace

    from fieldgen.agents import programs

    now, handed, in_time = [0.0], threading.Event(), []
    monkeypatch.setattr(loop, "time", SimpleNamespace(perf_counter=lambda: now[0]))
    started = programs.Compiling.started

    def held(self, *args):
        inner, done = started(self, *args), Future()

        def hold():
            out = jax.block_until_ready(inner.result())
            in_time.append(handed.wait(timeout=10))  # never, where the loop waits for the call before handing on
            handed.clear()
            now[0] += 100.0
            done.set_result(out)

        threading.Thread(target=hold).start()
        return done

    monkeypatch.setattr(programs.Compiling, "started", held)
    _, rows = loop.run_staged([crl.make_train(tiny_crl(), env_cache("point_nav"))], [0], 2, loop.OneStage(),
                              lambda index, rows: handed.set(), clock=0.0)
    assert in_time == [True, True]
    assert [r["wall_seconds"] for r in rows] == [0.0, 100.0, 200.0]


def test_a_calls_first_chunk_counts_toward_the_time_a_chunk_takes_only_while_it_is_the_only_one():
    """The first chunk of a command also waits for compiling, a refilled buffer and the state's move to the
    device: a time limit judged on it would stop a run a chunk early in every command."""
    assert loop.longest_chunk([]) is None
    assert loop.longest_chunk([118.0]) == 118.0
    assert loop.longest_chunk([118.0, 70.0, 72.0]) == 72.0
    assert loop.longest_chunk([60.0, 70.0]) == 70.0


class TurningOver:
    """An agent with a torso and nothing else: upright for its first two steps, upside down from its third, over
    episodes of 10 steps; just what the evaluation reads of an environment."""

    observation_names = ("root.x", "root.y", "root.z", *TORSO_QUATERNION, "goal.x", "goal.y")
    state_dim, goal_indices, success_goal_entries = 7, (0, 1), (0, 1)
    episode_length, variant_count = 10, 1

    def observe(self, t):
        quat = jnp.where(t >= 3, jnp.asarray([0.0, 1.0, 0.0, 0.0]), jnp.asarray([1.0, 0.0, 0.0, 0.0]))
        return jnp.concatenate([jnp.asarray([0.0, 0.0, 0.5]), quat, jnp.asarray([5.0, 0.0])])

    def reset(self, key):
        from brax.envs.base import State

        zero = jnp.zeros(())
        return State(zero, self.observe(0), zero, zero, {"success": zero}, {"t": jnp.zeros((), jnp.int32)})

    def step(self, state, action):
        t = state.info["t"] + 1
        return state.replace(obs=self.observe(t), done=(t >= self.episode_length).astype(jnp.float32),
                             info={"t": t})


def test_the_evaluation_reports_the_share_of_steps_an_agent_with_a_torso_spent_turned_over():
    metrics, _ = jax.device_get(loop.evaluate_policy(TurningOver(), lambda obs: obs[:, :1] * 0, jax.random.PRNGKey(0), 2))
    assert float(metrics["turned_over"]) == pytest.approx(7 / 9)  # steps 3-9 of the 9 inside the episode
    assert torso_entries(TurningOver.observation_names) == [3, 4, 5, 6]
    assert torso_entries(("agent.x", "agent.y", "goal.x", "goal.y")) is None  # a point: no metric


def test_staggered_starts_spread_the_first_episodes_ends_and_leave_the_later_ones_whole(env_cache):
    env = env_cache("point_nav", episode_length=12)
    key = jax.random.PRNGKey(5)
    plain = jax.jit(lambda k: loop.first_states(env, ppo.PPOConfig(num_envs=64), k))(key)
    same = jax.jit(jax.vmap(env.reset))(jax.random.split(key, 64))
    for a, b in zip(jax.tree.leaves(plain), jax.tree.leaves(same)):  # off: the batch every run began with
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
    staggered = jax.jit(lambda k: loop.first_states(env, ppo.PPOConfig(num_envs=64, stagger_starts=True), k))(key)
    begun = np.asarray(staggered.info["episode_step"])
    assert begun.min() >= 0 and begun.max() < 12 and len(set(begun.tolist())) > 6
    np.testing.assert_array_equal(np.asarray(staggered.obs), np.asarray(plain.obs))  # the same first states

    step = jax.jit(jax.vmap(env.step))
    state, ended = staggered, []
    for _ in range(2 * 12):  # still actions: time, not a fall or a goal, ends every episode
        state = step(state, jnp.zeros((64, env.action_size)))
        ended.append(np.asarray(state.done) > 0)
    ended = np.array(ended)  # [steps, envs]
    first, second = ended.argmax(0), 12 + ended[12:].argmax(0)
    np.testing.assert_array_equal(first + 1, 12 - begun)  # the first episode: what was left of it
    np.testing.assert_array_equal(second - first, np.full(64, 12))  # every later one whole
    assert len(set(first.tolist())) > 6  # ends spread over the episode's length, not all at one step


@pytest.mark.parametrize("algo", ["crl", "ppo", "sac", "td3"])
def test_every_trainer_starts_its_episodes_staggered_when_told(env_cache, algo):
    from fieldgen.agents import registry

    entry = registry.trainer(algo)
    small = dict(total_steps=100_000, num_envs=16, unroll_length=10, num_evals=2, eval_envs=8)  # init alone runs
    env = env_cache("point_nav")
    for stagger in (False, True):
        state = entry.make_train(entry.config(**small, stagger_starts=stagger), env).init(jax.random.PRNGKey(0))
        begun = np.asarray(state.env_state.info["episode_step"])
        assert (len(set(begun.tolist())) > 1) == stagger and begun.max() < env.episode_length
