#!/usr/bin/env python3
"""Command-line wrapper of :mod:`stb_hydra.scenegen.orbs` (same as
``python -m stb_hydra.scenegen.orbs``); run from the checkout with the package installed.

    python tools/gen_orbs.py --help
"""

import sys

from stb_hydra.scenegen.orbs import main

if __name__ == "__main__":
    sys.exit(main())
