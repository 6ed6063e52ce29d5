"""CRL's losses against hand-computed values, and CRL learning a point field on CPU."""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np
import pytest

from fieldgen.agents.contrastive import ENERGIES, LOSSES, critic_terms, energy, paired_energy
from fieldgen.agents.optim import adam_by_group

PHI = jnp.array([[0.0, 0.0], [1.0, 0.0]])
PSI = jnp.array([[0.0, 1.0], [1.0, 1.0]])
ONES = jnp.ones(2)


def test_energies_by_hand():
    r2 = np.sqrt(2.0)
    np.testing.assert_allclose(energy("norm", PHI, PSI), [[-1, -r2], [-r2, -1]], rtol=1e-5)
    np.testing.assert_allclose(energy("l2", PHI, PSI), [[-1, -2], [-2, -1]], rtol=1e-6)
    np.testing.assert_allclose(energy("dot", PHI, PSI), [[0, 0], [0, 1]], atol=1e-6)
    cos = energy("cosine", PHI + jnp.array([0.0, 1.0]), PSI, jnp.log(0.5))  # phi rows (0,1), (1,1)
    np.testing.assert_allclose(cos, np.array([[1, 1 / r2], [1 / r2, 1]]) / 0.5, rtol=1e-5)


def test_paired_energy_is_the_diagonal_and_near_pairs_keep_their_distance():
    rng = np.random.default_rng(0)
    phi = jnp.asarray(rng.normal(0, 5, (6, 64)), jnp.float32)
    psi = phi + jnp.asarray(rng.normal(0, 1e-2, (6, 64)), jnp.float32)  # positives close to their rows
    for kind in ENERGIES:
        np.testing.assert_array_equal(paired_energy(kind, phi, psi, jnp.log(0.5)),  # to the bit: critic_terms
                                      jnp.diagonal(energy(kind, phi, psi, jnp.log(0.5))))  # reads it as the diagonal
    direct = -np.linalg.norm(np.asarray(phi)[:, None] - np.asarray(psi)[None], axis=-1)
    np.testing.assert_allclose(energy("norm", phi, psi), direct, rtol=1e-3, atol=1e-3)


def test_the_energy_matrix_and_its_gradient_equal_every_pair_taken_apart():
    """The matrix from one product gives each pair's energy and gradient as `paired_energy` of that
    pair does, near pairs (the diagonal) and far ones alike."""
    import jax

    rng = np.random.default_rng(1)
    phi = jnp.asarray(rng.normal(0, 2, (8, 16)), jnp.float32)
    psi = phi + jnp.asarray(rng.normal(0, 1e-3, (8, 16)), jnp.float32)
    psi = psi.at[4:].set(jnp.asarray(rng.normal(0, 2, (4, 16)), jnp.float32))

    for kind in ENERGIES:
        matrix = lambda p, q: energy(kind, p, q, jnp.log(0.5))  # noqa: E731
        apart = lambda p, q: paired_energy(kind, p[:, None, :], q[None, :, :], jnp.log(0.5))  # noqa: E731
        np.testing.assert_allclose(matrix(phi, psi), apart(phi, psi), rtol=1e-4, atol=1e-4)
        for reduce in (lambda e: jnp.sum(jax.nn.logsumexp(e, axis=1)), lambda e: jnp.sum(jnp.diagonal(e))):
            mine = jax.grad(lambda p, q: reduce(matrix(p, q)), (0, 1))(phi, psi)
            theirs = jax.grad(lambda p, q: reduce(apart(p, q)), (0, 1))(phi, psi)
            for a, b in zip(mine, theirs):
                np.testing.assert_allclose(a, b, rtol=1e-3, atol=1e-4)


def terms(kind: str, logits: jnp.ndarray, weight: jnp.ndarray) -> tuple:
    return critic_terms(kind, logits, jnp.diagonal(logits), weight)


def test_critic_terms_by_hand():
    logits = jnp.array([[2.0, 0.0], [1.0, 3.0]])
    fwd = np.mean([-(2 - np.log(np.exp(2) + 1)), -(3 - np.log(np.exp(1) + np.exp(3)))])
    bwd = np.mean([-(2 - np.log(np.exp(2) + np.exp(1))), -(3 - np.log(1 + np.exp(3)))])
    assert float(terms("fwd_infonce", logits, ONES)[0]) == pytest.approx(fwd, rel=1e-5)
    assert float(terms("bwd_infonce", logits, ONES)[0]) == pytest.approx(bwd, rel=1e-5)
    assert float(terms("sym_infonce", logits, ONES)[0]) == pytest.approx((fwd + bwd) / 2, rel=1e-5)
    only_first = -(2 - np.log(np.exp(2) + 1))
    assert float(terms("fwd_infonce", logits, jnp.array([1.0, 0.0]))[0]) == pytest.approx(only_first, rel=1e-5)
    lse = np.mean([np.log(np.exp(2) + 1) ** 2, np.log(np.exp(1) + np.exp(3)) ** 2])
    assert float(terms("fwd_infonce", logits, ONES)[1]) == pytest.approx(lse, rel=1e-5)
    assert float(terms("fwd_infonce", logits, ONES)[2]) == 1.0
    assert float(terms("fwd_infonce", jnp.array([[2.0, 5.0], [1.0, 3.0]]), ONES)[2]) == 0.5


def taken_apart(kind: str, logits, weight) -> tuple:
    """The critic's three terms as the reference implementation writes them: a log-softmax per axis, the
    diagonal read off it, a logsumexp of its own for the penalty, an argmax for the accuracy."""
    import jax

    def mean(x):
        return jnp.sum(x * weight) / jnp.maximum(jnp.sum(weight), 1.0)

    fwd = -jnp.diagonal(jax.nn.log_softmax(logits, axis=1))
    bwd = -jnp.diagonal(jax.nn.log_softmax(logits, axis=0))
    per_row = {"fwd_infonce": fwd, "bwd_infonce": bwd, "sym_infonce": 0.5 * (fwd + bwd)}[kind]
    accuracy = (jnp.argmax(logits, axis=1) == jnp.arange(len(logits))).astype(jnp.float32)
    return mean(per_row), mean(jax.nn.logsumexp(logits, axis=1) ** 2), mean(accuracy)


@pytest.mark.parametrize("kind", LOSSES)
def test_critic_terms_and_their_gradients_equal_the_terms_taken_apart(kind):
    """From representations through every energy: the same loss, penalty and accuracy, and the same
    gradients for phi and psi, as each term taken apart."""
    import jax

    rng = np.random.default_rng(1)
    phi, psi = (jnp.asarray(rng.normal(0, 1, (16, 8)), jnp.float32) for _ in range(2))
    weight = jnp.asarray(rng.random(16) > 0.2, jnp.float32)
    for energy_kind in ENERGIES:
        def fused(phi, psi):
            logits = energy(energy_kind, phi, psi, jnp.log(0.5))
            loss, penalty, accuracy = critic_terms(kind, logits, paired_energy(energy_kind, phi, psi, jnp.log(0.5)),
                                                   weight)
            return loss + 0.1 * penalty, (loss, penalty, accuracy)

        def reference(phi, psi):
            loss, penalty, accuracy = taken_apart(kind, energy(energy_kind, phi, psi, jnp.log(0.5)), weight)
            return loss + 0.1 * penalty, (loss, penalty, accuracy)

        (_, got), got_grads = jax.value_and_grad(fused, argnums=(0, 1), has_aux=True)(phi, psi)
        (_, want), want_grads = jax.value_and_grad(reference, argnums=(0, 1), has_aux=True)(phi, psi)
        np.testing.assert_allclose(got, want, rtol=1e-5, atol=1e-6, err_msg=energy_kind)
        for g, w in zip(got_grads, want_grads):
            np.testing.assert_allclose(g, w, rtol=1e-4, atol=1e-6, err_msg=energy_kind)


def test_critic_terms_reduce_the_matrix_fewer_times_than_the_terms_taken_apart():
    """Each reduction over the [B, B] logits is a GPU kernel at every gradient step: the loss, penalty and
    accuracy with their gradient compile to fewer of them than the three terms taken apart."""
    import jax

    logits, weight = jnp.zeros((64, 64)), jnp.ones(64)

    def reductions(terms_of) -> int:
        def loss(logits):
            a, b, c = terms_of(logits)
            return a + 0.1 * b, c

        text = jax.jit(jax.grad(loss, has_aux=True)).lower(logits).as_text()
        return sum(1 for line in text.splitlines() if "reduce" in line and "64x64" in line)

    fused = reductions(lambda x: critic_terms("fwd_infonce", x, jnp.diagonal(x), weight))
    apart = reductions(lambda x: taken_apart("fwd_infonce", x, weight))
    assert 0 < fused < apart, (fused, apart)


def test_unknown_names_are_refused():
    with pytest.raises(ValueError, match="unknown energy 'cos'"):
        energy("cos", PHI, PSI)
    with pytest.raises(ValueError, match="unknown contrastive loss"):
        critic_terms("nce", PHI @ PSI.T, ONES, ONES)


def test_adam_by_group_equals_one_adam_per_group():
    import jax
    import optax

    rng = np.random.default_rng(1)
    # the first group stacks two networks on a leading axis, each with its own rate
    groups = ({"w": jnp.asarray(rng.normal(size=(2, 3, 2))), "b": jnp.ones((2, 2))}, jnp.asarray(rng.normal(size=4)))
    rates = (1e-2, 1e-3, 3e-1)  # network 0, network 1, the second group
    grouped, single = adam_by_group(jnp.array(rates[:2]), rates[2]), [optax.adam(r) for r in rates]
    split = lambda g: (jax.tree.map(lambda x: x[0], g[0]), jax.tree.map(lambda x: x[1], g[0]), g[1])  # noqa: E731
    state, states = grouped.init(groups), [tx.init(g) for tx, g in zip(single, split(groups))]
    for step in range(3):
        grads = jax.tree.map(lambda x: jnp.sin(x * (step + 1)), groups)
        updates, state = grouped.update(grads, state)
        expected = []
        for i, tx in enumerate(single):
            update, states[i] = tx.update(split(grads)[i], states[i])
            expected.append(update)
        for got, want in zip(jax.tree.leaves(split(updates)), jax.tree.leaves(tuple(expected))):
            np.testing.assert_allclose(got, want, rtol=1e-6, atol=1e-9)
        groups = optax.apply_updates(groups, updates)
    with pytest.raises(ValueError, match="2 learning rates"):
        grouped.init(groups[:1])


@pytest.mark.slow
@pytest.mark.parametrize("network", [dict(hidden=(64, 64)),
                                     dict(hidden=(64, 64, 64), skip_every=2, layer_norm=True),
                                     dict(hidden=(64, 64), actor_commanded_goals=0.5)],
                         ids=["mlp", "residual_layer_norm", "actor_on_commanded_goals"])
def test_crl_learns_point_nav(env_cache, network):
    """From an untrained policy to reaching a random target 3 away in at least 80% of episodes, in 40k steps,
    with the plain MLPs and with residual blocks of Dense -> LayerNorm -> swish."""
    from fieldgen.agents.crl import CRLConfig, make_train
    from fieldgen.agents.loop import run

    config = CRLConfig(total_steps=40_000, num_envs=16, unroll_length=25, batch_size=64, windows=64, min_replay_rows=100,
                       max_replay_rows=2000, repr_dim=16, num_evals=3, eval_envs=32, **network)
    _, history = run(make_train(config, env_cache("point_nav")), [0], config.num_evals)
    assert history[0]["success_any"] <= 0.3
    assert history[-1]["success_any"] >= 0.8
    assert history[-1]["time_at_goal"] > 30


@pytest.mark.slow
def test_the_buffer_keeps_the_commanded_goal_only_for_an_actor_that_learns_from_it(env_cache, tiny_crl):
    """With `actor_commanded_goals` the buffer keeps each step's commanded goal (point_nav's target, one per
    episode); without it the buffer, and so a checkpoint, is as it was."""
    import jax

    from fieldgen.agents.crl import make_train

    env = env_cache("point_nav")
    plain = make_train(tiny_crl(), env).start(jax.random.PRNGKey(0))
    assert "commanded" not in plain.buffer.data
    asked = make_train(tiny_crl(actor_commanded_goals=0.5), env).start(jax.random.PRNGKey(0))
    commanded, episode = (np.asarray(asked.buffer.data[k]) for k in ("commanded", "episode"))
    stored = np.abs(commanded).sum(-1) > 0
    assert stored.any() and commanded.shape[-1] == len(env.goal_indices)
    for env_index in range(episode.shape[1]):  # one goal per episode
        for e in np.unique(episode[stored[:, env_index], env_index]):
            rows = commanded[(episode[:, env_index] == e) & stored[:, env_index], env_index]
            assert np.allclose(rows, rows[0])


def test_a_share_of_commanded_goals_outside_zero_to_one_is_refused(tiny_crl):
    from fieldgen.agents.config import ConfigError

    with pytest.raises((ConfigError, ValueError), match="actor_commanded_goals"):
        tiny_crl(actor_commanded_goals=1.5)


def test_pairs_per_window_must_divide_the_batch_and_fit_an_episode(env_cache, tiny_crl):
    from fieldgen.agents.config import ConfigError

    env = env_cache("point_nav")
    longest = env.episode_length
    tiny_crl(pairs_per_window=4).validate_env(env)
    for bad, changes in ((3, {}), (2 * longest, {"batch_size": 4 * longest})):  # batch 32; longer than an episode
        with pytest.raises(ConfigError, match=f"crl.pairs_per_window {bad} must divide batch_size .* at most an "
                                              f"episode's {longest} steps"):
            tiny_crl(pairs_per_window=bad, **changes).validate_env(env)


@pytest.mark.slow
def test_early_updates_take_a_share_of_the_updates_until_their_env_steps_and_each_as_the_full_epoch_does(
        env_cache, tiny_crl):
    """Before `early_until` env steps an iteration takes the first `early_updates` share of its minibatch updates,
    every seed of the program alike, and all of them after; an early share that rounds to every update learns
    what the epoch without a schedule learns, update for update."""
    import jax

    from fieldgen.agents.buffer import gradient_steps, iterations
    from fieldgen.agents.crl import make_train
    from fieldgen.agents.loop import run

    env = env_cache("point_nav")
    plain = tiny_crl()
    _, per_eval = iterations(plain)
    _, updates = gradient_steps(plain, env.episode_length)
    early = round(0.5 * updates)
    scheduled = tiny_crl(early_updates=0.5, early_until=plain.steps_at(1) + 1)  # the first chunk's iterations
    state, _ = run(make_train(scheduled, env), [0, 1], scheduled.num_evals)
    assert np.asarray(state.grad_steps).tolist() == [per_eval * (early + updates)] * 2
    assert early < updates

    every = tiny_crl(early_updates=1 - 0.4 / updates, early_until=10 ** 9)  # rounds to every update
    alike, _ = run(make_train(every, env), [0], every.num_evals)
    reference, _ = run(make_train(plain, env), [0], plain.num_evals)
    assert int(alike.grad_steps[0]) == int(reference.grad_steps[0]) == 2 * per_eval * updates
    for got, want in zip(jax.tree.leaves(alike.nets), jax.tree.leaves(reference.nets)):
        np.testing.assert_allclose(np.asarray(got), np.asarray(want), rtol=1e-5, atol=1e-6)


def test_an_early_share_of_updates_outside_zero_to_one_is_refused(tiny_crl):
    from fieldgen.agents.config import ConfigError

    for bad in (0, 1.5):
        with pytest.raises((ConfigError, ValueError), match="early_updates"):
            tiny_crl(early_updates=bad)
    with pytest.raises((ConfigError, ValueError), match="early_until"):
        tiny_crl(early_until=-1)
    assert tiny_crl(early_until="10M").early_until == 10_000_000
