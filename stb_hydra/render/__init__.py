"""Render side: render index, GL delegate, engine, tasks, lighting methods.

``stb_hydra.render`` is both this package and the flat API function
``stb_hydra.render(stage, ...)`` (see ``stb_hydra.api``): importing a submodule
binds the package over the function's name, so the package itself is callable
and forwards to ``stb_hydra.api.render``.
"""

from __future__ import annotations

import sys
import types


class _CallableModule(types.ModuleType):
    def __call__(self, *args, **kwargs):
        from ..api import render

        return render(*args, **kwargs)


sys.modules[__name__].__class__ = _CallableModule
