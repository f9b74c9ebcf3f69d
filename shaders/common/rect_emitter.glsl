// Textured RectLights the camera sees (issue 37 item 3): the emitting (-Z) face of each
// rect in u_rect_seen (renderer/gl_delegate.seen_rect_emitters, up to LIM_RECT_TEXTURES,
// lights whose visibleInPrimaryRay is on) shows radiance x its texture wherever it is
// nearer than the pixel's surface. Render frame, metres, nits (before the exposure
// scale and the OCIO output, like every other radiance the lighting pass writes).
#ifndef STB_RECT_EMITTER_GLSL
#define STB_RECT_EMITTER_GLSL
#include "common/frame.glsl"
#include "common/rect_texture.glsl"

uniform int u_rect_seen_count;
// Per rect, 4 vec4: centre (m) + texture layer; +X half axis (m); +Y half axis (m);
// radiance (nits, the texture's mean).
uniform vec4 u_rect_seen[4 * LIM_RECT_TEXTURES];

// The camera ray through pixel centre `pixel`: origin on the near plane, unit direction.
void camera_ray(vec2 pixel, out vec3 O, out vec3 D) {
    O = world_pos_from_depth(pixel, u_clip.x);
    D = normalize(world_pos_from_depth(pixel, u_clip.x + 1.0) - O);
}

// Radiance (nits) of the nearest textured rect face the ray (O, D) meets at a distance
// under t_max (m); false when it meets none. The texture is prefiltered at the pixel's
// footprint on the rect.
bool rect_emitter_seen(vec3 O, vec3 D, float t_max, out vec3 rad) {
    rad = vec3(0.0);
    bool hit = false;
    float pix = 2.0 * u_tan_off.y * u_resolution.w;  // pixel height at unit depth (rad)
    for (int k = 0; k < u_rect_seen_count; ++k) {
        vec3 C = u_rect_seen[4 * k].xyz;
        vec3 hx = u_rect_seen[4 * k + 1].xyz, hy = u_rect_seen[4 * k + 2].xyz;
        vec3 Z = normalize(cross(hx, hy));      // light +Z: it emits along -Z
        float cz = dot(D, Z);
        if (cz <= 1e-6) continue;               // the ray sees its back (or its edge)
        float t = dot(C - O, Z) / cz;
        if (t <= 0.0 || t >= t_max) continue;
        vec3 q = O + D * t - C;
        vec2 ab = vec2(dot(q, hx) / dot(hx, hx), dot(q, hy) / dot(hy, hy));
        if (any(greaterThan(abs(ab), vec2(1.0)))) continue;
        float side = 2.0 * sqrt(length(hx) * length(hy));
        float foot = (u_cam_pos.w > 0.5 ? pix : pix * t) / max(cz, 0.05);  // m on the rect
        float lod = clamp(log2(foot / side * float(textureSize(u_rect_tex, 0).x)), 0.0, rect_tex_max_lod());
        rad = u_rect_seen[4 * k + 3].rgb * rect_tex_at(u_rect_seen[4 * k].w, ab * 0.5 + 0.5, lod);
        t_max = t;
        hit = true;
    }
    return hit;
}
#endif
