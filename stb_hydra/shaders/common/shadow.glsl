// Shadow terms of local lights from the shadow atlas. Until the atlas exists
// every local light is unshadowed (the reference method's documented state).
#ifndef STB_SHADOW_GLSL
#define STB_SHADOW_GLSL
#include "common/lights.glsl"

// Visibility in [0, 1] of light L from surface point P with normal N (1 = lit),
// already mixed with the light's shadow colour: returns an RGB factor.
vec3 local_shadow(Light L, vec3 P, vec3 N) {
    return vec3(1.0);
}
#endif
