"""The previewer's Dear ImGui panels (imgui-bundle): HUD, rendering controls, lights,
prims and time. Each widget calls a :class:`PreviewSession` action; nothing here
touches the engine directly."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from imgui_bundle import imgui

from .session import TEMPORAL_MODES, PreviewSession

_RED = imgui.ImVec4(1.0, 0.35, 0.3, 1.0)
_GREY = imgui.ImVec4(0.7, 0.7, 0.7, 1.0)


@dataclass
class PanelState:
    """What the panels remember between frames (search text, edit path, fps)."""

    search: str = ""
    edits_path: str = "preview_edits.usda"
    fps: float = 0.0
    last_saved: str = ""
    open_paths: set[str] = field(default_factory=set)


def draw_error(message: str, size: tuple[int, int]) -> None:
    """The stage could not be shown: the error, centred."""
    w, h = size
    imgui.set_next_window_pos(
        imgui.ImVec2(w * 0.5, h * 0.5), imgui.Cond_.always, imgui.ImVec2(0.5, 0.5)
    )
    imgui.set_next_window_size(imgui.ImVec2(min(w - 20.0, 600.0), 0.0), imgui.Cond_.always)
    flags = imgui.WindowFlags_.no_collapse | imgui.WindowFlags_.no_move
    imgui.begin("stb preview: cannot show the stage", None, flags)
    imgui.push_text_wrap_pos(0.0)
    imgui.text_colored(_RED, message)
    imgui.pop_text_wrap_pos()
    imgui.text_colored(_GREY, "The file is watched: fixing it opens the stage. Esc closes.")
    imgui.end()


def draw_hud(s: PreviewSession, ps: PanelState) -> None:
    """Top-left overlay: fps, per-pass ms, lights in view, shadows, samples."""
    imgui.set_next_window_pos(imgui.ImVec2(6.0, 6.0), imgui.Cond_.always)
    imgui.set_next_window_bg_alpha(0.55)
    flags = (
        imgui.WindowFlags_.no_decoration
        | imgui.WindowFlags_.always_auto_resize
        | imgui.WindowFlags_.no_focus_on_appearing
        | imgui.WindowFlags_.no_nav
        | imgui.WindowFlags_.no_move
    )
    imgui.begin("hud", None, flags)
    h = s.hud
    imgui.text(f"{ps.fps:5.1f} fps  frame {h.frame_ms:6.1f} ms  {s.method}  {h.temporal}")
    imgui.text(
        f"samples {h.samples}/{s.max_samples}  lights in view {h.lights_in_view}  "
        f"shadows pending {h.shadow_pending}  atlas {100.0 * h.atlas_occupancy:4.1f} %"
    )
    if s.engine is not None:
        st = s.engine.settings
        when = f"  time {s.time_text}{' (playing)' if s.playing else ''}"
        imgui.text(f"render {st.width}x{st.height}  view {s.view}{when}")
    if s.message:
        imgui.text_colored(_RED, s.message)
    if imgui.tree_node("passes (ms)"):
        top = [
            (k, v)
            for k, v in h.passes_ms.items()
            if "." not in k and k not in ("prepare", "sync", "commit")
        ]
        for k, v in sorted(top, key=lambda kv: -kv[1])[:12]:
            imgui.text(f"{k:>18s} {v:7.2f}")
        imgui.tree_pop()
    imgui.end()


def draw_controls(s: PreviewSession, ps: PanelState, size: tuple[int, int]) -> None:
    """The right-hand panel: render, lights, prims, time."""
    w, _ = size
    imgui.set_next_window_pos(imgui.ImVec2(w - 330.0, 6.0), imgui.Cond_.first_use_ever)
    imgui.set_next_window_size(imgui.ImVec2(324.0, 340.0), imgui.Cond_.first_use_ever)
    imgui.set_next_window_bg_alpha(0.8)
    # Small viewports start with the panel folded (click its title to open it).
    imgui.set_next_window_collapsed(w < 800, imgui.Cond_.first_use_ever)
    expanded, _ = imgui.begin("stb preview", None)
    if expanded and imgui.begin_tab_bar("tabs"):
        if imgui.begin_tab_item("Render")[0]:
            _render_tab(s)
            imgui.end_tab_item()
        if imgui.begin_tab_item("Lights")[0]:
            _lights_tab(s)
            imgui.end_tab_item()
        if imgui.begin_tab_item("Prims")[0]:
            _prims_tab(s, ps)
            imgui.end_tab_item()
        if imgui.begin_tab_item("Materials")[0]:
            _materials_tab(s)
            imgui.end_tab_item()
        if imgui.begin_tab_item("Time")[0]:
            _time_tab(s)
            imgui.end_tab_item()
        imgui.end_tab_bar()
    imgui.end()


def _combo(label: str, current: str, items: list[str]) -> str | None:
    idx = items.index(current) if current in items else 0
    changed, idx = imgui.combo(label, idx, items)
    return items[idx] if changed else None


def _render_tab(s: PreviewSession) -> None:
    m = _combo("method", s.method, s.methods)
    if m is not None:
        s.set_method(m)
    t = _combo("temporal", s.temporal, list(TEMPORAL_MODES))
    if t is not None:
        s.set_temporal(t)
    ch, n = imgui.slider_int("max samples", s.max_samples, 1, 1024)
    if ch:
        s.max_samples = max(1, n)
    view = _combo("view", s.view, s.views())
    if view is not None:
        s.set_view(view)
    ch, ev = imgui.slider_float("exposure", s.exposure, -8.0, 8.0, "%.2f stops")
    if ch:
        s.set_exposure(ev)
    if s.engine is not None:
        od = _combo("OCIO display", s.engine.color.display, s.engine.color.displays())
        if od is not None:
            s.set_ocio_display(od)
        ov = _combo("OCIO view", s.engine.color.view, s.engine.color.views())
        if ov is not None:
            s.set_ocio_view(ov)
        cams = ["(free camera)", *s.cameras()]
        c = _combo("camera", s.camera_path or cams[0], cams)
        if c is not None:
            s.set_camera(None if c == cams[0] else c)
    if imgui.collapsing_header(f"{s.method} options"):
        _method_options(s)


def _method_options(s: PreviewSession) -> None:
    """One widget per option of the current method (its schema: type, choices)."""
    opts: dict[str, Any] = s.options
    schema = getattr(s.engine.method, "options", None) if s.engine is not None else None
    # the engine's resolved values: defaults that depend on other options included
    resolved: dict[str, Any] = getattr(s.engine.method, "o", {}) if s.engine is not None else {}
    for opt in schema or ():
        cur = opts.get(opt.name, resolved.get(opt.name, opt.default))
        if opt.choices is not None:
            items = [str(c) for c in opt.choices]
            c = _combo(opt.name, str(cur), items)
            if c is not None:
                s.set_options(**{opt.name: list(opt.choices)[items.index(c)]})
            continue
        if cur is None:
            imgui.text_colored(_GREY, f"{opt.name}: auto")
            continue
        val: Any
        if opt.type is bool:
            ch, val = imgui.checkbox(opt.name, bool(cur))
        elif opt.type is int:
            ch, val = imgui.input_int(opt.name, int(cur))
        elif opt.type is float:
            ch, val = imgui.input_float(opt.name, float(cur))
        else:
            continue
        if ch:
            s.set_options(**{opt.name: val})


def _lights_tab(s: PreviewSession) -> None:
    for rec in s.lights():
        p = rec["path"]
        imgui.push_id(p)
        ch, on = imgui.checkbox("##on", rec["enabled"])
        if ch:
            s.set_light(p, enabled=on)
        imgui.same_line()
        tag = "  [linked]" if rec["linked"] else ""
        if imgui.tree_node(f"{p}  ({rec['type']}){tag}"):
            imgui.text_colored(_GREY, rec["links"])  # light / shadow linking
            ch, v = imgui.drag_float(
                "intensity", rec["intensity"], 0.05 * max(rec["intensity"], 1.0)
            )
            if ch:
                s.set_light(p, intensity=max(v, 0.0))
            ch, v = imgui.slider_float("exposure", rec["exposure"], -10.0, 10.0)
            if ch:
                s.set_light(p, exposure=v)
            ch, c = imgui.color_edit3("color", rec["color"])
            if ch:
                s.set_light(p, color=list(c))
            if imgui.button("select"):
                s.select(p)
            imgui.tree_pop()
        imgui.pop_id()


def _prims_tab(s: PreviewSession, ps: PanelState) -> None:
    _, ps.search = imgui.input_text_with_hint("##search", "search prims", ps.search)
    imgui.begin_child("tree", imgui.ImVec2(0.0, 150.0), imgui.ChildFlags_.borders)
    if ps.search:
        for p in s.prim_paths(ps.search)[:500]:
            if imgui.selectable(p, p == s.selected)[0]:
                s.select(p)
    else:
        _tree(s, "/")
    imgui.end_child()
    if s.selected:
        imgui.text(s.selected)
        if imgui.button("frame (F)"):
            s.frame_selection()
        imgui.begin_child("props", imgui.ImVec2(0.0, 0.0), imgui.ChildFlags_.borders)
        for k, v in s.properties(s.selected):
            imgui.text_colored(_GREY, k)
            imgui.same_line(160.0)
            imgui.text(v)
        imgui.end_child()
    _, ps.edits_path = imgui.input_text("##edits", ps.edits_path)
    imgui.same_line()
    if imgui.button("save edits"):
        out = s.save_edits(ps.edits_path)
        ps.last_saved = f"saved {out}" if out else ""
    if ps.last_saved:
        imgui.text_colored(_GREY, ps.last_saved)


def _materials_tab(s: PreviewSession) -> None:
    """Each material: its source, every input (constant / texture / primvar, with what
    the texture became on the GPU) and what fell back."""
    for rec in s.materials():
        imgui.push_id(rec["path"])
        label = f"{rec['path']}  ({rec['source']}, {rec['meshes']} meshes)"
        if imgui.tree_node(label):
            for name, kind, text in rec["inputs"]:
                imgui.text_colored(_GREY, name)
                imgui.same_line(140.0)
                imgui.text(f"{kind}: {text}" if kind != "constant" else text)
            for w in rec["warnings"]:
                imgui.text_colored(_RED, w)
            for n in rec["notes"]:
                imgui.text_colored(_GREY, n)
            imgui.tree_pop()
        imgui.pop_id()


def _tree(s: PreviewSession, path: str) -> None:
    for c in s.children(path):
        name = c.rsplit("/", 1)[-1]
        leaf = not s.children(c)
        flags = imgui.TreeNodeFlags_.open_on_arrow | imgui.TreeNodeFlags_.span_avail_width
        if leaf:
            flags |= imgui.TreeNodeFlags_.leaf | imgui.TreeNodeFlags_.no_tree_push_on_open
        if c == s.selected:
            flags |= imgui.TreeNodeFlags_.selected
        is_open = imgui.tree_node_ex(f"{name}##{c}", flags)
        if imgui.is_item_clicked() and not imgui.is_item_toggled_open():
            s.select(c)
        if is_open and not leaf:
            _tree(s, c)
            imgui.tree_pop()


def _time_tab(s: PreviewSession) -> None:
    rng = s.time_range()
    if rng is None:
        imgui.text("the stage has no authored time range")
        return
    t = s.time if s.time is not None else rng[0]
    if imgui.button("pause" if s.playing else "play"):
        s.set_playing(not s.playing)
    imgui.same_line()
    imgui.text(f"time {t:g}  [{rng[0]:g}, {rng[1]:g}]")
    ch, v = imgui.slider_float("time code", float(t), rng[0], rng[1], "%.1f")
    if ch:
        s.set_time(v)
