#!/usr/bin/env python3
"""Command-line wrapper of :mod:`stb_hydra.scenegen.chess` (same as
``python -m stb_hydra.scenegen.chess``); run from the checkout with the package installed.

    python tools/gen_chess_lights.py --help
"""

import sys

from stb_hydra.scenegen.chess import main

if __name__ == "__main__":
    sys.exit(main())
