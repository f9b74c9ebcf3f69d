"""MaterialX looks -> MaterialPrim (issue 30, deliverable 3): stb_hydra.scene.materialx
and the StageSceneIndex's synthesised materials.

Every expectation is computed from the values written in this file's own small
``.mtlx`` / ``.usda`` fixtures, or from the OpenChessSet's files read independently with
plain XML parsing; nothing is mocked.
"""

from __future__ import annotations

import json
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
from pxr import Usd

from stb_hydra.apps import cli
from stb_hydra.scene import prims
from stb_hydra.scene.materialx import (
    MtlxDocumentCache,
    load_document,
    material_prim_paths,
    mtlx_references,
)
from stb_hydra.scene.stage_scene_index import StageSceneIndex
from stb_hydra.scene.usd_diagnostics import UsdDiagnostics

HEADER = '<?xml version="1.0"?>\n<materialx version="1.39"{attrs}>\n'


def write_mtlx(path: Path, body: str, attrs: str = "") -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(HEADER.format(attrs=attrs) + body + "</materialx>\n")
    return path


def material(path: Path, name: str) -> prims.MaterialPrim:
    doc = load_document(str(path))
    assert doc.error == "", doc.error
    return doc.material(name, f"/Test/{name}")


def shader_material(name: str, inputs: str, shader: str = "standard_surface") -> str:
    return (
        f'  <{shader} name="SR_{name}" type="surfaceshader">\n{inputs}  </{shader}>\n'
        f'  <surfacematerial name="{name}" type="material">\n'
        f'    <input name="surfaceshader" type="surfaceshader" nodename="SR_{name}" />\n'
        "  </surfacematerial>\n"
    )


def inp(name: str, typ: str, value: str = "", **attrs: str) -> str:
    a = "".join(f' {k}="{v}"' for k, v in attrs.items())
    val = f' value="{value}"' if value else ""
    return f'    <input name="{name}" type="{typ}"{val}{a} />\n'


def touch(path: Path) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(b"not really an image")
    return path


def f0(ior: float) -> float:
    return ((ior - 1.0) / (ior + 1.0)) ** 2


# --- 1. standard_surface constants --------------------------------------------------------

BASE, BASE_COLOR = 0.5, (0.8, 0.4, 0.2)
METALNESS, ROUGHNESS, IOR = 0.3, 0.35, 1.8
COAT, COAT_COLOR, COAT_ROUGHNESS = 0.5, (0.6, 0.8, 1.0), 0.25
EMISSION, EMISSION_COLOR = 2.0, (0.5, 0.25, 1.0)
OPACITY = (0.2, 0.5, 0.8)


def _v(t: tuple[float, ...]) -> str:
    return ", ".join(str(x) for x in t)


@pytest.fixture
def constants_mtlx(tmp_path: Path) -> Path:
    full = "".join(
        [
            inp("base", "float", str(BASE)),
            inp("base_color", "color3", _v(BASE_COLOR)),
            inp("metalness", "float", str(METALNESS)),
            inp("specular_roughness", "float", str(ROUGHNESS)),
            inp("specular_IOR", "float", str(IOR)),
            inp("coat", "float", str(COAT)),
            inp("coat_color", "color3", _v(COAT_COLOR)),
            inp("coat_roughness", "float", str(COAT_ROUGHNESS)),
            inp("emission", "float", str(EMISSION)),
            inp("emission_color", "color3", _v(EMISSION_COLOR)),
            inp("opacity", "color3", _v(OPACITY)),
        ]
    )
    half_spec = inp("specular", "float", "0.5") + inp("specular_color", "color3", "1, 0.5, 0")
    lobes = "".join(
        [
            inp("base_color", "color3", "0.6, 0.6, 0.6"),
            inp("subsurface", "float", "0.25"),
            inp("subsurface_color", "color3", "0, 1, 0"),
            inp("subsurface_scale", "float", "0.01"),
            inp("transmission", "float", "1"),
            inp("sheen", "float", "0.5"),
            inp("thin_film_thickness", "float", "500"),
            inp("transmission_depth", "float", "0"),  # the default: no effect, no note
        ]
    )
    body = (
        shader_material("Full", full)
        + shader_material("HalfSpecular", half_spec)
        + shader_material("Lobes", lobes)
        + shader_material("Empty", "")
    )
    return write_mtlx(tmp_path / "c.mtlx", body)


def test_standard_surface_constants_follow_the_materialx_translation(constants_mtlx):
    mp = material(constants_mtlx, "Full")
    assert mp.source == "MaterialX" and not mp.uses_defaults
    assert mp.warnings == [] and mp.notes == [] and mp.textures == {}
    # coatAttenuation = mix(1, coat_color, coat); diffuse = base * base_color * it.
    att = [1.0 + (c - 1.0) * COAT for c in COAT_COLOR]
    np.testing.assert_allclose(mp.diffuse_color, [BASE * c * a for c, a in zip(BASE_COLOR, att)])
    assert mp.metallic == pytest.approx(METALNESS)
    assert mp.roughness == pytest.approx(ROUGHNESS)
    assert not mp.use_specular_workflow and mp.ior == pytest.approx(IOR)
    assert mp.clearcoat == pytest.approx(COAT * sum(COAT_COLOR) / 3)
    assert mp.clearcoat_roughness == pytest.approx(COAT_ROUGHNESS)
    np.testing.assert_allclose(
        mp.emissive_color, [EMISSION * c * a for c, a in zip(EMISSION_COLOR, att)]
    )
    assert mp.opacity == pytest.approx(sum(OPACITY) / 3)


def test_specular_weight_and_colour_fold_into_f0(constants_mtlx):
    mp = material(constants_mtlx, "HalfSpecular")
    # F0 = specular * mean(specular_color) * F0(1.5): 0.5 * 0.5 * 0.04.
    assert f0(mp.ior) == pytest.approx(0.5 * 0.5 * f0(1.5))
    assert any("specular_color" in n for n in mp.notes)  # the tint is lost: a note
    assert mp.warnings == []


def test_defaults_come_from_the_standard_library(constants_mtlx):
    mp = material(constants_mtlx, "Empty")
    # standard_surface's nodedef: base 1 * base_color 0.8, metalness 0, roughness 0.2, IOR 1.5.
    np.testing.assert_allclose(mp.diffuse_color, [0.8] * 3, rtol=1e-6)
    assert (mp.metallic, mp.ior, mp.clearcoat, mp.opacity) == (0.0, 1.5, 0.0, 1.0)
    assert mp.roughness == pytest.approx(0.2)
    assert mp.warnings == [] and mp.notes == []


def test_unmodelled_lobes_are_notes_not_warnings(constants_mtlx):
    mp = material(constants_mtlx, "Lobes")
    assert mp.warnings == []
    noted = sorted(n.split("input '")[1].split("'")[0] for n in mp.notes if "input '" in n)
    assert noted == [
        "sheen",
        "subsurface",
        "subsurface_color",
        "subsurface_scale",
        "thin_film_thickness",
        "transmission",
    ]
    assert all("'Lobes'" in n and "c.mtlx" in n for n in mp.notes)
    # The translation blends subsurface_color into the diffuse colour by subsurface.
    np.testing.assert_allclose(mp.diffuse_color, [0.6 * 0.75, 0.6 * 0.75 + 0.25, 0.6 * 0.75])


# --- 2. node graphs -----------------------------------------------------------------------

GRAPH = """
  <nodegraph name="NG" fileprefix="tex/" colorspace="srgb_texture">
    <texcoord name="uv1" type="vector2">
      <input name="index" type="integer" value="1" />
    </texcoord>
    <geompropvalue name="uvB" type="vector2">
      <input name="geomprop" type="string" value="uvB" />
    </geompropvalue>
    <image name="albedo" type="color3">
      <input name="file" type="filename" value="albedo.png" />
      <input name="default" type="color3" value="0.1, 0.2, 0.3" />
      <input name="uaddressmode" type="string" value="clamp" />
      <input name="vaddressmode" type="string" value="mirror" />
    </image>
    <multiply name="tint" type="color3">
      <input name="in1" type="color3" nodename="albedo" />
      <input name="in2" type="color3" value="0.5, 0.25, 1" />
    </multiply>
    <image name="rough" type="float">
      <input name="file" type="filename" value="rough.png" colorspace="srgb_texture" />
      <input name="texcoord" type="vector2" nodename="uv1" />
      <input name="uaddressmode" type="string" value="constant" />
    </image>
    <multiply name="rough_half" type="float">
      <input name="in1" type="float" nodename="rough" />
      <input name="in2" type="float" value="0.5" />
    </multiply>
    <add name="rough_biased" type="float">
      <input name="in1" type="float" nodename="rough_half" />
      <input name="in2" type="float" value="0.2" />
    </add>
    <tiledimage name="metal" type="float">
      <input name="file" type="filename" value="metal.png" />
      <input name="texcoord" type="vector2" nodename="uvB" />
      <input name="uvtiling" type="vector2" value="2, 3" />
      <input name="uvoffset" type="vector2" value="0.25, 0.5" />
    </tiledimage>
    <image name="packed" type="color3">
      <input name="file" type="filename" value="packed.png" colorspace="lin_rec709" />
    </image>
    <extract name="packed_g" type="float">
      <input name="in" type="color3" nodename="packed" />
      <input name="index" type="integer" value="1" />
    </extract>
    <separate3 name="split" type="multioutput">
      <input name="in" type="color3" nodename="packed" />
    </separate3>
    <mix name="coat_mix" type="float">
      <input name="fg" type="float" value="0.8" />
      <input name="bg" type="float" value="0.4" />
      <input name="mix" type="float" value="0.25" />
    </mix>
    <constant name="coat_roughness_const" type="float">
      <input name="value" type="float" value="0.3" />
    </constant>
    <image name="nrm" type="vector3">
      <input name="file" type="filename" value="normal.png" />
    </image>
    <normalmap name="nmap" type="vector3">
      <input name="in" type="vector3" nodename="nrm" />
      <input name="scale" type="float" value="0.5" />
    </normalmap>
    <output name="base_color_out" type="color3" nodename="tint" />
    <output name="rough_out" type="float" nodename="rough_biased" />
    <output name="metal_out" type="float" nodename="metal" />
    <output name="g_out" type="float" nodename="packed_g" />
    <output name="b_out" type="float" nodename="split" output="outb" />
    <output name="coat_out" type="float" nodename="coat_mix" />
    <output name="coatr_out" type="float" nodename="coat_roughness_const" />
    <output name="normal_out" type="vector3" nodename="nmap" />
  </nodegraph>
  <image name="emit" type="color3">
    <input name="file" type="filename" value="emit.<UDIM>.png" />
  </image>
  <image name="missing" type="float">
    <input name="file" type="filename" value="nope.png" />
  </image>
"""


def ng(out: str) -> dict[str, str]:
    return {"nodegraph": "NG", "output": out}


@pytest.fixture
def graph_mtlx(tmp_path: Path) -> Path:
    for f in ("albedo.png", "rough.png", "metal.png", "packed.png", "normal.png"):
        touch(tmp_path / "looks" / "tex" / f)
    touch(tmp_path / "looks" / "emit.1001.png")
    inputs = "".join(
        [
            inp("base_color", "color3", **ng("base_color_out")),
            inp("specular_roughness", "float", **ng("rough_out")),
            inp("metalness", "float", **ng("metal_out")),
            inp("coat", "float", **ng("coat_out")),
            inp("coat_roughness", "float", **ng("coatr_out")),
            inp("normal", "vector3", **ng("normal_out")),
            inp("emission", "float", "1"),
            inp("emission_color", "color3", nodename="emit"),
        ]
    )
    picks = inp("metalness", "float", **ng("g_out")) + inp(
        "specular_roughness", "float", **ng("b_out")
    )
    missing = inp("specular_roughness", "float", nodename="missing")
    body = (
        GRAPH
        + shader_material("Graph", inputs)
        + shader_material("Picks", picks)
        + shader_material("Missing", missing)
    )
    return write_mtlx(tmp_path / "looks" / "g.mtlx", body, ' colorspace="acescg"')


def test_image_multiply_and_add_fold_into_scale_and_bias(graph_mtlx):
    mp = material(graph_mtlx, "Graph")
    assert mp.warnings == [], mp.warnings
    d = mp.textures["diffuseColor"]
    tex = graph_mtlx.parent / "tex"
    assert d.file == str(tex / "albedo.png") and d.asset == "albedo.png"  # fileprefix
    assert d.channels == "rgb"
    # base_color = albedo * (0.5, 0.25, 1), then the coat attenuation mix(1, white, c) = 1.
    np.testing.assert_allclose(d.scale, (0.5, 0.25, 1.0, 1.0))
    np.testing.assert_allclose(d.bias, (0.0, 0.0, 0.0, 0.0))
    np.testing.assert_allclose(d.fallback, (0.1 * 0.5, 0.2 * 0.25, 0.3, 1.0))  # default
    assert (d.wrap_s, d.wrap_t) == ("clamp", "mirror")
    assert d.owner == "g.mtlx:NG/albedo"
    r = mp.textures["roughness"]
    assert r.channels == "r" and r.st == "st1"  # texcoord index 1
    assert r.scale == (0.5,) * 4 and r.bias == pytest.approx((0.2,) * 4)
    assert r.wrap_s == "black" and r.wrap_t == "repeat"  # constant, periodic (default)
    assert mp.clearcoat == pytest.approx(0.8 * 0.25 + 0.4 * 0.75)  # mix of constants
    assert mp.clearcoat_roughness == pytest.approx(0.3)  # a constant node
    assert "clearcoat" not in mp.textures


def test_tiledimage_uvtiling_and_uvoffset_become_the_st_transform(graph_mtlx):
    m = material(graph_mtlx, "Graph").textures["metallic"]
    assert m.st == "uvB"  # geompropvalue
    # tiledimage: st * uvtiling - uvoffset (real-world sizes 1), periodic.
    assert m.st_transform == pytest.approx((2.0, 0.0, -0.25, 0.0, 3.0, -0.5))
    assert (m.wrap_s, m.wrap_t) == ("repeat", "repeat")


def test_normalmap_scale_and_bias(graph_mtlx):
    n = material(graph_mtlx, "Graph").textures["normal"]
    assert n.file.endswith("normal.png") and n.channels == "rgb"
    s = 0.5  # the normalmap's scale, on x and y only
    assert n.scale == pytest.approx((2 * s, 2 * s, 2.0, 1.0))
    assert n.bias == pytest.approx((-s, -s, -1.0, 0.0))
    assert n.fallback == pytest.approx((0.0, 0.0, 1.0, 1.0))  # a missing map is flat


def test_colour_space_inheritance(graph_mtlx):
    mp = material(graph_mtlx, "Graph")
    assert mp.textures["diffuseColor"].source_color_space == "srgb_texture"  # the graph's
    assert mp.textures["emissiveColor"].source_color_space == "acescg"  # the document's
    # Float and vector images are data (MaterialX colour-manages colour images only),
    # even with a colorspace authored on the file.
    assert mp.textures["roughness"].source_color_space == "raw"
    assert mp.textures["normal"].source_color_space == "raw"
    picks = material(graph_mtlx, "Picks")
    # A channel of a colour image: the image is colour-managed (the file's own colorspace).
    assert {t.source_color_space for t in picks.textures.values()} == {"lin_rec709"}


def test_udim_token_is_kept_and_channel_picks(graph_mtlx):
    e = material(graph_mtlx, "Graph").textures["emissiveColor"]
    assert e.file == str(graph_mtlx.parent / "emit.<UDIM>.png")  # resolves: tile 1001 exists
    picks = material(graph_mtlx, "Picks")
    assert picks.textures["metallic"].channels == "g"  # extract index 1
    assert picks.textures["roughness"].channels == "b"  # separate3 outb
    assert picks.textures["metallic"].file.endswith("packed.png")
    assert picks.warnings == []


def test_missing_texture_file_warns_and_keeps_the_lookup(graph_mtlx):
    mp = material(graph_mtlx, "Missing")
    r = mp.textures["roughness"]
    assert r.file == "" and r.asset == "nope.png"
    assert len(mp.warnings) == 1 and "nope.png" in mp.warnings[0] and "'Missing'" in mp.warnings[0]


def test_unreducible_graph_falls_back_to_the_constant_with_one_warning(tmp_path: Path):
    touch(tmp_path / "a.png")
    touch(tmp_path / "b.png")
    body = """
  <noise3d name="grain" type="float">
    <input name="amplitude" type="float" value="1" />
  </noise3d>
  <image name="ia" type="color3"><input name="file" type="filename" value="a.png" /></image>
  <image name="ib" type="color3"><input name="file" type="filename" value="b.png" /></image>
  <mix name="blend" type="color3">
    <input name="fg" type="color3" nodename="ia" />
    <input name="bg" type="color3" nodename="ib" />
    <input name="mix" type="float" nodename="grain" />
  </mix>
""" + shader_material(
        "Noisy",
        inp("base_color", "color3", nodename="blend")
        + inp("specular_roughness", "float", nodename="grain")
        + inp("metalness", "float", "0.7"),
    )
    mp = material(write_mtlx(tmp_path / "n.mtlx", body), "Noisy")
    assert mp.textures == {}
    np.testing.assert_allclose(mp.diffuse_color, [0.8] * 3, rtol=1e-6)  # nodedef default
    assert mp.roughness == pytest.approx(0.2)
    assert mp.metallic == pytest.approx(0.7)  # the rest is read
    assert len(mp.warnings) == 2, mp.warnings  # one per input, each naming the node
    (w_base,) = [w for w in mp.warnings if "'base_color'" in w]
    (w_rough,) = [w for w in mp.warnings if "'specular_roughness'" in w]
    assert "'Noisy'" in w_base and "blend" in w_base and "grain" in w_base
    assert "noise3d" in w_rough and "grain" in w_rough


def test_malformed_graphs_warn_and_never_crash(tmp_path: Path):
    touch(tmp_path / "x.png")
    doc = tmp_path / "f.mtlx"
    doc.write_text("""<?xml version="1.0"?>
<materialx version="1.38">
  <nodegraph name="NG">
    <add name="a" type="float"><input name="in1" type="float" nodename="b" /></add>
    <add name="b" type="float"><input name="in1" type="float" nodename="a" /></add>
    <image name="img" type="color3"><input name="file" type="filename" value="x.png" /></image>
    <output name="cyc" type="float" nodename="a" />
    <output name="col" type="color3" nodename="img" channels="rrr" />
  </nodegraph>
  <standard_surface name="S1" type="surfaceshader">
    <input name="specular_roughness" type="float" nodegraph="NG" output="cyc" />
    <input name="metalness" type="float" nodegraph="NG" output="nothere" />
    <input name="base_color" type="color3" nodegraph="NG" output="col" />
    <input name="coat" type="float" nodename="ghost" />
  </standard_surface>
  <surfacematerial name="M1" type="material">
    <input name="surfaceshader" type="surfaceshader" nodename="S1" />
  </surfacematerial>
  <open_pbr_surface name="O" type="surfaceshader" />
  <surfacematerial name="M2" type="material">
    <input name="surfaceshader" type="surfaceshader" nodename="O" />
  </surfacematerial>
</materialx>
""")
    mp = material(doc, "M1")
    assert not mp.uses_defaults
    # 1.38's channels="rrr" (upgraded to a combine of extracts): one channel, broadcast.
    d = mp.textures["diffuseColor"]
    assert d.channels == "r" and d.file == str(tmp_path / "x.png")
    assert mp.roughness == pytest.approx(0.2) and mp.metallic == 0.0 and mp.clearcoat == 0.0
    assert len(mp.warnings) == 3, mp.warnings
    assert any("cycle" in w and "specular_roughness" in w for w in mp.warnings)
    assert any("ghost" in w for w in mp.warnings) and any("nothere" in w for w in mp.warnings)
    other = material(doc, "M2")
    assert other.uses_defaults and len(other.warnings) == 1
    assert "open_pbr_surface" in other.warnings[0]


def test_usd_preview_surface_node_maps_one_to_one(tmp_path: Path):
    body = shader_material(
        "Preview",
        inp("diffuseColor", "color3", "0.1, 0.2, 0.3")
        + inp("roughness", "float", "0.6")
        + inp("metallic", "float", "0.4")
        + inp("useSpecularWorkflow", "integer", "1")
        + inp("specularColor", "color3", "0.5, 0.5, 0.25")
        + inp("opacityThreshold", "float", "0.5")
        + inp("ior", "float", "1.33"),
        shader="UsdPreviewSurface",
    )
    mp = material(write_mtlx(tmp_path / "p.mtlx", body), "Preview")
    np.testing.assert_allclose(mp.diffuse_color, (0.1, 0.2, 0.3))
    np.testing.assert_allclose(mp.specular_color, (0.5, 0.5, 0.25))
    assert (mp.roughness, mp.metallic) == pytest.approx((0.6, 0.4))
    assert mp.use_specular_workflow and mp.opacity_threshold == pytest.approx(0.5)
    assert mp.ior == pytest.approx(1.33) and mp.warnings == []


def test_unparsable_document_is_an_error_not_a_crash(tmp_path: Path):
    bad = tmp_path / "bad.mtlx"
    bad.write_text("<materialx version='1.39'><standard_surface name=")
    doc = load_document(str(bad))
    assert doc.error and doc.materials == []
    cache = MtlxDocumentCache()
    assert cache.get(str(tmp_path / "absent.mtlx")).error


# --- 3. the stage -------------------------------------------------------------------------

MESH = """
    def Mesh "{name}" (prepend apiSchemas = ["MaterialBindingAPI"])
    {{
        int[] faceVertexCounts = [3]
        int[] faceVertexIndices = [0, 1, 2]
        point3f[] points = [(0, 0, 0), (1, 0, 0), (0, 1, 0)]
        rel material:binding = <{binding}>
    }}
"""


def usda(path: Path, body: str, default_prim: str = "World", meta: str = "") -> Path:
    path.write_text(f'#usda 1.0\n(\n    defaultPrim = "{default_prim}"\n{meta})\n{body}')
    return path


def two_materials(path: Path) -> Path:
    body = shader_material("M_Red", inp("base_color", "color3", "1, 0, 0")) + shader_material(
        "M_Blue", inp("base_color", "color3", "0, 0, 1")
    )
    return write_mtlx(path, body)


def scene_materials(si: StageSceneIndex) -> dict[str, prims.MaterialPrim]:
    return {
        p: si.get_prim(p).data_source.material()
        for p in si.prim_paths()
        if si.get_prim(p).prim_type == prims.MATERIAL
    }


def mesh_materials(si: StageSceneIndex) -> dict[str, str | None]:
    return {
        p: si.get_prim(p).data_source.material()
        for p in si.prim_paths()
        if si.get_prim(p).prim_type == prims.MESH
    }


def test_reference_targets_compose_at_usdmtlx_paths(tmp_path: Path):
    two_materials(tmp_path / "looks" / "m.mtlx")
    body = (
        'def Xform "World"\n{\n'
        '    def Scope "A" (prepend references = @./looks/m.mtlx@</MaterialX/Materials>) {}\n'
        '    def Scope "B" (references = @./looks/m.mtlx@</MaterialX>) {}\n'
        '    def Scope "C" (append references = @./looks/m.mtlx@) {}\n'
        '    def Material "D" (references = @./looks/m.mtlx@</MaterialX/Materials/M_Blue>) {}\n'
        + MESH.format(name="a", binding="/World/A/M_Red")
        + MESH.format(name="b", binding="/World/B/Materials/M_Blue")
        + MESH.format(name="d", binding="/World/D")
        + "}\n"
    )
    stage = Usd.Stage.Open(str(usda(tmp_path / "s.usda", body)))
    si = StageSceneIndex(stage)
    mats = scene_materials(si)
    assert set(mats) == {
        "/World/A/M_Red",
        "/World/A/M_Blue",
        "/World/B/Materials/M_Red",
        "/World/B/Materials/M_Blue",
        "/World/C/Materials/M_Red",
        "/World/C/Materials/M_Blue",
        "/World/D",
    }
    assert all(m.source == "MaterialX" and not m.warnings for m in mats.values())
    np.testing.assert_allclose(mats["/World/A/M_Red"].diffuse_color, (1, 0, 0))
    np.testing.assert_allclose(mats["/World/D"].diffuse_color, (0, 0, 1))
    assert mesh_materials(si) == {
        "/World/a": "/World/A/M_Red",
        "/World/b": "/World/B/Materials/M_Blue",
        "/World/d": "/World/D",
    }
    assert si.warnings == []
    # The reference list as authored: prepend / explicit / append, the layer's path.
    refs = mtlx_references(stage.GetPrimAtPath("/World/C"))
    assert [(r.asset, r.target) for r in refs] == [("./looks/m.mtlx", "")]
    assert refs[0].resolved == str(tmp_path / "looks" / "m.mtlx")
    assert material_prim_paths("/P", "/MaterialX/Shaders", ["M"]) is None


def test_binding_strength_is_honoured(tmp_path: Path):
    two_materials(tmp_path / "m.mtlx")
    body = (
        """def Xform "World"
{
    def Scope "Looks" (prepend references = @./m.mtlx@</MaterialX/Materials>) {}
    def Xform "G" (prepend apiSchemas = ["MaterialBindingAPI"])
    {
        rel material:binding = </World/Looks/M_Blue> (bindMaterialAs = "strongerThanDescendants")
"""
        + MESH.format(name="m", binding="/World/Looks/M_Red").replace("\n    ", "\n        ")
        + """
    }
    def Xform "H" (prepend apiSchemas = ["MaterialBindingAPI"])
    {
        rel material:binding = </World/Looks/M_Blue>
"""
        + MESH.format(name="n", binding="/World/Looks/M_Red").replace("\n    ", "\n        ")
        + """
    }
}
"""
    )
    si = StageSceneIndex(Usd.Stage.Open(str(usda(tmp_path / "s.usda", body))))
    assert mesh_materials(si) == {
        "/World/G/m": "/World/Looks/M_Blue",
        "/World/H/n": "/World/Looks/M_Red",
    }


def _asset_with_look(tmp_path: Path) -> Path:
    """An asset (as the chess pieces are): a Materials scope referencing a .mtlx in a
    sublayer, meshes bound in a shading variant."""
    two_materials(tmp_path / "asset" / "asset_mat.mtlx")
    usda(
        tmp_path / "asset" / "asset_look.usda",
        """over "Asset" (
    variants = { string shadingVariant = "Red" }
    add variantSets = "shadingVariant"
)
{
    def Scope "Materials" (prepend references = @./asset_mat.mtlx@</MaterialX/Materials>) {}
    variantSet "shadingVariant" = {
        "Red" {
            over "Geom" (apiSchemas = ["MaterialBindingAPI"])
            {
                rel material:binding = </Asset/Materials/M_Red>
            }
        }
        "Blue" {
            over "Geom" (apiSchemas = ["MaterialBindingAPI"])
            {
                rel material:binding = </Asset/Materials/M_Blue>
            }
        }
    }
}
""",
        "Asset",
    )
    geom = MESH.format(name="Geom", binding="/Nothing").replace(
        "        rel material:binding = </Nothing>\n", ""
    )
    usda(tmp_path / "asset" / "asset_geom.usda", f'over "Asset"\n{{{geom}}}\n', "Asset")
    return usda(
        tmp_path / "asset" / "asset.usda",
        'def Xform "Asset" {}\n',
        "Asset",
        "    subLayers = [@./asset_look.usda@, @./asset_geom.usda@]\n",
    )


def test_instance_proxies_and_point_instancer_prototypes(tmp_path: Path):
    _asset_with_look(tmp_path)
    body = """def Xform "World"
{
    def Xform "I1" (instanceable = true
        references = @./asset/asset.usda@
        variants = { string shadingVariant = "Blue" }) {}
    def Xform "I2" (instanceable = true
        references = @./asset/asset.usda@) {}
    def PointInstancer "PI"
    {
        point3f[] positions = [(0, 0, 0), (1, 0, 0)]
        int[] protoIndices = [0, 0]
        rel prototypes = </World/PI/Proto>
        def Xform "Proto" (references = @./asset/asset.usda@
            variants = { string shadingVariant = "Blue" }) {}
    }
}
"""
    stage = Usd.Stage.Open(str(usda(tmp_path / "s.usda", body)))
    assert stage.GetPrimAtPath("/World/I1/Materials").IsInstanceProxy()
    si = StageSceneIndex(stage)
    mats = scene_materials(si)
    for root in ("/World/I1", "/World/I2", "/World/PI/Proto"):
        assert {f"{root}/Materials/M_Red", f"{root}/Materials/M_Blue"} <= set(mats)
    assert mesh_materials(si) == {
        "/World/I1/Geom": "/World/I1/Materials/M_Blue",
        "/World/I2/Geom": "/World/I2/Materials/M_Red",
        "/World/PI/Proto/Geom": "/World/PI/Proto/Materials/M_Blue",
    }
    assert si.warnings == []


def test_variant_switch_and_resyncs_rebind(tmp_path: Path):
    _asset_with_look(tmp_path)
    body = """def Xform "World"
{
    def Xform "Piece" (references = @./asset/asset.usda@) {}
}
"""
    stage = Usd.Stage.Open(str(usda(tmp_path / "s.usda", body)))
    si = StageSceneIndex(stage)
    assert mesh_materials(si) == {"/World/Piece/Geom": "/World/Piece/Materials/M_Red"}
    # A variant switch (a resync of the referencing prim) re-derives and re-binds.
    stage.GetPrimAtPath("/World/Piece").GetVariantSet("shadingVariant").SetVariantSelection("Blue")
    si.apply_pending_updates()
    assert mesh_materials(si) == {"/World/Piece/Geom": "/World/Piece/Materials/M_Blue"}
    mats = scene_materials(si)
    np.testing.assert_allclose(mats["/World/Piece/Materials/M_Blue"].diffuse_color, (0, 0, 1))
    # A resync below the referencing prim (a new over on a synthesised material) keeps it.
    stage.OverridePrim("/World/Piece/Materials/M_Red")
    si.apply_pending_updates()
    assert "/World/Piece/Materials/M_Red" in scene_materials(si)
    # Removing the reference removes its materials.
    stage.GetPrimAtPath("/World/Piece").GetReferences().ClearReferences()
    si.apply_pending_updates()
    assert not any(p.startswith("/World/Piece") for p in si.prim_paths())


def test_missing_and_unparsable_mtlx_warn_once_and_the_rest_renders(tmp_path: Path, capfd):
    two_materials(tmp_path / "ok.mtlx")
    (tmp_path / "bad.mtlx").write_text("<materialx><standard_surface name='x'")
    body = (
        'def Xform "World"\n{\n'
        '    def Scope "Ok" (references = @./ok.mtlx@</MaterialX/Materials>) {}\n'
        '    def Scope "Gone" (references = @./gone.mtlx@</MaterialX/Materials>) {}\n'
        '    def Scope "Bad" (references = @./bad.mtlx@</MaterialX/Materials>) {}\n'
        + MESH.format(name="a", binding="/World/Ok/M_Red")
        + MESH.format(name="b", binding="/World/Gone/M_X")
        + "}\n"
    )
    scene = usda(tmp_path / "s.usda", body)
    with UsdDiagnostics() as diag:
        stage = Usd.Stage.Open(str(scene))
        usd = diag.drain()
    assert [d.text for d in usd if ".mtlx" in d.text] == []  # USD's arcs errors: dropped
    si = StageSceneIndex(stage)
    assert set(scene_materials(si)) == {"/World/Ok/M_Red", "/World/Ok/M_Blue"}
    assert set(mesh_materials(si)) == {"/World/a", "/World/b"}
    assert len(si.warnings) == 2, si.warnings
    (gone,) = [w for w in si.warnings if "gone.mtlx" in w]
    (bad,) = [w for w in si.warnings if "bad.mtlx" in w]
    assert "</World/Gone>" in gone and "not found" in gone
    assert "</World/Bad>" in bad and "could not be read" in bad
    code = cli.main(["inspect", str(scene), "--json"])
    out, err = capfd.readouterr()
    assert code == 0 and err == ""
    rep = json.loads(out)
    assert sorted(rep["warnings"]) == sorted(si.warnings)  # no "usd: ..." line beside them
    assert rep["prims"] == {"mesh": 2, "material": 2}


def test_standard_surface_authored_in_usd(tmp_path: Path):
    touch(tmp_path / "tex" / "wood.png")
    body = (
        """def Xform "World"
{
    def Material "Wood"
    {
        token outputs:mtlx:surface.connect = </World/Wood/SR.outputs:out>
        def Shader "SR"
        {
            uniform token info:id = "ND_standard_surface_surfaceshader"
            color3f inputs:base_color.connect = </World/Wood/Img.outputs:out>
            float inputs:metalness = 0.25
            float inputs:specular_roughness = 0.6
            float inputs:transmission = 0.5
            token outputs:out
        }
        def Shader "Img"
        {
            uniform token info:id = "ND_image_color3"
            asset inputs:file = @./tex/wood.png@ (colorSpace = "srgb_texture")
            string inputs:uaddressmode = "clamp"
            color3f outputs:out
        }
    }
"""
        + MESH.format(name="m", binding="/World/Wood")
        + "}\n"
    )
    si = StageSceneIndex(Usd.Stage.Open(str(usda(tmp_path / "s.usda", body))))
    mp = scene_materials(si)["/World/Wood"]
    assert mp.source == "MaterialX" and not mp.uses_defaults and mp.warnings == []
    d = mp.textures["diffuseColor"]
    assert d.file == str(tmp_path / "tex" / "wood.png") and d.asset == "./tex/wood.png"
    assert d.source_color_space == "srgb_texture" and d.wrap_s == "clamp" and d.wrap_t == "repeat"
    assert d.owner == "/World/Wood/Img"
    assert (mp.metallic, mp.roughness) == pytest.approx((0.25, 0.6))
    assert len(mp.notes) == 1 and "transmission" in mp.notes[0]
    assert mesh_materials(si) == {"/World/m": "/World/Wood"}


# --- 4. the OpenChessSet ------------------------------------------------------------------

CHESS_INPUTS = {  # standard_surface input -> our input
    "base_color": "diffuseColor",
    "metalness": "metallic",
    "specular_roughness": "roughness",
    "normal": "normal",
}


def _chess_xml(testdata: Path) -> dict[str, dict[str, str]]:
    """material name -> {our input: texture file (absolute)} from the chess .mtlx files,
    traced with plain XML parsing (surfacematerial -> shader -> nodegraph output ->
    node -> (normalmap in ->) image file)."""
    out: dict[str, dict[str, str]] = {}
    for f in sorted((testdata / "scenes" / "OpenChessSet" / "assets").glob("*/*.mtlx")):
        root = ET.parse(f).getroot()
        shaders = {e.get("name"): e for e in root if e.tag == "standard_surface"}
        graphs = {e.get("name"): e for e in root if e.tag == "nodegraph"}
        for m in root.iter("surfacematerial"):
            sh = shaders[m.find("input").get("nodename")]
            files = {}
            for i in sh.findall("input"):
                if i.get("name") not in CHESS_INPUTS or i.get("nodegraph") is None:
                    continue
                g = graphs[i.get("nodegraph")]
                nodes = {e.get("name"): e for e in g if e.tag != "output"}
                (o,) = [e for e in g.findall("output") if e.get("name") == i.get("output")]
                node = nodes[o.get("nodename")]
                if node.tag == "normalmap":
                    node = nodes[node.find("input").get("nodename")]
                assert node.tag == "image"
                files[CHESS_INPUTS[i.get("name")]] = str(f.parent / node.find("input").get("value"))
            out[m.get("name")] = files
    return out


@pytest.fixture(scope="module")
def chess(testdata):
    path = testdata / "scenes" / "OpenChessSet" / "chess_set.usda"
    with UsdDiagnostics():
        stage = Usd.Stage.Open(str(path))
    return path, StageSceneIndex(stage)


def test_chess_set_materials_resolve(testdata, chess):
    expected = _chess_xml(testdata)
    assert len(expected) == 15
    _path, si = chess
    mats = scene_materials(si)
    by_name: dict[str, list[prims.MaterialPrim]] = {}
    for p, mp in mats.items():
        by_name.setdefault(p.rsplit("/", 1)[1], []).append(mp)
    assert set(by_name) == set(expected)
    for name, mps in by_name.items():
        for mp in mps:
            assert mp.source == "MaterialX" and not mp.uses_defaults and mp.warnings == []
            assert {k: t.file for k, t in mp.textures.items()} == expected[name], name
            assert all(Path(t.file).is_file() for t in mp.textures.values())
            d = mp.textures.get("diffuseColor")
            assert d is None or d.source_color_space == "srgb_texture"
    assert si.warnings == []


def test_every_chess_mesh_gets_its_materialx_material(testdata, chess):
    expected = _chess_xml(testdata)
    _path, si = chess
    mats = scene_materials(si)
    meshes = mesh_materials(si)
    assert len(meshes) == 21
    assert any("/Pawns/" in p for p in meshes)  # through the point instancers
    for mesh, mat in meshes.items():
        assert mat in mats, mesh
        mp = mats[mat]
        assert mp.source == "MaterialX"
        assert set(mp.textures) == set(expected[mat.rsplit("/", 1)[1]])
        assert {"roughness", "normal"} <= set(mp.textures)


def test_chess_set_inspect_prints_no_warnings(chess, capfd):
    path, _si = chess
    capfd.readouterr()
    assert cli.main(["inspect", str(path), "--json"]) == 0
    out, err = capfd.readouterr()
    rep = json.loads(out)
    assert err == "" and rep["warnings"] == []
    assert rep["prims"]["mesh"] == 21
    mx = [m for m in rep["materials"] if m["source"] == "MaterialX"]
    assert len({m["path"].rsplit("/", 1)[1] for m in mx}) == 15
    notes = [n for m in mx for n in m["notes"]]
    assert any("M_Queen_W" in n and "subsurface" in n for n in notes)
    assert any("M_Pawn_Top_B" in n and "transmission" in n for n in notes)


class _Recorder:
    """A scene-index observer keeping the notices it receives."""

    def __init__(self) -> None:
        self.added: list[str] = []
        self.removed: list[str] = []

    def prims_added(self, sender, entries) -> None:
        self.added.extend(e.path for e in entries)

    def prims_removed(self, sender, paths) -> None:
        self.removed.extend(paths)

    def prims_dirtied(self, sender, entries) -> None:
        pass


def test_chess_piece_variant_switch_rebinds(testdata):
    path = testdata / "scenes" / "OpenChessSet" / "chess_set.usda"
    with UsdDiagnostics():
        stage = Usd.Stage.Open(str(path))
    si = StageSceneIndex(stage)
    mesh = "/ChessSet/Black/BishopL/Geom/Render"
    assert mesh_materials(si)[mesh] == "/ChessSet/Black/BishopL/Materials/M_Bishop_B"
    rec = _Recorder()
    si.add_observer(rec)
    with UsdDiagnostics():
        vs = stage.GetPrimAtPath("/ChessSet/Black/BishopL").GetVariantSet("shadingVariant")
        vs.SetVariantSelection("White")
        si.apply_pending_updates()
    got = mesh_materials(si)[mesh]
    assert got == "/ChessSet/Black/BishopL/Materials/M_Bishop_W"
    assert mesh in rec.removed and mesh in rec.added  # the piece was resynced
    assert got in rec.added
    assert all(p.startswith("/ChessSet/Black/BishopL") for p in rec.removed + rec.added)
    mp = scene_materials(si)[got]
    assert mp.textures["diffuseColor"].file.endswith("bishop_white_base_color.jpg")
    assert si.warnings == []
