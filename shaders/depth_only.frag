// Depth-only pass: nothing to write. ALPHA_TEST: cut-outs (opacity below the
// material's opacityThreshold) leave no depth, as in the G-buffer.
#ifdef ALPHA_TEST
#include "common/material.glsl"
in vec2 v_uv;
uniform float u_opacity;
uniform float u_opacity_threshold;
void main() {
    float opacity = mat_value(SLOT_OPACITY, v_uv, vec4(u_opacity)).x;
    if (!(opacity >= u_opacity_threshold)) discard;
}
#else
void main() { }
#endif
