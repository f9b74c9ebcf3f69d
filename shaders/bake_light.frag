// Bake, step 2: direct light of the static lights at each lightmap-space G-buffer
// texel, with the same light model and shadow-atlas lookup as the reference method
// (common/lights.glsl, common/shadow.glsl). With E_i the unshadowed illuminance facing
// light i, V_i its shadow transmission and w_i = lum(E_i V_i max(N.L_i, 0)):
//   o_diffuse   rgb: sum_i E_i V_i max(N.L_i, 0) diffuse_i     (irradiance, lux)
//   o_spec_top  rgb: E_k V_k (N.L_k) specular_k, k = argmax lum(E_i V_i specular_i) (the
//                    strongest light for the specular lobe: grazing light counts)
//   o_dir_top   xyz: L_k (unit)
//   o_spec_2nd, o_dir_2nd: the same for the second strongest
//   o_spec_rest rgb: the same sum over the other lights
//   o_dir_rest  xyz: sum_{i != k} w_i L_i, w: sum_{i != k} w_i (their mean direction)
// Radiance at runtime (shaders/bake_apply.frag): diffuse / PI * o_diffuse -- exactly
// the reference's Lambert term -- plus the GGX lobes towards the two strongest
// lights (exact for them) and towards the others' mean direction.
#include "common/frame.glsl"
#include "common/brdf.glsl"
#include "common/lights.glsl"
#include "common/shadow.glsl"
#include "common/links.glsl"

uniform sampler2D u_pos;     // rgba32f world position, w = coverage
uniform sampler2D u_normal;  // rgba32f world normal
// The light-buffer indices of the lights whose range sphere reaches this mesh's
// bounding box (bake/gpu.py mesh_lights): the others light none of its texels.
layout(std430, binding = SSBO_BAKE_LIGHTS) readonly buffer BakeLights { uint bake_lights[]; };
uniform uint u_bake_count;
#ifdef HAS_LINKS
uniform uint u_link_group;   // the baked mesh's light-link group: unlinked lights skipped
#endif

layout(location = 0) out vec4 o_diffuse;
layout(location = 1) out vec4 o_spec_top;
layout(location = 2) out vec4 o_dir_top;
layout(location = 3) out vec4 o_spec_2nd;
layout(location = 4) out vec4 o_dir_2nd;
layout(location = 5) out vec4 o_spec_rest;
layout(location = 6) out vec4 o_dir_rest;

void main() {
    ivec2 px = ivec2(gl_FragCoord.xy);
    vec4 pw = texelFetch(u_pos, px, 0);
    o_diffuse = o_spec_top = o_dir_top = o_spec_2nd = o_dir_2nd = vec4(0.0);
    o_spec_rest = o_dir_rest = vec4(0.0);
    if (pw.w <= 0.0) return;
    vec3 P = pw.xyz;
    vec3 N = normalize(texelFetch(u_normal, px, 0).xyz);
    vec3 ed = vec3(0.0), es = vec3(0.0), dir = vec3(0.0);
    float wsum = 0.0;
    vec3 top_es = vec3(0.0), top_dir = vec3(0.0), sec_es = vec3(0.0), sec_dir = vec3(0.0);
    float top_w = 0.0, top_wt = 0.0, sec_w = 0.0, sec_wt = 0.0;
    for (uint k = 0u; k < u_bake_count; ++k) {
        uint i = bake_lights[k];
#ifdef HAS_LINKS
        if (!light_linked(i, u_link_group)) continue;
#endif
        Light L = lights[i];
        vec3 Ldir; float dist;
        vec3 E = light_illuminance(L, P, Ldir, dist);
        if (E.r + E.g + E.b <= 0.0) continue;
        float NoL = dot(N, Ldir);
        if (NoL <= 0.0) continue;
        vec3 EVn = E * local_shadow(L, P, N);  // shadowed, facing the light
        vec3 EV = EVn * NoL;
        ed += EV * L.misc.z;
        vec3 s = EV * L.misc.w;
        float w = luminance(EV);
        es += s;
        dir += Ldir * w;
        wsum += w;
        float wt = luminance(EVn * L.misc.w);  // specular importance: grazing light counts
        if (wt > top_wt) {
            sec_wt = top_wt; sec_w = top_w; sec_es = top_es; sec_dir = top_dir;
            top_wt = wt; top_w = w; top_es = s; top_dir = Ldir;
        } else if (wt > sec_wt) {
            sec_wt = wt; sec_w = w; sec_es = s; sec_dir = Ldir;
        }
    }
    o_diffuse = vec4(sanitize_radiance(ed), 1.0);
    o_spec_top = vec4(sanitize_radiance(top_es), 1.0);
    o_dir_top = vec4(top_dir * top_w, top_w);
    o_spec_2nd = vec4(sanitize_radiance(sec_es), 1.0);
    o_dir_2nd = vec4(sec_dir * sec_w, sec_w);
    o_spec_rest = vec4(sanitize_radiance(es - top_es - sec_es), 1.0);
    o_dir_rest = vec4(dir - top_dir * top_w - sec_dir * sec_w, wsum - top_w - sec_w);
}
