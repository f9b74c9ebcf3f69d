// Bake, step 1: a static mesh rasterised in lightmap space (stb_hydra/bake/gpu.py).
// Each vertex is a triangle corner: lightmap UV in [0, 1], world position (m) and
// unit world normal (render frame).
in vec2 in_uv;
in vec3 in_pos;
in vec3 in_normal;

out vec3 v_pos;
out vec3 v_normal;

void main() {
    v_pos = in_pos;
    v_normal = in_normal;
    gl_Position = vec4(in_uv * 2.0 - 1.0, 0.0, 1.0);
}
