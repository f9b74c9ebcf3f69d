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

#: Largest coordinate or transform entry (m) accepted for a light, mesh or camera
#: (issue 21, tools/fuzz.py): beyond it float32 maths on the GPU overflows (squared
#: distances past 3.4e38) and the prim is a data error (1e15 m is ~6700 au).
MAX_COORDINATE_M = 1.0e15

#: Largest camera aperture offset accepted, in apertures (a lens shifted 1000 frame
#: widths): past it the frustum's edges cancel in float (1e30 divided by zero).
CAMERA_MAX_APERTURE_OFFSET = 1000.0

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
SAMPLE_WEIGHT_MAX = 2.0**32

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

#: Largest IES file read (bytes). Real files are < 100 KB; a 0.1-degree full-sphere
#: table is ~10 MB of text, so anything bigger is not photometry.
IES_MAX_FILE_BYTES = 16 * 1024 * 1024

#: Most vertical / horizontal angles per axis: 0.1-degree steps over 360 degrees is 3601.
IES_MAX_ANGLES = 4096

#: Smallest step (degrees) between successive IES angles. Files give angles with at
#: most 4 decimals; a 1e-320 degree step (subnormal) divided interpolation weights to
#: NaN (tools/fuzz.py, docs/RELIABILITY.md).
IES_MIN_ANGLE_STEP_DEG = 1.0e-6

#: Most candela values (n_vertical * n_horizontal): 8 MB of float64, ~a 0.25-degree
#: full-sphere grid; caps memory before a hostile header can make us allocate.
IES_MAX_CANDELA_VALUES = 1_000_000

#: Most TILT=INCLUDE angle/factor pairs (1-degree steps over 0..180 is 181).
IES_MAX_TILT_PAIRS = 1024

# --- Tiles (STB) ------------------------------------------------------------------------

#: Big tile side (px) of the talk's pipeline (``-o reuse=off``).
BIG_TILE_PX = 128
#: ... and under the reservoir reuse, the default of ``--lighting stb`` (issue 31): each
#: pixel resamples its big tile's K reservoirs itself, so a small big tile (K candidates
#: fit to 16 x 16 px) is what its quality rests on (docs/STB_NOTES.md, reuse5).
STB_REUSE_BIG_TILE_PX = 16
#: ... which the reuse's default (``-o big_tile=0``) picks per frame by its light count,
#: so that the big-tile pass keeps a fixed cost (issue 31's 50 -> 5,000 lights row): the
#: smallest of these tiles whose streaming pass evaluates at most
#: STB_REUSE_STREAM_TARGETS_PER_PX light targets per pixel (n / px^2: 16 px up to 512
#: lights, 32 px up to 2,048), else the largest drawing from light clusters with the
#: flux pick inside a cluster (``-o cluster_pick=flux``: one target per slot).
#: Measured in docs/STB_NOTES.md "(fixed cost)".
STB_REUSE_BIG_TILES_PX = (16, 32)
STB_REUSE_STREAM_TARGETS_PER_PX = 2.0
SMALL_TILE_PX = 16
QUAD_PX = 2
#: Big-tile reservoir slots K: 16 in the talk; 4..64 for the trade-off study. Default 64
#: (issue 13, measured in docs/STB_NOTES.md): each slot streams n/K of the lights, so the
#: big-tile pass costs the same for any K, the small-tile pass resamples K candidates per
#: small tile (1/256 of the pixels), and with n <= K lights in view the big tile holds
#: every light (no big-tile noise at all).
BIG_TILE_SLOTS_DEFAULT = 64
BIG_TILE_SLOTS_ALLOWED = (4, 8, 16, 32, 64)
#: Small-tile samples N: one RGBA32UI texel holds at most 4. Default 1 (the talk's fixed
#: cost); `-o N=4 -o select=pixel` (each pixel evaluates one of the 4) is the
#: decorrelated alternative and `-o N=4 -o select=ris` (each pixel resamples the 4 by a
#: cheap target and shades one) the lower-noise one, measured in docs/STB_NOTES.md
#: (issue 13).
SMALL_TILE_SAMPLES_MAX = 4
SMALL_TILE_SAMPLES_DEFAULT = 1
#: Light clusters of the big-tile pass for many lights (issue 16, ``-o bigtile``):
#: FoV lights in Morton order, cut into clusters of BIG_TILE_CLUSTER_LIGHTS, and runs
#: of BIG_TILE_CLUSTER_FANOUT clusters into super-clusters. A big tile scores every
#: super-cluster once (shared by its K slots); each slot then scores the F clusters of
#: the super-cluster it drew and picks one light of the G in the cluster it drew. Cost per
#: tile ~ n / (G F) + K x F scores, plus K x G light targets with ``cluster_pick=target``
#: or K with ``flux``. Issue 16 measured G = F = 16 (docs/PERFORMANCE.md, 5,000 -> 50,000
#: lights: one level of 32-light clusters 1.97x, two levels 1.7-2.1x, two levels reading
#: Morton-ordered light records 1.14x); issue 31's fixed cost took G = 4, F = 8: on the
#: 5,000-light scene the reuse's 32 px flux-pick pass costs the same (14-16 vs 15-18 ms)
#: and its 16-frame still is 10 % better (HDR-FLIP 0.188 vs 0.209; G = 2, F = 16: 0.184
#: for 19-20 ms; G = 1, F = 32: 0.182 for 29 ms; docs/STB_NOTES.md "(fixed cost)").
BIG_TILE_CLUSTER_LIGHTS = 4
BIG_TILE_CLUSTER_FANOUT = 8
#: Most super-clusters (shared-memory CDF of one workgroup: 4 bytes each, 16 KiB):
#: MAX_FOV_LIGHTS / (BIG_TILE_CLUSTER_LIGHTS x BIG_TILE_CLUSTER_FANOUT), rounded up.
BIG_TILE_SUPERS_MAX = 4096
#: With ``cluster_pick=flux`` a big tile scores every cluster itself (one shared CDF, no
#: super level) while there are at most this many (n <= 4 x 2,048 lights); past it the
#: super-clusters come first. Cost per tile n / G scores instead of n / (G F) + K F.
BIG_TILE_CLUSTERS_FLAT_MAX = 2048
#: ``-o bigtile=auto`` uses the clusters above this many FoV lights per slot: below it,
#: streaming n / K lights per slot costs about as much (and is exact WRS).
BIG_TILE_CLUSTER_MIN_LIGHTS_PER_SLOT = 64

# --- Shadows ----------------------------------------------------------------------------

#: Atlas side (texels, power of two). 4096^2 x 16-bit unorm = 32 MiB: holds 16 maps at
#: the max size or 16384 at the min size; fits the memory of the mobile-class targets.
SHADOW_ATLAS_SIZE_DEFAULT = 4096
#: Largest atlas side accepted: GL 4.5 guarantees GL_MAX_TEXTURE_SIZE >= 16384.
SHADOW_ATLAS_SIZE_MAX = 16384
#: Atlas textures a released engine leaves for the next engine of the same GL context
#: (``shadow_capture``'s pool), at most this many bytes in all: allocating and first
#: touching a 4096^2 16-bit atlas costs ~50-100 ms of page faults on llvmpipe, paid
#: again by every new engine (a stage reload, each render of a script or test). 64 MiB
#: keeps two default atlases; a larger one is freed as before.
SHADOW_ATLAS_POOL_BYTES = 64 * 1024 * 1024

#: PCF border (texels) around each map, inside its atlas rect: a 5x5 tent reads
#: +-2 texels around the centre, +1 for the bilinear/gather footprint -> 3.
SHADOW_MAP_BORDER_PX = 3

#: Smallest map side (texels, incl. border): 26 px interior = 66 % of the block; below
#: that the border eats most of the block and the map is no better than no shadow.
SHADOW_MAP_MIN_SIZE = 32
#: Largest map side (texels, incl. border): 1/16 of the default atlas, so one hero
#: light can never take more than a 16th of the shared space (and 1 Mtexel to render).
SHADOW_MAP_MAX_SIZE = 1024

#: Texels rendered per frame by shadow captures (a spot map of side s costs s^2,
#: an omni map SHADOW_OMNI_COST_FACTOR * s^2): 2 Mtexel ~ one 1080p depth pre-pass,
#: so shadow updates never cost more than the G-buffer's depth fill.
SHADOW_UPDATE_BUDGET_TEXELS_DEFAULT = 2 * 1024 * 1024
#: Budget of offline renders (``stb render``, ``stb_hydra.render``) unless one is
#: given: every pending map is captured before the frame that needs it, so a still
#: or an animation frame never shows a light unshadowed because the atlas is filling.
SHADOW_UPDATE_BUDGET_TEXELS_OFFLINE = 1 << 62
#: Omni capture cost per atlas texel: 6 cube faces of (s/2)^2 = 1.5 s^2 texels.
SHADOW_OMNI_COST_FACTOR = 1.5
#: Fixed budget charge per capture render pass (clear, state, draws, the copy), in
#: texel equivalents. Measured on llvmpipe at 745x360 (docs/PERFORMANCE.md, shadow
#: atlas): a frame of 443 small omni maps (2.2 Mtexel) took 478 ms against 77 ms for
#: 6 large ones (2.4 Mtexel), i.e. ~0.9 ms per omni capture (7 passes) against
#: ~30 ms per Mtexel, ~4k texels per pass. Without the charge a texel budget lets
#: hundreds of tiny maps through in one frame.
SHADOW_PASS_OVERHEAD_TEXELS = 4096
#: Render passes per capture, the copy into the atlas included.
SHADOW_SPOT_PASSES = 2
SHADOW_OMNI_PASSES = 7

#: Prior of the capture cost model (``shadows.cost``): ms per Mtexel, ms per render
#: pass, ms per Mtriangle submitted. Measured on llvmpipe (2 cores, docs/PERFORMANCE.md):
#: ~30 ms per Mtexel and ~0.13 ms per pass (the texel-budget figures above), ~50 ms per
#: Mtriangle (chess omni captures, per-face culled). A start-up calibration replaces it
#: unless the model is fixed (deterministic mode).
SHADOW_COST_COEFFS_DEFAULT = (30.0, 0.13, 50.0)
#: Frames of wall-clock samples the cost model is re-fitted over (a few seconds).
SHADOW_COST_FIT_WINDOW = 64
#: Weight of the prior in the re-fit, in frames' worth of samples: the model follows
#: the measurements after a few frames but a run of look-alike frames cannot make a
#: coefficient it says nothing about drift.
SHADOW_COST_PRIOR_WEIGHT = 1.0
#: Largest ``shadow_budget_ms`` accepted (one second of captures per frame).
SHADOW_UPDATE_BUDGET_MS_MAX = 1000.0

#: Fraction of the per-frame budget reserved for pending static maps (on top of the
#: guaranteed first static): a burst of statics (level load) drains at >= 1/4 speed
#: while dynamic hero lights keep >= 3/4 of the budget.
SHADOW_STATIC_RESERVE_FRACTION = 0.25

#: Resolution hysteresis (octaves) added to each side of a size's rounding band:
#: size s is kept while the continuous target stays in [s/2^(0.5+h), s*2^(0.5+h)],
#: i.e. +-19 % past the boundary, so a light at a boundary does not flip every frame.
SHADOW_RES_HYSTERESIS_OCTAVES = 0.25

#: Map texels per screen pixel of the light's projected influence diameter. Beyond
#: half the influence radius the light is within 2 stops of LIGHT_CUTOFF_LUX, where
#: shadow edges are invisible, so the inner disc (half the diameter) sets the density.
SHADOW_TEXELS_PER_PIXEL = 0.5
#: Flux (lm) that gets the plain projected size, as the camera sees it: the engine
#: passes flux x the camera's exposure scale, like the influence ranges, so map sizes
#: (hence the image) do not depend on the unit scale of the lights (issue 33): a
#: 1000 lm (75 W-equivalent) bulb seen at exposure scale 1. Scenes exposed darker
#: (the courtyard: -3 stops) get smaller maps than the absolute-flux rule gave them
#: (its median 160 -> 48 texels; 125 lm would keep them, but grows exposure-0 maps
#: to where the octahedral maps' grazing bias shows: tests/test_shadows_gl.py).
#: Validation's estimate uses VALIDATE_SHADOW_REFERENCE_EXPOSURE_SCALE.
SHADOW_REFERENCE_FLUX_LM = 1000.0
#: Clamp of the sqrt(flux / reference) size factor: +-2 octaves, so neither a
#: candle nor a stadium light escapes the distance-driven size entirely.
SHADOW_FLUX_SCALE_RANGE = (0.25, 4.0)

#: Screen-footprint map sizing (issue 33 item 5, ``RenderSettings.shadow_resolution``
#: "footprint" / "max"; tasks/shadow_footprint.py): a compute pass over the G-buffer
#: asks, per shadowed light, for the map side whose texels project to
#: SHADOW_FOOTPRINT_TEXELS_PER_PIXEL screen pixels at the receivers where the light is
#: visible. At most SHADOW_FOOTPRINT_LIGHTS_MAX lights a measurement (the highest
#: priorities; the rest keep the flux rule), every SHADOW_FOOTPRINT_STRIDE_PX-th pixel
#: in x and y.
SHADOW_FOOTPRINT_LIGHTS_MAX = 64
SHADOW_FOOTPRINT_STRIDE_PX = 2
SHADOW_FOOTPRINT_TEXELS_PER_PIXEL = 0.5
#: A receiver asks for the full density when the light gives this share of its
#: (unshadowed) illuminance from the measured lights, the sun and the dome; less in
#: proportion (a light giving 10 % asks for a 5x coarser map there).
SHADOW_FOOTPRINT_SHARE_FULL = 0.5
#: ... and asks nothing when the light's diffuse radiance on a white receiver, times
#: the camera's exposure scale, is below this (display-relative; 1 = white).
SHADOW_FOOTPRINT_DISPLAY_MIN = 0.01
#: Cap of a receiver's slope factor cos(view) / cos(light) (a surface the light grazes
#: stretches each texel by 1 / cos(light)): 4 = up to 2 octaves more on such walls.
SHADOW_FOOTPRINT_SLOPE_MAX = 4.0
#: "lift" (``RenderSettings.shadow_resolution``; ``policy.lift_targets``):
#: a light keeps the flux rule's side unless its measured footprint asks for more
#: than this many times the flux target (a continuous ratio, not octaves of the
#: power-of-two sides, so it does not depend on where the rounding falls) ...
SHADOW_LIFT_MIN_RATIO = 5.0
#: ... and lifts are granted (largest ratio first) only while all the maps' nominal
#: sides fit in this fraction of the atlas's texels.
SHADOW_LIFT_ATLAS_FRACTION = 0.5
#: Half-octave bins of the per-light histogram of the receivers' needs (sides 1 to
#: 2^16 texels), and the fraction of a light's receivers whose need the map meets:
#: 1.0 = all of them (the maximum, exact; below 1 the percentile's bin's upper edge).
SHADOW_FOOTPRINT_BINS = 32
SHADOW_FOOTPRINT_PERCENTILE = 1.0

#: Priority multiplier for lights whose influence sphere is outside the view: they
#: keep their map (no churn when the camera turns) but are downgraded and
#: refreshed last (16x = 4 octaves of projected size).
SHADOW_OUT_OF_VIEW_PRIORITY_SCALE = 1.0 / 16.0

#: Under-sized / evicted maps retried per frame (each success costs a re-render).
SHADOW_UPGRADES_PER_FRAME = 1
#: Frames before a failed upgrade of the same map is retried (0.5 s at 60 Hz).
SHADOW_UPGRADE_RETRY_FRAMES = 30

#: Window (frames) of the staleness statistics (10 s at 60 Hz).
SHADOW_STATS_WINDOW_FRAMES = 600

# --- taa spatial filter (RenderSettings.taa_filter; shaders/taa_filter.frag) -------------
#: Most a-trous levels (level k's taps are 2^k px apart: 5 levels reach 64 px).
TAA_FILTER_LEVELS_MAX = 5
#: Luminance stop (standard deviations of the temporal spread of the two pixels'
#: frames). Measured on the 320x180 60-frame courtyard orbit (frames 8+, GPU pass;
#: taa alone: HDR-FLIP 0.179, instability 1.68x): 1 level 0.174 / 1.30x, 2 levels
#: 0.174 / 1.13x, 3 levels 0.186 / 1.07x (numpy: a stop of 1 on the variance of the
#: mean, / n, 3 levels 0.173 / 1.26x). An oracle that removed all error below 4 px
#: (16 px) would only reach 0.133 (0.118): the error left is at the scale of the
#: tiles. 256-light chess orbit (pivot 1.07; taa 0.314 / 1.90x): 1 level 0.309 /
#: 1.48x, 2 levels 0.306 / 1.25x (oracle below 4 / 16 px: 0.217 / 0.144). Cost of
#: 2 levels on llvmpipe, 745x360: ~3x the temporal pass (27 % of the frame), so it
#: is off by default.
TAA_FILTER_SIGMA_L = 4.0

# --- Misc -------------------------------------------------------------------------------

#: Tiny positive PDF floor keeps every sampling weight finite (no 0/0).
PDF_EPSILON = 1.0e-20

TWO_PI = 2.0 * math.pi

# --- Validation -------------------------------------------------------------------------
# Thresholds of the `stb validate` rules (stb_hydra/validate, docs/VALIDATE.md).

#: Plausible luminous flux of one local light (lm). Below 1 lm (1/12 of a candle) a light
#: is invisible next to any lit surface yet still takes an STB slot; above 200 klm (a 2 kW
#: stadium floodlight) a prefab light is almost surely a units slip (cm radius read as m
#: gives 10^4 x the flux, intensity authored in cd or W instead of nits).
VALIDATE_LIGHT_FLUX_RANGE_LM = (1.0, 200_000.0)
#: Most total flux of one prefab (lm): five floodlight-class lights. A whole lit street
#: block is ~10^5 lm; 10^6 lm in one prefab is a scale or unit error, not a design.
VALIDATE_PREFAB_FLUX_MAX_LM = 1_000_000.0

#: Shadowed local lights per prefab before a warning: 8 maps of 512^2 fill the default
#: per-frame update budget (SHADOW_UPDATE_BUDGET_TEXELS_DEFAULT = 2 Mtexel), so more
#: cannot all be refreshed in one frame even at a modest size.
VALIDATE_SHADOWED_LIGHTS_PER_PREFAB_MAX = 8
#: Dynamic-shadow opt-ins per prefab before a warning: dynamic maps are re-rendered
#: round-robin every frame; two per prefab already take most of a frame's budget
#: when a handful of such prefabs are on screen.
VALIDATE_DYNAMIC_SHADOWS_PER_PREFAB_MAX = 2
#: Reference view for the shadow-atlas estimate: the prefab seen from 20 m (mid-ground)
#: in a 1080-px-high, 60-degree vertical field of view (a typical game camera).
VALIDATE_SHADOW_REFERENCE_DISTANCE_M = 20.0
VALIDATE_SHADOW_REFERENCE_HEIGHT_PX = 1080
VALIDATE_SHADOW_REFERENCE_FOV_DEG = 60.0
#: Camera exposure scale of that reference view, by which the estimate
#: multiplies a light's flux as the renderer does (SHADOW_REFERENCE_FLUX_LM).
VALIDATE_SHADOW_REFERENCE_EXPOSURE_SCALE = 1.0
#: Largest estimated atlas share of one prefab at the reference view: a quarter of the
#: default atlas (4 maps at SHADOW_MAP_MAX_SIZE), so four such prefabs fill it.
VALIDATE_PREFAB_ATLAS_FRACTION_MAX = 0.25

#: Lights whose influence spheres may overlap at one surface point before STB noise is
#: likely: the talk's K = 16 reservoir slots; beyond that each slot resamples several
#: lights and the variance grows with the count (STB_SPEC "Big-tile sampling"). Kept at
#: 16 when the renderer's default K became 64: it flags noise a person sees at 16
#: accumulated frames, not the reservoir size.
VALIDATE_STB_OVERLAP_MAX = 16
#: Surface points sampled per asset (area-weighted over its meshes) for the overlap
#: count: with 4096 points a region covering 0.1 % of the area is missed with
#: probability (1 - 0.001)^4096 ~ 1.7 %.
VALIDATE_OVERLAP_SAMPLES = 4096

#: |ies:angleScale| above this is a value typed in degrees, not a scale factor: 10 maps
#: the first 18 degrees of the profile onto the whole sphere; no real fixture does that.
VALIDATE_IES_ANGLE_SCALE_MAX = 10.0
#: A negative angleScale rescales the profile about the zenith and can turn a downlight
#: sideways or up: reported when the flux-weighted mean downward cosine of the remapped
#: profile falls below this fraction of the original's (the beam tilts past ~60 deg).
VALIDATE_IES_DOWNLIGHT_KEEP_MIN = 0.5
#: Share of a profile's flux below the horizon that makes it a downlight.
VALIDATE_IES_DOWNLIGHT_SHARE = 0.6

#: metersPerUnit values whose ratio is within this relative tolerance are "the same"
#: (also used to accept a compensating xform scale on a referencing prim).
VALIDATE_UNITS_RTOL = 0.01

#: Wall-clock limit (s) for one asset in a worker before it is killed and reported.
VALIDATE_ASSET_TIMEOUT_S = 300.0

# Hostile libraries (issue 21, item 7): per-asset bounds of `stb validate`.
#: Largest layer file opened (bytes). Real prefab layers are KB-MB; a 1 GB usdc of a
#: prefab is a mistake or an attack (USD maps and decodes it whole). Larger layers are
#: reported ``unreadable`` without being opened.
VALIDATE_LAYER_MAX_BYTES = 512 * 1024 * 1024
#: Most layers scanned for one asset (its sublayers, references and payloads, chained):
#: a deeply nested or combinatorial reference graph is reported instead of composed.
VALIDATE_MAX_LAYERS = 1000
#: Address space of one validate worker (bytes, RLIMIT_AS): an asset that makes USD
#: allocate past it ends that worker (a ``crash`` finding), not the machine. 16 GiB
#: leaves room for Python, USD, OCIO and a GL context (--thumbnails; llvmpipe maps
#: a few GiB of virtual memory).
VALIDATE_WORKER_MAX_BYTES = 16 * 1024**3

# --- Baselines --------------------------------------------------------------------------
# The exact many-light baselines `tiled`, `clustered`, `lighttree` (docs/BASELINES.md).

#: Tiled deferred tile side (px): Andersson 2009's 16x16 tiles = min/max depth level 4.
TILED_TILE_PX = 16
#: Default per-tile light-list cap: 64, as Unity HDRP's FPTL. Lights past it are dropped
#: (and counted): the flickering-tile artefact of capped tiled lighting.
TILED_CAP_DEFAULT = 64
#: Culling invocations per tile / cluster workgroup (tiled_cull.comp; one shared hit
#: mask word each).
CULL_GROUP_SIZE = 64
#: Lights each invocation of the cull kernel tests per batch, into one 32-bit hit mask
#: (<= 32): a batch of CULL_GROUP_SIZE x this many lights costs the workgroup four
#: barriers, which llvmpipe runs as switches between its invocations.
CULL_LIGHTS_PER_INVOCATION = 32

#: Most light-list entries (light x tile/cluster pairs) one frame may store: 32 Mi uint32
#: = 128 MiB of SSBO. Uncapped lists of huge lights over many cells past this get a
#: uniform per-cell cap (drops counted, one warning) instead of an allocation failure.
GRID_MAX_LIST_ENTRIES = 32 * 1024 * 1024
#: tiled / clustered (GPU assignment): most bytes of the per-entry ``pos_range`` copies
#: (16 B an entry, sized like the lists: cells x list stride) that let the shading's
#: list walk read one vec4 per step; past it the walk reads the light buffer instead
#: (same image, slower). CPU-built clustered lists are exact-size and always have it.
CELL_POS_RANGE_MAX_BYTES = 128 * 1024 * 1024

#: Clustered / light-tree screen tile (px): Persson 2013 uses 64 px tiles; O'Donnell and
#: Chajdas found 32-64 px the best CPU/GPU trade-off (their 48 px). The light tree's
#: default.
CLUSTER_TILE_PX_DEFAULT = 64
#: `clustered`'s default tile (px): tiled's 16. On llvmpipe a pixel's list walk costs
#: per entry of its cluster, and a 64 px tile puts 16x the pixels behind each listed
#: light (issue 34 item C: 5,000 sphere lights at 160x90, CPU time, 0.30x -> 0.24x the
#: reference; docs/PERFORMANCE.md).
CLUSTERED_TILE_PX_DEFAULT = 16
CLUSTER_TILE_PX_RANGE = (8, 256)
#: Exponential depth slices after the near slice (Persson: 16 incl. the near one; we
#: add the near slice on top, as the issue asks). 0 = 2D tiles only (tree-only mode).
CLUSTER_SLICES_DEFAULT = 16
#: More slices than this cost more cluster headers than they save list entries at any
#: resolution we render (and the per-cluster GPU assignment runs one workgroup each).
CLUSTER_SLICES_MAX = 64
#: End of the near slice as a fraction of the far end of the slicing when not given:
#: Persson's 5 m of 500 m (the near slice absorbs the first-person clutter).
CLUSTER_NEAR_FRACTION = 0.01

#: Relative widening of influence radii and of cell depth bounds in every culling test,
#: plus a depth-relative term: fp32 depth reconstruction on the GPU differs from the
#: float64 CPU binning by ~1e-7 relative, so "no cap" stays exactly the reference.
CULL_RADIUS_REL_MARGIN = 1.0e-4
CULL_DEPTH_REL_MARGIN = 1.0e-5

#: Light-tree leaf size (lights per leaf) by default: the paper targets "several".
LIGHTTREE_LEAF_LIGHTS_DEFAULT = 4
#: Packed node (Listing 1): 16-bit light count, 15-bit skip count. A list cell (one leaf)
#: holds at most 2^16 - 1 lights (bigger cells become trees); a tree at most 2^15 - 1
#: nodes, i.e. 16384 leaves (a full binary tree of L leaves has 2L - 1 nodes).
LIGHTTREE_MAX_NODE_LIGHTS = (1 << 16) - 1
LIGHTTREE_MAX_TREE_NODES = (1 << 15) - 1
LIGHTTREE_MAX_LEAVES = 1 << 14
#: Node budget per frame: 16 Mi nodes x 16 B = 256 MiB; with >= 2 lights per leaf the
#: nodes never outnumber GRID_MAX_LIST_ENTRIES, so this is a safety net, not a tuning knob.
LIGHTTREE_MAX_NODES = 16 * 1024 * 1024


# --- STB deferred shadow terms: where a 2x2 quad may share one term -----------------

#: A quad's pixels share its shadow term for a light only while every pixel lies within
#: this fraction of the light distance of the quad's representative point (about 9 deg
#: seen from the light) -- otherwise (a post in front of a far wall: 27x the distance) a
#: term computed on the wall would multiply the post's own 1/d^2 irradiance (up to
#: 7000x fireflies); those quads get per-pixel terms. 0.05 split 8 % of the quads of a
#: 500-light scene at 745x360 for no visible gain and cost ~1.3x in the term pass.
STB_TERM_SHARE_REL_DISTANCE = 0.15
#: Per-pixel resampling (``-o select=ris``): each of the tile's N samples is weighted at
#: the pixel by the unshadowed target x the quad's term, plus this share of the mean of
#: those targets (a defensive mixture, like the small tile's ``pdf_floor``). The term makes
#: the pick follow the shadows (courtyard, 16 frames: HDR-FLIP 0.136 without it, 0.098
#: with it); the mixture trades a little of that (0.104) for less 2x2 structure (2.53 ->
#: 1.80): a quad's pixels share its terms and would otherwise pick alike. A floor under
#: the term (0.2: FLIP 0.122, structure 1.25, one frame 0.36 instead of 0.29) was tried
#: and dropped. Measured in docs/STB_NOTES.md (issue 13, fourth pass).
STB_RIS_PDF_FLOOR = 0.25

# --- STB reservoir reuse (issue 31, ``-o reuse=on``) -----------------------------------
#: History confidence cap of the temporal reuse, in frames' worth of candidates (M of
#: the previous reservoir is clamped to this before it is combined): bounds how long
#: the history can outvote a changed light (ReSTIR's usual 20).
STB_REUSE_M_CAP = 20.0
#: Top of the ``reuse_m`` debug view's log2 scale of a reservoir's confidence M (the
#: stored M after spatial reuse reaches (k + 1) x (1 + STB_REUSE_M_CAP) = 105 at the
#: defaults; larger M saturates).
STB_REUSE_DEBUG_M_MAX = 128.0
#: Spatial neighbours per pixel (``-o reuse_k``), at most (shader arrays are sized by it).
STB_REUSE_K_MAX = 8
#: Spatial reuse radius (px) by default (``-o reuse_radius``): about one interleaved
#: footprint, so the neighbours come from other small tiles than the pixel's own.
STB_REUSE_RADIUS_PX = 24.0
#: Quad-resolution reservoirs (``-o reuse_res=quad``): defensive floor of the quad's
#: target, as a fraction of its candidates' mean target (dimensionless; > 0 keeps the
#: reservoir unbiased for the quad's other three pixels, larger adds noise at the one).
STB_REUSE_QUAD_FLOOR = 0.05
#: Quad-shared reservoirs (``-o reuse_res=share``): the MIS weight of the quad pixel i
#: that drew a light y is c_i / sum_j c_j, c_j = min(p_j(y) / (ratio x max_l p_l(y)), 1)
#: (p: each pixel's target). Pixels whose target is within this ratio of the quad's
#: largest weigh alike (one light, or a smooth target, comes out exact: the four pixels'
#: disjoint strata make the balance heuristic's p_i / sum p_j a per-quad noise of the
#: target's slope); below it the weight falls with p_i, which bounds the contribution of
#: a pixel that drew y with a small target by 1 / ratio of its weight sum (no fireflies).
#: 0.25: a glossy highlight's quads (targets 2-4x apart) are exact too, where 0.5 left
#: them 16 % off; 16-frame stills of chess / courtyard alike for 0.5 ... 0.1 (relMSE
#: within 3 %), 0.03 worse (docs/STB_NOTES.md "(share MIS)").
STB_REUSE_SHARE_MIS_RATIO = 0.25
#: Same-surface tests of the reuse (temporal and spatial): relative linear-depth
#: difference, cosine between the normals, roughness difference.
STB_REUSE_DEPTH_REL = 0.1
STB_REUSE_NORMAL_COS = 0.9
STB_REUSE_ROUGHNESS_DIFF = 0.25
#: Lights that changed since the last frame (``renderer/lighting/stb_reuse.py``): inside
#: a changed light's influence sphere the history's confidence is capped, per rule
#: (cap, relative intensity change above, move above this fraction of the range);
#: the first rule wins. Switched on/off (or re-typed) is the first rule. A history
#: sample's weight was made for the old lights: where they changed, old reservoirs of
#: *other* lights overstate (a switched-off light's share went into their W), so the
#: history is dropped there rather than merely re-weighted.
STB_REUSE_CHANGE_RULES: tuple[tuple[float, float, float], ...] = (
    (0.0, 0.5, 0.1),
    (2.0, 0.02, 0.01),
)
#: Changed-light spheres tested per pixel; more changed lights than this cap the
#: history everywhere (by the strictest rule that fired).
STB_REUSE_MAX_CHANGES = 32

# --- STB big-tile target ("shaped") --------------------------------------------------

#: Lower bound of the emission x cone x IES factor in the shaped big-tile target: the
#: factor is taken towards the tile's central segment only, so a light dark there may
#: still light the tile's corners; the floor keeps its probability positive (unbiased).
STB_BIGTILE_SHAPE_FLOOR = 0.1
#: ``-o reuse_target=tile`` (shaders/stb_reuse_slots.frag): the shaping (cone x IES x
#: emission model) of a slot's light is the maximum over an n x n grid of G-buffer points
#: spanning the pixels that may use the big tile (the tile and half a tile around it:
#: stochastic bilinear selection), floored at a fraction of its peak so it stays > 0
#: wherever the light may reach a pixel between the points (unbiased).
STB_REUSE_SLOT_GRID = 4
#: ... with its points at least this far apart (px): a 2 x 2 grid for 16 px big tiles
#: (``stb_reuse.slot_grid``), whose 4x more slots would cost 4x the slot pass's grid.
STB_REUSE_SLOT_GRID_MIN_PX = 16
STB_REUSE_SLOT_SHAPE_FLOOR = 0.01
#: The cone of a slot's light is not in that maximum: each pixel applies it (cos space,
#: a third slot texel). Its cutoff is widened by this fraction (relative, of the cutoff
#: angle) so rounding never zeroes the target where the shading is still > 0, and its
#: soft band (cos(smooth start) - cos(cutoff), unitless) is at least the second value
#: (hard cones: a target that falls to 0 over that band just inside the edge).
STB_REUSE_SLOT_CONE_MARGIN = 1e-3
STB_REUSE_SLOT_CONE_MIN_DCOS = 1e-5
#: ... and so is an IES table (a light without angleScale): each pixel looks up the
#: table's maximum over phi at its cos off the axis, from a per-layer table of this many
#: bins uniform in cos (each the maximum over its neighbours' span: a linear lookup
#: never falls below the table; ``gl_delegate.ies_cos_rowmax``).
STB_REUSE_IES_COS_BINS = 256

# --- STB interleaving patterns --------------------------------------------------------

#: Balanced random quad -> small-tile patterns drawn from at start-up; one is used per
#: frame (``-o pattern=random``), so the interleaving does not repeat frame to frame.
STB_PATTERN_BANK = 32
#: Gaussian preference (quads) of a tile for its own quadrant in the random patterns:
#: keeps a tile's quads local (its refined target stays representative).
STB_PATTERN_SIGMA_QUADS = 4.0

# --- Engine bookkeeping -----------------------------------------------------------------

#: Frames of per-pass timings an Engine keeps (``Engine.timings.frames``; between this
#: and twice this many). Unbounded, a long-running engine (previewer, soak) grew by
#: ~1.6 KiB per frame for ever (docs/RELIABILITY.md); benchmarks use far fewer frames.
TIMINGS_KEPT_FRAMES = 1024

# --- Static lighting bake (`stb bake`, stb_hydra/bake; issue 17) ------------------------

#: Default lightmap texel density (texels per metre, world space). 16/m = 6 cm texels:
#: finer than the shadow-map texels of the courtyard's lamps at 1080p (so lightmaps do
#: not blur the shadows further), ~0.6 Mtexel for its ~2500 m^2 of static surface.
BAKE_TEXEL_DENSITY_DEFAULT = 16.0
#: Largest lightmap side (texels); a mesh whose charts do not fit at the requested
#: density is packed at a lower one (with a warning): GL_MAX_TEXTURE_SIZE is >= 8192
#: on every GL 4.3 driver, 4096 keeps one lightmap <= 128 MiB at the bake's RGBA32F.
BAKE_LIGHTMAP_MAX_SIZE = 4096
#: The lightmap density a mesh gets (texels per metre measured on its UVs) may differ
#: from the one asked by this fraction; past it xatlas packs again at a corrected
#: ``texels_per_unit`` (its charts are stretched and rounded up to whole texels: small
#: dense props came out ~15 % too dense), at most BAKE_DENSITY_PASSES packings in all
#: (including those that lower the density to fit BAKE_LIGHTMAP_MAX_SIZE).
BAKE_DENSITY_TOLERANCE = 0.03
BAKE_DENSITY_PASSES = 8
#: Triangles above which a mesh is not unwrapped (lit dynamically, warned): xatlas's
#: chart growing is super-linear; 200 k triangles take ~1 min on one core.
BAKE_MAX_TRIANGLES = 200_000
#: Faces smaller than this (m^2) are degenerate: xatlas leaves them without charts,
#: so a mesh with any is not baked (warned) rather than sampled at garbage UVs.
BAKE_MIN_FACE_AREA_M2 = 1e-10
#: Supersampling per lightmap texel axis (2 = 4 evaluations per texel, box filter).
BAKE_SUPERSAMPLE = 2
#: Empty texels between charts (xatlas padding) and dilation passes into them, so
#: bilinear lookups at chart edges never blend in unbaked (black) texels.
BAKE_PADDING_TEXELS = 2
BAKE_DILATE_TEXELS = 4
#: Viewport height (px) the bake's shadow-map resolution policy is run for: maps are
#: sized as for a 1080p frame (the reference renders' quality), up to SHADOW_MAP_MAX_SIZE.
BAKE_SHADOW_VIEW_HEIGHT = 1080
#: `stb validate` (lightmap_density): lightmaps coarser than this (texels per metre,
#: 25 cm texels) blur light pools and shadows visibly at street-level viewing distances.
VALIDATE_LIGHTMAP_TEXEL_DENSITY_MIN = 4.0

# --- Area lights (issue 20; common/area.glsl, common/shadow.glsl) --------------------------

#: Below this ratio of the light's half extent to its distance, an area light is lit
#: with the point model (same result within r^2/d^2 = 0.09 % for a disk on its axis,
#: measured in tests/test_area_lights.py::test_point_threshold_error).
AREA_POINT_RATIO = 0.03
#: Vertices of the polygon a disk's rim, a sphere's silhouette or a cylinder's visible
#: strip is approximated by (area-preserving): 16 keeps the irradiance within 0.5 %
#: of the exact disk, median 0.2 % (tests/test_area_lights.py::
#: test_disk_light_matches_closed_form, test_sphere_cut_by_floor_matches_closed_form).
AREA_POLY_VERTS = 16
#: GGX specular of an area light (LTC, common/area.glsl): the light's angular radius s
#: (half extent / distance) against the lobe's width alpha. Below SPEC_POINT x alpha the
#: point model's specular is used (exact for a light much smaller than the lobe), above
#: SPEC_LTC x alpha the LTC integral, in between a linear blend of the two. A light
#: below AREA_POINT_RATIO still takes the area path when it is wide for the lobe of a
#: smooth surface (s > AREA_SPEC_POINT x alpha). Measured: tools/area_lights.py specular.
AREA_SPEC_POINT = 0.15
AREA_SPEC_LTC = 0.5
#: GGX alpha clamp of brdf.glsl (alpha = max(roughness^2, this)); the LTC table's
#: smallest alpha (tools/fit_ltc.py).
GGX_ALPHA_MIN = 0.002
#: Largest PCSS blocker-search / filter radius in shadow-map texels at the receiver
#: (soft shadows of area lights, common/shadow.glsl): bounds the kernel's footprint.
PCSS_MAX_TEXELS = 64.0
#: Soft shadows of area lights (common/shadow.glsl, shadow_area): visibility towards this
#: many points of the light (R2 set over its shape, shifted per pixel), each segment
#: ray-marched through the centre map. 0 switches back to PCSS (comparison runs only).
AREA_SHADOW_POINTS = 32
#: The same in STB's deferred term pass, whose point set is also shifted per frame, so
#: accumulated frames converge to the whole light's visibility.
AREA_SHADOW_POINTS_STB = 8
#: Taps of a blocker search first (PCSS's search region, a Vogel disk, plus one at the
#: receiver itself); none found: fully lit, no march (most pixels). 0: no search.
#: Measured (tools/area_lights.py accuracy, rect / disk with box, p95; 24-light
#: reference frame against PCSS's, 186x90): no search 8.9 % / 5.0 %, 16-20x; 8 taps
#: 8.9 % / 5.2 %, 2.2x; 16 taps 8.9 % / 5.0 %, 2.4x.
AREA_SHADOW_SEARCH = 8
#: The search's blockers must stand THICK_TEXELS / max(cos, SEARCH_COS) texels in front
#: of the tap (cos: receiver normal . direction to the light), or a grazing floor
#: "blocks" itself and every such pixel pays the full march.
AREA_SHADOW_SEARCH_COS = 0.125
#: A search tap counts only where the surface it sees could meet the cone receiver ->
#: light widened to this many times the light's half extent. Without it a blocker
#: anywhere in the (large) region sends the pixel to the march: 4.7x PCSS's frame;
#: with exactly the cone (1) the sparse taps miss blockers near the receiver, whose
#: useful region is small (disk p95 7.6 %); 2 keeps both.
AREA_SHADOW_SEARCH_CONE = 2.0
#: Stored depths (fraction of the map's range) at or above this are "nothing within the
#: range": a march point or search tap there is never behind a surface.
AREA_SHADOW_EMPTY_DEPTH = 0.9999
#: March samples per segment (light point -> receiver; plus one at the receiver), then
#: bisection steps at the first front-to-behind transition.
AREA_SHADOW_STEPS = 16
AREA_SHADOW_REFINE = 6
#: A transition is a real surface (a block) when, after bisection, the point lies less
#: than THICK_TEXELS map texels plus THICK_STEPS final bracket lengths behind the map's
#: depth; entering the centre's shadow volume past a silhouette leaves it much further
#: behind. Larger bands turn such side entries into blocks (too dark), smaller ones miss
#: grazing surfaces (tools/area_lights.py accuracy, rect with box).
AREA_SHADOW_THICK_TEXELS = 4.0
AREA_SHADOW_THICK_STEPS = 2.0
#: Within this many map texels (at the point's distance) of the receiver, march lookups
#: take the farthest depth of a 2x2 gather (the receiver's own surface must not block);
#: elsewhere the nearest texel (the gather-max shrinks every blocker by a texel).
AREA_SHADOW_RECEIVER_TEXELS = 6.0

# --- Material textures (renderer/textures.py, shaders/common/material.glsl) ----------------

#: GPU memory for material textures (bytes, mip chains included). Past it the largest
#: textures are halved (one warning naming them) until the set fits: 1 GiB holds the
#: OpenChessSet's ~45 distinct 2k maps at full size with room to spare.
TEXTURE_BUDGET_BYTES = 1024 * 1024 * 1024
#: Largest texture side uploaded (px); a larger file is halved on load (with a warning).
#: GL 4.5 guarantees GL_MAX_TEXTURE_SIZE >= 16384; 8192 keeps one texture <= 256 MiB.
TEXTURE_MAX_SIZE = 8192
#: UDIM tiles per texture: 1001-1100 (10 columns x 10 rows), one array layer each.
MAX_UDIM_TILES = 100
#: First UDIM tile number (u 0-1, v 0-1).
UDIM_FIRST_TILE = 1001
#: Anisotropic filtering of material textures (samples; GL clamps to what it has).
TEXTURE_ANISOTROPY = 16.0
#: Texture slots of one material (diffuseColor, emissiveColor, specularColor, metallic,
#: roughness, opacity, normal, occlusion, clearcoat, clearcoatRoughness): one sampler
#: each, under the 16 texture units a fragment shader is guaranteed (GL 4.3), beside
#: the G-buffer pass's none.
MATERIAL_TEXTURE_SLOTS = 10
#: Bytes per file read for a texture (a corrupt header claiming more is refused).
TEXTURE_MAX_FILE_BYTES = 1024 * 1024 * 1024
#: Texture file headers ``textures.read_info`` remembers per process, by (file, mtime,
#: size): a reopened stage does not open every file again (~10 % of loading the
#: OpenChessSet). A few hundred bytes each.
TEXTURE_INFO_CACHE_FILES = 4096
# --- Light and shadow linking (scene/links.py, issue 30) --------------------------------

#: Most light-link groups (prims sharing one light-link membership signature). A pixel's
#: group is one integer of the G-buffer's ``g_link`` target and each light's mask over the
#: groups is one 32-bit uint of the link SSBO, so a light's bit is one shift and AND in
#: every shader. Past it the closest groups are merged (their masks OR-ed: prims may be
#: over-lit by a light outside its collection, never under-lit), with one warning naming
#: the lights affected.
MAX_LIGHT_LINK_GROUPS = 32

#: Most shadow-link groups. Draw batches are split by shadow group (each shadow capture
#: draws the batches its light's shadow mask keeps, one bit test per batch), so the
#: batch count grows with them; 32 keeps the mask one uint like the light mask. Past it
#: the closest groups are merged and a merged group casts a light's shadow only if every
#: member did (fewer shadows: over-lit, never under-lit), with one warning.
MAX_SHADOW_LINK_GROUPS = 32

#: Distinct membership signatures past which the closest-pair merge (quadratic in the
#: signatures) gives way to keeping the largest groups and folding the rest into one.
LINK_MERGE_MAX_SIGNATURES = 2048


# --- Temporal pass, distant lights (per-frame uniform arrays) ---------------------------

#: Lights whose large change shortens taa's history per pixel (``u_light_spheres`` /
#: ``u_light_caps`` of temporal.frag); more changed lights than this in one frame: the
#: smallest cap everywhere.
MAX_LIGHT_CHANGES = 16
#: taa's history alpha holds its length n (frames) + r / TAA_EDGE_RUN_SCALE, r the
#: frames in a row an edge was beside the pixel, counted up to TAA_EDGE_RUN_MAX (so
#: r / scale < 0.25 and rounding the alpha gives n back).
TAA_EDGE_RUN_SCALE = 64
TAA_EDGE_RUN_MAX = 15
#: Side (taps, odd) of taa's young-history estimate's grid (``u_young_c`` of
#: temporal.frag, ``tasks.temporal.YOUNG_GRID``): a least-squares quadratic over
#: TAA_YOUNG_GRID^2 neighbours.
TAA_YOUNG_GRID = 5
#: Unshadowed distant lights beside the sun (``u_dist_dir`` / ``u_dist_illum`` of the
#: frame block, common/frame.glsl); more: the brightest are kept, with a warning.
MAX_EXTRA_DISTANT = 3
#: Faces of a cube shadow map (``u_face_vp`` / ``u_face_rot``): geometry, not a knob.
CUBE_FACES = 6

# --- Dome textures (issue 37, scene/dome.py, renderer/dome_env.py) ------------------

#: Width (texels) of the render-frame lat-long map a dome texture is resampled into
#: (height half of it). 1024 keeps a 0.35-degree texel, under the sun's 0.53-degree
#: disc, at 2 MiB of RGBA16F (+ mips) and a 0.5 M-entry sampling table.
DOME_MAX_WIDTH = 1024
#: Largest dome radiance factor kept from a texture (values above are clamped): far
#: above any real HDRI (the sun in a 16-bit EXR is ~1e5), under fp16's 65504 x the
#: light's own intensity only where the light's intensity is below 1.
DOME_MAX_RADIANCE = 1.0e6
#: Dome maps kept in memory (file, format, rotation): an animated dome rotation
#: resamples each frame and must not grow memory without bound.
DOME_CACHE_ENTRIES = 8
#: A dome's sun (``scene.dome.split_sun``, lit by the real-time methods as a shadowed
#: distant light): texels within this radius (degrees) of the brightest one ...
DOME_SUN_MAX_RADIUS_DEG = 6.0
#: ... at least this fraction of its luminance ...
DOME_SUN_THRESHOLD = 0.05
#: ... carrying at least this share of the dome's power (a real sun: 50-90 %).
DOME_SUN_MIN_SHARE = 0.2
#: Directions the reference method samples from a textured dome per frame, each with
#: its own directional shadow map (``--accumulate`` adds more per integrated frame).
DOME_REFERENCE_SAMPLES = 32
#: Side (texels) of each of those directional shadow maps.
DOME_SHADOW_MAP_PX = 512
#: Sky occlusion of the real-time methods (``renderer/dome_shadows.py``): fixed
#: directions drawn from the dome (its sun left out when the sun is split off), each
#: with a directional shadow map re-drawn only when the scene's geometry or the dome
#: changes; the visibility they give, weighted by the dome's light in each direction,
#: scales the prefiltered sky light. At most DOME_REFERENCE_SAMPLES (shared uniforms).
DOME_OCCLUSION_SAMPLES = 8
#: Spherical-harmonic coefficients of the real-time dome's irradiance: bands 0-2 (SH9,
#: Ramamoorthi & Hanrahan 2001's irradiance environment map; exact for a map of band
#: <= 2 such as the half sky). Sizes the u_dome_sh uniform array.
DOME_SH_COEFFS = 9

# --- RectLight textures (issue 37 item 3, scene/rect_texture.py, common/rect_texture.glsl) --

#: Side (texels) of the square layer a RectLight texture is box-resampled into (its
#: mip chain down to 1 x 1 is box-filtered too): 256 keeps a 0.4 % texel of the rect
#: at 256 KiB of RGB16F a layer (+ mips).
RECT_TEXTURE_PX = 256
#: Textured RectLights with distinct textures on the GPU at once (texture-array layers;
#: more: the rest emit their mean, with a warning). Also the most textured rects the
#: camera sees directly (``u_rect_seen``).
MAX_RECT_TEXTURES = 16
#: Cells per side of the grid the exact methods integrate a textured rect over (each
#: cell a uniform polygon of its box-filtered texel, mip level log2(RECT_TEXTURE_PX /
#: RECT_TEXTURE_GRID)): exact for a texture constant over those cells (a two-tone
#: half/half texture), 64 polygon integrals per pixel and light otherwise.
RECT_TEXTURE_GRID = 8
#: Cells per side for the real-time methods (STB): each cell's form factor / LTC
#: integral times Heitz et al. 2016's prefiltered lookup inside the cell (4 polygon
#: integrals per lobe instead of 1; exact for a texture constant over 2 x 2 cells).
RECT_TEXTURE_GRID_REALTIME = 2
#: STB's textured-LTC lookup (Heitz et al. 2016): the lobe's footprint on the rect, in
#: units of its distance to the rect's plane (in cosine / LTC space), sets the mip level.
#: Heitz's demo: 1 (its log-3 pyramid); measured by tools/rect_texture_accuracy.py.
RECT_TEXTURE_FOOTPRINT = 1.0

# -- Receiver bounds for narrow sphere lights (issue 34 item 2) --
#: Leaf boxes per mesh geometry (object space; its triangles split at the median along
#: the longest axis until there are this many): the exact methods' narrow-sphere bound
#: (``light_buffer.narrow_spheres``) takes the distance from a light to the nearest leaf
#: box instead of to the mesh's AABB. On the generated many-light scene (100 boxes in
#: one mesh) the mesh AABB spans every light: 31 of 500 spheres were provably narrow.
RECEIVER_LEAVES_PER_MESH = 256
#: Meshes whose leaf boxes ``receiver_bounds.leaf_boxes`` remembers (by content) for the
#: next engine of the process: at most 256 x 2 x 3 float64 each (12 KiB): 6 MiB in all.
#: Splitting the OpenChessSet's 157 meshes takes ~1.4 s; a reopened stage skips it.
RECEIVER_LEAF_CACHE_MESHES = 512
#: Most world leaf boxes in all (a mesh's leaves times its instances): past it, a
#: mesh's instances keep one box each (the mesh AABB): bounds the per-frame cost of
#: the (lights x boxes) distance test.
RECEIVER_BOXES_MAX = 4096

#: ``stb preview --script``'s ``{"wait_file": PATH}``: the longest wait (s) for the file;
#: past it the script goes on with a warning (a driver that died must not hang a test).
PREVIEW_WAIT_FILE_MAX_S = 120.0
