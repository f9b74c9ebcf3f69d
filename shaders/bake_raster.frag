// Bake, step 1: the lightmap-space G-buffer: world position (w = 1: covered) and
// world normal per (supersampled) lightmap texel.
in vec3 v_pos;
in vec3 v_normal;

layout(location = 0) out vec4 o_pos;
layout(location = 1) out vec4 o_normal;

void main() {
    vec3 n = normalize(v_normal);
    if (any(isnan(n))) n = vec3(0.0, 1.0, 0.0);
    o_pos = vec4(v_pos, 1.0);
    o_normal = vec4(n, 0.0);
}
