// Debug AOV "shadowterms": the 8-bit deferred shadow terms (shadow x cone x IES)
// brought back to screen space: each pixel shows, as grey, the term of its quad
// (or its own with shadow_res = "pixel") for sample k mod STB_N, k = the pixel's
// place in its 2x2 quad (the same mosaic as the "smalltile" AOV).
#include "common/frame.glsl"
#include "common/tiles.glsl"

uniform sampler2D u_terms;       // rgba8 terms, one 8x8 block of quads per small tile

layout(location = 0) out vec4 o_color;

void main() {
    ivec2 px = ivec2(gl_FragCoord.xy);
    ivec2 st;
    int slot;
    quad_owner(px, st, slot);
#ifdef STB_PIXEL_TERMS
    ivec2 tx = px;
#else
    ivec2 tx = term_texel(st, slot);
#endif
    vec4 t = texelFetch(u_terms, tx, 0);
    int j = ((px.x & 1) | ((px.y & 1) << 1)) % STB_N;
    o_color = vec4(vec3(t[j]), 1.0);
}
