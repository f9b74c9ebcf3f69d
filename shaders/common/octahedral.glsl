// Octahedral mapping of unit directions to [0, 1]^2 (world axes; Meyer et al.
// 2010 / Cigolle et al. 2014) and the border rule for filtering across its edges:
// a texel just outside the square continues at the point mirrored through the
// edge's midpoint (u > 1 -> (2 - u, 1 - v), v > 1 -> (1 - u, 2 - v), likewise
// below 0), which is the neighbouring direction on the sphere.
#ifndef STB_OCTAHEDRAL_GLSL
#define STB_OCTAHEDRAL_GLSL

vec2 oct_dir_to_uv(vec3 d) {
    d /= (abs(d.x) + abs(d.y) + abs(d.z));
    vec2 e = d.xz;
    if (d.y < 0.0) {
        e = (1.0 - abs(d.zx)) * vec2(d.x >= 0.0 ? 1.0 : -1.0, d.z >= 0.0 ? 1.0 : -1.0);
    }
    return e * 0.5 + 0.5;
}

vec3 oct_uv_to_dir(vec2 uv) {
    vec2 e = uv * 2.0 - 1.0;
    vec3 d = vec3(e.x, 1.0 - abs(e.x) - abs(e.y), e.y);
    if (d.y < 0.0) {
        vec2 f = (1.0 - abs(e.yx)) * vec2(e.x >= 0.0 ? 1.0 : -1.0, e.y >= 0.0 ? 1.0 : -1.0);
        d.x = f.x;
        d.z = f.y;
    }
    return normalize(d);
}

// Wrap a uv that lies up to one border width outside [0, 1]^2 back inside.
vec2 oct_wrap_uv(vec2 uv) {
    if (uv.x < 0.0) { uv = vec2(-uv.x, 1.0 - uv.y); }
    else if (uv.x > 1.0) { uv = vec2(2.0 - uv.x, 1.0 - uv.y); }
    if (uv.y < 0.0) { uv = vec2(1.0 - uv.x, -uv.y); }
    else if (uv.y > 1.0) { uv = vec2(1.0 - uv.x, 2.0 - uv.y); }
    return uv;
}
#endif
