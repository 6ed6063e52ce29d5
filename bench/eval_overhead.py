"""Where a training run's time goes between its chunks: evaluation, the checkpoint, the video.

Trains one field through the runner's own loop (`agents.loop.run_staged`, filming as
`fieldgen train` does) and, after every chunk, times each piece of work done there, one after
another and waited for: the evaluation episodes, the filmed one among them (between the chunk's
end and the progress callback), copying the training state to the host, serializing and
writing the checkpoint (atomically, synced to disk, into the run folder's file system: `--out`)
and drawing the GIF. The reference, measured in the same run, is the chunk itself; each piece
is printed in seconds and as a share of it, the mean over the evaluations after the first (the
first one compiles). In `fieldgen train` the last two run on a worker thread while the next
chunk trains.

    python bench/eval_overhead.py --field build/soccer_v1 --steps 12000000 --evals 4
"""

from __future__ import annotations

import os
import time
from pathlib import Path

import jax
import numpy as np

import fieldgen
from fieldgen.agents import checkpoint, loop, registry
from fieldgen.curriculum.contract import OneStage
from fieldgen.run import videos
from fieldgen.files import write_atomic
from fieldgen.env.throughput import run_arguments
from fieldgen.files import append_jsonl

PARTS = ("evaluation", "state_to_host", "write_checkpoint", "draw_gif")


def main() -> None:
    parser = run_arguments(__doc__)
    parser.add_argument("--out", type=Path, default=Path("runs"), help="where the checkpoint is written (then removed)")
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    written = args.out / f".eval_overhead_{os.getpid()}.msgpack"

    env = fieldgen.make(args.field)
    entry = registry.trainer(args.algo)
    config = entry.config.layered(total_steps=args.steps, num_envs=args.envs, num_evals=args.evals)
    trainer = entry.make_train(config, env)
    recorder = videos.EpisodeRecorder(env, fmt="gif")
    times: list[dict] = []
    mark = {"t": 0.0}

    def progress(index, rows):
        now = time.perf_counter()
        row = rows[0]
        chunk = (row["env_steps"] - times[-1]["env_steps"]) / row["steps_per_second"] if index else 0.0
        times.append({"eval": index, "env_steps": row["env_steps"], "chunk": chunk,
                      "evaluation": now - mark["t"] - chunk})

    def on_eval(state, index, stage, filmed, sampling):
        timing = times[-1]

        def timed(name, work):
            began = time.perf_counter()
            result = jax.block_until_ready(work())
            timing[name] = time.perf_counter() - began
            return result

        snapshot = timed("state_to_host", lambda: jax.device_get(state))
        timed("write_checkpoint", lambda: write_atomic(written, checkpoint.pieces(snapshot)))
        try:
            timed("draw_gif", lambda: videos.draw_episode(env.mj_model, recorder.episode(filmed[1]),
                                                          recorder.camera, recorder.fmt))
        except Exception:  # noqa: BLE001 - a machine without OpenGL: the GIF is drawn elsewhere
            timing["draw_gif"] = float("nan")
        mark["t"] = time.perf_counter()

    mark["t"] = time.perf_counter()
    try:
        loop.run_staged([trainer], [config.seed], config.num_evals, OneStage(), progress, on_eval,
                        film=videos.EpisodeRecorder.film)
    finally:
        written.unlink(missing_ok=True)
    timed_rows = times[2:] if len(times) > 2 else times[1:]
    chunk = float(np.mean([t["chunk"] for t in timed_rows]))
    result = {"bench": "eval_overhead", "field": env.spec.name, "algo": args.algo, "envs": args.envs,
              "steps_per_chunk": timed_rows[0]["env_steps"] - times[timed_rows[0]["eval"] - 1]["env_steps"],
              "device": jax.devices()[0].device_kind, "chunk_seconds": chunk}
    print(f"{env.spec.name}, {args.algo}, {args.envs} envs, {jax.devices()[0].device_kind}: "
          f"chunk {chunk:.2f} s (mean of evaluations {timed_rows[0]['eval']}..{timed_rows[-1]['eval']})")
    for part in PARTS:
        seconds = float(np.mean([t[part] for t in timed_rows]))
        result[f"{part}_seconds"] = seconds
        print(f"  {part:<22} {seconds:7.2f} s  {seconds / chunk:6.3f} of the chunk")
    if args.json:
        append_jsonl(args.json, result)


if __name__ == "__main__":
    main()
