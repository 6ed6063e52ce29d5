"""Where a run's numbers go besides metrics.jsonl, for the tools researchers already watch: TensorBoard
event files (RUN/tensorboard/seed_N/, one TensorBoard run per seed) or a Weights & Biases run (RUN/wandb/);
every number of each evaluation's rows against env steps, and each evaluation's video."""

from __future__ import annotations

import os
from pathlib import Path

from fieldgen.run.record import RunError, flat_row

LOGGERS = ("none", "tensorboard", "wandb")
TENSORBOARD = "tensorboard"
# the row's place, not a measurement: env_steps is the x axis; refilled_from, where a refilled run went on from
NOT_LOGGED = ("eval", "seed", "env_steps", "refilled_from")


def scalars(row: dict) -> dict[str, float]:
    """A metrics row's numbers by the names metrics.csv gives them: success_any, time_at_goal, term_<reward
    term>, each loss, entropy, steps_per_second, a mixed run's variants.<metric>.<stage>..."""
    return {name: float(value) for name, value in flat_row(row).items()
            if name not in NOT_LOGGED and isinstance(value, (int, float)) and not isinstance(value, bool)}


class TensorBoardLogger:
    def __init__(self, folder: Path, seeds: list[int]):
        from tensorboardX import FileWriter

        self.writers = {seed: FileWriter(str(folder / TENSORBOARD / f"seed_{seed}")) for seed in seeds}
        self.filmed = self.writers[seeds[0]]  # evaluations film the first seed

    def rows(self, rows: list[dict]) -> None:
        from tensorboardX.summary import scalar

        for row in rows:
            writer = self.writers[row["seed"]]
            for name, value in scalars(row).items():
                writer.add_summary(scalar(name, value), row["env_steps"])
            writer.flush()

    def video(self, video: Path, env_steps: int) -> None:
        """As a GIF (an MP4 re-encoded as one): TensorBoard's images tab plays an image summary that holds a GIF."""
        import imageio.v3 as iio
        from tensorboardX.proto.summary_pb2 import Summary

        from fieldgen.video import GIF_FPS, encode

        data = video.read_bytes() if video.suffix == ".gif" else encode(list(iio.imread(video, index=None)),
                                                                          GIF_FPS, "gif")[0]
        height, width, channels = iio.improps(data, index=0, extension=".gif").shape
        image = Summary.Image(height=height, width=width, colorspace=channels, encoded_image_string=data)
        self.filmed.add_summary(Summary(value=[Summary.Value(tag="video", image=image)]), env_steps)
        self.filmed.flush()

    def close(self) -> None:
        for writer in self.writers.values():
            writer.close()


class WandbLogger:
    """One W&B run per run folder (per session of it: a resumed run starts another in the same group),
    its config the run's; with several seeds each number is logged as seed_N/<name>."""

    def __init__(self, folder: Path, seeds: list[int], config: dict):
        import wandb

        try:
            self.run = wandb.init(project=os.environ.get("WANDB_PROJECT", "fieldgen"), name=folder.name,
                                  group=folder.name, dir=folder, config=config)
        except Exception as exc:  # noqa: BLE001 - wandb fails in its own ways (no login, no network)
            raise RunError(f"could not start a Weights & Biases run ({exc}); log in with `wandb login`, or set "
                           "WANDB_MODE=offline to keep it in the run folder and `wandb sync` it later") from None
        self.run.define_metric("env_steps")
        self.run.define_metric("*", step_metric="env_steps")
        self.prefix = (lambda seed: f"seed_{seed}/") if len(seeds) > 1 else (lambda seed: "")

    def rows(self, rows: list[dict]) -> None:
        data = {self.prefix(row["seed"]) + name: value for row in rows for name, value in scalars(row).items()}
        self.run.log({"env_steps": rows[0]["env_steps"], **data})

    def video(self, video: Path, env_steps: int) -> None:
        import wandb

        self.run.log({"env_steps": env_steps, "video": wandb.Video(str(video), format=video.suffix.lstrip("."))})

    def close(self) -> None:
        """Finish the run and wait until W&B's service has written it all (finish alone may return before)."""
        import wandb

        self.run.finish()
        wandb.teardown()


class NoLogger:
    def rows(self, rows: list[dict]) -> None:
        pass

    def video(self, video: Path, env_steps: int) -> None:
        pass

    def close(self) -> None:
        pass


def require(name: str) -> None:
    """Refuse a logger whose package is not installed, before a run folder is written for it."""
    if name == "wandb":
        try:
            import wandb  # noqa: F401
        except ImportError:
            raise RunError("--logger wandb needs Weights & Biases, an optional extra: "
                           "pip install 'fieldgen[wandb]'") from None


def open_logger(name: str, folder: Path, seeds: list[int], config: dict):
    """The logger `fieldgen train --logger NAME` writes to; close it when training ends."""
    require(name)
    if name == "tensorboard":
        return TensorBoardLogger(folder, seeds)
    if name == "wandb":
        return WandbLogger(folder, seeds, config)
    return NoLogger()
