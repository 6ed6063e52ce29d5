"""Where an exported policy leaves the ball: episode by episode, the ball's closest approach to the target and
where it ends, so that a success rate of 0.4 can be read as "scores in 4 of 10 kick-offs and brings the ball
near the target without scoring in 5" or "pins it against an obstacle in 6". Episodes are played on the CPU
(or whatever JAX finds) with the policy's mean actions, as `fieldgen eval` plays them.

    fieldgen export RUN --seed 730 -o policies/730
    python bench/ball_endings.py policies/730 --field RUN/field --episodes 32 --out endings.jsonl

Prints how many episodes scored (the ball's centre within the success radius of the target at some step),
came near without scoring (closest within --near metres), and ended elsewhere (and how many of those the
agent left where it started), with the 1 m cells where the ball most often ends; for an agent with a torso, how
many of the episodes without a score saw it turned upside down (its torso's up axis below the horizontal) and
when. --out keeps one row per episode, with the steps of the ball's first move, of its first score and of the agent's
first turn over, how many steps the agent spent upside down and its torso's median height meanwhile.
"""

from __future__ import annotations

import argparse
import collections
import json
from pathlib import Path

import numpy as np


def endings(policy: Path, field: str, episodes: int, seed: int) -> list[dict]:
    """One row per episode: the ball's closest distance to the target, its final position, whether it scored."""
    import jax
    import jax.numpy as jnp

    import fieldgen
    from fieldgen.env.contract import OVERFLOW, torso_entries, up_axis_z

    names = json.loads((policy / "policy.json").read_text())["observation_names"]
    if "ball.x" not in names:
        raise SystemExit(f"{policy}: its policy observes no ball (a field without one): nothing to follow")
    env = fieldgen.make(field)
    env.reserve_worlds(episodes)  # Warp's contact buffer is shared by the batch: sized for every episode at once
    act = jax.vmap(fieldgen.load_policy(policy))
    ball = [names.index("ball.x"), names.index("ball.y")]
    goal = [names.index("goal.x"), names.index("goal.y")]
    torso = torso_entries(names)
    height = names.index("root.z") if "root.z" in names else None

    def step(state, _):
        state = jax.vmap(env.step)(state, act(state.obs))
        level = jnp.ones(state.obs.shape[0])  # a point: always upright, at no height
        up = up_axis_z(state.obs[:, torso].T) if torso else level  # below 0: upside down
        z = state.obs[:, height] if height is not None else 0.0 * level
        overflow = state.info.get(OVERFLOW, jnp.zeros(episodes, jnp.int32))
        return state, (state.obs[:, ball], state.obs[:, goal], state.metrics["success"], up, z, overflow)

    @jax.jit
    def play(key):
        state = jax.vmap(env.reset)(jax.random.split(key, episodes))
        # one step short of the episode's length: the last step would start the next episode (auto-reset)
        _, trace = jax.lax.scan(step, state, None, length=env.episode_length - 1)
        return trace

    ball_xy, goal_xy, success, up, z, overflow = (np.asarray(x) for x in play(jax.random.PRNGKey(seed)))
    env.check_physics(overflow)
    distance = np.linalg.norm(ball_xy - goal_xy, axis=-1)
    moved = np.linalg.norm(ball_xy - ball_xy[:1], axis=-1) > MOVED
    return [{"episode": i, "scored": bool(success[:, i].max() > 0), "closest": float(distance[:, i].min()),
             "start": [round(float(v), 3) for v in ball_xy[0, i]],
             "final": [round(float(v), 3) for v in ball_xy[-1, i]],
             "first_move": first_step(moved[:, i]), "scored_at": first_step(success[:, i] > 0),
             **({"upside_down_at": first_step(up[:, i] < 0.0), "upside_down_steps": int((up[:, i] < 0.0).sum()),
                 "torso_height_upside_down": median_where(z[:, i], up[:, i] < 0.0)}
                if torso else {})} for i in range(episodes)]


MOVED = 0.05  # metres from where the ball stood after the first step: a move, not the solver settling it


def median_where(values: np.ndarray, flags: np.ndarray) -> float | None:
    """The median of `values` over the steps where `flags` holds, None where it never does."""
    return round(float(np.median(values[flags])), 3) if flags.any() else None


def first_step(flags: np.ndarray) -> int | None:
    """The first step (from 1) at which `flags` holds, None where it never does."""
    return int(np.argmax(flags)) + 1 if flags.any() else None


def report(rows: list[dict], near: float) -> str:
    scored = sum(r["scored"] for r in rows)
    close = sum(not r["scored"] and r["closest"] <= near for r in rows)
    still = sum(not r["scored"] and r["closest"] > near and np.hypot(*np.subtract(r["final"], r["start"])) < 0.5
                for r in rows)
    cells = collections.Counter((round(r["final"][0]), round(r["final"][1])) for r in rows if not r["scored"])
    common = ", ".join(f"({x}, {y}) x{n}" for (x, y), n in cells.most_common(5))
    line = (f"{len(rows)} episodes: {scored} scored, {close} came within {near} m of the target without scoring, "
            f"{len(rows) - scored - close} ended farther ({still} of them within 0.5 m of where the ball started); "
            f"where the ball ends in episodes without a score (1 m cells): {common or '-'}")
    missed = [r for r in rows if not r["scored"] and "upside_down_at" in r]
    turned = sorted(r["upside_down_at"] for r in missed if r["upside_down_at"] is not None)
    if missed:
        line += (f"; {len(turned)} of the {len(missed)} without a score saw the agent upside down"
                 + (f" (first at step {turned[0]}, median {int(np.median(turned))})" if turned else ""))
    return line


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("policies", nargs="+", type=Path, help="folders written by `fieldgen export`")
    parser.add_argument("--field", required=True, help="the field they play: a run's field/ folder, YAML or name")
    parser.add_argument("--episodes", type=int, default=32)
    parser.add_argument("--seed", type=int, default=0, help="the seed of the episodes' kick-offs")
    parser.add_argument("--near", type=float, default=1.5, help="metres from the target that count as near")
    parser.add_argument("--out", type=Path, help="a .jsonl of the episodes, one row each")
    args = parser.parse_args()
    lines = []
    for policy in args.policies:
        rows = endings(policy, args.field, args.episodes, args.seed)
        print(f"{policy}: {report(rows, args.near)}")
        lines += [json.dumps({"policy": str(policy), **row}) for row in rows]
    if args.out:
        args.out.write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
