"""Every hard limit of stb_hydra in one place, each with the reason it exists.

Units: metres, candela (cd), lux (lx), lumen (lm), nits (cd/m^2), pixels (px).
Change a value here, never a literal in a module or shader: shaders receive these
through the ``#define`` header the loader writes (``render.gl.limit_defines``).
"""

from __future__ import annotations

import math

# --- Light extraction (scene/lights.py) -----------------------------------------------

#: Illuminance (lux) under which a light's contribution is treated as zero; sets
#: the automatic influence radius r = sqrt(I_max / LIGHT_CUTOFF_LUX) used for
#: culling. 0.05 lx is ~4 stops under moonlight: invisible at the exposures of
#: night scenes (1 lx ~ mid grey) and far below indoor levels (100-500 lx).
LIGHT_CUTOFF_LUX = 0.05

#: Fraction of the influence radius where the smooth range window starts. Past it
#: the light fades with a smoothstep to exactly 0 at the radius, so culling never
#: pops. Inside it falloff is the exact inverse square (closed-form tests hold).
RANGE_FADE_START = 0.9

#: Smallest / largest automatic influence radius (m). The floor keeps tiny lights
#: from being culled before they light their own fixture; the ceiling keeps a
#: mis-authored 1e9 cd light from covering the whole world's culling grid.
MIN_LIGHT_RANGE_M = 0.05
MAX_LIGHT_RANGE_M = 10_000.0

#: |exposure| beyond this is treated as a data error (2^30 ~ 1e9): warning + light off.
MAX_ABS_EXPOSURE = 30.0

#: Luminous intensity (cd) above which a light is rejected as non-physical. The
#: brightest searchlights are ~1e9 cd; fp32 math on I/d^2 must stay finite.
MAX_INTENSITY_CD = 1.0e12

#: Distance floor (m) in every inverse-square evaluation: 1/d^2 must stay finite
#: for a light sitting on a surface. 1 mm is below any visible feature.
MIN_LIGHT_DISTANCE_M = 1.0e-3

#: Colour-temperature range accepted by UsdLux (K); values are clamped to it.
COLOR_TEMPERATURE_RANGE_K = (1000.0, 10000.0)

# --- Light buffer / FoV list (render) --------------------------------------------------

#: Index bits in a packed 32-bit STB sample (see STB "Sample packing" below). The
#: FoV-culled light list can hold at most 2^17 - 1 lights; code 2^17 - 1 is "empty".
SAMPLE_INDEX_BITS = 17
MAX_FOV_LIGHTS = (1 << SAMPLE_INDEX_BITS) - 1  # 131071
EMPTY_LIGHT_INDEX = (1 << SAMPLE_INDEX_BITS) - 1

#: Weight bits: log2-encoded, 512 steps per octave over [2^-32, 2^32).
#: Relative quantisation error <= 2^(1/1024) - 1 = 0.068 %, far under MC noise.
SAMPLE_WEIGHT_BITS = 32 - SAMPLE_INDEX_BITS  # 15
SAMPLE_WEIGHT_LOG2_MIN = -32.0
SAMPLE_WEIGHT_STEPS_PER_OCTAVE = 512
SAMPLE_WEIGHT_MAX = 2.0 ** 32

#: fp16 (render targets rgba16f) tops out at 65504; every lighting output is
#: clamped under it so no Inf is ever written.
HALF_MAX = 65504.0

# --- IES --------------------------------------------------------------------------------

#: Baked (theta, phi) table per profile for the GPU: theta 0..180 deg, phi 0..360 deg.
#: 256 theta rows resolve the luxtest 10-degree stripes and 0.5-degree source grids
#: to < 1 deg; 64 phi columns (5.6 deg) are enough for real asymmetric luminaires.
IES_TABLE_THETA = 256
IES_TABLE_PHI = 64

#: Profiles per texture array (GL_MAX_ARRAY_TEXTURE_LAYERS is >= 2048 on GL 4.5).
MAX_IES_PROFILES = 256

# --- Tiles (STB) ------------------------------------------------------------------------

BIG_TILE_PX = 128
SMALL_TILE_PX = 16
QUAD_PX = 2
#: Big-tile reservoir slots K: 16 in the talk; 4..64 for the trade-off study.
BIG_TILE_SLOTS_DEFAULT = 16
BIG_TILE_SLOTS_ALLOWED = (4, 8, 16, 32, 64)
#: Small-tile samples N: one RGBA32UI texel holds at most 4.
SMALL_TILE_SAMPLES_MAX = 4

# --- Shadows ----------------------------------------------------------------------------

SHADOW_ATLAS_SIZE_DEFAULT = 4096

# --- Misc -------------------------------------------------------------------------------

#: Tiny positive PDF floor keeps every sampling weight finite (no 0/0).
PDF_EPSILON = 1.0e-20

TWO_PI = 2.0 * math.pi
