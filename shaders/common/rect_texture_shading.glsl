// A textured RectLight's reflected light (issue 37 item 3): the texture integrated over
// the rect instead of the uniform radiance (common/area.glsl's light_reflect calls this
// for a light whose texture layer, L.tangent_tex.w, is >= 0; compiled only when the
// scene has one: RECT_TEXTURES). The texture factor has mean 1 (common/rect_texture.glsl),
// so the light's power and far field are those of its mean.
//
// The rect is cut into G x G cells, each integrated as its own polygon (horizon-clipped
// form factor for the diffuse lobe, LTC integral for the specular one) times a texture
// value:
// * RECT_TEXTURE_EXACT (the exact methods: reference, tiled, clustered, light tree):
//   G = LIM_RECT_TEXTURE_GRID; the value is the cell's texel of the box-filtered mip
//   level with G x G texels (the texture's mean over the cell). Exact for a texture
//   constant over the cells; otherwise the error is the texture's variation inside a
//   cell against the kernel's.
// * otherwise (STB): G = LIM_RECT_TEXTURE_GRID_RT; the value is Heitz, Dupuy, Hill &
//   Neubelt 2016's textured-LTC lookup inside the cell: the prefiltered texture where
//   the cell integral's mean direction (its vector form factor, in cosine / LTC space)
//   meets it, at the mip level of the lobe's footprint there (LIM_RECT_TEXTURE_FOOTPRINT
//   x the distance to the plane, over the cell's size), never coarser than the cell.
#ifndef STB_RECT_TEXTURE_SHADING_GLSL
#define STB_RECT_TEXTURE_SHADING_GLSL
#include "common/rect_texture.glsl"

#ifdef RECT_TEXTURE_EXACT
#define RECT_CELLS LIM_RECT_TEXTURE_GRID

// Contour term of edge a -> b (unit vectors from P) for normal N (polygon_form_factor's).
float edge_form_factor(vec3 a, vec3 b, vec3 N) {
    vec3 cr = cross(a, b);
    float s = length(cr);
    return dot(cr, N) * (s > 1e-9 ? atan(s, dot(a, b)) / s : 1.0);
}

// polygon_form_factor of quad a b c d (relative to P), without the copies and the
// clipping loop when it lies wholly above the horizon (nearly every cell).
float quad_form_factor(vec3 a, vec3 b, vec3 c, vec3 d, vec3 N) {
    if (min(min(dot(N, a), dot(N, b)), min(dot(N, c), dot(N, d))) < 0.0) {
        vec3 v[AREA_MAXV];
        v[0] = a; v[1] = b; v[2] = c; v[3] = d;
        return polygon_form_factor(v, 4, N);
    }
    a = normalize(a); b = normalize(b); c = normalize(c); d = normalize(d);
    float sum = edge_form_factor(d, a, N) + edge_form_factor(a, b, N)
              + edge_form_factor(b, c, N) + edge_form_factor(c, d, N);
    return min(abs(sum) / (2.0 * PI), 1.0);
}

// Cell (i, j) of G, quad a, a + dx, a + dx + dy, a + dy (relative to P, world or LTC
// space) for normal N: its integral x its texture value.
vec3 rect_cell_term(Light L, int lod, int G, int i, int j, vec3 a, vec3 dx, vec3 dy, vec3 N) {
    vec3 t = texelFetch(u_rect_tex, ivec3(G - 1 - i, G - 1 - j, int(L.tangent_tex.w)), lod).rgb;
    return t * quad_form_factor(a, a + dx, a + dx + dy, a + dy, N);
}
#else
#define RECT_CELLS LIM_RECT_TEXTURE_GRID_RT

// Vector form factor of polygon v (relative to P) clipped to the horizon of N: its dot
// with N is 2 pi x the form factor, its direction the mean direction of the light the
// surface receives from it (0 when the polygon is below the horizon).
vec3 polygon_form_vector(vec3 v[AREA_MAXV], int n, vec3 N) {
    n = clip_horizon(v, n, N);
    vec3 sum = vec3(0.0);
    if (n < 3) return sum;
    vec3 a = normalize(v[n - 1]);
    for (int i = 0; i < n; ++i) {
        vec3 b = normalize(v[i]);
        vec3 cr = cross(a, b);
        float s = length(cr);
        sum += cr * (s > 1e-9 ? atan(s, dot(a, b)) / s : 1.0);
        a = b;
    }
    return sum;
}

// Cell (i, j) of G, quad a, a + dx, a + dx + dy, a + dy (relative to P, world or LTC
// space: the cell fractions survive linear maps) for normal N: its integral x the
// prefiltered texture where its vector form factor's direction meets it, at the mip
// level of the lobe's footprint (no coarser than the cell's level `lod`), kept half a
// texel (of the coarser of the two levels filtered) inside the cell.
vec3 rect_cell_term(Light L, int lod, int G, int i, int j, vec3 a, vec3 dx, vec3 dy, vec3 N) {
    vec3 v[AREA_MAXV];
    v[0] = a; v[1] = a + dx; v[2] = a + dx + dy; v[3] = a + dy;
    vec3 D = polygon_form_vector(v, 4, N);
    float F = min(abs(dot(D, N)) / (2.0 * PI), 1.0);
    if (F <= 0.0) return vec3(0.0);
    vec3 nrm = cross(dx, dy);
    float area = max(length(nrm), 1e-20);
    float h = dot(nrm, a);
    float den = dot(nrm, D);
    vec2 ab = vec2(0.5);
    if (abs(den) > 1e-6 * area * length(D)) {
        vec3 q = D * (h / den) - a;   // the hit, relative to the cell's corner
        float xx = dot(dx, dx), xy = dot(dx, dy), yy = dot(dy, dy);
        float qx = dot(q, dx), qy = dot(q, dy);
        ab = vec2(yy * qx - xy * qy, xx * qy - xy * qx) / max(xx * yy - xy * xy, 1e-30);
    }
    float cell = float(textureSize(u_rect_tex, 0).x) / float(G);   // texels per cell side
    float foot = LIM_RECT_TEXTURE_FOOTPRINT * abs(h) / area;   // m (or LTC units)
    float l = clamp(log2(foot * inversesqrt(area) * cell), 0.0, float(lod));
    float half_texel = 0.5 * exp2(ceil(l)) / cell;   // of the coarser level filtered
    ab = clamp(ab, vec2(half_texel), vec2(1.0 - half_texel));
    return F * rect_tex_at(L.tangent_tex.w, (vec2(i, j) + ab) / float(G), l);
}
#endif

// When `diffuse`, the texture-weighted form factor ff (rgb), and when `spec`, the LTC
// specular per unit radiance sp (rgb, Fresnel included) of textured rect L, polygon v
// (area_polygon: corners -X-Y, +X-Y, +X+Y, -X+Y, relative to P); 0 otherwise.
void rect_texture_terms(Light L, Surface s, vec3 v[AREA_MAXV], bool diffuse, bool spec,
                        out vec3 ff, out vec3 sp) {
    int lod = int(rect_tex_max_lod()) - findMSB(RECT_CELLS);
    // G x G texels at that level: read back, not the constant, so the compiler cannot
    // unroll the loop (one copy of the cell code: a cold compile near the untextured one).
    int G = textureSize(u_rect_tex, lod).x;
    vec3 ex = (v[1] - v[0]) / float(G), ey = (v[3] - v[0]) / float(G);
    vec3 T1 = vec3(0.0), T2 = vec3(0.0), albedo = vec3(0.0);
    vec4 m = vec4(0.0);
    if (spec) ltc_setup(s, T1, T2, m, albedo);
    vec3 wx = ltc_apply(T1, T2, s.N, m, ex), wy = ltc_apply(T1, T2, s.N, m, ey);
    vec3 w0 = ltc_apply(T1, T2, s.N, m, v[0]);
    ff = vec3(0.0);
    sp = vec3(0.0);
    // Cell k % G along +X, k / G along +Y; k >= G^2: the same cells for the LTC lobe.
    int n = spec ? 2 * G * G : G * G;
    for (int k = diffuse ? 0 : G * G; k < n; ++k) {
        bool lobe = k >= G * G;
        int c = lobe ? k - G * G : k;
        int i = c % G, j = c / G;
        vec3 a = lobe ? w0 + float(i) * wx + float(j) * wy : v[0] + float(i) * ex + float(j) * ey;
        vec3 t = rect_cell_term(L, lod, G, i, j, a, lobe ? wx : ex, lobe ? wy : ey,
                                lobe ? vec3(0.0, 0.0, 1.0) : s.N);
        if (lobe) sp += t; else ff += t;
    }
    sp *= albedo;
}
#endif
