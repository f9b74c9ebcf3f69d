"""Plain output files (JSON reports, stats): checked before the work, written atomically
with the mode of any new file.

``tempfile.mkstemp`` creates 0600 files; a report renamed into place from it would
stay 0600 while the images beside it are 0644. :func:`new_file_mode` is what
``open(path, "w")`` would give (0666 minus the umask, or the mode of the file being
replaced); the image writer (:mod:`stb_hydra.io.images`) uses it too.
"""

from __future__ import annotations

import os
import stat
import tempfile
from pathlib import Path

PathLike = str | os.PathLike[str]


class FileWriteError(OSError):
    """A file cannot be written; ``str()`` is one line naming the path and reason."""

    def __init__(self, path: PathLike, reason: str) -> None:
        self.path = os.fspath(path)
        self.reason = " ".join(str(reason).split())
        super().__init__(f"cannot write '{self.path}': {self.reason}")


def current_umask() -> int:
    """The process umask (read from /proc without changing it where possible)."""
    try:
        with open("/proc/self/status", encoding="ascii") as f:
            for line in f:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError):
        pass
    mask = os.umask(0o022)  # not thread-safe; only where /proc is unavailable
    os.umask(mask)
    return mask


def new_file_mode(path: PathLike) -> int:
    """The permission bits for writing ``path``: those of the file it replaces, else
    0666 minus the umask."""
    try:
        return stat.S_IMODE(Path(os.fspath(path)).stat().st_mode)
    except FileNotFoundError:
        return 0o666 & ~current_umask()


def check_file_path(path: PathLike, what: str | None = None) -> None:
    """Raise :class:`FileWriteError` now if ``path`` cannot be written later: its
    directory exists, is a directory and is writable; the target is not a directory.
    ``what`` (e.g. ``--stats``) prefixes the reason."""
    p = Path(os.fspath(path))
    parent = p.parent
    pre = f"{what}: " if what else ""
    if not parent.exists():
        raise FileWriteError(p, f"{pre}directory does not exist: '{parent}'")
    if not parent.is_dir():
        raise FileWriteError(p, f"{pre}not a directory: '{parent}'")
    if p.is_dir():
        raise FileWriteError(p, f"{pre}the target is a directory")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise FileWriteError(p, f"{pre}directory is not writable: '{parent}'")


def write_text_atomic(path: PathLike, text: str) -> Path:
    """Write ``text`` to ``path`` through a temporary file in the same directory and
    a rename (never a half-written file), with :func:`new_file_mode`."""
    p = Path(os.fspath(path))
    try:
        fd, tmp_name = tempfile.mkstemp(prefix=f".{p.name}.tmp-", dir=p.parent)
    except OSError as exc:
        raise FileWriteError(p, exc.strerror or str(exc)) from None
    tmp = Path(tmp_name)
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            f.write(text)
        os.chmod(tmp, new_file_mode(p))
        os.replace(tmp, p)
    except BaseException as exc:
        tmp.unlink(missing_ok=True)
        if isinstance(exc, OSError):
            raise FileWriteError(p, exc.strerror or str(exc)) from None
        raise
    return p


def write_csv_atomic(path: PathLike, rows: list[dict], fields: list[str]) -> Path:
    """``rows`` as CSV with the header ``fields`` (keys not in ``fields`` ignored),
    formatted in memory first and written by :func:`write_text_atomic`: a row that
    cannot be formatted leaves any old file as it was."""
    import csv
    import io

    buf = io.StringIO(newline="")
    w = csv.DictWriter(buf, fieldnames=fields, extrasaction="ignore")
    w.writeheader()
    for r in rows:
        w.writerow(r)
    return write_text_atomic(path, buf.getvalue())
