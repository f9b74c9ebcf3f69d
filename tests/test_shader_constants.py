"""Constants shared by Python and GLSL (``stb_hydra/renderer/shader_constants.py``):
every shader gets them from the generated ``common/constants.glsl``, the GLSL keeps
no copy of their literals, and the light record's struct matches the Python layout."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from stb_hydra.renderer import shader_constants as sc
from stb_hydra.renderer.gl import (
    CONSTANTS_INCLUDE,
    ShaderLibrary,
    preprocess,
    shader_root,
    shader_source,
)

SHADERS = Path(str(shader_root()))
STAGES = sorted(p.name for p in SHADERS.iterdir() if p.suffix in (".vert", ".frag", ".comp"))
SOURCES = sorted(
    p.relative_to(SHADERS).as_posix()
    for p in SHADERS.rglob("*")
    if p.suffix in (".vert", ".frag", ".comp", ".glsl")
)


def _code(text: str) -> str:
    """GLSL without comments."""
    text = re.sub(r"/\*.*?\*/", " ", text, flags=re.S)
    return re.sub(r"//[^\n]*", "", text)


def test_every_shader_starts_with_the_generated_constants():
    gen = shader_source(CONSTANTS_INCLUDE)
    assert not (SHADERS / CONSTANTS_INCLUDE).exists(), "constants.glsl is generated, not a file"
    for name, value in sc.GLSL_CONSTANTS.items():
        assert f"#define {name} {value}\n" in gen
    for stage in STAGES:
        src = preprocess(stage, {"STB_N": 1})
        assert src.startswith("#version 430 core\n")
        assert src.count("#define STB_CONSTANTS_GLSL") == 1, stage
        assert src.index("#define STB_CONSTANTS_GLSL") < src.index("#line 1")


def test_constants_are_not_redefined_in_glsl():
    for rel in SOURCES:
        code = _code(shader_source(rel))
        for name in sc.GLSL_CONSTANTS:
            assert not re.search(rf"(#define|const\s+\w+)\s+{name}\b", code), (rel, name)


@pytest.mark.parametrize(
    ("pattern", "use"),
    [
        (r"\bbinding\s*=\s*\d", "UBO_*/SSBO_*/TEX_UNIT_*/IMAGE_UNIT_* binding constants"),
        (r"0\.2126|0\.7152|0\.0722", "LUMINANCE_REC709"),
        (r"3\.14159", "PI / CONE_CUTOFF_TEST_RAD"),
    ],
)
def test_glsl_has_no_copies_of_shared_literals(pattern: str, use: str):
    hits = [rel for rel in SOURCES if re.search(pattern, _code(shader_source(rel)))]
    assert not hits, f"{hits}: use {use} (stb_hydra/renderer/shader_constants.py)"


def test_interface_arrays_are_sized_by_generated_constants():
    """Issue 33 item 4: every array the host fills (uniforms, uniform/buffer block
    members, shared memory) is sized by a ``LIM_*`` / generated constant, never a
    literal that the Python side could drift from; local arrays (a quad's 4 pixels, a
    box's 8 corners, a triangle's 3 vertices) are geometry and may stay literal."""
    literal = re.compile(r"\[\s*\d+\s*\]")
    hits = []
    for rel in SOURCES:
        code = _code(shader_source(rel))
        for m in re.finditer(r"^\s*(uniform|shared)\b[^;{]*;", code, re.M):
            if literal.search(m.group(0)):
                hits.append((rel, m.group(0).strip()))
        for m in re.finditer(r"\b(uniform|buffer)\s+\w+\s*\{([^}]*)\}", code):
            hits += [(rel, ln.strip()) for ln in m.group(2).splitlines() if literal.search(ln)]
    assert not hits, f"literal array sizes (use limits.py via shader_constants): {hits}"


def test_light_struct_matches_the_python_layout():
    code = _code(shader_source("common/lights.glsl"))
    body = re.search(r"struct\s+Light\s*\{(.*?)\};", code, flags=re.S).group(1)
    members = re.findall(r"(\w+)\s+(\w+)\s*;", body)
    assert members == [("vec4", m) for m, _ in sc.LIGHT_LAYOUT]
    assert sc.LIGHT_STRIDE_FLOATS == 40 and sc.LIGHT_STRIDE_BYTES == 160  # + area (issue 20)
    # a few columns the Python side addresses by number today
    assert sc.LIGHT_COL_RANGE == 3
    assert sc.LIGHT_COL_FLUX == 15
    assert sc.LIGHT_COL_CUTOFF == 17
    assert sc.LIGHT_COL_SHADOW_MAP == 26
    assert sc.LIGHT_COL_SPECULAR == 35
    assert sc.LIGHT_COL_AREA_KIND == 38
    assert sorted(sc.LIGHT_COLUMNS.values()) == sorted(set(sc.LIGHT_COLUMNS.values()))


def test_codes_agree_with_their_python_owners():
    from stb_hydra import limits
    from stb_hydra.scene import prims

    assert float(sc.GLSL_CONSTANTS["EMIT_COSINE"]) == prims.EMIT_COSINE
    assert float(sc.GLSL_CONSTANTS["EMIT_CYLINDER"]) == prims.EMIT_CYLINDER
    # a light without a cone fails the GLSL cone test once stored as float32
    assert np.float32(prims.NO_CONE_CUTOFF_RAD) >= np.float32(
        float(sc.GLSL_CONSTANTS["CONE_CUTOFF_TEST_RAD"])
    )
    assert sc.INTERLEAVE_FOOTPRINT_PX == 2 * limits.SMALL_TILE_PX
    assert int(sc.GLSL_CONSTANTS["LIM_BIG_TILE_SLOTS_MAX"]) == max(limits.BIG_TILE_SLOTS_ALLOWED)


#: Every optional feature on: each #ifdef path that uses a constant gets compiled.
ALL_FEATURES = {
    "HAS_SUN": True,
    "HAS_SUN_SHADOW": True,
    "HAS_AMBIENT": True,
    "HAS_IES": True,
    "HAS_CONES": True,
    "HAS_SHADOWS": True,
    "STOCHASTIC_PCF": True,
    "LOCAL_LIGHTS": True,
    # the exact methods' loops by light model (lighting/base.light_loops never compiles
    # the wide-sphere loop beside the general one; tests/test_baselines compiles it)
    "LOOP_POINT": True,
    "LOOP_SPHERE_NARROW": True,
    "LOOP_GENERAL": True,
    "STB_N": 4,
    "STB_K": 64,
    "STB_PIXEL_TERMS": True,
    "CULL_GROUP_SIZE": 64,
    "CELL_POS_RANGE": True,  # tiled / clustered lists with each entry's pos_range
}
_VERTEX_OF = {
    "gbuffer.frag": "gbuffer.vert",
    "depth_only.frag": "depth_only.vert",
    "bake_raster.frag": "bake_raster.vert",
    "bake_apply.frag": "bake_apply.vert",
}


@pytest.mark.gl
def test_every_shader_compiles_with_every_feature(gl_ctx):
    lib = ShaderLibrary(gl_ctx)
    for stage in STAGES:
        if stage.endswith(".comp"):
            lib.compute(stage, ALL_FEATURES)
        elif stage.endswith(".frag"):
            lib.program(_VERTEX_OF.get(stage, "fullscreen.vert"), stage, ALL_FEATURES)


def test_program_cache_keys_on_the_generated_source(gl_ctx):
    """Issue 33 item 4: requests that generate the same GLSL share one compile
    (``True`` and ``1`` both write ``#define X 1``; ``False`` writes nothing), and a
    request whose text differs is a new program."""
    lib = ShaderLibrary(gl_ctx)
    a = lib.program("fullscreen.vert", "depth_only.frag", {"STB_CACHE_PROBE": True})
    b = lib.program("fullscreen.vert", "depth_only.frag", {"STB_CACHE_PROBE": 1})
    assert a is b and lib.compiled == 1
    c = lib.program("fullscreen.vert", "depth_only.frag", {"STB_CACHE_PROBE": False})
    d = lib.program("fullscreen.vert", "depth_only.frag")
    assert c is d and c is not a and lib.compiled == 2
