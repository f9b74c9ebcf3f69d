"""The spread of the convergence tests' statistics over seeds (issue 32,
docs/TESTING.md "Convergence tests"): how many frames a case needs for its bounds.

For one case of the suite's unbiasedness tests, renders the case's scene with several
seeds and prints, per seed, ``tests/convergence.py``'s statistics at the frame count
given: relMSE, relMSE at M / 8, the split-half squared bias and the image mean's ratio.

    PYTHONPATH=.:tests .venv/bin/python tools/convergence_spread.py reuse:0 --frames 64
    PYTHONPATH=.:tests .venv/bin/python tools/convergence_spread.py stb:all-stream --frames 256
    PYTHONPATH=.:tests .venv/bin/python tools/convergence_spread.py spots:ies:share --frames 128

Cases: ``reuse:I`` (the I-th option set of ``test_stb_reuse.py``'s closed-form test),
``stb:SELECT-BIGTILE`` (``test_stb.py``'s reference test), ``spots[:ies][:share]``
(the tile-target spot / IES test). Needs ``tests/`` on the path (the scenes are the
tests' own).
"""

from __future__ import annotations

import argparse
import json

import numpy as np


def _case(name: str):
    """(stage, truth, width, height, options, channel or None) of a test case."""

    kind, _, arg = name.partition(":")
    if kind == "reuse":
        import test_stb_reuse as r

        mark = next(
            m
            for m in r.test_unbiased_mean_converges_to_closed_form.pytestmark
            if m.name == "parametrize"
        )
        stage, truth = r.many_lights_scene()
        return stage, truth, r.W, r.H, dict(r.UNBIASED, **mark.args[1][int(arg)][0]), 0
    select, dash, bigtile = arg.partition("-")
    if kind == "stb" and dash:
        import test_stb as t

        stage, truth, (w, h), opts = t.unbiased_case(select, bigtile)
        return stage, truth, w, h, opts, None
    if kind == "spots":
        import test_stb_reuse as r

        flags = set(arg.split(":")) if arg else set()
        stage, truth = r.spot_scene_and_reference("ies" in flags)
        opts = dict(r.TILE_SPOTS, **({"reuse_res": "share"} if "share" in flags else {}))
        return stage, truth, r.W, r.H, opts, 0
    raise SystemExit(
        f"convergence_spread: unknown case {name!r} (reuse:I, stb:S-B, spots[:ies][:share])"
    )


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("case")
    ap.add_argument("--frames", type=int, default=64, help="M (a multiple of 8)")
    ap.add_argument("--seeds", default="0,1,2", help="comma-separated seeds")
    args = ap.parse_args(argv)

    from convergence import convergence, snapshot_counts

    import stb_hydra

    stage, truth, w, h, opts, chan = _case(args.case)
    for seed in (int(s) for s in args.seeds.split(",")):
        imgs = stb_hydra.render_progressive(
            stage, snapshot_counts(args.frames), width=w, height=h, lighting="stb", seed=seed,
            **opts,
        )  # fmt: skip
        if chan is not None:
            imgs = {n: im[..., chan] for n, im in imgs.items()}
        c = convergence(imgs, np.asarray(truth))
        print(json.dumps({"case": args.case, "seed": seed, **c.__dict__}), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
