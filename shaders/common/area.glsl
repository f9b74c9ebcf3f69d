// Area lights (issue 20): rect, disk, sphere and cylinder lights of uniform radiance
// integrated over the part of their emitting surface a shading point sees.
//
// Diffuse: the exact irradiance of a polygon (Lambert's contour integral, each edge
// clipped to the surface's horizon). The rect is its own polygon; the disk rim, the
// sphere's silhouette circle and the cylinder's visible strip (two silhouette lines and
// the two near half-rims) are polygons of LIM_AREA_POLY_VERTS vertices scaled to keep
// their area. A sphere or a tube of uniform radiance looks, from P, exactly like the
// region its silhouette bounds, so the same polygon serves both lobes. A sphere's diffuse
// part is its exact closed-form form factor instead (sphere_form_factor: no polygon).
// Specular (GGX): linearly transformed cosines (Heitz, Dupuy, Hill & Neubelt 2016): the
// polygon, in the frame (tangent towards V, bitangent, N), is mapped by the fitted
// inverse matrix Minv(N.V, alpha) and integrated as a clamped cosine (the same contour
// integral, clipped to the transformed horizon) x the lobe's albedo with Schlick's
// Fresnel split out (tools/fit_ltc.py, stb_hydra/data/ltc_ggx.npy, bound as u_ltc).
// A light much narrower than the lobe (s = half extent / distance below
// LIM_AREA_SPEC_POINT x alpha) keeps the point model's specular, which is exact there;
// above LIM_AREA_SPEC_LTC x alpha the LTC integral; linear blend in between.
//
// Shaping (cone, focus, focusTint, IES) is evaluated once per shading point, towards
// the point from the light's centre, and multiplies the area's radiance: far from the
// light this is exactly the point model's intensity distribution (I0 x emission x
// shaping). A light whose half extent is below LIM_AREA_POINT_RATIO of its distance
// (and, on a smooth surface, below LIM_AREA_SPEC_POINT x alpha), a treatAsPoint
// sphere, a mesh light and a zero-size light use the point model.
#ifndef STB_AREA_GLSL
#define STB_AREA_GLSL
#include "common/brdf.glsl"

#define AREA_MAXV (2 * LIM_AREA_POLY_VERTS + 2)

// LTC table (tools/fit_ltc.py): layer 0 Minv (m00, m02, m20, m22) with m11 = 1, layer 1
// (n, f): the lobe's albedo with F = 1 and its (1 - V.H)^5-weighted part. Texel (j, i):
// sqrt(alpha) from sqrt(LIM_GGX_ALPHA_MIN) to 1, sqrt(1 - N.V) from 0 to 1.
uniform sampler2DArray u_ltc;

vec3 light_bitangent(Light L) { return cross(-L.axis_emit.xyz, L.tangent_tex.xyz); }

// Half extent of the light (m): the radius of a disk or sphere, half the diagonal of a
// rect, half the length of a cylinder (0 for the point model).
float light_half_extent(Light L) {
    if (L.area.z == AREA_POINT) return 0.0;
    if (L.area.z == AREA_RECT) return length(L.area.xy);
    if (L.area.z == AREA_CYLINDER) return max(L.area.x, L.area.y);
    return L.area.x;
}

// Half axes (m, world) of the disk with the light's area as seen along -ldir (unit,
// from the receiver towards the light): the shape its soft shadows use (PCSS in
// common/shadow.glsl). Rect and cylinder: their axes scaled to the equal-area ellipse.
void light_shadow_axes(Light L, vec3 ldir, out vec3 A, out vec3 B) {
    vec3 X = L.tangent_tex.xyz;
    const float k = 1.1283792;  // 2 / sqrt(pi): square of half side 1 -> disk of equal area
    if (L.area.z == AREA_RECT) { A = X * L.area.x * k; B = light_bitangent(L) * L.area.y * k; return; }
    if (L.area.z == AREA_DISK) { A = X * L.area.x; B = light_bitangent(L) * L.area.x; return; }
    vec3 side = cross(X, ldir);
    if (L.area.z == AREA_CYLINDER && dot(side, side) > 1e-6) {
        A = X * L.area.x * k; B = normalize(side) * L.area.y * k; return;
    }
    vec3 u = normalize(abs(ldir.y) < 0.9 ? cross(ldir, vec3(0.0, 1.0, 0.0)) : cross(ldir, vec3(1.0, 0.0, 0.0)));
    float r = L.area.z == AREA_CYLINDER ? L.area.y : L.area.x;
    A = u * r; B = cross(ldir, u) * r;
}

bool light_is_area(Light L, float dist) {
    return L.area.z != AREA_POINT && light_half_extent(L) > LIM_AREA_POINT_RATIO * dist;
}

// Vertices (relative to the shading point P) of the region of the light P sees; 0 when
// it sees none of its emitting surface (behind a one-sided emitter, inside a sphere or
// tube).
int area_polygon(Light L, vec3 P, out vec3 v[AREA_MAXV]) {
    const int M = LIM_AREA_POLY_VERTS;
    vec3 c = L.pos_range.xyz - P;          // light centre relative to P
    vec3 X = L.tangent_tex.xyz;
    vec3 Y = light_bitangent(L);
    vec3 Z = L.axis_emit.xyz;              // emission axis (light -Z)
    float kind = L.area.z;
    // Polygon of M vertices with the area of its circumscribed circle.
    float grow = sqrt(2.0 * PI / (float(M) * sin(2.0 * PI / float(M))));
    if (kind == AREA_RECT || kind == AREA_DISK) {
        if (dot(-c, Z) <= 0.0) return 0;   // behind the emitting face (or in its plane)
        if (kind == AREA_RECT) {
            vec3 hx = X * L.area.x, hy = Y * L.area.y;
            v[0] = c - hx - hy; v[1] = c + hx - hy; v[2] = c + hx + hy; v[3] = c - hx + hy;
            return 4;
        }
        float r = L.area.x * grow;
        for (int k = 0; k < M; ++k) {
            float a = 2.0 * PI * float(k) / float(M);
            v[k] = c + r * (cos(a) * X + sin(a) * Y);
        }
        return M;
    }
    if (kind == AREA_SPHERE) {
        float d = length(c);
        float r = L.area.x;
        if (d <= r * 1.0001) return 0;     // inside: sees the emitter's back faces
        vec3 a = c / d;
        vec3 u = normalize(abs(a.y) < 0.9 ? cross(a, vec3(0.0, 1.0, 0.0)) : cross(a, vec3(1.0, 0.0, 0.0)));
        vec3 w = cross(a, u);
        vec3 cc = a * (d - r * r / d);    // centre of the silhouette circle
        float rho = r * sqrt(max(1.0 - r * r / (d * d), 0.0)) * grow;
        for (int k = 0; k < M; ++k) {
            float t = 2.0 * PI * float(k) / float(M);
            v[k] = cc + rho * (cos(t) * u + sin(t) * w);
        }
        return M;
    }
    // Cylinder along X, half length area.x, radius area.y: the visible side strip.
    float h = L.area.x, r = L.area.y;
    vec3 q = -c;                           // P relative to the centre
    float t = dot(q, X);
    vec3 qr = q - t * X;
    float rho = length(qr);
    if (rho <= r * 1.0001) return 0;       // inside the tube or on its axis: back faces
    vec3 e = qr / rho;
    vec3 f = cross(X, e);
    float phi0 = acos(r / rho);            // silhouette generators at +-phi0
    int K = M / 2;
    for (int k = 0; k < K; ++k) {
        float a = -phi0 + 2.0 * phi0 * float(k) / float(K - 1);
        vec3 rim = r * (cos(a) * e + sin(a) * f);
        v[k] = c - h * X + rim;            // near half-rim at -h, from -phi0 to +phi0
        v[2 * K - 1 - k] = c + h * X + rim;  // near half-rim at +h, back from +phi0
    }
    return 2 * K;
}

// Sutherland-Hodgman: keep the part of the polygon above the plane dot(N, x) = 0.
int clip_horizon(inout vec3 v[AREA_MAXV], int n, vec3 N) {
    vec3 o[AREA_MAXV];
    int m = 0;
    for (int i = 0; i < n; ++i) {
        vec3 a = v[i], b = v[(i + 1) % n];
        float da = dot(N, a), db = dot(N, b);
        if (da >= 0.0 && m < AREA_MAXV) o[m++] = a;
        if ((da >= 0.0) != (db >= 0.0) && m < AREA_MAXV) o[m++] = a + (b - a) * (da / (da - db));
    }
    for (int i = 0; i < m; ++i) v[i] = o[i];
    return m;
}

// Form factor of a polygon (relative to P) for a surface of unit normal N, horizon
// clipped: irradiance / (pi x radiance), in [0, 1].
float polygon_form_factor(vec3 v[AREA_MAXV], int n, vec3 N) {
    n = clip_horizon(v, n, N);
    if (n < 3) return 0.0;
    float sum = 0.0;
    vec3 a = normalize(v[n - 1]);
    for (int i = 0; i < n; ++i) {
        vec3 b = normalize(v[i]);
        vec3 cr = cross(a, b);
        float s = length(cr);
        float th = atan(s, dot(a, b));
        sum += dot(cr, N) * (s > 1e-9 ? th / s : 1.0);
        a = b;
    }
    return min(abs(sum) / (2.0 * PI), 1.0);
}

// Weight of the LTC specular against the point model's (0: point, 1: LTC) for a light
// of half extent `ext` at distance `dist` on a lobe of width alpha.
float area_spec_weight(float ext, float dist, float alpha) {
    float x = ext / (max(dist, LIM_MIN_LIGHT_DISTANCE) * alpha);
    return clamp((x - LIM_AREA_SPEC_POINT) / (LIM_AREA_SPEC_LTC - LIM_AREA_SPEC_POINT), 0.0, 1.0);
}

// The LTC of surface s: the frame (T1 towards V, T2, N), the fitted inverse matrix m
// (m00, m02, m20, m22) and the lobe's albedo with Schlick's Fresnel (f0) split out.
void ltc_setup(Surface s, out vec3 T1, out vec3 T2, out vec4 m, out vec3 albedo) {
    float NoV = clamp(dot(s.N, s.V), 1e-4, 1.0);
    T1 = s.V - s.N * dot(s.N, s.V);
    float lt = length(T1);
    T1 = lt > 1e-5 ? T1 / lt
        : normalize(abs(s.N.y) < 0.9 ? cross(s.N, vec3(0.0, 1.0, 0.0)) : cross(s.N, vec3(1.0, 0.0, 0.0)));
    T2 = cross(s.N, T1);
    vec2 size = vec2(textureSize(u_ltc, 0).xy);
    float amin = sqrt(LIM_GGX_ALPHA_MIN);
    vec2 t = vec2((sqrt(s.alpha) - amin) / (1.0 - amin), sqrt(1.0 - NoV));
    vec2 uv = (clamp(t, 0.0, 1.0) * (size - 1.0) + 0.5) / size;
    m = texture(u_ltc, vec3(uv, 0.0));
    vec2 nf = texture(u_ltc, vec3(uv, 1.0)).xy;
    albedo = s.f0 * (nf.x - nf.y) + nf.y;
}

// Point p (relative to P, world) mapped into the LTC's cosine space.
vec3 ltc_apply(vec3 T1, vec3 T2, vec3 N, vec4 m, vec3 p) {
    vec3 q = vec3(dot(T1, p), dot(T2, p), dot(N, p));
    return vec3(m.x * q.x + m.y * q.z, q.y, m.z * q.x + m.w * q.z);
}

// GGX specular x cos of a polygon (relative to P), integrated by LTC: per unit radiance,
// with Schlick's Fresnel (f0).
vec3 ltc_specular(Surface s, vec3 v[AREA_MAXV], int n) {
    vec3 T1, T2, albedo;
    vec4 m;
    ltc_setup(s, T1, T2, m, albedo);
    vec3 w[AREA_MAXV];
    for (int i = 0; i < n; ++i) w[i] = ltc_apply(T1, T2, s.N, m, v[i]);
    float I = polygon_form_factor(w, n, vec3(0.0, 0.0, 1.0));
    return albedo * I;
}

// ---- The same polygon integrals, streamed (issue 34) --------------------------------
// area_polygon + polygon_form_factor (+ ltc_specular) vertex by vertex, without arrays:
// on llvmpipe a local array indexed by a loop counter lives in memory and every access
// is a per-lane gather / scatter (the clip's copies, the LTC's transformed copy), which
// cost ~88 % of a disk / rect light's shading. The vertices are generated in
// area_polygon's order with its expressions, clipped to the horizon edge by edge
// (Sutherland-Hodgman's output edges: each original edge's part above the horizon, and
// from each exit point to the next entry point along the horizon) and summed as they
// come; only the order of the sum differs (float rounding). The exact methods
// (light_radiance) use it; light_reflect keeps the array form (STB, reuse).

// cos, sin of 2 pi k / LIM_AREA_POLY_VERTS, constant-folded as area_polygon's unrolled loop.
#define AREA_CS(k) vec2(cos(2.0 * PI * float(k) / float(LIM_AREA_POLY_VERTS)), \
                        sin(2.0 * PI * float(k) / float(LIM_AREA_POLY_VERTS)))
#if LIM_AREA_POLY_VERTS != 16
#error "AREA_CIRCLE lists 16 vertices: LIM_AREA_POLY_VERTS changed"
#endif
const vec2 AREA_CIRCLE[16] = vec2[](AREA_CS(0), AREA_CS(1), AREA_CS(2), AREA_CS(3), AREA_CS(4),
    AREA_CS(5), AREA_CS(6), AREA_CS(7), AREA_CS(8), AREA_CS(9), AREA_CS(10), AREA_CS(11),
    AREA_CS(12), AREA_CS(13), AREA_CS(14), AREA_CS(15));

// What area_polygon's vertex k needs (relative to P, world): a rect's centre and half
// axes; else vertex k = B + R (cos a_k U + sin a_k W), B = B0 (cylinder: B1 for its
// second half-rim), a_k = 2 pi k / M (cylinder: from -phi0 to +phi0 and back).
struct AreaPoly {
    float kind;
    int n;
    vec3 c, hx, hy;    // rect
    vec3 B0, B1, U, W; // circle / rims
    float R, phi0;
};

// area_polygon's set-up: the vertex count (0: P sees none of the emitting surface).
int area_poly_setup(Light L, vec3 P, out AreaPoly p) {
    const int M = LIM_AREA_POLY_VERTS;
    vec3 c = L.pos_range.xyz - P;
    vec3 X = L.tangent_tex.xyz;
    vec3 Y = light_bitangent(L);
    vec3 Z = L.axis_emit.xyz;
    p.kind = L.area.z;
    p.c = c; p.hx = X * L.area.x; p.hy = Y * L.area.y;
    p.B0 = c; p.B1 = c; p.U = X; p.W = Y; p.phi0 = 0.0;
    float grow = sqrt(2.0 * PI / (float(M) * sin(2.0 * PI / float(M))));
    p.R = L.area.x * grow;
    p.n = 0;
    if (p.kind == AREA_RECT || p.kind == AREA_DISK) {
        if (dot(-c, Z) <= 0.0) return 0;
        p.n = p.kind == AREA_RECT ? 4 : M;
        return p.n;
    }
    if (p.kind == AREA_SPHERE) {
        float d = length(c);
        float r = L.area.x;
        if (d <= r * 1.0001) return 0;
        vec3 a = c / d;
        vec3 u = normalize(abs(a.y) < 0.9 ? cross(a, vec3(0.0, 1.0, 0.0)) : cross(a, vec3(1.0, 0.0, 0.0)));
        p.B0 = a * (d - r * r / d);
        p.R = r * sqrt(max(1.0 - r * r / (d * d), 0.0)) * grow;
        p.U = u; p.W = cross(a, u);
        p.n = M;
        return M;
    }
#ifdef NO_CYLINDER_LIGHTS  // no cylinder in view (InViewLights.has_cylinders)
    return 0;
#else
    float h = L.area.x, r = L.area.y;
    vec3 q = -c;
    float t = dot(q, X);
    vec3 qr = q - t * X;
    float rho = length(qr);
    if (rho <= r * 1.0001) return 0;
    vec3 e = qr / rho;
    p.U = e; p.W = cross(X, e);
    p.phi0 = acos(r / rho);
    p.R = r;
    p.B0 = c - h * X; p.B1 = c + h * X;
    p.n = 2 * (M / 2);
    return p.n;
#endif
}

// Vertex k (0 <= k < p.n) of area_polygon, relative to P.
vec3 area_vertex(AreaPoly p, int k) {
    float sx = k == 1 || k == 2 ? 1.0 : -1.0, sy = k >= 2 ? 1.0 : -1.0;
    vec3 rect = p.c + sx * p.hx + sy * p.hy;
    vec2 cs = AREA_CIRCLE[k & 15];
    vec3 B = p.B0;
#ifndef NO_CYLINDER_LIGHTS  // its cos / sin per vertex ran for every light (llvmpipe)
    if (p.kind == AREA_CYLINDER) {
        int K = p.n / 2;
        int j = k < K ? k : 2 * K - 1 - k;
        float a = -p.phi0 + 2.0 * p.phi0 * float(j) / float(K - 1);
        cs = vec2(cos(a), sin(a));
        B = k < K ? p.B0 : p.B1;
        return B + p.R * (cs.x * p.U + cs.y * p.W);
    }
#endif
    return p.kind == AREA_RECT ? rect : B + p.R * (cs.x * p.U + cs.y * p.W);
}

// polygon_form_factor's term of edge a -> b (unit vectors) for normal N.
float contour_term(vec3 a, vec3 b, vec3 N) {
    vec3 cr = cross(a, b);
    float s = length(cr);
    float th = atan(s, dot(a, b));
    return dot(cr, N) * (s > 1e-9 ? th / s : 1.0);
}

// A horizon-clipped contour integral fed one polygon vertex at a time.
struct Contour {
    vec3 a, ah;          // the last vertex and its unit vector
    float da;            // its height over the horizon (dot(N, a))
    vec3 exit_h, entry_h;  // the pending exit point, the first entry point (unit)
    bool has_exit, has_entry;
    float sum;
    int count;           // vertices of the clipped polygon
};

void contour_start(out Contour c, vec3 a, vec3 N) {
    c.a = a; c.ah = normalize(a); c.da = dot(N, a);
    c.exit_h = vec3(0.0, 0.0, 1.0); c.entry_h = vec3(0.0, 0.0, 1.0);
    c.has_exit = false; c.has_entry = false;
    c.sum = 0.0; c.count = 0;
}

// Edge from the last vertex to b: its part above the horizon, and on entering, the
// horizon edge from the pending exit point (Sutherland-Hodgman's output edges).
void contour_edge(inout Contour c, vec3 b, vec3 N) {
    vec3 a = c.a;
    float da = c.da, db = dot(N, b);
    bool ina = da >= 0.0, inb = db >= 0.0;
    vec3 x = a + (b - a) * (da / (da - db));
    vec3 xh = normalize(x), bh = normalize(b);
    bool crossing = ina != inb;
    float seg = contour_term(ina ? c.ah : xh, inb ? bh : xh, N);
    if (ina || inb) c.sum += seg;
    float join = contour_term(c.exit_h, xh, N);
    if (crossing && inb) {            // entering: from the pending exit, or the first entry
        if (c.has_exit) c.sum += join;
        else if (!c.has_entry) { c.entry_h = xh; c.has_entry = true; }
        c.has_exit = false;
    }
    if (crossing && ina) { c.exit_h = xh; c.has_exit = true; }
    c.count += (ina ? 1 : 0) + (crossing ? 1 : 0);
    c.a = b; c.ah = bh; c.da = db;
}

// polygon_form_factor's value once every edge is in.
float contour_end(Contour c, vec3 N) {
    float sum = c.sum;
    if (c.has_exit && c.has_entry) sum += contour_term(c.exit_h, c.entry_h, N);
    return c.count < 3 ? 0.0 : min(abs(sum) / (2.0 * PI), 1.0);
}

// The diffuse form factor (normal s.N) and the LTC specular (albedo x clamped-cosine
// integral) of the polygon p, in one pass over its vertices.
// `diffuse` false: the LTC integral alone (F = 0; the sphere lights' closed form).
void area_integrals(AreaPoly p, Surface s, const bool diffuse, out float F, out vec3 ltc) {
    vec3 T1, T2, albedo;
    vec4 m;
    ltc_setup(s, T1, T2, m, albedo);
    const vec3 Z = vec3(0.0, 0.0, 1.0);
    Contour cd, cl;
    vec3 v0 = area_vertex(p, 0);
    contour_start(cd, v0, s.N);
    contour_start(cl, ltc_apply(T1, T2, s.N, m, v0), Z);
    for (int k = 1; k <= p.n; ++k) {
        vec3 v = area_vertex(p, k < p.n ? k : 0);
        if (diffuse) contour_edge(cd, v, s.N);
        contour_edge(cl, ltc_apply(T1, T2, s.N, m, v), Z);
    }
    F = diffuse && p.n > 0 ? contour_end(cd, s.N) : 0.0;
    ltc = p.n == 0 ? vec3(0.0) : albedo * contour_end(cl, Z);
}

#ifdef RECT_TEXTURES
#include "common/rect_texture_shading.glsl"
#endif

// Form factor of a sphere of radius r whose centre is at c (relative to P, |c| > r) for a
// surface of unit normal N, horizon clipped: irradiance / (pi x radiance), in [0, 1].
// Exact, in closed form (Snyder 1996, "Area light sources for real-time graphics";
// Lagarde & de Rousiers 2014, "Moving Frostbite to PBR", sphere illuminance): fully above
// the horizon sin^2(sigma) cos(theta), the point formula; across it the clipped cap.
float sphere_form_factor(vec3 c, float r, vec3 N) {
    float d2 = dot(c, c);
    float s2 = min(r * r / d2, 1.0);        // sin^2 of the angular radius sigma
    float ct = dot(N, c) * inversesqrt(d2); // cos theta, theta: from N to the centre
    if (ct * ct >= s2) return ct > 0.0 ? s2 * ct : 0.0;
    float st = sqrt(max(1.0 - ct * ct, 1e-12));
    float x = sqrt(max(1.0 / s2 - 1.0, 0.0));  // cot sigma
    float y = clamp(-x * ct / st, -1.0, 1.0);
    float sy = st * sqrt(1.0 - y * y);
    float e = (ct * acos(y) - x * sy) * s2 + atan(sy, x);
    return clamp(e / PI, 0.0, 1.0);
}

// light_reflect for a sphere light (L.area.z == AREA_SPHERE) past the point-model test, on
// a lobe the light is narrow against everywhere (ws == 0): the diffuse part is the
// sphere's closed-form form factor (no polygon), the specular the point model. Ldir,
// dist, f: light_falloff's. False inside the sphere.
bool sphere_reflect_narrow(Light L, Surface s, vec3 Ldir, float dist, float f, vec3 ssp,
                           out vec3 diff, out vec3 spec) {
    diff = vec3(0.0); spec = vec3(0.0);
    float r = L.area.x;
    if (dist <= r * 1.0001) return false;   // inside: sees the emitter's back faces
    float window = range_window(dist, L.pos_range.w);
    vec3 Lrad = L.intensity.rgb * L.area.w * window * light_tint_rgb(L, -Ldir);
    diff = s.diffuse * Lrad * sphere_form_factor(Ldir * dist, r, s.N);
    spec = ssp * L.intensity.rgb * light_shape_rgb(L, -Ldir) * f;
    return true;
}

// sphere_reflect_narrow with the specular blended by ws (area_spec_weight) towards the
// LTC integral over the sphere's silhouette polygon (built only when ws > 0; streamed:
// area_integrals; the exact methods' wide-sphere loop).
bool sphere_reflect(Light L, Surface s, vec3 Ldir, float dist, float f, float ws, vec3 ssp,
                    out vec3 diff, out vec3 spec) {
    if (!sphere_reflect_narrow(L, s, Ldir, dist, f, ssp, diff, spec)) return false;
    if (ws > 0.0) {
        spec *= 1.0 - ws;
#ifdef AREA_ARRAY_INTEGRALS  // the array form (tests compare the two)
        vec3 v[AREA_MAXV];
        int n = area_polygon(L, s.P, v);
        vec3 ltc = ltc_specular(s, v, n);
#else
        AreaPoly p;
        area_poly_setup(L, s.P, p);
        float unused;
        vec3 ltc;
        area_integrals(p, s, false, unused, ltc);  // the LTC integral, streamed
#endif
        vec3 Lrad = L.intensity.rgb * L.area.w * range_window(dist, L.pos_range.w)
                  * light_tint_rgb(L, -Ldir);
        spec += ltc * Lrad * ws;
    }
    return true;
}

#ifdef HAS_CLEARCOAT
// light_reflect for a clearcoated surface: the base as there, attenuated by the coat's
// Fresnel (per VoH for the point model; at NoV, a directional average, for the area
// integral), plus the coat lobe, point model and LTC blended by its own weight wc.
bool area_reflect_coated(Light L, Surface s, vec3 Ldir, float dist, float f, float ws,
                         float wc, out vec3 diff, out vec3 spec) {
    diff = vec3(0.0); spec = vec3(0.0);
    vec3 dsp, ssp;
    float csp, fc;
    brdf_eval_layers(s, Ldir, dsp, ssp, csp, fc);
    vec3 E = L.intensity.rgb * light_shape_rgb(L, -Ldir) * f;
    float NoV = max(dot(s.N, s.V), 1e-4);
    float fcv = s.coat * fresnel_schlick(NoV, vec3(COAT_F0)).x;
    vec3 v[AREA_MAXV];
    int n = area_polygon(L, s.P, v);
    bool area = light_is_area(L, dist);
    if (area && n == 0) return false;
    vec3 Lrad = L.intensity.rgb * L.area.w * range_window(dist, L.pos_range.w)
              * light_tint_rgb(L, -Ldir);
    float F = L.area.z == AREA_SPHERE ? sphere_form_factor(Ldir * dist, L.area.x, s.N)
                                      : polygon_form_factor(v, n, s.N);
    vec3 base_d = area ? s.diffuse * Lrad * F : dsp * E;
    vec3 base_s = ssp * E * (1.0 - ws);
    if (ws > 0.0 && n > 0) base_s += ltc_specular(s, v, n) * Lrad * ws;
    vec3 coat = vec3(csp) * E * (1.0 - wc);
    if (wc > 0.0 && n > 0) {
        Surface c = s;
        c.alpha = s.coat_alpha;
        c.f0 = vec3(COAT_F0);
        coat += ltc_specular(c, v, n) * Lrad * s.coat * wc;
    }
#ifdef RECT_TEXTURES
    if (L.tangent_tex.w >= 0.0 && n > 0) {  // a textured rect: every lobe over its texture
        vec3 ftex, stex, ctex = vec3(0.0), unused;
        rect_texture_terms(L, s, v, area, ws > 0.0, ftex, stex);
        if (wc > 0.0) {
            Surface c = s;
            c.alpha = s.coat_alpha;
            c.f0 = vec3(COAT_F0);
            rect_texture_terms(L, c, v, false, true, unused, ctex);
        }
        if (area) base_d = s.diffuse * Lrad * ftex;
        base_s = ssp * E * (1.0 - ws) + stex * Lrad * ws;
        coat = vec3(csp) * E * (1.0 - wc) + ctex * Lrad * s.coat * wc;
    }
#endif
    float att = area ? 1.0 - fcv : 1.0 - fc;
    diff = base_d * att;
    spec = base_s * att + coat;
    return true;
}
#endif

// Unshadowed radiance reflected towards s.V by light L, diffuse and specular parts
// (nits, before the light's diffuse/specular multipliers), WITHOUT the scalar shape
// (cone x normalised IES) -- the caller multiplies by light_shape_scalar(L, -Ldir).
// Ldir: unit direction from P to the light's centre. False when the light cannot
// reach P (out of range, behind a one-sided emitter, nothing visible).
// What light_reflect_head decided: the light does not reach P (false), the answer is
// complete (the point model or the clearcoat path: true), or the area path follows.
const int REFLECT_NONE = 0;
const int REFLECT_DONE = 1;
const int REFLECT_AREA = 2;

// The part light_reflect and light_reflect_exact share: the falloff, the specular LTC
// weight ws, the clearcoat path, the BRDF's specular factor ssp and the point model.
// For REFLECT_AREA, dist (m), f, ws and ssp are set and diff = spec = 0.
int light_reflect_head(Light L, Surface s, out vec3 Ldir, out float dist, out float f,
                       out float ws, out vec3 ssp, out vec3 diff, out vec3 spec) {
    diff = vec3(0.0); spec = vec3(0.0); ssp = vec3(0.0); ws = 0.0;
    f = light_falloff(L, s.P, Ldir, dist);
    if (f <= 0.0) return REFLECT_NONE;
    float ext = light_half_extent(L);
    // Specular LTC weight (0 when the light has no specular: nothing to integrate).
    ws = L.misc.w != 0.0 ? area_spec_weight(ext, dist, s.alpha) : 0.0;
    vec3 dsp;
#ifdef HAS_CLEARCOAT
    // The coat lobe has its own width: its own point/LTC weight.
    if (s.coat > 0.0) {
        float wc = L.misc.w != 0.0 ? area_spec_weight(ext, dist, s.coat_alpha) : 0.0;
        bool lit = area_reflect_coated(L, s, Ldir, dist, f, ws, wc, diff, spec);
        return lit ? REFLECT_DONE : REFLECT_NONE;
    }
#endif
    brdf_eval(s, Ldir, dsp, ssp);
    if (!light_is_area(L, dist) && ws <= 0.0) {
        vec3 E = L.intensity.rgb * light_shape_rgb(L, -Ldir) * f;
        diff = dsp * E; spec = ssp * E;
        return REFLECT_DONE;
    }
    return REFLECT_AREA;
}

bool light_reflect(Light L, Surface s, out vec3 Ldir, out vec3 diff, out vec3 spec) {
    float dist, f, ws;
    vec3 ssp;
    int head = light_reflect_head(L, s, Ldir, dist, f, ws, ssp, diff, spec);
    if (head != REFLECT_AREA) return head == REFLECT_DONE;
    // A sphere's diffuse is its closed form (sphere_form_factor), so it needs the
    // silhouette polygon only for the LTC specular; the other models integrate theirs.
    // One polygon and one LTC call serve both (each is inlined code: issue 34).
    bool sphere = L.area.z == AREA_SPHERE;
    if (sphere && dist <= L.area.x * 1.0001) return false;  // inside: back faces
    vec3 v[AREA_MAXV];
    int n = 0;
    if (!sphere || ws > 0.0) {
        n = area_polygon(L, s.P, v);
        if (n == 0 && !sphere) return false;
    }
    float window = range_window(dist, L.pos_range.w);
    // Radiance x focus tint x IES scale (no emission model: the polygon integrates it).
    vec3 Lrad = L.intensity.rgb * L.area.w * window * light_tint_rgb(L, -Ldir);
#ifdef RECT_TEXTURES
    if (L.tangent_tex.w >= 0.0) {  // a textured rect: its texture over the polygon
        vec3 ftex, stex;
        rect_texture_terms(L, s, v, true, ws > 0.0, ftex, stex);
        diff = s.diffuse * Lrad * ftex;
        if (ws < 1.0) spec = ssp * L.intensity.rgb * light_shape_rgb(L, -Ldir) * f * (1.0 - ws);
        if (ws > 0.0) spec += stex * Lrad * ws;
        return true;
    }
#endif
    float F = sphere ? sphere_form_factor(Ldir * dist, L.area.x, s.N)
                     : polygon_form_factor(v, n, s.N);
    diff = s.diffuse * Lrad * F;
    // Specular: the point model (the centre's direction, the far-field illuminance) for
    // a light narrow against the lobe, LTC for a wide one.
    if (ws < 1.0) spec = ssp * L.intensity.rgb * light_shape_rgb(L, -Ldir) * f * (1.0 - ws);
    if (ws > 0.0) spec += ltc_specular(s, v, n) * Lrad * ws;
    return true;
}

// light_reflect for the exact methods (light_radiance): the same value, the polygon's
// form factor and LTC integral streamed in one pass over its vertices (area_integrals:
// no vertex arrays; only the order of each contour sum differs). A textured rect
// (RECT_TEXTURES) and a clearcoat keep light_reflect's array path; AREA_ARRAY_INTEGRALS
// (tests only) takes it for every light.
bool light_reflect_exact(Light L, Surface s, out vec3 Ldir, out vec3 diff, out vec3 spec) {
#if defined(RECT_TEXTURES) || defined(AREA_ARRAY_INTEGRALS)
    return light_reflect(L, s, Ldir, diff, spec);
#else
    float dist, f, ws;
    vec3 ssp;
    int head = light_reflect_head(L, s, Ldir, dist, f, ws, ssp, diff, spec);
    if (head != REFLECT_AREA) return head == REFLECT_DONE;
    bool sphere = L.area.z == AREA_SPHERE;
    if (sphere && dist <= L.area.x * 1.0001) return false;  // inside: back faces
    AreaPoly p;
    int n = area_poly_setup(L, s.P, p);
    if (n == 0 && !sphere) return false;
    float window = range_window(dist, L.pos_range.w);
    vec3 Lrad = L.intensity.rgb * L.area.w * window * light_tint_rgb(L, -Ldir);
    float Fp;
    vec3 ltc;
    area_integrals(p, s, true, Fp, ltc);
    float F = sphere ? sphere_form_factor(Ldir * dist, L.area.x, s.N) : Fp;
    diff = s.diffuse * Lrad * F;
    if (ws < 1.0) spec = ssp * L.intensity.rgb * light_shape_rgb(L, -Ldir) * f * (1.0 - ws);
    if (ws > 0.0) spec += ltc * Lrad * ws;
    return true;
#endif
}

// Luminance of the unshadowed irradiance (lux) the light gives a surface (P, N), for
// STB's targets: the area integral for area lights, Ev x cos for the point model.
// Ev: the point model's facing illuminance luminance (the caller's), Ldir its direction.
float light_target_irradiance(Light L, vec3 P, vec3 N, vec3 Ldir, float dist, float Ev) {
    float NoL = dot(N, Ldir);
    if (!light_is_area(L, dist)) return Ev * max(NoL, 0.0);
    // A resampling target only needs to be roughly proportional and positive wherever
    // the light can reach P. A sphere of the light's half extent (sine of its angular
    // radius s): fully above the horizon its irradiance is exactly the point formula;
    // across the horizon the usual C1 quadratic (NoL + s)^2 / 4s; below it 0 -- at a
    // fraction of the polygon integral's cost (the small-tile pass evaluates K x 4 of
    // these per small tile).
    float s = clamp(light_half_extent(L) / max(dist, LIM_MIN_LIGHT_DISTANCE), 1e-4, 1.0);
    float c = NoL >= s ? NoL : (NoL > -s ? (NoL + s) * (NoL + s) / (4.0 * s) : 0.0);
    return Ev * c;
}
#endif
