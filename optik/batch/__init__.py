"""Batch and distributed solving: many IK targets on every core or a Dask cluster, FK of many
configurations.

`solve_ik_batch` cuts the targets into chunks solved by the compiled ``lm`` kernel on a thread
pool (or as Dask tasks with ``scheduler=``) and returns a `BatchResult` of arrays in input
order; `fk_batch` evaluates forward kinematics of many configurations in compiled code.
"""

from optik.batch.fk import fk_batch
from optik.batch.result import BatchResult
from optik.batch.solve import solve_ik_batch

__all__ = ["BatchResult", "fk_batch", "solve_ik_batch"]
