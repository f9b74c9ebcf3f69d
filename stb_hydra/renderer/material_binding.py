"""Materials on the GPU: a draw batch's :class:`MaterialParams` and their uniforms.

``material_params`` turns a scene :class:`MaterialPrim` (constants, texture and
primvar inputs) and the mesh it is drawn on into the hashable parameters a draw
batch is grouped by; ``bind_material`` sets them on a program that includes
``shaders/common/material.glsl`` (the G-buffer pass, the alpha-tested shadow
passes): per texture slot the texture array and its sampler (wrap modes), a 4x4
matrix taking the sampled texel to the input's value (the file's channel
expansion, UsdUVTexture's ``scale`` and the output channel picked), the bias, the
2x3 ``st`` transform, UDIM tiles, and the fallback read where a UDIM tile is
missing.

Texture slots (``limits.MATERIAL_TEXTURE_SLOTS``), as in ``material.glsl``::

    0 diffuseColor  1 emissiveColor  2 specularColor  3 metallic
    4 roughness     5 opacity        6 normal         7 occlusion
    8 clearcoat     9 clearcoatRoughness
"""

from __future__ import annotations

from dataclasses import dataclass

import moderngl
import numpy as np

from .. import limits
from ..scene import prims
from .gl import set_uniform
from .textures import GpuTexture, TextureCache, expand_matrix, resolve_wrap

#: Material input of each texture slot (index = slot).
SLOT_INPUTS = (
    "diffuseColor",
    "emissiveColor",
    "specularColor",
    "metallic",
    "roughness",
    "opacity",
    "normal",
    "occlusion",
    "clearcoat",
    "clearcoatRoughness",
)
SLOT_OF = {name: i for i, name in enumerate(SLOT_INPUTS)}
assert len(SLOT_INPUTS) == limits.MATERIAL_TEXTURE_SLOTS
#: Slots whose input is a colour / vector (the others are one float).
_VECTOR_SLOTS = frozenset({0, 1, 2, 6})
#: Targets of a float3 / float primvar input (``u_pv3_slot`` / ``u_pv1_slot``).
_PV3_SLOTS = (0, 1, 2)
_PV1_SLOTS = (3, 4, 5, 7, 8, 9)
_CHANNEL = {"r": 0, "g": 1, "b": 2, "a": 3}


def _t3(v: object) -> tuple[float, float, float]:
    a = np.asarray(v, dtype=np.float64).reshape(-1)
    return (float(a[0]), float(a[1]), float(a[2]))


@dataclass(frozen=True)
class MaterialParams:
    """What the G-buffer pass draws a batch with (hashable: batches group by it)."""

    base: tuple[float, float, float] = (0.18, 0.18, 0.18)
    use_vertex_color: bool = False
    roughness: float = 0.5
    metallic: float = 0.0
    specular_workflow: bool = False
    specular_color: tuple[float, float, float] = (0.0, 0.0, 0.0)
    emissive: tuple[float, float, float] = (0.0, 0.0, 0.0)
    opacity: float = 1.0
    #: Cut-out threshold (0 = none): fragments with opacity below it are discarded in
    #: the G-buffer and in every shadow map.
    opacity_threshold: float = 0.0
    #: Dielectric F0 from ``ior`` (metallic workflow): ((ior - 1) / (ior + 1))^2.
    f0_dielectric: float = 0.04
    occlusion: float = 1.0
    #: Clearcoat weight and roughness (UsdPreviewSurface; 0: no coat lobe).
    clearcoat: float = 0.0
    clearcoat_roughness: float = 0.01
    #: Constant tangent-space normal ((0, 0, 1): none).
    normal: tuple[float, float, float] = (0.0, 0.0, 1.0)
    #: Per slot the texture lookup, or None.
    textures: tuple[prims.TextureRef | None, ...] = (None,) * limits.MATERIAL_TEXTURE_SLOTS
    #: Slot a float3 / float material primvar drives (-1: none); the mesh has it.
    pv3_slot: int = -1
    pv1_slot: int = -1
    #: The material's path (texture-cache user, messages); "" for display colour.
    path: str = ""

    def key(self) -> tuple:
        return (
            self.base,
            self.use_vertex_color,
            self.roughness,
            self.metallic,
            self.specular_workflow,
            self.specular_color,
            self.emissive,
            self.opacity,
            self.opacity_threshold,
            self.f0_dielectric,
            self.occlusion,
            self.clearcoat,
            self.clearcoat_roughness,
            self.normal,
            self.textures,
            self.pv3_slot,
            self.pv1_slot,
            self.path,
        )

    @property
    def textured(self) -> bool:
        """Needs the textured G-buffer program (textures, a primvar, a constant normal
        tilt, or a cut-out)."""
        return (
            any(t is not None for t in self.textures)
            or self.pv3_slot >= 0
            or self.pv1_slot >= 0
            or self.normal != (0.0, 0.0, 1.0)
            or self.cutout
            or self.coated
        )

    @property
    def coated(self) -> bool:
        """Has a clearcoat lobe (the G-buffer's ``g_coat`` target is then needed)."""
        return self.clearcoat > 0.0 or self.textures[SLOT_OF["clearcoat"]] is not None

    @property
    def cutout(self) -> bool:
        return self.opacity_threshold > 0.0

    @property
    def needs_normal_map(self) -> bool:
        return self.textures[SLOT_OF["normal"]] is not None or self.normal != (0.0, 0.0, 1.0)


def alpha_floor(m: MaterialParams) -> float:
    """Smallest GGX alpha a surface of material ``m`` can have in the G-buffer
    (common/gbuffer.glsl: roughness squared, clamped; a roughness texture or primvar may
    reach the clamp; the 8-bit target may round a constant down by half a step)."""
    slot = SLOT_OF["roughness"]
    if m.textures[slot] is not None or m.pv1_slot == slot:
        return limits.GGX_ALPHA_MIN
    r = max(float(m.roughness) - 1.0 / 255.0, 0.0)
    return max(r * r, limits.GGX_ALPHA_MIN)


def material_params(mat: prims.MaterialPrim | None, mesh: prims.MeshPrim) -> MaterialParams:
    """Draw parameters of ``mesh`` with its resolved material (None / ``uses_defaults``:
    the display colour, per vertex where it varies)."""
    if mat is None or mat.uses_defaults:
        return MaterialParams(
            base=_t3(mesh.display_color), use_vertex_color=mesh.vertex_colors is not None
        )
    tex: list[prims.TextureRef | None] = [None] * limits.MATERIAL_TEXTURE_SLOTS
    for name, ref in mat.textures.items():
        slot = SLOT_OF.get(name)
        if slot is not None and ref.file:
            tex[slot] = ref
    use_vc = False
    pv3 = pv1 = -1
    for name, pv in mat.primvars.items():
        slot = SLOT_OF.get(name)
        if slot is None or tex[slot] is not None:
            continue
        if pv.name == "displayColor" and slot == 0:
            use_vc = mesh.vertex_colors is not None
            continue
        if mesh.attrs is None:
            continue  # the mesh lacks it: the constant (the reader's fallback) stands
        if slot in _PV3_SLOTS and pv3 < 0:
            pv3 = slot
        elif slot in _PV1_SLOTS and pv1 < 0:
            pv1 = slot
    ior = float(mat.ior)
    f0 = ((ior - 1.0) / (ior + 1.0)) ** 2
    base = _t3(mat.diffuse_color)
    if use_vc:
        base = _t3(mesh.display_color)
    return MaterialParams(
        base=base,
        use_vertex_color=use_vc,
        roughness=float(mat.roughness),
        metallic=float(mat.metallic),
        specular_workflow=bool(mat.use_specular_workflow),
        specular_color=_t3(mat.specular_color),
        emissive=_t3(mat.emissive_color),
        opacity=float(mat.opacity),
        opacity_threshold=float(mat.opacity_threshold),
        f0_dielectric=float(f0),
        occlusion=float(mat.occlusion),
        clearcoat=float(mat.clearcoat),
        clearcoat_roughness=float(mat.clearcoat_roughness),
        normal=_t3(mat.normal),
        textures=tuple(tex),
        pv3_slot=pv3,
        pv1_slot=pv1,
        path=mat.path,
    )


def value_matrix(
    ref: prims.TextureRef, slot: int, gpu: GpuTexture
) -> tuple[np.ndarray, np.ndarray]:
    """(4x4 matrix, bias) taking a sampled texel to the slot's value: the file's
    channel expansion, UsdUVTexture's ``scale`` and ``bias``, then the output used
    (rgb / rgba / one channel, broadcast to every component)."""
    expand = expand_matrix(gpu.channels)
    scale = np.diag(np.asarray(ref.scale, dtype=np.float64))
    bias = np.asarray(ref.bias, dtype=np.float64)
    pick = np.eye(4)
    c = _CHANNEL.get(ref.channels)
    if c is not None:
        pick = np.zeros((4, 4))
        pick[:, c] = 1.0
    m = pick @ scale @ expand
    return m, pick @ bias


def fallback_value(ref: prims.TextureRef) -> np.ndarray:
    c = _CHANNEL.get(ref.channels)
    fb = np.asarray(ref.fallback, dtype=np.float64)
    return np.full(4, fb[c]) if c is not None else fb


def bind_material(
    prog: moderngl.Program,
    params: MaterialParams,
    cache: TextureCache | None,
    unit0: int = 0,
) -> None:
    """Set ``params``' uniforms on ``prog`` and bind its textures to texture units
    ``unit0 ..`` (slots without a usable texture get a dummy and are switched off)."""
    set_uniform(prog, "u_base_color", params.base)
    set_uniform(prog, "u_use_vertex_color", 1.0 if params.use_vertex_color else 0.0)
    set_uniform(prog, "u_roughness", params.roughness)
    set_uniform(prog, "u_metallic", params.metallic)
    set_uniform(prog, "u_specular_workflow", 1.0 if params.specular_workflow else 0.0)
    set_uniform(prog, "u_specular_color", params.specular_color)
    set_uniform(prog, "u_emissive", params.emissive)
    if "u_mat_on" not in prog:
        return  # the untextured program: constants only
    set_uniform(prog, "u_opacity", params.opacity)
    set_uniform(prog, "u_opacity_threshold", params.opacity_threshold)
    set_uniform(prog, "u_f0_dielectric", params.f0_dielectric)
    set_uniform(prog, "u_occlusion", params.occlusion)
    set_uniform(prog, "u_clearcoat", params.clearcoat)
    set_uniform(prog, "u_clearcoat_roughness", params.clearcoat_roughness)
    set_uniform(prog, "u_normal_const", params.normal)
    set_uniform(prog, "u_pv3_slot", params.pv3_slot)
    set_uniform(prog, "u_pv1_slot", params.pv1_slot)
    n = limits.MATERIAL_TEXTURE_SLOTS
    on = 0
    mats = np.zeros((n, 4, 4), np.float32)
    bias = np.zeros((n, 4), np.float32)
    st = np.zeros((n, 2, 4), np.float32)
    udim = np.zeros((n, 2), np.int32)
    tiles = np.zeros((n, 4), np.uint32)
    fb = np.zeros((n, 4), np.float32)
    for slot, ref in enumerate(params.textures):
        unit = unit0 + slot
        gpu = cache.acquire(ref, params.path) if (ref is not None and cache is not None) else None
        if ref is None or gpu is None or cache is None:
            if cache is not None:
                cache.dummy().use(unit)
            continue
        on |= 1 << slot
        gpu.texture.use(unit)
        ws = resolve_wrap(ref.wrap_s, gpu.wrap_meta[0])
        wt = resolve_wrap(ref.wrap_t, gpu.wrap_meta[1])
        if gpu.udim_first:
            ws = wt = "repeat"  # tiles take fract(st); outside the set reads the fallback
        cache.sampler(ws, wt).use(unit)
        m, b = value_matrix(ref, slot, gpu)
        mats[slot] = m.T  # GLSL mat4 is column-major
        bias[slot] = b
        a = ref.st_transform
        st[slot, 0, :3] = a[0:3]
        st[slot, 1, :3] = a[3:6]
        udim[slot] = (gpu.udim_first, gpu.layers)
        fb[slot] = fallback_value(ref)
        if gpu.udim_first:
            present = _tile_mask(cache, ref, gpu)
            tiles[slot] = present
    if cache is not None:
        for slot in range(len(params.textures), n):
            cache.dummy().use(unit0 + slot)
    set_uniform(prog, "u_mat_on", on)
    _write_array(prog, "u_mat_tex", np.arange(unit0, unit0 + n, dtype=np.int32))
    _write_array(prog, "u_mat_value", mats)
    _write_array(prog, "u_mat_bias", bias)
    _write_array(prog, "u_mat_st", st.reshape(n * 2, 4))
    _write_array(prog, "u_mat_udim", udim)
    _write_array(prog, "u_mat_tiles", tiles)
    _write_array(prog, "u_mat_fallback", fb)


def unbind_samplers(ctx: moderngl.Context, unit0: int = 0) -> None:
    """Unbind the material slots' sampler objects: a sampler object bound to a unit
    overrides the sampling state of every texture later used on it (a shadow map's
    depth comparison, say)."""
    ctx.clear_samplers(unit0, unit0 + limits.MATERIAL_TEXTURE_SLOTS)


def _tile_mask(cache: TextureCache, ref: prims.TextureRef, gpu: GpuTexture) -> np.ndarray:
    """uvec4 bit mask of the UDIM tiles present (bit k: tile udim_first + k)."""
    info = cache.info(ref.file)
    mask = np.zeros(4, np.uint32)
    if info is None:
        return mask
    for _p, t in info.layers:
        k = t - gpu.udim_first
        if 0 <= k < 128:
            mask[k // 32] |= np.uint32(1 << (k % 32))
    return mask


def _write_array(prog: moderngl.Program, name: str, data: np.ndarray) -> None:
    """Write the first elements of a uniform array (a compiler may drop the elements
    a program never reads: the array is then shorter)."""
    try:
        u = prog[name]
    except KeyError:
        return
    assert isinstance(u, moderngl.Uniform)
    n = max(int(u.array_length), 1)
    u.write(np.ascontiguousarray(data[:n]).tobytes())
