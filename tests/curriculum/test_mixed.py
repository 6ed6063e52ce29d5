"""Mixed training: variants built to one structure, stepped in one batch, each env on its own variant."""

from __future__ import annotations

import json

import imageio.v3 as iio
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from typer.testing import CliRunner

from fieldgen import curriculum
from fieldgen.cli import app
from fieldgen.compile.variants import PARK_DEPTH, VariantError, compile_variants
from fieldgen.curriculum.schedule import Mixed, Staged, sampling_weights
from fieldgen.env import FieldEnv
from fieldgen.schema import bundled_fields

runner = CliRunner()
FIELDS = bundled_fields()


def variants(tmp_path, base: str, stages: list[dict]):
    c = curriculum.write(tmp_path / "c", base, FIELDS[base], "list", curriculum.explicit(FIELDS[base], stages),
                         curriculum.Promotion())
    return c.specs()


@pytest.fixture(scope="module")
def walled(tmp_path_factory):
    """point_soccer with its side walls at x = +-3, at x = +-2, and with no walls at all."""
    specs = variants(tmp_path_factory.mktemp("walls"), "point_soccer",
                     [{"field.width": 6}, {"field.width": 4}, {"walls.enabled": False}])
    return FieldEnv(compile_variants(specs), auto_reset=False)


def test_variants_share_one_structure_with_absent_walls_parked(walled):
    models = [v_env.model() for v_env in walled.artifacts]
    assert len({(m.ngeom, m.nbody, m.nq) for m in models}) == 1
    names = [[m.geom(i).name for i in range(m.ngeom)] for m in models]
    assert names[0] == names[1] == names[2]
    wall = models[2].geom("wall_left")
    assert wall.pos[2] < -PARK_DEPTH / 2 and wall.rgba[3] == 0  # parked and invisible where walls are off
    assert abs(models[0].geom("wall_left").pos[0]) == pytest.approx(3.0)
    assert abs(models[1].geom("wall_left").pos[0]) == pytest.approx(2.0)
    widths = [m.cam_resolution[m.cam("top").id][0] for m in models]
    assert widths[0] > widths[1]  # each variant's top view frames its own field, 6 wide and then 4



def test_render_draws_each_state_in_its_own_variants_field(walled):
    """A trajectory crossing variants (an auto-reset into another) is drawn field by field: the top view of the
    6-wide variant is wider than the 4-wide one's, and frames come back in the trajectory's order."""
    keys = jax.random.split(jax.random.PRNGKey(0), 2)
    wide, narrow = (walled.reset_variant(k, v) for k, v in zip(keys, (0, 1)))
    frames = walled.render([wide, narrow, wide], camera="top", height=96)
    assert [f.shape[0] for f in frames] == [96, 96, 96]
    assert frames[0].shape[1] > frames[1].shape[1]
    np.testing.assert_array_equal(frames[0], frames[2])


def test_goal_reached_judges_by_each_variants_own_rule(tmp_path):
    """Hindsight scores a state as `step` does: by the variant's own success radius and ball."""
    specs = variants(tmp_path, "point_soccer", [{"task.success": {"kind": "ball_near_target", "radius": 0.5}},
                                               {"task.success": {"kind": "ball_near_target", "radius": 1.5}}])
    env = FieldEnv(compile_variants(specs), auto_reset=False)
    state = env.reset_variant(jax.random.PRNGKey(0), 0).obs[:env.state_dim]
    ball = np.asarray(state[np.asarray(env.goal_indices)])
    goal = jnp.asarray(ball + np.array([1.0, 0.0]))  # a metre from the ball
    assert float(env.goal_reached(state, goal, 0)) == 0.0
    assert float(env.goal_reached(state, goal, 1)) == 1.0
    assert float(env.goal_reached(state, goal)) == 1.0  # the last variant's rule by default

@pytest.mark.slow
def test_each_environment_pushes_its_ball_into_its_own_walls(walled):
    """One vmapped step over three geometries: a ball kicked sideways stops at its own wall, or runs on."""
    env = walled
    state = jax.vmap(env.reset_variant)(jax.random.split(jax.random.PRNGKey(0), 3), jnp.arange(3))
    ball = jnp.asarray(env.layout.ball_qpos)
    data = state.pipeline_state
    data = data.replace(qpos=data.qpos.at[:, ball].set(jnp.array([0.0, 1.5])),
                        qvel=data.qvel.at[:, ball].set(jnp.array([10.0, 0.0])))
    state = state.replace(pipeline_state=data)
    step = jax.jit(jax.vmap(env.step))
    xs = []
    for _ in range(30):
        state = step(state, jnp.zeros((3, env.action_size)))
        xs.append(np.asarray(state.pipeline_state.qpos[:, ball[0]]))
    reach = np.max(xs, axis=0)
    radius, half_wall = 0.2, 0.05
    assert 3.0 - half_wall - radius - 0.3 < reach[0] <= 3.0 - half_wall - radius + 0.08  # soft contact: cm deep
    assert 2.0 - half_wall - radius - 0.3 < reach[1] <= 2.0 - half_wall - radius + 0.08
    assert reach[2] > 3.5  # no walls: the ball runs past where they would be


def test_sampling_weights_favour_variants_being_learnt():
    w = np.asarray(sampling_weights(jnp.array([0.0, 0.5, 1.0, 0.2])))
    assert w.sum() == pytest.approx(1.0)
    assert w[1] > w[3] > w[0] == pytest.approx(w[2])
    np.testing.assert_allclose(sampling_weights(jnp.zeros(4)), 0.25)


def test_schedules_answer_what_the_loop_asks():
    """A mixed run re-weights its variants and never moves on; a staged run moves on once its promotion rule
    is met on the stage it trains, and never past its last stage."""
    from fieldgen.curriculum.contract import OneStage
    from fieldgen.curriculum.promotion import Promotion

    success = jnp.array([0.0, 0.5, 1.0])
    np.testing.assert_allclose(Mixed().variant_weights(success), sampling_weights(success))
    assert Mixed().next_stage([{"eval": 1, "stage": 0, "success_any": 1.0}], 0, 3) == 0
    staged = Staged(Promotion(threshold=0.5, window=1))
    assert staged.next_stage([{"eval": 1, "stage": 0, "success_any": 0.4}], 0, 3) == 0
    assert staged.next_stage([{"eval": 1, "stage": 0, "success_any": 0.6}], 0, 3) == 1
    assert staged.next_stage([{"eval": 1, "stage": 2, "success_any": 0.9}], 2, 3) == 2
    assert OneStage().next_stage([{"eval": 1, "stage": 0, "success_any": 1.0}], 0, 1) == 0
    np.testing.assert_allclose(OneStage().variant_weights(success), 1 / 3)


@pytest.mark.slow
def test_new_episodes_draw_their_variant_from_the_weights(walled):
    env = FieldEnv(walled.artifacts, episode_length=1)
    state = jax.vmap(env.reset)(jax.random.split(jax.random.PRNGKey(1), 512))
    weights = jnp.array([0.7, 0.0, 0.3])
    state = env.with_variant_weights(state, weights)
    state = jax.jit(jax.vmap(env.step))(state, jnp.zeros((512, env.action_size)))  # every episode ends and restarts
    share = np.bincount(np.asarray(state.info["variant"]), minlength=3) / 512
    np.testing.assert_allclose(share, weights, atol=0.07)
    assert np.all(np.asarray(state.info["variant_weights"]) == np.asarray(weights))


def test_variants_that_disagree_on_what_collides_are_refused(tmp_path):
    specs = variants(tmp_path, "point_soccer", [{}, {"obstacles.goalie.solid": False}])
    with pytest.raises(VariantError, match="geom 'obstacle_goalie' is solid in some variants"):
        compile_variants(specs)


def test_mixed_needs_a_curriculum(tmp_path):
    result = runner.invoke(app, ["train", "point_nav", "--mixed", "--out", str(tmp_path)])
    assert result.exit_code == 1
    assert "--mixed trains the stages of a curriculum folder" in " ".join(result.output.split())


@pytest.mark.slow
def test_mixed_training_reports_every_stage_and_resumes(tmp_path):
    """point_nav targets 1 and 3 away in one batch: per-stage metrics, weights, plot, video, prepare + resume."""
    made = runner.invoke(app, ["curriculum", "point_nav", "-o", str(tmp_path / "ring"),
                               "--stage", "task.target.radius=1", "--stage", "task.target.radius=3"])
    assert made.exit_code == 0, made.output
    sets = ["crl.hidden=[32,32]", "crl.repr_dim=8", "crl.batch_size=64", "crl.unroll_length=25",
            "crl.min_replay_rows=100", "crl.max_replay_rows=400", "crl.num_evals=2", "crl.eval_envs=8"]
    args = ["train", str(tmp_path / "ring"), "--mixed", "--steps", "4000", "--envs", "8", "--out",
            str(tmp_path / "runs"), *[x for s in sets for x in ("--set", s)]]
    prepared = runner.invoke(app, [*args, "--prepare"])
    assert prepared.exit_code == 0, prepared.output
    run = tmp_path / "runs" / "ring-mixed-crl-0"
    assert json.loads((run / "run.json").read_text())["mixed"] and not (run / "checkpoint.msgpack").exists()
    result = runner.invoke(app, ["train", "--resume", str(run)])
    assert result.exit_code == 0, result.output
    rows = [json.loads(line) for line in (run / "metrics.jsonl").read_text().splitlines()]
    assert [r["eval"] for r in rows] == [0, 1, 2]
    for row in rows:
        variants = row["variants"]
        assert row["last_stage_success_any"] == variants["success_any"][1]
        assert len(variants["weight"]) == 2 and sum(variants["weight"]) == pytest.approx(1.0, abs=1e-5)
        assert row["success_any"] == pytest.approx(sum(variants["success_any"]) / 2)
    header = (run / "metrics.csv").read_text().splitlines()[0].split(",")
    assert {"variants.success_any.1", "variants.success_any.2", "variants.weight.2"} <= set(header)
    text = " ".join(result.output.split())
    assert "success_any per stage at the end: 1." in text and "success_any on the last stage (ring_s02)" in text
    # success, time at goal, closest approach, where episodes go and losses, 500 x 360 pixels each, three a row
    assert iio.imread(run / "success.png").shape == (720, 1500, 4) and (run / "videos" / "eval_002.mp4").exists()
    assert sorted(p.name for p in (run / "stages").iterdir()) == ["01", "02"]


@pytest.mark.slow
def test_the_video_of_a_mixed_evaluation_is_of_its_last_variant(walled):
    """A mixed curriculum is judged on its last stage: its video must show that stage, not the first."""
    from fieldgen.agents import loop

    still = lambda obs: jnp.zeros((obs.shape[0], walled.action_size))  # noqa: E731
    _, (variant, done) = loop.evaluate_policy(walled, still, jax.random.PRNGKey(0), 6, lambda s: s.info["variant"])
    assert np.all(np.asarray(variant) == 2) and done.shape == (walled.episode_length,)
