// IES profile lookup: one normalised (theta, phi) table per layer of a 2D array
// texture (rows: theta 0..pi from the light's -Z axis, both ends exact; columns:
// phi 0..2pi from +X towards +Y, periodic). Values are multiplied by the light's
// IES scale (cd per table unit, includes the profile normalisation).
#ifndef STB_IES_GLSL
#define STB_IES_GLSL
#ifdef HAS_IES
uniform sampler2DArray u_ies;

// Normalised table value (max 1) towards w: cos_axis = dot(w, -Z_light);
// x, y = components of w along the light's +X, +Y. Multiply by the light's IES scale.
float ies_table(int layer, float angle_scale, float cos_axis, float x, float y) {
    float theta = acos(clamp(cos_axis, -1.0, 1.0));
    if (angle_scale > 0.0) {
        theta = theta / angle_scale;
    } else if (angle_scale < 0.0) {
        theta = (theta - PI) / -angle_scale + PI;
    }
    if (theta < 0.0 || theta > PI) return 0.0;
    float phi = atan(y, x);
    if (phi < 0.0) phi += 2.0 * PI;
    float v = (theta / PI * float(LIM_IES_THETA - 1) + 0.5) / float(LIM_IES_THETA);
    float u = phi / (2.0 * PI) + 0.5 / float(LIM_IES_PHI);
    return texture(u_ies, vec3(u, v, float(layer))).r;
}
#endif
#endif
