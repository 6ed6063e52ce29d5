"""The pictures of a field: the top view frames the field in its own aspect, in colours that stay apart
for colour-blind readers, with the agent and the ball marked."""

from __future__ import annotations

import numpy as np
import pytest

from fieldgen.compile.artifact import compile_spec
from fieldgen.render import frame_size, render_pose, render_rollout
from fieldgen.schema import bundled_fields, load_spec

# Machado, Oliveira and Fernandes (2009), severity 1, on linear RGB.
COLOUR_BLINDNESS = {
    "deuteranopia": [[0.367322, 0.860646, -0.227968], [0.280085, 0.672501, 0.047413], [-0.011820, 0.042940, 0.968881]],
    "protanopia": [[0.152286, 1.052583, -0.204868], [0.114503, 0.786281, 0.099216], [-0.003882, -0.048116, 1.051998]],
    "tritanopia": [[1.255528, -0.076749, -0.178779], [-0.078411, 0.930809, 0.147602], [0.004733, 0.691367, 0.303900]],
}


def model(name: str):
    return compile_spec(load_spec(bundled_fields()[name])).model()


@pytest.fixture(scope="module")
def soccer():
    """point_soccer from above: 6 wide, 8 long, a goal at the far end with the target in it."""
    return render_pose(model("point_soccer"), camera="top").astype(int)


def regions(image) -> dict:
    """Pixels by what they show, told apart by hue."""
    r, g, b = image[..., 0], image[..., 1], image[..., 2]
    return {
        "floor": (np.ptp(image, axis=-1) < 4) & (r < 120),
        "goal": (b > r + 100) & (b > g + 40),
        "target": (r > g + 80) & (g > b + 30),
        "ball": (r > 180) & (g > 180) & (b < 120),
        "agent": (r > g + 40) & (b > g + 20),
    }


def test_a_portrait_field_gives_a_portrait_top_view_framed_with_a_margin(soccer):
    height, width, _ = soccer.shape
    assert height == 480 and width < 400 and width % 16 == 0
    floor = regions(soccer)["floor"]
    edges = np.concatenate([floor[:8].ravel(), floor[-8:].ravel(), floor[:, :8].ravel(), floor[:, -8:].ravel()])
    assert edges.all()  # nothing of the field, its walls or goal touches the frame
    goal_rows = np.nonzero(regions(soccer)["goal"].any(axis=1))[0]
    assert 8 < goal_rows.min() < 0.15 * height  # the goal near the top, clear of the edge


def test_a_landscape_field_gives_a_landscape_top_view(write_spec):
    wide = compile_spec(load_spec(write_spec("extends: point_nav\nname: wide\nfield: {length: 8, width: 24}\n")))
    height, width = frame_size(wide.model(), "top", 480)
    assert height == 480 and 2.5 < width / height < 3.1  # 24 x 8 and a margin all round
    assert frame_size(wide.model(), "follow", 240) == (240, 320)  # the perspective view stays 4:3


def test_target_goal_ball_and_agent_stand_out_for_colour_blind_readers(soccer):
    parts = regions(soccer)
    for name, mask in parts.items():
        assert mask.sum() > 50, f"no {name} in the top view"
    goal_rows, goal_cols = np.nonzero(parts["goal"])
    target_rows, target_cols = np.nonzero(parts["target"])
    assert goal_rows.min() <= target_rows.mean() <= goal_rows.max()  # the target shows inside the goal
    assert goal_cols.min() <= target_cols.mean() <= goal_cols.max()
    linear = {name: (soccer[mask].mean(axis=0) / 255) ** 2.2 for name, mask in parts.items()}
    for vision, matrix in [("normal", np.eye(3)), *COLOUR_BLINDNESS.items()]:
        seen = {name: 255 * np.clip(np.asarray(matrix) @ c, 0, 1) ** (1 / 2.2) for name, c in linear.items()}
        for a, b in [("target", "goal"), ("target", "floor"), ("goal", "floor"), ("ball", "floor"),
                     ("agent", "floor"), ("ball", "target"), ("agent", "target")]:
            assert np.linalg.norm(seen[a] - seen[b]) > 60, f"{a} and {b} look alike under {vision}"


def test_the_top_view_marks_the_agent_and_ball_wherever_they_go():
    m = model("point_soccer")
    home = m.key("home").qpos.copy()
    moved = home.copy()
    moved[:2] += (2.0, -2.0)  # the point to the lower right
    target = m.body("target").pos[None, None]
    before, after = (render_rollout(m, q[None], target, camera="top")[0] for q in (home, moved))
    agent_before, agent_after = (np.argwhere(regions(f.astype(int))["agent"]).mean(axis=0) for f in (before, after))
    assert agent_after[1] > agent_before[1] + 40 and agent_after[0] > agent_before[0] + 40  # rows grow downward
    disc = regions(before.astype(int))["agent"].sum()
    assert disc > np.pi * (0.25 * before.shape[0] / m.cam("top").fovy[0]) ** 2  # more than the bare point


@pytest.mark.parametrize("length,width", [(500, 500), (400, 300), (500, 10), (170, 100)])
def test_a_field_as_large_as_the_schema_allows_builds_and_renders(write_spec, tmp_path, length, width):
    """mujoco takes no camera fovy of 180 or more, which an orthographic top view of a field over about 160 m
    would need: such a field is framed in perspective, in the field's aspect, with the agent and ball marked.
    Before: the build of any of these died in the renderer with 'fovy too large'."""
    from fieldgen.compile.build import build

    spec = write_spec(f"extends: soccer_v2\nname: large\nfield: {{length: {length}, width: {width}}}\n"
                      "goal: {distance: 2}\n")
    built = build(spec, tmp_path / "build")
    assert (built.out_dir / "preview.png").exists()
    large = built.artifact.model()
    frame = render_pose(large, camera="top")
    height, frame_width = frame_size(large, "top", 480)
    assert frame.shape == (height, frame_width, 3) and abs(frame_width / height - width / length) < 0.2
    floor = np.median(frame.reshape(-1, 3), axis=0)
    marks = np.abs(frame.astype(int) - floor).max(axis=-1) > 60  # the agent's and the ball's, in colour on grey
    assert 20 < marks.sum() < 0.05 * marks.size
