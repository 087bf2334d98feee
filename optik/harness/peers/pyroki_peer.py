"""PyRoki (github.com/chungmin99/pyroki, MIT; not on PyPI) on the CPU: batch IK by JAX least squares.

PyRoki builds a robot from a URDF (through ``yourdfpy``) and solves IK as a nonlinear least-squares
problem of ``jaxls`` (github.com/brentyi/jaxls; the PyPI package named ``jaxls`` is another
project): a pose cost on the tip link and a soft joint-limit cost, Levenberg-Marquardt steps with
a trust region, vectorized over targets by ``jax.vmap`` and compiled by ``jax.jit``. It has no time
limit; its batch recipe (its own IK benchmark against cuRobo) is a beam over seeds: descend from
``seeds`` starts for ``first`` steps, keep the ``keep`` of lowest cost, descend ``steps - first``
more steps from them, and return the lowest-cost answer. This adapter follows that recipe with
PyRoki's published settings by default (64 seeds, keep 4, 6 + 10 steps); the first seed is the
start every solver of the benchmark gets, the others are drawn uniformly within the limits
(seeded). Arithmetic is float64 (``jax_enable_x64``, a process-wide JAX setting), as the
tolerances judged (1e-5 m / rad) are asked of every solver in float64.

The checkout is used where it lies (``DIR/src`` is put on ``sys.path``; nothing is copied into
optik); its dependencies (jax, jaxlib, jaxls from its repository, jaxlie, jax_dataclasses,
yourdfpy, ...) must be installed. Each call is compiled for one batch size: shorter batches are
padded with their last target and the answers trimmed, so one compilation serves every block.
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

import numpy as np

from optik.harness.peers.base import PeerUnavailable
from optik.mechanism import Mechanism

__all__ = ["PyRokiBatch"]


def _import(directory: str | Path) -> tuple[Any, ...]:
    """``(jax, jnp, jaxlie, jaxls, pyroki, yourdfpy)`` with ``directory/src`` on ``sys.path``."""
    src = Path(directory) / "src"
    if not (src / "pyroki" / "__init__.py").is_file():
        raise PeerUnavailable(f"pyroki: {src / 'pyroki'} not found (pass the folder of a PyRoki checkout)")
    if str(src) not in sys.path:
        sys.path.insert(0, str(src))
    try:
        import jax

        jax.config.update("jax_enable_x64", True)
        import jax.numpy as jnp
        import jaxlie
        import jaxls
        import pyroki
        import yourdfpy
    except Exception as exc:  # a missing dependency, a jaxls of another API, ...
        raise PeerUnavailable(f"pyroki: cannot import it or its dependencies: {exc}") from None
    return jax, jnp, jaxlie, jaxls, pyroki, yourdfpy


class PyRokiBatch:
    """PyRoki's beam IK over a batch of targets, compiled once for ``batch`` targets per call.

    Args:
        directory: the folder of a PyRoki checkout.
        m: optik's mechanism of the same URDF chain (its limits draw the seeds; its FK checks
            PyRoki's joint order and frames at construction).
        urdf, tip: the URDF file and the tip link.
        batch: targets per compiled call.
        seeds, keep, first, steps: the beam (see the module docstring).
        seed: seed of the drawn starts.

    Raises:
        PeerUnavailable: no checkout, a dependency missing, or PyRoki's FK of the chain differs
            from optik's (other joints, other order).
    """

    name = "PyRoki (JAX, CPU)"

    def __init__(
        self,
        directory: str | Path,
        m: Mechanism,
        urdf: str | Path,
        tip: str,
        batch: int,
        seeds: int = 64,
        keep: int = 4,
        first: int = 6,
        steps: int = 16,
        seed: int = 0,
    ) -> None:
        jax, jnp, jaxlie, jaxls, pk, yourdfpy = _import(directory)
        model = yourdfpy.URDF.load(
            str(urdf), load_meshes=False, load_collision_meshes=False, build_collision_scene_graph=False
        )
        robot = pk.Robot.from_urdf(model)
        if robot.joints.num_actuated_joints != m.n_q or tip not in robot.links.names:
            raise PeerUnavailable(f"pyroki: {robot.joints.num_actuated_joints} joints or no link {tip!r}")
        self.m, self.batch, self._jaxlie, self._jnp = m, int(batch), jaxlie, jnp
        index = jnp.array(robot.links.names.index(tip), dtype=jnp.int32)
        starts = jnp.asarray(m.random_q(seeds - 1, seed=seed))

        def descend(pose: Any, q: Any, damping: Any, iterations: int) -> tuple[Any, Any, Any]:
            var = robot.joint_var_cls(0)
            costs = [
                pk.costs.pose_cost_analytic_jac(robot, var, pose, index, pos_weight=1.0, ori_weight=1.0),
                pk.costs.limit_cost(robot, var, weight=100.0),
            ]
            solution, summary = (
                jaxls.LeastSquaresProblem(costs, [var])
                .analyze()
                .solve(
                    initial_vals=jaxls.VarValues.make([var.with_value(q)]),
                    verbose=False,
                    linear_solver="dense_cholesky",
                    termination=jaxls.TerminationConfig(max_iterations=iterations, early_termination=False),
                    trust_region=jaxls.TrustRegionConfig(lambda_initial=damping),
                    return_summary=True,
                )
            )
            return solution[var], summary.cost_history[-1], summary.lambda_history[-1]

        def beam(pose_wxyz_xyz: Any, q0: Any) -> Any:
            pose = jaxlie.SE3(pose_wxyz_xyz)
            qs, cost, damping = jax.vmap(descend, in_axes=(None, 0, None, None))(
                pose, jnp.concatenate([q0[None], starts]), 10.0, first
            )
            best = jnp.argsort(cost)[:keep]
            qs, cost, _ = jax.vmap(descend, in_axes=(None, 0, 0, None))(
                pose, qs[best], damping[best], steps - first
            )
            return qs[jnp.argmin(cost)]

        self._solve = jax.jit(jax.vmap(beam))
        self._fk = jax.jit(lambda q: robot.forward_kinematics(q)[index])
        q = m.random_q(3, seed=seed + 1)
        for qi in q:  # the same chain: PyRoki's FK of the tip equals optik's
            pk_pose = np.asarray(jaxlie.SE3(self._fk(jnp.asarray(qi))).as_matrix())
            if not np.allclose(pk_pose, m.fk(qi), atol=1e-9):
                raise PeerUnavailable(
                    "pyroki: its FK of the chain differs from optik's (joint order, frames)"
                )

    def solve(self, targets: np.ndarray, q0: np.ndarray) -> np.ndarray:
        """Raw answers (``(n, n_q)``, not clipped) for ``targets`` (``(n, 4, 4)``, ``n <= batch``)
        from the starts ``q0``; the first call compiles (warm it up untimed)."""
        n = len(targets)
        if not 0 < n <= self.batch:
            raise ValueError(f"pyroki: {n} targets, the compiled batch holds 1 to {self.batch}")
        pad = self.batch - n
        poses = np.stack([self._jaxlie.SE3.from_matrix(t).wxyz_xyz for t in targets])
        poses = np.concatenate([poses, np.repeat(poses[-1:], pad, axis=0)])
        starts = np.concatenate([q0, np.repeat(q0[-1:], pad, axis=0)])
        q = self._solve(self._jnp.asarray(poses), self._jnp.asarray(starts))
        return np.asarray(q.block_until_ready())[:n]
