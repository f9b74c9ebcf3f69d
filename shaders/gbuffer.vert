// G-buffer pass: instanced meshes. Per-instance model matrices (object -> render
// frame) for this frame and the previous one (motion vectors). With
// HAS_MATERIAL_TEXTURES: texture coordinates, tangent frames (object-space tangent
// + bitangent sign, see scene/geometry.compute_tangents) and material primvars.
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

#ifdef HAS_MATERIAL_TEXTURES
in vec2 in_uv;
in vec4 in_tangent;
in vec4 in_attr;
out vec2 v_uv;
out vec4 v_tangent;  // world tangent, w bitangent sign (mirrored instances flipped)
out vec4 v_attr;
#endif

void main() {
    vec4 w = in_model * vec4(in_pos, 1.0);
    v_world = w.xyz;
    mat3 m3 = mat3(in_model);
    v_normal = inverse(transpose(m3)) * in_normal;
    v_color = in_color;
    v_clip = u_view_proj * w;
    v_prev_clip = u_prev_view_proj * (in_prev_model * vec4(in_pos, 1.0));
#ifdef HAS_MATERIAL_TEXTURES
    v_uv = in_uv;
    v_tangent = vec4(m3 * in_tangent.xyz, in_tangent.w * (determinant(m3) < 0.0 ? -1.0 : 1.0));
    v_attr = in_attr;
#endif
    gl_Position = v_clip;
}
