"""The soak tool's short variant (issue 21, item 5): a dynamic scene (orbs spawning,
flying, dying at the time wrap, dynamic shadows under the real-time budget, STB with
taa, an orbiting camera) for 240 frames at 64x36 with the shadow atlas' invariants
checked every frame (docs/RELIABILITY.md). The scene's 24-frame time range wraps 10
times (every orb dies and respawns ten times: what leaks at a wrap shows by the
second), the camera turns an eighth of an orbit; it ran 500 frames (20 wraps) until
issue 32 halved it. Memory and time limits are loose here (a shared CI machine);
``tools/soak.py --frames 10000`` is the real run."""

from __future__ import annotations

import json

import pytest


@pytest.mark.slow
def test_soak_short_variant_keeps_atlas_invariants(gl_ctx, tmp_path):
    from tools import soak

    out = tmp_path / "soak.json"
    code = soak.main(
        [
            "--frames", "240", "--block", "48", "--orbs", "12", "--scene-frames", "24",
            "--size", "64x36", "--max-growth", "0.5", "--max-slowdown", "10",
            "--json", str(out),
        ]
    )  # fmt: skip
    doc = json.loads(out.read_text())
    assert doc["violations"] == []
    assert [b["frames"] for b in doc["blocks"]] == [48, 96, 144, 192, 240]
    assert all(b["mean_ms"] > 0 and b["rss_mib"] > 0 for b in doc["blocks"])
    assert code == 0


def test_engine_timings_stay_bounded():
    """A long-running engine keeps a bounded window of per-frame timings (the soak's
    memory growth: one dict per frame, for ever), newest last."""
    from stb_hydra import limits
    from stb_hydra.renderer.frame import Timings

    t = Timings()
    keep = limits.TIMINGS_KEPT_FRAMES
    for i in range(5 * keep + 3):
        t.start_frame()
        t.add("pass", float(i))
        t.end_frame()
        assert len(t.frames) < 2 * keep
    assert len(t.frames) >= keep
    assert t.frames[-1] == {"pass": float(5 * keep + 2)}
    assert [f["pass"] for f in t.frames] == list(range(5 * keep + 3 - len(t.frames), 5 * keep + 3))
