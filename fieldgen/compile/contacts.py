"""Contact pruning: which geom roles may touch, as contype/conaffinity bits.

Every colliding geom gets one role bit as its contype and the bits of the roles
it may touch as its conaffinity. The relation is symmetric, so MuJoCo's rule
(ct1 & ca2 or ct2 & ca1) selects exactly the intended role pairs and nothing
else. MJX pays for every candidate pair on every step, near or far, so this
table is the main lever on simulation speed beyond the agent itself.
"""

from __future__ import annotations

from itertools import combinations

import mujoco

from fieldgen.schema.backends import mjx_impl
from fieldgen.schema.models import AGENT_CONTACTS, FieldSpec

ROLES = ("floor", "ball", "foot", "torso", "wall", "obstacle", "post")
BIT = {role: 1 << i for i, role in enumerate(ROLES)}
STATIC = ("wall", "obstacle", "post")


def relation(spec: FieldSpec) -> set[frozenset[str]]:
    """Role pairs that can matter for this field."""
    pairs = {frozenset(p) for p in (("ball", "foot"), ("ball", "torso"), ("foot", "floor"))}
    if spec.ball.enabled:
        if ball_touches_floor(spec):
            pairs.add(frozenset(("ball", "floor")))
        pairs |= {frozenset(("ball", s)) for s in STATIC}
    pairs |= {frozenset((a, s)) for a in AGENT_CONTACTS[spec.sim.agent_contacts] for s in STATIC}
    if spec.teams is not None:  # agents push each other: torso on torso (an agent's own torso is one geom)
        pairs.add(frozenset(("torso",)))
    if spec.sim.contacts == "torso_floor":  # a turned-over ant lies on its back, not with its torso under the floor
        pairs.add(frozenset(("torso", "floor")))
    return pairs


def ball_touches_floor(spec: FieldSpec) -> bool:
    """Whether the ball has a floor contact: a free ball does, and so does a puck under brax, whose
    pipelines ignore joint frictionloss; under MJX a puck's floor friction is frictionloss (scene.py)."""
    return spec.ball.joint == "free" or mjx_impl(spec) is None


# The soccer study's XML: geoms default to 0/0, the floor and torso only receive
# (0/1), the feet send and receive (1/1), the ball only sends (1/0).
STUDY_BITS = {"floor": (0, 1), "torso": (0, 1), "foot": (1, 1), "ball": (1, 0)}


def bits(role: str, spec: FieldSpec) -> tuple[int, int]:
    """(contype, conaffinity) for a geom of this role."""
    if spec.sim.contacts == "study":
        return STUDY_BITS.get(role, (0, 0))
    affinity = 0
    for pair in relation(spec):
        if role in pair:
            other = set(pair - {role}) or {role}
            affinity |= BIT[other.pop()]
    return BIT[role], affinity


def contact_limit(spec: FieldSpec) -> int | None:
    """How many contacts the solver sees per step (nearest first), or None for all.

    Far-apart pairs still run their collision test but add no solver rows: the
    solver's cost grows with rows, and a field rarely has more than a few
    contacts active beyond the agent's feet on the floor.
    """
    limit = spec.sim.max_contacts
    if limit == "all":
        return None
    if limit != "auto":
        return limit
    agents = 1 if spec.teams is None else spec.teams.home.agents + spec.teams.away.agents
    resting = 4 * agents if spec.agent.kind == "ant" else 0
    resting += 1 if spec.ball.enabled and ball_touches_floor(spec) else 0
    return resting + 8


def candidate_pairs(model: mujoco.MjModel) -> list[tuple[str, str]]:
    """Geom pairs MuJoCo (and MJX) will test for contact, by MuJoCo's filter rules."""
    filterparent = not (model.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_FILTERPARENT)
    out = []
    for g1, g2 in combinations(range(model.ngeom), 2):
        ct1, ca1 = model.geom_contype[g1], model.geom_conaffinity[g1]
        ct2, ca2 = model.geom_contype[g2], model.geom_conaffinity[g2]
        if not (ct1 & ca2 or ct2 & ca1):
            continue
        w1, w2 = model.body_weldid[model.geom_bodyid[g1]], model.body_weldid[model.geom_bodyid[g2]]
        if w1 == w2:
            continue
        p1, p2 = model.body_weldid[model.body_parentid[w1]], model.body_weldid[model.body_parentid[w2]]
        if filterparent and w1 != 0 and w2 != 0 and (w1 == p2 or w2 == p1):
            continue
        out.append((model.geom(g1).name, model.geom(g2).name))
    return out
