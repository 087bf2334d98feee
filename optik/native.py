"""Compiled CasADi functions: C code generation, the system C compiler, ``ctypes``.

Calling a CasADi ``Function`` from Python costs tens to a hundred microseconds per call
(argument conversion to ``DM`` and back), more than a whole IK iteration or QP step should take.
`optik.native.library` generates C code for a list of functions
(``casadi.CodeGenerator``) and compiles it with the system C compiler into a shared library
cached on disk (keyed by a hash of the source, the compiler and its flags, so each machine
compiles a given model once); `optik.native.CCall` then calls one generated entry
point through ``ctypes`` on preallocated numpy buffers, about 1 us of overhead per call
(`optik.native.Binding`: the same once the library is ready). The IK solvers
(`NativeFunction`, `optik.solvers.lm_kernel`), differential IK (`optik.diffik._codegen`)
and `optik.batch` use it.

*No wait for the compiler.* Compiling a 7-joint arm's solver takes about half a second. With
``compile="auto"`` (the default) a library that is not in the cache yet is built in a background
(daemon) thread: until it is loaded, the callers evaluate the same functions with CasADi's own
``SX`` virtual machine (same operations in the same order, so the same numbers to rounding, and
the generated code is compiled with ``-ffp-contract=off`` so that no fused multiply-add changes
them), then switch to the compiled entry points at their next call. A failed build is logged (logger
``optik.native``) and the callers keep the virtual machine; nothing raises. A build still
running when the interpreter exits is stopped and its temporary files removed (the next process
starts it again). ``compile=True`` builds in the calling thread and raises when it cannot;
`optik.native.wait` blocks until the background builds are done.

Without a C compiler, with ``$OPTIK_NO_CODEGEN`` set, or with ``compile=False``, there is no
library and the callers always evaluate with CasADi's virtual machine (same numbers, slower).

The cache directory is ``$OPTIK_CACHE_DIR`` or ``~/.cache/optik``. A library is compiled in a
private temporary folder of the cache and renamed into place (``os.replace``), so processes and
threads compiling the same source at once never load a half-written file.

*A damaged cache never kills the process.* A library file is keyed by the hash of its source,
the compiler's path and version (``cc --version``), the flags and the machine's architecture,
and each build records the file's size and SHA-256 in a manifest beside it
(``<library>.json``, written atomically before the library is renamed into place). A cached
library is loaded only when its size and hash match its manifest: a truncated, zeroed or foreign
file (whose loading would fail or end the process with SIGBUS) or one without a manifest is
removed and rebuilt, with a warning on the ``optik.native`` logger. Loading a library marks it
used (its modification time); after each build the least recently used libraries are removed
while the cache holds more than `CACHE_MAX_BYTES` (``$OPTIK_CACHE_MAX_MB`` overrides it).
"""

from __future__ import annotations

import _thread
import atexit
import contextlib
import contextvars
import ctypes
import functools
import hashlib
import importlib.machinery
import json
import logging
import os
import platform
import shutil
import subprocess
import tempfile
import threading
import time
import uuid
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import Any

import casadi as ca
import numpy as np

from optik.errors import InvalidArgumentError, ShapeError, SolverUnavailableError

_INT = ctypes.c_longlong  # casadi_int of the generated code (see c_source)
_FLAGS = ("-O2", "-fPIC", "-shared", "-ffp-contract=off", "-fno-semantic-interposition")
"""Compiler flags (part of the cache key: a library built with other flags is never loaded).
No contraction into fused multiply-adds, so C and the virtual machine agree; no semantic
interposition: a call from optik's C into a generated function of the same library binds to it
(the compiler may inline it) instead of going through the dynamic linker's symbol table, where
another library's function of the same name could stand in for it. The libraries are loaded
with ``RTLD_LOCAL`` (``ctypes``' default) and nothing relies on interposing their symbols."""
_LOG = logging.getLogger(__name__)
_PACKAGE = Path(__file__).resolve().parent  # the optik package: the root of `source_digest`'s sources
_BUILDS: dict[Path, Library] = {}  # every library this process loaded or built, by path
_BUILDS_LOCK = threading.Lock()
_RUNNING: dict[subprocess.Popen, Path] = {}  # compiler processes at work -> their temporary folder
_RUNNING_LOCK = threading.Lock()
EVALUATOR_BUDGET = 0.25
"""Seconds of evaluation in CasADi's virtual machine, summed over the calls made while a library
builds, after which the next call waits for the build instead: the first answers come at once, and
a long computation started on a cold cache runs at most this long at the evaluator's speed."""
_EXITING = threading.Event()  # set at interpreter exit: unfinished builds are stopped, not failures
CACHE_MAX_BYTES = 512 * 1024 * 1024
"""Size of the compiled libraries in the cache above which the least recently used are removed
after a build (``$OPTIK_CACHE_MAX_MB`` overrides it); a 7-joint arm's LM kernel takes about 0.2 MB."""


_DEADLINE: contextvars.ContextVar[float | None] = contextvars.ContextVar("optik_deadline", default=None)


@contextlib.contextmanager
def deadline(at: float | None) -> Iterator[None]:
    """Within this block (this thread or task), a call never waits for a library being built
    past ``at`` (a ``time.perf_counter()`` value; None: no limit): it evaluates with CasADi
    instead. The solvers' entry points set it to the end of their time limit, so that no call
    waits for a C compile past its own limit."""
    token = _DEADLINE.set(at if at is not None and at < float("inf") else None)
    try:
        yield
    finally:
        _DEADLINE.reset(token)


def compiler() -> str | None:
    """The C compiler: ``$CC`` or ``gcc``/``cc`` on the PATH; None when there is none or
    ``$OPTIK_NO_CODEGEN`` is set (then everything runs in CasADi's evaluator).

    The PATH search runs once per value of ``$CC`` and ``$PATH``; later calls only check that the
    executable it found is still an executable file, and search again when it is not (removed,
    replaced), so a stale answer is never returned. Without a compiler every call searches (one
    installed meanwhile is found). Thread-safe.
    """
    if os.environ.get("OPTIK_NO_CODEGEN"):
        return None
    key = (os.environ.get("CC"), os.environ.get("PATH"))
    found = _COMPILERS.get(key)
    if found is not None and os.path.isfile(found[1]) and os.access(found[1], os.X_OK):
        return found[0]
    with _COMPILERS_LOCK:
        _COMPILERS.pop(key, None)
        for cand in (key[0], "gcc", "cc"):
            path = shutil.which(cand) if cand else None
            if path:
                _COMPILERS[key] = (cand, path)
                return cand
    return None


_COMPILERS: dict[tuple[str | None, str | None], tuple[str, str]] = {}
"""`compiler`'s answers by ``($CC, $PATH)``: the name returned and the executable it found."""
_COMPILERS_LOCK = threading.Lock()


_CACHE_DIR: contextvars.ContextVar[Path | None] = contextvars.ContextVar("optik_cache_dir", default=None)
"""The cache directory of an `in_background` thread: its caller's when it was started."""


def cache_dir() -> Path:
    """Directory of compiled libraries, ``$OPTIK_CACHE_DIR`` or ``~/.cache/optik`` (created on
    demand); in an `in_background` thread, the one of the call that started it."""
    d = _CACHE_DIR.get() or Path(os.environ.get("OPTIK_CACHE_DIR") or Path.home() / ".cache" / "optik")
    d.mkdir(parents=True, exist_ok=True)
    return d


def c_source(functions: Sequence[ca.Function], extra_source: str = "") -> str:
    """C code of ``functions`` in one file (no header, ``casadi_int`` = ``long long int``),
    followed by ``extra_source`` (optik's own C calling the generated functions)."""
    gen = ca.CodeGenerator(f"{functions[0].name()}.c", {"with_header": False, "casadi_int": "long long int"})
    for f in functions:
        gen.add(f)
    return gen.dump() + extra_source


@functools.lru_cache(maxsize=8)
def compiler_version(cc: str) -> str:
    """The first line of ``cc --version`` (empty when it cannot be run): part of the cache key,
    so that a library built by another compiler is never loaded.

    Running the compiler costs a process start (about 8 ms, more on a loaded machine), which a
    first solve or first `optik.diffik.step` of a fresh process would wait for: the answer is
    kept in the cache directory, in ``compilers/<hash>.txt`` keyed by the compiler executable's
    resolved path, size and modification time (an upgraded compiler is a new key), written
    atomically; a missing or unreadable record runs the compiler again. The record has the mode
    of the libraries' manifests beside it, ``0666`` less the umask: in a cache that several
    users share through ``$OPTIK_CACHE_DIR`` (a group umask such as ``002``), each reads the
    others' records instead of running the compiler, and only the owner (and group, if the
    umask allows) can change one; a compiler's version string is no secret."""
    memo = _version_memo(cc)
    if memo is not None:
        with contextlib.suppress(OSError):
            return memo.read_text()
    try:
        out = subprocess.run([cc, "--version"], capture_output=True, text=True, timeout=30, check=False)
    except (OSError, subprocess.SubprocessError):
        return ""
    version = out.stdout.partition("\n")[0].strip()
    if memo is not None and out.returncode == 0:
        with contextlib.suppress(OSError):
            memo.parent.mkdir(exist_ok=True)
            tmp = memo.parent / f".version-{uuid.uuid4().hex}"
            # os.open applies the umask to 0666 (mkstemp would make it 0600, private to one user)
            with os.fdopen(os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666), "w") as f:
                f.write(version)
            os.replace(tmp, memo)
    return version


def _version_memo(cc: str) -> Path | None:
    """The record of `compiler_version` for the executable ``cc`` resolves to, or None (the
    executable or the cache directory cannot be found)."""
    try:
        exe = os.path.realpath(shutil.which(cc) or cc)
        st = os.stat(exe)
        stamp = f"{exe}\0{st.st_size}\0{st.st_mtime_ns}"
        return cache_dir() / "compilers" / f"{hashlib.sha256(stamp.encode()).hexdigest()[:20]}.txt"
    except OSError:
        return None


def _library_file(stem: str, source: str, cc: str, flags: Sequence[str]) -> Path:
    """Cache path of the library of ``source`` compiled by ``cc`` with the flags on this machine
    (keyed by a hash of them, the compiler's version and the architecture)."""
    machine = f"{platform.system()}-{platform.machine()}"
    key = (source, cc, compiler_version(cc), machine, *_FLAGS, *flags)
    digest = hashlib.sha256("\0".join(key).encode()).hexdigest()[:20]
    return cache_dir() / f"{stem}_{digest}.so"


def _manifest_file(lib: Path) -> Path:
    return lib.with_name(lib.name + ".json")


def _fingerprint(path: Path) -> dict[str, int | str]:
    """``{"size": bytes, "sha256": hex digest}`` of a file."""
    data = path.read_bytes()
    return {"size": len(data), "sha256": hashlib.sha256(data).hexdigest()}


def _write_manifest(built: Path, lib: Path) -> None:
    """Record the size and hash of the freshly built ``built`` as the manifest of ``lib``
    (written to a temporary file and renamed: atomic)."""
    manifest = _manifest_file(lib)
    tmp = built.with_name(f"manifest-{uuid.uuid4().hex}.json")  # unique: builds of one folder at once
    tmp.write_text(json.dumps(_fingerprint(built)))
    os.replace(tmp, manifest)


def _damage(lib: Path) -> str | None:
    """Why the cached ``lib`` must not be loaded (no manifest, another size or hash), or None."""
    try:
        recorded = json.loads(_manifest_file(lib).read_text())
    except (OSError, ValueError):
        return "it has no readable manifest"
    if not isinstance(recorded, dict):
        return "its manifest is not a record"
    try:
        size = lib.stat().st_size
        if size != recorded.get("size"):
            return f"its size is {size} bytes, {recorded.get('size')} recorded"
        if _fingerprint(lib)["sha256"] != recorded.get("sha256"):
            return "its SHA-256 differs from the one recorded at build time"
    except OSError as exc:
        return f"it cannot be read: {exc}"
    return None


def _remove(lib: Path) -> None:
    for f in (lib, _manifest_file(lib)):
        with contextlib.suppress(OSError):
            f.unlink()


def _cache_limit() -> int:
    value = os.environ.get("OPTIK_CACHE_MAX_MB")
    try:
        return int(float(value) * 1024 * 1024) if value else CACHE_MAX_BYTES
    except ValueError:
        _LOG.warning("optik: $OPTIK_CACHE_MAX_MB=%r is not a number; %d bytes used", value, CACHE_MAX_BYTES)
        return CACHE_MAX_BYTES


def prune_cache(directory: Path, limit: int, keep: Path | None = None) -> list[Path]:
    """Remove the least recently used libraries (oldest modification time: loading one marks it)
    of ``directory`` while their sizes add up to more than ``limit`` bytes; never ``keep``.
    Returns the removed files (a library loaded by a process stays usable by it)."""
    libs = []
    for f in directory.glob("*.so"):
        with contextlib.suppress(OSError):
            st = f.stat()
            libs.append((st.st_mtime, st.st_size, f))
    total = sum(size for _, size, _ in libs)
    removed = []
    for _, size, f in sorted(libs):
        if total <= limit:
            break
        if f == keep:
            continue
        _remove(f)
        removed.append(f)
        total -= size
    return removed


def _start(source: str, cc: str, lib: Path, flags: Sequence[str]) -> tuple[subprocess.Popen, Path]:
    """Write ``source`` into a new temporary folder of the cache and start the compiler on it at a
    lower scheduling priority (returns at once); the compiler process and the folder.

    Raises:
        OSError: the cache directory is not writable, or the compiler cannot be started.
    """
    tmp = Path(tempfile.mkdtemp(dir=lib.parent, prefix=".build-"))
    try:
        (tmp / "f.c").write_text(source)
        with _RUNNING_LOCK:
            proc = subprocess.Popen(
                [cc, *_FLAGS, *flags, "-o", str(tmp / "f.so"), str(tmp / "f.c"), "-lm"],
                stdout=subprocess.DEVNULL,
                stderr=subprocess.PIPE,
                text=True,
            )
            _RUNNING[proc] = tmp
        with contextlib.suppress(OSError, AttributeError):  # a background job: let the solves go first
            os.setpriority(os.PRIO_PROCESS, proc.pid, 10)
    except OSError:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return proc, tmp


def _finish(proc: subprocess.Popen, tmp: Path, lib: Path) -> None:
    """Wait for the compiler started by `_start`, rename its output to ``lib``, remove ``tmp``.

    Raises:
        SolverUnavailableError: the compiler failed (its last error lines in the message).
        OSError: the rename failed.
    """
    try:
        try:
            _, err = proc.communicate()
        finally:
            with _RUNNING_LOCK:
                _RUNNING.pop(proc, None)
        if proc.returncode != 0:
            raise SolverUnavailableError(f"compiling {lib.name} failed: {err[-2000:]}")
        _write_manifest(tmp / "f.so", lib)  # first: a library in place always has its manifest
        os.replace(tmp / "f.so", lib)  # atomic: concurrent processes may compile the same source
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


@atexit.register
def _stop_builds() -> None:
    """Stop the compilers of unfinished background builds and remove their temporary folders."""
    _EXITING.set()
    with _RUNNING_LOCK:
        running = list(_RUNNING.items())
    for proc, tmp in running:
        proc.kill()
        proc.wait()
        shutil.rmtree(tmp, ignore_errors=True)


class Library:
    """A shared library of generated C code: loaded, being built in the background, or failed.

    Created by `optik.native.library` (one object per library file and process).

    Attributes:
        path: the library file in the cache.
        error: why the build or the load failed (None otherwise).
    """

    def __init__(self, path: Path, flags: Sequence[str] = ()) -> None:
        self.path = path
        self.flags = tuple(flags)
        self.error: str | None = None
        self._cdll: ctypes.CDLL | None = None
        self._done = threading.Event()
        self._evaluated = 0.0  # seconds the callers spent in CasADi's evaluator while it builds
        self.shipped = False  # a library of the installed package (`prebuilt_library`), not the cache's

    @classmethod
    def loaded(cls, path: Path, cdll: ctypes.CDLL) -> Library:
        """A ready `Library` of the file ``path`` already loaded as ``cdll`` (`prebuilt_library`)."""
        lib = cls(path)
        lib._cdll, lib.shipped = cdll, True
        lib._done.set()
        return lib

    @property
    def state(self) -> str:
        """``"building"``, ``"ready"`` or ``"failed"``."""
        if not self._done.is_set():
            return "building"
        return "ready" if self._cdll is not None else "failed"

    def get(self) -> ctypes.CDLL | None:
        """The loaded library when it is ready, else None; blocks until the build is done only
        once the callers have spent `EVALUATOR_BUDGET` seconds in CasADi's evaluator meanwhile,
        and never past the caller's `deadline`."""
        if not self._done.is_set() and self._evaluated > EVALUATOR_BUDGET:
            until = _DEADLINE.get()
            self._done.wait(None if until is None else max(0.0, until - time.perf_counter()))
        return self._cdll if self._done.is_set() else None

    def files(self) -> list[Path]:
        """This library's files in the cache that exist: the library, its manifest and the record
        of the compiler's version its key was made with (what another cache directory needs to
        load it: `optik benchmark first_solve` copies them); none for a `shipped` library."""
        if self.shipped:
            return []
        cc = compiler()
        memo = None if cc is None else _version_memo(cc)
        found = (self.path, _manifest_file(self.path), memo)
        return [f for f in found if f is not None and f.exists()]

    def evaluated(self, seconds: float) -> None:
        """Account ``seconds`` spent evaluating in CasADi instead of this library (see `get`)."""
        self._evaluated += seconds

    def wait(self, timeout: float | None = None) -> ctypes.CDLL | None:
        """Block until the build is done (at most ``timeout`` seconds); the loaded library or None."""
        self._done.wait(timeout)
        return self.get()

    def _make(self, source: str, cc: str, background: bool) -> None:
        """Load the cached file, or start the compiler and load its output: in a daemon thread that
        waits for it when ``background``, else here. A failure is recorded (and logged), not raised."""
        try:
            if self.path.exists():
                damage = _damage(self.path)
                if damage is None:
                    self._settle(None, None)
                    return
                _LOG.warning("optik: the cached library %s is damaged (%s): rebuilt", self.path.name, damage)
                _remove(self.path)
            proc, tmp = _start(
                source, cc, self.path, self.flags
            )  # here: the thread does no Python work meanwhile
            if not background:
                self._settle(proc, tmp)
                return
            name = f"optik-build-{self.path.stem}"
            threading.Thread(target=self._settle, args=(proc, tmp), name=name, daemon=True).start()
        except Exception as exc:
            self._fail(exc)
            if not isinstance(exc, OSError):  # OSError: the compiler could not be started
                raise

    def _make_later(self, make_source: Callable[[], str], cc: str) -> None:
        """Load the cached file here when it is sound, else make the source and compile it in a
        daemon thread (`keyed_library`)."""
        if self.path.exists() and _damage(self.path) is None:
            self._settle(None, None)
            return

        def build() -> None:
            try:
                source = make_source()
            except Exception as exc:  # the source generation failed: logged, no library
                self._fail(exc)
                return
            with contextlib.suppress(Exception):  # _make records and logs its own failures
                self._make(source, cc, False)

        threading.Thread(target=build, name=f"optik-build-{self.path.stem}", daemon=True).start()

    def _settle(self, proc: subprocess.Popen | None, tmp: Path | None) -> None:
        """Finish the build (when ``proc`` runs) and load the library; record a failure."""
        try:
            if proc is not None and tmp is not None:
                _finish(proc, tmp, self.path)
                prune_cache(self.path.parent, _cache_limit(), keep=self.path)
            else:
                with contextlib.suppress(OSError):
                    os.utime(self.path)  # used now (the cache is pruned least recently used first)
            self._cdll = ctypes.CDLL(str(self.path))
        except (SolverUnavailableError, OSError) as exc:  # broken toolchain, unwritable cache, bad file
            self._fail(exc)
        finally:
            self._done.set()

    def _fail(self, exc: Exception) -> None:
        self.error = str(exc)
        if not _EXITING.is_set():  # logged before the waiters wake, so they find the record
            _LOG.warning(
                "optik: no compiled code for %s, its caller falls back (CasADi's evaluator for generated "
                "code; another build or numpy for hand-written C): %s",
                self.path.name,
                exc,
            )
        self._done.set()


def library(
    functions: Sequence[ca.Function],
    compile: bool | str = "auto",
    extra_source: str = "",
    flags: Sequence[str] = (),
) -> Library | None:
    """The compiled library of ``functions`` (possibly still building), or None: evaluate them
    with CasADi instead.

    Args:
        functions: the functions to compile into one library.
        compile: ``True`` compile now in this thread (raise when impossible), ``False`` never
            compile (None), ``"auto"`` load the cached library, or start the compiler and
            return at once when it is not cached yet (a daemon thread waits for the compiler
            and loads the library; None without a C compiler).
        extra_source: C code appended to the generated code (see `c_source`).
        flags: extra compiler options (e.g. include directories; part of the cache key).

    Raises:
        InvalidArgumentError: bad ``compile`` value.
        SolverUnavailableError: ``compile=True`` without a working compiler.
    """
    cc = _compiler_for(compile)
    if cc is None:
        return None
    source = c_source(functions, extra_source)
    return _library(source, functions[0].name(), cc, compile, compile == "auto", flags)


def source_library(
    source: str, stem: str, compile: bool | str = "auto", flags: Sequence[str] = ()
) -> ctypes.CDLL | None:
    """The loaded library of hand-written C ``source``, compiled in this thread (blocking), or None.

    Args:
        source: C source text.
        stem: file name stem of the library (``<stem>_<hash>.so`` in `cache_dir`).
        compile: as for `library`, except that ``"auto"`` waits for the compiler too (None when
            it fails).
        flags: extra compiler options (part of the cache key).

    Raises:
        InvalidArgumentError: bad ``compile`` value.
        SolverUnavailableError: ``compile=True`` without a working compiler.
    """
    cc = _compiler_for(compile)
    if cc is None:
        return None
    lib = _library(source, stem, cc, compile, False, flags)
    return None if lib is None else lib.wait()


def source_digest(sources: Sequence[str], *parts: object, casadi: bool = True) -> str:
    """The key of generated code for `keyed_library`: the SHA-256 of CasADi's version and
    ``parts`` (as text, NUL-separated), then the bytes of each file of ``sources``.

    Args:
        sources: the files the code is generated from, relative to the ``optik`` package.
        parts: what else selects the code (a joint count, a task structure).
        casadi: include CasADi's version (False for `prebuilt_library`: the package is built
            with the CasADi of its build environment, and any version's code computes the same
            functions).

    Raises:
        OSError: a source cannot be read (a partial install).
    """
    h = hashlib.sha256("\0".join([ca.__version__ if casadi else "", *map(str, parts)]).encode())
    for rel in sources:
        h.update((_PACKAGE / rel).read_bytes())
    return h.hexdigest()


KEY_SYMBOL = "optik_key"
"""Name of the C string in a prebuilt library that holds the `source_digest` it was generated from."""


def prebuilt_path(folder: Path, name: str) -> Path:
    """The file of the extension module ``name`` in ``folder`` (this Python's extension suffix)."""
    return folder / f"{name}{importlib.machinery.EXTENSION_SUFFIXES[0]}"


def prebuilt_library(folder: Path, name: str, key: str) -> Library | None:
    """The library ``name`` compiled when the package was installed (``setup.py``'s optional
    extensions), loaded, or None: then the caller builds its library in the cache as usual.

    The file ``prebuilt_path(folder, name)`` is loaded only when its size and SHA-256 match the
    manifest written beside it at build time (as for the cache: a truncated or foreign file is
    never loaded) and its `KEY_SYMBOL` string equals ``key`` (it was generated from the sources
    now installed: an editable install whose sources changed since its build finds it stale). A
    damaged or stale file is logged (logger ``optik.native``) and left in place; a missing one
    (no compiler at install time) is logged at debug level.

    Args:
        folder: where the package's extension modules are.
        name: the module's name (file name stem).
        key: the `source_digest` the library must have been generated from.
    """
    path = prebuilt_path(folder, name)
    if not path.exists():
        _LOG.debug("optik: no prebuilt %s (none was compiled at install)", path.name)
        return None
    damage = _damage(path)
    if damage is not None:
        _LOG.warning("optik: the prebuilt library %s is damaged (%s): not loaded", path, damage)
        return None
    try:
        cdll = ctypes.CDLL(str(path))
        found = (ctypes.c_char * (len(key) + 1)).in_dll(cdll, KEY_SYMBOL).value.decode()
    except (OSError, ValueError) as exc:
        _LOG.warning("optik: the prebuilt library %s cannot be loaded: %s", path, exc)
        return None
    if found != key:
        _LOG.info("optik: the prebuilt library %s was made from other sources: not used", path.name)
        return None
    return Library.loaded(path, cdll)


def write_manifest(lib: Path) -> None:
    """Record the size and SHA-256 of the built library ``lib`` beside it (atomically), as a
    build into the cache does: what `prebuilt_library` checks before loading it."""
    _write_manifest(lib, lib)


def keyed_library(stem: str, key: str, make_source: Callable[[], str]) -> Library | None:
    """The library cached under ``key`` (a digest of everything its source is made from), its
    source made only when it is not cached: for code whose generation costs more than a first
    call may wait (`optik.solvers.generic_chain`).

    A cached, undamaged library is loaded here (about a millisecond). Otherwise a daemon thread
    calls ``make_source()`` and compiles it (``compile="auto"`` of `library`); the returned
    `Library` is then ``"building"``. A failure of either is logged and leaves it ``"failed"``.
    None without a C compiler or a usable cache directory (logged).

    Args:
        stem: file name stem of the library (``<stem>_<hash>.so`` in `cache_dir`).
        key: identifies the source; with the compiler, its version and the architecture it
            makes the file name.
        make_source: returns the C source of ``key``.
    """
    cc = compiler()
    if cc is None:
        return None
    return _library(key, stem, cc, "auto", True, (), make_source)


def driver_source(path: Path, compile: bool | str = "auto") -> str | None:
    """The text of the hand-written C driver ``path`` that is compiled with generated code, or
    None when it cannot be read (a damaged or partial install): the caller then evaluates with
    CasADi instead, and the reason is logged.

    Raises:
        SolverUnavailableError: ``compile=True`` and the file cannot be read.
    """
    try:
        return path.read_text()
    except OSError as exc:
        if compile is True:
            raise SolverUnavailableError(f"the C driver {path} cannot be read: {exc}") from exc
        _LOG.warning("optik: the C driver %s cannot be read, CasADi's evaluator is used: %s", path, exc)
        return None


def check_compile(compile: Any) -> bool | str:
    """``compile`` itself when it is a ``compile`` option of this module (True, False or
    ``"auto"``): a caller that keys a cache by it checks it before building anything.

    Raises:
        InvalidArgumentError: any other value.
    """
    if compile not in (True, False, "auto"):
        raise InvalidArgumentError("compile", f"expected True, False or 'auto', got {compile!r}")
    return compile


def _compiler_for(compile: bool | str) -> str | None:
    """The `compiler` to build with under a validated ``compile`` option, None for no compiled
    code (``compile=False``, or no compiler with ``"auto"``).

    Raises:
        InvalidArgumentError: ``compile`` is not True, False or ``"auto"`` (`check_compile`).
        SolverUnavailableError: ``compile=True`` without a compiler.
    """
    if check_compile(compile) is False:
        return None
    cc = compiler()
    if cc is None and compile is True:
        raise SolverUnavailableError("no C compiler found (set $CC or install gcc; unset $OPTIK_NO_CODEGEN)")
    return cc


def _library(
    source: str,
    stem: str,
    cc: str,
    compile: bool | str,
    background: bool,
    flags: Sequence[str],
    make_source: Callable[[], str] | None = None,
) -> Library | None:
    """The `Library` of ``source`` (one per file and process): loaded from the cache, or built
    here or, when ``background``, by the compiler started here and a daemon thread waiting for it.
    With ``make_source``, ``source`` is only the key of the file name and the source to compile
    is ``make_source()``, made in that daemon thread (see `keyed_library`)."""
    try:
        path = _library_file(stem, source, cc, flags)
    except OSError as exc:  # the cache directory cannot be created
        if compile is True:
            raise
        _LOG.warning("optik: no compiled code, the cache directory is not usable: %s", exc)
        return None
    with _BUILDS_LOCK:
        lib = _BUILDS.get(path)
        fresh = lib is None
        if fresh:
            lib = _BUILDS[path] = Library(path, flags)
    if fresh and make_source is not None:
        lib._make_later(make_source, cc)
    elif fresh:
        lib._make(source, cc, background)  # cached: loading takes a millisecond
    if compile is True and lib.wait() is None:
        raise SolverUnavailableError(lib.error or f"{path.name}: no library")
    return lib


_PREPARING: set[threading.Event] = set()  # one per `in_background` work still running
_PREPARING_LOCK = threading.Lock()


HANDOVER = 0.002
"""Seconds an `in_background` thread sleeps before its work: the caller, whose answer is ready,
gets the interpreter back first (a thread running Python code otherwise takes it for a switch
interval, 5 ms, from the thread that started it)."""


def in_background(work: Callable[[], object]) -> None:
    """Run ``work`` in a new thread, after `HANDOVER` seconds, that `wait` waits for too: the
    preparation of a library (its code generation) that a caller does not wait for
    (`optik.solvers.generic_chain`, `optik.diffik.generic_stack`).

    The thread is started by ``_thread.start_new_thread``, which returns at once, where
    ``threading.Thread.start`` waits until the new thread runs (on a loaded machine, until the
    system schedules it: milliseconds the caller would add to its answer). Like a daemon thread,
    it does not keep the interpreter alive; an exception of ``work`` is logged. Its libraries go
    to the cache directory of the call that started it (`cache_dir`), whatever
    ``$OPTIK_CACHE_DIR`` says meanwhile."""
    done = threading.Event()
    directory = cache_dir()

    def run() -> None:
        try:
            _CACHE_DIR.set(directory)
            time.sleep(HANDOVER)
            work()
        except Exception:
            _LOG.warning("optik: a background preparation failed", exc_info=True)
        finally:
            with _PREPARING_LOCK:
                _PREPARING.discard(done)
            done.set()

    with _PREPARING_LOCK:
        _PREPARING.add(done)
    _thread.start_new_thread(run, ())


def wait(timeout: float | None = None) -> bool:
    """Wait until every background build of this process is done (at most ``timeout`` seconds
    in all), the preparations started by `in_background` first; True when none is left running."""
    deadline = None if timeout is None else time.monotonic() + timeout
    with _PREPARING_LOCK:
        preparing = list(_PREPARING)
    for done in preparing:
        done.wait(None if deadline is None else max(0.0, deadline - time.monotonic()))
    with _BUILDS_LOCK:
        builds = list(_BUILDS.values())
    for lib in builds:
        lib.wait(None if deadline is None else max(0.0, deadline - time.monotonic()))
    return all(done.is_set() for done in preparing) and all(lib.state != "building" for lib in builds)


def _check_buffers(lib: ctypes.CDLL, name: str, side: str, buffers: Sequence[np.ndarray]) -> None:
    """Check the input (``side="in"``) or output buffers of the generated function ``name``
    against its signature in ``lib`` (see `CCall`)."""
    argument = f"{side}puts"
    count = getattr(lib, f"{name}_n_{side}")
    count.restype, count.argtypes = _INT, []
    sparsity = getattr(lib, f"{name}_sparsity_{side}")
    sparsity.restype, sparsity.argtypes = ctypes.POINTER(_INT), [_INT]
    n = int(count())
    if len(buffers) != n:
        raise InvalidArgumentError(argument, f"{name} takes {n} {argument}, got {len(buffers)} buffers")
    for i, b in enumerate(buffers):
        if not isinstance(b, np.ndarray) or b.dtype != np.float64 or not b.flags.contiguous:
            what = f"{type(b).__name__} {getattr(b, 'dtype', '')}".strip()
            raise InvalidArgumentError(
                argument, f"{name}: buffer {i} must be a contiguous float64 array, got {what}"
            )
        if side == "out" and not b.flags.writeable:
            raise InvalidArgumentError(argument, f"{name}: output buffer {i} is read-only")
        sp = sparsity(i)
        rows, cols = int(sp[0]), int(sp[1])
        nnz = rows * cols if sp[2] == 1 else int(sp[2 + cols])  # compact dense form [rows, cols, 1]
        if b.size != nnz:
            raise ShapeError(argument, f"{name}: buffer {i} has {b.size} entries, its argument {nnz}")


class CCall:
    """One generated function of a loaded library, bound to preallocated numpy buffers.

    Args:
        lib: the loaded library (`Library.get`) that holds ``name``.
        name: the CasADi function's name.
        inputs: one contiguous float64 array per input (dense, column-major).
        outputs: one contiguous float64 array per output.

    The arrays are bound by address: write into ``inputs``, call, read ``outputs``. Keep them
    alive (and never reallocate them) while the call object is in use. They are checked once,
    here, against the generated function's own signature (its numbers of inputs and outputs and
    the nonzeros of each, from ``<name>_n_in`` and ``<name>_sparsity_in`` ...), so that a call
    never reads or writes past a buffer.

    Raises:
        InvalidArgumentError: another number of ``inputs`` or ``outputs`` than the function has,
            or a buffer that is not a contiguous float64 numpy array (writeable for outputs).
        ShapeError: a buffer of another size than its argument's nonzeros.
    """

    def __init__(
        self, lib: ctypes.CDLL, name: str, inputs: Sequence[np.ndarray], outputs: Sequence[np.ndarray]
    ) -> None:
        self.name = name
        for side, buffers in (("in", inputs), ("out", outputs)):
            _check_buffers(lib, name, side, buffers)
        self._buffers = (list(inputs), list(outputs))  # keep the bound memory alive
        sizes = [_INT() for _ in range(4)]
        getattr(lib, f"{name}_work")(*[ctypes.byref(s) for s in sizes])
        n_arg, n_res, n_iw, n_w = (max(int(s.value), 1) for s in sizes)
        self._argv = (ctypes.c_void_p * n_arg)(*[b.ctypes.data for b in inputs])
        self._resv = (ctypes.c_void_p * n_res)(*[b.ctypes.data for b in outputs])
        self._iw = (_INT * n_iw)()
        self._w = (ctypes.c_double * n_w)()
        self._fn = getattr(lib, name)
        self._fn.argtypes = [ctypes.c_void_p, ctypes.c_void_p, ctypes.c_void_p, ctypes.c_void_p, ctypes.c_int]
        self._fn.restype = ctypes.c_int

    def __call__(self) -> None:
        """Evaluate on the current contents of the input buffers.

        Raises:
            SolverUnavailableError: the generated code reported an error.
        """
        if self._fn(self._argv, self._resv, self._iw, self._w, 0) != 0:
            raise SolverUnavailableError(f"{self.name}: evaluation failed")


class Binding:
    """A `CCall` of a `Library` that may still be building: made at the first call after the
    library is ready.

    Args:
        lib: the library that holds ``name`` (None: never compiled).
        name, inputs, outputs: as for `CCall`.

    While there is no compiled code (still building, failed or never compiled) a call runs the
    caller's own evaluation instead.
    """

    def __init__(
        self, lib: Library | None, name: str, inputs: Sequence[np.ndarray], outputs: Sequence[np.ndarray]
    ) -> None:
        self._lib = lib
        self._args = (name, inputs, outputs)
        self._call: CCall | None = None

    @property
    def compiled(self) -> bool:
        """True once calls go to the compiled code."""
        return self._call is not None or self._bind()

    def _bind(self) -> bool:
        """Make the `CCall` when the library has become ready; True when made."""
        lib = self._lib
        cdll = lib.get() if lib is not None else None
        if cdll is None:
            if lib is not None and lib.state == "failed":
                self._lib = None  # stop asking
            return False
        self._call, self._lib = CCall(cdll, *self._args), None
        return True

    def __call__(self, evaluate: Callable[[], object]) -> None:
        """Evaluate on the current input buffers: the compiled code when it is there, else
        ``evaluate()`` (CasADi's evaluator writing the outputs), timed for `Library.get`.

        Raises:
            SolverUnavailableError: the generated code reported an error.
        """
        if self._call is None and not self._bind():
            lib, start = self._lib, time.perf_counter()
            evaluate()
            if lib is not None:
                lib.evaluated(time.perf_counter() - start)
            return
        self._call()


class CFunction:
    """One function of a hand-written C file (reentrant, called through ``ctypes``), compiled
    once per machine in the background the first time it is asked for (`keyed_library`, keyed by
    the file's text, so an edited file is a new library).

    `get` never waits: None until the library is loaded, and for good without a C compiler, when
    the file cannot be read or when the build failed (each logged); the caller then takes its
    Python path. Thread-safe.

    Args:
        path: the C file.
        stem: file name stem of the library in `cache_dir`.
        symbol: the function's name.
        argtypes, restype: its ``ctypes`` signature.
    """

    def __init__(
        self,
        path: Path,
        stem: str,
        symbol: str,
        argtypes: Sequence[type],
        restype: type | None = ctypes.c_int,
    ) -> None:
        self.path, self.stem, self.symbol = path, stem, symbol
        self.argtypes, self.restype = list(argtypes), restype
        self.library: Library | None = None
        self._fn: ctypes._CFuncPtr | None = None
        self._started = False
        self._lock = threading.Lock()

    def get(self) -> ctypes._CFuncPtr | None:
        """The function once its library is loaded, else None (see the class)."""
        if self._fn is not None:
            return self._fn
        if not self._started:
            with self._lock:
                if not self._started:
                    text = driver_source(self.path)
                    self.library = None if text is None else keyed_library(self.stem, text, lambda: text)
                    self._started = True
        lib = self.library
        if lib is None or lib.state != "ready":
            return None
        fn = getattr(lib.get(), self.symbol)
        fn.argtypes, fn.restype = self.argtypes, self.restype
        self._fn = fn
        return fn


def native_functions(functions: list[ca.Function], compile: bool | str = "auto") -> list[NativeFunction]:
    """`NativeFunction` wrappers of several functions compiled into one library.

    Args:
        functions: functions with dense column inputs and outputs.
        compile: ``True`` compile now (raise when impossible), ``False`` use CasADi's evaluator,
            ``"auto"`` use the cached library, or CasADi's evaluator while it is built in the
            background (and for good when there is no working C compiler).

    Raises:
        InvalidArgumentError: bad ``compile`` value or non-dense inputs/outputs.
        SolverUnavailableError: ``compile=True`` without a working compiler.
    """
    for f in functions:
        _check_dense(f)  # before compiling
    lib = library(functions, compile)
    return [NativeFunction(f, lib) for f in functions]


def _check_dense(f: ca.Function) -> None:
    for i in range(f.n_in()):
        if f.size2_in(i) != 1 or not f.sparsity_in(i).is_dense():
            raise InvalidArgumentError("f", f"input {i} of {f.name()} must be a dense column")
    for i in range(f.n_out()):
        if f.size2_out(i) != 1 or not f.sparsity_out(i).is_dense():
            raise InvalidArgumentError("f", f"output {i} of {f.name()} must be a dense column")


class NativeFunction:
    """A CasADi function with dense vector inputs/outputs, callable on preallocated buffers.

    Write the inputs into `inputs` (numpy arrays), call, read `outputs` (views of
    preallocated buffers: copy them to keep them across calls). Not thread-safe.

    Args:
        f: the function; every input and output must be a dense column or scalar.
        library: library holding ``f`` (`optik.native.library`; None: CasADi's evaluator).
            Until it is ready the calls go to CasADi's evaluator, then to the C code.
    """

    def __init__(self, f: ca.Function, library: Library | None = None) -> None:
        _check_dense(f)
        self.function = f
        self.inputs = [np.zeros(f.size1_in(i)) for i in range(f.n_in())]
        self.outputs = [np.zeros(f.size1_out(i)) for i in range(f.n_out())]
        self.library = library
        self._native = Binding(library, f.name(), self.inputs, self.outputs)
        self._buffer: Any = None  # CasADi's evaluator on the same buffers, made at its first use

    @property
    def compiled(self) -> bool:
        """True when calls go to generated, compiled C code (False while it is being built)."""
        return self._native.compiled

    def __call__(self) -> list[np.ndarray]:
        """Evaluate on the current contents of `inputs`; returns `outputs`."""
        self._native(self._evaluate)
        return self.outputs

    def _evaluate(self) -> None:
        """CasADi's evaluator, into `outputs`: ``Function.buffer`` bound to `inputs` and
        `outputs` (about a microsecond of overhead per call instead of the hundred or so of a
        call through ``DM`` conversions, which would dominate the first solves while the library
        builds)."""
        if self._buffer is None:
            buffer, call = self.function.buffer()
            for i, a in enumerate(self.inputs):
                buffer.set_arg(i, memoryview(a))
            for i, a in enumerate(self.outputs):
                buffer.set_res(i, memoryview(a))
            self._buffer = (buffer, call)
        self._buffer[1]()
