// Lightmap pass: baked direct light of static lights, added to g_emission (nits,
// before exposure, like every light) where this fragment is the G-buffer's surface.
// Diffuse: the reference's Lambert term with the baked irradiance; specular: the
// GGX lobe towards the baked dominant direction times the baked illuminance.
#include "common/gbuffer.glsl"

in vec3 v_world;
in vec2 v_uv;

uniform sampler2D u_lightmap0;  // rgb irradiance (lux), diffuse multipliers applied
uniform sampler2D u_lightmap1;  // rgb illuminance facing the lights (lux), specular mult.
uniform sampler2D u_lightmap2;  // xyz unit dominant direction (world), 0 = none
uniform float u_depth_match;    // relative view-depth tolerance

layout(location = 0) out vec4 o_emission;

void main() {
    if (!gl_FrontFacing) discard;  // the bake lit the authored front side only
    ivec2 px = ivec2(gl_FragCoord.xy);
    float depth = texelFetch(g_depth, px, 0).r;
    float vd = -(u_view * vec4(v_world, 1.0)).z;
    if (depth <= 0.0 || abs(vd - depth) > u_depth_match * depth) discard;
    Surface s;
    if (!read_surface(px, s)) discard;
    vec3 c = s.diffuse / PI * max(texture(u_lightmap0, v_uv).rgb, vec3(0.0));
    vec3 es = max(texture(u_lightmap1, v_uv).rgb, vec3(0.0));
    vec3 dir = texture(u_lightmap2, v_uv).xyz;
    if (dot(dir, dir) > 1e-6 && es.r + es.g + es.b > 0.0) {
        vec3 d, sp;
        brdf_eval(s, normalize(dir), d, sp);
        c += sp * es;
    }
    o_emission = vec4(sanitize_radiance(c), 0.0);
}
