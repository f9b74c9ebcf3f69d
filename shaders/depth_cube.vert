// One-submission omni capture (shadow_capture.py, mode "one_pass"): world positions
// of instanced meshes; depth_cube.geom projects each triangle into the cube faces.
in vec3 in_pos;
in mat4 in_model;
#ifdef ALPHA_TEST
in vec2 in_uv;
out vec2 v_uv_vs;
#endif
void main() {
#ifdef ALPHA_TEST
    v_uv_vs = in_uv;
#endif
    gl_Position = in_model * vec4(in_pos, 1.0);
}
