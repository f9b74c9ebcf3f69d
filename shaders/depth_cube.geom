// One-submission omni capture: each triangle goes to every cube face (bit f of
// u_face_mask, the CPU's per-batch culling) whose clip volume it may touch (outcode
// test), into that face's cell of the 3x2 grid target. The face's viewport transform
// is done here (x -> (x + kx w) / 3, y -> (y + ky w) / 2) with the face's side planes
// as clip distances, so one full-target viewport serves all six faces and a triangle
// never spills into a neighbouring cell. Depth (z / w) is that of the per-face path.
layout(triangles) in;
layout(triangle_strip, max_vertices = 18) out;
uniform mat4 u_face_vp[LIM_CUBE_FACES];
uniform int u_face_mask;
out float gl_ClipDistance[4];
#ifdef ALPHA_TEST
in vec2 v_uv_vs[];
out vec2 v_uv;
#endif

bool outside(vec4 a, vec4 b, vec4 c) {
    // every vertex beyond the same clip plane
    return (a.x > a.w && b.x > b.w && c.x > c.w) || (a.x < -a.w && b.x < -b.w && c.x < -c.w)
        || (a.y > a.w && b.y > b.w && c.y > c.w) || (a.y < -a.w && b.y < -b.w && c.y < -c.w)
        || (a.z > a.w && b.z > b.w && c.z > c.w) || (a.z < -a.w && b.z < -b.w && c.z < -c.w);
}

void main() {
    for (int f = 0; f < 6; ++f) {
        if ((u_face_mask & (1 << f)) == 0) continue;
        vec4 c0 = u_face_vp[f] * gl_in[0].gl_Position;
        vec4 c1 = u_face_vp[f] * gl_in[1].gl_Position;
        vec4 c2 = u_face_vp[f] * gl_in[2].gl_Position;
        if (outside(c0, c1, c2)) continue;
        vec2 k = vec2(float(2 * (f % 3) - 2), float(2 * (f / 3) - 1));
        vec4 cs[3] = vec4[3](c0, c1, c2);
        for (int i = 0; i < 3; ++i) {
            vec4 p = cs[i];
            gl_ClipDistance[0] = p.w - p.x;
            gl_ClipDistance[1] = p.w + p.x;
            gl_ClipDistance[2] = p.w - p.y;
            gl_ClipDistance[3] = p.w + p.y;
            gl_Position = vec4((p.x + k.x * p.w) / 3.0, (p.y + k.y * p.w) / 2.0, p.z, p.w);
#ifdef ALPHA_TEST
            v_uv = v_uv_vs[i];
#endif
            EmitVertex();
        }
        EndPrimitive();
    }
}
