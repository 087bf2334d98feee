"""The dampers' rows in one compiled call: screening bounds to rows without Python per pair.

`DRIVER` (C, compiled with the dampers' screen: `optik.diffik.collision.screen_blocks`) takes
that screen's outputs (`optik.collision.screen`: part poses, the bound of every sphere against
every world slot, the bound of every self-collision pair; and each moving body's ``[J^0; J_w]``),
takes each part's bound against an object as the least of its spheres', and for every pair
whose bound is below the influence distance ``d_i`` computes the exact signed distance and
witness points; the pairs closer than ``d_i`` give, closest first, their rows ``G``, ``h``
(`optik.diffik.collision`'s formula, with the ``+-1`` selection of the two ends' bodies).

*Distances.* Every part of the kinds below is ``H + B(r)``, the convex hull ``H`` of a few points
grown by a ball of radius ``r`` (`optik.collision.shapes.shape_vertices`, which is exact for
them): a box (its corners, ``r = 0``), a sphere (its centre, ``r``), a capsule (its two end
centres, ``r``), a convex mesh (its hull's vertices, ``r = 0``; coal queries the same hull). For
two such parts whose hulls are apart by ``delta > 0`` with nearest points ``x_a, x_b`` (GJK on the
support functions ``s_H(u) = argmax_{v in H} u^T v``, the nearest point of each simplex found among
all of its faces), ``n = (x_a - x_b) / delta`` and

    d = delta - r_a - r_b,   p_a = x_a - r_a n,   p_b = x_b + r_b n,

the signed distance (also when the balls overlap: the penetration of ``H_a + B(r_a)`` and
``H_b + B(r_b)`` is then ``r_a + r_b - delta`` along ``n``) and its witness points, with
``sign(d) (p_a - p_b) / |p_a - p_b| = n`` in both cases, as for coal's. GJK stops when the duality
gap ``|v|^2 - v^T w`` is below ``1e-13 |v|^2`` (``v`` the current nearest point of the Minkowski
difference, ``w`` its support point along ``-v``), so that ``delta`` is exact to ``1e-13`` of itself.
When the hulls touch or overlap (coal's EPA would be needed), a part is of another kind (a
cylinder), or GJK does not converge, the call returns ``-1`` and the caller queries coal for every
pair, as it does without a compiler.
"""

from __future__ import annotations

import ctypes
from pathlib import Path
from typing import Any

import numpy as np

from optik.collision.robot import RobotGeometry
from optik.collision.shapes import shape_vertices
from optik.collision.spheres import sphere_model
from optik.collision.world import WorldState

__all__ = ["DRIVER", "EXACT_KINDS", "CompiledPairs", "shape_table"]

DRIVER = Path(__file__).with_name("damper_pairs.c")
"""The C source of ``optik_damper_pairs``."""

EXACT_KINDS = ("box", "sphere", "capsule", "mesh")
"""Shape kinds that are exactly a hull of points grown by a ball (a point cloud's parts are spheres)."""

_P = ctypes.c_void_p


def shape_table(parts: Any, poses: list[np.ndarray] | None = None) -> tuple[np.ndarray, ...]:
    """``(starts, vertices, radii, exact)`` of ``parts`` for the driver: part ``k``'s hull
    vertices are ``vertices[starts[k]:starts[k + 1]]`` (in its own frame, or in the base frame
    through ``poses[k]``), ``radii[k]`` its ball, ``exact[k]`` 1 for `EXACT_KINDS` (else its
    vertices are a placeholder and the driver leaves the pair to coal)."""
    starts, chunks, radii, exact = [0], [], [], []
    for k, part in enumerate(parts):
        ok = part.shape.kind in EXACT_KINDS
        v, r = shape_vertices(part.shape) if ok else (np.zeros((1, 3)), 0.0)
        if poses is not None:
            v = v @ poses[k][:3, :3].T + poses[k][:3, 3]
        chunks.append(np.asarray(v, dtype=float).reshape(-1, 3))
        starts.append(starts[-1] + len(chunks[-1]))
        radii.append(r)
        exact.append(int(ok))
    vertices = np.ascontiguousarray(np.concatenate(chunks) if chunks else np.zeros((0, 3)))
    return (
        np.array(starts, dtype=np.int64),
        vertices,
        np.array(radii, dtype=float),
        np.array(exact, dtype=np.int64),
    )


class CompiledPairs:
    """One thread's call of the driver for one robot geometry.

    Args:
        geo: the geometry.
        cdll: the loaded library holding ``optik_damper_pairs``.
        moving: per part, True when it is on a moving body.
        body: per part, its body's index in the row function's selection (unused when not moving).
        n_bodies: the selection's length per pair.
        n_q: the mechanism's coordinates.
    """

    def __init__(
        self,
        geo: RobotGeometry,
        cdll: ctypes.CDLL,
        moving: list[bool],
        body: list[int],
        n_bodies: int,
        n_q: int,
    ):
        self._fn = cdll["optik_damper_pairs"]  # its own function object: argtypes per call site
        self._fn.argtypes, self._fn.restype = [_P, _P, _P, _P], ctypes.c_int
        spheres = sphere_model(geo).part
        self._n_spheres = len(spheres)
        n_parts = len(geo.parts)
        self._robot = (
            np.searchsorted(spheres, np.arange(n_parts + 1)).astype(np.int64),
            np.array(moving, dtype=np.int64),
            np.array([b if ok else 0 for b, ok in zip(body, moving, strict=True)], dtype=np.int64),
            np.ascontiguousarray(geo.self_pairs, dtype=np.int64).reshape(-1),
            *shape_table(geo.parts),
        )
        self._n_parts, self._n_self, self._n_b = n_parts, len(geo.self_pairs), n_bodies
        self._n_q = n_q
        self.dims = np.zeros(6, dtype=np.int64)
        self.par = np.zeros(3)
        self.d_min = np.zeros(1)
        self._args: tuple[int, int, int, int] | None = None
        self._keep: tuple[Any, ...] = ()
        self._state: WorldState | None = None
        self._screen: tuple[np.ndarray, ...] = ()
        self.rows = np.zeros(0)

    def bind(self, state: WorldState, screen_outputs: list[np.ndarray]) -> None:
        """Point the driver at ``state``'s objects and the screen evaluator's output buffers
        (poses, world bounds, self bounds, body blocks; only when either changed)."""
        if state is self._state and self._screen and screen_outputs[0] is self._screen[0]:
            return
        n_obj = len(state.parts)
        world = shape_table(state.parts, [p.offset for p in state.parts])
        most = self._n_parts * n_obj + self._n_self
        scratch = np.zeros(8 * most), np.zeros(self._n_b * most), np.zeros(most)  # pairs, sigma, distances
        self.rows = np.zeros((self._n_q + 1) * most)
        buffers = (*screen_outputs[:3], *self._robot, *world, *scratch, screen_outputs[3], self.rows)
        table = (_P * len(buffers))(*[b.ctypes.data for b in buffers])
        self._keep = (buffers, table)  # the arrays the table points into live as long as it
        self.dims[:] = self._n_parts, n_obj, self._n_self, self._n_b, self._n_spheres, self._n_q
        self._args = (
            ctypes.addressof(table),
            self.dims.ctypes.data,
            self.par.ctypes.data,
            self.d_min.ctypes.data,
        )
        self._state, self._screen = state, tuple(screen_outputs)

    def __call__(self, influence: float, gain: float, margin: float, self_collision: bool) -> int:
        """The driver on the bound screen outputs: the count ``k`` of rows (in `rows`, ``n_q + 1``
        numbers each: ``G``'s row, then ``h``; closest first), or -1 (ask coal); `d_min` holds the
        least distance queried."""
        assert self._args is not None  # bind first
        self.par[:] = influence, gain, margin
        self.dims[2] = self._n_self if self_collision else 0
        return int(self._fn(*self._args))
