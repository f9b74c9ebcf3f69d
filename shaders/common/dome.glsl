// A textured DomeLight (issue 37; renderer/dome_env.py): its render-frame lat-long
// map (OpenEXR convention: v = 0 the zenith +Y, u = 0.5 facing +Z), SH9 irradiance
// for the diffuse term and the map's mip chain as prefiltered radiance for the
// split-sum specular term. Radiance in nits, directions in the render frame.
#ifndef STB_DOME_GLSL
#define STB_DOME_GLSL
#include "common/brdf.glsl"

uniform sampler2D u_dome_map;  // rgb radiance factor, mipmapped, repeat in u (lighting:
                               // without its sun when the sun is lit as the shadowed sun)
uniform sampler2D u_dome_sky;  // the whole map (what the camera sees)
uniform vec3 u_dome_sh[LIM_DOME_SH_COEFFS];     // SH9 of E(n) / pi (nits), the light's scale applied
uniform vec4 u_dome_scale;     // rgb nits per map unit, w: the map's last mip level
uniform vec4 u_dome_mult;      // x diffuse, y specular multiplier, z camera visible, w map width

// Lat-long coordinates of a unit direction.
vec2 dome_uv(vec3 d) {
    float lon = atan(d.x, d.z);
    return vec2((PI - lon) / (2.0 * PI), acos(clamp(d.y, -1.0, 1.0)) / PI);
}

// Dome radiance (nits) arriving from unit direction d, prefiltered at mip `lod`.
vec3 dome_radiance(vec3 d, float lod) {
    return textureLod(u_dome_map, dome_uv(d), lod).rgb * u_dome_scale.rgb;
}

// The dome as the camera sees it (nits), sun included.
vec3 dome_sky(vec3 d) {
    return textureLod(u_dome_sky, dome_uv(d), 0.0).rgb * u_dome_scale.rgb;
}

// E(n) / pi (nits): the radiance a white Lambert surface of normal n reflects.
vec3 dome_irradiance(vec3 n) {
    vec3 e = u_dome_sh[0] * 0.282095
        + u_dome_sh[1] * (0.488603 * n.y) + u_dome_sh[2] * (0.488603 * n.z)
        + u_dome_sh[3] * (0.488603 * n.x)
        + u_dome_sh[4] * (1.092548 * n.x * n.y) + u_dome_sh[5] * (1.092548 * n.y * n.z)
        + u_dome_sh[6] * (0.315392 * (3.0 * n.z * n.z - 1.0))
        + u_dome_sh[7] * (1.092548 * n.x * n.z)
        + u_dome_sh[8] * (0.546274 * (n.x * n.x - n.y * n.y));
    return max(e, vec3(0.0));
}

// Mip level whose texel spans the GGX lobe of `roughness` (lobe width ~ alpha rad).
float dome_lod(float roughness) {
    float alpha = max(roughness * roughness, 1e-4);
    return clamp(log2(alpha * u_dome_mult.w / PI), 0.0, u_dome_scale.w);
}

// Reflected radiance (nits) of the textured dome: diffuse from SH9, specular by the
// split sum, times `occlusion` (the material's) and the share `vis` (diffuse,
// specular) of the sky that reaches the point (common/dome_occlusion.glsl; vec2(1):
// unshadowed).
// A clearcoat (HAS_CLEARCOAT) adds its own split-sum lobe at its roughness and takes
// its Fresnel share off the base layer, as brdf_eval does for the other lights.
vec3 dome_light(Surface s, float occlusion, vec2 vis) {
    float NoV = max(dot(s.N, s.V), 1e-4);
    vec3 diff = s.diffuse * dome_irradiance(s.N);
    vec3 R = reflect(-s.V, s.N);
    vec3 spec = env_brdf_approx(s.f0, s.roughness, NoV) * dome_radiance(R, dome_lod(s.roughness));
    vec3 c = diff * (u_dome_mult.x * vis.x) + spec * (u_dome_mult.y * vis.y);
#ifdef HAS_CLEARCOAT
    if (s.coat > 0.0) {
        float fc = s.coat * fresnel_schlick(NoV, vec3(COAT_F0)).x;
        float coat_rough = sqrt(s.coat_alpha);
        vec3 coat = s.coat * env_brdf_approx(vec3(COAT_F0), coat_rough, NoV)
            * dome_radiance(R, dome_lod(coat_rough));
        c = c * (1.0 - fc) + coat * (u_dome_mult.y * vis.y);
    }
#endif
    return c * occlusion;
}
#endif
