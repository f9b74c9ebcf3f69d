"""GLSL sources of stb_hydra: ``<task>.{vert,frag,comp}`` and ``common/*.glsl`` includes.

This directory is the top-level ``shaders/`` of the checkout; it ships as the package
``stb_hydra.shaders`` (``package-dir`` in pyproject.toml), so wheels and editable
installs alike find it with ``importlib.resources``. Loaded by
``stb_hydra.renderer.gl``.
"""
