"""What every trainer shares: evaluating a policy, and the chunked loop between evaluations."""

from __future__ import annotations

from typing import Callable

import jax
import jax.numpy as jnp


def evaluate_policy(env, act: Callable, key: jax.Array, n_envs: int) -> dict:
    """One episode per environment with `act(obs)`, counted up to its first `done`."""
    env_state = jax.vmap(env.reset)(jax.random.split(key, n_envs))

    def step(carry, _):
        env_state, alive = carry
        nxt = jax.vmap(env.step)(env_state, act(env_state.obs))
        out = {"success": nxt.metrics["success"] * alive, "reward": nxt.reward * alive}
        return (nxt, alive * (1.0 - nxt.done)), out

    _, out = jax.lax.scan(step, (env_state, jnp.ones(n_envs)), None, length=env.episode_length)
    return {"success_any": jnp.mean(jnp.any(out["success"] > 0, axis=0)),
            "time_at_goal": jnp.mean(jnp.sum(out["success"], axis=0)),
            "episode_return": jnp.mean(jnp.sum(out["reward"], axis=0))}


def run_evaluations(first: Callable, chunk: Callable, evaluate: Callable, num_evals: int, seed: int,
                    progress: Callable[[int, dict], None], on_eval: Callable, resume=None):
    """Evaluate once at the start (index 0), then after each of num_evals jitted chunks.

    `first()` gives the starting state; `chunk(state) -> (state, metrics)`; `evaluate(state, key)`.
    Evaluation keys come from (seed, index), so a resumed run sees the same keys as an unbroken one.
    """
    history = []

    def record(state, metrics, index):
        key = jax.random.fold_in(jax.random.PRNGKey(seed + 1), index)
        metrics = {name: float(v) for name, v in {**metrics, **jax.device_get(evaluate(state, key))}.items()}
        history.append({"eval": index, "env_steps": int(state.env_steps), **metrics})
        progress(int(state.env_steps), metrics)
        on_eval(state, index)

    if resume is None:
        state, start = first(), 1
        record(state, {}, 0)
    else:
        state, start = resume[0], resume[1] + 1
    for index in range(start, num_evals + 1):
        state, metrics = chunk(state)
        record(state, jax.device_get(metrics), index)
    return state, history
