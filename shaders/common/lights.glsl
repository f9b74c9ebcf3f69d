// The packed FoV light buffer (std430 SSBO, binding SSBO_LIGHTS) and the light's emitted
// intensity towards a direction. Layout: LIGHT_LAYOUT in renderer/shader_constants.py
// (the same members in the same order), written by renderer/light_buffer.py.
#ifndef STB_LIGHTS_GLSL
#define STB_LIGHTS_GLSL
#include "common/ies.glsl"

struct Light {
    vec4 pos_range;     // xyz position (m), w influence radius (m)
    vec4 axis_emit;     // xyz emission axis (light -Z, unit), w emission model (0 iso, 1 cosine, 2 cylinder)
    vec4 tangent_tex;   // xyz light +X (unit), w RectLight texture layer (-1 none)
    vec4 intensity;     // rgb peak intensity (cd) before IES, w luminous weight (lm) for big-tile pdf
    vec4 cone;          // x cos(cutoff), y cutoff (rad), z smooth start (rad), w focus exponent
    vec4 tint_ies;      // rgb focusTint, w IES layer (-1 none)
    vec4 ies_shadow;    // x IES scale (cd per table unit), y angleScale, z shadow map (-1 none), w shadow flags
    vec4 shadow_color;  // rgb shadow colour, w shadow max distance (m, <0 none)
    vec4 misc;          // x shadow falloff (m), y falloff gamma, z diffuse mult, w specular mult
    vec4 area;          // xy half sizes (m), z area shape code (AREA_*), w radiance per cd (m^-2)
};

layout(std430, binding = SSBO_LIGHTS) readonly buffer LightBuffer { Light lights[]; };

// Smooth fade to exactly 0 over the last (1 - LIM_RANGE_FADE_START) of the range.
float range_window(float d, float range) {
    return 1.0 - smoothstep(range * LIM_RANGE_FADE_START, range, d);
}

// The light's angular distribution towards unit direction `w` leaving it is
// split in two so STB can store one part in its 8-bit shadow terms:
//   light_shape_scalar: cone x normalised IES table, in [0, 1]
//   light_shape_rgb:    emission model x focusTint colour x IES scale (cd per table unit)
// light_shape = scalar * rgb.
float light_shape_scalar(Light L, vec3 w) {
    float c = dot(w, L.axis_emit.xyz);      // cos of the angle off the axis
    float shape = 1.0;
#ifdef HAS_CONES
    if (L.cone.y < CONE_CUTOFF_TEST_RAD) {
        float theta = acos(clamp(c, -1.0, 1.0));
        if (theta > L.cone.y) return 0.0;
        if (L.cone.y > L.cone.z) {
            float t = clamp((theta - L.cone.z) / (L.cone.y - L.cone.z), 0.0, 1.0);
            shape *= 1.0 - t * t * (3.0 - 2.0 * t);
        }
    }
#endif
#ifdef HAS_IES
    if (L.tint_ies.w >= 0.0) {
        vec3 bitangent = cross(-L.axis_emit.xyz, L.tangent_tex.xyz);  // light +Y = Z x X
        shape *= ies_table(int(L.tint_ies.w), L.ies_shadow.y, c,
                           dot(w, L.tangent_tex.xyz), dot(w, bitangent));
    }
#endif
    return shape;
}

// Emission model towards unit direction `w` leaving the light: 1 (isotropic),
// cos+ off the axis (disk, rect: one-sided), sin to the X axis (cylinder side).
float emission_shape(Light L, vec3 w) {
    if (L.axis_emit.w == EMIT_COSINE) return max(dot(w, L.axis_emit.xyz), 0.0);
    if (L.axis_emit.w == EMIT_CYLINDER) {
        float ca = dot(w, L.tangent_tex.xyz);
        return sqrt(max(1.0 - ca * ca, 0.0));
    }
    return 1.0;
}

// focusTint colour x IES scale towards w (light_shape_rgb without the emission model).
vec3 light_tint_rgb(Light L, vec3 w) {
    float shape = 1.0;
#ifdef HAS_IES
    if (L.tint_ies.w >= 0.0) shape *= L.ies_shadow.x;
#endif
    vec3 tint = vec3(1.0);
    if (L.cone.w > 0.0) {
        float f = pow(abs(dot(w, L.axis_emit.xyz)), L.cone.w);
        tint = mix(L.tint_ies.rgb, vec3(1.0), f);
    }
    return tint * shape;
}

vec3 light_shape_rgb(Light L, vec3 w) {
    return light_tint_rgb(L, w) * emission_shape(L, w);
}

vec3 light_shape(Light L, vec3 w) {
    return light_shape_scalar(L, w) * light_shape_rgb(L, w);
}

// Inverse-square falloff times the range window (1/m^2); Ldir = unit direction
// from P to the light, dist in metres. Zero outside the range.
float light_falloff(Light L, vec3 P, out vec3 Ldir, out float dist) {
    vec3 d = L.pos_range.xyz - P;
    dist = length(d);
    Ldir = d / max(dist, 1e-12);
    if (dist >= L.pos_range.w) return 0.0;
    float r = max(dist, LIM_MIN_LIGHT_DISTANCE);
    return range_window(dist, L.pos_range.w) / (r * r);
}

// Unshadowed illuminance (lux, RGB) facing the light at P.
vec3 light_illuminance(Light L, vec3 P, out vec3 Ldir, out float dist) {
    float f = light_falloff(L, P, Ldir, dist);
    if (f <= 0.0) return vec3(0.0);
    return L.intensity.rgb * light_shape(L, -Ldir) * f;
}

#include "common/area.glsl"
#endif
