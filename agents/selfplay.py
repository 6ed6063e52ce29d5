"""Self-play PPO on a team field (fieldgen/env/team_contract.py): one network plays both sides of a match.

Every agent observes and acts in its own side's frame, so the one policy drives home and away alike. In each
environment the policy plays either itself (`self_play_share` of the episodes: every agent's steps are its
own, to learn from), a random policy (`random_share`: uniform actions, the opponent a league's specialised
selves stop scoring against) or an earlier snapshot of itself, on a side drawn at random (against another, only
its own side's steps are learned from). A snapshot is taken at every evaluation and plays as `opponent_actions`
says (its actions drawn, or its mean actions); the opponent pool is the newest `pool_size` of them, drawn by
recency (weight `recency_decay ** age`, the newest age 0) or by win rate (prioritized fictitious
self-play: weight (1 - w) ** `win_rate_power`, w the learner's score against that snapshot in training so far,
wins 1 and draws 1/2, with one win and one loss assumed before any game), as `pool_sampling` says. An episode
that ends draws its environment's next opponent and side; a new snapshot redraws them all.

With `exploiter_share` above 0, that share of the episodes is played against an exploiter (a league's main
exploiter): a second network of the same shape, with its own optimiser, that learns only from its own side of
those matches, so that it seeks whatever the policy loses to, where a policy against itself gains on one side
what it gives up on the other. Its observations are normalised with the policy's statistics; it is never a
snapshot nor judged; the policy's score against it in training (wins 1, draws 1/2) is the metric
`exploiter_score`, over the `exploiter_games` that ended in the chunk. With `exploiter_reset_every` N, at every
Nth evaluation it becomes a copy of the policy with a fresh optimiser (a league's exploiter reset, forked from the
policy rather than from nothing).

The learner is PPO as agents/ppo/train.py trains it (the same clipped surrogate, GAE, squashed Gaussian,
observation normaliser and settings under `ppo.`), each agent a stream of its own: its side's reward (the
match's dense reward, zero-sum in its goal and ball-progress terms, or with `reward: sparse` its goals for
less its goals against), the shared `done`, its own value from its own observation. A snapshot keeps the
policy with its normaliser's statistics of that moment.

At each evaluation the new snapshot (the current policy) plays `eval_envs` episodes against a random policy
(uniform actions) and against each of a fixed set of earlier snapshots (`league_opponents`, evenly spaced from
the first, the untrained policy, to the one before: `fixed_opponents`), on the home side in half the episodes
and the away side in the other half; an episode is a win or a loss by its goal, a draw where time runs out.
Those counts rate every snapshot (agents/elo.py, K = `elo_k`); fieldgen/run/selfplay.py keeps the run.
"""

from __future__ import annotations

import dataclasses
from typing import Annotated, Callable, Literal

import flax.struct
import jax
import jax.numpy as jnp
import numpy as np
import optax
from pydantic import Field

from ..env.contract import OVERFLOW, merged_overflow
from .actor import Policy
from .choices import EVAL_ACTIONS
from .config import ConfigError, Count, Float, Int, Rate, Share, Unknown
from .loop import batched_with, first_states
from .ppo.config import PPOConfig
from .ppo.train import Normalizer, advantages, exported_policy, gaussian, networks, optimizer, squashed_entropy

POOL_SAMPLINGS = ("recency", "win_rate")
PoolSampling = Annotated[Literal[POOL_SAMPLINGS], Unknown(
    "unknown ppo.pool_sampling '{}'; choose recency (newer snapshots more often) or win_rate (the snapshots the "
    "policy beats least, more often)")]
OpponentActions = Annotated[Literal[EVAL_ACTIONS], Unknown(
    "unknown ppo.opponent_actions '{}'; choose sampled (drawn from the snapshot's policy) or mean (its mean "
    "action, as the evaluations play it)")]
RESULTS = ("win", "draw", "loss")
# an environment's opponent that is no snapshot: the policy itself, a random policy, the exploiter
ITSELF, RANDOM, EXPLOITER = -1, -2, -3


class SelfPlayConfig(PPOConfig):
    """PPO's settings (under `ppo.`, as a single-agent PPO run takes them) and self-play's own."""

    pool_size: Count = 8  # the newest snapshots the policy trains against
    pool_sampling: PoolSampling = "recency"
    recency_decay: Annotated[Float, Field(gt=0, le=1)] = 0.7  # pool_sampling recency: weight decay ** age
    win_rate_power: Rate = 2.0  # pool_sampling win_rate: weight (1 - win rate) ** power
    self_play_share: Share = 0.5  # episodes the policy plays against itself rather than a snapshot
    random_share: Share = 0.0  # episodes it plays against a random policy (uniform actions)
    exploiter_share: Share = 0.0  # episodes it plays against the exploiter, which learns only from those
    # every this many evaluations the exploiter starts again from a copy of the policy (0: never), so that it
    # seeks what the policy of now loses to rather than holding an old rival
    exploiter_reset_every: Annotated[Int, Field(ge=0)] = 0
    # how snapshots act in training matches: drawn from their policies, or their mean actions, as the evaluations
    # play them (the opponent the policy is judged against)
    opponent_actions: OpponentActions = "sampled"
    league_opponents: Count = 4  # earlier snapshots each snapshot plays at its evaluation
    elo_k: Rate = 32.0  # the Elo K factor

    def validate_env(self, env, devices: int = 1, seeds: int = 1) -> None:
        super().validate_env(env, devices, seeds)
        if self.eval_envs % 2:
            raise ConfigError(f"ppo.eval_envs {self.eval_envs} is odd: a snapshot plays half its evaluation "
                              "episodes on each side; give an even number")
        if self.self_play_share + self.random_share + self.exploiter_share > 1:
            raise ConfigError(f"ppo.self_play_share {self.self_play_share:g}, ppo.random_share "
                              f"{self.random_share:g} and ppo.exploiter_share {self.exploiter_share:g} add up to "
                              "more than every episode; keep their sum at most 1")


@flax.struct.dataclass
class SelfPlayState:
    params: dict  # policy, value (and log_std with spread global)
    opt: optax.OptState
    normalizer: Normalizer
    env_state: object  # [envs] matches
    key: jax.Array
    env_steps: jax.Array
    league: dict  # every snapshot, stacked over [num_evals + 1]: policy (params but the value), obs_mean, obs_std
    taken: jax.Array  # [num_evals + 1]: which snapshots exist
    newest: jax.Array  # the newest snapshot's index (its evaluation's)
    wins: jax.Array  # [num_evals + 1]: the learner's score in training against each snapshot (win 1, draw 1/2)
    games: jax.Array  # [num_evals + 1]: training episodes the learner played against each snapshot
    opponent: jax.Array  # [envs]: the snapshot each environment's episode plays, or ITSELF, RANDOM, EXPLOITER
    learner_side: jax.Array  # [envs]: the side the learner plays against a snapshot (0 home, 1 away)
    exploiter: dict | None = None  # the exploiter's params (policy, value), None without one
    exploiter_opt: optax.OptState | None = None


def fixed_opponents(index: int, count: int) -> list[int]:
    """The earlier snapshots that snapshot `index` plays at its evaluation: up to `count`, evenly spaced from the
    first (0, the untrained policy) to the one before it, the same for every run."""
    if index < 1:
        return []
    return sorted({int(round(x)) for x in np.linspace(0, index - 1, min(count, index))})


def pool_actions(act: Callable, pool: dict, obs: jax.Array, key: jax.Array, how: str) -> jax.Array:
    """Every pool snapshot's actions in every match, [pool_size, envs, agents, n]: drawn from its policy, or (`how`
    "mean") its mean action, as the evaluations play it; then the policy trains against the opponent it is judged
    against, whose pushes do not vary from one match to the next."""
    if how == "mean":
        return jax.vmap(act, in_axes=(0, None))(pool, obs)
    keys = jax.random.split(key, jax.tree.leaves(pool)[0].shape[0])
    return jax.vmap(act, in_axes=(0, None, 0))(pool, obs, keys)


def pool_probabilities(config: SelfPlayConfig, newest, taken, wins, games) -> tuple[jax.Array, jax.Array]:
    """(ids, probabilities), each [pool_size]: the pool's snapshots, newest first (an id below 0 is no snapshot),
    and the chance each is drawn as an opponent when one is; all zero while there is none."""
    ids = newest - jnp.arange(config.pool_size)
    safe = jnp.maximum(ids, 0)
    valid = (ids >= 0) & taken[safe]
    if config.pool_sampling == "recency":
        weight = config.recency_decay ** jnp.arange(config.pool_size, dtype=jnp.float32)
    else:
        rate = (wins[safe] + 1.0) / (games[safe] + 2.0)
        weight = (1.0 - rate) ** config.win_rate_power + 1e-6
    weight = jnp.where(valid, weight, 0.0)
    return ids, weight / jnp.maximum(weight.sum(), 1e-12)


def draw_opponents(config: SelfPlayConfig, key, count: int, newest, taken, wins, games):
    """([count] opponents, [count] learner sides): each environment's next opponent, ITSELF with chance
    self_play_share, RANDOM (a random policy) with chance random_share, EXPLOITER with chance exploiter_share,
    else a snapshot drawn from the pool (the policy itself while no snapshot exists)."""
    k_pick, k_self, k_side = jax.random.split(key, 3)
    ids, probs = pool_probabilities(config, newest, taken, wins, games)
    picked = ids[jax.random.categorical(k_pick, jnp.log(jnp.maximum(probs, 1e-30)), shape=(count,))]
    u = jax.random.uniform(k_self, (count,))
    others = config.self_play_share + config.random_share
    itself = (u < config.self_play_share) | ((u >= others + config.exploiter_share) & (probs.sum() <= 0))
    random = ~itself & (u < others)
    exploiter = ~itself & ~random & (u < others + config.exploiter_share)
    opponent = jnp.where(itself, ITSELF, jnp.where(random, RANDOM, jnp.where(exploiter, EXPLOITER, picked)))
    return opponent.astype(jnp.int32), jax.random.randint(k_side, (count,), 0, 2, jnp.int32)


@dataclasses.dataclass(frozen=True)
class SelfPlay:
    """Self-play as pure functions of a SelfPlayState (jit them, vmapped over seeds where several train at once;
    fieldgen/run/selfplay.py runs them)."""

    config: SelfPlayConfig
    env: object
    init: Callable  # key -> the state before training, snapshot 0 not yet taken
    chunk: Callable  # state -> (state, mean training metrics): the iterations between two evaluations
    judge: Callable  # (state, index, opponents [league_opponents], key) -> (state with snapshot index, results)
    act: Callable  # (actor, obs [..., agents, n], key=None) -> actions: an actor's, mean or sampled
    current: Callable  # state -> the learner as an actor (policy, obs_mean, obs_std)
    snapshot: Callable  # (state, index) -> an actor: snapshot index
    # (actor a, actor b or None for random, key) -> ([3] a's wins, draws, losses over eval_envs, the physics'
    # overflow flags of its matches merged, or None on physics without them)
    match: Callable
    controls: Callable  # (opponent [envs], learner_side [envs]) -> [envs, agents]: the agents the learner drives
    film: Callable  # (actor a, actor b or None, key) -> one match, a at home, filmed: ((qpos, mocap_pos), done) a step
    export: Callable  # state -> the learner as one agent's Policy (agents/actor.py), either side's


def make_selfplay(config: SelfPlayConfig, env) -> SelfPlay:
    c = config
    iters_per_eval = c.iterations_per_eval
    if iters_per_eval < 1:
        raise ValueError(f"total_steps {c.total_steps:,} leaves no iteration between evaluations")
    agents, n_obs, n_act = len(env.agent_names), env.observation_size, env.action_size
    sides = jnp.asarray(env.agent_sides, jnp.int32)
    snapshots = c.num_evals + 1
    policy_net, value_net = networks(c, n_act)
    tx = optimizer(c)
    batch = c.num_envs * c.unroll_length * agents
    minibatch = batch // c.num_minibatches
    sampled_eval = c.eval_actions == "sampled"
    exploits = c.exploiter_share > 0

    def distribution(params, obs):
        return gaussian(policy_net, c.spread, params, obs)

    def log_prob(log_std, noise):  # as PPO's: the Gaussian's, before tanh
        return jnp.sum(-0.5 * noise**2 - log_std - 0.5 * jnp.log(2 * jnp.pi), -1)

    def normalized(obs, mean, std):
        return jnp.clip((obs - mean) / std, -Normalizer.CLIP, Normalizer.CLIP) if c.normalize_observations else obs

    def act(actor, obs, key=None):
        """The actor's squashed mean action, or with `key` one drawn from it."""
        mean, log_std = distribution(actor["policy"], normalized(obs, actor["obs_mean"], actor["obs_std"]))
        if key is not None:
            mean = mean + jnp.exp(log_std) * jax.random.normal(key, mean.shape)
        return jnp.tanh(mean)

    def current(ts: SelfPlayState) -> dict:
        return {"policy": {k: v for k, v in ts.params.items() if k != "value"},
                "obs_mean": ts.normalizer.mean, "obs_std": ts.normalizer.std}

    def snapshot(ts: SelfPlayState, index) -> dict:
        return jax.tree.map(lambda x: x[index], ts.league)

    def controls(opponent, learner_side):
        """[envs, agents]: the agents the learner drives (all of them against itself)."""
        return (opponent[:, None] == ITSELF) | (sides[None, :] == learner_side[:, None])

    def init(key) -> SelfPlayState:
        k_pi, k_v, k_env, key = jax.random.split(key, 4)
        obs = jnp.zeros((1, n_obs))

        def fresh(k_pi, k_v):
            params = {"policy": policy_net.init(k_pi, obs), "value": value_net.init(k_v, obs)}
            if c.spread == "global":
                params["log_std"] = jnp.full(n_act, -0.5)
            return params

        params = fresh(k_pi, k_v)
        normalizer = Normalizer(jnp.zeros(()), jnp.zeros(n_obs), jnp.zeros(n_obs))
        env_state = first_states(env, c, k_env)
        ts = SelfPlayState(params, tx.init(params), normalizer, env_state, key, jnp.zeros((), jnp.int32),
                           None, jnp.zeros(snapshots, bool), jnp.zeros((), jnp.int32), jnp.zeros(snapshots),
                           jnp.zeros(snapshots), jnp.full(c.num_envs, ITSELF, jnp.int32),
                           jnp.zeros(c.num_envs, jnp.int32))
        league = jax.tree.map(lambda x: jnp.zeros((snapshots,) + x.shape, x.dtype), current(ts))
        if exploits:
            exploiter = fresh(jax.random.fold_in(k_pi, 1), jax.random.fold_in(k_v, 1))
            ts = ts.replace(exploiter=exploiter, exploiter_opt=tx.init(exploiter))
        return ts.replace(league=league)

    def drawn(params, obs, key, learns):
        """One network's step in every match: its actions drawn before tanh (`raw`), their log-probabilities, its
        values, and the agents it drives (`learns`, the steps it learns from)."""
        mean, log_std = distribution(params, obs)
        noise = jax.random.normal(key, mean.shape)
        return {"raw": mean + jnp.exp(log_std) * noise, "log_prob": log_prob(log_std, noise),
                "value": value_net.apply(params["value"], obs)[..., 0], "learns": learns.astype(jnp.float32)}

    def rollout(ts: SelfPlayState):
        ids = jnp.maximum(ts.newest - jnp.arange(c.pool_size), 0)
        pool = jax.tree.map(lambda x: x[ids], ts.league)  # [pool_size, ...], newest first
        envs = jnp.arange(c.num_envs)

        def step(carry, key):
            env_state, opponent, learner_side, wins, games = carry
            # random opponents' actions fold into k_opp, so runs without them draw as they did before
            k_act, k_opp, k_draw = jax.random.split(key, 3)
            obs = ts.normalizer(env_state.obs, c.normalize_observations)  # [envs, agents, n]
            learns = controls(opponent, learner_side)
            mine = drawn(ts.params, obs, k_act, learns)
            theirs = pool_actions(act, pool, env_state.obs, k_opp, c.opponent_actions)
            slot = jnp.clip(ts.newest - opponent, 0, c.pool_size - 1)
            theirs = theirs[slot, envs]
            if c.random_share > 0:  # drawn only where a random policy can be an opponent
                uniform = jax.random.uniform(jax.random.fold_in(k_opp, c.pool_size), mine["raw"].shape, minval=-1.0,
                                             maxval=1.0)
                theirs = jnp.where((opponent == RANDOM)[:, None, None], uniform, theirs)
            actions = jnp.where(learns[..., None], jnp.tanh(mine["raw"]), theirs)
            if exploits:
                exploiter = drawn(ts.exploiter, obs, jax.random.fold_in(k_act, 1),
                                  (opponent == EXPLOITER)[:, None] & ~learns)
                actions = jnp.where(exploiter["learns"][..., None] > 0, jnp.tanh(exploiter["raw"]), actions)
            nxt = jax.vmap(env.step)(env_state, actions)
            success = nxt.metrics["success"]  # [envs, 2]
            side_reward = nxt.reward if c.reward == "dense" else success - success[:, ::-1]
            # the learner's training games against snapshots, each scored once, when it ends
            score = 0.5 + 0.5 * (success[envs, learner_side] - success[envs, 1 - learner_side])
            counted = nxt.done * (opponent >= 0)
            at = jnp.maximum(opponent, 0)
            wins = wins.at[at].add(counted * score)
            games = games.at[at].add(counted)
            data = {"obs": env_state.obs, **mine, "reward": side_reward[:, sides], "done": nxt.done,
                    "goals": jnp.sum(success, -1)}
            if exploits:  # the exploiter's own stream, and the policy's games against it
                played = nxt.done * (opponent == EXPLOITER)
                data |= {"exploiter": exploiter, "exploiter_games": jnp.sum(played),
                         "exploiter_points": jnp.sum(played * score)}
            fresh_opponent, fresh_side = draw_opponents(c, k_draw, c.num_envs, ts.newest, ts.taken, wins, games)
            ended = nxt.done > 0
            opponent = jnp.where(ended, fresh_opponent, opponent)
            learner_side = jnp.where(ended, fresh_side, learner_side)
            return (nxt, opponent, learner_side, wins, games), data

        key, k = jax.random.split(ts.key)
        carry = (ts.env_state, ts.opponent, ts.learner_side, ts.wins, ts.games)
        (env_state, opponent, learner_side, wins, games), data = jax.lax.scan(
            step, carry, jax.random.split(k, c.unroll_length))
        last_obs = ts.normalizer(env_state.obs, c.normalize_observations)
        last = {"policy": value_net.apply(ts.params["value"], last_obs)[..., 0]}
        if exploits:
            last["exploiter"] = value_net.apply(ts.exploiter["value"], last_obs)[..., 0]
        ts = ts.replace(env_state=env_state, opponent=opponent, learner_side=learner_side, wins=wins, games=games,
                        key=key)
        return ts, data, last

    def loss(params, normalizer, mb):
        """PPO's loss over the learner's own steps (`learns`); an opponent's steps weigh nothing."""
        w = mb["learns"]
        total = jnp.maximum(w.sum(), 1.0)

        def average(x):
            return jnp.sum(w * x) / total

        obs = normalizer(mb["obs"], c.normalize_observations)
        mean, log_std = distribution(params, obs)
        noise = (mb["raw"] - mean) / jnp.exp(log_std)
        ratio = jnp.exp(log_prob(log_std, noise) - mb["log_prob"])
        centre = average(mb["adv"])
        adv = (mb["adv"] - centre) / (jnp.sqrt(average((mb["adv"] - centre) ** 2)) + 1e-8)
        surrogate = -average(jnp.minimum(ratio * adv, jnp.clip(ratio, 1 - c.clip, 1 + c.clip) * adv))
        value_loss = average((value_net.apply(params["value"], obs)[:, 0] - mb["target"]) ** 2)
        entropy = average(squashed_entropy(mean, log_std, noise))
        objective = surrogate + c.value_coef * value_loss - c.entropy_coef * entropy
        return objective, {"policy_loss": surrogate, "value_loss": value_loss, "entropy": entropy}

    def flattened(data, stream, last):
        """One network's steps as PPO's batch: its own actions, log-probabilities, values and `learns` from
        `stream`, the match's observations, rewards and ends from `data`, its advantages and value targets."""
        streams = {"reward": data["reward"], "value": stream["value"],
                   "done": jnp.broadcast_to(data["done"][..., None], data["reward"].shape)}  # per agent
        adv, target = advantages(streams, last, c.discount, c.gae_lambda)
        return jax.tree.map(lambda x: x.reshape((batch,) + x.shape[3:]),
                            {"obs": data["obs"], "raw": stream["raw"], "log_prob": stream["log_prob"], "adv": adv,
                             "target": target, "learns": stream["learns"]})

    def update(params, opt, normalizer, flat, key):
        """PPO's epochs of minibatch steps on one network: (params, opt), the loss terms of every step."""
        def epoch(carry, key):
            def sgd(carry, mb):
                params, opt = carry
                (_, metrics), grads = jax.value_and_grad(loss, has_aux=True)(params, normalizer, mb)
                updates, opt = tx.update(grads, opt)
                return (optax.apply_updates(params, updates), opt), metrics

            perm = jax.random.permutation(key, batch)
            mbs = jax.tree.map(lambda x: x[perm].reshape((c.num_minibatches, minibatch) + x.shape[1:]), flat)
            return jax.lax.scan(sgd, carry, mbs)

        return jax.lax.scan(epoch, (params, opt), jax.random.split(key, c.update_epochs))

    def iteration(ts: SelfPlayState):
        ts, data, last = rollout(ts)
        flat = flattened(data, data, last["policy"])
        normalizer = ts.normalizer.update(flat["obs"])
        key, k = jax.random.split(ts.key)
        (params, opt), metrics = update(ts.params, ts.opt, normalizer, flat, k)
        learner = data["learns"]
        stats = {"train_reward": jnp.sum(learner * data["reward"]) / jnp.maximum(learner.sum(), 1.0),
                 "train_goals": jnp.mean(data["goals"]), "self_play_share": jnp.mean(ts.opponent == ITSELF)}
        if exploits:
            flat = flattened(data, data["exploiter"], last["exploiter"])
            (exploiter, exploiter_opt), _ = update(ts.exploiter, ts.exploiter_opt, normalizer, flat,
                                                   jax.random.fold_in(k, 1))
            ts = ts.replace(exploiter=exploiter, exploiter_opt=exploiter_opt)
            stats |= {"exploiter_games": jnp.sum(data["exploiter_games"]),
                      "exploiter_points": jnp.sum(data["exploiter_points"])}
        ts = ts.replace(params=params, opt=opt, normalizer=normalizer, key=key,
                        env_steps=ts.env_steps + c.num_envs * c.unroll_length)
        return ts, {**jax.tree.map(jnp.mean, metrics), **stats}

    def chunk(ts: SelfPlayState):
        ts, metrics = jax.lax.scan(lambda t, _: iteration(t), ts, None, length=iters_per_eval)
        if exploits:  # the policy's score over every game against the exploiter that ended in the chunk
            games, points = jnp.sum(metrics.pop("exploiter_games")), jnp.sum(metrics.pop("exploiter_points"))
            metrics["exploiter_score"] = points / jnp.maximum(games, 1.0)  # 0 where none ended
            metrics["exploiter_games"] = games
        return ts, jax.tree.map(jnp.mean, metrics)

    def match(a, b, key):
        """([3]: a's wins, draws and losses over eval_envs episodes against b (None: a random policy), a on the
        home side in the even environments and the away side in the odd; the physics' overflow flags of those
        matches merged, None where the physics has none)."""
        n = c.eval_envs
        k_reset, k_play = jax.random.split(key)
        env_state = jax.vmap(env.reset)(jax.random.split(k_reset, n))
        a_side = jnp.arange(n, dtype=jnp.int32) % 2
        mine = sides[None, :] == a_side[:, None]
        rows = jnp.arange(n)

        def step(carry, key):
            env_state, alive, outcome = carry
            k_a, k_b = jax.random.split(key)
            ours = act(a, env_state.obs, k_a if sampled_eval else None)
            if b is None:
                theirs = jax.random.uniform(k_b, ours.shape, minval=-1.0, maxval=1.0)
            else:
                theirs = act(b, env_state.obs, k_b if sampled_eval else None)
            nxt = jax.vmap(env.step)(env_state, jnp.where(mine[..., None], ours, theirs))
            success = nxt.metrics["success"]
            result = jnp.where(success[rows, a_side] > 0, 1, jnp.where(success[rows, 1 - a_side] > 0, -1, 0))
            outcome = outcome + alive * result
            return (nxt, alive * (1 - nxt.done.astype(jnp.int32)), outcome), None

        start = batched_with(key, (env_state, jnp.ones(n, jnp.int32), jnp.zeros(n, jnp.int32)))
        (last, _, outcome), _ = jax.lax.scan(step, start, jax.random.split(k_play, env.episode_length))
        wins, losses = jnp.sum(outcome > 0), jnp.sum(outcome < 0)
        flags = merged_overflow(last.info[OVERFLOW]) if OVERFLOW in last.info else None
        return jnp.stack([wins, n - wins - losses, losses]), flags

    def film(a, b, key):
        """One match, a on the home side against b (None: a random policy) on the away side, acting as in the
        evaluations: the state before each step ((qpos, mocap_pos) of fieldgen.run.videos.EpisodeRecorder.film)
        and that step's done, [episode_length, ...]."""
        k_reset, k_play = jax.random.split(key)
        env_state = jax.vmap(env.reset)(k_reset[None])
        home = (sides == 0)[None, :, None]

        def step(env_state, key):
            k_a, k_b = jax.random.split(key)
            ours = act(a, env_state.obs, k_a if sampled_eval else None)
            theirs = jax.random.uniform(k_b, ours.shape, minval=-1.0, maxval=1.0) if b is None else \
                act(b, env_state.obs, k_b if sampled_eval else None)
            nxt = jax.vmap(env.step)(env_state, jnp.where(home, ours, theirs))
            frame = (env_state.pipeline_state.qpos[0], env_state.pipeline_state.mocap_pos[0])
            return nxt, (frame, nxt.done[0])

        _, filmed = jax.lax.scan(step, env_state, jax.random.split(k_play, env.episode_length))
        return filmed

    def forked(ts: SelfPlayState, now) -> SelfPlayState:
        """The state with its exploiter a copy of the policy and a fresh optimiser where `now`, else as it was."""
        def pick(new, old):
            return jax.tree.map(lambda a, b: jnp.where(now, a, b), new, old)

        return ts.replace(exploiter=pick(ts.params, ts.exploiter),
                          exploiter_opt=pick(tx.init(ts.params), ts.exploiter_opt))

    def judge(ts: SelfPlayState, index, opponents, key):
        """The state with snapshot `index` taken (the current policy; every environment's opponent drawn anew)
        and its results: {"random": [3], "earlier": [league_opponents, 3]} (rows of an opponent id below 0
        are zeros: no match), and on physics of fixed capacities OVERFLOW, the flags of every match merged."""
        league = jax.tree.map(lambda all_, one: all_.at[index].set(one), ts.league, current(ts))
        taken = ts.taken.at[index].set(True)
        wins, games = ts.wins.at[index].set(0.0), ts.games.at[index].set(0.0)
        key_draw, key_next = jax.random.split(ts.key)
        opponent, side = draw_opponents(c, key_draw, c.num_envs, index, taken, wins, games)
        ts = ts.replace(league=league, taken=taken, newest=jnp.asarray(index, jnp.int32), wins=wins, games=games,
                        opponent=opponent, learner_side=side, key=key_next)
        if exploits and c.exploiter_reset_every:
            ts = forked(ts, (index > 0) & (index % c.exploiter_reset_every == 0))
        me = current(ts)
        vs_random, flags = match(me, None, jax.random.fold_in(key, 0))
        nothing = jax.tree.map(lambda x: jnp.zeros(x.shape, x.dtype), (vs_random, flags))  # no match played

        def against(item):
            j, k = item
            return jax.lax.cond(j >= 0, lambda: match(me, snapshot(ts, jnp.maximum(j, 0)), k), lambda: nothing)

        keys = jax.vmap(lambda i: jax.random.fold_in(key, i))(jnp.arange(1, c.league_opponents + 1))
        earlier, earlier_flags = jax.lax.map(against, (opponents, keys))
        results = {"random": vs_random, "earlier": earlier}
        if flags is not None:
            results[OVERFLOW] = flags | merged_overflow(earlier_flags)
        return ts, results

    def export(ts: SelfPlayState) -> Policy:
        """The learner as one agent's policy: it reads an agent's observation in its own side's frame."""
        return exported_policy(c, env, ts.params["policy"], ts.normalizer)

    return SelfPlay(config, env, init, chunk, judge, act, current, snapshot, match, controls, film, export)
