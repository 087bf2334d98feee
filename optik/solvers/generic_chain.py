"""A robot-independent compiled ``"lm"`` kernel: the first solves on a robot never compiled before.

The per-robot kernel of `optik.solvers.lm_kernel` bakes a robot's geometry into generated C:
building it (symbolic model, code generation, the compiler) takes from a tenth of a second to
seconds, and until it is loaded the answers come from CasADi's evaluator, tens of milliseconds
for a first solve. This module compiles, once per machine and joint count ``n``, the same LM
iteration and success check for *any* serial chain of ``n`` revolute or prismatic joints, the
chain's geometry being an input:

``T(q) = A_0 M_0(q_0) A_1 M_1(q_1) ... A_{n-1} M_{n-1}(q_{n-1}) A_n``

with the fixed transforms ``A_k`` (the joint origins, with every fixed joint and the task
frame's offset folded in) and the joint motions
``M_k(q) = [[I + sin(q) [w_k]x + (1 - cos(q)) [w_k]x^2, v_k q], [0, 1]]``: a revolute joint has
the unit axis ``w_k`` and ``v_k = 0``, a prismatic joint ``w_k = 0`` and the unit axis ``v_k``
(Rodrigues' formula and a slide, exactly the motions of `optik.mechanism.joint.Joint.motion`).
The parameters ride after the 12 target parameters, ``[vec(R*); p*; chain]`` with
``chain = [A_0 ... A_n (12 each: vec(R) column-major, p); w_0, v_0, ..., w_{n-1}, v_{n-1}]``, so
the compiled driver ``lm_chunk.c`` and the iteration of `optik.solvers.lm_kernel.lm_iteration_function`
run unchanged: same residual, step, restarts, stop tests and time limit; the answers agree with
the per-robot kernel's to rounding, and they are checked by the same error definitions
(`optik.problem.frame_errors`) evaluated by this kernel's compiled FK, in `optik.solvers.base.make_result`.

*Where it applies.* `solve_first` answers a ``"lm"`` request with ``compile="auto"`` (the default)
for a pose task on one frame of a mechanism without loops or mimic joints whose coordinates are
exactly the revolute and prismatic joints on the path from the base to that frame, in order (every
catalog arm and URDF chain); anything else returns None and the per-robot path runs. It answers
until the per-robot kernel is compiled: its first call starts building that kernel in a daemon
thread (cached on disk as always), and once it is loaded the per-robot path takes over.

*Cache.* The library is ``optik_chain<n>_<hash>.so`` in `optik.native.cache_dir`, keyed by a digest
of the sources its code is generated from (this module, `optik.solvers.lm_kernel`, ``lm_chunk.c``,
`optik.problem`, `optik.spatial`, `optik.native`) and CasADi's version, so that generating the code
(which costs more than a first solve may wait) happens only when it is built. The first robot of
``n`` joints on a machine finds no library: its library is generated and compiled in a daemon
thread (about a second; logged when it fails) and the per-robot path answers meanwhile. Without a
C compiler there is no library and the per-robot path (CasADi's evaluator) answers, as before.
`build` makes the library ahead of time (``optik benchmark first_solve`` does it for its runs).

*Shipped with the package.* So that the first robot on a fresh install waits for nothing, the
install compiles the kernels of `PREBUILT` joint counts (``setup.py``: optional C extensions
``optik._chain<n>`` made from `prebuilt_source`; a missing compiler leaves them out and the
install goes on). `ChainKernel` loads such a library when its manifest and its key (a digest of
the sources above, without CasADi's version) match (`optik.native.prebuilt_library`), and builds
its own in the cache otherwise (logged when the shipped one is damaged).
"""

from __future__ import annotations

import ctypes
import logging
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import casadi as ca
import numpy as np

from optik import spatial
from optik.errors import SolverUnavailableError
from optik.mechanism import Mechanism
from optik.mechanism.memo import PerMechanism
from optik.native import (
    KEY_SYMBOL,
    CCall,
    Library,
    c_source,
    driver_source,
    in_background,
    keyed_library,
    prebuilt_library,
    source_digest,
)
from optik.problem import frame_errors, target_parameters, task_blocks
from optik.results import IKResult
from optik.solvers.base import IKRequest
from optik.solvers.evaluation import error_function
from optik.solvers.lm_kernel import (
    _ERRORS,
    DRIVER,
    OneTarget,
    cached_kernel,
    conf_length,
    driver_defines,
    lm_iteration_function,
)

_LOG = logging.getLogger(__name__)
_SOURCES = (
    "solvers/generic_chain.py",
    "solvers/lm_kernel.py",
    "solvers/lm_chunk.c",
    "problem.py",
    "spatial.py",
)
_SOURCES += ("native.py",)
PREBUILT = (6, 7)
"""Joint counts whose kernels the install compiles into the package (``setup.py``)."""
PREBUILT_DIR = Path(__file__).resolve().parent.parent
"""Where the install puts them: the ``optik`` package folder."""


def n_chain_parameters(n: int) -> int:
    """Length of the ``chain`` parameters of ``n`` joints: ``n + 1`` transforms and ``n`` screws."""
    return 12 * (n + 1) + 6 * n


def chain_pose(q: ca.SX, chain: ca.SX) -> ca.SX:
    """``T(q)`` of the chain described by the parameters ``chain`` (see the module docstring)."""
    n = int(q.shape[0])

    def fixed(k: int) -> ca.SX:
        a = chain[12 * k : 12 * k + 12]
        return ca.vertcat(ca.horzcat(ca.reshape(a[:9], 3, 3), a[9:12]), ca.DM([[0, 0, 0, 1]]))

    t = fixed(0)
    for k in range(n):
        screw = chain[12 * (n + 1) + 6 * k : 12 * (n + 1) + 6 * k + 6]
        w = spatial.hat(screw[:3])
        r = ca.SX.eye(3) + ca.sin(q[k]) * w + (1 - ca.cos(q[k])) * ca.mtimes(w, w)
        motion = ca.vertcat(ca.horzcat(r, screw[3:] * q[k]), ca.DM([[0, 0, 0, 1]]))
        t = ca.mtimes([t, motion, fixed(k + 1)])
    return t


@dataclass(frozen=True)
class ChainProblem:
    """The pose IK problem of a generic chain of ``n`` joints, for
    `optik.solvers.lm_kernel.lm_iteration_function` and `optik.solvers.evaluation.error_function`
    (the attributes of `optik.IKProblem` they read).

    Attributes:
        q: coordinates (``SX``, ``n`` x 1).
        target: ``[vec(R*); p*; chain]`` (``SX``, ``12 + n_chain_parameters(n)`` x 1).
        weights: task weights ``[w_p, w_o]``.
        q_ref: reference posture.
        closure: no loop closures (``SX``, 0 x 1).
        pose: ``T(q)`` of the chain.
    """

    q: ca.SX
    target: ca.SX
    weights: ca.SX
    q_ref: ca.SX
    closure: ca.SX
    pose: ca.SX

    @classmethod
    def of_size(cls, n: int) -> ChainProblem:
        """The problem of ``n`` joints."""
        q = ca.SX.sym("q", n)
        target = ca.SX.sym("target", 12 + n_chain_parameters(n))
        pose = chain_pose(q, target[12:])
        return cls(q, target, ca.SX.sym("weights", 2), ca.SX.sym("q_ref", n), ca.SX(0, 1), pose)

    def weighted_residual(self, closure_weight: float | None = None) -> ca.SX:
        """``[w_p r_p; w_o r_o]`` of the pose task (`optik.problem.task_blocks`; no closure rows)."""
        r_p, r_o = task_blocks("pose", self.pose, self.target[:12])
        return ca.vertcat(self.weights[0] * r_p, self.weights[1] * r_o)

    def error_expressions(self) -> tuple[ca.SX, ca.SX, ca.SX]:
        """Position error, orientation error and 0 (no closure), as `optik.problem.frame_errors`."""
        pos, ori = frame_errors("pose", self.pose, self.target[:12])
        return pos, ori, ca.SX.zeros(1, 1)


def chain_parameters(m: Mechanism, frame: str | None) -> np.ndarray | None:
    """The ``chain`` parameters of the path from the base of ``m`` to ``frame`` (None: the end
    effector), or None when the generic kernel does not apply: loops, a mimic, universal,
    spherical or free joint on the path, a tree joint traversed from its child, or coordinates
    that are not exactly the path's joints in order.

    Raises:
        UnknownFrameError: the frame does not exist.
    """
    body, offset = m._frame(frame)
    if m.is_closed:
        return None
    into = {}  # body -> index of the tree joint whose child it is
    for edge in m.topology.order:
        j = m.joints[edge.joint]
        if edge.reversed:
            return None
        into[j.child] = edge.joint
    path = []
    while body != m.base:
        i = into.get(body)
        if i is None:
            return None
        path.append(i)
        body = m.joints[i].parent
    transforms, screws = [], []
    acc = np.eye(4)
    for i in reversed(path):
        j = m.joints[i]
        if j.type == "fixed":
            acc = acc @ j.origin @ np.linalg.inv(j.child_offset)
            continue
        if j.type not in ("revolute", "prismatic") or j.mimic is not None:
            return None
        if m._slices[i].start != len(screws):  # coordinates in path order, one per joint
            return None
        transforms.append(acc @ j.origin)
        zero = np.zeros(3)
        screws.append(np.concatenate([j.axis, zero] if j.type == "revolute" else [zero, j.axis]))
        acc = np.linalg.inv(j.child_offset)
    if len(screws) != m.n_q or not screws:
        return None
    transforms.append(acc @ offset)
    return np.concatenate([*(target_parameters(t) for t in transforms), *screws])


def _source(n: int) -> str:
    """The C source of the kernel of ``n`` joints (CasADi's code of the LM iteration and the error
    check of `ChainProblem`, with the driver ``lm_chunk.c``)."""
    problem = ChainProblem.of_size(n)
    step = lm_iteration_function(problem, 0.0)  # type: ignore[arg-type]  # IKProblem's attributes
    errors = error_function(problem)  # type: ignore[arg-type]
    driver = driver_source(DRIVER, True)
    return c_source([step, errors], driver_defines(n, 12 + n_chain_parameters(n)) + str(driver))


def prebuilt_name(n: int) -> str:
    """Module name (in the ``optik`` package) of the shipped kernel of ``n`` joints."""
    return f"_chain{n}"


def prebuilt_key(n: int) -> str:
    """The key a shipped kernel of ``n`` joints must carry: a digest of its sources and ``n``."""
    return source_digest(_SOURCES, n, "prebuilt", casadi=False)


def prebuilt_source(n: int) -> str:
    """The C source of the shipped kernel of ``n`` joints: `_source` and its key (`KEY_SYMBOL`)."""
    return f'{_source(n)}\nconst char {KEY_SYMBOL}[] = "{prebuilt_key(n)}";\n'


class ChainKernel:
    """The generic kernel of ``n`` joints (thread-safe: each thread has its own buffers).

    Args:
        n: number of joints.

    Attributes:
        calls: solves answered (`solve_first`), for the record.
    """

    def __init__(self, n: int) -> None:
        self.n = n
        self.n_target = 12 + n_chain_parameters(n)
        self.library: Library | None = None
        try:
            if n in PREBUILT:
                self.library = prebuilt_library(PREBUILT_DIR, prebuilt_name(n), prebuilt_key(n))
            if self.library is None:
                digest = source_digest(_SOURCES, n)
                self.library = keyed_library(f"optik_chain{n}", digest, lambda: _source(n))
        except OSError as exc:  # a partial install: no generic kernel, the per-robot path answers
            _LOG.warning("optik: no generic lm kernel, its sources cannot be read: %s", exc)
        self.calls = 0
        self._packed: Any = None
        self._local = threading.local()

    @property
    def ready(self) -> bool:
        """True when the compiled library is loaded (never waits: False while it builds, or
        without a compiler)."""
        if self._packed is None and self.library is not None and self.library.state == "ready":
            packed = self.library.get().optik_lm_packed  # type: ignore[union-attr]
            packed.argtypes, packed.restype = [ctypes.c_void_p], ctypes.c_int
            self._packed = packed
        return self._packed is not None

    def _buffers(self) -> tuple[OneTarget, CCall, list[np.ndarray]]:
        """This thread's driver buffers, its error function and that function's buffers
        ``[q, target, position, orientation, closure]``."""
        local = self._local
        if not hasattr(local, "one"):
            local.one = OneTarget(self.n, self.n_target, conf_length(self.n))
            local.bufs = [np.zeros(self.n), np.zeros(self.n_target), np.zeros(1), np.zeros(1), np.zeros(1)]
            local.errors = CCall(self.library.get(), _ERRORS, local.bufs[:2], local.bufs[2:])  # type: ignore[union-attr, arg-type]
        return local.one, local.errors, local.bufs

    def run_one(
        self, target: np.ndarray, q0: np.ndarray, seed: int, conf: np.ndarray
    ) -> tuple[np.ndarray, tuple[float, float, float], int, int, int]:
        """`optik.solvers.lm_kernel.LMKernel.run_one` with ``target`` = ``[target; chain]``
        (`ready` must be True).

        Raises:
            SolverUnavailableError: the compiled code reported an error.
        """
        one, _, _ = self._buffers()
        one.target[:] = target
        one.q0[:] = q0
        one.seed[0] = seed
        one.conf[:] = conf
        if self._packed(one.args) != 0:
            raise SolverUnavailableError("optik_lm_chunk: evaluation of the generic chain code failed")
        self.calls += 1
        e = one.errors.tolist()
        it, restarts, status = one.counts.tolist()[:3]
        return one.q.copy(), (e[0], e[1], e[2]), it, restarts, status

    def final_errors(self, q: np.ndarray, target: np.ndarray) -> tuple[float, float, float]:
        """Position, orientation and closure (0) errors of ``q`` against ``[target; chain]`` (as
        `optik.solvers.lm_kernel.LMKernel.final_errors`)."""
        _, fn, bufs = self._buffers()
        bufs[0][:] = q
        bufs[1][:] = target
        fn()
        return float(bufs[2][0]), float(bufs[3][0]), float(bufs[4][0])


_KERNELS: dict[int, ChainKernel] = {}
_KERNELS_LOCK = threading.Lock()


def chain_kernel(n: int) -> ChainKernel:
    """The generic kernel of ``n`` joints (one per process; its library loaded from the cache, or
    built in the background on first use on this machine)."""
    found = _KERNELS.get(n)
    if found is None:
        with _KERNELS_LOCK:
            found = _KERNELS.get(n)
            if found is None:
                found = _KERNELS[n] = ChainKernel(n)
    return found


def build(n: int, timeout: float | None = None) -> bool:
    """Build (or load) the generic kernel of ``n`` joints and wait for it; True when it is loaded."""
    k = chain_kernel(n)
    if k.library is not None:
        k.library.wait(timeout)
    return k.ready


def machine_files(n: int) -> list[Path]:
    """The cache files of the generic kernel of ``n`` joints once built (`build`;
    `optik.native.Library.files`): what a cache holds for every robot of ``n`` joints, as opposed
    to a robot's own libraries."""
    k = chain_kernel(n)
    return [] if k.library is None else k.library.files()


class _Builder:
    """The per-robot kernel of one request key, built once in a daemon thread."""

    def __init__(self, prepare: Callable[[IKRequest], Any], request: IKRequest) -> None:
        self.failed = False
        self._started = False
        self._lock = threading.Lock()
        self._prepare, self._request = prepare, request

    def start(self) -> None:
        with self._lock:
            if self._started:
                return
            self._started = True
        in_background(self._run)

    def _run(self) -> None:
        try:
            self._prepare(self._request)
        except Exception:  # the per-robot path will raise it again in the caller's thread
            _LOG.warning("optik: building the per-robot lm kernel failed", exc_info=True)
            self.failed = True
        finally:
            self._request = None  # type: ignore[assignment]


_CHAINS: PerMechanism[dict[Any, np.ndarray | None]] = PerMechanism()
_BUILDERS: PerMechanism[dict[Any, _Builder]] = PerMechanism()


def solve_first(
    request: IKRequest,
    settings: Any,
    closure_weight: float,
    compile: bool | str,
    prepare: Callable[[IKRequest], Any],
    seed: int,
    result_of: Callable[..., IKResult],
) -> IKResult | None:
    """The ``"lm"`` answer by the generic kernel while the per-robot kernel is not compiled, or
    None (the per-robot path answers): see the module docstring for when it applies.

    Args:
        request: the request.
        settings: its `optik.solvers.lm_kernel.Settings`.
        closure_weight, compile: its options (``compile`` must be ``"auto"``).
        prepare: builds the per-robot kernel of a request (run in a daemon thread).
        seed: the kernel's restart seed.
        result_of: the result of a kernel's run (`optik.solvers.lm.lm_result`, given a kernel
            with ``final_errors``).
    """
    if (
        compile != "auto"
        or request.task != "pose"
        or not (request.frame is None or isinstance(request.frame, str))
    ):
        return None
    m = request.mechanism
    g = m.geometry
    per_robot = cached_kernel(g, request.task, request.frame, closure_weight, compile)
    if per_robot is not None and per_robot.compiled:
        return None
    key = (request.task, request.frame, closure_weight)
    builder = _BUILDERS.setdefault(g, {}).get(key)
    if builder is not None and builder.failed:
        return None
    setup = time.perf_counter()
    chains = _CHAINS.setdefault(g, {})
    if request.frame not in chains:
        chains[request.frame] = chain_parameters(g, request.frame)
    chain = chains[request.frame]
    if chain is None:
        return None
    k = chain_kernel(m.n_q)
    if not k.ready:
        return None
    request.exclude_setup(setup)  # a first call: the chain read and the library loaded
    if builder is None:
        builder = _BUILDERS[g].setdefault(key, _Builder(prepare, request))
    conf = settings.conf(m)
    conf[3] = max(request.remaining(), 0.0)
    params = np.concatenate([target_parameters(request.target), chain])
    q, err, iterations, restarts, code = k.run_one(params, request.q0, seed, conf)
    result = result_of(request, k, q, err, iterations, restarts, code, params)
    builder.start()
    return result
