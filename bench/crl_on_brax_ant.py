"""CRL on brax's own ant made goal-conditioned the way the CRL reference implementation
does it, on brax's generalized pipeline or on MJX (brax's MJX settings, like ant_nav's).

The reference reached about 0.6 success on this task within 10M steps. If our CRL
learns here but not on ant_nav, the trainer is sound; comparing the two backends
separates the physics from the rest of the environment.

    python bench/crl_on_brax_ant.py --steps 10000000 --backend mjx --json results.jsonl
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import jax
import jax.numpy as jnp
from brax import envs

from fieldgen.agents import crl, loop
from fieldgen.files import append_jsonl


class GoalAnt:
    """brax `ant` (terminating when the torso leaves z 0.2..1.0) + a target 10 away; obs = q, qd, target."""

    state_dim, goal_indices = 29, jnp.array([0, 1])
    variant_count = 1  # one field: the contract's variants part

    def __init__(self, backend: str, episode_length: int = 1001, radius: float = 10.0):
        self.base = envs.get_environment("ant", backend=backend, exclude_current_positions_from_observation=False)
        self.episode_length, self.radius = episode_length, radius
        self.observation_size, self.action_size = 31, self.base.action_size

    def _fresh(self, key):
        k_env, k_angle = jax.random.split(key)
        state = self.base.reset(k_env)
        angle = 2 * jnp.pi * jax.random.uniform(k_angle)
        goal = self.radius * jnp.stack([jnp.cos(angle), jnp.sin(angle)])
        return state, goal

    def reset(self, key):
        key, k = jax.random.split(key)
        state, goal = self._fresh(k)
        info = {"rng": key, "goal": goal, "steps": jnp.zeros((), jnp.int32), "truncation": jnp.zeros(()),
                "episode": jnp.zeros((), jnp.int32)}
        return state.replace(obs=jnp.concatenate([state.obs, goal]), info=info,
                             metrics={"success": jnp.zeros(())})

    def step(self, state, action):
        info = state.info
        inner = state.replace(obs=state.obs[:29], info={}, metrics={})
        nxt = self.base.step(inner, action)
        dist = jnp.linalg.norm(nxt.pipeline_state.q[:2] - info["goal"])
        success = (dist < 0.5).astype(jnp.float32)
        steps = info["steps"] + 1
        truncated = steps >= self.episode_length
        fell = nxt.done > 0
        done = truncated | fell
        rng, k = jax.random.split(info["rng"])
        fresh, fresh_goal = self._fresh(k)
        pick = lambda a, b: jax.tree.map(lambda x, y: jnp.where(done, x, y), a, b)  # noqa: E731
        pipeline = pick(fresh.pipeline_state, nxt.pipeline_state)
        goal = jnp.where(done, fresh_goal, info["goal"])
        obs = jnp.concatenate([jnp.where(done, fresh.obs, nxt.obs), goal])
        new_info = {"rng": rng, "goal": goal, "steps": jnp.where(done, 0, steps),
                    "truncation": (truncated & ~fell).astype(jnp.float32),
                    "episode": info["episode"] + done.astype(jnp.int32)}
        return nxt.replace(pipeline_state=pipeline, obs=obs, reward=success, done=done.astype(jnp.float32),
                           metrics={"success": success}, info=new_info)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--steps", type=int, default=10_000_000)
    parser.add_argument("--envs", type=int, default=1024)
    parser.add_argument("--backend", default="generalized", choices=("generalized", "mjx", "spring", "positional"))
    parser.add_argument("--json", type=Path)
    args = parser.parse_args()
    config = crl.CRLConfig(total_steps=args.steps, num_envs=args.envs, num_evals=10, eval_envs=256)
    started = time.perf_counter()

    def progress(index, rows):
        row = {"env": f"brax_ant_{args.backend}", "seconds": time.perf_counter() - started, **rows[0]}
        print(json.dumps({k: round(v, 4) if isinstance(v, float) else v for k, v in row.items()}), flush=True)
        append_jsonl(args.json, row)

    loop.run(crl.make_train(config, GoalAnt(args.backend)), [0], config.num_evals, progress)


if __name__ == "__main__":
    main()
