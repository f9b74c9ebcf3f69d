// Depth-only pass (shadow maps): instanced meshes into a light's clip space.
// ALPHA_TEST: texture coordinates for the material's cut-out (depth_only.frag).
in vec3 in_pos;
in mat4 in_model;
uniform mat4 u_light_view_proj;
#ifdef ALPHA_TEST
in vec2 in_uv;
out vec2 v_uv;
#endif
void main() {
#ifdef ALPHA_TEST
    v_uv = in_uv;
#endif
    gl_Position = u_light_view_proj * (in_model * vec4(in_pos, 1.0));
}
