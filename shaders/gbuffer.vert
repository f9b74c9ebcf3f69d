// G-buffer pass: instanced meshes. Per-instance model matrices (object -> render
// frame) for this frame and the previous one (motion vectors).
#include "common/frame.glsl"

in vec3 in_pos;
in vec3 in_normal;
in vec3 in_color;
in mat4 in_model;
in mat4 in_prev_model;

out vec3 v_world;
out vec3 v_normal;
out vec3 v_color;
out vec4 v_clip;
out vec4 v_prev_clip;

void main() {
    vec4 w = in_model * vec4(in_pos, 1.0);
    v_world = w.xyz;
    v_normal = inverse(transpose(mat3(in_model))) * in_normal;
    v_color = in_color;
    v_clip = u_view_proj * w;
    v_prev_clip = u_prev_view_proj * (in_prev_model * vec4(in_pos, 1.0));
    gl_Position = v_clip;
}
