"""What this machine can do with fieldgen, checked one part at a time: the first thing to run when a command
misbehaves, and what a bug report should carry (`fieldgen doctor --json`).

Each check says what it found and, where something is missing or broken, the one step that mends it. Only a
machine that cannot step a field at all (or has an NVIDIA GPU that JAX does not use) fails; missing extras are
notes, since fieldgen runs without them.
"""

from __future__ import annotations

import dataclasses
import importlib.metadata
import importlib.util
import os
import platform
import shutil
import sys
from pathlib import Path
from typing import Callable

OK, NOTE, PROBLEM = "ok", "note", "problem"

# optional extras (warp has a check of its own): the import that shows one, the distribution whose version is
# shown, what it brings
EXTRAS = {
    "onnx": ("onnxruntime", "onnx", "fieldgen export --format onnx"),
    "wandb": ("wandb", "wandb", "fieldgen train --logger wandb"),
    "playground": ("mujoco_playground", "playground", "fieldgen.playground (MuJoCo Playground's MjxEnv)"),
    "slurm": ("submitit", "submitit", "fieldgen sweep with backend slurm"),
}
REINSTALL = "reinstall fieldgen's pins: python -m pip install -c requirements.lock -e ."
STEPPED_FIELD = "point_nav"  # the smallest bundled field: compiles and steps in seconds on a CPU


@dataclasses.dataclass(frozen=True)
class Check:
    """One part of the machine: what was found (`detail`), whether it works, and how to mend it (`remedy`)."""

    name: str
    status: str  # OK, NOTE (works without it, or works slowly) or PROBLEM (fieldgen cannot work as it should)
    detail: str
    remedy: str | None = None


def version(distribution: str) -> str | None:
    """The installed version of a distribution, None where it is not installed."""
    try:
        return importlib.metadata.version(distribution)
    except importlib.metadata.PackageNotFoundError:
        return None


def nvidia_gpu_present() -> bool:
    """Whether the machine has an NVIDIA GPU with its driver loaded, whatever JAX uses."""
    return Path("/proc/driver/nvidia/gpus").is_dir() or shutil.which("nvidia-smi") is not None


def platform_problem() -> str | None:
    """Why JAX cannot start the platform JAX_PLATFORMS names (a GPU on a machine without one or without JAX's plugin
    for it: a RuntimeError, or for CUDA without its plugin an empty AssertionError, from wherever JAX first starts),
    in a sentence; None where JAX starts, or has not been loaded."""
    platforms = os.environ.get("JAX_PLATFORMS", "")
    if not platforms or "jax" not in sys.modules:
        return None
    import jax

    try:
        jax.devices()
    except (RuntimeError, AssertionError) as exc:
        said = str(exc).split(" (set JAX_PLATFORMS")[0] or "JAX has no plugin for it here"
        return (f"JAX_PLATFORMS={platforms} names a platform JAX cannot start here ({said}); unset JAX_PLATFORMS for "
                "JAX to use what this machine has, or set JAX_PLATFORMS=cpu")
    return None


def check_fieldgen() -> Check:
    from fieldgen.version import VERSION

    return Check("fieldgen", OK, f"{VERSION} on Python {platform.python_version()}, {platform.system()} "
                                 f"{platform.machine()}, {os.cpu_count()} CPU cores")


def _device_text(devices) -> str:
    """'1 x NVIDIA H100 80GB HBM3 (79.1 GiB)' or '1 x cpu'."""
    kinds: dict[str, int] = {}
    for device in devices:
        kinds[device.device_kind] = kinds.get(device.device_kind, 0) + 1
    memory = ""
    try:
        limit = (devices[0].memory_stats() or {}).get("bytes_limit")
        memory = f" ({limit / 2**30:.1f} GiB each)" if limit else ""
    except Exception:  # noqa: BLE001 - a backend without memory statistics
        pass
    return ", ".join(f"{count} x {kind}" for kind, count in kinds.items()) + memory


def check_jax(gpu_present: Callable[[], bool] = nvidia_gpu_present) -> Check:
    try:
        import jax

        backend = jax.default_backend()
        devices = jax.devices()
    except Exception as exc:  # noqa: BLE001 - a broken install fails in its own way; say how
        return Check("JAX", PROBLEM, f"cannot start: {type(exc).__name__}: {exc}", platform_problem() or REINSTALL)
    platforms = os.environ.get("JAX_PLATFORMS")
    detail = f"{jax.__version__}, {backend}: {_device_text(devices)}" + (
        f" (JAX_PLATFORMS={platforms})" if platforms else "")
    if backend == "cpu" and gpu_present() and not platforms:
        return Check("JAX", PROBLEM, detail + "; this machine has an NVIDIA GPU that JAX does not use",
                     f"install JAX's CUDA plugin of the same version, jax[cuda12]=={jax.__version__} (JAX's "
                     "installation guide), then run fieldgen doctor again")
    if backend == "cpu":
        return Check("JAX", NOTE, detail + "; no GPU: the ant and soccer fields' recipes (100M env steps or more) "
                                           "take hours or days here",
                     "train small fields here, or add --preset cpu; --prepare sets a run up to train on a GPU "
                     "machine")
    return Check("JAX", OK, detail)


def check_physics(field: str = STEPPED_FIELD) -> Check:
    """Build the smallest bundled field and step it once on JAX's default device: the whole path a run takes."""
    try:
        import jax
        import mujoco

        import fieldgen

        env = fieldgen.make(field)
        state = jax.jit(env.reset)(jax.random.PRNGKey(0))
        state = jax.jit(env.step)(state, jax.numpy.zeros(env.action_size))
        jax.block_until_ready(state.obs)
    except Exception as exc:  # noqa: BLE001 - whatever stops it is the finding
        return Check("MuJoCo and MJX", PROBLEM, f"{field} could not be built and stepped: {type(exc).__name__}: "
                                                f"{exc}", REINSTALL)
    return Check("MuJoCo and MJX", OK, f"mujoco {mujoco.__version__}, mujoco-mjx {version('mujoco-mjx')}, "
                                       f"dm_control {version('dm-control')}; {field} built and stepped on "
                                       f"{jax.default_backend()}")


def check_warp() -> Check:
    installed = version("warp-lang")
    if installed is None:
        return Check("Warp physics", NOTE, "warp-lang is not installed: fields on sim.backend: warp are refused, and "
                                           "the dense fields' recipes train on MJX's JAX physics instead",
                     "pip install -c requirements.lock -e '.[warp]' (or pip install 'fieldgen[warp]')")
    from fieldgen.run.recipe import warp_runs_here  # what a recipe naming Warp goes by

    if not warp_runs_here():
        return Check("Warp physics", NOTE, f"warp-lang {installed}, no CUDA GPU for JAX: sim.backend: warp runs "
                                           "Warp's CPU kernels, slowly; the recipes that name it keep MJX's physics")
    return Check("Warp physics", OK, f"warp-lang {installed} on the GPU")


def check_rendering() -> Check:
    """Open an offscreen context and draw one small frame, as previews, videos and `fieldgen render` do."""
    backend = os.environ.get("MUJOCO_GL", "")
    try:
        import mujoco

        from fieldgen.render import RenderError, renderer

        model = mujoco.MjModel.from_xml_string("<mujoco><worldbody><geom size='1'/></worldbody></mujoco>")
        data = mujoco.MjData(model)
        with renderer(model, (16, 16)) as context:
            context.update_scene(data)
            context.render()
    except RenderError as exc:
        return Check("Rendering", NOTE, f"MUJOCO_GL={backend}: nothing can be drawn (previews, videos and "
                                        "fieldgen render are left out; training is not affected)", str(exc))
    except Exception as exc:  # noqa: BLE001 - an OpenGL library that loads and then fails
        return Check("Rendering", NOTE, f"MUJOCO_GL={backend}: drawing failed: {type(exc).__name__}: {exc}",
                     "set MUJOCO_GL to another back end (egl, osmesa), or unset it for fieldgen to pick one")
    return Check("Rendering", OK, f"MUJOCO_GL={backend}: a frame drawn offscreen")


def check_videos() -> Check:
    from fieldgen.video import FORMATS, VideoError, choose

    default = choose(None)  # the richest this machine writes
    for fmt in FORMATS:
        try:
            choose(fmt)
        except VideoError as exc:
            return Check("Videos", NOTE, f"{default} only: {fmt} cannot be written here", str(exc))
    return Check("Videos", OK, f"{', '.join(FORMATS)}; {default} by default")


def check_viewer() -> Check:
    from fieldgen.view import no_display_reason

    reason = no_display_reason()
    if reason:
        return Check("Viewer", NOTE, f"fieldgen view needs a display: {reason}",
                     "fieldgen render FIELD writes a picture, and runs keep videos of their evaluations")
    return Check("Viewer", OK, "a display for fieldgen view")


def check_extras() -> list[Check]:
    checks = []
    for extra, (module, distribution, brings) in EXTRAS.items():
        installed = version(distribution)
        if installed is not None and importlib.util.find_spec(module) is not None:
            checks.append(Check(f"extra: {extra}", OK, f"{distribution} {installed}: {brings}"))
        else:
            checks.append(Check(f"extra: {extra}", NOTE, f"not installed: {brings}",
                                f"pip install -c requirements.lock -e '.[{extra}]' (or pip install "
                                f"'fieldgen[{extra}]')"))
    return checks


def check_cache() -> Check:
    """XLA's compiled programs kept between commands (fieldgen.xla_cache): where, and whether it can write."""
    if os.environ.get("JAX_ENABLE_COMPILATION_CACHE", "").lower() in ("0", "false"):
        return Check("Compile cache", NOTE, "off (JAX_ENABLE_COMPILATION_CACHE): every command compiles again")
    folder = Path(os.environ.get("JAX_COMPILATION_CACHE_DIR", ""))
    probe = folder
    while not probe.exists() and probe != probe.parent:
        probe = probe.parent
    if not os.access(probe, os.W_OK):
        return Check("Compile cache", NOTE, f"{folder} cannot be written: every command compiles again",
                     "set JAX_COMPILATION_CACHE_DIR to a folder you can write")
    return Check("Compile cache", OK, str(folder))


def run_checks() -> list[Check]:
    """Every check, in the order a reader follows: what runs, then what draws, then what is optional. The
    compile cache is pointed where fieldgen's commands point it (fieldgen.xla_cache) before JAX loads."""
    from fieldgen import xla_cache

    xla_cache.enable()
    checks = [check_fieldgen(), check_jax(), check_physics()]
    checks += [check_warp(), check_rendering(), check_videos(), check_viewer(), *check_extras(), check_cache()]
    return checks


def report(checks: list[Check]) -> dict:
    """The checks as `--json` writes them: each one's fields, and whether the machine passes."""
    return {"passed": all(c.status != PROBLEM for c in checks), "python": sys.version.split()[0],
            "checks": [dataclasses.asdict(c) for c in checks]}
