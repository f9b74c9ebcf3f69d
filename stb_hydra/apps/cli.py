"""The ``stb`` command: one verb per module in ``stb_hydra.apps``."""

from __future__ import annotations

import argparse
import importlib
import sys

VERBS = ("render", "inspect", "bench", "validate", "tradeoff")


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(
        prog="stb",
        description="stb_hydra: USD scenes with many lights, Stochastic Tile-Based lighting.",
    )
    sub = ap.add_subparsers(dest="verb", required=True)
    for verb in VERBS:
        try:
            mod = importlib.import_module(f"stb_hydra.apps.{verb}")
        except ImportError:
            continue
        mod.add_parser(sub)
    return ap


def main(argv: list[str] | None = None) -> int:
    ap = build_parser()
    args = ap.parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except KeyboardInterrupt:
        print("stb: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
