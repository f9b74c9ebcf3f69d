"""The previewer's window: GLFW (OpenGL 4.3 core; the engine renders in the window's
own context through ``moderngl.create_context()``), Dear ImGui panels (imgui-bundle's
GLFW backend), usdview's camera bindings, scripted events and snapshots.

Each tick: poll input -> run due script events -> ``PreviewSession.step()`` (renders
a frame if anything is left to do) -> blit the engine's OCIO display texture (or the
selected AOV) to the window -> panels -> screenshot requests (read back from the
window's back buffer, i.e. exactly what is then presented) -> swap. When nothing is
left to render and no input arrives the loop sleeps in ``glfw.wait_events_timeout``
and the window keeps its last image.
"""

from __future__ import annotations

import sys
import time
from collections import deque
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, cast

import glfw
import moderngl
import numpy as np

from .. import limits
from ..renderer.frame import RenderSettings
from ..renderer.gl import use_context
from .script import Event, ScriptError
from .session import TEMPORAL_MODES, PreviewSession
from .session_reload import changes_file

#: Number keys 1..6 switch methods in this order (the issue's list).
METHOD_KEYS = ("stb", "reference", "sun", "tiled", "clustered", "lighttree")
#: Display exposure step of the +/- keys (stops).
EXPOSURE_STEP = 0.5
#: Seconds the loop keeps redrawing after the last input (the panels react).
UI_ACTIVE_S = 0.5

BINDINGS = (
    ("LMB click", "select the prim under the cursor (ID buffer)"),
    ("Alt+LMB drag", "tumble"),
    ("Alt+MMB drag", "track"),
    ("Alt+RMB drag / wheel", "dolly"),
    ("RMB held + W/A/S/D, Q/E", "fly"),
    ("F / A", "frame selection / frame all"),
    ("C", "next stage camera (free camera after the last)"),
    ("1..6", "stb, reference, sun, tiled, clustered, lighttree"),
    ("T", "next temporal mode (auto, accumulate, taa, off)"),
    ("V", "next view (colour, AOVs, debug views)"),
    ("+ / -", "display exposure +/- 0.5 stop"),
    ("Space, Left/Right", "play/pause, step time"),
    ("R", "restart accumulation"),
    ("H", "hide/show panels"),
    ("P or F12", "screenshot (PNG through OIIO)"),
    ("Esc", "quit"),
)

_BLIT_VS = """
#version 330
out vec2 uv;
void main() {
    vec2 p = vec2(float((gl_VertexID << 1) & 2), float(gl_VertexID & 2));
    uv = p;
    gl_Position = vec4(p * 2.0 - 1.0, 0.0, 1.0);
}
"""
_BLIT_FS = """
#version 330
uniform sampler2D img;
in vec2 uv;
out vec4 color;
void main() { color = vec4(texture(img, uv).rgb, 1.0); }
"""


class WindowError(RuntimeError):
    """The window (or its OpenGL 4.3 context) cannot be opened."""


@dataclass
class RunOptions:
    """What ``stb preview`` asked for beyond the render settings."""

    script: list[Event] = field(default_factory=list)
    snapshot: str | None = None
    after_frames: int = 1
    show_ui: bool = True
    screenshot_dir: str = "."
    title: str = "stb preview"
    #: Exit once the script has run (also without --snapshot).
    exit_after_script: bool = False
    #: Live reload: watch the stage's layer files.
    watch: bool = True


class PreviewWindow:
    """A GLFW window whose context the engine renders in."""

    def __init__(self, width: int, height: int, title: str = "stb preview") -> None:
        glfw.ERROR_REPORTING = "raise"
        try:
            if not glfw.init():
                raise WindowError("cannot open a window: GLFW could not initialise")
            glfw.window_hint(glfw.CONTEXT_VERSION_MAJOR, 4)
            glfw.window_hint(glfw.CONTEXT_VERSION_MINOR, 3)
            glfw.window_hint(glfw.OPENGL_PROFILE, glfw.OPENGL_CORE_PROFILE)
            glfw.window_hint(glfw.OPENGL_FORWARD_COMPAT, True)
            glfw.window_hint(glfw.RESIZABLE, True)
            self.win = glfw.create_window(width, height, title, None, None)
        except glfw.GLFWError as exc:
            glfw.terminate()
            raise WindowError(f"cannot open a window: {_one_line(exc)}") from None
        if not self.win:
            glfw.terminate()
            raise WindowError("cannot open a window with an OpenGL 4.3 core context")
        glfw.ERROR_REPORTING = "ignore"
        glfw.make_context_current(self.win)
        glfw.swap_interval(0)
        try:
            self.ctx = moderngl.create_context(require=430)
        except Exception as exc:  # noqa: BLE001 - one line, whatever the driver says
            glfw.terminate()
            raise WindowError(f"no OpenGL 4.3 context in the window: {_one_line(exc)}") from None
        self.blit = self.ctx.program(vertex_shader=_BLIT_VS, fragment_shader=_BLIT_FS)
        self.vao = self.ctx.vertex_array(self.blit, [])
        self.sampler = self.ctx.sampler(
            filter=(moderngl.NEAREST, moderngl.NEAREST), repeat_x=False, repeat_y=False
        )
        self._view_tex: moderngl.Texture | None = None

    @property
    def x11_id(self) -> int:
        try:
            return int(glfw.get_x11_window(self.win))
        except Exception:  # noqa: BLE001 - not on X11
            return 0

    def framebuffer_size(self) -> tuple[int, int]:
        w, h = glfw.get_framebuffer_size(self.win)
        return int(w), int(h)

    def draw_texture(self, tex: moderngl.Texture | None) -> None:
        """The image (GL rows bottom-up) over the whole window, or dark grey."""
        scr = self.ctx.screen
        scr.use()
        w, h = self.framebuffer_size()
        self.ctx.viewport = (0, 0, w, h)
        self.ctx.scissor = None
        self.ctx.disable(moderngl.BLEND | moderngl.DEPTH_TEST | moderngl.CULL_FACE)
        if tex is None:
            self.ctx.clear(0.12, 0.12, 0.12, 1.0)
            return
        # Own sampler object on unit 0: the engine's passes may leave one bound there.
        tex.use(0)
        # nearest when 1:1 (the window shows the display image's exact codes), linear
        # when a reduced-resolution frame (--moving-scale) is stretched over the window
        f = moderngl.NEAREST if tuple(tex.size) == (w, h) else moderngl.LINEAR
        self.sampler.filter = (f, f)
        self.sampler.use(0)
        cast(moderngl.Uniform, self.blit["img"]).value = 0
        self.vao.render(moderngl.TRIANGLES, vertices=3)
        self.sampler.clear(0)

    def image_texture(self, rgb8: np.ndarray) -> moderngl.Texture:
        """An (h, w, 3) uint8 image, top row first, as a texture for :meth:`draw_texture`."""
        h, w = rgb8.shape[:2]
        if self._view_tex is None or self._view_tex.size != (w, h):
            if self._view_tex is not None:
                self._view_tex.release()
            self._view_tex = self.ctx.texture((w, h), 3, dtype="f1")
        self._view_tex.write(np.ascontiguousarray(rgb8[::-1]).tobytes())
        return self._view_tex

    def read_pixels(self) -> np.ndarray:
        """The window's back buffer as (h, w, 3) uint8, top row first."""
        w, h = self.framebuffer_size()
        data = self.ctx.screen.read(viewport=(0, 0, w, h), components=3, alignment=1)
        return np.frombuffer(data, np.uint8).reshape(h, w, 3)[::-1].copy()

    def close(self) -> None:
        glfw.destroy_window(self.win)
        glfw.terminate()


class PreviewApp:
    """The window, the session, the panels, input and the script: :meth:`run` returns
    the exit code (0; 2 when the stage could not be shown or a write failed)."""

    def __init__(
        self,
        scene: str,
        settings: RenderSettings,
        opts: RunOptions,
        *,
        color: Any = None,
        max_samples: int = 64,
        temporal: str = "auto",
        time: float | None = None,
        moving: str = "taa",
        scale: float = 1.0,
        err: Any = None,
    ) -> None:
        self.opts = opts
        self.err = err or sys.stderr
        assert settings.height
        title = f"{opts.title} - {Path(scene).name}"
        self.window = PreviewWindow(settings.width, int(settings.height), title)
        use_context(self.window.ctx)
        self._session_args = (scene, settings, color, max_samples, temporal, time, moving, scale)
        self.session = self._open_session()
        self.exit_code = 0
        self._retry: Any = None
        self._retry_flag = False
        if self.session.error:
            self._report(self.session.error)
            self.exit_code = 2
            if opts.watch and opts.snapshot is None:
                self._watch_for_retry(scene)
        elif opts.watch:
            self.session.watch()
        from imgui_bundle import imgui
        from imgui_bundle.python_backends.glfw_backend import GlfwRenderer

        from .panels import PanelState

        self.imgui = imgui
        imgui.create_context()
        imgui.get_io().set_ini_filename(None)
        self.gui = GlfwRenderer(self.window.win, attach_callbacks=False)
        self.panels = PanelState()
        self.show_ui = opts.show_ui
        self._events = list(opts.script)
        self._check_keys()
        self._wait = 0
        self._wait_converged = False
        self._sleep_until = 0.0
        #: ``{"wait_file": PATH}`` in progress: (the path, the deadline, perf_counter s).
        self._wait_file: tuple[str, float] | None = None
        self._ticks_after_script = 0
        self._shots: list[str] = []
        self._last_input = 0.0
        self._drag: tuple[int, float, float] | None = None
        self._click: tuple[float, float] | None = None
        self._mouse = (0.0, 0.0)
        self._fly_keys: set[int] = set()
        self._quit = False
        self._shot_counter = 0
        #: Wall time (ms) of the last frame's panels: imgui frame + its draw (CPU side).
        self.ui_ms = 0.0
        self._frame_times: deque[float] = deque(maxlen=30)
        self._install_callbacks()

    def _open_session(self) -> PreviewSession:
        scene, settings, color, max_samples, temporal, time_, moving, scale = self._session_args
        return PreviewSession(
            scene,
            settings,
            ctx=self.window.ctx,
            color=color,
            max_samples=max_samples,
            temporal=temporal,
            time=time_,
            moving_temporal=moving,
            moving_scale=scale,
        )

    def _watch_for_retry(self, scene: str) -> None:
        """The stage could not be opened: watch its file and try again when it changes
        (the window shows the error meanwhile)."""
        import os

        try:
            from watchdog.events import FileSystemEvent, FileSystemEventHandler
            from watchdog.observers import Observer
        except ImportError:
            return
        target = os.path.realpath(scene)
        folder = os.path.dirname(target)
        if not os.path.isdir(folder):
            return
        app = self

        class _Handler(FileSystemEventHandler):
            def on_any_event(self, event: FileSystemEvent) -> None:
                if not changes_file(event):
                    return
                for p in (event.src_path, getattr(event, "dest_path", "")):
                    if p and os.path.realpath(os.fsdecode(p)) == target:
                        app._retry_flag = True

        obs = Observer()
        obs.schedule(_Handler(), folder, recursive=False)
        obs.daemon = True
        obs.start()
        self._retry = obs

    def _retry_open(self) -> None:
        """The broken stage's file changed: open it again (once it settles)."""
        if not self._retry_flag:
            return
        self._retry_flag = False
        time.sleep(0.2)  # editors write in several steps
        session = self._open_session()
        if session.error:
            self.session.error = session.error
            return
        self.session = session
        self.exit_code = 0
        print(f"stb preview: opened {session.scene}", flush=True)
        if self._retry is not None:
            self._retry.stop()
            self._retry = None
        if self.opts.watch:
            session.watch()

    # -- output --
    def _report(self, msg: str, warning: bool = False) -> None:
        print(
            f"stb preview: {'warning: ' if warning else 'error: '}{msg}", file=self.err, flush=True
        )

    def _check_keys(self) -> None:
        for ev in self._events:
            if ev.kind == "key" and _key_code(ev.value) is None:
                raise ScriptError(f"event {ev.index}: unknown key {ev.value!r}")

    # -- input --
    def _install_callbacks(self) -> None:
        w = self.window.win
        glfw.set_key_callback(w, self._on_key)
        glfw.set_char_callback(w, self.gui.char_callback)
        glfw.set_cursor_pos_callback(w, self._on_cursor)
        glfw.set_mouse_button_callback(w, self._on_button)
        glfw.set_scroll_callback(w, self._on_scroll)
        glfw.set_framebuffer_size_callback(w, self._on_resize)

    def _ui_wants(self, what: str) -> bool:
        if not self.show_ui:
            return False
        io = self.imgui.get_io()
        return bool(io.want_capture_mouse if what == "mouse" else io.want_capture_keyboard)

    def _on_key(self, win: Any, key: int, scancode: int, action: int, mods: int) -> None:
        self._last_input = time.perf_counter()
        self.gui.keyboard_callback(win, key, scancode, action, mods)
        if key in _FLY:
            if action == glfw.PRESS:
                self._fly_keys.add(key)
            elif action == glfw.RELEASE:
                self._fly_keys.discard(key)
        if action != glfw.PRESS or self._ui_wants("keyboard"):
            return
        self.press(key, mods)

    def press(self, key: int, mods: int = 0) -> None:
        """One key press through the bindings (also the script's ``key`` event)."""
        s = self.session
        if key == glfw.KEY_ESCAPE:
            self._quit = True
        elif self._fly_active() and key in _FLY:
            return
        elif key == glfw.KEY_F:
            s.frame_selection()
        elif key == glfw.KEY_A:
            s.frame_all()
        elif key == glfw.KEY_C and s.ok:
            cams = [None, *s.cameras()]
            i = cams.index(s.camera_path) if s.camera_path in cams else 0
            s.set_camera(cams[(i + 1) % len(cams)])
        elif glfw.KEY_1 <= key <= glfw.KEY_6:
            s.set_method(METHOD_KEYS[key - glfw.KEY_1])
        elif key == glfw.KEY_T:
            s.set_temporal(TEMPORAL_MODES[(TEMPORAL_MODES.index(s.temporal) + 1) % 4])
        elif key == glfw.KEY_V and s.ok:
            vs = s.views()
            s.set_view(vs[(vs.index(s.view) + 1) % len(vs)] if s.view in vs else "color")
        elif key in (glfw.KEY_EQUAL, glfw.KEY_KP_ADD) and s.ok:
            s.set_exposure(s.exposure + EXPOSURE_STEP)
        elif key in (glfw.KEY_MINUS, glfw.KEY_KP_SUBTRACT) and s.ok:
            s.set_exposure(s.exposure - EXPOSURE_STEP)
        elif key == glfw.KEY_SPACE:
            s.set_playing(not s.playing)
        elif key in (glfw.KEY_LEFT, glfw.KEY_RIGHT) and s.ok:
            rng = s.time_range()
            if rng is not None:
                t = (s.time if s.time is not None else rng[0]) + (
                    1 if key == glfw.KEY_RIGHT else -1
                )
                s.set_time(min(max(t, rng[0]), rng[1]))
        elif key == glfw.KEY_R and s.ok:
            s.set_temporal(s.temporal)
        elif key == glfw.KEY_H:
            self.show_ui = not self.show_ui
        elif key in (glfw.KEY_P, glfw.KEY_F12):
            self._shot_counter += 1
            path = Path(self.opts.screenshot_dir) / f"stb_preview_{self._shot_counter:04d}.png"
            self._shots.append(str(path))

    def _fly_active(self) -> bool:
        return glfw.get_mouse_button(
            self.window.win, glfw.MOUSE_BUTTON_RIGHT
        ) == glfw.PRESS and not (
            glfw.get_key(self.window.win, glfw.KEY_LEFT_ALT) == glfw.PRESS
            or glfw.get_key(self.window.win, glfw.KEY_RIGHT_ALT) == glfw.PRESS
        )

    def _on_button(self, win: Any, button: int, action: int, mods: int) -> None:
        self._last_input = time.perf_counter()
        self.gui.mouse_button_callback(win, button, action, mods)
        x, y = glfw.get_cursor_pos(win)
        if action == glfw.PRESS and not self._ui_wants("mouse"):
            if mods & glfw.MOD_ALT:
                self._drag = (button, x, y)
            elif button == glfw.MOUSE_BUTTON_LEFT:
                self._click = (x, y)
        elif action == glfw.RELEASE:
            self._drag = None
            c, self._click = self._click, None
            if (
                c is not None
                and button == glfw.MOUSE_BUTTON_LEFT
                and abs(x - c[0]) + abs(y - c[1]) < 4
            ):
                self._pick_at(x, y)

    def _pick_at(self, x: float, y: float) -> None:
        """A click: select the prim under the cursor (window -> viewport pixels)."""
        ww, wh = glfw.get_window_size(self.window.win)
        vw, vh = self.session.size if self.session.ok else (ww, wh)
        self.session.pick(int(x * vw / max(ww, 1)), int(y * vh / max(wh, 1)))

    def _on_cursor(self, win: Any, x: float, y: float) -> None:
        self._last_input = time.perf_counter()
        self.gui.mouse_callback(win, x, y)
        if self._drag is None:
            return
        button, x0, y0 = self._drag
        dx, dy = x - x0, y - y0
        self._drag = (button, x, y)
        s = self.session
        if button == glfw.MOUSE_BUTTON_LEFT:
            s.tumble(dx, dy)
        elif button == glfw.MOUSE_BUTTON_MIDDLE:
            s.track(dx, dy)
        elif button == glfw.MOUSE_BUTTON_RIGHT:
            s.dolly(px=dx + dy)

    def _on_scroll(self, win: Any, xoff: float, yoff: float) -> None:
        self._last_input = time.perf_counter()
        self.gui.scroll_callback(win, xoff, yoff)
        if not self._ui_wants("mouse"):
            self.session.dolly(wheel=yoff)

    def _on_resize(self, win: Any, w: int, h: int) -> None:
        self._last_input = time.perf_counter()
        if w > 0 and h > 0 and self.session.ok:
            self.session.resize(w, h)

    def _apply_fly(self) -> None:
        if not self._fly_keys or not self._fly_active():
            return
        k = self._fly_keys
        f = (glfw.KEY_W in k) - (glfw.KEY_S in k)
        r = (glfw.KEY_D in k) - (glfw.KEY_A in k)
        u = (glfw.KEY_E in k) - (glfw.KEY_Q in k)
        if f or r or u:
            self.session.fly(f, r, u)

    # -- script --
    def _script_busy(self) -> bool:
        return bool(
            self._events
            or self._wait
            or self._wait_converged
            or self._sleep_until
            or self._wait_file
        )

    def _run_script(self) -> None:
        if self._sleep_until:
            if time.perf_counter() < self._sleep_until:
                return
            self._sleep_until = 0.0
        if self._wait_file is not None:
            path, deadline = self._wait_file
            if not Path(path).exists():
                if time.perf_counter() < deadline:
                    return
                self._report(
                    f"script: {path} did not appear within "
                    f"{limits.PREVIEW_WAIT_FILE_MAX_S:g} s; going on",
                    True,
                )
            self._wait_file = None
        if self._wait_converged:
            if not (self.session.converged or not self.session.ok):
                return
            self._wait_converged = False
        if self._wait:
            self._wait -= 1
            return
        while self._events and not (
            self._wait or self._wait_converged or self._sleep_until or self._wait_file
        ):
            ev = self._events.pop(0)
            if ev.kind == "screenshot" and self._shots:
                self._events.insert(0, ev)  # one per drawn frame: the state at this point
                break
            try:
                self._apply_event(ev)
            except (ValueError, TypeError, KeyError) as exc:
                self._report(f"script event {ev.index} ({ev.kind}): {_one_line(exc)}", True)

    def _apply_event(self, ev: Event) -> None:
        s, v, x = self.session, ev.value, ev.extra
        before = s.message
        k = ev.kind
        if k == "wait":
            if v == "converged":
                self._wait_converged = True
            else:
                self._wait = int(v)
        elif k == "sleep":
            self._sleep_until = time.perf_counter() + float(v)
        elif k == "wait_file":
            self._wait_file = (str(v), time.perf_counter() + limits.PREVIEW_WAIT_FILE_MAX_S)
        elif k == "orbit":
            s.tumble(*v)
        elif k == "track":
            s.track(*v)
        elif k == "dolly":
            s.dolly(px=float(v))
        elif k == "wheel":
            s.dolly(wheel=float(v))
        elif k == "key":
            code = _key_code(v)
            assert code is not None  # checked in __init__
            self.press(code)
        elif k == "method":
            s.set_method(v, x.get("options"))
        elif k == "options":
            s.set_options(**v)
        elif k == "temporal":
            s.set_temporal(v)
        elif k == "light":
            s.set_light(v, **x)
        elif k == "camera":
            s.set_camera(v)
        elif k == "time":
            s.set_time(float(v))
        elif k == "play":
            s.set_playing(v)
        elif k == "view":
            s.set_view(v)
        elif k == "exposure":
            s.set_exposure(float(v))
        elif k == "ocio_view":
            s.set_ocio_view(v)
        elif k == "select":
            s.select(v)
        elif k == "pick":
            print(f"stb preview: picked {s.pick(int(v[0]), int(v[1]))}", flush=True)
        elif k == "ui":
            self.show_ui = bool(v)
        elif k == "screenshot":
            self._shots.append(v)
            self._wait = 1  # drawn (and written) before the next event runs
        elif k == "save_edits":
            if s.save_edits(v) is None:
                self.exit_code = 2
        elif k == "mark":
            print(
                f"stb preview: mark {v} window=0x{self.window.x11_id:x} "
                f"selected={s.selected or '-'}",
                flush=True,
            )
        elif k == "quit":
            self._quit = bool(v)
        if s.message and s.message != before:
            self._report(f"script event {ev.index} ({k}): {s.message}", True)

    # -- drawing --
    def _draw(self) -> None:
        imgui = self.imgui
        s = self.session
        view = s.view_image()
        tex = self.window.image_texture(view) if view is not None else s.display_texture()
        self.window.draw_texture(tex)
        t_ui = time.perf_counter()
        self.gui.process_inputs()
        imgui.new_frame()
        size = self.window.framebuffer_size()
        from .panels import draw_controls, draw_error, draw_hud

        if s.error:
            draw_error(s.error, size)
        elif self.show_ui:
            draw_hud(s, self.panels)
            draw_controls(s, self.panels, size)
        imgui.render()
        if s.error or self.show_ui:
            # PyOpenGL (the imgui backend) raises on any pending GL error flag, also
            # one left by an earlier draw: read (and so clear) it first.
            _ = self.window.ctx.error
            self.gui.render(imgui.get_draw_data())
        self.ui_ms = (time.perf_counter() - t_ui) * 1e3
        for path in self._shots:
            self._write_screenshot(path)
        self._shots.clear()
        glfw.swap_buffers(self.window.win)

    def _write_screenshot(self, path: str) -> None:
        """What the window shows (already display-referred through OCIO) as a PNG/TIFF
        through OIIO, written atomically."""
        from ..io.images import ImageWriteError, write_image

        pixels = self.window.read_pixels()
        s = self.session
        meta: dict[str, Any] = {"stb:scene": s.scene, "stb:preview": True}
        pipeline = None
        if s.ok and s.engine is not None:
            pipeline = s.engine.color
            meta.update(
                {
                    "stb:lighting": s.method,
                    "stb:samples": s.samples,
                    "stb:view": s.view,
                    "stb:ocio_display": pipeline.display,
                    "stb:ocio_view": pipeline.view,
                    "stb:exposure": pipeline.exposure,
                }
            )
        try:
            write_image(path, pixels, metadata=meta, color_pipeline=pipeline, display_referred=True)
        except (ImageWriteError, OSError, ValueError) as exc:
            self._report(f"cannot write screenshot '{path}': {_one_line(exc)}")
            self.exit_code = 2
            return
        print(f"stb preview: wrote {path}", flush=True)

    # -- the loop --
    def run(self) -> int:
        try:
            return self._loop()
        finally:
            if self._retry is not None:
                self._retry.stop()
            self.session.release()
            try:
                self.gui.shutdown()
            except Exception:  # noqa: BLE001 - the context goes away anyway
                pass
            self.window.close()

    def _loop(self) -> int:
        opts = self.opts
        ticks = 0
        last = time.perf_counter()
        drew_last = False
        while not glfw.window_should_close(self.window.win) and not self._quit:
            busy = self._script_busy() or opts.snapshot is not None
            now = time.perf_counter()
            idle = self.session.converged or not self.session.ok  # nothing to render
            if (self._sleep_until or self._wait_file) and idle:
                glfw.wait_events_timeout(0.05)  # a scripted sleep: no need to spin
            elif busy or not idle or now - self._last_input < UI_ACTIVE_S:
                glfw.poll_events()
            else:
                glfw.wait_events_timeout(0.25)
            self._retry_open()
            self._run_script()
            self._apply_fly()
            rendered = self.session.step()
            now = time.perf_counter()
            active = now - self._last_input < UI_ACTIVE_S
            if rendered or active or busy or self._shots or ticks < 2:
                self._draw()
                if drew_last:  # frame-to-frame time of consecutive draws only
                    self._frame_times.append(now - last)
                    self.panels.fps = 1.0 / max(float(np.median(self._frame_times)), 1e-6)
                last = now
                drew_last = True
            else:
                drew_last = False
            ticks += 1
            if not self._script_busy():
                if opts.snapshot is not None:
                    self._ticks_after_script += 1
                    if self._ticks_after_script >= opts.after_frames:
                        self._shots.append(opts.snapshot)
                        self._draw()
                        break
                elif opts.exit_after_script and opts.script:
                    break
        return self.exit_code


_FLY = {glfw.KEY_W, glfw.KEY_A, glfw.KEY_S, glfw.KEY_D, glfw.KEY_Q, glfw.KEY_E}


def _key_code(name: str) -> int | None:
    """GLFW key code of a key name (``"F"``, ``"1"``, ``"SPACE"``, ``"F12"``, ``"ESCAPE"``)."""
    aliases = {"+": "EQUAL", "-": "MINUS", "ESC": "ESCAPE", " ": "SPACE"}
    n = aliases.get(name, name).upper()
    code = getattr(glfw, f"KEY_{n}", None)
    return int(code) if isinstance(code, int) else None


def _one_line(exc: BaseException) -> str:
    return " ".join(str(exc).split()) or type(exc).__name__
