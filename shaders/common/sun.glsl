// The sun (one shadowed DistantLight) and the dome ambient, shared by every method.
#ifndef STB_SUN_GLSL
#define STB_SUN_GLSL
#include "common/frame.glsl"
#include "common/brdf.glsl"
#include "common/links.glsl"
#ifdef HAS_DOME_MAP
#include "common/dome.glsl"
#endif
#if defined(DOME_OCCLUSION) || defined(DOME_SAMPLED)
// The dome's shadow-map atlas (the reference's samples or the sky occlusion's fixed
// directions). Here, before any other include of it: each file is expanded once, at its
// first #include, whatever the #if around it.
#include "common/dome_sampled.glsl"
#endif
#ifdef DOME_OCCLUSION
#include "common/dome_occlusion.glsl"
#endif

#ifdef HAS_SUN_SHADOW
uniform sampler2DShadow u_sun_shadow;

// 3x3 PCF on the hardware-compared depth map (each tap is a 2x2 bilinear compare).
float sun_shadow(vec3 P, vec3 N) {
    vec3 p = P + N * u_sun_mult.w;
    vec4 c = u_sun_view_proj * vec4(p, 1.0);
    vec3 q = c.xyz / c.w * 0.5 + 0.5;
    if (any(lessThan(q.xy, vec2(0.0))) || any(greaterThan(q.xy, vec2(1.0))) || q.z > 1.0) {
        return 1.0;
    }
    float ref = q.z - u_sun_mult.z;
    float t = u_sun_shadow_color.w;
    float sum = 0.0;
    for (int y = -1; y <= 1; ++y)
        for (int x = -1; x <= 1; ++x)
            sum += texture(u_sun_shadow, vec3(q.xy + vec2(x, y) * t, ref));
    return sum / 9.0;
}
#else
float sun_shadow(vec3 P, vec3 N) { return 1.0; }
#endif

// Sun + dome contribution to the reflected radiance (nits). With HAS_LINKS: of the
// distant lights and domes that light link group `group` (common/links.glsl).
#ifdef HAS_LINKS
vec3 sun_and_ambient(Surface s, uint group) {
#else
vec3 sun_and_ambient(Surface s) {
#endif
    vec3 c = vec3(0.0);
#ifdef HAS_SUN
#if defined(DOME_SUN_SAMPLED)
    if (false) {  // the sun is the dome's: the reference samples it with the dome
#elif defined(HAS_LINKS)
    if (u_sun_dir.w > 0.5 && distant_linked(0, group)) {
#else
    if (u_sun_dir.w > 0.5) {
#endif
        vec3 d, sp;
        brdf_eval(s, u_sun_dir.xyz, d, sp);
        float v = u_sun_illum.w > 0.5 ? sun_shadow(s.P, s.N) : 1.0;
        vec3 vis = mix(u_sun_shadow_color.rgb, vec3(1.0), v);
        c += (d * u_sun_mult.x + sp * u_sun_mult.y) * u_sun_illum.rgb * vis;
    }
    for (int i = 0; i < int(u_ambient.w); ++i) {
#ifdef HAS_LINKS
        if (!distant_linked(i + 1, group)) continue;
#endif
        vec3 d, sp;
        brdf_eval(s, u_dist_dir[i].xyz, d, sp);
        c += (d * u_dist_dir[i].w + sp * u_dist_illum[i].w) * u_dist_illum[i].rgb;
    }
#endif
#ifdef HAS_AMBIENT
    float NoV = max(dot(s.N, s.V), 1e-4);
#ifdef HAS_LINKS
    c += link_ambient[group].rgb * env_albedo(s, NoV) * s.occlusion;
#else
    c += u_ambient.rgb * env_albedo(s, NoV) * s.occlusion;
#endif
#endif
#if defined(HAS_DOME_MAP) && !defined(DOME_SAMPLED)
    // The textured dome (common/dome.glsl); the reference samples it (DOME_SAMPLED).
    // Under light linking it lights the groups its link collection reaches
    // (link_ambient[group].w; the other domes' means are in link_ambient's rgb).
#ifdef HAS_LINKS
    float dome_on = link_ambient[group].w;
#else
    float dome_on = 1.0;
#endif
#ifdef DOME_OCCLUSION
    c += dome_light(s, s.occlusion, dome_sky_visibility(s)) * dome_on;
#else
    c += dome_light(s, s.occlusion, vec2(1.0)) * dome_on;
#endif
#endif
    return c;
}
#endif
