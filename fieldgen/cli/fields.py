"""Commands on fields: validate, build, render, curriculum, list, schema, bench."""

from __future__ import annotations

import json
from collections import Counter
from pathlib import Path
from typing import Annotated, Optional

import typer
from rich.table import Column, Table
from rich.text import Text

from fieldgen import files, limits
from fieldgen.cli.app import (SpecArg, app, bounded, choice, count, err, fail, field_source, numeric, os_problem, out,
                              spec_path)
from fieldgen.cameras import CAMERAS
from fieldgen.schema import SpecError, bundled_fields, geometry, load_spec
from fieldgen.suggest import did_you_mean, shell


@app.command()
def validate(specs: Annotated[list[str], typer.Argument(
        metavar="SPEC", help="YAML files, bundled field names or curriculum folders")]) -> None:
    """Check field specs (or a curriculum's stages) and report every problem with file:line:column and key path.

    Example: fieldgen validate fields/soccer_v2.yaml my_field.yaml
    """
    from fieldgen import curriculum

    failed = 0
    for ref in specs:
        if curriculum.is_curriculum(Path(ref)):
            try:
                stages = curriculum.load(Path(ref)).stages
            except curriculum.CurriculumError as exc:
                failed += 1
                err.print(str(exc), highlight=False)
                continue
            out.print(Text.assemble(("ok", "green"), f" {ref}: {len(stages)} stages, {stages[0].name} to "
                                                     f"{stages[-1].name}"))
            continue
        try:
            spec = load_spec(spec_path(ref))
        except SpecError as exc:
            failed += 1
            err.print(str(exc), highlight=False)
            continue
        out.print(Text.assemble(("ok", "green"), f" {ref}: {spec.name}"))
        if note := geometry.goal_behind_wall(spec):
            out.print(Text(f"note: {note}", style="yellow"))
    if failed:
        raise typer.Exit(1)


@app.command()
def build(
    specs: Annotated[list[str], typer.Argument(metavar="SPEC", help="YAML files or bundled field names")],
    out_dir: Annotated[Path, typer.Option("--out", "-o", metavar="DIR",
                                          help="where build/<name>/ folders go")] = Path("build"),
    force: Annotated[bool, typer.Option(help="rebuild even when the build is current")] = False,
    preview: Annotated[bool, typer.Option(help="render preview.png")] = True,
) -> None:
    """Compile specs to build/<name>/: scene.xml, field.json and preview.png.

    A build whose inputs are unchanged is reused (cache hit).
    Example: fieldgen build fields/soccer_v2.yaml --out build
    """
    from fieldgen import curriculum
    from fieldgen.compile.build import build as run_build
    from fieldgen.files import FolderError
    from fieldgen.render import RenderError

    failed = 0
    for ref in specs:
        try:
            if curriculum.is_curriculum(Path(ref)):
                failed += _build_curriculum(Path(ref), out_dir, preview, force)
                continue
            result = run_build(spec_path(ref), out_dir, preview=preview, force=force)
        except SpecError as exc:
            failed += 1
            err.print(str(exc), highlight=False)
            continue
        except RenderError as exc:
            fail(f"{exc}; or build without preview.png: fieldgen build {' '.join(specs)} --no-preview")
        except FolderError as exc:
            fail(str(exc))
        except OSError as exc:
            fail(f"{os_problem(exc)}; any earlier build there is unchanged: {files.way_on(out_dir, '--out', exc, said=True)}")
        _report(result)
    if failed:
        raise typer.Exit(1)


def _build_curriculum(folder: Path, out_dir: Path, preview: bool, force: bool) -> int:
    """Build every stage; one table row each. Returns 1 on failure."""
    from fieldgen import curriculum
    from fieldgen.compile.build import build as run_build

    try:
        c = curriculum.load(folder)
    except curriculum.CurriculumError as exc:
        err.print(Text.assemble(("error:", "bold red"), f" {exc}"), highlight=False)
        return 1
    table = Table("stage", "name", "build", "geoms", "contact pairs", "seconds", title=f"{folder} ({c.kind})")
    for i, path in enumerate(c.spec_paths(), 1):
        result = run_build(path, out_dir, preview=preview, force=force)
        meta = json.loads((result.out_dir / "field.json").read_text())
        table.add_row(str(i), meta["name"], "cache hit" if result.cache_hit else "built", str(meta["model"]["ngeom"]),
                      str(len(meta["contact_pairs"])), f"{result.seconds:.2f}")
    out.print(table)
    return 0


def _report(result) -> None:
    meta = json.loads((result.out_dir / "field.json").read_text())  # written by the build: no recompiling here
    model = meta["model"]
    state = ("cache hit", "yellow") if result.cache_hit else ("built", "green")
    out.print(Text.assemble(state, " ", (meta["name"], "bold"),
                            f" -> {result.out_dir}/  ({result.seconds:.2f} s, hash {meta['hash']})"))
    table = Table(show_header=False, box=None, padding=(0, 2))
    table.add_row("model", f"{model['nbody']} bodies, {model['ngeom']} geoms, nq {model['nq']}, nv {model['nv']}, "
                  f"nu {model['nu']}")
    slices = ", ".join(f"{k} {a}:{b}" for k, a, b in ((k, *v) for k, v in meta["observation"]["slices"].items()))
    table.add_row("observation", f"{meta['observation']['size']} = {slices}")
    table.add_row("goal", f"state_dim {meta['state_dim']}, goal_indices {meta['goal_indices']}")
    table.add_row("task", f"success {meta['success']['kind']}; reward "
                  + " + ".join(f"{t['weight']:g}*{t['term']}" for t in meta["reward"]))
    pairs = meta["contact_pairs"]
    kinds = Counter(" - ".join(sorted(_role(g) for g in p)) for p in pairs)
    table.add_row("contact pairs", f"{len(pairs)}: " + ", ".join(f"{k} x{n}" for k, n in sorted(kinds.items())))
    out.print(table)


def _role(geom: str) -> str:
    for prefix in ("wall", "obstacle", "post", "crossbar"):
        if geom.startswith(prefix):
            return "goal frame" if prefix == "crossbar" else prefix
    return "foot" if geom.endswith("_foot") else geom


@app.command()
def render(
    spec: SpecArg,
    output: Annotated[Optional[Path], typer.Option("-o", "--output", metavar="FILE", show_default=False,
                                                   help="PNG file to write [default: field.png; with --levels, "
                                                        "levels.png in the run's folder]")] = None,
    camera: Annotated[str, typer.Option(help="the view; both: side by side",
                                        **choice("camera", (*CAMERAS, "both")))] = "top",
    levels: Annotated[bool, typer.Option("--levels", help="SPEC is a run of an automatic (or mixed) curriculum: "
                                                          "draw the levels it favours now, each with its share "
                                                          "of new episodes and its success")] = False,
) -> None:
    """Render a field to a PNG, headless.

    Example: fieldgen render fields/soccer_v2.yaml -o v2.png --camera follow
    Example: fieldgen render runs/soccer_v2-auto-crl-0 --levels -o levels.png
    Example: fieldgen render runs/soccer_v2-auto-crl-0 -o all_levels.png  (every level the run has built)
    """
    import numpy as np

    from fieldgen.compile.artifact import ArtifactError, compile_spec, load_artifact
    from fieldgen.files import RENDER, check_file, write_file
    from fieldgen.render import RenderError, legend, png_bytes, preview, render_pose
    from fieldgen import curriculum

    if output is not None and output.suffix.lower() != ".png":
        fail(f"-o {output}: fieldgen render writes PNG images; give the file the .png ending, "
             f"such as {output.with_suffix('.png')}")
    if levels:
        from fieldgen.run.favoured import favoured_levels
        from fieldgen.run.record import RunError

        if not Path(spec).is_dir() and (spec in bundled_fields() or Path(spec).is_file()):
            fail(f"--levels draws the levels a run of the automatic (or mixed) curriculum favours, and {spec} is a "
                 f"field, not a run folder: fieldgen render RUN --levels (or fieldgen render {shell(spec)} -o field.png "
                 f"for the field)")

        named, output = output is not None, output or Path(spec) / "levels.png"
        # before reading the run: a file of the user's there, or no folder for -o's file, is one line now
        check_file(output, RENDER, folder_made=not named)
        try:
            image_bytes, said, buffer = favoured_levels(Path(spec), "top" if camera == "both" else camera)
            write_file(output, image_bytes, RENDER)
        except (RunError, RenderError, OSError) as exc:
            fail(str(exc))
        out.print(f"wrote {output}: {said}")
        for line in buffer:  # one level of one seed's buffer a line
            out.print(f"  {line}", soft_wrap=True)
        return
    output = output or Path("field.png")
    check_file(output, RENDER, folder_made=False)
    if curriculum.is_curriculum(Path(spec)):
        from fieldgen.curriculum.sheet import stage_sheet

        view = "top" if camera == "both" else camera
        try:
            c = curriculum.load(Path(spec))
            write_file(output, stage_sheet(c, view), RENDER)
        except (curriculum.CurriculumError, RenderError, OSError) as exc:
            fail(str(exc))
        out.print(f"wrote {output}: {len(c.stages)} stages of {spec}, camera {view}")
        return
    from fieldgen.curriculum.sheet import built_fields

    built = built_fields(Path(spec))
    if built:  # a folder of built fields: a curriculum run's levels or stages, or a build folder
        from fieldgen.curriculum.sheet import built_sheet
        from fieldgen.run.favoured import level_captions

        view = "top" if camera == "both" else camera
        try:
            write_file(output, built_sheet(built, view, level_captions(Path(spec), len(built))), RENDER)
        except (ArtifactError, RenderError, OSError) as exc:
            fail(str(exc))
        out.print(f"wrote {output}: {len(built)} built field{'s' * (len(built) != 1)} of {spec}, camera {view}")
        missing = _missing_copies(Path(spec))
        if missing:
            out.print(Text(f"note: the run's {', '.join(missing)} {'is' if len(missing) == 1 else 'are'} missing: the "
                           "sheet shows the fields that are there, numbered in order, and no level's place",
                           style="yellow"), soft_wrap=True)
        return
    try:
        path = Path(spec)
        artifact = load_artifact(path) if path.is_dir() else compile_spec(load_spec(spec_path(spec)))
    except (SpecError, ArtifactError) as exc:
        fail(str(exc))
    model = artifact.model()
    try:
        if camera == "both":
            image = preview(model)
        else:  # one view over the legend of its colours, as the preview has
            view = render_pose(model, camera=camera)
            image = np.concatenate([view, legend(model, view.shape[1])], axis=0)
        write_file(output, png_bytes(image), RENDER)
    except (RenderError, OSError) as exc:
        fail(str(exc))
    out.print(f"wrote {output} ({image.shape[1]}x{image.shape[0]}, camera {camera})")


@app.command("curriculum")
def make_curriculum(
    base: Annotated[str, typer.Argument(help="the first (easiest) field: a YAML file or bundled name")],
    output: Annotated[Path, typer.Option("-o", "--out", metavar="DIR", help="curriculum folder to write")],
    to: Annotated[Optional[str], typer.Option(metavar="SPEC",
                                              help="the last (hardest) field: interpolate from BASE to it")] = None,
    stages: Annotated[int, typer.Option(parser=bounded("--stages", limits.STAGES), metavar="N",
                                        help="stages of an interpolation, both ends included")] = 5,
    geometric: Annotated[Optional[list[str]], typer.Option(metavar="KEY",
                                                           help="interpolate this key geometrically")] = None,
    switch_at: Annotated[Optional[int], typer.Option(
        parser=numeric("--switch-at", "the stage where booleans and choices switch", whole=True), metavar="STAGE",
        help="stage where booleans and choices switch (default halfway)")] = None,
    vary: Annotated[Optional[list[str]], typer.Option(metavar="KEY=V1,V2",
                                                      help="a grid axis (repeat for more axes); a list value "
                                                           "in brackets: ball.spawn.x=[-1,1],[-2,2]")] = None,
    stage: Annotated[Optional[list[str]], typer.Option(metavar="'KEY=V ...'",
                                                       help="one listed variant (repeat)")] = None,
    start_near: Annotated[Optional[float], typer.Option(
        parser=numeric("--start-near", "the first stage's distance from the ball to the target"), metavar="DISTANCE",
        help="a start-state curriculum: the first stage spawns the ball this far from the target, later "
             "stages move the kick-off back to BASE's (--stages of them)")] = None,
    agent_near: Annotated[Optional[float], typer.Option(
        parser=numeric("--agent-near", "the first stage's distance from the agent to the ball"), metavar="DISTANCE",
        help="with --start-near: the first stage also starts the agent this far from the ball, later stages "
             "widen the gap back to BASE's")] = None,
    then: Annotated[Optional[list[str]], typer.Option(metavar="SPEC",
        help="then go on from the last stage to this field by interpolation (repeat to go on further)")] = None,
    then_stages: Annotated[Optional[int], typer.Option(parser=bounded("--then-stages", limits.THEN_STAGES), metavar="N",
        help="stages each --then adds, SPEC the last of them (default: one fewer than --stages)")] = None,
    threshold: Annotated[float, typer.Option(
        parser=numeric("--threshold", "the success_any that promotes a run to the next stage"),
        help="success_any that promotes a run to the next stage")] = 0.5,
    window: Annotated[int, typer.Option(
        parser=numeric("--window", "the number of evaluations averaged for promotion", whole=True), metavar="N",
        help="evaluations averaged for promotion")] = 2,
    force: Annotated[bool, typer.Option(help="replace an existing folder")] = False,
) -> None:
    """Write field variants and a curriculum.yaml: an interpolation (--to), a grid (--vary), a list (--stage)
    or start states (--start-near), going on by interpolation to further fields (--then) if asked.

    Example: fieldgen curriculum fields/soccer_v1.yaml --to fields/v2_wide_goalie.yaml --stages 6 -o curricula/v1_to_wide
    Example: fieldgen curriculum soccer_v2 --start-near 3 --stages 4 -o curricula/v2_start_states
    Example: fieldgen curriculum soccer_v1 --start-near 1.5 --agent-near 1.75 --stages 5 -o curricula/v1_close
    Example: fieldgen curriculum soccer_v1 --start-near 1.5 --stages 5 --then soccer_v2 --then-stages 3 -o curricula/v1_close_to_v2
    """
    from fieldgen import curriculum
    from fieldgen.files import FolderError

    typed = {ref: spec_path(ref) for ref in (base, to, *(then or ())) if ref is not None}
    base_path = typed[base]
    try:
        asked = curriculum.Asked(to=typed.get(to), stages=stages,
                                 geometric=tuple(geometric or ()), switch_at=switch_at, vary=tuple(vary or ()),
                                 listed=tuple(stage or ()), start_near=start_near, agent_near=agent_near,
                                 then=tuple(typed[s] for s in then or ()), then_stages=then_stages)
        kind, variants = curriculum.variants(base_path, asked)
        variants = [(changes, _as_typed(origin, typed)) for changes, origin in variants]
        c = curriculum.write(output, base, base_path, kind, variants, curriculum.Promotion(threshold, window), force)
    except (curriculum.CurriculumError, FolderError) as exc:
        fail(_as_typed(str(exc), typed))
    except OSError as exc:
        fail(f"cannot write {output}: {exc.strerror}; nothing was written: {files.way_on(output, '-o', exc, said=True)}")
    table = Table("stage", "name", "changes from the base", title=f"{output}/{curriculum.INDEX} ({c.kind})")
    for i, st in enumerate(c.stages, 1):
        table.add_row(str(i), st.name, _flat_changes(st.changes) or "(the base itself)")
    out.print(table)
    for i, spec in enumerate(c.specs(), 1):
        for name in geometry.in_the_way(spec):
            sx, sy = spec.agent.start
            out.print(Text(f"stage {i}: obstacle '{name}' stands between the agent's start ({sx:g}, {sy:g}) and the "
                           "ball: the agent must walk around it to reach the ball", style="yellow"))
    out.print(f"build them: fieldgen build {shell(output)}; see them: fieldgen render {shell(output)} -o sheet.png")


def _as_typed(text: str, typed: dict[str, Path]) -> str:
    """`text` with the files fields were found in written as the user named them (point_nav, not the bundled
    file's absolute path, which differs between installs)."""
    for ref, path in typed.items():
        text = text.replace(str(path), ref)
    return text


def _flat_changes(tree: dict, prefix: str = "") -> str:
    parts = []
    for k, v in tree.items():
        key = f"{prefix}.{k}" if prefix else k
        parts.append(_flat_changes(v, key) if isinstance(v, dict) and v else f"{key}={v}")
    return ", ".join(parts)


@app.command("list")
def list_fields(
    names: Annotated[Optional[list[str]], typer.Argument(
        metavar="[FIELD]...", help="bundled fields to list (default: all); with --recipes, each stated in full",
        show_default=False)] = None,
    recipes: Annotated[bool, typer.Option(
        "--recipes", help="show each field's recipe (what `fieldgen train FIELD` trains it with) and the headline "
                          "of the figure it measured, with its seeds, in place of the descriptions")] = False,
) -> None:
    """List the bundled fields, one line each.

    Example: fieldgen list
    Example: fieldgen list --recipes
    Example: fieldgen list --recipes v2_wide_goalie   (its recipe and figure in full, with the page of its runs)
    """
    fields = bundled_fields()
    for name in names or []:
        if name not in fields:
            fail(f"'{name}' is not a bundled field{did_you_mean(name, fields) or '.'} fieldgen list names them all")
    chosen = {name: fields[name] for name in names} if names else fields
    if recipes:
        _list_recipes(list(chosen) if names else None)
        return
    table = Table("name", "description", box=None)
    for name, path in chosen.items():
        try:
            table.add_row(name, load_spec(path).description)
        except SpecError as exc:
            table.add_row(name, Text(f"invalid: {exc.problems[0].message}", style="red"))
    out.print(table)


def _list_recipes(names: list[str] | None) -> None:
    """The recipes of every bundled field in a table, or of the fields named, each stated in full."""
    from fieldgen.agents.recipes import RecipeError
    from fieldgen.run.recipe import listing, statement

    try:
        if names:
            for name in names:
                out.print(statement(name), soft_wrap=True)
            return
        rows = listing()
    except RecipeError as exc:
        fail(str(exc))
    # a long token (a path, a --set) folds onto the next line rather than losing its end to an ellipsis
    table = Table(Column("name", no_wrap=True), Column("recipe", overflow="fold"), Column("measured", overflow="fold"),
                  box=None)
    for row in rows:
        table.add_row(*row)
    out.print(table)
    out.print("each figure in full, with the page of its runs: fieldgen list --recipes FIELD", style="dim")


def _missing_copies(folder: Path) -> list[str]:
    """The copies of its fields a run folder's run.json lists that are not there (a run copied in part); [] for
    any other folder."""
    from fieldgen.compile.artifact import META
    from fieldgen.run.record import RunError, read_run

    try:
        listed = read_run(folder).fields
    except RunError:
        return []
    return [name for name in listed if not (folder / name / META).is_file()]


@app.command()
def doctor(
    as_json: Annotated[bool, typer.Option("--json", help="print the checks as JSON, for a bug report")] = False,
) -> None:
    """Check what this machine can do with fieldgen: JAX and its devices, a field built and stepped, Warp's
    physics, drawing, videos, the viewer, the optional extras and the compile cache, each with the step that
    mends it. Exits with status 1 where fieldgen cannot work as it should (no field steps, or an NVIDIA GPU that
    JAX does not use).

    Example: fieldgen doctor
    Example: fieldgen doctor --json > machine.json
    """
    from fieldgen import doctor as checking

    if not as_json:
        out.print(f"stepping {checking.STEPPED_FIELD} once to check the physics (seconds, a compile included)...",
                  style="dim")
    checks = checking.run_checks()
    report = checking.report(checks)
    if as_json:
        print(json.dumps(report, indent=2))
    else:
        styles = {checking.OK: "green", checking.NOTE: "yellow", checking.PROBLEM: "bold red"}
        table = Table(Column("check", no_wrap=True), "", Column("found", overflow="fold"), box=None)
        for check in checks:
            table.add_row(check.name, Text(check.status, style=styles[check.status]), check.detail)
        out.print(table)
        for check in checks:
            if check.remedy:
                out.print(Text.assemble((f"{check.name}: ", styles[check.status]), check.remedy), soft_wrap=True)
    if not report["passed"]:
        raise typer.Exit(1)


@app.command()
def schema() -> None:
    """Print the JSON Schema of a field spec, for editors that check YAML as it is typed.

    Example: fieldgen schema > fieldgen.schema.json
    """
    from fieldgen.schema.editor import schema_text

    print(schema_text(), end="")


@app.command()
def bench(
    spec: SpecArg,
    envs: Annotated[Optional[list[int]], typer.Option("--envs", parser=count, metavar="N",
                                                      help="batch sizes; repeat the option")] = None,
    steps: Annotated[int, typer.Option(parser=bounded("--steps", limits.ROLLOUT_STEPS), metavar="N",
                                       help="steps per timed rollout")] = 200,
) -> None:
    """Measure env-steps per second of a field at several batch sizes (random actions, lax.scan).

    Example: fieldgen bench fields/soccer_v2.yaml --envs 1024 --envs 8192
    """
    import fieldgen
    from fieldgen.agents import memory
    from fieldgen.agents.config import ConfigError
    from fieldgen.compile.artifact import ArtifactError
    from fieldgen.env.throughput import measure
    from fieldgen.run.record import RunError
    from fieldgen.run.session import refuse_folder_of_fields

    try:
        refuse_folder_of_fields(Path(spec), "fieldgen bench")
        env = fieldgen.make(field_source(spec))
        for n in envs or []:
            memory.check(memory.episodes(env, n), f"benchmarking {n:,} envs", {memory.EPISODES: "--envs"})
    except (SpecError, ArtifactError, ConfigError, RunError) as exc:
        fail(str(exc))
    table = Table("envs", "steps/s", "seconds per rollout", title=f"{env.spec.name}, {steps}-step rollouts")
    for n in envs or [64]:
        result = measure(env, n, steps)
        table.add_row(str(n), f"{result.steps_per_second:,.0f}", f"{result.seconds:.3f}")
    out.print(table)
