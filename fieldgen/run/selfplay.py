"""A self-play run on a team field (agents/selfplay.py) in its folder: set up, trained one evaluation at a
time with a checkpoint after each (resumed exactly from it), rated, plotted and judged. Its seeds train at once,
vmapped in one program as a single-agent run's do (agents/loop.py), each seed's state stacked on a leading axis
and starting as a run of that seed alone would; each seed is a league of its own.

The folder is a training run's (fieldgen/run/record.py): run.json (its `selfplay` entry marks it, `seeds` lists
its seeds), the field's own copy in field/, metrics.jsonl and metrics.csv (a row per evaluation and seed, each
with its `seed`), checkpoint.msgpack (the whole training state of every seed, every snapshot with it), and
ratings.png. A row holds, beside the training losses, the new snapshot's games against the random policy
(`win_vs_random`, `draw_vs_random`, `loss_vs_random`, as shares; `success_any` is the share won, as other runs'
figures read it), `league` (its win, draw and loss counts against `random` and each earlier snapshot it played, by
index), `elo` (its rating once those games are counted) and `ratings` (every player's in that seed's league).
"""

from __future__ import annotations

import dataclasses
import json
import time
from pathlib import Path
from types import SimpleNamespace

import jax
import jax.numpy as jnp
import numpy as np

from fieldgen import files, stops
from fieldgen.agents import checkpoint, elo, loop, memory
from fieldgen.agents.programs import reserve_worlds
from fieldgen.agents.selfplay import RESULTS, SelfPlayConfig, fixed_opponents, make_selfplay
from fieldgen.compile.artifact import ArtifactError, write_artifact
from fieldgen.env.contract import DIVERGED, OVERFLOW
from fieldgen.env.mjx_physics import PhysicsOverflow
from fieldgen.run import record
from fieldgen.run.videos import video_name
from fieldgen.suggest import shell

FIELD = "field"
RATINGS_PLOT = "ratings.png"
EVALUATION = "selfplay_eval.json"  # what `fieldgen eval` on a self-play run writes
RANDOM = "random"
FILMED = 1_000_003  # the stream of an evaluation's key that films its match, apart from the judged matches'


@dataclasses.dataclass
class TeamRun:
    folder: Path
    config: SelfPlayConfig
    env: object
    seeds: list[int]
    rows: list[dict]  # a row per evaluation and seed
    state: object = None  # the checkpointed training state, where it has one: every seed's, stacked

    @property
    def finished(self) -> bool:
        return bool(self.rows) and self.rows[-1]["eval"] >= self.config.num_evals

    @property
    def label(self) -> str:
        return f"{self.env.spec.name}: self-play ppo"

    @property
    def algorithm(self):
        return programs(self.config, self.env, len(self.seeds))[0]


_compiled: dict = {}  # (config but its seed, the field's spec) -> programs(...)


def programs(config: SelfPlayConfig, env, seeds: int) -> tuple:
    """(SelfPlay, jitted init, chunk, judge, film) for `config` on `env`'s field, made once in a process: a resume
    or other seeds of the same settings in the same process reuse them instead of compiling again. init, chunk
    and judge run every seed at once, vmapped over the state's leading seed axis (init over seed keys, judge over
    the state and each seed's evaluation key; the snapshot's index and opponents are every seed's). `film(state,
    j, key)` films a match of one seed's policy (home) against its snapshot j (away). The field they step is
    sized first for the matches of `seeds` seeds stepped at once (reserve_worlds: seeds x the larger of num_envs
    and eval_envs; a film steps one), before any of them, a checkpoint's template or a memory estimate is
    traced."""
    key = (config.model_copy(update={"seed": 0}), json.dumps(env.spec.model_dump(mode="json"), sort_keys=True))
    if key not in _compiled:
        sp = make_selfplay(config, env)
        _compiled[key] = (sp, jax.jit(jax.vmap(sp.init)), jax.jit(jax.vmap(sp.chunk), donate_argnums=0),
                          jax.jit(jax.vmap(sp.judge, in_axes=(0, None, None, 0)), donate_argnums=0),
                          jax.jit(lambda ts, j, k: sp.film(sp.current(ts), sp.snapshot(ts, j), k)))
    reserve_worlds(_compiled[key][0], seeds)  # the field the programs step, which may be an earlier run's copy
    return _compiled[key]


def is_team_run(folder: Path) -> bool:
    """Whether `folder` holds a self-play run (its run.json says so); False for any other folder."""
    try:
        return bool(files.parsed_json((folder / record.RUN).read_bytes()).get("selfplay"))
    except (OSError, ValueError, AttributeError):
        return False


def _team_env(source):
    import fieldgen

    env = fieldgen.make(source)
    if not hasattr(env, "agent_sides"):
        raise record.RunError(f"{env.spec.name} has no teams: self-play trains a team field (teams.home/away)")
    return env


def new_run(source: Path, config: SelfPlayConfig, out: Path, seeds: list[int], check_memory: bool = True,
            recipe: dict | None = None) -> TeamRun:
    """A run folder for the team field `source` training `seeds` at once (the first is the config's seed),
    written once its settings are known good (and, with `check_memory`, once this machine can hold it); with
    `recipe`, the recipe it was set up from, as run.json keeps it."""
    from fieldgen.agents.config import ConfigError

    env = _team_env(source)
    try:
        config.validate_env(env, seeds=len(seeds))
        if check_memory:
            fits_memory(config, env, len(seeds))
    except ConfigError as exc:
        raise record.RunError(str(exc)) from None
    folder = out / record.run_name(env.spec.name, config.algo, seeds)
    if (taken := record.occupied(folder)) is not None:
        raise record.RunError(taken)
    files.claim(folder, record.RUN_FOLDER)
    try:
        folder.mkdir(parents=True, exist_ok=True)
        files.mark(folder, record.RUN_FOLDER)
        files.remove_leftovers(folder)
        for stale in (record.METRICS, record.CSV, RATINGS_PLOT):
            (folder / stale).unlink(missing_ok=True)
        write_artifact(env.artifact, folder / FIELD)
        record.write_run(folder, env.spec.model_dump(mode="json"), config.algo, config, env.layout.to_json(),
                         seeds, {"fields": [FIELD], "selfplay": True, **({"recipe": recipe} if recipe else {})})
    except OSError as exc:
        raise record.RunError(f"cannot set up the run folder {folder}: "
                              f"{files.way_on(folder.parent, '--out', exc)}") from None
    return TeamRun(folder, config, env, seeds, [])


def fits_memory(config: SelfPlayConfig, env, seeds: int) -> None:
    """Refuse (ConfigError) a self-play run whose matches, snapshots and rollouts need more memory than the
    machine has, before anything is allocated (agents.memory, as a single-agent run is checked)."""
    more = " or --seeds" if seeds > 1 else ""
    lower = {memory.EPISODES: f"--envs{more}", memory.BATCH: f"--envs or ppo.unroll_length{more}",
             memory.NETWORKS: f"ppo.hidden or ppo.num_evals (a snapshot is kept at every evaluation){more}",
             memory.BUFFER: f"--envs{more}"}
    memory.check(memory.training(programs(config, env, seeds)[0], seeds),  # the SelfPlay training will use
                 f"training {seeds:,} seed{'s' * (seeds > 1)} of self-play {config.algo} with {config.num_envs:,} "
                 "matches", lower)


def open_run(folder: Path, load_state: bool = True, to_train: bool = False) -> TeamRun:
    """A self-play run folder with its field and (with load_state) its last checkpoint; its rows are those up to
    the checkpoint's evaluation (later ones, of a chunk whose checkpoint a kill cut short, train again), every
    seed's. A run opened `to_train` that is not complete is checked against this machine's memory first."""
    from fieldgen.agents.config import ConfigError

    saved = record.read_run(folder)
    record.check_field_copy(folder / FIELD)
    try:
        env = _team_env(folder / FIELD)
    except ArtifactError as exc:
        raise record.field_copy_error(folder / FIELD, exc.problem) from None
    try:
        config = SelfPlayConfig.layered(**saved.config)
    except ConfigError as exc:
        raise record.RunError(f"{folder / record.RUN} holds no usable self-play config ({exc})") from None
    seeds = saved.seeds or [config.seed]
    run = TeamRun(folder, config, env, seeds, _league_rows(folder, seeds))
    if to_train and not run.finished:
        try:
            fits_memory(config, env, len(run.seeds))
        except ConfigError as exc:
            raise record.RunError(str(exc)) from None
    if load_state and (folder / record.CHECKPOINT).exists():
        template = jax.eval_shape(jax.vmap(run.algorithm.init), loop.seed_keys(run.seeds))
        try:
            run.state = checkpoint.load(folder / record.CHECKPOINT, template)
        except checkpoint.CheckpointError as exc:
            raise record.RunError(str(exc)) from None
        last = int(run.state.newest[0])
        run.rows = [row for row in run.rows if row["eval"] <= last]
        if {row["seed"] for row in run.rows if row["eval"] == last} != set(run.seeds):
            raise record.RunError(f"{folder / record.METRICS} lacks evaluation {last}, which its checkpoint "
                                  "holds; restore the run from a copy, or start it again in a new folder")
    return run


def _league_rows(folder: Path, seeds: list[int]) -> list[dict]:
    """The run's rows, each with its league, rating and ratings (record.MetricsRow checks their types where
    present): a resumed run rates its new snapshots from the leagues before, and eval reports the ratings."""
    rows = record.read_metrics(folder, seeds)
    for s in seeds:  # every evaluation of every seed: eval finds the snapshot from a third of the way among them
        held = sorted(row["eval"] for row in rows if row["seed"] == s)
        gap = next((i for i, e in enumerate(held) if e != i), None)
        if gap is not None:
            raise record.RunError(f"{folder / record.METRICS} lacks evaluation {gap} of seed {s}, which a self-play "
                                  "run's later evaluations and its ratings build on (edited or damaged); restore the "
                                  "file from a copy, or start the run again in a new folder")
    for row in rows:
        lacks = [key for key in ("league", "elo", "ratings") if key not in row]
        if lacks:
            raise record.RunError(f"{folder / record.METRICS}: evaluation {row['eval']} of seed {row['seed']} lacks "
                                  f"{', '.join(lacks)}, which every row of a self-play run holds (edited or damaged); "
                                  "restore the file from a copy, or start the run again in a new folder")
    return rows


def opponents_of(index: int, count: int) -> jax.Array:
    """The fixed earlier snapshots snapshot `index` plays, padded with -1 to `count`."""
    chosen = fixed_opponents(index, count)
    return jnp.asarray(chosen + [-1] * (count - len(chosen)), jnp.int32)


def ratings(rows: list[dict], k: float) -> dict[str, float]:
    """Every player's Elo rating after the leagues of `rows` (one seed's) in order (agents/elo.py): each
    snapshot's games against the random policy, then against its earlier snapshots."""
    return elo.league_ratings(((str(row["eval"]), opponent, games) for row in rows
                               for opponent, games in row["league"].items()), k)


def league_row(index: int, results: dict, count: int) -> dict:
    """`league` of a metrics row: the snapshot's win, draw and loss counts by opponent."""
    league = {RANDOM: dict(zip(RESULTS, map(int, results["random"])))}
    for j, counts in zip(fixed_opponents(index, count), np.asarray(results["earlier"])):
        league[str(j)] = dict(zip(RESULTS, map(int, counts)))
    return league

def of_seed(rows: list[dict], seed: int) -> list[dict]:
    """One seed's rows of a run's, in order."""
    return [row for row in rows if row["seed"] == seed]


def train(run: TeamRun, say=print, deadline: float | None = None, recorder=None) -> bool:
    """Train every seed until the run's last evaluation, writing the rows (one per seed), the plot and the
    checkpoint of each; a resumed run goes on from its checkpoint exactly as if it had never stopped. With
    `deadline` (time.monotonic()), stop at the last evaluation whose next chunk, as long as the longest one yet
    with its evaluation, would not end by then. With `recorder` (a fieldgen.run.videos.EpisodeRecorder of the
    run's field), film at every evaluation a match of the first seed's new snapshot against its one before
    (videos/eval_NNN: one video an evaluation, of the first seed, as a single-agent run films), both sides in
    view. Returns whether the run is complete."""
    c = run.config
    if run.finished and run.state is not None:
        say(f"{run.folder} is already complete ({run.rows[-1]['env_steps']:,} env steps)")
        return True
    took: list[float] = []  # seconds each chunk with its evaluation and checkpoint took in this command
    sp, init, chunk, judge, film = programs(c, run.env, len(run.seeds))
    keys = loop.seed_keys(run.seeds)
    clock = time.perf_counter() - (run.rows[-1].get("wall_seconds", 0.0) if run.rows else 0.0)
    with files.locked(run.folder):
        files.remove_leftovers(run.folder)
        if run.state is None:
            run.rows = []
            state, first = init(keys), 0
        else:
            state, first = run.state, run.rows[-1]["eval"] + 1
        for index in range(first, c.num_evals + 1):
            stops.check()  # a Ctrl-C dropped where it was raised stops the run here, before its next chunk
            if index > 0 and deadline is not None and took and time.monotonic() + max(took) > deadline:
                last = run.rows[-1]
                say(f"stopped at the time limit after evaluation {last['eval']} of {c.num_evals} "
                    f"({last['env_steps']:,} of {c.trained_steps:,} env steps): the next chunk with its evaluation "
                    f"and checkpoint (about {max(took):.0f} s) would not have ended in time. Continue with: "
                    f"fieldgen train --resume {shell(run.folder)}")
                return False
            began = time.perf_counter()
            metrics = {}
            if index > 0:
                state, metrics = chunk(state)
                stop_if_overflowed(sp.env, jax.device_get(state.env_state.info.get(OVERFLOW)), "training")
                metrics.update(loop.diverged_episodes(jax.device_get(state.env_state.info[DIVERGED]), len(run.seeds)))
            state, results = judge(state, index, opponents_of(index, c.league_opponents),
                                   jax.vmap(loop.eval_key, in_axes=(0, None))(keys, index))
            metrics, results, steps = jax.device_get((metrics, results, state.env_steps))
            stop_if_overflowed(sp.env, results.pop(OVERFLOW, None), "training")
            steps, seconds = int(steps[0]), time.perf_counter() - began
            rows = [seed_row(run, index, seed, {k: v[i] for k, v in metrics.items()}, loop.seed_slice(results, i),
                             steps) for i, seed in enumerate(run.seeds)]
            for row in rows:
                if index > 0:
                    row["steps_per_second"] = (steps - run.rows[-1]["env_steps"]) / seconds
                row["wall_seconds"] = time.perf_counter() - clock
                stop_if_diverged(run, row)
            run.rows.extend(rows)
            record.write_metrics(run.folder, run.rows)
            plot_ratings(run.folder, run.rows, run.label)
            run.state = state
            files.write_atomic(run.folder / record.CHECKPOINT, checkpoint.pieces(jax.device_get(state)))
            if recorder is not None:
                filmed = film(loop.seed_slice(state, 0), max(index - 1, 0),
                              jax.random.fold_in(loop.eval_key(keys[0], index), FILMED))
                recorder.save(run.folder, video_name(run.folder, index), recorder.episode(filmed),
                              SimpleNamespace(print=say))
            for row in rows:
                say(progress_line(row, c, len(run.seeds) > 1))
            if index > 0:
                took.append(time.perf_counter() - began)
    return True


def seed_row(run: TeamRun, index: int, seed: int, metrics: dict, results: dict, steps: int) -> dict:
    """Seed `seed`'s row of evaluation `index`: its training `metrics` and its snapshot's games (`results`, as
    SelfPlay.judge gives them), rated in its own league (its rows before this one)."""
    row = {"eval": index, "seed": seed, "env_steps": steps, **{k: float(v) for k, v in metrics.items()}}
    league = league_row(index, results, run.config.league_opponents)
    games = sum(league[RANDOM].values())
    row.update({f"{r}_vs_random": league[RANDOM][r] / games for r in RESULTS})
    row["success_any"] = row["win_vs_random"]
    row["league"] = league
    rated = ratings(of_seed(run.rows, seed) + [row], run.config.elo_k)
    row["elo"], row["ratings"] = rated[str(index)], rated
    return row


def stop_if_overflowed(env, overflow, what: str) -> None:
    """Stop `what` (training, evaluation) in one line (record.RunError) where `overflow`, the physics' overflow
    flags of its matches (None: physics without them), says a match outgrew Warp's capacities
    (agents.loop.stop_on_overflow)."""
    try:
        loop.stop_on_overflow(env, overflow)
    except PhysicsOverflow as exc:
        raise record.RunError(f"{what} stopped: {exc}") from None


def stop_if_diverged(run: TeamRun, row: dict) -> None:
    bad = sorted(k for k, v in row.items() if isinstance(v, float) and not np.isfinite(v))
    if bad:
        raise record.RunError(f"training diverged: after {row['env_steps']:,} env steps (evaluation {row['eval']}) "
                              f"seed {row['seed']}'s {', '.join(bad)} {'is' if len(bad) == 1 else 'are'} not "
                              f"finite; {run.folder} keeps the evaluation before. Train again with a smaller "
                              "ppo.learning_rate (--set) or another --seed")


def progress_line(row: dict, config: SelfPlayConfig, named: bool = False) -> str:
    """One seed's evaluation in a line; `named`: with its seed, where a run trains several."""
    earlier = [f"vs {j}: {g['win']}/{g['draw']}/{g['loss']}" for j, g in row["league"].items() if j != RANDOM]
    r = row["league"][RANDOM]
    return (f"eval {row['eval']}/{config.num_evals} at {row['env_steps']:,} env steps"
            + (f", seed {row['seed']}" if named else "") + f": vs random "
            f"{r['win']}/{r['draw']}/{r['loss']} (win/draw/loss)" + (f", {', '.join(earlier)}" if earlier else "")
            + f"; Elo {row['elo']:.0f}")


def plot_ratings(run_dir: Path, rows: list[dict], title: str) -> None:
    """ratings.png: each snapshot's Elo rating as of the last evaluation (and as it stood when it joined) against
    the env steps it was taken at, the random policy's as a line; the shares of games won, drawn and lost against
    the random policy at each evaluation. With several seeds, each seed's lines in a colour of its own."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from fieldgen.run.plots import save_figure

    fig, axes = plt.subplots(1, 2, figsize=(10, 3.6), sharex=True, squeeze=False)
    axes = list(axes.flat)
    seeds = list(dict.fromkeys(row["seed"] for row in rows))
    several = len(seeds) > 1
    for k, seed in enumerate(seeds):
        mine = of_seed(rows, seed)
        colour, named = (f"C{k}", f"seed {seed} ") if several else (None, "")
        steps = [row["env_steps"] for row in mine]
        final = mine[-1]["ratings"]
        axes[0].plot(steps, [final[str(row["eval"])] for row in mine], marker="o", color=colour, label=f"{named}now")
        axes[0].plot(steps, [row["elo"] for row in mine], ls="--", marker=".", color=colour,
                     label=f"{named}when taken")
        axes[0].axhline(final[RANDOM], color=colour or "grey", ls=":", label=f"{named}random policy")
        for result, style in zip(RESULTS, ("-", "--", ":") if several else ("-",) * len(RESULTS)):
            axes[1].plot(steps, [row[f"{result}_vs_random"] for row in mine], ls=style, marker="o", color=colour,
                         label=f"{named}{result}")
    axes[0].set(xlabel="env steps", ylabel="Elo", title="snapshots' ratings")
    axes[1].set(xlabel="env steps", ylabel="share of games", title="against a random policy", ylim=(-0.02, 1.02))
    save_figure(fig, axes, title, run_dir / RATINGS_PLOT)


def earlier_snapshot(run: TeamRun) -> int:
    """The snapshot `fieldgen eval` sets the policy against: the one from a third of the way through."""
    return int(round(int(run.state.newest[0]) / 3))


def evaluate(run: TeamRun, episodes: int | None = None, seed: int = 0, actions: str | None = None,
             film: int | None = None) -> tuple[dict, object]:
    """Each seed's last snapshot (its policy as of the last evaluation) against the random policy and against its
    snapshot from a third of the way through, `episodes` each (half on either side, every seed on the same
    kick-offs), with its ratings; over several seeds, also the interquartile mean of the seeds' shares won
    against each with its 95% bootstrap interval (fieldgen.run.summary). With `film` (a place in `run.seeds`),
    also one more match of that seed's two (the last snapshot at home) filmed for a video
    (EpisodeRecorder.episode's input), else None."""
    if episodes and episodes % 2:  # else refused below as the run's own ppo.eval_envs, which the user did not give
        raise record.RunError(f"--episodes {episodes} is odd: the last snapshot plays half its episodes on each side; "
                              f"give an even number, such as {episodes + 1:,}")
    config = run.config.model_copy(update={"eval_envs": episodes or run.config.eval_envs,
                                           "eval_actions": actions or run.config.eval_actions})
    from fieldgen.agents.config import ConfigError
    from fieldgen.run.summary import MetricSummary

    try:
        config.validate_env(run.env, seeds=len(run.seeds))
    except ConfigError as exc:
        raise record.RunError(str(exc)) from None
    sp = make_selfplay(config, run.env)
    reserve_worlds(sp, len(run.seeds))
    state, earlier = run.state, earlier_snapshot(run)
    newest = int(state.newest[0])
    key = jax.random.PRNGKey(seed)

    def both(state, key):
        me = sp.snapshot(state, newest)
        return (sp.match(me, None, jax.random.fold_in(key, 0)),
                sp.match(me, sp.snapshot(state, earlier), jax.random.fold_in(key, 1)))

    keys = jnp.broadcast_to(key, (len(run.seeds),) + key.shape)  # one key a seed, so that the matches batch at once
    (vs_random, flags), (vs_earlier, earlier_flags) = jax.device_get(jax.jit(jax.vmap(both))(state, keys))
    stop_if_overflowed(run.env, None if flags is None else flags | earlier_flags, "evaluation")
    filmed = jax.jit(lambda state, key: sp.film(sp.snapshot(state, newest), sp.snapshot(state, earlier), key))(
        loop.seed_slice(state, film), jax.random.fold_in(key, FILMED)) if film is not None else None
    at = {"snapshot": earlier, "env_steps": next(r["env_steps"] for r in run.rows if r["eval"] == earlier)}
    per_seed = {}
    for i, s in enumerate(run.seeds):
        last = of_seed(run.rows, s)[-1]
        per_seed[s] = {"vs_random": dict(zip(RESULTS, map(int, vs_random[i]))),
                       "vs_snapshot": {**at, **dict(zip(RESULTS, map(int, vs_earlier[i])))},
                       "elo": last["elo"], "ratings": last["ratings"]}
    result = {"run": str(run.folder), "eval": newest, "env_steps": run.rows[-1]["env_steps"],
              "episodes": config.eval_envs, "actions": config.eval_actions, "seed": seed, "seeds": run.seeds,
              "per_seed": per_seed}
    if len(run.seeds) > 1:
        for opponent in ("vs_random", "vs_snapshot"):
            won = MetricSummary.of({s: one[opponent]["win"] / config.eval_envs for s, one in per_seed.items()})
            result[f"win_{opponent}"] = won.model_dump(mode="json")
    return result, filmed
