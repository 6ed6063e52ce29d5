"""The `fieldgen` command line: validate, build, render, curriculum, list, schema, bench, train, eval, videos."""

from __future__ import annotations

import json
from collections import Counter
from decimal import Decimal, InvalidOperation
from pathlib import Path
from typing import Annotated, Optional

import typer
from rich.console import Console
from rich.table import Table

from fieldgen.schema import SpecError, bundled_fields, load_spec, resolve_spec_path
from fieldgen.video import Format

app = typer.Typer(
    help="Robot-soccer fields from YAML specs, compiled to GPU-batched MJX environments.",
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    add_completion=False,
)
out = Console()
err = Console(stderr=True, soft_wrap=True)  # messages wrap in the terminal, not mid-phrase here

SpecArg = Annotated[str, typer.Argument(help="a YAML file, a bundled field name, or (render, bench) a build directory")]
VideoFormat = Annotated[Optional[Format], typer.Option(
    "--video-format", help="videos as mp4 (the default where imageio-ffmpeg's encoder is installed) or gif")]


SUFFIXES = {"k": 1_000, "m": 1_000_000, "g": 1_000_000_000}


def count(text: str) -> int:
    """A whole count as people write them: 50M, 1.5k, 2e6, 10_000_000 or 40000 (read as a Decimal, so
    that 1.1k is exactly 1100)."""
    cleaned = text.strip().replace("_", "").replace(",", "")
    scale = SUFFIXES.get(cleaned[-1:].lower(), 1)
    try:
        value = Decimal(cleaned[:-1] if scale > 1 else cleaned) * scale
    except InvalidOperation:
        value = Decimal(0)
    if not (value.is_finite() and 1 <= value < 10**15 and value == value.to_integral_value()):
        raise typer.BadParameter(f"'{text}' is not a positive whole count; write it as 40000, 50M, 1.5k or 2e6 "
                                 "(k, M and G stand for thousand, million and billion)")
    return int(value)


def _fail(message: str) -> None:
    err.print(f"[bold red]error:[/] {message}", highlight=False)
    raise typer.Exit(1)


def _video_format(fmt: str | None) -> str:
    """The video format to write, checked before anything loads."""
    from fieldgen.video import VideoError, choose

    try:
        return choose(fmt)
    except VideoError as exc:
        _fail(str(exc))


def _spec_path(ref: str) -> Path:
    path = resolve_spec_path(ref)
    if not path.exists():
        names = ", ".join(bundled_fields())
        _fail(f"'{ref}' is neither a file nor a bundled field ({names})")
    return path


def _field_source(ref: str) -> Path:
    """A build folder as it is; else a YAML file or bundled field name."""
    return Path(ref) if Path(ref).is_dir() else _spec_path(ref)


@app.command()
def validate(specs: Annotated[list[str], typer.Argument(help="YAML files or bundled field names")]) -> None:
    """Check field specs and report every problem with file:line:column and key path.

    Example: fieldgen validate fields/soccer_v2.yaml my_field.yaml
    """
    failed = 0
    for ref in specs:
        try:
            spec = load_spec(_spec_path(ref))
        except SpecError as exc:
            failed += 1
            err.print(str(exc), highlight=False)
            continue
        out.print(f"[green]ok[/] {ref}: {spec.name}")
    if failed:
        raise typer.Exit(1)


@app.command()
def build(
    specs: Annotated[list[str], typer.Argument(help="YAML files or bundled field names")],
    out_dir: Annotated[Path, typer.Option("--out", help="where build/<name>/ folders go")] = Path("build"),
    force: Annotated[bool, typer.Option(help="rebuild even when the build is current")] = False,
    preview: Annotated[bool, typer.Option(help="render preview.png")] = True,
) -> None:
    """Compile specs to build/<name>/: scene.xml, field.json and preview.png.

    A build whose inputs are unchanged is reused (cache hit).
    Example: fieldgen build fields/soccer_v2.yaml --out build
    """
    from fieldgen import curriculum
    from fieldgen.compile.build import build as run_build
    from fieldgen.render import RenderError

    failed = 0
    for ref in specs:
        try:
            if curriculum.is_curriculum(Path(ref)):
                failed += _build_curriculum(Path(ref), out_dir, preview, force)
                continue
            result = run_build(_spec_path(ref), out_dir, preview=preview, force=force)
        except SpecError as exc:
            failed += 1
            err.print(str(exc), highlight=False)
            continue
        except RenderError as exc:
            _fail(f"{exc}; or build without preview.png: fieldgen build {' '.join(specs)} --no-preview")
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
        err.print(f"[bold red]error:[/] {exc}", highlight=False)
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
    state = "[yellow]cache hit[/]" if result.cache_hit else "[green]built[/]"
    out.print(f"{state} [bold]{meta['name']}[/] -> {result.out_dir}/  ({result.seconds:.2f} s, hash {meta['hash']})")
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
    output: Annotated[Path, typer.Option("-o", "--output", help="PNG file to write")] = Path("field.png"),
    camera: Annotated[str, typer.Option(help="top, follow, or both (side by side)")] = "top",
) -> None:
    """Render a field to a PNG, headless.

    Example: fieldgen render fields/soccer_v2.yaml -o v2.png --camera follow
    """
    from fieldgen.compile.artifact import ArtifactError, compile_spec, load_artifact
    from fieldgen.files import write_atomic
    from fieldgen.render import CAMERAS, RenderError, png_bytes, preview, render_pose

    from fieldgen import curriculum

    if camera not in CAMERAS + ("both",):
        _fail(f"unknown camera '{camera}'; choose one of: {', '.join(CAMERAS)}, both")
    if curriculum.is_curriculum(Path(spec)):
        from fieldgen.render import contact_sheet

        try:
            c = curriculum.load(Path(spec))
            models = [compile_spec(s).model() for s in c.specs()]
        except curriculum.CurriculumError as exc:
            _fail(str(exc))
        view = "top" if camera == "both" else camera
        try:
            images = [render_pose(m, camera=view, height=240) for m in models]
        except RenderError as exc:
            _fail(str(exc))
        write_atomic(output, contact_sheet(images, [f"{i}. {st.name}" for i, st in enumerate(c.stages, 1)]))
        out.print(f"wrote {output}: {len(models)} stages of {spec}, camera {view}")
        return
    try:
        path = Path(spec)
        artifact = load_artifact(path) if path.is_dir() else compile_spec(load_spec(_spec_path(spec)))
    except (SpecError, ArtifactError) as exc:
        _fail(str(exc))
    model = artifact.model()
    try:
        image = preview(model) if camera == "both" else render_pose(model, camera=camera)
    except RenderError as exc:
        _fail(str(exc))
    write_atomic(output, png_bytes(image))
    out.print(f"wrote {output} ({image.shape[1]}x{image.shape[0]}, camera {camera})")


@app.command("curriculum")
def make_curriculum(
    base: Annotated[str, typer.Argument(help="the first (easiest) field: a YAML file or bundled name")],
    output: Annotated[Path, typer.Option("-o", "--out", help="curriculum folder to write")],
    to: Annotated[Optional[str], typer.Option(help="the last (hardest) field: interpolate from BASE to it")] = None,
    stages: Annotated[int, typer.Option(help="stages of an interpolation, both ends included")] = 5,
    geometric: Annotated[Optional[list[str]], typer.Option(help="interpolate this key geometrically")] = None,
    switch_at: Annotated[Optional[int], typer.Option(help="stage where booleans and choices switch (default halfway)")] = None,
    vary: Annotated[Optional[list[str]], typer.Option(help="a grid axis: KEY=V1,V2,... (repeat for more axes)")] = None,
    stage: Annotated[Optional[list[str]], typer.Option(help="one listed variant: 'KEY=V KEY=V' (repeat)")] = None,
    threshold: Annotated[float, typer.Option(help="success_any that promotes a run to the next stage")] = 0.5,
    window: Annotated[int, typer.Option(help="evaluations averaged for promotion")] = 2,
    force: Annotated[bool, typer.Option(help="replace an existing folder")] = False,
) -> None:
    """Write field variants and a curriculum.yaml: an interpolation (--to), a grid (--vary) or a list (--stage).

    Example: fieldgen curriculum fields/soccer_v1.yaml --to fields/v2_wide_goalie.yaml --stages 6 -o curricula/v1_to_wide
    """
    from fieldgen import curriculum

    kinds = [k for k, given in (("interpolation", to), ("grid", vary), ("list", stage)) if given]
    if len(kinds) != 1:
        _fail("give exactly one of --to FIELD (interpolation), --vary KEY=V1,V2 (grid) or --stage 'KEY=V' (list)")
    base_path = _spec_path(base)
    try:
        if to is not None:
            variants = curriculum.interpolate(base_path, _spec_path(to), stages, tuple(geometric or ()), switch_at)
        elif vary:
            variants = curriculum.grid(base_path, dict(curriculum.parse_axis(v) for v in vary))
        else:
            variants = curriculum.explicit(base_path, [curriculum.parse_assignments(s.split(), "--stage")
                                                       for s in stage])
        c = curriculum.write(output, base, base_path, kinds[0], variants,
                             curriculum.Promotion(threshold, window), force)
    except curriculum.CurriculumError as exc:
        _fail(str(exc))
    table = Table("stage", "name", "changes from the base", title=f"{output}/{curriculum.INDEX} ({c.kind})")
    for i, st in enumerate(c.stages, 1):
        table.add_row(str(i), st.name, _flat_changes(st.changes) or "(the base itself)")
    out.print(table)
    out.print(f"build them: fieldgen build {output}; see them: fieldgen render {output} -o sheet.png")


def _flat_changes(tree: dict, prefix: str = "") -> str:
    parts = []
    for k, v in tree.items():
        key = f"{prefix}.{k}" if prefix else k
        parts.append(_flat_changes(v, key) if isinstance(v, dict) and v else f"{key}={v}")
    return ", ".join(parts)


@app.command("list")
def list_fields() -> None:
    """List the bundled fields, one line each.

    Example: fieldgen list
    """
    table = Table("name", "description", box=None)
    for name, path in bundled_fields().items():
        try:
            table.add_row(name, load_spec(path).description)
        except SpecError as exc:
            table.add_row(name, f"[red]invalid: {exc.problems[0].message}[/]")
    out.print(table)


@app.command()
def schema() -> None:
    """Print the JSON Schema of a field spec, for editors that check YAML as it is typed.

    Example: fieldgen schema > fieldgen.schema.json
    """
    from fieldgen.schema import FieldSpec

    print(json.dumps(FieldSpec.model_json_schema(), indent=1))


@app.command()
def bench(
    spec: SpecArg,
    envs: Annotated[Optional[list[int]], typer.Option("--envs", help="batch sizes; repeat the option")] = None,
    steps: Annotated[int, typer.Option(help="steps per timed rollout")] = 200,
) -> None:
    """Measure env-steps per second of a field at several batch sizes (random actions, lax.scan).

    Example: fieldgen bench fields/soccer_v2.yaml --envs 1024 --envs 8192
    """
    import fieldgen
    from fieldgen.compile.artifact import ArtifactError
    from fieldgen.env.throughput import measure

    try:
        env = fieldgen.make(_field_source(spec))
    except (SpecError, ArtifactError) as exc:
        _fail(str(exc))
    table = Table("envs", "steps/s", "seconds per rollout", title=f"{env.spec.name}, {steps}-step rollouts")
    for n in envs or [64]:
        result = measure(env, n, steps)
        table.add_row(str(n), f"{result.steps_per_second:,.0f}", f"{result.seconds:.3f}")
    out.print(table)


def _train(run, videos: bool, video_format: str | None = None) -> None:
    """Train a run; Ctrl-C exits with 130, and a failed write or a diverged run says what to do (training.train
    says how to go on)."""
    from fieldgen.run import record
    from fieldgen.run.train import train as train_run

    try:
        train_run(run, out, videos, video_format)
    except KeyboardInterrupt:
        raise typer.Exit(130) from None
    except record.RunError as exc:  # training diverged
        _fail(str(exc))
    except OSError as exc:  # every file of a run is replaced atomically, so the last good ones remain
        _fail(f"could not write {exc.filename or run.folder}: {exc.strerror or exc}; the files already there are "
              f"intact: free some space (or fix the folder's permissions) and continue with "
              f"fieldgen train --resume {run.folder}")


@app.command()
def train(
    spec: Annotated[Optional[str], typer.Argument(
        help="a YAML file, bundled field name or build folder (omit with --resume)")] = None,
    algo: Annotated[str, typer.Option(help="training algorithm: crl, icrl, ppo, sac or td3")] = "crl",
    steps: Annotated[Optional[int], typer.Option(parser=count, metavar="N",
                                                 help="total env steps: 40000, 50M, 1.5k, 2e6")] = None,
    envs: Annotated[Optional[int], typer.Option(parser=count, metavar="N", help="parallel environments")] = None,
    seed: Annotated[int, typer.Option(help="random seed; names the run folder")] = 0,
    seeds: Annotated[int, typer.Option(help="train this many seeds at once (seed, seed+1, ...), vmapped")] = 1,
    sets: Annotated[Optional[list[str]], typer.Option("--set", help="override a config key: crl.repr_dim=128")] = None,
    config: Annotated[Optional[Path], typer.Option(help="YAML file: {crl: {key: value}}")] = None,
    runs: Annotated[Path, typer.Option("--out", help="folder for run folders")] = Path("runs"),
    resume: Annotated[Optional[Path], typer.Option(help="continue the run in this folder")] = None,
    videos: Annotated[bool, typer.Option(help="write videos/eval_NNN.mp4 of the policy at every evaluation")] = True,
    video_format: VideoFormat = None,
    mixed: Annotated[bool, typer.Option(help="a curriculum's stages all at once, each env its own stage, "
                                              "re-weighted by progress (default: one stage after another)")] = False,
    prepare: Annotated[bool, typer.Option(help="write the run folder (config, built fields) and stop; start it "
                                                "later with --resume, e.g. on a machine without dm_control")] = False,
) -> None:
    """Train an agent on a field or through a curriculum folder's stages; writes runs/<name>-<algo>-<seed>/.

    Resumes exactly after an interrupt (--resume). A curriculum run moves to the next stage when its
    promotion rule is met and reports which stage it reached, when, and success on the last stage;
    with --mixed it trains on every stage at once, favouring those being learnt (success neither 0 nor 1).

    Example: fieldgen train point_nav --algo crl --steps 40000 --envs 16 --set 'crl.hidden=[64,64]'
    """
    from fieldgen.agents import registry
    from fieldgen.run import record, session
    from fieldgen.agents.config import ConfigError

    fmt = _video_format(video_format) if videos else None
    try:
        if resume is not None:
            run = session.open_run(resume)
        else:
            if spec is None:
                _fail("name a field to train on, or --resume a run folder")
            if seeds < 1:
                _fail(f"--seeds {seeds}: train at least one seed")
            algo_config = registry.trainer(algo).config.layered(config, sets or [], total_steps=steps,
                                                                num_envs=envs, seed=seed)
            source = _field_source(spec)
            run = session.new_run(source, algo, list(range(seed, seed + seeds)), algo_config, runs, mixed)
    except (SpecError, ConfigError, record.RunError) as exc:
        _fail(str(exc))
    if prepare:
        out.print(f"prepared {run.folder}; start it with: fieldgen train --resume {run.folder}")
        return
    _train(run, videos, fmt)


@app.command()
def compare(
    spec: Annotated[str, typer.Argument(help="a YAML file, bundled field name or build folder")],
    algos: Annotated[str, typer.Option(help="comma-separated algorithms: crl, icrl, ppo, sac, td3")] = "crl,ppo",
    steps: Annotated[Optional[int], typer.Option(parser=count, metavar="N",
                                                 help="total env steps of each run: 40000, 50M, 1.5k")] = None,
    envs: Annotated[Optional[int], typer.Option(parser=count, metavar="N",
                                                help="parallel environments of each run")] = None,
    seeds: Annotated[int, typer.Option(help="seeds per algorithm (0, 1, ...), vmapped in one run")] = 1,
    sets: Annotated[Optional[list[str]], typer.Option("--set", help="override a config key: sac.her=0.8")] = None,
    config: Annotated[Optional[Path], typer.Option(help="YAML file: {crl: {...}, sac: {...}}")] = None,
    runs: Annotated[Optional[Path], typer.Option("--out", help="folder of the runs and the plot "
                                                               "(default runs/compare-<field>)")] = None,
    videos: Annotated[bool, typer.Option(help="write each run's videos")] = False,
    prepare: Annotated[bool, typer.Option(help="write the run folders and stop (train them with "
                                                "fieldgen train --resume, then compare again to plot)")] = False,
) -> None:
    """Train several algorithms on one field and plot success against env steps and wall-clock time.

    Runs train one after another (the seeds of each at once); rerunning the same comparison
    resumes unfinished runs and redraws compare.png and compare.json.

    Example: fieldgen compare point_nav --algos crl,icrl,sac --steps 40000 --envs 16 --seeds 2
    """
    from fieldgen.agents.config import ConfigError
    from fieldgen.run import compare as comparing
    from fieldgen.run import record

    if seeds < 1:
        _fail(f"--seeds {seeds}: compare at least one seed")
    source = _field_source(spec)
    names = [a.strip() for a in algos.split(",") if a.strip()]
    try:
        folder, todo = comparing.runs(source, names, list(range(seeds)), runs, config, sets or [],
                                      total_steps=steps, num_envs=envs)
    except (SpecError, ConfigError, record.RunError) as exc:
        _fail(str(exc))
    if prepare:
        out.print(f"prepared {len(todo)} runs in {folder}; train each with fieldgen train --resume RUN, "
                  "then run this comparison again to plot")
        return
    for run in todo:
        if run.finished:
            out.print(f"{run.folder} is already complete ({run.rows[-1]['env_steps']:,} env steps)")
            continue
        out.print(f"[bold]{run.algo}[/] -> {run.folder}")
        _train(run, videos)
    comparing.report(todo, folder, out)


@app.command("eval")
def evaluate(
    run_dir: Annotated[Path, typer.Argument(help="a run folder written by fieldgen train")],
    episodes: Annotated[int, typer.Option(help="evaluation episodes per seed, one per parallel env")] = 128,
    video: Annotated[bool, typer.Option(help="write eval.mp4 of one episode of the run's first seed")] = True,
    video_format: VideoFormat = None,
    camera: Annotated[str, typer.Option(help="video camera: follow or top")] = "follow",
    seed: Annotated[int, typer.Option(help="evaluation seed")] = 0,
    field: Annotated[Optional[str], typer.Option(
        help="judge the policy on this field instead (YAML file, bundled name or build folder) with the "
             "run's observations and actions; the video is eval_<field>.mp4")] = None,
) -> None:
    """Evaluate a run's last checkpoint (on a curriculum's last stage, or --field): success rate, time at goal,
    return, video.

    Example: fieldgen eval runs/point_nav-crl-0 --episodes 256
    """
    from fieldgen.agents.config import ConfigError
    from fieldgen.render import CAMERAS
    from fieldgen.run import record, session
    from fieldgen.run.evaluate import evaluate as judge
    from fieldgen.run.evaluate import video_path
    from fieldgen.run.videos import EpisodeRecorder

    if camera not in CAMERAS:
        _fail(f"unknown camera '{camera}'; choose one of: {', '.join(CAMERAS)}")
    fmt = _video_format(video_format) if video else None
    try:
        run = session.open_run(run_dir)
        if field is not None:
            run = session.on_field(run, _field_source(field))
    except (SpecError, ConfigError, record.RunError) as exc:
        _fail(str(exc))
    if run.state is None:
        _fail(f"{run_dir} has not started training yet; start it with: fieldgen train --resume {run_dir}")
    evaluation = judge(run, episodes, seed, video)
    result, steps = evaluation.metrics, evaluation.env_steps
    table = Table("seed", "success_any", "time_at_goal", "closest", "length", "return",
                  title=f"{run_dir} at {steps:,} env steps on {run.env.spec.name}, {episodes} episodes per seed")
    for i, s in enumerate(run.seeds):
        table.add_row(str(s), f"{result['success_any'][i]:.3f}",
                      f"{result['time_at_goal'][i]:.1f} of {run.env.episode_length} steps",
                      f"{result['closest_distance'][i]:.2f}", f"{result['episode_length'][i]:.0f}",
                      f"{result['episode_return'][i]:.2f}")
    out.print(table)
    if video:  # the first seed's first evaluation episode
        name = video_path(run, run_dir, field is not None)
        drawn = EpisodeRecorder(run.env, camera, fmt).save(run_dir, name, evaluation.episode, err)
        if drawn is not None:
            out.print(f"video: {name.with_suffix('.' + fmt)} ({drawn} frames, {camera} camera)")


@app.command()
def videos(
    run_dir: Annotated[Path, typer.Argument(help="a run folder written by fieldgen train")],
    field: Annotated[Optional[str], typer.Option(
        help="the field that `fieldgen eval --field` played eval_<field>.npz on")] = None,
    video_format: VideoFormat = None,
) -> None:
    """Draw the episodes a run kept where nothing could render (videos/eval_NNN.npz, eval.npz) as videos beside them.

    A training machine without OpenGL keeps each evaluation's episode as joint positions; run this
    wherever mujoco's renderer works (MUJOCO_GL=egl or osmesa). Videos already drawn are left alone.

    Example: fieldgen videos runs/soccer_v1-crl-0
    """
    from fieldgen.agents.config import ConfigError
    from fieldgen.render import RenderError
    from fieldgen.run import record, session
    from fieldgen.run.videos import draw_kept, kept_episodes

    fmt = _video_format(video_format)
    try:
        run = session.open_run(run_dir, load_state=False)
        if field is not None:
            run.envs.append(session.on_field(run, _field_source(field)).env)
    except (SpecError, ConfigError, record.RunError) as exc:
        _fail(str(exc))
    kept = kept_episodes(run_dir)
    if not kept:
        _fail(f"nothing to draw: {run_dir / record.VIDEOS} holds no eval_NNN.npz and {run_dir} no eval.npz "
              "(training and fieldgen eval keep them only where they could not render)")
    models = {env.spec.name: env.mj_model for env in run.envs}
    table = Table("episode", "field", "frames", "video", title=f"{run_dir}: kept episodes")
    for path in kept:
        try:
            played, frames = draw_kept(path, models, fmt)
        except (RenderError, record.RunError) as exc:
            _fail(str(exc))
        video = path.with_suffix(f".{fmt}").name
        table.add_row(path.name, played, "" if frames is None else str(frames),
                      f"{video} (already drawn)" if frames is None else video)
    out.print(table)


if __name__ == "__main__":
    app()
