"""xatlas in a throwaway child process: one packing per child, which leaves without
destroying its atlas.

Why: xatlas 0.0.11 (the C++ library's ``TaskScheduler``) can hang for ever when an
``Atlas`` is destroyed. The destructor wakes its worker threads without holding their
mutexes; a worker that has just tested its wake-up flag and not yet blocked misses the
wake-up, and the destructor then waits in ``join`` for it. Found in the test suite on
the loaded 2-core machine (a bake stuck in ``xatlas::Destroy`` -> ``~TaskScheduler`` ->
``std::thread::join``, the worker in ``condition_variable::wait``; docs/TESTING.md,
"A hang in xatlas"). The window is short, but a preempted worker sits in it; nothing
in the Python API can reach the scheduler, and a destructor runs with the GIL held, so
a hang there stops the whole process.

So no ``Atlas`` is ever destroyed in the calling process: :func:`generate` runs one
packing in a child (forked from a fork server that has imported this module, a few
ms a child; spawned where there is no fork server), the child sends the result back
and ends with ``os._exit`` -- its atlas is never destroyed, and the process's exit
frees everything. A child that dies (a crash in xatlas) raises ``RuntimeError`` here;
nothing hangs.
"""

from __future__ import annotations

import multiprocessing
import os
import threading
from typing import Any

import numpy as np

__all__ = ["generate"]

_lock = threading.Lock()
_ctx: Any = None  # a multiprocessing context (fork server or spawn)
#: A child's atlases: kept so that no destructor runs before ``os._exit``.
_kept: list = []


def _context() -> Any:
    """The start method for the children: a fork server (POSIX; this module preloaded,
    so a child starts with xatlas imported), else spawn."""
    global _ctx
    with _lock:
        if _ctx is None:
            if "forkserver" in multiprocessing.get_all_start_methods():
                _ctx = multiprocessing.get_context("forkserver")
                _ctx.set_forkserver_preload(["__main__", __name__])
            else:
                _ctx = multiprocessing.get_context("spawn")
        return _ctx


def _pack_here(
    points: np.ndarray, tris: np.ndarray, texels_per_unit: float, padding: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, int]:
    """One xatlas packing in this process: (vmapping, indices, uvs in [0, 1], [w, h]
    texels, atlas count); the first atlas's arrays (empty when there is none). The
    ``Atlas`` object is kept in ``_kept``: call this only in a child that ends with
    ``os._exit``."""
    import xatlas

    atlas = xatlas.Atlas()
    atlas.add_mesh(
        np.ascontiguousarray(points, dtype=np.float32), np.ascontiguousarray(tris, np.uint32)
    )
    po = xatlas.PackOptions()
    po.texels_per_unit = float(texels_per_unit)
    po.padding = int(padding)
    po.bilinear = True
    po.resolution = 0
    atlas.generate(xatlas.ChartOptions(), po)
    count = int(atlas.atlas_count)
    if count >= 1:
        vmap, idx, uvs = atlas[0]
    else:
        vmap = idx = np.zeros(0, np.uint32)
        uvs = np.zeros((0, 2), np.float32)
    size = np.array([atlas.width, atlas.height])
    _kept.append(atlas)  # never destroyed in the child (it ends with os._exit)
    return np.asarray(vmap), np.asarray(idx), np.asarray(uvs), size, count


def _child(conn, points, tris, texels_per_unit, padding) -> None:  # pragma: no cover - child
    try:
        out: tuple[str, Any]
        try:
            out = ("ok", _pack_here(points, tris, texels_per_unit, padding))
        except Exception as exc:  # noqa: BLE001 - xatlas raises bare RuntimeErrors
            out = ("error", " ".join(str(exc).split())[:300] or type(exc).__name__)
        conn.send(out)
        conn.close()
    finally:
        os._exit(0)


def generate(
    points: np.ndarray, tris: np.ndarray, texels_per_unit: float, padding: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, int]:
    """One xatlas packing of the mesh (``points`` (n, 3) m, ``tris`` (m, 3) indices) at
    ``texels_per_unit`` texels/m with ``padding`` texels between charts, in a child
    process (module docstring): (vmapping, indices, uvs normalised to [0, 1], [w, h]
    texels, atlas count). Raises ``RuntimeError`` with xatlas's message, or when the
    child ends without a result."""
    ctx = _context()
    recv, send = ctx.Pipe(duplex=False)
    proc = ctx.Process(
        target=_child,
        args=(
            send,
            np.ascontiguousarray(points, dtype=np.float32),
            np.ascontiguousarray(tris, dtype=np.uint32),
            float(texels_per_unit),
            int(padding),
        ),
        daemon=True,
    )
    proc.start()
    send.close()
    try:
        status, value = recv.recv()
    except EOFError:
        proc.join()
        code = proc.exitcode
        raise RuntimeError(f"the xatlas child ended without a result (exit code {code})") from None
    finally:
        recv.close()
    proc.join()
    if status != "ok":
        raise RuntimeError(value)
    return value
