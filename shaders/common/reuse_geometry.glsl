// STB reuse (issue 31): may a reservoir of one surface be reused at another? Linear
// depths (m, > 0) within LIM_REUSE_DEPTH_REL of each other, normals within
// acos(LIM_REUSE_NORMAL_COS), roughness within LIM_REUSE_ROUGHNESS_DIFF (a material
// test: a rough floor's reservoir is a poor guess for a mirror). Depth 0 = background.
#ifndef STB_REUSE_GEOMETRY_GLSL
#define STB_REUSE_GEOMETRY_GLSL

bool reuse_similar(float d0, vec3 n0, float r0, float d1, vec3 n1, float r1) {
    return d0 > 0.0 && d1 > 0.0 && abs(d0 - d1) <= LIM_REUSE_DEPTH_REL * d0
        && dot(n0, n1) >= LIM_REUSE_NORMAL_COS && abs(r0 - r1) <= LIM_REUSE_ROUGHNESS_DIFF;
}
#endif
