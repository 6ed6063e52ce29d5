"""Where a turned-over ant comes to rest, under a field's contact set and under `sim.contacts: torso_floor`: the
ant dropped upside down from 0.6 m with its motors idle, stepped by MuJoCo for 4 s, drawn from the side at the
floor's height beside its torso's height. Under the default contacts the torso has no floor contact and sinks
through it, and only the feet show above the floor; with torso_floor the ant lies on its back.

    python bench/turned_over_ant.py soccer_v2_dense --out turned_over.png
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

import fieldgen  # noqa: F401  (first: it picks the headless OpenGL back end before mujoco loads)
import mujoco

UPSIDE_DOWN = (0.0, 1.0, 0.0, 0.0)  # half a turn about x: the torso's up axis points down
SECONDS = 4.0


def rest(model: mujoco.MjModel) -> mujoco.MjData:
    """The model's data once an ant dropped upside down has come to rest."""
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key("home").id)
    root = model.joint("root").qposadr[0]
    data.qpos[root + 2: root + 7] = (0.6, *UPSIDE_DOWN)
    for _ in range(int(SECONDS / model.opt.timestep)):
        mujoco.mj_step(model, data)
    return data


def side_view(model: mujoco.MjModel, data: mujoco.MjData, size: tuple[int, int] = (300, 400)) -> np.ndarray:
    """The ant from the side, the camera a little above the floor and looking at the torso's floor point."""
    from fieldgen.render import renderer

    camera = mujoco.MjvCamera()
    camera.type = mujoco.mjtCamera.mjCAMERA_FREE
    torso = data.xpos[model.body("torso").id]
    camera.lookat[:] = (torso[0], torso[1], 0.1)
    camera.distance, camera.azimuth, camera.elevation = 2.2, 0.0, -8.0
    with renderer(model, size) as r:
        r.update_scene(data, camera=camera)
        return r.render()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("field", help="an ant field: bundled name or YAML")
    parser.add_argument("--out", type=Path, required=True, help="the PNG to write")
    args = parser.parse_args()

    from fieldgen.compile.artifact import compile_spec
    from fieldgen.render import contact_sheet
    from fieldgen.schema import load_spec, resolve_spec_path

    spec = load_spec(resolve_spec_path(args.field))
    images, titles, captions = [], [], []
    for contacts in ("pruned", "torso_floor"):
        variant = spec.model_copy(update={"sim": spec.sim.model_copy(update={"contacts": contacts})})
        model = compile_spec(variant).model()
        data = rest(model)
        height = data.qpos[model.joint("root").qposadr[0] + 2]
        images.append(side_view(model, data))
        titles.append(f"sim.contacts: {contacts}")
        captions.append(f"torso centre at {height:+.2f} m after {SECONDS:g} s")
        print(f"{contacts}: torso centre at {height:+.3f} m")
    args.out.write_bytes(contact_sheet(images, titles, columns=2, captions=captions))


if __name__ == "__main__":
    main()
