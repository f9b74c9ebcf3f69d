#!/usr/bin/env python3
"""Command-line wrapper of :mod:`stb_hydra.scenegen.lights` (same as
``python -m stb_hydra.scenegen.lights``); run from the checkout with the package installed.

    python tools/gen_lights_scene.py --help
"""

import sys

from stb_hydra.scenegen.lights import main

if __name__ == "__main__":
    sys.exit(main())
