"""OpenColorIO colour correction: scene-linear -> display-referred (Hydra's ColorCorrectionTask).

Colour spaces:

* input: the rendering space, scene-linear Rec.709 / sRGB primaries (``lin_rec709_srgb``,
  "Linear Rec.709 (sRGB)" in the ACES studio config), relative radiometric units where
  0.18 is mid grey;
* output: the display/view colour space of the OCIO config (default: the config's default
  display and view; the built-in studio config gives "sRGB - Display" with the ACES 2.0 SDR
  view), display-referred code values clamped to [0, 1]. Alpha passes through, clamped.

``exposure`` (stops) scales scene-linear values by ``2**exposure`` before the view
transform. It is an OCIO dynamic property (``ExposureContrastTransform``), so the GPU
program is compiled once per (config, input space, display, view) and exposure changes
only update a uniform; the CPU path runs the very same OCIO processor.

Non-finite input is sanitised identically on both paths: NaN -> 0, +-inf -> +-65504
(the largest half float; the GPU input is normally ``rgba16f``).
"""

from __future__ import annotations

import functools
import math
import os
import threading
import weakref
from collections.abc import Iterable
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import PyOpenColorIO as ocio

if TYPE_CHECKING:  # moderngl is only needed for the GPU path
    import moderngl

#: Built-in config used when neither ``config_path`` nor ``$OCIO`` is given.
BUILTIN_CONFIG_URI = "ocio://studio-config-latest"

#: Names and aliases of linear Rec.709 (sRGB primaries, D65) in common configs, in order
#: of preference. ``scene_linear`` is used only when it is one of these.
LINEAR_REC709_NAMES = (
    "lin_rec709_srgb",
    "Linear Rec.709 (sRGB)",
    "lin_rec709",
    "lin_rec709_scene",
    "lin_srgb",
    "Utility - Linear - sRGB",
    "Utility - Linear - Rec.709",
)

#: Largest finite half float; +-inf scene-linear input is clamped to it on both paths.
HALF_MAX = 65504.0

_FUNCTION_NAME = "OCIODisplay"
_RESOURCE_PREFIX = "ocio_"

# OCIO caches processors per config, so two pipelines with the same transforms share one
# CPU processor and with it the exposure dynamic property: set it and apply under a lock.
_CPU_LOCK = threading.Lock()


def _one_line(text: str) -> str:
    return " ".join(str(text).split())


def _quoted_list(names: Iterable[str]) -> str:
    return ", ".join(f"'{n}'" for n in names)


@functools.lru_cache(maxsize=8)
def _load_config(source: str, mtime_ns: int) -> ocio.Config:
    """Parse an OCIO config file or ``ocio://`` URI (cached; ``mtime_ns`` busts the cache)."""
    del mtime_ns
    return ocio.Config.CreateFromFile(source)


def resolve_config(config_path: str | os.PathLike[str] | None = None) -> tuple[ocio.Config, str]:
    """Config from ``config_path``, else ``$OCIO``, else the built-in studio config.

    Returns ``(config, source)`` where ``source`` is the absolute file path or the
    ``ocio://`` URI. Raises ``ValueError`` for a missing or unparsable config.
    """
    origin = "--ocio-config"
    source = os.fspath(config_path) if config_path is not None else ""
    if not source:
        origin, source = "$OCIO", os.environ.get("OCIO", "")
    if not source:
        origin, source = "built-in", BUILTIN_CONFIG_URI
    mtime_ns = 0
    if not source.startswith("ocio://"):
        path = Path(source).expanduser()
        if not path.is_file():
            raise ValueError(f"OCIO config not found ({origin}): '{source}'")
        source = str(path.resolve())
        mtime_ns = path.stat().st_mtime_ns
    try:
        return _load_config(source, mtime_ns), source
    except ocio.Exception as exc:
        raise ValueError(
            f"cannot load OCIO config ({origin}) '{source}': {_one_line(exc)}"
        ) from None


def _colorspace_names(config: ocio.Config) -> list[str]:
    return [cs.getName() for cs in config.getColorSpaces()]


def find_linear_rec709(config: ocio.Config) -> str:
    """Name of the linear Rec.709 / sRGB-primaries colour space of ``config``.

    ``scene_linear`` is taken only if it is linear Rec.709; otherwise the known names and
    aliases are looked up, then OCIO's interchange-space identification against the
    built-in studio config. Raises ``ValueError`` when none matches.
    """
    wanted = {n.lower() for n in LINEAR_REC709_NAMES}
    scene_linear = config.getColorSpace(ocio.ROLE_SCENE_LINEAR)
    if scene_linear is not None:
        names = [scene_linear.getName(), *scene_linear.getAliases()]
        if any(n.lower() in wanted for n in names):
            return scene_linear.getName()
    for name in LINEAR_REC709_NAMES:
        cs = config.getColorSpace(name)
        if cs is not None:
            return cs.getName()
    try:  # needs the config's interchange roles; any failure means "not identifiable"
        builtin, _ = resolve_config(BUILTIN_CONFIG_URI)
        name = ocio.Config.IdentifyBuiltinColorSpace(config, builtin, "lin_rec709_srgb")
        if name:
            return config.getColorSpace(name).getName()
    except (ocio.Exception, ValueError, AttributeError):
        pass
    raise ValueError(
        "OCIO config has no linear Rec.709 (sRGB primaries) colour space "
        f"(looked for scene_linear and {_quoted_list(LINEAR_REC709_NAMES)}); pass input_space"
    )


class ColorPipeline:
    """OCIO scene-linear -> display/view pipeline with exposure, shared by CPU and GPU paths.

    Args:
        config_path: OCIO config file or ``ocio://`` URI; ``None`` -> ``$OCIO`` -> built-in
            studio config.
        display, view: OCIO display and view; ``None`` -> the config's defaults.
        exposure: stops applied in scene-linear before the view (x ``2**exposure``).
        input_space: rendering colour space; ``None`` -> linear Rec.709 found in the config.

    Raises ``ValueError`` (one line, naming the bad value and the valid ones) for an
    unknown display, view or colour space, or an unloadable config.
    """

    def __init__(
        self,
        config_path: str | os.PathLike[str] | None = None,
        display: str | None = None,
        view: str | None = None,
        exposure: float = 0.0,
        input_space: str | None = None,
    ) -> None:
        self._config, self._config_source = resolve_config(config_path)
        cfg = self._config

        displays = list(cfg.getDisplays())
        self._display = display if display is not None else cfg.getDefaultDisplay()
        if self._display not in displays:
            raise ValueError(
                f"unknown OCIO display '{self._display}' (valid: {_quoted_list(displays)})"
            )
        views = list(cfg.getViews(self._display))
        self._view = view if view is not None else cfg.getDefaultView(self._display)
        if self._view not in views:
            raise ValueError(
                f"unknown OCIO view '{self._view}' for display '{self._display}' "
                f"(valid: {_quoted_list(views)})"
            )
        if input_space is None:
            self._input_space = find_linear_rec709(cfg)
        else:
            cs = cfg.getColorSpace(input_space)
            if cs is None:
                raise ValueError(
                    f"unknown OCIO colour space '{input_space}' "
                    f"(valid: {_quoted_list(_colorspace_names(cfg))})"
                )
            self._input_space = cs.getName()

        self._exposure = 0.0
        self.exposure = exposure

        group = ocio.GroupTransform(
            [
                ocio.ExposureContrastTransform(
                    style=ocio.EXPOSURE_CONTRAST_LINEAR,
                    exposure=0.0,
                    contrast=1.0,
                    pivot=0.18,
                    dynamicExposure=True,
                ),
                ocio.DisplayViewTransform(
                    src=self._input_space, display=self._display, view=self._view
                ),
            ]
        )
        try:
            self._processor = cfg.getProcessor(group)
            self._cpu = self._processor.getDefaultCPUProcessor()
        except ocio.Exception as exc:
            raise ValueError(
                f"OCIO cannot build '{self._input_space}' -> '{self._display}' / "
                f"'{self._view}': {_one_line(exc)}"
            ) from None

    # --- resolved names -------------------------------------------------------------

    @property
    def config(self) -> ocio.Config:
        return self._config

    @property
    def config_source(self) -> str:
        """Absolute config file path or ``ocio://`` URI."""
        return self._config_source

    @property
    def display(self) -> str:
        return self._display

    @property
    def view(self) -> str:
        return self._view

    @property
    def input_space(self) -> str:
        """Canonical name of the scene-linear input colour space."""
        return self._input_space

    @property
    def display_space(self) -> str:
        """Colour space of the display-referred output (for image metadata)."""
        name = self._config.getDisplayViewColorSpaceName(self._display, self._view)
        return self._display if name in ("", ocio.OCIO_VIEW_USE_DISPLAY_NAME) else name

    @property
    def processor(self) -> ocio.Processor:
        return self._processor

    @property
    def cache_key(self) -> str:
        """Identifies the compiled GPU program: same key -> same shader (exposure excluded)."""
        return self._processor.getCacheID()

    @property
    def exposure(self) -> float:
        """Exposure in stops (scene-linear x ``2**exposure``); settable."""
        return self._exposure

    @exposure.setter
    def exposure(self, value: float) -> None:
        value = float(value)
        if not math.isfinite(value):
            raise ValueError(f"exposure must be finite (got {value})")
        self._exposure = value

    def displays(self) -> list[str]:
        return list(self._config.getDisplays())

    def views(self, display: str | None = None) -> list[str]:
        return list(self._config.getViews(display or self._display))

    def metadata(self) -> dict[str, Any]:
        """Image-header attributes describing this pipeline."""
        return {
            "stb:ocio:config": self._config_source,
            "stb:ocio:inputColorSpace": self._input_space,
            "stb:ocio:display": self._display,
            "stb:ocio:view": self._view,
            "stb:ocio:exposure": self._exposure,
        }

    def __repr__(self) -> str:
        return (
            f"ColorPipeline(config={self._config_source!r}, input={self._input_space!r}, "
            f"display={self._display!r}, view={self._view!r}, exposure={self._exposure})"
        )

    # --- CPU path -------------------------------------------------------------------

    def apply_cpu(self, rgb: np.ndarray) -> np.ndarray:
        """Scene-linear ``(..., 3|4)`` float -> display-referred float32 in [0, 1].

        Same shape as the input; alpha (4th channel) passes through, clamped to [0, 1].
        """
        src = np.asarray(rgb, dtype=np.float32)
        if src.ndim < 2 or src.shape[-1] not in (3, 4):
            raise ValueError(f"apply_cpu expects (..., 3) or (..., 4) pixels, got {src.shape}")
        color = np.ascontiguousarray(src[..., :3]).copy()
        np.nan_to_num(color, copy=False, nan=0.0, posinf=HALF_MAX, neginf=-HALF_MAX)
        np.clip(color, -HALF_MAX, HALF_MAX, out=color)
        flat = color.reshape(-1, 3)
        with _CPU_LOCK:
            if self._cpu.hasDynamicProperty(ocio.DYNAMIC_PROPERTY_EXPOSURE):
                prop = self._cpu.getDynamicProperty(ocio.DYNAMIC_PROPERTY_EXPOSURE)
                prop.setDouble(self._exposure)
            self._cpu.applyRGB(flat)
        np.nan_to_num(color, copy=False, nan=0.0)
        np.clip(color, 0.0, 1.0, out=color)
        if src.shape[-1] == 3:
            return color
        alpha = np.clip(np.nan_to_num(src[..., 3:4], nan=0.0), 0.0, 1.0)
        return np.concatenate([color, alpha.astype(np.float32)], axis=-1)

    def to_uint8(self, rgb: np.ndarray) -> np.ndarray:
        """Scene-linear -> display-referred 8-bit code values."""
        return quantize(self.apply_cpu(rgb), 8)

    def to_uint16(self, rgb: np.ndarray) -> np.ndarray:
        """Scene-linear -> display-referred 16-bit code values."""
        return quantize(self.apply_cpu(rgb), 16)


def quantize(display: np.ndarray, bits: int) -> np.ndarray:
    """Display-referred float in [0, 1] -> unsigned ints (round to nearest), 8 or 16 bits."""
    if bits not in (8, 16):
        raise ValueError(f"bits must be 8 or 16 (got {bits})")
    top = (1 << bits) - 1
    x = np.nan_to_num(np.asarray(display, dtype=np.float32), nan=0.0)
    return np.rint(np.clip(x, 0.0, 1.0) * top).astype(np.uint8 if bits == 8 else np.uint16)


# --- GPU path --------------------------------------------------------------------------

_VERTEX_SHADER = """#version 430 core
// Full-screen triangle: (-1,-1), (3,-1), (-1,3); no vertex buffer.
void main() {
    vec2 p = vec2(float((gl_VertexID << 1) & 2), float(gl_VertexID & 2));
    gl_Position = vec4(p * 2.0 - 1.0, 0.0, 1.0);
}
"""

_FRAGMENT_MAIN = """
uniform sampler2D stb_src;       // scene-linear RGBA (rendering colour space)
uniform bool stb_same_size;      // src and dst sizes match: exact texel fetch
uniform vec2 stb_dst_size;       // dst size in pixels (resampling case)
out vec4 stb_frag_color;         // display-referred RGBA in [0, 1]

void main() {
    vec4 c = stb_same_size
        ? texelFetch(stb_src, ivec2(gl_FragCoord.xy), 0)
        : textureLod(stb_src, gl_FragCoord.xy / stb_dst_size, 0.0);
    c = mix(c, vec4(0.0), isnan(c));
    c.rgb = clamp(c.rgb, vec3(-65504.0), vec3(65504.0));
    vec4 o = OCIODisplay(vec4(c.rgb, 1.0));
    o.rgb = mix(o.rgb, vec3(0.0), isnan(o.rgb));
    stb_frag_color = vec4(clamp(o.rgb, 0.0, 1.0), clamp(c.a, 0.0, 1.0));
}
"""


class _GpuProgram:
    """One compiled OCIO program with its LUT textures, for one context and pipeline key."""

    def __init__(self, ctx: moderngl.Context, pipeline: ColorPipeline) -> None:
        import moderngl

        desc = ocio.GpuShaderDesc.CreateShaderDesc(
            language=ocio.GPU_LANGUAGE_GLSL_4_0,
            functionName=_FUNCTION_NAME,
            resourcePrefix=_RESOURCE_PREFIX,
        )
        desc.setAllowTexture1D(False)  # moderngl has no 1D textures
        pipeline.processor.getDefaultGPUProcessor().extractGpuShaderInfo(desc)
        self.desc = desc
        self.fragment_source = "#version 430 core\n" + desc.getShaderText() + _FRAGMENT_MAIN
        self.program = ctx.program(
            vertex_shader=_VERTEX_SHADER, fragment_shader=self.fragment_source
        )
        self.vao = ctx.vertex_array(self.program, [])
        self.textures: list[tuple[int, Any]] = []  # (unit, moderngl texture)
        #: The exposure whose uniforms the program holds (None: not set yet).
        self._pushed_exposure: float | None = None

        def bind(sampler_name: str, texture: Any, interpolation: Any) -> None:
            mode = moderngl.NEAREST if interpolation == ocio.INTERP_NEAREST else moderngl.LINEAR
            texture.filter = (mode, mode)
            texture.repeat_x = texture.repeat_y = False
            unit = 1 + len(self.textures)  # unit 0 is the source image
            self.textures.append((unit, texture))
            if sampler_name in self.program:
                self.program[sampler_name].value = unit

        for lut in desc.get3DTextures():
            edge = lut.edgeLen
            values = np.ascontiguousarray(lut.getValues(), dtype=np.float32)
            tex = ctx.texture3d((edge, edge, edge), 3, values.tobytes(), dtype="f4")
            tex.repeat_z = False
            bind(lut.samplerName, tex, lut.interpolation)
        for lut in desc.getTextures():
            if lut.dimensions != ocio.GpuShaderDesc.TEXTURE_2D:
                raise RuntimeError(f"OCIO asked for a 1D texture '{lut.textureName}'")
            comps = 1 if lut.channel == ocio.GpuShaderDesc.TEXTURE_RED_CHANNEL else 3
            values = np.ascontiguousarray(lut.getValues(), dtype=np.float32)
            tex = ctx.texture((lut.width, lut.height), comps, values.tobytes(), dtype="f4")
            bind(lut.samplerName, tex, lut.interpolation)

        self.program["stb_src"].value = 0
        self.src_nearest = ctx.sampler(
            filter=(moderngl.NEAREST, moderngl.NEAREST), repeat_x=False, repeat_y=False
        )
        self.src_linear = ctx.sampler(
            filter=(moderngl.LINEAR, moderngl.LINEAR), repeat_x=False, repeat_y=False
        )

    def set_uniforms(self, exposure: float) -> None:
        """Push OCIO's dynamic properties (exposure) and other uniforms to the program;
        nothing when the program already holds them for this exposure (only this method
        writes them, and they depend on nothing else)."""
        if exposure == self._pushed_exposure:
            return
        self._pushed_exposure = exposure
        desc = self.desc
        if desc.hasDynamicProperty(ocio.DYNAMIC_PROPERTY_EXPOSURE):
            desc.getDynamicProperty(ocio.DYNAMIC_PROPERTY_EXPOSURE).setDouble(exposure)
        for name, data in desc.getUniforms():
            if name not in self.program:  # optimised out by the GLSL compiler
                continue
            uniform = self.program[name]
            kind = data.type
            if kind == ocio.UNIFORM_DOUBLE:
                uniform.value = float(data.getDouble())
            elif kind == ocio.UNIFORM_BOOL:
                uniform.value = bool(data.getBool())
            elif kind == ocio.UNIFORM_FLOAT3:
                uniform.value = tuple(float(v) for v in data.getFloat3())
            elif kind in (ocio.UNIFORM_VECTOR_FLOAT, ocio.UNIFORM_VECTOR_INT):
                is_float = kind == ocio.UNIFORM_VECTOR_FLOAT
                values = list(data.getVectorFloat() if is_float else data.getVectorInt())
                length = max(uniform.array_length, 1)
                values = (values + [0] * length)[:length]
                uniform.value = values if length > 1 else values[0]
            else:
                raise RuntimeError(f"unsupported OCIO uniform type {kind} for '{name}'")

    def release(self) -> None:
        for _, tex in self.textures:
            tex.release()
        for obj in (self.vao, self.program, self.src_nearest, self.src_linear):
            obj.release()


# Compiled programs live on the context itself (keyed by the pipeline's processor cache
# id), so they go away with it; a module-level weak map would be kept alive by the
# programs' own references to the context.
_CACHE_ATTR = "_stb_color_programs"


def _program_for(ctx: moderngl.Context, pipeline: ColorPipeline) -> _GpuProgram:
    per_ctx: dict[str, _GpuProgram] | None = getattr(ctx, _CACHE_ATTR, None)
    if per_ctx is None:
        per_ctx = {}
        setattr(ctx, _CACHE_ATTR, per_ctx)
    key = pipeline.cache_key
    program = per_ctx.get(key)
    if program is None:
        program = per_ctx[key] = _GpuProgram(ctx, pipeline)
    return program


class ColorCorrectionPass:
    """GPU colour correction: scene-linear texture -> display-referred RGBA target.

    The program (OCIO GLSL + LUT textures) is compiled once per context and pipeline key
    and shared by every pass using it; ``pipeline.exposure`` is read at each ``run``.
    """

    def __init__(self, ctx: moderngl.Context, pipeline: ColorPipeline) -> None:
        self.ctx = ctx
        self.pipeline = pipeline
        self._gpu = _program_for(ctx, pipeline)
        self._fbo_cache: tuple[Any, Any] | None = None  # (weakref to texture, framebuffer)

    @property
    def fragment_source(self) -> str:
        """The full fragment shader (OCIO-generated function + our main)."""
        return self._gpu.fragment_source

    @property
    def program(self) -> moderngl.Program:
        """The compiled program, shared by every pass of this context and pipeline key."""
        return self._gpu.program

    @property
    def lut_textures(self) -> list[Any]:
        """The LUT textures OCIO asked for (3D ones first), bound after the source image."""
        return [tex for _, tex in self._gpu.textures]

    def _framebuffer_for(self, dst: Any) -> Any:
        import moderngl

        if isinstance(dst, moderngl.Framebuffer):
            return dst
        cached = self._fbo_cache
        if cached is not None and cached[0]() is dst:
            return cached[1]
        if cached is not None:
            cached[1].release()
        fbo = self.ctx.framebuffer(color_attachments=[dst])
        self._fbo_cache = (weakref.ref(dst), fbo)
        return fbo

    def run(self, src: moderngl.Texture, dst: moderngl.Framebuffer | moderngl.Texture) -> None:
        """Draw ``src`` (rgba16f/rgba32f, scene-linear) into ``dst``.

        ``dst`` is a framebuffer or a colour texture (``rgba8`` for 8-bit output,
        ``f2``/``f4`` for 16-bit PNG / TIFF). Blending, depth test and culling are off
        during the draw; the previous framebuffer and enable flags are restored.
        """
        import moderngl

        gpu = self._gpu
        fbo = self._framebuffer_for(dst)
        width, height = fbo.size
        same = tuple(src.size) == (width, height)
        gpu.set_uniforms(self.pipeline.exposure)
        gpu.program["stb_same_size"].value = same
        if "stb_dst_size" in gpu.program:
            gpu.program["stb_dst_size"].value = (float(width), float(height))
        sampler = gpu.src_nearest if same else gpu.src_linear
        # Textures are bound by hand: moderngl 5.13's Scope(textures=...) raises
        # GL_INVALID_ENUM and leaves the units unbound on Mesa.
        src.use(0)
        sampler.use(0)
        for unit, tex in gpu.textures:
            tex.use(unit)
        try:
            with self.ctx.scope(framebuffer=fbo, enable_only=moderngl.NOTHING):
                self.ctx.viewport = (0, 0, width, height)
                gpu.vao.render(mode=moderngl.TRIANGLES, vertices=3)
        finally:
            sampler.clear(0)

    def run_to_array(self, src: moderngl.Texture, dtype: str = "f1") -> np.ndarray:
        """Run into a temporary ``(h, w)`` RGBA target and read it back.

        ``dtype`` ``'f1'`` -> uint8 ``(h, w, 4)``; ``'f2'``/``'f4'`` -> float32 in [0, 1].
        Row 0 is the texture's first row (same order as ``src`` was uploaded).
        """
        width, height = src.size
        tex = self.ctx.texture((width, height), 4, dtype=dtype)
        try:
            self.run(src, tex)
            data = tex.read()
        finally:
            if self._fbo_cache is not None and self._fbo_cache[0]() is tex:
                self._fbo_cache[1].release()
                self._fbo_cache = None
            tex.release()
        np_dtype = {"f1": np.uint8, "f2": np.float16, "f4": np.float32}[dtype]
        out = np.frombuffer(data, dtype=np_dtype).reshape(height, width, 4)
        return out.copy() if dtype == "f1" else out.astype(np.float32)

    def release(self) -> None:
        """Release this pass's framebuffer; the shared program stays cached."""
        if self._fbo_cache is not None:
            self._fbo_cache[1].release()
            self._fbo_cache = None
