"""A built team field -> a batched MJX match (the contract of team_contract.py).

Every agent observes and acts in its side's own frame, the away side's being the field's turned half a turn
about the centre spot, so that one policy plays either side: `SideFrame` turns an agent's joints, the ball and
the other agents into it, and its actions back out. A step scores each side from the match terms
(fieldgen/schema/terms.py MATCH_TERMS); the per-agent ones are the single-agent terms of fieldgen/env/task.py,
averaged over the side's agents. An episode ends for both sides at a goal (counted on that step alone, as the
next step already plays a fresh episode) or on time; a diverged simulation ends it with nothing scored.
"""

from __future__ import annotations

import fieldgen.env.quiet  # noqa: F401  (before MJX and brax)
import jax
import jax.numpy as jnp
import numpy as np
from brax.envs.base import State

from fieldgen.compile.artifact import Artifact
from fieldgen.compile.layout import team_layout
from fieldgen.env import mjx_physics
from fieldgen.env.batch import own_device
from fieldgen.env.contract import DIVERGED
from fieldgen.env.field import advance, diverged, restart
from fieldgen.env.rules import ball_in_region
from fieldgen.env.task import IMPLEMENTATIONS, Transition, ball_in_goal_fn, progress
from fieldgen.schema import geometry
from fieldgen.schema.backends import mjx_impl
from fieldgen.schema.terms import MATCH_TERMS

# How an agent's own joints look from the other end of the field: new[i] = sign[i] * old[order[i]]. A point's
# slides are the field's x, y; an ant's free joint holds the torso's world position, its orientation (w, x, y, z)
# and world velocity, then its angular velocity in its own frame, which turning the field leaves alone, as it
# leaves the hinges. Its quaternion turned: q_z(-pi) * q = (z, y, -x, -w).
TURNED_QPOS = {"point": ((0, 1), (-1, -1)),
               "ant": ((0, 1, 2, 6, 5, 4, 3, *range(7, 15)), (-1, -1, 1, 1, 1, -1, -1, *[1] * 8))}
TURNED_QVEL = {"point": ((0, 1), (-1, -1)),
               "ant": (tuple(range(14)), (-1, -1, *[1] * 12))}
TURNED_ACTION = {"point": (-1, -1), "ant": (1,) * 8}  # a point's motors push along the field's axes; an ant's turn with it
# the match terms `score` computes; the others are task.py's, for each agent
# info under teams.lack_of_progress: the control steps the ball has stayed near its anchor, and the anchor (x, y)
STILL_STEPS, ANCHOR = "ball_still_steps", "ball_anchor"
MATCH_OWN = ("goal", "ball_progress", "ball_goal_progress")
if set(MATCH_OWN) != {name for name, t in MATCH_TERMS.items() if not t.per_agent}:
    raise ImportError(f"the match terms of fieldgen/schema/terms.py that are not per agent must be computed in "
                      f"{__name__}.TeamFieldEnv.score, which computes {', '.join(MATCH_OWN)}")


class SideFrame:
    """An agent kind's joints and actions as the away side sees them: a signed reordering of the entries."""

    def __init__(self, kind: str):
        self.qpos_order, self.qpos_sign = (np.asarray(a) for a in TURNED_QPOS[kind])
        self.qvel_order, self.qvel_sign = (np.asarray(a) for a in TURNED_QVEL[kind])
        self.action_sign = np.asarray(TURNED_ACTION[kind], np.float32)

    def qpos(self, q: jax.Array) -> jax.Array:
        return q[..., self.qpos_order] * self.qpos_sign

    def qvel(self, v: jax.Array) -> jax.Array:
        return v[..., self.qvel_order] * self.qvel_sign


def turned_xy(p: jax.Array) -> jax.Array:
    """A position or velocity (x, y[, z]) turned half a turn about the vertical."""
    return p.at[..., :2].multiply(-1.0)


class TeamFieldEnv(mjx_physics.SizedForBatch):
    """A match on a team field: observations [agents, observation_size], actions [agents, action_size], reward,
    success and terms per side [home, away]. On Warp's physics its batches are reserved and its flags read as a
    single-agent field's (`reserve_worlds`, `check_physics`)."""

    backend = "mjx"

    def __init__(self, artifact: Artifact, episode_length: int | None = None, auto_reset: bool = True):
        self.artifact, self.spec = artifact, artifact.spec
        spec = self.spec
        self.name = spec.name
        self.mj_model = artifact.model()
        self.layout = layout = team_layout(spec, self.mj_model)
        self.impl = mjx_impl(spec)
        self.sys = mjx_physics.put_model(self.mj_model, self.impl, own_device(), field=self.name)
        self.home_qpos = jnp.asarray(self.mj_model.key("home").qpos)
        self.data0 = mjx_physics.home_data(self.mj_model, self.impl, own_device(), field=self.name)
        self.episode_length = episode_length or spec.episode.length
        self.auto_reset = auto_reset
        self.n_substeps, self.dt = spec.episode.substeps, spec.episode.control_dt
        self.agent_names = layout.agents
        self.agent_sides = np.asarray(layout.sides)
        self.observation_size, self.observation_names = layout.size, layout.names
        self.action_size, self.action_names = len(layout.action_names), layout.action_names
        self.frame = SideFrame(spec.agent.kind)
        self._is_ant = spec.agent.kind == "ant"
        self._turned = jnp.asarray(self.agent_sides == 1)
        n = len(self.agent_names)
        # for each agent, the others it observes: its teammates, then its opponents, each in index order
        self._others = np.asarray([[j for j in range(n) if j != i and self.agent_sides[j] == self.agent_sides[i]]
                                   + [j for j in range(n) if self.agent_sides[j] != self.agent_sides[i]]
                                   for i in range(n)], np.int32)
        self._in_goal = ball_in_goal_fn(spec)  # the goal at +y; the home goal is it, turned
        self._goal_point = jnp.asarray([[0.0, spec.goal.distance], [0.0, -spec.goal.distance]])  # each side attacks
        self.terms = tuple(t.term for t in spec.task.reward)
        self._weights = jnp.asarray([t.weight for t in spec.task.reward])
        self._per_agent = {t.term: IMPLEMENTATIONS[t.term](spec, t) for t in spec.task.reward
                           if MATCH_TERMS[t.term].per_agent}
        self.zero_sum_terms = tuple(t for t in dict.fromkeys(self.terms) if MATCH_TERMS[t].zero_sum)
        self.metric_names = ("success", *dict.fromkeys(self.terms))
        self._stall = spec.teams.lack_of_progress
        if self._stall is not None:
            ball = ("ball",) if spec.ball.joint == "free" else ("ball_x", "ball_y")
            dofs = [range(int(self.mj_model.joint(j).dofadr[0]),
                          int(self.mj_model.joint(j).dofadr[0]) + (6 if j == "ball" else 1)) for j in ball]
            self._ball_dofs = jnp.asarray([d for r in dofs for d in r])  # x, y (planar) or x, y, z and spin (free)
            self._stall_steps = max(1, round(self._stall.seconds / self.dt))
            quarter, half = spec.field.width / 4, spec.goal.distance / 2
            self._neutral_spots = jnp.asarray([[0.0, 0.0], *[[sx * quarter, sy * half] for sx in (-1, 1)
                                                              for sy in (-1, 1)]])

    @property
    def unwrapped(self) -> "TeamFieldEnv":
        return self

    def _size_for(self, worlds: int) -> None:
        self.data0 = mjx_physics.home_data(self.mj_model, self.impl, own_device(), worlds, self.name)

    # -- reset -------------------------------------------------------------

    def reset(self, rng: jax.Array) -> State:
        rng, key = jax.random.split(rng)
        data = self._fresh(key)
        zero = jnp.zeros(())
        info = {"rng": rng, "episode_step": jnp.zeros((), jnp.int32), "truncation": zero,
                "episode": jnp.zeros((), jnp.int32), DIVERGED: jnp.zeros((), jnp.int32)}
        if self._stall is not None:
            info[STILL_STEPS], info[ANCHOR] = jnp.zeros((), jnp.int32), self._ball(data)[:2]
        if self.impl == "warp":
            info[mjx_physics.OVERFLOW] = jnp.zeros((), jnp.int32)
        metrics = {name: jnp.zeros(2) for name in self.metric_names}
        return State(data, self.observe(data), jnp.zeros(2), zero, metrics, info)

    def _fresh(self, key: jax.Array):
        """A new episode's physics state: every agent at its kick-off with the spec's reset noise, the ball in
        its spawn region."""
        k_q, k_v, k_ball = jax.random.split(key, 3)
        noise, qpos_at, qvel_at = self.spec.agent.reset_noise, self.layout.agent_qpos, self.layout.agent_qvel
        agent_noise = jax.random.uniform(k_q, qpos_at.shape, minval=-noise.qpos, maxval=noise.qpos)
        if self._is_ant:
            agent_noise = agent_noise.at[:, 3:7].set(0.0)  # keep each torso quaternion a unit quaternion
        qpos = self.home_qpos.at[jnp.asarray(qpos_at)].add(agent_noise)
        qpos = qpos.at[jnp.asarray(self.layout.ball_qpos[:2])].set(ball_in_region(k_ball, self.spec.ball.spawn))
        qvel = jnp.zeros(self.data0.qvel.shape).at[jnp.asarray(qvel_at)].set(
            noise.qvel * jax.random.normal(k_v, qvel_at.shape))
        return self.data0.replace(qpos=qpos, qvel=qvel)

    # -- step --------------------------------------------------------------

    def step(self, state: State, actions: jax.Array) -> State:
        actions = jnp.clip(actions, -1.0, 1.0)
        before = state.pipeline_state
        ctrl = jnp.zeros(self.mj_model.nu).at[jnp.asarray(self.layout.actuators)].set(
            jnp.where(self._turned[:, None], actions * self.frame.action_sign, actions))
        with jax.default_matmul_precision(self.spec.sim.precision):
            data, overflow = advance(self.sys, before, ctrl, self.n_substeps, self.impl, self._guard)
        metrics, reward, scored = self.score(before, data, actions)
        steps = state.info["episode_step"] + 1
        truncated = steps >= self.episode_length
        broken = diverged(data)
        metrics, reward = jax.tree.map(lambda x: jnp.where(broken, jnp.zeros_like(x), x), (metrics, reward))
        goal = scored & ~broken
        done = truncated | goal | broken
        info = dict(state.info, episode_step=steps, truncation=(truncated & ~goal & ~broken).astype(jnp.float32))
        info[DIVERGED] = state.info[DIVERGED] + broken.astype(jnp.int32)  # kept over episodes, as OVERFLOW
        if overflow is not None:
            info[mjx_physics.OVERFLOW] = state.info[mjx_physics.OVERFLOW] | overflow
        if self._stall is not None:
            data, info[STILL_STEPS], info[ANCHOR] = self._restart_stalled(data, state.info[STILL_STEPS],
                                                                          state.info[ANCHOR])
        obs = self.observe(data)
        if self.auto_reset:
            rng, key = jax.random.split(state.info["rng"])
            fresh = self._fresh(key)
            data = restart(done, fresh, data)
            obs = jnp.where(done, self.observe(fresh), obs)
            info.update(rng=rng, episode_step=jnp.where(done, 0, steps),
                        episode=state.info["episode"] + done.astype(jnp.int32))
            if self._stall is not None:  # a new episode counts from its own kick-off
                info[STILL_STEPS] = jnp.where(done, 0, info[STILL_STEPS])
                info[ANCHOR] = jnp.where(done, self._ball(data)[:2], info[ANCHOR])
        return State(data, obs, reward, done.astype(jnp.float32), metrics, info)

    def _restart_stalled(self, data, still: jax.Array, anchor: jax.Array):
        """(data, still steps, anchor): the ball moved, at rest, to the neutral spot farthest from every agent once
        it has stayed within the rule's distance of its anchor for the rule's time; a ball that leaves that
        distance anchors there anew. After the step's scoring, so the move itself pays no term."""
        ball = self._ball(data)[:2]
        moved = jnp.linalg.norm(ball - anchor) > self._stall.distance
        still = jnp.where(moved, 0, still + 1)
        stalled = still >= self._stall_steps
        agents = self._agent_positions(data)[:, :2]
        clearance = jnp.min(jnp.linalg.norm(self._neutral_spots[:, None] - agents[None], axis=-1), axis=1)
        spot = self._neutral_spots[jnp.argmax(clearance)]
        at = jnp.asarray(self.layout.ball_qpos[:2])
        qpos = jnp.where(stalled, data.qpos.at[at].set(spot), data.qpos)
        qvel = jnp.where(stalled, data.qvel.at[self._ball_dofs].set(0.0), data.qvel)
        anchor = jnp.where(moved | stalled, jnp.where(stalled, spot, ball), anchor)
        return data.replace(qpos=qpos, qvel=qvel), jnp.where(stalled, 0, still), anchor

    def score(self, before, after, actions: jax.Array) -> tuple[dict, jax.Array, jax.Array]:
        """(metrics [2] per name, reward [2], whether a goal was scored) of one step from `before` to `after`."""
        ball_before, ball = self._ball(before), self._ball(after)
        agents_before, agents = self._agent_positions(before), self._agent_positions(after)
        in_away_goal = self._in_goal(Transition(ball, ball, ball, ball, self._goal_point[0], actions[0], self.dt))
        turned = turned_xy(ball)  # the home goal is the away goal turned half a turn
        in_home_goal = self._in_goal(Transition(turned, turned, turned, turned, self._goal_point[0], actions[0], self.dt))
        success = jnp.stack([in_away_goal, in_home_goal])  # home scores in the away goal (+y), away in the home goal
        values = {"goal": success - success[::-1],
                  "ball_progress": jnp.stack([1.0, -1.0]) * (ball[1] - ball_before[1]) / self.dt}
        if "ball_goal_progress" in self.terms:
            to_attacked, to_defended = (progress(ball_before, ball, g, self.dt) for g in self._goal_point)
            values["ball_goal_progress"] = jnp.stack([0.5, -0.5]) * (to_attacked - to_defended)  # home's view
        for name, fn in self._per_agent.items():
            per_agent = jax.vmap(lambda b, a, act, side: fn(Transition(ball_before, ball, b, a, self._goal_point[side],
                                                                       act, self.dt)))(
                agents_before, agents, actions, jnp.asarray(self.agent_sides))
            values[name] = jnp.stack([per_agent[self.agent_sides == s].mean() for s in (0, 1)])
        metrics = {"success": success, **{name: values[name] for name in dict.fromkeys(self.terms)}}
        reward = sum(w * values[name] for w, name in zip(self._weights, self.terms))
        return metrics, reward, jnp.any(success > 0)

    # -- views -------------------------------------------------------------

    def observe(self, data) -> jax.Array:
        """[agents, observation_size]: each agent's own joints, the ball, then each teammate's and opponent's
        position and velocity, all in its side's frame."""
        layout, frame = self.layout, self.frame
        qpos, qvel = data.qpos[jnp.asarray(layout.agent_qpos)], data.qvel[jnp.asarray(layout.agent_qvel)]
        ball = [data.qpos[jnp.asarray(layout.ball_qpos)], data.qvel[jnp.asarray(layout.ball_qvel)]]
        planar = jnp.concatenate([qpos[:, :2], qvel[:, :2]], axis=1)  # x, y, vx, vy of each agent in the field

        def seen_by(i):
            others = planar[self._others[i]].ravel()
            if self.agent_sides[i] == 0:
                return jnp.concatenate([qpos[i], qvel[i], *ball, others])
            seen_ball = [turned_xy(b) if b.shape[0] else b for b in ball]
            return jnp.concatenate([frame.qpos(qpos[i]), frame.qvel(qvel[i]), *seen_ball, -others])

        return jnp.stack([seen_by(i) for i in range(len(self.agent_names))])

    def _ball(self, data) -> jax.Array:
        p = data.qpos[jnp.asarray(self.layout.ball_qpos)]
        return p if p.shape[0] == 3 else jnp.append(p, self.spec.ball.radius)

    def _agent_positions(self, data) -> jax.Array:
        """[agents, 3]: each ant's torso, or each point (at its radius' height)."""
        q = data.qpos[jnp.asarray(self.layout.agent_qpos)]
        if self._is_ant:
            return q[:, :3]
        return jnp.concatenate([q[:, :2], jnp.full((q.shape[0], 1), geometry.POINT_RADIUS)], axis=1)
