// Depth-only pass (shadow maps): instanced meshes into a light's clip space.
in vec3 in_pos;
in mat4 in_model;
uniform mat4 u_light_view_proj;
void main() {
    gl_Position = u_light_view_proj * (in_model * vec4(in_pos, 1.0));
}
