// Sky occlusion of the real-time methods' textured dome (issue 37;
// renderer/dome_shadows.SkyOcclusion): a fixed set of directions drawn from the dome
// (its split-off sun left out), each with a directional shadow map in the dome atlas of
// common/dome_sampled.glsl. The share of the sky light that reaches P is the
// light-weighted mean of their visibilities: for the diffuse term weighted by each
// direction's illuminance x cos, for the specular term by illuminance x a Phong lobe
// of the surface's roughness about the mirror direction (the diffuse share where no
// direction falls in the lobe). Multiplies dome_light's two terms.
// Needs common/dome_sampled.glsl included before it (common/sun.glsl does: includes
// are expanded once, textually, so both sit under the same condition there).
#ifndef STB_DOME_OCCLUSION_GLSL
#define STB_DOME_OCCLUSION_GLSL

// (diffuse, specular) share of the prefiltered dome light that reaches surface s.
vec2 dome_sky_visibility(Surface s) {
    vec3 R = reflect(-s.V, s.N);
    float alpha = max(s.roughness * s.roughness, LIM_GGX_ALPHA_MIN);
    float lobe = clamp(2.0 / (alpha * alpha) - 2.0, 1.0, 256.0);  // Phong exponent
    float wd = 0.0, vd = 0.0, ws = 0.0, vs = 0.0;
    int n = int(u_dome_tiles.z);
    for (int k = 0; k < n; ++k) {
        vec3 L = u_dome_dir[k].xyz;
        float NoL = dot(L, s.N);
        if (NoL <= 0.0) continue;
        float e = luminance(u_dome_illum[k].rgb);
        float v = dome_sample_visibility(k, s.P, s.N, NoL);
        wd += e * NoL;
        vd += e * NoL * v;
        float w = e * pow(max(dot(R, L), 0.0), lobe);
        ws += w;
        vs += w * v;
    }
    float diffuse = wd > 0.0 ? vd / wd : 1.0;
    float specular = ws > 1e-6 * wd ? vs / ws : diffuse;
    return vec2(diffuse, specular);
}
#endif
