// STB's cheap light target at one surface point (luminance, unshadowed, without the
// term's cone/IES part): area irradiance x diffuse + Blinn-Phong specular from the
// light's centre. Shared by the small tile's refined target (4 points, averaged
// material) and the lighting pass's per-pixel resampling (select=ris).
// Returns (lit part, Ev x (diffuse + specular)): the caller scales the first by its
// visibility and adds the second x eps, which keeps the target > 0 wherever the light
// reaches the point. kd, ks: luminance of diffuse albedo and F0; spec_n, spec_norm:
// the Blinn-Phong exponent and normalisation; with_scalar: include the light's cone x IES
// (light_shape_scalar) -- false where a shadow term that holds them multiplies the target.
#ifndef STB_TARGET_GLSL
#define STB_TARGET_GLSL

vec2 stb_point_target(Light L, vec3 P, vec3 N, vec3 V, float kd, float ks, float spec_n,
                      float spec_norm, bool with_scalar) {
    vec3 Ldir; float dist;
    float f = light_falloff(L, P, Ldir, dist);
    if (f <= 0.0) return vec2(0.0);
    vec3 shape = with_scalar ? light_shape(L, -Ldir) : light_shape_rgb(L, -Ldir);
    float Ev = luminance(L.intensity.rgb * shape) * f;
    float Ea = light_target_irradiance(L, P, N, Ldir, dist, Ev);
    float NoL = max(dot(N, Ldir), 0.0);
    vec3 H = normalize(V + Ldir);
    float NoH = max(dot(N, H), 0.0);
    float fv = kd / PI + ks * spec_norm * pow(NoH, spec_n);
    // Area irradiance for the diffuse part (issue 20): positive wherever the light
    // reaches the point, so Ev x eps keeps the target positive there.
    return vec2(kd / PI * Ea + Ev * ks * spec_norm * pow(NoH, spec_n) * NoL, Ev * fv);
}
#endif
