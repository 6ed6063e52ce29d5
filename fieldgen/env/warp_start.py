"""MuJoCo's start of the constraint solve on MuJoCo Warp's physics, so that sim.backend warp steps a field's own
physics.

MuJoCo, and MJX's JAX implementation with it, start each step's constraint solve from whichever of two
accelerations costs less: the previous step's (the warm start) or the unconstrained one. MuJoCo Warp starts from
the warm start wherever the step has constraints, a choice its authors made for speed (google-deepmind/
mujoco_warp#5). Solved to convergence the start makes no difference; at the fields' one solver iteration it is
the whole difference between the two implementations, so a policy trained on Warp's physics and judged on the
field's own met another physics there. `install` puts MuJoCo's choice in front of Warp's solve: the two costs
(MJX's `Context.create`: the Gauss term and each constraint row's) per world, and the cheaper start handed to
Warp's solve as its warm start. Applied where MuJoCo's cost is this simple: pyramidal cones (every bundled
field's), no sleeping, not the discrete integrator; elsewhere Warp keeps its own start (`covers`).
"""

from __future__ import annotations

import dataclasses
import functools

PATCHED = "_fieldgen_mujoco_start"  # the attribute that marks Warp's solve as already wrapped


def covers(m) -> bool:
    """Whether MuJoCo's start is put in front of Warp's solve for the Warp model `m` (its options are static)."""
    from mujoco.mjx.third_party.mujoco_warp._src import types

    return (not m.opt.disableflags & types.DisableBit.WARMSTART and m.opt.cone == types.ConeType.PYRAMIDAL
            and m.opt.integrator != types.IntegratorType.DISCRETE and not m.opt.enableflags & types.EnableBit.SLEEP)


@functools.cache
def _kernels(is_sparse: bool, nv: int):
    """Warp kernels of MuJoCo's choice: the Gauss term's share of (cost of the warm start - cost of the
    unconstrained acceleration) a thread per world and dof, each constraint row's a thread per world and row (MJX's
    `Context.create` costs, pyramidal cones), and the start, the warm start where that excess is below zero (the
    unconstrained acceleration on a tie, as MJX)."""
    import warp as wp
    from mujoco.mjx.third_party.mujoco_warp._src import types

    always_active_below = int(types.ConstraintType.LIMIT_JOINT)  # equality and friction rows: active either side
    friction_dof, friction_tendon = int(types.ConstraintType.FRICTION_DOF), int(types.ConstraintType.FRICTION_TENDON)
    minval = float(types.MJ_MINVAL)

    @wp.func
    def row_cost(kind: int, jaref: float, efc_d: float, floss: float) -> float:
        if floss > 0.0 and (kind == wp.static(friction_dof) or kind == wp.static(friction_tendon)):
            r = 1.0 / wp.static(minval)
            if efc_d != 0.0:
                r = 1.0 / efc_d
            if jaref <= -r * floss:
                return -0.5 * r * floss * floss - floss * jaref
            if jaref >= r * floss:
                return -0.5 * r * floss * floss + floss * jaref
        if kind < wp.static(always_active_below) or jaref < 0.0:
            return 0.5 * efc_d * jaref * jaref
        return 0.0

    @wp.kernel(module="unique", enable_backward=False)
    def gauss(
        ma_warmstart_in: wp.array2d(dtype=float),
        qfrc_smooth_in: wp.array2d(dtype=float),
        qacc_warmstart_in: wp.array2d(dtype=float),
        qacc_smooth_in: wp.array2d(dtype=float),
        excess_out: wp.array(dtype=float),
    ):
        world, dof = wp.tid()
        wp.atomic_add(excess_out, world, 0.5 * (ma_warmstart_in[world, dof] - qfrc_smooth_in[world, dof])
                      * (qacc_warmstart_in[world, dof] - qacc_smooth_in[world, dof]))

    @wp.kernel(module="unique", enable_backward=False)
    def rows(
        nefc_in: wp.array(dtype=int),
        efc_type_in: wp.array2d(dtype=int),
        efc_J_rownnz_in: wp.array2d(dtype=int),
        efc_J_rowadr_in: wp.array2d(dtype=int),
        efc_J_colind_in: wp.array3d(dtype=int),
        efc_J_in: wp.array3d(dtype=float),
        efc_aref_in: wp.array2d(dtype=float),
        efc_D_in: wp.array2d(dtype=float),
        efc_frictionloss_in: wp.array2d(dtype=float),
        qacc_warmstart_in: wp.array2d(dtype=float),
        qacc_smooth_in: wp.array2d(dtype=float),
        excess_out: wp.array(dtype=float),
    ):
        world, row = wp.tid()
        if row >= nefc_in[world]:
            return
        jw = -efc_aref_in[world, row]
        js = -efc_aref_in[world, row]
        if wp.static(is_sparse):
            adr = efc_J_rowadr_in[world, row]
            for k in range(efc_J_rownnz_in[world, row]):
                col = efc_J_colind_in[world, 0, adr + k]
                jac = efc_J_in[world, 0, adr + k]
                jw += jac * qacc_warmstart_in[world, col]
                js += jac * qacc_smooth_in[world, col]
        else:
            for i in range(wp.static(nv)):
                jac = efc_J_in[world, row, i]
                jw += jac * qacc_warmstart_in[world, i]
                js += jac * qacc_smooth_in[world, i]
        kind = efc_type_in[world, row]
        efc_d = efc_D_in[world, row]
        floss = efc_frictionloss_in[world, row]
        wp.atomic_add(excess_out, world, row_cost(kind, jw, efc_d, floss) - row_cost(kind, js, efc_d, floss))

    @wp.kernel(module="unique", enable_backward=False)
    def choose(
        excess_in: wp.array(dtype=float),
        qacc_warmstart_in: wp.array2d(dtype=float),
        qacc_smooth_in: wp.array2d(dtype=float),
        start_out: wp.array2d(dtype=float),
    ):
        world, dof = wp.tid()
        if excess_in[world] < 0.0:
            start_out[world, dof] = qacc_warmstart_in[world, dof]
        else:
            start_out[world, dof] = qacc_smooth_in[world, dof]

    return gauss, rows, choose


def mujoco_start(m, d):
    """`d` with MuJoCo's start of the solve as its warm start (new arrays: the step's own warm start is kept)."""
    import warp as wp
    from mujoco.mjx.third_party.mujoco_warp._src import support

    gauss, rows, choose = _kernels(bool(m.is_sparse), int(m.nv))
    ma_warmstart = wp.zeros_like(d.qacc_warmstart)
    support.mul_m(m, d, ma_warmstart, d.qacc_warmstart)
    excess = wp.zeros(d.nworld, dtype=float, device=d.qacc.device)
    wp.launch(gauss, dim=(d.nworld, m.nv), inputs=[ma_warmstart, d.qfrc_smooth, d.qacc_warmstart, d.qacc_smooth],
              outputs=[excess])
    wp.launch(rows, dim=(d.nworld, d.njmax),
              inputs=[d.nefc, d.efc.type, d.efc.J_rownnz, d.efc.J_rowadr, d.efc.J_colind, d.efc.J, d.efc.aref,
                      d.efc.D, d.efc.frictionloss, d.qacc_warmstart, d.qacc_smooth], outputs=[excess])
    start = wp.zeros_like(d.qacc_warmstart)
    wp.launch(choose, dim=(d.nworld, m.nv), inputs=[excess, d.qacc_warmstart, d.qacc_smooth], outputs=[start])
    return dataclasses.replace(d, qacc_warmstart=start)


def install() -> None:
    """Wrap MuJoCo Warp's solve (once a process) so that every solve `covers` takes starts from MuJoCo's choice."""
    from mujoco.mjx.third_party.mujoco_warp._src import solver

    solve = solver._solve
    if getattr(solve, PATCHED, False):
        return

    @functools.wraps(solve)
    def solve_from_mujocos_start(m, d, ctx, compact: bool = False):
        if not compact and covers(m):
            d = mujoco_start(m, d)
        return solve(m, d, ctx, compact=compact)

    setattr(solve_from_mujocos_start, PATCHED, True)
    solver._solve = solve_from_mujocos_start


def remove() -> None:
    """Warp's own start back (for measuring what MuJoCo's changes: bench/warp_agreement.py --warp-start warp)."""
    from mujoco.mjx.third_party.mujoco_warp._src import solver

    if getattr(solver._solve, PATCHED, False):
        solver._solve = solver._solve.__wrapped__
