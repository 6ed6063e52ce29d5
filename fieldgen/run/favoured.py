"""The levels a run of several variants favours now (an automatic or mixed curriculum), drawn: what the
sampler is training on at the run's last evaluation, each under its share of new episodes and its success."""

from __future__ import annotations

import textwrap
from pathlib import Path

import numpy as np

from fieldgen.run import record, session


def favoured_levels(folder: Path, camera: str, top: int = 6) -> tuple[bytes, str]:
    """(PNG bytes of the `top` stages with the largest share of new episodes after the last evaluation, most
    favoured first, a line saying what was drawn); RunError for a run that weighs no variants or has not
    been evaluated."""
    from fieldgen.render import contact_sheet, render_pose

    run = session.open_run(folder, load_state=False)
    if not run.mixed:
        raise record.RunError(f"{folder} trains one stage at a time; --levels draws the levels a mixed or automatic "
                              "curriculum weighs (fieldgen train SPEC --curriculum auto)")
    if not run.rows:
        raise record.RunError(f"{folder} has no evaluation yet: the levels are weighed after each one; draw all of "
                              f"them with fieldgen render {folder}, or train it first")
    last = [r for r in run.rows if r["eval"] == run.rows[-1]["eval"]]
    share = np.mean([r["variants"]["weight"] for r in last], axis=0)
    success = np.mean([r["variants"]["success_any"] for r in last], axis=0)
    coordinates = record.read_run(folder).levels
    order = [int(k) for k in np.argsort(-share, kind="stable")[:top]]
    kind = run.variant_name
    images, titles = [], []
    for k in order:
        images.append(render_pose(run.envs[k].artifact.model(), camera=camera, height=240))
        where = textwrap.fill(level_text(coordinates[k]), 40) if coordinates else ""  # a title's width
        name = "the field itself" if k == len(run.envs) - 1 else f"{kind} {k + 1}"
        titles.append(f"{name}: {share[k]:.0%} of episodes, success {success[k]:.2f}" + (f"\n{where}" if where else ""))
    said = (f"the {len(order)} most played of {len(run.envs)} levels after evaluation {last[0]['eval']} "
            f"({last[0]['env_steps']:,} env steps)")
    return contact_sheet(images, titles), said


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
