// Lightmap pass (renderer/tasks/lightmap.py): a baked static mesh, world positions
// (render frame, m) per triangle corner and its lightmap UV.
#include "common/frame.glsl"

in vec3 in_pos;
in vec2 in_uv;

out vec3 v_world;
out vec2 v_uv;

void main() {
    v_world = in_pos;
    v_uv = in_uv;
    gl_Position = u_view_proj * vec4(in_pos, 1.0);
}
