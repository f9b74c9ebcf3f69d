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
// The *_m forms take the Light members they read (the point loop loads only those,
// past its range test: light_radiance_point_at); the Light forms call them.
float light_shape_scalar_m(vec4 axis_emit, vec4 cone, vec4 tint_ies, vec3 tangent,
                           float angle_scale, vec3 w) {
    float c = dot(w, axis_emit.xyz);      // cos of the angle off the axis
    float shape = 1.0;
#ifdef HAS_CONES
    if (cone.y < CONE_CUTOFF_TEST_RAD) {
        float theta = acos(clamp(c, -1.0, 1.0));
        if (theta > cone.y) return 0.0;
        if (cone.y > cone.z) {
            float t = clamp((theta - cone.z) / (cone.y - cone.z), 0.0, 1.0);
            shape *= 1.0 - t * t * (3.0 - 2.0 * t);
        }
    }
#endif
#ifdef HAS_IES
    if (tint_ies.w >= 0.0) {
        vec3 bitangent = cross(-axis_emit.xyz, tangent);  // light +Y = Z x X
        shape *= ies_table(int(tint_ies.w), angle_scale, c, dot(w, tangent), dot(w, bitangent));
    }
#endif
    return shape;
}
float light_shape_scalar(Light L, vec3 w) {
    return light_shape_scalar_m(L.axis_emit, L.cone, L.tint_ies, L.tangent_tex.xyz,
                                L.ies_shadow.y, w);
}

// Emission model towards unit direction `w` leaving the light: 1 (isotropic),
// cos+ off the axis (disk, rect: one-sided), sin to the X axis (cylinder side).
float emission_shape_m(vec4 axis_emit, vec3 tangent, vec3 w) {
    if (axis_emit.w == EMIT_COSINE) return max(dot(w, axis_emit.xyz), 0.0);
    if (axis_emit.w == EMIT_CYLINDER) {
        float ca = dot(w, tangent);
        return sqrt(max(1.0 - ca * ca, 0.0));
    }
    return 1.0;
}
float emission_shape(Light L, vec3 w) { return emission_shape_m(L.axis_emit, L.tangent_tex.xyz, w); }

// focusTint colour x IES scale towards w (light_shape_rgb without the emission model).
vec3 light_tint_rgb_m(vec4 axis_emit, vec4 cone, vec4 tint_ies, float ies_scale, vec3 w) {
    float shape = 1.0;
#ifdef HAS_IES
    if (tint_ies.w >= 0.0) shape *= ies_scale;
#endif
    vec3 tint = vec3(1.0);
#ifndef NO_FOCUS  // no light in view has a focus (InViewLights.has_focus): tint is 1
    if (cone.w > 0.0) {
        float f = pow(abs(dot(w, axis_emit.xyz)), cone.w);
        tint = mix(tint_ies.rgb, vec3(1.0), f);
    }
#endif
    return tint * shape;
}
vec3 light_tint_rgb(Light L, vec3 w) {
    return light_tint_rgb_m(L.axis_emit, L.cone, L.tint_ies, L.ies_shadow.x, w);
}

vec3 light_shape_rgb(Light L, vec3 w) {
    return light_tint_rgb(L, w) * emission_shape(L, w);
}

vec3 light_shape(Light L, vec3 w) {
    return light_shape_scalar(L, w) * light_shape_rgb(L, w);
}

// Inverse-square falloff times the range window (1/m^2); Ldir = unit direction
// from P to the light, dist in metres. Zero outside the range.
float light_falloff_m(vec4 pos_range, vec3 P, out vec3 Ldir, out float dist) {
    vec3 d = pos_range.xyz - P;
    dist = length(d);
    Ldir = d / max(dist, 1e-12);
    if (dist >= pos_range.w) return 0.0;
    float r = max(dist, LIM_MIN_LIGHT_DISTANCE);
    return range_window(dist, pos_range.w) / (r * r);
}
float light_falloff(Light L, vec3 P, out vec3 Ldir, out float dist) {
    return light_falloff_m(L.pos_range, P, Ldir, dist);
}

// Whether light i's range reaches P: light_falloff's own test (the same expression), on
// pos_range alone -- a loop tests it before it copies the Light from the SSBO.
bool light_reaches(uint i, vec3 P) {
    return length(lights[i].pos_range.xyz - P) < lights[i].pos_range.w;
}

// Unshadowed illuminance (lux, RGB) facing the light at P.
vec3 light_illuminance(Light L, vec3 P, out vec3 Ldir, out float dist) {
    float f = light_falloff(L, P, Ldir, dist);
    if (f <= 0.0) return vec3(0.0);
    return L.intensity.rgb * light_shape(L, -Ldir) * f;
}

#include "common/area.glsl"
#endif
