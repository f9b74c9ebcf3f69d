"""Plain typed records the scene index hands to render prims.

Coordinate frame of every record: the *render frame* -- right-handed, +Y up,
metres. ``StageSceneIndex`` folds the stage's ``upAxis`` and ``metersPerUnit``
into ``render_from_stage`` (a 4x4) so world transforms below are already in it.
Matrices are row-vector (USD) convention: ``p_world = p_local @ M``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

# Hydra prim type tokens.
MESH = "mesh"
CAMERA = "camera"
MATERIAL = "material"
SPHERE_LIGHT = "sphereLight"
DISK_LIGHT = "diskLight"
RECT_LIGHT = "rectLight"
CYLINDER_LIGHT = "cylinderLight"
DISTANT_LIGHT = "distantLight"
DOME_LIGHT = "domeLight"
MESH_LIGHT = "meshLight"
PORTAL_LIGHT = "portalLight"

LIGHT_TYPES = (
    SPHERE_LIGHT,
    DISK_LIGHT,
    RECT_LIGHT,
    CYLINDER_LIGHT,
    DISTANT_LIGHT,
    DOME_LIGHT,
    MESH_LIGHT,
    PORTAL_LIGHT,
)
#: Lights that live at a point in space (culled, sampled by STB, shadow-mapped).
LOCAL_LIGHT_TYPES = (SPHERE_LIGHT, DISK_LIGHT, RECT_LIGHT, CYLINDER_LIGHT, MESH_LIGHT)

#: Far-field emission models of local lights (see STB_SPEC "Light units").
EMIT_ISOTROPIC = 0  # sphere, mesh: I(w) = I0
EMIT_COSINE = 1  # disk, rect: one-sided, I(w) = I0 * max(0, cos theta)
EMIT_CYLINDER = 2  # cylinder side: I(w) = I0 * sin(angle to the X axis)

#: Cone half-angle (degrees) that cuts nothing: ShapingAPI's widest cone, and the
#: ``cone_angle`` of a light without one (``has_cone`` False).
NO_CONE_ANGLE_DEG = 180.0
#: Cone cut-off (radians from the axis) of a light without a cone: the whole sphere.
NO_CONE_CUTOFF_RAD = math.pi
#: A stored cut-off (radians) below this is a real cone: ``NO_CONE_CUTOFF_RAD`` less a
#: margin that survives float32 storage (the renderer's light table and GLSL ``cone.y``).
CONE_CUTOFF_TEST_RAD = 3.14159

SHADOW_STATIC = "static"
SHADOW_DYNAMIC = "dynamic"
#: ``stb:mobility`` tokens: static lights may be baked into lightmaps (``stb bake``).
MOBILITY_STATIC = "static"
MOBILITY_DYNAMIC = "dynamic"


def identity4() -> np.ndarray:
    return np.eye(4, dtype=np.float64)


def _const(*values: float) -> np.ndarray:
    a = np.array(values, dtype=np.float64)
    a.flags.writeable = False
    return a


# Shared read-only defaults: records are built by the thousand, and every field
# that matters is assigned a fresh array by its reader (never mutated in place).
_ZERO3 = _const(0.0, 0.0, 0.0)
_DOWN3 = _const(0.0, -1.0, 0.0)
_X3 = _const(1.0, 0.0, 0.0)
_EYE4 = np.eye(4)
_EYE4.flags.writeable = False


@dataclass(eq=False)
class DomeMap:
    """A dome texture resampled into the render frame (``scene/dome.py``): an OpenEXR
    lat-long map, Y up, linear Rec.709 radiance factors (the light's
    ``LightPrim.dome_scale`` multiplies them)."""

    #: (h, w, 3) float32, w = 2 h; row 0 is the zenith (+Y), column w/2 faces +Z.
    latlong: np.ndarray
    #: Solid-angle mean RGB of ``latlong`` (the uniform dome of the same power).
    mean: np.ndarray
    #: (9, 3) SH coefficients of E(n) / pi (unshadowed Lambert response, albedo 1).
    sh9: np.ndarray
    #: Resolved file path and the concrete ``texture:format`` it was read as.
    source: str = ""
    format: str = "latlong"
    #: A sun split off the map (``scene.dome.split_sun``; None: none): the map without
    #: it, its SH9, the unit direction to it (render frame) and its illuminance facing
    #: it per map unit (lux RGB). The real-time methods light it as a shadowed sun.
    rest: np.ndarray | None = None
    rest_sh9: np.ndarray | None = None
    sun_direction: np.ndarray | None = None
    sun_illuminance: np.ndarray | None = None


@dataclass
class LightPrim:
    """One UsdLux light in physical units (render frame, metres).

    ``intensity`` meaning depends on ``type``:
      * local lights: luminous intensity in cd (RGB, linear Rec.709) along the
        light's axis (peak of the far-field distribution), every UsdLux scalar
        (intensity, exposure, colour, temperature, normalize, shape area) applied;
      * distantLight: illuminance in lux (RGB) on a surface facing the light;
      * domeLight: radiance in nits (RGB), uniform (a texture's solid-angle mean
        applied; the texture itself is ``dome_map`` x ``dome_scale``).
    """

    path: str
    type: str
    #: Renders: ``valid`` and visible.
    enabled: bool = True
    #: The light's data is usable (False after a bad-input warning).
    valid: bool = True
    position: np.ndarray = field(default_factory=lambda: _ZERO3)
    #: Emission axis (light-local -Z) in the render frame, unit length.
    direction: np.ndarray = field(default_factory=lambda: _DOWN3)
    #: Light-local +X in the render frame, unit (IES phi = 0, cylinder axis).
    tangent: np.ndarray = field(default_factory=lambda: _X3)
    intensity: np.ndarray = field(default_factory=lambda: _ZERO3)
    emission: int = EMIT_ISOTROPIC
    #: Luminous flux estimate (lm) of the luminance channel; sun/dome: 0.
    flux: float = 0.0
    # Shape (metres, world-space scale applied).
    radius: float = 0.0
    width: float = 0.0
    height: float = 0.0
    length: float = 0.0
    #: SphereLight ``treatAsPoint``: lit with the point model (no area integration).
    treat_as_point: bool = False
    # ShapingAPI.
    has_cone: bool = False
    cone_angle: float = NO_CONE_ANGLE_DEG  # degrees, half angle
    cone_softness: float = 0.0
    focus: float = 0.0
    focus_tint: np.ndarray = field(default_factory=lambda: _ZERO3)
    ies_file: str | None = None  # resolved path, None when absent/unresolved
    ies_asset: str | None = None  # authored asset path
    ies_angle_scale: float = 0.0
    ies_normalize: bool = False
    #: Multiplier applied to the normalised baked IES table (cd per table unit),
    #: i.e. candela = intensity * ies_scale * table(theta, phi); 1 without IES.
    ies_scale: float = 1.0
    ies_power: float = 0.0  # profile power (mean cd over its solid angle)
    # LightAPI multipliers.
    diffuse: float = 1.0
    specular: float = 1.0
    # ShadowAPI.
    shadow_enable: bool = True
    shadow_color: np.ndarray = field(default_factory=lambda: _ZERO3)
    shadow_distance: float = -1.0  # metres, <0 = unlimited
    shadow_falloff: float = -1.0  # metres, <=0 = none
    shadow_falloff_gamma: float = 1.0
    # stb:* (StbLightAPI).
    shadow_update: str = SHADOW_STATIC
    #: ``stb:mobility`` (static lights never move: ``stb bake`` may bake them).
    mobility: str = MOBILITY_DYNAMIC
    #: ``stb:baked``: the light's direct light is in the lightmaps (runtime skips it).
    baked: bool = False
    #: Influence radius (m) at camera exposure scale 1: authored ``stb:range``, else
    #: where the peak illuminance falls to ``limits.LIGHT_CUTOFF_LUX``
    #: (:func:`stb_hydra.scene.lights.influence_range`; renderers rescale it with the
    #: camera exposure so the display image does not depend on the unit scale).
    range: float = 0.0
    range_authored: bool = False
    #: Peak luminous intensity (cd, luminance-weighted, IES peak included).
    peak_intensity: float = 0.0
    # DistantLight.
    angle: float = 0.0  # angular diameter, degrees
    # DomeLight (and RectLight ``inputs:texture:file``).
    texture_file: str | None = None
    #: The dome's texture in the render frame (None: uniform dome, ``intensity``).
    dome_map: DomeMap | None = None
    #: RGB radiance (nits) per unit of ``dome_map``: ``intensity = dome_scale *
    #: dome_map.mean``.
    dome_scale: np.ndarray = field(default_factory=lambda: _ZERO3)
    #: A RectLight's usable texture (``scene/rect_texture.py``): resolved path, colour
    #: space; None without one (or when unreadable): the rect emits ``intensity``
    #: uniformly. ``intensity`` carries the texture's mean either way.
    rect_texture: tuple[str, str] | None = None
    #: The camera sees the light (dome background, a textured rect's emitting face;
    #: ``visibleInPrimaryRay``).
    camera_visible: bool = True
    #: Light-linking: False when either collection is not the default "everything".
    default_linking: bool = True
    #: Bit g: the light lights the meshes of light-link group g (``scene/links.py``;
    #: every bit set without light linking).
    light_link_mask: int = 0xFFFFFFFF
    #: Bit g: the meshes of shadow-link group g cast this light's shadow.
    shadow_link_mask: int = 0xFFFFFFFF
    #: One-line human-readable problems found while reading this light.
    warnings: list[str] = field(default_factory=list)
    #: Instance id for lights expanded from a PointInstancer, else -1.
    instance_id: int = -1
    #: World scale factor (mean axis scale of the light's transform, render frame).
    world_scale: float = 1.0
    #: Full world transform of the light (render frame, row-vector convention).
    transform: np.ndarray = field(default_factory=lambda: _EYE4)


@dataclass
class MeshPrim:
    """Triangulated geometry. Points/normals in object space (stage units);
    ``transform`` maps object space to the render frame (metres, Y-up)."""

    path: str
    points: np.ndarray  # (n, 3) float32
    normals: np.ndarray  # (n, 3) float32, unit, per vertex (vertices split as needed)
    indices: np.ndarray  # (m, 3) uint32
    transform: np.ndarray = field(default_factory=identity4)
    #: (k, 4, 4) per-instance transforms (render frame) -- PointInstancer / shared
    #: prototypes. ``None`` = one instance with ``transform``.
    instance_transforms: np.ndarray | None = None
    #: PointInstancer of a prototype mesh, the instance id of each row of
    #: ``instance_transforms`` and the mesh's path below the prototype root's parent
    #: (``scene.instancing.instance_light_path`` names one instance by them).
    instancer: str | None = None
    instance_ids: np.ndarray | None = None
    instance_rel_path: str = ""
    display_color: np.ndarray = field(default_factory=lambda: np.full(3, 0.18))
    #: (n, 3) per-vertex colour when displayColor varies over the mesh, else None.
    vertex_colors: np.ndarray | None = None
    #: (n, 2) texture coordinates (the st primvar the material reads), else None.
    uvs: np.ndarray | None = None
    #: (n, 4) object-space tangent (xyz) and bitangent sign (w), with ``uvs``.
    tangents: np.ndarray | None = None
    #: (n, 4) material primvars (float3 in xyz, float in w), else None.
    attrs: np.ndarray | None = None
    material: str | None = None  # bound material path
    visible: bool = True
    #: Dynamic geometry is drawn into dynamic shadow maps only.
    dynamic: bool = False
    double_sided: bool = False
    #: Key shared by meshes with identical topology/points (instance prototypes).
    geometry_key: str = ""
    #: Light-link and shadow-link groups (``scene/links.py``; 0 without linking).
    link_group: int = 0
    shadow_group: int = 0

    @property
    def num_instances(self) -> int:
        return 1 if self.instance_transforms is None else len(self.instance_transforms)

    def world_transforms(self) -> np.ndarray:
        """(k, 4, 4) object -> render-frame matrices."""
        if self.instance_transforms is None:
            return self.transform[None]
        return self.instance_transforms


#: ``TextureRef.wrap_s``/``wrap_t`` values (UsdUVTexture's tokens; MaterialX
#: ``periodic``/``clamp``/``mirror``/``constant`` map to repeat/clamp/mirror/black).
WRAP_MODES = ("repeat", "mirror", "clamp", "black", "useMetadata")
#: ``TextureRef.channels``: the reader output an input uses.
TEXTURE_CHANNELS = ("rgb", "rgba", "r", "g", "b", "a")
#: Material inputs that may be driven by a texture (UsdPreviewSurface names; MaterialX
#: ``standard_surface`` is translated onto them). ``normal`` holds a tangent-space
#: normal in [-1, 1] (+X along +s, +Y along +t, +Z the geometric normal) after the
#: reader's scale and bias.
TEXTURABLE_INPUTS = (
    "diffuseColor",
    "emissiveColor",
    "specularColor",
    "metallic",
    "roughness",
    "clearcoat",
    "clearcoatRoughness",
    "opacity",
    "normal",
    "occlusion",
)
#: Identity ``TextureRef.st_transform`` (row-major 2x3 affine).
ST_IDENTITY = (1.0, 0.0, 0.0, 0.0, 1.0, 0.0)


@dataclass(frozen=True)
class TextureRef:
    """One texture lookup feeding a material input (a UsdUVTexture, or a MaterialX
    ``image``/``tiledimage``), resolved on the CPU; no GL.

    The value an input receives at texture coordinates ``st`` (the mesh primvar named
    :attr:`st`, after :attr:`st_transform`) is ``texel * scale + bias`` where ``texel``
    is the file's value in scene-linear Rec.709 (colour spaces converted, see
    :attr:`source_color_space`), swizzled by :attr:`channels`; outside [0, 1] the wrap
    modes apply; a file that cannot be read gives :attr:`fallback` (then ``scale`` and
    ``bias`` are not applied, as in UsdUVTexture).
    """

    #: Resolved file path (may hold the ``<UDIM>`` token); "" when it did not resolve.
    file: str
    #: The authored asset path (for messages).
    asset: str = ""
    #: "auto" | "sRGB" | "raw" (UsdUVTexture tokens) or an OCIO colour-space name
    #: (MaterialX ``colorspace``, e.g. "srgb_texture", "lin_rec709").
    source_color_space: str = "auto"
    wrap_s: str = "useMetadata"
    wrap_t: str = "useMetadata"
    #: Which output of the reader the input is connected to (``TEXTURE_CHANNELS``).
    channels: str = "rgb"
    scale: tuple[float, float, float, float] = (1.0, 1.0, 1.0, 1.0)
    bias: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0)
    fallback: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 1.0)
    #: Name of the texture-coordinate primvar (without ``primvars:``).
    st: str = "st"
    #: Row-major 2x3 affine applied to ``st`` before the lookup:
    #: ``(s', t') = (a*s + b*t + c, d*s + e*t + f)`` (UsdTransform2d, MaterialX
    #: ``tiledimage`` uvtiling/uvoffset).
    st_transform: tuple[float, float, float, float, float, float] = ST_IDENTITY
    #: Prim path (or MaterialX node name) of the reader, for messages.
    owner: str = ""


@dataclass(frozen=True)
class PrimvarRef:
    """A material input read from a mesh primvar (``UsdPrimvarReader_*``): the
    primvar's value per vertex, interpolated; :attr:`fallback` where the mesh has no
    such primvar (or it has the wrong size)."""

    #: Primvar name without ``primvars:`` (``displayColor`` is the vertex colour).
    name: str
    fallback: tuple[float, ...] = (0.0, 0.0, 0.0)
    owner: str = ""


@dataclass
class MaterialPrim:
    """A surface material in our model: UsdPreviewSurface's inputs (metallic or
    specular workflow), each a constant or a :class:`TextureRef` (``textures[name]``
    overrides the constant of input ``name``; names from ``TEXTURABLE_INPUTS``).
    Colours are scene-linear Rec.709; MaterialX ``standard_surface`` looks are
    translated onto the same inputs (``scene.materialx``)."""

    path: str
    diffuse_color: np.ndarray = field(default_factory=lambda: np.full(3, 0.18))
    roughness: float = 0.5
    metallic: float = 0.0
    emissive_color: np.ndarray = field(default_factory=lambda: np.zeros(3))
    opacity: float = 1.0
    #: Cut-out threshold: opacity below it is not drawn (G-buffer, shadows, bake);
    #: 0 = no cut-out (opacity < 1 is then translucency).
    opacity_threshold: float = 0.0
    use_specular_workflow: bool = False
    specular_color: np.ndarray = field(default_factory=lambda: np.zeros(3))
    ior: float = 1.5
    clearcoat: float = 0.0
    clearcoat_roughness: float = 0.01
    occlusion: float = 1.0
    #: Tangent-space normal of an undriven ``normal`` input (unit; (0, 0, 1) = none).
    normal: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, 1.0]))
    #: Texture-driven inputs: input name -> lookup.
    textures: dict[str, TextureRef] = field(default_factory=dict)
    #: Primvar-driven inputs (``UsdPrimvarReader_*``): input name -> primvar.
    primvars: dict[str, PrimvarRef] = field(default_factory=dict)
    #: No readable surface: every value above is a default and a renderer should use
    #: the mesh's display colour instead (``warnings`` says why).
    uses_defaults: bool = False
    #: Where the material came from: "UsdPreviewSurface" | "MaterialX" | "".
    source: str = ""
    #: One-line problems (each names the material / node); reported once.
    warnings: list[str] = field(default_factory=list)
    #: Documented approximations that are not problems (lobes the engine does not
    #: model, e.g. standard_surface subsurface): shown in the previewer's material
    #: panel and ``stb inspect``, not printed as warnings.
    notes: list[str] = field(default_factory=list)

    @property
    def st_primvars(self) -> tuple[str, ...]:
        """Texture-coordinate primvars the material's textures read (sorted)."""
        return tuple(sorted({t.st for t in self.textures.values()}))


@dataclass
class CameraPrim:
    """UsdGeom.Camera. Camera looks down its local -Z with +Y up."""

    path: str
    transform: np.ndarray = field(default_factory=identity4)  # camera -> render frame
    projection: str = "perspective"
    #: Focal length and apertures in the same unit (USD: tenths of a scene unit,
    #: conventionally mm); only their ratios matter for the projection.
    focal_length: float = 50.0
    horizontal_aperture: float = 20.955
    vertical_aperture: float = 15.2908
    horizontal_aperture_offset: float = 0.0
    vertical_aperture_offset: float = 0.0
    near: float = 0.1  # metres
    far: float = 1000.0  # metres
    #: Extra clipping planes (a, b, c, d) in camera space, metres.
    clipping_planes: np.ndarray = field(default_factory=lambda: np.zeros((0, 4)))

    @property
    def aspect(self) -> float:
        return float(self.horizontal_aperture / max(self.vertical_aperture, 1e-9))
