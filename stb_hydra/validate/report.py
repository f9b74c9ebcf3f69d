"""Reports of a validation run: console summary (rich), JSON document, HTML page.

JSON schema (``schema`` = 1; docs/VALIDATE.md)::

    {"schema": 1, "tool": "stb validate", "stb_hydra": str, "usd": str,
     "fail_on": "error"|"warning", "rules": [validator names],
     "summary": {"assets": n, "status": {status: n}, "findings": {severity: n},
                 "rules": {rule: n}, "wall_s": s, "jobs": n},
     "assets": [{"path", "root", "status", "opened", "findings": [{"rule",
                 "severity", "prim", "message", "hint", "validator"}],
                 "timings": {"scan", "open", "validate", "thumbnail", "total"},
                 "stats": {"lights", "meshes"}}]}
"""

from __future__ import annotations

import contextlib
import html
import json
import os
import sys
from collections import Counter
from collections.abc import Sequence

from .findings import SEVERITIES, AssetReport, severity_rank

SCHEMA_VERSION = 1
_STATUS_ORDER = ("crash", "error", "warning", "ok")


def summary(reports: Sequence[AssetReport], wall_s: float, jobs: int) -> dict:
    status = Counter(r.status for r in reports)
    sev = Counter(f.severity for r in reports for f in r.findings)
    rules = Counter(f.rule for r in reports for f in r.findings)
    return {
        "assets": len(reports),
        "status": {k: status.get(k, 0) for k in _STATUS_ORDER},
        "findings": {k: sev.get(k, 0) for k in SEVERITIES[::-1]},
        "rules": dict(sorted(rules.items(), key=lambda kv: (-kv[1], kv[0]))),
        "wall_s": round(wall_s, 3),
        "jobs": jobs,
    }


def document(
    reports: Sequence[AssetReport],
    wall_s: float,
    jobs: int,
    fail_on: str,
    validators: Sequence[str],
) -> dict:
    """The ``--json`` document (thumbnails are left out: see ``--html``)."""
    from pxr import Usd

    import stb_hydra

    assets = []
    for r in reports:
        d = r.to_dict()
        d.pop("thumbnail_png_b64", None)
        assets.append(d)
    ver = Usd.GetVersion()
    return {
        "schema": SCHEMA_VERSION,
        "tool": "stb validate",
        "stb_hydra": stb_hydra.__version__,
        "usd": ".".join(str(v) for v in ver[1:]) if ver[0] == 0 else ".".join(map(str, ver)),
        "fail_on": fail_on,
        "rules": list(validators),
        "summary": summary(reports, wall_s, jobs),
        "assets": assets,
    }


def _write_atomic(path: str, write) -> None:
    """``write(f)`` into ``path``'s temporary sibling, then rename it onto ``path``; on
    any failure the temporary file is removed and ``path`` is left as it was."""
    tmp = f"{path}.tmp-{os.getpid()}"
    try:
        with open(tmp, "w", encoding="utf-8") as f:
            write(f)
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise


def write_json(path: str, doc: dict) -> None:
    def write(f) -> None:
        json.dump(doc, f, indent=1)
        f.write("\n")

    _write_atomic(path, write)


def _rel(r: AssetReport) -> str:
    try:
        return os.path.relpath(r.path, r.root)
    except ValueError:
        return r.path


def print_console(
    reports: Sequence[AssetReport], summ: dict, fail_on: str, max_rows: int = 60, file=None
) -> None:
    """Summary table of the assets with findings, then the findings themselves."""
    from rich.console import Console
    from rich.table import Table

    out = file or sys.stdout
    con = Console(file=out, width=None if out.isatty() else 200, highlight=False)
    bad = [r for r in reports if r.findings]
    bad.sort(key=lambda r: (-r.worst(), _rel(r)))
    colour = {
        "crash": "magenta",
        "error": "red",
        "warning": "yellow",
        "ok": "green",
        "info": "blue",
    }
    if bad:
        t = Table(title="stb validate: assets with findings", show_lines=False)
        for col in ("asset", "status", "errors", "warnings", "info", "rules"):
            t.add_column(col, overflow="fold")
        for r in bad[:max_rows]:
            c = Counter(f.severity for f in r.findings)
            rules = Counter(f.rule for f in r.findings)
            t.add_row(
                _rel(r),
                f"[{colour.get(r.status, 'white')}]{r.status}[/]",
                str(c.get("error", 0)),
                str(c.get("warning", 0)),
                str(c.get("info", 0)),
                ", ".join(f"{k}" + (f" x{v}" if v > 1 else "") for k, v in rules.most_common(4)),
            )
        con.print(t)
        if len(bad) > max_rows:
            con.print(f"... and {len(bad) - max_rows} more assets with findings (see --json)")
        shown = 0
        total = sum(1 for r in bad for f in r.findings if severity_rank(f.severity) >= 1)
        for r in bad:
            lines = [f for f in r.findings if severity_rank(f.severity) >= 1]
            if not lines or shown >= max_rows * 2:
                continue
            con.print(f"[bold]{_rel(r)}[/]")
            for f in lines:
                if shown >= max_rows * 2:
                    break
                shown += 1
                con.print(
                    f"  [{colour[f.severity]}]{f.severity:7}[/] {f.rule}  <{f.prim}>  "
                    f"{f.message}" + (f" [dim](fix: {f.hint})[/]" if f.hint else ""),
                    markup=True,
                    soft_wrap=True,
                )
        if total > shown:
            con.print(f"... {total - shown} more findings (see --json)")
    s = summ
    st = s["status"]
    fs = s["findings"]
    con.print(
        f"[bold]{s['assets']} assets[/] in {s['wall_s']:.1f} s (jobs {s['jobs']}): "
        f"[green]{st['ok']} ok[/], [yellow]{st['warning']} warning[/], "
        f"[red]{st['error']} error[/], [magenta]{st['crash']} crash[/]; findings: "
        f"{fs['error']} errors, {fs['warning']} warnings, {fs['info']} info "
        f"(fail on {fail_on})"
    )


_CSS = """
body{font:13px/1.4 system-ui,sans-serif;margin:1.5em;color:#222}
table{border-collapse:collapse;width:100%}
th,td{border-bottom:1px solid #ddd;padding:4px 6px;vertical-align:top;text-align:left}
th{background:#f4f4f4;position:sticky;top:0}
.st{font-weight:600;border-radius:3px;padding:1px 6px;color:#fff}
.ok{background:#2e7d32}.warning{background:#b8860b}.error{background:#c62828}
.crash{background:#6a1b9a}.info{background:#1565c0}
td.f table td{border:none;padding:1px 4px;font-size:12px}
code{font-size:12px}.hint{color:#666}
img{image-rendering:auto;border:1px solid #ccc;background:#000}
"""


def write_html(
    path: str, reports: Sequence[AssetReport], summ: dict, fail_on: str, thumbnails: bool
) -> None:
    """One row per asset: (thumbnail), path, status, timings, findings."""
    e = html.escape
    rows = []
    for r in reports:
        thumb = ""
        if thumbnails:
            if r.thumbnail_png_b64:
                thumb = f'<img alt="thumbnail" src="data:image/png;base64,{r.thumbnail_png_b64}">'
            else:
                thumb = "<span class=hint>no thumbnail</span>"
        fl = "".join(
            f"<tr><td><span class='st {e(f.severity)}'>{e(f.severity)}</span></td>"
            f"<td><code>{e(f.rule)}</code></td><td><code>{e(f.prim)}</code></td>"
            f"<td>{e(f.message)}"
            + (f"<br><span class=hint>fix: {e(f.hint)}</span>" if f.hint else "")
            + "</td></tr>"
            for f in r.findings
        )
        tm = r.timings.get("total", 0.0)
        rows.append(
            "<tr>"
            + (f"<td>{thumb}</td>" if thumbnails else "")
            + f"<td><code>{e(_rel(r))}</code><br><span class=hint>"
            f"{r.stats.get('lights', '-')} lights, {r.stats.get('meshes', '-')} meshes, "
            f"{tm * 1000:.0f} ms</span></td>"
            f"<td><span class='st {e(r.status)}'>{e(r.status)}</span></td>"
            f"<td class=f>" + (f"<table>{fl}</table>" if fl else "-") + "</td></tr>"
        )
    st, fs = summ["status"], summ["findings"]
    head = ("<th>thumbnail</th>" if thumbnails else "") + (
        "<th>asset</th><th>status</th><th>findings</th>"
    )
    doc = f"""<!DOCTYPE html>
<html><head><meta charset="utf-8"><title>stb validate</title><style>{_CSS}</style></head>
<body><h1>stb validate</h1>
<p>{summ["assets"]} assets in {summ["wall_s"]:.1f} s: {st["ok"]} ok, {st["warning"]} warning,
{st["error"]} error, {st["crash"]} crash. Findings: {fs["error"]} errors, {fs["warning"]}
warnings, {fs["info"]} info. Fail on: {e(fail_on)}.</p>
<table><thead><tr>{head}</tr></thead><tbody>
{"".join(rows)}
</tbody></table></body></html>
"""
    _write_atomic(path, lambda f: f.write(doc))
