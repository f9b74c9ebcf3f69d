// Lightmap pass, part 2: pixels no lightmap covered (dynamic geometry, static meshes
// that could not be baked, back faces) still receive the baked lights: every
// in-view baked light evaluated exactly as the reference method does, unshadowed
// (baked lights have no shadow maps), added to g_emission.
#include "common/gbuffer.glsl"
#include "common/lights.glsl"
#include "common/links.glsl"

uniform sampler2D u_mask;   // r8: 1 where a lightmap was applied
uniform int u_baked_count;  // lights in the bound light buffer (the baked ones)

layout(location = 0) out vec4 o_emission;

void main() {
    ivec2 px = ivec2(gl_FragCoord.xy);
    if (texelFetch(u_mask, px, 0).r > 0.5) discard;
    Surface s;
    if (!read_surface(px, s)) discard;
    vec3 c = vec3(0.0);
#ifdef HAS_LINKS
    uint group = link_group(px);
#endif
    for (int i = 0; i < u_baked_count; ++i) {
#ifdef HAS_LINKS
        if (!light_linked(uint(i), group)) continue;
#endif
        Light L = lights[i];
        vec3 Ldir; float dist;
        vec3 E = light_illuminance(L, s.P, Ldir, dist);
        if (E.r + E.g + E.b <= 0.0) continue;
        vec3 d, sp;
        brdf_eval(s, Ldir, d, sp);
        c += (d * L.misc.z + sp * L.misc.w) * E;
    }
    o_emission = vec4(sanitize_radiance(c * u_clip.w), 0.0);  // g_emission is exposed
}
