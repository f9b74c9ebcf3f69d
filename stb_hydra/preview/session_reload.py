"""Live reload of a :class:`~stb_hydra.preview.session.PreviewSession`
(:class:`LiveReload`): watching the stage's layer files and the textures it reads
(watchdog), reloading a changed layer once its file has been quiet for
:data:`RELOAD_SETTLE_S`, and keeping the last good scene when a layer no longer parses.
"""

from __future__ import annotations

import os
import threading
import time as _time
from typing import TYPE_CHECKING, Any

from .session_state import SessionState

if TYPE_CHECKING:
    from watchdog.events import FileSystemEvent

#: Live reload: a changed layer is reloaded once its file has been quiet this long (s);
#: editors often write a file in several steps.
RELOAD_SETTLE_S = 0.2

#: watchdog events that do not change a file: reading a layer (ours, on every reload)
#: opens and closes it, and counting those queued a reload of our own every 0.25 s.
_READ_ONLY_EVENTS = frozenset({"opened", "closed_no_write"})


def changes_file(event: FileSystemEvent) -> bool:
    """Does this watchdog event write, create, move or delete its file?"""
    return event.event_type not in _READ_ONLY_EVENTS


class LiveReload(SessionState):
    """The live-reload part of the session (``watch``; ``step`` reloads)."""

    _observer: Any
    _lock: threading.Lock
    _changed_files: set[str]
    _changed_at: float
    reloads: int
    texture_reloads: int
    _watch_files: set[str]
    _watch_dirs: set[str]
    _watch_handler: Any

    # -- live reload --
    def watch(self) -> bool:
        """Watch the stage's layer files (watchdog): a change reloads that layer on the
        next frame (the camera and edits stay); a layer that no longer parses keeps
        the last good scene and says why in :attr:`message`. False if not watchable."""
        if not self.ok or self._observer is not None:
            return False
        try:
            from watchdog.events import FileSystemEventHandler
            from watchdog.observers import Observer
        except ImportError:
            self.message = "live reload needs watchdog (the preview extra)"
            return False
        files = self._watched_files()
        session = self

        class _Handler(FileSystemEventHandler):
            def on_any_event(self, event: FileSystemEvent) -> None:
                if not changes_file(event):
                    return
                for p in (event.src_path, getattr(event, "dest_path", "")):
                    if not p:
                        continue
                    real = os.path.realpath(os.fsdecode(p))
                    if real in session._watch_files:
                        with session._lock:
                            session._changed_files.add(real)
                            session._changed_at = _time.monotonic()

        self._watch_files = files
        self._watch_handler = _Handler()
        obs = Observer()
        for d in sorted({os.path.dirname(f) for f in files}):
            obs.schedule(self._watch_handler, d, recursive=False)
            self._watch_dirs.add(d)
        obs.daemon = True
        obs.start()
        self._observer = obs
        return True

    def _watched_files(self) -> set[str]:
        """The stage's layer files and the texture files the renderer reads."""
        files = {
            os.path.realpath(layer.realPath)
            for layer in self.stage.GetUsedLayers()
            if layer.realPath and not layer.anonymous
        }
        if self.engine is not None:
            files |= {os.path.realpath(p) for p in self.engine.delegate.texture_files()}
        return files

    def _rewatch(self) -> None:
        """Textures (and layers) that appeared since the watch began are watched too."""
        if self._observer is None:
            return
        files = self._watched_files()
        if files <= self._watch_files:
            return
        self._watch_files = self._watch_files | files
        for d in sorted({os.path.dirname(f) for f in files} - self._watch_dirs):
            self._observer.schedule(self._watch_handler, d, recursive=False)
            self._watch_dirs.add(d)

    def _reload_changed(self) -> None:
        """Reload the layers whose files changed (after RELOAD_SETTLE_S of quiet)."""
        from pxr import Tf

        from ..scene.stage_io import tf_message

        with self._lock:
            if not self._changed_files or _time.monotonic() - self._changed_at < RELOAD_SETTLE_S:
                return
            changed, self._changed_files = self._changed_files, set()
        errors = []
        layers = {
            os.path.realpath(layer.realPath): layer
            for layer in self.stage.GetUsedLayers()
            if layer.realPath
        }
        textures = changed - set(layers)
        if textures and self.engine is not None:
            self.engine.reload_files(textures)
            self.texture_reloads += 1
        touched = [(real, layer) for real, layer in layers.items() if real in changed]
        for real, layer in touched:
            try:
                ok = layer.Reload(force=True)
            except Tf.ErrorException as exc:
                ok = False
                errors.append(f"cannot reload '{real}': {tf_message(exc, stage_file=real)}")
                continue
            if not ok:
                errors.append(f"cannot reload '{real}': unreadable or missing")
        if touched:
            self.reloads += 1
        if errors:
            self.message = "; ".join(errors) + " (showing the last good scene)"
        elif self.message and "cannot reload" in self.message:
            self.message = None
        self._scene_dirty = True
