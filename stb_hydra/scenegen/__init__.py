"""Procedural test scenes as deterministic .usda text (``stb bench gen:...``, ``stb tradeoff``).

* :mod:`.lights`: ground, occluders and N mixed UsdLux lights (``build_lights_stage``);
* :mod:`.chess`: the OpenChessSet under N tiny shadowed lights (``build_chess_stage``);
* :mod:`.orbs`: an arena where N light-carrying orbs spawn over time (``build_orbs_stage``);
* :mod:`.common`: the USDA writer, meshes, photometry helpers and input-asset lookup.

Each generator module is also a command: ``python -m stb_hydra.scenegen.lights OUT ...``.
The same arguments give byte-identical text. Input assets: the IES profiles and the
orbs' prefabs ship as package data (``stb_hydra/data``, :func:`.common.ies_dir`); the
chess set comes from an explicit path or the shared test data (:func:`.common.chess_set`).
"""
