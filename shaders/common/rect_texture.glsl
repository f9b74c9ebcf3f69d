// The RectLight texture array (issue 37 item 3; renderer/gl_delegate.py,
// scene/rect_texture.py): one square layer per texture holding texture / its mean per
// channel (RGB16F), with an exactly box-filtered mip chain (each texel of level k the
// mean of the texture over its part of the rect). The light's intensity carries the
// mean, so radiance (nits) at a point of the rect = the uniform radiance x this factor.
//
// Addressing (UsdLux: "a texture file's min coordinates at (+X, +Y), max at (-X, -Y)"):
// (a, b) in [0, 1]^2 are the fractions of the rect from its -X edge along +X and from
// its -Y edge along +Y; the image's first column lies on +X, its top row on +Y.
#ifndef STB_RECT_TEXTURE_GLSL
#define STB_RECT_TEXTURE_GLSL

uniform sampler2DArray u_rect_tex;

// Prefiltered texture factor at rect fractions ab, mip level lod (0: full size).
vec3 rect_tex_at(float layer, vec2 ab, float lod) {
    return textureLod(u_rect_tex, vec3(1.0 - ab, layer), lod).rgb;
}

// Last mip level (1 x 1: the mean, i.e. 1).
float rect_tex_max_lod() {
    return log2(float(textureSize(u_rect_tex, 0).x));
}
#endif
