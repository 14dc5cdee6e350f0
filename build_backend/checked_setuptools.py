"""fuzzynav's build backend: setuptools' own (``setuptools.build_meta``), after a check of setuptools' version.

pyproject.toml declares the compiled kernels as ``[[tool.setuptools.ext-modules]]``, which setuptools reads from
74.1 on. An isolated build installs that version itself (``[build-system] requires``), but ``pip install
--no-build-isolation`` builds with whatever setuptools the environment has, and setuptools before 74.1 stops on a
schema error that does not say what to do (``tool.setuptools must not contain {'ext-modules'} properties``); this
module stops first, with a message that does.
"""

from __future__ import annotations

import re
import sys

import setuptools

REQUIRED = (74, 1)  # [[tool.setuptools.ext-modules]] in pyproject.toml


def _version(text: str) -> tuple[int, ...]:
    """The leading numbers of a version string (``74.1.2`` -> (74, 1, 2))."""
    return tuple(int(part) for part in re.findall(r"\d+", text.split("+")[0])[:3])


if _version(setuptools.__version__) < REQUIRED:
    sys.exit(f"error: building fuzzynav needs setuptools>={'.'.join(map(str, REQUIRED))} (pyproject.toml declares its "
             f"optional C kernels as [[tool.setuptools.ext-modules]]), but this environment has setuptools "
             f"{setuptools.__version__}: upgrade it (pip install 'setuptools>=74.1') or install without "
             f"--no-build-isolation")

from setuptools.build_meta import *  # noqa: E402, F403 (the PEP 517 hooks, once the version is known to be good)
from setuptools.build_meta import __all__  # noqa: E402, F401
