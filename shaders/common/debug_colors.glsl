// Colours of the debug views (numpy twins in stb_hydra/io/debug_views.py).
#ifndef STB_DEBUG_COLORS_GLSL
#define STB_DEBUG_COLORS_GLSL

// Hash colour of a light index (numpy twin: io/debug_views.hash_colors).
vec3 light_color(uint i) {
    uint h = i * 747796405u + 2891336453u;
    h = ((h >> ((h >> 28u) + 4u)) ^ h) * 277803737u;
    h = (h >> 22u) ^ h;
    float hue = float(h & 1023u) / 1024.0;
    vec3 c = clamp(abs(fract(hue + vec3(0.0, 2.0 / 3.0, 1.0 / 3.0)) * 6.0 - 3.0) - 1.0, 0.0, 1.0);
    float v = 0.55 + 0.45 * float((h >> 10u) & 255u) / 255.0;
    return mix(vec3(1.0), c, 0.85) * v;
}

// Heat ramp t in [0, 1] -> blue, cyan, green, yellow, red (numpy twin:
// io/debug_views.heat_ramp).
vec3 heat_ramp(float t) {
    const vec3 stops[5] = vec3[5](vec3(0.1, 0.2, 1.0), vec3(0.0, 0.85, 1.0),
                                  vec3(0.1, 0.9, 0.2), vec3(1.0, 0.9, 0.0), vec3(1.0, 0.15, 0.1));
    float x = clamp(t, 0.0, 1.0) * 4.0;
    int i = min(int(x), 3);
    return mix(stops[i], stops[i + 1], x - float(i));
}

#endif
