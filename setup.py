"""Package layout that pyproject.toml cannot say alone: the top-level source folders ``problems/``
(TOML problem files) and ``benchmarks/`` (focused benchmark scripts) are installed as the packages
``optik.problems`` and ``optik.benchmarks``, so that a wheel carries them and a clone and an
install run the same ``optik bench`` and ``optik benchmark NAME``. Everything else is in
pyproject.toml."""

from setuptools import find_packages, setup

setup(
    packages=[*find_packages(include=["optik", "optik.*"]), "optik.problems", "optik.benchmarks"],
    package_dir={"optik.problems": "problems", "optik.benchmarks": "benchmarks"},
)
