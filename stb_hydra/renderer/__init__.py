"""Render side: render index, GL delegate, engine, passes (tasks), lighting methods.

The flat entry point is :func:`stb_hydra.render` (``stb_hydra.api.render``); this
package holds what it drives.
"""
