// Lightmap pass: baked direct light of static lights, added to g_emission (nits, stored
// times the exposure scale u_clip.w like all of g_emission) where this fragment is the
// G-buffer's surface.
// Diffuse: the reference's Lambert term with the baked irradiance. Specular: the GGX
// lobes towards the two strongest baked lights (exact for them) plus the lobe towards
// the other lights' mean direction, each times its baked irradiance (bake_light.frag).
#include "common/gbuffer.glsl"

// Hidden fragments fail the G-buffer's depth test before shading (no depth writes).
layout(early_fragment_tests) in;

in vec3 v_world;
in vec2 v_uv;

uniform sampler2D u_lightmap0;  // rgb irradiance (lux), diffuse multipliers applied
uniform sampler2D u_lightmap1;  // rgb strongest light's irradiance (lux), specular mult.
uniform sampler2D u_lightmap2;  // xyz its unit direction (world)
uniform sampler2D u_lightmap3;  // rgb, xyz: the same for the second strongest light
uniform sampler2D u_lightmap4;
uniform sampler2D u_lightmap5;  // rgb the other lights' irradiance (lux), specular mult.
uniform sampler2D u_lightmap6;  // xyz their mean direction (world)
uniform float u_depth_match;    // relative view-depth tolerance
uniform float u_facet_match;    // min |cos| between the facet and the G-buffer normal

layout(location = 0) out vec4 o_emission;
layout(location = 1) out float o_mask;  // 1: this pixel's light comes from a lightmap

// GGX lobe towards `dir` (any length > 0) times irradiance `e` that already has N.L.
vec3 baked_specular(Surface s, vec3 dir, vec3 e) {
    if (dot(dir, dir) < 1e-8 || e.r + e.g + e.b <= 0.0) return vec3(0.0);
    vec3 L = normalize(dir);
    vec3 d, sp;
    brdf_eval(s, L, d, sp);  // sp includes N.L: divide it out
    return sp / max(dot(s.N, L), 1e-2) * e;
}

void main() {
    if (!gl_FrontFacing) discard;  // the bake lit the authored front side only
    ivec2 px = ivec2(gl_FragCoord.xy);
    float depth = texelFetch(g_depth, px, 0).r;
    float vd = -(u_view * vec4(v_world, 1.0)).z;
    if (depth <= 0.0 || abs(vd - depth) > u_depth_match * depth) discard;
    Surface s;
    if (!read_surface(px, s)) discard;
    // Where two surfaces meet (wall on floor) both match the depth: keep the one whose
    // facet agrees with the G-buffer normal (the shading normal of a coarse curved
    // mesh is within ~30 degrees of its facets).
    vec3 ng = cross(dFdx(v_world), dFdy(v_world));
    if (dot(ng, ng) > 0.0 && abs(dot(normalize(ng), s.N)) < u_facet_match) discard;
    vec3 c = s.diffuse / PI * max(texture(u_lightmap0, v_uv).rgb, vec3(0.0));
    c += baked_specular(s, texture(u_lightmap2, v_uv).xyz, max(texture(u_lightmap1, v_uv).rgb, vec3(0.0)));
    c += baked_specular(s, texture(u_lightmap4, v_uv).xyz, max(texture(u_lightmap3, v_uv).rgb, vec3(0.0)));
    c += baked_specular(s, texture(u_lightmap6, v_uv).xyz, max(texture(u_lightmap5, v_uv).rgb, vec3(0.0)));
    o_emission = vec4(sanitize_radiance(c * u_clip.w), 0.0);  // g_emission is exposed
    o_mask = 1.0;
}
