"""MuJoCo's start of the constraint solve on MuJoCo Warp's physics, so that sim.backend warp steps a field's own
physics.

MuJoCo, and MJX's JAX implementation with it, start each step's constraint solve from whichever of two
accelerations costs less: the previous step's (the warm start) or the unconstrained one. MuJoCo Warp starts from
the warm start wherever the step has constraints, a choice its authors made for speed (google-deepmind/
mujoco_warp#5). Solved to convergence the start makes no difference; at the fields' one solver iteration it is
the whole difference between the two implementations, so a policy trained on Warp's physics and judged on the
field's own met another physics there. `install` puts MuJoCo's choice in front of Warp's solve: the two costs
(MJX's `Context.create`: the Gauss term and each constraint row's, pyramidal or elliptic cones) per world, and the
cheaper start handed to Warp's solve as its warm start. Not with sleeping or the discrete integrator, whose solves
change the metric; there Warp keeps its own start (`covers`).
"""

import dataclasses  # no postponed annotations: Warp reads its kernels' annotations as they are defined
import functools

PATCHED = "_fieldgen_mujoco_start"  # the attribute that marks Warp's solve as already wrapped


def covers(m) -> bool:
    """Whether MuJoCo's start is put in front of Warp's solve for the Warp model `m` (its options are static)."""
    from mujoco.mjx.third_party.mujoco_warp._src import types

    return (not m.opt.disableflags & types.DisableBit.WARMSTART and m.opt.integrator != types.IntegratorType.DISCRETE
            and not m.opt.enableflags & types.EnableBit.SLEEP)


@functools.cache
def _kernels(is_sparse: bool, nv: int):
    """Two Warp kernels of MuJoCo's choice. `excess`, a thread per world and constraint row: the row's share of the
    warm start's cost less the unconstrained acceleration's (MJX's `Context.create` costs: each row's quadratic or
    friction-loss cost, an elliptic contact's cone cost on its first row, the Gauss term on row 0). `choose`, a
    thread per world and dof: the warm start where that excess is below zero, else the unconstrained acceleration
    (on a tie too, as MJX)."""
    import warp as wp
    from mujoco.mjx.third_party.mujoco_warp._src import types

    always_active_below = int(types.ConstraintType.LIMIT_JOINT)  # equality and friction rows: active either side
    friction_dof, friction_tendon = int(types.ConstraintType.FRICTION_DOF), int(types.ConstraintType.FRICTION_TENDON)
    elliptic = int(types.ConstraintType.CONTACT_ELLIPTIC)
    minval = float(types.MJ_MINVAL)

    @wp.func
    def jaref(world: int, row: int, x: wp.array2d(dtype=float), rownnz: wp.array2d(dtype=int),
              rowadr: wp.array2d(dtype=int), colind: wp.array3d(dtype=int), jac: wp.array3d(dtype=float),
              aref: wp.array2d(dtype=float)) -> float:
        value = -aref[world, row]
        if wp.static(is_sparse):
            adr = rowadr[world, row]
            for k in range(rownnz[world, row]):
                value += jac[world, 0, adr + k] * x[world, colind[world, 0, adr + k]]
        else:
            for i in range(wp.static(nv)):
                value += jac[world, row, i] * x[world, i]
        return value

    @wp.func
    def row_cost(kind: int, jr: float, efc_d: float, floss: float) -> float:
        if floss > 0.0 and (kind == wp.static(friction_dof) or kind == wp.static(friction_tendon)):
            r = 1.0 / wp.static(minval)
            if efc_d != 0.0:
                r = 1.0 / efc_d
            if jr <= -r * floss:
                return -0.5 * r * floss * floss - floss * jr
            if jr >= r * floss:
                return -0.5 * r * floss * floss + floss * jr
        if kind < wp.static(always_active_below) or jr < 0.0:
            return 0.5 * efc_d * jr * jr
        return 0.0

    @wp.func
    def cone_cost(world: int, con: int, mu: float, x: wp.array2d(dtype=float), rownnz: wp.array2d(dtype=int),
                  rowadr: wp.array2d(dtype=int), colind: wp.array3d(dtype=int), jac: wp.array3d(dtype=float),
                  aref: wp.array2d(dtype=float), efc_d: wp.array2d(dtype=float), dim: wp.array(dtype=int),
                  friction: wp.array(dtype=types.vec5), address: wp.array2d(dtype=int)) -> float:
        first = address[con, 0]
        normal = jaref(world, first, x, rownnz, rowadr, colind, jac, aref)
        quadratic = 0.5 * efc_d[world, first] * normal * normal
        tangent = float(0.0)
        for j in range(1, dim[con]):
            row = address[con, j]
            if row < 0:
                return 0.0  # a contact Warp leaves out of the solve
            jr = jaref(world, row, x, rownnz, rowadr, colind, jac, aref)
            u = jr * friction[con][j - 1]
            tangent += u * u
            quadratic += 0.5 * efc_d[world, row] * jr * jr
        n = normal * mu
        t = wp.sqrt(tangent)
        if (t <= 0.0 and n < 0.0) or (t > 0.0 and mu * n + t <= 0.0):
            return quadratic  # bottom zone
        if t > 0.0 and n < mu * t and mu * n + t > 0.0:  # middle zone
            dm = efc_d[world, first] / wp.max(mu * mu * (1.0 + mu * mu), wp.static(minval))
            return 0.5 * dm * (n - mu * t) * (n - mu * t)
        return 0.0

    @wp.kernel(module="unique", enable_backward=False)
    def excess(
        impratio_invsqrt: wp.array(dtype=float),
        nefc_in: wp.array(dtype=int),
        nacon_in: wp.array(dtype=int),
        contact_dim_in: wp.array(dtype=int),
        contact_friction_in: wp.array(dtype=types.vec5),
        contact_efc_address_in: wp.array2d(dtype=int),
        efc_type_in: wp.array2d(dtype=int),
        efc_id_in: wp.array2d(dtype=int),
        efc_J_rownnz_in: wp.array2d(dtype=int),
        efc_J_rowadr_in: wp.array2d(dtype=int),
        efc_J_colind_in: wp.array3d(dtype=int),
        efc_J_in: wp.array3d(dtype=float),
        efc_aref_in: wp.array2d(dtype=float),
        efc_D_in: wp.array2d(dtype=float),
        efc_frictionloss_in: wp.array2d(dtype=float),
        qacc_warmstart_in: wp.array2d(dtype=float),
        qacc_smooth_in: wp.array2d(dtype=float),
        qfrc_smooth_in: wp.array2d(dtype=float),
        ma_warmstart_in: wp.array2d(dtype=float),
        excess_out: wp.array(dtype=float),
    ):
        world, row = wp.tid()
        if row >= nefc_in[world]:
            return
        share = float(0.0)
        if row == 0:  # the Gauss term: zero at the unconstrained acceleration
            for i in range(wp.static(nv)):
                share += 0.5 * (ma_warmstart_in[world, i] - qfrc_smooth_in[world, i]) * (
                    qacc_warmstart_in[world, i] - qacc_smooth_in[world, i])
        kind = efc_type_in[world, row]
        if kind == wp.static(elliptic):
            con = efc_id_in[world, row]
            if con < nacon_in[0] and contact_efc_address_in[con, 0] == row:  # a contact's cost on its first row
                mu = contact_friction_in[con][0] * impratio_invsqrt[world % impratio_invsqrt.shape[0]]
                share += cone_cost(world, con, mu, qacc_warmstart_in, efc_J_rownnz_in, efc_J_rowadr_in,
                                   efc_J_colind_in, efc_J_in, efc_aref_in, efc_D_in, contact_dim_in,
                                   contact_friction_in, contact_efc_address_in)
                share -= cone_cost(world, con, mu, qacc_smooth_in, efc_J_rownnz_in, efc_J_rowadr_in,
                                   efc_J_colind_in, efc_J_in, efc_aref_in, efc_D_in, contact_dim_in,
                                   contact_friction_in, contact_efc_address_in)
        else:
            efc_d = efc_D_in[world, row]
            floss = efc_frictionloss_in[world, row]
            share += row_cost(kind, jaref(world, row, qacc_warmstart_in, efc_J_rownnz_in, efc_J_rowadr_in,
                                          efc_J_colind_in, efc_J_in, efc_aref_in), efc_d, floss)
            share -= row_cost(kind, jaref(world, row, qacc_smooth_in, efc_J_rownnz_in, efc_J_rowadr_in,
                                          efc_J_colind_in, efc_J_in, efc_aref_in), efc_d, floss)
        wp.atomic_add(excess_out, world, share)

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

    return excess, choose


def mujoco_start(m, d):
    """`d` with MuJoCo's start of the solve as its warm start (new arrays: the step's own warm start is kept)."""
    import warp as wp
    from mujoco.mjx.third_party.mujoco_warp._src import support

    excess, choose = _kernels(bool(m.is_sparse), int(m.nv))
    ma_warmstart = wp.zeros_like(d.qacc_warmstart)
    support.mul_m(m, d, ma_warmstart, d.qacc_warmstart)
    excess_cost = wp.zeros(d.nworld, dtype=float, device=d.qacc.device)
    wp.launch(excess, dim=(d.nworld, d.njmax),
              inputs=[m.opt.impratio_invsqrt, d.nefc, d.nacon, d.contact.dim, d.contact.friction,
                      d.contact.efc_address, d.efc.type, d.efc.id, d.efc.J_rownnz, d.efc.J_rowadr, d.efc.J_colind,
                      d.efc.J, d.efc.aref, d.efc.D, d.efc.frictionloss, d.qacc_warmstart, d.qacc_smooth,
                      d.qfrc_smooth, ma_warmstart], outputs=[excess_cost])
    start = wp.zeros_like(d.qacc_warmstart)
    wp.launch(choose, dim=(d.nworld, m.nv), inputs=[excess_cost, d.qacc_warmstart, d.qacc_smooth], outputs=[start])
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
