"""Maps this folder onto the `actaim2` package, so `src/actaim2/sim/` imports as `actaim2.sim`.

pyproject.toml cannot express "this directory is the package" together with automatic
sub-package discovery; everything else (metadata, dependencies, scripts) lives there.
"""
from setuptools import find_packages, setup

setup(
    packages=["actaim2"] + [f"actaim2.{name}" for name in find_packages(".", exclude=["build*"])],
    package_dir={"actaim2": "."},
)
