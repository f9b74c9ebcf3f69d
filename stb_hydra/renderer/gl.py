"""OpenGL context and shader loading.

* :func:`get_context` -- one moderngl context per process: standalone EGL by
  default (Mesa llvmpipe on CPU machines, NVIDIA EGL on GPU machines), or a
  window's context handed in with :func:`use_context`.
* :class:`ShaderLibrary` -- loads ``shaders/<name>.{vert,frag,comp}`` (the package
  ``stb_hydra.shaders``, read with :mod:`importlib.resources`: the same in a wheel and
  in an editable install), expands ``#include "common/x.glsl"`` (each file once),
  prepends ``#version``, the feature ``#define``s and the generated constants
  (``common/constants.glsl``, from :mod:`.shader_constants`), and caches programs per
  (sources, defines): only the variants a scene needs are ever compiled.
"""

from __future__ import annotations

import hashlib
import posixpath
import re
import threading
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from importlib import resources
from typing import TYPE_CHECKING, cast

import moderngl
import numpy as np

from .shader_constants import GLSL_CONSTANTS, constants_glsl

if TYPE_CHECKING:
    # importlib.resources.abc is 3.11+; importlib.abc.Traversable is the 3.10 spelling.
    from importlib.abc import Traversable

#: The package holding the GLSL (the checkout's top-level ``shaders/``).
SHADER_PACKAGE = "stb_hydra.shaders"
#: Include generated from :mod:`.shader_constants`; no file on disk, in every shader.
CONSTANTS_INCLUDE = "common/constants.glsl"
GLSL_VERSION = "#version 430 core"
#: A define ``GLSL_EXT_<name>`` (true) also emits ``#extension <name> : require`` right
#: after ``#version`` (e.g. ``GLSL_EXT_GL_ARB_derivative_control`` for ``dFdxFine``).
EXTENSION_PREFIX = "GLSL_EXT_"

_lock = threading.Lock()
_ctx: moderngl.Context | None = None


class GLError(RuntimeError):
    """No usable OpenGL 4.3+ context, or a shader failed to compile."""


def get_context(backend: str = "egl") -> moderngl.Context:
    """The process-wide context (created on first use)."""
    global _ctx
    with _lock:
        if _ctx is None:
            try:
                # moderngl's stub types ``backend`` as a dict; the runtime takes the name.
                _ctx = moderngl.create_standalone_context(
                    backend=backend,  # type: ignore[arg-type]
                    require=430,
                )
            except Exception as exc:  # noqa: BLE001 - report one clear line
                raise GLError(
                    f"cannot create an OpenGL 4.3 context with backend '{backend}': {exc}"
                ) from None
        return _ctx


def use_context(ctx: moderngl.Context) -> None:
    """Render into an existing context (e.g. a previewer window's)."""
    global _ctx
    with _lock:
        _ctx = ctx


_parking: dict[int, moderngl.Framebuffer] = {}


def park(ctx: moderngl.Context) -> None:
    """Bind a persistent 1x1 framebuffer. Call before releasing framebuffers:
    moderngl restores the previously bound framebuffer after some operations
    (e.g. ``Framebuffer.clear``), and re-binding a deleted one is a GL error."""
    fb = _parking.get(id(ctx))
    if fb is None:
        tex = ctx.texture((1, 1), 4, dtype="f1")
        fb = ctx.framebuffer(color_attachments=[tex])
        _parking[id(ctx)] = fb
    fb.use()


def renderer_info(ctx: moderngl.Context) -> str:
    i = ctx.info
    return f"{i['GL_RENDERER']} | OpenGL {i['GL_VERSION']} | {i['GL_VENDOR']}"


def limit_defines() -> dict[str, object]:
    """Limits every shader sees (``LIM_<NAME>``): part of :data:`GLSL_CONSTANTS`."""
    return {k: v for k, v in GLSL_CONSTANTS.items() if k.startswith("LIM_")}


def shader_root() -> Traversable:
    """The directory of the shader sources, wherever the package is installed."""
    return resources.files(SHADER_PACKAGE)


_INCLUDE = re.compile(r'^\s*#include\s+"([^"]+)"\s*$', re.MULTILINE)


def shader_source(name: str) -> str:
    """Text of ``shaders/<name>`` (``/``-separated, relative to the shader root);
    :data:`CONSTANTS_INCLUDE` is generated."""
    if name == CONSTANTS_INCLUDE:
        return constants_glsl()
    text = _sources.get(name)
    if text is None:
        node = shader_root()
        for part in name.split("/"):
            node = node.joinpath(part)
        try:
            text = node.read_text(encoding="utf-8")
        except OSError as exc:
            raise GLError(f"shader source not found: {SHADER_PACKAGE}/{name}") from exc
        _sources[name] = text
    return text


#: Shader files read once per process (package data does not change under a process).
_sources: dict[str, str] = {}


def _expand(name: str, seen: set[str]) -> str:
    name = posixpath.normpath(name)
    if name in seen:
        return f"// (already included: {name})\n"
    seen.add(name)
    text = shader_source(name)

    def sub(m: re.Match) -> str:
        inc = m.group(1)
        return f"// begin {inc}\n{_expand(inc, seen)}\n// end {inc}"

    return _INCLUDE.sub(sub, text)


def preprocess(name: str, defines: dict[str, object] | None = None) -> str:
    """Full GLSL source of ``shaders/<name>`` with includes expanded."""
    head = [GLSL_VERSION]
    for k, v in (defines or {}).items():
        if k.startswith(EXTENSION_PREFIX) and v:  # must precede any declaration
            head.append(f"#extension {k[len(EXTENSION_PREFIX) :]} : require")
    for k, v in (defines or {}).items():
        if v is False or v is None:
            continue
        head.append(f"#define {k} {1 if v is True else v}")
    seen: set[str] = set()
    head.append(_expand(CONSTANTS_INCLUDE, seen))
    body = _expand(name, seen)
    return "\n".join(head) + "\n#line 1\n" + body


@dataclass(frozen=True)
class ProgramKey:
    """A compiled program's identity: its stage files and the SHA-1 of the full
    generated source of every stage (version, defines, generated constants, expanded
    includes), so two requests that produce the same GLSL share one compile and a
    change anywhere in the text is a new program."""

    stages: tuple[str, ...]
    source_sha1: str


class ShaderLibrary:
    """Compiles and caches programs for one context."""

    def __init__(self, ctx: moderngl.Context) -> None:
        self.ctx = ctx
        self._programs: dict[ProgramKey, moderngl.Program] = {}
        self._compute: dict[ProgramKey, moderngl.ComputeShader] = {}
        self._texts: dict[
            tuple[tuple[str, ...], tuple[tuple[str, str], ...]],
            tuple[ProgramKey, tuple[str | None, ...]],
        ] = {}
        self._ltc: moderngl.TextureArray | None = None
        self.compiled = 0

    def ltc_texture(self) -> moderngl.TextureArray:
        """The GGX LTC table (``data/ltc_ggx.npy``, tools/fit_ltc.py) as a 2-layer
        rgba32f texture array, bilinear, clamped: ``u_ltc`` of common/area.glsl."""
        if self._ltc is None:
            table = load_ltc_table()
            layers, rows, cols, _ = table.shape
            tex = self.ctx.texture_array((cols, rows, layers), 4, table.tobytes(), dtype="f4")
            tex.filter = (moderngl.LINEAR, moderngl.LINEAR)
            tex.repeat_x = tex.repeat_y = False
            self._ltc = tex
        return self._ltc

    def _sources(
        self, stages: Iterable[str], defines: Mapping[str, object] | None
    ) -> tuple[ProgramKey, tuple[str | None, ...]]:
        """(key, preprocessed source per stage; None for an absent stage). The text of
        a (stages, defines) request is memoised: preprocessing costs ~1 ms."""
        names = tuple(stages)
        req = (names, tuple(sorted((k, repr(v)) for k, v in (defines or {}).items())))
        hit = self._texts.get(req)
        if hit is None:
            d = dict(defines or {})
            texts = tuple(preprocess(n, d) if n else None for n in names)
            h = hashlib.sha1()
            for t in texts:
                h.update(b"\0" if t is None else t.encode("utf-8") + b"\0")
            hit = (ProgramKey(names, h.hexdigest()), texts)
            self._texts[req] = hit
        return hit

    def program(
        self,
        vertex: str,
        fragment: str | None = None,
        defines: dict[str, object] | None = None,
        geometry: str | None = None,
    ) -> moderngl.Program:
        stages = (vertex, fragment or "") + ((geometry,) if geometry else ())
        key, texts = self._sources(stages, defines)
        prog = self._programs.get(key)
        if prog is None:
            vs = cast(str, texts[0])
            fs = texts[1]
            gs = texts[2] if geometry else None
            try:
                prog = self.ctx.program(vertex_shader=vs, fragment_shader=fs, geometry_shader=gs)
            except moderngl.Error as exc:
                names = " + ".join(n for n in (vertex, geometry, fragment) if n)
                raise GLError(f"compiling {names} failed:\n{exc}") from None
            self._programs[key] = prog
            self.compiled += 1
        return prog

    def compute(
        self, name: str, defines: dict[str, object] | None = None
    ) -> moderngl.ComputeShader:
        key, texts = self._sources((name,), defines)
        cs = self._compute.get(key)
        if cs is None:
            try:
                cs = self.ctx.compute_shader(cast(str, texts[0]))
            except moderngl.Error as exc:
                raise GLError(f"compiling {name} failed:\n{exc}") from None
            self._compute[key] = cs
            self.compiled += 1
        return cs


_libraries: dict[int, ShaderLibrary] = {}


def load_ltc_table() -> np.ndarray:
    """The fitted GGX LTC table, float32 (2, rows = view angle, cols = roughness, 4)."""
    import io

    raw = resources.files("stb_hydra").joinpath("data/ltc_ggx.npy").read_bytes()
    table = np.load(io.BytesIO(raw), allow_pickle=False)
    return np.ascontiguousarray(table, dtype=np.float32)


def shader_library(ctx: moderngl.Context) -> ShaderLibrary:
    lib = _libraries.get(id(ctx))
    if lib is None or lib.ctx is not ctx:
        lib = ShaderLibrary(ctx)
        _libraries[id(ctx)] = lib
    return lib


def set_uniform(prog: moderngl.Program | moderngl.ComputeShader, name: str, value: object) -> None:
    """Set a uniform if the (optimised) program still has it: numpy arrays are
    written as bytes (float arrays as float32), anything else as ``.value``."""
    try:
        u = cast(moderngl.Uniform, prog[name])
    except KeyError:
        return
    if isinstance(value, (np.ndarray, np.generic)):
        u.write(value.astype("f4").tobytes() if value.dtype.kind == "f" else value.tobytes())
    else:
        u.value = value
