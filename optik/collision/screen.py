"""Screening bounds of the exact check: a lower bound of every pair's signed distance at ``q``, in one call.

The exact check (`optik.collision.check`) asks coal only for the pairs that can be the closest,
closer than the margin, or touching; a pair whose lower bound is above all three is skipped. The
bounds come from models that contain the parts (`optik.collision.spheres`, `optik.collision.slots`):

* robot part ``a`` to world object ``o``: ``min_s (sdf_o(c_s) - R_s)`` over the spheres
  ``(c_s, R_s)`` that cover ``a``, with ``sdf_o`` the signed distance function of the rounded box
  that contains ``o``; or, *coarse*, ``sdf_o(c_a) - r_a`` of the part's bounding sphere alone (one
  row per part instead of one per sphere: the cheaper call, mostly looser bounds);
* robot part ``a`` to robot part ``b`` (the self-collision pairs): the larger of the distance of
  their capsules, ``|x_a - x_b| - rho_a - rho_b`` at the closest points of the segments, and of
  their bounding spheres, ``|c_a - c_b| - r_a - r_b`` (`optik.collision.parts.Part`).

Each is at most the exact distance wherever that is ``>= 0`` (a model containing both parts is
apart by at most as much as they are), which is all the search needs: it skips a pair only when
the bound is above ``max(margin, 0, smallest distance found)``.

`screen_function` is one CasADi function per robot geometry and slot capacity,
``(q, slots) -> (part poses, sphere-slot bounds, self-pair bounds)``, the sphere-slot rows mapped
over slots and spheres (a loop in the generated C); `screen` compiles it with `optik.native` in the
background (CasADi's evaluator answers meanwhile, with the same numbers) and keeps one evaluator
per thread. The library holds `CLEAR_SOURCE` too, ``optik_screen_clear``: the function and the
test whether any bound is at most a limit, in one C call that another C function can make
(`Screen.clear_function`, `optik.collision.check.ClearTest`).
"""

from __future__ import annotations

import ctypes
import threading
import weakref
from typing import NamedTuple

import casadi as ca
import numpy as np

from optik.collision.robot import RobotGeometry
from optik.collision.slots import SLOT_SIZE, slot_distance
from optik.collision.spheres import segment_distance, sphere_model
from optik.native import NativeFunction, library

__all__ = ["CLEAR_SOURCE", "Screen", "screen", "screen_function"]

CLEAR_SOURCE = """
/* optik_screen_clear(args, q): the screen function at q and whether some bound is at most the
 * limit, with a check's signature (optik_check_fn of optik/solvers/lm_chunk.c). args: [slots,
 * n_self, n_rows (integers), known, use (n_rows doubles each), &limit, poses, world, self (the
 * outputs), iw, w (work), verdict (one int64)]. The bounds tested: self[0..n_self) and world
 * row r < n_rows, known[r] in its place where use[r] != 0; verdict = 1 when none is <= limit
 * (NaN is not), 0 when one is. Returns nonzero when the evaluation failed. */
CASADI_SYMBOL_EXPORT int optik_screen_clear(void *const *args, const double *q) {
  const double *arg[OPTIK_SCREEN_SZ_ARG] = {q, (const double *)args[0]};
  double *res[OPTIK_SCREEN_SZ_RES] = {(double *)args[6], (double *)args[7], (double *)args[8]};
  if (optik_collision_screen(arg, res, (casadi_int *)args[9], (double *)args[10], 0)) return 1;
  const casadi_int n_self = (casadi_int)args[1], n_rows = (casadi_int)args[2];
  const double *known = (const double *)args[3], *use = (const double *)args[4];
  const double limit = *(const double *)args[5], *world = res[1], *own = res[2];
  casadi_int *verdict = (casadi_int *)args[11];
  *verdict = 0;
  for (casadi_int i = 0; i < n_self; ++i)
    if (own[i] <= limit) return 0;
  for (casadi_int r = 0; r < n_rows; ++r)
    if ((use[r] != 0.0 ? known[r] : world[r]) <= limit) return 0;
  *verdict = 1;
  return 0;
}
"""
"""The C test of `Screen.clear_function`, compiled with the screen function (after
``#define``s of its argument and result array lengths)."""


def screen_function(
    geo: RobotGeometry, capacity: int, extra: ca.SX | None = None, coarse: bool = False
) -> ca.Function:
    """``(q, slots) -> (poses, world, self)`` for a world of ``capacity`` slots
    (`optik.collision.slots`), and ``extra`` (a dense column of expressions in ``q``, computed with
    the poses, sharing their subexpressions) as a fourth output when given.

    ``poses``: ``12 P`` numbers, each part's base-frame rotation (row-major) and origin;
    ``world``: ``capacity * S`` bounds, sphere ``s`` against slot ``k`` at ``k * S + s`` (an empty
    slot's entries are meaningless: the caller drops them), the spheres those of the sphere model
    or, when ``coarse``, each part's bounding sphere (``S = P``: a quarter of the rows on the Panda,
    mostly looser bounds, some tighter);
    ``self``: one bound per row of ``geo.self_pairs``.
    """
    m = geo.mechanism
    model, capsule = _spheres(geo, coarse), sphere_model(geo)
    links = [m.frame_expr(link) for link in geo.links]

    def placed(k: int, x: np.ndarray) -> ca.SX:
        t = links[int(geo.part_link[k])]
        return ca.mtimes(t[:3, :3], ca.DM(x)) + t[:3, 3]

    poses = []
    for k, part in enumerate(geo.parts):
        t = ca.mtimes(links[int(geo.part_link[k])], ca.DM(part.offset))
        poses.append(ca.vertcat(ca.vec(t[:3, :3].T), t[:3, 3]))
    centres = ca.horzcat(*(placed(int(k), c) for k, c in zip(model.part, model.centres, strict=True)))
    # each part's capsule ends and bounding-sphere centre, placed once; the self rows are one
    # function mapped over the pairs (a loop in the generated C, not one copy of it per pair)
    n_p = len(geo.parts)
    ends = [ca.horzcat(*(placed(k, capsule.segments[k][e]) for k in range(n_p))) for e in (0, 1)]
    middles = ca.horzcat(*(placed(k, geo.parts[k].centre) for k in range(n_p)))
    q = m.q_sym
    outs = [ca.vertcat(*poses), centres, ends[0], ends[1], middles] + ([] if extra is None else [extra])
    # common subexpressions merged (a part's placed points share its link's pose)
    robot = ca.Function("robot", [q], outs, {"cse": True})
    c, radius, slot = ca.SX.sym("c", 3), ca.SX.sym("radius"), ca.SX.sym("slot", SLOT_SIZE)
    row = ca.Function("sphere_slot", [c, radius, slot], [slot_distance(slot, c, 0.0) - radius])
    n_s = len(model.radii)
    qm, slots = ca.MX.sym("q", m.n_q), ca.MX.sym("slots", capacity * SLOT_SIZE)
    pose_out, centre_out, a_out, b_out, middle_out, *more = robot(qm)
    # one map over every (slot k, sphere s) at column k S + s: spheres repeated, slots each S times
    spheres = ca.repmat(centre_out, 1, capacity), ca.repmat(ca.DM(model.radii).T, 1, capacity)
    per_slot = ca.kron(ca.reshape(slots, SLOT_SIZE, capacity), ca.DM.ones(1, n_s))
    bounds = row.map(capacity * n_s)(*spheres, per_slot)
    pairs = np.asarray(geo.self_pairs, dtype=int).reshape(-1, 2)
    if len(pairs):
        x = [ca.SX.sym(name, 3) for name in ("p1", "q1", "p2", "q2", "ci", "cj")]
        rho_i, rho_j, r_i, r_j = (ca.SX.sym(name) for name in ("rho_i", "rho_j", "r_i", "r_j"))
        capsules = segment_distance(*x[:4]) - rho_i - rho_j
        pair = ca.Function(
            "self_pair",
            [*x, rho_i, rho_j, r_i, r_j],
            [ca.fmax(capsules, ca.norm_2(x[4] - x[5]) - r_i - r_j)],
        )
        i, j = pairs[:, 0].tolist(), pairs[:, 1].tolist()
        rho, r = capsule.capsule_radii, np.array([p.radius for p in geo.parts])
        args = [a_out[:, i], b_out[:, i], a_out[:, j], b_out[:, j], middle_out[:, i], middle_out[:, j]]
        consts = [ca.DM(v[idx]).T for v in (rho, r) for idx in (pairs[:, 0], pairs[:, 1])]
        own = ca.vec(pair.map(len(pairs))(*args, consts[0], consts[1], consts[2], consts[3]))
    else:
        own = ca.MX(0, 1)
    return ca.Function("optik_collision_screen", [qm, slots], [pose_out, ca.vec(bounds), own, *more])


class _Spheres(NamedTuple):
    """The spheres of the world rows: centres in their part's frame, radii, owning part."""

    centres: np.ndarray
    radii: np.ndarray
    part: np.ndarray


def _spheres(geo: RobotGeometry, coarse: bool) -> _Spheres:
    """The sphere model of ``geo`` (`optik.collision.spheres.sphere_model`), or when ``coarse``
    each part's bounding sphere (`optik.collision.parts.Part`: it contains the part)."""
    if not coarse:
        model = sphere_model(geo)
        return _Spheres(model.centres, model.radii, model.part)
    centres = np.array([p.centre for p in geo.parts]).reshape(-1, 3)
    return _Spheres(centres, np.array([p.radius for p in geo.parts]), np.arange(len(geo.parts)))


class Screen:
    """`screen_function` of one geometry and capacity, compiled, with one evaluator per thread.

    Args:
        geo: the robot geometry.
        capacity: the world's slot capacity.
        coarse: the world rows from the parts' bounding spheres (see `screen_function`).
    """

    def __init__(self, geo: RobotGeometry, capacity: int, coarse: bool = False) -> None:
        self.function = f = screen_function(geo, capacity, coarse=coarse)
        sizes = f"#define OPTIK_SCREEN_SZ_ARG {f.sz_arg()}\n#define OPTIK_SCREEN_SZ_RES {f.sz_res()}\n"
        self.library = library([f], "auto", sizes + CLEAR_SOURCE)
        self.capacity = capacity
        self.n_parts = len(geo.parts)
        part = _spheres(geo, coarse).part
        self._starts = np.searchsorted(part, np.arange(self.n_parts))  # spheres are in part order
        self._spheres = len(part)
        self._one_each = bool(np.array_equal(part, np.arange(self.n_parts)))  # the coarse model
        self._local = threading.local()

    def bounds(
        self, q: np.ndarray, slots: np.ndarray, n_objects: int
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(poses (P, 12), world (P, n_objects), self (k,))`` at ``q`` for the slot values ``slots``
        of ``n_objects`` obstacles: the part poses, and the bounds of every part against every
        object and of every self-collision pair (see the module docstring)."""
        return self.reduce(self._evaluate(q, slots), n_objects)

    def pair_bounds(
        self,
        q: np.ndarray,
        slots: np.ndarray,
        n_objects: int,
        n_self: int,
        outputs: list[np.ndarray] | None = None,
    ) -> tuple[np.ndarray, np.ndarray]:
        """`bounds` as the exact check reads them: ``(poses, lb)``, ``lb`` the bounds of the first
        ``n_self`` self-collision pairs, then part ``a`` against object ``o`` at ``n_self + o P +
        a`` (object-major: the evaluator's order where each part has one sphere, one copy).
        ``poses`` ``(P, 12)`` is a view of this thread's evaluator buffer (of ``outputs``): valid
        until its next call on this thread. ``outputs``: this function's outputs at ``q`` and
        ``slots`` made already (`optik.collision.check.ClearTest`'s), read instead of a new call."""
        poses, world, own = self._evaluate(q, slots) if outputs is None else outputs
        if self._one_each:
            rows = world[: n_objects * self.n_parts]
        else:
            rows = self._part_rows(world, n_objects).T.ravel()
        return poses.reshape(self.n_parts, 12), np.concatenate((own[:n_self], rows))

    def _evaluate(self, q: np.ndarray, slots: np.ndarray) -> list[np.ndarray]:
        """This thread's evaluator's outputs at ``q`` and ``slots`` (its buffers, not copies)."""
        fn = getattr(self._local, "fn", None)
        if fn is None:
            fn = self._local.fn = self.evaluator()
        fn.inputs[0][:] = q
        fn.inputs[1][:] = slots
        return fn()

    def clear_function(self) -> tuple[int, int, int] | None:
        """``(address of optik_screen_clear, iw length, w length)`` (`CLEAR_SOURCE`, its work
        lengths from the generated ``optik_collision_screen_work``) once the library is loaded,
        else None (never waited for)."""
        lib = self.library
        if lib is None or lib.state != "ready":
            return None
        cdll = lib.get()
        if cdll is None:
            return None
        sizes = [ctypes.c_longlong() for _ in range(4)]
        cdll.optik_collision_screen_work(*[ctypes.byref(v) for v in sizes])
        address = ctypes.cast(cdll.optik_screen_clear, ctypes.c_void_p).value
        return int(address), max(int(sizes[2].value), 1), max(int(sizes[3].value), 1)

    def evaluator(self) -> NativeFunction:
        """A new evaluator of `function` (for one thread): inputs ``q`` and the slot values."""
        return NativeFunction(self.function, self.library)

    def reduce(self, outputs: list[np.ndarray], n_objects: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """`bounds` from an `evaluator`'s outputs: each part's bound against an object is the
        least of its spheres' (copies, not views of the evaluator's buffers)."""
        poses, world, own = outputs
        parts = self._part_rows(world, n_objects)
        return poses.reshape(self.n_parts, 12).copy(), np.array(parts), own.copy()

    def _part_rows(self, world: np.ndarray, n_objects: int) -> np.ndarray:
        """``(P, n_objects)``: each part's least sphere bound against each object (a view of
        ``world`` when every part has one sphere, as in the coarse model)."""
        spheres = world.reshape(self.capacity, self._spheres)[:n_objects].T
        if self._one_each or not n_objects:
            return spheres[: self.n_parts]
        return np.minimum.reduceat(spheres, self._starts, axis=0)


_CACHE: weakref.WeakKeyDictionary[RobotGeometry, dict[tuple[int, bool], Screen]] = weakref.WeakKeyDictionary()
_LOCK = threading.Lock()


def screen(geo: RobotGeometry, capacity: int, coarse: bool = False) -> Screen:
    """The `Screen` of ``geo`` for ``capacity`` slots, with the world rows of the bounding spheres
    when ``coarse`` (built once, under a lock, and cached with the geometry; a built one is read
    without the lock: each exact check asks for it, and a dict read is atomic)."""
    per = _CACHE.get(geo)
    hit = None if per is None else per.get((capacity, coarse))
    if hit is not None:
        return hit
    with _LOCK:
        per = _CACHE.setdefault(geo, {})
        hit = per.get((capacity, coarse))
        if hit is None:
            hit = per[capacity, coarse] = Screen(geo, capacity, coarse)
        return hit
