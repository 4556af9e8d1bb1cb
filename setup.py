"""Packages are found, not listed: every package under hdl/, gen/ and sim/ installs as
kfgen.hdl.*, kfgen.gen.*, kfgen.sim.* (the top level is fixed; the import namespace is kfgen).

pyproject.toml holds everything else. setuptools' own ``packages.find`` cannot put a prefix on
the names it finds, which is why this file exists.
"""

from setuptools import find_packages, setup

TOP = ("hdl", "gen", "sim")

setup(
    package_dir={f"kfgen.{top}": top for top in TOP},
    packages=[f"kfgen.{top}" for top in TOP] + [f"kfgen.{top}.{sub}" for top in TOP for sub in find_packages(top)],
)
