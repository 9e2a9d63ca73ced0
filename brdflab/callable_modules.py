"""Modules that are also the public function of the same name.

``brdflab.render``, ``brdflab.validate`` and ``brdflab.report`` are modules *and* the API functions
``bl.render``, ``bl.validate`` and ``bl.report``: Python sets a package attribute when a submodule is first
imported, so ``brdflab.validate`` may hold either. :func:`make_callable` gives such a module a class whose
``__call__`` forwards to the function (module ``__class__`` assignment, Python ≥ 3.5), imported on the first
call so that no import cycle arises.
"""

from __future__ import annotations

import importlib
import sys
import types


def make_callable(module: str, target: str) -> None:
    """Let the module named ``module`` be called as ``target`` (``"package.module:function"``)."""
    mod_name, _, func = target.partition(":")

    class _Callable(types.ModuleType):
        def __call__(self, *args, **kwargs):
            return getattr(importlib.import_module(mod_name), func)(*args, **kwargs)

    _Callable.__call__.__doc__ = f"Call :func:`{mod_name}.{func}`."
    sys.modules[module].__class__ = _Callable
