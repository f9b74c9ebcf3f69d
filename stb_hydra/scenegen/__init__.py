"""Procedural test scenes as deterministic .usda text (``stb bench gen:...``, ``stb tradeoff``).

* :mod:`.lights`: ground, occluders and N mixed UsdLux lights (``build_lights_stage``);
* :mod:`.chess`: the OpenChessSet under N tiny shadowed lights (``build_chess_stage``);
* :mod:`.orbs`: an arena where N light-carrying orbs spawn over time (``build_orbs_stage``);
* :mod:`.common`: the USDA writer, meshes, photometry helpers and input-asset lookup.

Each generator module is also a command: ``python -m stb_hydra.scenegen.lights OUT ...``.
The same arguments give byte-identical text. Input assets outside the package (IES
profiles, prefabs, the chess set) come from explicit arguments, else from the source
checkout / shared test data (see :func:`.common.ies_dir`, :func:`.common.chess_set`).
"""
