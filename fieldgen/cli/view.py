"""`fieldgen view`: a field, or a run's or an exported policy's play on it, in MuJoCo's interactive viewer."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Optional

import typer

from fieldgen import limits, stops
from fieldgen.cameras import CAMERAS, FREE
from fieldgen.cli.app import app, bounded, choice, fail, field_source, out
from fieldgen.suggest import shell


@app.command()
def view(
    source: Annotated[str, typer.Argument(
        metavar="FIELD|RUN|POLICY", help="a YAML file, bundled field name or build folder; a run folder (its "
                                         "policy at its last evaluation plays); or a folder of fieldgen export")],
    field: Annotated[Optional[str], typer.Option(
        metavar="SPEC", help="the field a policy plays on (YAML file, bundled name or build folder) [default: the "
                             "run's own, or the field as written that it keeps where its recipe trained it on another "
                             "form of it; for an exported policy, the bundled field it names]")] = None,
    seed: Annotated[Optional[int], typer.Option(parser=bounded("--seed", limits.SEED), metavar="SEED",
                                                help="which of a run's seeds plays (default: its first)")] = None,
    camera: Annotated[str, typer.Option(help="the view: free turns with the mouse; the others are the scene's",
                                        **choice("camera", (FREE, *CAMERAS)))] = FREE,
) -> None:
    """Watch a field, or a policy play on it, live in MuJoCo's interactive viewer.

    One environment steps in real time on the CPU through the environment's own reset and step, so what the
    policy observes is what training gave it. Space pauses and resumes; Backspace starts a new episode (goal,
    ball and kick-off drawn as a reset draws them); the viewer's own keys and mouse work as usual.

    Example: fieldgen view soccer_v1
    Example: fieldgen view runs/point_nav-crl-0
    Example: fieldgen view policies/point_nav --field my_nav.yaml
    Example: fieldgen view runs/soccer_2v2-ppo-0   (a self-play run: its policy plays both sides)
    """
    from fieldgen.view import no_display_reason

    _check_arguments(source, field, seed)
    reason = no_display_reason()
    if reason is not None:  # said before anything loads
        _no_display(reason, source)
    env, act = _playing(source, field, seed)
    from fieldgen.view import KEYS, NoDisplay, Player, open_viewer, play

    player = Player(env, act)
    try:
        handle = open_viewer(player, camera)
    except NoDisplay as exc:
        _no_display(str(exc), source)
    out.print(f"viewing {env.spec.name}" + (" played by the policy" if act is not None else "") +
              f" at {1 / env.dt:g} control steps a second; {KEYS}", soft_wrap=True)
    try:
        play(handle, player, camera)
    except KeyboardInterrupt:
        handle.close()
        raise typer.Exit(stops.status()) from None


def _check_arguments(source: str, field: str | None, seed: int | None) -> None:
    """Refuse a source that names nothing, or an option it does not take, before the display is looked for:
    without one, advice to draw what `source` names would hide the mistake."""
    from fieldgen.compile.artifact import META
    from fieldgen.policy_folder import DESCRIPTION
    from fieldgen.run.record import RUN

    folder = Path(source)
    if (folder / RUN).is_file():
        return
    if seed is not None:
        fail(f"--seed picks one of a run's seeds; {source} is not a run folder (it holds no {RUN})")
    if (folder / DESCRIPTION).is_file():
        return
    if folder.is_dir() and not (folder / META).is_file():  # else told only that it is no built field
        fail(f"{source} holds nothing fieldgen view plays: no {META} (a field fieldgen build wrote), {RUN} (a run "
             f"fieldgen train wrote) or {DESCRIPTION} (a policy fieldgen export wrote); name one of those folders, a "
             "spec file or a bundled field")
    if field is not None:
        fail(f"--field names the field a policy plays on; {source} is a field itself (no {RUN} or {DESCRIPTION} in "
             "it)")
    field_source(source, "a build, run or policy folder")  # a field that is there, else refused with the nearest names


def _no_display(reason: str, source: str) -> None:
    """No viewer: what draws the same without a display, for what `source` is (a run, an exported policy, a field)."""
    from fieldgen.policy_folder import DESCRIPTION
    from fieldgen.run.record import RUN, has_trained

    folder = Path(source)
    if (folder / RUN).is_file() and not has_trained(folder):  # eval would refuse it as well
        instead = (f"{source} has not trained yet: `fieldgen train --resume {shell(source)}` trains it, then `fieldgen eval "
                   f"{source}` writes videos of its policy")
    elif (folder / RUN).is_file():
        instead = f"`fieldgen eval {shell(source)}` writes videos of its policy"
    elif (folder / DESCRIPTION).is_file():
        instead = ("`fieldgen eval RUN` writes videos of the run it was exported from, and `fieldgen render FIELD "
                   "-o field.png` draws the field it plays on")
    else:
        instead = (f"`fieldgen render {shell(source)} -o field.png` draws the field, `fieldgen eval RUN` writes videos of "
                   "a run's policy")
    fail(f"no display here ({reason}), so no viewer opens; {instead}")


def _playing(source: str, field: str | None, seed: int | None):
    """(environment, policy's act or None) of what `source` names; a policy with the environment it plays on."""
    import jax

    import fieldgen
    from fieldgen.agents.config import ConfigError
    from fieldgen.compile.artifact import ArtifactError
    from fieldgen.policy_folder import DESCRIPTION, PolicyError, load_policy, read_description
    from fieldgen.run import record, selfplay, session
    from fieldgen.run.export import learned_policy, team_policy
    from fieldgen.schema import SpecError, bundled_fields

    folder = Path(source)
    try:
        if selfplay.is_team_run(folder):  # its learner plays every agent of both sides, on its own field
            if field is not None:
                fail(f"{source} is a self-play run: it plays on its own team field alone; leave out --field")
            run = selfplay.open_run(folder)
            _, policy, _ = team_policy(run, seed)
            return run.env, jax.tree_util.Partial(type(policy).__call__, policy)
        if (folder / record.RUN).is_file():
            run = session.open_run(folder, learned=True)
            if field is not None or run.judged is not None:  # by default where its figures are judged
                run = session.on_field(run, field_source(field) if field is not None else run.judged)
            _, policy, _ = learned_policy(run, seed)
            return run.env, jax.tree_util.Partial(type(policy).__call__, policy)
        if (folder / DESCRIPTION).is_file():
            about = read_description(folder)
            if field is None and about.field not in bundled_fields():
                fail(f"{folder / DESCRIPTION} names field '{about.field}', which is not a bundled one; name its YAML "
                     f"file or build folder: fieldgen view {shell(source)} --field SPEC")
            act = load_policy(folder)
            env = fieldgen.make(field_source(field or about.field))
            if (tuple(about.observation_names), tuple(about.action_names)) != (env.observation_names, env.action_names):
                fail(f"{folder} observes or acts differently from {env.spec.name} ({len(about.observation_names)} "
                     f"observations and {len(about.action_names)} actions against {env.observation_size} and "
                     f"{env.action_size}, or other names); a policy plays only on a field of its layout: --field SPEC")
            return env, act
        return fieldgen.make(field_source(source)), None  # _check_arguments refused any --field or --seed
    except (SpecError, ArtifactError, ConfigError, record.RunError, PolicyError) as exc:
        fail(str(exc))
