"""Package layout that pyproject.toml cannot say alone, and the kernels compiled at install.

The top-level source folders ``problems/`` (TOML problem files) and ``benchmarks/`` (focused
benchmark scripts) are installed as the packages ``optik.problems`` and ``optik.benchmarks``, so
that a wheel carries them and a clone and an install run the same ``optik bench`` and ``optik
benchmark NAME``.

The generic lm kernels of the common joint counts (`optik.solvers.generic_chain.PREBUILT`) are
optional C extensions ``optik._chain<n>``: their C source is generated here by CasADi from the
package's own sources (`optik.solvers.generic_chain.prebuilt_source`), compiled, and a manifest
(size, SHA-256) is written beside each, so that the first solve on a fresh install finds them. A
missing compiler or a failed generation is reported and the install goes on without them (optik
then builds them in its cache on first use). Everything else is in pyproject.toml.
"""

import importlib
import sys
import types
from pathlib import Path

from setuptools import Extension, find_packages, setup
from setuptools.command.build_ext import build_ext

HERE = Path(__file__).resolve().parent
FLAGS = ["-O2", "-ffp-contract=off", "-fno-semantic-interposition"]  # as optik.native's builds
SIZES = (6, 7)  # optik.solvers.generic_chain.PREBUILT (checked in BuildKernels)


def _optik_modules() -> tuple[types.ModuleType, types.ModuleType]:
    """`optik.solvers.generic_chain` and `optik.native` of this source tree, imported without the
    package's ``__init__`` (which imports every optional layer): only CasADi, numpy and lxml
    (pyproject.toml's build requirements) are needed."""
    package = types.ModuleType("optik")
    package.__path__ = [str(HERE / "optik")]
    sys.modules["optik"] = package
    return importlib.import_module("optik.solvers.generic_chain"), importlib.import_module("optik.native")


class BuildKernels(build_ext):
    """``build_ext`` that writes each kernel's generated source before compiling it and its
    manifest after."""

    def build_extension(self, ext: Extension) -> None:
        n = int(ext.name.rsplit("_chain", 1)[1])
        try:
            generic_chain, native = _optik_modules()
            if tuple(generic_chain.PREBUILT) != SIZES:
                raise RuntimeError(f"setup.py SIZES {SIZES} != generic_chain.PREBUILT")
            source = Path(self.build_temp) / f"optik_chain{n}.c"
            source.parent.mkdir(parents=True, exist_ok=True)
            source.write_text(generic_chain.prebuilt_source(n))
        except Exception as exc:  # no CasADi in the build environment, a broken source tree
            print(f"warning: optik: the kernel of {n} joints is not prebuilt ({exc})", file=sys.stderr)
            return
        ext.sources = [str(source)]
        super().build_extension(ext)  # optional: a compiler error is reported, not raised
        native.write_manifest(Path(self.get_ext_fullpath(ext.name)))

    def copy_extensions_to_source(self) -> None:
        """An editable install (``--inplace``) copies each built kernel and its manifest."""
        super().copy_extensions_to_source()
        build_py = self.get_finalized_command("build_py")
        for ext in self.extensions:
            inplace, regular = self._get_inplace_equivalent(build_py, ext)
            if Path(regular + ".json").exists():
                self.copy_file(regular + ".json", inplace + ".json", level=self.verbose)


setup(
    packages=[*find_packages(include=["optik", "optik.*"]), "optik.problems", "optik.benchmarks"],
    package_dir={"optik.problems": "problems", "optik.benchmarks": "benchmarks"},
    ext_modules=[
        Extension(f"optik._chain{n}", sources=[], extra_compile_args=FLAGS, optional=True) for n in SIZES
    ],
    cmdclass={"build_ext": BuildKernels},
)
