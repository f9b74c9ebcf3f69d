// Lambert + GGX microfacet BRDF (Smith height-correlated visibility, Schlick Fresnel).
// Shared by every lighting method so images compare pixel for pixel. PI and
// LUMINANCE_REC709 come from the generated common/constants.glsl (shader_constants.py).
#ifndef STB_BRDF_GLSL
#define STB_BRDF_GLSL
struct Surface {
    vec3 P;        // world position (m)
    vec3 N;        // unit normal (world)
    vec3 V;        // unit direction to the eye
    vec3 diffuse;  // Lambert albedo (base * (1 - metallic))
    vec3 f0;       // specular reflectance at normal incidence
    float alpha;   // GGX alpha = roughness^2 (clamped)
    float roughness;
    float occlusion;  // ambient occlusion of the dome term (material occlusion input)
};

float ggx_d(float NoH, float a) {
    float a2 = a * a;
    float d = NoH * NoH * (a2 - 1.0) + 1.0;
    return a2 / (PI * d * d);
}
float smith_ggx_correlated_v(float NoV, float NoL, float a) {
    float a2 = a * a;
    float gv = NoL * sqrt(NoV * NoV * (1.0 - a2) + a2);
    float gl = NoV * sqrt(NoL * NoL * (1.0 - a2) + a2);
    return 0.5 / max(gv + gl, 1e-8);
}
vec3 fresnel_schlick(float VoH, vec3 f0) {
    float f = pow(1.0 - VoH, 5.0);
    return f0 + (1.0 - f0) * f;
}

// Reflected radiance factor for light arriving from unit direction L:
// returns (diffuse_brdf * kd, specular_brdf * ks) already multiplied by NoL,
// so radiance = (d + s) * E_perp with E_perp the illuminance facing the light.
void brdf_eval(Surface s, vec3 L, out vec3 diff, out vec3 spec) {
    float NoL = dot(s.N, L);
    if (NoL <= 0.0) { diff = vec3(0.0); spec = vec3(0.0); return; }
    vec3 H = normalize(s.V + L);
    float NoV = max(dot(s.N, s.V), 1e-4);
    float NoH = max(dot(s.N, H), 0.0);
    float VoH = max(dot(s.V, H), 0.0);
    diff = s.diffuse * (NoL / PI);
    spec = ggx_d(NoH, s.alpha) * smith_ggx_correlated_v(NoV, NoL, s.alpha)
         * fresnel_schlick(VoH, s.f0) * NoL;
}

// Directional albedo of the specular lobe under uniform lighting (Karis 2014,
// "Physically Based Shading on Mobile" analytic fit), for dome ambient.
vec3 env_brdf_approx(vec3 f0, float roughness, float NoV) {
    const vec4 c0 = vec4(-1.0, -0.0275, -0.572, 0.022);
    const vec4 c1 = vec4(1.0, 0.0425, 1.04, -0.04);
    vec4 r = roughness * c0 + c1;
    float a004 = min(r.x * r.x, exp2(-9.28 * NoV)) * r.x + r.y;
    vec2 ab = vec2(-1.04, 1.04) * a004 + r.zw;
    return f0 * ab.x + ab.y;
}

// Luminance (Rec.709).
float luminance(vec3 c) { return dot(c, LUMINANCE_REC709); }

// Finite, non-negative, under fp16 max: what every lighting pass writes.
vec3 sanitize_radiance(vec3 c) {
    c = max(c, vec3(0.0));
    c = vec3(isnan(c.x) ? 0.0 : c.x, isnan(c.y) ? 0.0 : c.y, isnan(c.z) ? 0.0 : c.z);
    return min(c, vec3(LIM_HALF_MAX));
}
#endif
