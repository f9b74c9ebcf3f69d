"""Developer tools: scene generators, IES profile writer, benchmarks (not CLI verbs).

Importable as a package so tests and benchmarks can call the generators in-process,
e.g. ``from tools.gen_lights_scene import build_lights_stage``.
"""
