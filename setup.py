"""Package list for setuptools (the rest of the metadata is in pyproject.toml).

``cli/`` is installed as ``brdflab.cli`` (see ``[tool.setuptools.package-dir]`` in pyproject.toml); every
(namespace) package under ``brdflab/`` is found automatically.
"""

from setuptools import find_namespace_packages, setup

setup(packages=[*find_namespace_packages(include=["brdflab", "brdflab.*"], exclude=["*.__pycache__"]), "brdflab.cli"])
