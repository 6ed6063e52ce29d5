"""Contrastive RL (CRL): goal-conditioned, sparse reward, a contrastive critic.

The critic is two encoders, phi(s, a) and psi(g); their energy is trained with
InfoNCE on hindsight goals drawn from each transition's own future. The actor
is a tanh-Gaussian that maximises the energy towards its goal, with an entropy
coefficient tuned to a target entropy. Defaults follow the reference
implementation (JaxGCRL) so results compare.

`make_train(config, env, team)` returns the run as pure functions (agents.loop.Trainer).
With a team of several controllers (agents.team, used by agents.icrl) every network, loss
and entropy coefficient gains a leading controller axis and is vmapped over it; the default
team is one controller that sees and drives everything.
"""

from __future__ import annotations

import functools

import flax.struct
import jax
import jax.numpy as jnp
import optax

from .. import buffer as replay
from .config import CRLConfig
from ..contrastive import critic_terms, energy, paired_energy, weighted_mean
from ..loop import Trainer, first_states
from ..networks import Stacked, gaussian_head, sample_tanh_gaussian
from ..optim import adam_by_group
from ..actor import Policy
from ..team import Team, whole


@flax.struct.dataclass
class TrainState:
    nets: dict  # the actor, phi(s, a) and psi(g), stacked in that order (agents.networks.Stacked)
    log_temperature: jax.Array
    log_alpha: jax.Array
    opt: optax.OptState  # of (nets, log_temperature, log_alpha), one flat Adam
    env_state: object
    buffer: replay.Buffer
    key: jax.Array
    env_steps: jax.Array
    grad_steps: jax.Array


def make_train(config: CRLConfig, env, team: Team | None = None, shared: bool = False) -> Trainer:
    """CRL for one controller that sees and drives everything, or for a team of independent controllers
    (ICRL): each with its own actor, critic and entropy coefficient, all vmapped over a leading controller
    axis (with `shared`, one actor and one critic that every controller applies)."""
    c = config
    team = team or whole(env)
    prefill_iters, iters_per_eval = replay.iterations(config)
    if iters_per_eval < 1:
        raise ValueError(f"total_steps {c.total_steps:,} leaves no training iteration between evaluations")
    state_dim, action_size = env.state_dim, env.action_size
    goal_indices = jnp.asarray(env.goal_indices)
    window = env.episode_length
    windows, updates = replay.gradient_steps(config, window)
    scheduled = c.early_until > 0 and c.early_updates < 1
    early_count = max(1, round(c.early_updates * updates))  # at least one: an epoch's losses are its last one's
    early_until = min(c.early_until, jnp.iinfo(jnp.int32).max)  # compared with the state's int32 env steps
    seen, own, goal_size = team.observed.shape[1], team.actions.shape[1], len(env.goal_indices)
    # one batched network call evaluates the actor and both encoders together
    nets = Stacked(c.hidden, (seen + goal_size, seen + own, goal_size), (2 * own, c.repr_dim, c.repr_dim),
                   c.layer_norm, team.size, shared, c.skip_every, c.matmul)
    tx = adam_by_group(jnp.array([c.actor_lr, c.critic_lr, c.critic_lr]), c.critic_lr, c.alpha_lr)
    target_entropy = c.target_entropy_per_action * own
    commanded = c.actor_commanded_goals > 0  # the buffer keeps each step's commanded goal only when used
    energies = jax.vmap(functools.partial(energy, c.energy))
    paired_energies = jax.vmap(functools.partial(paired_energy, c.energy))

    def init(key: jax.Array) -> TrainState:
        k_actor, k_sa, k_g, k_env, key = jax.random.split(key, 5)
        params = nets.init([k_actor, k_sa, k_g])
        log_temperature, log_alpha = jnp.zeros(team.size), jnp.zeros(team.size)
        env_state = first_states(env, c, k_env)
        example = {"state": jnp.zeros(state_dim), "action": jnp.zeros(action_size),
                   "episode": jnp.zeros((), jnp.int32)}
        if commanded:
            example["commanded"] = jnp.zeros(goal_size)
        return TrainState(params, log_temperature, log_alpha, tx.init((params, log_temperature, log_alpha)),
                          env_state, replay.init(c.max_replay_rows, c.num_envs, example), key,
                          jnp.zeros((), jnp.int32), jnp.zeros((), jnp.int32))

    def controller_obs(state, goal):
        mine, goals = team.observe(state, goal)
        return jnp.concatenate([mine, goals], -1), mine, goals

    def policy(actor, obs, key=None):
        """A sampled action, or the mean action when key is None; `actor`: the stack's member 0."""
        controller_input, _, _ = controller_obs(obs[:, :state_dim], obs[:, state_dim:])
        mean, log_std = gaussian_head(nets.apply_member(actor, 0, controller_input))
        if key is None:
            return team.joint_action(jnp.tanh(mean))
        return team.joint_action(sample_tanh_gaussian(key, mean, log_std)[0])

    def collect(ts: TrainState) -> tuple[TrainState, dict]:
        """unroll_length steps of every environment, appended to the buffer; returns step statistics."""

        actor = nets.member(ts.nets, 0)

        def step(carry, key):
            env_state = carry
            action = policy(actor, env_state.obs, key)
            row = {"state": env_state.obs[:, :state_dim], "action": action, "episode": env_state.info["episode"]}
            if commanded:
                row["commanded"] = env_state.obs[:, state_dim:]
            nxt = jax.vmap(env.step)(env_state, action)
            fell = nxt.done * (1.0 - nxt.info["truncation"])
            return nxt, (row, {"train_success": nxt.metrics["success"], "train_falls": fell})

        key, k = jax.random.split(ts.key)
        env_state, (rows, stats) = jax.lax.scan(step, ts.env_state, jax.random.split(k, c.unroll_length))
        ts = ts.replace(env_state=env_state, buffer=replay.insert(ts.buffer, rows), key=key,
                        env_steps=ts.env_steps + c.num_envs * c.unroll_length)
        return ts, jax.tree.map(jnp.mean, stats)

    def losses(learner: tuple, batch: dict, key: jax.Array) -> tuple[jax.Array, dict]:
        """Critic, actor and entropy-coefficient losses, summed over controllers and over the three.

        Each part reads the others' parameters through stop_gradient, so the one gradient equals the
        three separate ones taken at the same parameters, while the goals are encoded once. The critic
        is each controller's InfoNCE on its own view and actions; the actor maximises the energy of its own
        sampled action towards its goal (the critic's, or for `actor_commanded_goals` of the rows the goal the
        episode commanded); alpha grows while a policy is below its target entropy."""
        params, log_temperature, log_alpha = learner
        controller_input, mine, goals = controller_obs(batch["state"], batch["goal"])
        actor_goals = goals  # the critic's (later states), or for a share of rows the commanded goal
        if commanded:
            controller_input, _, actor_goals = controller_obs(batch["state"], batch["actor_goal"])
        w = batch["weight"]
        mean_w = jax.vmap(lambda x: weighted_mean(x, w))
        taken = jnp.concatenate([mine, team.own_actions(batch["action"])], -1)
        actor_out, phi, psi = nets.apply(params, [controller_input, taken, goals])
        positives = paired_energies(phi, psi, log_temperature)  # [controllers, batch]
        energy_ = energies(phi, psi, log_temperature, positives)  # [controllers, batch, batch], positives its diagonal
        contrastive, penalty, accuracy = jax.vmap(
            lambda x, p: critic_terms(c.contrastive_loss, x, p, w))(energy_, positives)
        critic = contrastive + c.logsumexp_penalty * penalty

        # [controllers, batch, own], [controllers, batch]
        action, log_prob = sample_tanh_gaussian(key, *gaussian_head(actor_out))
        # phi of the actor's own action (and psi of the commanded goals), frozen: only those encoders of
        # the stack run again, not the actor
        own_action = jnp.concatenate([mine, action], -1)
        frozen = jax.lax.stop_gradient(params)
        if commanded:
            phi_pi, psi_goal = nets.apply_some(frozen, 1, [own_action, actor_goals])
        else:
            (phi_pi,) = nets.apply_some(frozen, 1, [own_action])
            psi_goal = jax.lax.stop_gradient(psi)  # the critic's goals: its own pass's
        q = paired_energies(phi_pi, psi_goal, jax.lax.stop_gradient(log_temperature))
        alpha = jnp.exp(log_alpha)[:, None]
        actor_ = mean_w(jax.lax.stop_gradient(alpha) * log_prob - q)
        alpha_ = mean_w(alpha * jax.lax.stop_gradient(-log_prob - target_entropy))
        total = jnp.sum(critic) + jnp.sum(actor_) + jnp.sum(alpha_)
        return total, {"critic_loss": jnp.mean(critic), "contrastive_loss": jnp.mean(contrastive),
                       "critic_accuracy": jnp.mean(accuracy), "actor_loss": jnp.mean(actor_),
                       "entropy": -jnp.mean(log_prob)}

    def update(ts: TrainState, batch: dict, key: jax.Array) -> TrainState:
        learner = (ts.nets, ts.log_temperature, ts.log_alpha)
        grads, _ = jax.grad(losses, has_aux=True)(learner, batch, key)
        updates, opt = tx.update(grads, ts.opt)
        params, log_temperature, log_alpha = optax.apply_updates(learner, updates)
        return ts.replace(nets=params, log_temperature=log_temperature, log_alpha=log_alpha, opt=opt,
                          grad_steps=ts.grad_steps + 1)

    def taken(batch: dict, i) -> dict:
        """Minibatch i of an epoch's batch, i a number or a traced index."""
        return jax.tree.map(lambda x: jax.lax.dynamic_index_in_dim(x, i, keepdims=False), batch)

    def update_epoch(ts: TrainState) -> tuple[TrainState, dict]:
        """Windows from the buffer, hindsight goals, then one pass of shuffled minibatch updates."""
        if commanded:
            key, k_batch, k_perm, k_upd, k_ask = jax.random.split(ts.key, 5)
        else:
            key, k_batch, k_perm, k_upd = jax.random.split(ts.key, 4)
        sampled = replay.hindsight_batch(ts.buffer, k_batch, windows, window, c.discount, goal_indices)
        batch = {"state": sampled["state"], "action": sampled["action"], "goal": sampled["future_goal"],
                 "weight": sampled["has_future"].astype(jnp.float32)}
        if commanded:
            asked = jax.random.uniform(k_ask, (windows * window,)) < c.actor_commanded_goals
            batch["actor_goal"] = jnp.where(asked[:, None], sampled["commanded"], sampled["future_goal"])
        perm = replay.minibatch_rows(k_perm, windows, window, updates * c.batch_size, c.pairs_per_window)
        batch = jax.tree.map(lambda x: x[perm].reshape((updates, c.batch_size) + x.shape[1:]), batch)

        def body(ts, xs):
            minibatch, k = xs
            return update(ts, minibatch, k), None

        keys = jax.random.split(k_upd, updates)
        if scheduled:
            ts, last = scheduled_updates(ts.replace(key=key), batch, keys)
        else:
            # two updates per loop iteration: a GPU pays a loop-condition round trip per iteration
            ts, _ = jax.lax.scan(body, ts.replace(key=key), (batch, keys), unroll=2)
            last = updates - 1
        # the losses are logged once per epoch, on its last minibatch after the updates: computing them at
        # every step would cost a GPU more small kernels than the step's own matmuls
        _, metrics = losses((ts.nets, ts.log_temperature, ts.log_alpha), taken(batch, last), keys[last])
        return ts, {**metrics, "alpha": jnp.mean(jnp.exp(ts.log_alpha))}

    def scheduled_updates(ts: TrainState, batch: dict, keys: jax.Array) -> tuple[TrainState, jax.Array]:
        """The epoch's first `early_updates` share of minibatch updates before `early_until` env steps, all of
        them after; returns the state and the last minibatch's index. The count is a loop bound, not a mask:
        under the seeds' vmap every seed holds the same env steps, so the loop stops for all at once and the
        updates left out are never computed. The second update of each pair is a cond, which under vmap computes
        it whatever the count says: an odd count costs one update it does not keep."""
        active = jnp.where(ts.env_steps < early_until, early_count, updates)

        def pair(carry):
            ts, i = carry
            ts = update(ts, taken(batch, i), keys[i])
            second = jnp.minimum(i + 1, updates - 1)  # two per loop iteration, as the scan's unroll
            ts = jax.lax.cond(i + 1 < active, lambda t: update(t, taken(batch, second), keys[second]),
                              lambda t: t, ts)
            return ts, i + 2

        ts, _ = jax.lax.while_loop(lambda carry: carry[1] < active, pair, (ts, jnp.zeros((), jnp.int32)))
        return ts, active - 1

    def prefill(ts: TrainState) -> TrainState:
        return jax.lax.fori_loop(0, prefill_iters, lambda _, ts: collect(ts)[0], ts)

    def chunk(ts: TrainState) -> tuple[TrainState, dict]:
        def body(ts, _):
            ts, stats = collect(ts)
            ts, metrics = update_epoch(ts)
            return ts, {**stats, **metrics}

        ts, metrics = jax.lax.scan(body, ts, None, length=iters_per_eval)
        return ts, jax.tree.map(jnp.mean, metrics)

    def act(ts: TrainState, obs: jax.Array, key: jax.Array | None = None) -> jax.Array:
        return policy(nets.member(ts.nets, 0), obs, key)

    def export(ts: TrainState) -> Policy:
        """The actor alone: each controller reads its own entries of the state, then the goal."""
        actor = nets.alone(ts.nets, 0)
        per_controller = team.size > 1 and not shared
        if team.size == 1 and not shared:
            actor = jax.tree.map(lambda w: w[0], actor)  # the controller axis of one
        goal = tuple(range(state_dim, state_dim + goal_size))
        observes = tuple(tuple(o) + goal for o in team.observed.tolist())
        return Policy(actor, observes, tuple(map(tuple, team.actions.tolist())), tuple(c.hidden), 2 * own,
                      layer_norm=c.layer_norm, skip_every=c.skip_every, per_controller=per_controller,
                      matmul=c.matmul, observation_size=env.observation_size)

    return Trainer(config, env, init, prefill, chunk, act, {"env_state": 0, "buffer": 1}, export)
