"""Developer tools of the source checkout: prefab / IES writers, benchmarks (not CLI verbs).

The scene generators live in the package (:mod:`stb_hydra.scenegen`); the
``gen_*.py`` scripts here are thin command-line wrappers around them. Importable as a
package so tests can call the checkout-only writers in-process, e.g.
``from tools import gen_prefab_library``.
"""
