"""The collision-aware IPOPT's NLP functions, built from small mapped pieces (`nlp_functions`).

The NLP of the collision-aware ``nlp`` (`optik.solvers.collision_free`) is

```text
minimize_q  f(q; p)   subject to  q_min <= q <= q_max,  c(q) = 0,
            a_k (d_k(q) - b) >= 0  for every world row and every self-collision pair,
```

``d_k`` a lower bound of a signed distance (`optik.collision.spheres`), ``b`` the bound and
``a_k`` an active flag (a slot's, a pair's: parameters). Every ``d_k`` depends on ``q`` only
through a few **points**: the two ends ``P`` of each capsule segment (a self pair reads four) or
the centre of one moving sphere (a world row reads one). Written as one expression, the rows, their
Jacobian and above all their Hessian are large (the dual Panda's 376 pairs: 1.4 million ``SX``
operations for the Hessian, milliseconds an IPOPT iteration in CasADi's virtual machine, 47 MB of C).
Here each is assembled from the points instead:

* the points ``P(q)`` (``3 N``) and their Jacobian ``J_P = dP/dq`` (sparse: a point moves with the
  joints of its chain), one ``SX`` function of ``q``: the ends ``a, b`` of each capsule in a pair,
  its direction ``e = R (b - a)`` (identically 0 for a sphere's point segment) and the moving
  spheres' centres;
* one row ``h_k(x_k)`` of its points ``x_k = S_k P`` (``S_k`` a selection), its gradient
  ``u_k = dh_k/dx_k`` and its weighted Hessian ``lambda_k d^2 h_k / dx_k^2``: small ``SX`` functions
  **mapped** over the pairs (and over spheres and slots), loops in the generated code;
* the constraint Jacobian by the chain rule, ``dh/dq = D J_P`` with ``D`` the sparse matrix of the
  rows ``u_k^T S_k``;
* the Hessian of the Lagrangian ``sigma f + lambda_c^T c + sum_k lambda_k h_k``, exactly, as
  ``H = nabla^2 (sigma f + lambda_c^T c) + J_P^T K J_P + nabla_q^2 (w^T P(q))`` with
  ``K = sum_k lambda_k S_k^T (d^2 h_k / dx_k^2) S_k`` (``3 N x 3 N``, summed by one sparse product)
  and ``w = D^T lambda`` the multiplier-weighted point gradients: the second term is the rows'
  curvature in the points, the third the points' own curvature in ``q`` (one ``SX`` function of
  ``q`` and ``w``, the size of the forward kinematics' second derivatives). A pair's Hessian is
  taken in the 9 numbers its distance depends on, ``z = (e_i, e_j, a_i - a_j)``
  (`optik.collision.spheres.relative_segment_distance`: 1.8k operations instead of 2.7k for the
  12 segment ends), and ``K`` is summed on those points: on the ends ``a, b`` themselves the
  curvature along a point segment's zero direction (up to ``1 / 10^-12``, the divisors' floor)
  would meet ``J_b - J_a = 0`` only after rounding, leaving errors of ``10^-6`` in ``H``.

The five functions IPOPT calls (``f``, ``g``, ``grad_f``, ``jac_g``, ``hess_lag``) are ``MX``
graphs of those pieces: about a hundred nodes, evaluated by CasADi's virtual machine, and small
generated C (`optik.native.library`, compiled once per machine in the background).
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

from optik.collision.robot import RobotGeometry
from optik.collision.slots import SLOT_SIZE, slot_distance
from optik.collision.spheres import relative_segment_distance, segment_distance, sphere_model
from optik.problem import IKProblem

__all__ = ["NLPFunctions", "nlp_functions"]

_EPS = 1e-9  # the norm smoothing of `optik.collision.spheres`


@dataclass(frozen=True)
class NLPFunctions:
    """The functions of one collision-aware NLP (see the module docstring).

    Attributes:
        f: ``(x, p) -> f``.
        g: ``(x, p) -> g``.
        grad_f: ``(x, p) -> (f, grad_f_x)``.
        jac_g: ``(x, p) -> (g, jac_g_x)``.
        hess_lag: ``(x, p, lam_f, lam_g) -> triu_hess_gamma_x_x`` (upper triangle).
        n_closure: leading equality rows of ``g`` (the loop closures).
    """

    f: ca.Function
    g: ca.Function
    grad_f: ca.Function
    jac_g: ca.Function
    hess_lag: ca.Function
    n_closure: int

    def all(self) -> list[ca.Function]:
        """The five functions, in the order of the attributes."""
        return [self.f, self.g, self.grad_f, self.jac_g, self.hess_lag]


def _row_functions(
    name: str, h: ca.SX, x: ca.SX, h_z: ca.SX, z: ca.SX, t: np.ndarray, rest: list[ca.SX]
) -> list[ca.Function]:
    """``(x, *rest) -> h``, ``(x, *rest) -> dh/dx`` and ``(x, *rest, lam) -> lam d^2h/dz^2`` of one
    row ``h`` of its point coordinates ``x``, which depends on them through ``z = t x`` only
    (``h_z`` the same row as an expression of ``z``): the Hessian in ``x`` is ``t^T (d^2h/dz^2) t``."""
    lam = ca.SX.sym("lam")
    hess_z = ca.substitute(ca.hessian(h_z, z)[0], z, ca.mtimes(ca.DM(t), x))
    ins = [x, *rest]
    return [
        ca.Function(f"{name}_value", ins, [h]),
        ca.Function(f"{name}_grad", ins, [ca.densify(ca.gradient(h, x))]),
        ca.Function(f"{name}_hess", [*ins, lam], [ca.densify(lam * hess_z)]),
    ]


_PAIR_T = np.kron(np.array([[-1, 1, 0, 0], [0, 0, -1, 1], [1, 0, -1, 0]]), np.eye(3))
"""``z = (q1 - p1, q2 - p2, p1 - p2) = _PAIR_T x`` of a pair's segment ends ``x = (p1, q1, p2, q2)``:
where its Hessian is evaluated (the directions as the distance computes them)."""


def _pair_functions() -> list[ca.Function]:
    """One self pair: ``x`` the ends of its two segments (12), ``ri, rj`` the capsule radii,
    ``h = a ((|seg_i - seg_j| - r_i - r_j) - b)``."""
    x, ri, rj = ca.SX.sym("x", 12), ca.SX.sym("ri"), ca.SX.sym("rj")
    bound, active = ca.SX.sym("bound"), ca.SX.sym("active")
    h = active * (segment_distance(*(x[3 * k : 3 * k + 3] for k in range(4))) - ri - rj - bound)
    z = ca.SX.sym("z", 9)
    h_z = active * (relative_segment_distance(z[:3], z[3:6], z[6:]) - ri - rj - bound)
    return _row_functions("optik_pair", h, x, h_z, z, _PAIR_T, [ri, rj, bound, active])


def _world_functions() -> list[ca.Function]:
    """One sphere (centre ``x``, radius ``R``) against one slot:
    ``h = a ((sd_slot(x) - R) - b)``, ``a`` the slot's active flag."""
    x, slot, radius, bound = ca.SX.sym("x", 3), ca.SX.sym("slot", SLOT_SIZE), ca.SX.sym("R"), ca.SX.sym("b")
    z = ca.SX.sym("z", 3)
    h, h_z = (slot[SLOT_SIZE - 1] * (slot_distance(slot, v, _EPS) - radius - bound) for v in (x, z))
    return _row_functions("optik_world", h, x, h_z, z, np.eye(3), [slot, radius, bound])


def _scatter(
    rows: np.ndarray, cols: np.ndarray, src: np.ndarray, coef: np.ndarray, shape: tuple[int, int], n_in: int
) -> tuple[ca.Sparsity, ca.DM]:
    """The sparsity of a ``shape`` matrix ``A`` with entries at ``(rows[i], cols[i])`` and the
    constant matrix ``G`` (nonzeros of ``A`` x ``n_in``) with ``nz(A) = G v`` for the terms
    ``A[rows[i], cols[i]] += coef[i] v[src[i]]`` (nonzeros in column-major order)."""
    lin = np.asarray(cols, dtype=np.int64) * shape[0] + np.asarray(rows, dtype=np.int64)
    unique, nz = np.unique(lin, return_inverse=True)
    sp = ca.Sparsity.triplet(shape[0], shape[1], (unique % shape[0]).tolist(), (unique // shape[0]).tolist())
    key, where = np.unique(np.asarray(src, dtype=np.int64) * len(unique) + nz, return_inverse=True)
    values = np.zeros(len(key))
    np.add.at(values, where, coef)  # a term repeated in (nonzero, input) is summed
    g_sp = ca.Sparsity.triplet(len(unique), n_in, (key % len(unique)).tolist(), (key // len(unique)).tolist())
    return sp, ca.DM(g_sp, values)  # key is sorted by input then nonzero: column-major


def _gradient_terms(c: np.ndarray, row0: int) -> tuple[np.ndarray, ...]:
    """Terms of `_scatter` that place the mapped gradients (``n_x`` x rows, rows of coordinates
    ``c``, the first row ``row0``) as the rows of ``D``: ``D[row0 + r, c[r, a]] = u_r[a]``."""
    n_rows, n_x = c.shape
    return (np.repeat(np.arange(n_rows) + row0, n_x), c.ravel(), np.arange(c.size), np.ones(c.size))


def _hessian_terms(zc: np.ndarray, coef: np.ndarray) -> tuple[np.ndarray, ...]:
    """Terms of `_scatter` that sum the mapped Hessians (``n_z`` x ``n_z`` per row, in the row's
    ``z``) into ``K``: component ``i`` of row ``r``'s ``z`` is ``sum_a coef[i, a] P[zc[r, i, a]]``,
    so ``K[zc[r, i, a], zc[r, j, b]] += coef[i, a] coef[j, b] H_r[i, j]``, with ``H_r[i, j]`` at
    ``r n_z^2 + j n_z + i`` (column-major blocks side by side)."""
    n_rows, n_z, width = zc.shape
    i, j, a, b = (v.ravel() for v in np.indices((n_z, n_z, width, width)))
    keep = (coef[i, a] != 0) & (coef[j, b] != 0)
    i, j, a, b = i[keep], j[keep], a[keep], b[keep]
    r = np.repeat(np.arange(n_rows), len(i))
    src = r * n_z * n_z + np.tile(j * n_z + i, n_rows)
    rows, cols = zc[r, np.tile(i, n_rows), np.tile(a, n_rows)], zc[r, np.tile(j, n_rows), np.tile(b, n_rows)]
    return rows, cols, src, np.tile(coef[i, a] * coef[j, b], n_rows)


_PAIR_COEF = np.repeat([[1.0, 0.0], [1.0, 0.0], [1.0, -1.0]], 3, axis=0)
"""``z = (e_i, e_j, a_i - a_j)`` of a pair (`_hessian_terms`): the segments' directions
``e = b - a`` (one point each) and the difference of their starts ``a``."""


def nlp_functions(
    problem: IKProblem, geo: RobotGeometry, capacity: int, self_collision: bool
) -> NLPFunctions:
    """The functions of the collision-aware NLP of ``problem`` against a world of ``capacity``
    slots, with every self-collision pair of ``geo`` when ``self_collision`` (see the module
    docstring). Parameters ``p``: the problem's, then the ``capacity * SLOT_SIZE`` slot values,
    the bound ``b`` and one active flag per self pair; rows of ``g``: the closures, the world rows
    (sphere by sphere, slot by slot), the self pairs (in the order of ``geo.self_pairs``).

    Args:
        problem: the pose problem (`optik.problem.build_ik_problem`).
        geo: the robot geometry.
        capacity: world slots (0: no world rows).
        self_collision: add a row per self-collision pair.
    """
    m = geo.mechanism
    q, n = problem.q, m.n_q
    model = sphere_model(geo)
    pairs = geo.self_pairs if self_collision else np.zeros((0, 2), dtype=int)
    frames = [m.frame_expr(link) for link in geo.links]

    # the points: both ends of each capsule in a pair, then the moving spheres' centres
    points: list[ca.SX] = []
    end_of: dict[tuple[int, int], int] = {}
    for k in sorted({int(k) for k in pairs.ravel()}):
        t = frames[int(geo.part_link[k])]
        for e, end in enumerate(model.segments[k]):
            end_of[(k, e)] = len(points)
            points.append(ca.mtimes(t[:3, :3], ca.DM(end)) + t[:3, 3])
        # the direction b - a, exactly 0 (no Jacobian) for a point: the Hessian is assembled on it
        end_of[(k, 2)] = len(points)
        points.append(ca.mtimes(t[:3, :3], ca.DM(model.segments[k][1] - model.segments[k][0])))
    spheres = []
    if capacity:
        for s, k in enumerate(model.part):
            t = frames[int(geo.part_link[k])]
            if m.frames[geo.links[int(geo.part_link[k])]][0] != m.base:  # base spheres: constant rows
                spheres.append((s, len(points)))
                points.append(ca.mtimes(t[:3, :3], ca.DM(model.centres[s])) + t[:3, 3])
    n_pts = 3 * len(points)
    p_sx = ca.vertcat(*points) if points else ca.SX(0, 1)
    w = ca.SX.sym("w", n_pts)
    point_fn = ca.Function("optik_points", [q], [p_sx, ca.jacobian(p_sx, q)])
    point_hess = ca.Function("optik_points_hess", [q, w], [ca.hessian(ca.dot(w, p_sx), q)[0]])

    n_task = problem.parameters.shape[0]
    n_pairs, n_world = len(pairs), capacity * len(spheres)
    n_c = m.n_closure
    x = ca.MX.sym("x", n)
    p = ca.MX.sym("p", n_task + capacity * SLOT_SIZE + 1 + n_pairs)
    lam_f, lam_g = ca.MX.sym("lam_f"), ca.MX.sym("lam_g", n_c + n_world + n_pairs)
    task = p[:n_task]
    slots = ca.reshape(p[n_task : n_task + capacity * SLOT_SIZE], SLOT_SIZE, capacity)
    bound, flags = p[n_task + capacity * SLOT_SIZE], p[n_task + capacity * SLOT_SIZE + 1 :].T
    lam_w, lam_s = lam_g[n_c : n_c + n_world].T, lam_g[n_c + n_world :].T

    sigma, lam_c = ca.SX.sym("sigma"), ca.SX.sym("lam_c", n_c)
    base_lagrangian = sigma * problem.objective + ca.dot(lam_c, problem.closure)
    base_fn = ca.Function("optik_base", [q, problem.parameters], [problem.objective, problem.closure])
    grad_fn = ca.Function(
        "optik_base_grad",
        [q, problem.parameters],
        [problem.objective, ca.gradient(problem.objective, q), ca.jacobian(problem.closure, q)],
    )
    base_hess = ca.Function(
        "optik_base_hess", [q, problem.parameters, sigma, lam_c], [ca.hessian(base_lagrangian, q)[0]]
    )

    pts, jac_pts = point_fn(x)
    # each kind of row: its coordinates in P (rows x width), z = t x, its mapped functions' outputs
    kinds: list[tuple[np.ndarray, np.ndarray, np.ndarray, ca.MX, ca.MX, ca.MX]] = []
    if n_world:
        world_value, world_grad, world_hess = _world_functions()
        # row s * capacity + k: sphere s against slot k
        c_idx = np.repeat([[3 * i + a for a in range(3)] for _, i in spheres], capacity, axis=0)
        centres = ca.reshape(pts[c_idx.ravel().tolist()], 3, n_world)
        radii = ca.DM(np.repeat(model.radii[[s for s, _ in spheres]], capacity)).T
        ins = [centres, ca.repmat(slots, 1, len(spheres)), radii, bound]
        outs = [f.map(n_world)(*ins) for f in (world_value, world_grad)]
        zc = np.stack([c_idx, np.zeros_like(c_idx)], axis=2)  # z = the centre
        kinds.append((c_idx, zc, np.array([[1.0, 0.0]] * 3), *outs, world_hess.map(n_world)(*ins, lam_w)))
    if n_pairs:
        pair_value, pair_grad, pair_hess = _pair_functions()
        ends = [
            [end_of[(int(i), e)] for e in (0, 1)] + [end_of[(int(j), e)] for e in (0, 1)] for i, j in pairs
        ]
        s_idx = np.array([[3 * e + a for e in row for a in range(3)] for row in ends])  # (pairs, 12)
        xs = ca.reshape(pts[s_idx.ravel().tolist()], 12, n_pairs)
        radii = [ca.DM(model.capsule_radii[pairs[:, c]]).T for c in (0, 1)]
        ins = [xs, *radii, bound, flags]
        outs = [f.map(n_pairs)(*ins) for f in (pair_value, pair_grad)]
        first = [[3 * end_of[(int(k), e)] + a for a in range(3)] for k in pairs.ravel() for e in (2, 0)]
        first = np.array(first).reshape(n_pairs, 2, 2, 3)  # pair, part, (direction, start), xyz
        zc = np.zeros((n_pairs, 9, 2), dtype=int)
        zc[:, 0:3, 0], zc[:, 3:6, 0] = first[:, 0, 0], first[:, 1, 0]
        zc[:, 6:9, 0], zc[:, 6:9, 1] = first[:, 0, 1], first[:, 1, 1]
        kinds.append((s_idx, zc, _PAIR_COEF, *outs, pair_hess.map(n_pairs)(*ins, lam_s)))

    f, closure = base_fn(x, task)
    g = ca.vertcat(closure, *(kind[3].T for kind in kinds))
    f_value, grad_f, jac = grad_fn(x, task)
    hess = base_hess(x, task, lam_f, lam_g[:n_c])
    if kinds:
        # D: the rows' gradients in P; K: their weighted Hessians in P, summed
        offsets = np.cumsum([0] + [len(kind[0]) for kind in kinds])
        grads = ca.vertcat(*(ca.vec(kind[4]) for kind in kinds))
        terms = [_gradient_terms(kind[0], int(row0)) for kind, row0 in zip(kinds, offsets, strict=False)]
        starts = np.cumsum([0] + [kind[0].size for kind in kinds])
        d_sp, d_g = _scatter(*_joined(terms, starts), (n_world + n_pairs, n_pts), grads.shape[0])
        d = ca.MX(d_sp, ca.mtimes(d_g, grads))
        hessians = ca.vertcat(*(ca.vec(kind[5]) for kind in kinds))
        terms = [_hessian_terms(kind[1], kind[2]) for kind in kinds]
        starts = np.cumsum([0] + [len(kind[0]) * kind[2].shape[0] ** 2 for kind in kinds])
        k_sp, k_g = _scatter(*_joined(terms, starts), (n_pts, n_pts), hessians.shape[0])
        big_k = ca.MX(k_sp, ca.mtimes(k_g, hessians))
        jac = ca.vertcat(jac, ca.mtimes(d, jac_pts))
        weights = ca.mtimes(d.T, lam_g[n_c:])
        hess = hess + ca.mtimes(jac_pts.T, ca.mtimes(big_k, jac_pts)) + point_hess(x, weights)
    return NLPFunctions(
        ca.Function("optik_cnlp_f", [x, p], [f], ["x", "p"], ["f"]),
        ca.Function("optik_cnlp_g", [x, p], [g], ["x", "p"], ["g"]),
        ca.Function("optik_cnlp_grad_f", [x, p], [f_value, grad_f], ["x", "p"], ["f", "grad_f_x"]),
        ca.Function("optik_cnlp_jac_g", [x, p], [g, jac], ["x", "p"], ["g", "jac_g_x"]),
        ca.Function(
            "optik_cnlp_hess_l",
            [x, p, lam_f, lam_g],
            [ca.triu(hess)],
            ["x", "p", "lam_f", "lam_g"],
            ["triu_hess_gamma_x_x"],
        ),
        n_c,
    )


def _joined(terms: list[tuple[np.ndarray, ...]], starts: np.ndarray) -> tuple[np.ndarray, ...]:
    """The `_scatter` terms of several kinds of rows in one list, the inputs of kind ``k`` from
    ``starts[k]`` on (their values stacked one kind after the other)."""
    rows, cols, src, coef = (np.concatenate(v) for v in zip(*terms, strict=True))
    shift = np.concatenate([np.full(len(t[2]), int(s0)) for t, s0 in zip(terms, starts, strict=False)])
    return rows, cols, src + shift, coef
