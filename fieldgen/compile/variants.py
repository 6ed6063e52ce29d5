"""Variants of a field built to one structure, so that one batched simulation steps them all.

MJX batches models that differ only in array values (geom positions and sizes,
body positions...). Variants of a curriculum differ in structure too: one has
walls or a goalie, another not. Here every variant gets the union of all the
variants' static geoms, in one order; a geom a variant lacks is kept, parked deep
under the floor and made invisible, so it never touches anything.
"""

from __future__ import annotations

import hashlib

from fieldgen.compile.artifact import Artifact, spec_hash
from fieldgen.schema.models import FieldSpec

# Metres below where the geom would stand: no body gets there, and the floor hides it. Not far away
# sideways: the model's extent (which scales the cameras' near plane) would grow with it.
PARK_DEPTH = 20.0


class VariantError(Exception):
    """Variants that cannot share one batched simulation."""


def compile_variants(specs: list[FieldSpec]) -> list[Artifact]:
    """One artifact per spec, all with the same bodies, joints and geoms in the same order."""
    from fieldgen.compile.scene import build_scene, fixtures

    own = [{g["name"]: g for g in fixtures(spec)} for spec in specs]
    order = list(dict.fromkeys(name for geoms in own for name in geoms))
    for name in order:
        kinds = {(g[name]["type"], g[name]["contype"], g[name]["conaffinity"]) for g in own if name in g}
        if len(kinds) > 1:
            raise VariantError(f"geom '{name}' is solid in some variants and not in others (or changes shape); "
                               "variants trained in one batch must agree on what collides")
    artifacts = []
    for spec, geoms in zip(specs, own):
        placed = [geoms[n] if n in geoms else _parked(next(g[n] for g in own if n in g)) for n in order]
        digest = hashlib.sha256(f"{spec_hash(spec)}\n{','.join(order)}".encode()).hexdigest()[:16]
        scene = build_scene(spec, placed)
        scene.model = specs[-1].name  # one model name: MJX keeps names (and their lengths) as structure
        artifacts.append(Artifact(spec, scene.to_xml_string(), digest))
    return artifacts


def _parked(attrs: dict) -> dict:
    """The same geom, moved out of play and made invisible."""
    out = dict(attrs, rgba=tuple(attrs["rgba"][:3]) + (0.0,))
    if "fromto" in attrs:
        x0, y0, z0, x1, y1, z1 = attrs["fromto"]
        out["fromto"] = (x0, y0, z0 - PARK_DEPTH, x1, y1, z1 - PARK_DEPTH)
    else:
        x, y, z = attrs["pos"]
        out["pos"] = (x, y, z - PARK_DEPTH)
    return out
