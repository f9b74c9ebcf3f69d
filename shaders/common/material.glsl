// Material texture lookups of a draw batch (renderer/material_binding.py binds them).
// Slots (LIM_MATERIAL_TEXTURE_SLOTS): 0 diffuseColor, 1 emissiveColor, 2 specularColor,
// 3 metallic, 4 roughness, 5 opacity, 6 normal, 7 occlusion, 8 clearcoat,
// 9 clearcoatRoughness. A slot's value at st is
//   u_mat_value[i] * texel + u_mat_bias[i]
// with texel sampled (trilinear, anisotropic, the slot's wrap modes as a sampler
// object) at (u_mat_st rows) * (s, t, 1); UDIM slots (u_mat_udim.x = first tile) pick
// the layer from floor(st) and read u_mat_fallback outside the tiles present.
#ifndef STB_MATERIAL_GLSL
#define STB_MATERIAL_GLSL

const int SLOT_DIFFUSE = 0;
const int SLOT_EMISSIVE = 1;
const int SLOT_SPECULAR = 2;
const int SLOT_METALLIC = 3;
const int SLOT_ROUGHNESS = 4;
const int SLOT_OPACITY = 5;
const int SLOT_NORMAL = 6;
const int SLOT_OCCLUSION = 7;
const int SLOT_CLEARCOAT = 8;
const int SLOT_CLEARCOAT_ROUGHNESS = 9;

uniform sampler2DArray u_mat_tex[LIM_MATERIAL_TEXTURE_SLOTS];
uniform int u_mat_on;                                   // bit i: slot i is textured
uniform mat4 u_mat_value[LIM_MATERIAL_TEXTURE_SLOTS];   // texel -> value
uniform vec4 u_mat_bias[LIM_MATERIAL_TEXTURE_SLOTS];
uniform vec4 u_mat_st[2 * LIM_MATERIAL_TEXTURE_SLOTS];  // rows of the 2x3 st transform
uniform ivec2 u_mat_udim[LIM_MATERIAL_TEXTURE_SLOTS];   // first tile (0: none), layers
uniform uvec4 u_mat_tiles[LIM_MATERIAL_TEXTURE_SLOTS];  // UDIM tiles present (bits)
uniform vec4 u_mat_fallback[LIM_MATERIAL_TEXTURE_SLOTS];

bool mat_textured(int i) { return ((u_mat_on >> i) & 1) != 0; }

vec4 mat_lookup(int i, vec2 st) {
    vec3 s1 = vec3(st, 1.0);
    vec2 uv = vec2(dot(u_mat_st[2 * i].xyz, s1), dot(u_mat_st[2 * i + 1].xyz, s1));
    // Derivatives of the continuous coordinates: no mip seams at UDIM tile edges.
    vec2 dx = dFdx(uv);
    vec2 dy = dFdy(uv);
    float layer = 0.0;
    if (u_mat_udim[i].x > 0) {
        vec2 tile = floor(uv);
        int k = int(tile.x) + 10 * int(tile.y);
        bool inside = tile.x >= 0.0 && tile.x <= 9.0 && tile.y >= 0.0
                      && k + LIM_UDIM_FIRST_TILE - u_mat_udim[i].x >= 0
                      && k + LIM_UDIM_FIRST_TILE - u_mat_udim[i].x < u_mat_udim[i].y;
        if (!inside) return u_mat_fallback[i];
        int l = k + LIM_UDIM_FIRST_TILE - u_mat_udim[i].x;
        if (((u_mat_tiles[i][l >> 5] >> uint(l & 31)) & 1u) == 0u) return u_mat_fallback[i];
        uv -= tile;
        layer = float(l);
    }
    vec4 texel = textureGrad(u_mat_tex[i], vec3(uv, layer), dx, dy);
    return u_mat_value[i] * texel + u_mat_bias[i];
}

// The slot's value if textured, else `constant`.
vec4 mat_value(int i, vec2 st, vec4 constant) {
    return mat_textured(i) ? mat_lookup(i, st) : constant;
}
#endif
