// Bake, step 2: direct light of the static lights at each lightmap-space G-buffer
// texel, with the same light model and shadow-atlas lookup as the reference method
// (common/lights.glsl, common/shadow.glsl): per texel
//   o_diffuse  rgb: sum_i E_i max(N.L_i, 0) diffuse_i V_i   (irradiance, lux)
//   o_specular rgb: sum_i E_i [N.L_i > 0] specular_i V_i    (illuminance facing the lights)
//   o_dir      xyz: sum_i lum(E_i N.L_i V_i) L_i (dominant direction, unnormalised)
// with E_i the unshadowed illuminance facing light i and V_i its shadow transmission.
// Radiance at runtime: diffuse / PI * o_diffuse (exactly the reference's Lambert term).
#include "common/frame.glsl"
#include "common/brdf.glsl"
#include "common/lights.glsl"
#include "common/shadow.glsl"

uniform sampler2D u_pos;     // rgba32f world position, w = coverage
uniform sampler2D u_normal;  // rgba32f world normal

layout(location = 0) out vec4 o_diffuse;
layout(location = 1) out vec4 o_specular;
layout(location = 2) out vec4 o_dir;

void main() {
    ivec2 px = ivec2(gl_FragCoord.xy);
    vec4 pw = texelFetch(u_pos, px, 0);
    o_diffuse = vec4(0.0);
    o_specular = vec4(0.0);
    o_dir = vec4(0.0);
    if (pw.w <= 0.0) return;
    vec3 P = pw.xyz;
    vec3 N = normalize(texelFetch(u_normal, px, 0).xyz);
    vec3 ed = vec3(0.0), es = vec3(0.0), dir = vec3(0.0);
    uint n = u_counts.x;
    for (uint i = 0u; i < n; ++i) {
        Light L = lights[i];
        vec3 Ldir; float dist;
        vec3 E = light_illuminance(L, P, Ldir, dist);
        if (E.r + E.g + E.b <= 0.0) continue;
        float NoL = dot(N, Ldir);
        if (NoL <= 0.0) continue;
        vec3 EV = E * local_shadow(L, P, N);
        ed += EV * (NoL * L.misc.z);
        es += EV * L.misc.w;
        dir += Ldir * luminance(EV * NoL);
    }
    o_diffuse = vec4(sanitize_radiance(ed), 1.0);
    o_specular = vec4(sanitize_radiance(es), 1.0);
    o_dir = vec4(dir, 1.0);
}
