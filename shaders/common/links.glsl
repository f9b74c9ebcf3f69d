// Light linking (scene/links.py, renderer/link_masks.py). Only with HAS_LINKS (a scene
// where some light lights less than everything): the G-buffer's g_link holds each
// pixel's link group (< LIM_LINK_GROUPS), the link SSBO each light's mask over the
// groups; a light lights a pixel when its bit for the pixel's group is set. Without
// HAS_LINKS this file declares nothing (link-free scenes compile today's shaders).
#ifndef STB_LINKS_GLSL
#define STB_LINKS_GLSL
#ifdef HAS_LINKS
uniform usampler2D g_link;  // r8ui link group per pixel (gbuffer.frag)

layout(std430, binding = SSBO_LIGHT_LINKS) readonly buffer LinkBuffer {
    uvec4 link_distant;                  // masks: x the sun, y..w the extra distant lights
    vec4 link_ambient[LIM_LINK_GROUPS];  // rgb ambient radiance (nits) of each group
    uint link_mask[];                    // per light of the bound light buffer, same order
};

uint link_group(ivec2 px) { return texelFetch(g_link, px, 0).r; }

// Light i of the light buffer lights link group `group`.
bool light_linked(uint i, uint group) { return ((link_mask[i] >> group) & 1u) != 0u; }

// Distant light j (0: the sun, 1..3: the extra ones) lights link group `group`.
bool distant_linked(int j, uint group) { return ((link_distant[j] >> group) & 1u) != 0u; }
#endif
#endif
