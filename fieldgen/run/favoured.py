"""The levels a run of several variants favours now (an automatic or mixed curriculum), drawn: what the
sampler is training on at the run's last evaluation, each under its share of new episodes and its success;
for an automatic curriculum also its level buffer, read from `learner.msgpack`: which kick-off points of each
level episodes start from, and the success the sampler estimates there (a level's success in the metrics is
measured at its own kick-off, the hardest of its points)."""

from __future__ import annotations

import dataclasses
import textwrap
from pathlib import Path

import numpy as np

from fieldgen.curriculum.auto import HeldLevel
from fieldgen.run import record, session
from fieldgen.suggest import shell


@dataclasses.dataclass(frozen=True)
class BufferLevel(HeldLevel):
    """What one seed's level buffer holds of one level (curriculum.auto.HeldLevel), and the seed's line of it."""

    seed: int

    def text(self, levels: int) -> str:
        name = "the field itself" if self.level == levels - 1 else f"level {self.level + 1}"
        if self.episodes < 0.05:  # the sampler knows nothing here yet: its estimate is the prior's
            counted = f"no episode counted yet, success {span(*self.success)} (the prior)"
        else:  # older episodes count for less, so a count is seldom whole
            amount = f"{self.episodes:.1f}" if self.episodes < 10 else f"{self.episodes:,.0f}"
            counted = f"{amount} episodes counted, success {span(*self.success)}"
        return (f"seed {self.seed}, {name}: {self.points} point{'s' * (self.points > 1)} at kick-off "
                f"{span(*self.kickoff)}, {self.share:.0%} of new episodes, {counted}")


def span(low: float, high: float) -> str:
    """A range of values as the buffer's lines write it: "0.03-0.32", or one value where both ends agree."""
    return f"{low:.2f}" if f"{low:.2f}" == f"{high:.2f}" else f"{low:.2f}-{high:.2f}"


def level_buffer(run) -> list[BufferLevel]:
    """Each seed's level buffer after the run's last evaluation, level by level (`BufferLevel`); none for a
    run without kick-off points or without `learner.msgpack` yet. RunError where that file cannot be read."""
    from fieldgen.agents import checkpoint
    from fieldgen.curriculum.auto import buffer_shapes, held_levels

    learner, plan = run.folder / record.LEARNER, run.plan
    if not plan.kickoffs or not learner.is_file():
        return []
    try:
        sampling = checkpoint.load_tail(learner, buffer_shapes(len(run.seeds), plan.kickoffs))
    except checkpoint.CheckpointError as exc:
        raise record.RunError(str(exc)) from None
    if sampling is None:
        return []
    return [BufferLevel(**dataclasses.asdict(held), seed=seed) for k, seed in enumerate(run.seeds)
            for held in held_levels(plan.kickoffs, {name: kept[k] for name, kept in sampling.items()}, plan.sampler)]


def favoured_levels(folder: Path, camera: str, top: int = 6) -> tuple[bytes, str, list[str]]:
    """(PNG bytes of the `top` stages with the largest share of new episodes after the last evaluation, most
    favoured first, a line saying what was drawn, a line for each level of each seed's buffer); RunError for
    a run that weighs no variants or has not been evaluated."""
    from fieldgen.render import contact_sheet, render_pose

    run = session.open_run(folder, load_state=False)
    if not run.plan.mixed:
        raise record.RunError(f"{folder} trains one stage at a time; --levels draws the levels a mixed or automatic "
                              "curriculum weighs (fieldgen train SPEC --curriculum auto)")
    if not run.rows:
        raise record.RunError(f"{folder} has no evaluation yet: the levels are weighed after each one; draw all of "
                              f"them with fieldgen render {shell(folder)}, or train it first")
    last = [r for r in run.rows if r["eval"] == run.rows[-1]["eval"]]  # each with its levels' results: open_run checks
    share = np.mean([r["variants"]["weight"] for r in last], axis=0)  # in [0, 1]: record.read_metrics checks
    measured = np.array([r["variants"]["success_any"] for r in last], dtype=float)  # NaN: a level no episode played
    success = [np.nanmean(column) if np.isfinite(column).any() else None for column in measured.T]
    coordinates = run.plan.levels
    order = [int(k) for k in np.argsort(-share, kind="stable")[:top]]
    kind = run.plan.variant_name
    images, titles = [], []
    for k in order:
        images.append(render_pose(run.envs[k].artifact.model(), camera=camera, height=240))
        where = textwrap.fill(level_text(coordinates[k]), 40) if coordinates else ""  # a title's width
        name = "the field itself" if k == len(run.envs) - 1 else f"{kind} {k + 1}"
        measured = "not measured" if success[k] is None else f"{success[k]:.2f}"
        titles.append(f"{name}: {share[k]:.0%} of episodes, success {measured}" + (f"\n{where}" if where else ""))
    said = (f"the {len(order)} most played of {len(run.envs)} levels after evaluation {last[0]['eval']} "
            f"({last[0]['env_steps']:,} env steps)")
    buffer = level_buffer(run)
    for i, k in enumerate(order):
        held = [b for b in buffer if b.level == k]
        if held:  # where its episodes start, over every seed's buffer
            titles[i] += f"\nplayed at kick-off {span(min(b.kickoff[0] for b in held), max(b.kickoff[1] for b in held))}"
    if buffer:
        said += ("; the level buffer (success at each level's own kick-off is in the titles; estimated by the "
                 "sampler over the points it plays here):")
    return contact_sheet(images, titles), said, [b.text(len(run.envs)) for b in buffer]


def level_text(coordinates: dict) -> str:
    """A level's place on its curriculum's axes, as its drawings say it: "kickoff 0.29, walls 0.00"."""
    return ", ".join(f"{axis} {value:.2f}" for axis, value in coordinates.items())


def level_captions(folder: Path, count: int) -> list[str] | None:
    """Under each of an automatic curriculum run's `count` built levels, its place on the axes (run.json's
    `levels`); None for any other folder."""
    try:
        coordinates = record.read_run(folder).levels
    except record.RunError:
        return None
    return [level_text(c) for c in coordinates] if len(coordinates) == count else None
