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
    float coat;       // clearcoat weight (UsdPreviewSurface clearcoat; 0: none)
    float coat_alpha; // its GGX alpha = clearcoatRoughness^2 (clamped)
};

//: Clearcoat layer: UsdPreviewSurface's second, white specular lobe, IOR 1.5.
const float COAT_F0 = 0.04;

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

// The layers of the BRDF towards unit direction L, each times NoL: the base's
// diffuse and specular lobes (not attenuated by the coat), the clearcoat lobe
// (weight included) and the fraction fc of light the coat reflects (Schlick at VoH
// times the weight): the base sees (1 - fc) of it.
void brdf_eval_layers(Surface s, vec3 L, out vec3 diff, out vec3 spec, out float coat,
                      out float fc) {
    coat = 0.0; fc = 0.0;
    float NoL = dot(s.N, L);
    if (NoL <= 0.0) { diff = vec3(0.0); spec = vec3(0.0); return; }
    vec3 H = normalize(s.V + L);
    float NoV = max(dot(s.N, s.V), 1e-4);
    float NoH = max(dot(s.N, H), 0.0);
    float VoH = max(dot(s.V, H), 0.0);
    diff = s.diffuse * (NoL / PI);
    spec = ggx_d(NoH, s.alpha) * smith_ggx_correlated_v(NoV, NoL, s.alpha)
         * fresnel_schlick(VoH, s.f0) * NoL;
#ifdef HAS_CLEARCOAT
    if (s.coat > 0.0) {
        fc = s.coat * fresnel_schlick(VoH, vec3(COAT_F0)).x;
        coat = ggx_d(NoH, s.coat_alpha) * smith_ggx_correlated_v(NoV, NoL, s.coat_alpha)
             * fc * NoL;
    }
#endif
}

// Reflected radiance factor for light arriving from unit direction L:
// returns (diffuse_brdf * kd, specular_brdf * ks) already multiplied by NoL,
// so radiance = (d + s) * E_perp with E_perp the illuminance facing the light.
// With a clearcoat the base is attenuated by (1 - fc) and the coat lobe is in spec.
void brdf_eval(Surface s, vec3 L, out vec3 diff, out vec3 spec) {
    float coat, fc;
    brdf_eval_layers(s, L, diff, spec, coat, fc);
#ifdef HAS_CLEARCOAT
    diff *= 1.0 - fc;
    spec = spec * (1.0 - fc) + vec3(coat);
#endif
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

// Directional albedo of the whole surface (diffuse + specular + coat) under uniform
// lighting of unit radiance, for the dome: the base attenuated by the coat's Fresnel.
vec3 env_albedo(Surface s, float NoV) {
    vec3 a = s.diffuse + env_brdf_approx(s.f0, s.roughness, NoV);
#ifdef HAS_CLEARCOAT
    if (s.coat > 0.0) {
        float fc = s.coat * fresnel_schlick(NoV, vec3(COAT_F0)).x;
        a = a * (1.0 - fc) + s.coat * env_brdf_approx(vec3(COAT_F0), sqrt(s.coat_alpha), NoV);
    }
#endif
    return a;
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
