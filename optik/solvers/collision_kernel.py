"""The step and error functions of the collision-aware ``lm`` kernel, with the world rows as a loop.

The residual is the one of `optik.solvers.lm_kernel`'s kernel with the collision hinges appended
to the closure rows, ``e = [w_p r_p; w_o r_o; w_c c; w_c h_self; w_c h_world]``, with
``h = max(0, b - d)`` for the distance bounds ``d`` of `optik.collision.spheres` (``h_world``
times the slot's active flag). Unrolled as one expression the world rows make the generated C
large (the Panda with 8 slots: 520 rows, 275k operations, minutes of compiling), so the function
is built in three pieces:

* the robot (an ``SX`` function of ``q``): the task and self-collision rows and their Jacobian,
  the moving spheres' centres ``c_s`` and their point Jacobians ``J_s = dc_s/dq``;
* one world row (``SX``): ``h`` of one sphere and one slot, and its gradient by the chain rule
  ``dh/dq = (dh/dc) J_s`` (3 columns instead of ``n``);
* the step (``MX``): that row **mapped** over spheres and slots (a loop in the generated C), the
  Gauss-Newton matrix ``J^T J`` and gradient ``J^T e`` of the stacked rows, and the projected LM
  trial (`_trial_function`), accepted as in `optik.solvers.lm_kernel.lm_iteration_function`
  (same inputs and outputs).

Target parameters: the 12 of each frame target (`optik.problem.target_parameters`), then the
``capacity * SLOT_SIZE`` slot values, the bound ``b`` (margin + buffer) and one active flag per
self-collision pair (`bound_parameters`): the margin is a number the compiled code reads, so a
new margin builds no new code.
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from optik.collision.robot import RobotGeometry
from optik.collision.slots import SLOT_SIZE, slot_distance
from optik.collision.spheres import segment_distance, separable_pairs, sphere_model
from optik.problem import IKProblem
from optik.solvers.lm_kernel import accept_or_keep

__all__ = ["bound_parameters", "constrained_functions"]

_EPS = 1e-9


def _moving_spheres(geo: RobotGeometry) -> np.ndarray:
    """Indices of the spheres of parts that are not on the base body."""
    m, model = geo.mechanism, sphere_model(geo)
    link = geo.part_link[model.part]
    moving = [m.frames[geo.links[k]][0] != m.base for k in link]
    return np.flatnonzero(moving)


def _links(problem: IKProblem, geo: RobotGeometry) -> tuple[ca.Function, ca.Function]:
    """``q -> (L, dL)`` and ``q -> L``: ``L`` the ``(12, links)`` rotation (column-major) and origin
    of each link of ``geo``, ``dL`` the ``(12, n links)`` Jacobians of the columns side by side."""
    m, q = geo.mechanism, problem.q
    cols = [ca.vertcat(ca.vec(t[:3, :3]), t[:3, 3]) for t in (m.frame_expr(link) for link in geo.links)]
    lq = ca.horzcat(*cols)
    dl = ca.horzcat(*(ca.jacobian(col, q) for col in cols))
    return ca.Function("links", [q], [lq, dl]), ca.Function("links_values", [q], [lq])


def _point(l: ca.SX, x: ca.SX) -> ca.SX:
    """The base-frame position of the link-frame point ``x`` for link columns ``l`` (12)."""
    return ca.mtimes(ca.reshape(l[:9], 3, 3), x) + l[9:12]


def _sphere(n: int) -> tuple[ca.Function, ca.Function]:
    """One sphere centre from its link: ``(l, dl, x) -> (c, dc/dq)`` and ``(l, x) -> c``."""
    l, dl, x = ca.SX.sym("l", 12), ca.SX.sym("dl", 12, n), ca.SX.sym("x", 3)
    c = _point(l, x)
    return (
        ca.Function("sphere", [l, dl, x], [c, ca.mtimes(ca.jacobian(c, l), dl)]),
        ca.Function("sphere_value", [l, x], [c]),
    )


def _self_row(n: int) -> tuple[ca.Function, ca.Function]:
    """One self-collision pair of capsules on links ``i`` and ``j``: ``(l_i, dl_i, l_j, dl_j,
    ends, rho, b, a) -> (h, dh/dq)`` and ``(l_i, l_j, ends, rho, b, a) -> h`` with
    ``h = a max(0, b - d)``, ``d`` the capsules' distance, ``ends`` the four segment ends in their
    link frames, ``rho`` the sum of the radii, ``a`` the pair's active flag."""
    li, lj = ca.SX.sym("li", 12), ca.SX.sym("lj", 12)
    dli, dlj = ca.SX.sym("dli", 12, n), ca.SX.sym("dlj", 12, n)
    ends, rho = ca.SX.sym("ends", 12), ca.SX.sym("rho")
    bound, active = ca.SX.sym("bound"), ca.SX.sym("active")
    pts = [_point(l, ends[3 * k : 3 * k + 3]) for l, k in ((li, 0), (li, 1), (lj, 2), (lj, 3))]
    h = active * ca.fmax(0, bound - (segment_distance(*pts) - rho))
    grad = ca.mtimes(ca.jacobian(h, li), dli) + ca.mtimes(ca.jacobian(h, lj), dlj)
    return (
        ca.Function("self_row", [li, dli, lj, dlj, ends, rho, bound, active], [h, grad.T]),
        ca.Function("self_row_value", [li, lj, ends, rho, bound, active], [h]),
    )


def _trial_function(n: int) -> ca.Function:
    """``(q, H, g, mu, gain, q_ref, lo, hi) -> clip(q + dq, lo, hi)``, the projected LM trial of
    `optik.solvers.lm_kernel.lm_iteration_function` from ``H = J^T J`` and ``g = J^T e``: with
    ``D`` the coordinates not held at a limit that ``g`` pushes outwards,
    ``(D H D + mu I + (I - D)) dq = D (-g + gain mu (q_ref - q))``."""
    q, jtj, g = ca.SX.sym("q", n), ca.SX.sym("jtj", n, n), ca.SX.sym("g", n)
    mu, gain, q_ref = ca.SX.sym("mu"), ca.SX.sym("gain"), ca.SX.sym("q_ref", n)
    lo, hi = ca.SX.sym("lower", n), ca.SX.sym("upper", n)
    free = 1 - ca.logic_or(ca.logic_and(q <= lo, g > 0), ca.logic_and(q >= hi, g < 0))
    d = ca.diag(free)
    lhs = ca.mtimes([d, jtj, d]) + ca.diag(mu + 1 - free)
    dq = ca.solve(lhs, free * (-g + gain * mu * (q_ref - q)))
    return ca.Function(
        "projected_trial", [q, jtj, g, mu, gain, q_ref, lo, hi], [ca.fmin(ca.fmax(q + dq, lo), hi)]
    )


def _columns(n: int, links: np.ndarray) -> list[int]:
    """Columns of ``dL`` (blocks of ``n``) for each of ``links``, in order."""
    return [int(k) * n + j for k in links for j in range(n)]


def _world_row(n: int) -> tuple[ca.Function, ca.Function]:
    """One sphere against one slot: ``(c, J_c, slot, R, b) -> (h, dh/dq)`` and
    ``(c, slot, R, b) -> h``."""
    c, jc = ca.SX.sym("c", 3), ca.SX.sym("jc", 3, n)
    slot, radius, bound = ca.SX.sym("slot", SLOT_SIZE), ca.SX.sym("radius"), ca.SX.sym("bound")
    h = slot[SLOT_SIZE - 1] * ca.fmax(0, bound - (slot_distance(slot, c, _EPS) - radius))
    grad = ca.mtimes(ca.jacobian(h, c), jc).T
    return (
        ca.Function("world_row", [c, jc, slot, radius, bound], [h, grad]),
        ca.Function("world_row_value", [c, slot, radius, bound], [h]),
    )


def bound_parameters(geo: RobotGeometry, self_collision: bool, bound: float) -> np.ndarray:
    """The parameters after the slots (see the module docstring): ``bound`` and the active flag
    of each self-collision pair, 1 for the pairs whose capsules can keep ``bound`` apart
    (`optik.collision.spheres.separable_pairs`), the others left to the exact check."""
    flags = separable_pairs(geo, bound).astype(float) if self_collision else np.zeros(0)
    return np.concatenate([[bound], flags])


def constrained_functions(
    problem: IKProblem,
    geo: RobotGeometry,
    capacity: int,
    self_collision: bool,
    closure_weight: float,
) -> tuple[ca.Function, ca.Function]:
    """The step (``optik_lm_step``) and error (``optik_ik_errors``) functions of the constrained
    kernel for a world of ``capacity`` slots, the required distance bound a parameter.

    Args:
        problem: the pose problem (`optik.problem.build_ik_problem`).
        geo: the robot geometry.
        capacity: world slots.
        self_collision: add the capsule rows of the self-collision pairs (each with its flag).
        closure_weight: the weight ``w_c`` of closure and collision rows.
    """
    m = geo.mechanism
    n = m.n_q
    model = sphere_model(geo)
    spheres = _moving_spheres(geo)
    n_s = len(spheres)
    sphere_links = geo.part_link[model.part[spheres]]
    pairs = geo.self_pairs if self_collision else np.zeros((0, 2), dtype=int)
    pair_links = geo.part_link[pairs].reshape(-1, 2)
    ends = ca.DM(np.array([model.segments[pair].reshape(-1) for pair in pairs]).reshape(-1, 12).T)
    rhos = ca.DM(model.capsule_radii[pairs].sum(axis=1).reshape(1, -1))
    links, links_values = _links(problem, geo)
    # mapped over spheres and pairs; none of them without any (a map of 0 is refused by CasADi)
    if n_s:
        sphere, sphere_value = (f.map(n_s) for f in _sphere(n))
        row, row_value = _world_row(n)
        world = row.map(capacity).map(n_s)  # index s * capacity + k: sphere s, slot k
        world_value = row_value.map(capacity).map(n_s)
    if len(pairs):
        self_row, self_row_value = (f.map(len(pairs)) for f in _self_row(n))
    radii = ca.DM(model.radii[spheres]).T
    local = ca.DM(model.centres[spheres].T)
    ins = [problem.q, problem.target, problem.weights]
    e_task = problem.weighted_residual(closure_weight)
    task = ca.Function("task", ins, [e_task, *problem.error_expressions()])
    task_jac = ca.Function("task_jacobian", ins, [ca.jacobian(e_task, problem.q)])

    q, mu, gain = ca.MX.sym("q", n), ca.MX.sym("mu"), ca.MX.sym("gain")
    n_pose = problem.target.numel()  # 12 per frame target
    n_world = capacity * SLOT_SIZE
    target = ca.MX.sym("target", n_pose + n_world + 1 + len(pairs))
    weights, q_ref = ca.MX.sym("weights", 2), ca.MX.sym("q_ref", n)
    lo, hi = ca.MX.sym("lower", n), ca.MX.sym("upper", n)
    pose, slots = target[:n_pose], ca.reshape(target[n_pose : n_pose + n_world], SLOT_SIZE, capacity)
    bound, active = target[n_pose + n_world], target[n_pose + n_world + 1 :].T

    i_links, j_links = [int(k) for k in pair_links[:, 0]], [int(k) for k in pair_links[:, 1]]
    s_links = [int(k) for k in sphere_links]

    def rows_at(x: ca.MX, w: ca.MX | ca.DM) -> tuple[ca.MX, ca.MX, ca.MX, ca.MX]:
        """The residual at ``x`` and the errors (collision hinges in the closure error)."""
        e, pos, ori, clo = task(x, pose, w)
        lx = links_values(x)
        h = [ca.MX(0, 1)]
        if len(pairs):
            h.append(self_row_value(lx[:, i_links], lx[:, j_links], ends, rhos, bound, active).T)
        if n_s:
            h.append(world_value(sphere_value(lx[:, s_links], local), slots, radii, bound).T)
        hinge = ca.vertcat(*h)
        if hinge.shape[0]:
            clo = ca.fmax(clo, ca.mmax(hinge))
        return ca.vertcat(e, closure_weight * hinge), pos, ori, clo

    lq, dl = links(q)
    e_rows, j_rows = [task(q, pose, weights)[0]], [task_jac(q, pose, weights)]
    if len(pairs):
        h, grad = self_row(
            lq[:, i_links],
            dl[:, _columns(n, i_links)],
            lq[:, j_links],
            dl[:, _columns(n, j_links)],
            ends,
            rhos,
            bound,
            active,
        )
        e_rows.append(closure_weight * h.T)
        j_rows.append(closure_weight * grad.T)
    if n_s:
        c, jc = sphere(lq[:, s_links], dl[:, _columns(n, s_links)], local)
        h, grad = world(c, jc, slots, radii, bound)
        e_rows.append(closure_weight * h.T)
        j_rows.append(closure_weight * grad.T)
    e, jac = ca.vertcat(*e_rows), ca.vertcat(*j_rows)
    jtj, g = ca.mtimes(jac.T, jac), ca.mtimes(jac.T, e)
    q_trial = _trial_function(n)(q, jtj, g, mu, gain, q_ref, lo, hi)
    e_trial, pos, ori, clo = rows_at(q_trial, weights)
    outs = accept_or_keep(q, q_trial, mu, e, e_trial, [pos, ori, clo])
    step = ca.Function("optik_lm_step", [q, mu, target, weights, q_ref, gain, lo, hi], outs)
    _, pos0, ori0, clo0 = rows_at(q, ca.DM.ones(2))  # the errors do not depend on the weights
    errors = ca.Function("optik_ik_errors", [q, target], [pos0, ori0, clo0])
    return step, errors
