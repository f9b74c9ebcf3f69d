// Copy a freshly rendered depth capture into its atlas rect: linearise,
// convert to distance along each texel's ray, add the bias, normalise by the
// range, and fill the 3 px border (spot: clamp to the interior; omni:
// octahedral mirroring). Drawn with the viewport = the whole rect (border included).
#include "common/octahedral.glsl"

uniform sampler2D u_depth;      // spot: S x S perspective depth; omni: 3F x 2F cube-face grid
uniform ivec4 u_rect;           // rect x, y, side (incl. border), border
uniform int u_omni;
uniform float u_near;
uniform float u_far;
uniform float u_tan_half;       // spot: tan(fov / 2)
uniform float u_range;
uniform float u_bias_angle;     // bias = u_bias_angle * distance (rad: ~1 texel)
uniform mat3 u_face_rot[LIM_CUBE_FACES];     // omni: world direction -> face view space (looks down -Z)

layout(location = 0) out float o_depth;

float linear_z(float depth) {
    float z = depth * 2.0 - 1.0;
    return 2.0 * u_near * u_far / (u_far + u_near - z * (u_far - u_near));
}

void main() {
    vec2 local = gl_FragCoord.xy - vec2(u_rect.xy);      // 0 .. side
    float border = float(u_rect.w);
    float S = float(u_rect.z) - 2.0 * border;            // interior side
    vec2 uv = (local - border) / S;                       // may be outside [0,1] in the border
    float dist;
    float raw;
    if (u_omni == 0) {
        uv = clamp(uv, 0.5 / S, 1.0 - 0.5 / S);
        raw = texture(u_depth, uv).r;
        float z = linear_z(raw);
        vec2 ndc = uv * 2.0 - 1.0;
        dist = z * length(vec3(ndc * u_tan_half, 1.0));
    } else {
        vec3 dir = oct_uv_to_dir(oct_wrap_uv(uv));
        // face with the largest |component| (same faces the capture rendered)
        vec3 a = abs(dir);
        int face = a.x >= a.y && a.x >= a.z ? (dir.x > 0.0 ? 0 : 1)
                 : (a.y >= a.z ? (dir.y > 0.0 ? 2 : 3) : (dir.z > 0.0 ? 4 : 5));
        vec3 v = u_face_rot[face] * dir;                   // view space, -z forward
        vec2 fuv = (v.xy / -v.z) * 0.5 + 0.5;
        vec2 cell = vec2(face % 3, face / 3);
        vec2 tuv = (cell + clamp(fuv, vec2(0.001), vec2(0.999))) / vec2(3.0, 2.0);
        raw = texture(u_depth, tuv).r;
        float z = linear_z(raw);
        dist = z / max(-v.z, 1e-6);
    }
    // Nothing rendered there (depth at the far plane): no occluder within range.
    o_depth = raw >= 1.0 ? 1.0 : clamp(dist * (1.0 + u_bias_angle) / u_range, 0.0, 1.0);
}
