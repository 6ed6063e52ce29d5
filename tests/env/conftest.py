"""What brax's and MuJoCo Playground's training wrappers must make of a field's episodes."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest


@pytest.fixture
def check_wrapped_episodes():
    """Check that, inside vmap, episode and auto-reset wrappers, point_nav's episodes last their 100 steps (not
    50: the wrappers' step counter is theirs alone), end truncated, and start again somewhere new (not at the
    first reset's start, which the wrappers would replay)."""

    def check(wrapped, action_size: int):
        state = jax.jit(wrapped.reset)(jax.random.split(jax.random.PRNGKey(0), 4))
        first = np.asarray(state.obs)

        def step(state, _):
            state = wrapped.step(state, jnp.zeros((4, action_size)))
            return state, (state.done, state.info["truncation"], state.obs)

        _, (done, truncation, obs) = jax.jit(lambda s: jax.lax.scan(step, s, None, length=250))(state)
        ends = [int(t) + 1 for t in np.flatnonzero(np.asarray(done)[:, 0])]
        assert ends == [100, 200]  # the 100th and 200th steps end an episode
        assert np.all(np.asarray(truncation)[np.asarray(ends) - 1] == 1)
        restarted = [np.asarray(obs)[t - 1] for t in ends]  # what a done step returns: the next episode's start
        for start in restarted:
            assert not np.allclose(start, first)
        assert not np.allclose(restarted[0], restarted[1])
        return state

    return check
