// STB reuse (issue 31), fused shading pass: the pick's area-light shading in a second,
// compacted pass (stb_reuse_area.frag). llvmpipe (Mesa 22.3) runs a SIMD group -- a 4x2
// stamp of a fragment pass -- through the straight-line code of both sides of every
// branch, masked; only a loop stops early, once none of its lanes goes on. Calling
// light_reflect per pixel therefore cost every stamp its polygon / LTC / form-factor
// code, and the polygon loops ran in full in the ~37 % of stamps (500 lights) holding
// one area pick among eight different picks. The first pass now shades the picks
// light_reflect shades by its point model with that model's code alone
// (reuse_point_reflect); a pick that needs the area path lists its pixel with the
// radiance so far, and the second pass shades the list eight listed pixels to a stamp:
// the same light_reflect, term and weight per pixel, summed in the same order -- the
// same image, bit for bit (docs/STB_NOTES.md, reuse5).
#ifndef STB_REUSE_AREA_GLSL
#define STB_REUSE_AREA_GLSL

// The list of pixels (x | y << 16) whose pick needs the area path; the count first
// (zeroed by the CPU each frame).
layout(std430, binding = SSBO_STB_REUSE_AREA) buffer ReuseAreaList {
    uint reuse_area_count;
    uint reuse_area_px[];
};

// Shadow x cone x normalised IES of light L at P (stb_shadow.frag's sample_term).
float reuse_term(Light L, vec3 P, vec3 N) {
    vec3 Ldir = normalize(L.pos_range.xyz - P);
    return clamp(light_shape_scalar(L, -Ldir) * luminance(local_shadow(L, P, N)), 0.0, 1.0);
}

const int REUSE_OUT_OF_REACH = 0;  // light_reflect returns false before its area path
const int REUSE_POINT_MODEL = 1;   // light_reflect returns its point model: diff, spec set
const int REUSE_AREA_PATH = 2;     // light_reflect takes its area (or clearcoat) path

// light_reflect (common/area.glsl) up to its point model, by its own tests in its
// order: REUSE_POINT_MODEL with Ldir, diff and spec exactly as light_reflect returns
// them, or which other way it goes (diff and spec then 0). No polygon, LTC or form
// factor code in the caller: on llvmpipe every SIMD group runs the straight-line code
// of both sides of a branch, so the shading pass calls light_reflect nowhere.
int reuse_point_reflect(Light L, Surface s, out vec3 Ldir, out vec3 diff, out vec3 spec) {
    diff = vec3(0.0); spec = vec3(0.0);
    float dist;
    float f = light_falloff(L, s.P, Ldir, dist);
    if (f <= 0.0) return REUSE_OUT_OF_REACH;
#ifdef HAS_CLEARCOAT
    if (s.coat > 0.0) return REUSE_AREA_PATH;
#endif
    float ws = L.misc.w != 0.0 ? area_spec_weight(light_half_extent(L), dist, s.alpha) : 0.0;
    if (light_is_area(L, dist) || ws > 0.0) return REUSE_AREA_PATH;
    vec3 dsp, ssp;
    brdf_eval(s, Ldir, dsp, ssp);
    vec3 E = L.intensity.rgb * light_shape_rgb(L, -Ldir) * f;
    diff = dsp * E; spec = ssp * E;
    return REUSE_POINT_MODEL;
}
#endif
