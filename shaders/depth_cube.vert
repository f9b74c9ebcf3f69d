// One-submission omni capture (shadow_capture.py, mode "one_pass"): world positions
// of instanced meshes; depth_cube.geom projects each triangle into the cube faces.
in vec3 in_pos;
in mat4 in_model;
void main() {
    gl_Position = in_model * vec4(in_pos, 1.0);
}
