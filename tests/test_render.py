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
        "goal": (b > r + 100) & (b > g + 40) & (r < 60),  # not the walls' lighter sky blue
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
    assert_apart(soccer, parts, [("target", "goal"), ("target", "floor"), ("goal", "floor"), ("ball", "floor"),
                                 ("agent", "floor"), ("ball", "target"), ("agent", "target")])


def assert_apart(image, parts: dict, pairs: list[tuple[str, str]]) -> None:
    """Each pair of parts' mean colours differ clearly, in normal vision and under each colour blindness."""
    linear = {name: (image[mask].mean(axis=0) / 255) ** 2.2 for name, mask in parts.items()}
    for vision, matrix in [("normal", np.eye(3)), *COLOUR_BLINDNESS.items()]:
        seen = {name: 255 * np.clip(np.asarray(matrix) @ c, 0, 1) ** (1 / 2.2) for name, c in linear.items()}
        for a, b in pairs:
            assert np.linalg.norm(seen[a] - seen[b]) > 60, f"{a} and {b} look alike under {vision}"


def test_walls_and_the_goalie_show_from_above_apart_from_the_lines_and_the_rest():
    """soccer_v2 from above: its side walls stand on the white boundary lines and its goalie before the goal;
    both show in colours of the palette (black, sky blue), not as lines or a dark dash on the dark floor."""
    image = render_pose(model("soccer_v2"), camera="top").astype(int)
    height, width, _ = image.shape
    r, g, b = image[..., 0], image[..., 1], image[..., 2]
    parts = {**regions(image), "walls": image.max(axis=-1) < 40, "goalie": (b > 200) & (g > 170) & (r < 140),
             "lines": (r > 200) & (g > 200) & (b > 200)}
    rows, cols = np.nonzero(parts["walls"])
    assert cols.min() < 0.1 * width and cols.max() > 0.9 * width and rows.max() - rows.min() > 0.8 * height
    rows, cols = np.nonzero(parts["goalie"])
    assert len(rows) > 50 and abs(cols.mean() - width / 2) < 0.05 * width and rows.mean() < 0.3 * height
    assert_apart(image, parts, [("walls", "lines"), ("walls", "floor"), ("walls", "goal"), ("goalie", "floor"),
                                ("goalie", "walls"), ("goalie", "goal"), ("goalie", "target"), ("goalie", "lines"),
                                ("goalie", "ball"), ("goalie", "agent")])


def test_the_preview_has_a_legend_of_the_colours_its_field_shows():
    """A strip under the two views names each colour in a swatch of it: those of the field's parts, only."""
    from fieldgen.compile.scene import RGBA
    from fieldgen.render import LEGEND_HEIGHT, preview

    def swatches(name):
        strip = preview(model(name))[-LEGEND_HEIGHT:].astype(int)
        found = {part for part in ("wall", "obstacle", "ball", "goal_area", "target", "line")
                 if (np.abs(strip - np.round(255 * np.asarray(RGBA[part][:3]))).max(axis=-1) <= 1).sum() > 20}
        return found

    assert swatches("soccer_v2") == {"wall", "obstacle", "ball", "goal_area", "target", "line"}
    assert swatches("point_nav") == {"target", "line"}  # no ball, goal, walls or obstacles there


def test_a_legend_narrower_than_its_entries_wraps_them_into_rows():
    """One view alone (a third of the preview's width) still names every colour: its legend takes two rows."""
    from fieldgen.render import LEGEND_HEIGHT, legend

    soccer = model("soccer_v2")
    wide, narrow = legend(soccer, 1024), legend(soccer, 384)
    assert wide.shape == (LEGEND_HEIGHT, 1024, 3)
    assert narrow.shape[0] > LEGEND_HEIGHT and narrow.shape[1] == 384
    inked = (narrow.astype(int) - 51).any(axis=-1)  # not the strip's grey background
    assert inked[:, :8].sum() == 0 and inked[:, -8:].sum() == 0  # nothing cut at either edge


def test_captions_tell_fields_apart_by_goal_goalie_and_target():
    from fieldgen.curriculum.sheet import field_caption
    from fieldgen.schema import bundled_fields, load_spec

    fields = bundled_fields()
    assert field_caption(load_spec(fields["v2_wide_goalie"])) == "field 32 wide, 40 long; goal 20 ahead, 8 wide; goalie 3 wide"
    assert field_caption(load_spec(fields["ant_nav"])) == "field 26 wide, 26 long; target 10 away"


def test_fields_of_different_sizes_drawn_at_one_scale(write_spec):
    """same_scale frames every model alike, so a field twice as wide is drawn twice as wide."""
    from fieldgen.render import same_scale

    small, large = (compile_spec(load_spec(write_spec(f"extends: point_nav\nname: f{n}\nfield: {{length: {n}, "
                                                      f"width: {n}}}\n", f"f{n}.yaml"))).model() for n in (10, 20))
    same_scale([small, large])
    widths = []
    for m in (small, large):
        image = render_pose(m, camera="top").astype(int)
        cols = np.nonzero(((image > 200).all(axis=-1)).any(axis=0))[0]  # the white boundary lines
        widths.append(cols.max() - cols.min())
        assert image.shape == (480, 480, 3) and (image[:4] < 120).all()  # floor up to the frame's edge
    assert widths[1] == pytest.approx(2 * widths[0], rel=0.05)
    # a field framed in perspective (too large for an orthographic view) leaves every view as it is
    vast = compile_spec(load_spec(write_spec("extends: point_nav\nname: vast\nfield: {length: 400, width: 400}\n",
                                             "vast.yaml"))).model()
    before = [(m.cam("top").pos.copy(), m.cam("top").fovy.copy()) for m in (small, vast)]
    same_scale([small, vast])
    for m, (pos, fovy) in zip((small, vast), before):
        assert (m.cam("top").pos == pos).all() and (m.cam("top").fovy == fovy).all()


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


def test_a_curriculum_sheet_draws_its_stages_at_one_scale_with_their_sizes(monkeypatch):
    """point_nav_to_far's fields grow from 10 to 40 wide: drawn at one scale, each over its size."""
    from pathlib import Path

    from fieldgen import curriculum
    from fieldgen.curriculum import sheet

    drawn = {}
    monkeypatch.setattr(sheet, "contact_sheet", lambda images, titles, captions: drawn.update(
        images=images, captions=captions) or b"")
    sheet.stage_sheet(curriculum.load(Path(__file__).parents[1] / "curricula" / "point_nav_to_far"), "top")
    assert [caption.split(";")[0] for caption in drawn["captions"]] == [f"field {n} wide, {n} long"
                                                                         for n in (10, 20, 30, 40)]
    assert all("; target " in caption for caption in drawn["captions"])  # where each stage's target lies
    assert len({image.shape for image in drawn["images"]}) == 1
    lines = [(image.min(axis=-1) > 115) & (np.ptp(image, axis=-1) < 20) for image in drawn["images"]]  # light grey
    spans = [np.ptp(np.nonzero(line.any(axis=0))[0]) for line in lines]
    assert spans[-1] == pytest.approx(4 * spans[0], rel=0.1)  # the white boundary lines, 40 against 10 wide


@pytest.fixture(scope="module")
def point_env():
    import jax

    from fieldgen.env.field import FieldEnv

    env = FieldEnv(compile_spec(load_spec(bundled_fields()["point_soccer"])))
    return env, jax.jit(env.reset)(jax.random.PRNGKey(0))


def test_environment_renders_a_state_or_a_trajectory_at_the_size_asked(point_env):
    env, state = point_env
    assert [f.shape for f in env.render([state, state], height=96, width=128)] == [(96, 128, 3)] * 2
    assert env.render([state], 64, 80)[0].shape == (64, 80, 3)  # brax's order: height, width, camera
    (frame,) = env.render(state, camera="top", height=96)  # one state; the top view's own aspect
    assert frame.shape == (96, *frame_size(env.mj_model, "top", 96)[1:], 3)


@pytest.mark.parametrize("kwargs, says", [
    (dict(trajectory=[]), "given none"),
    (dict(camera="side"), "cameras top, follow"),
    (dict(width=5000), "16 to 640 pixels wide"),
    (dict(height=2.5), "pixels high"),
    (dict(batched=True), "take environment j of a batch"),
])
def test_environment_render_refuses_what_it_cannot_draw_in_a_sentence(point_env, kwargs, says):
    import jax

    env, state = point_env
    if kwargs.pop("batched", False):
        kwargs["trajectory"] = [jax.tree.map(lambda x: x[None].repeat(2, 0), state)]
    kwargs.setdefault("trajectory", [state])
    with pytest.raises(ValueError, match=says):
        env.render(**kwargs)


def test_a_contact_sheet_wraps_a_caption_wider_than_its_panel_and_makes_room_for_it():
    """Three stages' captions side by side ran into each other: a long one is wrapped, its row taller."""
    import io

    import imageio.v3 as iio

    from fieldgen.render import contact_sheet

    images = [np.full((60, 40, 3), 128, np.uint8)] * 3
    short = iio.imread(io.BytesIO(contact_sheet(images, ["a", "b", "c"], captions=["field 16 wide"] * 3)))
    caption = "field 32 wide, 40 long; goal 20 ahead, 8 wide; goalie 1.5 wide; walls 0.6 high"
    long = iio.imread(io.BytesIO(contact_sheet(images, ["a", "b", "c"], captions=[caption] * 3)))
    assert long.shape[0] > short.shape[0]  # the wrapped lines below the panels
    assert long.shape[1] <= 3 * 320  # three panels of 3.2 inches at 100 dpi: no caption reaches past the sheet
    ink = (long[..., :3].min(axis=-1) < 100)  # the captions' dark text on white
    gaps = ~ink[short.shape[0] - 20:].any(axis=0)  # columns with no caption text in the caption band
    runs = np.flatnonzero(np.diff(gaps.astype(int)) == 1)  # where a text span ends and a gap begins
    assert len(runs) >= 3  # three separate spans of text, none run into the next
