// G-buffer pass: linear depth, octahedral normal, base colour + roughness,
// F0 + metallic, motion vectors (px), emission (nits x exposure scale) + occlusion.
// HAS_MATERIAL_TEXTURES: inputs from textures / primvars (common/material.glsl),
// tangent-space normal mapping, opacity cut-outs (discard below the threshold).
#include "common/frame.glsl"
#include "common/packing.glsl"

in vec3 v_world;
in vec3 v_normal;
in vec3 v_color;
in vec4 v_clip;
in vec4 v_prev_clip;

uniform vec3 u_base_color;
uniform float u_use_vertex_color;   // 1: base colour from the vertex colour (displayColor)
uniform float u_roughness;
uniform float u_metallic;
uniform float u_specular_workflow;  // 1: F0 = u_specular_color, metallic ignored
uniform vec3 u_specular_color;
uniform vec3 u_emissive;

layout(location = 0) out float o_depth;
layout(location = 1) out vec2 o_normal;
layout(location = 2) out vec4 o_base_rough;
layout(location = 3) out vec4 o_f0_metal;
layout(location = 4) out vec2 o_motion;
layout(location = 5) out vec4 o_emission;  // rgb emitted radiance (nits) x u_clip.w, a occlusion

#ifdef HAS_MATERIAL_TEXTURES
#include "common/material.glsl"
in vec2 v_uv;
in vec4 v_tangent;
in vec4 v_attr;
uniform float u_opacity;
uniform float u_opacity_threshold;  // > 0: cut-out
uniform float u_f0_dielectric;      // ((ior - 1) / (ior + 1))^2
uniform float u_occlusion;
uniform vec3 u_normal_const;        // tangent-space normal of an untextured input
uniform int u_pv3_slot;             // slot a float3 primvar (v_attr.xyz) drives, -1 none
uniform int u_pv1_slot;             // slot a float primvar (v_attr.w) drives, -1 none
uniform float u_clearcoat;
uniform float u_clearcoat_roughness;

vec4 input_value(int slot, vec4 constant) {
    if (u_pv3_slot == slot) return vec4(v_attr.xyz, 1.0);
    if (u_pv1_slot == slot) return vec4(v_attr.w);
    return mat_value(slot, v_uv, constant);
}

// Tangent-space normal -> world, MikkTSpace style: the interpolated frame, the
// bitangent rebuilt per pixel as sign * cross(N, T). No usable tangent: N.
vec3 perturb_normal(vec3 N, vec3 ts) {
    vec3 T = v_tangent.xyz - N * dot(N, v_tangent.xyz);
    if (dot(T, T) < 1e-12) return N;
    T = normalize(T);
    vec3 B = v_tangent.w * cross(N, T);
    vec3 n = ts.x * T + ts.y * B + ts.z * N;
    return dot(n, n) > 1e-12 ? normalize(n) : N;
}
#endif

#ifdef HAS_CLEARCOAT
// Clearcoat weight and roughness -> g_coat (rg16f) at COAT_TARGET_LOCATION (only for
// scenes with a coated material; renderer/tasks/gbuffer.py).
layout(location = COAT_TARGET_LOCATION) out vec2 o_coat;
#endif

#ifdef HAS_LINKS
// Light linking (scene/links.py): the batch's light-link group -> g_link (r8ui), at the
// attachment after the others (LINK_TARGET_LOCATION, renderer/tasks/gbuffer.py).
uniform uint u_link_group;
layout(location = LINK_TARGET_LOCATION) out uint o_link;
#endif

void main() {
    vec3 n = normalize(v_normal);
    if (!gl_FrontFacing) n = -n;  // single-sided meshes are not culled: light the visible side
    if (any(isnan(n))) n = vec3(0.0, 1.0, 0.0);
    vec3 base = mix(u_base_color, v_color, u_use_vertex_color);
    float rough = u_roughness;
    float metal_in = u_metallic;
    vec3 spec = u_specular_color;
    vec3 emissive = u_emissive;
    float occlusion = 1.0;
    float f0_dielectric = 0.04;
#ifdef HAS_MATERIAL_TEXTURES
    float opacity = input_value(SLOT_OPACITY, vec4(u_opacity)).x;
    if (u_opacity_threshold > 0.0 && !(opacity >= u_opacity_threshold)) discard;
    base = input_value(SLOT_DIFFUSE, vec4(base, 1.0)).rgb;
    rough = input_value(SLOT_ROUGHNESS, vec4(rough)).x;
    metal_in = input_value(SLOT_METALLIC, vec4(metal_in)).x;
    spec = input_value(SLOT_SPECULAR, vec4(spec, 1.0)).rgb;
    emissive = input_value(SLOT_EMISSIVE, vec4(emissive, 1.0)).rgb;
    occlusion = clamp(input_value(SLOT_OCCLUSION, vec4(u_occlusion)).x, 0.0, 1.0);
    f0_dielectric = u_f0_dielectric;
    vec3 ts = mat_value(SLOT_NORMAL, v_uv, vec4(u_normal_const, 0.0)).xyz;
    if (ts != vec3(0.0, 0.0, 1.0)) n = perturb_normal(n, ts);
#ifdef HAS_CLEARCOAT
    float coat = clamp(input_value(SLOT_CLEARCOAT, vec4(u_clearcoat)).x, 0.0, 1.0);
    float coat_rough = input_value(SLOT_CLEARCOAT_ROUGHNESS, vec4(u_clearcoat_roughness)).x;
    o_coat = vec2(coat, clamp(coat_rough, 0.0, 1.0));
#endif
#elif defined(HAS_CLEARCOAT)
    o_coat = vec2(0.0, 1.0);  // the constant program: batches without a coat
#endif
    base = clamp(base, 0.0, 1.0);
    float metal = u_specular_workflow > 0.5 ? 0.0 : clamp(metal_in, 0.0, 1.0);
    vec3 f0 = u_specular_workflow > 0.5 ? clamp(spec, 0.0, 1.0)
                                        : mix(vec3(f0_dielectric), base, metal);
    o_depth = max(-(u_view * vec4(v_world, 1.0)).z, 1e-6);
    o_normal = oct_encode(n);
    o_base_rough = vec4(base, clamp(rough, 0.0, 1.0));
    o_f0_metal = vec4(f0, metal);
    vec2 cur = v_clip.xy / v_clip.w;
    vec2 prev = v_prev_clip.xy / v_prev_clip.w;
    o_motion = (cur - prev) * 0.5 * u_resolution.xy;
    o_emission = vec4(min(max(emissive, 0.0) * u_clip.w, vec3(LIM_HALF_MAX)), occlusion);
#ifdef HAS_LINKS
    o_link = u_link_group;
#endif
}
