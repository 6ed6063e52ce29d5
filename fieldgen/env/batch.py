"""Several variants of a field as one batched MJX model: what must agree between them, and the
model whose leaves that differ are stacked on a leading variant axis."""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING

import jax
import jax.numpy as jnp
import numpy as np

from fieldgen.compile.layout import observation_layout
from fieldgen.env import mjx_physics

if TYPE_CHECKING:
    from fieldgen.env.rules import EpisodeRules


def check_compatible(rules: list[EpisodeRules], models, layout) -> None:
    """Variants batched together must share the observation layout, the control period and the structure."""
    first = rules[0].spec
    for v, model in zip(rules[1:], models[1:]):
        if observation_layout(v.spec, model).to_json() != layout.to_json():
            raise ValueError(f"{v.spec.name} and {first.name} observe different things; "
                             "variants trained in one batch need one observation layout")
        e, f = v.spec.episode, first.episode
        if (e.control_dt, e.substeps) != (f.control_dt, f.substeps):
            raise ValueError(f"{v.spec.name} steps {e.substeps} x {e.physics_dt} s and {first.name} "
                             f"{f.substeps} x {f.physics_dt} s; variants trained in one batch need one control period")
        if v.spec.sim.precision != first.sim.precision:
            raise ValueError(f"{v.spec.name} and {first.name} differ in sim.precision")
        if v.spec.sim.backend != first.sim.backend:
            raise ValueError(f"{v.spec.name} and {first.name} differ in sim.backend")


# Static (non-array) model fields that differ between variants but that stepping never reads:
# keyframes (each variant's home pose is read from its own MjModel), height-field bounds and the
# cameras' resolution (the top view's aspect follows each variant's field; rendering reads its own MjModel).
_UNREAD_STATIC = {"key_time", "key_qpos", "key_qvel", "key_act", "key_mpos", "key_mquat", "key_ctrl",
                  "geom_rbound_hfield", "cam_resolution"}


def own_device() -> jax.Device:
    """Where mjx puts a field's model and first state: this process's first device. mjx's default,
    jax.devices()[0], is process 0's in a run over several, which no other process may compute with."""
    return jax.local_devices()[0]


def refuse_warp_batch(names: list[str], impl: str) -> None:
    """ValueError where variants (a mixed curriculum's stages, an automatic curriculum's levels) of Warp's physics
    would be batched in one model."""
    if impl == "warp" and len(names) > 1:
        raise ValueError(f"{names[-1]}: variants batched in one model (a mixed curriculum's stages, --curriculum "
                         "auto's levels) run on sim.backend mjx only (fieldgen stacks the models of MJX's JAX "
                         "implementation, not Warp's, whose static fields it cannot compare): train the stages in "
                         "turn (without --mixed), or the field on sim.backend: mjx")


def batched_model(models, names: list[str], impl: str = "jax") -> tuple[object, frozenset[int]]:
    """One mjx.Model of MJX's implementation `impl` whose leaves that differ between the variants are stacked on
    a leading axis, and the indices of those leaves."""
    refuse_warp_batch(names, impl)
    systems = [mjx_physics.put_model(m, impl, own_device(), field=n) for m, n in zip(models, names)]
    first = systems[0]
    systems = [first] + [_static_like(first, s, f"{n} and {names[0]}") for s, n in zip(systems[1:], names[1:])]
    columns = zip(*(jax.tree.leaves(s) for s in systems))
    leaves, varying = [], set()
    for i, column in enumerate(columns):
        if all(np.array_equal(np.asarray(column[0]), np.asarray(c)) for c in column[1:]):
            leaves.append(column[0])
        else:
            leaves.append(jnp.stack(column))
            varying.add(i)
    return jax.tree.structure(systems[0]).unflatten(leaves), frozenset(varying)


def _static_like(first, other, which: str):
    """`other` with the unread static fields of `first`; any other static difference is an error."""
    changes = {}
    for field in dataclasses.fields(other):
        a, b = getattr(first, field.name), getattr(other, field.name)
        if dataclasses.is_dataclass(b) and not isinstance(b, type):
            b = _static_like(a, b, which)
        elif isinstance(b, jax.Array) or _same(a, b):
            continue
        elif field.name not in _UNREAD_STATIC:
            raise ValueError(f"{which} differ in the model's structure ({field.name}); variants trained in one "
                             "batch must share bodies, joints, geoms and contact settings (build them with "
                             "fieldgen.compile.variants.compile_variants)")
        else:
            b = a
        changes[field.name] = b
    return other.replace(**changes) if changes else other


def _same(a, b) -> bool:
    try:
        return bool(np.array_equal(np.asarray(a), np.asarray(b)))
    except (TypeError, ValueError):
        return a == b
