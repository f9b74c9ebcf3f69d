// G-buffer pass: linear depth, octahedral normal, base colour + roughness,
// F0 + metallic, motion vectors (px), emission (nits).
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
layout(location = 5) out vec4 o_emission;
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
    base = clamp(base, 0.0, 1.0);
    float metal = u_specular_workflow > 0.5 ? 0.0 : clamp(u_metallic, 0.0, 1.0);
    vec3 f0 = u_specular_workflow > 0.5 ? clamp(u_specular_color, 0.0, 1.0)
                                        : mix(vec3(0.04), base, metal);
    o_depth = max(-(u_view * vec4(v_world, 1.0)).z, 1e-6);
    o_normal = oct_encode(n);
    o_base_rough = vec4(base, clamp(u_roughness, 0.0, 1.0));
    o_f0_metal = vec4(f0, metal);
    vec2 cur = v_clip.xy / v_clip.w;
    vec2 prev = v_prev_clip.xy / v_prev_clip.w;
    o_motion = (cur - prev) * 0.5 * u_resolution.xy;
    o_emission = vec4(min(max(u_emissive, 0.0), vec3(LIM_HALF_MAX)), 1.0);
#ifdef HAS_LINKS
    o_link = u_link_group;
#endif
}
