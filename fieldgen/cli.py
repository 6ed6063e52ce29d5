"""The `fieldgen` command line: validate, build, render, list, schema, bench, train, eval."""

from __future__ import annotations

import json
from collections import Counter
from pathlib import Path
from typing import Annotated, Optional

import typer
from rich.console import Console
from rich.table import Table

from fieldgen.schema import SpecError, bundled_fields, load_spec, resolve_spec_path

app = typer.Typer(
    help="Robot-soccer fields from YAML specs, compiled to GPU-batched MJX environments.",
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    add_completion=False,
)
out = Console()
err = Console(stderr=True, soft_wrap=True)  # messages wrap in the terminal, not mid-phrase here

SpecArg = Annotated[str, typer.Argument(help="a YAML file, a bundled field name, or (render, bench) a build directory")]


def _fail(message: str) -> None:
    err.print(f"[bold red]error:[/] {message}", highlight=False)
    raise typer.Exit(1)


def _spec_path(ref: str) -> Path:
    path = resolve_spec_path(ref)
    if not path.exists():
        names = ", ".join(bundled_fields())
        _fail(f"'{ref}' is neither a file nor a bundled field ({names})")
    return path


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
    from fieldgen.compile.build import build as run_build

    failed = 0
    for ref in specs:
        try:
            result = run_build(_spec_path(ref), out_dir, preview=preview, force=force)
        except SpecError as exc:
            failed += 1
            err.print(str(exc), highlight=False)
            continue
        _report(result)
    if failed:
        raise typer.Exit(1)


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
    from fieldgen.compile.artifact import ArtifactError, compile_spec, load_artifact, write_atomic
    from fieldgen.render import CAMERAS, png_bytes, preview, render_pose

    if camera not in CAMERAS + ("both",):
        _fail(f"unknown camera '{camera}'; choose one of: {', '.join(CAMERAS)}, both")
    try:
        path = Path(spec)
        artifact = load_artifact(path) if path.is_dir() else compile_spec(load_spec(_spec_path(spec)))
    except (SpecError, ArtifactError) as exc:
        _fail(str(exc))
    model = artifact.model()
    image = preview(model) if camera == "both" else render_pose(model, camera=camera)
    write_atomic(output, png_bytes(image))
    out.print(f"wrote {output} ({image.shape[1]}x{image.shape[0]}, camera {camera})")


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
    from fieldgen.throughput import measure

    try:
        env = fieldgen.make(spec if Path(spec).is_dir() else _spec_path(spec))
    except (SpecError, ArtifactError) as exc:
        _fail(str(exc))
    table = Table("envs", "steps/s", "seconds per rollout", title=f"{env.spec.name}, {steps}-step rollouts")
    for n in envs or [64]:
        result = measure(env, n, steps)
        table.add_row(str(n), f"{result.steps_per_second:,.0f}", f"{result.seconds:.3f}")
    out.print(table)


@app.command()
def train(
    spec: Annotated[Optional[str], typer.Argument(help="a YAML file or bundled field name (omit with --resume)")] = None,
    algo: Annotated[str, typer.Option(help="training algorithm: crl or ppo")] = "crl",
    steps: Annotated[Optional[int], typer.Option(help="total env steps")] = None,
    envs: Annotated[Optional[int], typer.Option(help="parallel environments")] = None,
    seed: Annotated[int, typer.Option(help="random seed; names the run folder")] = 0,
    sets: Annotated[Optional[list[str]], typer.Option("--set", help="override a config key: crl.repr_dim=128")] = None,
    config: Annotated[Optional[Path], typer.Option(help="YAML file: {crl: {key: value}}")] = None,
    out: Annotated[Path, typer.Option(help="folder for run folders")] = Path("runs"),
    resume: Annotated[Optional[Path], typer.Option(help="continue the run in this folder")] = None,
) -> None:
    """Train an agent on a field; writes runs/<field>-<algo>-<seed>/ and resumes exactly after an interrupt.

    Example: fieldgen train point_nav --algo crl --steps 40000 --envs 16 --set 'crl.hidden=[64,64]'
    """
    from fieldgen import training

    try:
        if resume is not None:
            run_dir, algo, env, algo_config, rows, state = _resume_run(resume)
        else:
            if spec is None:
                _fail("name a field to train on, or --resume a run folder")
            run_dir, env, algo_config = _new_run(spec, algo, steps, envs, seed, sets or [], config, out)
            rows, state = [], None
    except (SpecError, training.RunError) as exc:
        _fail(str(exc))
    _train_loop(run_dir, algo, env, algo_config, rows, state)


def _new_run(spec, algo, steps, envs, seed, sets, config_file, out):
    import fieldgen
    from fieldgen import training

    algo_config = training.make_config(algo, config_file, sets, total_steps=steps, num_envs=envs, seed=seed)
    field = load_spec(_spec_path(spec))
    run_dir = out / f"{field.name}-{algo}-{seed}"
    if (run_dir / training.RUN).exists():
        raise training.RunError(f"{run_dir} already holds a run; continue it with --resume {run_dir}, "
                                "or pick another --seed or --out")
    env = fieldgen.make(field)
    training.check_config(algo_config, env)
    training.write_run(run_dir, field.model_dump(mode="json"), algo, algo_config, env.layout.to_json())
    return run_dir, env, algo_config


def _resume_run(run_dir: Path):
    import jax

    import fieldgen
    from agents import checkpoint
    from fieldgen import training
    from fieldgen.schema import FieldSpec

    record = training.read_run(run_dir)
    env = fieldgen.make(FieldSpec.model_validate(record["field"]))
    if record["observation"] != env.layout.to_json():
        raise training.RunError(f"{run_dir} was trained on a different observation layout than its field gives now")
    config = training.make_config(record["algo"], **{k: tuple(v) if isinstance(v, list) else v
                                                     for k, v in record["config"].items()})
    rows = training.read_metrics(run_dir)
    template = training.algorithm(record["algo"]).make_train(config, env).init(jax.random.PRNGKey(config.seed))
    try:
        state = checkpoint.load(run_dir / training.CHECKPOINT, template)
    except checkpoint.CheckpointError as exc:
        raise training.RunError(str(exc)) from None
    rows = [r for r in rows if r["env_steps"] <= int(state.env_steps)]
    return run_dir, record["algo"], env, config, rows, state


def _train_loop(run_dir: Path, algo: str, env, config, rows: list, state) -> None:
    import time

    from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

    from agents import checkpoint
    from fieldgen import training
    from fieldgen.compile.artifact import write_atomic

    if state is not None and rows and rows[-1]["eval"] >= config.num_evals:
        out.print(f"{run_dir} is already complete ({rows[-1]['env_steps']:,} env steps)")
        return
    started = time.perf_counter()
    first_steps = rows[-1]["env_steps"] if rows else 0
    columns = (TextColumn("[bold]{task.description}"), BarColumn(), TextColumn("{task.completed:,.0f} steps"),
               TextColumn("{task.fields[rate]}"), TextColumn("{task.fields[stats]}"), TimeElapsedColumn())
    with Progress(*columns, console=out, transient=False) as bar:
        task = bar.add_task(env.spec.name, total=config.total_steps, completed=first_steps, rate="compiling...",
                            stats="")

        def on_eval(ts, index):
            write_atomic(run_dir / training.CHECKPOINT, checkpoint.to_bytes(ts))

        def progress(step, metrics):
            rate = (step - first_steps) / max(time.perf_counter() - started, 1e-9)
            rows.append({"eval": len(rows), "env_steps": step, "wall_seconds": time.perf_counter() - started,
                         **metrics})
            training.write_metrics(run_dir, rows)
            training.plot_success(run_dir, rows, f"{env.spec.name}: {algo}")
            stats = f"success {metrics['success_any']:.2f}  at goal {metrics['time_at_goal']:.1f}"
            for name in ("critic_loss", "actor_loss", "policy_loss", "value_loss"):
                if name in metrics:
                    stats += f"  {name.removesuffix('_loss')} {metrics[name]:.3f}"
            bar.update(task, completed=step, rate=f"{rate:,.0f} steps/s", stats=stats)

        try:
            resume_at = (state, rows[-1]["eval"]) if state is not None else None
            training.algorithm(algo).train(config, env, progress, on_eval, resume_at)
        except KeyboardInterrupt:
            err.print(f"interrupted; the last checkpoint is intact. Continue with: fieldgen train --resume {run_dir}")
            raise typer.Exit(130) from None
    table = Table("env steps", "success_any", "time_at_goal", "return", title=f"{run_dir}")
    for r in rows:
        table.add_row(f"{r['env_steps']:,}", f"{r['success_any']:.2f}", f"{r['time_at_goal']:.1f}",
                      f"{r['episode_return']:.1f}")
    out.print(table)
    out.print(f"metrics: {run_dir / training.CSV}; plot: {run_dir / training.PLOT}")


@app.command("eval")
def evaluate(
    run_dir: Annotated[Path, typer.Argument(help="a run folder written by fieldgen train")],
    episodes: Annotated[int, typer.Option(help="evaluation episodes, one per parallel env")] = 128,
    video: Annotated[bool, typer.Option(help="write eval.gif of one episode")] = True,
    camera: Annotated[str, typer.Option(help="video camera: follow or top")] = "follow",
    seed: Annotated[int, typer.Option(help="evaluation seed")] = 0,
) -> None:
    """Evaluate a run's last checkpoint: success rate, time at goal, return, and a video.

    Example: fieldgen eval runs/point_nav-crl-0 --episodes 256
    """
    import dataclasses

    import jax
    import numpy as np

    from fieldgen import training
    from fieldgen.compile.artifact import write_atomic
    from fieldgen.render import CAMERAS, gif_bytes, render_rollout

    if camera not in CAMERAS:
        _fail(f"unknown camera '{camera}'; choose one of: {', '.join(CAMERAS)}")
    try:
        run_dir, algo_name, env, config, _, state = _resume_run(run_dir)
    except (SpecError, training.RunError) as exc:
        _fail(str(exc))
    algo = training.algorithm(algo_name).make_train(dataclasses.replace(config, eval_envs=episodes), env)
    result = jax.device_get(jax.jit(algo.evaluate)(state, jax.random.PRNGKey(seed)))
    table = Table("metric", "value", title=f"{run_dir} at {int(state.env_steps):,} env steps, {episodes} episodes")
    table.add_row("success_any", f"{result['success_any']:.3f}")
    table.add_row("time_at_goal", f"{result['time_at_goal']:.1f} of {env.episode_length} steps")
    table.add_row("episode_return", f"{result['episode_return']:.2f}")
    out.print(table)
    if video:
        def step(s, _):
            nxt = env.step(s, algo.act(state, s.obs))
            return nxt, (s.pipeline_state.qpos, s.pipeline_state.mocap_pos, nxt.done)

        first = env.reset(jax.random.PRNGKey(seed))
        _, (qpos, mocap, done) = jax.jit(lambda s: jax.lax.scan(step, s, None, length=env.episode_length))(first)
        end = int(np.argmax(np.asarray(done))) + 1 if np.any(np.asarray(done)) else env.episode_length
        stride = max(1, end // 300)  # at most ~300 frames
        frames = render_rollout(env.mj_model, np.asarray(qpos)[:end:stride], np.asarray(mocap)[:end:stride], camera)
        write_atomic(run_dir / "eval.gif", gif_bytes(frames, fps=1 / (env.dt * stride)))
        out.print(f"video: {run_dir / 'eval.gif'} ({len(frames)} frames, {camera} camera)")


if __name__ == "__main__":
    app()
