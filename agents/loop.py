"""What every trainer shares: its shape, evaluating a policy, and running several seeds at
once (vmap) over every local device (jax.sharding) between evaluations.

A trainer is the pure functions of `Trainer`. `pure_train(trainer)` strings them
into one `train(key)` that can be jitted and vmapped over seeds; `run` does the same
work one evaluation at a time, so a caller can checkpoint, log and resume between them.
"""

from __future__ import annotations

import dataclasses
import functools
import itertools
import time
from typing import Callable, Sequence

import flax.struct
import jax
import jax.numpy as jnp
import numpy as np

from ..curriculum.contract import OneStage, Schedule, adapt, start_sampling, with_episode_sampling
from ..env.contract import (DIVERGED, OVERFLOW, Environment, merged_overflow, shared_by_batch, torso_entries,
                            up_axis_z)
from .config import RunConfig
from .programs import Programs, computed
from .sharding import from_host, meet, to_host

EVAL_STREAM = 0x5EED  # evaluation keys: fold_in(fold_in(seed key, EVAL_STREAM), evaluation index)
_meetings = itertools.count()  # each `meet` of this process's runs under a name of its own


@dataclasses.dataclass(frozen=True)
class Trainer:
    """One run of one algorithm on one environment, as pure functions of a training state."""

    config: RunConfig
    env: Environment
    init: Callable  # key -> state before any env step: fresh episodes, an empty replay buffer
    prefill: Callable  # state -> state ready for a chunk: its replay buffer filled by its own policy (or as it is)
    chunk: Callable  # state -> (state, mean training metrics): the iterations between two evaluations
    # (state, obs [batch, observation_size], key=None) -> actions [batch, action_size]: deterministic, or with a
    # key the actions the policy samples in training
    act: Callable
    env_axes: dict  # state field -> the axis of its leaves that runs over environments (sharded)
    export: Callable  # state -> the deterministic actor alone (agents.actor.Policy): what `act` computes
    # jitted programs by seed count, kept here so that later runs of this trainer in the same
    # process (a resume, an evaluation) reuse them instead of compiling again
    compiled: dict = dataclasses.field(default_factory=dict, init=False, compare=False, repr=False)

    def start(self, key: jax.Array):
        """A new run's state, ready for its first chunk."""
        return self.prefill(self.init(key))

    def learned(self, state):
        """What `state` has learned, without what belongs to its environments (`env_axes`: episodes, the
        replay buffer): all a run needs to go on, in megabytes where the whole state takes gigabytes."""
        return state.replace(**{name: None for name in self.env_axes})

    def refill(self, learned):
        """A `learned` state back in training: fresh episodes, and a replay buffer filled anew by its own
        policy (the env steps this takes count as training steps)."""
        k_env, key = jax.random.split(learned.key)
        fresh = self.init(k_env)
        return self.prefill(learned.replace(key=key, **{name: getattr(fresh, name) for name in self.env_axes}))

    def holds_environments(self, state) -> bool:
        """Whether `state` is whole, rather than what `learned` keeps."""
        return all(getattr(state, name) is not None for name in self.env_axes)


def evaluate_policy(env, act: Callable, key: jax.Array, n_envs: int, film: Callable | None = None,
                    sampled: bool = False) -> tuple[dict, object]:
    """One episode per environment with `act(obs)`, counted up to its first `done`. Returns (metrics, film).
    With `sampled`, `act(obs, key)` with a fresh key at every step: the policy as it acts in training, where
    the mean action alone may do less (or more) than the policy's own draws.

    success_any: share of episodes with a successful step; time_at_goal: successful steps
    per episode; closest_distance: the mean over episodes of the smallest distance between the
    target and what the success judges (the goal's `env.success_goal_entries` and the state entries
    `env.goal_indices` compares them with), over
    the states observed before the episode ended, a sign of progress long before the first success;
    farthest_from_start: the mean over episodes of the largest distance what the success judges moved from
    where the episode began (on a ball field, how far the agent pushed the ball: zero until it first touches
    it, where hindsight goals about the ball begin to differ from its kick-off);
    episode_length: steps before the episode ended, short where the agent falls (leaves its
    healthy band) early; episode_return; and `term_<name>`: each reward term's mean per live step;
    on a field whose agent has a torso, turned_over: the share of steps with its up axis below the horizontal
    (an ant's torso, which touches no floor under the default contacts, then sinks through it).
    An environment of several variants (`env.variant_count > 1`) is evaluated on each in turn,
    and also reports each variant's own under `variants` (a `VariantResults`).

    With `film` (a batch of environment states -> arrays with a leading environment axis), also
    one episode as a video needs it, for free: `film` of the state before each step and that
    step's `done`, both [episode_length, ...], of the first episode (of the last variant's first,
    with several); without, None.
    """
    keys = jax.random.split(key, n_envs)
    count = env.variant_count
    if count > 1:
        env_state = jax.vmap(env.reset_variant)(keys, jnp.arange(n_envs) % count)
    else:
        env_state = jax.vmap(env.reset)(keys)
    terms = [name for name in env_state.metrics if name != "success"]
    judged = np.asarray(env.success_goal_entries)
    state_entries, goal_entries = np.asarray(env.goal_indices)[judged], env.state_dim + judged

    def goal_distance(obs):
        return jnp.linalg.norm(obs[:, state_entries] - obs[:, goal_entries], axis=-1)

    def distance_from(start, obs):
        return jnp.linalg.norm(obs[:, state_entries] - start, axis=-1)

    filmed = count - 1  # 0 without variants; with them, the last (a mixed curriculum's hardest stage)
    torso = torso_entries(env.observation_names)

    def step(carry, act_key):
        env_state, alive, closest, start, farthest = carry
        nxt = jax.vmap(env.step)(env_state, act(env_state.obs) if act_key is None else act(env_state.obs, act_key))
        out = {"success": nxt.metrics["success"] * alive, "reward": nxt.reward * alive, "alive": alive,
               **{name: nxt.metrics[name] * alive for name in terms}}
        # under auto-reset the obs of an episode's last step is already the next episode's
        still = alive * (1.0 - nxt.done)
        if torso is not None:
            out["still"] = still
            out["turned_over"] = still * (up_axis_z(nxt.obs[:, torso].T) < 0.0)
        closest = jnp.where(still > 0, jnp.minimum(closest, goal_distance(nxt.obs)), closest)
        farthest = jnp.where(still > 0, jnp.maximum(farthest, distance_from(start, nxt.obs)), farthest)
        frame = None if film is None else (jax.tree.map(lambda x: x[filmed], film(env_state)), nxt.done[filmed])
        return (nxt, still, closest, start, farthest), (out, frame)

    start = batched_with(key, (env_state, jnp.ones(n_envs), goal_distance(env_state.obs),
                               env_state.obs[:, state_entries], jnp.zeros(n_envs)))
    act_keys = jax.random.split(jax.random.fold_in(key, 1), env.episode_length) if sampled else None
    (last, _, closest, _, farthest), (out, frames) = jax.lax.scan(step, start, act_keys, length=env.episode_length)
    live_steps = jnp.sum(out["alive"])
    succeeded = jnp.any(out["success"] > 0, axis=0)
    at_goal = jnp.sum(out["success"], axis=0)
    metrics = {"success_any": jnp.mean(succeeded), "time_at_goal": jnp.mean(at_goal),
               "closest_distance": jnp.mean(closest), "farthest_from_start": jnp.mean(farthest),
               "episode_length": live_steps / n_envs,
               "episode_return": jnp.mean(jnp.sum(out["reward"], axis=0)),
               **{f"term_{name}": jnp.sum(out[name]) / live_steps for name in terms}}
    if torso is not None:
        metrics["turned_over"] = jnp.sum(out["turned_over"]) / jnp.maximum(jnp.sum(out["still"]), 1.0)
    if OVERFLOW in last.info:  # the physics' overflow flags of any environment (stop_on_overflow reads them)
        metrics[OVERFLOW] = merged_overflow(last.info[OVERFLOW])
    if count > 1:
        share = jax.nn.one_hot(env_state.info["variant"], count)  # [envs, variants]
        share = share / jnp.sum(share, axis=0)
        metrics["variants"] = VariantResults(succeeded @ share, at_goal @ share, closest @ share, jnp.zeros(count))
    return metrics, frames


def first_states(env, config: RunConfig, key: jax.Array):
    """The training batch's first states, one environment each from `key`. With `config.stagger_starts` each
    environment's episode counter starts at a step drawn evenly from 0 to the episode's last: the first
    episodes end after 1 to episode_length steps (a share of them before the agent could succeed), every later
    one is whole, and the batch's episodes end spread over time instead of together at every multiple of the
    episode's length."""
    states = jax.vmap(env.reset)(jax.random.split(key, config.num_envs))
    if not config.stagger_starts:
        return states
    begun = jax.random.randint(jax.random.fold_in(key, 1), (config.num_envs,), 0, env.episode_length)
    return states.replace(info=dict(states.info, episode_step=begun.astype(states.info["episode_step"].dtype)))


def diverged_episodes(counted, seeds: int) -> dict:
    """{"diverged_episodes": [seeds]}: each seed's training episodes that its environments ended because the
    simulation blew up (`counted`, State.info[DIVERGED] of every environment, on the host) since they started
    (a run's start or resume from its checkpoint keeps them; a new stage starts them anew); {} where the
    environment does not count them."""
    if counted is None:
        return {}
    return {"diverged_episodes": np.asarray(counted).reshape(seeds, -1).sum(1)}


def stop_on_overflow(env, overflow) -> None:
    """Raise (Environment.check_physics) where `overflow`, the overflow flags of environments (info[OVERFLOW] of
    a batch, or an evaluation's metric), says one outgrew the physics' capacities; None: the environment runs on
    no such capacities."""
    if overflow is not None:
        env.check_physics(overflow)


def batched_with(key: jax.Array, tree):
    """`tree`, each array less a zero drawn from `key`: the same values, now varying wherever the key does.
    Under a vmap over seeds, a scan whose carry starts the same for every seed but differs after one step
    (episodes alive, an environment's counters) has its body batched again until the carry's batching
    settles, the whole environment step traced anew each time; carries tied to the seed's key settle at
    once. Typed PRNG keys are left as they are, and so is what a batch of environments shares (Warp's contact
    buffer, `shared_by_batch`), which is no seed's own."""
    zero = (jax.random.key_data(key) if jnp.issubdtype(key.dtype, jax.dtypes.prng_key) else key).ravel()[0] * 0

    def tie(path, x):
        x = jnp.asarray(x)
        if jnp.issubdtype(x.dtype, jax.dtypes.prng_key) or shared_by_batch(path):
            return x
        return x | (zero > 0) if x.dtype == jnp.bool_ else x - zero.astype(x.dtype)  # x - 0 is x, -0.0 too
    return jax.tree_util.tree_map_with_path(tie, tree)


@flax.struct.dataclass
class VariantResults:
    """An evaluation's results on each variant of a mixed environment, indexed by variant (the last is the
    field the run is judged on), and the sampling weight each variant gets next."""

    success_any: jax.Array
    time_at_goal: jax.Array
    closest_distance: jax.Array
    weight: jax.Array

    # with kick-off points: the new episodes' share by kick-off (fieldgen.curriculum.contract.KICKOFF_BINS)
    kickoff_share: jax.Array | None = None

    def per_seed(self, i: int) -> dict[str, list[float]]:
        """Seed i's results (of a batch vmapped over seeds), as a row of metrics.jsonl keeps them."""
        return {f.name: [float(x) for x in getattr(self, f.name)[i]] for f in dataclasses.fields(self)
                if getattr(self, f.name) is not None}


def evaluate(trainer: Trainer, state, key: jax.Array, film: Callable | None = None,
             sampled: bool | None = None) -> tuple[dict, object]:
    """Every algorithm is judged here, by the environment's own success metric (`evaluate_policy`): on its
    mean actions, or with `sampled` on the actions its policy draws as in training; None: as its config's
    `eval_actions` says."""
    if sampled is None:
        sampled = trainer.config.eval_actions == "sampled"
    return evaluate_policy(trainer.env, functools.partial(trainer.act, state), key, trainer.config.eval_envs, film,
                           sampled)


def adapted(trainer: Trainer, state, sampling: dict, variants: VariantResults,
            schedule: Schedule) -> tuple[object, dict, VariantResults]:
    """The state with its environments drawing their next episodes as `schedule` says after an evaluation, and
    the sampling carried beside it moved on (fieldgen.curriculum.contract.adapt), and the evaluation's results
    with each variant's weight recorded (and, with kick-off points, the weights' share by kick-off)."""
    env_state, sampling, weight, share = adapt(schedule, trainer.env, state.env_state, sampling,
                                               variants.success_any, state.key)
    return state.replace(env_state=env_state), sampling, variants.replace(weight=weight, kickoff_share=share)


def eval_key(seed_key: jax.Array, index) -> jax.Array:
    return jax.random.fold_in(jax.random.fold_in(seed_key, EVAL_STREAM), index)


def pure_train(trainer: Trainer, num_evals: int, schedule: Schedule = OneStage()) -> Callable:
    """train(key) -> (final state, metrics stacked over the num_evals evaluations); jit- and vmap-able."""

    def train(key):
        def interval(carried, index):
            state, sampling = carried
            state, metrics = trainer.chunk(state)
            metrics.update(evaluate(trainer, state, eval_key(key, index))[0])
            if "variants" in metrics:
                state, sampling, metrics["variants"] = adapted(trainer, state, sampling, metrics["variants"], schedule)
            return (state, sampling), metrics

        state = trainer.start(key)
        (state, _), metrics = jax.lax.scan(interval, (state, start_sampling(state.env_state)),
                                           jnp.arange(1, num_evals + 1))
        return state, metrics

    return train


def run(trainer: Trainer, seeds: Sequence[int], num_evals: int,
        progress: Callable[[int, list[dict]], None] = lambda index, rows: None,
        on_eval: Callable = lambda state, index: None, resume: tuple | None = None):
    """Train every seed at once (vmapped), evaluating untrained (index 0) and after each of num_evals chunks.

    With several local devices, seeds that fill them evenly are split among them (each device
    trains its own); otherwise the environments (and whatever else `trainer.env_axes` names)
    are sharded across them, and gradients of the losses, means over the sharded batch, are
    averaged across devices by the compiler (agents.sharding). `progress(index, rows)` gets
    one row per seed; `on_eval(state, index)` runs after every evaluation (checkpoints);
    `resume=(state, index)` continues after evaluation `index` exactly as if never stopped.
    Returns (state, rows).
    """
    staged_resume = None if resume is None else (*resume, 0)
    return run_staged([trainer], seeds, num_evals, OneStage(), progress,
                      lambda state, index, stage, episode, sampling: on_eval(state, index), staged_resume)


def drawing_as(state, sampling: dict, placement):
    """A refilled state (seeds stacked) whose environments draw their episodes as `sampling` says; in place."""
    put = jax.vmap(lambda s, kept: s.replace(env_state=with_episode_sampling(s.env_state, kept)))
    return jax.jit(put, donate_argnums=0, out_shardings=placement)(state, sampling)


def run_staged(trainers: Sequence[Trainer], seeds: Sequence[int], num_evals: int, schedule: Schedule,
               progress: Callable[[int, list[dict]], None] = lambda index, rows: None,
               on_eval: Callable = lambda state, index, stage, episode, sampling: None, resume: tuple | None = None,
               film: Callable | None = None, sampling: dict | None = None,
               stop: Callable[[float | None], bool] = lambda longest: False, clock: float | None = None):
    """`run` through a sequence of trainers (a curriculum's stages) whose environments share one observation
    layout, as `schedule` says.

    Training starts on stage 0; after each evaluation it goes on with `schedule.next_stage(history, stage,
    stages)` (every row so far), keeping everything it learned (networks, optimizers, replay buffer,
    normalizer) and starting fresh episodes of the next stage; an environment of several variants is
    re-weighted as the schedule says (`adapted`). With several stages every row also holds `stage` and
    `last_stage_success_any` (the same policy evaluated on the last stage), and a promoting row `promoted_to`.
    Beside the training state the loop carries its environments' sampling (fieldgen.curriculum.contract.
    start_sampling: the weights and level counts a curriculum draws episodes by), which each re-weighing moves on.
    `on_eval(state, index, stage, episode, sampling)` gets the stage the next chunk trains on, with `film` the
    first seed's episode filmed by the evaluation just done (`evaluate_policy`) with the stage it was filmed on,
    `(stage, film)`, else None, and the sampling (seeds stacked) that goes on with the state;
    `resume=(state, index, stage)` continues from there, its environments drawing as `sampling` says where given
    (else as the state's environments draw, their counts tallied since the last re-weighing); a state that is
    only what it learned (`Trainer.learned`) goes on with fresh episodes and a buffer filled anew, drawn as
    `sampling` says where given, the rows of its first evaluation holding `refilled_from` (the env steps it had
    learned from: where its episodes and buffer began anew). An evaluation is handed to `progress` and `on_eval`
    once the next chunk has started, on a thread of its own (its call may hold that thread until the chunk
    ends), so that the device trains while the host writes; in a run over several processes, once the chunk's
    call has returned, so that every process runs the chunk's collectives and then the gathering of the
    evaluation's state in one order. Before each chunk
    `stop(longest)` is asked, with the time a chunk and its evaluation take in this call (`longest_chunk`; None
    before the first): True ends the run there, its last evaluation handed on as at the end (a time limit: the
    run goes on later from it). With `clock` (a time.perf_counter() value) every row holds `wall_seconds`, from
    it to the end of the row's evaluation, stamped here: a row handed on after a chunk's call that held the host
    would be dated a chunk late.
    """
    keys = seed_keys(seeds)
    staged, last = len(trainers) > 1, len(trainers) - 1

    def programs(k: int) -> Programs:
        """Stage k's programs, compiled once."""
        trainer = trainers[k]
        kept = (len(seeds), film, schedule)
        if kept not in trainer.compiled:
            weighed = functools.partial(adapted, schedule=schedule)
            trainer.compiled[kept] = Programs(trainer, keys, film, evaluate, weighed)
        return trainer.compiled[kept]

    def judge(k: int, state, index: int) -> tuple[dict, object]:
        """Metrics per seed, and the first seed's episode filmed on stage k (None without `film`)."""
        metrics, frames = computed(programs(k).evaluate(state, jax.vmap(eval_key, in_axes=(0, None))(keys, index)),
                                   to_host)
        stop_on_overflow(trainers[k].env, metrics.pop(OVERFLOW, None))
        return metrics, None if frames is None else (k, seed_slice(frames, 0))

    history: list[dict] = []
    reported = None  # the last evaluation's (index, rows, state, stage, episode, sampling), not yet handed on

    def report(index, rows, state, stage, episode, sampling):
        progress(index, rows)
        on_eval(state, index, stage, episode, sampling)

    stage = 0 if resume is None else resume[2]
    refilling = resume is not None and not trainers[stage].holds_environments(resume[0])
    # every program the first evaluations need compiles at once, in the order they run
    programs(stage).prepare(*(("start",) if resume is None else ("refill",) if refilling else ()), "sampling",
                            "evaluate", "chunk", *(("adapt",) if trainers[stage].env.variant_count > 1 else ()))
    if staged and stage != last:
        programs(last).prepare("evaluate")
    if jax.process_count() > 1:  # no process calls a program before every process has compiled them (`meet`)
        for k in {stage, last}:
            programs(k).compiled()
        computed(None, lambda _: meet(f"fieldgen/compiled/{next(_meetings)}"))
    if resume is None:
        state, first, previous = programs(0).start(keys), 1, 0
        sampling = programs(0).sampling(state)
    else:
        state, index, _ = resume
        if refilling:  # where its rows mark the refill
            learned_at = int(np.asarray(state.env_steps).reshape(-1)[0])
        state = programs(stage).refill(state) if refilling else from_host(state, programs(stage).placement)
        if refilling and sampling:
            state = drawing_as(state, sampling, programs(stage).placement)
        if sampling is None:  # as its environments draw now
            sampling = programs(stage).sampling(state)
        first, previous = index + 1, int(to_host(state.env_steps)[0])
    took: list[float] = []  # seconds each chunk and its evaluation took
    for index in range(0 if resume is None else first, num_evals + 1):
        if index > 0 and stop(longest_chunk(took)):
            break
        began = time.perf_counter()
        metrics = {}
        if index > 0:
            called = programs(stage).chunk_started(state)
            if jax.process_count() > 1:  # every process gathers the reported state after the chunk's collectives
                called.result()
            if reported is not None:  # its metrics, checkpoint and video, written on the host while the chunk trains
                report(*reported)
            state, metrics = called.result()
            metrics = computed(metrics, to_host)  # waits for the chunk
            stop_on_overflow(trainers[stage].env, to_host(state.env_state.info.get(OVERFLOW)))
            metrics.update(diverged_episodes(to_host(state.env_state.info.get(DIVERGED)), len(seeds)))
        seconds = time.perf_counter() - began
        judged, episode = judge(stage, state, index)
        metrics.update(judged)
        if trainers[stage].env.variant_count > 1:  # a mixed run: judged on its last variant, and re-weighted
            state, sampling, variants = programs(stage).adapt(state, sampling, metrics["variants"])
            metrics["variants"] = to_host(variants)
            metrics["last_stage_success_any"] = metrics["variants"].success_any[:, -1]
        if staged and stage != last:
            metrics["last_stage_success_any"] = judge(last, state, index)[0]["success_any"]
        elif staged:
            metrics["last_stage_success_any"] = metrics["success_any"]
        steps = int(to_host(state.env_steps)[0])
        evaluated = time.perf_counter()
        rows = []
        for i, seed in enumerate(seeds):
            row = {"eval": index, "seed": seed, "env_steps": steps, **({"stage": stage} if staged else {}),
                   **{k: float(v[i]) for k, v in metrics.items() if k != "variants"}}
            if "variants" in metrics:
                row["variants"] = metrics["variants"].per_seed(i)
            if index > 0:
                row["steps_per_second"] = (steps - previous) / seconds
            if clock is not None:
                row["wall_seconds"] = evaluated - clock
            if refilling and index == first:
                row["refilled_from"] = learned_at
            rows.append(row)
        previous = steps
        history.extend(rows)
        following = schedule.next_stage(history, stage, len(trainers)) if index > 0 else stage
        if following != stage:
            stage = following
            state = jax.device_put(_with_env(trainers[stage], state, index), programs(stage).placement)
            sampling = programs(stage).sampling(state)
            for row in rows:
                row["promoted_to"] = stage
        reported = (index, rows, state, stage, episode, sampling)
        if index > 0:
            took.append(time.perf_counter() - began)
    if reported is not None:
        report(*reported)
    return state, history


def longest_chunk(took: list[float]) -> float | None:
    """The longest of a call's chunks (each with its evaluation) but its first, which alone also waits for what
    is done once (programs compiled, a buffer refilled, the state moved to the device); the first while it is
    the only one, None before any."""
    return max(took[1:] or took, default=None)


def _with_env(trainer: Trainer, state, index: int):
    """The vmapped state with fresh episodes of `trainer`'s environment in every slot (the next stage's field).

    Episode counters carry on, so hindsight goals never join an old-stage episode to a new one."""

    def one(ts):
        key = jax.random.fold_in(ts.key, index)
        fresh = jax.vmap(trainer.env.reset)(jax.random.split(key, trainer.config.num_envs))
        info = dict(fresh.info, episode=ts.env_state.info["episode"] + 1)
        return ts.replace(env_state=fresh.replace(info=info))

    return jax.vmap(one)(state)


def seed_keys(seeds: Sequence[int]) -> jax.Array:
    """One PRNG key per seed, stacked along the seed axis that vmapped training states carry."""
    return jnp.stack([jax.random.PRNGKey(s) for s in seeds])


def seed_slice(state, i: int):
    """Seed i's state out of a vmapped one."""
    return jax.tree.map(lambda x: x[i], state)
